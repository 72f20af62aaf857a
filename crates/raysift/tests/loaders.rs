//! Scene loaders on small files written to a temp dir: counts, positions, fan order, primitive
//! ids, gzip, PLY binary LE/BE, glTF node hierarchies and GLB, and malformed inputs whose error
//! must name the file and the place (line, element or byte).

use glam::Vec3;
use raysift::scene::load;
use raysift::Scene;
use std::io::Write;
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn tri(s: &Scene, i: usize) -> [Vec3; 3] {
    s.triangles().get(i)
}

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Loads `bytes` as `name`; returns the error message, asserting it names the file and `place`.
fn load_err(dir: &Path, name: &str, bytes: &[u8], place: &str) -> String {
    let p = write(dir, name, bytes);
    let e = match load(&p) {
        Ok(s) => panic!("{name}: expected an error, loaded {} triangles", s.len()),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains(&p.display().to_string()),
        "{name}: message does not name the file: {e}"
    );
    assert!(
        e.contains(place),
        "{name}: message does not name the place {place:?}: {e}"
    );
    e
}

// The unit square's corners, counter-clockwise, used by most tests.
const SQ: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];

fn sq(i: usize) -> Vec3 {
    Vec3::from_array(SQ[i])
}

// ---------------------------------------------------------------- OBJ

#[test]
fn obj_quads_negative_indices_crlf_missing_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let text = "mtllib missing.mtl\r\nusemtl red\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\ng quad\r\nf -4 -3 -2 -1\r\n";
    let s = load(write(dir.path(), "q.obj", text.as_bytes())).unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(s.meshes().len(), 1);
    assert_eq!(s.meshes()[0].name, "quad");
    // Fan in order: (v0, v1, v2), (v0, v2, v3).
    assert_eq!(tri(&s, 0), [sq(0), sq(1), sq(2)]);
    assert_eq!(tri(&s, 1), [sq(0), sq(2), sq(3)]);
}

#[test]
fn obj_polygon_fan_and_corner_forms() {
    let dir = tempfile::tempdir().unwrap();
    // A pentagon with v/vt/vn corners, then a triangle with v//vn and one with v/vt.
    let text = "\
v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 3 0\nv -1 1 0\n\
vt 0 0\nvt 1 0\nvn 0 0 1\n\
f 1/1/1 2/2/1 3/1/1 4/2/1 5/1/1\n\
f 1//1 3//1 5//1\n\
f 2/1 4/2 5/1\n";
    let s = load(write(dir.path(), "poly.obj", text.as_bytes())).unwrap();
    assert_eq!(s.len(), 5);
    let p = [
        v(0., 0., 0.),
        v(2., 0., 0.),
        v(3., 1., 0.),
        v(1., 3., 0.),
        v(-1., 1., 0.),
    ];
    assert_eq!(tri(&s, 0), [p[0], p[1], p[2]]);
    assert_eq!(tri(&s, 1), [p[0], p[2], p[3]]);
    assert_eq!(tri(&s, 2), [p[0], p[3], p[4]]);
    assert_eq!(tri(&s, 3), [p[0], p[2], p[4]]);
    assert_eq!(tri(&s, 4), [p[1], p[3], p[4]]);
    // Positions are not duplicated by differing vt/vn.
    assert_eq!(s.vertex_count(), 5);
}

#[test]
fn obj_interleaved_groups_keep_file_order() {
    let dir = tempfile::tempdir().unwrap();
    let text = "\
v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
g a\nf 1 2 3\n\
g b\nf 1 2 4\nf 2 3 4\n\
g a\nf 1 3 4\n";
    let s = load(write(dir.path(), "groups.obj", text.as_bytes())).unwrap();
    let names: Vec<&str> = s.meshes().iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["a", "b", "a"]);
    assert_eq!(s.len(), 4);
    let p = [v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.), v(0., 0., 1.)];
    // Primitive id = triangle index in file order, across the interleaved groups.
    assert_eq!(tri(&s, 0), [p[0], p[1], p[2]]);
    assert_eq!(tri(&s, 1), [p[0], p[1], p[3]]);
    assert_eq!(tri(&s, 2), [p[1], p[2], p[3]]);
    assert_eq!(tri(&s, 3), [p[0], p[2], p[3]]);
    assert_eq!(s.mesh_prims(1), 1..3);
}

