//! Bad input and usage errors: a clear message naming the argument or file and the place, a
//! non-zero exit, no output left behind; and what new users ran into.

use super::*;

#[test]
fn bad_input_is_a_clean_error_without_output() {
    let d = tmp();
    let out = p(d.path(), "out.npy");
    let rays = p(d.path(), "rays.npy");
    ok(&[
        "rays",
        "camera",
        "sphere:80",
        "--width",
        "4",
        "--height",
        "4",
        "--out",
        &rays,
    ]);

    fails(
        &[
            "trace",
            "sphere:80",
            "--rays",
            &rays,
            "--tracer",
            "nope",
            "--out",
            &out,
        ],
        "unknown tracer",
    );
    fails(
        &[
            "trace",
            "sphere:80",
            "--rays",
            &p(d.path(), "missing.npy"),
            "--tracer",
            "naive",
            "--out",
            &out,
        ],
        "missing.npy",
    );
    fails(
        &[
            "trace",
            "sphere:abc",
            "--rays",
            &rays,
            "--tracer",
            "naive",
            "--out",
            &out,
        ],
        "sphere:abc",
    );
    fails(&["info", &p(d.path(), "mesh.xyz")], "unknown scene format");

    // A truncated rays file.
    let bytes = std::fs::read(&rays).unwrap();
    let cut = p(d.path(), "cut.npy");
    std::fs::write(&cut, &bytes[..bytes.len() - 7]).unwrap();
    fails(
        &[
            "trace",
            "sphere:80",
            "--rays",
            &cut,
            "--tracer",
            "naive",
            "--out",
            &out,
        ],
        "cut.npy",
    );
    // Garbage.
    let junk = p(d.path(), "junk.npy");
    std::fs::write(&junk, b"not numpy at all").unwrap();
    fails(
        &[
            "trace",
            "sphere:80",
            "--rays",
            &junk,
            "--tracer",
            "naive",
            "--out",
            &out,
        ],
        "junk.npy",
    );

    // A malformed mesh file, a truncated one and an empty one.
    let off = p(d.path(), "bad.off");
    std::fs::write(&off, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n").unwrap();
    fails(
        &[
            "trace", &off, "--rays", &rays, "--tracer", "naive", "--out", &out,
        ],
        "bad.off",
    );
    let empty = p(d.path(), "empty.ply");
    std::fs::write(&empty, "").unwrap();
    fails(&["info", &empty], "empty.ply");

    // Zero rays.
    let zero = p(d.path(), "zero.npy");
    ok(&[
        "rays",
        "random",
        "sphere:80",
        "--count",
        "1",
        "--out",
        &zero,
    ]);
    raysift::rays::npy::write_rays(&zero, &raysift::RayBatch::default()).unwrap();
    fails(
        &[
            "trace",
            "sphere:80",
            "--rays",
            &zero,
            "--tracer",
            "naive",
            "--out",
            &out,
        ],
        "no rays",
    );

    // Bad camera and arguments.
    fails(
        &[
            "rays",
            "camera",
            "sphere:80",
            "--eye",
            "0,0,0",
            "--look",
            "0,0,0",
            "--out",
            &out,
        ],
        "camera",
    );
    fails(
        &[
            "render",
            "sphere:80",
            "--tracer",
            "naive",
            "--width",
            "0",
            "--out",
            &p(d.path(), "x.png"),
        ],
        "width",
    );
    fails(
        &[
            "render",
            "sphere:80",
            "--tracer",
            "naive",
            "--opt",
            "foo=1",
            "--out",
            &p(d.path(), "x.png"),
        ],
        "option",
    );

    assert!(
        !PathBuf::from(&out).exists(),
        "no output file may be left behind"
    );
    assert!(!d.path().join("x.png").exists());
    let leftovers: Vec<_> = std::fs::read_dir(d.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".raysift-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn usage_errors_print_claps_whole_message() {
    // The missing argument is named, not just "the following required arguments...".
    let e = usage_fails(&["trace", "teapot.obj"], "--rays");
    assert!(e.contains("required"), "{e}");
    // The allowed values are listed.
    let e = usage_fails(&["render", "--integrator", "foo"], "foo");
    assert!(e.contains("raycast") && e.contains("path"), "{e}");
    let e = usage_fails(&["render", "--shade", "flat"], "flat");
    assert!(e.contains("diffuse") && e.contains("depth"), "{e}");
    let e = usage_fails(&["animate", "--motion", "wobble"], "wobble");
    assert!(e.contains("explode") && e.contains("spin-parts"), "{e}");
}

#[test]
fn no_arguments_print_the_help() {
    let o = raysift(&[]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !err.contains("error: Batch"),
        "the description is not an error: {err}"
    );
    for cmd in [
        "Usage:", "info", "rays", "trace", "render", "animate", "export", "tracers",
    ] {
        assert!(err.contains(cmd), "help should list {cmd}: {err}");
    }
}

#[test]
fn images_other_than_png_or_exr_are_refused_before_any_work() {
    let d = tmp();
    for name in ["x.exr", "x.jpg", "x.PNG.tiff", "noext"] {
        let out = p(d.path(), name);
        // The scene does not exist: the image path is checked first.
        let e = fails(
            &["render", &p(d.path(), "missing.obj"), "--out", &out],
            name,
        );
        assert!(e.contains(".png"), "{e}");
        let e = fails(
            &["render", "sphere:80", "--heatmap", "nodes", "--out", &out],
            name,
        );
        // (.exr is refused here because a heatmap is not radiance.)
        assert!(e.contains(".png"), "{e}");
        assert!(!d.path().join(name).exists(), "{name} written");
    }
    // Upper case is still PNG.
    let out = p(d.path(), "X.PNG");
    ok(&[
        "render",
        "sphere:80",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        &out,
    ]);
    assert_eq!(&std::fs::read(&out).unwrap()[1..4], b"PNG");
}

#[test]
fn spp_bounces_shade_and_light_belong_to_their_integrator() {
    let d = tmp();
    let out = p(d.path(), "x.png");
    let base = [
        "render",
        "sphere:80",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        &out,
    ];
    let with = |extra: &[&'static str]| {
        let mut v = base.to_vec();
        v.extend_from_slice(extra);
        v
    };
    usage_fails(&with(&["--integrator", "path", "--spp", "0"]), "--spp");
    fails(&with(&["--spp", "2"]), "--spp");
    fails(&with(&["--bounces", "2"]), "--bounces");
    fails(
        &with(&["--integrator", "path", "--shade", "depth"]),
        "--shade",
    );
    fails(
        &with(&["--integrator", "path", "--light", "1,2,3"]),
        "--light",
    );
    fails(&with(&["--shade", "normal", "--light", "1,2,3"]), "--light");
    assert!(!d.path().join("x.png").exists());
    ok(&with(&[
        "--integrator",
        "path",
        "--spp",
        "1",
        "--bounces",
        "1",
    ]));
    ok(&with(&["--shade", "diffuse", "--light", "-1,2,3"]));
}

#[test]
fn animate_without_images_needs_no_out() {
    let o = ok(&[
        "animate",
        "sphere:200",
        "--frames",
        "2",
        "--no-images",
        "--tracer",
        "naive",
        "--width",
        "8",
        "--height",
        "8",
        "--json",
    ]);
    assert_eq!(json(&o)["frames"].as_array().unwrap().len(), 2);
    // Images still need a folder.
    usage_fails(&["animate", "sphere:200", "--frames", "2"], "--out");
}

#[test]
fn trace_without_out_says_it_wrote_nothing() {
    let d = tmp();
    let rays = p(d.path(), "rays.npy");
    ok(&[
        "rays",
        "random",
        "sphere:80",
        "--count",
        "50",
        "--out",
        &rays,
    ]);
    for extra in [&[][..], &["--json"], &["--occlusion"]] {
        let mut args = vec!["trace", "sphere:80", "--rays", &rays, "--tracer", "naive"];
        args.extend_from_slice(extra);
        let err = String::from_utf8(ok(&args).stderr).unwrap();
        assert!(err.contains("no --out") && err.contains("written"), "{err}");
    }
    let err = String::from_utf8(
        ok(&[
            "trace",
            "sphere:80",
            "--rays",
            &rays,
            "--out",
            &p(d.path(), "h.npy"),
        ])
        .stderr,
    )
    .unwrap();
    assert!(!err.contains("no --out"), "{err}");
}

#[test]
fn errors_name_the_users_path_never_a_temporary_file() {
    let d = tmp();
    let rays = p(d.path(), "rays.npy");
    ok(&[
        "rays",
        "random",
        "sphere:80",
        "--count",
        "10",
        "--out",
        &rays,
    ]);
    let missing = d.path().join("no-such-folder");
    let png = missing.join("x.png").display().to_string();
    let hits = missing.join("h.npy").display().to_string();
    for (args, name) in [
        (
            vec![
                "render",
                "sphere:80",
                "--width",
                "8",
                "--height",
                "8",
                "--out",
                &png,
            ],
            "x.png",
        ),
        (
            vec!["trace", "sphere:80", "--rays", &rays, "--out", &hits],
            "h.npy",
        ),
        (vec!["export", "sphere:80", "--out", &hits], "h.npy"),
    ] {
        let e = fails(&args, name);
        assert!(
            e.contains("no-such-folder") && !e.contains(".raysift-"),
            "{e}"
        );
    }
    // A folder given as the output file.
    let dir = d.path().display().to_string();
    let e = fails(
        &["trace", "sphere:80", "--rays", &rays, "--out", &dir],
        "folder",
    );
    assert!(!e.contains(".raysift-"), "{e}");
}

#[test]
fn float64_rays_are_converted() {
    let d = tmp();
    let (r32, r64) = (p(d.path(), "r32.npy"), p(d.path(), "r64.npy"));
    ok(&[
        "rays",
        "camera",
        "sphere:500",
        "--width",
        "16",
        "--height",
        "12",
        "--out",
        &r32,
    ]);
    // The same rays as numpy writes them by default: float64, here flat (N, 8).
    let f = npyz::NpyFile::new(std::fs::File::open(&r32).unwrap()).unwrap();
    let v: Vec<f32> = f.into_vec().unwrap();
    let mut w = {
        use npyz::WriterBuilder;
        npyz::WriteOptions::<f64>::new()
            .default_dtype()
            .shape(&[(v.len() / 8) as u64, 8])
            .writer(std::fs::File::create(&r64).unwrap())
            .begin_nd()
            .unwrap()
    };
    w.extend(v.iter().map(|&x| x as f64)).unwrap();
    w.finish().unwrap();
    let (h32, h64) = (p(d.path(), "h32.npy"), p(d.path(), "h64.npy"));
    for (r, h) in [(&r32, &h32), (&r64, &h64)] {
        ok(&[
            "trace",
            "sphere:500",
            "--rays",
            r,
            "--tracer",
            "bvh",
            "--out",
            h,
        ]);
    }
    assert!(std::fs::read(&h32).unwrap() == std::fs::read(&h64).unwrap());
}

#[test]
fn unknown_options_list_the_valid_ones() {
    let d = tmp();
    let rays = p(d.path(), "rays.npy");
    ok(&[
        "rays",
        "random",
        "sphere:80",
        "--count",
        "10",
        "--out",
        &rays,
    ]);
    for (tracer, valid) in [("bvh", "max_leaf"), ("dacrt", "r_limit")] {
        let e = fails(
            &[
                "trace",
                "sphere:80",
                "--rays",
                &rays,
                "--tracer",
                tracer,
                "--opt",
                "nope=1",
            ],
            "nope",
        );
        assert!(e.contains(valid) && e.contains("tracers --verbose"), "{e}");
    }
    fails(
        &[
            "trace",
            "sphere:80",
            "--rays",
            &rays,
            "--tracer",
            "naive",
            "--opt",
            "nope=1",
        ],
        "takes no options",
    );
}

/// Renderer arguments: a zero-area or negative-power light, a malformed light, a distribution
/// render without any light, flags of another integrator: one line naming the flag, exit 2,
/// no image written.
#[test]
fn render_light_and_integrator_errors_write_nothing() {
    let d = tmp();
    let out = p(d.path(), "img.png");
    let base = [
        "render",
        "sphere:20",
        "--width",
        "8",
        "--height",
        "8",
        "--out",
        &out,
    ];
    let with = |extra: &[&str]| -> Vec<String> {
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    let run = |extra: &[&str], needle: &str| {
        let a = with(extra);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        fails(&a, needle);
        assert!(!Path::new(&out).exists(), "{extra:?} wrote {out}");
    };
    let dist = ["--integrator", "distribution"];
    run(
        &[&dist[..], &["--area-light", "0,2,0,0,10"]].concat(),
        "zero area",
    );
    run(
        &[&dist[..], &["--area-light", "0,2,0,1,-3"]].concat(),
        "non-negative",
    );
    run(
        &[&dist[..], &["--area-light", "0,2,0,1"]].concat(),
        "--area-light",
    );
    run(
        &[&dist[..], &["--area-light", "0,x,0,1,1"]].concat(),
        "--area-light",
    );
    run(&dist, "needs a light");
    run(&[&dist[..], &["--spp", "4"]].concat(), "--spp");
    run(&["--aa", "2"], "--aa applies to --integrator distribution");
    run(
        &[&dist[..], &["--no-mis"]].concat(),
        "--no-mis applies to --integrator path only",
    );
    run(&["--seed", "2"], "--seed");
    run(
        &["--vpls", "10"],
        "--vpls applies to --integrator instant-radiosity",
    );
    run(&["--integrator", "instant-radiosity"], "needs a light");
    run(
        &["--integrator", "path", "--light-samples", "2"],
        "--light-samples",
    );
    // And the good case writes the image.
    ok(&with(
        &[
            &dist[..],
            &["--area-light", "0,2,0,1,10", "--light-samples", "2"],
        ]
        .concat(),
    )
    .iter()
    .map(String::as_str)
    .collect::<Vec<_>>());
    assert!(Path::new(&out).exists());
}

#[test]
fn bad_gltf_animations_fail_without_frames() {
    use raysift::testkit::gltf_rig::{at, Rig};
    let d = tmp();
    let out = p(d.path(), "frames");
    let run = |name: &str, rig: &Rig, needle: &str| {
        let path = p(d.path(), name);
        std::fs::write(&path, rig.glb()).unwrap();
        let e = fails(&["animate", &path, "--frames", "2", "--out", &out], needle);
        assert!(e.contains(&path), "{e}");
        assert!(!Path::new(&out).exists(), "{name}: nothing written");
    };
    let mut r = Rig::new();
    r.json["animations"][0]["channels"] = serde_json::json!([]);
    run(
        "empty.glb",
        &r,
        "animations[0].channels: the animation has no channels",
    );
    let mut r = Rig::new();
    r.json["animations"][0]["channels"][0]["target"]["node"] = 40.into();
    run(
        "missing-node.glb",
        &r,
        "animations[0].channels[0].target.node",
    );
    let mut r = Rig::new();
    r.json["accessors"][9]["count"] = 1.into();
    run(
        "count.glb",
        &r,
        "animations[0].samplers[2].output: accessor 9 has 1 values, 2 expected",
    );
    let mut r = Rig::new();
    r.json["accessors"][4]["count"] = 2.into();
    run(
        "weights.glb",
        &r,
        "attributes.WEIGHTS_0: accessor 4 has 2 elements but POSITION has 4",
    );
    let mut r = Rig::new();
    r.set_f32(at::ROT_STEP + 16, f32::NAN);
    run(
        "nan.glb",
        &r,
        "animations[0].samplers[2].output (accessors[9], element 1): non-finite",
    );
    // Arguments that do not fit the file.
    let rig = p(d.path(), "rig.glb");
    std::fs::write(&rig, Rig::new().glb()).unwrap();
    fails(
        &["animate", &rig, "--animation", "run", "--no-images"],
        "0 (\"wave\")",
    );
    fails(
        &["animate", "sphere:80", "--motion", "gltf", "--no-images"],
        "--motion gltf",
    );
    let mut r = Rig::new();
    r.json.as_object_mut().unwrap().remove("animations");
    let still = p(d.path(), "still.glb");
    std::fs::write(&still, r.glb()).unwrap();
    fails(
        &["animate", &still, "--motion", "gltf", "--no-images"],
        "has no animations",
    );
}
