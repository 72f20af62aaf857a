#!/usr/bin/env python3
"""raysift vs Embree 4.4, side by side, on the same rays, in the same run, on this machine.

    python3 bench/run.py            full run: every mesh in ../shared/scenes + sphere/soup at 100K and 1M
    python3 bench/run.py --quick    two scenes, fewer rounds (< 5 minutes once built)
    python3 bench/run.py --check    agreement only, one small scene, all tracers vs Embree (CI, < 1 minute)
    python3 bench/run.py --report bench/results/X.json    re-make BENCHMARKS.generated.md and plots

Set-up: see bench/README.md (pip install -r bench/requirements.txt; cargo builds both binaries).

Each scene's workloads are generated once with `raysift rays` and fed to every contender as the same
rays.npy: camera rays (4x4-tiled 16-ray packets for Embree), shadow rays to a point light from the
camera hits (packets over the same tiles), cosine-weighted bounce rays, and uniform random rays inside
the bounds (single rays for Embree). Contenders run as separate processes pinned with CPU affinity,
alternating A B C ... A B C ... for a warm-up round plus --rounds measured rounds; prepare and trace
times are read from each tool's own JSON. The warm-up round's hits are checked against Embree's; a
disagreement is printed loudly and fails the run.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

import common
from common import BENCH, ProcError, fmt3, log, loud, run_proc, slug
from report import write_report

MISS = np.uint32(common.MISS)

# Agreement tolerances (issue #3, point 5).
T_REL_TOL = 1e-4  # t within 1e-4 relative
T_ABS_POS = 1e-6  # ... or within 1e-6 x scene size in distance (hits next to the origin)
UV_ABS_TOL = 1e-2  # u, v of the same primitive (catches a struct-layout mismatch)
GRAZE_FRAC = 1e-4  # at most this fraction of rays may differ in the miss set / hit surface
GRAZE_MIN = 3  # ... or this many, whichever is larger (tiny workloads)

SLOW_RUN_S = 6.0  # a contender whose warm-up run (prepare + trace) takes longer than this ...
SLOW_ROUNDS = 3  # ... is measured in this many rounds only (flagged in the report), to keep the
# full run within its time budget on 2 cores
LONG_RUN_MS = 200  # a run at least this long is measured once per process (warm-up hardly matters)
PROCEDURAL = ["sphere:100000", "soup:100000", "sphere:1000000", "soup:1000000"]

MODES = {
    # naive_budget: rays x triangles above which a brute-force tracer is skipped (common.over_budget)
    "full": dict(width=1024, height=1024, random=1 << 19, rounds=5, threads=[1, 2], naive_budget=common.NAIVE_BUDGET,
                 scenes=None),
    "quick": dict(width=1024, height=1024, random=1 << 19, rounds=2, threads=[1, 2], naive_budget=common.NAIVE_BUDGET,
                  scenes=["CornellBox-Original.obj", "bun_zipper.ply", "sphere:100000"]),
    "check": dict(width=128, height=128, random=1 << 14, rounds=0, threads=[2], naive_budget=float("inf"),
                  scenes=["bun_zipper_res2.ply"]),
}
WORKLOADS = ["camera", "shadow", "bounce", "random"]


def scene_list(args, mode):
    """Scene specs: --scenes, else the mode's, else every mesh of the scene folder + PROCEDURAL."""
    sdir = common.scenes_dir(args.scenes_dir)
    if args.scenes:
        wanted = common.split_list(args.scenes)
    elif mode["scenes"] is not None:
        wanted = list(mode["scenes"])
    else:
        files = common.mesh_files(sdir)
        if not files:
            log(f"NOTE: {sdir} is absent or empty: skipping the shared meshes, running procedural scenes only")
        wanted = files + PROCEDURAL
    return common.resolve_scenes(wanted, sdir)


# ------------------------------------------------------------------------------------------------
# workloads

