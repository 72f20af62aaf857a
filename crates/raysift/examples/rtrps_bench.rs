//! RTRPS (Suzuki 2010) measurements for BENCHMARKS.md § RTRPS (issue #14).
//!
//! `cargo run --release -p raysift --example rtrps_bench -- table3`: spheres, leaf spheres and
//! triangles per leaf for the bunny, Sponza and the dragon (leaf sizes 1 and 2, both centre rules).
//! `... -- fig11 [scene] [origins] [shadow]`: plane/sphere tests split as Fig. 11 (all planes,
//! culling, tree, both; flat inner spheres, no depth cull, as the paper), then ours (binary
//! levels, then the depth cull) on 16×16 area-light shadow grids and (unless `shadow`) 8×8
//! hemisphere bounce grids from camera hits.
//! `... -- table5 [scene] [origins]`: the same shadow grids timed: rtrps (planes) vs its random-ray
//! mode vs `bvh` and `dacrt` (occlusion), alternating, medians of 3 (`RTRPS_ONLY=a,b`: only the
//! first contender and those whose names contain `a` or `b`).
//! `... -- crossover [scene] [origins]`: shadow grids of side 1…32 from the same points: per ray,
//! ray-planes against random rays and `bvh` (Fig. 10's question: from which group size).
//! `... -- table6 [scene] [frames]`: first hit at 1024²: update + trace per frame under
//! `spin-parts` (a `.glb` scene plays its own animation), rtrps vs `bvh` rebuild, `bvh
//! update=refit`, `dacrt` and, when `bench/target/release/embree-peer` is built, Embree's low
//! and medium builds with 16-ray packets on the same rays.
//! `[scene]` is a path or a procedural spec; default the bunny from shared/scenes.

use glam::Vec3;
use raysift::rays::{generate, Camera, Ray, RayBatch, RayLayout};
use raysift::scene::animate::{Animation, Motion};
use raysift::scene::{procedural, Scene};
use raysift::tracers;
use std::time::Instant;

fn open(spec: &str) -> Scene {
    let shared = [
        "../shared/scenes",
        "../../shared/scenes",
        "/work/shared/scenes",
    ]
    .iter()
    .map(std::path::PathBuf::from)
    .find(|p| p.is_dir());
    if let Some(dir) = shared {
        let p = dir.join(spec);
        if p.exists() {
            return raysift::scene::load(&p).expect("load");
        }
    }
    procedural::open(spec).expect("scene")
}

/// (label, registry name, options).
type Contender = (&'static str, &'static str, Vec<(String, String)>);

