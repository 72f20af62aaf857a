#!/usr/bin/env python3
"""Reference check of raysift's path tracer against Mitsuba 3 (variant scalar_rgb).

Both render the Cornell box of assets/scenes/CornellBox-Original.obj with raysift's model of it:
the .mtl Kd reflected on both faces of every surface (Mitsuba's `twosided` around `diffuse`),
the ceiling light's Ke emitted from both faces (in Mitsuba two one-sided emitters 0.1 mm apart,
both reflecting the light's Kd), with the same camera (raysift's
convention: vertical fov in degrees, look-at, pixel (i, j) from the top left), the same number
of bounces and a box pixel filter. raysift writes linear radiance to .exr, so no tone mapping
enters the comparison. Wall masks come from casting raysift's pixel-centre camera rays into
Mitsuba's scene (shape -> material). The check: per-channel mean over the image and over each
wall within TOL (2%); a difference image is written for a person to look at.

Usage: python3 bench/mitsuba_check.py [--raysift target/release/raysift] [--size 64]
       [--spp 4096] [--seed 1] [--out docs/mitsuba-check.png]
Needs: pip install mitsuba numpy
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OBJ = os.path.join(ROOT, "assets", "scenes", "CornellBox-Original.obj")
MTL = os.path.join(ROOT, "assets", "scenes", "CornellBox-Original.mtl")
EYE, LOOK, UP, FOV = (0.0, 1.0, 3.4), (0.0, 1.0, 0.0), (0.0, 1.0, 0.0), 40.0
TOL = 0.02


def read_mtl(path):
    mats, cur = {}, None
    for line in open(path):
        w = line.split("#")[0].split()
        if not w:
            continue
        if w[0] == "newmtl":
            cur = w[1]
            mats[cur] = {"Kd": [0.0] * 3, "Ke": [0.0] * 3}
        elif w[0] in ("Kd", "Ke") and cur:
            mats[cur][w[0]] = [float(x) for x in w[1:4]]
    return mats


def split_obj(path, outdir):
    """One OBJ per material (Mitsuba's obj plugin gives one BSDF per file)."""
    verts, groups, mat = [], {}, None
    for line in open(path):
        w = line.split()
        if not w:
            continue
        if w[0] == "v":
            verts.append([float(x) for x in w[1:4]])
        elif w[0] == "usemtl":
            mat = w[1]
        elif w[0] == "f":
            idx = [int(x.split("/")[0]) for x in w[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            for k in range(1, len(idx) - 1):
                groups.setdefault(mat, []).append((idx[0], idx[k], idx[k + 1]))
    files = {}
    for m, tris in groups.items():
        f = os.path.join(outdir, f"{m}.obj")
        with open(f, "w") as o:
            for t in tris:
                for i in t:
                    o.write("v %f %f %f\n" % tuple(verts[i]))
            for k in range(len(tris)):
                o.write("f %d %d %d\n" % (3 * k + 1, 3 * k + 2, 3 * k + 3))
        v = np.array(verts)
        n = sum(np.cross(v[b] - v[a], v[c] - v[a]) for a, b, c in tris)
        files[m] = (f, n)
    return files


def mitsuba_scene(mi, files, mats, size, spp, bounces):
    shapes = {}
    for m, (f, n) in files.items():
        s = {
            "type": "obj",
            "filename": f,
            # raysift's surfaces reflect on both faces; Mitsuba's diffuse BSDF on the front only.
            "bsdf": {"type": "twosided", "bsdf": {
                "type": "diffuse", "reflectance": {"type": "rgb", "value": mats[m]["Kd"]}}},
        }
        if max(mats[m]["Ke"]) > 0:
            s["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": mats[m]["Ke"]}}
            # Mitsuba's area lights emit on the normal's side: make it face down into the box.
            s["flip_normals"] = bool(n[1] > 0)
            # raysift's area lights emit from both faces (render/light.rs): so does this one,
            # as a second copy facing up (it lights the ceiling 1 cm above it).
            # Offset 0.1 mm up so that the two copies are not coplanar.
            back = f[:-4] + "_back.obj"
            with open(f) as src, open(back, "w") as dst:
                for line in src:
                    w = line.split()
                    if w and w[0] == "v":
                        line = "v %f %f %f\n" % (float(w[1]), float(w[2]) + 1e-4, float(w[3]))
                    dst.write(line)
            # The copy reflects like the light (Kd) too: between the light's top and the
            # ceiling 1 cm above it light bounces many times, and raysift's light reflects there.
            shapes[m + "_back"] = dict(s, filename=back, flip_normals=not s["flip_normals"])
        shapes[m] = s
    return mi.load_dict(
        {
            "type": "scene",
            # max_depth 1 = emission only, 2 = direct light: raysift's bounces + 2. No roulette.
            "integrator": {"type": "path", "max_depth": bounces + 2, "rr_depth": 1000},
            "sensor": {
                "type": "perspective",
                "fov": FOV,
                "fov_axis": "y",
                "to_world": mi.ScalarTransform4f().look_at(origin=EYE, target=LOOK, up=UP),
                "film": {
                    "type": "hdrfilm",
                    "width": size,
                    "height": size,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": spp},
            },
            **shapes,
        }
    )


def masks(mi, scene, size):
    """Material per pixel from raysift's camera convention (pixel centres)."""
    eye, look, up = map(np.array, (EYE, LOOK, UP))
    fwd = (look - eye) / np.linalg.norm(look - eye)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    up2 = np.cross(right, fwd)
    tan = np.tan(np.radians(FOV) / 2)
    out = np.full((size, size), "", dtype=object)
    for j in range(size):
        for i in range(size):
            x = (2 * (i + 0.5) / size - 1) * tan
            y = (1 - 2 * (j + 0.5) / size) * tan
            d = x * right + y * up2 + fwd
            d /= np.linalg.norm(d)
            si = scene.ray_intersect(mi.Ray3f(mi.ScalarPoint3f(*eye), mi.ScalarVector3f(*d)))
            if si.is_valid():
                out[j, i] = si.shape.id()
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--raysift", default=os.path.join(ROOT, "target", "release", "raysift"))
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=1, help="seed of both renderers")
    ap.add_argument("--bounces", type=int, default=5)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "mitsuba-check.png"))
    a = ap.parse_args()
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    tmp = tempfile.mkdtemp(prefix="mitsuba-check-")
    rs_exr = os.path.join(tmp, "raysift.exr")
    cmd = [
        a.raysift, "render", OBJ, "--integrator", "path", "--spp", str(a.spp),
        "--bounces", str(a.bounces), "--width", str(a.size), "--height", str(a.size),
        "--eye", ",".join(map(str, EYE)), "--look", ",".join(map(str, LOOK)),
        "--fov", str(FOV), "--seed", str(a.seed), "--out", rs_exr, "--json", "--quiet",
    ]
    rep = json.loads(subprocess.run(cmd, check=True, capture_output=True).stdout)
    print(f"raysift: {rep['rays']} rays, {rep['trace_ms']:.0f} ms of tracing")
    ours = np.array(mi.Bitmap(rs_exr), dtype=np.float64)[..., :3]

    mats = read_mtl(MTL)
    files = split_obj(OBJ, tmp)
    scene = mitsuba_scene(mi, files, mats, a.size, a.spp, a.bounces)
    ref = np.array(mi.render(scene, seed=a.seed), dtype=np.float64)[..., :3]
    mi.Bitmap(ref.astype(np.float32)).write(os.path.join(tmp, "mitsuba.exr"))
    # Mitsuba merges meshes of equal BSDFs into one shape: the masks come from a copy of the
    # scene whose materials are all different.
    unique = {m: {"Kd": [0.01 * (k + 1)] * 3, "Ke": mats[m]["Ke"]} for k, m in enumerate(mats)}
    mask = masks(mi, mitsuba_scene(mi, files, unique, a.size, 1, 0), a.size)

    ok = True
    rows = [("image", np.ones(mask.shape, bool))]
    rows += [(m, mask == m) for m in ("leftWall", "rightWall", "backWall", "floor", "ceiling")]
    print(f"{'region':10} {'pixels':>6}  {'raysift RGB':>26}  {'mitsuba RGB':>26}  rel. diff")
    for name, m in rows:
        if m.sum() == 0:
            print(f"{name}: no pixels (camera mismatch?)")
            ok = False
            continue
        o, r = ours[m].mean(0), ref[m].mean(0)
        rel = np.abs(o - r) / np.maximum(r, 1e-6)
        good = bool((rel <= TOL).all())
        ok &= good
        fmt = lambda v: " ".join(f"{x:8.4f}" for x in v)
        print(f"{name:10} {int(m.sum()):6d}  {fmt(o)}  {fmt(r)}  "
              + " ".join(f"{x * 100:5.2f}%" for x in rel) + ("" if good else "  FAIL"))

    # Difference image: raysift | Mitsuba | |difference| x 4, tone-mapped alike, for a person.
    def tm(x):
        x = np.clip(x, 0, 1)  # the sRGB transfer function, as raysift's PNGs
        x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
        return (x * 255 + 0.5).astype(np.uint8)

    diff = np.abs(ours - ref) * 4
    strip = np.concatenate([tm(ours), tm(ref), tm(diff)], axis=1)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    mi.Bitmap(strip, pixel_format=mi.Bitmap.PixelFormat.RGB).write(a.out)
    print(f"wrote {a.out} (raysift | Mitsuba | 4 x |difference|)")
    print("mitsuba check: " + ("1 passed, 0 failed" if ok else "0 passed, 1 failed"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
