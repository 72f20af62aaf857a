//! `dacrt5d` against `dacrt` and `bvh` (and its own options against each other) on the issue's
//! batches, in one run, contenders alternating, times the best of R runs:
//!
//! ```text
//! cargo run --release -p raysift --example dacrt5d_bench -- SCENE_SPEC \
//!     [--width W] [--random N] [--bounces B] [--repeat R] [--threads N] \
//!     [--tracer "NAME key=value ..."]... [--counters] [--eye X,Y,Z --look X,Y,Z] [--fov F]
//!     [--light X,Y,Z] [--only LABEL]
//! ```
//!
//! `--only LABEL` runs only the batches whose label is `LABEL` (e.g. `"camera shuffled"`).
//!
//! Batches: W×W pinhole camera rays (default framing, or `--eye`/`--look`), the same rays shuffled (no layout),
//! 2×2 jittered samples per pixel of a (W/2)² image, image-shaped and shuffled,
//! shadow rays from the camera hits to a light above the scene or at `--light` (occlusion), N random rays
//! (origins in the scene's box), and B path-tracing bounces (cosine-weighted diffuse rays from
//! the previous bounce's hits, as `render::path` makes them; bounce 1 leaves the camera hits).
//! Per batch and tracer: Mrays/s (trace only; prepare is timed once per tracer and printed),
//! and per ray the ray/triangle tests and the cull tests, and the mean triangles surviving a
//! `dacrt5d` cull. Every answer is compared with the first contender's (they must agree).
//! `--counters` adds every work counter of each contender as an HTML comment line.

use raysift::rays::generate::{bounce_rays, random_in_box, shadow_rays};
use raysift::rays::{Camera, RayLayout};
use raysift::{scene::procedural, tracers, HitBatch, RayBatch, Tracer};
use std::time::Instant;

fn main() {
    if let Err(e) = run() {
        eprintln!("dacrt5d_bench: {e}");
        std::process::exit(2);
    }
}

type Res<T> = Result<T, Box<dyn std::error::Error + Send + Sync>>;

