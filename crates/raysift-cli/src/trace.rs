//! `raysift trace`: one tracer over a rays file, hits (or occlusion flags) to a file, times and
//! counters to stderr or `--json`.

use crate::args::{make_tracer, open_scene, TracerArgs, SCENE_HELP};
use crate::progress::spinner;
use crate::report::{median, mrays_per_s, print_json, Counts, TraceReport};
use anyhow::{bail, Result};
use clap::Args;
use raysift::rays::npy;
use raysift::HitBatch;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct TraceArgs {
    #[arg(help = SCENE_HELP)]
    scene: String,
    /// Input rays.npy.
    #[arg(long)]
    rays: PathBuf,
    /// Output hits.npy (or uint8 occlusion flags with --occlusion); without it nothing is
    /// written (stderr says so), for timing runs.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Any-hit query instead of closest hit.
    #[arg(long)]
    occlusion: bool,
    /// Add each hit's unit geometric normal to hits.npy (field `ng`, three float32).
    #[arg(long, conflicts_with = "occlusion")]
    normals: bool,
    /// Prepare and trace this many times in-process; times reported are medians. The output
    /// buffers are made once, before any timing, and reused by every run.
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    #[command(flatten)]
    pub tracer: TracerArgs,
}

pub fn run(a: &TraceArgs) -> Result<()> {
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
        let ts = if a.occlusion {
            tracer.occluded(&s, &rays, &mut occ, None)?
        } else {
            tracer.intersect(&s, &rays, &mut hits, None)?
        };
        tr.push(t0.elapsed().as_secs_f64() * 1e3);
        pb.finish_and_clear();
        prep.push(ps.prepare_ms);
        last = Some(Counts::of_frame(&ps, &ts));
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
            npy::write_hits(path, &hits, &s, a.normals)?;
        }
    }
    let (prepare_ms, trace_ms) = (median(&prep), median(&tr));
    let mrays = mrays_per_s(rays.len() as u64, trace_ms);
    let threads = rayon::current_num_threads();
    if a.out.is_none() {
        eprintln!(
            "raysift: note: no --out given, so no {} were written",
            if a.occlusion {
                "occlusion flags"
            } else {
                "hits"
            }
        );
    }
    if a.tracer.json {
        return print_json(&TraceReport {
            scene: s.name.clone(),
            triangles: s.len(),
            tracer: tracer.name(),
            rays: rays.len(),
            threads,
            occlusion: a.occlusion,
            normals: a.normals,
            prepare_ms,
            trace_ms,
            mrays_per_s: mrays,
            hits: nhit,
            tracer_bytes: tracer.bytes(),
            bytes_per_triangle: tracer.bytes() as f64 / s.len() as f64,
            prepare_ms_runs: prep,
            trace_ms_runs: tr,
            stats,
            out: a.out.as_ref().map(|p| p.display().to_string()),
        });
    }
    let what = if a.occlusion { "occluded" } else { "hit" };
    let runs = if a.repeat > 1 { " (medians)" } else { "" };
    eprintln!(
        "{}: {} rays, {nhit} {what}, prepare {prepare_ms:.1} ms, trace {trace_ms:.1} ms{runs} ({mrays:.3} Mrays/s, {threads} threads)",
        tracer.name(),
        rays.len(),
    );
    Ok(())
}
