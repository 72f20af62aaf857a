//! OBJ loader cases.

use super::*;

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
