"""Mora 2011, Fig. 14, from benchmark results: DACRT's whole frame against build + trace.

    python3 bench/fig14.py bench/results/<date>.json [more.json ...] [--threads 1] [--min-tris 50000]
                           [--run last|first]

For every scene of at least --min-tris triangles with a camera workload (1024x1024 primary rays in
the full run), one row: DACRT's frame (prepare + trace: it has no structure to keep), our BVH's
build + trace and trace alone, Embree's fastest build + 16-wide packet trace (LOW or MEDIUM, the
faster per round) and its trace alone, and the ratios the issue sets targets for. Ratios are
medians of per-round ratios (contenders alternate within a round, so a round shares the machine's
state), not ratios of medians; the ratios to Embree are bench/common.py's ratio_to_embree, the
harness's own (bench/README.md, "Ratio to Embree"). Two targets compare DACRT's whole frame with
the others' trace alone ("DACRT frame ÷ ... trace"). Prints a Markdown table.

--run picks the run inside each process: the last (default, what the harness measures: a process
warmed by its earlier runs, as a renderer's steady state) or the first (a cold process: page faults
of fresh memory included). The harness keeps several runs per process only for contenders whose
warm-up run is shorter than its --long-run-ms; run it with a huge --long-run-ms to compare every
contender both ways.
"""

from __future__ import annotations

import argparse
import json
import sys

import common
from common import contender_name, median, paired_ratio, ratio_to_embree, round_values


def rows(results, threads, min_tris, run="last", tracer="dacrt", baseline="bvh"):
    """One row per scene of the Fig. 14 table. Every ratio is common.paired_ratio's (median over the
    rounds both sides ran of the per-round ratio); every ratio to Embree is common.ratio_to_embree's
    (the fastest Embree configuration of each round)."""
    out = []
    d_name, b_name = contender_name(tracer, threads), contender_name(baseline, threads)
    for s in results["scenes"]:
        w = s.get("workloads", {}).get("camera")
        if not w or s["triangles"] < min_tris:
            continue
        cs = w["contenders"]
        d, b = cs.get(d_name, {}), cs.get(b_name, {})
        d_frame, d_trace = round_values(d, "frame", run), round_values(d, "trace", run)
        b_frame, b_trace = round_values(b, "frame", run), round_values(b, "trace", run)
        ratios = dict(
            r_bvh_frame=paired_ratio(d_frame, b_frame),
            r_bvh_trace=paired_ratio(d_frame, b_trace),  # DACRT's whole frame vs the BVH's trace alone
            r_embree_frame=ratio_to_embree(cs, d_name, "frame", run),
            r_embree_trace=ratio_to_embree(cs, d_name, "frame", run, embree_metric="trace"),  # the same
        )
        if any(r is None for r in ratios.values()):
            continue
        out.append(dict(
            scene=s["name"], triangles=s["triangles"], rays=w["rays"], hit=w.get("hit_fraction"),
            dacrt=median(d_frame.values()), dacrt_trace=median(d_trace.values()),
            dacrt_prepare=median(round_values(d, "prepare", run).values()),
            bvh_frame=median(b_frame.values()), bvh_trace=median(b_trace.values()),
            embree_frame=common.embree_best_ms(cs, threads, "frame", run),
            embree_trace=common.embree_best_ms(cs, threads, "trace", run),
            rounds=min(r["rounds"] for r in ratios.values()),
            **{k: r["median"] for k, r in ratios.items()},
        ))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="+")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--min-tris", type=int, default=50_000)
    ap.add_argument("--run", choices=("last", "first"), default="last",
                    help="which run of each process: last (warm, default) or first (cold)")
    a = ap.parse_args(argv)
    table = []
    for p in a.results:
        with open(p) as f:
            table += rows(json.load(f), a.threads, a.min_tris, a.run)
    if not table:
        print("no scene with a camera workload and both dacrt and bvh runs", file=sys.stderr)
        return 1
    print("| scene | triangles | hit frac. | DACRT frame ms (prepare + trace) | BVH build + trace ms | "
          "BVH trace ms | Embree best build + trace ms | Embree trace ms | DACRT ÷ BVH frame "
          "(target ≤ 0.5) | DACRT frame ÷ BVH trace (≤ 1.5) | DACRT ÷ Embree frame (≤ 0.5) | "
          "DACRT frame ÷ Embree trace (stretch ≤ 1.4) | rounds |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in table:
        print(f"| {r['scene']} | {r['triangles']:,} | {r['hit']:.2f} | {r['dacrt']:,.0f} "
              f"({r['dacrt_prepare']:,.0f} + {r['dacrt_trace']:,.0f}) | {r['bvh_frame']:,.0f} | "
              f"{r['bvh_trace']:,.0f} | {r['embree_frame']:,.0f} | {r['embree_trace']:,.0f} | "
              f"{r['r_bvh_frame']:.2f} | {r['r_bvh_trace']:.2f} | {r['r_embree_frame']:.2f} | "
              f"{r['r_embree_trace']:.2f} | {r['rounds']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
