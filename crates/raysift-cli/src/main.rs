//! `raysift`: the command line over the raysift library: scene info, ray generation, batch tracing
//! with any tracer, rendering, and export.
//!
//! Every error is one line on stderr naming the file and place, with exit code 2; output files are
//! written atomically, so a failed command leaves none behind.

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use raysift::rays::{generate, npy, Camera, HitBatch, RayBatch};
use raysift::render::{self, Shade};
use raysift::scene::{self, procedural, Scene};
use raysift::tracers;
use raysift::Tracer;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(name = "raysift", version, about = "Batch ray/triangle intersection for dynamic scenes", long_about = None)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Print triangles, vertices, bounds, meshes and bytes of a scene.
    Info {
        /// Scene file (.obj .ply .gltf .glb .off, optionally .gz) or generator (sphere:N, soup:N[:SEED], cornell, tile:K:FILE).
        scene: String,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Generate rays and write them as rays.npy (float32, N×8).
    #[command(subcommand)]
    Rays(RaysCmd),
    /// Trace a rays file with one tracer and write hits.npy (or occlusion flags).
    Trace(TraceArgs),
    /// Render an image (the embedded bunny when no scene is given).
    Render(RenderArgs),
    /// Render a sequence whose geometry changes every frame, re-preparing the tracer each frame.
    Animate(AnimateArgs),
    /// Write the world-space triangles as a float32 (T, 9) .npy file [v0 v1 v2], in primitive-id order.
    Export {
        /// Scene file or generator.
        scene: String,
        /// Output .npy file.
        #[arg(long)]
        out: PathBuf,
    },
    /// List the available tracers.
    Tracers,
}

#[derive(Subcommand)]
enum RaysCmd {
    /// Pinhole camera rays, ordered j·W+i (see README, "Camera").
    Camera {
        /// Scene (for the default framing); the embedded bunny when omitted.
        scene: Option<String>,
        #[command(flatten)]
        view: ViewArgs,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
    },
    /// Uniformly random rays: origins in the scene bounds, directions on the sphere.
    Random {
        /// Scene (for its bounds).
        scene: String,
        /// Number of rays.
        #[arg(long)]
        count: usize,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
    },
    /// Shadow rays from the hits of a batch to a point light (t = 1 at the light).
    Shadow {
        /// Scene the hits refer to.
        scene: String,
        /// The rays that produced the hits.
        #[arg(long)]
        rays: PathBuf,
        /// Their hits.npy.
        #[arg(long)]
        hits: PathBuf,
        /// Light position x,y,z.
        #[arg(long, value_parser = parse_vec3)]
        light: Vec3,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
        /// Also write, for each output ray, the index of its source ray (uint32 .npy).
        #[arg(long)]
        map: Option<PathBuf>,
    },
    /// Cosine-weighted diffuse bounce rays from the hits of a batch.
    Bounce {
        /// Scene the hits refer to.
        scene: String,
        /// The rays that produced the hits.
        #[arg(long)]
        rays: PathBuf,
        /// Their hits.npy.
        #[arg(long)]
        hits: PathBuf,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
        /// Also write, for each output ray, the index of its source ray (uint32 .npy).
        #[arg(long)]
        map: Option<PathBuf>,
    },
}

#[derive(Args, Clone)]
struct ViewArgs {
    /// Image width in pixels.
    #[arg(long, default_value_t = 512)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// Eye position x,y,z (default: framing the scene bounds from +z).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    eye: Option<Vec3>,
    /// Point looked at x,y,z (default: centre of the bounds).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    look: Option<Vec3>,
    /// Up vector x,y,z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "0,1,0")]
    up: Vec3,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = Camera::DEFAULT_FOV)]
    fov: f32,
}

#[derive(Args)]
struct TracerArgs {
    /// Tracer name (see `raysift tracers`).
    #[arg(long, default_value = "bvh")]
    tracer: String,
    /// Tracer option key=value (repeatable; see each tracer's Config).
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Pin worker thread k to core k (mod the cores this process may use), for steady benchmarks.
    #[arg(long)]
    pin: bool,
    /// Print one JSON object with scene, tracer, counts, times and counters.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct TraceArgs {
    /// Scene file or generator.
    scene: String,
    /// Input rays.npy.
    #[arg(long)]
    rays: PathBuf,
    /// Output hits.npy (or uint8 occlusion flags with --occlusion).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Any-hit query instead of closest hit.
    #[arg(long)]
    occlusion: bool,
    /// Prepare and trace this many times in-process; times reported are medians. The output
    /// buffers are made once, before any timing, and reused by every run.
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    #[command(flatten)]
    tracer: TracerArgs,
}

