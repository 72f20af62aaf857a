//! Running a call's tasks over disjoint windows of the rays in parallel: chunks of one size
//! ([`par_ray_chunks`], [`par_occlusion_chunks`]) or bands of any sizes ([`par_ray_bands`],
//! [`par_occlusion_bands`]), each window of the outputs reset first, the tasks' results summed.

use super::{CostMut, HitsMut, RayCost};
use crate::rays::{HitBatch, RayBatch, MISS};
use rayon::prelude::*;
use std::ops::Range;

/// Per-chunk windows of a cost record (reset to `n` zeros).
fn cost_windows(c: &mut RayCost, n: usize, chunk: usize) -> Vec<CostMut<'_>> {
    c.reset(n);
    c.nodes
        .chunks_mut(chunk)
        .zip(c.tests.chunks_mut(chunk))
        .zip(c.triangles.chunks_mut(chunk))
        .map(|((nodes, tests), triangles)| CostMut {
            nodes,
            tests,
            triangles,
        })
        .collect()
}

/// A window of a call's outputs, split in two at a ray.
pub trait SplitOut: Send + Sized {
    /// The first `k` rays' window and the rest's.
    fn split_at(self, k: usize) -> (Self, Self);
}

/// A window struct of slices, split field by field at `k`.
macro_rules! split_fields {
    ($ty:ident, $s:expr, $k:expr, $($f:ident),+) => {{
        let s = $s;
        $(let $f = s.$f.split_at_mut($k);)+
        ($ty { $($f: $f.0),+ }, $ty { $($f: $f.1),+ })
    }};
}

impl SplitOut for HitsMut<'_> {
    fn split_at(self, k: usize) -> (Self, Self) {
        split_fields!(HitsMut, self, k, t, prim, u, v)
    }
}

impl SplitOut for &mut [bool] {
    fn split_at(self, k: usize) -> (Self, Self) {
        self.split_at_mut(k)
    }
}

impl SplitOut for CostMut<'_> {
    fn split_at(self, k: usize) -> (Self, Self) {
        split_fields!(CostMut, self, k, nodes, tests, triangles)
    }
}

impl<A: SplitOut, B: SplitOut> SplitOut for (A, Option<B>) {
    fn split_at(self, k: usize) -> (Self, Self) {
        let (a0, a1) = self.0.split_at(k);
        match self.1 {
            Some(b) => {
                let (b0, b1) = b.split_at(k);
                ((a0, Some(b0)), (a1, Some(b1)))
            }
            None => ((a0, None), (a1, None)),
        }
    }
}

/// Runs `f(band, rays, window)` over the bands `bounds[b]..bounds[b + 1]` (increasing, from 0
/// to the batch's length) in parallel, splitting `out` with them (halves by `rayon::join`,
/// nothing allocated), and sums the results.
fn par_bands<O, R, F>(first: usize, bounds: &[usize], out: O, f: &F) -> R
where
    O: SplitOut,
    R: Default + Send + std::ops::Add<Output = R>,
    F: Fn(usize, Range<usize>, O) -> R + Sync,
{
    match bounds.len() {
        0 | 1 => R::default(),
        2 => f(first, bounds[0]..bounds[1], out),
        n => {
            let mid = n / 2;
            let (a, b) = out.split_at(bounds[mid] - bounds[0]);
            let (ra, rb) = rayon::join(
                || par_bands(first, &bounds[..=mid], a, f),
                || par_bands(first + mid, &bounds[mid..], b, f),
            );
            ra + rb
        }
    }
}

/// The whole of a cost record (reset to `n` zeros) as one window.
fn whole_cost(c: &mut RayCost, n: usize) -> CostMut<'_> {
    c.reset(n);
    CostMut {
        nodes: &mut c.nodes,
        tests: &mut c.tests,
        triangles: &mut c.triangles,
    }
}