fn run() -> Res<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut spec, mut specs) = (None, Vec::new());
    let (mut width, mut random, mut bounces, mut repeat, mut threads) =
        (512u32, 1usize << 18, 3usize, 3usize, 0usize);
    let mut counters = false;
    let mut only: Option<String> = None;
    let (mut eye, mut look, mut fov, mut light_at) = (None, None, 45.0f32, None);
    let vec3 = |v: &String| -> Res<glam::Vec3> {
        let c: Vec<f32> = v
            .split(',')
            .map(|x| x.trim().parse())
            .collect::<Result<_, _>>()?;
        match c[..] {
            [x, y, z] => Ok(glam::Vec3::new(x, y, z)),
            _ => Err(format!("expected x,y,z, got {v:?}").into()),
        }
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--width" => width = val()?.parse()?,
            "--random" => random = val()?.parse()?,
            "--bounces" => bounces = val()?.parse()?,
            "--repeat" => repeat = val()?.parse::<usize>()?.max(1),
            "--threads" => threads = val()?.parse()?,
            "--tracer" => specs.push(val()?.clone()),
            "--counters" => counters = true,
            "--only" => only = Some(val()?.clone()),
            "--eye" => eye = Some(vec3(val()?)?),
            "--look" => look = Some(vec3(val()?)?),
            "--fov" => fov = val()?.parse()?,
            "--light" => light_at = Some(vec3(val()?)?),
            s if spec.is_none() => spec = Some(s.to_string()),
            s => return Err(format!("unexpected argument {s:?}").into()),
        }
    }
    let spec = spec.ok_or("usage: dacrt5d_bench SCENE_SPEC [--width W] [--random N] [--bounces B] [--repeat R] [--threads N] [--tracer \"NAME k=v ...\"]... [--counters]")?;
    if specs.is_empty() {
        specs = [
            "bvh",
            "dacrt",
            "dacrt5d cull=frustum",
            "dacrt5d cull=cone",
            "dacrt5d stop=fixed",
            "dacrt5d spatial=false",
        ]
        .map(String::from)
        .to_vec();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| -> Res<()> {
        let scene = procedural::open(&spec)?;
        println!("scene {} ({} triangles), {} threads, best of {repeat}", scene.name, scene.len(), rayon::current_num_threads());
        let mut ts: Vec<(String, Box<dyn Tracer>)> = Vec::new();
        for s in &specs {
            let mut w = s.split_whitespace();
            let name = w.next().ok_or("empty --tracer")?;
            let opts: Vec<String> = w.map(String::from).collect();
            let mut t = tracers::create(name, &tracers::parse_opts(&opts)?)?;
            let t0 = Instant::now();
            t.prepare(&scene)?;
            println!("prepare {s}: {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
            ts.push((s.clone(), t));
        }
        let b = scene.bounds();
        let mut camera = Camera::framing(&b, fov, 1.0);
        if let (Some(e), Some(l)) = (eye, look) {
            (camera.eye, camera.look) = (e, l);
        }
        let cam = camera.rays(width, width);
        let (mut hits, mut occ) = (HitBatch::new(0), Vec::new());
        ts[0].1.intersect(&scene, &cam, &mut hits, None)?;
        let n = cam.len();
        let mut shuffled = RayBatch::from_rays((0..n).map(|i| cam.get(i * 7919 % n)));
        shuffled.layout = RayLayout::Unknown;
        let light = light_at.unwrap_or(b.center() + glam::Vec3::new(0.0, b.extent().y * 0.45, 0.0));
        let (shadow, _) = shadow_rays(&scene, &cam, &hits, light);
        // 2×2 jittered samples per pixel of a (W/2)² image (as many rays), image-shaped and
        // shuffled.
        let samples = camera.sample_rays(width / 2, width / 2, 2, 11);
        let m = samples.len().max(1);
        let mut samples_shuffled = RayBatch::from_rays((0..m).map(|i| samples.get(i * 7919 % m)));
        samples_shuffled.layout = RayLayout::Unknown;
        let mut batches = vec![
            ("camera".to_string(), cam.clone(), false),
            ("camera shuffled".to_string(), shuffled, false),
            ("camera 2x2 samples".to_string(), samples, false),
            ("camera 2x2 samples shuffled".to_string(), samples_shuffled, false),
            ("shadow".to_string(), shadow, true),
            ("random".to_string(), random_in_box(&b, random, 7), false),
        ];
        let (mut prev, mut prev_hits) = (cam, hits.clone());
        for k in 1..=bounces {
            let (rays, _) = bounce_rays(&scene, &prev, &prev_hits, k as u64);
            ts[0].1.intersect(&scene, &rays, &mut prev_hits, None)?;
            batches.push((format!("bounce {k}"), rays.clone(), false));
            prev = rays;
        }
        println!("| batch | rays | tracer | Mrays/s | ms | ray/tri per ray | cull tests per ray | survivors per cull | terminated |");
        println!("|---|---|---|---|---|---|---|---|---|");
        for (label, rays, any) in &batches {
            if only.as_ref().is_some_and(|o| o != label) {
                continue;
            }
            let mut best = vec![f64::INFINITY; ts.len()];
            let mut work = vec![raysift::Stats::default(); ts.len()];
            let mut want: Option<(HitBatch, Vec<bool>)> = None;
            for _ in 0..repeat {
                for (k, (_, t)) in ts.iter().enumerate() {
                    let t0 = Instant::now();
                    let st = if *any {
                        t.occluded(&scene, rays, &mut occ, None)?
                    } else {
                        t.intersect(&scene, rays, &mut hits, None)?
                    };
                    best[k] = best[k].min(t0.elapsed().as_secs_f64());
                    work[k] = st;
                    match &want {
                        None => want = Some((hits.clone(), occ.clone())),
                        Some((h, o)) => {
                            let same = if *any { o == &occ } else { h == &hits };
                            if !same {
                                return Err(format!("{label}: {} disagrees with {}", ts[k].0, ts[0].0).into());
                            }
                        }
                    }
                }
            }
            let r = rays.len().max(1) as f64;
            for (k, (name, _)) in ts.iter().enumerate() {
                let w = &work[k].work;
                let cull = w.get("frustum_tests") + w.get("cone_tests") + w.get("tri_box") + w.get("ray_box");
                let culls = w.get("culls");
                let surv: u64 = ["surv_d0", "surv_d1", "surv_d2", "surv_d3", "surv_d4_7", "surv_d8_15", "surv_d16_31", "surv_d32"]
                    .iter()
                    .map(|c| w.get(c))
                    .sum();
                println!(
                    "| {label} | {} | {name} | {:.2} | {:.1} | {:.1} | {:.1} | {} | {} |",
                    rays.len(),
                    r / best[k] / 1e6,
                    best[k] * 1e3,
                    w.get("ray_tri") as f64 / r,
                    cull as f64 / r,
                    if culls > 0 { format!("{:.0}", surv as f64 / culls as f64) } else { "-".into() },
                    if name.starts_with("dacrt5d") { w.get("terminated").to_string() } else { "-".into() },
                );
                if counters {
                    let all: Vec<String> = w.iter().map(|(k, v)| format!("{k}={v}")).collect();
                    println!("<!-- {label} {name}: {} -->", all.join(" "));
                }
            }
        }
        Ok(())
    })
}
