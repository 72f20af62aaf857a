#!/usr/bin/env python3
"""Wiche & Kuri 2020, Tables 1 and 2, as counts: nodes entered and triangle encounters per pixel
in the paper's measuring mode (n = inf, triangles counted, not tested), for the BVH and the
kd-tree, cones at five apertures and 4/16/64 rays per pixel, averaged over three viewpoints.

    python3 bench/cone_tables.py [--size 128] [--timeout 90] [--scenes teapot,bunny,dragon,sponza]
        [--structures kdtree,bvh,sbvh] [--out bench/results/cone-tables.jsonl]

Runs `raysift cones ... --count --json` (the release CLI, target/release/raysift) once per
(scene, structure, row, view) and appends each report to the JSONL file; a row already in the
file is not run again (so a run can be resumed). `--markdown` prints the table from the file.
"""

import argparse
import json
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "scenes")
EXE = os.path.join(ROOT, "target", "release", "raysift")

SCENES = {
    "teapot": "teapot.obj",
    "bunny": "bun_zipper.ply",
    "dragon": "dragon_vrip.ply.gz",
    "sponza": "sponza.obj.gz",
}
APERTURES = [0.04, 0.5, 1.5, 2.5, 5.0]
RAYS = [4, 16, 64]
FOV = 45.0

# The paper's Tables 1 and 2 (GTX 1080, 1024^2, averages of three views): (ms, nodes, inter.)
# per row; Sponza is the Crytek Sponza of Table 2 (ours is the Dabrovic Sponza).
PAPER = {
    ("bvh", "teapot"): [(4.7, 62.9, 29.1), (14.3, 251.9, 116.8), (48.7, 1007.8, 467.3),
                        (18, 18, 10), (35, 30, 27), (93, 71, 88), (178, 132, 184), (497, 370, 573)],
    ("bvh", "bunny"): [(5.2, 79.8, 22.3), (17.2, 319.9, 90.1), (60.3, 1279, 361),
                       (34, 24.6, 10), (93, 57.3, 52), (337, 198, 256), (734, 432, 613),
                       (3338, 1426, 2176)],
    ("bvh", "dragon"): [(6.3, 76.8, 34.4), (21, 308, 138), (74, 1235, 553), (94, 39.6, 53),
                        (421, 197, 449), (2918, 1010, 2652), (5496, 2473, 6699), None],
    ("bvh", "sponza"): [(14.2, 360, 244), (57, 1443, 980.3), (211, 4411, 3923), (68.3, 93, 67),
                        (135, 133.3, 163), (394, 301, 612), (1154, 578, 1392), (3669, 1745, 4779)],
    ("kdtree", "teapot"): [(4.7, 132, 48), (14, 532, 196), (48, 2129, 785), (7, 35, 14),
                           (47, 54, 64), (275, 170, 259), (725, 369, 596), (1567, 1369, 2411)],
    ("kdtree", "bunny"): [(9.5, 183, 48), (21.4, 736, 195), (67.6, 2946, 783), (14, 50, 16),
                          (61, 136, 126), (365, 534, 727), (1611, 1222, 1825), (4685, 4212, 6744)],
    ("kdtree", "dragon"): [(34.6, 184, 90), (79, 739, 249), (164.5, 2960, 998), (32, 60.6, 28),
                           (492, 516, 737), (4180, 3387, 5633), None, None],
    ("kdtree", "sponza"): [(15.4, 484, 299.6), (41, 1939, 1201), (137.6, 6395, 3440.6),
                           (25, 128.6, 85), (96, 282, 346), (1023, 1061, 1831),
                           (2863, 2450, 3682), None],
}


def rows():
    return [("rays", k) for k in RAYS] + [("cone", a) for a in APERTURES]


def bounds(path):
    out = subprocess.run([EXE, "info", path, "--json"], check=True, capture_output=True, text=True)
    b = json.loads(out.stdout)["bounds"]
    return b["min"], b["max"]


def views(name, lo, hi):
    """Three viewpoints: (eye, look) or None for the default framing (from +z)."""
    c = [(a + b) / 2 for a, b in zip(lo, hi)]
    h = [(b - a) / 2 for a, b in zip(lo, hi)]
    if name == "sponza":
        # Inside the atrium (the paper's Sponza views are interior views): along its long axis
        # both ways, and diagonally down across it from the upper gallery.
        y = lo[1] + 0.25 * (hi[1] - lo[1])
        return [
            ((c[0] - 0.8 * h[0], y, c[2]), (c[0] + h[0], y, c[2])),
            ((c[0] + 0.8 * h[0], y, c[2]), (c[0] - h[0], y + 0.2 * h[1], c[2])),
            ((c[0] - 0.5 * h[0], lo[1] + 0.6 * (hi[1] - lo[1]), c[2] + 0.6 * h[2]), (c[0] + 0.5 * h[0], lo[1] + 0.2 * (hi[1] - lo[1]), c[2] - 0.6 * h[2])),
        ]
    t = math.tan(math.radians(FOV / 2))
    dx = h[0] + max(h[2], h[1]) / t * 1.02  # framing from +x, as the default does from +z
    dd = max(h[2] + max(h[0], h[1]) / t * 1.02, dx) * 1.1
    s = 1 / math.sqrt(1 + 0.7 ** 2 + 1)
    return [
        None,
        ((c[0] + dx, c[1], c[2]), tuple(c)),
        ((c[0] + dd * s, c[1] + 0.7 * dd * s, c[2] + dd * s), tuple(c)),
    ]


