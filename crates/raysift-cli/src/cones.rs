//! `raysift cones`: cone tracing (Wiche & Kuri 2020): the n nearest triangles per cone, one cone
//! per pixel of the camera or cones from a file, hits to a file, counts and times to stderr or
//! `--json`.

use crate::args::{camera_for, open_scene, ViewArgs, SCENE_HELP};
use crate::image_out::{format_of, Format};
use crate::report::{median, print_json};
use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use raysift::render::heatmap::{self, HeatScale};
use raysift::tracers::cone::{self, io, BoxTest, ConeBatch, ConeHits, Query, Structure, Traversal};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Clone, Copy, ValueEnum)]
enum StructureArg {
    /// The shared binned-SAH BVH (32 bins, at most 8 triangles per leaf, as the paper).
    Bvh,
    /// The same BVH with spatial splits (the paper's SBVH; references cut by boxes).
    Sbvh,
    /// The shared SAH kd-tree (pbrt-v3's build parameters, as the paper).
    Kdtree,
    /// Brute force: every triangle, the exact test (the ground truth).
    Oracle,
}

#[derive(Clone, Copy, ValueEnum)]
enum TraversalArg {
    /// Depth first with a stack (the paper's measured variant).
    Stack,
    /// Nodes sorted by their range's start, exact early-out at t_n.
    Sorted,
}

#[derive(Clone, Copy, ValueEnum)]
enum BoxTestArg {
    /// Listing 2, branching.
    Basic,
    /// Branchless, both children at once.
    Improved,
}

#[derive(Args)]
pub struct ConesArgs {
    #[arg(help = SCENE_HELP)]
    scene: String,
    /// Cone half-angle α in degrees, in (0, 90) (the paper's α: 0.04 covers a pixel at 1024²),
    /// for the camera's cones; required unless --cones is given.
    #[arg(long)]
    aperture: Option<f32>,
    /// Cones from a file instead of the camera: float32 (N, 8) rows
    /// [apex xyz, axis xyz, half-angle in degrees, t_near].
    #[arg(long, conflicts_with = "aperture")]
    cones: Option<PathBuf>,
    /// The paper's ray rows: K rays per pixel (K a square: 4, 16, 64) through the same walkers,
    /// each a cone of half-angle 1e-6° through the centre of one cell of a √K×√K grid over the
    /// pixel; counts are then reported per pixel (summed over its K rays).
    #[arg(long, value_name = "K", conflicts_with_all = ["aperture", "cones"])]
    rays_per_pixel: Option<u32>,
    /// Nearest triangles per cone; omitted: all of them (the paper's n = ∞).
    #[arg(long)]
    n: Option<usize>,
    /// The paper's counting mode: n = ∞, count the triangles met in leaves, test none.
    #[arg(long, conflicts_with = "n")]
    count: bool,
    /// Acceleration structure.
    #[arg(long, value_enum, default_value_t = StructureArg::Bvh)]
    structure: StructureArg,
    /// Build options of --structure bvh or sbvh, KEY=VALUE, repeatable: bins, max_leaf,
    /// traversal_cost, intersection_cost (defaults: the paper's 32 bins and at most 8 triangles
    /// per leaf, SAH costs 1 and 1); with sbvh also alpha, max_growth (defaults 1e-5 and 1).
    #[arg(long = "bvh", value_name = "KEY=VALUE")]
    bvh: Vec<String>,
    /// Traversal order.
    #[arg(long, value_enum, default_value_t = TraversalArg::Stack)]
    traversal: TraversalArg,
    /// Cone-frustum/box test.
    #[arg(long = "box-test", value_enum, default_value_t = BoxTestArg::Improved)]
    box_test: BoxTestArg,
    /// Output: records (cone u4, prim u4, t f4), cone by cone, each sorted by (t, prim).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also draw each camera cone's cost (nodes entered + triangles met, the paper's Fig. 1) as a
    /// PNG heatmap with its colour bar (cones from the camera: --aperture or --rays-per-pixel,
    /// whose K rays of a pixel are summed).
    #[arg(long, value_name = "PNG")]
    heatmap: Option<PathBuf>,
    /// Trace this many times; times are medians.
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Print one JSON object instead of the summary line.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    view: ViewArgs,
}

