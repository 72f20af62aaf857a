#!/usr/bin/env python3
"""Writes the initial seed inputs of every fuzz target into fuzz/seeds/<target>/.

The committed corpus (fuzz/corpus/<target>/) is what `cargo fuzz cmin` kept of these seeds plus
what the fuzzing runs found (docs/fuzzing.md). Run from the repository root:

    python3 fuzz/make_seeds.py

Uses numpy for the .npy seeds (so they are numpy's own files) and, when it exists,
../shared/scenes for two small real meshes.
"""
import base64
import gzip
import io
import json
import os
import struct
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "fuzz", "seeds")
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "scenes")

SQ = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]


def put(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def obj_seeds():
    yield "quad_crlf_neg.obj", "mtllib m.mtl\r\nusemtl red\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\ng quad\r\nf -4 -3 -2 -1\r\n"
    yield "corners.obj", ("v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 3 0\nv -1 1 0 1\nvt 0 0\nvt 1 0\nvn 0 0 1\n"
                          "o poly\nf 1/1/1 2/2/1 3/1/1 4/2/1 5/1/1\nf 1//1 3//1 5//1\nf 2/1 4/2 5/1\n")
    yield "groups_lines.obj", ("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0\nv 0 0 1\ng a\nf 1 2 3\ng b\nf 1 2 4\n"
                               "p 1\nl 1 2 3\ng a\nf 1 3 4\n# comment\n")
    p = os.path.join(SHARED, "CornellBox-Original.obj")
    if os.path.exists(p):
        yield "cornell.obj", open(p, "rb").read()


def ply_ascii():
    return ("ply\r\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty float confidence\n"
            "property float x\nproperty double y\nproperty float z\nproperty uchar intensity\n"
            "element face 2\nproperty list uchar int vertex_index\nelement edge 1\nproperty int vertex1\n"
            "property int vertex2\nend_header\n"
            "0.5 0 0 0 7\n0.5 1 0 0 7\n0.5 1 1 0 7\n0.5 0 1 0 7\n4 0 1 2 3\n3 3 2 1\n0 1\n")


def ply_binary(be):
    fmt = "binary_big_endian" if be else "binary_little_endian"
    e = ">" if be else "<"
    out = (f"ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float confidence\nproperty double x\n"
           "property float y\nproperty float z\nproperty uchar intensity\nelement face 2\n"
           "property ushort flags\nproperty list uint short vertex_indices\nelement edge 1\n"
           "property list uchar int ends\nend_header\n").encode()
    for p in SQ:
        out += struct.pack(e + "fdffB", 0.5, p[0], p[1], p[2], 7)
    out += struct.pack(e + "HI4h", 9, 4, 0, 1, 2, 3)
    out += struct.pack(e + "HI3h", 9, 3, 3, 2, 1)
    out += struct.pack(e + "B2i", 2, 0, 1)
    return out


def ply_seeds():
    yield "ascii.ply", ply_ascii()
    yield "le.ply", ply_binary(False)
    yield "be.ply", ply_binary(True)
    # Other index types and a uint8 count with a double vertex.
    out = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
           "property double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n").encode()
    for p in SQ[:3]:
        out += struct.pack("<3d", *p)
    out += struct.pack("<B3I", 3, 0, 1, 2)
    yield "double_uint.ply", out
    p = os.path.join(SHARED, "bun_zipper_res4.ply")
    if os.path.exists(p):
        # The real bunny's header and first lines, with the counts cut to match.
        lines = open(p, "rb").read().split(b"\n")
        head = lines[: lines.index(b"end_header") + 1]
        head = [b"element vertex 12" if l.startswith(b"element vertex") else
                b"element face 4" if l.startswith(b"element face") else l for l in head]
        body = lines[len(head): len(head) + 12]
        body += [b"3 0 1 2", b"3 3 4 5", b"3 6 7 8", b"3 9 10 11"]
        yield "bunny_head.ply", b"\n".join(head + body) + b"\n"


def off_seeds():
    yield "comments.off", "OFF\n# a comment\n\n4 2 0\n0 0 0\n1 0 0 # trailing\n1 1 0\n0 1 0\n4 0 1 2 3\n3 3 2 1\n"
    yield "coff_crlf.off", ("COFF 4 1 0\r\n0 0 0 255 0 0 255\r\n1 0 0 255 0 0 255\r\n1 1 0 0 0 0 255\r\n"
                            "0 1 0 0 0 0 255\r\n4 0 1 2 3 0.5 0.5 0.5\r\n")
    yield "noff.off", "NOFF\n3 1\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n"


def gltf_buffer():
    b = b"".join(struct.pack("<3f", *p) for p in SQ)
    b += struct.pack("<6H", 0, 1, 2, 0, 2, 3)
    return b