#[test]
fn obj_points_and_lines_make_no_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\np 1\nl 1 2 3 4\nf 1 2\nf 1 2 3\n";
    let s = load(write(dir.path(), "lines.obj", text.as_bytes())).unwrap();
    assert_eq!(s.len(), 1);
    assert_eq!(tri(&s, 0), [sq(0), sq(1), sq(2)]);
}

#[test]
fn obj_gzip() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let s = load(write(dir.path(), "q.obj.gz", &gzip(text.as_bytes()))).unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(tri(&s, 1), [sq(0), sq(2), sq(3)]);
}

#[test]
fn obj_malformed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let e = load_err(
        d,
        "badnum.obj",
        b"v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n",
        "line 2",
    );
    assert!(e.contains("bad number"), "{e}");
    let e = load_err(
        d,
        "range.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
        "line 4",
    );
    assert!(e.contains("out of range"), "{e}");
    load_err(
        d,
        "neg.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
        "line 4",
    );
    load_err(
        d,
        "zero.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
        "line 4",
    );
    // A texture index far below zero overflows tobj's arithmetic: must be an error, not a panic.
    load_err(
        d,
        "vt.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/-9999999999 2/1 3/1\n",
        "line 5",
    );
    let e = load_err(
        d,
        "nan.obj",
        b"v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n",
        "line 2",
    );
    assert!(e.contains("non-finite"), "{e}");
    load_err(
        d,
        "inf.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n",
        "line 3",
    );
    let e = load_err(d, "empty.obj", b"", "line 1");
    assert!(e.contains("empty"), "{e}");
    // Truncated in the middle of a vertex line.
    load_err(d, "trunc.obj", b"v 0 0 0\nv 1 0 0\nv 0 1", "line 3");
    load_err(d, "utf8.obj", b"v 0 0 0\n# \xff\xfe\n", "line 2");
    load_err(
        d,
        "corner.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",
        "line 4",
    );
}

// ---------------------------------------------------------------- PLY

fn ply_ascii() -> String {
    // x, y, z not first, an extra element, `vertex_index`, a quad and a triangle.
    "ply\r\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty float confidence\n\
property float x\nproperty double y\nproperty float z\nproperty uchar intensity\n\
element face 2\nproperty list uchar int vertex_index\nelement edge 1\nproperty int vertex1\n\
property int vertex2\nend_header\n\
0.5 0 0 0 7\n0.5 1 0 0 7\n0.5 1 1 0 7\n0.5 0 1 0 7\n4 0 1 2 3\n3 3 2 1\n0 1\n"
        .to_string()
}

fn check_ply(s: &Scene) {
    assert_eq!(s.len(), 3);
    assert_eq!(s.vertex_count(), 4);
    assert_eq!(tri(s, 0), [sq(0), sq(1), sq(2)]);
    assert_eq!(tri(s, 1), [sq(0), sq(2), sq(3)]);
    assert_eq!(tri(s, 2), [sq(3), sq(2), sq(1)]);
}

#[test]
fn ply_ascii_extra_properties_and_gzip() {
    let dir = tempfile::tempdir().unwrap();
    let text = ply_ascii();
    check_ply(&load(write(dir.path(), "a.ply", text.as_bytes())).unwrap());
    check_ply(&load(write(dir.path(), "a.ply.gz", &gzip(text.as_bytes()))).unwrap());
}