#[derive(Args)]
struct AnimateArgs {
    /// Scene file or generator; the embedded bunny when omitted.
    scene: Option<String>,
    /// Motion: explode (triangles fly apart) or spin-parts (meshes rotate rigidly).
    #[arg(long, default_value = "explode")]
    motion: raysift::scene::animate::Motion,
    /// Number of frames (time runs from 0 to 1 over them).
    #[arg(long, default_value_t = 8)]
    frames: u32,
    /// Output folder for frame_NNNN.png (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// Only time the frames; write no images.
    #[arg(long)]
    no_images: bool,
    #[command(flatten)]
    view: ViewArgs,
    /// Shading: normal, depth or diffuse.
    #[arg(long, default_value = "diffuse")]
    shade: Shade,
    #[command(flatten)]
    tracer: TracerArgs,
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file or generator; the embedded bunny when omitted.
    scene: Option<String>,
    #[command(flatten)]
    view: ViewArgs,
    /// Point light x,y,z for diffuse shading (default: above and right of the eye).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    light: Option<Vec3>,
    /// Shading: normal, depth or diffuse (with shadows).
    #[arg(long, default_value = "diffuse")]
    shade: Shade,
    /// Integrator: raycast (one ray per pixel, shaded) or path (diffuse path tracing under a sky).
    #[arg(long, default_value = "raycast", value_parser = ["raycast", "path"])]
    integrator: String,
    /// Path tracing: samples per pixel.
    #[arg(long, default_value_t = 4)]
    spp: u32,
    /// Path tracing: bounces after the primary hit (no Russian roulette).
    #[arg(long, default_value_t = 7)]
    bounces: u32,
    /// Output PNG.
    #[arg(long, default_value = "raysift.png")]
    out: PathBuf,
    /// Print the work counters to stderr.
    #[arg(long)]
    stats: bool,
    #[command(flatten)]
    tracer: TracerArgs,
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected x,y,z numbers, got {s:?}"))?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

fn main() {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) if !e.use_stderr() => e.exit(), // --help, --version
        Err(e) => {
            // Usage errors as one line, like every other error (the full usage is in --help).
            let text = e.render().to_string();
            let first = text
                .lines()
                .next()
                .unwrap_or("invalid arguments")
                .trim_start_matches("error: ");
            eprintln!("raysift: error: {first} (see --help)");
            std::process::exit(2);
        }
    };
    if let Err(e) = run(cli) {
        eprintln!("raysift: error: {e:#}");
        std::process::exit(2);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Info { scene, json } => info(&open_scene(&scene)?, json),
        Cmd::Rays(r) => rays(r),
        Cmd::Trace(t) => with_threads(t.tracer.threads, t.tracer.pin, || trace(&t)),
        Cmd::Render(r) => with_threads(r.tracer.threads, r.tracer.pin, || render_cmd(&r)),
        Cmd::Animate(a) => with_threads(a.tracer.threads, a.tracer.pin, || animate(&a)),
        Cmd::Export { scene, out } => export(&open_scene(&scene)?, &out),
        Cmd::Tracers => {
            for n in tracers::names() {
                println!("{n}");
            }
            Ok(())
        }
    }
}

/// Runs `f` in a rayon pool of `threads` workers (all cores when `None`), optionally pinning
/// worker k to the k-th core this process may run on.
fn with_threads<T: Send>(
    threads: Option<usize>,
    pin: bool,
    f: impl FnOnce() -> Result<T> + Send,
) -> Result<T> {
    if threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    if threads.is_none() && !pin {
        return f();
    }
    let mut b = rayon::ThreadPoolBuilder::new().num_threads(threads.unwrap_or(0));
    if pin {
        let cores = core_affinity::get_core_ids().unwrap_or_default();
        if cores.is_empty() {
            bail!("--pin: cannot read this process's CPU affinity");
        }
        b = b.start_handler(move |k| {
            core_affinity::set_for_current(cores[k % cores.len()]);
        });
    }
    b.build().context("starting the thread pool")?.install(f)
}

