"""Every tracer's cast_rays and test_occlusions equal the CLI's `raysift trace` on the same rays,
bit for bit (t, prim, u, v compared by field name, so added fields of hits.npy do not matter)."""

import numpy as np
import pytest

import raysift
from conftest import BUNNY, assert_bits_equal, find_shared_scenes, global_prims

TRACERS = [t["name"] for t in raysift.tracers()]
# naive costs rays x triangles: it gets small batches
NAIVE_BUDGET = 4e7

SCENES = [("bunny", str(BUNNY)), ("cornell", "cornell")]
_shared = find_shared_scenes()
if _shared is not None:
    SCENES += [
        ("bun_zipper_res4", str(_shared / "bun_zipper_res4.ply")),
        ("sponza", str(_shared / "sponza.obj.gz")),
        ("dragon_res3", str(_shared / "dragon_vrip_res3.ply")),
    ]
else:
    print("SKIPPED: real-scene cases of test_cli_agreement: ../shared/scenes not found (CI has it)")


class Workloads:
    """Rays files made by the CLI for one scene: camera (image-shaped), random, shadow, bounce."""

    def __init__(self, cli, spec, folder, size, count):
        self.spec, self.dir = spec, folder
        cam = folder / "camera.npy"
        cli("rays", "camera", spec, "--width", size, "--height", size, "--out", cam)
        rnd = folder / "random.npy"
        cli("rays", "random", spec, "--count", count, "--seed", 7, "--out", rnd)
        hits = folder / "camera_hits.npy"
        cli("trace", spec, "--rays", cam, "--tracer", "bvh", "--out", hits)
        lo, hi = np.array(raysift.Scene.load(spec).bounds, np.float64)
        light = ",".join(f"{x:.6g}" for x in (hi + 0.3 * (hi - lo)))
        sh = folder / "shadow.npy"
        cli("rays", "shadow", spec, "--rays", cam, "--hits", hits, "--light", light, "--out", sh)
        bo = folder / "bounce.npy"
        cli("rays", "bounce", spec, "--rays", cam, "--hits", hits, "--out", bo)
        self.files = {"camera": cam, "random": rnd, "shadow": sh, "bounce": bo}


@pytest.fixture(scope="module")
def workloads(cli, tmp_path_factory):
    made = {}

    def get(name, spec, small):
        key = (name, small)
        if key not in made:
            folder = tmp_path_factory.mktemp(f"{name}{'_small' if small else ''}")
            made[key] = Workloads(cli, spec, folder, 24 if small else 96, 600 if small else 6000)
        return made[key]

    return get


def compare_closest(cli, scene, spec, rays_file, tracer, opts, out, python_rays=None):
    cli("trace", spec, "--rays", rays_file, "--tracer", tracer, "--out", out,
        *[a for k, v in opts.items() for a in ("--opt", f"{k}={v}")])
    want = np.load(out)
    rays = np.load(rays_file) if python_rays is None else python_rays
    got = scene.cast_rays(rays, tracer=tracer, **opts)
    assert got["t_hit"].shape == rays.shape[:-1]
    assert_bits_equal("t", got["t_hit"], want["t"])
    assert_bits_equal("prim", global_prims(scene, got), want["prim"])
    assert_bits_equal("u", got["primitive_uvs"][..., 0], want["u"])
    assert_bits_equal("v", got["primitive_uvs"][..., 1], want["v"])
    return got


def compare_occluded(cli, scene, spec, rays_file, tracer, opts, out):
    cli("trace", spec, "--rays", rays_file, "--tracer", tracer, "--occlusion", "--out", out,
        *[a for k, v in opts.items() for a in ("--opt", f"{k}={v}")])
    want = np.load(out).astype(bool)
    got = scene.test_occlusions(np.load(rays_file), tracer=tracer, **opts)
    assert got.dtype == np.bool_
    np.testing.assert_array_equal(got.reshape(-1), want.reshape(-1))