def gltf_doc(buffer):
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "parent", "translation": [10, 0, 0], "children": [1]},
            {"name": "child", "scale": [2, 2, 2], "mesh": 0},
        ],
        "meshes": [{"name": "square", "primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1},
            {"attributes": {"POSITION": 0}, "mode": 5},
            {"attributes": {"POSITION": 0}, "mode": 6},
            {"attributes": {"POSITION": 0}, "mode": 0},
        ]}],
        "buffers": [buffer],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
    }


def glb(doc, bin_):
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    bin_ += b"\0" * (-len(bin_) % 4)
    total = 12 + 8 + len(j) + 8 + len(bin_)
    return (b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(j)) + b"JSON" + j
            + struct.pack("<I", len(bin_)) + b"BIN\0" + bin_)


def gltf_seeds():
    buf = gltf_buffer()
    uri = "data:application/octet-stream;base64," + base64.b64encode(buf).decode()
    yield "embedded.gltf", json.dumps(gltf_doc({"byteLength": 60, "uri": uri}), indent=1)
    yield "bin.glb", glb(gltf_doc({"byteLength": 60}), buf)
    # Sparse accessor (with and without a base bufferView), byteStride, a matrix node.
    sb = buf + bytes([2, 0, 0, 0]) + struct.pack("<3f", 5, 5, 0)
    d = gltf_doc({"byteLength": 76, "uri": "data:application/octet-stream;base64,"
                  + base64.b64encode(sb).decode()})
    d["bufferViews"] += [{"buffer": 0, "byteOffset": 60, "byteLength": 1},
                         {"buffer": 0, "byteOffset": 64, "byteLength": 12}]
    d["bufferViews"][0]["byteStride"] = 12
    d["accessors"][0]["sparse"] = {"count": 1, "indices": {"bufferView": 2, "componentType": 5121},
                                   "values": {"bufferView": 3}}
    d["nodes"].append({"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1], "mesh": 0})
    d["scenes"].append({"nodes": [2]})
    del d["scene"]
    yield "sparse.gltf", json.dumps(d)
    d2 = json.loads(json.dumps(d))
    del d2["accessors"][0]["bufferView"]
    yield "sparse_zeros.gltf", json.dumps(d2)


def gzip_seeds():
    # First byte: 0 obj, 1 ply, 2 off, 3 gltf, 4 glb (see fuzz/src/lib.rs).
    picks = [(0, obj_seeds), (1, ply_seeds), (2, off_seeds)]
    for k, gen in picks:
        name, data = next(iter(gen()))
        if isinstance(data, str):
            data = data.encode()
        yield f"{name}.gz", bytes([k]) + gzip.compress(data, mtime=0)
    seeds = dict(gltf_seeds())
    yield "embedded.gltf.gz", bytes([3]) + gzip.compress(seeds["embedded.gltf"].encode(), mtime=0)
    yield "bin.glb.gz", bytes([4]) + gzip.compress(seeds["bin.glb"], mtime=0)
    # Two members, as `cat a.gz b.gz` gives.
    text = ply_ascii().encode()
    yield "two_members.ply.gz", bytes([1]) + gzip.compress(text[:100], mtime=0) + gzip.compress(text[100:], mtime=0)


def npy_seeds():
    import numpy as np
    def save(a):
        f = io.BytesIO()
        np.save(f, a)
        return f.getvalue()
    rays8 = np.array([[0, 0, 5, 0, 0, -1, 0, np.inf], [1, 2, 3, 0.5, 0, 0, 0.25, 9]], dtype="<f4")
    yield "rays_n8.npy", save(rays8)
    yield "rays_n6_be.npy", save(rays8[:, :6].astype(">f4"))
    img = np.zeros((2, 3, 8), dtype="<f4")
    img[..., 2] = 4
    img[..., 3] = np.linspace(-0.1, 0.1, 6).reshape(2, 3)
    img[..., 5] = -1
    img[..., 7] = np.inf
    yield "rays_image.npy", save(img)
    yield "rays_fortran.npy", save(np.asfortranarray(rays8))
    hits = np.zeros(3, dtype=[("t", "<f4"), ("prim", "<u4"), ("u", "<f4"), ("v", "<f4")])
    hits["t"] = [np.inf, 2.5, 1]
    hits["prim"] = [4294967295, 7, 0]
    yield "hits.npy", save(hits)
    yield "occlusion.npy", save(np.array([1, 0, 1], dtype="u1"))
    f = io.BytesIO()
    np.lib.format.write_array(f, rays8, version=(2, 0))
    yield "rays_v2.npy", f.getvalue()


def main():
    for target, gen in [("obj", obj_seeds), ("ply", ply_seeds), ("off", off_seeds),
                        ("gltf", gltf_seeds), ("gzip", gzip_seeds), ("npy", npy_seeds)]:
        for name, data in gen():
            put(target, name, data)
    print("seeds written to", OUT, file=sys.stderr)


if __name__ == "__main__":
    main()
