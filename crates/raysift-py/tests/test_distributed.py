"""raysift.distributed on a local Ray cluster of two worker processes (issue #19): tiles, frames
and ray chunks equal the one-process results bit for bit, whatever the workers and the order; a
worker killed mid-run loses nothing; a rerun resumes; bad input fails before any work."""

import os
import signal

import numpy as np
import pytest

import raysift
from conftest import assert_bits_equal, find_shared_scenes, skip

ray = pytest.importorskip("ray", reason="pip install ray (CI installs it with raysift[test])")
from raysift import distributed as rd  # noqa: E402

SIZE = 64  # Cornell and BrainStem images: small, so the module runs in about a minute
FRAMES = 16


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of 2 CPUs (two worker processes), stopped at the end."""
    if ray.is_initialized():
        ray.shutdown()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def cornell():
    d = find_shared_scenes()
    p = d / "CornellBox-Original.obj" if d else None
    return str(p) if p and p.is_file() else "cornell"  # the generator when ../shared is absent


@pytest.fixture(scope="module")
def brainstem():
    d = find_shared_scenes()
    p = d / "animated" / "BrainStem.glb" if d else None
    if not (p and p.is_file()):
        skip("../shared/scenes/animated/BrainStem.glb not found (CI has it)")
    return str(p)


PATH = dict(spp=4, bounces=3, seed=11)


class Halt(Exception):
    """Raised by a callback to stop a run midway (as Ctrl-C or a lost driver would)."""


@pytest.fixture(scope="module")
def cornell_reference(cornell):
    return raysift.Scene.load(cornell).render(SIZE, SIZE, integrator="path", tracer="dacrt", **PATH)


def frames_one_process(spec, frames, size, tracer="bvh"):
    """The frames render_animation writes, made here in one process, as uint8 images."""
    anim = raysift.Animation.load(spec)
    cam = anim.camera(frames, size, size)
    out = []
    for k in range(frames):
        anim.set_time(anim.frame_time(k, frames))
        img = anim.scene.render(size, size, tracer=tracer, **cam)
        out.append(np.rint(img * 255).astype(np.uint8))
    return out


@pytest.mark.parametrize("workers,order", [(1, None), (2, None), (2, "shuffle")])
def test_tiles_equal_one_process(cluster, cornell, cornell_reference, workers, order):
    s = rd.render_tiles(cornell, SIZE, SIZE, tile=16, workers=workers, order=order, quiet=True,
                        **PATH)
    assert s["workers"] == workers and len(s["computed"]) == 16
    assert_bits_equal("tiled image", s["image"], cornell_reference)


def test_tiles_to_png(cluster, cornell, cornell_reference, tmp_path):
    out = tmp_path / "cb.png"
    # Uneven tiles: 24 px, so the last row and column are 16.
    s = rd.render_tiles(cornell, SIZE, SIZE, tile=24, out=out, quiet=True, **PATH)
    assert len(s["computed"]) == 9
    assert_bits_equal("png", rd.read_png(out).astype(np.float32) / np.float32(255), cornell_reference)
    assert sorted(os.listdir(tmp_path)) == ["cb.png", "cb.png.job.json"], "no partial file left"
    again = rd.render_tiles(cornell, SIZE, SIZE, tile=24, out=out, quiet=True, **PATH)
    assert again["computed"] == [] and len(again["skipped"]) == 9
    assert_bits_equal("png again", again["image"], cornell_reference)


def test_tiles_resume_after_interruption(cluster, cornell, cornell_reference, tmp_path):
    out = tmp_path / "cb.npy"
    seen = []

    def halt(key, info):
        seen.append(key)
        if len(seen) == 5:
            raise Halt

    with pytest.raises(Halt):
        rd.render_tiles(cornell, SIZE, SIZE, tile=16, out=out, quiet=True, callback=halt, **PATH)
    assert not out.exists(), "no final output from an interrupted run"
    s = rd.render_tiles(cornell, SIZE, SIZE, tile=16, out=out, quiet=True, **PATH)
    assert sorted(s["skipped"]) == sorted(seen)
    assert len(s["computed"]) == 16 - len(seen)
    assert_bits_equal("resumed image", np.load(out), cornell_reference)
    with pytest.raises(ValueError, match="another job"):
        rd.render_tiles(cornell, SIZE, SIZE, tile=16, out=out, quiet=True, spp=8)


def test_brainstem_frames_equal_one_process(cluster, brainstem, tmp_path):
    s = rd.render_animation(brainstem, FRAMES, out=tmp_path, width=SIZE, height=SIZE,
                            workers=2, quiet=True)
    assert sorted(s["computed"]) == list(range(FRAMES)) and s["workers"] == 2
    want = frames_one_process(brainstem, FRAMES, SIZE)
    for k in range(FRAMES):
        got = rd.read_png(tmp_path / f"frame_{k:04d}.png")
        assert_bits_equal(f"frame {k}", got, want[k])
    assert len({w.tobytes() for w in want}) > FRAMES // 2, "the frames differ: it moves"


def test_brainstem_frames_equal_the_cli(cluster, brainstem, cli, tmp_path):
    pil = pytest.importorskip("PIL.Image")
    rd.render_animation(brainstem, 4, out=tmp_path / "ray", width=SIZE, height=SIZE, quiet=True)
    cli("animate", brainstem, "--frames", 4, "--width", SIZE, "--height", SIZE,
        "--out", tmp_path / "cli")
    for k in range(4):
        want = np.asarray(pil.open(tmp_path / "cli" / f"frame_{k:04d}.png").convert("RGB"))
        assert_bits_equal(f"frame {k}", rd.read_png(tmp_path / "ray" / f"frame_{k:04d}.png"), want)


def test_worker_killed_mid_run_loses_nothing(cluster, brainstem, tmp_path):
    killed = []

    def kill_the_other(key, info):
        if not killed:
            victim = info["worker_pids"][1 - info["worker"]]
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)

    s = rd.render_animation(brainstem, FRAMES, out=tmp_path, width=SIZE, height=SIZE,
                            workers=2, quiet=True, callback=kill_the_other)
    assert killed, "the callback ran"
    assert s["restarts"] >= 1, f"the killed worker was restarted: {s['pids']}"
    assert any(killed[0] in p and len(p) > 1 for p in s["pids"]), s["pids"]
    assert sorted(s["computed"]) == list(range(FRAMES))
    want = frames_one_process(brainstem, FRAMES, SIZE)
    for k in range(FRAMES):
        assert_bits_equal(f"frame {k}", rd.read_png(tmp_path / f"frame_{k:04d}.png"), want[k])
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")], "no temporary file left"


def test_rerun_recomputes_only_what_is_missing(cluster, brainstem, tmp_path):
    rd.render_animation(brainstem, 8, out=tmp_path, width=32, height=32, quiet=True)
    files = {k: tmp_path / f"frame_{k:04d}.png" for k in range(8)}
    before = {k: (f.stat().st_mtime_ns, f.read_bytes()) for k, f in files.items()}
    files[5].unlink()
    s = rd.render_animation(brainstem, 8, out=tmp_path, width=32, height=32, quiet=True)
    assert s["computed"] == [5] and sorted(s["skipped"]) == [0, 1, 2, 3, 4, 6, 7]
    for k, f in files.items():
        if k != 5:
            assert f.stat().st_mtime_ns == before[k][0], f"frame {k} untouched"
        assert f.read_bytes() == before[k][1]
    with pytest.raises(ValueError, match="another job"):
        rd.render_animation(brainstem, 8, out=tmp_path, width=48, height=48, quiet=True)


def test_cast_rays_chunks_equal_scene_cast_rays(cluster, cornell, tmp_path):
    scene = raysift.Scene.load(cornell)
    rng = np.random.default_rng(4)
    cam = scene.camera_rays(48, 40).reshape(-1, 8)
    c = scene.bounds.mean(axis=0)
    rand = np.concatenate([c + rng.normal(0, 0.3, (2000, 3)), rng.normal(size=(2000, 3))], axis=1)
    rays = np.concatenate([cam[:, :6].astype(np.float64), rand])  # float64: converted as the CLI
    path = tmp_path / "rays.npy"
    np.save(path, rays)
    out = tmp_path / "hits.npy"
    seen = []

    def halt(key, info):
        seen.append(key)
        if len(seen) == 2:
            raise Halt

    with pytest.raises(Halt):
        rd.cast_rays(cornell, path, out=out, chunk=500, quiet=True, normals=True, callback=halt)
    assert not out.exists()
    s = rd.cast_rays(cornell, path, out=out, chunk=500, quiet=True, normals=True)
    chunks = -(-len(rays) // 500)
    assert sorted(s["skipped"]) == sorted(seen) and len(s["computed"]) == chunks - len(seen)
    got = np.load(out)
    want = scene.cast_rays(rays, tracer="dacrt")
    assert_bits_equal("t", got["t"], want["t_hit"])
    miss = want["primitive_ids"] == raysift.MISS
    prim = np.where(miss, raysift.MISS, scene.primitive_offsets[np.where(miss, 0, want["geometry_ids"])]
                    + want["primitive_ids"])
    assert_bits_equal("prim", got["prim"], prim)
    assert_bits_equal("geom", got["geom"], want["geometry_ids"])
    assert_bits_equal("u", got["u"], want["primitive_uvs"][:, 0])
    assert_bits_equal("v", got["v"], want["primitive_uvs"][:, 1])
    assert_bits_equal("ng", got["ng"], want["primitive_normals"])
    assert (~miss).sum() > 1000


def test_bad_input_fails_before_any_work(tmp_path, cornell):
    """No cluster needed: these fail before Ray is asked for anything, and write nothing."""
    out = tmp_path / "out"
    with pytest.raises(ValueError, match="tracer: 'nope'"):
        rd.render_tiles(cornell, 8, 8, tracer="nope", out=out / "x.png", quiet=True)
    with pytest.raises(FileNotFoundError, match="scene_file"):
        rd.render_animation(tmp_path / "missing.glb", 4, out=out, quiet=True)
    with pytest.raises(ValueError, match="rays_source: dtype int64"):
        rd.cast_rays(cornell, np.zeros((4, 6), np.int64), out=out / "h.npy", quiet=True)
    with pytest.raises(ValueError, match=r"rays_source: shape \(4, 5\)"):
        rd.cast_rays(cornell, np.zeros((4, 5)), out=out / "h.npy", quiet=True)
    with pytest.raises(FileNotFoundError, match="rays_source"):
        rd.cast_rays(cornell, tmp_path / "none.npy", out=out / "h.npy", quiet=True)
    with pytest.raises(ValueError, match="integrator"):
        rd.render_animation(cornell, 4, out=out, integrator="magic", quiet=True)
    assert not out.exists() or not any(out.iterdir())


def test_window_of_the_path_tracer(cornell, cornell_reference):
    """Scene.render(window=...) alone (no Ray): a tile is its window of the full image."""
    scene = raysift.Scene.load(cornell)
    tile = scene.render(SIZE, SIZE, integrator="path", window=(8, 40, 20, 9), **PATH)
    assert tile.shape == (9, 20, 3)
    assert_bits_equal("window", tile, cornell_reference[40:49, 8:28])
    with pytest.raises(ValueError, match="window"):
        scene.render(SIZE, SIZE, integrator="path", window=(60, 0, 8, 8))
    with pytest.raises(ValueError, match="window"):
        scene.render(SIZE, SIZE, integrator="raycast", window=(0, 0, 8, 8))
