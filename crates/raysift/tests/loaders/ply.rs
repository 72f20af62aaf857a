//! PLY (ascii, binary little and big endian) loader cases.

use super::*;

pub(crate) fn ply_ascii() -> String {
    // x, y, z not first, an extra element, `vertex_index`, a quad and a triangle.
    "ply\r\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty float confidence\n\
property float x\nproperty double y\nproperty float z\nproperty uchar intensity\n\
element face 2\nproperty list uchar int vertex_index\nelement edge 1\nproperty int vertex1\n\
property int vertex2\nend_header\n\
0.5 0 0 0 7\n0.5 1 0 0 7\n0.5 1 1 0 7\n0.5 0 1 0 7\n4 0 1 2 3\n3 3 2 1\n0 1\n"
        .to_string()
}

pub(crate) fn check_ply(s: &Scene) {
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
pub(crate) fn ply_binary(be: bool) -> Vec<u8> {
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

/// A square of two triangles whose vertices are red, green, blue and white.
fn ply_colors_ascii(ty: &str, vals: [&str; 4]) -> String {
    format!(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty {ty} red\nproperty {ty} green\nproperty {ty} blue\nelement face 2\n\
property list uchar int vertex_indices\nend_header\n\
0 0 0 {}\n1 0 0 {}\n1 1 0 {}\n0 1 0 {}\n3 0 1 2\n3 0 2 3\n",
        vals[0], vals[1], vals[2], vals[3]
    )
}

/// Vertex colours (`red green blue`, uchar or float, ascii or binary) become the mesh's
/// `colors`, scaled to [0, 1], and `Scene::albedo` interpolates them with a hit's (u, v).
#[test]
fn ply_vertex_colors() {
    use raysift::scene::Material;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let want = [
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::ONE,
    ];
    let uchar = ply_colors_ascii("uchar", ["255 0 0", "0 255 0", "0 0 255", "255 255 255"]);
    let float = ply_colors_ascii("float", ["1 0 0", "0 1 0", "0 0 1", "1 1 1"]);
    // Binary little endian, float positions and uchar colours.
    let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n\
property uchar blue\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    for (p, c) in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]
        .iter()
        .zip(want)
    {
        p.iter()
            .for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
        bin.extend(c.to_array().map(|x| (x * 255.0) as u8));
    }
    for f in [[0i32, 1, 2], [0, 2, 3]] {
        bin.push(3);
        f.iter()
            .for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
    }
    let grey = Material::default();
    for (name, bytes) in [
        ("u8.ply", uchar.as_bytes()),
        ("f32.ply", float.as_bytes()),
        ("bin.ply", &bin[..]),
    ] {
        let s = load(write(d, name, bytes)).unwrap();
        assert_eq!(s.meshes()[0].colors, want, "{name}");
        // Triangle 0 is vertices 0, 1, 2: at (u, v) the colour is (1-u-v)·c0 + u·c1 + v·c2.
        assert_eq!(s.albedo(0, 0.0, 0.0, &grey), want[0]);
        assert_eq!(s.albedo(0, 1.0, 0.0, &grey), want[1]);
        assert_eq!(s.albedo(1, 0.0, 1.0, &grey), want[3]);
        let mid = s.albedo(0, 0.25, 0.5, &grey);
        assert!(
            (mid - Vec3::new(0.25, 0.25, 0.5)).abs().max_element() < 1e-6,
            "{mid}"
        );
    }
    // Without colours the material's (or the default's) diffuse colour.
    let s = load(write(d, "plain.ply", ply_ascii().as_bytes())).unwrap();
    assert!(s.meshes()[0].colors.is_empty());
    assert_eq!(s.albedo(0, 0.3, 0.3, &grey), grey.diffuse);
    // Only two of the three channels: no colours (nothing to interpolate), not an error.
    let two = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty uchar red\nproperty uchar green\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 0 255 0\n1 0 0 0 255\n1 1 0 9 9\n3 0 1 2\n";
    let s = load(write(d, "two.ply", two.as_bytes())).unwrap();
    assert!(s.meshes()[0].colors.is_empty());
    // A float colour outside [0, 1], a negative integer one: the file, line and vertex named.
    let e = load_err(
        d,
        "big.ply",
        float.replace("0 1 0 1 1 1", "0 1 0 1 1.5 1").as_bytes(),
        "line 16",
    );
    assert!(
        e.contains("vertex 3") && e.contains("outside [0, 1]"),
        "{e}"
    );
    let e = load_err(
        d,
        "neg.ply",
        ply_colors_ascii("char", ["1 0 0", "0 1 0", "0 0 -1", "1 1 1"]).as_bytes(),
        "line 15",
    );
    assert!(e.contains("vertex 2"), "{e}");
    let e = load_err(
        d,
        "word.ply",
        uchar.replace("1 1 0 0 0 255", "1 1 0 0 0 blue").as_bytes(),
        "line 15",
    );
    assert!(e.contains("vertex 2") && e.contains("blue"), "{e}");
}
