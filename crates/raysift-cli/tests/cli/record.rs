//! `render --record-rays`: the files hold every ray the render traced and the tracer's answers,
//! so another engine (the Embree peer) can trace the same workload.

use super::*;

#[test]
fn record_rays_writes_the_renders_rays_and_answers() {
    let d = tmp();
    let dir = p(d.path(), "rec");
    let img = p(d.path(), "dist.png");
    let obj = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/CornellBox-Original.obj"
    );
    let v = json(&ok(&[
        "render",
        obj,
        "--integrator",
        "distribution",
        "--aa",
        "2",
        "--light-samples",
        "4",
        "--width",
        "16",
        "--height",
        "12",
        "--tracer",
        "kdtree",
        "--json",
        "--out",
        &img,
        "--record-rays",
        &dir,
    ]));
    let pass_rays = |name: &str| {
        let ps = v["passes"].as_array().unwrap();
        ps.iter()
            .find(|p| p["pass"] == name)
            .map_or(0, |p| p["rays"].as_u64().unwrap())
    };
    let calls: serde_json::Value =
        serde_json::from_slice(&std::fs::read(p(Path::new(&dir), "calls.json")).unwrap()).unwrap();
    let calls = calls.as_array().unwrap();
    let total = |kind: &str| -> u64 {
        calls
            .iter()
            .filter(|c| c["kind"] == kind)
            .map(|c| c["rays"].as_u64().unwrap())
            .sum()
    };
    assert_eq!(calls[0]["kind"], "intersect");
    assert_eq!(calls[0]["layout"], "pixel-samples 16x12x4");
    assert_eq!(calls[0]["rays"], 16 * 12 * 4);
    assert!(calls
        .iter()
        .any(|c| c["kind"] == "occluded" && c["layout"] == "origin-grids 4"));
    assert_eq!(total("occluded"), pass_rays("shadow"));
    assert!(total("occluded") > 0);
    assert_eq!(
        total("intersect"),
        pass_rays("primary") + pass_rays("reflection")
    );
    // Each call's rows follow the previous call's of its kind.
    let mut next = std::collections::HashMap::new();
    for c in calls {
        let at = next.entry(c["kind"].as_str().unwrap()).or_insert(0u64);
        assert_eq!(c["start"].as_u64().unwrap(), *at);
        *at += c["rays"].as_u64().unwrap();
    }
    // The recorded answers are the render tracer's; the brute-force tracer gives the same bytes.
    let f = |name: &str| p(Path::new(&dir), name);
    let (occ, hits) = (p(d.path(), "occ.npy"), p(d.path(), "hits.npy"));
    let orays = f("occluded-rays.npy");
    let irays = f("intersect-rays.npy");
    ok(&[
        "trace",
        obj,
        "--rays",
        &orays,
        "--occlusion",
        "--tracer",
        "naive",
        "--out",
        &occ,
    ]);
    ok(&[
        "trace", obj, "--rays", &irays, "--tracer", "naive", "--out", &hits,
    ]);
    assert!(std::fs::read(&occ).unwrap() == std::fs::read(f("occluded.npy")).unwrap());
    assert!(std::fs::read(&hits).unwrap() == std::fs::read(f("intersect-hits.npy")).unwrap());
    let blocked = std::fs::read(f("occluded.npy")).unwrap();
    assert!(blocked
        .iter()
        .rev()
        .take(total("occluded") as usize)
        .any(|&b| b == 1));
}

#[test]
fn record_rays_into_a_file_is_refused_before_rendering() {
    let d = tmp();
    let file = p(d.path(), "not-a-folder");
    std::fs::write(&file, "x").unwrap();
    let img = p(d.path(), "x.png");
    fails(
        &[
            "render",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
            &img,
            "--record-rays",
            &file,
        ],
        "--record-rays",
    );
    assert!(!Path::new(&img).exists());
}
