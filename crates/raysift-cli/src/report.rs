//! The `--json` reports, one typed struct per command (serde), so a report's keys are written
//! down once and checked by the compiler.
//!
//! Times appear once: a report's top-level `prepare_ms`/`trace_ms` are its times (for `trace
//! --repeat K`, the medians over the K runs, each run listed in `prepare_ms_runs`/`trace_ms_runs`);
//! the counters under `stats` (and `prepare`, `passes`, `per_bounce`) carry no times of their own
//! except a pass's own `trace_ms`.

use raysift::tracer::Counters;
use raysift::Stats;
use serde::Serialize;

/// Prints a report as one line of JSON on stdout.
pub fn print_json(report: &impl Serialize) -> anyhow::Result<()> {
    println!("{}", serde_json::to_string(report)?);
    Ok(())
}

/// The median (of a non-empty list).
pub fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Rays per microsecond (= Mrays/s).
pub fn mrays_per_s(rays: u64, ms: f64) -> f64 {
    rays as f64 / (ms * 1e3).max(1e-9)
}

/// A tracer's counters from a prepare and/or a trace, without times: rays, peak bytes, what the
/// prepare built and what the trace did (each map left out when empty).
#[derive(Serialize)]
pub struct Counts {
    /// Rays traced.
    pub rays: u64,
    /// Peak bytes the tracer allocated for the work.
    pub peak_bytes: u64,
    /// What the prepare built (`Stats::built`).
    #[serde(skip_serializing_if = "Counters::is_empty")]
    pub built: Counters,
    /// What the trace did (`Stats::work`).
    #[serde(skip_serializing_if = "Counters::is_empty")]
    pub work: Counters,
}

impl Counts {
    /// The counters of one call.
    pub fn of(s: &Stats) -> Self {
        Self::of_frame(&Stats::default(), s)
    }

    /// The counters of a prepare followed by a trace.
    pub fn of_frame(prepare: &Stats, trace: &Stats) -> Self {
        Self {
            rays: trace.rays,
            peak_bytes: prepare.peak_bytes.max(trace.peak_bytes),
            built: prepare.built,
            work: trace.work,
        }
    }
}

/// `trace --json`. bench/ reads `prepare_ms`, `trace_ms`, `*_runs`, `hits`, `stats.work`.
#[derive(Serialize)]
pub struct TraceReport {
    pub scene: String,
    pub triangles: usize,
    pub tracer: &'static str,
    pub rays: usize,
    pub threads: usize,
    pub occlusion: bool,
    /// hits.npy has the `ng` field.
    pub normals: bool,
    /// Median over the runs.
    pub prepare_ms: f64,
    /// Median over the runs.
    pub trace_ms: f64,
    /// From the median trace time.
    pub mrays_per_s: f64,
    /// Hits (or occluded rays).
    pub hits: usize,
    pub tracer_bytes: usize,
    pub bytes_per_triangle: f64,
    /// Every run's prepare time, in order.
    pub prepare_ms_runs: Vec<f64>,
    /// Every run's trace time, in order.
    pub trace_ms_runs: Vec<f64>,
    /// The last run's counters.
    pub stats: Counts,
    /// The file written, if any.
    pub out: Option<String>,
}

/// One pass of `render --json` (raycast): `primary`, then `shadow` with diffuse shading.
#[derive(Serialize)]
pub struct PassReport {
    pub pass: &'static str,
    pub rays: u64,
    pub trace_ms: f64,
    pub mrays_per_s: f64,
    pub stats: Counts,
}

impl PassReport {
    pub fn of(pass: &'static str, s: &Stats) -> Self {
        Self {
            pass,
            rays: s.rays,
            trace_ms: s.trace_ms,
            mrays_per_s: mrays_per_s(s.rays, s.trace_ms),
            stats: Counts::of(s),
        }
    }
}

/// `render --json` (ray casting).
#[derive(Serialize)]
pub struct RenderReport {
    pub scene: String,
    pub triangles: usize,
    pub tracer: &'static str,
    pub integrator: &'static str,
    pub shade: &'static str,
    pub width: u32,
    pub height: u32,
    pub threads: usize,
    /// Rays of every pass.
    pub rays: u64,
    /// Primary rays that hit.
    pub hits: u64,
    pub prepare_ms: f64,
    /// The sum of the passes' trace times.
    pub trace_ms: f64,
    /// Prepare, trace, shading and writing.
    pub frame_ms: f64,
    pub mrays_per_s: f64,
    pub tracer_bytes: usize,
    /// What the prepare built.
    pub prepare: Counts,
    pub passes: Vec<PassReport>,
    pub out: String,
}

/// One bounce depth of `render --integrator path --json` (0 = camera rays).
#[derive(Serialize)]
pub struct BounceReport {
    pub depth: u32,
    pub rays: u64,
    pub hits: u64,
    pub trace_ms: f64,
    pub mrays_per_s: f64,
    pub stats: Counts,
}

/// `render --integrator path --json`. bench/dynamic.py reads `prepare_ms`, `trace_ms` and
/// `per_bounce` (`depth`, `rays`, `mrays_per_s`, `stats.work`).
#[derive(Serialize)]
pub struct PathReport {
    pub scene: String,
    pub triangles: usize,
    pub tracer: &'static str,
    pub integrator: &'static str,
    pub spp: u32,
    pub bounces: u32,
    pub width: u32,
    pub height: u32,
    pub threads: usize,
    pub rays: u64,
    pub prepare_ms: f64,
    /// The sum over the bounces.
    pub trace_ms: f64,
    pub frame_ms: f64,
    pub mrays_per_s: f64,
    pub tracer_bytes: usize,
    pub prepare: Counts,
    pub per_bounce: Vec<BounceReport>,
    pub out: String,
}

