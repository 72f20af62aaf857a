"""Bad input raises ValueError naming the argument and the first bad index; accepted input
(float64, Fortran order, views, lists) gives the float32 answer, converted once."""

import tracemalloc

import numpy as np
import pytest

import raysift


@pytest.fixture(scope="module")
def scene():
    return raysift.Scene.load("sphere:500")


def rays(n=10):
    r = np.zeros((n, 6), np.float32)
    r[:, 2] = 5.0
    r[:, 5] = -1.0
    r[:, 0] = np.linspace(-0.5, 0.5, n)
    return r


@pytest.mark.parametrize("shape", [(10,), (10, 5), (10, 7), (2, 3, 9), ()])
def test_wrong_ray_shapes(scene, shape):
    with pytest.raises(ValueError, match=r"rays: shape .*expected \(\.\.\., 6\)"):
        scene.cast_rays(np.zeros(shape, np.float32))


@pytest.mark.parametrize("query", ["cast_rays", "test_occlusions"])
def test_nan_and_zero_directions_name_the_first_bad_ray(scene, query):
    f = getattr(scene, query)
    r = rays()
    r[7, 1] = np.nan
    r[8, 4] = np.inf
    with pytest.raises(ValueError, match=r"rays\[7\]: non-finite origin or direction"):
        f(r)
    r = rays()
    r[3, 3:6] = 0.0
    r[9, 3:6] = 0.0
    with pytest.raises(ValueError, match=r"rays\[3\]: zero direction"):
        f(r)
    img = rays(12).reshape(3, 4, 6).copy()
    img[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"rays\[2, 1\]: non-finite"):
        f(img)
    r8 = np.concatenate([rays(), np.zeros((10, 2), np.float32)], axis=1)
    r8[:, 7] = np.inf
    r8[5, 6] = np.nan
    with pytest.raises(ValueError, match=r"rays\[5\]: tmin or tmax is NaN"):
        f(r8)


def test_non_numeric_rays(scene):
    with pytest.raises(ValueError, match="rays: expected numbers"):
        scene.cast_rays(np.array([["a"] * 6]))
    with pytest.raises(ValueError, match="rays: "):
        scene.cast_rays([[1, 2, 3], [1, 2]])


def test_triangle_indices_out_of_range():
    s = raysift.Scene()
    v = np.zeros((4, 3))
    with pytest.raises(ValueError, match=r"triangles\[1, 2\]: vertex index 4 out of range \(the vertices have 4 rows\)"):
        s.add_triangles(v, [[0, 1, 2], [0, 2, 4], [9, 9, 9]])
    with pytest.raises(ValueError, match=r"triangles\[0, 1\]: vertex index -1 out of range"):
        s.add_triangles(v, np.array([[0, -1, 2]], np.int32))
    with pytest.raises(ValueError, match=r"triangles: expected integer indices"):
        s.add_triangles(v, np.array([[0.0, 1.0, 2.0]]))
    with pytest.raises(ValueError, match=r"triangles: shape \(2, 4\); expected \(T, 3\)"):
        s.add_triangles(v, np.zeros((2, 4), np.int64))
    with pytest.raises(ValueError, match=r"vertices: shape \(4, 2\); expected \(V, 3\)"):
        s.add_triangles(np.zeros((4, 2)), [[0, 1, 2]])
    bad = np.zeros((4, 3))
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"vertices\[2\]: non-finite coordinate"):
        s.add_triangles(bad, [[0, 1, 2]])
    with pytest.raises(ValueError, match="triangles: missing"):
        s.add_triangles(v)
    assert s.mesh_count == 0, "a rejected mesh is not added"


def test_transforms_and_changes_are_checked():
    s = raysift.Scene()
    m = s.add_triangles(np.eye(3), [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"transform: last row is \[1\.0, 0\.0, 0\.0, 1\.0\]"):
        s.set_transform(m, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]])
    with pytest.raises(ValueError, match=r"transform\[1, 3\]: non-finite entry"):
        s.set_transform(m, [[1, 0, 0, 0], [0, 1, 0, np.nan], [0, 0, 1, 0], [0, 0, 0, 1]])
    with pytest.raises(ValueError, match=r"transform: shape \(3, 3\)"):
        s.set_transform(m, np.eye(3))
    with pytest.raises(ValueError, match="mesh 5 out of range"):
        s.set_transform(5, np.eye(4))
    with pytest.raises(ValueError, match="2 positions given, the mesh has 3 vertices"):
        s.set_vertices(m, np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"vertices\[1\]: non-finite"):
        s.set_vertices(m, [[0, 0, 0], [np.inf, 0, 0], [0, 0, 1]])
    assert s.version == 0, "rejected changes change nothing"


