//! `raysift animate`: frames whose geometry changes in place, the tracer prepared again each
//! frame (rebuilding or updating what changed).

use crate::args::{camera_for, make_tracer, open_scene_or_default, TracerArgs, ViewArgs};
use crate::progress;
use crate::report::{print_json, AnimateReport, FrameReport};
use anyhow::{bail, Context, Result};
use clap::Args;
use raysift::render::{self, Shade};
use raysift::scene::animate::{Animation, Motion};
use raysift::scene::{Change, Stamp};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct AnimateArgs {
    /// Scene file or generator; the embedded bunny when omitted.
    scene: Option<String>,
    /// Motion: explode (triangles fly apart) or spin-parts (meshes rotate rigidly).
    #[arg(long, default_value = "explode")]
    motion: Motion,
    /// Number of frames (time runs from 0 to 1 over them).
    #[arg(long, default_value_t = 8)]
    frames: u32,
    /// Output folder for frame_NNNN.png (created if missing; not needed with --no-images).
    #[arg(long, required_unless_present = "no_images")]
    out: Option<PathBuf>,
    /// Only time the frames; write no images.
    #[arg(long)]
    no_images: bool,
    #[command(flatten)]
    view: ViewArgs,
    /// Shading: diffuse (with shadows), normal or depth.
    #[arg(long, default_value = "diffuse", value_parser = crate::render::shade_parser())]
    shade: Shade,
    #[command(flatten)]
    pub tracer: TracerArgs,
}

fn motion_name(m: Motion) -> &'static str {
    match m {
        Motion::Explode => "explode",
        Motion::SpinParts => "spin-parts",
    }
}

pub fn run(a: &AnimateArgs) -> Result<()> {
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if a.view.width == 0 || a.view.height == 0 {
        bail!("--width and --height must be positive");
    }
    let mut tracer = make_tracer(&a.tracer)?;
    let base = open_scene_or_default(a.scene.as_deref())?;
    let mut anim = Animation::new(&base, a.motion)?;
    // Frame the whole motion: the union of the first and last frames' bounds.
    let bounds = anim.at(0.0)?.bounds().union(anim.at(1.0)?.bounds());
    let cam = camera_for(&bounds, &a.view)?;
    // The folder for the frames, None with --no-images (clap demands --out otherwise).
    let out = a.out.as_ref().filter(|_| !a.no_images);
    if let Some(dir) = out {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    }
    let pb = progress::frames(a.frames);
    let mut frames = Vec::new();
    // The scene as the tracer was last prepared for it.
    let mut prepared: Option<Stamp> = None;
    for k in 0..a.frames {
        let t = if a.frames == 1 {
            0.0
        } else {
            k as f32 / (a.frames - 1) as f32
        };
        let u0 = Instant::now();
        let scene = anim.at(t)?;
        let update_ms = u0.elapsed().as_secs_f64() * 1e3;
        let (change, moved, deformed) = match prepared.map(|p| scene.changes_since(p)) {
            None | Some(Change::All) => ("all", 0, 0),
            Some(Change::None) => ("none", 0, 0),
            Some(Change::Meshes { moved, deformed }) => ("meshes", moved.len(), deformed.len()),
        };
        prepared = Some(scene.stamp());
        let prep = tracer.prepare_timed(scene)?;
        let (w, h) = (a.view.width, a.view.height);
        let (img, rs) = render::raycast(scene, tracer.as_ref(), &cam, w, h, a.shade, None)?;
        let trace_ms = rs.primary.trace_ms + rs.shadow.as_ref().map_or(0.0, |s| s.trace_ms);
        if let Some(dir) = out {
            img.save_png(&dir.join(format!("frame_{k:04}.png")))?;
        }
        frames.push(FrameReport {
            frame: k,
            time: t,
            change,
            moved,
            deformed,
            update_ms,
            prepare_ms: prep.prepare_ms,
            trace_ms,
            frame_ms: prep.prepare_ms + trace_ms,
            hits: rs.hits,
            tracer_bytes: tracer.bytes(),
            built: prep.built,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mean = |f: fn(&FrameReport) -> f64| frames.iter().map(f).sum::<f64>() / frames.len() as f64;
    let (u, p, t, f) = (
        mean(|f| f.update_ms),
        mean(|f| f.prepare_ms),
        mean(|f| f.trace_ms),
        mean(|f| f.frame_ms),
    );
    if a.tracer.json {
        return print_json(&AnimateReport {
            scene: base.name.clone(),
            triangles: base.len(),
            tracer: tracer.name(),
            motion: motion_name(a.motion),
            meshes: anim.scene().meshes().len(),
            width: a.view.width,
            height: a.view.height,
            threads: rayon::current_num_threads(),
            mean_update_ms: u,
            mean_prepare_ms: p,
            mean_trace_ms: t,
            mean_frame_ms: f,
            frames,
        });
    }
    eprintln!(
        "{} frames with {}: mean prepare {p:.1} ms + trace {t:.1} ms = {f:.1} ms per frame",
        a.frames,
        tracer.name()
    );
    Ok(())
}
