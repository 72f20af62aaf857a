"""raysift: batch ray/triangle intersection for scenes that change every frame.

numpy in, numpy out, every tracer of the raysift engine (``raysift.tracers()``), each returning
exactly the brute-force answer, bit for bit. Names follow Open3D's ``RaycastingScene``::

    import raysift
    scene = raysift.Scene.load("bunny.ply")          # or Scene() + add_triangles(v, f)
    rays = scene.camera_rays(640, 480)               # (480, 640, 8) float32
    hits = scene.cast_rays(rays, tracer="dacrt")     # dict of arrays of shape (480, 640, ...)
    depth = hits["t_hit"]

``raysift.trimesh.RayMeshIntersector`` gives trimesh's ray interface (``mesh.ray = ...``);
``raysift.Animation`` poses a file's motion at any time; ``raysift.distributed`` runs frames,
image tiles and ray batches on a Ray cluster (``pip install "raysift[cluster]"``).
"""

from ._raysift import (
    DEFAULT_CHUNK_RAYS,
    Animation,
    MISS,
    Scene,
    __version__,
    create_rays_pinhole,
    tracers,
)

__all__ = [
    "DEFAULT_CHUNK_RAYS",
    "Animation",
    "MISS",
    "Scene",
    "__version__",
    "create_rays_pinhole",
    "tracers",
]
