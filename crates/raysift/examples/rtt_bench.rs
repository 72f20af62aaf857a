//! The relevant-triangle shafts paper's Table 1 and antialiasing sweep: `rtt` against the
//! single-ray `kdtree` on the same rays, alternating, best of R.
//!
//! ```text
//! cargo run --release -p raysift --example rtt_bench -- SCENE_SPEC \
//!     [--width W] [--height H] [--aa 1,2,4] [--repeat R] [--threads N]
//!     [--eye X,Y,Z] [--look X,Y,Z] [--fov DEG] [--light X,Y,Z] [--export-rays rays.npy]
//!     [--kd-packets 1|4]
//!     [key=value ...]
//! ```
//!
//! For each a in `--aa`: W×H pixels of a×a stratified jittered samples from the camera (default:
//! the framing of the scene's box, 45° fov), closest hit; for a = 1 also shadow rays from the hits
//! to a point light (default: above the scene's centre, inside its box), any hit. Options `key=value` go to `rtt`. Prints per measure
//! both times, their ratio, and `rtt`'s Table 1 counters: rays traced through the tree (corner,
//! fallback), share answered from lists, mean list length, triangle tests per ray.
//! `--kd-packets 4` makes the baseline the 4-ray packet kd-tree (the paper's). `--export-rays` writes the primary rays of the last `--aa` value (for `embree-peer`).
//! `--only-rtt` skips the baseline (for profiling). Output buffers are allocated and touched
//! once per measure and reused by every run, as `embree-peer` does (a renderer reuses its
//! buffers from frame to frame): the times do not include page faults on fresh output.

use glam::Vec3;
use raysift::rays::{generate, Camera};
use raysift::{scene::procedural, tracers, RayBatch, Scene, Stats, Tracer};
use std::time::Instant;

type Res<T> = Result<T, Box<dyn std::error::Error + Send + Sync>>;

fn main() {
    if let Err(e) = run() {
        eprintln!("rtt_bench: {e}");
        std::process::exit(2);
    }
}

fn run() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut pos, mut opts) = (Vec::new(), Vec::new());
    let (mut w, mut h, mut repeat, mut threads) = (640u32, 480u32, 3usize, 0usize);
    let mut aa = vec![1u32];
    let (mut eye, mut look, mut fov, mut light) = (None, None, 45.0f32, None);
    let mut export: Option<String> = None;
    let mut kd_packets = "1".to_string();
    let mut only_rtt = false;
    let vec3 = |s: &str| -> Res<Vec3> {
        let v: Vec<f32> = s.split(',').map(|x| x.parse()).collect::<Result<_, _>>()?;
        match v[..] {
            [x, y, z] => Ok(Vec3::new(x, y, z)),
            _ => Err(format!("{s:?}: expected x,y,z").into()),
        }
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--width" => w = val()?.parse()?,
            "--height" => h = val()?.parse()?,
            "--repeat" => repeat = val()?.parse::<usize>()?.max(1),
            "--threads" => threads = val()?.parse()?,
            "--eye" => eye = Some(vec3(val()?)?),
            "--look" => look = Some(vec3(val()?)?),
            "--fov" => fov = val()?.parse()?,
            "--light" => light = Some(vec3(val()?)?),
            "--export-rays" => export = Some(val()?.clone()),
            "--kd-packets" => kd_packets = val()?.clone(),
            "--only-rtt" => only_rtt = true,
            "--aa" => {
                aa = val()?
                    .split(',')
                    .map(|s| s.parse())
                    .collect::<Result<_, _>>()?
            }
            s if s.contains('=') => opts.push(s.to_string()),
            s => pos.push(s.to_string()),
        }
    }
    let [spec] = &pos[..] else {
        return Err("usage: rtt_bench SCENE_SPEC [--width W] [--height H] [--aa 1,2] [--repeat R] [--threads N] [key=value ...]".into());
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| -> Res<()> {
        let scene = procedural::open(spec)?;
        let mut kd = tracers::create("kdtree", &[("packets".into(), kd_packets.clone())])?;
        let mut rtt = tracers::create("rtt", &tracers::parse_opts(&opts)?)?;
        let t0 = Instant::now();
        kd.prepare(&scene)?;
        let build = t0.elapsed().as_secs_f64() * 1e3;
        rtt.prepare(&scene)?;
        println!(
            "scene {} ({} triangles), rtt {opts:?}, kdtree packets={kd_packets}, {} threads, kd-tree built in {build:.0} ms",
            scene.name,
            scene.len(),
            rayon::current_num_threads()
        );
        let mut cam = Camera::framing(&scene.bounds(), fov, w as f32 / h as f32);
        cam.eye = eye.unwrap_or(cam.eye);
        cam.look = look.unwrap_or(cam.look);
        cam.fov_deg = fov;
        for &a in &aa {
            let rays = if a == 1 {
                cam.rays(w, h)
            } else {
                cam.sample_rays(w, h, a, a as u64)
            };
            if let Some(path) = &export {
                // The last sweep's rays, for the Embree peer (float32 (N, 8)).
                raysift::rays::npy::write_rays(path, &rays)?;
            }
            let label = format!("primary {w}x{h} aa {a}x{a}");
            measure(&label, &scene, &*kd, &*rtt, &rays, repeat, false, only_rtt)?;
            if a == 1 {
                let (hits, _) = kd.intersect_timed(&scene, &rays)?;
                let b = scene.bounds();
                let light = light.unwrap_or(
                    b.min.lerp(b.max, 0.5) + Vec3::new(0.1, 0.45, 0.2) * (b.max - b.min),
                );
                let (shadow, _) = generate::shadow_rays(&scene, &rays, &hits, light);
                measure(
                    "shadow (point light)",
                    &scene,
                    &*kd,
                    &*rtt,
                    &shadow,
                    repeat,
                    true,
                    only_rtt,
                )?;
            }
        }
        Ok(())
    })
}

