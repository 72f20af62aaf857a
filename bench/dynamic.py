"""Mora 2011, Fig. 9 and Fig. 10 for raysift: an animated scene and a path tracer, every tracer.

    python3 bench/dynamic.py [--scenes A,B] [--scenes-dir D] [--tracers dacrt,bvh] [--frames 8]
                             [--size 1024] [--path-size 512] [--spp 1] [--threads 1] [--rounds 3]
    python3 bench/dynamic.py --report bench/results/<date>-dynamic.json    re-make the tables

Animated (Fig. 9): `raysift animate SCENE --motion explode` renders frames whose triangles fly
apart (every frame is a new scene: DACRT re-reads its min/max lists, the BVH is rebuilt), diffuse
shading with one shadow ray per hit; per frame, prepare and trace ms (camera + shadow rays).

Path tracing (Fig. 10): `raysift render SCENE --integrator path` with 7 bounces, no Russian
roulette, every bounce one batch; Mrays/s per bounce depth (bounces 1+ are incoherent: DACRT's
random-ray mode) and the structure's build, which a dynamic scene pays once per frame.

Scenes (default: the bunny, Sponza and the two dragons of the scene folder): the bunny and the
dragons are open meshes (most bounce rays escape, so deep bounces are small batches); Sponza is an
interior, where every bounce stays near the pixel count, as in the paper's Fig. 10 scenes. Sponza
gets its preset inside camera (bench/common.py), every other scene raysift's default framing.

Contenders: every tracer `raysift tracers` lists (--tracers to restrict; `dacrt:top_below=0` is a
contender of its own, the tracer with `--opt top_below=0`, options joined by `+`); a brute-force tracer only
where rays x triangles stays within --naive-budget. They alternate (A, B, C, A, B, C, ...) for
--rounds rounds; tables give medians over rounds, and each tracer's frame ÷ the --baseline tracer's
(default bvh) as the median of per-round ratios (common.paired_ratio).

Writes bench/results/<date>-dynamic.json (every run's JSON, the commands, the machine) and the
tables as Markdown beside it (<date>-dynamic.md), and prints them. Frames and images go to a
temporary folder of the run's own (--work to choose it, --keep-work to keep it).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import sys
import tempfile
import time
from pathlib import Path

import common
from common import ProcError, log, loud, median, paired_ratio

DEFAULT_SCENES = ["bun_zipper.ply", "sponza.obj.gz", "dragon_vrip_res2.ply.gz", "dragon_vrip.ply.gz"]
BASELINE = "bvh"


def animate_cmd(a, ctx, spec, tracer, work):
    return [ctx["raysift"], "animate", spec, "--motion", "explode", "--frames", a.frames, "--no-images",
            "--width", a.size, "--height", a.size, *common.tracer_args(tracer), "--threads", a.threads, "--pin", "--json",
            "--out", work / "frames", *common.camera_args(common.camera_preset(spec))]


def path_cmd(a, ctx, spec, tracer, work):
    return [ctx["raysift"], "render", spec, "--integrator", "path", "--spp", a.spp, "--bounces", a.bounces,
            "--width", a.path_size, "--height", a.path_size, *common.tracer_args(tracer), "--threads", a.threads, "--pin",
            "--json", "--out", work / f"{common.slug(spec)}-{common.slug(tracer)}.png",
            *common.camera_args(common.camera_preset(spec))]


def rounds_of(runs, key):
    """{round: value} of a tracer's runs (round numbers as they ran, from 1)."""
    return {r["round"]: r["json"][key] for r in runs}


def frames_of(runs):
    """{round: prepare + trace ms} of a tracer's path-tracing runs."""
    return {r["round"]: r["json"]["prepare_ms"] + r["json"]["trace_ms"] for r in runs}


def summarize_animate(runs):
    return dict(prepare_ms=median(r["json"]["mean_prepare_ms"] for r in runs),
                trace_ms=median(r["json"]["mean_trace_ms"] for r in runs),
                frame_ms=median(r["json"]["mean_frame_ms"] for r in runs))


