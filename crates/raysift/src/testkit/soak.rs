//! The soak: adversarial cases ([`super::adversarial`]) by the thousand, every tracer and preset
//! against `naive`, every disagreement kept with what reproduces it, and every tracer's time per
//! ray against `naive`'s (an input that makes a tracer pathologically slow is a defect too).

use super::adversarial::{self, Case};
use super::Oracle;
use crate::rays::{HitBatch, RayBatch};
use crate::tracers::{self, Entry};
use serde::Serialize;
use std::time::Instant;

/// What to soak.
#[derive(Clone, Debug)]
pub struct SoakConfig {
    /// Total rays (spread over the cases).
    pub rays: usize,
    /// Rays per case.
    pub rays_per_case: usize,
    /// First seed.
    pub seed: u64,
    /// Tracers (registry names) to check; empty: every tracer but naive.
    pub tracers: Vec<String>,
    /// Classes; empty: all of [`adversarial::CLASSES`].
    pub classes: Vec<String>,
    /// Also every preset of each tracer (else its defaults only).
    pub presets: bool,
}

impl Default for SoakConfig {
    fn default() -> Self {
        Self {
            rays: 1_000_000,
            rays_per_case: 2000,
            seed: 1,
            tracers: Vec::new(),
            classes: Vec::new(),
            presets: true,
        }
    }
}

/// One disagreement with `naive`.
#[derive(Clone, Debug, Serialize)]
pub struct Disagreement {
    /// `class:seed` of the case.
    pub case: String,
    /// Tracer and preset.
    pub tracer: String,
    /// `closest` or `occlusion`.
    pub query: &'static str,
    /// Ray index in the case.
    pub ray: usize,
    /// What naive answered and what the tracer did.
    pub detail: String,
}

/// Per tracer configuration: rays, disagreements, and time against naive.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TracerSummary {
    /// Tracer and preset.
    pub tracer: String,
    /// Rays checked (closest hit and occlusion each).
    pub rays: u64,
    /// Rays whose closest hit differed.
    pub closest_disagreements: u64,
    /// Rays whose occlusion differed.
    pub occlusion_disagreements: u64,
    /// True for a tracer's default configuration: the one a time limit applies to (presets are
    /// tuned for one workload each, and a soak case is rarely it; their ratios are reported).
    pub default: bool,
    /// Largest ratio over the cases of this configuration's prepare + closest-hit + occlusion
    /// time to naive's (naive's counted as at least [`NAIVE_FLOOR_MS`]; creating the tracer is
    /// not timed), and the case where it happened.
    pub worst_time_ratio: f64,
    /// The case of the worst ratio.
    pub worst_case: String,
}

/// What a soak found.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SoakReport {
    /// Cases generated.
    pub cases: u64,
    /// Rays in all cases.
    pub rays: u64,
    /// Per tracer configuration.
    pub tracers: Vec<TracerSummary>,
    /// The first disagreements (at most 100 kept), each reproducible from its case name.
    pub disagreements: Vec<Disagreement>,
}

impl SoakReport {
    /// Total disagreements over all tracers.
    pub fn total_disagreements(&self) -> u64 {
        self.tracers
            .iter()
            .map(|t| t.closest_disagreements + t.occlusion_disagreements)
            .sum()
    }
}

