//! `raysift render`: an image by ray casting (normal, depth or diffuse shading with shadows),
//! diffuse path tracing, or a heatmap of the tracer's per-ray cost.

use crate::args::{camera_for, make_tracer, open_scene_or_default, parse_vec3};
use crate::args::{TracerArgs, ViewArgs};
use crate::image_out::{format_of, write_radiance, Format};
use crate::progress::spinner;
use crate::progress::{Plan, RenderBar};
use crate::report::{mrays_per_s, print_json, BounceReport, Counts, PassReport};
use crate::report::{HeatmapReport, PathReport, RenderReport};
use anyhow::{bail, Result};
use clap::Args;
use glam::Vec3;
use raysift::render::heatmap::{self, CostKind};
use raysift::render::{self, Shade};
use raysift::Stats;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args, Clone)]
pub struct RenderArgs {
    /// Scene file or generator, or a scene description (.toml or .json: meshes, camera, lights,
    /// settings; the flags typed here override it); the embedded bunny when omitted.
    pub(crate) scene: Option<String>,
    #[command(flatten)]
    pub(crate) view: ViewArgs,
    /// Point light x,y,z for diffuse shading (default: above and right of the eye).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub(crate) light: Option<Vec3>,
    /// Ray casting's shading: diffuse (with shadows; the default), normal or depth.
    #[arg(long, value_parser = shade_parser())]
    pub(crate) shade: Option<Shade>,
    /// Integrator: raycast (one ray per pixel, shaded) or path (diffuse path tracing under a sky).
    #[arg(long, value_enum, default_value_t = Integrator::Raycast)]
    pub(crate) integrator: Integrator,
    /// Path tracing and instant radiosity: samples per pixel, at least 1 [default: 4 for path,
    /// 1 for instant radiosity].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) spp: Option<u32>,
    /// Path tracing: bounces after the primary hit, no Russian roulette [default: 7].
    #[arg(long)]
    pub(crate) bounces: Option<u32>,
    /// Path tracing: plain next-event estimation, without multiple importance sampling of the
    /// lights that bounce rays hit (the same image in expectation, noisier next to lights).
    #[arg(long)]
    pub(crate) no_mis: bool,
    /// Random seed (path, distribution): the same seed gives the same image, whatever the
    /// thread count and the tracer [default: 1].
    #[arg(long)]
    pub(crate) seed: Option<u64>,
    /// Distribution: a×a stratified antialiasing samples per pixel [default: 1].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub(crate) aa: Option<u32>,
    /// Distribution: N×N shadow samples per light per hit [default: 4; RTRPS uses 16].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub(crate) light_samples: Option<u32>,
    /// Distribution: N×N diffuse bounce samples per hit, 0 for none [default: 0].
    #[arg(long, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub(crate) bounce_samples: Option<u32>,
    /// A square area light x,y,z,size,power (horizontal, facing down, white, power in watts);
    /// repeatable; added to the scene's emissive meshes (path, distribution).
    #[arg(long, value_name = "X,Y,Z,SIZE,POWER", allow_hyphen_values = true)]
    pub(crate) area_light: Vec<String>,
    /// Instant radiosity: VPLs wanted (Mora: 1000, 10000, 40000) [default: 1000].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=10_000_000))]
    pub(crate) vpls: Option<u32>,
    /// Instant radiosity: diffuse bounces of each photon (Mora: 1, 3, 5) [default: 1].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub(crate) vpl_bounces: Option<u32>,
    /// Instant radiosity: VPLs each camera hit sends shadow rays to [default: 64].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub(crate) vpl_subset: Option<u32>,
    /// Draw the tracer's per-ray cost instead of shading: nodes entered, tests, or ray/triangle
    /// tests, in false colour with a colour bar (the scale is printed too).
    #[arg(long, value_name = "COUNT", value_parser = heatmap_parser())]
    pub(crate) heatmap: Option<CostKind>,
    /// Output image: .png (8-bit sRGB, clamped) or .exr (linear radiance, float RGB; path,
    /// distribution and instant radiosity only).
    #[arg(long, default_value = "raysift.png")]
    pub(crate) out: PathBuf,
    /// Also write every ray the render traced, and the tracer's answers, into this folder
    /// (intersect-rays.npy, intersect-hits.npy, occluded-rays.npy, occluded.npy, calls.json),
    /// for tracing the same workload with another engine. Recording slows the render.
    #[arg(long, value_name = "DIR")]
    pub(crate) record_rays: Option<PathBuf>,
    /// No progress bar or spinner (they are drawn only on a terminal, after about a second).
    #[arg(long)]
    pub(crate) quiet: bool,
    /// Print the work counters to stderr.
    #[arg(long)]
    pub(crate) stats: bool,
    #[command(flatten)]
    pub tracer: TracerArgs,
}