/// A window of hits reset to misses.
fn reset_window(out: HitsMut<'_>) -> HitsMut<'_> {
    out.t.fill(f32::INFINITY);
    out.prim.fill(MISS);
    out.u.fill(0.0);
    out.v.fill(0.0);
    out
}

/// [`par_ray_chunks`] over bands of any sizes: `f(band, rays, hits, cost)` for the rays
/// `bounds[b]..bounds[b + 1]` (increasing, from 0 to the batch's length), each window of `hits`
/// reset to misses first and of `cost` (when asked) to zeros. Allocates nothing when `hits`
/// and `cost` have the batch's size.
pub fn par_ray_bands<R, F>(
    rays: &RayBatch,
    hits: &mut HitBatch,
    cost: Option<&mut RayCost>,
    bounds: &[usize],
    f: F,
) -> R
where
    R: Default + Send + std::ops::Add<Output = R>,
    F: Fn(usize, Range<usize>, HitsMut<'_>, Option<CostMut<'_>>) -> R + Sync,
{
    let n = rays.len();
    debug_assert!(bounds.first() == Some(&0) && bounds.last() == Some(&n));
    if [hits.t.len(), hits.prim.len(), hits.u.len(), hits.v.len()] != [n; 4] {
        hits.reset(n);
    }
    let out = HitsMut {
        t: &mut hits.t,
        prim: &mut hits.prim,
        u: &mut hits.u,
        v: &mut hits.v,
    };
    let cost = cost.map(|c| whole_cost(c, n));
    par_bands(0, bounds, (out, cost), &|b, range, (out, cost)| {
        f(b, range, reset_window(out), cost)
    })
}

/// [`par_occlusion_chunks`] over bands of any sizes (see [`par_ray_bands`]).
pub fn par_occlusion_bands<R, F>(
    rays: &RayBatch,
    occluded: &mut Vec<bool>,
    cost: Option<&mut RayCost>,
    bounds: &[usize],
    f: F,
) -> R
where
    R: Default + Send + std::ops::Add<Output = R>,
    F: Fn(usize, Range<usize>, &mut [bool], Option<CostMut<'_>>) -> R + Sync,
{
    let n = rays.len();
    debug_assert!(bounds.first() == Some(&0) && bounds.last() == Some(&n));
    occluded.clear();
    occluded.resize(n, false);
    let cost = cost.map(|c| whole_cost(c, n));
    par_bands(
        0,
        bounds,
        (&mut occluded[..], cost),
        &|b, range, (out, cost)| f(b, range, out, cost),
    )
}

/// Runs `f` over chunks of `chunk` rays in parallel, each with its window of `hits` (reset to
/// misses first) and of `cost` (reset to zeros, when asked), and sums the returned results.
/// Allocates nothing when no cost is asked.
pub fn par_ray_chunks<R, F>(
    rays: &RayBatch,
    hits: &mut HitBatch,
    cost: Option<&mut RayCost>,
    chunk: usize,
    f: F,
) -> R
where
    R: Default + Send + std::ops::Add<Output = R>,
    F: Fn(Range<usize>, HitsMut<'_>, Option<CostMut<'_>>) -> R + Sync,
{
    let n = rays.len();
    // Each chunk resets its own window (in parallel: a serial reset of a million hits was a
    // few ms of every camera call); a batch of another size is reset here first.
    if [hits.t.len(), hits.prim.len(), hits.u.len(), hits.v.len()] != [n; 4] {
        hits.reset(n);
    }
    let chunk = chunk.max(1);
    let windows = hits
        .t
        .par_chunks_mut(chunk)
        .zip(hits.prim.par_chunks_mut(chunk))
        .zip(hits.u.par_chunks_mut(chunk))
        .zip(hits.v.par_chunks_mut(chunk))
        .enumerate();
    fn window(c: usize, chunk: usize, out: HitsMut<'_>) -> (Range<usize>, HitsMut<'_>) {
        (c * chunk..c * chunk + out.t.len(), reset_window(out))
    }
    match cost {
        None => windows
            .map(|(c, (((t, prim), u), v))| {
                let (range, out) = window(c, chunk, HitsMut { t, prim, u, v });
                f(range, out, None)
            })
            .reduce(R::default, |a, b| a + b),
        Some(cost) => windows
            .zip(cost_windows(cost, n, chunk))
            .map(|((c, (((t, prim), u), v)), cost)| {
                let (range, out) = window(c, chunk, HitsMut { t, prim, u, v });
                f(range, out, Some(cost))
            })
            .reduce(R::default, |a, b| a + b),
    }
}

/// Runs `f` over chunks of `chunk` rays in parallel, each with its window of `occluded` (reset to
/// false first) and of `cost` (when asked), and sums the returned results. Allocates nothing
/// when no cost is asked.
pub fn par_occlusion_chunks<R, F>(
    rays: &RayBatch,
    occluded: &mut Vec<bool>,
    cost: Option<&mut RayCost>,
    chunk: usize,
    f: F,
) -> R
where
    R: Default + Send + std::ops::Add<Output = R>,
    F: Fn(Range<usize>, &mut [bool], Option<CostMut<'_>>) -> R + Sync,
{
    let n = rays.len();
    occluded.clear();
    occluded.resize(n, false);
    let chunk = chunk.max(1);
    let windows = occluded.par_chunks_mut(chunk).enumerate();
    match cost {
        None => windows
            .map(|(c, out)| f(c * chunk..c * chunk + out.len(), out, None))
            .reduce(R::default, |a, b| a + b),
        Some(cost) => windows
            .zip(cost_windows(cost, n, chunk))
            .map(|((c, out), cost)| f(c * chunk..c * chunk + out.len(), out, Some(cost)))
            .reduce(R::default, |a, b| a + b),
    }
}