fn opts(s: &[(&str, &str)]) -> Vec<(String, String)> {
    s.iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// Camera hits at 256² and, from every `step`-th, a 16×16 shadow grid towards a square light
/// above the scene and an 8×8 cosine hemisphere grid.
fn groups(scene: &Scene, origins: usize) -> (RayBatch, RayBatch) {
    shadow_and_bounce(scene, origins, 16)
}

/// [`groups`] with `side`×`side` shadow grids over the same light square.
fn shadow_and_bounce(scene: &Scene, origins: usize, side: usize) -> (RayBatch, RayBatch) {
    let b = scene.bounds();
    let cam = Camera::framing(&b, 45.0, 1.0).rays(256, 256);
    let mut naive = tracers::create("bvh", &[]).unwrap();
    naive.prepare(scene).unwrap();
    let (hits, _) = naive.intersect_timed(scene, &cam).unwrap();
    let hit: Vec<usize> = (0..cam.len()).filter(|&i| hits.is_hit(i)).collect();
    let step = (hit.len() / origins.max(1)).max(1);
    let eps = generate::surface_offset(scene);
    let e = b.extent();
    let centre = b.center() + Vec3::new(0.3 * e.x, 1.2 * e.y, 0.4 * e.z);
    let (mut sh, mut bo) = (Vec::new(), Vec::new());
    for &i in hit.iter().step_by(step) {
        let (p, n) = generate::hit_frame(scene, &cam, &hits, i);
        let o = p + n * eps;
        let (k, mid) = (side as f32, (side as f32 - 1.0) / 2.0);
        for r in 0..side {
            for c in 0..side {
                let y = centre
                    + Vec3::new(
                        (c as f32 - mid) / k * 0.3 * e.x,
                        0.0,
                        (r as f32 - mid) / k * 0.3 * e.z,
                    );
                sh.push(Ray {
                    origin: o,
                    dir: y - o,
                    tmin: 0.0,
                    tmax: 1.0,
                });
            }
        }
        for c in 0..64 {
            let (a, bb) = ((c % 8) as f32 + 0.5, (c / 8) as f32 + 0.5);
            bo.push(Ray {
                origin: o,
                dir: generate::cosine_direction(n, a / 8.0, bb / 8.0),
                tmin: 0.0,
                tmax: f32::INFINITY,
            });
        }
    }
    let mut sh = RayBatch::from_rays(sh);
    sh.layout = RayLayout::OriginGrids { side: side as u32 };
    let mut bo = RayBatch::from_rays(bo);
    bo.layout = RayLayout::OriginGrids { side: 8 };
    (sh, bo)
}

fn table3() {
    println!("| scene | triangles | leaf_size | centre | spheres | parts | inner | leaves | triangles per leaf | build ms |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for spec in ["bun_zipper.ply", "sponza.obj.gz", "dragon_vrip.ply.gz"] {
        let scene = open(spec);
        for (ls, centre) in [("1", "box"), ("2", "box"), ("2", "mean"), ("4", "box")] {
            let mut t =
                tracers::create("rtrps", &opts(&[("leaf_size", ls), ("centre", centre)])).unwrap();
            let st = t.prepare_timed(&scene).unwrap();
            let g = |k: &str| st.built.get(k);
            println!(
                "| {spec} | {} | {ls} | {centre} | {} | {} | {} | {} | {:.2} | {:.0} |",
                scene.len(),
                g("spheres"),
                g("parts"),
                g("inner"),
                g("leaves"),
                g("triangles") as f64 / g("leaves") as f64,
                st.prepare_ms
            );
        }
    }
}

fn fig11(spec: &str, origins: usize, shadow_only: bool) {
    let scene = open(spec);
    let (sh, bo) = groups(&scene, origins);
    println!(
        "scene {spec} ({} triangles): {} shadow rays (16x16 grids), {} bounce rays (8x8 grids)",
        scene.len(),
        sh.len(),
        bo.len()
    );
    println!("| rays | config | centre | outline | internal | total | vs all planes | spheres visited | culled | depth culled | rays reproduced | tri tests | leaves edge-culled |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let sets = [("shadow 16x16", &sh, true), ("bounce 8x8", &bo, false)];
    for (what, rays, occl) in sets.into_iter().take(if shadow_only { 1 } else { 2 }) {
        for centre in ["box", "mean"] {
            let mut base = 0;
            // (row, culling, tree, levels, depth cull, ray check, plane runs, edge cull, live
            // planes and hit cut): the paper's rows first (no plane runs, no edge cull), then
            // ours one at a time.
            let (f, t) = ("false", "true");
            for (name, c, tr, lv, dc, rc, rg, ec, lp) in [
                ("all planes", f, f, "flat", f, f, f, f, f),
                ("culling", t, f, "flat", f, f, f, f, f),
                ("tree", f, t, "flat", f, f, f, f, f),
                ("culling+tree", t, t, "flat", f, f, f, f, f),
                ("+ binary levels", t, t, "binary", f, f, f, f, f),
                ("+ depth cull", t, t, "binary", t, f, f, f, f),
                ("+ ray check", t, t, "binary", t, t, f, f, f),
                ("+ plane runs", t, t, "binary", t, t, t, f, f),
                ("+ edge cull", t, t, "binary", t, t, t, t, f),
                (
                    "+ live planes, hit cut, near first (default)",
                    t,
                    t,
                    "binary",
                    t,
                    t,
                    t,
                    t,
                    t,
                ),
            ] {
                let o = [
                    ("live_planes", lp),
                    ("hit_cut", lp),
                    ("near_first", lp),
                    ("culling", c),
                    ("tree", tr),
                    ("centre", centre),
                    ("levels", lv),
                    ("depth_cull", dc),
                    ("ray_check", rc),
                    ("ranges", rg),
                    ("edge_cull", ec),
                    // Every group as ray-planes, however loose (the figure counts plane tests).
                    ("max_slack", "1"),
                ];
                let mut tr = tracers::create("rtrps", &opts(&o)).unwrap();
                tr.prepare(&scene).unwrap();
                let w = if occl {
                    tr.occluded_timed(&scene, rays).unwrap().1.work
                } else {
                    tr.intersect_timed(&scene, rays).unwrap().1.work
                };
                let (o, i) = (w.get("outline_tests"), w.get("internal_tests"));
                if base == 0 {
                    base = o + i;
                }
                println!(
                    "| {what} | {name} | {centre} | {o} | {i} | {} | {:.1}% | {} | {} | {} | {} | {} | {} |",
                    o + i,
                    100.0 * (o + i) as f64 / base as f64,
                    w.get("spheres_visited"),
                    w.get("spheres_culled"),
                    w.get("depth_culled"),
                    w.get("rays_reproduced"),
                    w.get("tri_tests"),
                    w.get("edge_culled")
                );
            }
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Table 5 form on the shadow grids (occlusion), or with `bounce` on the 8×8 cosine hemisphere
/// grids (closest hits).
fn table5(spec: &str, origins: usize, bounce: bool) {
    let scene = open(spec);
    let (sh, bo) = groups(&scene, origins);
    let (sh, what, side) = if bounce {
        (bo, "bounce", 8)
    } else {
        (sh, "shadow", 16)
    };
    println!(
        "scene {spec} ({} triangles): {} {what} rays in {} {side}x{side} grids, {} threads",
        scene.len(),
        sh.len(),
        sh.len() / (side * side),
        rayon::current_num_threads()
    );
    let contenders: Vec<Contender> = vec![
        ("rtrps", "rtrps", vec![]),
        (
            "rtrps flat, no depth cull",
            "rtrps",
            opts(&[("levels", "flat"), ("depth_cull", "false")]),
        ),
        (
            "rtrps, no ray check",
            "rtrps",
            opts(&[("ray_check", "false")]),
        ),
        (
            "rtrps common origin (no aligned form)",
            "rtrps",
            opts(&[("tri_test", "origin")]),
        ),
        (
            "rtrps aligned, no ray check",
            "rtrps",
            opts(&[("tri_test", "aligned"), ("ray_check", "false")]),
        ),
        ("rtrps aligned", "rtrps", opts(&[("tri_test", "aligned")])),
        (
            "rtrps leaves of 4, common origin",
            "rtrps",
            opts(&[("tri_test", "origin"), ("leaf_size", "4")]),
        ),
        (
            "rtrps leaves of 4, aligned",
            "rtrps",
            opts(&[("tri_test", "aligned"), ("leaf_size", "4")]),
        ),
        ("rtrps random rays", "rtrps", opts(&[("mode", "random")])),
        ("bvh", "bvh", vec![]),
        ("dacrt", "dacrt", vec![]),
    ];
    // `RTRPS_ONLY=a,b`: the first contender and those whose names contain `a` or `b`.
    let only = std::env::var("RTRPS_ONLY").unwrap_or_default();
    let contenders: Vec<Contender> = contenders
        .into_iter()
        .enumerate()
        .filter(|(k, c)| *k == 0 || only.is_empty() || only.split(',').any(|w| c.0.contains(w)))
        .map(|(_, c)| c)
        .collect();
    let mut live: Vec<_> = contenders
        .iter()
        .map(|(_, n, o)| tracers::create(n, o).unwrap())
        .collect();
    let mut prep = vec![0.0; live.len()];
    for (k, t) in live.iter_mut().enumerate() {
        prep[k] = t.prepare_timed(&scene).unwrap().prepare_ms;
    }
    let mut times = vec![Vec::new(); live.len()];
    let mut want = None;
    for _ in 0..3 {
        for (k, t) in live.iter().enumerate() {
            let t0 = Instant::now();
            let ans = if bounce {
                let (h, _) = t.intersect_timed(&scene, &sh).unwrap();
                (h.t, h.prim)
            } else {
                let (occ, _) = t.occluded_timed(&scene, &sh).unwrap();
                (Vec::new(), occ.into_iter().map(u32::from).collect())
            };
            times[k].push(t0.elapsed().as_secs_f64() * 1e3);
            match &want {
                None => want = Some(ans),
                Some(w) => assert!(*w == ans, "{} disagrees", contenders[k].0),
            }
        }
    }
    let base = median(times[0].clone());
    println!("| tracer | build ms | trace ms (median of 3) | trace / rtrps |");
    println!("|---|---|---|---|");
    for (k, (name, _, _)) in contenders.iter().enumerate() {
        let m = median(times[k].clone());
        println!("| {name} | {:.1} | {m:.1} | {:.2} |", prep[k], m / base);
    }
}

/// The Embree peer (`bench/target/release/embree-peer`), when built.
fn embree_peer() -> Option<std::path::PathBuf> {
    ["../../bench", "bench", "/work/main/bench"]
        .iter()
        .map(|d| std::path::Path::new(d).join("target/release/embree-peer"))
        .find(|p| p.is_file())
}

/// Embree's build + trace of `rays` (16-ray packets over 4×4 tiles of the image) on the frame
/// in `dir`: (prepare ms, trace ms, rays whose primitive equals `want`'s).
fn embree_frame(
    peer: &std::path::Path,
    dir: &std::path::Path,
    quality: &str,
    size: u32,
    want: &raysift::HitBatch,
) -> (f64, f64, usize) {
    let threads = rayon::current_num_threads().to_string();
    let hits = dir.join("hits.npy");
    let out = std::process::Command::new(peer)
        .args(["--tris", &dir.join("tris.npy").to_string_lossy()])
        .args(["--rays", &dir.join("rays.npy").to_string_lossy()])
        .args(["--out", &hits.to_string_lossy()])
        .args([
            "--quality",
            quality,
            "--packet",
            "16",
            "--threads",
            &threads,
        ])
        .args(["--tile", &format!("{size},{size}")])
        .output()
        .expect("run embree-peer");
    assert!(
        out.status.success(),
        "embree-peer: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).expect("peer JSON");
    let h = raysift::rays::npy::read_hits(&hits).expect("peer hits");
    let same = (0..want.len())
        .filter(|&i| h.prim[i] == want.prim[i])
        .count();
    (
        j["prepare_ms"].as_f64().unwrap(),
        j["trace_ms"].as_f64().unwrap(),
        same,
    )
}

fn table6(spec: &str, frames: u32) {
    let (scene, mut anim, motion) = if spec.ends_with(".glb") || spec.ends_with(".gltf") {
        let path = [
            "../shared/scenes",
            "../../shared/scenes",
            "/work/shared/scenes",
        ]
        .iter()
        .map(|d| std::path::Path::new(d).join(spec))
        .find(|p| p.exists())
        .expect("glTF scene under shared/scenes");
        let (scene, playback) = raysift::scene::io::gltf_anim::load_animated(&path).unwrap();
        let anim = Animation::from_playback(scene.clone(), playback.expect("an animation"));
        (scene, anim, "its glTF animation")
    } else {
        let scene = open(spec);
        let anim = Animation::new(&scene, Motion::SpinParts).unwrap();
        (scene, anim, "spin-parts")
    };
    let size = 1024;
    let cam = Camera::framing(&scene.bounds(), 45.0, 1.0).rays(size, size);
    let names: Vec<Contender> = vec![
        ("rtrps", "rtrps", vec![]),
        (
            "rtrps, no ray check",
            "rtrps",
            opts(&[("ray_check", "false")]),
        ),
        (
            "rtrps, hierarchy's order",
            "rtrps",
            opts(&[("near_first", "false")]),
        ),
        ("rtrps, retighten", "rtrps", opts(&[("retighten", "true")])),
        ("rtrps, no hit cut", "rtrps", opts(&[("hit_cut", "false")])),
        (
            "rtrps, no hit cut, hierarchy's order",
            "rtrps",
            opts(&[("hit_cut", "false"), ("near_first", "false")]),
        ),
        ("bvh rebuild", "bvh", vec![]),
        ("bvh refit", "bvh", opts(&[("update", "refit")])),
        ("dacrt", "dacrt", vec![]),
    ];
    let mut live: Vec<_> = names
        .iter()
        .map(|(_, n, o)| tracers::create(n, o).unwrap())
        .collect();
    let peer = embree_peer();
    let qualities = ["low", "medium"];
    let rows = live.len() + if peer.is_some() { qualities.len() } else { 0 };
    let mut upd = vec![Vec::new(); rows];
    let mut tr = vec![Vec::new(); rows];
    let mut work = String::new();
    let mut agree = (0usize, 0usize);
    let dir = tempfile::tempdir().unwrap();
    let mut flat = cam.clone();
    flat.layout = RayLayout::Unknown;
    raysift::rays::npy::write_rays(dir.path().join("rays.npy"), &flat).unwrap();
    let mut meshes = 0;
    for f in 0..frames {
        let s = anim.at(anim.frame_time(f, frames)).unwrap();
        meshes = s.meshes().len();
        let mut first: Option<raysift::HitBatch> = None;
        for (k, t) in live.iter_mut().enumerate() {
            let st = t.prepare_timed(s).unwrap();
            let (h, ts) = t.intersect_timed(s, &cam).unwrap();
            match &first {
                None => first = Some(h),
                Some(h0) => assert!(*h0 == h, "{} disagrees with rtrps", names[k].0),
            }
            if f > 0 {
                upd[k].push(st.prepare_ms);
                tr[k].push(ts.trace_ms);
            }
            if k == 0 {
                let b: Vec<_> = st.built.iter().collect();
                let w: Vec<_> = ts.work.iter().collect();
                work = format!("{b:?} {w:?}");
            }
        }
        if let Some(peer) = &peer {
            raysift::rays::npy::write_triangles(dir.path().join("tris.npy"), s).unwrap();
            for (q, quality) in qualities.iter().enumerate() {
                let want = first.as_ref().unwrap();
                let (p, t, same) = embree_frame(peer, dir.path(), quality, size, want);
                if f > 0 {
                    upd[live.len() + q].push(p);
                    tr[live.len() + q].push(t);
                    agree = (agree.0 + same, agree.1 + want.len());
                }
            }
        }
    }
    println!("rtrps, last frame: {work}");
    println!(
        "scene {spec} ({motion}, {} meshes, {} triangles), {size}x{size} first hit, {} threads, {} frames after the first (medians)",
        meshes,
        scene.len(),
        rayon::current_num_threads(),
        frames - 1
    );
    match &peer {
        Some(_) => println!(
            "Embree 16-ray packets over 4x4 tiles: primitive ids equal raysift's on {} of {} rays",
            agree.0, agree.1
        ),
        None => println!("Embree not run: bench/target/release/embree-peer is not built"),
    }
    println!("| tracer | update ms | trace ms | total ms | total / rtrps |");
    println!("|---|---|---|---|---|");
    let tot = |k: usize| median(upd[k].clone()) + median(tr[k].clone());
    let mut labels: Vec<String> = names.iter().map(|n| n.0.to_string()).collect();
    if peer.is_some() {
        labels.extend(
            qualities
                .iter()
                .map(|q| format!("Embree {q} build, 16-ray packets")),
        );
    }
    for (k, name) in labels.iter().enumerate() {
        println!(
            "| {name} | {:.2} | {:.1} | {:.1} | {:.2} |",
            median(upd[k].clone()),
            median(tr[k].clone()),
            tot(k),
            tot(k) / tot(0)
        );
    }
}

/// Fig. 10 form: shadow grids of side 1…32 from the same surface points to the same light
/// square; per ray, time and work of ray-planes, of random rays on the same hierarchy, and of
/// `bvh`: where ray-planes start to pay.
fn crossover(spec: &str, origins: usize) {
    let scene = open(spec);
    let contenders: Vec<Contender> = vec![
        ("rtrps", "rtrps", vec![]),
        ("rtrps random rays", "rtrps", opts(&[("mode", "random")])),
        ("bvh", "bvh", vec![]),
        ("rtrps moller", "rtrps", opts(&[("tri_test", "moller")])),
        (
            "rtrps common origin",
            "rtrps",
            opts(&[("tri_test", "origin")]),
        ),
        ("rtrps aligned", "rtrps", opts(&[("tri_test", "aligned")])),
    ];
    let mut live: Vec<_> = contenders
        .iter()
        .map(|(_, n, o)| tracers::create(n, o).unwrap())
        .collect();
    for t in live.iter_mut() {
        t.prepare(&scene).unwrap();
    }
    println!(
        "scene {spec} ({} triangles), shadow grids from {origins} surface points, occlusion, {} threads, medians of 3 alternating rounds",
        scene.len(),
        rayon::current_num_threads()
    );
    println!("| side | rays | planes ns/ray | random ns/ray | bvh ns/ray | planes / random | plane tests/ray | spheres/ray (planes) | tri tests/ray (planes) | sphere tests/ray (random) | tri tests/ray (random) | planes, Möller ns/ray | planes, common origin ns/ray | common origin / Möller | planes, aligned ns/ray | aligned / Möller | tri tests/ray (common origin) | tri tests/ray (aligned) | span-culled rays/ray (aligned) |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for side in [1, 2, 4, 8, 16, 32] {
        let (sh, _) = shadow_and_bounce(&scene, origins, side);
        let mut times = vec![Vec::new(); live.len()];
        let mut work = Vec::new();
        let mut want = None;
        for round in 0..3 {
            for (k, t) in live.iter().enumerate() {
                let (occ, st) = t.occluded_timed(&scene, &sh).unwrap();
                times[k].push(st.trace_ms);
                if round == 0 {
                    work.push(st.work);
                }
                match &want {
                    None => want = Some(occ),
                    Some(w) => assert_eq!(w, &occ, "{} disagrees", contenders[k].0),
                }
            }
        }
        let n = sh.len() as f64;
        let ns = |k: usize| median(times[k].clone()) * 1e6 / n;
        let per = |k: usize, c: &str| work[k].get(c) as f64 / n;
        println!(
            "| {side} | {} | {:.0} | {:.0} | {:.0} | {:.2} | {:.1} | {:.2} | {:.2} | {:.1} | {:.2} | {:.0} | {:.0} | {:.2} | {:.0} | {:.2} | {:.2} | {:.2} | {:.2} |",
            sh.len(),
            ns(0),
            ns(1),
            ns(2),
            ns(0) / ns(1),
            per(0, "outline_tests") + per(0, "internal_tests"),
            per(0, "spheres_visited"),
            per(0, "tri_tests"),
            per(1, "ray_sphere"),
            per(1, "tri_tests"),
            ns(3),
            ns(4),
            ns(4) / ns(3),
            ns(5),
            ns(5) / ns(3),
            per(4, "tri_tests"),
            per(5, "tri_tests"),
            per(5, "span_culled"),
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let what = args.first().map(String::as_str).unwrap_or("table3");
    let spec = args.get(1).map(String::as_str).unwrap_or("bun_zipper.ply");
    let n: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(2000);
    match what {
        "table3" => table3(),
        "fig11" => fig11(spec, n, args.get(3).is_some_and(|a| a == "shadow")),
        "table5" => table5(spec, n, args.get(3).is_some_and(|a| a == "bounce")),
        "table6" => table6(spec, n.min(50) as u32),
        "crossover" => crossover(spec, n),
        _ => eprintln!("usage: rtrps_bench table3 | fig11 [scene] [origins] [shadow] | table5 [scene] [origins] [bounce] | table6 [scene] [frames]"),
    }
}
