"""Frames, image tiles and ray batches on a Ray cluster (``pip install "raysift[cluster]"``).

Three calls, each on the cluster ``ray.init(address=address)`` connects to (a local one, on this
machine's cores, when no address is given and Ray is not already initialised)::

    from raysift import distributed as rd
    rd.render_animation("BrainStem.glb", frames=1000, out="frames/")     # frames/frame_NNNN.png
    img = rd.render_tiles("CornellBox-Original.obj", 1920, 1080, spp=256, tile=64, out="cb.png")
    rd.cast_rays("city.glb", "rays.npy", out="hits.npy", chunk=2**22)    # hits.npy as `raysift trace`

How the work runs:

- **Scene once per worker.** ``workers`` Ray actors (one process each, ``threads`` cores each)
  load the scene in their constructor and keep it; tasks (frames, tiles, ray chunks) are method
  calls on them, at most ``2`` queued per actor, the next one given to whichever actor finishes
  first. The scene file's bytes (with an ``.obj``'s ``.mtl`` and a ``.gltf``'s buffers) are put
  in Ray's object store once and every actor writes them to its own temporary folder and loads
  them from there (``scene_transport="object_store"``, the default): it needs no storage shared
  between machines, and costs one copy of the file per node. ``scene_transport="path"`` makes
  every actor read ``scene_file`` itself (a path every node can read: NFS, a bucket mount) and
  ships nothing; use it for scenes of many gigabytes.
- **Output by the driver, atomically.** Results come back to this process, which writes them:
  a frame's PNG (encoded by the worker) to a temporary name then renamed (so a frame file that
  exists is complete), ray
  hits into a memory-mapped ``.npy`` at their offsets (``out + ".partial"``, with the finished
  chunks listed in ``out + ".done"``; renamed to ``out`` when every chunk is in), tiles into a
  memory-mapped image likewise. A killed or failed run leaves no half-written output file.
- **Faults.** A worker process that dies (killed, out of memory, its machine lost) is restarted
  by Ray (``max_restarts=retries``), loads the scene again, and the tasks it held are run again
  (``max_task_retries=retries``); each task's result depends only on its inputs, so the output
  is the same as an undisturbed run. An exception raised by raysift (bad input) is not retried:
  it is raised here.
- **Resume.** Run again with the same output: frames whose file exists, and chunks or tiles
  listed as done, are skipped (a record of the job's parameters beside the output refuses a
  rerun with different ones).
- **Determinism.** A frame is a function of its time alone; a path-traced pixel's random
  numbers come from (seed, sample, depth, its index in the full image); every tracer returns
  the same hits bit for bit. So the output does not depend on the number of workers, on the
  order tasks run in, nor on retries.

Each call returns a summary dict: ``computed`` and ``skipped`` (task keys: frame numbers, tile
origins ``(x0, y0)``, chunk offsets), ``workers``, ``pids`` (per worker, the process ids that
served it: more than one after a restart), ``restarts``, ``load_s`` (each worker's scene
load), ``seconds`` (the whole call), ``start_s`` (until every worker had loaded the scene) and
``work_s`` (the rest: tasks and writing); ``render_tiles`` adds
``image``. ``callback(key, info)``, if given, is called here after each task's output is
written (``info``: ``pid`` of the worker process that computed it, ``worker`` its index,
``worker_pids`` the first pid of every worker).
"""

from __future__ import annotations

import json
import os
import struct
import sys
import tempfile
import time
import zlib
from collections import deque
from pathlib import Path
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

import raysift

__all__ = ["render_animation", "render_tiles", "cast_rays", "connect", "read_png", "write_png"]

PathLike = Union[str, "os.PathLike[str]"]

#: Tasks queued per actor (one running, one waiting: no idle gap between tasks).
QUEUE_PER_WORKER = 2


# ----------------------------------------------------------------------------------------------
# PNG, npy and small-file helpers (no dependency beyond numpy)


def _png_chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))


