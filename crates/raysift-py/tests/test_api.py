"""The API as documented: outputs, shapes, ids, conventions, threads, the GIL, Ctrl-C, stubs and
docstrings, and the README's example."""

import ast
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import raysift
from conftest import BUNNY, REPO, global_prims

PKG = Path(raysift.__file__).parent


def down_rays(xy, z=5.0):
    """Rays straight down -z from height z over the points xy."""
    xy = np.asarray(xy, np.float32)
    r = np.zeros((len(xy), 6), np.float32)
    r[:, :2] = xy
    r[:, 2] = z
    r[:, 5] = -1.0
    return r


def quad(z):
    v = np.array([[0, 0, z], [1, 0, z], [1, 1, z], [0, 1, z]], np.float64)
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def test_tracers_lists_the_registry():
    ts = raysift.tracers()
    names = [t["name"] for t in ts]
    assert names[:3] == ["naive", "bvh", "dacrt"]
    for t in ts:
        assert t["paper"] and t["summary"]
        assert t["counters"]["work"], t["name"]
        for o in t["options"]:
            assert set(o) == {"key", "default", "doc"} and o["doc"] != "(undocumented)"
    bvh = next(t for t in ts if t["name"] == "bvh")
    assert any(o["key"] == "max_leaf" and isinstance(o["default"], int) for o in bvh["options"])


