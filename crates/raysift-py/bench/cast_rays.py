"""Python cast_rays against the CLI's trace, embreex and trimesh on one rays file.

    python3 crates/raysift-py/bench/cast_rays.py SCENE RAYS.npy --threads 1 [--rounds 5]
        [--tracers bvh,dacrt] [--contenders py,cli,embreex,trimesh,trimesh-triangle]
        [--subset-triangle 16384] [--json out.json]

Each round runs every contender once, in turn (so a noisy neighbour hits all of them alike), and
the tables give medians over rounds:

- ``py``: ``scene.cast_rays(rays, tracer=T, threads=N)`` on the float32 (H, W, 8) array as
  ``np.load`` returns it, timed around the call (``total``), with the library's intersect time
  inside it (``last_stats["trace_ms"]``, what the CLI times); the tracer was prepared by a warm-up
  call, as a renderer's tracer is between frames of a static scene.
- ``cli``: ``raysift trace SCENE --rays RAYS --tracer T --threads N --repeat 3 --json``: its
  ``trace_ms`` (median of the 3 in-process runs).
- ``embreex``: ``EmbreeScene`` + ``TriangleMesh`` over the same world triangles and a first
  one-ray ``run`` (embreex commits, i.e. builds its BVH, then): the build; then
  ``scene.run(origins, directions)`` (primitive ids only) and ``run(..., output=1)`` (t, u, v, Ng,
  ids): embreex's loop of rtcIntersect1 calls, one thread whatever ``--threads`` (the build uses
  TBB's threads: run the script under ``taskset -c 0`` for one).
- ``trimesh``: ``trimesh.Trimesh(...).ray.intersects_first(origins, directions)``, trimesh's default
  backend (``ray_pyembree`` when embreex is installed), first call (builds its Embree scene) and a
  second call.
- ``trimesh-triangle``: trimesh's pure-numpy backend (``ray_triangle``, needs rtree) on the first
  ``--subset-triangle`` rays, scaled to the whole batch (it is far too slow for 1M rays).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import raysift

REPO = Path(__file__).resolve().parents[3]


def cli_exe():
    return Path(os.environ.get("RAYSIFT_CLI", REPO / "target" / "release" / "raysift"))


def run_cli(scene, rays, tracer, threads):
    r = subprocess.run(
        [str(cli_exe()), "trace", str(scene), "--rays", str(rays), "--tracer", tracer,
         "--threads", str(threads), "--repeat", "3", "--json"],
        capture_output=True, text=True, check=True)
    j = json.loads(r.stdout)
    return {"trace_ms": j["trace_ms"], "prepare_ms": j["prepare_ms"], "hits": j["hits"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("rays")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--tracers", default="bvh,dacrt")
    ap.add_argument("--contenders", default="py,cli,embreex,trimesh,trimesh-triangle")
    ap.add_argument("--subset-triangle", type=int, default=4096)
    ap.add_argument("--json")
    a = ap.parse_args()
    tracers = a.tracers.split(",")
    contenders = a.contenders.split(",")

    t0 = time.perf_counter()
    scene = raysift.Scene.load(a.scene)
    load_ms = (time.perf_counter() - t0) * 1e3
    rays = np.load(a.rays)
    flat = rays.reshape(-1, rays.shape[-1])
    n = len(flat)
    origins = np.ascontiguousarray(flat[:, 0:3])
    dirs = np.ascontiguousarray(flat[:, 3:6])
    tris = scene.triangles()
    print(f"{a.scene}: {len(scene)} triangles (loaded in {load_ms:.0f} ms); {n} rays {rays.shape}; "
          f"threads {a.threads}", file=sys.stderr)

    res = {k: [] for k in [f"py:{t}" for t in tracers] + [f"cli:{t}" for t in tracers]
           + ["embreex", "trimesh", "trimesh-triangle"]}
    prepared = {}
    if "py" in contenders:
        for t in tracers:  # warm-up: prepare
            scene.cast_rays(rays, tracer=t, threads=a.threads)
            prepared[t] = scene.last_stats["prepare"]["prepare_ms"]
    emb_mesh = None
    for rnd in range(a.rounds):
        for t in tracers:
            if "py" in contenders:
                t1 = time.perf_counter()
                h = scene.cast_rays(rays, tracer=t, threads=a.threads)
                total = (time.perf_counter() - t1) * 1e3
                st = scene.last_stats
                assert st["prepare"] is None and st["chunks"] == 1
                res[f"py:{t}"].append(dict(total_ms=total, trace_ms=st["trace_ms"], convert_ms=st["convert_ms"],
                                           output_ms=st["output_ms"],
                                           hits=int((h["primitive_ids"] != raysift.MISS).sum())))
            if "cli" in contenders:
                res[f"cli:{t}"].append(run_cli(a.scene, a.rays, t, a.threads))
        if "embreex" in contenders:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            t1 = time.perf_counter()
            es = rtcore_scene.EmbreeScene()
            TriangleMesh(es, tris)
            es.run(origins[:1], dirs[:1])  # embreex commits (builds the BVH) on the first run
            build = (time.perf_counter() - t1) * 1e3
            t1 = time.perf_counter()
            ids = es.run(origins, dirs)
            ids_ms = (time.perf_counter() - t1) * 1e3
            t1 = time.perf_counter()
            e = es.run(origins, dirs, output=1)
            trace = (time.perf_counter() - t1) * 1e3
            assert np.array_equal(ids, e["primID"])
            res["embreex"].append(dict(build_ms=build, trace_ms=trace, ids_ms=ids_ms,
                                       hits=int((e["primID"] != -1).sum())))
            del es
        if "trimesh" in contenders:
            import trimesh

            mesh = trimesh.Trimesh(vertices=tris.reshape(-1, 3), faces=np.arange(3 * len(tris)).reshape(-1, 3),
                                   process=False)
            t1 = time.perf_counter()
            first = mesh.ray.intersects_first(origins, dirs)
            call1 = (time.perf_counter() - t1) * 1e3
            t1 = time.perf_counter()
            first = mesh.ray.intersects_first(origins, dirs)
            call2 = (time.perf_counter() - t1) * 1e3
            res["trimesh"].append(dict(backend=type(mesh.ray).__module__, first_call_ms=call1, trace_ms=call2,
                                       hits=int((first >= 0).sum())))
        if "trimesh-triangle" in contenders and rnd == 0:
            import trimesh

            if emb_mesh is None:
                emb_mesh = trimesh.Trimesh(vertices=tris.reshape(-1, 3),
                                           faces=np.arange(3 * len(tris)).reshape(-1, 3), process=False)
            rt = trimesh.ray.ray_triangle.RayMeshIntersector(emb_mesh)
            k = min(a.subset_triangle, n)
            step = max(1, n // k)
            sub = slice(0, n, step)
            t1 = time.perf_counter()
            rt.intersects_first(origins[sub], dirs[sub])
            ms = (time.perf_counter() - t1) * 1e3
            res["trimesh-triangle"].append(dict(rays=len(origins[sub]), ms=ms, trace_ms=ms * n / len(origins[sub])))
        print(f"round {rnd + 1}/{a.rounds} done", file=sys.stderr)

    def med(rows, key):
        return statistics.median(r[key] for r in rows) if rows else float("nan")

    def lo(rows, key):
        return min(r[key] for r in rows) if rows else float("nan")

    out = dict(scene=a.scene, triangles=len(scene), rays=n, shape=list(rays.shape), threads=a.threads,
               rounds=a.rounds, prepare_ms=prepared, runs=res)
    print(f"\n| contender | threads | ms, median of {a.rounds} (min) | vs CLI (min vs min) | notes |")
    print("|---|---:|---:|---:|---|")
    for t in tracers:
        cli, cli_lo = med(res[f"cli:{t}"], "trace_ms"), lo(res[f"cli:{t}"], "trace_ms")
        if res[f"cli:{t}"]:
            print(f"| CLI `raysift trace --tracer {t}`: trace | {a.threads} | {cli:.1f} ({cli_lo:.1f}) | 1.00 | "
                  f"prepare {med(res[f'cli:{t}'], 'prepare_ms'):.1f} ms (every run) |")
        if res[f"py:{t}"]:
            rows = res[f"py:{t}"]
            tot, tr = med(rows, "total_ms"), med(rows, "trace_ms")
            cv, ou = med(rows, "convert_ms"), med(rows, "output_ms")
            print(f"| Python `cast_rays(tracer=\"{t}\")`: whole call | {a.threads} | {tot:.1f} ({lo(rows, 'total_ms'):.1f}) | "
                  f"{tot / cli:.3f} ({lo(rows, 'total_ms') / cli_lo:.3f}) | input {cv:.1f} ms, outputs {ou:.1f} ms; "
                  f"prepared once before: {prepared.get(t, 0):.1f} ms |")
            print(f"| Python, the library's trace inside the call | {a.threads} | {tr:.1f} ({lo(rows, 'trace_ms'):.1f}) | "
                  f"{tr / cli:.3f} ({lo(rows, 'trace_ms') / cli_lo:.3f}) | `last_stats[\"trace_ms\"]` |")
    if res["embreex"]:
        e = res["embreex"]
        print(f"| embreex `run(o, d)` (ids only) | 1 (serial loop) | {med(e, 'ids_ms'):.1f} ({lo(e, 'ids_ms'):.1f}) | | build {med(e, 'build_ms'):.1f} ms |")
        print(f"| embreex `run(o, d, output=1)` (t, u, v, Ng, ids) | 1 (serial loop) | {med(e, 'trace_ms'):.1f} ({lo(e, 'trace_ms'):.1f}) | | |")
    if res["trimesh"]:
        tm = res["trimesh"]
        print(f"| trimesh default `mesh.ray.intersects_first` ({tm[0]['backend']}) | 1 (serial loop) | "
              f"{med(tm, 'trace_ms'):.1f} ({lo(tm, 'trace_ms'):.1f}) | | first call (builds) {med(tm, 'first_call_ms'):.1f} ms |")
    if res["trimesh-triangle"]:
        r0 = res["trimesh-triangle"][0]
        print(f"| trimesh `ray_triangle.intersects_first` (pure numpy + rtree) | 1 | {r0['trace_ms']:.0f} (scaled) | | "
              f"{r0['rays']} rays in {r0['ms']:.0f} ms, once |")
    hits = {k: v[0]["hits"] for k, v in res.items() if v and "hits" in v[0]}
    print(f"\nhits: {hits}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
