#!/usr/bin/env python3
"""Bias and noise of bench/mitsuba_check.py's comparison: K seeds of both renderers.

For each region (image, walls) prints the relative difference of the K-seed means (raysift's
over Mitsuba's) and the standard error of each renderer's K-seed mean, per channel, and each
run's red-channel difference. Seeds 100 .. 100 + K - 1, the same for both.

Usage: python3 bench/mitsuba_noise.py [--raysift target/release/raysift] [--size 64]
       [--spp 512] [--seeds 6] [--no-mis]
Needs: pip install mitsuba numpy
"""

import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_check as mc  # noqa: E402

REGIONS = ["image", "leftWall", "rightWall", "backWall", "floor", "ceiling"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--raysift", default=os.path.join(mc.ROOT, "target", "release", "raysift"))
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=512)
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--bounces", type=int, default=5)
    ap.add_argument("--no-mis", action="store_true", help="raysift with plain next-event estimation")
    a = ap.parse_args()
    if a.seeds < 2:
        ap.error("--seeds must be at least 2 (a standard error needs two runs)")
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    tmp = tempfile.mkdtemp(prefix="mitsuba-noise-")
    mats = mc.read_mtl(mc.MTL)
    files = mc.split_obj(mc.OBJ, tmp)
    unique = {m: {"Kd": [0.01 * (k + 1)] * 3, "Ke": mats[m]["Ke"]} for k, m in enumerate(mats)}
    mask = mc.masks(mi, mc.mitsuba_scene(mi, files, unique, a.size, 1, 0), a.size)

    def regions(img):
        return np.array([img[np.ones(mask.shape, bool) if r == "image" else mask == r].mean(0)
                         for r in REGIONS])

    ours, ref = [], []
    for k in range(a.seeds):
        seed = 100 + k
        exr = os.path.join(tmp, f"raysift{k}.exr")
        cmd = [a.raysift, "render", mc.OBJ, "--integrator", "path", "--spp", str(a.spp),
               "--bounces", str(a.bounces), "--width", str(a.size), "--height", str(a.size),
               "--eye", ",".join(map(str, mc.EYE)), "--look", ",".join(map(str, mc.LOOK)),
               "--fov", str(mc.FOV), "--seed", str(seed), "--out", exr, "--json", "--quiet"]
        subprocess.run(cmd + (["--no-mis"] if a.no_mis else []), check=True, capture_output=True)
        ours.append(regions(np.array(mi.Bitmap(exr), dtype=np.float64)[..., :3]))
        scene = mc.mitsuba_scene(mi, files, mats, a.size, a.spp, a.bounces)
        ref.append(regions(np.array(mi.render(scene, seed=seed), dtype=np.float64)[..., :3]))
    ours, ref = np.array(ours), np.array(ref)
    fmt = lambda v: " ".join(f"{x:6.2f}" for x in v)
    for k in range(a.seeds):
        print(f"seed {100 + k}: red difference per region % " + fmt((ours[k] / ref[k] - 1)[:, 0] * 100))
    print(f"{'region':10} {'difference % (RGB)':>22}  {'raysift s.e. %':>22}  {'mitsuba s.e. %':>22}")
    for i, r in enumerate(REGIONS):
        o, m = ours[:, i].mean(0), ref[:, i].mean(0)
        se = lambda x, mu: x.std(0, ddof=1) / np.sqrt(a.seeds) / mu * 100
        print(f"{r:10} {fmt((o / m - 1) * 100)}  {fmt(se(ours[:, i], o))}  {fmt(se(ref[:, i], m))}")


if __name__ == "__main__":
    main()