def png_bytes(rgb: np.ndarray) -> bytes:
    """An 8-bit RGB PNG of ``rgb`` (H, W, 3) uint8."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, _ = rgb.shape
    raw = np.zeros((h, 1 + 3 * w), np.uint8)  # filter byte 0 (None) per row
    raw[:, 1:] = rgb.reshape(h, 3 * w)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr)
            + _png_chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)) + _png_chunk(b"IEND", b""))


def _write_atomic(path: Path, data: bytes) -> None:
    """Writes ``data`` to a temporary file beside ``path``, then renames it to ``path``."""
    fd, tmp = tempfile.mkstemp(prefix="." + path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_png(path: PathLike, rgb: np.ndarray) -> None:
    """Writes ``rgb`` ((H, W, 3) uint8, or float in [0, 1] as ``Scene.render`` returns) as a
    PNG, atomically."""
    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8:
        rgb = np.rint(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)
    _write_atomic(Path(path), png_bytes(rgb))


def read_png(path: PathLike) -> np.ndarray:
    """(H, W, 3) uint8 of an 8-bit RGB PNG as ``write_png`` writes it (filter 0 rows, no
    interlace); other PNGs: use Pillow."""
    data = Path(path).read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos, idat = 8, []
    w = h = 0
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        tag, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        if tag == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if (depth, colour, interlace) != (8, 2, 0):
                raise ValueError(f"{path}: not an 8-bit RGB non-interlaced PNG; use Pillow")
        elif tag == b"IDAT":
            idat.append(body)
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8).reshape(h, 1 + 3 * w)
    if raw[:, 0].any():
        raise ValueError(f"{path}: rows use PNG filters other than None; read it with Pillow")
    return raw[:, 1:].reshape(h, w, 3).copy()


class _Job:
    """The record of a job's parameters beside its output (``<out>/.raysift-job.json`` or
    ``<out>.job.json``): a rerun with the same output must be the same job."""

    def __init__(self, path: Path, params: dict):
        self.path, self.params = path, json.loads(json.dumps(params))

    def check_or_write(self) -> None:
        if self.path.exists():
            old = json.loads(self.path.read_text())
            if old != self.params:
                diff = sorted(k for k in set(old) | set(self.params) if old.get(k) != self.params.get(k))
                raise ValueError(
                    f"out: {self.path} records another job (differs in {', '.join(diff)}); "
                    "use another output or delete the old one")
        else:
            _write_atomic(self.path, json.dumps(self.params, indent=1, sort_keys=True).encode())


class _Ledger:
    """Task keys done, one line each, appended and fsynced after the task's data is flushed."""

    def __init__(self, path: Path):
        self.path = path
        self.done = set()
        if path.exists():
            for line in path.read_text().splitlines():
                if line.strip():
                    self.done.add(tuple(json.loads(line)) if line.startswith("[") else json.loads(line))

    def add(self, key) -> None:
        with open(self.path, "a") as f:
            f.write(json.dumps(list(key) if isinstance(key, tuple) else key) + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.done.add(key)


# ----------------------------------------------------------------------------------------------
# Progress


class _Progress:
    def __init__(self, total: int, unit: str, quiet: bool, initial: int = 0):
        self.total, self.n, self.unit, self.quiet = total, initial, unit, quiet
        self.bar = None
        self.t0 = time.monotonic()
        if quiet:
            return
        try:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=initial, unit=unit, file=sys.stderr,
                            desc="raysift", leave=False)
        except ImportError:
            self._line()

    def _line(self):
        rate = (self.n / max(time.monotonic() - self.t0, 1e-9))
        sys.stderr.write(f"\rraysift: {self.n}/{self.total} {self.unit} ({rate:.1f}/s)")
        sys.stderr.flush()

    def update(self, k: int = 1):
        self.n += k
        if self.quiet:
            return
        if self.bar is not None:
            self.bar.update(k)
        else:
            self._line()

    def close(self):
        if self.quiet:
            return
        if self.bar is not None:
            self.bar.close()
        else:
            sys.stderr.write("\n")


# ----------------------------------------------------------------------------------------------
# Scenes shipped to workers


def _scene_files(spec: str) -> Optional[list]:
    """The files of a scene: the file, an .obj's mtllib files, a .gltf's external buffers and
    images (relative paths); None for a generator spec (``cornell``, ``sphere:N``, ...)."""
    p = Path(spec)
    if not p.exists():
        return None
    if not p.is_file():
        raise ValueError(f"scene_file: {spec} is not a file")
    files = [p.name]
    name = p.name.lower()
    if name.endswith(".obj"):
        for line in p.read_text(errors="replace").splitlines():
            parts = line.strip().split(None, 1)
            if len(parts) == 2 and parts[0] == "mtllib":
                for m in parts[1].split():
                    if (p.parent / m).is_file():
                        files.append(m)
    elif name.endswith(".gltf"):
        doc = json.loads(p.read_text())
        for item in doc.get("buffers", []) + doc.get("images", []):
            uri = item.get("uri")
            if uri and not uri.startswith("data:") and (p.parent / uri).is_file():
                files.append(uri)
    return files


