//! Closest-hit and any-hit traversal of a [`Bvh`], one ray at a time over a chunk of rays.
//!
//! At an interior node both children's boxes are tested against `[tmin, best_t]` with one
//! 4-wide slab test ([`SlabRay::entry2`], bit for bit the scalar [`SlabRay::entry`] on each); the
//! nearer hit child (by entry distance) is visited next and the farther one pushed with its
//! entry, and a popped entry beyond the (since shrunk) `best_t` is dropped. The walk is
//! instantiated once per ray octant (the const parameters), so the near/far plane choice costs
//! nothing per node. Counters live in locals and are returned once per chunk.

use super::{Bvh, NodePair, MAX_DEPTH};
use crate::geom::{intersect_triangle, SlabRay};
use crate::rays::{RayBatch, MISS};
use crate::tracer::{closer, HitsMut, Stats};
use glam::Vec3;
use std::ops::Range;

/// Work counters of one chunk, flushed into [`Stats`] at its end.
#[derive(Default)]
struct Counters {
    ray_box: u64,
    ray_tri: u64,
    nodes: u64,
    leaves: u64,
}

impl Counters {
    fn stats(&self, rays: usize) -> Stats {
        Stats {
            rays: rays as u64,
            ray_box: self.ray_box,
            ray_tri: self.ray_tri,
            nodes: self.nodes,
            leaves: self.leaves,
            ..Stats::default()
        }
    }
}

/// A node to visit: its offset and count (as in [`NodePair`]) and its entry distance.
#[derive(Clone, Copy, Default)]
struct Entry {
    offset: u32,
    count: u32,
    t: f32,
}

/// One ray's query.
struct Query {
    o: Vec3,
    d: Vec3,
    ray: SlabRay,
    tmin: f32,
    tmax: f32,
}

/// Calls `$f::<NX, NY, NZ>($args)` for the octant of `$neg`.
macro_rules! by_octant {
    ($neg:expr, $f:ident($($a:expr),*)) => {
        match $neg {
            [false, false, false] => $f::<false, false, false>($($a),*),
            [false, false, true] => $f::<false, false, true>($($a),*),
            [false, true, false] => $f::<false, true, false>($($a),*),
            [false, true, true] => $f::<false, true, true>($($a),*),
            [true, false, false] => $f::<true, false, false>($($a),*),
            [true, false, true] => $f::<true, false, true>($($a),*),
            [true, true, false] => $f::<true, true, false>($($a),*),
            [true, true, true] => $f::<true, true, true>($($a),*),
        }
    };
}

/// Closest hits of rays `range`, written to `out` (which starts all-miss).
pub(super) fn closest_chunk(
    bvh: &Bvh,
    rays: &RayBatch,
    range: Range<usize>,
    out: HitsMut<'_>,
) -> Stats {
    let mut c = Counters::default();
    let nrays = range.len();
    let Some(root) = bvh.root() else {
        return c.stats(nrays);
    };
    let mut stack = [Entry::default(); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
        let q = Query {
            o,
            d,
            ray: SlabRay::new(o, d),
            tmin,
            tmax: rays.tmax[i],
        };
        c.ray_box += 1;
        let Some(t) = q.ray.entry(root.min, root.max, tmin, q.tmax) else {
            continue;
        };
        let start = Entry {
            offset: root.offset,
            count: root.count as u32,
            t,
        };
        let (best_t, best_p, bu, bv) =
            by_octant!(q.ray.neg, closest_ray(bvh, &q, start, &mut stack, &mut c));
        if best_p != MISS {
            (out.t[k], out.prim[k], out.u[k], out.v[k]) = (best_t, best_p, bu, bv);
        }
    }
    c.stats(nrays)
}

