//! Each command doing its job: tracers, render, trace, rays, info/export, animate, path tracing,
//! heatmaps, JSON reports.

use super::*;

#[test]
fn tracers_lists_the_registry_with_options_and_counters() {
    let text = String::from_utf8(ok(&["tracers"]).stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), raysift::tracers::REGISTRY.len());
    for (line, e) in lines.iter().zip(raysift::tracers::REGISTRY) {
        assert!(line.starts_with(e.name) && line.contains(e.paper) && line.contains(e.summary));
    }
    let verbose = String::from_utf8(ok(&["tracers", "--verbose"]).stdout).unwrap();
    for e in raysift::tracers::REGISTRY {
        for o in e.options() {
            assert!(
                verbose.contains(o.key) && verbose.contains(o.doc),
                "{}",
                o.key
            );
        }
        for (name, doc) in e.work_counters.iter().chain(e.built_counters) {
            assert!(verbose.contains(name) && verbose.contains(doc), "{name}");
        }
    }
    let v = json(&ok(&["tracers", "--json"]));
    let bvh = v
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["name"] == "bvh")
        .unwrap();
    assert!(bvh["paper"].as_str().unwrap().contains("Wald"));
    assert!(bvh["summary"].is_string());
    let opts = bvh["options"].as_array().unwrap();
    let max_leaf = opts.iter().find(|o| o["key"] == "max_leaf").unwrap();
    assert_eq!(max_leaf["default"], 4);
    assert!(max_leaf["doc"].as_str().unwrap().contains("leaf"));
    assert!(bvh["presets"].as_array().unwrap()[0]["opts"].is_object());
    assert!(bvh["counters"]["built"].as_array().unwrap().len() > 1);
    assert!(bvh["counters"]["work"]
        .as_array()
        .unwrap()
        .iter()
        .any(|c| c["name"] == "ray_tri" && c["doc"].is_string()));
}

#[test]
fn opt_help_prints_the_tracers_options_and_exits_0() {
    // Before any other argument is checked: `trace` would otherwise demand SCENE and --rays.
    for (args, key) in [
        (
            &["trace", "--tracer", "dacrt", "--opt", "help"][..],
            "r_limit",
        ),
        (&["render", "--tracer=bvh", "--opt=help"][..], "max_leaf"),
        (&["animate", "--opt", "help"][..], "max_leaf"),
        (&["trace", "--tracer", "naive", "--opt", "help"][..], "none"),
    ] {
        let out = String::from_utf8(ok(args).stdout).unwrap();
        assert!(out.contains(key), "{args:?}: {out}");
    }
    fails(
        &["trace", "--tracer", "nope", "--opt", "help"],
        "unknown tracer",
    );
}