/// A binary PLY with the same content as `ply_ascii`, mixing types.
fn ply_binary(be: bool) -> Vec<u8> {
    let fmt = if be {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = format!(
        "ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float confidence\nproperty double x\n\
property float y\nproperty float z\nproperty uchar intensity\nelement face 2\n\
property ushort flags\nproperty list uint short vertex_indices\nelement edge 1\n\
property list uchar int ends\nend_header\n"
    )
    .into_bytes();
    macro_rules! put {
        ($x:expr) => {
            if be {
                out.extend_from_slice(&$x.to_be_bytes())
            } else {
                out.extend_from_slice(&$x.to_le_bytes())
            }
        };
    }
    for p in SQ {
        put!(0.5f32);
        put!(p[0] as f64);
        put!(p[1]);
        put!(p[2]);
        out.push(7u8);
    }
    put!(9u16);
    put!(4u32);
    for i in [0i16, 1, 2, 3] {
        put!(i);
    }
    put!(9u16);
    put!(3u32);
    for i in [3i16, 2, 1] {
        put!(i);
    }
    out.push(2u8);
    put!(0i32);
    put!(1i32);
    out
}

#[test]
fn ply_binary_little_and_big_endian() {
    let dir = tempfile::tempdir().unwrap();
    check_ply(&load(write(dir.path(), "le.ply", &ply_binary(false))).unwrap());
    check_ply(&load(write(dir.path(), "be.ply", &ply_binary(true))).unwrap());
    check_ply(&load(write(dir.path(), "be.ply.gz", &gzip(&ply_binary(true)))).unwrap());
}

#[test]
fn ply_malformed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let a = ply_ascii();
    // Line 16 is vertex 0.
    let e = load_err(
        d,
        "badnum.ply",
        a.replacen("0.5 0 0 0 7", "0.5 0 zero 0 7", 1).as_bytes(),
        "line 16",
    );
    assert!(e.contains("bad number"), "{e}");
    let e = load_err(
        d,
        "nan.ply",
        a.replacen("0.5 1 1 0 7", "0.5 1 nan 0 7", 1).as_bytes(),
        "line 18",
    );
    assert!(e.contains("non-finite") && e.contains("vertex 2"), "{e}");
    let e = load_err(
        d,
        "range.ply",
        a.replace("3 3 2 1", "3 3 2 4").as_bytes(),
        "line 21",
    );
    assert!(e.contains("out of range") && e.contains("face 1"), "{e}");
    let e = load_err(d, "trunc.ply", &a.as_bytes()[..a.len() - 12], "line");
    assert!(e.contains("end of file"), "{e}");
    let e = load_err(
        d,
        "short.ply",
        a.replace("4 0 1 2 3", "4 0 1 2").as_bytes(),
        "line 20",
    );
    assert!(e.contains("declares 4 items"), "{e}");
    let e = load_err(
        d,
        "count.ply",
        a.replace("element face 2", "element face 1").as_bytes(),
        "line 21",
    );
    assert!(
        e.contains("wrong element count") || e.contains("extra value"),
        "{e}"
    );
    let e = load_err(d, "empty.ply", b"", "line 1");
    assert!(e.contains("empty"), "{e}");
    let e = load_err(d, "header.ply", b"plx\nformat ascii 1.0\n", "line 1");
    assert!(e.contains("not a PLY"), "{e}");
    load_err(
        d,
        "noend.ply",
        b"ply\nformat ascii 1.0\nelement vertex 1\n",
        "line 4",
    );
    load_err(
        d,
        "fmt.ply",
        b"ply\nformat binary_middle_endian 1.0\nend_header\n",
        "line 2",
    );

    // Binary: truncated data and a bad index report byte offsets.
    let b = ply_binary(false);
    let header_len = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let e = load_err(d, "trunc_bin.ply", &b[..b.len() - 3], "byte");
    assert!(e.contains("end of file") && e.contains("edge 0"), "{e}");
    // Vertex 0's x (a double at offset 4) set to NaN.
    let mut nan = b.clone();
    nan[header_len + 4..header_len + 12].copy_from_slice(&f64::NAN.to_le_bytes());
    let e = load_err(d, "nan_bin.ply", &nan, &format!("byte {header_len}"));
    assert!(e.contains("vertex 0") && e.contains("non-finite"), "{e}");
    // Face 0's third index: after 4 vertices of 21 bytes, a ushort, a uint count, two shorts.
    let at = header_len + 4 * 21 + 2 + 4 + 2 * 2;
    let mut bad = b.clone();
    bad[at..at + 2].copy_from_slice(&100i16.to_le_bytes());
    let e = load_err(d, "range_bin.ply", &bad, &format!("byte {at}"));
    assert!(e.contains("out of range") && e.contains("face 0"), "{e}");
    let mut extra = b.clone();
    extra.extend_from_slice(&[0, 0]);
    load_err(d, "extra_bin.ply", &extra, &format!("byte {}", b.len()));
    // A hostile count must fail cleanly, not allocate or panic.
    load_err(
        d,
        "huge.ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        "byte",
    );
}

// ---------------------------------------------------------------- OFF

