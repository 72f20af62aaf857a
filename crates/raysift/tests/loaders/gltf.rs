//! glTF and GLB loader cases.

use super::*;

pub(crate) fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Buffer: the unit square's 4 positions (48 bytes) then u16 indices 0 1 2 0 2 3 (12 bytes).
pub(crate) fn gltf_buffer() -> Vec<u8> {
    let mut b = Vec::new();
    for p in SQ {
        for c in p {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

/// A document: node 0 (translation 10,0,0) has child node 1 (scale 2) with mesh 0, whose
/// primitives are the indexed quad (TRIANGLES), the same 4 positions as a non-indexed
/// TRIANGLE_STRIP, and a POINTS primitive (skipped). `buffer` is the buffer object's JSON.
pub(crate) fn gltf_json(buffer: &str) -> String {
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [
    {{"name": "parent", "translation": [10, 0, 0], "children": [1]}},
    {{"name": "child", "scale": [2, 2, 2], "mesh": 0}}
  ],
  "meshes": [{{"name": "square", "primitives": [
    {{"attributes": {{"POSITION": 0}}, "indices": 1}},
    {{"attributes": {{"POSITION": 0}}, "mode": 5}},
    {{"attributes": {{"POSITION": 0}}, "mode": 0}}
  ]}}],
  "buffers": [{buffer}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]
}}"#
    )
}

pub(crate) fn check_gltf(s: &Scene) {
    let w = |i: usize| sq(i) * 2.0 + v(10., 0., 0.);
    assert_eq!(s.meshes().len(), 1);
    assert_eq!(s.meshes()[0].name, "child/square");
    assert_eq!(s.len(), 4);
    assert_eq!(tri(s, 0), [w(0), w(1), w(2)]);
    assert_eq!(tri(s, 1), [w(0), w(2), w(3)]);
    // Strip: (0, 1, 2), then (1, 3, 2) for the odd triangle (spec order).
    assert_eq!(tri(s, 2), [w(0), w(1), w(2)]);
    assert_eq!(tri(s, 3), [w(1), w(3), w(2)]);
}

pub(crate) fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

