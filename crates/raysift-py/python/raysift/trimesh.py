"""trimesh's ray interface on raysift: ``mesh.ray = RayMeshIntersector(mesh)``.

The methods and return values are those of ``trimesh.ray.ray_pyembree.RayMeshIntersector``
(``intersects_first``, ``intersects_any``, ``intersects_id``, ``intersects_location``,
``contains_points``), so code written for trimesh keeps working, ``mesh.contains(points)``
included.

Semantics, where trimesh leaves them to the backend:

- Directions are normalised (as trimesh does); rays have no end and start just after their origin
  (t > 0, as Embree's tnear = 0 excludes hits at the origin itself).
- First hits are raysift's exact closest hits: the smallest t, ties going to the smaller face
  index, both faces of every triangle.
- ``multiple_hits=True`` lists the surfaces met along each ray as trimesh's Embree backend does:
  after a hit at distance t the ray is traced again from the same origin from ``t + offset`` on
  (at least one float32 step past t), with ``offset = max(1e-8, 1e-6 * mesh.scale)``, up to
  ``max_hits`` times; so two faces sharing the hit point (an edge or a vertex) count once.
- Locations are computed in float64 on the hit face's plane, as trimesh does.

The raysift scene is made from the mesh on first use and kept; when the mesh's vertices change
(same faces) it is updated in place (``Scene.set_vertices``: the tracer refits or re-reads rather
than rebuilds), and rebuilt when its faces change.
"""

import numpy as np
import trimesh as _trimesh

from ._raysift import MISS, Scene

__all__ = ["RayMeshIntersector"]

_OFFSET_FACTOR = 1e-6
_OFFSET_FLOOR = 1e-8
# t > 0: the smallest positive float32 as tmin
_TNEAR = float(np.nextafter(np.float32(0), np.float32(1)))