/// How `render` makes its image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Integrator {
    /// One ray per pixel, shaded (`--shade`).
    Raycast,
    /// Diffuse path tracing, one batch per bounce, with next-event estimation to the area lights
    /// (under a sky when there are none).
    Path,
    /// Distribution ray tracing: a×a antialiasing, N×N shadow samples per light per hit as
    /// origin-grid groups, optional N_b×N_b diffuse bounce.
    Distribution,
    /// Instant radiosity: photons from the lights leave VPLs; camera hits shadow-ray a subset.
    InstantRadiosity,
}

/// Parses `--area-light x,y,z,size,power` (the error names the flag and the value).
fn area_light(s: &str) -> Result<raysift::render::light::AreaLight> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--area-light {s:?}: expected x,y,z,size,power numbers"))?;
    let [x, y, z, size, power] = v[..] else {
        bail!(
            "--area-light {s:?}: expected 5 numbers x,y,z,size,power, got {}",
            v.len()
        );
    };
    if !Vec3::new(x, y, z).is_finite() {
        bail!("--area-light {s:?}: position must be finite");
    }
    Ok(raysift::render::light::AreaLight::square(
        Vec3::new(x, y, z),
        size,
        power,
        &format!("--area-light {s:?}"),
    )?)
}

/// `--shade`'s parser: the allowed names listed in `--help` and in the error.
pub fn shade_parser() -> impl clap::builder::TypedValueParser<Value = Shade> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(["diffuse", "normal", "depth"])
        .map(|s| s.parse::<Shade>().expect("a listed shading"))
}

/// `--heatmap`'s parser: the allowed names listed in `--help` and in the error.
fn heatmap_parser() -> impl clap::builder::TypedValueParser<Value = CostKind> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(CostKind::ALL.map(CostKind::name))
        .map(|s| s.parse::<CostKind>().expect("a listed count"))
}

/// Refuses arguments the chosen integrator would ignore, and an image it cannot write, before any
/// work is done.
fn check(a: &RenderArgs) -> Result<()> {
    if format_of(&a.out)? == Format::Exr
        && (a.integrator == Integrator::Raycast || a.heatmap.is_some())
    {
        bail!(
            "{}: .exr holds linear radiance, which ray casting and --heatmap do not make; use --integrator path, distribution or instant-radiosity, or name the file .png",
            a.out.display()
        );
    }
    for l in &a.area_light {
        area_light(l)?;
    }
    if let Some(d) = &a.record_rays {
        if d.exists() && !d.is_dir() {
            bail!("--record-rays {}: exists and is not a folder", d.display());
        }
    }
    let dist = a.integrator == Integrator::Distribution;
    let ir = a.integrator == Integrator::InstantRadiosity;
    if a.no_mis && a.integrator != Integrator::Path {
        bail!("--no-mis applies to --integrator path only");
    }
    for (given, flag) in [
        (a.vpls.is_some(), "--vpls"),
        (a.vpl_bounces.is_some(), "--vpl-bounces"),
        (a.vpl_subset.is_some(), "--vpl-subset"),
    ] {
        if given && !ir {
            bail!("{flag} applies to --integrator instant-radiosity only");
        }
    }
    if ir {
        for (given, flag) in [
            (a.heatmap.is_some(), "--heatmap"),
            (a.shade.is_some(), "--shade"),
            (a.light.is_some(), "--light (use --area-light)"),
            (a.bounces.is_some(), "--bounces (use --vpl-bounces)"),
        ] {
            if given {
                bail!("--integrator instant-radiosity takes no {flag}");
            }
        }
    }
    for (given, flag) in [
        (a.aa.is_some(), "--aa"),
        (a.light_samples.is_some(), "--light-samples"),
        (a.bounce_samples.is_some(), "--bounce-samples"),
    ] {
        if given && !dist {
            bail!("{flag} applies to --integrator distribution only");
        }
    }
    if a.integrator == Integrator::Raycast && (!a.area_light.is_empty() || a.seed.is_some()) {
        bail!("--area-light and --seed apply to --integrator path or distribution, not to ray casting");
    }
    if dist {
        for (given, flag) in [
            (a.heatmap.is_some(), "--heatmap"),
            (a.shade.is_some(), "--shade"),
            (a.light.is_some(), "--light (use --area-light)"),
            (a.spp.is_some(), "--spp (use --aa)"),
            (a.bounces.is_some(), "--bounces (use --bounce-samples)"),
        ] {
            if given {
                bail!("--integrator distribution takes no {flag}");
            }
        }
        return Ok(());
    }
    let path = a.integrator == Integrator::Path;
    if a.heatmap.is_some() {
        for (given, flag) in [
            (path, "--integrator path"),
            (a.shade.is_some(), "--shade"),
            (a.light.is_some(), "--light"),
        ] {
            if given {
                bail!("--heatmap draws the camera rays' cost; it takes no {flag}");
            }
        }
    }
    if path {
        if a.shade.is_some() {
            bail!("--shade applies to ray casting, not to --integrator path (which shades diffusely under a sky)");
        }
        if a.light.is_some() {
            bail!("--light applies to ray casting with --shade diffuse, not to --integrator path (use --area-light)");
        }
    } else {
        if a.spp.is_some() && !ir {
            bail!("--spp applies to --integrator path or instant-radiosity only");
        }
        if a.bounces.is_some() {
            bail!("--bounces applies to --integrator path only");
        }
        if a.light.is_some() && a.shade.is_some_and(|s| s != Shade::Diffuse) {
            bail!("--light applies to --shade diffuse only");
        }
    }
    Ok(())
}

