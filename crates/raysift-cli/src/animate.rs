//! `raysift animate`: frames whose geometry changes in place, the tracer prepared again each
//! frame (rebuilding or updating what changed).

use crate::args::{camera_for, make_tracer, open_scene_or_default, TracerArgs, ViewArgs};
use crate::progress;
use crate::report::{print_json, AnimateReport, FrameReport};
use anyhow::{bail, Context, Result};
use clap::Args;
use raysift::render::{self, Shade};
use raysift::scene::animate::{Animation, Motion};
use raysift::scene::io::gltf_anim::load_animated;
use raysift::scene::io::Format;
use raysift::scene::{Change, Scene, Stamp};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
pub struct AnimateArgs {
    /// Scene file or generator; the embedded bunny when omitted.
    scene: Option<String>,
    /// Motion: explode (triangles fly apart), spin-parts (meshes rotate rigidly) or gltf (the
    /// file's own animation: keyframed nodes, skinning). Default: gltf for a .gltf/.glb file
    /// with animations, explode otherwise.
    #[arg(long)]
    motion: Option<Motion>,
    /// The glTF animation to play, by name or index (default: the first).
    #[arg(long)]
    animation: Option<String>,
    /// Number of frames (explode, spin-parts: time runs from 0 to 1 over them; gltf: frame f
    /// is at f · duration / frames seconds).
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
    /// No progress bar (it is drawn only on a terminal).
    #[arg(long)]
    quiet: bool,
    #[command(flatten)]
    pub tracer: TracerArgs,
}

/// Whether `spec` names a glTF file (its own animation can be played).
fn is_gltf(spec: &str) -> bool {
    matches!(
        raysift::scene::io::detect_format(Path::new(spec)),
        Ok((Format::Gltf | Format::Glb, _))
    )
}

/// The animation of the arguments: the file's own (gltf motion), or a generated motion of the
/// scene; everything is checked before any frame is made.
fn open_animation(a: &AnimateArgs) -> Result<(Scene, Animation)> {
    if let Some(spec) = a.scene.as_deref().filter(|s| is_gltf(s)) {
        if a.motion.is_none_or(|m| m == Motion::Gltf) {
            let (scene, playback) = load_animated(spec)?;
            match playback {
                Some(p) => {
                    let mut anim = Animation::from_playback(scene.clone(), p);
                    if let Some(which) = &a.animation {
                        anim.select(which)?;
                    }
                    return Ok((scene, anim));
                }
                None if a.motion == Some(Motion::Gltf) => {
                    bail!("{spec}: the file has no animations (--motion gltf)")
                }
                None if a.animation.is_some() => {
                    bail!("{spec}: the file has no animations (--animation)")
                }
                None => {
                    let anim = Animation::new(&scene, Motion::Explode)?;
                    return Ok((scene, anim));
                }
            }
        }
    } else if a.motion == Some(Motion::Gltf) {
        bail!("--motion gltf plays a .gltf or .glb file's animation; give such a file");
    }
    if a.animation.is_some() {
        bail!("--animation chooses a glTF file's animation; it needs the gltf motion");
    }
    let base = open_scene_or_default(a.scene.as_deref())?;
    let anim = Animation::new(&base, a.motion.unwrap_or(Motion::Explode))?;
    Ok((base, anim))
}

pub fn run(a: &AnimateArgs) -> Result<()> {
    progress::set_quiet(a.quiet);
    if a.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if a.view.width == 0 || a.view.height == 0 {
        bail!("--width and --height must be positive");
    }
    let mut tracer = make_tracer(&a.tracer)?;
    let (base, mut anim) = open_animation(a)?;
    // Frame the whole motion: the union of the bounds of a few frames across it.
    let mut bounds = anim.at(anim.frame_time(0, a.frames))?.bounds();
    for k in 1..=8 {
        let t = anim.frame_time(k * a.frames.saturating_sub(1) / 8, a.frames);
        bounds = bounds.union(anim.at(t)?.bounds());
    }
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
        let t = anim.frame_time(k, a.frames);
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
            motion: anim.motion().name(),
            animation: anim.playback().map(|p| p.clip().name.clone()),
            duration_s: anim.playback().map(|p| p.clip().duration),
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
    let moved = frames.iter().map(|f| f.moved).max().unwrap_or(0);
    let deformed = frames.iter().map(|f| f.deformed).max().unwrap_or(0);
    eprintln!(
        "{} frames of {} with {}: up to {moved} meshes moved and {deformed} deformed per frame; mean animation {u:.1} ms, prepare {p:.1} ms + trace {t:.1} ms = {f:.1} ms per frame",
        a.frames,
        anim.playback().map_or(anim.motion().name(), |p| p.clip().name.as_str()),
        tracer.name()
    );
    Ok(())
}
