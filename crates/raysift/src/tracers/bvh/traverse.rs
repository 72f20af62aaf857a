//! Closest-hit and any-hit traversal of a [`Bvh`], one ray at a time over a chunk of rays.
//!
//! At an interior node both children's boxes are tested against `[tmin, best_t]` with one
//! 4-wide slab test ([`SlabRay::entry2`], bit for bit the scalar [`SlabRay::entry`] on each); the
//! nearer hit child (by entry distance) is visited next and the farther one pushed with its
//! entry, and a popped entry beyond the (since shrunk) `best_t` is dropped. The walk is
//! instantiated once per ray octant (the const parameters), so the near/far plane choice costs
//! nothing per node. Counters live in locals and are returned once per chunk.

use super::{LeafBvh, Node, NodePair, MAX_DEPTH};
use crate::geom::{intersect_triangle, SlabRay};
use crate::rays::{RayBatch, MISS};
use crate::tracer::{closer, CostMut, HitsMut};
use glam::Vec3;
use std::ops::Range;

crate::counters! {
    /// What a `bvh` trace counts.
    pub struct Counters {
        /// Ray/box slab tests (the root's, then two per interior node visited).
        ray_box,
        /// Ray/triangle tests.
        ray_tri,
        /// Interior nodes visited.
        nodes,
        /// Leaves visited.
        leaves,
    }
}

/// A node to visit: its offset and count (as in [`NodePair`]) and its entry distance.
#[derive(Clone, Copy, Default)]
struct Entry {
    offset: u32,
    count: u32,
    t: f32,
}