/// Times `kd` and `rtt` alternating, best of `repeat`, and prints the line.
#[allow(clippy::too_many_arguments)]
fn measure(
    label: &str,
    scene: &Scene,
    kd: &dyn Tracer,
    rtt: &dyn Tracer,
    rays: &RayBatch,
    repeat: usize,
    any: bool,
    only_rtt: bool,
) -> Res<()> {
    // Buffers of the batch's size, touched once, reused by every run.
    let mut hits = raysift::HitBatch::new(rays.len());
    let mut occ = vec![false; rays.len()];
    let mut run = |t: &dyn Tracer| -> raysift::Result<Stats> {
        let t0 = Instant::now();
        let mut s = if any {
            t.occluded(scene, rays, &mut occ, None)?
        } else {
            t.intersect(scene, rays, &mut hits, None)?
        };
        s.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(s)
    };
    let (mut best_kd, mut best_rtt) = (f64::INFINITY, f64::INFINITY);
    let (mut skd, mut srtt) = (Stats::default(), Stats::default());
    for _ in 0..repeat {
        if !only_rtt {
            let s = run(kd)?;
            if s.trace_ms < best_kd {
                (best_kd, skd) = (s.trace_ms, s);
            }
        }
        let s = run(rtt)?;
        if s.trace_ms < best_rtt {
            (best_rtt, srtt) = (s.trace_ms, s);
        }
    }
    // The last run was rtt's: its answers, for comparison with a peer's.
    let found = if any {
        occ.iter().filter(|&&o| o).count()
    } else {
        hits.prim
            .iter()
            .filter(|&&p| p != raysift::rays::MISS)
            .count()
    };
    let n = rays.len().max(1) as f64;
    let c = |k: &str| srtt.work.get(k);
    let traced = c("corner_rays") + c("fallback_rays");
    println!(
        "{label:<24} {} rays | kdtree {best_kd:8.1} ms {:5.2} Mrays/s, {:.2} tri/ray | rtt {best_rtt:8.1} ms {:5.2} Mrays/s, speedup {:.2}x, hits {found} | traced {traced} ({:.1}%: corner {}, fallback {}), from lists {:.1}%, mean list {:.2}, tiles listed {:.1}%, tri/ray {:.2} (lists {:.2}), per tile: shaft cells {:.1}, shaft box tests {:.1}",
        rays.len(),
        n / best_kd / 1e3,
        skd.work.get("ray_tri") as f64 / n,
        n / best_rtt / 1e3,
        best_kd / best_rtt,
        100.0 * traced as f64 / n,
        c("corner_rays"),
        c("fallback_rays"),
        100.0 * c("list_rays") as f64 / n,
        c("list_len") as f64 / c("tiles_listed").max(1) as f64,
        100.0 * c("tiles_listed") as f64 / c("tiles").max(1) as f64,
        (c("ray_tri") + c("list_tests")) as f64 / n,
        c("list_tests") as f64 / n,
        c("shaft_nodes") as f64 / c("tiles").max(1) as f64,
        c("shaft_boxes") as f64 / c("tiles").max(1) as f64,
    );
    Ok(())
}