def _pack_scene(spec: str, transport: str) -> dict:
    """What a worker needs to load the scene: the spec itself (``path`` transport, generator
    specs) or the files' bytes (``object_store``)."""
    files = _scene_files(spec)
    if files is None or transport == "path":
        return {"spec": os.path.abspath(spec) if files is not None else spec}
    base = Path(spec).parent
    return {"name": files[0], "files": {f: (base / f).read_bytes() for f in files}}


def _unpack_scene(pack: dict) -> tuple:
    """(spec to load, temporary folder or None) on the worker."""
    if "spec" in pack:
        return pack["spec"], None
    d = tempfile.mkdtemp(prefix="raysift-scene-")
    for rel, data in pack["files"].items():
        q = Path(d) / rel
        q.parent.mkdir(parents=True, exist_ok=True)
        q.write_bytes(data)
    return str(Path(d) / pack["name"]), d


class _Worker:
    """A Ray actor: loads the scene once, then serves tasks (frames, tiles, ray chunks)."""

    def __init__(self, pack: dict, kind: str, threads: int, params: dict):
        import shutil
        t0 = time.perf_counter()
        spec, tmp = _unpack_scene(pack)
        try:
            if kind == "animation":
                self.anim = raysift.Animation.load(spec, motion=params.get("motion"),
                                                   animation=params.get("animation"))
                self.scene = self.anim.scene
            else:
                self.scene = raysift.Scene.load(spec)
        finally:
            if tmp:
                shutil.rmtree(tmp, ignore_errors=True)
        self.threads, self.params = threads, params
        self.load_s = time.perf_counter() - t0
        self.pid = os.getpid()

    def info(self) -> dict:
        return {"pid": self.pid, "load_s": self.load_s, "triangles": self.scene.triangle_count}

    def ping(self, x=None):
        return x

    def frame(self, k: int):
        p = self.params
        self.anim.set_time(self.anim.frame_time(k, p["frames"]))
        img = self.scene.render(p["width"], p["height"], threads=self.threads, **p["render"])
        # Encoded here, so the driver only writes bytes (its share per frame stays small).
        return png_bytes(np.rint(img * 255.0).astype(np.uint8)), self.pid

    def tile(self, win: tuple):
        p = self.params
        img = self.scene.render(p["width"], p["height"], threads=self.threads,
                                window=tuple(win), **p["render"])
        return np.rint(img * 255.0).astype(np.uint8), self.pid

    def cast(self, start: int, rays: np.ndarray):
        p = self.params
        try:
            h = self.scene.cast_rays(rays, tracer=p["tracer"], threads=self.threads, **p["options"])
        except ValueError as e:
            raise ValueError(f"rays {start}..{start + len(rays)} (chunk at offset {start}): {e}") from None
        out = np.empty(len(rays), _hit_dtype(p["normals"]))
        geom, local = h["geometry_ids"], h["primitive_ids"]
        miss = local == raysift.MISS
        offsets = self.scene.primitive_offsets
        out["t"] = h["t_hit"]
        out["prim"] = np.where(miss, raysift.MISS, offsets[np.where(miss, 0, geom)] + local)
        out["geom"] = geom
        out["u"] = h["primitive_uvs"][:, 0]
        out["v"] = h["primitive_uvs"][:, 1]
        if p["normals"]:
            out["ng"] = h["primitive_normals"]
        return out, self.pid


def _hit_dtype(normals: bool) -> np.dtype:
    """The records of ``raysift trace``'s hits.npy (README, "Formats")."""
    fields = [("t", "<f4"), ("prim", "<u4"), ("geom", "<u4"), ("u", "<f4"), ("v", "<f4")]
    if normals:
        fields.append(("ng", "<f4", (3,)))
    return np.dtype(fields)


# ----------------------------------------------------------------------------------------------
# The cluster and the scheduling loop


