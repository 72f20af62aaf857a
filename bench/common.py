"""What every script in bench/ shares (issue #12, item 7: one benchmark library).

* the scene folder (`--scenes-dir`, `$RAYSIFT_SCENES`, default `../shared/scenes`) and the scene
  list: names in that folder, paths, or generators (`sphere:N`, `soup:N`, `cornell`, `tile:K:SCENE`);
* camera presets (Sponza's inside camera), automatic framing, and the camera as CLI arguments;
* the `raysift` and `embree-peer` binaries: building them, finding them, asking raysift its tracers;
* running a command (pinned, timed, peak RSS) and reading the JSON it prints;
* reading raysift's JSON report: times, and the work counters through `work_counters` alone;
* contender names (`bvh-2t`, `embree-low-1t`, ...);
* THE ratio to Embree (`ratio_to_embree`, defined in bench/README.md, "Ratio to Embree"), and the
  per-round paired ratio it is made of (`paired_ratio`), which the scripts use for every other
  ratio too (DACRT ÷ BVH);
* the machine and version facts written into every results JSON.

Scripts import it as `import common` (python3 puts bench/ on the path when it runs bench/X.py).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import platform
import re
import shlex
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
RESULTS = BENCH / "results"


def log(*a):
    print(*a, flush=True)


def loud(msg):
    bar = "!" * 78
    print(f"\n{bar}\n!! {msg}\n{bar}\n", flush=True, file=sys.stderr)


# ------------------------------------------------------------------------------------------------
# scenes

SCENES_ENV = "RAYSIFT_SCENES"
DEFAULT_SCENES_DIR = ROOT.parent / "shared" / "scenes"
SCENE_EXTS = (".ply", ".obj", ".off", ".gltf", ".glb")
GENERATORS = ("sphere", "soup", "cornell", "tile")
# What a run uses when a shared mesh is absent (a fresh clone without ../shared): a scene of the
# same size class, so that --check and --quick still run.
FALLBACKS = {"bun_zipper.ply": "sphere:65536", "bun_zipper_res2.ply": "sphere:20000",
             "CornellBox-Original.obj": "cornell"}


def add_scene_args(ap: argparse.ArgumentParser, default_help: str):
    """--scenes and --scenes-dir, the same in every script."""
    ap.add_argument("--scenes", help="comma-separated scenes: names in the scene folder, paths, or generators "
                    f"(sphere:N, soup:N, cornell, tile:K:SCENE); default: {default_help}")
    ap.add_argument("--scenes-dir", help=f"folder of shared meshes (default ${SCENES_ENV}, else ../shared/scenes "
                    "next to the repository)")


def scenes_dir(arg=None) -> Path:
    """The scene folder: --scenes-dir, else $RAYSIFT_SCENES, else ../shared/scenes."""
    if arg:
        return Path(arg)
    if os.environ.get(SCENES_ENV):
        return Path(os.environ[SCENES_ENV])
    return DEFAULT_SCENES_DIR


def is_generator(spec: str) -> bool:
    head = spec.split(":", 1)[0]
    return head in GENERATORS and (":" in spec or head == "cornell")


def mesh_files(sdir: Path) -> list[str]:
    """Every mesh in the scene folder, smallest file first (file size stands in for triangle count,
    so that a run cut short still covers most scenes)."""
    if not sdir.is_dir():
        return []
    return [p.name for p in sorted(sdir.iterdir(), key=lambda p: p.stat().st_size)
            if p.is_file() and p.name.lower().removesuffix(".gz").endswith(SCENE_EXTS)]


def split_list(s):
    return [x.strip() for x in (s or "").split(",") if x.strip()]


def resolve_scenes(wanted, sdir: Path) -> list[str]:
    """Scene specs raysift takes: generators as they are, files as absolute paths (looked up as
    paths, then in the scene folder; an absent one is replaced by its FALLBACKS entry or skipped,
    with a note)."""
    specs = []
    for w in wanted:
        if is_generator(w):
            specs.append(w)
        elif Path(w).is_file():
            specs.append(str(Path(w).resolve()))
        elif (sdir / w).is_file():
            specs.append(str((sdir / w).resolve()))
        elif w in FALLBACKS:
            log(f"NOTE: {w} not found in {sdir}: using {FALLBACKS[w]} instead")
            specs.append(FALLBACKS[w])
        else:
            log(f"NOTE: scene {w} not found in {sdir}: skipped")
    return specs


def scene_file_name(spec: str) -> str:
    """The file name of a file spec (what presets are keyed by); a generator spec as it is."""
    return Path(spec).name if "/" in spec else spec


def slug(spec: str) -> str:
    """A short name for a scene spec, safe as a file name (results and tables use it)."""
    if spec.startswith("tile:") and spec.count(":") >= 2:
        _, k, f = spec.split(":", 2)
        return f"tile{k}x{k}_" + slug(f)
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", scene_file_name(spec))


# ------------------------------------------------------------------------------------------------
# cameras

MISS = 0xFFFFFFFF
FRAME_HIT_TARGET = 0.7  # automatic framing: narrow the view until this fraction of a preview hits
FRAME_FOVS = (45.0, 38.0, 32.0, 27.0, 23.0, 19.0, 16.0, 13.0, 11.0, 9.0)
_SPONZA_CAMERA = dict(eye=(-13.0, 2.5, 0.0), look=(10.0, 4.5, 0.0), up=(0.0, 1.0, 0.0), fov=60.0)
# Interiors need the camera inside; everything else is framed (frame_camera) or left to raysift's
# default framing (from +z, bounds filling the view).
CAMERA_PRESETS = {"sponza.obj.gz": _SPONZA_CAMERA, "sponza.obj": _SPONZA_CAMERA}
LIGHT_PRESETS = {"sponza.obj.gz": (0.0, 12.0, 0.0), "sponza.obj": (0.0, 12.0, 0.0)}  # under the open roof


def camera_preset(spec: str):
    """The preset camera of a scene (dict eye, look, up, fov, how='preset'), or None."""
    o = CAMERA_PRESETS.get(scene_file_name(spec))
    if o is None:
        return None
    return dict(eye=list(o["eye"]), look=list(o["look"]), up=list(o["up"]), fov=o["fov"], how="preset")


def fmt3(v):
    return ",".join(f"{x:.9g}" for x in v)


def camera_args(cam) -> list[str]:
    """A camera dict (eye, look, up, fov; any may be absent) as the options of `raysift rays camera`,
    `render` and `animate`; None: no options (raysift's default framing)."""
    if not cam:
        return []
    out = []
    for k in ("eye", "look", "up"):
        if cam.get(k) is not None:
            out.append(f"--{k}={fmt3(cam[k])}")  # '=': a first coordinate may be negative
    if cam.get("fov") is not None:
        out += ["--fov", f"{cam['fov']:g}"]
    return out


def camera_basis(eye, look, up):
    f = np.asarray(look, float) - np.asarray(eye, float)
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return r, u, f


def numpy_camera_rays(eye, look, up, fov, w, h):
    """The same pinhole convention as `raysift rays camera` (ordered j*W+i), for framing previews."""
    r, u, f = camera_basis(eye, look, up)
    tan = math.tan(math.radians(fov) / 2)
    j, i = np.mgrid[0:h, 0:w]
    x = (2 * (i + 0.5) / w - 1) * tan * w / h
    y = (1 - 2 * (j + 0.5) / h) * tan
    d = x[..., None] * r + y[..., None] * u + f
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    rays = np.zeros((w * h, 8), np.float32)
    rays[:, 0:3] = eye
    rays[:, 3:6] = d.reshape(-1, 3)
    rays[:, 7] = np.inf
    return rays


def default_eye(lo, hi, aspect=1.0):
    """raysift's default framing (Camera::framing at 45 degrees): from +z, bounds filling the view."""
    c = (lo + hi) / 2
    half = np.maximum((hi - lo) / 2, 1e-6)
    tv = math.tan(math.radians(45.0) / 2)
    th = tv * aspect
    dist = half[2] + max(half[0] / th, half[1] / tv) * 1.02
    return c + np.array([0.0, 0.0, dist]), c


def hit_fraction(hits_path):
    h = np.load(hits_path)
    return float((h["prim"] != np.uint32(MISS)).mean()) if len(h) else 0.0


def frame_camera(spec, bounds, peer, tris, wdir: Path, cpus):
    """The camera of a scene: its preset, or raysift's default eye with the field of view narrowed
    about the centre of the bounds until >= 70% of a 64x64 preview hits (Embree, through `peer` on
    the exported triangles `tris`, traces the previews). A scene covering 20% of the image would
    mostly measure misses."""
    preset = camera_preset(spec)
    if preset:
        return preset
    lo, hi = np.array(bounds[0]), np.array(bounds[1])
    eye, look = default_eye(lo, hi)
    best = None
    for fov in FRAME_FOVS:
        rp, hp = wdir / "preview.npy", wdir / "preview_hits.npy"
        np.save(rp, numpy_camera_rays(eye, look, (0, 1, 0), fov, 64, 64))
        run_proc([peer, "--tris", tris, "--rays", rp, "--out", hp, "--threads", "1"], cpus=cpus[:1])
        f = hit_fraction(hp)
        if best is None or f > best[1] + 1e-9 or f >= FRAME_HIT_TARGET:
            best = (fov, f)
        if f >= FRAME_HIT_TARGET:
            break
    return dict(eye=eye.tolist(), look=look.tolist(), up=[0.0, 1.0, 0.0], fov=best[0],
                how=f"auto (preview hit fraction {best[1]:.3f})")


def light_for(spec, bounds):
    """The point light of the shadow workload: a preset, else above, to the right and in front (the
    camera side), so that most visible surfaces face it and the scene's relief casts shadows."""
    if scene_file_name(spec) in LIGHT_PRESETS:
        return list(LIGHT_PRESETS[scene_file_name(spec)])
    lo, hi = np.array(bounds[0]), np.array(bounds[1])
    c, ext = (lo + hi) / 2, np.maximum(hi - lo, 1e-6)
    return (c + ext * np.array([0.6, 1.5, 1.2])).tolist()


# ------------------------------------------------------------------------------------------------
# processes


class ProcError(RuntimeError):
    pass


def run_proc(cmd, cpus=None, timeout=None, cwd=ROOT):
    """Runs cmd (pinned to `cpus` when given); returns (stdout, stderr, peak_rss_bytes, wall_s).
    Raises ProcError on a non-zero exit or a timeout."""
    def pin():
        if cpus:
            os.sched_setaffinity(0, cpus)

    with tempfile.TemporaryFile() as out_f, tempfile.TemporaryFile() as err_f:
        t0 = time.perf_counter()
        p = subprocess.Popen([str(c) for c in cmd], stdout=out_f, stderr=err_f, preexec_fn=pin, cwd=cwd)
        killer = None
        if timeout:
            killer = threading.Timer(timeout, p.kill)
            killer.start()
        _, status, ru = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        if killer:
            killer.cancel()
        out_f.seek(0)
        err_f.seek(0)
        out = out_f.read().decode(errors="replace")
        err = err_f.read().decode(errors="replace")
    if p.returncode != 0:
        what = "timed out" if p.returncode == -9 and timeout and wall >= timeout else f"exit {p.returncode}"
        raise ProcError(f"{what}: {shlex.join(str(c) for c in cmd)}\n{err.strip()[-2000:]}")
    return out, err, ru.ru_maxrss * 1024, wall


def last_json(out):
    """The last line of `out` that is a JSON object (the tools print one JSON line, maybe after
    other output)."""
    for line in reversed(out.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise ValueError(f"no JSON object in output: {out[-500:]!r}")


def run_json(cmd, cpus=None, timeout=None):
    """Runs cmd and returns (its JSON object, peak_rss_bytes, wall_s)."""
    out, _, rss, wall = run_proc(cmd, cpus=cpus, timeout=timeout)
    return last_json(out), rss, wall


# ------------------------------------------------------------------------------------------------
# the binaries

RAYSIFT_BIN = ROOT / "target" / "release" / "raysift"
PEER_BIN = BENCH / "target" / "release" / "embree-peer"


def build(raysift=True, peer=True):
    """cargo build --release of the binaries the script needs (a no-op when they are up to date)."""
    if raysift:
        log("building raysift (cargo build --release -p raysift-cli) ...")
        subprocess.run(["cargo", "build", "--release", "-q", "-p", "raysift-cli"], cwd=ROOT, check=True)
    if peer:
        log("building embree-peer (cargo build --release --manifest-path bench/Cargo.toml) ...")
        subprocess.run(["cargo", "build", "--release", "-q", "--manifest-path", str(BENCH / "Cargo.toml")],
                       cwd=ROOT, check=True)


def tool_path(given, default: Path) -> Path:
    p = Path(given) if given else default
    if not p.exists():
        sys.exit(f"missing {p}: build it (see bench/README.md) or drop --no-build")
    return p


def _tracer_names(j):
    """Tracer names from `raysift tracers --json`: a list of names or of objects with a "name", bare
    or under "tracers"."""
    if isinstance(j, dict):
        j = j.get("tracers", j)
    if isinstance(j, dict):  # {"bvh": {...}, ...}
        return list(j)
    return [t if isinstance(t, str) else t["name"] for t in j]


def list_tracers(raysift) -> list[str]:
    """The registered tracers, in the order raysift lists them: `raysift tracers --json` where the
    CLI has it, else today's text output (one tracer a line, its name first)."""
    try:
        out = run_proc([raysift, "tracers", "--json"])[0]
        return _tracer_names(json.loads(out))
    except (ProcError, ValueError, KeyError, TypeError):
        out = run_proc([raysift, "tracers"])[0]
        return [line.split()[0] for line in out.splitlines() if line.strip()]


def choose_tracers(available, wanted):
    """--tracers: None = every registered tracer; "a,b" = those (exits on an unknown name); "" = none
    (Embree alone, in run.py). A contender may carry options: `dacrt:top_below=0+leaf_pairs=9` is
    dacrt with those `--opt`s (see tracer_args)."""
    if wanted is None:
        return list(available)
    tracers = split_list(wanted)
    unknown = [t for t in tracers if tracer_base(t) not in available]
    if unknown:
        sys.exit(f"unknown tracer(s) {unknown}; `raysift tracers` lists {available}")
    return tracers


# Tracers without a structure, which test every triangle against every ray: run only where
# rays x triangles stays under a budget (about a second per run here at 1e8).
BRUTE_FORCE = {"naive"}
NAIVE_BUDGET = 1e8


def tracer_base(contender):
    """The registered tracer of a contender: `dacrt:top_below=0` -> `dacrt`."""
    return contender.partition(":")[0]


def tracer_args(contender):
    """raysift's arguments for a contender: `dacrt:top_below=0+leaf_pairs=9` -> --tracer dacrt
    --opt top_below=0 --opt leaf_pairs=9."""
    name, _, opts = contender.partition(":")
    args = ["--tracer", name]
    for o in filter(None, opts.split("+")):
        args += ["--opt", o]
    return args


def over_budget(tracer, rays, triangles, budget=NAIVE_BUDGET):
    return tracer_base(tracer) in BRUTE_FORCE and float(rays) * triangles > budget


# ------------------------------------------------------------------------------------------------
# raysift's (and embree-peer's) JSON report

# stats entries that are not work counters (times, sizes, inputs)
_NOT_WORK = {"prepare_ms", "trace_ms", "rays", "peak_bytes", "threads"}


def report_times(j):
    """The times of one `trace --json` report (raysift's or embree-peer's): prepare and trace ms of
    the process's last run, the lists of every run (--repeat), and the hit count."""
    pre = j.get("prepare_ms_runs") or [j["prepare_ms"]]
    tr = j.get("trace_ms_runs") or [j["trace_ms"]]
    return dict(prepare_ms=float(pre[-1]), trace_ms=float(tr[-1]), hits=int(j["hits"]),
                prepare_ms_runs=[float(x) for x in pre], trace_ms_runs=[float(x) for x in tr])


def work_counters(j, tracer=None) -> dict:
    """THE accessor for the work counters (ray-box, ray-triangle, triangle-box tests, nodes, ...) of
    a raysift JSON report, or of one entry of `render --json`'s per_bounce. Accepts today's shape
    (flat in `stats`, next to its times) and the typed report's (under `stats.work`, either flat or
    one object per tracer name). Returns {name: number}; {} when the report has none."""
    st = j.get("stats") or {}
    src = st.get("work", st)
    if isinstance(src, dict):
        t = tracer or j.get("tracer")
        if isinstance(src.get(t), dict):
            src = src[t]
    else:
        src = {}
    return {k: v for k, v in src.items()
            if k not in _NOT_WORK and isinstance(v, (int, float)) and not isinstance(v, bool)}


# ------------------------------------------------------------------------------------------------
# contenders

EMBREE_QUALITIES = ("medium", "low")  # the first is the agreement reference


def contender_name(base, threads):
    """`bvh-2t`, `embree-low-1t`: a raysift tracer's name or `embree-<quality>`, and its threads."""
    return f"{base}-{threads}t"


def embree_name(quality, threads):
    return contender_name(f"embree-{quality}", threads)


def split_name(name):
    """(base, threads) of a contender name; threads 0 when the name has none."""
    base, _, t = name.rpartition("-")
    if base and t.endswith("t") and t[:-1].isdigit():
        return base, int(t[:-1])
    return name, 0


def order_names(names):
    """Embree configurations first, then raysift's tracers; by name, then threads."""
    def key(n):
        base, t = split_name(n)
        return (not base.startswith("embree"), base, t)
    return sorted(names, key=key)


# ------------------------------------------------------------------------------------------------
# ratios (bench/README.md, "Ratio to Embree")

METRICS = ("trace", "prepare", "frame")
RATIO_DEFINITION = ("median over measured rounds of (contender's ms in the round / fastest Embree configuration's "
                    "ms in the same round, same thread count), process's last run; trace and frame = prepare + "
                    "trace (bench/README.md)")


def _value(run, metric, k):
    pre = run.get("prepare_ms_runs") or [run["prepare_ms"]]
    tr = run.get("trace_ms_runs") or [run["trace_ms"]]
    if metric == "trace":
        return float(tr[k])
    if metric == "prepare":
        return float(pre[k])
    if metric == "frame":
        return float(pre[k]) + float(tr[k])
    raise ValueError(f"metric {metric!r} not in {METRICS}")


def round_values(contender, metric, run="last"):
    """{round: ms} of a contender's measured rounds (trace, prepare, or frame = prepare + trace), of
    the process's last run (warm, the default) or its first (cold). Rounds are numbered from 1 in
    the order they ran; a run records its round as "round" (older results: its position)."""
    k = -1 if run == "last" else 0
    return {r.get("round", i + 1): _value(r, metric, k) for i, r in enumerate(contender.get("runs") or [])}


def median(x):
    x = list(x)
    return float(statistics.median(x)) if x else float("nan")


def paired_ratio(num: dict, den: dict):
    """Median over the rounds both have of num[round] / den[round], with min, max and the round
    count; None when they share no round. (Contenders alternate within a round, so a round's two
    numbers share the machine's state: a per-round ratio, not a ratio of medians.)"""
    rounds = sorted(set(num) & set(den))
    if not rounds:
        return None
    r = [num[k] / max(den[k], 1e-9) for k in rounds]
    return dict(median=median(r), min=float(min(r)), max=float(max(r)), rounds=len(rounds))


def embree_best(contenders, threads, metric, run="last"):
    """{round: (ms, name)}: the fastest Embree configuration of each round at `threads`, over the
    rounds in which every configuration that was measured at all ran."""
    emb = {n: round_values(c, metric, run) for n, c in contenders.items()
           if c.get("kind") == "embree" and c.get("threads") == threads and c.get("runs")}
    if not emb:
        return {}
    rounds = set.intersection(*(set(v) for v in emb.values()))
    return {k: min((v[k], n) for n, v in emb.items()) for k in sorted(rounds)}


def ratio_to_embree(contenders, name, metric="trace", run="last", embree_metric=None):
    """THE ratio to Embree of contender `name` (a key of `contenders`, one workload's contenders as
    run.py stores them): the median over measured rounds of its `metric` in that round ÷ the fastest
    Embree configuration's `embree_metric` (default: the same metric) in that same round, at the same
    thread count. metric "trace" is the trace-only ratio, "frame" (prepare + trace) the dynamic-frame
    ratio; fig14.py's stretch target compares DACRT's frame with Embree's trace
    (metric="frame", embree_metric="trace"). Returns dict(median, min, max, rounds, vs, best), vs =
    the configuration fastest in most rounds, best = {configuration: rounds it was fastest}; None
    when no round pairs up."""
    c = contenders.get(name)
    if not c:
        return None
    own = round_values(c, metric, run)
    best = embree_best(contenders, c.get("threads"), embree_metric or metric, run)
    r = paired_ratio(own, {k: v for k, (v, _) in best.items()})
    if r is None:
        return None
    wins = Counter(best[k][1] for k in best if k in own)
    r["vs"] = wins.most_common(1)[0][0]
    r["best"] = dict(wins)
    return r


def embree_best_ms(contenders, threads, metric, run="last"):
    """Median over rounds of the fastest Embree configuration's time (what the ratio divides by)."""
    return median(v for v, _ in embree_best(contenders, threads, metric, run).values())


def add_ratios(contenders, run="last"):
    """Sets ratio_trace and ratio_dynamic (frame) on every measured contender of one workload."""
    for name, c in contenders.items():
        if c.get("runs"):
            c["ratio_trace"] = ratio_to_embree(contenders, name, "trace", run)
            c["ratio_dynamic"] = ratio_to_embree(contenders, name, "frame", run)


# ------------------------------------------------------------------------------------------------
# facts for the results JSON


def cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def git_commit():
    try:
        c = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True).stdout.strip()
        return c + ("+dirty" if dirty else "")
    except OSError:
        return "unknown"


def versions():
    v = dict(python=platform.python_version())
    try:
        from importlib.metadata import version
        for pkg in ("numpy", "embreex", "matplotlib"):
            try:
                v[pkg] = version(pkg)
            except Exception:  # noqa: BLE001  (not installed)
                pass
    except ImportError:
        pass
    return v


def run_meta(script, argv, raysift=None):
    """The facts every results JSON starts with: when, the command, the machine, the commit, the
    versions (and the raysift binary's, when given)."""
    now = dt.datetime.now(dt.timezone.utc)
    m = dict(date=now.strftime("%Y-%m-%d %H:%M UTC"),
             command=f"python3 bench/{script} " + shlex.join(sys.argv[1:] if argv is None else [str(a) for a in argv]),
             cpu_model=cpu_model(), logical_cpus=os.cpu_count(), cpus_used=sorted(os.sched_getaffinity(0)),
             raysift_commit=git_commit(), kernel=platform.release(), versions=versions(), load=os.getloadavg())
    if raysift:
        m["raysift_binary"] = str(raysift)
        m["raysift_version"] = run_proc([raysift, "--version"])[0].strip()
    return m, now


def results_path(now, suffix=""):
    """bench/results/<date>[-suffix].json"""
    return RESULTS / (now.strftime("%Y-%m-%d") + (f"-{suffix}" if suffix else "") + ".json")


def write_json(path: Path, obj):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=1))