/// Descends into an interior node whose children `mask` (bit k: child k entered, at `e[k]`)
/// says were entered: returns the nearer child (ties to the left) and pushes the farther one,
/// if both were entered, onto `stack` at `*sp`. Shared by every walk so the order is one rule.
#[inline(always)]
fn descend(pair: &NodePair, mask: u32, e: [f32; 2], stack: &mut [Entry], sp: &mut usize) -> Entry {
    let near = if mask == 3 {
        (e[1] < e[0]) as usize
    } else {
        (mask >> 1) as usize
    };
    if mask == 3 {
        let far = near ^ 1;
        stack[*sp] = Entry {
            offset: pair.offset[far],
            count: pair.count[far] as u32,
            t: e[far],
        };
        *sp += 1;
    }
    Entry {
        offset: pair.offset[near],
        count: pair.count[near] as u32,
        t: e[near],
    }
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

/// Charges one ray's share of the counters (`after - before`) to its cost record.
#[inline]
fn charge(cost: &mut Option<CostMut<'_>>, k: usize, before: &Counters, after: &Counters) {
    if let Some(cost) = cost {
        let box_tests = after.ray_box - before.ray_box;
        let tri_tests = after.ray_tri - before.ray_tri;
        // Nodes entered: the root's box, then every node visited below it.
        let nodes = (after.nodes - before.nodes) + (after.leaves - before.leaves);
        cost.add(k, nodes, box_tests + tri_tests, tri_tests);
    }
}

/// Prepared query of ray `i`, and its entry into the root's box (`None`: it misses the root).
#[inline(always)]
fn start_ray(root: &Node, rays: &RayBatch, i: usize, c: &mut Counters) -> Option<(Query, Entry)> {
    let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
    let q = Query {
        o,
        d,
        ray: SlabRay::new(o, d),
        tmin,
        tmax: rays.tmax[i],
    };
    c.ray_box += 1;
    let t = q.ray.entry(root.min, root.max, tmin, q.tmax)?;
    let start = Entry {
        offset: root.offset,
        count: root.count as u32,
        t,
    };
    Some((q, start))
}

/// Closest hits of rays `range`, written to `out` (which starts all-miss); per-ray cost into
/// `cost` when asked.
pub(super) fn closest_chunk(
    bvh: &LeafBvh,
    rays: &RayBatch,
    range: Range<usize>,
    out: HitsMut<'_>,
    mut cost: Option<CostMut<'_>>,
) -> Counters {
    let mut c = Counters::default();
    let Some(root) = bvh.root() else {
        return c;
    };
    let mut stack = [Entry::default(); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let before = c;
        if let Some((q, start)) = start_ray(&root, rays, i, &mut c) {
            let (best_t, best_p, bu, bv) =
                by_octant!(q.ray.neg, closest_ray(bvh, &q, start, &mut stack, &mut c));
            if best_p != MISS {
                (out.t[k], out.prim[k], out.u[k], out.v[k]) = (best_t, best_p, bu, bv);
            }
        }
        charge(&mut cost, k, &before, &c);
    }
    c
}

/// Closest hit of one ray whose root box is entered: `(t, prim, u, v)`, `prim == MISS` when none.
#[inline(always)]
fn closest_ray<const NX: bool, const NY: bool, const NZ: bool>(
    bvh: &LeafBvh,
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
                n = descend(pair, mask, e, &mut stack[..], &mut sp);
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

/// Any-hit of rays `range`, written to `out` (which starts all-false); per-ray cost into `cost`
/// when asked.
pub(super) fn occluded_chunk(
    bvh: &LeafBvh,
    rays: &RayBatch,
    range: Range<usize>,
    out: &mut [bool],
    mut cost: Option<CostMut<'_>>,
) -> Counters {
    let mut c = Counters::default();
    let Some(root) = bvh.root() else {
        return c;
    };
    let mut stack = [Entry::default(); MAX_DEPTH];
    for (k, i) in range.enumerate() {
        let before = c;
        if let Some((q, start)) = start_ray(&root, rays, i, &mut c) {
            out[k] = by_octant!(q.ray.neg, occluded_ray(bvh, &q, start, &mut stack, &mut c));
        }
        charge(&mut cost, k, &before, &c);
    }
    c
}

/// Any hit of one ray whose root box is entered.
#[inline(always)]
fn occluded_ray<const NX: bool, const NY: bool, const NZ: bool>(
    bvh: &LeafBvh,
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
                n = descend(pair, mask, e, &mut stack[..], &mut sp);
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

/// Most rays [`interleaved_chunk`] keeps in flight.
pub const MAX_LANES: usize = 16;

/// Hints the CPU to fetch the cache line holding `p` (a no-op off x86_64).
#[inline(always)]
fn prefetch<T>(p: *const T) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse"))]
    // SAFETY: a prefetch is only a hint: it never faults or changes memory, whatever the
    // address (callers pass in-bounds addresses anyway); SSE is enabled for this target.
    // Exercised by every traversal test (conformance, proptest).
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(p as *const i8)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse")))]
    let _ = p;
}

/// One ray in flight in [`interleaved_chunk`].
struct Lane {
    q: Query,
    best_t: f32,
    best_p: u32,
    bu: f32,
    bv: f32,
    n: Entry,
    sp: usize,
    /// Position of the ray in the chunk.
    k: usize,
}

/// The data a node refers to: its children's pair (interior) or its triangles (leaf).
#[inline(always)]
fn prefetch_entry(bvh: &LeafBvh, n: Entry) {
    if n.count != 0 {
        let t = bvh.tris.as_ptr().wrapping_add(n.offset as usize);
        prefetch(t);
        // A leaf's corners span up to 3 cache lines (36 B each, up to 255 of them: the first
        // few matter).
        prefetch(t.wrapping_add(n.count as usize - 1));
    } else {
        prefetch(bvh.pairs.as_ptr().wrapping_add(n.offset as usize));
    }
}

/// Closest hit (`ANY = false`) or any hit of rays `range`, `lanes` rays at a time: each round
/// advances every ray in flight by one node (the same walk as [`closest_chunk`] /
/// [`occluded_chunk`], near/far planes picked by masks instead of per octant), prefetching the
/// node each will visit next, so the cache misses of different rays overlap instead of
/// serialising (the traversal of a big scene is bound by memory latency, not arithmetic).
/// A finished ray's lane takes the next ray of the chunk. Each ray's work and result are
/// exactly those of the one-at-a-time walk. `done(k, lane)` receives each ray that reached
/// the root's box when it finishes.
fn interleaved_chunk<const ANY: bool>(
    bvh: &LeafBvh,
    rays: &RayBatch,
    range: Range<usize>,
    lanes: usize,
    c: &mut Counters,
    mut done: impl FnMut(&Lane, bool),
) {
    let Some(root) = bvh.root() else {
        return;
    };
    let lanes = lanes.clamp(1, MAX_LANES);
    let pairs: &[NodePair] = &bvh.pairs;
    let base = range.start;
    let mut next = range.start;
    let end = range.end;
    // Starts the next ray that enters the root box, if any is left.
    let mut start = |c: &mut Counters| -> Option<Lane> {
        while next < end {
            let i = next;
            next += 1;
            let (o, d, tmin, tmax) = (rays.origin(i), rays.dir(i), rays.tmin[i], rays.tmax[i]);
            let ray = SlabRay::new(o, d);
            c.ray_box += 1;
            if let Some(t) = ray.entry(root.min, root.max, tmin, tmax) {
                let n = Entry {
                    offset: root.offset,
                    count: root.count as u32,
                    t,
                };
                return Some(Lane {
                    q: Query {
                        o,
                        d,
                        ray,
                        tmin,
                        tmax,
                    },
                    best_t: tmax,
                    best_p: MISS,
                    bu: 0.0,
                    bv: 0.0,
                    n,
                    sp: 0,
                    k: i - base,
                });
            }
        }
        None
    };
    let mut slots: [Option<Lane>; MAX_LANES] = Default::default();
    let mut stacks = [[Entry::default(); MAX_DEPTH]; MAX_LANES];
    let mut active = 0;
    for s in slots.iter_mut().take(lanes) {
        *s = start(c);
        active += s.is_some() as usize;
    }
    while active > 0 {
        for (slot, stack) in slots.iter_mut().zip(stacks.iter_mut()).take(lanes) {
            let Some(l) = slot.as_mut() else {
                continue;
            };
            // One step: visit `l.n`, then choose the next node (descend or pop).
            let n = l.n;
            let mut hit_any = false;
            if n.count != 0 {
                c.leaves += 1;
                let first = n.offset as usize;
                let last = first + n.count as usize;
                if ANY {
                    for tri in &bvh.tris[first..last] {
                        c.ray_tri += 1;
                        let (q, t) = (&l.q, tri);
                        if intersect_triangle(q.o, q.d, t[0], t[1], t[2], q.tmin, q.tmax).is_some()
                        {
                            hit_any = true;
                            break;
                        }
                    }
                } else {
                    c.ray_tri += n.count as u64;
                    for (p, tri) in (first..last).zip(&bvh.tris[first..last]) {
                        let q = &l.q;
                        if let Some(h) =
                            intersect_triangle(q.o, q.d, tri[0], tri[1], tri[2], q.tmin, l.best_t)
                        {
                            let id = bvh.ids[p];
                            if closer(h.t, id, l.best_t, l.best_p) {
                                (l.best_t, l.best_p, l.bu, l.bv) = (h.t, id, h.u, h.v);
                            }
                        }
                    }
                }
            } else {
                c.nodes += 1;
                c.ray_box += 2;
                let pair = &pairs[n.offset as usize];
                let (mask, e) = l.q.ray.entry2_masked(&pair.boxes, l.q.tmin, l.best_t);
                if mask != 0 {
                    l.n = descend(pair, mask, e, &mut stack[..], &mut l.sp);
                    prefetch_entry(bvh, l.n);
                    continue;
                }
            }
            let mut finished = hit_any;
            if !finished {
                // Pop the next subtree still worth entering (closest hit: inclusive cull).
                finished = true;
                while l.sp > 0 {
                    l.sp -= 1;
                    let nx = stack[l.sp];
                    if ANY || nx.t <= l.best_t {
                        l.n = nx;
                        prefetch_entry(bvh, nx);
                        finished = false;
                        break;
                    }
                }
            }
            if finished {
                done(l, hit_any);
                *slot = start(c);
                if slot.is_none() {
                    active -= 1;
                }
            }
        }
    }
}

/// [`closest_chunk`] with `lanes` rays in flight (see [`interleaved_chunk`]).
pub(super) fn closest_chunk_interleaved(
    bvh: &LeafBvh,
    rays: &RayBatch,
    range: Range<usize>,
    lanes: usize,
    out: HitsMut<'_>,
) -> Counters {
    let mut c = Counters::default();
    interleaved_chunk::<false>(bvh, rays, range, lanes, &mut c, |l, _| {
        if l.best_p != MISS {
            let k = l.k;
            (out.t[k], out.prim[k], out.u[k], out.v[k]) = (l.best_t, l.best_p, l.bu, l.bv);
        }
    });
    c
}

/// [`occluded_chunk`] with `lanes` rays in flight (see [`interleaved_chunk`]).
pub(super) fn occluded_chunk_interleaved(
    bvh: &LeafBvh,
    rays: &RayBatch,
    range: Range<usize>,
    lanes: usize,
    out: &mut [bool],
) -> Counters {
    let mut c = Counters::default();
    interleaved_chunk::<true>(bvh, rays, range, lanes, &mut c, |l, hit| {
        out[l.k] = hit;
    });
    c
}
