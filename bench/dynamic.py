"""Mora 2011, Fig. 9 and Fig. 10 for raysift: an animated scene and a path tracer, DACRT vs BVH.

    python3 bench/dynamic.py [--scenes A,B] [--frames 8] [--size 1024] [--spp 1] [--threads 1]
                             [--rounds 3] [--raysift target/release/raysift]

Animated (Fig. 9): `raysift animate SCENE --motion explode` renders frames whose triangles fly
apart (every frame is a new scene: DACRT re-reads its min/max lists, the BVH is rebuilt), diffuse
shading with one shadow ray per hit; per frame, prepare and trace ms (camera + shadow rays).

Path tracing (Fig. 10): `raysift render SCENE --integrator path` with 7 bounces, no Russian
roulette, every bounce one batch; Mrays/s per bounce depth (bounces 1+ are incoherent: DACRT's
random-ray mode) and the BVH's build, which a dynamic scene pays once per frame.

Scenes: the bunny and the dragons are open meshes (most bounce rays escape, so deep bounces are
small batches); Sponza is an interior, where every bounce stays near the pixel count, as in the
paper's Fig. 10 scenes.

Tracers alternate (dacrt, bvh, dacrt, bvh, ...) for --rounds rounds; medians are printed as
Markdown tables with the command lines used.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TRACERS = ["dacrt", "bvh"]
# Interiors need the camera inside (as in run.py); other scenes use raysift's default framing.
CAMERAS = {"sponza.obj.gz": ["--eye=-13,2.5,0", "--look=10,4.5,0", "--fov", "60"]}


def run_json(cmd):
    p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {shlex.join(map(str, cmd))}\n{p.stderr.strip()}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    shared = ROOT.parent / "shared" / "scenes"
    ap.add_argument("--scenes", default=",".join(str(shared / n) for n in
                                                  ("bun_zipper.ply", "sponza.obj.gz", "dragon_vrip_res2.ply.gz",
                                                   "dragon_vrip.ply.gz")))
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--size", type=int, default=1024, help="animation image width and height")
    ap.add_argument("--path-size", type=int, default=512, help="path tracing image width and height")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--raysift", default=str(ROOT / "target" / "release" / "raysift"))
    a = ap.parse_args(argv)
    scenes = [s for s in a.scenes.split(",") if s]
    rs = a.raysift
    med = statistics.median

    print(f"Command: `python3 bench/dynamic.py {' '.join(shlex.quote(x) for x in (argv or sys.argv[1:]))}`\n")
    print(f"### Animated: exploding mesh, {a.frames} frames at {a.size}×{a.size}, {a.threads} thread(s), "
          f"median of {a.rounds} rounds of the per-sequence means\n")
    print("| scene | triangles | tracer | prepare ms / frame | trace ms / frame (camera + shadow) | "
          "frame ms | DACRT ÷ BVH frame |")
    print("|---|---:|---|---:|---:|---:|---:|")
    cmds = []
    for sc in scenes:
        res = {t: [] for t in TRACERS}
        for _ in range(a.rounds):
            for t in TRACERS:
                cmd = [rs, "animate", sc, "--motion", "explode", "--frames", a.frames, "--no-images",
                       "--width", a.size, "--height", a.size, "--tracer", t, "--threads", a.threads,
                       "--pin", "--json", "--out", "/tmp/raysift-dynamic-frames"] + CAMERAS.get(Path(sc).name, [])
                res[t].append(run_json(cmd))
        cmds.append(shlex.join(map(str, cmd)))
        ratio = med(d["mean_frame_ms"] / b["mean_frame_ms"] for d, b in zip(res["dacrt"], res["bvh"]))
        for t in TRACERS:
            j = res[t]
            print(f"| {Path(sc).name} | {j[0]['triangles']:,} | {t} | {med(x['mean_prepare_ms'] for x in j):,.1f} | "
                  f"{med(x['mean_trace_ms'] for x in j):,.1f} | {med(x['mean_frame_ms'] for x in j):,.1f} | "
                  f"{f'{ratio:.2f}' if t == 'dacrt' else ''} |")
    print(f"\nLast command per scene: `{cmds[-1]}` (and `--tracer dacrt`).\n")

    print(f"### Path tracing: 7 bounces, {a.spp} spp at {a.path_size}×{a.path_size}, {a.threads} thread(s), "
          f"Mrays/s per bounce depth (median of {a.rounds} rounds)\n")
    print("| scene | tracer | prepare ms | " + " | ".join(f"depth {k}" for k in range(8)) + " | all depths |")
    print("|---|---|---:|" + "---:|" * 9)
    for sc in scenes:
        res = {t: [] for t in TRACERS}
        for _ in range(a.rounds):
            for t in TRACERS:
                cmd = [rs, "render", sc, "--integrator", "path", "--spp", a.spp, "--bounces", 7,
                       "--width", a.path_size, "--height", a.path_size, "--tracer", t,
                       "--threads", a.threads, "--pin", "--json", "--out", "/tmp/raysift-dynamic-path.png"]
                cmd += CAMERAS.get(Path(sc).name, [])
                res[t].append(run_json(cmd))
        for t in TRACERS:
            j = res[t]
            depths = j[0]["per_bounce"]
            cells = []
            for k in range(len(depths)):
                cells.append(f"{med(x['per_bounce'][k]['mrays_per_s'] for x in j):.2f}")
            rays = sum(d["rays"] for d in depths)
            total = med(x["trace_ms"] for x in j)
            print(f"| {Path(sc).name} | {t} | {med(x['prepare_ms'] for x in j):,.1f} | " + " | ".join(cells)
                  + f" | {rays / total / 1e3:.2f} |")
    print(f"\nCommand per scene and tracer: `{shlex.join(map(str, cmd))}`.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