def prepare_scene(ctx, spec):
    mode = ctx["mode"]
    wdir = ctx["work"] / slug(spec)
    wdir.mkdir(parents=True, exist_ok=True)
    rs = ctx["raysift"]
    sc = dict(spec=spec, name=slug(spec), tris=str(wdir / "tris.npy"))
    t0 = time.perf_counter()
    run_proc([rs, "export", spec, "--out", sc["tris"]])
    tris = np.load(sc["tris"], mmap_mode="r")
    sc["triangles"] = int(tris.shape[0])
    v = np.asarray(tris).reshape(-1, 3)
    sc["bounds"] = [v.min(0).tolist(), v.max(0).tolist()] if len(v) else [[0, 0, 0], [0, 0, 0]]
    # coordinate magnitude: what limits the precision of a hit distance
    sc["size"] = float(np.abs(np.array(sc["bounds"])).max() + np.ptp(np.array(sc["bounds"]), axis=0).max())
    del v, tris
    try:
        info = common.run_json([rs, "info", spec, "--json"])[0]
        sc["vertices"] = info.get("vertices")
        sc["scene_bytes"] = info.get("bytes")
    except (ProcError, ValueError) as e:
        log(f"  (raysift info failed: {e})")
    cam = common.frame_camera(spec, sc["bounds"], ctx["peer"], sc["tris"], wdir, ctx["cpus"])
    sc["camera"] = cam
    W, H = mode["width"], mode["height"]
    wl = {}
    cam_rays = wdir / "camera.npy"
    run_proc([rs, "rays", "camera", spec, "--width", W, "--height", H, *common.camera_args(cam), "--out", cam_rays])
    # Camera hits (for the secondary rays) from Embree; the agreement check later compares every
    # tracer with Embree on these very rays.
    cam_hits = wdir / "camera_hits.npy"
    run_proc([ctx["peer"], "--tris", sc["tris"], "--rays", cam_rays, "--out", cam_hits, "--threads",
              len(ctx["cpus"]), "--packet", "16", "--tile", f"{W},{H}"], cpus=ctx["cpus"])
    wl["camera"] = dict(rays=str(cam_rays), occlusion=False, packet=16, tile=(W, H))
    light = common.light_for(spec, sc["bounds"])
    sc["light"] = light
    sh, shm = wdir / "shadow.npy", wdir / "shadow_map.npy"
    run_proc([rs, "rays", "shadow", spec, "--rays", cam_rays, "--hits", cam_hits, "--light", fmt3(light),
              "--out", sh, "--map", shm])
    wl["shadow"] = dict(rays=str(sh), occlusion=True, packet=16, tile=(W, H), map=str(shm))
    bo = wdir / "bounce.npy"
    run_proc([rs, "rays", "bounce", spec, "--rays", cam_rays, "--hits", cam_hits, "--seed", "7", "--out", bo])
    wl["bounce"] = dict(rays=str(bo), occlusion=False, packet=1)
    ra = wdir / "random.npy"
    run_proc([rs, "rays", "random", spec, "--count", mode["random"], "--seed", "11", "--out", ra])
    wl["random"] = dict(rays=str(ra), occlusion=False, packet=1)
    for k, w in wl.items():
        # rows, or pixels of image-shaped camera rays (H, W, 8)
        w["count"] = int(np.prod(np.load(w["rays"], mmap_mode="r").shape[:-1]))
    sc["workloads"] = wl
    sc["camera"]["hit_fraction"] = common.hit_fraction(cam_hits)
    sc["setup_s"] = time.perf_counter() - t0
    return sc, wdir


# ------------------------------------------------------------------------------------------------
# contenders


def contenders_for(ctx, sc, wname, w):
    """Embree configs first (the first is the agreement reference), then raysift's tracers."""
    cs = []
    for n in ctx["threads"]:
        for q in common.EMBREE_QUALITIES:
            cs.append(dict(name=common.embree_name(q, n), kind="embree", quality=q, threads=n))
    cs.sort(key=lambda c: (c["threads"] != min(ctx["threads"]), common.EMBREE_QUALITIES.index(c["quality"])))
    budget = ctx["mode"]["naive_budget"]
    for t in ctx["tracers"]:
        if common.over_budget(t, w["count"], sc["triangles"], budget):
            if wname == "camera":
                log(f"  {t} skipped on {sc['name']}: {w['count']} rays x {sc['triangles']} triangles "
                    f"= {float(w['count']) * sc['triangles']:.2g} ray-triangle tests > budget {budget:.2g}")
            continue
        for n in ctx["threads"]:
            cs.append(dict(name=common.contender_name(t, n), kind="raysift", tracer=t, threads=n))
    return cs


