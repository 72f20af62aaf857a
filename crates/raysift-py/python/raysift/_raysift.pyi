"""Type stubs of raysift's native module (crates/raysift-py/src). Docstrings are in the module
itself: ``help(raysift.Scene)``."""

from os import PathLike
from typing import Any, Literal, Optional, Sequence, TypedDict, Union

import numpy as np
import numpy.typing as npt

__version__: str
MISS: int
"""Primitive and geometry id of a miss: 4294967295."""
DEFAULT_CHUNK_RAYS: int
"""Rays per uninterruptible chunk of a query (2**20)."""

ArrayLike = npt.ArrayLike
Vec3 = Union[Sequence[float], npt.NDArray[np.floating[Any]]]

class CastResult(TypedDict):
    t_hit: npt.NDArray[np.float32]
    geometry_ids: npt.NDArray[np.uint32]
    primitive_ids: npt.NDArray[np.uint32]
    primitive_uvs: npt.NDArray[np.float32]
    primitive_normals: npt.NDArray[np.float32]

class OptionInfo(TypedDict):
    key: str
    default: Any
    doc: str

class PresetInfo(TypedDict):
    name: str
    options: dict[str, str]

class CounterInfo(TypedDict):
    built: list[tuple[str, str]]
    work: list[tuple[str, str]]

class TracerInfo(TypedDict):
    name: str
    paper: str
    summary: str
    options: list[OptionInfo]
    presets: list[PresetInfo]
    counters: CounterInfo

class Scene:
    """A triangle scene: meshes with rigid transforms, traced by any tracer of
    ``raysift.tracers()``."""

    def __init__(self) -> None: ...
    @staticmethod
    def load(path: Union[str, PathLike[str]]) -> Scene: ...
    @staticmethod
    def bunny() -> Scene: ...
    def add_triangles(
        self,
        vertices: Any,
        triangles: Optional[ArrayLike] = None,
        transform: Optional[ArrayLike] = None,
        name: Optional[str] = None,
    ) -> int: ...
    def set_transform(self, mesh_id: int, transform: ArrayLike) -> None: ...
    def set_vertices(self, mesh_id: int, vertices: ArrayLike) -> None: ...
    def cast_rays(
        self,
        rays: ArrayLike,
        tracer: str = "dacrt",
        threads: int = 0,
        chunk_rays: Optional[int] = None,
        **options: Union[bool, int, float, str],
    ) -> CastResult: ...
    def test_occlusions(
        self,
        rays: ArrayLike,
        tnear: Optional[float] = None,
        tfar: Optional[float] = None,
        tracer: str = "dacrt",
        threads: int = 0,
        chunk_rays: Optional[int] = None,
        **options: Union[bool, int, float, str],
    ) -> npt.NDArray[np.bool_]: ...
    def count_intersections(self, *args: Any, **kwargs: Any) -> None:
        """Not provided: raises NotImplementedError (no tracer enumerates every hit exactly)."""
    def list_intersections(self, *args: Any, **kwargs: Any) -> None:
        """Not provided: raises NotImplementedError (no tracer enumerates every hit exactly)."""
    def camera_rays(
        self,
        width: int = 512,
        height: int = 512,
        *,
        eye: Optional[Vec3] = None,
        look: Optional[Vec3] = None,
        up: Optional[Vec3] = None,
        fov: float = 45.0,
    ) -> npt.NDArray[np.float32]: ...
    def render(
        self,
        width: int = 512,
        height: int = 512,
        *,
        eye: Optional[Vec3] = None,
        look: Optional[Vec3] = None,
        up: Optional[Vec3] = None,
        fov: float = 45.0,
        integrator: Literal["raycast", "path"] = "raycast",
        shade: Literal["diffuse", "normal", "depth"] = "diffuse",
        light: Optional[Vec3] = None,
        spp: int = 4,
        bounces: int = 7,
        seed: int = 1,
        tracer: str = "dacrt",
        threads: int = 0,
        window: Optional[tuple[int, int, int, int]] = None,
        **options: Union[bool, int, float, str],
    ) -> npt.NDArray[np.float32]: ...
    def triangles(self) -> npt.NDArray[np.float32]: ...
    @property
    def primitive_offsets(self) -> npt.NDArray[np.uint32]: ...
    @property
    def bounds(self) -> npt.NDArray[np.float32]: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def mesh_count(self) -> int: ...
    @property
    def mesh_names(self) -> list[str]: ...
    @property
    def name(self) -> str: ...
    @property
    def version(self) -> int: ...
    @property
    def last_stats(self) -> Optional[dict[str, Any]]: ...
    def __len__(self) -> int: ...

class CameraInfo(TypedDict):
    eye: list[float]
    look: list[float]
    up: list[float]
    fov: float

class Animation:
    """A scene file's motion (glTF animation, explode, spin-parts), posed into ``.scene`` at
    any time."""

    @staticmethod
    def load(
        path: Union[str, PathLike[str]],
        motion: Optional[Literal["gltf", "explode", "spin-parts"]] = None,
        animation: Optional[str] = None,
    ) -> Animation: ...
    @property
    def scene(self) -> Scene: ...
    @property
    def motion(self) -> str: ...
    @property
    def clip(self) -> Optional[str]: ...
    @property
    def duration(self) -> Optional[float]: ...
    def frame_time(self, k: int, frames: int) -> float: ...
    def set_time(self, t: float) -> None: ...
    def camera(self, frames: int, width: int = 512, height: int = 512, fov: float = 45.0) -> CameraInfo: ...

def tracers() -> list[TracerInfo]: ...
def create_rays_pinhole(
    fov_deg: float,
    center: Vec3,
    eye: Vec3,
    up: Vec3,
    width_px: int,
    height_px: int,
) -> npt.NDArray[np.float32]: ...