@pytest.mark.parametrize("tracer", TRACERS)
@pytest.mark.parametrize("name,spec", SCENES, ids=[s[0] for s in SCENES])
def test_cast_rays_equals_cli_trace(cli, workloads, tmp_path, name, spec, tracer):
    scene = raysift.Scene.load(spec)
    small = tracer == "naive" and 96 * 96 * len(scene) > NAIVE_BUDGET
    w = workloads(name, spec, small)
    for kind, f in w.files.items():
        got = compare_closest(cli, scene, spec, f, tracer, {}, tmp_path / f"{kind}.npy")
        assert scene.last_stats["tracer"] == tracer
        if kind == "camera":
            # the same rays flat: one answer whatever the array's shape
            flat = np.load(f).reshape(-1, 8)
            again = scene.cast_rays(flat, tracer=tracer)
            assert_bits_equal("t (flat)", again["t_hit"], got["t_hit"])
    for kind in ("shadow", "camera"):
        compare_occluded(cli, scene, spec, w.files[kind], tracer, {}, tmp_path / f"{kind}_occ.npy")


@pytest.mark.parametrize("tracer", [t for t in raysift.tracers() if t["presets"]], ids=lambda t: t["name"])
def test_presets_equal_cli_trace_with_opts(cli, workloads, tmp_path, tracer):
    """Options given as keywords reach the tracer as `--opt key=value` does."""
    spec = str(BUNNY)
    scene = raysift.Scene.load(spec)
    w = workloads("bunny", spec, False)
    for p in tracer["presets"]:
        for kind in ("camera", "random"):
            compare_closest(cli, scene, spec, w.files[kind], tracer["name"], p["options"],
                            tmp_path / f"{p['name']}_{kind}.npy")
        compare_occluded(cli, scene, spec, w.files["shadow"], tracer["name"], p["options"],
                         tmp_path / f"{p['name']}_occ.npy")


def test_camera_rays_equal_cli_rays_camera(cli, tmp_path):
    spec = str(BUNNY)
    scene = raysift.Scene.load(spec)
    f = tmp_path / "cam.npy"
    cli("rays", "camera", spec, "--width", 40, "--height", 30, "--out", f)
    assert_bits_equal("default framing", scene.camera_rays(40, 30), np.load(f))
    cli("rays", "camera", spec, "--width", 16, "--height", 20, "--eye", "0.3,0.2,0.4",
        "--look", "0,0.1,0", "--up", "0,0,1", "--fov", 30, "--out", f)
    got = scene.camera_rays(16, 20, eye=(0.3, 0.2, 0.4), look=[0, 0.1, 0], up=(0, 0, 1), fov=30)
    assert got.shape == (20, 16, 8)
    assert_bits_equal("explicit camera", got, np.load(f))


def test_chunked_batches_equal_one_call(cli, workloads, tmp_path):
    """Batches cut into chunks (image rays by whole rows) give the one-call answer."""
    spec = str(BUNNY)
    scene = raysift.Scene.load(spec)
    w = workloads("bunny", spec, False)
    for tracer in ("bvh", "dacrt"):
        for kind in ("camera", "random", "shadow"):
            rays = np.load(w.files[kind])
            whole = scene.cast_rays(rays, tracer=tracer)
            for chunk in (1000, 4096, 96 * 9):
                part = scene.cast_rays(rays, tracer=tracer, chunk_rays=chunk)
                n = rays.size // rays.shape[-1]
                assert (scene.last_stats["chunks"] > 1) == (n > chunk), (n, chunk)
                for k in whole:
                    assert_bits_equal(f"{tracer} {kind} {k} chunk {chunk}", part[k], whole[k])
                occ = scene.test_occlusions(rays, tracer=tracer, chunk_rays=chunk)
                np.testing.assert_array_equal(occ, scene.test_occlusions(rays, tracer=tracer))
