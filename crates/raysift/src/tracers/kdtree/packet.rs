//! 4-ray packets through a [`KdTree`] (Wald, Slusallek, Benthin & Wagner 2001, "Interactive
//! rendering with coherent ray tracing": the relevant-triangle shafts paper's SIMD baseline).
//!
//! Four rays whose directions have the same sign on every axis (the sign bit, as the single-ray
//! walk's `neg`) walk the tree together: at an interior node every ray computes its widened
//! split window and its near and far intervals exactly as the single-ray walk does
//! (`traverse.rs`); the packet enters the near child if any ray's near interval is not empty and
//! defers the far child if any ray's far interval is not empty; a ray whose interval in a child is
//! empty rides along inactive there (its interval is stored empty). All rays share one near/far
//! order (same signs), so each ray meets every node of its own single-ray walk with the same
//! interval, and tests every leaf triangle it would against its `[tmin, best_t]`: the answers
//! are the single-ray walk's, bit for bit. Packets with mixed signs are walked ray by ray.
//!
//! The lanes are `[f32; 4]` arrays processed in loops of four, which the compiler turns into SSE
//! for the split distances and windows; the triangle test is the shared scalar one per active ray.

use super::traverse::{walk, Best, Counters, StackEntry};
use crate::accel::kdtree::{KdTree, MAX_DEPTH};
use crate::geom::{intersect_triangle, SlabRay};
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::closer;

/// A deferred subtree of a packet: its node and the four rays' intervals (empty: `tn > tf`).
#[derive(Clone, Copy)]
pub struct Entry4 {
    node: u32,
    tn: [f32; 4],
    tf: [f32; 4],
}

impl Default for Entry4 {
    fn default() -> Self {
        Self {
            node: 0,
            tn: [f32::INFINITY; 4],
            tf: [f32::NEG_INFINITY; 4],
        }
    }
}

/// Stacks of both walks (one per parallel task).
pub struct Stacks {
    /// The packet walk's.
    pub packet: [Entry4; MAX_DEPTH],
    /// The single-ray walk's (mixed-sign packets).
    pub single: [StackEntry; MAX_DEPTH],
}

impl Default for Stacks {
    fn default() -> Self {
        Self {
            packet: [Entry4::default(); MAX_DEPTH],
            single: [StackEntry::default(); MAX_DEPTH],
        }
    }
}

/// Walks rays `ids` (1 to 4; a short packet repeats its last ray, answered once) and returns
/// their closest (or, with `ANY`, first) hits, in `ids` order.
pub fn walk4<const ANY: bool>(
    tree: &KdTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    ids: &[usize],
    st: &mut Stacks,
    c: &mut Counters,
) -> [Best; 4] {
    let mut best: [Best; 4] = [(f32::INFINITY, MISS, 0.0, 0.0); 4];
    let n = ids.len().min(4);
    let lane = |k: usize| ids[k.min(n - 1)];
    let slab: [SlabRay; 4] =
        std::array::from_fn(|k| SlabRay::new(rays.origin(lane(k)), rays.dir(lane(k))));
    if slab.iter().any(|s| s.neg != slab[0].neg) {
        for (k, b) in best.iter_mut().enumerate().take(n) {
            *b = walk::<ANY>(tree, soup, rays, ids[k], &mut st.single, c);
        }
        return best;
    }
    let neg = slab[0].neg;
    // Origins and reciprocal directions by axis, lanes contiguous.
    let org: [[f32; 4]; 3] = std::array::from_fn(|a| std::array::from_fn(|k| slab[k].origin[a]));
    let inv: [[f32; 4]; 3] = std::array::from_fn(|a| std::array::from_fn(|k| slab[k].inv_dir[a]));
    let tmin: [f32; 4] = std::array::from_fn(|k| rays.tmin[lane(k)]);
    let mut bt: [f32; 4] = std::array::from_fn(|k| rays.tmax[lane(k)]);
    for k in 0..4 {
        best[k].0 = bt[k];
    }
    let (mut tn, mut tf) = ([f32::INFINITY; 4], [f32::NEG_INFINITY; 4]);
    for k in 0..n {
        c.ray_box += 1;
        if let Some((a, b)) = slab[k].interval(tree.bounds.min, tree.bounds.max, tmin[k], bt[k]) {
            (tn[k], tf[k]) = (a, b);
        }
    }
    // Lanes past `n` stay empty: never active.
    let (nodes, (v0, v1, v2)) = (&tree.nodes[..], (&soup.v0, &soup.v1, &soup.v2));
    let mut done = [false; 4];
    let active = |tn: &[f32; 4], tf: &[f32; 4], bt: &[f32; 4], done: &[bool; 4]| -> u32 {
        let mut m = 0;
        for k in 0..4 {
            m |= ((tn[k] <= tf[k] && tn[k] <= bt[k] && !done[k]) as u32) << k;
        }
        m
    };
    let mut mask = active(&tn, &tf, &bt, &done);
    let mut node = 0usize;
    let mut sp = 0usize;
    'walk: loop {
        if mask != 0 {
            let nd = nodes[node];
            if nd.is_leaf() {
                c.leaves += 1;
                let ids_leaf = tree.leaf_ids(nd);
                for &p in ids_leaf {
                    let t = p as usize;
                    for k in 0..4 {
                        if mask >> k & 1 == 0 {
                            continue;
                        }
                        c.ray_tri += 1;
                        let (o, d) = (slab[k].origin, rays.dir(lane(k)));
                        if let Some(h) =
                            intersect_triangle(o, d, v0[t], v1[t], v2[t], tmin[k], bt[k])
                        {
                            if closer(h.t, p, best[k].0, best[k].1) {
                                best[k] = (h.t, p, h.u, h.v);
                                bt[k] = h.t;
                                if ANY {
                                    done[k] = true;
                                    mask &= !(1 << k);
                                }
                            }
                        }
                    }
                }
            } else {
                c.nodes += 1;
                let a = nd.axis();
                let split = nd.split();
                let below = node + 1;
                let above = nd.above() as usize;
                let (near, far) = if neg[a] {
                    (above, below)
                } else {
                    (below, above)
                };
                // Branch-free over the four lanes (SSE): inactive lanes compute too, and are
                // masked out after.
                let (mut n_tf, mut f_tn) = ([0.0f32; 4], [0.0f32; 4]);
                let (mut go_near, mut go_far) = (0u32, 0u32);
                for k in 0..4 {
                    let ts = (split - org[a][k]) * inv[a][k];
                    let (lo, hi) = KdTree::split_window(ts);
                    n_tf[k] = if hi < tf[k] { hi } else { tf[k] };
                    f_tn[k] = if lo > tn[k] { lo } else { tn[k] };
                    go_near |= ((tn[k] <= n_tf[k]) as u32) << k;
                    go_far |= ((f_tn[k] <= tf[k] && f_tn[k] <= bt[k]) as u32) << k;
                }
                let (go_near, go_far) = (go_near & mask, go_far & mask);
                // Lanes not going a way get an empty interval there.
                let (mut n_tn, mut f_tf) = (tn, tf);
                for k in 0..4 {
                    if go_near >> k & 1 == 0 {
                        (n_tn[k], n_tf[k]) = (f32::INFINITY, f32::NEG_INFINITY);
                    }
                    if go_far >> k & 1 == 0 {
                        (f_tn[k], f_tf[k]) = (f32::INFINITY, f32::NEG_INFINITY);
                    }
                }
                if go_near != 0 {
                    if go_far != 0 {
                        st.packet[sp] = Entry4 {
                            node: far as u32,
                            tn: f_tn,
                            tf: f_tf,
                        };
                        sp += 1;
                    }
                    (node, tn, tf, mask) = (near, n_tn, n_tf, go_near);
                    continue 'walk;
                }
                if go_far != 0 {
                    (node, tn, tf, mask) = (far, f_tn, f_tf, go_far);
                    continue 'walk;
                }
            }
        }
        // Pop the next subtree some ray still needs (inclusive: ties need the visit).
        while sp > 0 {
            sp -= 1;
            let e = st.packet[sp];
            let m = active(&e.tn, &e.tf, &bt, &done);
            if m != 0 {
                (node, tn, tf, mask) = (e.node as usize, e.tn, e.tf, m);
                continue 'walk;
            }
            c.culled += 1;
        }
        return best;
    }
}