/// The CLI name of a shading.
pub fn shade_name(s: Shade) -> &'static str {
    match s {
        Shade::Normal => "normal",
        Shade::Depth => "depth",
        Shade::Diffuse => "diffuse",
    }
}

/// The ids of the `render` arguments typed on the command line (not defaults), which a scene
/// file's settings do not override.
pub fn given_ids(m: &clap::ArgMatches) -> Vec<String> {
    m.ids()
        .filter(|id| m.value_source(id.as_str()) == Some(clap::parser::ValueSource::CommandLine))
        .map(|id| id.as_str().to_string())
        .collect()
}

pub fn run(a: &RenderArgs, given: &[String]) -> Result<()> {
    crate::progress::set_quiet(a.quiet);
    match a
        .scene
        .as_deref()
        .filter(|s| crate::scenefile::is_scene_file(s))
    {
        Some(file) => {
            let file = std::path::Path::new(file);
            let f = crate::scenefile::read(file)?;
            let a = crate::scenefile::apply(file, &f, a, given)?;
            check(&a)?;
            let make = make_tracer(&a.tracer)?;
            let s = crate::scenefile::load(file, &f)?;
            render_recorded(&a, make, s)
        }
        None => {
            check(a)?;
            let make = make_tracer(&a.tracer)?;
            let s = open_scene_or_default(a.scene.as_deref())?;
            render_recorded(a, make, s)
        }
    }
}

/// Renders, then writes the recorded rays when `--record-rays` asks for them.
fn render_recorded(
    a: &RenderArgs,
    tracer: Box<dyn raysift::Tracer>,
    s: raysift::Scene,
) -> Result<()> {
    let rec = a
        .record_rays
        .as_ref()
        .map(|_| crate::record::Recorder::default());
    render_scene(a, tracer, &s, rec.as_ref())?;
    if let (Some(dir), Some(rec)) = (&a.record_rays, &rec) {
        rec.write(dir, &s)?;
    }
    Ok(())
}