def command(ctx, sc, w, c, out):
    if c["kind"] == "embree":
        cmd = [ctx["peer"], "--tris", sc["tris"], "--rays", w["rays"], "--quality", c["quality"],
               "--threads", c["threads"], "--packet", w["packet"]]
        if w["packet"] == 16:
            cmd += ["--tile", f"{w['tile'][0]},{w['tile'][1]}"]
            if w.get("map"):
                cmd += ["--map", w["map"]]
    else:
        cmd = [ctx["raysift"], "trace", sc["spec"], "--rays", w["rays"], *common.tracer_args(c["tracer"]),
               "--threads", c["threads"], "--pin", "--json"]
    if w["occlusion"]:
        cmd.append("--occlusion")
    if out:
        cmd += ["--out", out]
    return cmd


def run_contender(ctx, sc, w, c, out=None, inproc=None):
    """One process: prepare + trace `inproc` times (--repeat); the last run counts (the earlier
    ones warm the process: page faults, allocator, thread pools), as in a renderer's steady state."""
    cpus = ctx["cpus"][: c["threads"]]
    cmd = command(ctx, sc, w, c, out) + ["--repeat", inproc or ctx["inproc"]]
    j, rss, wall = common.run_json(cmd, cpus=cpus, timeout=ctx["timeout"])
    r = common.report_times(j)
    r.update(peak_rss_bytes=int(rss), wall_s=wall, bytes_per_triangle=j.get("bytes_per_triangle"), raw=j)
    work = common.work_counters(j)
    if work:
        r["work"] = work
    return r


# ------------------------------------------------------------------------------------------------
# agreement


def ray_tri_t(tris, prim, o, d):
    """Möller–Trumbore in float64 with a little slack on the barycentrics: (t, inside)."""
    v = np.asarray(tris[prim], np.float64).reshape(-1, 3, 3)
    e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(all="ignore"):
        inv = 1.0 / det
        s = o - v[:, 0]
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        w = np.einsum("ij,ij->i", d, q) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    eps = 1e-5
    inside = (det != 0) & (u >= -eps) & (w >= -eps) & (u + w <= 1 + eps)
    return t, inside