#[derive(serde::Serialize)]
struct ConesReport {
    scene: String,
    triangles: usize,
    tracer: String,
    cones: usize,
    aperture_deg: Option<f32>,
    n: Option<usize>,
    count_only: bool,
    threads: usize,
    prepare_ms: f64,
    trace_ms: f64,
    trace_ms_runs: Vec<f64>,
    reported: usize,
    nodes_per_cone: f64,
    tri_encounters_per_cone: f64,
    /// Rays (thin cones) per pixel with --rays-per-pixel, else 1.
    cones_per_pixel: u32,
    nodes_per_pixel: f64,
    tri_encounters_per_pixel: f64,
    counters: raysift::tracer::Counters,
    /// What the prepare built (nodes, leaves; the BVHs' references and spatial splits).
    built: raysift::tracer::Counters,
    tracer_bytes: usize,
    /// The heatmap's scale (min, max, mean cost per pixel) when one was drawn.
    heatmap_scale: Option<HeatScale>,
}

/// Sums the cost of each pixel's `k` cones (a √k×√k block of the finer camera's pixels) and
/// writes the heatmap; returns its scale.
fn write_heatmap(p: &Path, cost: &[u32], w: u32, h: u32, k: u32) -> Result<HeatScale> {
    let s = (k as f64).sqrt().round() as u32;
    let mut px = vec![0u32; (w * h) as usize];
    for (c, &v) in cost.iter().enumerate() {
        let (x, y) = (c as u32 % (w * s), c as u32 / (w * s));
        let q = &mut px[((y / s) * w + x / s) as usize];
        *q = q.saturating_add(v);
    }
    let scale = HeatScale::of(&px);
    heatmap::draw(&px, w, h, &scale).save_png(p)?;
    Ok(scale)
}

pub fn run(a: &ConesArgs) -> Result<()> {
    if a.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if a.threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()?;
    pool.install(|| run_in_pool(a))
}

