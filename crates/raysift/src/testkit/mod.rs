//! What every test of a tracer needs, in one place (svenstaro/bvh's `testbase`): the one hit
//! comparer (bit for bit), the check of every registered tracer and preset against `naive`, and
//! the one finder of the real meshes in `../shared/scenes`. Public so that a tracer written
//! outside raysift can be held to the same contract.

pub mod adversarial;
pub mod gltf_rig;
pub mod soak;

use crate::rays::{HitBatch, RayBatch};
use crate::scene::Scene;
use crate::tracer::RayCost;
use crate::tracers::{self, Entry};
use std::path::PathBuf;

/// The first ray where two hit batches differ in `t`, `prim`, `u` or `v` (compared as bits, so
/// `-0.0` differs from `0.0`), described; `None` when they are equal.
pub fn first_difference(want: &HitBatch, got: &HitBatch) -> Option<String> {
    if want.len() != got.len() {
        return Some(format!("length {} vs {}", want.len(), got.len()));
    }
    (0..want.len()).find_map(|i| {
        let same = want.t[i].to_bits() == got.t[i].to_bits()
            && want.prim[i] == got.prim[i]
            && want.u[i].to_bits() == got.u[i].to_bits()
            && want.v[i].to_bits() == got.v[i].to_bits();
        (!same).then(|| {
            format!(
                "ray {i}: want (t {}, prim {}, u {}, v {}) got (t {}, prim {}, u {}, v {})",
                want.t[i],
                want.prim[i],
                want.u[i],
                want.v[i],
                got.t[i],
                got.prim[i],
                got.u[i],
                got.v[i]
            )
        })
    })
}

/// The first ray whose occlusion flags differ, described.
pub fn first_occlusion_difference(want: &[bool], got: &[bool]) -> Option<String> {
    if want.len() != got.len() {
        return Some(format!("length {} vs {}", want.len(), got.len()));
    }
    (0..want.len())
        .find(|&i| want[i] != got[i])
        .map(|i| format!("ray {i}: want occluded={} got {}", want[i], got[i]))
}

/// Naive's answers for a scene and batch: closest hits and occlusion.
pub struct Oracle {
    /// Closest hits.
    pub hits: HitBatch,
    /// Occlusion flags.
    pub occluded: Vec<bool>,
}

impl Oracle {
    /// Traces `rays` with `naive`.
    pub fn new(scene: &Scene, rays: &RayBatch) -> Self {
        let mut t = tracers::create("naive", &[]).expect("naive exists");
        t.prepare(scene).expect("naive prepares anything");
        let (hits, _) = t.intersect_timed(scene, rays).expect("prepared");
        let (occluded, _) = t.occluded_timed(scene, rays).expect("prepared");
        Self { hits, occluded }
    }
}

/// Checks one tracer configuration against `want` on `scene` and `rays`: closest hits and
/// occlusion bit for bit, `Stats::rays`, the same answers with a per-ray cost record asked for
/// (records of the batch's length, and every hit charged at least one triangle test), and the same answers after preparing again for a new
/// frame of the same geometry ([`Scene::touch`]).
pub fn check_tracer(
    entry: &Entry,
    opts: &[(String, String)],
    scene: &mut Scene,
    rays: &RayBatch,
    want: &Oracle,
) -> Result<(), String> {
    let scene_name = scene.name.clone();
    let label = |what: &str| format!("{} {opts:?} {what} on {scene_name}", entry.name);
    let mut t = entry
        .create(opts)
        .map_err(|e| label(&format!("create: {e}")))?;
    t.prepare(scene)
        .map_err(|e| label(&format!("prepare: {e}")))?;
    let (got, stats) = t
        .intersect_timed(scene, rays)
        .map_err(|e| label(&e.to_string()))?;
    if let Some(d) = first_difference(&want.hits, &got) {
        return Err(label(&format!("closest hit: {d}")));
    }
    if stats.rays != rays.len() as u64 {
        return Err(label(&format!(
            "stats.rays = {} for {} rays",
            stats.rays,
            rays.len()
        )));
    }
    let (occ, _) = t
        .occluded_timed(scene, rays)
        .map_err(|e| label(&e.to_string()))?;
    if let Some(d) = first_occlusion_difference(&want.occluded, &occ) {
        return Err(label(&format!("occlusion: {d}")));
    }
    // Asking for per-ray cost changes no answer.
    let mut cost = RayCost::default();
    let mut hits = HitBatch::new(0);
    t.intersect(scene, rays, &mut hits, Some(&mut cost))
        .map_err(|e| label(&e.to_string()))?;
    if let Some(d) = first_difference(&want.hits, &hits) {
        return Err(label(&format!("closest hit with per-ray cost: {d}")));
    }
    if cost.len() != rays.len() {
        return Err(label(&format!(
            "{} cost records for {} rays",
            cost.len(),
            rays.len()
        )));
    }
    // A hit was found by a ray/triangle test of that ray; every test counted is a test.
    if let Some(i) = (0..rays.len())
        .find(|&i| (hits.is_hit(i) && cost.triangles[i] == 0) || cost.tests[i] < cost.triangles[i])
    {
        return Err(label(&format!(
            "per-ray cost of ray {i}: {} tests, {} triangle tests, hit {}",
            cost.tests[i],
            cost.triangles[i],
            hits.is_hit(i)
        )));
    }
    let mut occ = Vec::new();
    t.occluded(scene, rays, &mut occ, Some(&mut cost))
        .map_err(|e| label(&e.to_string()))?;
    if let Some(d) = first_occlusion_difference(&want.occluded, &occ) {
        return Err(label(&format!("occlusion with per-ray cost: {d}")));
    }
    // A new frame of the same geometry (the tracer rebuilds or updates) gives the same answer.
    scene.touch();
    t.prepare(scene)
        .map_err(|e| label(&format!("second prepare: {e}")))?;
    let (again, _) = t
        .intersect_timed(scene, rays)
        .map_err(|e| label(&e.to_string()))?;
    if let Some(d) = first_difference(&want.hits, &again) {
        return Err(label(&format!("closest hit after a new frame: {d}")));
    }
    Ok(())
}

