"""raysift.distributed on a local Ray cluster: frames per second with 1 and 2 workers, and the
per-task overhead (issue #19, BENCHMARKS.md "Ray cluster").

    python3 crates/raysift-py/bench/cluster.py [SCENE.glb] [--frames 32] [--size 160]
        [--cpus 2] [--rounds 2] [--json out.json]

Measures, on ``ray.init(num_cpus=CPUS)`` (started here):

- ``one process``: the frames made in this process, one core (``threads=1``), no Ray:
  ``Animation.set_time`` + ``Scene.render`` per frame (the work of one task);
- ``render_animation`` with ``workers=1`` and ``workers=2`` (``threads=1`` each), wall time from
  the call to its return (actor start, scene shipping and load, every frame, PNG writing), and
  its frames per second; each round into a fresh folder (nothing skipped);
- per-task overhead: the round trip of an empty actor method (``ping``: scheduling, one
  message each way) and of a method returning a SIZE×SIZE×3 uint8 image; an actor's start
  (process + ``import raysift``, ``ray.get`` of its first call) and the scene load inside it
  (bytes from the object store written to a temporary folder and loaded: ``load_s``).
"""

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import raysift
from raysift import distributed as rd

HERE = Path(__file__).resolve()


def default_scene():
    for a in HERE.parents:
        p = a / "shared" / "scenes" / "animated" / "BrainStem.glb"
        if p.is_file():
            return str(p)
    sys.exit("BrainStem.glb not found: give a scene")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", nargs="?")
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--size", type=int, default=160)
    ap.add_argument("--cpus", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--json")
    a = ap.parse_args()
    spec = a.scene or default_scene()
    import ray

    out = {"scene": spec, "frames": a.frames, "size": a.size, "cpus": a.cpus}

    # One process, one thread: the work alone.
    anim = raysift.Animation.load(spec)
    cam = anim.camera(a.frames, a.size, a.size)
    t0 = time.perf_counter()
    for k in range(a.frames):
        anim.set_time(anim.frame_time(k, a.frames))
        anim.scene.render(a.size, a.size, tracer="bvh", threads=1, **cam)
    one = time.perf_counter() - t0
    out["one_process_s"] = one
    print(f"one process, 1 thread: {a.frames} frames in {one:.2f} s = {a.frames / one:.2f} frames/s")

    ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
    runs = {1: [], 2: []}
    for r in range(a.rounds):
        for w in (1, 2):
            with tempfile.TemporaryDirectory() as d:
                t0 = time.perf_counter()
                s = rd.render_animation(spec, a.frames, out=d, width=a.size, height=a.size,
                                        workers=w, quiet=True)
                dt = time.perf_counter() - t0
            runs[w].append({"seconds": dt, "start_s": s["start_s"], "work_s": s["work_s"],
                            "load_s": s["load_s"]})
            print(f"round {r}: workers={w}: {dt:.2f} s = {a.frames / dt:.2f} frames/s; start "
                  f"(actors up, scene loaded) {s['start_s']:.2f} s, then frames {s['work_s']:.2f} s "
                  f"= {a.frames / s['work_s']:.2f} frames/s (scene load in the workers: "
                  f"{', '.join(f'{x * 1e3:.0f} ms' for x in s['load_s'])})")
    out["runs"] = runs
    for w in (1, 2):
        for key in ("seconds", "start_s", "work_s"):
            out[f"workers{w}_{key}"] = statistics.median(x[key] for x in runs[w])
        out[f"workers{w}_fps"] = a.frames / out[f"workers{w}_seconds"]
        out[f"workers{w}_work_fps"] = a.frames / out[f"workers{w}_work_s"]
    out["speedup"] = out["workers1_seconds"] / out["workers2_seconds"]
    out["work_speedup"] = out["workers1_work_s"] / out["workers2_work_s"]
    print(f"median: 1 worker {out['workers1_fps']:.2f} frames/s ({out['workers1_work_fps']:.2f} "
          f"after start), 2 workers {out['workers2_fps']:.2f} ({out['workers2_work_fps']:.2f}): "
          f"{out['speedup']:.2f}x whole call, {out['work_speedup']:.2f}x after start")

    # Per-task overhead.
    pack = ray.put(rd._pack_scene(spec, "object_store"))
    cls = ray.remote(rd._Worker)
    t0 = time.perf_counter()
    actor = cls.options(num_cpus=1).remote(pack, "animation", 1, {"frames": a.frames})
    info = ray.get(actor.info.remote())
    out["actor_start_s"] = time.perf_counter() - t0
    out["scene_load_s"] = info["load_s"]
    ray.get(actor.ping.remote())
    img = np.zeros((a.size, a.size, 3), np.uint8)
    for name, arg in (("ping_ms", None), ("image_round_trip_ms", img)):
        ts = []
        for _ in range(200):
            t0 = time.perf_counter()
            ray.get(actor.ping.remote(arg))
            ts.append((time.perf_counter() - t0) * 1e3)
        out[name] = statistics.median(ts)
    # Pipelined: 200 pings in flight at once (what QUEUE_PER_WORKER hides).
    t0 = time.perf_counter()
    ray.get([actor.ping.remote() for _ in range(200)])
    out["ping_pipelined_ms"] = (time.perf_counter() - t0) * 1e3 / 200
    print(f"actor start (process, import, scene load) {out['actor_start_s']:.2f} s, of which scene "
          f"load {out['scene_load_s'] * 1e3:.0f} ms; empty task round trip {out['ping_ms']:.2f} ms "
          f"({out['ping_pipelined_ms']:.2f} ms pipelined); {a.size}x{a.size} image round trip "
          f"{out['image_round_trip_ms']:.2f} ms")
    # The driver's serial part per frame: the atomic write of the PNG bytes a worker encoded
    # (and, for scale, the encoding itself, which the worker does).
    with tempfile.TemporaryDirectory() as d:
        anim.set_time(anim.frame_time(a.frames // 2, a.frames))
        rgb = np.rint(anim.scene.render(a.size, a.size, tracer="bvh", threads=1, **cam) * 255).astype(np.uint8)
        enc, wr = [], []
        for i in range(50):
            t0 = time.perf_counter()
            png = rd.png_bytes(rgb)
            t1 = time.perf_counter()
            rd._write_atomic(Path(d) / f"f{i}.png", png)
            t2 = time.perf_counter()
            enc.append((t1 - t0) * 1e3)
            wr.append((t2 - t1) * 1e3)
        out["png_encode_ms"] = statistics.median(enc)
        out["driver_write_ms"] = statistics.median(wr)
        out["png_bytes"] = len(png)
    print(f"PNG of a {a.size}x{a.size} frame: {out['png_bytes']} bytes, encoded (in the worker) in "
          f"{out['png_encode_ms']:.2f} ms; the driver's atomic write (fsync) {out['driver_write_ms']:.2f} ms")
    ray.shutdown()
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