def summarize_path(runs):
    js = [r["json"] for r in runs]
    depths = []
    for k, d in enumerate(js[0]["per_bounce"]):
        depths.append(dict(depth=d.get("depth", k), rays=d["rays"],
                           mrays_per_s=median(j["per_bounce"][k]["mrays_per_s"] for j in js),
                           work=common.work_counters(d, js[0].get("tracer"))))
    trace = median(j["trace_ms"] for j in js)
    rays = sum(d["rays"] for d in depths)
    return dict(prepare_ms=median(j["prepare_ms"] for j in js), trace_ms=trace, rays=rays,
                frame_ms=median(j["prepare_ms"] + j["trace_ms"] for j in js),
                mrays_per_s=rays / trace / 1e3 if trace > 0 else float("nan"), per_bounce=depths)


def run_part(a, ctx, spec, part, make_cmd, results, sres):
    """--rounds rounds of every tracer that fits the budget, alternating; stores runs, summaries and
    the ratios to the baseline under sres[part]."""
    tris = sres.get("triangles")
    if part == "animate":
        cost = a.frames * 2 * a.size ** 2  # camera + at most one shadow ray per pixel, per frame
    else:
        cost = a.spp * (a.bounces + 1) * a.path_size ** 2  # at most one ray per pixel per depth
    pres = sres[part] = dict(tracers={}, commands={})
    alive = []
    for t in ctx["tracers"]:
        if tris is not None and common.over_budget(t, cost, tris, a.naive_budget):
            log(f"  {t} skipped ({part}): {cost} rays x {tris} triangles > budget {a.naive_budget:.2g}")
            pres["tracers"][t] = dict(skipped=f"rays x triangles > {a.naive_budget:.2g}")
            continue
        alive.append(t)
        pres["tracers"][t] = dict(runs=[])
    for rnd in range(1, a.rounds + 1):
        for t in list(alive):
            cmd = make_cmd(a, ctx, spec, t, ctx["work"])
            pres["commands"][t] = shlex.join(map(str, cmd))
            try:
                j, rss, wall = common.run_json(cmd, timeout=a.timeout)
            except (ProcError, ValueError) as e:
                loud(f"{sres['name']} / {part} / {t} failed: {e}")
                results["failures"].append(dict(scene=sres["name"], part=part, tracer=t, round=rnd, error=str(e)))
                pres["tracers"][t]["error"] = str(e)[:2000]
                alive.remove(t)
                continue
            sres.setdefault("triangles", j.get("triangles"))
            pres["tracers"][t]["runs"].append(dict(round=rnd, json=j, peak_rss_bytes=rss, wall_s=wall))
    key = "mean_frame_ms" if part == "animate" else "trace_ms"
    summarize = summarize_animate if part == "animate" else summarize_path
    base = pres["tracers"].get(ctx["baseline"], {}).get("runs")
    for t, tres in pres["tracers"].items():
        if tres.get("runs"):
            tres["summary"] = summarize(tres["runs"])
            if base and t != ctx["baseline"]:
                tres["ratio_to_baseline"] = paired_ratio(rounds_of(tres["runs"], key), rounds_of(base, key))
                if part == "path":  # the frame of a dynamic scene: the structure's build + trace
                    tres["frame_ratio_to_baseline"] = paired_ratio(frames_of(tres["runs"]), frames_of(base))


def bench_scene(a, ctx, spec, results):
    name = common.slug(spec)
    log(f"\n=== {spec}")
    preset = common.camera_preset(spec)
    sres = dict(spec=spec, name=name, camera=preset or "raysift's default framing")
    results["scenes"].append(sres)
    try:
        sres["triangles"] = common.run_json([ctx["raysift"], "info", spec, "--json"])[0].get("triangles")
    except (ProcError, ValueError) as e:
        log(f"  (raysift info failed: {e})")
    t0 = time.perf_counter()
    if "animate" in a.parts:
        run_part(a, ctx, spec, "animate", animate_cmd, results, sres)
    if "path" in a.parts:
        run_part(a, ctx, spec, "path", path_cmd, results, sres)
    sres["elapsed_s"] = time.perf_counter() - t0


# ------------------------------------------------------------------------------------------------
# tables


