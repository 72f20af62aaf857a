//! `raysift cones`: camera cones and cones from a file give the oracle's answer through the
//! files; bad cones files and apertures are one-line errors with exit code 2 and no output.

use super::*;

/// A `.npy` of `rows` float32 rows of `cols` (or another dtype descr), written by hand.
fn npy(path: &str, descr: &str, shape: &str, data: &[u8]) {
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((h.len() as u16).to_le_bytes());
    b.extend(h.as_bytes());
    b.extend(data);
    std::fs::write(path, b).unwrap();
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Records (cone, prim, t bits) of a hits file, read back as bytes after the header.
fn records(path: &str) -> Vec<(u32, u32, u32)> {
    let b = std::fs::read(path).unwrap();
    let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
    b[10 + hl..]
        .chunks(12)
        .map(|c| {
            let w = |k: usize| u32::from_le_bytes(c[k..k + 4].try_into().unwrap());
            (w(0), w(4), w(8))
        })
        .collect()
}

#[test]
fn camera_and_file_cones_equal_the_oracle() {
    let d = tmp();
    let (a, b) = (p(d.path(), "bvh.npy"), p(d.path(), "oracle.npy"));
    let view = [
        "--width",
        "8",
        "--height",
        "8",
        "--aperture",
        "1.5",
        "--n",
        "4",
    ];
    let o = ok(&[
        &[
            "cones",
            "sphere:500",
            "--out",
            &a,
            "--traversal",
            "sorted",
            "--json",
        ][..],
        &view,
    ]
    .concat());
    let j = json(&o);
    assert_eq!(j["cones"], 64);
    assert!(j["reported"].as_u64().unwrap() > 50);
    ok(&[
        &["cones", "sphere:500", "--out", &b, "--structure", "oracle"][..],
        &view,
    ]
    .concat());
    let (ra, rb) = (records(&a), records(&b));
    assert_eq!(ra, rb);
    assert!(ra.len() <= 64 * 4 && !ra.is_empty());
    // Cones from a file: two rows, the second continuing from t_near = 1.
    let cones = p(d.path(), "cones.npy");
    npy(
        &cones,
        "<f4",
        "(2, 8)",
        &f32s(&[
            0., 0., 5., 0., 0., -1., 10., 0., 0., 0., 5., 0., 0., -1., 10., 4.5,
        ]),
    );
    let (c1, c2) = (p(d.path(), "c1.npy"), p(d.path(), "c2.npy"));
    ok(&["cones", "sphere:500", "--cones", &cones, "--out", &c1]);
    ok(&[
        "cones",
        "sphere:500",
        "--cones",
        &cones,
        "--out",
        &c2,
        "--structure",
        "oracle",
        "--box-test",
        "basic",
    ]);
    let r = records(&c1);
    assert_eq!(r, records(&c2));
    let near: Vec<_> = r.iter().filter(|x| x.0 == 1).collect();
    assert!(r.iter().any(|x| x.0 == 0) && near.iter().all(|x| f32::from_bits(x.2) >= 4.5));
    // Counting mode reports nothing but counts.
    let j = json(&ok(&[
        "cones",
        "sphere:500",
        "--aperture",
        "0.5",
        "--width",
        "4",
        "--height",
        "4",
        "--count",
        "--json",
    ]));
    assert_eq!(j["reported"], 0);
    assert!(j["tri_encounters_per_cone"].as_f64().unwrap() > 0.0);
}

#[test]
fn kdtree_rays_per_pixel_and_heatmap() {
    let d = tmp();
    let (k, o) = (p(d.path(), "kd.npy"), p(d.path(), "oracle.npy"));
    let view = [
        "--width",
        "8",
        "--height",
        "8",
        "--aperture",
        "2",
        "--n",
        "3",
    ];
    ok(&[
        &["cones", "sphere:500", "--out", &k, "--structure", "kdtree"][..],
        &view,
    ]
    .concat());
    ok(&[
        &["cones", "sphere:500", "--out", &o, "--structure", "oracle"][..],
        &view,
    ]
    .concat());
    assert_eq!(records(&k), records(&o));
    assert!(!records(&k).is_empty());
    // 4 rays per pixel: 4× the cones, counts per pixel = 4 × per cone; the heatmap is drawn
    // at the pixel size (8 + the colour bar wide).
    let heat = p(d.path(), "heat.png");
    let j = json(&ok(&[
        "cones",
        "sphere:500",
        "--rays-per-pixel",
        "4",
        "--count",
        "--width",
        "8",
        "--height",
        "8",
        "--structure",
        "kdtree",
        "--heatmap",
        &heat,
        "--json",
    ]));
    assert_eq!(j["cones"], 256);
    assert_eq!(j["cones_per_pixel"], 4);
    let (pc, pp) = (
        j["nodes_per_cone"].as_f64().unwrap(),
        j["nodes_per_pixel"].as_f64().unwrap(),
    );
    assert!(pc > 0.0 && (pp - 4.0 * pc).abs() < 1e-9);
    let scale = &j["heatmap_scale"];
    let mean = scale["mean"].as_f64().unwrap();
    let per_px = pp + j["tri_encounters_per_pixel"].as_f64().unwrap();
    assert!((mean - per_px).abs() < 1e-6 * per_px, "{mean} vs {per_px}");
    let (w, h) = super::commands::png_size(&heat);
    assert!(h == 8 && w > 8, "{w}×{h}");
}

#[test]
fn bad_cones_are_clean_errors() {
    let d = tmp();
    let out = p(d.path(), "out.npy");
    let f = p(d.path(), "c.npy");
    let good = [0., 0., 5., 0., 0., -1., 1., 0.];
    npy(&f, "<f8", "(1, 8)", &[0u8; 64]);
    fails(
        &["cones", "sphere:50", "--cones", &f, "--out", &out],
        "expected float32",
    );
    npy(&f, "<f4", "(1, 7)", &f32s(&good[..7]));
    fails(
        &["cones", "sphere:50", "--cones", &f, "--out", &out],
        "expected (N, 8)",
    );
    let mut nan = good;
    nan[4] = f32::NAN;
    npy(&f, "<f4", "(1, 8)", &f32s(&nan));
    fails(
        &["cones", "sphere:50", "--cones", &f, "--out", &out],
        "row 0: non-finite",
    );
    for alpha in [0.0, 90.0, -3.0] {
        let mut r = good;
        r[6] = alpha;
        npy(&f, "<f4", "(2, 8)", &f32s(&[good, r].concat()));
        fails(
            &["cones", "sphere:50", "--cones", &f, "--out", &out],
            "row 1: half-angle",
        );
    }
    let mut zero = good;
    zero[3..6].copy_from_slice(&[0.0; 3]);
    npy(&f, "<f4", "(1, 8)", &f32s(&zero));
    fails(
        &["cones", "sphere:50", "--cones", &f, "--out", &out],
        "zero axis",
    );
    npy(&f, "<f4", "(3, 8)", &f32s(&good));
    fails(
        &["cones", "sphere:50", "--cones", &f, "--out", &out],
        "truncated",
    );
    fails(
        &["cones", "sphere:50", "--aperture", "95", "--out", &out],
        "--aperture",
    );
    fails(
        &["cones", "sphere:50", "--aperture", "NaN", "--out", &out],
        "--aperture",
    );
    fails(&["cones", "sphere:50", "--out", &out], "--aperture");
    fails(
        &["cones", "sphere:50", "--rays-per-pixel", "5", "--out", &out],
        "not a positive square",
    );
    let heat = p(d.path(), "heat.jpg");
    fails(
        &[
            "cones",
            "sphere:50",
            "--aperture",
            "1",
            "--heatmap",
            &heat,
            "--out",
            &out,
        ],
        "heat.jpg",
    );
    npy(&f, "<f4", "(1, 8)", &f32s(&good));
    let heat = p(d.path(), "heat.png");
    fails(
        &[
            "cones",
            "sphere:50",
            "--cones",
            &f,
            "--heatmap",
            &heat,
            "--out",
            &out,
        ],
        "--heatmap needs cones from the camera",
    );
    assert!(!Path::new(&out).exists() && !Path::new(&heat).exists());
}

#[test]
fn sbvh_and_bvh_options_equal_the_oracle_and_bad_options_fail() {
    let d = tmp();
    let view = [
        "--width",
        "8",
        "--height",
        "8",
        "--aperture",
        "2",
        "--n",
        "8",
    ];
    let (o, s, b) = (
        p(d.path(), "o.npy"),
        p(d.path(), "s.npy"),
        p(d.path(), "b.npy"),
    );
    ok(&[
        &["cones", "cornell", "--out", &o, "--structure", "oracle"][..],
        &view,
    ]
    .concat());
    let j = json(&ok(&[
        &[
            "cones",
            "cornell",
            "--out",
            &s,
            "--structure",
            "sbvh",
            "--bvh",
            "alpha=0",
            "--bvh",
            "max_leaf=1",
            "--json",
        ][..],
        &view,
    ]
    .concat()));
    // The Cornell box's walls cross the small boxes' space: planes are taken and cut triangles.
    let built = &j["built"];
    assert!(built["spatial_splits"].as_u64().unwrap() > 0, "{built}");
    assert!(built["references"].as_u64().unwrap() > j["triangles"].as_u64().unwrap());
    ok(&[
        &["cones", "cornell", "--out", &b, "--bvh", "traversal_cost=4"][..],
        &view,
    ]
    .concat());
    let want = records(&o);
    assert!(!want.is_empty());
    assert_eq!(records(&s), want);
    assert_eq!(records(&b), want);
    let out = p(d.path(), "x.npy");
    for (opt, msg) in [
        ("colour=red", "unknown key \"colour\""),
        ("bins=many", "bins must be a whole number"),
        ("bins=99", "bins must be in 2..=32"),
        ("alpha", "expected KEY=VALUE"),
        ("alpha=0", "alpha needs --structure sbvh"),
    ] {
        fails(
            &[
                &["cones", "sphere:50", "--out", &out, "--bvh", opt][..],
                &view,
            ]
            .concat(),
            msg,
        );
    }
    fails(
        &[
            &[
                "cones",
                "sphere:50",
                "--out",
                &out,
                "--structure",
                "kdtree",
                "--bvh",
                "bins=4",
            ][..],
            &view,
        ]
        .concat(),
        "only with --structure bvh or sbvh",
    );
}
