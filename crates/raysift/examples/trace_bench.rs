//! Build and trace timing for one tracer on one scene.
//!
//! ```text
//! cargo run --release -p raysift --example trace_bench -- SCENE_SPEC TRACER \
//!     [--threads N] [--width W] [--random N] [--repeat R] [key=value ...]
//! ```
//!
//! Opens `SCENE_SPEC` (`sphere:N`, `soup:N`, `cornell`, a file), prepares the tracer (options as
//! `key=value`), then traces W×W camera rays (default framing, 45° fov; W = 1024) and N random
//! rays (origins in the scene's box, uniform directions; N = 1M) for closest hit, and the random
//! rays again for occlusion, in a rayon pool of N threads (default: all cores). Times are the best
//! of R runs (default 3); counts are per ray. "cpu" is the process's CPU time over the same run
//! (all threads, from /proc), a steadier measure than wall time on a shared machine: Mrays per
//! CPU-second is the per-thread rate.

use raysift::rays::{generate::random_in_box, Camera};
use raysift::{scene::procedural, tracers, RayBatch, Scene, Stats, Tracer};
use std::time::Instant;

fn main() {
    if let Err(e) = run() {
        eprintln!("trace_bench: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut pos, mut opts) = (Vec::new(), Vec::new());
    let (mut threads, mut width, mut random, mut repeat) = (0usize, 1024u32, 1usize << 20, 3usize);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--threads" => threads = val()?.parse()?,
            "--width" => width = val()?.parse()?,
            "--random" => random = val()?.parse()?,
            "--repeat" => repeat = val()?.parse::<usize>()?.max(1),
            s if s.contains('=') => opts.push(s.to_string()),
            s => pos.push(s.to_string()),
        }
    }
    let [spec, name] = &pos[..] else {
        return Err("usage: trace_bench SCENE_SPEC TRACER [--threads N] [--width W] [--random N] [--repeat R] [key=value ...]".into());
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let t0 = Instant::now();
        let mut scene = procedural::open(spec)?;
        let load_ms = t0.elapsed().as_secs_f64() * 1e3;
        let mut tracer = tracers::create(name, &tracers::parse_opts(&opts)?)?;
        let n = scene.len().max(1) as f64;
        println!(
            "scene {} ({} triangles, loaded in {load_ms:.0} ms), tracer {name} {opts:?}, {} threads",
            scene.name,
            scene.len(),
            rayon::current_num_threads()
        );
        let mut build_ms = f64::INFINITY;
        let mut build_cpu = f64::INFINITY;
        let mut prep = Stats::default();
        for _ in 0..repeat {
            let c0 = cpu_ms();
            scene.touch(); // a new frame: every repeat builds from scratch
            prep = tracer.prepare_timed(&scene)?;
            if prep.prepare_ms < build_ms {
                (build_ms, build_cpu) = (prep.prepare_ms, cpu_ms() - c0);
            }
        }
        println!(
            "build      {build_ms:9.1} ms (cpu {build_cpu:7.0} ms)  {} nodes, {} leaves, {:.1} bytes/triangle",
            prep.built.get("nodes"),
            prep.built.get("leaves"),
            tracer.bytes() as f64 / n
        );
        let cam = Camera::framing(&scene.bounds(), 45.0, 1.0).rays(width, width);
        bench("camera", &scene, &*tracer, &cam, repeat, false)?;
        let rnd = random_in_box(&scene.bounds(), random, 1);
        bench("random", &scene, &*tracer, &rnd, repeat, false)?;
        bench("random-occ", &scene, &*tracer, &rnd, repeat, true)?;
        Ok(())
    })
}

fn bench(
    label: &str,
    scene: &Scene,
    tracer: &dyn Tracer,
    rays: &RayBatch,
    repeat: usize,
    occlusion: bool,
) -> raysift::Result<()> {
    let mut best = f64::INFINITY;
    let mut best_cpu = f64::INFINITY;
    let mut stats = Stats::default();
    let mut hits = 0;
    for _ in 0..repeat {
        let c0 = cpu_ms();
        let (ms, s, h) = if occlusion {
            let (o, s) = tracer.occluded_timed(scene, rays)?;
            (s.trace_ms, s, o.iter().filter(|&&b| b).count())
        } else {
            let (hb, s) = tracer.intersect_timed(scene, rays)?;
            (s.trace_ms, s, hb.hit_count())
        };
        let cpu = cpu_ms() - c0;
        if ms < best {
            (best, stats, hits) = (ms, s, h);
        }
        best_cpu = best_cpu.min(cpu);
    }
    let r = rays.len().max(1) as f64;
    println!(
        "{label:<10} {best:9.1} ms (cpu {best_cpu:7.0} ms) {:6.2} Mrays/s, {:6.2} per cpu-s; {} rays, {:.1}% hit; per ray: {:.1} box, {:.2} tri, {:.1} nodes, {:.2} leaves",
        rays.len() as f64 / best / 1e3,
        rays.len() as f64 / best_cpu / 1e3,
        rays.len(),
        100.0 * hits as f64 / r,
        stats.work.get("ray_box") as f64 / r,
        stats.work.get("ray_tri") as f64 / r,
        stats.work.get("nodes") as f64 / r,
        stats.work.get("leaves") as f64 / r
    );
    Ok(())
}

/// CPU time of the whole process (all threads) in ms: the sum of every thread's run time in
/// `/proc/self/task/*/schedstat` (Linux, ns resolution; 0 elsewhere).
fn cpu_ms() -> f64 {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return 0.0;
    };
    let ns: u64 = dir
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<u64>().ok())
        .sum();
    ns as f64 / 1e6
}
