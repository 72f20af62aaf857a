//! Fig. 8 of Mora 2011 for raysift's `dacrt`: counters and times for Basic (ray mode), Conic
//! packets and Conic + 1 light (shadow rays to a point light), on a scene spec, camera rays from
//! `Camera::framing`. Three versions of the packet rows: the paper's (camera tiles bounded by
//! cones and flushed to rays, shadow rays in light cones: `screen_cull=false pixel_cull=false
//! pixel_leaf=false max_shadow_cone_deg=1`), screen-space and pixel culling with the paper's
//! flushes (`pixel_leaf=false`), and raysift's defaults (the same culling ending in tile
//! leaves); shadow rays are traced as rays in the last two.
//!
//! `cargo run --release -p raysift --example dacrt_counts -- sphere:1000000 [W H] [key=value ...]`
//! (options are passed to every dacrt run; `naive=1` also times the brute-force tracer on a
//! 1/64 subsample of the camera rays and extrapolates).

use raysift::rays::generate::shadow_rays;
use raysift::rays::Camera;
use raysift::scene::procedural;
use raysift::{tracers, Stats};
use std::time::Instant;

fn fmt(n: u64) -> String {
    match n {
        n if n >= 10_000_000 => format!("{:.1} M", n as f64 / 1e6),
        n if n >= 1_000_000 => format!("{:.2} M", n as f64 / 1e6),
        n if n >= 10_000 => format!("{:.1} K", n as f64 / 1e3),
        n => format!("{n}"),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let spec = args.first().map(String::as_str).unwrap_or("sphere:1000000");
    let nums: Vec<u32> = args[1..].iter().filter_map(|a| a.parse().ok()).collect();
    let (w, h) = (*nums.first().unwrap_or(&1280), *nums.get(1).unwrap_or(&800));
    let mut extra: Vec<(String, String)> = args[1..]
        .iter()
        .filter_map(|a| a.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let naive_too = extra.iter().any(|(k, _)| k == "naive");
    extra.retain(|(k, _)| k != "naive");

    let t0 = Instant::now();
    let scene = procedural::open(spec).expect("scene");
    let load_ms = t0.elapsed().as_secs_f64() * 1e3;
    let b = scene.bounds();
    let cam = Camera::framing(&b, 45.0, w as f32 / h as f32);
    let rays = cam.rays(w, h);
    // A point light above and in front of the scene.
    let light = b.center() + b.extent() * glam::Vec3::new(0.6, 1.2, 0.9);
    println!(
        "scene {spec}: {} triangles (generated in {load_ms:.0} ms), {w}x{h} = {} camera rays, {} rayon threads",
        scene.len(),
        rays.len(),
        rayon::current_num_threads()
    );

    let make = |opts: &[(&str, &str)]| {
        let mut o = extra.clone();
        for (k, v) in opts {
            if !o.iter().any(|(key, _)| key == k) {
                o.push((k.to_string(), v.to_string()));
            }
        }
        let mut t = tracers::create("dacrt", &o).expect("options");
        let p = t.prepare_timed(&scene).unwrap();
        (t, p)
    };
    let mut cols: Vec<(&str, Stats, f64)> = Vec::new();
    // Basic: ray mode.
    let (t, p) = make(&[("mode", "ray")]);
    println!(
        "prepare (per-axis min/max lists): {:.1} ms, {} bytes held",
        p.prepare_ms,
        t.bytes()
    );
    let (_, s) = t.intersect_timed(&scene, &rays).unwrap();
    cols.push(("Basic (ray)", s.clone(), p.prepare_ms + s.trace_ms));
    // Conic packets and Conic + 1 light (camera pass plus shadow pass, occlusion), as in the
    // paper, then with raysift's defaults.
    let mut shadow = raysift::RayBatch::default();
    for (packets, light_pass, shadow_pass, opts) in [
        (
            "Conic packets",
            "Conic + 1 light",
            "(shadow pass)",
            [
                ("mode", "packet"),
                ("screen_cull", "false"),
                ("pixel_cull", "false"),
                ("pixel_leaf", "false"),
                ("max_shadow_cone_deg", "1"),
            ],
        ),
        (
            "Screen-culled",
            "Screen + 1 light",
            "(shadow rays)",
            [
                ("mode", "packet"),
                ("screen_cull", "true"),
                ("pixel_cull", "true"),
                ("pixel_leaf", "false"),
                ("max_shadow_cone_deg", "0"),
            ],
        ),
        (
            "Tile leaves",
            "Tiles + 1 light",
            "(shadow rays)",
            [
                ("mode", "packet"),
                ("screen_cull", "true"),
                ("pixel_cull", "true"),
                ("pixel_leaf", "true"),
                ("max_shadow_cone_deg", "0"),
            ],
        ),
    ] {
        let (t, p) = make(&opts);
        let (hits, s) = t.intersect_timed(&scene, &rays).unwrap();
        cols.push((packets, s.clone(), p.prepare_ms + s.trace_ms));
        shadow = shadow_rays(&scene, &rays, &hits, light).0;
        let (_, s2) = t.occluded_timed(&scene, &shadow).unwrap();
        let sum = s.clone() + s2.clone();
        cols.push((light_pass, sum, p.prepare_ms + s.trace_ms + s2.trace_ms));
        cols.push((shadow_pass, s2.clone(), s2.trace_ms));
    }
    // The random-ray mode on camera rays, for reference.
    let (t, p) = make(&[("mode", "random")]);
    let (_, s) = t.intersect_timed(&scene, &rays).unwrap();
    cols.push(("Random mode", s.clone(), p.prepare_ms + s.trace_ms));
    // Incoherent rays: as many uniformly random rays in the scene box, random mode (auto).
    let random = raysift::rays::generate::random_in_box(&b, rays.len(), 1);
    let (_, s) = t.intersect_timed(&scene, &random).unwrap();
    cols.push(("Random rays", s.clone(), p.prepare_ms + s.trace_ms));

    println!(
        "{:<16} {:>10} {:>10} {:>10} {:>11} {:>11} {:>10} {:>10} {:>10}",
        "", "ms", "fps", "Ray/Box", "Cone/Box", "Tri/Box", "Ray/Tri", "Nodes", "Leaves"
    );
    for (name, s, ms) in &cols {
        println!(
            "{:<16} {:>10.1} {:>10.2} {:>10} {:>11} {:>11} {:>10} {:>10} {:>10}",
            name,
            ms,
            1e3 / ms,
            fmt(s.work.get("ray_box")),
            fmt(s.work.get("cone_box")),
            fmt(s.work.get("tri_box")),
            fmt(s.work.get("ray_tri")),
            fmt(s.work.get("nodes")),
            fmt(s.work.get("leaves"))
        );
    }
    println!("shadow rays: {}", shadow.len());
    if naive_too {
        // Every 64th camera ray, timed with the brute-force tracer, extrapolated.
        let mut sub = raysift::RayBatch::default();
        for i in (0..rays.len()).step_by(64) {
            sub.push(rays.get(i));
        }
        let n_tris = scene.len();
        let mut n = tracers::create("naive", &[]).unwrap();
        n.prepare(&scene).unwrap();
        let (_, s) = n.intersect_timed(&scene, &sub).unwrap();
        println!(
            "naive: {:.1} ms for {} rays x {} triangles, about {:.0} ms for all {} camera rays (x64)",
            s.trace_ms,
            sub.len(),
            n_tris,
            s.trace_ms * 64.0,
            rays.len()
        );
    }
}
