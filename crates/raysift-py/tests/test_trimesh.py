"""trimesh's own ray-test expectations (trimesh/tests/test_ray.py), met through
raysift.trimesh.RayMeshIntersector on trimesh's primitives (box, sphere) and a mesh of
../shared/scenes; and agreement with trimesh's default backend on that mesh."""

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
import raysift.trimesh as rt  # noqa: E402


def with_raysift(mesh, **kw):
    mesh.ray = rt.RayMeshIntersector(mesh, **kw)
    return mesh


def unit_cube():
    return with_raysift(trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]]))


@pytest.mark.parametrize("tracer", ["bvh", "dacrt", "naive"])
def test_on_vertex(tracer):
    """Rays from the centre of a box through each of its vertices hit, once each."""
    m = with_raysift(trimesh.creation.box(), tracer=tracer)
    origins = np.zeros_like(m.vertices)
    vectors = m.vertices.copy()
    assert m.ray.intersects_any(ray_origins=origins, ray_directions=vectors).all()
    _loc, index_ray, _tri = m.ray.intersects_location(ray_origins=origins, ray_directions=vectors)
    assert (np.bincount(index_ray, minlength=len(origins)) == 1).all()


def test_box():
    """A grid of rays along +z over a unit cube: every hit's xy is its ray's, its z a face's."""
    mesh = unit_cube()
    origins = trimesh.util.grid_linspace(mesh.bounds[:, :2] + np.reshape([-0.02, 0.02], (-1, 1)), 100)
    origins = np.column_stack((origins, np.ones(len(origins)) * -100))
    vectors = np.ones((len(origins), 3)) * [0, 0, 1.0]
    pos, ray, _tri = mesh.ray.intersects_location(ray_origins=origins, ray_directions=vectors)
    assert len(pos) > 0
    # trimesh's per-hit checks, vectorised
    assert np.allclose(pos[:, :2], origins[ray][:, :2])
    assert np.isclose(pos[:, 2:3], mesh.bounds[:, 2][None, :]).any(axis=1).all()
    # rays inside the square enter and leave: two hits each
    inside = (origins[:, :2] > 0.001).all(axis=1) & (origins[:, :2] < 0.999).all(axis=1)
    counts = np.bincount(ray, minlength=len(origins))
    assert (counts[inside] == 2).all()


def test_multiple_hits():
    """A camera behind a cube: first hits land on the two triangles of the near face; all hits
    on more."""
    f = 1000.0
    h = w = 256
    d = trimesh.util.grid_arange([[-h / 2, -w / 2], [h / 2, w / 2]], step=2.0)
    d = np.column_stack((d, np.ones(len(d)) * f))
    o = np.tile([0, 0, -15.0], (len(d), 1))
    cube = with_raysift(trimesh.creation.box(extents=[2, 2, 2]))
    tri, _ray = cube.ray.intersects_id(ray_origins=o, ray_directions=d, multiple_hits=False)
    assert len(np.unique(tri)) == 2
    tri, _ray = cube.ray.intersects_id(ray_origins=o, ray_directions=d, multiple_hits=True)
    assert len(np.unique(tri)) > 2


def test_contains():
    scale = 1.5
    mesh = with_raysift(trimesh.creation.box())  # centred on the origin
    assert mesh.ray.contains_points(mesh.vertices * (1.0 / scale)).all()
    assert not mesh.ray.contains_points(mesh.vertices * scale).any()
    way_out = (np.random.default_rng(3).random((30, 3)) * 100) + 1.0 + mesh.bounds[1]
    assert not mesh.ray.contains_points(way_out).any()
    assert mesh.ray.contains_points([mesh.center_mass]).all()
    assert mesh.contains([[0.1, 0.2, -0.3], [2, 2, 2]]).tolist() == [True, False], "mesh.contains uses mesh.ray"


def test_empty():
    """Queries with no hits still return numpy arrays."""
    sphere = with_raysift(trimesh.creation.icosphere())
    o = np.random.default_rng(4).random((100, 3))
    o[:, 2] = -5
    d = np.tile([0, 1, 0], (100, 1))
    assert all(isinstance(a, np.ndarray) and a.shape[0] == 0 for a in sphere.ray.intersects_id(o, d))
    assert all(isinstance(a, np.ndarray) and a.shape[0] == 0 for a in sphere.ray.intersects_location(o, d))
    assert (sphere.ray.intersects_first(o, d) == -1).all()
    assert not sphere.ray.intersects_any(o, d).any()