def connect(address: Optional[str] = None, **init_kwargs):
    """Ray, initialised: ``ray.init(address=address)`` unless already initialised (``None``: a
    local cluster on this machine, unless ``RAY_ADDRESS`` is set; ``"auto"``: the cluster this
    machine joined with ``ray start``; ``"ray://HEAD:10001"``: Ray Client)."""
    try:
        import ray
    except ImportError:
        raise ImportError('raysift.distributed needs Ray: pip install "ray>=2.9"') from None
    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False, **init_kwargs)
    return ray


def _check_common(tracer: str, workers: Optional[int], threads: int, retries: int,
                  transport: str) -> None:
    names = [t["name"] for t in raysift.tracers()]
    if tracer not in names:
        raise ValueError(f"tracer: {tracer!r} is not a raysift tracer; expected one of {', '.join(names)}")
    if workers is not None and workers < 1:
        raise ValueError(f"workers: {workers}; expected at least 1")
    if threads < 1:
        raise ValueError(f"threads: {threads}; expected at least 1 core per worker")
    if retries < 0:
        raise ValueError(f"retries: {retries}; expected 0 or more")
    if transport not in ("object_store", "path"):
        raise ValueError(f'scene_transport: {transport!r}; expected "object_store" or "path"')


def _check_scene_file(scene_file) -> str:
    spec = os.fspath(scene_file)
    if _scene_files(spec) is None and not _looks_generated(spec):
        raise FileNotFoundError(f"scene_file: {spec}: no such file")
    return spec


def _looks_generated(spec: str) -> bool:
    return spec in ("cornell",) or spec.split(":")[0] in ("sphere", "soup", "tile", "cornell")