/// Closest hit of one ray whose root box is entered: `(t, prim, u, v)`, `prim == MISS` when none.
#[inline(always)]
fn closest_ray<const NX: bool, const NY: bool, const NZ: bool>(
    bvh: &Bvh,
    q: &Query,
    start: Entry,
    stack: &mut [Entry; MAX_DEPTH],
    c: &mut Counters,
) -> (f32, u32, f32, f32) {
    let pairs: &[NodePair] = &bvh.pairs;
    let (o, d, tmin) = (q.o, q.d, q.tmin);
    let (mut best_t, mut best_p, mut bu, mut bv) = (q.tmax, MISS, 0.0, 0.0);
    let mut n = start;
    let mut sp = 0usize;
    'walk: loop {
        if n.count != 0 {
            c.leaves += 1;
            let first = n.offset as usize;
            let end = first + n.count as usize;
            c.ray_tri += n.count as u64;
            for (p, tri) in (first..end).zip(&bvh.tris[first..end]) {
                if let Some(h) = intersect_triangle(o, d, tri[0], tri[1], tri[2], tmin, best_t) {
                    // The id is read only on a hit: it lives in another cache line.
                    let id = bvh.ids[p];
                    if closer(h.t, id, best_t, best_p) {
                        (best_t, best_p, bu, bv) = (h.t, id, h.u, h.v);
                    }
                }
            }
        } else {
            c.nodes += 1;
            c.ray_box += 2;
            let pair = &pairs[n.offset as usize];
            let (mask, e) = q.ray.entry2::<NX, NY, NZ>(&pair.boxes, tmin, best_t);
            if mask != 0 {
                // One child entered: it is the near one; both: the nearer (ties to the left).
                let near = if mask == 3 {
                    (e[1] < e[0]) as usize
                } else {
                    (mask >> 1) as usize
                };
                if mask == 3 {
                    let far = near ^ 1;
                    stack[sp] = Entry {
                        offset: pair.offset[far],
                        count: pair.count[far] as u32,
                        t: e[far],
                    };
                    sp += 1;
                }
                n = Entry {
                    offset: pair.offset[near],
                    count: pair.count[near] as u32,
                    t: e[near],
                };
                continue 'walk;
            }
        }
        // Pop the next subtree still worth entering (inclusive: ties need the visit).
        loop {
            if sp == 0 {
                break 'walk;
            }
            sp -= 1;
            let next = stack[sp];
            if next.t <= best_t {
                n = next;
                continue 'walk;
            }
        }
    }
    (best_t, best_p, bu, bv)
}

/// Any-hit of rays `range`, written to `out` (which starts all-false).
pub(super) fn occluded_chunk(
    bvh: &Bvh,
    rays: &RayBatch,
    range: Range<usize>,
    out: &mut [bool],
) -> Stats {
    let mut c = Counters::default();
    let nrays = range.len();
    let Some(root) = bvh.root() else {
        return c.stats(nrays);
    };
    let mut stack = [Entry::default(); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
        let q = Query {
            o,
            d,
            ray: SlabRay::new(o, d),
            tmin,
            tmax: rays.tmax[i],
        };
        c.ray_box += 1;
        let Some(t) = q.ray.entry(root.min, root.max, tmin, q.tmax) else {
            continue;
        };
        let start = Entry {
            offset: root.offset,
            count: root.count as u32,
            t,
        };
        out[k] = by_octant!(q.ray.neg, occluded_ray(bvh, &q, start, &mut stack, &mut c));
    }
    c.stats(nrays)
}

/// Any hit of one ray whose root box is entered.
#[inline(always)]
fn occluded_ray<const NX: bool, const NY: bool, const NZ: bool>(
    bvh: &Bvh,
    q: &Query,
    start: Entry,
    stack: &mut [Entry; MAX_DEPTH],
    c: &mut Counters,
) -> bool {
    let pairs: &[NodePair] = &bvh.pairs;
    let (o, d, tmin, tmax) = (q.o, q.d, q.tmin, q.tmax);
    let mut n = start;
    let mut sp = 0usize;
    loop {
        if n.count != 0 {
            c.leaves += 1;
            let first = n.offset as usize;
            for tri in &bvh.tris[first..first + n.count as usize] {
                c.ray_tri += 1;
                if intersect_triangle(o, d, tri[0], tri[1], tri[2], tmin, tmax).is_some() {
                    return true;
                }
            }
        } else {
            c.nodes += 1;
            c.ray_box += 2;
            let pair = &pairs[n.offset as usize];
            let (mask, e) = q.ray.entry2::<NX, NY, NZ>(&pair.boxes, tmin, tmax);
            // Near first still pays for any-hit: the near child is likelier to block.
            if mask != 0 {
                let near = if mask == 3 {
                    (e[1] < e[0]) as usize
                } else {
                    (mask >> 1) as usize
                };
                if mask == 3 {
                    let far = near ^ 1;
                    stack[sp] = Entry {
                        offset: pair.offset[far],
                        count: pair.count[far] as u32,
                        t: e[far],
                    };
                    sp += 1;
                }
                n = Entry {
                    offset: pair.offset[near],
                    count: pair.count[near] as u32,
                    t: e[near],
                };
                continue;
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        n = stack[sp];
    }
}