def agree(ref_path, got_path, occlusion, rays_path, scene_size, tris_path):
    """Compares a contender's hits with Embree's. Returns a dict; 'ok' False on disagreement.

    t agrees when |dt| <= T_REL_TOL * t, or (for hits right next to the ray origin, where float
    positions limit the precision of t) |dt| * |dir| <= T_ABS_POS * scene_size."""
    if occlusion:
        a = np.load(ref_path).astype(bool)
        b = np.load(got_path).astype(bool)
        if a.shape != b.shape:
            return dict(ok=False, n=int(a.size), error=f"shape {b.shape} vs Embree's {a.shape}")
        diff = np.nonzero(a != b)[0]
        n = a.size
        allowed = max(GRAZE_MIN, int(GRAZE_FRAC * n))
        return dict(ok=len(diff) <= allowed, n=int(n), occluded_ref=int(a.sum()), occluded=int(b.sum()),
                    differ=int(len(diff)), allowed=allowed, examples=diff[:10].tolist())
    a = np.load(ref_path)
    b = np.load(got_path)
    if a.shape != b.shape:
        return dict(ok=False, n=int(a.size), error=f"shape {b.shape} vs Embree's {a.shape}")
    n = a.size
    rays = np.load(rays_path, mmap_mode="r")
    rays = rays.reshape(-1, rays.shape[-1])  # camera rays are image-shaped (H, W, 8)
    ha, hb = a["prim"] != MISS, b["prim"] != MISS
    miss_diff = np.nonzero(ha != hb)[0]
    both = np.nonzero(ha & hb)[0]
    ta, tb = a["t"][both].astype(np.float64), b["t"][both].astype(np.float64)
    dlen = np.linalg.norm(np.asarray(rays[both, 3:6], np.float64), axis=1)
    dt = np.abs(ta - tb)
    tol = np.maximum(T_REL_TOL * np.maximum(np.abs(ta), np.abs(tb)), T_ABS_POS * scene_size / np.maximum(dlen, 1e-30))
    t_bad = dt > tol
    same = a["prim"][both] == b["prim"][both]
    other_surface = t_bad & ~same
    t_off = t_bad & same
    # a tie: another primitive at the same t (shared edge or vertex, overlapping triangles); check
    # that the ray really meets the contender's primitive there
    cand = np.nonzero(~same & ~t_bad)[0]
    wrong = np.zeros(len(both), bool)
    if len(cand):
        tris = np.load(tris_path, mmap_mode="r")
        idx = both[cand]
        o = np.asarray(rays[idx, 0:3], np.float64)
        d = np.asarray(rays[idx, 3:6], np.float64)
        t2, inside = ray_tri_t(tris, b["prim"][idx].astype(np.int64), o, d)
        ok2 = inside & (np.abs(t2 - tb[cand]) <= tol[cand])
        wrong[cand[~ok2]] = True
    ties = ~same & ~t_bad & ~wrong
    uv_bad = same & ~t_bad & ((np.abs(a["u"][both] - b["u"][both]) > UV_ABS_TOL)
                              | (np.abs(a["v"][both] - b["v"][both]) > UV_ABS_TOL))
    # A ray grazing an edge may slip between two triangles under one test and not the other: then
    # the miss sets differ, or it hits another surface behind. Only a tiny fraction may do so.
    # (u, v of grazing rays on tiny triangles are ill-conditioned, so these share the budget too;
    # a layout mismatch breaks them on nearly every ray)
    graze = len(miss_diff) + int(t_bad.sum()) + int(wrong.sum()) + int(uv_bad.sum())
    allowed = max(GRAZE_MIN, int(GRAZE_FRAC * n))
    ok = graze <= allowed
    good = ~t_bad
    rel = dt[good] / np.maximum(np.maximum(np.abs(ta[good]), np.abs(tb[good])), 1e-30)
    res = dict(ok=ok, n=int(n), hits_ref=int(ha.sum()), hits=int(hb.sum()), miss_set_differ=int(len(miss_diff)),
               other_surface=int(other_surface.sum()), t_differ=int(t_off.sum()), prim_ties=int(ties.sum()),
               wrong_prim=int(wrong.sum()),
               uv_differ=int(uv_bad.sum()), allowed=allowed, max_rel_t=float(rel.max()) if len(rel) else 0.0)
    bad = np.sort(np.concatenate([miss_diff, both[t_bad], both[uv_bad], both[wrong]]))
    if len(bad):
        ex = []
        for i in bad[:8]:
            ex.append(dict(ray=int(i), ray_data=[float(x) for x in rays[i]],
                           embree=[float(a["t"][i]), int(a["prim"][i]), float(a["u"][i]), float(a["v"][i])],
                           got=[float(b["t"][i]), int(b["prim"][i]), float(b["u"][i]), float(b["v"][i])]))
        res["examples"] = ex
    return res


def describe_agreement(r):
    if "error" in r:
        return r["error"]
    if "occluded_ref" in r:
        return f"{r['differ']} of {r['n']} rays differ (allowed {r['allowed']})"
    return (f"miss set differs on {r['miss_set_differ']}, other surface on {r['other_surface']}, t off on "
            f"{r['t_differ']}, wrong primitive on {r['wrong_prim']}, u/v off on {r['uv_differ']} (allowed {r['allowed']} together), ties {r['prim_ties']}, "
            f"max rel t {r['max_rel_t']:.1e}")


# ------------------------------------------------------------------------------------------------
# the run


def summarize(runs):
    pre = [r["prepare_ms"] for r in runs]
    tr = [r["trace_ms"] for r in runs]
    dyn = [p + t for p, t in zip(pre, tr)]

    def st(x):
        return dict(median=common.median(x), min=float(min(x)), max=float(max(x)),
                    q1=float(np.percentile(x, 25)), q3=float(np.percentile(x, 75)))
    return dict(prepare_ms=st(pre), trace_ms=st(tr), dynamic_ms=st(dyn),
                peak_rss_bytes=int(common.median(r["peak_rss_bytes"] for r in runs)),
                bytes_per_triangle=runs[-1].get("bytes_per_triangle"))