fn spinner(msg: impl Into<String>) -> ProgressBar {
    // indicatif draws nothing when stderr is not a terminal, so scripts see clean output.
    let pb = ProgressBar::new_spinner().with_message(msg.into());
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").expect("valid template"),
    );
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

fn open_scene(spec: &str) -> Result<Scene> {
    let pb = spinner(format!("loading {spec}"));
    let s = procedural::open(spec);
    pb.finish_and_clear();
    let s = s?;
    if s.is_empty() {
        bail!("{spec}: the scene has no triangles");
    }
    Ok(s)
}

fn open_scene_or_default(spec: Option<&str>) -> Result<Scene> {
    match spec {
        Some(s) => open_scene(s),
        None => Ok(scene::default_scene()?),
    }
}

fn info(s: &Scene, json: bool) -> Result<()> {
    let b = s.bounds();
    let v = json!({
        "scene": s.name,
        "triangles": s.len(),
        "vertices": s.vertex_count(),
        "degenerate_triangles": s.degenerate_count(),
        "meshes": s.meshes().len(),
        "bounds": {"min": b.min.to_array(), "max": b.max.to_array()},
        "bytes": s.bytes(),
        "bytes_per_triangle": s.bytes() as f64 / s.len().max(1) as f64,
    });
    if json {
        println!("{v}");
    } else {
        println!("scene      {}", s.name);
        println!(
            "triangles  {} ({} degenerate)",
            s.len(),
            s.degenerate_count()
        );
        println!("vertices   {}", s.vertex_count());
        println!("meshes     {}", s.meshes().len());
        println!(
            "bounds     ({}, {}, {}) – ({}, {}, {})",
            b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
        );
        println!(
            "bytes      {} ({:.1} per triangle)",
            s.bytes(),
            s.bytes() as f64 / s.len().max(1) as f64
        );
    }
    Ok(())
}

fn camera_for(scene: &Scene, v: &ViewArgs) -> Result<Camera> {
    if v.width == 0 || v.height == 0 {
        bail!("--width and --height must be positive");
    }
    let mut cam = Camera::framing(&scene.bounds(), v.fov, v.width as f32 / v.height as f32);
    if let Some(eye) = v.eye {
        cam.eye = eye;
    }
    if let Some(look) = v.look {
        cam.look = look;
    }
    cam.up = v.up;
    cam.validate()?;
    Ok(cam)
}

fn write_map(path: &Option<PathBuf>, map: &[u32]) -> Result<()> {
    if let Some(p) = path {
        raysift::output::write_atomic(p, |w| {
            use npyz::WriterBuilder;
            let mut out = npyz::WriteOptions::<u32>::new()
                .default_dtype()
                .shape(&[map.len() as u64])
                .writer(w)
                .begin_nd()?;
            out.extend(map.iter().copied())?;
            out.finish()
        })?;
    }
    Ok(())
}

fn secondary_inputs(
    scene: &Scene,
    rays: &Path,
    hits: &Path,
) -> Result<(RayBatch, raysift::HitBatch)> {
    let r = npy::read_rays(rays)?;
    let h = npy::read_hits(hits)?;
    if r.len() != h.len() {
        bail!(
            "{}: {} hits for {} rays in {}",
            hits.display(),
            h.len(),
            r.len(),
            rays.display()
        );
    }
    if let Some(i) = (0..h.len()).find(|&i| h.is_hit(i) && h.prim[i] as usize >= scene.len()) {
        bail!(
            "{}: record {i}: primitive {} is out of range for {} ({} triangles)",
            hits.display(),
            h.prim[i],
            scene.name,
            scene.len()
        );
    }
    Ok((r, h))
}

fn rays(cmd: RaysCmd) -> Result<()> {
    match cmd {
        RaysCmd::Camera { scene, view, out } => {
            let s = open_scene_or_default(scene.as_deref())?;
            let cam = camera_for(&s, &view)?;
            npy::write_rays(&out, &cam.rays(view.width, view.height))?;
        }
        RaysCmd::Random {
            scene,
            count,
            seed,
            out,
        } => {
            if count == 0 {
                bail!("--count must be at least 1");
            }
            let s = open_scene(&scene)?;
            npy::write_rays(&out, &generate::random_in_box(&s.bounds(), count, seed))?;
        }
        RaysCmd::Shadow {
            scene,
            rays,
            hits,
            light,
            out,
            map,
        } => {
            let s = open_scene(&scene)?;
            let (r, h) = secondary_inputs(&s, &rays, &hits)?;
            let (sr, from) = generate::shadow_rays(&s, &r, &h, light);
            npy::write_rays(&out, &sr)?;
            write_map(&map, &from)?;
        }
        RaysCmd::Bounce {
            scene,
            rays,
            hits,
            seed,
            out,
            map,
        } => {
            let s = open_scene(&scene)?;
            let (r, h) = secondary_inputs(&s, &rays, &hits)?;
            let (br, from) = generate::bounce_rays(&s, &r, &h, seed);
            npy::write_rays(&out, &br)?;
            write_map(&map, &from)?;
        }
    }
    Ok(())
}

