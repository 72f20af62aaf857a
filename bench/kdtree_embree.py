#!/usr/bin/env python3
"""The kd-tree sweep with Embree beside it (issue #15: "against bvh and Embree, same rays, one and
two threads"): on every mesh of the scene folder, 512² camera rays (default framing) and 131,072
random rays in the bounds, traced by `kdtree` (single rays and 4-ray packets), `bvh` and Embree 4.4
(embree-peer, `medium` build, single rays and 16-ray packets: camera packets over 4×4 pixel tiles),
on one and two pinned threads; every contender of a (scene, rays, threads) cell runs once per round,
in order, for `--rounds` rounds, and the medians of the trace times are reported. Each process
traces `--repeat` times and reports the last run. Answers are compared: the rays whose hit ids
differ between the kd-tree and Embree are counted, and among them those that are not near-ties
(distances more than 1e-5 apart, relative, or a hit against a miss).

    cargo build --release -p raysift-cli
    cargo build --release --manifest-path bench/Cargo.toml      # embree-peer
    python3 bench/kdtree_embree.py [--rounds 2] [--scenes a,b] > bench/results/DATE-kdtree-embree.md

Prints a markdown table (Mrays/s of trace time; build ms) and writes the raw runs as JSON lines
to `--raw`.
"""

import argparse
import json
import os
import statistics
import sys
import tempfile

import numpy as np

import common

CONTENDERS = [
    ("kdtree", ["--tracer", "kdtree"]),
    ("kdtree packets", ["--tracer", "kdtree", "--opt", "packets=4"]),
    ("bvh", ["--tracer", "bvh"]),
    ("embree 1", ["--packet", "1"]),
    ("embree 16", ["--packet", "16"]),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_scene_args(ap, "every mesh in the folder")
    ap.add_argument("--width", type=int, default=512)
    ap.add_argument("--random", type=int, default=131072)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--raw", default=str(common.RESULTS / "kdtree-embree-raw.jsonl"))
    a = ap.parse_args()
    sdir = common.scenes_dir(a.scenes_dir)
    scenes = common.resolve_scenes(common.split_list(a.scenes), sdir) if a.scenes else [str(sdir / m) for m in common.mesh_files(sdir)]
    rs, peer = str(common.RAYSIFT_BIN), str(common.PEER_BIN)
    cpus = sorted(os.sched_getaffinity(0))
    w = a.width
    print("| scene (triangles) | rays | threads | kdtree | kdtree 4-ray packets | bvh | Embree single | Embree 16-packets | kd ÷ Embree best (time) | builds ms: kd / bvh / Embree | hit ids ≠ Embree's: all / not a near-tie |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    raw = open(a.raw, "a")
    for scene in scenes:
        with tempfile.TemporaryDirectory() as d:
            tris, cam, rnd = f"{d}/tris.npy", f"{d}/cam.npy", f"{d}/rnd.npy"
            common.run_proc([rs, "export", scene, "--out", tris])
            common.run_proc([rs, "rays", "camera", scene, "--width", w, "--height", w, "--out", cam])
            common.run_proc([rs, "rays", "random", scene, "--count", a.random, "--out", rnd])
            ntri = np.load(tris).shape[0]
            for rays_name, rays, nrays in [("camera", cam, w * w), ("random", rnd, a.random)]:
                for threads in (1, 2):
                    pin = cpus[:threads]
                    times = {c: [] for c, _ in CONTENDERS}
                    builds = {c: [] for c, _ in CONTENDERS}
                    hits = {}
                    for _ in range(a.rounds):
                        for name, args in CONTENDERS:
                            out = f"{d}/{name.replace(' ', '_')}.npy"
                            if name.startswith("embree"):
                                cmd = [peer, "--tris", tris, "--rays", rays, "--threads", threads,
                                       "--repeat", a.repeat, "--quality", "medium", "--out", out] + args
                                if rays_name == "camera" and "16" in args:
                                    cmd += ["--tile", f"{w},{w}"]
                            else:
                                cmd = [rs, "trace", scene, "--rays", rays, "--threads", threads, "--pin",
                                       "--repeat", a.repeat, "--json", "--out", out] + args
                            j, _, _ = common.run_json(cmd, cpus=pin)
                            t = common.report_times(j)
                            times[name].append(t["trace_ms"])
                            builds[name].append(t["prepare_ms"])
                            h = np.load(out)
                            hits[name] = (h["prim"], h["t"])
                            raw.write(json.dumps(dict(scene=scene, rays=rays_name, threads=threads,
                                                      contender=name, **t)) + "\n")
                    med = {c: statistics.median(v) for c, v in times.items()}
                    mr = {c: nrays / (med[c] * 1e3) for c in med}
                    best_e = min(med["embree 1"], med["embree 16"])
                    best_kd = min(med["kdtree"], med["kdtree packets"])
                    (kp, kt), (ep, et) = hits["kdtree"], hits["embree 1"]
                    neq = kp != ep
                    # Of those, hits at distances more than 1e-5 apart (relative), or a hit against
                    # a miss: not two near-ties at a shared edge decided the other way.
                    with np.errstate(invalid="ignore"):
                        miss = np.uint32(0xFFFFFFFF)
                        far = ((kp == miss) != (ep == miss)) | ~(np.abs(kt - et) <= 1e-5 * np.abs(kt))
                    differ = f"{int(neq.sum())} / {int((neq & far).sum())}"
                    b = lambda c: statistics.median(builds[c])
                    print(f"| {os.path.basename(scene)} ({ntri:,}) | {rays_name} | {threads} | "
                          f"{mr['kdtree']:.2f} | {mr['kdtree packets']:.2f} | {mr['bvh']:.2f} | "
                          f"{mr['embree 1']:.2f} | {mr['embree 16']:.2f} | {best_kd / best_e:.2f} | "
                          f"{b('kdtree'):.0f} / {b('bvh'):.0f} / {b('embree 1'):.0f} | {differ} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