#[test]
fn gltf_embedded_external_and_glb() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let buf = gltf_buffer();
    let embedded = gltf_json(&format!(
        r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
        base64(&buf)
    ));
    check_gltf(&load(write(d, "emb.gltf", embedded.as_bytes())).unwrap());
    check_gltf(&load(write(d, "emb.gltf.gz", &gzip(embedded.as_bytes()))).unwrap());
    write(d, "square data.bin", &buf);
    let external = gltf_json(r#"{"byteLength": 60, "uri": "square%20data.bin"}"#);
    check_gltf(&load(write(d, "ext.gltf", external.as_bytes())).unwrap());
    let g = glb(&gltf_json(r#"{"byteLength": 60}"#), &buf);
    check_gltf(&load(write(d, "bin.glb", &g)).unwrap());
}

#[test]
fn gltf_instances_and_all_scenes_without_default() {
    let dir = tempfile::tempdir().unwrap();
    // No "scene": both scenes are loaded in order; the mesh is instanced twice.
    let buf = gltf_buffer();
    let json = gltf_json(&format!(
        r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
        base64(&buf)
    ))
    .replace(r#""scene": 0,"#, "")
    .replace(
        r#""scenes": [{"nodes": [0]}]"#,
        r#""scenes": [{"nodes": [0]}, {"nodes": [2]}]"#,
    )
    .replace(
        r#"{"name": "child", "scale": [2, 2, 2], "mesh": 0}"#,
        r#"{"name": "child", "scale": [2, 2, 2], "mesh": 0},
    {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1], "mesh": 0}"#,
    );
    let s = load(write(dir.path(), "two.gltf", json.as_bytes())).unwrap();
    assert_eq!(s.meshes().len(), 2);
    assert_eq!(s.len(), 8);
    assert_eq!(s.meshes()[1].name, "node 2/square");
    assert_eq!(
        tri(&s, 4),
        [
            sq(0) + v(0., 0., 5.),
            sq(1) + v(0., 0., 5.),
            sq(2) + v(0., 0., 5.)
        ]
    );
}

#[test]
fn gltf_malformed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let buf = gltf_buffer();
    let emb = |b: &[u8]| {
        gltf_json(&format!(
            r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
            base64(b)
        ))
    };
    // Index 2 of the quad (u16 at byte 52) set to 9: out of range.
    let mut bad = buf.clone();
    bad[52..54].copy_from_slice(&9u16.to_le_bytes());
    let e = load_err(
        d,
        "range.gltf",
        emb(&bad).as_bytes(),
        "accessors[1], element 2 (buffer 0, byte 52)",
    );
    assert!(e.contains("out of range"), "{e}");
    // Vertex 1's y (bytes 16..20) set to NaN.
    let mut nan = buf.clone();
    nan[16..20].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = load_err(
        d,
        "nan.gltf",
        emb(&nan).as_bytes(),
        "accessors[0], element 1 (buffer 0, byte 12)",
    );
    assert!(e.contains("non-finite"), "{e}");
    // Accessor running past its view.
    let over = emb(&buf).replace(r#""count": 6"#, r#""count": 7"#);
    let e = load_err(d, "over.gltf", over.as_bytes(), "accessors[1]");
    assert!(e.contains("do not fit"), "{e}");
    let zero = emb(&buf).replace(r#""count": 6"#, r#""count": 0"#);
    // count 0 is invalid glTF (minimum 1), though the gltf crate does not check it.
    let e = load_err(d, "zero.gltf", zero.as_bytes(), "accessors[1]");
    assert!(e.contains("count is 0"), "{e}");
    let e = load_err(
        d,
        "syntax.gltf",
        b"{\n  \"asset\": {\"version\": \"2.0\"},\n  oops\n}",
        "line 3",
    );
    assert!(e.contains("JSON"), "{e}");
    load_err(d, "empty.gltf", b"", "byte 0");
    let badpos = emb(&buf).replace(
        r#""POSITION": 0}, "indices""#,
        r#""POSITION": 7}, "indices""#,
    );
    load_err(
        d,
        "attr.gltf",
        badpos.as_bytes(),
        "meshes[0].primitives[0].attributes",
    );
    load_err(
        d,
        "missing.gltf",
        gltf_json(r#"{"byteLength": 60, "uri": "nope.bin"}"#).as_bytes(),
        "buffers[0]",
    );
    load_err(
        d,
        "pct.gltf",
        gltf_json(r#"{"byteLength": 60, "uri": "a%ff.bin"}"#).as_bytes(),
        "buffers[0].uri",
    );
    let cyc = emb(&buf).replace(r#""mesh": 0}"#, r#""mesh": 0, "children": [0]}"#);
    let e = load_err(d, "cycle.gltf", cyc.as_bytes(), "nodes[0]");
    assert!(e.contains("reached twice"), "{e}");
    // Two parents sharing a child (a DAG, not a tree) is rejected the same way.
    let dag = emb(&buf).replace(r#""children": [1]"#, r#""children": [1, 1]"#);
    load_err(d, "dag.gltf", dag.as_bytes(), "nodes[1]");
    // GLB: truncated file, and a header shorter than itself.
    let g = glb(&gltf_json(r#"{"byteLength": 60}"#), &buf);
    let e = load_err(d, "trunc.glb", &g[..g.len() - 10], "byte 8");
    assert!(e.contains("truncated"), "{e}");
    load_err(d, "tiny.glb", b"glTF\x02\0\0\0\x04\0\0\0", "byte 8");
    load_err(d, "hdr.glb", b"glTF\x02\0", "byte 6");
    let mut chunk = g.clone();
    chunk[12..16].copy_from_slice(&100000u32.to_le_bytes());
    load_err(d, "chunk.glb", &chunk, "byte 12");
}

#[test]
fn gltf_sparse_accessors() {
    // Buffer: the usual 60 bytes, then sparse index u8 [2] (padded to 4), then one VEC3 value.
    let mut buf = gltf_buffer();
    buf.extend_from_slice(&[2, 0, 0, 0]);
    for c in [5f32, 5., 0.] {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    let sparse = |view: &str| {
        format!(
            r#"{{{view}"componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [5, 5, 0],
      "sparse": {{"count": 1, "indices": {{"bufferView": 2, "componentType": 5121}}, "values": {{"bufferView": 3}}}}}}"#
        )
    };
    let make = |acc0: String| {
        gltf_json(&format!(
            r#"{{"byteLength": 76, "uri": "data:application/octet-stream;base64,{}"}}"#,
            base64(&buf)
        ))
        .replace(
            r#"{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}"#,
            &acc0,
        )
        .replace(
            r#"{"buffer": 0, "byteOffset": 48, "byteLength": 12}"#,
            r#"{"buffer": 0, "byteOffset": 48, "byteLength": 12},
    {"buffer": 0, "byteOffset": 60, "byteLength": 1},
    {"buffer": 0, "byteOffset": 64, "byteLength": 12}"#,
        )
    };
    let w = |p: Vec3| p * 2.0 + v(10., 0., 0.);
    let dir = tempfile::tempdir().unwrap();
    // Base values from bufferView 0, element 2 replaced by (5, 5, 0).
    let s = load(write(
        dir.path(),
        "sparse.gltf",
        make(sparse(r#""bufferView": 0, "#)).as_bytes(),
    ))
    .unwrap();
    assert_eq!(tri(&s, 0), [w(sq(0)), w(sq(1)), w(v(5., 5., 0.))]);
    assert_eq!(tri(&s, 1), [w(sq(0)), w(v(5., 5., 0.)), w(sq(3))]);
    // No bufferView: base values are zeros (the triangles are degenerate, so check the mesh).
    let s = load(write(dir.path(), "zeros.gltf", make(sparse("")).as_bytes())).unwrap();
    let p = &s.meshes()[0].positions;
    assert_eq!(p[..4], [Vec3::ZERO, Vec3::ZERO, v(5., 5., 0.), Vec3::ZERO]);
    // A huge count with no bufferView behind it: an error, not a huge allocation.
    let huge = make(sparse("")).replace(
        r#""count": 4, "type": "VEC3""#,
        r#""count": 4000000000, "type": "VEC3""#,
    );
    let e = load_err(dir.path(), "huge.gltf", huge.as_bytes(), "accessors[0]");
    assert!(e.contains("implausibly large"), "{e}");
    // A sparse index past the accessor's count.
    let mut bad = make(sparse(r#""bufferView": 0, "#));
    bad = bad.replace(&base64(&buf), &{
        let mut b = buf.clone();
        b[60] = 9;
        base64(&b)
    });
    let e = load_err(
        dir.path(),
        "badsparse.gltf",
        bad.as_bytes(),
        "accessors[0], sparse index 0 (buffer 0, byte 60)",
    );
    assert!(e.contains("out of range"), "{e}");
}

#[test]
fn gltf_deep_hierarchy_does_not_overflow_the_stack() {
    // A chain of 200,000 nodes: recursion would overflow the stack (an abort, not an error).
    let n = 200_000;
    let buf = gltf_buffer();
    let mut nodes = String::new();
    for i in 0..n {
        if i + 1 < n {
            nodes.push_str(&format!(r#"{{"children": [{}]}},"#, i + 1));
        } else {
            nodes.push_str(r#"{"translation": [0, 0, 1], "mesh": 0}"#);
        }
    }
    let json = gltf_json(&format!(
        r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
        base64(&buf)
    ))
    .replace(
        r#"{"name": "parent", "translation": [10, 0, 0], "children": [1]},
    {"name": "child", "scale": [2, 2, 2], "mesh": 0}"#,
        &nodes,
    );
    let dir = tempfile::tempdir().unwrap();
    let s = load(write(dir.path(), "deep.gltf", json.as_bytes())).unwrap();
    assert_eq!(s.len(), 4);
    assert_eq!(tri(&s, 0)[1], v(1., 0., 1.));
}

/// glTF materials: baseColorFactor → diffuse, emissiveFactor → emission, metallic 1 with
/// roughness 0 → mirror; per primitive range of the node's mesh.
#[test]
fn gltf_materials() {
    let dir = tempfile::tempdir().unwrap();
    let buffer = format!(
        r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
        base64(&gltf_buffer())
    );
    let json = gltf_json(&buffer)
        .replace(
            r#"{"attributes": {"POSITION": 0}, "indices": 1}"#,
            r#"{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}"#,
        )
        .replace(
            r#"{"attributes": {"POSITION": 0}, "mode": 5}"#,
            r#"{"attributes": {"POSITION": 0}, "mode": 5, "material": 1}"#,
        )
        .replace(
            r#""buffers""#,
            r#""materials": [
    {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 1.0]}, "emissiveFactor": [2, 3, 4]},
    {"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.0}}
  ],
  "buffers""#,
        );
    let s = load(write(dir.path(), "m.gltf", json.as_bytes())).unwrap();
    check_gltf(&s);
    let m0 = *s.material(0).unwrap();
    assert_eq!(m0.diffuse, v(0.5, 0.25, 1.0));
    assert_eq!(m0.emission, v(2., 3., 4.));
    assert!(!m0.mirror);
    assert_eq!(*s.material(1).unwrap(), m0);
    let m2 = *s.material(2).unwrap();
    assert!(m2.mirror && m2.diffuse == Vec3::ONE && m2.emission == Vec3::ZERO);
    assert_eq!(*s.material(3).unwrap(), m2);
}