/// A tracer configuration: label, registry entry, options, whether it is the default.
type Configuration = (String, &'static Entry, Vec<(String, String)>, bool);

/// Naive's time on a case counts as at least this in time ratios: a small case takes naive a
/// fraction of a millisecond, where scheduling noise on a shared machine alone makes ratios of
/// 10 or more.
pub const NAIVE_FLOOR_MS: f64 = 2.0;

/// The tracer configurations a soak checks.
fn configurations(cfg: &SoakConfig) -> crate::Result<Vec<Configuration>> {
    let mut out = Vec::new();
    let names: Vec<String> = if cfg.tracers.is_empty() {
        tracers::names()
            .into_iter()
            .filter(|n| *n != "naive")
            .map(String::from)
            .collect()
    } else {
        cfg.tracers.clone()
    };
    for n in &names {
        let e = tracers::entry(n)?;
        out.push((e.name.to_string(), e, Vec::new(), true));
        if cfg.presets {
            for p in e.presets {
                out.push((
                    format!("{} [{}]", e.name, p.name),
                    e,
                    tracers::preset_opts(p),
                    false,
                ));
            }
        }
    }
    Ok(out)
}

/// Regenerates a case by its `class:seed` name.
pub fn regenerate(name: &str, rays: usize) -> Option<Case> {
    let (class, seed) = name.split_once(':')?;
    adversarial::case(class, seed.parse().ok()?, rays)
}

/// Runs the soak; `progress(done_rays, total_rays)` is called after each case.
pub fn soak(cfg: &SoakConfig, mut progress: impl FnMut(u64, u64)) -> crate::Result<SoakReport> {
    let classes: Vec<String> = if cfg.classes.is_empty() {
        adversarial::CLASSES.iter().map(|s| s.to_string()).collect()
    } else {
        cfg.classes.clone()
    };
    for c in &classes {
        if !adversarial::CLASSES.contains(&c.as_str()) {
            return Err(crate::Error::Invalid(format!(
                "unknown soak class {c:?}; classes: {}",
                adversarial::CLASSES.join(", ")
            )));
        }
    }
    let confs = configurations(cfg)?;
    let mut report = SoakReport {
        tracers: confs
            .iter()
            .map(|(l, _, _, default)| TracerSummary {
                tracer: l.clone(),
                default: *default,
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    };
    let per_case = cfg.rays_per_case.max(1);
    let mut seed = cfg.seed;
    while report.rays < cfg.rays as u64 {
        let class = &classes[(seed as usize) % classes.len()];
        let n = per_case.min(cfg.rays - report.rays as usize);
        let case = adversarial::case(class, seed, n).expect("known class");
        seed += 1;
        let t0 = Instant::now();
        let want = Oracle::new(&case.scene, &case.rays);
        let naive_ms = t0.elapsed().as_secs_f64() * 1e3;
        for (k, (label, entry, opts, _)) in confs.iter().enumerate() {
            let mut t = entry.create(opts)?;
            let t0 = Instant::now();
            t.prepare(&case.scene)?;
            let (hits, _) = t.intersect_timed(&case.scene, &case.rays)?;
            let (occ, _) = t.occluded_timed(&case.scene, &case.rays)?;
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            let s = &mut report.tracers[k];
            s.rays += case.rays.len() as u64;
            let ratio = ms / naive_ms.max(NAIVE_FLOOR_MS);
            if ratio > s.worst_time_ratio {
                s.worst_time_ratio = ratio;
                s.worst_case = case.name.clone();
            }
            compare(
                &case,
                &want,
                &hits,
                &occ,
                label,
                s,
                &mut report.disagreements,
            );
        }
        report.cases += 1;
        report.rays += case.rays.len() as u64;
        progress(report.rays, cfg.rays as u64);
    }
    Ok(report)
}

#[allow(clippy::needless_range_loop)] // rays, hits and flags indexed alike
fn compare(
    case: &Case,
    want: &Oracle,
    hits: &HitBatch,
    occ: &[bool],
    label: &str,
    s: &mut TracerSummary,
    out: &mut Vec<Disagreement>,
) {
    let rays: &RayBatch = &case.rays;
    for i in 0..rays.len() {
        let w = &want.hits;
        let same = w.t[i].to_bits() == hits.t[i].to_bits()
            && w.prim[i] == hits.prim[i]
            && w.u[i].to_bits() == hits.u[i].to_bits()
            && w.v[i].to_bits() == hits.v[i].to_bits();
        if !same {
            s.closest_disagreements += 1;
            if out.len() < 100 {
                out.push(Disagreement {
                    case: case.name.clone(),
                    tracer: label.to_string(),
                    query: "closest",
                    ray: i,
                    detail: format!(
                        "ray {:?}: naive (t {}, prim {}, u {}, v {}) vs (t {}, prim {}, u {}, v {})",
                        rays.get(i),
                        w.t[i],
                        w.prim[i],
                        w.u[i],
                        w.v[i],
                        hits.t[i],
                        hits.prim[i],
                        hits.u[i],
                        hits.v[i]
                    ),
                });
            }
        }
        if want.occluded[i] != occ[i] {
            s.occlusion_disagreements += 1;
            if out.len() < 100 {
                out.push(Disagreement {
                    case: case.name.clone(),
                    tracer: label.to_string(),
                    query: "occlusion",
                    ray: i,
                    detail: format!(
                        "ray {:?}: naive occluded={} vs {}",
                        rays.get(i),
                        want.occluded[i],
                        occ[i]
                    ),
                });
            }
        }
    }
}