/// The tracers the checks compare with `naive`: every registered one but `naive`, or, when
/// `RAYSIFT_CHECK_TRACERS` holds a comma-separated list of names, those only (CI reruns the
/// suite on DACRT's four-lane path with `RAYSIFT_CHECK_TRACERS=dacrt`: the only tracer on
/// `geom::Lanes`). An unknown name in the list panics, so a typo cannot check nothing.
pub fn contenders() -> Vec<&'static tracers::Entry> {
    let all = tracers::REGISTRY.iter().filter(|e| e.name != "naive");
    match std::env::var("RAYSIFT_CHECK_TRACERS") {
        Ok(list) if !list.trim().is_empty() => {
            let names: Vec<&str> = list.split(',').map(str::trim).collect();
            for n in &names {
                assert!(
                    tracers::REGISTRY.iter().any(|e| e.name == *n),
                    "RAYSIFT_CHECK_TRACERS: unknown tracer {n:?}"
                );
            }
            all.filter(|e| names.contains(&e.name)).collect()
        }
        _ => all.collect(),
    }
}

/// Checks every registered tracer but `naive` ([`contenders`]), in its defaults and every preset
/// it declares, against `naive` on `scene` and `rays` ([`check_tracer`]); returns the first failure.
pub fn check_all(scene: &Scene, rays: &RayBatch) -> Result<(), String> {
    let want = Oracle::new(scene, rays);
    let mut scene = scene.clone();
    for entry in contenders() {
        check_tracer(entry, &[], &mut scene, rays, &want)?;
        for p in entry.presets {
            check_tracer(entry, &tracers::preset_opts(p), &mut scene, rays, &want)
                .map_err(|e| format!("preset {:?}: {e}", p.name))?;
        }
    }
    Ok(())
}

/// Checks every registered tracer and preset through an animation: each keeps one tracer
/// instance and prepares it again every frame (so tracers that update instead of rebuilding are
/// checked on their update path), and must equal `naive` on every frame. `step(scene, f)`
/// changes the scene for frame `f` (through `set_transform` / `replace_positions`).
pub fn check_animation(
    scene: &Scene,
    frames: usize,
    mut step: impl FnMut(&mut Scene, usize),
    rays: &RayBatch,
) -> Result<(), String> {
    let mut configs = Vec::new();
    for entry in contenders() {
        configs.push((entry, Vec::new(), "defaults"));
        for p in entry.presets {
            configs.push((entry, tracers::preset_opts(p), p.name));
        }
    }
    let mut live: Vec<_> = configs
        .iter()
        .map(|(e, o, _)| e.create(o).map_err(|err| err.to_string()))
        .collect::<Result<_, _>>()?;
    let mut scene = scene.clone();
    for f in 0..frames {
        if f > 0 {
            step(&mut scene, f);
        }
        let want = Oracle::new(&scene, rays);
        for (t, (e, _, preset)) in live.iter_mut().zip(&configs) {
            let label = format!("{} [{preset}] frame {f} of {}", e.name, scene.name);
            t.prepare(&scene).map_err(|err| format!("{label}: {err}"))?;
            let (hits, _) = t
                .intersect_timed(&scene, rays)
                .map_err(|err| format!("{label}: {err}"))?;
            if let Some(d) = first_difference(&want.hits, &hits) {
                return Err(format!("{label}: closest hit: {d}"));
            }
            let (occ, _) = t
                .occluded_timed(&scene, rays)
                .map_err(|err| format!("{label}: {err}"))?;
            if let Some(d) = first_occlusion_difference(&want.occluded, &occ) {
                return Err(format!("{label}: occlusion: {d}"));
            }
        }
    }
    Ok(())
}

/// The folder of real meshes, `shared/scenes` beside the checkout (or `$RAYSIFT_SCENES`), found
/// from the current directory upwards; `None`, after printing `SKIPPED: {what}: ...` to stderr,
/// when absent (tests that need it then return early; CI has it).
pub fn shared_scenes(what: &str) -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("RAYSIFT_SCENES").map(PathBuf::from) {
        if p.is_dir() {
            return Some(p);
        }
    }
    let cwd = std::env::current_dir().ok()?;
    let found = cwd
        .ancestors()
        .map(|a| a.join("shared").join("scenes"))
        .find(|p| p.is_dir());
    if found.is_none() {
        eprintln!("SKIPPED: {what}: ../shared/scenes not found (CI has it)");
    }
    found
}