fn make_tracer(args: &TracerArgs) -> Result<Box<dyn Tracer>> {
    let opts = tracers::parse_opts(&args.opts)?;
    Ok(tracers::create(&args.tracer, &opts)?)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn trace(a: &TraceArgs) -> Result<()> {
    if a.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let mut tracer = make_tracer(&a.tracer)?;
    let mut s = open_scene(&a.scene)?;
    let rays = npy::read_rays(&a.rays)?;
    if rays.is_empty() {
        bail!("{}: no rays", a.rays.display());
    }
    let (mut prep, mut tr) = (Vec::new(), Vec::new());
    let mut last = None;
    // Output buffers made and touched once, before any timing, and reused by every run, as a
    // renderer keeps its buffers from frame to frame (and as bench/embree-peer does): the
    // timed call fills them, but does not pay for fresh memory.
    let mut hits = HitBatch::new(0);
    let mut occ = Vec::new();
    if a.occlusion {
        occ.resize(rays.len(), false);
    } else {
        hits.reset(rays.len());
    }
    for run in 0..a.repeat {
        let pb = spinner(format!(
            "{}: prepare + trace {} rays (run {}/{})",
            tracer.name(),
            rays.len(),
            run + 1,
            a.repeat
        ));
        // Every run is a new frame of the same geometry: the tracer rebuilds (or updates).
        s.touch();
        let ps = tracer.prepare_timed(&s)?;
        let t0 = Instant::now();
        let mut ts = if a.occlusion {
            tracer.occluded(&s, &rays, &mut occ, None)?
        } else {
            tracer.intersect(&s, &rays, &mut hits, None)?
        };
        ts.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
        pb.finish_and_clear();
        prep.push(ps.prepare_ms);
        tr.push(ts.trace_ms);
        ts.prepare_ms = ps.prepare_ms;
        ts.peak_bytes = ts.peak_bytes.max(ps.peak_bytes);
        last = Some(ts);
    }
    let stats = last.expect("repeat >= 1");
    let nhit = if a.occlusion {
        occ.iter().filter(|&&b| b).count()
    } else {
        hits.hit_count()
    };
    if let Some(path) = &a.out {
        if a.occlusion {
            npy::write_occlusion(path, &occ)?;
        } else {
            npy::write_hits(path, &hits, &s, false)?;
        }
    }
    let hits = nhit;
    let (prepare_ms, trace_ms) = (median(&mut prep.clone()), median(&mut tr.clone()));
    let mrays = rays.len() as f64 / (trace_ms * 1e3).max(1e-9);
    if a.tracer.json {
        let v = json!({
            "scene": s.name, "triangles": s.len(), "tracer": tracer.name(), "rays": rays.len(),
            "threads": rayon::current_num_threads(), "occlusion": a.occlusion,
            "prepare_ms": prepare_ms, "trace_ms": trace_ms, "mrays_per_s": mrays, "hits": hits,
            "tracer_bytes": tracer.bytes(), "bytes_per_triangle": tracer.bytes() as f64 / s.len() as f64,
            "prepare_ms_runs": prep, "trace_ms_runs": tr, "stats": stats,
        });
        println!("{v}");
    } else {
        let what = if a.occlusion { "occluded" } else { "hit" };
        eprintln!(
            "{}: {} rays, {hits} {what}, prepare {prepare_ms:.1} ms, trace {trace_ms:.1} ms ({mrays:.3} Mrays/s, {} threads)",
            tracer.name(),
            rays.len(),
            rayon::current_num_threads()
        );
    }
    Ok(())
}

fn render_cmd(a: &RenderArgs) -> Result<()> {
    let mut tracer = make_tracer(&a.tracer)?;
    let s = open_scene_or_default(a.scene.as_deref())?;
    let cam = camera_for(&s, &a.view)?;
    let t0 = Instant::now();
    let pb = spinner(format!(
        "{}: rendering {}×{}",
        tracer.name(),
        a.view.width,
        a.view.height
    ));
    let prep = tracer.prepare_timed(&s)?;
    if a.integrator == "path" {
        return path_render(a, &s, tracer.as_ref(), &cam, &prep, t0, pb);
    }
    let (img, rs) = render::raycast(
        &s,
        tracer.as_ref(),
        &cam,
        a.view.width,
        a.view.height,
        a.shade,
        a.light,
    )?;
    pb.finish_and_clear();
    img.save_png(&a.out)?;
    let total_ms = t0.elapsed().as_secs_f64() * 1e3;
    let rays = rs.primary.rays + rs.shadow.as_ref().map_or(0, |s| s.rays);
    let trace_ms = rs.primary.trace_ms + rs.shadow.as_ref().map_or(0.0, |s| s.trace_ms);
    if a.tracer.json {
        let v = json!({
            "scene": s.name, "triangles": s.len(), "tracer": tracer.name(), "width": a.view.width, "height": a.view.height,
            "threads": rayon::current_num_threads(), "rays": rays, "hits": rs.hits,
            "prepare_ms": prep.prepare_ms, "trace_ms": trace_ms, "frame_ms": total_ms,
            "mrays_per_s": rays as f64 / (trace_ms * 1e3).max(1e-9), "tracer_bytes": tracer.bytes(),
            "stats": {"prepare": prep, "primary": rs.primary, "shadow": rs.shadow}, "out": a.out.display().to_string(),
        });
        println!("{v}");
    } else {
        eprintln!(
            "wrote {} ({}×{}, {} of {} pixels hit) in {total_ms:.0} ms",
            a.out.display(),
            a.view.width,
            a.view.height,
            rs.hits,
            rs.primary.rays
        );
    }
    if a.stats {
        eprintln!(
            "prepare: {:.1} ms, {} bytes",
            prep.prepare_ms,
            tracer.bytes()
        );
        for (name, st) in [
            ("primary", Some(&rs.primary)),
            ("shadow", rs.shadow.as_ref()),
        ] {
            if let Some(st) = st {
                let r = st.rays.max(1) as f64;
                eprintln!(
                    "{name}: {} rays, {:.1} ms; per ray: {:.2} ray-box, {:.2} ray-tri, {:.2} nodes; totals: ray-box {}, ray-tri {}, tri-box {}, cone-box {}, nodes {}, leaves {}",
                    st.rays,
                    st.trace_ms,
                    st.work.get("ray_box") as f64 / r,
                    st.work.get("ray_tri") as f64 / r,
                    st.work.get("nodes") as f64 / r,
                    st.work.get("ray_box"),
                    st.work.get("ray_tri"),
                    st.work.get("tri_box"),
                    st.work.get("cone_box"),
                    st.work.get("nodes"),
                    st.work.get("leaves")
                );
            }
        }
    }
    Ok(())
}

fn export(s: &Scene, out: &Path) -> Result<()> {
    let t = s.triangles();
    raysift::output::write_atomic(out, |w| {
        use npyz::WriterBuilder;
        let mut o = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[t.len() as u64, 9])
            .writer(w)
            .begin_nd()?;
        for i in 0..t.len() {
            for v in t.get(i) {
                o.extend(v.to_array())?;
            }
        }
        o.finish()
    })?;
    Ok(())
}