fn render_scene(
    a: &RenderArgs,
    mut tracer: Box<dyn raysift::Tracer>,
    s: &raysift::Scene,
    rec: Option<&crate::record::Recorder>,
) -> Result<()> {
    let cam = camera_for(&s.bounds(), &a.view)?;
    let (w, h) = (a.view.width, a.view.height);
    let t0 = Instant::now();
    let pb = spinner(format!("{}: preparing {w}×{h}", tracer.name()));
    let prep = tracer.prepare_timed(&s)?;
    pb.finish_and_clear();
    let pixels = w as u64 * h as u64;
    let extra = a
        .area_light
        .iter()
        .map(|l| area_light(l))
        .collect::<Result<Vec<_>>>()?;
    let lights = render::light::Lights::new(&s, extra);
    let plan = match a.integrator {
        Integrator::Raycast => Plan::Raycast { pixels },
        Integrator::Path => {
            let d = render::path::PathConfig::default();
            Plan::Path {
                spp: a.spp.unwrap_or(d.spp),
                bounces: a.bounces.unwrap_or(d.bounces),
                pixels,
            }
        }
        Integrator::Distribution => {
            let d = render::distribution::DistConfig::default();
            let ls = a.light_samples.unwrap_or(d.light_side) as u64;
            let nb = a.bounce_samples.unwrap_or(d.bounce_side) as u64;
            let nl = lights.lights.len().max(1) as u64;
            Plan::Distribution {
                per_hit: nl * ls * ls + nb * nb * (1 + nl),
            }
        }
        Integrator::InstantRadiosity => Plan::Radiosity {
            subset: a
                .vpl_subset
                .unwrap_or(render::radiosity::IrConfig::default().subset)
                as u64,
            spp: a.spp.unwrap_or(1),
        },
    };
    let bar = RenderBar::new(plan);
    let hook = |c: render::progress::Call| {
        bar.on(c);
        if let Some(r) = rec {
            r.on(c);
        }
    };
    let inner = tracer;
    let watched = render::progress::Watched::new(inner.as_ref(), &hook);
    let tracer: &dyn raysift::Tracer = &watched;
    let pb = &bar;
    if let Some(kind) = a.heatmap {
        let m = heatmap::heatmap(&s, tracer, &cam, w, h, kind)?;
        pb.finish();
        m.image.save_png(&a.out)?;
        let sc = m.scale;
        eprintln!(
            "{} per ray ({}): min {}, max {}, mean {:.2}; wrote {} ({w}×{h} + {} pixel colour bar)",
            kind.name(),
            tracer.name(),
            sc.min,
            sc.max,
            sc.mean,
            a.out.display(),
            m.image.width - w
        );
        if a.tracer.json {
            print_json(&HeatmapReport {
                scene: s.name.clone(),
                triangles: s.len(),
                tracer: tracer.name(),
                heatmap: kind.name(),
                width: w,
                height: h,
                image_width: m.image.width,
                image_height: m.image.height,
                threads: rayon::current_num_threads(),
                rays: m.stats.rays,
                hits: m.hits,
                scale: sc,
                prepare_ms: prep.prepare_ms,
                trace_ms: m.stats.trace_ms,
                mrays_per_s: mrays_per_s(m.stats.rays, m.stats.trace_ms),
                tracer_bytes: tracer.bytes(),
                stats: Counts::of_frame(&prep, &m.stats),
                out: a.out.display().to_string(),
            })?;
        }
        if a.stats {
            print_counters(&prep, tracer.bytes(), &[("camera", &m.stats)]);
        }
        return Ok(());
    }
    if a.integrator != Integrator::Raycast && a.integrator != Integrator::Path && lights.is_empty()
    {
        bail!("this integrator needs a light: the scene has no emissive material; add --area-light x,y,z,size,power");
    }
    if a.integrator == Integrator::InstantRadiosity {
        let d = render::radiosity::IrConfig::default();
        let cfg = render::radiosity::IrConfig {
            vpls: a.vpls.unwrap_or(d.vpls),
            bounces: a.vpl_bounces.unwrap_or(d.bounces),
            subset: a.vpl_subset.unwrap_or(d.subset),
            seed: a.seed.unwrap_or(d.seed),
            spp: a.spp.unwrap_or(d.spp),
            ..d
        };
        let (rad, nv, phases) =
            render::radiosity::instant_radiosity(&s, tracer, &cam, w, h, &lights, &cfg)?;
        pb.finish();
        write_radiance(&a.out, &rad, w, h)?;
        return report_phases(
            a,
            &s,
            tracer,
            &prep,
            t0,
            &phases,
            serde_json::json!({
                "integrator": "instant-radiosity", "vpls": nv, "vpl_bounces": cfg.bounces,
                "vpl_subset": cfg.subset, "spp": cfg.spp, "lights": lights.lights.len(),
            }),
        );
    }
    if a.integrator == Integrator::Distribution {
        let d = render::distribution::DistConfig::default();
        let cfg = render::distribution::DistConfig {
            aa: a.aa.unwrap_or(d.aa),
            light_side: a.light_samples.unwrap_or(d.light_side),
            bounce_side: a.bounce_samples.unwrap_or(d.bounce_side),
            seed: a.seed.unwrap_or(d.seed),
        };
        let (rad, phases) =
            render::distribution::distribution(&s, tracer, &cam, w, h, &lights, &cfg)?;
        pb.finish();
        write_radiance(&a.out, &rad, w, h)?;
        return report_phases(
            a,
            &s,
            tracer,
            &prep,
            t0,
            &phases,
            serde_json::json!({
                "integrator": "distribution", "aa": cfg.aa, "light_samples": cfg.light_side,
                "bounce_samples": cfg.bounce_side, "lights": lights.lights.len(),
            }),
        );
    }
    if a.integrator == Integrator::Path {
        let defaults = render::path::PathConfig::default();
        let cfg = render::path::PathConfig {
            spp: a.spp.unwrap_or(defaults.spp),
            bounces: a.bounces.unwrap_or(defaults.bounces),
            seed: a.seed.unwrap_or(defaults.seed),
            mis: !a.no_mis,
            ..defaults
        };
        let (rad, per_depth) = render::path::path_trace_lit(&s, tracer, &cam, w, h, &cfg, &lights)?;
        pb.finish();
        write_radiance(&a.out, &rad, w, h)?;
        let rays: u64 = per_depth.iter().map(|b| b.rays + b.shadow_rays).sum();
        let trace_ms: f64 = per_depth
            .iter()
            .map(|b| b.stats.trace_ms + b.shadow.trace_ms)
            .sum();
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
                    "depth {}: {} rays, {} hits, {:.1} ms, {:.2} Mrays/s; {} shadow rays, {:.1} ms",
                    b.depth,
                    b.rays,
                    b.hits,
                    b.stats.trace_ms,
                    b.mrays_per_s,
                    b.shadow_rays,
                    b.shadow.trace_ms
                );
            }
        }
        return Ok(());
    }
    let shade = a.shade.unwrap_or_default();
    let (img, rs) = render::raycast(&s, tracer, &cam, w, h, shade, a.light)?;
    pb.finish();
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
            shade: shade_name(shade),
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