#[test]
fn off_comments_fan_and_variants() {
    let dir = tempfile::tempdir().unwrap();
    let text = "OFF\n# a comment\n\n4 2 0\n0 0 0\n1 0 0 # trailing comment\n1 1 0\n0 1 0\n4 0 1 2 3\n3 3 2 1\n";
    let s = load(write(dir.path(), "a.off", text.as_bytes())).unwrap();
    assert_eq!(s.len(), 3);
    assert_eq!(tri(&s, 0), [sq(0), sq(1), sq(2)]);
    assert_eq!(tri(&s, 1), [sq(0), sq(2), sq(3)]);
    assert_eq!(tri(&s, 2), [sq(3), sq(2), sq(1)]);
    // COFF with colours, counts on the header line, CRLF, face colours, gzip.
    let coff = "COFF 4 1 0\r\n0 0 0 255 0 0 255\r\n1 0 0 255 0 0 255\r\n1 1 0 0 0 0 255\r\n0 1 0 0 0 0 255\r\n4 0 1 2 3 0.5 0.5 0.5\r\n";
    let s = load(write(dir.path(), "c.off.gz", &gzip(coff.as_bytes()))).unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(tri(&s, 1), [sq(0), sq(2), sq(3)]);
}

#[test]
fn off_malformed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let e = load_err(
        d,
        "badnum.off",
        ok.replace("1 0 0", "1 O 0").as_bytes(),
        "line 4",
    );
    assert!(e.contains("bad number") && e.contains("vertex 1"), "{e}");
    let e = load_err(
        d,
        "range.off",
        ok.replace("3 0 1 2", "3 0 1 3").as_bytes(),
        "line 6",
    );
    assert!(e.contains("out of range") && e.contains("face 0"), "{e}");
    let e = load_err(
        d,
        "nan.off",
        ok.replace("0 1 0", "0 nan 0").as_bytes(),
        "line 5",
    );
    assert!(e.contains("non-finite"), "{e}");
    let e = load_err(d, "trunc.off", &ok.as_bytes()[..ok.len() - 8], "line");
    assert!(e.contains("end of file") && e.contains("faces"), "{e}");
    let e = load_err(d, "empty.off", b"", "line 1");
    assert!(e.contains("empty"), "{e}");
    let e = load_err(d, "header.off", b"OBJ\n3 1 0\n", "line 1");
    assert!(e.contains("not an OFF"), "{e}");
    let e = load_err(
        d,
        "count.off",
        ok.replace("3 1 0", "3 2 0").as_bytes(),
        "line 6",
    );
    assert!(e.contains("declares 2 faces"), "{e}");
    let e = load_err(
        d,
        "extra.off",
        format!("{ok}3 2 1 0\n").as_bytes(),
        "line 7",
    );
    assert!(e.contains("wrong counts"), "{e}");
    load_err(
        d,
        "short_face.off",
        ok.replace("3 0 1 2", "4 0 1 2").as_bytes(),
        "line 6",
    );
    load_err(d, "4off.off", b"4OFF\n1 0 0\n0 0 0 0\n", "line 1");
}

// ---------------------------------------------------------------- glTF