def _run(ray, *, spec: str, kind: str, params: dict, keys: Sequence, method: str,
         args_of: Callable, write: Callable, workers: Optional[int], threads: int, retries: int,
         transport: str, unit: str, quiet: bool, skipped: list,
         callback: Optional[Callable]) -> dict:
    """Runs ``method(*args_of(key))`` for every key on the actors; ``write(key, result)`` here,
    as results arrive; returns the summary."""
    t0 = time.perf_counter()
    if workers is None:
        workers = max(1, int(ray.cluster_resources().get("CPU", 1)) // threads)
    workers = max(1, min(workers, len(keys))) if keys else 0
    summary = {"computed": [], "skipped": list(skipped), "workers": workers, "pids": [],
               "restarts": 0, "load_s": [], "seconds": 0.0}
    if not keys:
        summary["seconds"] = time.perf_counter() - t0
        return summary
    pack = ray.put(_pack_scene(spec, transport))
    cls = ray.remote(_Worker)
    actors = [cls.options(num_cpus=threads, max_restarts=retries, max_task_retries=retries)
              .remote(pack, kind, threads, params) for _ in range(workers)]
    infos = ray.get([a.info.remote() for a in actors])
    summary["start_s"] = time.perf_counter() - t0
    first = [i["pid"] for i in infos]
    pids = [[p] for p in first]
    summary["load_s"] = [i["load_s"] for i in infos]
    pending = deque(keys)
    inflight = {}

    def submit(w):
        key = pending.popleft()
        ref = getattr(actors[w], method).remote(*args_of(key))
        inflight[ref] = (key, w)

    bar = _Progress(len(keys) + len(skipped), unit, quiet, initial=len(skipped))
    try:
        for w in range(workers):
            for _ in range(QUEUE_PER_WORKER):
                if pending:
                    submit(w)
        while inflight:
            ready, _ = ray.wait(list(inflight), num_returns=1)
            key, w = inflight.pop(ready[0])
            try:
                result, pid = ray.get(ready[0])
            except ray.exceptions.RayTaskError as e:
                cause = e.as_instanceof_cause()
                if isinstance(cause, ValueError):
                    raise ValueError(str(cause).splitlines()[-1]) from None
                raise
            if pid not in pids[w]:
                pids[w].append(pid)
            write(key, result)
            summary["computed"].append(key)
            bar.update()
            if callback is not None:
                callback(key, {"pid": pid, "worker": w, "worker_pids": first})
            if pending:
                submit(w)
    finally:
        bar.close()
        for a in actors:
            ray.kill(a)
    summary["pids"] = pids
    summary["restarts"] = sum(len(p) - 1 for p in pids)
    summary["seconds"] = time.perf_counter() - t0
    summary["work_s"] = summary["seconds"] - summary["start_s"]
    return summary


# ----------------------------------------------------------------------------------------------
# The three calls


def _render_kwargs(integrator, shade, spp, bounces, seed, tracer, options, camera):
    if integrator not in ("raycast", "path"):
        raise ValueError(f'integrator: {integrator!r}; expected "raycast" or "path"')
    if shade not in ("diffuse", "normal", "depth"):
        raise ValueError(f'shade: {shade!r}; expected "diffuse", "normal" or "depth"')
    if spp < 1:
        raise ValueError(f"spp: {spp}; expected at least 1")
    return {"integrator": integrator, "shade": shade, "spp": int(spp), "bounces": int(bounces),
            "seed": int(seed), "tracer": tracer, **camera, **options}


def render_animation(scene_file: PathLike, frames: int = 8, *, out: PathLike,
                     width: int = 512, height: int = 512, tracer: str = "bvh",
                     integrator: str = "raycast", shade: str = "diffuse", spp: int = 4,
                     bounces: int = 7, seed: int = 1, motion: Optional[str] = None,
                     animation: Optional[str] = None, fov: float = 45.0,
                     address: Optional[str] = None, workers: Optional[int] = None,
                     threads: int = 1, retries: int = 3, scene_transport: str = "object_store",
                     quiet: bool = False, callback: Optional[Callable] = None,
                     **options) -> dict:
    """Renders ``frames`` frames of ``scene_file``'s motion into ``out/frame_NNNN.png``, the
    frames ``raysift animate SCENE --frames N --width W --height H --out OUT`` writes (same
    motion, times, camera and image, bit for bit), one task per frame on the cluster.

    ``integrator="path"`` path-traces each frame instead (``spp``, ``bounces``, ``seed``).
    ``workers`` actors (default: the cluster's CPUs / ``threads``) of ``threads`` cores each.
    Frames already in ``out`` are skipped (resume). Tracer options as keywords.
    """
    spec = _check_scene_file(scene_file)
    if frames < 1:
        raise ValueError(f"frames: {frames}; expected at least 1")
    if width < 1 or height < 1:
        raise ValueError(f"width, height: {width}x{height}; expected at least 1x1")
    _check_common(tracer, workers, threads, retries, scene_transport)
    anim = raysift.Animation.load(spec, motion=motion, animation=animation)  # errors now, here
    camera = anim.camera(frames, width, height, fov)
    render = _render_kwargs(integrator, shade, spp, bounces, seed, tracer, options, camera)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    params = {"scene": os.path.basename(spec), "frames": frames, "width": width,
              "height": height, "motion": motion, "animation": animation, "render": render}
    _Job(out / ".raysift-job.json", params).check_or_write()
    name = lambda k: out / f"frame_{k:04d}.png"  # noqa: E731
    skipped = [k for k in range(frames) if name(k).exists()]
    todo = [k for k in range(frames) if not name(k).exists()]
    ray = connect(address)
    return _run(ray, spec=spec, kind="animation", params=params, keys=todo, method="frame",
                args_of=lambda k: (k,), write=lambda k, png: _write_atomic(name(k), png),
                workers=workers, threads=threads, retries=retries, transport=scene_transport,
                unit="frames", quiet=quiet, skipped=skipped, callback=callback)


def tiles_of(width: int, height: int, tile) -> list:
    """The windows ``(x0, y0, w, h)`` of a ``width`` × ``height`` image cut in ``tile`` (an int,
    or (tw, th)) pixel tiles, row by row (the last row and column may be smaller)."""
    tw, th = (tile, tile) if np.isscalar(tile) else tile
    if tw < 1 or th < 1:
        raise ValueError(f"tile: {tile}; expected a positive tile size")
    return [(x, y, min(tw, width - x), min(th, height - y))
            for y in range(0, height, th) for x in range(0, width, tw)]


def render_tiles(scene_file: PathLike, width: int, height: int, spp: int = 4, *,
                 tile=64, out: Optional[PathLike] = None, bounces: int = 7, seed: int = 1,
                 eye=None, look=None, up=None, fov: float = 45.0, tracer: str = "dacrt",
                 order: Union[str, Sequence, None] = None,
                 address: Optional[str] = None, workers: Optional[int] = None, threads: int = 1,
                 retries: int = 3, scene_transport: str = "object_store", quiet: bool = False,
                 callback: Optional[Callable] = None, **options) -> dict:
    """Path-traces ``scene_file`` at ``width`` × ``height``, ``spp`` samples per pixel, one task
    per ``tile`` × ``tile`` pixel window; the summary's ``image`` is the float32 (H, W, 3) that
    ``Scene.load(scene_file).render(width, height, integrator="path", spp=spp, ...)`` returns,
    bit for bit, whatever the workers and the order (``order="shuffle"`` or a list of tile
    indices runs them in another order; for tests).

    ``out`` (``.png`` or ``.npy``, optional): written atomically at the end; while running, the
    tiles are kept in ``out + ".partial"`` (a memory-mapped .npy) with the finished ones listed
    in ``out + ".done"``, so a rerun resumes. Camera as ``Scene.render``.
    """
    spec = _check_scene_file(scene_file)
    if width < 1 or height < 1:
        raise ValueError(f"width, height: {width}x{height}; expected at least 1x1")
    _check_common(tracer, workers, threads, retries, scene_transport)
    wins = tiles_of(width, height, tile)
    if order is not None:
        if isinstance(order, str):
            if order != "shuffle":
                raise ValueError(f'order: {order!r}; expected "shuffle" or a permutation')
            order = np.random.default_rng(12345).permutation(len(wins)).tolist()
        if sorted(order) != list(range(len(wins))):
            raise ValueError(f"order: not a permutation of the {len(wins)} tiles")
        wins = [wins[i] for i in order]
    camera = {k: (list(map(float, v)) if k != "fov" else float(v))
              for k, v in (("eye", eye), ("look", look), ("up", up), ("fov", fov)) if v is not None}
    raysift.Scene.load(spec)  # errors now, here: a malformed file raises before any work
    render = _render_kwargs("path", "diffuse", spp, bounces, seed, tracer, options, camera)
    params = {"scene": os.path.basename(spec), "width": width, "height": height,
              "tile": list(tile) if not np.isscalar(tile) else tile, "render": render}
    final = Path(out) if out is not None else None
    if final is not None and final.suffix.lower() not in (".png", ".npy"):
        raise ValueError(f"out: {final}: expected a .png or .npy file name")
    if final is not None and final.exists():
        _Job(Path(str(final) + ".job.json"), params).check_or_write()
        img = (read_png(final).astype(np.float32) / np.float32(255.0) if final.suffix.lower() == ".png"
               else np.load(final))
        return {"computed": [], "skipped": [w[:2] for w in wins], "workers": 0, "pids": [],
                "restarts": 0, "load_s": [], "seconds": 0.0, "image": img}
    if final is not None:
        _Job(Path(str(final) + ".job.json"), params).check_or_write()
        partial, ledger = Path(str(final) + ".partial"), _Ledger(Path(str(final) + ".done"))
        if partial.exists() and ledger.done:
            img = np.lib.format.open_memmap(partial, mode="r+")
        else:
            img = np.lib.format.open_memmap(partial, mode="w+", dtype=np.uint8, shape=(height, width, 3))
            ledger = _Ledger(ledger.path)
    else:
        img, ledger = np.zeros((height, width, 3), np.uint8), None
    done = ledger.done if ledger is not None else set()
    skipped = [w[:2] for w in wins if tuple(w[:2]) in done]
    todo = [w for w in wins if tuple(w[:2]) not in done]
    by_origin = {w[:2]: w for w in wins}

    def write(xy, rgb):
        x0, y0, w, h = by_origin[xy]
        img[y0:y0 + h, x0:x0 + w] = rgb
        if ledger is not None:
            img.flush()
            ledger.add(tuple(xy))

    ray = connect(address)
    s = _run(ray, spec=spec, kind="scene", params=params, keys=[w[:2] for w in todo],
             method="tile", args_of=lambda xy: (by_origin[xy],), write=write, workers=workers,
             threads=threads, retries=retries, transport=scene_transport, unit="tiles",
             quiet=quiet, skipped=skipped, callback=callback)
    rgb = np.array(img)
    if final is not None:
        if final.suffix.lower() == ".png":
            _write_atomic(final, png_bytes(rgb))
        else:
            fd, tmp = tempfile.mkstemp(dir=final.parent, suffix=".npy")
            os.close(fd)
            np.save(tmp, rgb.astype(np.float32) / np.float32(255.0))
            os.replace(tmp, final)
        del img
        partial.unlink()
        ledger.path.unlink()
    s["image"] = rgb.astype(np.float32) / np.float32(255.0)
    return s


def _rays_of(rays_source) -> np.ndarray:
    """The rays as an (N, 6) or (N, 8) float32/float64 array (a .npy memory-mapped)."""
    if isinstance(rays_source, (str, os.PathLike)):
        p = Path(rays_source)
        if not p.is_file():
            raise FileNotFoundError(f"rays_source: {p}: no such file")
        try:
            a = np.load(p, mmap_mode="r")
        except Exception as e:
            raise ValueError(f"rays_source: {p}: not a .npy array ({e})") from None
    else:
        a = np.asarray(rays_source)
    if a.dtype not in (np.float32, np.float64):
        raise ValueError(f"rays_source: dtype {a.dtype}; expected float32 or float64 (README, Formats)")
    if a.ndim < 2 or a.shape[-1] not in (6, 8):
        raise ValueError(f"rays_source: shape {a.shape}; expected (N, 6) or (N, 8) (or (H, W, 8))")
    return a.reshape(-1, a.shape[-1])


def cast_rays(scene_file: PathLike, rays_source, *, out: PathLike, chunk: int = 1 << 20,
              tracer: str = "dacrt", normals: bool = False, address: Optional[str] = None,
              workers: Optional[int] = None, threads: int = 1, retries: int = 3,
              scene_transport: str = "object_store", quiet: bool = False,
              callback: Optional[Callable] = None, **options) -> dict:
    """Closest hits of ``rays_source`` (a ``.npy`` path, memory-mapped, or an array: (N, 6) or
    (N, 8) float32/float64, the CLI's rays format) in ``chunk``-ray tasks, into ``out``, the
    ``hits.npy`` ``raysift trace`` writes (records ``t``, ``prim`` (scene-wide), ``geom``,
    ``u``, ``v``, and ``ng`` with ``normals=True``), equal to ``Scene.cast_rays`` bit for bit.

    The driver reads each chunk and ships it with its task; each result is written into a
    memory-mapped ``out + ".partial"`` at the chunk's offset and the chunk recorded in ``out +
    ".done"``; ``out`` appears (a rename) when every chunk is in. A rerun resumes.
    """
    spec = _check_scene_file(scene_file)
    _check_common(tracer, workers, threads, retries, scene_transport)
    if chunk < 1:
        raise ValueError(f"chunk: {chunk}; expected at least 1 ray")
    rays = _rays_of(rays_source)
    n = len(rays)
    raysift.Scene.load(spec)  # errors now, here
    final = Path(out)
    src = os.path.abspath(rays_source) if isinstance(rays_source, (str, os.PathLike)) else "array"
    params = {"scene": os.path.basename(spec), "rays": src, "n": n, "chunk": chunk,
              "tracer": tracer, "normals": normals, "options": options}
    starts = list(range(0, n, chunk))
    if final.exists():
        _Job(Path(str(final) + ".job.json"), params).check_or_write()
        return {"computed": [], "skipped": starts, "workers": 0, "pids": [], "restarts": 0,
                "load_s": [], "seconds": 0.0}
    _Job(Path(str(final) + ".job.json"), params).check_or_write()
    partial, ledger = Path(str(final) + ".partial"), _Ledger(Path(str(final) + ".done"))
    dtype = _hit_dtype(normals)
    if partial.exists() and ledger.done:
        hits = np.lib.format.open_memmap(partial, mode="r+")
    else:
        hits = np.lib.format.open_memmap(partial, mode="w+", dtype=dtype, shape=(n,))
        ledger = _Ledger(ledger.path)
    skipped = [s for s in starts if s in ledger.done]
    todo = [s for s in starts if s not in ledger.done]

    def write(start, recs):
        hits[start:start + len(recs)] = recs
        hits.flush()
        ledger.add(start)

    ray = connect(address)
    s = _run(ray, spec=spec, kind="scene",
             params={"tracer": tracer, "normals": normals, "options": options}, keys=todo,
             method="cast", args_of=lambda st: (st, np.ascontiguousarray(rays[st:st + chunk])),
             write=write, workers=workers, threads=threads, retries=retries,
             transport=scene_transport, unit="chunks", quiet=quiet, skipped=skipped,
             callback=callback)
    del hits
    os.replace(partial, final)
    ledger.path.unlink()
    return s