/// One frame of `animate --json`.
#[derive(Serialize)]
pub struct FrameReport {
    pub frame: u32,
    /// Animation time: 0 to 1 (explode, spin-parts), seconds (gltf).
    pub time: f32,
    /// What changed since the previous frame (what the tracer's prepare was told):
    /// `all` (the first frame: never prepared), `none`, or `meshes` (see `moved`, `deformed`).
    pub change: &'static str,
    /// Meshes that moved rigidly (a new transform, same positions).
    pub moved: usize,
    /// Meshes whose positions changed (deformed; they may also have moved).
    pub deformed: usize,
    pub update_ms: f64,
    pub prepare_ms: f64,
    /// Camera (and shadow) rays.
    pub trace_ms: f64,
    /// prepare_ms + trace_ms.
    pub frame_ms: f64,
    pub hits: u64,
    pub tracer_bytes: usize,
    /// What the prepare built.
    pub built: Counters,
}

/// `animate --json`. bench/dynamic.py reads `mean_prepare_ms`, `mean_trace_ms`, `mean_frame_ms`.
#[derive(Serialize)]
pub struct AnimateReport {
    pub scene: String,
    pub triangles: usize,
    pub tracer: &'static str,
    pub motion: &'static str,
    /// The glTF animation played (motion `gltf`), and its length in seconds.
    pub animation: Option<String>,
    pub duration_s: Option<f32>,
    /// Meshes of the animated scene (spin-parts splits a single mesh into octant parts).
    pub meshes: usize,
    pub width: u32,
    pub height: u32,
    pub threads: usize,
    pub mean_update_ms: f64,
    pub mean_prepare_ms: f64,
    pub mean_trace_ms: f64,
    pub mean_frame_ms: f64,
    pub frames: Vec<FrameReport>,
}

/// `[x, y, z]` corners of a box.
#[derive(Serialize)]
pub struct Bounds {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

impl From<raysift::geom::Aabb> for Bounds {
    fn from(b: raysift::geom::Aabb) -> Self {
        Self {
            min: b.min.to_array(),
            max: b.max.to_array(),
        }
    }
}

/// One mesh of a scene: its primitive ids are `prims.start..prims.end` (the `geom` of those
/// primitives' hits is the mesh's index in the list).
#[derive(Serialize)]
pub struct MeshInfo {
    pub name: String,
    /// Primitive-id range, end exclusive: `{"start": s, "end": e}`.
    pub prims: std::ops::Range<usize>,
    pub triangles: usize,
    pub vertices: usize,
    /// World-space bounds.
    pub bounds: Bounds,
}

/// Every mesh of a scene, in geometry-id order.
pub fn meshes_of(s: &raysift::Scene) -> Vec<MeshInfo> {
    s.meshes()
        .iter()
        .enumerate()
        .map(|(m, mesh)| {
            let prims = s.mesh_prims(m);
            MeshInfo {
                name: mesh.name.clone(),
                triangles: prims.len(),
                prims,
                vertices: mesh.positions.len(),
                bounds: s.mesh_bounds(m).into(),
            }
        })
        .collect()
}

/// `info --json`.
#[derive(Serialize)]
pub struct InfoReport {
    pub scene: String,
    pub triangles: usize,
    pub vertices: usize,
    pub degenerate_triangles: usize,
    /// Each mesh, in geometry-id order (its length is the mesh count).
    pub meshes: Vec<MeshInfo>,
    pub bounds: Bounds,
    pub bytes: usize,
    pub bytes_per_triangle: f64,
}

/// `export --meshes FILE`: the scene's meshes and their primitive ranges.
#[derive(Serialize)]
pub struct MeshesReport {
    pub scene: String,
    pub triangles: usize,
    pub meshes: Vec<MeshInfo>,
}

/// A counter's name and meaning.
#[derive(Serialize)]
pub struct CounterDoc {
    pub name: &'static str,
    pub doc: &'static str,
}

/// A tracer's counters: what a prepare builds, what a trace does.
#[derive(Serialize)]
pub struct CountersDoc {
    pub built: Vec<CounterDoc>,
    pub work: Vec<CounterDoc>,
}

/// A configuration the conformance suite checks.
#[derive(Serialize)]
pub struct PresetReport {
    pub name: &'static str,
    /// `key: value` (the values as `--opt` takes them).
    pub opts: std::collections::BTreeMap<&'static str, &'static str>,
}

/// One entry of `raysift tracers --json` (a list of these, in registry order).
#[derive(Serialize)]
pub struct TracerReport {
    pub name: &'static str,
    pub paper: &'static str,
    pub summary: &'static str,
    /// `{key, default, doc}`, in the Config's order.
    pub options: Vec<raysift::tracers::OptionInfo>,
    pub presets: Vec<PresetReport>,
    pub counters: CountersDoc,
}

/// `render --heatmap KIND --json`.
#[derive(Serialize)]
pub struct HeatmapReport {
    pub scene: String,
    pub triangles: usize,
    pub tracer: &'static str,
    /// What was drawn: nodes, tests or triangles (per ray).
    pub heatmap: &'static str,
    /// The view (the camera rays).
    pub width: u32,
    pub height: u32,
    /// The image written: the view plus the colour bar to its right.
    pub image_width: u32,
    pub image_height: u32,
    pub threads: usize,
    pub rays: u64,
    pub hits: u64,
    /// The drawn count's smallest, largest and mean value per ray.
    pub scale: raysift::render::heatmap::HeatScale,
    pub prepare_ms: f64,
    /// The camera rays traced with a per-ray cost record.
    pub trace_ms: f64,
    pub mrays_per_s: f64,
    pub tracer_bytes: usize,
    /// The prepare's and the trace's counters.
    pub stats: Counts,
    pub out: String,
}