fn base64(data: &[u8]) -> String {
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
fn gltf_buffer() -> Vec<u8> {
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
fn gltf_json(buffer: &str) -> String {
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

fn check_gltf(s: &Scene) {
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

fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
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

#[test]
fn unknown_extension_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "a.stl", b"solid");
    assert!(load(&p)
        .unwrap_err()
        .to_string()
        .contains("unknown scene format"));
}

// ---------------------------------------------------------------- robustness

mod no_panic {
    //! Truncated and byte-flipped versions of the valid test files must give `Ok` or `Err`,
    //! never a panic (proptest reports a panic as a failure).
    use super::*;
    use proptest::prelude::*;
    use raysift::scene::io::{gltf, obj, off, ply};

    fn samples() -> Vec<(&'static str, Vec<u8>)> {
        let buf = gltf_buffer();
        vec![
            ("a.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\ng x\nf 1/1/1 2/1/1 3/1/1\nf -3 -2 -1\nl 1 2\n".to_vec()),
            ("a.ply", ply_ascii().into_bytes()),
            ("le.ply", ply_binary(false)),
            ("be.ply", ply_binary(true)),
            ("a.off", b"OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n3 3 2 1\n".to_vec()),
            (
                "a.gltf",
                gltf_json(&format!(
                    r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
                    base64(&buf)
                ))
                .into_bytes(),
            ),
            ("a.glb", glb(&gltf_json(r#"{"byteLength": 60}"#), &buf)),
        ]
    }

    fn parse(name: &str, bytes: &[u8]) {
        let _ = match name.rsplit('.').next().unwrap() {
            "obj" => obj::parse(bytes, name),
            "ply" => ply::parse(bytes, name),
            "off" => off::parse(bytes, name),
            _ => gltf::parse(bytes, name, None),
        };
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
        #[test]
        fn mangled_files_never_panic(
            which in 0usize..7,
            cut in 0.0f64..1.0,
            flips in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..4),
        ) {
            let (name, mut bytes) = samples().swap_remove(which);
            for (at, b) in flips {
                let n = bytes.len();
                bytes[(((n as f64) * at) as usize).min(n - 1)] = b;
            }
            // About a sixth of the cases keep the whole file.
            let keep = ((bytes.len() as f64) * (1.2 * cut)).min(bytes.len() as f64) as usize;
            parse(name, &bytes[..keep]);
        }
    }
}

// ---------------------------------------------------------------- resource limits and fuzz regressions
//
// Each test here failed on the code before its fix (docs/fuzzing.md lists which run or review
// found it). "Fails quickly" is checked with a deadline on a worker thread, "does not allocate"
// with the tracking allocator below, which records the largest single allocation made by the
// calling thread.

mod limits {
    use super::*;
    use raysift::rays::npy;
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;
    use std::sync::mpsc;
    use std::time::Duration;

    struct Tracking;

    thread_local! {
        static LARGEST: Cell<usize> = const { Cell::new(0) };
    }

    fn note(n: usize) {
        let _ = LARGEST.try_with(|l| {
            if n > l.get() {
                l.set(n)
            }
        });
    }

    unsafe impl GlobalAlloc for Tracking {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            note(l.size());
            unsafe { System.alloc(l) }
        }
        unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
            note(l.size());
            unsafe { System.alloc_zeroed(l) }
        }
        unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
            note(new);
            unsafe { System.realloc(p, l, new) }
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            unsafe { System.dealloc(p, l) }
        }
    }

    #[global_allocator]
    static ALLOC: Tracking = Tracking;

    /// Runs `f` on a worker thread; fails the test if it takes more than `secs` seconds (a
    /// hang) or panics. Returns `f`'s result and the largest single allocation it made.
    fn quick<T: Send + 'static>(secs: u64, f: impl FnOnce() -> T + Send + 'static) -> (T, usize) {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            LARGEST.with(|l| l.set(0));
            let r = f();
            let _ = tx.send((r, LARGEST.with(|l| l.get())));
        });
        match rx.recv_timeout(Duration::from_secs(secs)) {
            Ok(r) => r,
            Err(mpsc::RecvTimeoutError::Timeout) => panic!("still running after {secs} s: a hang"),
            Err(mpsc::RecvTimeoutError::Disconnected) => panic!("panicked (see above)"),
        }
    }

    /// `load` on a file holding `bytes`, within 5 s; the error message and the largest allocation.
    fn load_fails(dir: &Path, name: &str, bytes: &[u8]) -> (String, usize) {
        let p = write(dir, name, bytes);
        let (r, big) = quick(5, move || {
            load(&p).map(|s| s.len()).map_err(|e| e.to_string())
        });
        let e = match r {
            Ok(n) => panic!("{name}: expected an error, loaded {n} triangles"),
            Err(e) => e,
        };
        assert!(
            e.contains(&dir.join(name).display().to_string()),
            "{name}: message does not name the file: {e}"
        );
        (e, big)
    }

    fn npy_bytes(header: &str, data: &[u8]) -> Vec<u8> {
        let mut h = header.as_bytes().to_vec();
        while !(10 + h.len() + 1).is_multiple_of(64) {
            h.push(b' ');
        }
        h.push(b'\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(h.len() as u16).to_le_bytes());
        out.extend_from_slice(&h);
        out.extend_from_slice(data);
        out
    }

    fn rays_header(shape: &str) -> String {
        format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}")
    }

    /// `read_rays` (and the hits and occlusion readers) on a file, within 5 s.
    fn npy_fails(dir: &Path, name: &str, bytes: &[u8]) -> (String, usize) {
        let p = write(dir, name, bytes);
        let (r, big) = quick(5, move || {
            let a = npy::read_rays(&p).map(|_| ()).map_err(|e| e.to_string());
            let b = npy::read_hits(&p).map(|_| ());
            let c = npy::read_occlusion(&p).map(|_| ());
            assert!(b.is_err() && c.is_err());
            a
        });
        let e = r.expect_err("expected an error");
        assert!(
            e.contains(name),
            "{name}: message does not name the file: {e}"
        );
        (e, big)
    }

    /// A sparse file of `len` bytes starting with `head` (takes no disk space).
    fn sparse_file(dir: &Path, name: &str, head: &[u8], len: u64) -> Option<PathBuf> {
        let p = dir.join(name);
        let mut f = std::fs::File::create(&p).ok()?;
        f.write_all(head).ok()?;
        f.set_len(len).ok()?;
        Some(p)
    }

    fn mem_available() -> Option<u64> {
        let t = std::fs::read_to_string("/proc/meminfo").ok()?;
        let l = t.lines().find(|l| l.starts_with("MemAvailable:"))?;
        Some(l.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
    }

    // ---- found by fuzzing and review (docs/fuzzing.md, "Crashes found")
    #[test]
    fn fuzz_npy_header_length_of_2gb_is_refused_before_allocating() {
        // From the npy target's first run: a version 2.0 header declaring 2070151284 bytes made
        // npyz allocate that much before reading it.
        let mut b = b"\x93NUMPY\x02\x00".to_vec();
        b.extend_from_slice(&2_070_151_284u32.to_le_bytes());
        b.extend_from_slice(b"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 8), }\n");
        let dir = tempfile::tempdir().unwrap();
        let (e, big) = npy_fails(dir.path(), "hdr.npy", &b);
        assert!(e.contains("header") && e.contains("2070151284"), "{e}");
        assert!(big < 1 << 20, "allocated {big} bytes");
    }

    #[test]
    fn fuzz_npy_shape_product_overflow_is_an_error_not_a_panic() {
        // npyz multiplies the shape unchecked (overflow panics with overflow checks on, as in
        // the test profile and the fuzz builds) and so do its strides, even when a zero makes
        // the product 0.
        let dir = tempfile::tempdir().unwrap();
        for (name, shape) in [
            ("product.npy", "(4294967296, 4294967296, 8)"),
            ("strides.npy", "(0, 4294967296, 4294967296, 8)"),
        ] {
            let (e, _) = npy_fails(dir.path(), name, &npy_bytes(&rays_header(shape), &[]));
            assert!(e.contains("header"), "{e}");
        }
    }

    #[test]
    fn fuzz_npy_deeply_nested_header_fails_quickly() {
        // py_literal (npyz's header parser) backtracks exponentially on nested brackets.
        let dir = tempfile::tempdir().unwrap();
        let shape = format!("{}{}", "[".repeat(3000), "]".repeat(3000));
        let (e, _) = npy_fails(
            dir.path(),
            "deep.npy",
            &npy_bytes(&rays_header(&shape), &[]),
        );
        assert!(e.contains("header") && e.contains("nested"), "{e}");
    }

    #[test]
    fn fuzz_ply_binary_element_without_properties_does_not_hang() {
        // A binary element with no properties takes no bytes, so a count of 10^18 looped 10^18
        // times doing nothing.
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
element nothing 1000000000000000000\nend_header\n"
            .to_vec();
        for c in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.push(3);
        for i in [0i32, 1, 2] {
            b.extend_from_slice(&i.to_le_bytes());
        }
        let dir = tempfile::tempdir().unwrap();
        let p = write(dir.path(), "noprops.ply", &b);
        let (s, _) = quick(5, move || {
            load(&p).map(|s| s.len()).map_err(|e| e.to_string())
        });
        assert_eq!(s, Ok(1));
        // The same in ascii.
        let mut a = String::from_utf8(b[..b.len() - 49].to_vec()).unwrap();
        a = a.replace("binary_little_endian", "ascii");
        a.push_str("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
        let p = write(dir.path(), "noprops_ascii.ply", a.as_bytes());
        let (s, _) = quick(5, move || {
            load(&p).map(|s| s.len()).map_err(|e| e.to_string())
        });
        assert_eq!(s, Ok(1));
    }

    #[test]
    fn fuzz_gltf_sparse_accessor_without_view_does_not_allocate_hundreds_of_mb() {
        // A 712-byte file: a sparse u8 index accessor of count 16,000,000 with no bufferView
        // (all zeros) passed the old bound (16 x buffer bytes + 16 MiB) and made a 512 MB
        // element list.
        let mut buf = Vec::new();
        for c in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        buf.extend_from_slice(&[0, 0, 0, 0]);
        let json = format!(
            r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "mode": 5}}]}}],
  "buffers": [{{"byteLength": 40, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 1}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"componentType": 5121, "count": 16000000, "type": "SCALAR",
      "sparse": {{"count": 1, "indices": {{"bufferView": 1, "componentType": 5121}}, "values": {{"bufferView": 1}}}}}}]}}"#,
            base64(&buf)
        );
        let dir = tempfile::tempdir().unwrap();
        let (e, big) = load_fails(dir.path(), "sparse.gltf", json.as_bytes());
        assert!(
            e.contains("accessors[1]") && e.contains("implausibly large"),
            "{e}"
        );
        assert!(big < 4 << 20, "allocated {big} bytes");
    }

    #[test]
    fn gltf_external_buffer_must_be_a_regular_file() {
        // A buffer URI naming a FIFO (or a device such as /dev/zero) blocked or read forever.
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe.bin");
        let ok = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            eprintln!("SKIPPED: mkfifo not available");
            return;
        }
        let json = gltf_json(r#"{"byteLength": 60, "uri": "pipe.bin"}"#);
        let (e, _) = load_fails(dir.path(), "fifo.gltf", json.as_bytes());
        assert!(
            e.contains("buffers[0]") && e.contains("regular file"),
            "{e}"
        );
    }

    #[test]
    fn gltf_instances_beyond_memory_are_refused_before_copying() {
        // Instancing legitimately multiplies a file's triangles, so the bound is memory: one
        // TRIANGLE_FAN mesh of 65536 vertices (65534 triangles, all at the origin) in a GLB's
        // BIN chunk, and enough nodes instancing it to need twice the available memory. Before
        // the budget, every instance was copied until memory ran out.
        let Some(avail) = mem_available() else {
            eprintln!("SKIPPED: no /proc/meminfo");
            return;
        };
        let nv = 65536u64;
        let per = nv * 12 + (nv - 2) * 48;
        let nodes = (2 * avail / per + 1) as usize;
        let list: Vec<String> = (0..nodes).map(|i| i.to_string()).collect();
        let json = format!(
            r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [{}]}}],
  "nodes": [{}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "mode": 6}}]}}],
  "buffers": [{{"byteLength": {b}}}], "bufferViews": [{{"buffer": 0, "byteLength": {b}}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": {nv}, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0]}}]}}"#,
            list.join(","),
            vec![r#"{"mesh": 0}"#; nodes].join(","),
            b = nv * 12
        );
        let g = glb(&json, &vec![0u8; (nv * 12) as usize]);
        let dir = tempfile::tempdir().unwrap();
        let (e, big) = load_fails(dir.path(), "instances.glb", &g);
        assert!(e.contains("nodes[") && e.contains("MemAvailable"), "{e}");
        assert!(big < 64 << 20, "allocated {big} bytes");
    }

    // ---- limits: counts against bytes
    #[test]
    fn ply_header_claiming_1e12_vertices_fails_at_the_header() {
        let dir = tempfile::tempdir().unwrap();
        for fmt in ["ascii", "binary_little_endian", "binary_big_endian"] {
            let mut b = format!(
                "ply\nformat {fmt} 1.0\nelement vertex 1000000000000\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
            )
            .into_bytes();
            b.resize(200, b'0');
            let (e, big) = load_fails(dir.path(), &format!("{fmt}.ply"), &b);
            assert!(
                e.contains("header, element 0 (vertex)") && e.contains("1000000000000"),
                "{e}"
            );
            assert!(e.contains("can hold"), "{e}");
            assert!(big < 1 << 16, "allocated {big} bytes");
        }
        // Any element, not only vertices: 10^15 edges of two ints in a small binary file.
        let b = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
property float y\nproperty float z\nelement edge 1000000000000000\nproperty int a\nproperty int b\nend_header\n";
        let (e, _) = load_fails(dir.path(), "edges.ply", b);
        assert!(
            e.contains("element 1 (edge)") && e.contains("can hold"),
            "{e}"
        );
    }

    #[test]
    fn ply_binary_list_size_beyond_the_file_fails_without_allocating() {
        // Already bounded before this work (the list's bytes are taken from the input before any
        // item is stored); kept as a check of the rule.
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n"
            .to_vec();
        let at = b.len() + 36;
        b.extend_from_slice(&[0; 36]);
        b.extend_from_slice(&u32::MAX.to_le_bytes());
        b.extend_from_slice(&[0; 12]);
        let dir = tempfile::tempdir().unwrap();
        let (e, big) = load_fails(dir.path(), "list.ply", &b);
        assert!(
            e.contains(&format!("byte {}", at + 4)) && e.contains("face 0"),
            "{e}"
        );
        assert!(big < 1 << 16, "allocated {big} bytes");
    }

    #[test]
    fn off_counts_beyond_the_file_fail_at_the_counts_line() {
        let dir = tempfile::tempdir().unwrap();
        for (name, text) in [
            ("v.off", "OFF\n3000000000 1 0\n0 0 0\n"),
            (
                "f.off",
                "OFF 3 1000000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            ),
        ] {
            let (e, big) = load_fails(dir.path(), name, text.as_bytes());
            assert!(e.contains("can hold"), "{e}");
            let line = if name == "v.off" { "line 2" } else { "line 1" };
            assert!(e.contains(line), "{e}");
            assert!(big < 1 << 16, "allocated {big} bytes");
        }
    }

    #[test]
    fn npy_shape_1e12_rows_fails_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let (e, big) = npy_fails(
            dir.path(),
            "huge.npy",
            &npy_bytes(&rays_header("(1000000000000, 8)"), &[0; 64]),
        );
        assert!(
            e.contains("data") && e.contains("32000000000000 bytes") && e.contains("64"),
            "{e}"
        );
        assert!(big < 1 << 16, "allocated {big} bytes");
        // Trailing bytes after the data the shape declares are an error too.
        let mut row = Vec::new();
        for c in [0f32, 0., 0., 1., 0., 0., 0., 1.] {
            row.extend_from_slice(&c.to_le_bytes());
        }
        let ok = npy_bytes(&rays_header("(1, 8)"), &row);
        assert_eq!(npy::parse_rays(&ok, "ok.npy").unwrap().len(), 1);
        let mut extra = ok.clone();
        extra.extend_from_slice(&[0; 4]);
        let e = npy::parse_rays(&extra, "extra.npy")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("extra.npy: data") && e.contains("4 bytes after"),
            "{e}"
        );
    }

    // ---- limits: gzip
    #[test]
    fn gzip_bomb_is_refused_at_the_cap() {
        // About 1 KB of gzip inflating to 1 MB of OBJ comment lines: above the cap
        // (64 x 1 KB + 64 KiB), so refused while inflating, naming the file.
        let text = format!("v 0 0 0\n{}", "#".repeat(1 << 20));
        let gz = gzip(text.as_bytes());
        assert!(gz.len() < 1500, "{}", gz.len());
        let dir = tempfile::tempdir().unwrap();
        let (e, big) = load_fails(dir.path(), "bomb.obj.gz", &gz);
        let cap = 64 * gz.len() + (64 << 10);
        assert!(
            e.contains("gzip") && e.contains(&format!("more than {cap} bytes")),
            "{e}"
        );
        assert!(big <= 2 * cap, "allocated {big} bytes for a cap of {cap}");
        // A real mesh's ratio (3-6x) is far below the cap.
        let ok = gzip(ply_ascii().as_bytes());
        assert!(load(write(dir.path(), "ok.ply.gz", &ok)).is_ok());
    }

    // ---- limits: memory
    #[test]
    fn rays_file_larger_than_memory_is_refused() {
        let Some(avail) = mem_available() else {
            eprintln!("SKIPPED: no /proc/meminfo");
            return;
        };
        // A consistent file (shape and length agree) whose rays need twice the available memory.
        let n = avail / 16; // 32 bytes per ray in memory
        let head = npy_bytes(&rays_header(&format!("({n}, 8)")), &[]);
        let dir = tempfile::tempdir().unwrap();
        let Some(p) = sparse_file(dir.path(), "big.npy", &head, head.len() as u64 + n * 32) else {
            eprintln!("SKIPPED: cannot make a sparse file");
            return;
        };
        let (r, big) = quick(5, move || {
            npy::read_rays(&p).map(|_| ()).map_err(|e| e.to_string())
        });
        let e = r.unwrap_err();
        assert!(
            e.contains("big.npy") && e.contains("MemAvailable") && e.contains("rays"),
            "{e}"
        );
        assert!(big < 1 << 20, "allocated {big} bytes");
    }

    #[test]
    fn scene_file_larger_than_memory_is_refused() {
        let Some(avail) = mem_available() else {
            eprintln!("SKIPPED: no /proc/meminfo");
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let Some(p) = sparse_file(dir.path(), "big.ply", b"ply\n", avail * 2) else {
            eprintln!("SKIPPED: cannot make a sparse file");
            return;
        };
        let (r, big) = quick(5, move || load(&p).map(|_| ()).map_err(|e| e.to_string()));
        let e = r.unwrap_err();
        assert!(e.contains("big.ply") && e.contains("MemAvailable"), "{e}");
        assert!(big < 1 << 20, "allocated {big} bytes");
    }
}
