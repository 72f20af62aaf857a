"""Mora 2011, Fig. 14, from benchmark results: DACRT's whole frame against build + trace.

    python3 bench/fig14.py bench/results/<date>.json [more.json ...] [--threads 1] [--min-tris 50000]
                           [--run last|first]

For every scene of at least --min-tris triangles with a camera workload (1024x1024 primary rays in
the full run), one row: DACRT's frame (prepare + trace: it has no structure to keep), our BVH's
build + trace and trace alone, Embree's fastest build + 16-wide packet trace (LOW or MEDIUM, the
faster per round) and its trace alone, and the ratios the issue sets targets for. Ratios are
medians of per-round ratios (contenders alternate within a round, so a round shares the machine's
state), not ratios of medians. Prints a Markdown table.

--run picks the run inside each process: the last (default, what the harness measures: a process
warmed by its earlier runs, as a renderer's steady state) or the first (a cold process: page faults
of fresh memory included). The harness keeps several runs per process only for contenders whose
warm-up run is shorter than its --long-run-ms; run it with a huge --long-run-ms to compare every
contender both ways.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys


def per_round(c, run="last"):
    """(prepare + trace, trace) per measured round of a contender, of the process's last or first
    run."""
    k = -1 if run == "last" else 0
    out = []
    for r in c.get("runs", []):
        pre = r.get("prepare_ms_runs") or [r["prepare_ms"]]
        tr = r.get("trace_ms_runs") or [r["trace_ms"]]
        out.append((pre[k] + tr[k], tr[k]))
    return out


def rows(results, threads, min_tris, run="last"):
    out = []
    for s in results["scenes"]:
        w = s.get("workloads", {}).get("camera")
        if not w or s["triangles"] < min_tris:
            continue
        cs = w["contenders"]
        d = per_round(cs.get(f"dacrt-{threads}t", {}), run)
        b = per_round(cs.get(f"bvh-{threads}t", {}), run)
        es = [per_round(cs.get(f"embree-{q}-{threads}t", {}), run) for q in ("low", "medium")]
        es = [e for e in es if e]
        n = min([len(d), len(b)] + [len(e) for e in es])
        if n == 0:
            continue
        # Embree at its best in each round: the faster configuration for the frame, and for trace.
        e_frame = [min(e[k][0] for e in es) for k in range(n)]
        e_trace = [min(e[k][1] for e in es) for k in range(n)]
        med = statistics.median
        out.append(dict(
            scene=s["name"], triangles=s["triangles"], rays=w["rays"], hit=w.get("hit_fraction"),
            dacrt=med(x[0] for x in d[:n]), dacrt_trace=med(x[1] for x in d[:n]),
            dacrt_prepare=med(x[0] - x[1] for x in d[:n]),
            bvh_frame=med(x[0] for x in b[:n]), bvh_trace=med(x[1] for x in b[:n]),
            embree_frame=med(e_frame), embree_trace=med(e_trace),
            r_bvh_frame=med(d[k][0] / b[k][0] for k in range(n)),
            r_bvh_trace=med(d[k][0] / b[k][1] for k in range(n)),
            r_embree_frame=med(d[k][0] / e_frame[k] for k in range(n)),
            r_embree_trace=med(d[k][0] / e_trace[k] for k in range(n)),
            rounds=n,
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
    print(f"| scene | triangles | hit frac. | DACRT frame ms (prepare + trace) | BVH build + trace ms | "
          f"BVH trace ms | Embree best build + trace ms | Embree trace ms | DACRT ÷ BVH frame "
          f"(target ≤ 0.5) | DACRT ÷ BVH trace (≤ 1.5) | DACRT ÷ Embree frame (≤ 0.5) | "
          f"DACRT ÷ Embree trace (stretch ≤ 1.4) | rounds |")
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