def _ratio(r):
    return f"{r['median']:.2f}" if r else ""


def markdown(res):
    m = res["meta"]
    c = m["config"]
    base = c["baseline"]
    L = [f"<!-- generated by bench/dynamic.py from its results JSON ({m['date']}); do not edit by hand -->", "",
         f"Command: `{m['command']}` at commit `{m['raysift_commit']}` ({m['cpu_model']}, load average "
         f"{m['load'][0]:.2f} at the start).", ""]
    if any(s.get("animate") for s in res["scenes"]):
        L.append(f"### Animated: exploding mesh, {c['frames']} frames at {c['size']}×{c['size']}, {c['threads']} "
                 f"thread(s), median of {c['rounds']} rounds of the per-sequence means")
        L.append("")
        L.append("| scene | triangles | tracer | prepare ms / frame | trace ms / frame (camera + shadow) | frame ms | "
                 f"frame ÷ {base} frame |")
        L.append("|---|---:|---|---:|---:|---:|---:|")
        cmds = {}
        for s in res["scenes"]:
            for t, tr in s.get("animate", {}).get("tracers", {}).items():
                tri = f"{s['triangles']:,}" if s.get("triangles") is not None else "–"
                sm = tr.get("summary")
                if not sm:
                    why = "failed" if tr.get("error") else tr.get("skipped", "–")
                    L.append(f"| {s['name']} | {tri} | {t} | {why} | – | – | – |")
                    continue
                r = tr.get("ratio_to_baseline")
                L.append(f"| {s['name']} | {tri} | {t} | {sm['prepare_ms']:,.1f} | {sm['trace_ms']:,.1f} | "
                         f"{sm['frame_ms']:,.1f} | {_ratio(r)} |")
            cmds.update(s.get("animate", {}).get("commands", {}))
        if cmds:
            L += ["", f"Last command: `{list(cmds.values())[-1]}` (the same with each `--tracer`).", ""]
    if any(s.get("path") for s in res["scenes"]):
        L.append(f"### Path tracing: {c['bounces']} bounces, {c['spp']} spp at {c['path_size']}×{c['path_size']}, "
                 f"{c['threads']} thread(s), Mrays/s per bounce depth (median of {c['rounds']} rounds)")
        L.append("")
        depth_n = max((len(tr["summary"]["per_bounce"]) for s in res["scenes"]
                       for tr in s.get("path", {}).get("tracers", {}).values() if tr.get("summary")), default=0)
        L.append("| scene | tracer | prepare ms | " + " | ".join(f"depth {k}" for k in range(depth_n))
                 + f" | all depths | trace ÷ {base} trace | frame ms (prepare + trace) | frame ÷ {base} frame |")
        L.append("|---|---|---:|" + "---:|" * (depth_n + 4))
        cmds = {}
        for s in res["scenes"]:
            for t, tr in s.get("path", {}).get("tracers", {}).items():
                sm = tr.get("summary")
                if not sm:
                    why = "failed" if tr.get("error") else tr.get("skipped", "–")
                    L.append(f"| {s['name']} | {t} | {why} |" + " – |" * (depth_n + 4))
                    continue
                cells = [f"{d['mrays_per_s']:.2f}" for d in sm["per_bounce"]]
                cells += ["–"] * (depth_n - len(cells))
                r = tr.get("ratio_to_baseline")
                fr = sm.get("frame_ms")
                L.append(f"| {s['name']} | {t} | {sm['prepare_ms']:,.1f} | " + " | ".join(cells)
                         + f" | {sm['mrays_per_s']:.2f} | {_ratio(r)} | "
                         + (f"{fr:,.1f}" if fr is not None else "–")
                         + f" | {_ratio(tr.get('frame_ratio_to_baseline'))} |")
            cmds.update(s.get("path", {}).get("commands", {}))
        if cmds:
            L += ["", f"Last command: `{list(cmds.values())[-1]}` (the same with each `--tracer`)."]
    if res["failures"]:
        L += ["", f"**{len(res['failures'])} run(s) failed**: "
              + "; ".join(f"{f['scene']}/{f['part']}/{f['tracer']}" for f in res["failures"])]
    return "\n".join(L) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--report", metavar="RESULTS.json", help="only re-make the tables from a results file")
    common.add_scene_args(ap, ",".join(DEFAULT_SCENES))
    ap.add_argument("--tracers", help="raysift tracers to run (default: all that `raysift tracers` lists)")
    ap.add_argument("--parts", default="animate,path", help="which parts to run (default %(default)s)")
    ap.add_argument("--baseline", default=BASELINE, help="the tracer the ratios divide by (default %(default)s)")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--size", type=int, default=1024, help="animation image width and height")
    ap.add_argument("--path-size", type=int, default=512, help="path tracing image width and height")
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--bounces", type=int, default=7)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--naive-budget", type=float, default=common.NAIVE_BUDGET,
                    help="rays x triangles above which a brute-force tracer is skipped (default %(default)g)")
    ap.add_argument("--timeout", type=float, default=1800, help="seconds before one run is killed")
    ap.add_argument("--raysift", help="raysift binary (default target/release/raysift)")
    ap.add_argument("--no-build", action="store_true", help="do not run cargo build first")
    ap.add_argument("--work", help="scratch folder for frames and images (default: a new temporary folder)")
    ap.add_argument("--keep-work", action="store_true", help="keep the scratch folder")
    ap.add_argument("--out", help="results JSON (default bench/results/<date>-dynamic.json)")
    ap.add_argument("--md", help="Markdown tables (default: the results JSON's name with .md)")
    a = ap.parse_args(argv)

    if a.report:
        res = json.loads(Path(a.report).read_text())
        md = markdown(res)
        print(md, end="")
        if a.md:
            Path(a.md).write_text(md)
        return 0

    if not a.no_build:
        common.build(peer=False)
    raysift = common.tool_path(a.raysift, common.RAYSIFT_BIN)
    a.parts = common.split_list(a.parts)
    if not a.parts or set(a.parts) - {"animate", "path"}:
        sys.exit(f"--parts takes animate and/or path, not {a.parts}")
    tracers = common.choose_tracers(common.list_tracers(raysift), a.tracers)
    if not tracers:
        sys.exit("no tracer to run")
    work = Path(a.work) if a.work else Path(tempfile.mkdtemp(prefix="raysift-dynamic-"))
    work.mkdir(parents=True, exist_ok=True)
    ctx = dict(raysift=raysift, tracers=tracers, baseline=a.baseline, work=work)
    specs = common.resolve_scenes(common.split_list(a.scenes) or DEFAULT_SCENES, common.scenes_dir(a.scenes_dir))
    meta, now = common.run_meta("dynamic.py", argv, raysift)
    meta["config"] = dict(frames=a.frames, size=a.size, path_size=a.path_size, spp=a.spp, bounces=a.bounces,
                          threads=a.threads, rounds=a.rounds, tracers=tracers, baseline=a.baseline,
                          naive_budget=a.naive_budget, motion="explode", integrator="path")
    res = dict(meta=meta, scenes=[], failures=[])
    out = Path(a.out) if a.out else common.results_path(now, "dynamic")
    log(f"{len(specs)} scenes, tracers {tracers}, {a.rounds} rounds, {a.threads} thread(s); scratch folder {work}")
    started = time.perf_counter()
    try:
        for k, spec in enumerate(specs):
            bench_scene(a, ctx, spec, res)
            meta["partial"] = f"{k + 1} of {len(specs)} scenes"
            common.write_json(out, res)  # partial results survive an interrupted run
    finally:
        if not a.keep_work:
            shutil.rmtree(work, ignore_errors=True)
    meta.pop("partial", None)
    meta["elapsed_s"] = time.perf_counter() - started
    meta["load_end"] = os.getloadavg()
    common.write_json(out, res)
    md = markdown(res)
    md_path = Path(a.md) if a.md else out.with_suffix(".md")
    md_path.write_text(md)
    print("\n" + md)
    log(f"wrote {out} and {md_path}" + (f"; kept {work}" if a.keep_work else ""))
    if res["failures"]:
        loud(f"{len(res['failures'])} run(s) failed")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
