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

/// OBJ materials: `Kd`/`Ke`/`illum 3` from the `.mtl` next to the file, per `usemtl` range
/// without splitting meshes; a missing `.mtl` gives no materials; a malformed one names its line.
#[test]
fn obj_materials_from_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let obj = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng a\nusemtl red\nf 1 2 3 4\nusemtl lamp\nf 1 2 3\nusemtl nothere\nf 1 3 4\ng b\nusemtl glass\nf 1 2 3\n";
    let p = write(dir.path(), "s.obj", obj);
    // No .mtl yet: loads, no materials.
    let s = load(&p).unwrap();
    assert!((0..5).all(|k| s.material(k).is_none()));
    write(
        dir.path(),
        "m.mtl",
        b"newmtl red\nKd 0.8 0.1 0.1 # comment\nnewmtl lamp\nKd 0 0 0\nKe 10 9 8\nnewmtl glass\nillum 3\n",
    );
    let s = load(&p).unwrap();
    assert_eq!(s.meshes().len(), 2, "usemtl does not split meshes");
    let m = |k: u32| *s.material(k).unwrap();
    assert_eq!(m(0).diffuse, v(0.8, 0.1, 0.1));
    assert_eq!(m(1), m(0));
    assert_eq!(m(2).emission, v(10., 9., 8.));
    assert!(!m(2).mirror && s.has_emission());
    assert_eq!(
        m(3),
        raysift::scene::Material::default(),
        "unknown name after a known one"
    );
    assert!(m(4).mirror);
    // Bytes only: no file system, no materials.
    let s = raysift::scene::io::load_bytes(obj, "s.obj", None).unwrap();
    assert!(s.material(0).is_none());
    // A malformed .mtl names itself and the line.
    write(dir.path(), "m.mtl", b"newmtl red\n\nKd 0.8 x 0.1\n");
    let e = load(&p).unwrap_err().to_string();
    assert!(
        e.contains("m.mtl") && e.contains("line 3") && e.contains("Kd"),
        "{e}"
    );
    write(dir.path(), "m.mtl", b"newmtl red\nKe 1 2\n");
    let e = load(&p).unwrap_err().to_string();
    assert!(e.contains("m.mtl") && e.contains("line 2"), "{e}");
}

/// The shared Cornell box: red left wall, green right wall, an emissive ceiling light.
#[test]
fn obj_cornell_box_materials() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/scenes/CornellBox-Original.obj");
    if !p.exists() {
        eprintln!("skipped: {} not found", p.display());
        return;
    }
    let s = load(&p).unwrap();
    let by_name = |n: &str| {
        let m = s.meshes().iter().position(|m| m.name == n).unwrap();
        *s.material(s.mesh_prims(m).start as u32).unwrap()
    };
    assert_eq!(by_name("rightWall").diffuse, v(0.14, 0.45, 0.091));
    assert_eq!(by_name("light").emission, v(17., 12., 4.));
    assert!(by_name("floor").emission == Vec3::ZERO);
    // leftWall's mesh holds the red wall then the short box faces (the file's `g` order).
    let lw = s
        .meshes()
        .iter()
        .position(|m| m.name == "leftWall")
        .unwrap();
    assert_eq!(
        s.material(s.mesh_prims(lw).start as u32).unwrap().diffuse,
        v(0.63, 0.065, 0.05)
    );
}
