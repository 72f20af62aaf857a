//! Single-ray stack traversal of a [`KdTree`] (pbrt-v3's `KdTreeAccel::Intersect`, with the
//! exact split window of [`KdTree::split_window`]; the proof is in `accel/kdtree`'s module doc).
//!
//! A node's interval `[tn, tf]` is split at the widened plane distance: the near child gets
//! `[tn, min(tf, hi)]`, the far one `[max(tn, lo), tf]`; each non-empty one is visited, the far
//! one deferred on a stack of 12-byte entries and dropped when popped with an entry beyond the
//! closest hit so far. Leaves test every triangle against the ray's whole `[tmin, best_t]`.

use crate::accel::kdtree::{KdTree, MAX_DEPTH};
use crate::geom::{intersect_triangle, SlabRay};
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::{closer, CostMut, HitsMut};
use std::ops::Range;

crate::counters! {
    /// What a `kdtree` trace counts.
    pub struct Counters {
        /// Ray/box slab tests (one per ray, against the root's box).
        ray_box,
        /// Interior nodes visited (one split-plane distance each).
        nodes,
        /// Leaves visited.
        leaves,
        /// Ray/triangle tests (a triangle in several leaves may be tested once per leaf).
        ray_tri,
        /// Deferred far children dropped because their entry lay beyond the closest hit.
        culled,
    }
}

/// A deferred subtree: its node and interval (12 bytes, the cone walk's entry too).
#[derive(Clone, Copy, Default)]
pub struct StackEntry {
    /// Node index.
    pub node: u32,
    /// Entry distance.
    pub tn: f32,
    /// Exit distance.
    pub tf: f32,
}

/// The closest hit so far: `(t, prim, u, v)`, `prim == MISS` for none.
pub type Best = (f32, u32, f32, f32);

/// Walks ray `i`, testing leaves' triangles against `[tmin, best.0]`; with `ANY`, stops at the
/// first hit. Returns the closest (or first) hit.
#[inline(always)]
pub fn walk<const ANY: bool>(
    tree: &KdTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    i: usize,
    stack: &mut [StackEntry; MAX_DEPTH],
    c: &mut Counters,
) -> Best {
    let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
    let mut best: Best = (rays.tmax[i], MISS, 0.0, 0.0);
    let ray = SlabRay::new(o, d);
    c.ray_box += 1;
    let Some((mut tn, mut tf)) = ray.interval(tree.bounds.min, tree.bounds.max, tmin, best.0)
    else {
        return best;
    };
    let (nodes, (v0, v1, v2)) = (&tree.nodes[..], (&soup.v0, &soup.v1, &soup.v2));
    let mut node = 0usize;
    let mut sp = 0usize;
    'walk: loop {
        let n = nodes[node];
        if n.is_leaf() {
            c.leaves += 1;
            let ids = tree.leaf_ids(n);
            c.ray_tri += ids.len() as u64;
            for &p in ids {
                let k = p as usize;
                if let Some(h) = intersect_triangle(o, d, v0[k], v1[k], v2[k], tmin, best.0) {
                    if closer(h.t, p, best.0, best.1) {
                        best = (h.t, p, h.u, h.v);
                        if ANY {
                            return best;
                        }
                    }
                }
            }
        } else {
            c.nodes += 1;
            let a = n.axis();
            let ts = (n.split() - o[a]) * ray.inv_dir[a];
            let (lo, hi) = KdTree::split_window(ts);
            let below = node + 1;
            let above = n.above() as usize;
            let (near, far) = if ray.neg[a] {
                (above, below)
            } else {
                (below, above)
            };
            let near_exit = if hi < tf { hi } else { tf };
            let far_entry = if lo > tn { lo } else { tn };
            let go_near = tn <= near_exit;
            let go_far = far_entry <= tf && far_entry <= best.0;
            match (go_near, go_far) {
                (true, true) => {
                    stack[sp] = StackEntry {
                        node: far as u32,
                        tn: far_entry,
                        tf,
                    };
                    sp += 1;
                    (node, tf) = (near, near_exit);
                    continue 'walk;
                }
                (true, false) => {
                    (node, tf) = (near, near_exit);
                    continue 'walk;
                }
                (false, true) => {
                    (node, tn) = (far, far_entry);
                    continue 'walk;
                }
                (false, false) => {}
            }
        }
        // Pop the next subtree still worth entering (inclusive: ties need the visit).
        while sp > 0 {
            sp -= 1;
            let e = stack[sp];
            if e.tn <= best.0 {
                (node, tn, tf) = (e.node as usize, e.tn, e.tf);
                continue 'walk;
            }
            c.culled += 1;
        }
        return best;
    }
}

/// Charges one ray's share of the counters (`after - before`) to its cost record.
#[inline]
pub(super) fn charge(
    cost: &mut Option<CostMut<'_>>,
    k: usize,
    before: &Counters,
    after: &Counters,
) {
    if let Some(cost) = cost {
        let tri = after.ray_tri - before.ray_tri;
        let nodes = (after.nodes - before.nodes) + (after.leaves - before.leaves);
        let tests = (after.ray_box - before.ray_box) + (after.nodes - before.nodes) + tri;
        cost.add(k, nodes, tests, tri);
    }
}

/// Closest hits of rays `range` into `out` (all-miss on entry).
pub(super) fn closest_chunk(
    tree: &KdTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    range: Range<usize>,
    out: HitsMut<'_>,
    mut cost: Option<CostMut<'_>>,
) -> Counters {
    let mut c = Counters::default();
    let mut stack = [StackEntry::default(); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let before = c;
        let (t, p, u, v) = walk::<false>(tree, soup, rays, i, &mut stack, &mut c);
        if p != MISS {
            (out.t[k], out.prim[k], out.u[k], out.v[k]) = (t, p, u, v);
        }
        charge(&mut cost, k, &before, &c);
    }
    c
}

/// Any-hit of rays `range` into `out` (all-false on entry).
pub(super) fn occluded_chunk(
    tree: &KdTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    range: Range<usize>,
    out: &mut [bool],
    mut cost: Option<CostMut<'_>>,
) -> Counters {
    let mut c = Counters::default();
    let mut stack = [StackEntry::default(); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let before = c;
        out[k] = walk::<true>(tree, soup, rays, i, &mut stack, &mut c).1 != MISS;
        charge(&mut cost, k, &before, &c);
    }
    c
}