def test_unknown_tracers_and_options(scene):
    with pytest.raises(ValueError, match=r'unknown tracer "nope"; available: naive, bvh, dacrt'):
        scene.cast_rays(rays(), tracer="nope")
    with pytest.raises(ValueError, match="bad option.*max_leaf"):
        scene.cast_rays(rays(), tracer="bvh", max_leaf_=3)
    with pytest.raises(ValueError, match="tracer naive takes no options"):
        scene.cast_rays(rays(), tracer="naive", x=1)
    with pytest.raises(ValueError, match="expected a bool, a number or a string"):
        scene.cast_rays(rays(), tracer="bvh", max_leaf=[1])
    with pytest.raises(ValueError, match="unknown tracer"):
        scene.cast_rays(np.zeros((0, 6), np.float32), tracer="nope")


def test_files():
    with pytest.raises(FileNotFoundError, match="missing.ply"):
        raysift.Scene.load("missing.ply")
    with pytest.raises(ValueError, match="expected a positive whole number"):
        raysift.Scene.load("sphere:x")


def test_camera_arguments(scene):
    with pytest.raises(ValueError, match="eye and look must be finite and distinct"):
        scene.camera_rays(8, 8, eye=(0, 0, 0), look=(0, 0, 0))
    with pytest.raises(ValueError, match=r"eye: shape \(2,\); expected 3 numbers"):
        scene.camera_rays(8, 8, eye=(0, 0))
    with pytest.raises(ValueError, match="width and height must be at least 1"):
        scene.render(0, 8)
    with pytest.raises(ValueError, match="unknown shading"):
        scene.render(8, 8, shade="flat")
    with pytest.raises(ValueError, match="integrator"):
        scene.render(8, 8, integrator="bdpt")
    with pytest.raises(ValueError, match="fov_deg"):
        raysift.create_rays_pinhole(0, [0, 0, 0], [0, 0, 1], [0, 1, 0], 4, 4)
    with pytest.raises(ValueError, match="up must not be parallel"):
        raysift.create_rays_pinhole(60, [0, 0, 0], [0, 0, 1], [0, 0, 1], 4, 4)


def test_conversions_give_the_float32_answer(scene):
    r = scene.camera_rays(24, 16)
    want = scene.cast_rays(r, tracer="bvh")
    f64 = r.astype(np.float64)
    fortran = np.asfortranarray(r)
    strided = np.stack([r, r], axis=-1)[..., 0]  # a non-contiguous view equal to r
    assert not strided.flags.c_contiguous and np.array_equal(strided, r)
    as_list = r.reshape(-1, 8).tolist()
    for name, x in [("float64", f64), ("fortran", fortran), ("strided", strided), ("list", as_list)]:
        got = scene.cast_rays(x, tracer="bvh")
        for k in want:
            np.testing.assert_array_equal(got[k].reshape(-1), want[k].reshape(-1), err_msg=f"{name} {k}")
    ints = np.array([[0, 0, 5, 0, 0, -1]])
    assert scene.cast_rays(ints)["t_hit"][0] == scene.cast_rays(ints.astype(np.float32))["t_hit"][0]


def test_float32_contiguous_rays_are_not_copied(scene):
    """tracemalloc sees numpy's allocations: converting float64 rays allocates a float32 copy,
    float32 C-contiguous rays allocate nothing of their size (the outputs are Rust memory)."""
    r = np.ascontiguousarray(np.tile(rays(1), (200_000, 1)))
    r[:, 0] = np.linspace(-0.5, 0.5, len(r))
    f64 = r.astype(np.float64)
    scene.cast_rays(r[:10], tracer="bvh")  # prepare outside the measurement
    peaks = {}
    for name, x in [("float32", r), ("float64", f64)]:
        tracemalloc.start()
        scene.cast_rays(x, tracer="bvh")
        peaks[name] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert peaks["float32"] < r.nbytes / 20, peaks
    assert peaks["float64"] >= r.nbytes, peaks