def test_large_box_one_exit():
    """trimesh's test_embree_duplicate_hits: from the top face of a huge box straight down, the
    only hit is the bottom face (rays start just after their origin, as Embree's)."""
    mesh = trimesh.creation.box()
    mesh.apply_scale(10000.0)
    with_raysift(mesh)
    tri, _ = mesh.ray.intersects_id([[0.0, 0.0, 5000.0]], [[0.0, 0.0, -1.0]], multiple_hits=True)
    assert len(tri) == 1


def test_sphere_enter_and_exit():
    sphere = with_raysift(trimesh.creation.icosphere(subdivisions=4, radius=2.0))
    rng = np.random.default_rng(5)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = -6.0 * d + rng.normal(scale=0.3, size=(500, 3))
    loc, index_ray, _ = sphere.ray.intersects_location(o, d)
    assert (np.bincount(index_ray, minlength=500) == 2).all()
    r = np.linalg.norm(loc, axis=1)
    assert (r <= 2.0 + 1e-9).all() and (r > 1.98).all(), "on the tessellated sphere"
    first = sphere.ray.intersects_first(o, d)
    assert (first >= 0).all()
    np.testing.assert_array_equal(first, sphere.ray.intersects_id(o, d, multiple_hits=False)[0][np.argsort(
        sphere.ray.intersects_id(o, d, multiple_hits=False)[1])])


def test_follows_the_mesh_as_it_moves():
    mesh = unit_cube()
    o, d = [[0.5, 0.5, -10.0]], [[0, 0, 1.0]]
    assert mesh.ray.intersects_location(o, d, multiple_hits=False)[0][0, 2] == pytest.approx(0.0)
    scene = mesh.ray.scene
    mesh.vertices = mesh.vertices + [0, 0, 3.0]
    assert mesh.ray.intersects_location(o, d, multiple_hits=False)[0][0, 2] == pytest.approx(3.0)
    assert mesh.ray.scene is scene and scene.version == 1, "same faces: updated in place"
    mesh.faces = mesh.faces[:6]
    assert mesh.ray.scene is not scene and mesh.ray.scene.triangle_count == 6


def test_shared_mesh_against_trimesh_default(scenes_dir):
    """On a watertight scanned mesh: first hits, any-hits and contains agree with trimesh's
    default ray backend (Embree through embreex when installed, else its own ray_triangle)."""
    path = scenes_dir / "armadillo.off"
    mesh = trimesh.load(path, process=False)
    ref = trimesh.load(path, process=False).ray
    ours = rt.RayMeshIntersector(mesh)
    rng = np.random.default_rng(6)
    lo, hi = mesh.bounds
    o = lo + rng.random((20_000, 3)) * (hi - lo)
    d = rng.normal(size=(20_000, 3))
    any_ours, any_ref = ours.intersects_any(o, d), ref.intersects_any(o, d)
    assert (any_ours != any_ref).sum() <= 3, "any-hit: at most a few grazing rays differ"
    first_ours, first_ref = ours.intersects_first(o, d), ref.intersects_first(o, d)
    assert (first_ours != first_ref).mean() < 1e-3, (first_ours != first_ref).sum()
    pts = lo + rng.random((3000, 3)) * (hi - lo)
    c_ours, c_ref = ours.contains_points(pts), ref.contains_points(pts)
    assert c_ours.any() and (c_ours != c_ref).sum() <= 3
    loc, index_ray, index_tri = ours.intersects_location(o[:500], d[:500])
    counts = np.bincount(index_ray, minlength=500)
    inside = ours.contains_points(o[:500])
    assert ((counts % 2 == 1) == inside).mean() > 0.99, "hit parity tells inside from outside"
    # locations lie on the faces they name
    tri = mesh.triangles[index_tri]
    n = mesh.face_normals[index_tri]
    assert np.abs(np.einsum("ij,ij->i", loc - tri[:, 0], n)).max() < 1e-9 * mesh.scale * 1e3


def test_bad_input():
    mesh = unit_cube()
    with pytest.raises(ValueError, match="differ in shape"):
        mesh.ray.intersects_first(np.zeros((3, 3)), np.ones((2, 3)))
    with pytest.raises(ValueError, match=r"ray_directions\[1\]: zero"):
        mesh.ray.intersects_any(np.zeros((2, 3)), [[0, 0, 1], [0, 0, 0]])
    with pytest.raises(ValueError, match=r"ray_origins\[0\]: non-finite"):
        mesh.ray.intersects_id([[np.nan, 0, 0]], [[0, 0, 1]])

