#!/usr/bin/env python3
"""Release-build tables of the renderer issue (#13), every tracer, contenders alternated.

  table4     RTRPS Table 4's ray counts on the bunny: 256², one square light, 16×16 shadow
             samples per primary hit (distribution ray tracing; shadow rays = 256 × hits).
  ir         instant radiosity at 1K/10K/40K VPLs (1 and 3 photon bounces) on the Cornell box
             and Sponza: rays and Mrays/s per phase.
  brainstem  per-frame animation, prepare and trace of BrainStem.glb's clip, 60 frames.
  embree     the Table 4 bunny and the instant-radiosity Cornell box and Sponza (10K VPLs), each
             recorded once (`render --record-rays`, bvh) and its camera, photon and shadow rays
             traced by the Embree peer (`--packet 1` and `--packet 16`) beside the raysift
             renders; Embree's answers are checked against the recorded ones.

Each part runs `--rounds` rounds; within a round every tracer runs once, in rotated order, and
the tables give medians over rounds. Prints Markdown tables (and the commands) to stdout.

Usage: python3 bench/renderers.py [--raysift target/release/raysift] [--shared ../shared]
       [--rounds 3] [--parts table4,ir,brainstem,embree] [--peer bench/target/release/embree-peer]
       [--embree-work 0,1,2,3] [--tracers bvh,rtrps]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TRACERS = ["bvh", "dacrt", "dacrt5d", "kdtree", "rtt", "rtrps"]


def run(cmd):
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def rounds(n, tracers, job):
    """{tracer: [result per round]}, the order rotated each round."""
    res = {t: [] for t in tracers}
    for r in range(n):
        order = tracers[r % len(tracers):] + tracers[: r % len(tracers)]
        for t in order:
            res[t].append(job(t))
            print(f"  round {r + 1} {t}", file=sys.stderr)
    return res


def med(xs):
    return statistics.median(xs)


def passes(v):
    return {p["pass"]: p for p in v["passes"]}


def table4(a):
    bunny = os.path.join(a.shared, "scenes", "bun_zipper.ply")
    base = [a.raysift, "render", bunny, "--integrator", "distribution", "--width", "256",
            "--height", "256", "--light-samples", "16", "--area-light", "-0.017,0.35,0.0,0.05,1",
            "--json", "--quiet", "--out", "/tmp/renderers-bunny.png"]
    print("```\n" + " ".join(base[1:]) + " --tracer T\n```\n")
    res = rounds(a.rounds, TRACERS, lambda t: run(base + ["--tracer", t]))
    print("| tracer | primary rays | primary hits | shadow rays | = 256 × hits | prepare ms | primary ms "
          "| shadow ms | shadow Mrays/s |")
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|")
    for t in TRACERS:
        vs = res[t]
        p0 = passes(vs[0])
        hits, sh = vs[0]["phase_hits"]["primary"], p0["shadow"]["rays"]
        shadow_ms = med([passes(v)["shadow"]["trace_ms"] for v in vs])
        print(f"| {t} | {p0['primary']['rays']:,} | {hits:,} | {sh:,} | "
              f"{'yes' if sh == 256 * hits else 'NO'} | {med([v['prepare_ms'] for v in vs]):.0f} | "
              f"{med([passes(v)['primary']['trace_ms'] for v in vs]):.1f} | {shadow_ms:.0f} | "
              f"{sh / shadow_ms / 1e3:.2f} |")
    print()


def ir(a):
    scenes = [("Cornell box", os.path.join(ROOT, "assets", "scenes", "CornellBox-Original.obj"), []),
              ("Sponza", os.path.join(a.shared, "scenes", "sponza.obj.gz"),
               ["--area-light", "0,12,0,2,2000"])]
    for name, path, extra in scenes:
        for vpls in (1000, 10000, 40000):
            for b in (1, 3):
                base = [a.raysift, "render", path, "--integrator", "instant-radiosity", "--width",
                        "128", "--height", "128", "--vpls", str(vpls), "--vpl-bounces", str(b),
                        "--vpl-subset", "64", "--json", "--quiet", "--out",
                        "/tmp/renderers-ir.png"] + extra
                tr = (["naive"] if name == "Cornell box" else []) + TRACERS
                res = rounds(a.rounds, tr, lambda t: run(base + ["--tracer", t]))
                v0 = res[tr[0]][0]
                p0 = passes(v0)
                rays = {k: p0[k]["rays"] if k in p0 else 0
                        for k in ("photon emission", "photon bounces", "camera", "shadow")}
                print(f"**{name}, {vpls:,} VPLs asked / {v0['vpls']:,} made, {b} photon "
                      f"bounce{'s' if b > 1 else ''}**: rays per phase " +
                      ", ".join(f"{k} {r:,}" for k, r in rays.items()) +
                      f" (`{' '.join(base[1:])} --tracer T`)\n")
                print("| tracer | prepare ms | " + " | ".join(f"{k} Mrays/s" for k in rays) +
                      " | total trace ms |")
                print("|---|---:|" + "---:|" * len(rays) + "---:|")
                for t in tr:
                    vs = res[t]
                    cells = []
                    for k, r in rays.items():
                        if r == 0:
                            cells.append("—")
                            continue
                        ms = med([passes(v)[k]["trace_ms"] for v in vs])
                        cells.append(f"{r / max(ms, 1e-6) / 1e3:.2f}")
                    print(f"| {t} | {med([v['prepare_ms'] for v in vs]):.0f} | " + " | ".join(cells) +
                          f" | {med([v['trace_ms'] for v in vs]):.0f} |")
                print()


def brainstem(a):
    glb = os.path.join(a.shared, "scenes", "animated", "BrainStem.glb")
    base = [a.raysift, "animate", glb, "--frames", "60", "--width", "320", "--height", "240",
            "--no-images", "--json", "--quiet"]
    print("```\n" + " ".join(base[1:]) + " --tracer T [--opt update=U]\n```\n")
    configs = {"bvh update=rebuild": ["--tracer", "bvh", "--opt", "update=rebuild"],
               "bvh update=refit": ["--tracer", "bvh", "--opt", "update=refit"],
               "bvh update=auto": ["--tracer", "bvh", "--opt", "update=auto"]}
    configs.update({t: ["--tracer", t] for t in TRACERS if t != "bvh"})
    names = list(configs)
    res = rounds(a.rounds, names, lambda t: run(base + configs[t]))
    print("| tracer | animation ms | prepare ms | trace ms | prepare + trace ms |")
    print("|---|---:|---:|---:|---:|")
    for t in names:
        vs = res[t]
        u, p, tr = (med([v[k] for v in vs]) for k in ("mean_update_ms", "mean_prepare_ms",
                                                       "mean_trace_ms"))
        print(f"| {t} | {u:.1f} | {p:.1f} | {tr:.1f} | {med([v['mean_prepare_ms'] + v['mean_trace_ms'] for v in vs]):.1f} |")
    print()


def embree(a):
    import numpy as np

    bunny = os.path.join(a.shared, "scenes", "bun_zipper.ply")
    cornell = os.path.join(ROOT, "assets", "scenes", "CornellBox-Original.obj")
    sponza = os.path.join(a.shared, "scenes", "sponza.obj.gz")
    ir = ["--integrator", "instant-radiosity", "--width", "128", "--height", "128", "--vpls",
          "10000", "--vpl-bounces", "1", "--vpl-subset", "64"]
    brainstem = os.path.join(a.shared, "scenes", "animated", "BrainStem.glb")
    medium = [("embree packet 1", 1, "medium"), ("embree packet 16", 16, "medium")]
    # (title, scene, render arguments, raysift tracers, Embree contenders: name, packet, quality)
    work = [("Table 4, bunny 256², 16×16 light samples", bunny,
             ["--integrator", "distribution", "--width", "256", "--height", "256",
              "--light-samples", "16", "--area-light", "-0.017,0.35,0.0,0.05,1"],
             ["bvh", "dacrt", "kdtree", "rtt", "rtrps"], medium),
            ("instant radiosity, Cornell box, 10K VPLs", cornell, ir,
             ["naive", "bvh", "dacrt", "kdtree"], medium),
            ("instant radiosity, Sponza, 10K VPLs", sponza,
             ir + ["--area-light", "0,12,0,2,2000"], ["bvh", "dacrt", "kdtree"], medium),
            ("BrainStem, one frame (the glTF's pose as loaded), 320×240 with shadow rays",
             brainstem, ["--width", "320", "--height", "240"], ["bvh", "dacrt"],
             [("embree low packet 16", 16, "low"), ("embree packet 16", 16, "medium")])]
    threads = str(os.cpu_count() or 1)
    for k, (name, scene, args, tracers, embrees) in enumerate(work):
        if a.embree_work is not None and k not in a.embree_work:
            continue
        if a.tracers:
            tracers = [t for t in tracers if t in a.tracers]
        d = f"/tmp/renderers-embree-{k}"
        base = [a.raysift, "render", scene] + args + ["--json", "--quiet", "--out",
                                                      f"/tmp/renderers-embree-{k}.png"]
        subprocess.run(base + ["--tracer", "bvh", "--record-rays", d], check=True,
                       capture_output=True)
        tris = f"{d}/tris.npy"
        subprocess.run([a.raysift, "export", scene, "--out", tris], check=True,
                       capture_output=True)
        calls = json.load(open(f"{d}/calls.json"))
        rays = {"intersect": np.load(f"{d}/intersect-rays.npy"),
                "occluded": np.load(f"{d}/occluded-rays.npy")}
        answer = {"intersect": np.load(f"{d}/intersect-hits.npy")["prim"],
                  "occluded": np.load(f"{d}/occluded.npy")}
        # Phases: camera rays (a pinhole layout), photons (the other closest-hit calls), shadow.
        phase_of = lambda c: ("shadow" if c["kind"] == "occluded" else
                              "camera" if c["layout"].startswith("pinhole") else "photon")
        phases = {}
        for c in calls:
            kind, rows = c["kind"], slice(c["start"], c["start"] + c["rays"])
            phases.setdefault(phase_of(c), (kind, []))[1].append(rows)
        files = {}
        for ph, (kind, rows) in phases.items():
            idx = np.concatenate([np.arange(r.start, r.stop) for r in rows])
            f = f"{d}/{ph}-rays.npy"
            np.save(f, rays[kind][idx])
            files[ph] = (kind, f, answer[kind][idx])
        width = args[args.index("--width") + 1]
        height = args[args.index("--height") + 1]

        def peer(ph, packet, quality):
            kind, f, _ = files[ph]
            cmd = [a.peer, "--tris", tris, "--rays", f, "--packet", str(packet), "--threads",
                   threads, "--repeat", "3", "--quality", quality, "--out",
                   f"{d}/{ph}-embree{packet}-{quality}.npy"]
            if kind == "occluded":
                cmd.append("--occlusion")
            if ph == "camera" and packet == 16:
                cmd += ["--tile", f"{width},{height}"]
            return run(cmd)

        embree_of = {e[0]: e[1:] for e in embrees}
        contenders = tracers + list(embree_of)

        def job(c):
            if c in tracers:
                return run(base + ["--tracer", c])
            packet, quality = embree_of[c]
            return {ph: peer(ph, packet, quality) for ph in files
                    if packet == 1 or ph != "photon"}

        res = rounds(a.rounds, contenders, job)
        print(f"**{name}** (`{' '.join(base[1:])} --tracer T`; Embree: the recorded rays, "
              f"`embree-peer --threads {threads} --repeat 3`, camera 16-packets over 4×4 tiles, "
              "shadow 16-packets of 16 consecutive rays; prepare = Embree's build)\n")
        order = [ph for ph in ("camera", "photon", "shadow") if ph in files]
        for ph in order:
            kind, _, want = files[ph]
            bad = []
            for e, (packet, quality) in embree_of.items():
                out = f"{d}/{ph}-embree{packet}-{quality}.npy"
                if not os.path.exists(out):
                    continue
                got = np.load(out)
                got = got["prim"] if kind == "intersect" else got
                bad.append(f"{e}: {int((got != want).sum()):,}")
            print(f"- {ph}: {len(want):,} rays; Embree answers differing from raysift's "
                  f"({'primitive' if kind == 'intersect' else 'occlusion'}): " + ", ".join(bad))
        print()
        print("| contender | prepare ms | " +
              " | ".join(f"{ph} ms | {ph} Mrays/s" for ph in order) + " | prepare + trace ms |")
        print("|---|---:|" + "---:|---:|" * len(order) + "---:|")
        raysift_phase = {"camera": ["primary", "camera"], "photon": ["photon emission",
                                                                   "photon bounces"],
                         "shadow": ["shadow"]}
        for c in contenders:
            cells, total = [], 0.0
            if c in tracers:
                prep = med([v["prepare_ms"] for v in res[c]])
            else:
                prep = med([v[order[-1]]["prepare_ms"] for v in res[c]])
            total += prep
            for ph in order:
                n = len(files[ph][2])
                if c in tracers:
                    ms = med([sum(passes(v)[p]["trace_ms"] for p in raysift_phase[ph]
                                  if p in passes(v)) for v in res[c]])
                elif ph in res[c][0]:
                    ms = med([v[ph]["trace_ms"] for v in res[c]])
                else:
                    cells += ["—", "—"]
                    continue
                total += ms
                cells += [f"{ms:.1f}", f"{n / max(ms, 1e-6) / 1e3:.2f}"]
            print(f"| {c} | {prep:.1f} | " + " | ".join(cells) + f" | {total:.1f} |")
        print()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--raysift", default=os.path.join(ROOT, "target", "release", "raysift"))
    ap.add_argument("--shared", default=os.path.join(ROOT, "..", "shared"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--parts", default="table4,ir,brainstem,embree")
    ap.add_argument("--embree-work", type=lambda v: [int(x) for x in v.split(",")],
                    help="embree part: only these workloads (0 Table 4, 1 Cornell IR, "
                         "2 Sponza IR, 3 BrainStem)")
    ap.add_argument("--tracers", type=lambda v: v.split(","),
                    help="embree part: only these raysift tracers")
    ap.add_argument("--peer", default=os.path.join(ROOT, "bench", "target", "release",
                                                   "embree-peer"))
    a = ap.parse_args()
    parts = {"table4": table4, "ir": ir, "brainstem": brainstem, "embree": embree}
    for p in a.parts.split(","):
        if p not in parts:
            ap.error(f"--parts: unknown part {p!r} (table4, ir, brainstem, embree)")
    for p in a.parts.split(","):
        print(f"### {p}\n")
        sys.stdout.flush()
        parts[p](a)
        sys.stdout.flush()


if __name__ == "__main__":
    main()
