//! `raysift soak`: adversarial scenes and rays (coplanar grids, rays through shared edges and
//! vertices, near-parallel rays, needle fans, duplicated triangles, huge and tiny scales, denormal
//! and huge directions, grazing cameras, ray groups from one origin) by the million, every tracer and preset against `naive`
//! (`raysift::testkit::soak`). Each disagreement is printed with the files that reproduce it (the
//! case's scene as OBJ, its rays as rays.npy, and the `raysift trace` command); each tracer's worst
//! time against `naive` is reported. Exit code 1 on any disagreement or a time ratio above
//! `--max-time-ratio`.

use crate::progress;
use anyhow::{bail, Context, Result};
use clap::Args;
use raysift::rays::npy;
use raysift::testkit::soak::{self, SoakConfig};
use std::collections::BTreeSet;
use std::path::PathBuf;

#[derive(Args)]
pub struct SoakArgs {
    /// Rays in all (spread over cases of a few thousand rays each).
    #[arg(long, default_value_t = 1_000_000)]
    rays: usize,
    /// Rays per case.
    #[arg(long, default_value_t = 2000)]
    rays_per_case: usize,
    /// First seed (case k of a run uses seed + k; a case is `class:seed`).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Tracers to check (comma-separated registry names); default every tracer but naive.
    #[arg(long, value_delimiter = ',')]
    tracers: Vec<String>,
    /// Classes (comma-separated): vertex, grid, tilted, fan, duplicates, scale, directions, camera, grids.
    #[arg(long, value_delimiter = ',')]
    classes: Vec<String>,
    /// Check each tracer's defaults only, not every preset of its registry entry.
    #[arg(long)]
    no_presets: bool,
    /// Folder for the reproductions of disagreeing cases.
    #[arg(long, default_value = "soak-failures")]
    out: PathBuf,
    /// Fail when a tracer's default configuration takes more than this many times naive's time
    /// on a case (prepare and both queries; naive's time counted from 2 ms up). Presets' ratios
    /// are reported, not limited.
    #[arg(long, default_value_t = 20.0)]
    max_time_ratio: f64,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Only write the files of case CLASS:SEED (its scene as OBJ, its rays as .npy) into --out,
    /// to reproduce or study it; no soak.
    #[arg(long, value_name = "CLASS:SEED")]
    write_case: Option<String>,
}

pub fn run(a: &SoakArgs) -> Result<()> {
    if a.rays == 0 || a.rays_per_case == 0 {
        bail!("--rays and --rays-per-case must be positive");
    }
    if let Some(case) = &a.write_case {
        let (obj, rays) = write_case(case, a.rays_per_case, &a.out)?;
        eprintln!("wrote {} and {}", obj.display(), rays.display());
        return Ok(());
    }
    let cfg = SoakConfig {
        rays: a.rays,
        rays_per_case: a.rays_per_case,
        seed: a.seed,
        tracers: a.tracers.clone(),
        classes: a.classes.clone(),
        presets: !a.no_presets,
    };
    let t0 = std::time::Instant::now();
    let pb = progress::spinner(format!("soak: {} rays", a.rays));
    let report = soak::soak(&cfg, |done, total| {
        pb.set_message(format!("soak: {done} of {total} rays"));
    })?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    // Reproductions: one scene and rays file per disagreeing case.
    let cases: BTreeSet<&str> = report
        .disagreements
        .iter()
        .map(|d| d.case.as_str())
        .collect();
    let mut repro = Vec::new();
    for case in cases {
        let (obj, rays) = write_case(case, a.rays_per_case, &a.out)?;
        repro.push((case.to_string(), obj, rays));
    }
    if a.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "{} cases, {} rays, {:.0} s; disagreements with naive: {}",
            report.cases,
            report.rays,
            secs,
            report.total_disagreements()
        );
        println!(
            "{:<70} {:>9} {:>9} {:>9}  worst time vs naive",
            "tracer [preset]", "rays", "closest", "occluded"
        );
        for t in &report.tracers {
            println!(
                "{:<70} {:>9} {:>9} {:>9}  {:.1}x ({})",
                t.tracer,
                t.rays,
                t.closest_disagreements,
                t.occlusion_disagreements,
                t.worst_time_ratio,
                t.worst_case
            );
        }
        for d in &report.disagreements {
            println!(
                "{} {} {} ray {}: {}",
                d.case, d.tracer, d.query, d.ray, d.detail
            );
        }
        for (case, obj, rays) in &repro {
            println!(
                "reproduce {case}: raysift trace {} --rays {} --tracer TRACER [--opt ...] --out hits.npy",
                obj.display(),
                rays.display()
            );
        }
    }
    if report.total_disagreements() > 0 {
        bail!(
            "{} disagreements with naive (reproductions in {})",
            report.total_disagreements(),
            a.out.display()
        );
    }
    if let Some(t) = report
        .tracers
        .iter()
        .find(|t| t.default && t.worst_time_ratio > a.max_time_ratio)
    {
        bail!(
            "{} took {:.1}x naive's time on {} (limit {}x)",
            t.tracer,
            t.worst_time_ratio,
            t.worst_case,
            a.max_time_ratio
        );
    }
    Ok(())
}

/// Writes case `name` (`class:seed`) as `DIR/class-seed.obj` and `DIR/class-seed-rays.npy`.
fn write_case(name: &str, rays: usize, dir: &std::path::Path) -> Result<(PathBuf, PathBuf)> {
    let Some(c) = soak::regenerate(name, rays) else {
        bail!(
            "--write-case {name:?}: expected CLASS:SEED with a class of {}",
            raysift::testkit::adversarial::CLASSES.join(", ")
        );
    };
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let stem = name.replace(':', "-");
    let obj = dir.join(format!("{stem}.obj"));
    let path = dir.join(format!("{stem}-rays.npy"));
    write_obj(&c.scene, &obj)?;
    npy::write_rays(&path, &c.rays)?;
    Ok((obj, path))
}

/// The scene's world triangles as an OBJ file, one `f` per triangle in primitive-id order, so
/// the file loads back with the same ids and corners (f32 printed exactly).
fn write_obj(scene: &raysift::Scene, path: &std::path::Path) -> Result<()> {
    let t = scene.triangles();
    raysift::output::write_atomic(path, |w| {
        writeln!(w, "# {}: {} triangles (raysift soak)", scene.name, t.len())?;
        for i in 0..t.len() {
            for v in t.get(i) {
                writeln!(w, "v {} {} {}", v.x, v.y, v.z)?;
            }
        }
        for i in 0..t.len() {
            writeln!(w, "f {} {} {}", 3 * i + 1, 3 * i + 2, 3 * i + 3)?;
        }
        Ok(())
    })?;
    Ok(())
}