/// The report of a phased render (distribution, instant radiosity): JSON with `extra`'s fields,
/// or one line; `--stats` adds a line per phase with rays and Mrays/s.
fn report_phases(
    a: &RenderArgs,
    s: &raysift::Scene,
    tracer: &dyn raysift::Tracer,
    prep: &Stats,
    t0: Instant,
    phases: &[raysift::render::distribution::Phase],
    extra: serde_json::Value,
) -> Result<()> {
    let (w, h) = (a.view.width, a.view.height);
    let frame_ms = t0.elapsed().as_secs_f64() * 1e3;
    let passes: Vec<PassReport> = phases
        .iter()
        .filter(|p| p.rays > 0)
        .map(|p| PassReport::of(p.name, &p.stats))
        .collect();
    let rays: u64 = phases.iter().map(|p| p.rays).sum();
    let trace_ms: f64 = phases.iter().map(|p| p.stats.trace_ms).sum();
    if a.tracer.json {
        let mut j = serde_json::json!({
            "scene": s.name, "triangles": s.len(), "tracer": tracer.name(),
            "width": w, "height": h, "threads": rayon::current_num_threads(),
            "rays": rays, "prepare_ms": prep.prepare_ms,
            "trace_ms": trace_ms, "frame_ms": frame_ms,
            "mrays_per_s": mrays_per_s(rays, trace_ms), "passes": passes,
            "phase_hits": phases.iter().map(|p| (p.name, p.hits)).collect::<std::collections::BTreeMap<_, _>>(),
            "out": a.out.display().to_string(),
        });
        if let (Some(j), serde_json::Value::Object(e)) = (j.as_object_mut(), extra) {
            j.extend(e);
        }
        print_json(&j)?;
    } else {
        eprintln!(
            "wrote {} ({rays} rays in {trace_ms:.0} ms of tracing)",
            a.out.display()
        );
    }
    if a.stats {
        for p in phases.iter().filter(|p| p.rays > 0) {
            eprintln!(
                "{}: {} rays, {} hit/blocked, {:.1} ms, {:.2} Mrays/s",
                p.name,
                p.rays,
                p.hits,
                p.stats.trace_ms,
                mrays_per_s(p.rays, p.stats.trace_ms)
            );
        }
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