/// How a batch is cut into packets.
#[derive(Clone, Copy, Debug)]
pub enum Plan {
    /// A pinhole image `width` pixels wide: 2×2 pixel packets, tasks of two rows.
    Image { width: usize },
    /// Four consecutive rays.
    Runs,
}

/// Rays per task for runs of four.
const RUN_CHUNK: usize = 256;

/// The plan for `rays` (its layout hint, checked against its length).
pub fn plan(rays: &RayBatch) -> Plan {
    match rays.layout {
        crate::rays::RayLayout::Pinhole { width, height, .. }
            if width as usize * height as usize == rays.len() && width > 0 =>
        {
            Plan::Image {
                width: width as usize,
            }
        }
        _ => Plan::Runs,
    }
}

impl Plan {
    /// Rays per parallel task.
    pub fn chunk(self) -> usize {
        match self {
            Plan::Image { width } => 2 * width,
            Plan::Runs => RUN_CHUNK,
        }
    }
}

/// Walks rays `range` in packets as `plan` says, calling `emit(i, hit)` for every ray;
/// `cost`'s window starts at `range.start`, and every ray of a packet is charged the packet's
/// work (a shared test counts for each ray).
pub fn chunk<const ANY: bool>(
    tree: &KdTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    plan: Plan,
    range: std::ops::Range<usize>,
    mut cost: Option<crate::tracer::CostMut<'_>>,
    emit: &mut impl FnMut(usize, Best),
) -> Counters {
    let mut c = Counters::default();
    let mut st = Stacks::default();
    let start = range.start;
    let mut run = |ids: &[usize], c: &mut Counters| {
        let before = *c;
        let hits = walk4::<ANY>(tree, soup, rays, ids, &mut st, c);
        for (k, &i) in ids.iter().enumerate() {
            super::traverse::charge(&mut cost, i - start, &before, c);
            emit(i, hits[k]);
        }
    };
    match plan {
        Plan::Image { width } => {
            let rows = range.len() / width;
            for i in (0..width).step_by(2) {
                let mut ids = [0usize; 4];
                let mut n = 0;
                for j in 0..rows.min(2) {
                    for di in 0..2.min(width - i) {
                        ids[n] = start + j * width + i + di;
                        n += 1;
                    }
                }
                run(&ids[..n], &mut c);
            }
        }
        Plan::Runs => {
            for first in range.clone().step_by(4) {
                let ids: [usize; 4] = std::array::from_fn(|k| first + k);
                run(&ids[..(range.end - first).min(4)], &mut c);
            }
        }
    }
    c
}