def test_outputs_of_a_two_mesh_scene():
    s = raysift.Scene()
    a = s.add_triangles(*quad(0.0), name="low")
    b = s.add_triangles(*quad(1.0), transform=np.diag([1.0, 1.0, 1.0, 1.0]), name="high")
    assert (a, b) == (0, 1)
    assert s.mesh_count == 2 and s.triangle_count == 4 and len(s) == 4
    assert s.mesh_names == ["low", "high"]
    np.testing.assert_array_equal(s.primitive_offsets, [0, 2, 4])
    np.testing.assert_array_equal(s.bounds, [[0, 0, 0], [1, 1, 1]])
    r = down_rays([[0.75, 0.25], [0.25, 0.75], [3, 3]])
    h = s.cast_rays(r, tracer="bvh")
    assert {k: v.dtype for k, v in h.items()} == {
        "t_hit": np.float32, "geometry_ids": np.uint32, "primitive_ids": np.uint32,
        "primitive_uvs": np.float32, "primitive_normals": np.float32}
    np.testing.assert_array_equal(h["t_hit"], [4, 4, np.inf])
    np.testing.assert_array_equal(h["geometry_ids"], [1, 1, raysift.MISS])
    np.testing.assert_array_equal(h["primitive_ids"], [0, 1, raysift.MISS])  # within the mesh
    np.testing.assert_array_equal(global_prims(s, h), [2, 3, raysift.MISS])
    np.testing.assert_array_equal(h["primitive_normals"], [[0, 0, 1], [0, 0, 1], [0, 0, 0]])
    # hit point = (1-u-v) v0 + u v1 + v v2
    tri = s.triangles()[global_prims(s, h)[:2]]
    u, v = h["primitive_uvs"][:2, 0:1], h["primitive_uvs"][:2, 1:2]
    p = (1 - u - v) * tri[:, 0] + u * tri[:, 1] + v * tri[:, 2]
    np.testing.assert_allclose(p[:, :2], r[:2, :2], atol=1e-6)
    # moving the upper quad away uncovers the lower one
    s.set_transform(b, [[1, 0, 0, 5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    assert s.version == 1
    h = s.cast_rays(r, tracer="dacrt")
    np.testing.assert_array_equal(h["geometry_ids"], [0, 0, raysift.MISS])
    np.testing.assert_array_equal(h["t_hit"], [5, 5, np.inf])
    # a (3, 4) matrix, and deformation
    s.set_transform(b, np.eye(4)[:3])
    s.set_vertices(a, quad(2.0)[0])
    np.testing.assert_array_equal(s.cast_rays(r)["t_hit"], [3, 3, np.inf])


def test_leading_shapes_single_and_empty_batches():
    s = raysift.Scene.load("sphere:200")
    one = s.cast_rays(np.array([0, 0, 5, 0, 0, -1], np.float32))
    assert one["t_hit"].shape == () and one["primitive_uvs"].shape == (2,)
    assert 3.9 < float(one["t_hit"]) < 4.1
    r = np.broadcast_to(down_rays([[0.1, 0.1]]), (2, 3, 4, 6))
    h = s.cast_rays(r)
    assert h["t_hit"].shape == (2, 3, 4) and h["primitive_normals"].shape == (2, 3, 4, 3)
    empty = s.cast_rays(np.zeros((0, 6), np.float32))
    assert empty["t_hit"].shape == (0,) and empty["primitive_uvs"].shape == (0, 2)
    assert s.test_occlusions(np.zeros((0, 5, 8))).shape == (0, 5)


def test_occlusion_intervals():
    s = raysift.Scene()
    s.add_triangles(*quad(0.0))
    r = down_rays([[0.5, 0.5]] * 4)  # the quad is at t = 5
    np.testing.assert_array_equal(s.test_occlusions(r), [True] * 4)
    np.testing.assert_array_equal(s.test_occlusions(r, tfar=4.9), [False] * 4)
    np.testing.assert_array_equal(s.test_occlusions(r, tnear=5.1), [False] * 4)
    np.testing.assert_array_equal(s.test_occlusions(r, tnear=5.0, tfar=5.0), [True] * 4)
    r8 = np.concatenate([r, [[0, 10], [0, 4], [6, 9], [-1, 5]]], axis=1)
    np.testing.assert_array_equal(s.test_occlusions(r8), [True, False, False, True])
    np.testing.assert_array_equal(s.test_occlusions(r8, tfar=4.0), [False] * 4)
    np.testing.assert_array_equal(s.test_occlusions(r8, tnear=0.0), [True, False, False, True])
    h = s.cast_rays(r8)
    np.testing.assert_array_equal(h["t_hit"], [5, np.inf, np.inf, 5])
    with pytest.raises(ValueError, match="tnear: NaN"):
        s.test_occlusions(r, tnear=float("nan"))


def test_threads_give_one_answer():
    s = raysift.Scene.load(str(BUNNY))
    r = s.camera_rays(64, 48)
    for tracer in ("bvh", "dacrt"):
        one = s.cast_rays(r, tracer=tracer, threads=1)
        assert s.last_stats["threads"] == 1
        two = s.cast_rays(r, tracer=tracer, threads=2)
        assert s.last_stats["threads"] == 2
        for k in one:
            np.testing.assert_array_equal(one[k], two[k])


def test_tracers_are_cached_and_updated_not_rebuilt():
    s = raysift.Scene.load(str(BUNNY))
    r = s.camera_rays(32, 32)
    s.cast_rays(r, tracer="bvh", update="refit")
    assert s.last_stats["prepare"]["built"]["builds"] == 1
    s.cast_rays(r, tracer="bvh", update="refit")
    assert s.last_stats["prepare"] is None, "unchanged scene: no prepare"
    s.set_transform(0, np.eye(4))  # a rigid motion (here none): refit, not rebuild
    s.cast_rays(r, tracer="bvh", update="refit")
    built = s.last_stats["prepare"]["built"]
    assert built["refitted"] > 0 and built["builds"] == 0, built
    assert s.last_stats["options"] == {"update": "refit"}


def test_create_rays_pinhole_follows_open3d():
    eye, center = np.array([0.0, 0.0, 10.0]), np.array([0.0, 0.0, 0.0])
    r = raysift.create_rays_pinhole(90.0, center, eye, [0, 1, 0], 8, 4)
    assert r.shape == (4, 8, 6) and r.dtype == np.float32
    np.testing.assert_array_equal(r[..., :3], np.broadcast_to(eye, (4, 8, 3)).astype(np.float32))
    d = r[..., 3:]
    np.testing.assert_allclose(d[..., 2], -1.0, atol=1e-6)  # unit component along the view axis
    # horizontal fov 90: the outer pixel centres sit at x = +-(1 - 1/8) of the view depth
    np.testing.assert_allclose(d[0, [0, -1], 0], [-0.875, 0.875], atol=1e-6)
    assert d[0, 0, 1] > 0 > d[-1, 0, 1], "row 0 is the top of the image"
    s = raysift.Scene()
    s.add_triangles(np.array([[-50, -50, 0], [50, -50, 0], [0, 50, 0]], float), [[0, 1, 2]])
    np.testing.assert_allclose(s.cast_rays(r)["t_hit"], 10.0, rtol=1e-6)  # t_hit is the depth


def test_render_returns_float_rgb():
    s = raysift.Scene.load(str(BUNNY))
    for kw in ({}, {"shade": "normal"}, {"shade": "depth", "tracer": "bvh"},
               {"integrator": "path", "spp": 1, "bounces": 1}):
        img = s.render(40, 30, **kw)
        assert img.shape == (30, 40, 3) and img.dtype == np.float32
        assert 0.0 <= img.min() and img.max() <= 1.0 and img.std() > 0.01, kw
        levels = np.unique(np.round(img * 255))
        np.testing.assert_allclose(levels, np.round(levels))


def test_counts_and_lists_are_documented_as_absent():
    s = raysift.Scene.load("sphere:100")
    for f in (s.count_intersections, s.list_intersections):
        with pytest.raises(NotImplementedError, match="closest hit and any hit"):
            f(np.zeros((1, 6), np.float32))


def test_docstrings_and_stubs():
    for f in ("cast_rays", "test_occlusions", "add_triangles", "set_transform", "set_vertices",
              "load", "camera_rays", "render"):
        doc = getattr(raysift.Scene, f).__doc__
        assert doc and len(doc) > 60, f
    assert "cast_rays" in raysift.Scene.__doc__
    assert "tracer" in (raysift.Scene.cast_rays.__text_signature__ or "")
    assert raysift.tracers.__doc__ and raysift.create_rays_pinhole.__doc__
    stub = PKG / "_raysift.pyi"
    assert stub.is_file() and (PKG / "py.typed").is_file(), "stubs are installed with the package"
    tree = ast.parse(stub.read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Scene")
    stubbed = {n.name for n in cls.body if isinstance(n, ast.FunctionDef)}
    public = {n for n in dir(raysift.Scene) if not n.startswith("_")}
    assert public <= stubbed, f"missing from the stub: {public - stubbed}"
    top = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert {"tracers", "create_rays_pinhole"} <= top


def test_gil_is_released_while_tracing():
    s = raysift.Scene.load("sphere:20000")
    r = np.ascontiguousarray(np.tile(s.camera_rays(64, 64), (4, 1, 1)))
    done = []
    t = threading.Thread(target=lambda: done.append(s.cast_rays(r, tracer="naive", threads=1)))
    t.start()
    ticks = 0
    while t.is_alive():
        ticks += 1
        time.sleep(0.001)
    t.join()
    assert done and done[0]["t_hit"].shape == (256, 64)
    assert ticks > 50, f"the main thread ran only {ticks} times while tracing"


def test_ctrl_c_interrupts_between_chunks():
    s = raysift.Scene.load("sphere:20000")
    r = np.ascontiguousarray(np.tile(s.camera_rays(64, 64), (16, 1, 1)))  # 65536 rays
    s.cast_rays(r[:1], tracer="naive")
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        s.cast_rays(r, tracer="naive", threads=1, chunk_rays=256)
    elapsed = time.perf_counter() - t0
    timer.join()
    assert elapsed < 5.0, f"interrupted only after {elapsed:.1f} s"
    small = s.cast_rays(r[:2], tracer="naive")  # the scene still works
    assert small["t_hit"].shape == (2, 64)


def readme_python_example():
    text = (REPO / "README.md").read_text()
    section = text.split("## Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks, "README: no python block in the Python section"
    return blocks[0]


def test_readme_example_runs(tmp_path):
    code = readme_python_example()
    assert len(code.strip().splitlines()) <= 12
    (tmp_path / "assets").mkdir()
    shutil.copy(BUNNY, tmp_path / "assets" / BUNNY.name)
    pytest.importorskip("PIL")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    from PIL import Image

    img = np.asarray(Image.open(tmp_path / "depth.png"))
    assert img.ndim == 2 and img.max() > 200 and (img == 0).mean() > 0.2


def test_normals_per_hit_and_per_triangle_agree():
    """Large batches take the normals from a per-triangle table, small ones compute them per hit:
    the same numbers either way."""
    rays = raysift.Scene.load(str(BUNNY)).camera_rays(128, 128)  # 16,384 rays >= half the triangles
    small = raysift.Scene.load(str(BUNNY))
    few = small.cast_rays(rays[60:64], tracer="bvh")  # per hit
    big = raysift.Scene.load(str(BUNNY)).cast_rays(rays, tracer="bvh")  # per triangle
    np.testing.assert_array_equal(few["primitive_normals"], big["primitive_normals"][60:64])
    assert (np.linalg.norm(few["primitive_normals"], axis=-1)[few["t_hit"] < np.inf] > 0.999).all()