#[test]
fn render_default_scene_writes_a_png() {
    let d = tmp();
    let out = p(d.path(), "bunny.png");
    let o = ok(&[
        "render", "--tracer", "naive", "--width", "64", "--height", "48", "--out", &out, "--json",
        "--stats",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["triangles"], 16301);
    assert!(
        v["hits"].as_u64().unwrap() > 64 * 48 / 5,
        "the default framing should fill the view: {v}"
    );
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
}

#[test]
fn trace_agrees_between_tracers_through_files() {
    let d = tmp();
    let rays = p(d.path(), "rays.npy");
    ok(&[
        "rays",
        "camera",
        "sphere:2000",
        "--width",
        "40",
        "--height",
        "30",
        "--out",
        &rays,
    ]);
    let random = p(d.path(), "random.npy");
    ok(&[
        "rays",
        "random",
        "sphere:2000",
        "--count",
        "1500",
        "--seed",
        "4",
        "--out",
        &random,
    ]);
    for r in [&rays, &random] {
        let mut outputs = Vec::new();
        for t in tracer_names() {
            // `trace` of these rays with tracer `t` into `out`, plus `extra` options.
            let trace = |out: &str, extra: &[&str]| {
                let mut args = vec!["trace", "sphere:2000", "--rays", r, "--tracer", &t];
                args.extend(["--out", out]);
                args.extend(extra);
                ok(&args)
            };
            let hits = p(d.path(), &format!("hits-{t}.npy"));
            let o = trace(&hits, &["--json", "--threads", "2"]);
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert_eq!(v["tracer"], t.as_str());
            assert_eq!(v["threads"], 2);
            let occ = p(d.path(), &format!("occ-{t}.npy"));
            trace(&occ, &["--occlusion"]);
            // Runs in one process reuse the output buffers: the last run writes what one run does.
            let (hits3, occ3) = (p(d.path(), "hits3.npy"), p(d.path(), "occ3.npy"));
            trace(&hits3, &["--repeat", "3"]);
            trace(&occ3, &["--repeat", "3", "--occlusion"]);
            assert!(
                std::fs::read(&hits3).unwrap() == std::fs::read(&hits).unwrap(),
                "{t}"
            );
            assert!(
                std::fs::read(&occ3).unwrap() == std::fs::read(&occ).unwrap(),
                "{t}"
            );
            outputs.push((
                t,
                std::fs::read(&hits).unwrap(),
                std::fs::read(&occ).unwrap(),
            ));
        }
        for (t, h, o) in &outputs[1..] {
            assert!(
                h == &outputs[0].1,
                "{t} hits.npy differs from {}",
                outputs[0].0
            );
            assert!(
                o == &outputs[0].2,
                "{t} occlusion differs from {}",
                outputs[0].0
            );
        }
    }
}

#[test]
fn secondary_rays_from_hits() {
    let d = tmp();
    let (rays, hits, sh, map) = (
        p(d.path(), "c.npy"),
        p(d.path(), "h.npy"),
        p(d.path(), "s.npy"),
        p(d.path(), "m.npy"),
    );
    ok(&[
        "rays", "camera", "cornell", "--width", "32", "--height", "32", "--out", &rays,
    ]);
    ok(&[
        "trace", "cornell", "--rays", &rays, "--tracer", "naive", "--out", &hits,
    ]);
    ok(&[
        "rays", "shadow", "cornell", "--rays", &rays, "--hits", &hits, "--light", "0,1.9,0",
        "--out", &sh, "--map", &map,
    ]);
    ok(&[
        "rays",
        "bounce",
        "cornell",
        "--rays",
        &rays,
        "--hits",
        &hits,
        "--seed",
        "3",
        "--out",
        &p(d.path(), "b.npy"),
    ]);
    let o = ok(&[
        "trace",
        "cornell",
        "--rays",
        &sh,
        "--tracer",
        "naive",
        "--occlusion",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["rays"].as_u64().unwrap() > 500);
    // Hits from another scene are rejected.
    fails(
        &[
            "rays",
            "shadow",
            "soup:10",
            "--rays",
            &rays,
            "--hits",
            &hits,
            "--light",
            "0,1,0",
            "--out",
            &p(d.path(), "x.npy"),
        ],
        "out of range",
    );
    assert!(!d.path().join("x.npy").exists());
}

#[test]
fn info_and_export() {
    let o = ok(&["info", "cornell", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["triangles"], 32);
    let d = tmp();
    let out = p(d.path(), "t.npy");
    ok(&["export", "sphere:80", "--out", &out]);
    assert_eq!(std::fs::metadata(&out).unwrap().len(), 128 + 80 * 36);
}

/// The meshes of `info --json` (and of `export --meshes`) cover the primitive ids in order.
fn check_meshes(v: &serde_json::Value, triangles: u64) {
    let meshes = v["meshes"].as_array().unwrap();
    let mut next = 0;
    for m in meshes {
        assert!(m["name"].is_string());
        assert_eq!(m["prims"]["start"], next);
        next = m["prims"]["end"].as_u64().unwrap();
        assert_eq!(
            m["triangles"].as_u64().unwrap(),
            next - m["prims"]["start"].as_u64().unwrap()
        );
    }
    assert_eq!(next, triangles);
}

#[test]
fn info_and_export_give_each_meshs_primitive_range() {
    let v = json(&ok(&["info", "cornell", "--json"]));
    assert_eq!(v["meshes"].as_array().unwrap().len(), 8);
    assert_eq!(v["meshes"][6]["name"], "short_block");
    check_meshes(&v, 32);
    let text = String::from_utf8(ok(&["info", "cornell"]).stdout).unwrap();
    assert!(
        text.contains("prims 12..22 (10 triangles)  short_block"),
        "{text}"
    );

    let d = tmp();
    let (tris, meshes) = (p(d.path(), "t.npy"), p(d.path(), "meshes.json"));
    ok(&["export", "cornell", "--out", &tris, "--meshes", &meshes]);
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&meshes).unwrap()).unwrap();
    assert_eq!(m["triangles"], 32);
    check_meshes(&m, 32);
    assert_eq!(m["meshes"], v["meshes"]);
    // --meshes alone is enough.
    std::fs::remove_file(&meshes).unwrap();
    ok(&["export", "cornell", "--meshes", &meshes]);
    assert!(std::path::Path::new(&meshes).exists());
}

#[test]
fn hits_say_which_mesh_and_optionally_the_normal() {
    #[derive(npyz::Deserialize)]
    struct Rec {
        t: f32,
        prim: u32,
        geom: u32,
        #[allow(dead_code)]
        u: f32,
        #[allow(dead_code)]
        v: f32,
        ng: [f32; 3],
    }
    let d = tmp();
    let (rays, hits, plain) = (
        p(d.path(), "r.npy"),
        p(d.path(), "h.npy"),
        p(d.path(), "p.npy"),
    );
    ok(&[
        "rays", "camera", "cornell", "--width", "32", "--height", "32", "--out", &rays,
    ]);
    ok(&[
        "trace",
        "cornell",
        "--rays",
        &rays,
        "--tracer",
        "bvh",
        "--out",
        &hits,
        "--normals",
    ]);
    let scene = raysift::scene::procedural::open("cornell").unwrap();
    let recs: Vec<Rec> = npyz::NpyFile::new(std::fs::File::open(&hits).unwrap())
        .unwrap()
        .into_vec()
        .unwrap();
    assert_eq!(recs.len(), 32 * 32);
    let mut meshes_hit = std::collections::BTreeSet::new();
    for r in &recs {
        if r.prim == u32::MAX {
            assert_eq!((r.geom, r.ng), (u32::MAX, [0.0; 3]));
            assert!(r.t.is_infinite());
            continue;
        }
        assert!(scene
            .mesh_prims(r.geom as usize)
            .contains(&(r.prim as usize)));
        let n = glam::Vec3::from_array(r.ng);
        assert!((n.length() - 1.0).abs() < 1e-5, "{n}");
        assert_eq!(n, scene.normal(r.prim as usize));
        meshes_hit.insert(r.geom);
    }
    assert!(meshes_hit.len() > 3, "{meshes_hit:?}");
    // Without --normals: geom but no ng; both are read back by `rays shadow`.
    ok(&[
        "trace", "cornell", "--rays", &rays, "--tracer", "bvh", "--out", &plain,
    ]);
    let header = String::from_utf8_lossy(&std::fs::read(&plain).unwrap()[..128]).to_string();
    assert!(
        header.contains("'geom'") && !header.contains("'ng'"),
        "{header}"
    );
    for h in [&hits, &plain] {
        ok(&[
            "rays",
            "shadow",
            "cornell",
            "--rays",
            &rays,
            "--hits",
            h,
            "--light",
            "0,1.9,0",
            "--out",
            &p(d.path(), "s.npy"),
        ]);
    }
    let o = raysift(&[
        "trace",
        "cornell",
        "--rays",
        &rays,
        "--out",
        &hits,
        "--normals",
        "--occlusion",
    ]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "--normals has no meaning for occlusion"
    );
}

#[test]
fn animate_writes_frames_and_reports_per_frame_times() {
    let d = tmp();
    let out = p(d.path(), "frames");
    for motion in ["explode", "spin-parts"] {
        let o = ok(&[
            "animate",
            "sphere:300",
            "--motion",
            motion,
            "--frames",
            "3",
            "--tracer",
            "naive",
            "--width",
            "24",
            "--height",
            "16",
            "--out",
            &out,
            "--json",
        ]);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let frames = v["frames"].as_array().unwrap();
        assert_eq!(frames.len(), 3);
        assert!(frames
            .iter()
            .all(|f| f["trace_ms"].as_f64().unwrap() > 0.0 && f["prepare_ms"].is_number()));
        // The geometry changes between frames, so the hit counts do too (explode spreads out).
        assert!(d.path().join("frames/frame_0002.png").exists());
        // Each frame says what changed since the last: everything at first, then explode
        // deforms its one mesh and spin-parts moves every part rigidly.
        let meshes = v["meshes"].as_u64().unwrap();
        assert_eq!(frames[0]["change"], "all");
        for f in &frames[1..] {
            assert_eq!(f["change"], "meshes");
            let (moved, deformed) = (
                f["moved"].as_u64().unwrap(),
                f["deformed"].as_u64().unwrap(),
            );
            match motion {
                "explode" => assert_eq!((moved, deformed), (0, 1)),
                _ => assert_eq!((moved, deformed), (meshes, 0)),
            }
        }
        assert!(v["mean_frame_ms"].as_f64().unwrap() > 0.0);
    }
    usage_fails(
        &["animate", "sphere:300", "--motion", "wobble", "--out", &out],
        "wobble",
    );
}

#[test]
fn path_tracing_reports_every_bounce() {
    let d = tmp();
    let out = p(d.path(), "pt.png");
    let o = ok(&[
        "render",
        "cornell",
        "--tracer",
        "naive",
        "--integrator",
        "path",
        "--spp",
        "2",
        "--bounces",
        "3",
        "--width",
        "24",
        "--height",
        "24",
        "--out",
        &out,
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let b = v["per_bounce"].as_array().unwrap();
    assert_eq!(b.len(), 4);
    assert_eq!(b[0]["rays"], 2 * 24 * 24);
    // Inside the closed-ish box most paths keep bouncing; each depth traces the previous depth's hits.
    for k in 1..4 {
        assert_eq!(b[k]["rays"], b[k - 1]["hits"]);
    }
    assert!(std::fs::metadata(&out).unwrap().len() > 100);
}

#[test]
fn instant_radiosity_takes_samples_per_pixel() {
    let d = tmp();
    let out = p(d.path(), "ir.exr");
    let obj = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/CornellBox-Original.obj"
    );
    let run = |spp: &str| {
        let o = ok(&[
            "render",
            obj,
            "--integrator",
            "instant-radiosity",
            "--vpls",
            "40",
            "--vpl-subset",
            "8",
            "--spp",
            spp,
            "--width",
            "12",
            "--height",
            "10",
            "--out",
            &out,
            "--json",
        ]);
        json(&o)
    };
    let (one, three) = (run("1"), run("3"));
    assert_eq!(three["spp"], 3);
    let hits = |v: &serde_json::Value| v["phase_hits"]["camera"].as_u64().unwrap();
    let rays = |v: &serde_json::Value, pass: &str| {
        let passes = v["passes"].as_array().unwrap();
        let p = passes.iter().find(|p| p["pass"] == pass).unwrap();
        p["rays"].as_u64().unwrap()
    };
    // Photons once; camera rays and shadow rays once per sample.
    assert_eq!(rays(&one, "camera"), 120);
    assert_eq!(rays(&three, "camera"), 360);
    assert_eq!(rays(&three, "shadow"), 8 * hits(&three));
    assert_eq!(
        rays(&three, "photon emission"),
        rays(&one, "photon emission")
    );
    assert!(std::fs::metadata(&out).unwrap().len() > 100);
}

// ---- What a new user ran into (issue 12, item 6): each of these failed before the fix.

/// Width and height of a PNG, from its IHDR chunk.
pub(crate) fn png_size(path: &str) -> (u32, u32) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[1..4], b"PNG");
    let be = |k: usize| u32::from_be_bytes(b[k..k + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn heatmaps_draw_per_ray_cost_with_a_scale() {
    let d = tmp();
    let (w, h) = (48u32, 32u32);
    let (ws, hs) = (w.to_string(), h.to_string());
    let heat = |tracer: &str, kind: &str, out: &str| {
        let o = ok(&[
            "render",
            "sphere:400",
            "--tracer",
            tracer,
            "--heatmap",
            kind,
            "--width",
            &ws,
            "--height",
            &hs,
            "--out",
            out,
            "--json",
        ]);
        (json(&o), String::from_utf8(o.stderr).unwrap())
    };
    // Brute force tests every triangle for every ray.
    let out = p(d.path(), "naive.png");
    let (v, err) = heat("naive", "triangles", &out);
    let tris = v["triangles"].as_u64().unwrap();
    assert_eq!(v["scale"]["min"], tris);
    assert_eq!(v["scale"]["max"], tris);
    assert_eq!(v["scale"]["mean"].as_f64().unwrap(), tris as f64);
    assert!(err.contains(&format!("min {tris}, max {tris}")), "{err}");
    // The BVH does more work where the sphere is than around it; the image is the view plus
    // the bar, as the report says.
    let out = p(d.path(), "bvh.png");
    let (v, err) = heat("bvh", "nodes", &out);
    let (min, max) = (
        v["scale"]["min"].as_u64().unwrap(),
        v["scale"]["max"].as_u64().unwrap(),
    );
    assert!(min < max, "{v}");
    assert!(
        err.contains("nodes per ray") && err.contains("mean"),
        "{err}"
    );
    let (iw, ih) = png_size(&out);
    assert_eq!((iw, ih), (v["image_width"].as_u64().unwrap() as u32, h));
    assert!(iw > w, "a colour bar beside the {w}-pixel view: {iw}");
    assert_eq!(v["width"], w);
    assert_eq!(v["rays"], (w * h) as u64);
    assert!(v["stats"]["work"]["nodes"].as_u64().unwrap() > 0);
    // Every tracer draws (one that records no cost yet draws a scale of 0 to 0).
    for t in tracer_names() {
        heat(&t, "tests", &p(d.path(), &format!("{t}.png")));
    }
    // A heatmap shades nothing and traces no paths.
    let out = p(d.path(), "x.png");
    fails(
        &[
            "render",
            "--heatmap",
            "nodes",
            "--shade",
            "depth",
            "--out",
            &out,
        ],
        "--shade",
    );
    fails(
        &[
            "render",
            "--heatmap",
            "nodes",
            "--integrator",
            "path",
            "--out",
            &out,
        ],
        "path",
    );
    usage_fails(
        &["render", "--heatmap", "bytes", "--out", &out],
        "triangles",
    );
}

#[test]
fn trace_json_times_once_medians_at_the_top_counters_under_stats() {
    let d = tmp();
    let rays = p(d.path(), "rays.npy");
    ok(&[
        "rays",
        "random",
        "sphere:500",
        "--count",
        "300",
        "--out",
        &rays,
    ]);
    let o = ok(&[
        "trace",
        "sphere:500",
        "--rays",
        &rays,
        "--tracer",
        "bvh",
        "--repeat",
        "3",
        "--json",
    ]);
    let v = json(&o);
    // The keys bench/ reads.
    for k in [
        "scene",
        "triangles",
        "tracer",
        "rays",
        "threads",
        "occlusion",
        "prepare_ms",
        "trace_ms",
        "mrays_per_s",
        "hits",
        "tracer_bytes",
        "bytes_per_triangle",
        "prepare_ms_runs",
        "trace_ms_runs",
        "stats",
    ] {
        assert!(!v[k].is_null(), "{k} missing: {v}");
    }
    let runs = |k: &str| -> Vec<f64> {
        let mut r: Vec<f64> = v[k]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        r.sort_by(f64::total_cmp);
        r
    };
    assert_eq!(
        v["trace_ms"].as_f64().unwrap(),
        runs("trace_ms_runs")[1],
        "the median"
    );
    assert_eq!(
        v["prepare_ms"].as_f64().unwrap(),
        runs("prepare_ms_runs")[1]
    );
    // No second trace_ms: stats has the last run's counters only.
    let st = v["stats"].as_object().unwrap();
    assert!(
        !st.contains_key("trace_ms") && !st.contains_key("prepare_ms"),
        "{v}"
    );
    assert_eq!(st["rays"], 300);
    assert!(st["work"]["ray_tri"].as_u64().unwrap() > 0);
    assert!(st["built"]["nodes"].as_u64().unwrap() > 0);
}

/// Writes the hand-built animated rig (`raysift::testkit::gltf_rig`) as `name` in `dir`.
fn write_rig(dir: &Path, name: &str, rig: &raysift::testkit::gltf_rig::Rig) -> String {
    let path = p(dir, name);
    std::fs::write(&path, rig.glb()).unwrap();
    path
}

#[test]
fn animate_plays_a_gltf_animation() {
    let d = tmp();
    let rig = write_rig(d.path(), "rig.glb", &raysift::testkit::gltf_rig::Rig::new());
    let out = p(d.path(), "frames");
    let o = ok(&[
        "animate", &rig, "--frames", "4", "--tracer", "bvh", "--width", "24", "--height", "16",
        "--out", &out, "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["motion"], "gltf");
    assert_eq!(v["animation"], "wave");
    assert_eq!(v["duration_s"], 2.0);
    let frames = v["frames"].as_array().unwrap();
    // Frame f at f · 2 s / 4: 0, 0.5, 1, 1.5 s.
    let times: Vec<f64> = frames.iter().map(|f| f["time"].as_f64().unwrap()).collect();
    assert_eq!(times, [0.0, 0.5, 1.0, 1.5]);
    // The quad deforms every frame; the STEP-rotated triangle moves only at 1 s.
    let md: Vec<(u64, u64)> = frames[1..]
        .iter()
        .map(|f| {
            (
                f["moved"].as_u64().unwrap(),
                f["deformed"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(md, [(0, 1), (1, 1), (0, 1)]);
    assert!(d.path().join("frames/frame_0003.png").exists());
    // By index, and the explode motion still plays on the same file.
    ok(&[
        "animate",
        &rig,
        "--animation",
        "0",
        "--frames",
        "2",
        "--no-images",
    ]);
    let o = ok(&[
        "animate",
        &rig,
        "--motion",
        "explode",
        "--frames",
        "2",
        "--no-images",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["motion"], "explode");
}
