"""BENCHMARKS tables and plots from a bench/results/<date>.json (see run.py).

    python3 bench/run.py --report bench/results/<date>.json
"""

from __future__ import annotations

import math
from pathlib import Path

import common

WORKLOAD_TEXT = {
    "camera": "camera rays (Embree: 16-ray packets over 4×4 pixel tiles, rtcIntersect16)",
    "shadow": "shadow rays to a point light from the camera hits, any hit (Embree: 16-ray packets over the "
              "same tiles, rtcOccluded16)",
    "bounce": "cosine-weighted diffuse bounce rays from the camera hits (Embree: single rays, rtcIntersect1)",
    "random": "uniformly random rays inside the scene bounds (Embree: single rays, rtcIntersect1)",
}


def _f(x, nd=1):
    if x is None or (isinstance(x, float) and (math.isnan(x) or math.isinf(x))):
        return "–"
    if abs(x) >= 100:
        return f"{x:,.0f}"
    return f"{x:.{nd}f}"


def _scene_label(s):
    return s["name"]


def plots(res, plot_dir: Path, stem: str):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plot_dir.mkdir(parents=True, exist_ok=True)
    scenes = sorted(res["scenes"], key=lambda s: s["triangles"])
    workloads = [w for w in ("camera", "shadow", "bounce", "random")
                 if any(w in s["workloads"] for s in scenes)]
    tmax = max(res["meta"]["threads"])
    names = common.order_names({n for s in scenes for w in s["workloads"].values() for n, c in w["contenders"].items()
                    if c["threads"] == tmax and c.get("summary")})
    cmap = plt.get_cmap("tab10")
    colors = {n: cmap(i % 10) for i, n in enumerate(names)}
    out = {}

    def bars(metric, fname, ylabel, title, value):
        fig, axes = plt.subplots(len(workloads), 1, figsize=(max(10, 0.9 * len(scenes) * max(1, len(names)) / 3), 3.3 * len(workloads)),
                                 squeeze=False)
        for ax, wname in zip(axes[:, 0], workloads):
            width = 0.8 / max(1, len(names))
            for k, n in enumerate(names):
                xs, ys = [], []
                for i, s in enumerate(scenes):
                    c = s["workloads"].get(wname, {}).get("contenders", {}).get(n)
                    if c and c.get("summary"):
                        xs.append(i + (k - (len(names) - 1) / 2) * width)
                        ys.append(value(c, s["workloads"][wname]))
                ax.bar(xs, ys, width, label=n, color=colors[n])
            ax.set_yscale("log")
            ax.set_xticks(range(len(scenes)))
            ax.set_xticklabels([f"{_scene_label(s)}\n{s['triangles']:,}" for s in scenes], fontsize=7, rotation=30,
                               ha="right")
            ax.set_ylabel(ylabel)
            ax.set_title(f"{title}: {wname}", fontsize=10)
            ax.grid(axis="y", which="both", alpha=0.3)
        axes[0, 0].legend(fontsize=8, ncol=min(6, len(names)), loc="upper right")
        fig.tight_layout()
        p = plot_dir / f"{stem}-{fname}.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        out[metric] = p

    bars("mrays", "mrays", "Mrays/s (higher is better)", f"Mrays/s per scene and tracer, {tmax} threads",
         lambda c, w: w["rays"] / c["summary"]["trace_ms"]["median"] / 1e3)
    bars("dynamic", "dynamic", "prepare + trace, ms (lower is better)",
         f"Dynamic frame (prepare + trace) per scene and tracer, {tmax} threads",
         lambda c, w: c["summary"]["dynamic_ms"]["median"])

    # cost versus triangle count, camera rays, log-log
    if "camera" in workloads:
        allnames = common.order_names({n for s in scenes for n, c in s["workloads"].get("camera", {}).get("contenders", {}).items()
                           if c.get("summary")})
        fig, axes = plt.subplots(1, 3, figsize=(19, 5.5))
        for metric, ax, lab in (("trace_ms", axes[0], "trace ms"), ("prepare_ms", axes[1], "prepare (build) ms"),
                                ("dynamic_ms", axes[2], "dynamic frame ms")):
            for i, n in enumerate(allnames):
                pts = []
                for s in scenes:
                    c = s["workloads"].get("camera", {}).get("contenders", {}).get(n)
                    if c and c.get("summary"):
                        pts.append((s["triangles"], c["summary"][metric]["median"]))
                if pts:
                    xs, ys = zip(*sorted(pts))
                    ls = "-" if n.endswith(f"-{tmax}t") else "--"
                    ax.plot(xs, ys, ls, marker="o", ms=3, label=n, color=cmap(i % 10))
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("triangles")
            ax.set_ylabel(lab)
            ax.set_title(f"camera rays ({res['meta']['camera'][0]}×{res['meta']['camera'][1]}): {lab} vs triangles",
                         fontsize=10)
            ax.grid(which="both", alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        p = plot_dir / f"{stem}-scaling.png"
        fig.savefig(p, dpi=90)
        plt.close(fig)
        out["scaling"] = p
    return out


def write_report(res, results_path: Path, md_path: Path):
    root = common.ROOT
    stem = results_path.stem
    m = res["meta"]
    # the ratios from the runs, by the one definition (common.ratio_to_embree), whatever the
    # results file stored (files older than the shared module used another rule: bench/README.md)
    for s in res["scenes"]:
        for w in s["workloads"].values():
            common.add_ratios(w["contenders"])
    if not m.get("embree_version"):  # partial results: take it from a peer's own JSON
        m["embree_version"] = next((c["json"].get("embree_version") for s in res["scenes"]
                                    for w in s["workloads"].values() for c in w["contenders"].values()
                                    if c["kind"] == "embree" and c.get("json")), None)
    try:
        pl = plots(res, results_path.resolve().parent / "plots", stem)
    except Exception as e:  # noqa: BLE001  (the tables matter more than the pictures)
        print(f"plots failed: {e}")
        pl = {}

    def rel(p):
        try:
            return str(Path(p).resolve().relative_to(root))
        except ValueError:
            return str(p)

    L = []
    L.append(f"<!-- generated by bench/report.py from {rel(results_path)}; do not edit by hand -->")
    L.append(f"## raysift vs Embree {_ver(m.get('embree_version'))} ({m['mode']} run, {m['date']})")
    if m.get("partial"):
        L.append("")
        L.append(f"**Partial run: {m['partial']} finished.**")
    L.append("")
    L.append(f"* Machine: **{m['cpu_model']}**, {m['logical_cpus']} logical CPUs (used: {m['cpus_used']}), "
             f"Linux {m.get('kernel', '?')}; load average at start {m['load'][0]:.2f}, at end "
             f"{m.get('load_end', [float('nan')])[0]:.2f} (the machine is shared: absolute times drift, "
             "ratios from the same run hold).")
    binary = "" if m.get("raysift_binary", "").endswith("target/release/raysift") and "/tmp/" not in m.get(
        "raysift_binary", "") else f" (raysift binary {m.get('raysift_binary')})"
    L.append(f"* Command: `{m['command']}` at commit `{m['raysift_commit']}`{binary}, "
             + (f"{m['elapsed_s'] / 60:.1f} minutes." if m.get("elapsed_s") else
              f"stopped after {sum(x.get('elapsed_s', 0) for x in res['scenes']) / 60:.1f} minutes."))
    v = m.get("versions", {})
    L.append(f"* Contenders: raysift tracers {', '.join(m['raysift_tracers'])} (`raysift trace --json --pin`), "
             f"Embree {_ver(m.get('embree_version'))} from the embreex {v.get('embreex', '?')} wheel through "
             "`bench/embree-peer` (build quality LOW and MEDIUM; 16-ray packets over 4×4 tiles for camera and "
             "shadow rays, single rays otherwise; FTZ/DAZ on pinned tracing threads). "
             f"Threads: {', '.join(map(str, m['threads']))}, set by CPU affinity (and `--threads`) on both sides.")
    L.append(f"* Workloads per scene, the same `rays.npy` for everyone: camera {m['camera'][0]}×{m['camera'][1]}, "
             f"shadow and bounce rays from the camera hits, {m['random_rays']:,} random rays. "
             f"Each contender is a separate process; contenders alternate (A B C … A B C …), "
             f"1 warm-up round + {m['rounds']} measured rounds; each process prepares and traces "
             f"{m.get('inproc_runs', 1)} time(s) (once where a run takes ≥ {m.get('long_run_ms', 400) / 1e3:g} s, and for naive) and its last run counts (steady state: buffers, allocator and "
             "thread pools warm, the structure rebuilt from scratch); times are medians over rounds with "
             "[min–max] spread, read from each tool's own JSON (process start-up and file loading excluded).")
    L.append("* *Dynamic frame* = prepare (build) + trace, as for a scene that changes every frame. "
             "*Ratio* = raysift ÷ the fastest Embree configuration of the same round at the same thread count, "
             "median over rounds (> 1: raysift is slower; bench/README.md, \"Ratio to Embree\"). Peak RSS is the whole process (scene, rays, hits, structure). "
             "Bytes/triangle: raysift's own report of its structure; for Embree, the resident-memory growth "
             "across the build (an estimate).")
    if any(c.get("slow") for s in res["scenes"] for w in s["workloads"].values() for c in w["contenders"].values()):
        L.append(f"* Contenders whose warm-up run took more than {m.get('slow_run_s', 6):g} s were measured in "
                 f"{m.get('slow_rounds', 3)} rounds only (marked in the tables), to keep the full run within its time "
                 "budget.")
    nd = len(res["disagreements"])
    nchk = sum(len(w["agreement"]) for s in res["scenes"] for w in s["workloads"].values())
    L.append(f"* Agreement with Embree (same miss set, t within {m['tolerances']['t_rel']:g} relative, same "
             f"primitive except ties; at most {m['tolerances']['graze_frac']:g} of rays may differ at grazing "
             f"edges): **{nchk - nd} of {nchk} checks passed**"
             + (f", **{nd} FAILED** (see below)" if nd else "") + ".")
    if res["failures"]:
        L.append(f"* **{len(res['failures'])} run(s) failed**: "
                 + "; ".join(f"{f.get('scene')}/{f.get('workload', '')}/{f.get('contender', '')}"
                             for f in res["failures"]))
    L.append("")
    for k, title in (("mrays", "Mrays/s"), ("dynamic", "Dynamic frame"), ("scaling", "Cost vs triangle count")):
        if k in pl:
            L.append(f"![{title}]({rel(pl[k])})")
    L.append("")

    scenes = sorted(res["scenes"], key=lambda s: s["triangles"])
    # summary: raysift vs Embree ratios
    rs_names = common.order_names({n for s in scenes for w in s["workloads"].values() for n, c in w["contenders"].items()
                       if c["kind"] == "raysift" and c.get("ratio_trace")})
    if rs_names:
        L.append("### Summary: raysift ÷ best Embree (trace only / dynamic frame)")
        L.append("")
        L.append("Each cell: trace-time ratio / dynamic-frame ratio against the fastest Embree configuration "
                 "(LOW or MEDIUM) of each round at the same thread count; below 1 means raysift is faster.")
        L.append("")
        L.append("| scene | triangles | workload | hit (occluded) frac. | " + " | ".join(rs_names) + " |")
        L.append("|---|---:|---|---:|" + "---:|" * len(rs_names))
        for s in scenes:
            for wname, w in s["workloads"].items():
                cells = []
                for n in rs_names:
                    c = w["contenders"].get(n)
                    if c and c.get("ratio_trace"):
                        cells.append(f"{c['ratio_trace']['median']:.2f} / {c['ratio_dynamic']['median']:.2f}")
                    elif c and c.get("error"):
                        cells.append("failed")
                    else:
                        cells.append("–")
                L.append(f"| {s['name']} | {s['triangles']:,} | {wname} | {_f(w.get('hit_fraction'), 3)} | "
                         + " | ".join(cells) + " |")
        L.append("")

    for wname in ("camera", "shadow", "bounce", "random"):
        rows = [(s, s["workloads"][wname]) for s in scenes if wname in s["workloads"]]
        if not rows:
            continue
        L.append(f"### {wname}: {WORKLOAD_TEXT[wname]}")
        L.append("")
        L.append("| scene | triangles | rays | hit (occluded) frac. | contender | prepare ms | trace ms [min–max] | Mrays/s | "
                 "dynamic ms | trace ratio | dynamic ratio | peak RSS MB | bytes/tri | agrees |")
        L.append("|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
        for s, w in rows:
            for n in common.order_names(list(w["contenders"])):
                c = w["contenders"][n]
                a = w["agreement"].get(n)
                agrees = "reference" if n == w.get("reference") else ("–" if a is None else ("yes" if a["ok"] else "**NO**"))
                if not c.get("summary"):
                    L.append(f"| {s['name']} | {s['triangles']:,} | {w['rays']:,} | {_f(w.get('hit_fraction'), 3)} | {n} | "
                             + ("failed | " if c.get("error") else "– | ") + "– | – | – | – | – | – | – | – | " + agrees + " |")
                    continue
                sm = c["summary"]
                tr = sm["trace_ms"]
                rt = c.get("ratio_trace")
                rd = c.get("ratio_dynamic")
                bpt = sm.get("bytes_per_triangle")
                if c["kind"] == "embree" and s["triangles"] < 10000:
                    bpt = None  # an RSS difference says nothing about a tiny structure
                nm = n + (f" ({len(c['runs'])} rounds)" if c.get("slow") else "")
                L.append(
                    f"| {s['name']} | {s['triangles']:,} | {w['rays']:,} | {_f(w.get('hit_fraction'), 3)} | {nm} | "
                    f"{_f(sm['prepare_ms']['median'], 2)} | {_f(tr['median'], 2)} [{_f(tr['min'], 2)}–{_f(tr['max'], 2)}] | "
                    f"{_f(w['rays'] / tr['median'] / 1e3, 2)} | {_f(sm['dynamic_ms']['median'], 2)} | "
                    f"{'–' if not rt or c['kind'] == 'embree' else _f(rt['median'], 2)} | "
                    f"{'–' if not rd or c['kind'] == 'embree' else _f(rd['median'], 2)} | "
                    f"{_f(sm['peak_rss_bytes'] / 2**20, 0)} | {_f(bpt, 0) if bpt is not None else '–'} | {agrees} |")
        L.append("")

    L.append("### Scenes and cameras")
    L.append("")
    L.append("| scene | triangles | camera | fov | camera hit fraction | light |")
    L.append("|---|---:|---|---:|---:|---|")
    for s in scenes:
        c = s["camera"]
        L.append(f"| {s['name']} | {s['triangles']:,} | eye ({', '.join(f'{x:.3g}' for x in c['eye'])}) → "
                 f"({', '.join(f'{x:.3g}' for x in c['look'])}), {c['how']} | {c['fov']:g} | {c['hit_fraction']:.3f} | "
                 f"({', '.join(f'{x:.3g}' for x in s['light'])}) |")
    L.append("")
    if res["disagreements"]:
        L.append("### Disagreements")
        L.append("")
        for d in res["disagreements"]:
            L.append(f"* {d['scene']} / {d['workload']} / {d['contender']}: "
                     + ", ".join(f"{k}={v}" for k, v in d.items() if k not in ("scene", "workload", "contender", "examples")))
        L.append("")
    md_path.write_text("\n".join(L) + "\n")
    print(f"wrote {md_path}" + "".join(f", {p}" for p in pl.values()))


def _ver(v):
    if not v:
        return "4"
    v = int(v)
    return f"{v // 10000}.{v // 100 % 100}.{v % 100}"
