//! The tracer contract: every technique (brute force, SAH BVH, DACRT, RTRPS, shafts, cones)
//! implements [`Tracer`], and everything above (CLI, renderers, benchmarks, tests) sees only it.
//!
//! Semantics every implementation must meet exactly (the conformance suite checks them against
//! `naive`):
//! - **closest hit**: for each ray, the triangle whose [`intersect_triangle`] hit has the smallest
//!   `t` in `[tmin, tmax]`; ties in `t` go to the smaller primitive id ([`closer`]), so the answer
//!   is unique and every tracer returns the same `t`, `prim`, `u`, `v` bit for bit;
//! - **occlusion**: true when any triangle is hit with `tmin <= t <= tmax`;
//! - tracers work on the scene's world soup as of their last [`Tracer::prepare`]; before any
//!   prepare, every ray misses.
//!
//! [`intersect_triangle`]: crate::geom::intersect_triangle

use crate::error::Result;
use crate::rays::{HitBatch, RayBatch};
use crate::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

/// Work counters and times. Counters are kept in locals by tracers and added once per chunk of
/// rays, never per test.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Rays traced.
    pub rays: u64,
    /// Ray/box tests.
    pub ray_box: u64,
    /// Ray/triangle tests.
    pub ray_tri: u64,
    /// Triangle/box (classification) tests.
    pub tri_box: u64,
    /// Cone (or shaft, frustum) / box tests.
    pub cone_box: u64,
    /// Nodes visited (tree nodes, or divide-and-conquer steps).
    pub nodes: u64,
    /// Leaves visited (or naive leaf steps).
    pub leaves: u64,
    /// Wall time of prepare (build or update), in ms.
    pub prepare_ms: f64,
    /// Wall time of tracing, in ms.
    pub trace_ms: f64,
    /// Peak bytes the tracer itself allocated for the work (acceleration structure or scratch).
    pub peak_bytes: u64,
}

impl std::ops::AddAssign<&Stats> for Stats {
    fn add_assign(&mut self, o: &Stats) {
        self.rays += o.rays;
        self.ray_box += o.ray_box;
        self.ray_tri += o.ray_tri;
        self.tri_box += o.tri_box;
        self.cone_box += o.cone_box;
        self.nodes += o.nodes;
        self.leaves += o.leaves;
        self.prepare_ms += o.prepare_ms;
        self.trace_ms += o.trace_ms;
        self.peak_bytes = self.peak_bytes.max(o.peak_bytes);
    }
}

impl std::ops::Add for Stats {
    type Output = Stats;
    fn add(mut self, o: Stats) -> Stats {
        self += &o;
        self
    }
}

/// A ray/triangle intersection engine.
pub trait Tracer: Send + Sync {
    /// The registry name (`naive`, `bvh`, ...).
    fn name(&self) -> &'static str;

    /// Builds or updates whatever the tracer needs for `scene` (call again after the scene
    /// changes). Returns counters; [`Tracer::prepare_timed`] adds the wall time.
    fn prepare(&mut self, scene: Arc<Scene>) -> Result<Stats>;

    /// Closest hits of all rays; `hits` is resized to `rays.len()`.
    fn intersect(&self, rays: &RayBatch, hits: &mut HitBatch) -> Stats;

    /// Any-hit of all rays; `occluded` is resized to `rays.len()`.
    fn occluded(&self, rays: &RayBatch, occluded: &mut Vec<bool>) -> Stats;

    /// Bytes the tracer holds between calls (its acceleration structure; 0 for none).
    fn bytes(&self) -> usize;

    /// [`Tracer::prepare`], timed.
    fn prepare_timed(&mut self, scene: Arc<Scene>) -> Result<Stats> {
        let t0 = Instant::now();
        let mut s = self.prepare(scene)?;
        s.prepare_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(s)
    }

    /// [`Tracer::intersect`] into a new batch, timed.
    fn intersect_timed(&self, rays: &RayBatch) -> (HitBatch, Stats) {
        let mut hits = HitBatch::new(0);
        let t0 = Instant::now();
        let mut s = self.intersect(rays, &mut hits);
        s.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
        (hits, s)
    }

    /// [`Tracer::occluded`] into a new vector, timed.
    fn occluded_timed(&self, rays: &RayBatch) -> (Vec<bool>, Stats) {
        let mut occ = Vec::new();
        let t0 = Instant::now();
        let mut s = self.occluded(rays, &mut occ);
        s.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
        (occ, s)
    }
}

/// The closest-hit order: smaller `t`, then smaller primitive id.
#[inline(always)]
pub fn closer(t: f32, prim: u32, best_t: f32, best_prim: u32) -> bool {
    t < best_t || (t == best_t && prim < best_prim)
}

/// A mutable window of a [`HitBatch`].
pub struct HitsMut<'a> {
    /// Hit distances.
    pub t: &'a mut [f32],
    /// Triangle ids.
    pub prim: &'a mut [u32],
    /// Barycentric u.
    pub u: &'a mut [f32],
    /// Barycentric v.
    pub v: &'a mut [f32],
}

/// Runs `f` over chunks of `chunk` rays in parallel, each with its window of `hits` (reset to
/// misses first), and sums the returned counters.
pub fn par_ray_chunks<F>(rays: &RayBatch, hits: &mut HitBatch, chunk: usize, f: F) -> Stats
where
    F: Fn(Range<usize>, HitsMut<'_>) -> Stats + Sync,
{
    let n = rays.len();
    hits.reset(n);
    let chunk = chunk.max(1);
    hits.t
        .par_chunks_mut(chunk)
        .zip(hits.prim.par_chunks_mut(chunk))
        .zip(hits.u.par_chunks_mut(chunk))
        .zip(hits.v.par_chunks_mut(chunk))
        .enumerate()
        .map(|(c, (((t, prim), u), v))| {
            let start = c * chunk;
            f(start..start + t.len(), HitsMut { t, prim, u, v })
        })
        .reduce(Stats::default, |a, b| a + b)
}

/// Runs `f` over chunks of `chunk` rays in parallel, each with its window of `occluded` (reset to
/// false first), and sums the returned counters.
pub fn par_occlusion_chunks<F>(
    rays: &RayBatch,
    occluded: &mut Vec<bool>,
    chunk: usize,
    f: F,
) -> Stats
where
    F: Fn(Range<usize>, &mut [bool]) -> Stats + Sync,
{
    occluded.clear();
    occluded.resize(rays.len(), false);
    let chunk = chunk.max(1);
    occluded
        .par_chunks_mut(chunk)
        .enumerate()
        .map(|(c, out)| {
            let start = c * chunk;
            f(start..start + out.len(), out)
        })
        .reduce(Stats::default, |a, b| a + b)
}
