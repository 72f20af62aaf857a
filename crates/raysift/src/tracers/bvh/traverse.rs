//! Closest-hit and any-hit traversal of a [`Bvh`], one ray at a time over a chunk of rays.
//!
//! At an interior node both children's boxes are tested against `[tmin, best_t]`; the nearer
//! hit child (by entry distance) is visited next and the farther one pushed with its entry, and a
//! popped entry beyond the (since shrunk) `best_t` is dropped. Counters live in locals and are
//! returned once per chunk.

use super::{Bvh, MAX_DEPTH};
use crate::geom::{intersect_triangle, SlabRay};
use crate::rays::{RayBatch, MISS};
use crate::tracer::{closer, HitsMut, Stats};
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
    let mut stack = [(root, 0f32); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
        let ray = SlabRay::new(o, d);
        let (mut best_t, mut best_p, mut bu, mut bv) = (rays.tmax[i], MISS, 0.0, 0.0);
        c.ray_box += 1;
        if ray.entry(root.min, root.max, tmin, best_t).is_none() {
            continue;
        }
        let mut n = root;
        let mut sp = 0usize;
        'walk: loop {
            if n.is_leaf() {
                c.leaves += 1;
                let first = n.offset as usize;
                let end = first + n.count as usize;
                c.ray_tri += (end - first) as u64;
                for (p, tri) in (first..end).zip(&bvh.tris[first..end]) {
                    if let Some(h) = intersect_triangle(o, d, tri[0], tri[1], tri[2], tmin, best_t)
                    {
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
                let [l, r] = bvh.children(n);
                let el = ray.entry(l.min, l.max, tmin, best_t);
                let er = ray.entry(r.min, r.max, tmin, best_t);
                match (el, er) {
                    (Some(a), Some(b)) => {
                        let (near, far, far_t) = if a <= b { (l, r, b) } else { (r, l, a) };
                        stack[sp] = (far, far_t);
                        sp += 1;
                        n = near;
                        continue 'walk;
                    }
                    (Some(_), None) => {
                        n = l;
                        continue 'walk;
                    }
                    (None, Some(_)) => {
                        n = r;
                        continue 'walk;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next subtree still worth entering (inclusive: ties need the visit).
            loop {
                if sp == 0 {
                    break 'walk;
                }
                sp -= 1;
                let (next, entry) = stack[sp];
                if entry <= best_t {
                    n = next;
                    continue 'walk;
                }
            }
        }
        if best_p != MISS {
            (out.t[k], out.prim[k], out.u[k], out.v[k]) = (best_t, best_p, bu, bv);
        }
    }
    c.stats(nrays)
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
    let mut stack = [root; MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let (o, d, tmin, tmax) = (rays.origin(i), rays.dir(i), rays.tmin[i], rays.tmax[i]);
        let ray = SlabRay::new(o, d);
        c.ray_box += 1;
        if ray.entry(root.min, root.max, tmin, tmax).is_none() {
            continue;
        }
        let mut n = root;
        let mut sp = 0usize;
        'walk: loop {
            if n.is_leaf() {
                c.leaves += 1;
                let first = n.offset as usize;
                for tri in &bvh.tris[first..first + n.count as usize] {
                    c.ray_tri += 1;
                    if intersect_triangle(o, d, tri[0], tri[1], tri[2], tmin, tmax).is_some() {
                        out[k] = true;
                        break 'walk;
                    }
                }
            } else {
                c.nodes += 1;
                c.ray_box += 2;
                let [l, r] = bvh.children(n);
                let el = ray.entry(l.min, l.max, tmin, tmax);
                let er = ray.entry(r.min, r.max, tmin, tmax);
                // Near first still pays for any-hit: the near child is likelier to block.
                match (el, er) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        stack[sp] = far;
                        sp += 1;
                        n = near;
                        continue 'walk;
                    }
                    (Some(_), None) => {
                        n = l;
                        continue 'walk;
                    }
                    (None, Some(_)) => {
                        n = r;
                        continue 'walk;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            n = stack[sp];
        }
    }
    c.stats(nrays)
}
