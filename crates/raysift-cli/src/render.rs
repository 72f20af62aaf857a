//! `raysift render`: an image by ray casting (normal, depth or diffuse shading with shadows) or
//! diffuse path tracing.

use crate::args::{camera_for, make_tracer, open_scene_or_default, parse_vec3};
use crate::args::{TracerArgs, ViewArgs};
use crate::progress::spinner;
use crate::report::{mrays_per_s, print_json, BounceReport, Counts, PassReport};
use crate::report::{PathReport, RenderReport};
use anyhow::Result;
use clap::Args;
use glam::Vec3;
use raysift::render::{self, Shade};
use raysift::Stats;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
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
    pub tracer: TracerArgs,
}

/// The CLI name of a shading.
pub fn shade_name(s: Shade) -> &'static str {
    match s {
        Shade::Normal => "normal",
        Shade::Depth => "depth",
        Shade::Diffuse => "diffuse",
    }
}

pub fn run(a: &RenderArgs) -> Result<()> {
    let mut tracer = make_tracer(&a.tracer)?;
    let s = open_scene_or_default(a.scene.as_deref())?;
    let cam = camera_for(&s.bounds(), &a.view)?;
    let (w, h) = (a.view.width, a.view.height);
    let t0 = Instant::now();
    let pb = spinner(format!("{}: rendering {w}×{h}", tracer.name()));
    let prep = tracer.prepare_timed(&s)?;
    if a.integrator == "path" {
        let cfg = render::path::PathConfig {
            spp: a.spp.max(1),
            bounces: a.bounces,
            ..Default::default()
        };
        let (img, per_depth) = render::path::path_trace(&s, tracer.as_ref(), &cam, w, h, &cfg)?;
        pb.finish_and_clear();
        img.save_png(&a.out)?;
        let rays: u64 = per_depth.iter().map(|b| b.rays).sum();
        let trace_ms: f64 = per_depth.iter().map(|b| b.stats.trace_ms).sum();
        if a.tracer.json {
            print_json(&PathReport {
                scene: s.name.clone(),
                triangles: s.len(),
                tracer: tracer.name(),
                integrator: "path",
                spp: cfg.spp,
                bounces: cfg.bounces,
                width: w,
                height: h,
                threads: rayon::current_num_threads(),
                rays,
                prepare_ms: prep.prepare_ms,
                trace_ms,
                frame_ms: t0.elapsed().as_secs_f64() * 1e3,
                mrays_per_s: mrays_per_s(rays, trace_ms),
                tracer_bytes: tracer.bytes(),
                prepare: Counts::of(&prep),
                per_bounce: per_depth
                    .iter()
                    .map(|b| BounceReport {
                        depth: b.depth,
                        rays: b.rays,
                        hits: b.hits,
                        trace_ms: b.stats.trace_ms,
                        mrays_per_s: b.mrays_per_s,
                        stats: Counts::of(&b.stats),
                    })
                    .collect(),
                out: a.out.display().to_string(),
            })?;
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
        return Ok(());
    }
    let (img, rs) = render::raycast(&s, tracer.as_ref(), &cam, w, h, a.shade, a.light)?;
    pb.finish_and_clear();
    img.save_png(&a.out)?;
    let frame_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut passes = vec![("primary", &rs.primary)];
    passes.extend(rs.shadow.as_ref().map(|s| ("shadow", s)));
    let rays: u64 = passes.iter().map(|(_, p)| p.rays).sum();
    let trace_ms: f64 = passes.iter().map(|(_, p)| p.trace_ms).sum();
    if a.tracer.json {
        print_json(&RenderReport {
            scene: s.name.clone(),
            triangles: s.len(),
            tracer: tracer.name(),
            integrator: "raycast",
            shade: shade_name(a.shade),
            width: w,
            height: h,
            threads: rayon::current_num_threads(),
            rays,
            hits: rs.hits,
            prepare_ms: prep.prepare_ms,
            trace_ms,
            frame_ms,
            mrays_per_s: mrays_per_s(rays, trace_ms),
            tracer_bytes: tracer.bytes(),
            prepare: Counts::of(&prep),
            passes: passes.iter().map(|(n, p)| PassReport::of(n, p)).collect(),
            out: a.out.display().to_string(),
        })?;
    } else {
        eprintln!(
            "wrote {} ({w}×{h}, {} of {} pixels hit) in {frame_ms:.0} ms",
            a.out.display(),
            rs.hits,
            rs.primary.rays
        );
    }
    if a.stats {
        print_counters(&prep, tracer.bytes(), &passes);
    }
    Ok(())
}

/// `--stats`: per-pass counters on stderr, per ray and in total.
pub fn print_counters(prep: &Stats, bytes: usize, passes: &[(&str, &Stats)]) {
    let built: Vec<String> = prep.built.iter().map(|(k, v)| format!("{k} {v}")).collect();
    eprintln!(
        "prepare: {:.1} ms, {bytes} bytes{}{}",
        prep.prepare_ms,
        if built.is_empty() { "" } else { "; built: " },
        built.join(", ")
    );
    for (name, st) in passes {
        let r = st.rays.max(1) as f64;
        let per: Vec<String> = st
            .work
            .iter()
            .map(|(k, v)| format!("{:.2} {k}", v as f64 / r))
            .collect();
        let total: Vec<String> = st.work.iter().map(|(k, v)| format!("{k} {v}")).collect();
        eprintln!(
            "{name}: {} rays, {:.1} ms; per ray: {}; totals: {}",
            st.rays,
            st.trace_ms,
            per.join(", "),
            total.join(", ")
        );
    }
}