fn run_in_pool(a: &ConesArgs) -> Result<()> {
    let scene = open_scene(&a.scene)?;
    let mut per_pixel = 1;
    let cones: ConeBatch = match (&a.cones, a.aperture) {
        (None, None) if a.rays_per_pixel.is_some() => {
            let k = a.rays_per_pixel.unwrap_or(1);
            let s = (k as f64).sqrt().round() as u32;
            if k == 0 || s * s != k {
                bail!("--rays-per-pixel: {k} is not a positive square (4, 16, 64, ...)");
            }
            per_pixel = k;
            let cam = camera_for(&scene.bounds(), &a.view)?;
            // The camera at s× the resolution: its pixel centres are the centres of an s×s
            // grid over each of ours.
            let thin = 1e-6f32.to_radians();
            ConeBatch::from_camera(&cam, a.view.width * s, a.view.height * s, thin)?
        }
        (Some(p), _) => io::read_cones(p)?,
        (None, Some(deg)) => {
            if !(deg > 0.0 && deg < 90.0) {
                bail!("--aperture: {deg}° is not in (0, 90)");
            }
            let cam = camera_for(&scene.bounds(), &a.view)?;
            ConeBatch::from_camera(&cam, a.view.width, a.view.height, deg.to_radians())?
        }
        (None, None) => {
            bail!("give --aperture DEG (cones from the camera), --rays-per-pixel K or --cones FILE")
        }
    };
    if cones.is_empty() {
        bail!("no cones");
    }
    if let Some(p) = &a.heatmap {
        if a.cones.is_some() {
            bail!("--heatmap needs cones from the camera (--aperture or --rays-per-pixel), not --cones");
        }
        if format_of(p)? != Format::Png {
            bail!(
                "{}: a heatmap is a picture, not radiance: name it .png",
                p.display()
            );
        }
    }
    let structure = match a.structure {
        StructureArg::Bvh => Structure::Bvh,
        StructureArg::Sbvh => Structure::Sbvh,
        StructureArg::Kdtree => Structure::Kdtree,
        StructureArg::Oracle => Structure::Oracle,
    };
    let traversal = match a.traversal {
        TraversalArg::Stack => Traversal::Stack,
        TraversalArg::Sorted => Traversal::Sorted,
    };
    let box_test = match a.box_test {
        BoxTestArg::Basic => BoxTest::Basic,
        BoxTestArg::Improved => BoxTest::Improved,
    };
    let q = if a.count {
        Query::count()
    } else {
        Query {
            n: a.n,
            count_only: false,
        }
    };
    let mut tracer = match structure {
        Structure::Bvh | Structure::Sbvh if !a.bvh.is_empty() => {
            bvh_with(&a.bvh, structure == Structure::Sbvh, traversal, box_test)?
        }
        _ if !a.bvh.is_empty() => bail!("--bvh: only with --structure bvh or sbvh"),
        _ => cone::create(structure, traversal, box_test),
    };
    let t0 = Instant::now();
    let built = tracer.prepare(&scene)?.built;
    let prepare_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut hits = ConeHits::default();
    let mut runs = Vec::new();
    let mut stats = None;
    for _ in 0..a.repeat {
        let t0 = Instant::now();
        stats = Some(tracer.trace(&scene, &cones, &q, &mut hits)?);
        runs.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    let stats = stats.expect("repeat >= 1");
    if let Some(p) = &a.out {
        io::write_cone_hits(p, &hits)?;
    }
    let heat = match &a.heatmap {
        Some(p) => Some(write_heatmap(
            p,
            &hits.cost,
            a.view.width,
            a.view.height,
            per_pixel,
        )?),
        None => None,
    };
    let per = |k: &str| stats.work.get(k) as f64 / cones.len() as f64;
    let r = ConesReport {
        scene: scene.name.clone(),
        triangles: scene.len(),
        tracer: tracer.name(),
        cones: cones.len(),
        aperture_deg: a.aperture,
        n: q.n,
        count_only: q.count_only,
        threads: rayon::current_num_threads(),
        prepare_ms,
        trace_ms: median(&runs),
        trace_ms_runs: runs,
        reported: hits.prim.len(),
        nodes_per_cone: per("nodes"),
        tri_encounters_per_cone: per("tri_encounters"),
        cones_per_pixel: per_pixel,
        nodes_per_pixel: per("nodes") * per_pixel as f64,
        tri_encounters_per_pixel: per("tri_encounters") * per_pixel as f64,
        counters: stats.work.clone(),
        built,
        tracer_bytes: tracer.bytes(),
        heatmap_scale: heat,
    };
    if a.json {
        return print_json(&r);
    }
    eprintln!(
        "{}: {} cones, {} triangles reported, {:.1} nodes and {:.1} triangle encounters per cone, prepare {:.1} ms, trace {:.1} ms ({} threads)",
        r.tracer, r.cones, r.reported, r.nodes_per_cone, r.tri_encounters_per_cone, r.prepare_ms, r.trace_ms, r.threads
    );
    if a.out.is_none() {
        eprintln!("raysift: note: no --out given, so no hits were written");
    }
    Ok(())
}

/// The cone BVH built with `--bvh KEY=VALUE` options over the paper's build.
fn bvh_with(
    opts: &[String],
    spatial: bool,
    traversal: Traversal,
    box_test: BoxTest,
) -> Result<Box<dyn cone::ConeTracer>> {
    let mut build = cone::bvh::paper_build();
    let mut sp = raysift::accel::bvh::SpatialConfig::default();
    for o in opts {
        let Some((k, v)) = o.split_once('=') else {
            bail!("--bvh {o}: expected KEY=VALUE");
        };
        let num = |what: &str| -> Result<f64> {
            v.parse::<f64>()
                .map_err(|_| anyhow::anyhow!("--bvh {o}: {what} must be a number, got {v:?}"))
        };
        let int = |what: &str| -> Result<usize> {
            v.parse::<usize>()
                .map_err(|_| anyhow::anyhow!("--bvh {o}: {what} must be a whole number, got {v:?}"))
        };
        match k {
            "bins" => build.bins = int(k)?,
            "max_leaf" => build.max_leaf = int(k)?,
            "traversal_cost" => build.traversal_cost = num(k)? as f32,
            "intersection_cost" => build.intersection_cost = num(k)? as f32,
            "alpha" | "max_growth" if !spatial => bail!("--bvh {o}: {k} needs --structure sbvh"),
            "alpha" => sp.alpha = num(k)? as f32,
            "max_growth" => sp.max_growth = num(k)? as f32,
            _ => bail!(
                "--bvh {o}: unknown key {k:?} (valid: bins, max_leaf, traversal_cost, intersection_cost, alpha, max_growth)"
            ),
        }
    }
    build.check("--bvh")?;
    sp.check("--bvh")?;
    Ok(if spatial {
        Box::new(cone::bvh::ConeBvh::with_spatial(
            traversal, box_test, build, sp,
        ))
    } else {
        Box::new(cone::bvh::ConeBvh::with_build(traversal, box_test, build))
    })
}