def key(r):
    return (r["scene_key"], r["structure"], r["row"][0], r["row"][1], r["view"])


def split_structure(s):
    """`bvh[traversal_cost=4,max_leaf=8]` -> ("bvh", ["traversal_cost=4", "max_leaf=8"])."""
    if "[" not in s:
        return s, []
    base, rest = s.split("[", 1)
    return base, [o for o in rest.rstrip("]").split(";") if o]


def run(args):
    done = set()
    if os.path.exists(args.out):
        with open(args.out) as f:
            for line in f:
                done.add(key(json.loads(line)))
    for name in args.scenes.split(","):
        path = os.path.join(SHARED, SCENES[name])
        if not os.path.exists(path):
            print(f"SKIPPED {name}: {path} absent", file=sys.stderr)
            continue
        lo, hi = bounds(path)
        for structure in args.structures.split(","):
            for kind, v in rows():
                for vi, view in enumerate(views(name, lo, hi)):
                    k = (name, structure, kind, v, vi)
                    if k in done:
                        continue
                    base, opts = split_structure(structure)
                    cmd = [EXE, "cones", path, "--count", "--json", "--structure", base,
                           "--width", str(args.size), "--height", str(args.size)]
                    for o in opts:
                        cmd += ["--bvh", o]
                    cmd += ["--rays-per-pixel", str(v)] if kind == "rays" else ["--aperture", str(v)]
                    if view is not None:
                        cmd += ["--eye", ",".join(f"{x:.6g}" for x in view[0]),
                                "--look", ",".join(f"{x:.6g}" for x in view[1])]
                    try:
                        out = subprocess.run(cmd, check=True, capture_output=True, text=True,
                                             timeout=args.timeout)
                        rep = json.loads(out.stdout)
                    except subprocess.TimeoutExpired:
                        rep = {"timeout_s": args.timeout}
                    rep.update(scene_key=name, structure=structure, row=[kind, v], view=vi,
                               size=args.size, command=" ".join(cmd))
                    with open(args.out, "a") as f:
                        f.write(json.dumps(rep) + "\n")
                    print(name, structure, kind, v, vi, rep.get("nodes_per_pixel"),
                          rep.get("trace_ms"), file=sys.stderr, flush=True)


def markdown(args):
    reps = {}
    with open(args.out) as f:
        for line in f:
            r = json.loads(line)
            reps.setdefault((r["scene_key"], r["structure"], r["row"][0], r["row"][1]), []).append(r)
    print("| structure | scene | row | nodes/px | tris/px | CPU ms (3 views) | paper nodes/px | paper inter./px | ratio nodes | ratio inter. |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for structure in args.structures.split(","):
        for name in SCENES:
            for i, (kind, v) in enumerate(rows()):
                rs = reps.get((name, structure, kind, v))
                if not rs:
                    continue
                label = f"{v} rays" if kind == "rays" else f"{v}°"
                # The paper's BVH is an SBVH: its columns stand beside both of ours.
                base = split_structure(structure)[0]
                paper = PAPER.get(("bvh" if base == "sbvh" else base, name), [None] * 8)[i]
                pn, pi = (f"{paper[1]:g}", f"{paper[2]:g}") if paper else ("-", "-")
                if any("timeout_s" in r for r in rs) or len(rs) < 3:
                    print(f"| {structure} | {name} | {label} | over {rs[0].get('timeout_s', '?')} s | | | {pn} | {pi} | | |")
                    continue
                nodes = sum(r["nodes_per_pixel"] for r in rs) / len(rs)
                tris = sum(r["tri_encounters_per_pixel"] for r in rs) / len(rs)
                ms = sum(r["trace_ms"] for r in rs)
                rn = f"{nodes / paper[1]:.2f}" if paper else "-"
                ri = f"{tris / paper[2]:.2f}" if paper else "-"
                print(f"| {structure} | {name} | {label} | {nodes:.1f} | {tris:.1f} | {ms:.0f} | {pn} | {pi} | {rn} | {ri} |")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--timeout", type=float, default=90)
    p.add_argument("--scenes", default="teapot,bunny,sponza,dragon")
    p.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "cone-tables.jsonl"))
    p.add_argument("--structures", default="kdtree,bvh",
                   help="comma-separated: kdtree, bvh, sbvh (the BVH with spatial splits); a BVH "
                        "may carry build options, semicolon-separated: 'bvh[traversal_cost=4]'")
    p.add_argument("--markdown", action="store_true")
    a = p.parse_args()
    markdown(a) if a.markdown else run(a)


if __name__ == "__main__":
    main()