class RayMeshIntersector:
    """Ray queries on a ``trimesh.Trimesh`` through raysift.

    ``tracer``: any name of ``raysift.tracers()``; the default, ``"bvh"``, is built once and then
    answers each call from its tree, which suits trimesh's many small queries (``"dacrt"`` keeps
    no tree and re-sorts the triangles on every call: fastest for one large batch per frame).
    ``threads``: worker threads (0: one per core). Other keywords are tracer options.
    """

    def __init__(self, mesh, tracer="bvh", threads=0, **options):
        self.mesh = mesh
        self.tracer = tracer
        self.threads = threads
        self.options = options
        self._scene = None
        self._key = None

    # -- the raysift scene, following the mesh ------------------------------------------------

    @property
    def scene(self):
        """The ``raysift.Scene`` of the mesh as it is now."""
        key = hash(self.mesh)
        if self._scene is None or key != self._key:
            faces = np.asarray(self.mesh.faces)
            faces_key = (faces.shape, hash(self.mesh.faces))
            vertices = np.asarray(self.mesh.vertices, dtype=np.float64)
            if (
                self._scene is not None
                and self._faces_key == faces_key
                and self._nverts == len(vertices)
            ):
                self._scene.set_vertices(0, vertices)
            else:
                scene = Scene()
                scene.add_triangles(vertices, faces)
                self._scene = scene
                self._faces_key = faces_key
                self._nverts = len(vertices)
            self._key = key
        return self._scene

    def _rays(self, ray_origins, ray_directions):
        origins = np.asarray(ray_origins, dtype=np.float64)
        directions = np.asarray(ray_directions, dtype=np.float64)
        if origins.ndim == 1 and len(origins) == 3:
            origins, directions = origins[None], directions.reshape(-1, 3)
        if origins.shape != directions.shape:
            raise ValueError(
                f"ray_origins {origins.shape} and ray_directions {directions.shape} differ in shape"
            )
        if origins.ndim != 2 or origins.shape[1] != 3:
            raise ValueError(f"ray_origins: shape {origins.shape}; expected (n, 3)")
        bad = np.nonzero(~np.isfinite(origins).all(axis=1))[0]
        if len(bad):
            raise ValueError(f"ray_origins[{bad[0]}]: non-finite coordinate {origins[bad[0]].tolist()}")
        length = np.linalg.norm(directions, axis=1)
        zero = np.nonzero(~(length > 0))[0]
        if len(zero):
            raise ValueError(
                f"ray_directions[{zero[0]}]: zero or non-finite direction {directions[zero[0]].tolist()}"
            )
        return origins, directions / length[:, None]

    def _cast(self, origins, directions, tmin):
        rays = np.empty((len(origins), 8), dtype=np.float32)
        rays[:, 0:3] = origins
        rays[:, 3:6] = directions
        rays[:, 6] = tmin
        rays[:, 7] = np.inf
        return self.scene.cast_rays(
            rays, tracer=self.tracer, threads=self.threads, **self.options
        )

    def _locations(self, origins, directions, index_tri, t):
        """Hit points in float64 on each hit face's plane (the ray's t where it is parallel)."""
        o = origins
        d = directions
        if len(index_tri) == 0:
            return np.zeros((0, 3), dtype=np.float64)
        q = self.mesh.triangles[index_tri, 0, :]
        n = self.mesh.face_normals[index_tri]
        dn = np.einsum("ij,ij->i", d, n)
        ok = np.abs(dn) > 1e-12
        tp = np.where(ok, np.einsum("ij,ij->i", q - o, n) / np.where(ok, dn, 1.0), t)
        return o + d * tp[:, None]

    # -- trimesh's interface ------------------------------------------------------------------

    def intersects_id(
        self,
        ray_origins,
        ray_directions,
        multiple_hits=True,
        max_hits=100,
        return_locations=False,
        **kwargs,
    ):
        """Faces hit by each ray: ``(index_tri, index_ray)``, plus ``locations`` (m, 3) when
        ``return_locations``; with ``multiple_hits`` every surface along the ray (see the module
        doc), else the first hit only."""
        origins, directions = self._rays(ray_origins, ray_directions)
        n = len(origins)
        offset = max(_OFFSET_FLOOR, float(self.mesh.scale) * _OFFSET_FACTOR)
        live = np.arange(n)
        tmin = np.full(n, _TNEAR, dtype=np.float64)
        tris, rays, ts = [], [], []
        for _ in range(max_hits if multiple_hits else 1):
            if len(live) == 0:
                break
            hits = self._cast(origins[live], directions[live], tmin)
            prim = hits["primitive_ids"]
            hit = prim != MISS
            t = hits["t_hit"][hit].astype(np.float64)
            tris.append(prim[hit].astype(np.int64))
            rays.append(live[hit])
            ts.append(t)
            live = live[hit]
            # past this hit by the offset, and by at least one float32 step
            tmin = np.maximum(
                (t + offset).astype(np.float32),
                np.nextafter(t.astype(np.float32), np.float32(np.inf)),
            ).astype(np.float64)
        index_tri = np.concatenate(tris) if tris else np.zeros(0, dtype=np.int64)
        index_ray = np.concatenate(rays) if rays else np.zeros(0, dtype=np.int64)
        if not return_locations:
            return index_tri, index_ray
        t = np.concatenate(ts) if ts else np.zeros(0)
        locations = self._locations(origins[index_ray], directions[index_ray], index_tri, t)
        return index_tri, index_ray, locations

    def intersects_location(self, ray_origins, ray_directions, multiple_hits=True, **kwargs):
        """Where rays hit the mesh: ``(locations, index_ray, index_tri)``."""
        index_tri, index_ray, locations = self.intersects_id(
            ray_origins,
            ray_directions,
            multiple_hits=multiple_hits,
            return_locations=True,
            **kwargs,
        )
        return locations, index_ray, index_tri

    def intersects_first(self, ray_origins, ray_directions, **kwargs):
        """The first face each ray hits, int64 (n,), -1 on a miss."""
        origins, directions = self._rays(ray_origins, ray_directions)
        prim = self._cast(origins, directions, _TNEAR)["primitive_ids"]
        out = prim.astype(np.int64)
        out[prim == MISS] = -1
        return out

    def intersects_any(self, ray_origins, ray_directions, **kwargs):
        """Whether each ray hits any face, bool (n,)."""
        origins, directions = self._rays(ray_origins, ray_directions)
        rays = np.empty((len(origins), 6), dtype=np.float32)
        rays[:, 0:3] = origins
        rays[:, 3:6] = directions
        return self.scene.test_occlusions(
            rays, tnear=_TNEAR, tracer=self.tracer, threads=self.threads, **self.options
        )

    def contains_points(self, points):
        """Whether each point is inside the (watertight) mesh, by trimesh's own ray-parity
        test."""
        return _trimesh.ray.ray_util.contains_points(self, points)