def bench_scene(ctx, spec, results):
    t0 = time.perf_counter()
    log(f"\n=== {spec}")
    try:
        sc, wdir = prepare_scene(ctx, spec)
    except ProcError as e:
        loud(f"could not prepare scene {spec}: {e}")
        results["failures"].append(dict(scene=spec, stage="prepare", error=str(e)))
        return
    cam = sc["camera"]
    log(f"  {sc['triangles']} triangles; camera {cam['how']}, fov {cam['fov']}, "
        f"hit fraction {cam['hit_fraction']:.3f}; workloads made in {sc['setup_s']:.1f} s")
    scene_res = {k: v for k, v in sc.items() if k not in ("workloads",)}
    scene_res["workloads"] = {}
    results["scenes"].append(scene_res)
    for wname in ctx["workloads"]:
        w = sc["workloads"][wname]
        cs = contenders_for(ctx, sc, wname, w)
        wres = dict(rays=w["count"], occlusion=w["occlusion"], embree_packet=w["packet"], contenders={},
                    agreement={})
        scene_res["workloads"][wname] = wres
        for c in cs:
            wres["contenders"][c["name"]] = dict(kind=c["kind"], threads=c["threads"],
                                                 tracer=c.get("tracer", "embree"), quality=c.get("quality"),
                                                 runs=[])
        alive = list(cs)
        ref_out = None
        for rnd in range(ctx["rounds"] + 1):
            warm = rnd == 0
            for c in list(alive):
                if not warm and rnd > c.get("max_rounds", ctx["rounds"]):
                    continue
                out = wdir / f"{wname}__{c['name']}.npy" if warm else None
                try:
                    # the warm-up round only checks the hits: one run per process is enough
                    # (naive has no structure to build: one run per process)
                    r = run_contender(ctx, sc, w, c, out, inproc=1 if warm else c["inproc"])
                except (ProcError, ValueError, KeyError) as e:
                    loud(f"{sc['name']} / {wname} / {c['name']} failed: {e}")
                    results["failures"].append(dict(scene=sc["name"], workload=wname, contender=c["name"],
                                                    stage="warm-up" if warm else f"round {rnd}", error=str(e)))
                    alive.remove(c)
                    wres["contenders"][c["name"]]["error"] = str(e)[:2000]
                    continue
                cres = wres["contenders"][c["name"]]
                if warm:
                    # Runs of a second or more hardly feel process warm-up: one run per process
                    # there (saves time on big scenes); naive has no structure to build.
                    long_run = r["prepare_ms"] + r["trace_ms"] > ctx["long_run_ms"]
                    c["inproc"] = 1 if long_run or common.tracer_base(c.get("tracer", "")) in common.BRUTE_FORCE else ctx["inproc"]
                    cres["inproc"] = c["inproc"]
                    if (r["prepare_ms"] + r["trace_ms"]) / 1e3 > ctx["slow_s"] and ctx["rounds"] > SLOW_ROUNDS:
                        c["max_rounds"] = SLOW_ROUNDS
                        cres["slow"] = True
                        log(f"  {c['name']} on {wname}: {(r['prepare_ms'] + r['trace_ms']) / 1e3:.1f} s per run > "
                            f"{ctx['slow_s']:g} s: measured in {SLOW_ROUNDS} rounds only")
                    cres["warmup"] = {k: v for k, v in r.items() if k != "raw"}
                    cres["json"] = r["raw"]
                    if ref_out is None:
                        if c["kind"] != "embree":
                            loud(f"{sc['name']} / {wname}: no Embree reference ran: {c['name']} unchecked")
                            results["failures"].append(dict(scene=sc["name"], workload=wname, contender=c["name"],
                                                            stage="warm-up", error="no Embree reference"))
                            continue
                        ref_out = out
                        ref_name = c["name"]
                        wres["reference"] = ref_name
                        hf = (r["hits"] / w["count"]) if w["count"] else 0.0
                        wres["hit_fraction"] = hf
                        continue
                    a = agree(ref_out, out, w["occlusion"], w["rays"], sc["size"], sc["tris"])
                    a["vs"] = ref_name
                    wres["agreement"][c["name"]] = a
                    if not a["ok"]:
                        loud(f"DISAGREEMENT: {sc['name']} / {wname}: {c['name']} vs {ref_name}: "
                             f"{describe_agreement(a)}\n!! examples: {json.dumps(a.get('examples', [])[:4])}")
                        results["disagreements"].append(dict(scene=sc["name"], workload=wname,
                                                             contender=c["name"], **a))
                    elif a.get("miss_set_differ", 0) + a.get("other_surface", 0) + a.get("t_differ", 0) + a.get("wrong_prim", 0) + a.get("differ", 0):
                        log(f"  note: {c['name']} vs {ref_name} on {wname}: {describe_agreement(a)}; "
                            f"rays: {[e['ray'] if isinstance(e, dict) else e for e in a.get('examples', [])]}")
                else:
                    cres["runs"].append(dict({k: v for k, v in r.items() if k not in ("raw", "work")}, round=rnd))
        for name, cres in wres["contenders"].items():
            if cres["runs"]:
                cres["summary"] = summarize(cres["runs"])
        common.add_ratios(wres["contenders"])
        line = [f"  {wname:7s} {w['count']:>8d} rays, hit/occluded fraction {wres.get('hit_fraction', float('nan')):.3f}:"]
        for name, cres in wres["contenders"].items():
            s = cres.get("summary")
            if s:
                rt = cres.get("ratio_trace")
                line.append(f"    {name:18s} prepare {s['prepare_ms']['median']:9.2f} ms  trace "
                            f"{s['trace_ms']['median']:9.2f} ms [{s['trace_ms']['min']:.1f}-{s['trace_ms']['max']:.1f}]"
                            f"  {w['count'] / s['trace_ms']['median'] / 1e3:8.2f} Mrays/s"
                            + (f"  trace x{rt['median']:.2f} vs Embree's best per round" if rt and cres["kind"] != "embree" else ""))
            elif ctx["rounds"] == 0 and cres.get("warmup"):
                a = wres["agreement"].get(name)
                line.append(f"    {name:18s} {'reference' if a is None else ('agrees' if a['ok'] else 'DISAGREES')}"
                            + ("" if a is None else f": {describe_agreement(a)}"))
            elif cres.get("error"):
                line.append(f"    {name:18s} FAILED")
        log("\n".join(line))
    scene_res["elapsed_s"] = time.perf_counter() - t0
    if not ctx["keep_work"]:
        shutil.rmtree(wdir, ignore_errors=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="two scenes, fewer rounds (< 5 minutes once built)")
    g.add_argument("--check", action="store_true", help="agreement only on one small scene; exit 1 on disagreement")
    g.add_argument("--report", metavar="RESULTS.json", help="only regenerate BENCHMARKS.generated.md and plots")
    common.add_scene_args(ap, "every mesh of the scene folder + sphere/soup at 100K and 1M (--quick, --check: "
                          "their own)")
    ap.add_argument("--workloads", default=",".join(WORKLOADS), help="subset of camera,shadow,bounce,random")
    ap.add_argument("--tracers", help="raysift tracers to run (default: all that `raysift tracers` lists)")
    ap.add_argument("--threads", help="thread counts, e.g. 1,2 (default: mode's)")
    ap.add_argument("--rounds", type=int, help="measured rounds after the warm-up (default 5; quick 3)")
    ap.add_argument("--inproc", type=int, help="prepare+trace runs inside each process, the last one "
                    "measured (default 2; --check 1)")
    ap.add_argument("--long-run-ms", type=float, default=LONG_RUN_MS, help="a contender whose warm-up run "
                    "(prepare + trace) takes longer is run once per process, measuring a cold process "
                    "(default %(default)s; a huge value keeps --inproc runs for everyone, so that "
                    "fig14.py can compare first and last runs alike)")
    ap.add_argument("--slow", type=float, default=SLOW_RUN_S, help="seconds per run above which a contender is "
                    f"measured in {SLOW_ROUNDS} rounds only (default %(default)s; 0 = never)")
    ap.add_argument("--timeout", type=float, default=600, help="seconds before one contender run is killed")
    ap.add_argument("--raysift", help="raysift binary (default target/release/raysift)")
    ap.add_argument("--peer", help="embree-peer binary (default bench/target/release/embree-peer)")
    ap.add_argument("--no-build", action="store_true", help="do not run cargo build first")
    ap.add_argument("--work", help="scratch folder for rays/hits (default bench/work)")
    ap.add_argument("--keep-work", action="store_true", help="keep the rays and hits files")
    ap.add_argument("--out", help="results JSON (default bench/results/<date>[-quick].json)")
    ap.add_argument("--md", help="Markdown output (default bench/BENCHMARKS.generated.md; "
                    "bench/BENCHMARKS.quick.generated.md for --quick)")
    args = ap.parse_args(argv)

    if args.report:
        res = json.loads(Path(args.report).read_text())
        write_report(res, Path(args.report), Path(args.md or BENCH / "BENCHMARKS.generated.md"))
        return 0

    mode_name = "check" if args.check else "quick" if args.quick else "full"
    mode = dict(MODES[mode_name])
    if args.rounds is not None:
        mode["rounds"] = args.rounds
    started = time.perf_counter()
    if not args.no_build:
        common.build()
    raysift = common.tool_path(args.raysift, common.RAYSIFT_BIN)
    peer = common.tool_path(args.peer, common.PEER_BIN)
    all_cpus = sorted(os.sched_getaffinity(0))
    threads = [int(x) for x in args.threads.split(",")] if args.threads else list(mode["threads"])
    threads = [t for t in threads if t <= len(all_cpus)] or [len(all_cpus)]
    tracers = common.choose_tracers(common.list_tracers(raysift), args.tracers)  # "--tracers=": Embree alone
    ctx = dict(mode=mode, raysift=raysift, peer=peer, cpus=all_cpus, threads=threads, tracers=tracers,
               rounds=mode["rounds"], timeout=args.timeout,
               slow_s=args.slow if args.slow > 0 else float("inf"),
               inproc=args.inproc or (1 if mode_name == "check" else 2), keep_work=args.keep_work, long_run_ms=args.long_run_ms,
               workloads=[w for w in args.workloads.split(",") if w in WORKLOADS],
               work=Path(args.work) if args.work else BENCH / "work" / mode_name)
    ctx["work"].mkdir(parents=True, exist_ok=True)
    meta, now = common.run_meta("run.py", argv, raysift)
    meta.update(mode=mode_name, cpus_used=all_cpus, threads=threads, rounds=mode["rounds"], warmup_rounds=1,
                slow_run_s=ctx["slow_s"], slow_rounds=SLOW_ROUNDS, inproc_runs=ctx["inproc"],
                long_run_ms=ctx["long_run_ms"], camera=[mode["width"], mode["height"]], random_rays=mode["random"],
                naive_budget=mode["naive_budget"], raysift_tracers=tracers, ratio=common.RATIO_DEFINITION,
                tolerances=dict(t_rel=T_REL_TOL, t_abs_pos=T_ABS_POS, uv_abs=UV_ABS_TOL, graze_frac=GRAZE_FRAC,
                                graze_min=GRAZE_MIN))
    results = dict(
        meta=meta,
        scenes=[], disagreements=[], failures=[])
    specs = scene_list(args, mode)
    log(f"mode {mode_name}: {len(specs)} scenes, tracers {tracers}, threads {threads}, rounds {mode['rounds']} "
        f"(+1 warm-up), cpus {all_cpus}, load average {os.getloadavg()[0]:.2f}")
    out = Path(args.out) if args.out else common.results_path(now, "quick" if mode_name == "quick" else "")
    for k, spec in enumerate(specs):
        bench_scene(ctx, spec, results)
        if mode_name != "check":  # partial results survive an interrupted run
            results["meta"]["partial"] = f"{k + 1} of {len(specs)} scenes"
            common.write_json(out, results)
        log(f"  [{k + 1}/{len(specs)} scenes, {(time.perf_counter() - started) / 60:.1f} min elapsed, "
            f"load average {os.getloadavg()[0]:.2f}]")
    results["meta"]["elapsed_s"] = time.perf_counter() - started
    results["meta"]["load_end"] = os.getloadavg()
    emb = None
    for s in results["scenes"]:
        for w in s["workloads"].values():
            for c in w["contenders"].values():
                if c["kind"] == "embree" and c.get("json"):
                    emb = c["json"].get("embree_version")
    results["meta"]["embree_version"] = emb

    ok = not results["disagreements"] and not results["failures"]
    if mode_name != "check":
        results["meta"].pop("partial", None)
        common.write_json(out, results)
        log(f"\nwrote {out}")
        md = args.md or BENCH / ("BENCHMARKS.quick.generated.md" if args.quick else "BENCHMARKS.generated.md")
        write_report(results, out, Path(md))
    n_checks = sum(len(w["agreement"]) for s in results["scenes"] for w in s["workloads"].values())
    n_bad = len(results["disagreements"])
    log(f"\n{len(results['failures'])} failed run(s); {time.perf_counter() - started:.0f} s")
    log(f"agreement: {n_checks - n_bad} passed, {n_bad} failed")
    if not ok:
        loud(f"RUN FAILED: {n_bad} disagreement(s) with Embree, {len(results['failures'])} failed run(s)")
        return 1
    if n_checks == 0:
        loud("no agreement check ran")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