fn path_render(
    a: &RenderArgs,
    s: &Scene,
    tracer: &dyn Tracer,
    cam: &Camera,
    prep: &raysift::Stats,
    t0: Instant,
    pb: ProgressBar,
) -> Result<()> {
    let cfg = render::path::PathConfig {
        spp: a.spp.max(1),
        bounces: a.bounces,
        ..Default::default()
    };
    let (img, per_depth) =
        render::path::path_trace(s, tracer, cam, a.view.width, a.view.height, &cfg)?;
    pb.finish_and_clear();
    img.save_png(&a.out)?;
    let rays: u64 = per_depth.iter().map(|b| b.rays).sum();
    let trace_ms: f64 = per_depth.iter().map(|b| b.stats.trace_ms).sum();
    if a.tracer.json {
        let v = json!({"scene": s.name, "triangles": s.len(), "tracer": tracer.name(), "integrator": "path", "spp": cfg.spp, "bounces": cfg.bounces,
                       "width": a.view.width, "height": a.view.height, "threads": rayon::current_num_threads(), "rays": rays,
                       "prepare_ms": prep.prepare_ms, "trace_ms": trace_ms, "frame_ms": t0.elapsed().as_secs_f64() * 1e3,
                       "mrays_per_s": rays as f64 / (trace_ms * 1e3).max(1e-9), "per_bounce": per_depth, "out": a.out.display().to_string()});
        println!("{v}");
    } else {
        eprintln!(
            "wrote {} ({rays} rays in {trace_ms:.0} ms of tracing)",
            a.out.display()
        );
    }
    if a.stats {
        for b in &per_depth {
            eprintln!(
                "depth {}: {} rays, {} hits, {:.1} ms, {:.2} Mrays/s",
                b.depth, b.rays, b.hits, b.stats.trace_ms, b.mrays_per_s
            );
        }
    }
    Ok(())
}

