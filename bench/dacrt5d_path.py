#!/usr/bin/env python3
"""Issue #17's path-tracing table: Mrays/s per bounce depth of dacrt5d, dacrt, bvh and Embree 4.4
on the same rays, and the frame (one build or prepare + every depth's trace).

    python3 bench/dacrt5d_path.py [--scenes bun_zipper.ply,sponza.obj.gz,dragon_vrip.ply.gz]
        [--size 512] [--bounces 7] [--rounds 3] [--tracers dacrt5d,dacrt,bvh]
        [--embree low,medium] [--old OTHER_RAYSIFT (contenders 'old:TRACER' run on it)]

Each scene is rendered once (`raysift render --integrator path --spp 1`, the renderer of
BENCHMARKS.md's Fig. 10, Sponza from bench/common.py's inside camera) with `--record-rays`; the
recorded batches (one closest-hit batch per depth: the camera rays, then each bounce's) are cut
into one rays file per depth. raysift's tracers render the same frame in one process (`raysift
render --tracer T --pin --threads 1`: per-depth trace times from its JSON, and whatever a tracer
keeps between calls counts as in a frame); Embree traces each depth's file in its own process,
`embree-peer --packet 1 --threads 1` at its `low` and `medium` builds (16-ray packets over 4×4
tiles for the camera rays, Embree's best there), all pinned to core 0. Contenders alternate
within each round; medians over rounds.
Every raysift answer is compared with the recorded one (bit for bit on prim, t, u, v) and Embree's
primitive ids are counted where they differ. Prints Markdown tables and the commands.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(cmd):
    out = subprocess.run(["taskset", "-c", "0"] + [str(c) for c in cmd], check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="bun_zipper.ply,sponza.obj.gz,dragon_vrip.ply.gz")
    ap.add_argument("--scenes-dir", default=os.path.join(ROOT, "..", "shared", "scenes"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--bounces", type=int, default=7)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--tracers", default="dacrt5d,dacrt,bvh")
    ap.add_argument("--old", default=None,
                    help="another raysift binary: contenders written 'old:TRACER' run on it")
    ap.add_argument("--embree", default="low,medium",
                    help="Embree builds to run (comma-separated; empty for none)")
    ap.add_argument("--raysift", default=os.path.join(ROOT, "target", "release", "raysift"))
    ap.add_argument("--peer", default=os.path.join(ROOT, "bench", "target", "release", "embree-peer"))
    a = ap.parse_args()
    tracers = a.tracers.split(",")
    embrees = [(f"embree {q}", q) for q in filter(None, a.embree.split(","))]
    work = tempfile.mkdtemp(prefix="dacrt5d-path-")
    print(f"`python3 bench/dacrt5d_path.py --scenes {a.scenes} --size {a.size} --bounces {a.bounces} "
          f"--rounds {a.rounds} --tracers {a.tracers} --embree {a.embree}"
          + (f" --old {a.old}" if a.old else "") + "`\n")
    for sc in a.scenes.split(","):
        path = os.path.join(a.scenes_dir, sc)
        d = os.path.join(work, common.slug(sc))
        cam = common.camera_args(common.camera_preset(sc))
        subprocess.run([a.raysift, "render", path, "--integrator", "path", "--spp", "1", "--bounces",
                        str(a.bounces), "--width", str(a.size), "--height", str(a.size), "--tracer", "bvh",
                        "--record-rays", d, "--quiet", "--json", "--out", d + ".png", *cam],
                       check=True, capture_output=True)
        tris = os.path.join(d, "tris.npy")
        subprocess.run([a.raysift, "export", path, "--out", tris], check=True, capture_output=True)
        calls = [c for c in json.load(open(os.path.join(d, "calls.json"))) if c["kind"] == "intersect"]
        rays = np.load(os.path.join(d, "intersect-rays.npy"))
        hits = np.load(os.path.join(d, "intersect-hits.npy"))
        depth_files = []
        for k, c in enumerate(calls):
            rows = slice(c["start"], c["start"] + c["rays"])
            f = os.path.join(d, f"depth{k}.npy")
            np.save(f, rays[rows])
            depth_files.append((f, hits[rows], c["layout"]))
        contenders = tracers + [e[0] for e in embrees]
        quality = dict(embrees)
        res = {c: [[] for _ in depth_files] for c in contenders}
        prep = {c: [] for c in contenders}
        bad = {c: 0 for c in contenders}
        for r in range(a.rounds):
            order = contenders[r % len(contenders):] + contenders[:r % len(contenders)]
            for c in order:
                if c in tracers:
                    # One frame in one process (the renderer's own calls: what a tracer keeps
                    # between calls counts as it would in a frame); its per-depth times. The
                    # renderer is deterministic and every tracer's answers are the same, so its
                    # rays are the recorded ones (checked: the rays per depth).
                    exe, spec = (a.old, c[4:]) if c.startswith("old:") else (a.raysift, c)
                    j = run([exe, "render", path, "--integrator", "path", "--spp", "1", "--bounces",
                             str(a.bounces), "--width", str(a.size), "--height", str(a.size), "--threads", "1",
                             "--pin", "--quiet", "--json", "--out", d + f"-{common.slug(c)}.png", *cam,
                             *common.tracer_args(spec)])
                    per = j["per_bounce"]
                    assert [p["rays"] for p in per] == [len(w) for _, w, _ in depth_files], sc
                    for k, p in enumerate(per):
                        res[c][k].append(p["trace_ms"])
                    prep[c].append(j["prepare_ms"])
                    if r == 0:
                        # Each depth's rays traced alone; answers bit for bit against the recording.
                        for k, (f, want, _) in enumerate(depth_files):
                            out = os.path.join(d, f"out-{k}.npy")
                            run([exe, "trace", path, "--rays", f, "--threads", "1", "--json",
                                 *common.tracer_args(spec), "--out", out])
                            got = np.load(out)
                            bad[c] += not all(np.array_equal(got[x].view(np.uint32), want[x].view(np.uint32))
                                              for x in ("t", "prim", "u", "v"))
                    print(f"  {sc} round {r + 1} {c}", file=sys.stderr)
                    continue
                for k, (f, want, layout) in enumerate(depth_files):
                    out = os.path.join(d, f"out-{k}.npy")
                    cmd = [a.peer, "--tris", tris, "--rays", f, "--threads", "1", "--repeat", "1",
                           "--quality", quality[c], "--out", out]
                    if layout.startswith("pinhole"):
                        cmd += ["--packet", "16", "--tile", f"{a.size},{a.size}"]
                    j = run(cmd)
                    if r == 0:
                        bad[c] += int((np.load(out)["prim"] != want["prim"]).sum())
                    res[c][k].append(j["trace_ms"])
                    if k == 0:
                        prep[c].append(j["prepare_ms"])
                print(f"  {sc} round {r + 1} {c}", file=sys.stderr)
        med = statistics.median
        n = [len(w) for _, w, _ in depth_files]
        print(f"**{sc}** ({sum(n):,} rays; rays per depth: {', '.join(f'{x:,}' for x in n)})\n")
        print("| contender | prepare / build ms | " + " | ".join(f"d{k}" for k in range(len(n)))
              + " | all | frame ms | answers |")
        print("|---|---:|" + "---:|" * len(n) + "---:|---:|---|")
        for c in contenders:
            ms = [med(x) for x in res[c]]
            rate = [f"{nk / max(m, 1e-6) / 1e3:.2f}" for nk, m in zip(n, ms)]
            frame = med(prep[c]) + sum(ms)
            ans = ("bit-equal to the recording" if bad[c] == 0 else f"{bad[c]} depths differ") \
                if c in tracers else f"{bad[c]:,} prim ids differ"
            print(f"| {c} | {med(prep[c]):.1f} | " + " | ".join(rate)
                  + f" | {sum(n) / max(sum(ms), 1e-6) / 1e3:.2f} | {frame:.1f} | {ans} |")
        print()
        sys.stdout.flush()


if __name__ == "__main__":
    main()