fn animate(a: &AnimateArgs) -> Result<()> {
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if a.view.width == 0 || a.view.height == 0 {
        bail!("--width and --height must be positive");
    }
    let mut tracer = make_tracer(&a.tracer)?;
    let base = open_scene_or_default(a.scene.as_deref())?;
    let mut anim = raysift::scene::animate::Animation::new(&base, a.motion)?;
    // Frame the whole motion: the union of the first and last frames' bounds.
    let bounds = anim.at(0.0)?.bounds().union(anim.at(1.0)?.bounds());
    let mut cam = Camera::framing(
        &bounds,
        a.view.fov,
        a.view.width as f32 / a.view.height as f32,
    );
    cam.eye = a.view.eye.unwrap_or(cam.eye);
    cam.look = a.view.look.unwrap_or(cam.look);
    cam.up = a.view.up;
    cam.validate()?;
    if !a.no_images {
        std::fs::create_dir_all(&a.out)
            .with_context(|| format!("{}: cannot create the folder", a.out.display()))?;
    }
    let pb = ProgressBar::new(a.frames as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames [{elapsed}<{eta}]")
            .expect("valid template"),
    );
    let mut frames = Vec::new();
    for k in 0..a.frames {
        let t = if a.frames == 1 {
            0.0
        } else {
            k as f32 / (a.frames - 1) as f32
        };
        let u0 = Instant::now();
        let scene = anim.at(t)?;
        let update_ms = u0.elapsed().as_secs_f64() * 1e3;
        let prep = tracer.prepare_timed(scene)?;
        let (img, rs) = render::raycast(
            scene,
            tracer.as_ref(),
            &cam,
            a.view.width,
            a.view.height,
            a.shade,
            None,
        )?;
        let trace_ms = rs.primary.trace_ms + rs.shadow.as_ref().map_or(0.0, |s| s.trace_ms);
        if !a.no_images {
            img.save_png(&a.out.join(format!("frame_{k:04}.png")))?;
        }
        frames.push(json!({"frame": k, "time": t, "update_ms": update_ms, "prepare_ms": prep.prepare_ms, "trace_ms": trace_ms,
                           "frame_ms": prep.prepare_ms + trace_ms, "hits": rs.hits, "tracer_bytes": tracer.bytes()}));
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mean = |key: &str| {
        frames
            .iter()
            .map(|f| f[key].as_f64().unwrap_or(0.0))
            .sum::<f64>()
            / frames.len() as f64
    };
    if a.tracer.json {
        let v = json!({"scene": base.name, "triangles": base.len(), "tracer": tracer.name(), "motion": format!("{:?}", a.motion),
                       "width": a.view.width, "height": a.view.height, "threads": rayon::current_num_threads(),
                       "mean_prepare_ms": mean("prepare_ms"), "mean_trace_ms": mean("trace_ms"), "mean_frame_ms": mean("frame_ms"), "frames": frames});
        println!("{v}");
    } else {
        let (p, t, f) = (mean("prepare_ms"), mean("trace_ms"), mean("frame_ms"));
        eprintln!(
            "{} frames with {}: mean prepare {p:.1} ms + trace {t:.1} ms = {f:.1} ms per frame",
            a.frames,
            tracer.name()
        );
    }
    Ok(())
}
