//! Ours: rays from one point (a camera's eye), traced in that point's frame. A task whose rays
//! all start at one point (bitwise) is where the 5D hierarchy degenerates: the origin box has
//! no extent and only the slopes `(u, v)` tell the rays apart, which are the coordinates of a
//! cube map around the eye. The pass is `dacrt`'s light-space pass (`tracers/dacrt/light.rs`,
//! an irregular z-buffer) with the eye in the light's place and closest hits:
//! - each ray is a point of one face (its direction's, [`ray_view`]), sorted into buckets of
//!   about `eye_bucket` rays (a counting sort; the grids are shared with `light.rs`: [`Faces`]);
//! - the triangles are streamed once: each triangle's box gets its footprint on every face
//!   ([`LightView::footprint`]), and only the rays of the buckets under it whose coordinates
//!   the footprint holds, and whose best hit so far is not nearer than the box, go through the
//!   shared test (gathered per triangle and tested four at a time from the eye:
//!   [`TriFromOrigin`], bit-equal to it);
//! - a ray's depth is its best hit's face-axis coordinate `t·|d_k|` (exact in f64), so a ray
//!   whose hit lies nearer than a box's nearest point skips it exactly (`geom::light_space`,
//!   `every_eye_ray_hit_is_inside_its_footprint`); each bucket keeps an upper bound of its
//!   rays' depths, lowered after the tests that improved them;
//! - occlusion is any-hit: an occluded ray's depth becomes `-inf`, it is never tested again;
//! - triangles in a tiny ball around the eye have no footprint and are tested against every ray.
//!
//! **Order** (`eye_tree`, ours): the triangles come from the kept levels (`top.rs`, made here
//! if no call made them yet), walked near to far, and a node whose box's footprints cover only
//! buckets that are empty or whose rays all hit nearer than the box is skipped whole (a
//! hierarchical z-buffer: a triangle in the box has a footprint inside the box's and an `x0`
//! beyond it). Without them, near to far in `eye_bins` bins of the boxes' distance (a counting
//! sort into the task's triangle list). Either way a ray's best hit comes early and the
//! buckets' bounds then skip what lies behind it.
//!
//! The footprints' rectangles go through a short software pipeline: their buckets' records,
//! then those buckets' first rays, are asked for (prefetched) a few rectangles before they are
//! traced (3–10% on the bunny's shuffled camera, BENCHMARKS.md).
//!
//! Used for a task's whole share when every ray starts at the same point with `tmin >= 0`, a
//! finite, non-zero direction and a `tmax` that is not NaN, the point lies outside the
//! scene's box (unless `eye_inside`), and the share holds at least `eye_ratio` (0.25) times as
//! many rays as the scene has live triangles (the pass walks the triangles per task);
//! otherwise the task goes through the 5D recursion. Measured in BENCHMARKS.md § "dacrt5d:
//! rays from one point".

// Negated comparisons on purpose (NaN-safe).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::top::Top;
use super::{Counts, Dacrt5d};
use crate::geom::lanes::Lanes;
use crate::geom::{ray_view, LightView, TriFromOrigin, Vec3};
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::{closer, CostMut};
use crate::tracers::dacrt::light::{bucket_cap, next_up, FacePoints, Faces, LightPoint, Rect};
use crate::tracers::dacrt::partition::prefetch;
use crate::tracers::dacrt::scratch::reuse;
use glam::Vec4;
use std::ops::Range;

/// The most distance bins of the triangle stream (`eye_bins` is clamped to it).
const MAX_BINS: usize = 1024;

/// A ray in its bucket: its face coordinates, its depth bound (the face-axis coordinate of
/// its best hit so far, raised to f32) and its task-local index, as `light.rs`'s segments.
type EyePoint = LightPoint;

/// A ray in its bucket: its [`EyePoint`], then what its tests read, its direction and its best
/// `t` so far (starting at `tmax`). 32 bytes, aligned: one half cache line, so the sort writes
/// one scattered line per ray.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub(super) struct EyeRec {
    p: EyePoint,
    d: [f32; 3],
    t: f32,
}

/// The rest of a ray's best hit (same slot), written only when a test improves it.
#[derive(Clone, Copy, Debug)]
pub(super) struct EyeHit {
    prim: u32,
    u: f32,
    v: f32,
}

/// A task's buffers for the eye pass, kept between calls.
#[derive(Default)]
pub(super) struct EyeScratch {
    /// Per ray of the share: its coordinates, depth and face, then its bucket.
    key: Vec<EyePoint>,
    recs: Vec<EyeRec>,
    hits: Vec<EyeHit>,
    buckets: Vec<Bucket>,
}

/// A bucket: its live rays are `recs[start..live]`, their depths at most `depth`.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
struct Bucket {
    start: u32,
    live: u32,
    depth: f32,
}

impl EyeScratch {
    pub(super) fn bytes(&self) -> usize {
        16 * self.key.capacity()
            + 32 * self.recs.capacity()
            + 12 * (self.hits.capacity() + self.buckets.capacity())
    }
}

/// The outputs of a task (closest hits, or occlusion), task-local.
pub(super) struct Out<'o> {
    pub(super) t: &'o mut [f32],
    pub(super) prim: &'o mut [u32],
    pub(super) u: &'o mut [f32],
    pub(super) v: &'o mut [f32],
    pub(super) occ: &'o mut [bool],
}

impl Dacrt5d {
    /// The eye pass over rays `range` into `out` (reset to misses), or `false` (nothing
    /// written) when the share does not fit it.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn eye_task<const ANY: bool>(
        &self,
        tris: &TriangleSoup,
        rays: &RayBatch,
        range: Range<usize>,
        sc: &mut EyeScratch,
        order: &mut Vec<u32>,
        out: Out<'_>,
        cost: Option<&mut CostMut<'_>>,
        st: &mut Counts,
    ) -> bool {
        let n = range.len();
        if n == 0 || (n as f64) < self.cfg.eye_ratio as f64 * self.live as f64 {
            return false;
        }
        let eye = rays.origin(range.start);
        // From inside the scene's box, every triangle lies around the eye (large ones
        // covering many buckets, in many depth orders): the recursion culls better there.
        let [lo, hi] = self.bounds.map(Vec3::from);
        if !self.cfg.eye_inside && eye.cmpge(lo).all() && eye.cmple(hi).all() {
            return false;
        }
        // Every ray from the eye (bitwise), with `tmin >= 0` and a `tmax` that is not NaN,
        // checked before anything is allocated (a batch of rays from many points stops at its
        // second ray).
        let fits =
            |i: usize| rays.origin(i) == eye && rays.tmin[i] >= 0.0 && !rays.tmax[i].is_nan();
        if !eye.is_finite() || !range.clone().all(fits) {
            return false;
        }
        // Each ray's face, coordinates (f32: the footprints' pad covers their rounding, and the
        // buckets are taken from these same values) and depth; the faces' bounds and counts. A
        // zero or non-finite direction (which the loaders refuse) sends the share to the
        // recursion from here, with the key buffer kept.
        let mut key = reuse(std::mem::take(&mut sc.key), n, true);
        let mut points = FacePoints::default();
        // One `tmin` for every ray (bitwise) is kept once; else the tests read the batch's.
        let tmin = rays.tmin[range.start];
        let uniform = rays.tmin[range.clone()]
            .iter()
            .all(|t| t.to_bits() == tmin.to_bits());
        for i in range.clone() {
            let (d, tmax) = (rays.dir(i), rays.tmax[i]);
            let Some(r) = ray_view(d) else {
                sc.key = key;
                return false;
            };
            let (a, b) = (r.a as f32, r.b as f32);
            points.add(r.face, a, b);
            let x = tmax as f64 * r.axis;
            key.push(EyePoint {
                a,
                b,
                depth: next_up(x as f32, x),
                ray: r.face as u32,
            });
        }
        let per = self.cfg.eye_bucket.max(1);
        let faces = Faces::fit(&points, per);
        let nb = faces.buckets();
        // The frame: slack 0 (every point of a ray lies along its direction from the eye);
        // the boxes' pad from the scene's and the eye's magnitudes.
        let Some(view) = LightView::new(eye, 0.0, self.scale as f64, 0.0) else {
            sc.key = key;
            return false;
        };
        // The counting sort into buckets (`ray` holds the face, then the bucket).
        let cap = bucket_cap(n, per);
        let mut bk = reuse(std::mem::take(&mut sc.buckets), cap, true);
        bk.resize(
            nb,
            Bucket {
                start: 0,
                live: 0,
                depth: f32::NEG_INFINITY,
            },
        );
        // Counts in `live`, then the starts, then `live` is the placing cursor.
        for k in key.iter_mut() {
            let b = faces.bucket(k.ray as usize, k.a, k.b);
            k.ray = b as u32;
            bk[b].live += 1;
            bk[b].depth = bk[b].depth.max(k.depth);
        }
        let mut at = 0;
        for b in bk.iter_mut() {
            (b.start, at) = (at, at + b.live);
            b.live = b.start;
        }
        let mut recs = reuse(std::mem::take(&mut sc.recs), n, true);
        let mut hits = reuse(std::mem::take(&mut sc.hits), n, true);
        recs.resize(n, EyeRec::default());
        let miss = EyeHit {
            prim: MISS,
            u: 0.0,
            v: 0.0,
        };
        hits.resize(n, miss);
        for (j, i) in range.clone().enumerate() {
            let k = key[j];
            let b = &mut bk[k.ray as usize];
            let at = b.live as usize;
            b.live += 1;
            recs[at] = EyeRec {
                p: EyePoint { ray: j as u32, ..k },
                d: rays.dir(i).to_array(),
                t: rays.tmax[i],
            };
        }
        // Each bucket's cursor now ends at the next's start: every ray is live.
        st.eye_rays += n as u64;
        let mut pass = Pass::<ANY> {
            tris,
            eye,
            recs: &mut recs,
            hits: &mut hits,
            tmin: (uniform, tmin, &rays.tmin[range.clone()]),
            bk: &mut bk,
            occ: out.occ,
            cost,
            st,
        };
        // The kept levels (made here if no call made them yet), walked near to far: a node
        // whose box covers only buckets whose rays all hit nearer (or none) is skipped whole,
        // a hierarchical z-buffer; without them (`top_leaf = 0`, `eye_tree=false`), the
        // triangles near to far in `eye_bins` bins of their boxes' distance (index order
        // inside a bin, a counting sort into `order`). Either way a ray's best hit comes early,
        // and the buckets' depths then cull what lies behind it.
        // The task's triangle list (the recursion's `4·T`, kept in the pool slot for it): the
        // bins' order when there is no walk.
        let mut ord = reuse(std::mem::take(order), self.boxes.len(), true);
        let mut stream = Stream::new();
        let tree = (self.cfg.eye_tree && self.cfg.top_leaf > 0).then(|| {
            let mut built = 0;
            let top = self.top.get_or_init(|| {
                let top = Top::new(
                    &self.boxes,
                    self.cfg.top_leaf,
                    self.cfg.max_depth,
                    self.cfg.top_split,
                );
                built = top.nodes.len() as u64;
                top
            });
            pass.st.top_built += built;
            top
        });
        if let Some(top) = tree.filter(|t| !t.nodes.is_empty()) {
            let mut stack = [0u32; STACK];
            let mut sp = 1;
            while sp > 0 {
                sp -= 1;
                let node = top.nodes[stack[sp] as usize];
                let (lo, hi) = (node.set.lo, node.set.hi);
                if !view.near(lo, hi) && pass.hidden(&faces, &view, lo, hi) {
                    pass.st.eye_hidden += node.len as u64;
                    continue;
                }
                let tris = &top.order[node.start as usize..(node.start + node.len) as usize];
                if node.kids == 0 || sp + 2 > STACK {
                    for &t in tris {
                        stream.feed(&mut pass, &faces, &view, t as usize, nb, &self.boxes);
                    }
                    continue;
                }
                let k = node.kids as usize;
                let gap = |i: usize| gap(eye, top.nodes[i].set.lo, top.nodes[i].set.hi);
                let (near, far) = if gap(k) <= gap(k + 1) {
                    (k, k + 1)
                } else {
                    (k + 1, k)
                };
                stack[sp] = far as u32;
                stack[sp + 1] = near as u32;
                sp += 2;
            }
        } else {
            let bins = self.cfg.eye_bins.min(MAX_BINS);
            if bins > 0 {
                let far = (eye - lo).abs().max((eye - hi).abs()).length();
                let scale = if far > 0.0 { bins as f32 / far } else { 0.0 };
                let bin = |bx: &[f32; 6]| {
                    let (lo, hi) = (
                        Vec3::new(bx[0], bx[1], bx[2]),
                        Vec3::new(bx[3], bx[4], bx[5]),
                    );
                    // NaN-safe (`as` saturates): a bin in range.
                    ((gap(eye, lo, hi) * scale) as usize).min(bins - 1)
                };
                // On the stack: nothing is allocated per call.
                let mut at = [0u32; MAX_BINS + 1];
                for bx in self.boxes.iter().filter(|b| b[0] <= b[3]) {
                    at[bin(bx) + 1] += 1;
                }
                for b in 0..bins {
                    at[b + 1] += at[b];
                }
                ord.resize(at[bins] as usize, 0);
                for (t, bx) in self.boxes.iter().enumerate().filter(|(_, b)| b[0] <= b[3]) {
                    let b = bin(bx);
                    ord[at[b] as usize] = t as u32;
                    at[b] += 1;
                }
            } else {
                ord.extend(super::top::live_ids(&self.boxes));
            }
            for &t in &ord {
                stream.feed(&mut pass, &faces, &view, t as usize, nb, &self.boxes);
            }
        }
        stream.drain(&mut pass);
        if !ANY {
            for (r, h) in recs.iter().zip(&hits) {
                if h.prim != MISS {
                    let k = r.p.ray as usize;
                    (out.t[k], out.prim[k], out.u[k], out.v[k]) = (r.t, h.prim, h.u, h.v);
                }
            }
        }
        key.clear();
        (sc.key, sc.recs, sc.hits) = (key, recs, hits);
        sc.buckets = bk;
        ord.clear();
        *order = ord;
        true
    }
}

/// Footprints in flight: a short software pipeline over the triangles' rectangles, whose
/// buckets' records, then those buckets' first rays, are asked for (prefetched) before they
/// are traced (each triangle makes at most six).
struct Stream {
    ring: [(u32, Rect); RING],
    head: usize,
    tail: usize,
}

/// Rectangles in flight, and the ring's size.
const AHEAD: usize = 16;
const RING: usize = 32;

/// The kept levels' walk: its stack (a node deeper than this has its triangles streamed).
const STACK: usize = 256;

/// A node covering more buckets than this is not checked for being hidden (its children are).
const HIDDEN_MAX_BUCKETS: usize = 64;

impl Stream {
    fn new() -> Self {
        let none = Rect {
            fp: crate::geom::Footprint {
                a: [0.0; 2],
                b: [0.0; 2],
                x0: 0.0,
            },
            first: 0,
            w: 0,
            h: 0,
            stride: 0,
        };
        Self {
            ring: [(0, none); RING],
            head: 0,
            tail: 0,
        }
    }

    /// Triangle `t`: near the eye, against every ray at once; else its rectangles into the
    /// ring, and the rectangles `AHEAD` places earlier traced.
    #[inline]
    fn feed<const ANY: bool>(
        &mut self,
        pass: &mut Pass<'_, '_, ANY>,
        faces: &Faces,
        view: &LightView,
        t: usize,
        nb: usize,
        boxes: &[[f32; 6]],
    ) {
        let bx = &boxes[t];
        let (lo, hi) = (
            Vec3::new(bx[0], bx[1], bx[2]),
            Vec3::new(bx[3], bx[4], bx[5]),
        );
        // Degenerate or non-finite (an empty box): never hit.
        if !(lo.x <= hi.x) {
            return;
        }
        if view.near(lo, hi) {
            pass.st.eye_near += 1;
            pass.everywhere(t, nb);
            return;
        }
        pass.st.eye_footprints += faces.rects(view, lo, hi, |r| {
            for row in r.rows() {
                prefetch(pass.bk, row);
                prefetch(pass.bk, row + r.w - 1);
            }
            prefetch(&pass.tris.v0, t);
            prefetch(&pass.tris.v1, t);
            prefetch(&pass.tris.v2, t);
            self.ring[self.tail % RING] = (t as u32, r);
            self.tail += 1;
        });
        while self.tail - self.head > AHEAD {
            let (t, r) = self.ring[self.head % RING];
            let (_, soon) = self.ring[(self.head + AHEAD / 2) % RING];
            for row in soon.rows() {
                prefetch(pass.recs, pass.bk[row].start as usize);
            }
            pass.rect(t as usize, &r);
            self.head += 1;
        }
    }

    /// Traces the rectangles still in flight.
    fn drain<const ANY: bool>(&mut self, pass: &mut Pass<'_, '_, ANY>) {
        while self.head < self.tail {
            let (t, r) = self.ring[self.head % RING];
            pass.rect(t as usize, &r);
            self.head += 1;
        }
    }
}

/// The distance from `eye` to the box `[lo, hi]` (0 inside it).
#[inline]
fn gap(eye: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    (lo - eye).max(eye - hi).max(Vec3::ZERO).length()
}

/// Candidates of one triangle gathered before they are tested four at a time.
const CANDIDATES: usize = 64;

/// The triangle stream's state.
struct Pass<'p, 'c, const ANY: bool> {
    tris: &'p TriangleSoup,
    eye: Vec3,
    recs: &'p mut [EyeRec],
    hits: &'p mut [EyeHit],
    /// Whether every ray has the one `tmin`, that `tmin`, and the share's (task-local).
    tmin: (bool, f32, &'p [f32]),
    bk: &'p mut [Bucket],
    occ: &'p mut [bool],
    cost: Option<&'p mut CostMut<'c>>,
    st: &'p mut Counts,
}

impl<const ANY: bool> Pass<'_, '_, ANY> {
    /// Triangle `t` against the rays of the buckets under one of its footprints: those the
    /// footprint holds and whose best hit is not nearer than the box are gathered, then
    /// tested four at a time from the eye ([`TriFromOrigin`], bit-equal to the shared test).
    /// Each bucket's depth bound is lowered to its rays' on the way (an occluded ray's depth
    /// becomes `-inf`: it is never a candidate again).
    #[inline]
    fn rect(&mut self, t: usize, r: &Rect) {
        self.st.eye_buckets += r.buckets() as u64;
        let fp = &r.fp;
        let mut tri = None;
        // The candidates' slots and buckets.
        let (mut cand, mut cb) = ([0u32; CANDIDATES], [0u32; CANDIDATES]);
        let mut nc = 0;
        r.for_each(|b| {
            let bk = self.bk[b];
            if (bk.depth as f64) < fp.x0 {
                return;
            }
            let mut deepest = f32::NEG_INFINITY;
            for q in bk.start as usize..bk.live as usize {
                let p = self.recs[q].p;
                self.st.eye_checks += 1;
                deepest = deepest.max(p.depth);
                if p.outside(fp) {
                    if let Some(c) = self.cost.as_deref_mut() {
                        c.add(p.ray as usize, 0, 1, 0);
                    }
                    continue;
                }
                (cand[nc], cb[nc]) = (q as u32, b as u32);
                nc += 1;
                if nc == CANDIDATES {
                    self.test(t, &mut tri, &cand, &cb);
                    nc = 0;
                }
            }
            // An upper bound: depths only fall (the tests below may lower some more).
            self.bk[b].depth = deepest;
        });
        if nc > 0 {
            self.test(t, &mut tri, &cand[..nc], &cb[..nc]);
        }
    }

    /// True when no ray can hit inside box `[lo, hi]` (not near the eye) nearer than its
    /// best hit: every bucket under the box's footprints is empty or its depth bound lies
    /// before the footprint's `x0` (a triangle in the box has a footprint inside the box's and
    /// an `x0` beyond it). Footprints over many buckets answer false.
    fn hidden(&self, faces: &Faces, view: &LightView, lo: Vec3, hi: Vec3) -> bool {
        let mut hidden = true;
        faces.rects(view, lo, hi, |r| {
            if !hidden {
                return;
            }
            if r.buckets() > HIDDEN_MAX_BUCKETS {
                hidden = false;
                return;
            }
            r.for_each(|b| {
                let k = self.bk[b];
                hidden &= !(k.live > k.start && k.depth as f64 >= r.fp.x0);
            });
        });
        hidden
    }

    /// Triangle `t` (near the eye) against every live ray.
    fn everywhere(&mut self, t: usize, nb: usize) {
        let mut tri = None;
        for b in 0..nb {
            let (s, e) = (self.bk[b].start as usize, self.bk[b].live as usize);
            for q0 in (s..e).step_by(CANDIDATES) {
                let cand: [u32; CANDIDATES] = std::array::from_fn(|k| (q0 + k) as u32);
                let k = CANDIDATES.min(e - q0);
                self.test(t, &mut tri, &cand[..k], &[b as u32; CANDIDATES][..k]);
            }
        }
    }

    /// The shared test of the rays in slots `cand` against triangle `t` (set up from the eye
    /// once, in `tri`), four at a time: a closest hit updates a ray's best and depth, an any
    /// hit marks it occluded and takes it out of every later test (depth `-inf`).
    #[inline]
    fn test(&mut self, t: usize, tri: &mut Option<TriFromOrigin>, cand: &[u32], cb: &[u32]) {
        let eye = self.eye;
        let tris = self.tris;
        let tri = tri.get_or_insert_with(|| {
            let [a, b, c] = tris.get(t);
            TriFromOrigin::new(eye, a, b, c, 0.0)
        });
        self.st.ray_tri += cand.len() as u64;
        // Buckets whose rays' depths fell (candidates come bucket by bucket).
        let mut dirty = [0u32; CANDIDATES];
        let mut nd = 0;
        for (gi, group) in cand.chunks(4).enumerate() {
            // A short group repeats its first ray (its extra lanes are ignored).
            let slot = |l: usize| group.get(l).copied().unwrap_or(group[0]) as usize;
            let recs = &self.recs;
            let d = [0, 1, 2].map(|k| Vec4::from_fn(|l| recs[slot(l)].d[k]));
            let tmin = match self.tmin {
                (true, t, _) => Vec4::splat(t),
                (false, _, all) => Vec4::from_fn(|l| all[recs[slot(l)].p.ray as usize]),
            };
            let tmax = Vec4::from_fn(|l| recs[slot(l)].t);
            let h = tri.intersect_lanes_each::<Vec4>(d, tmin, tmax);
            let mut m = h.mask & ((1u32 << group.len()) - 1);
            if let Some(c) = self.cost.as_deref_mut() {
                for &q in group {
                    c.add(self.recs[q as usize].p.ray as usize, 0, 1, 1);
                }
            }
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                let q = group[l] as usize;
                let b = cb[4 * gi + l];
                if nd == 0 || dirty[nd - 1] != b {
                    dirty[nd] = b;
                    nd += 1;
                }
                let r = &mut self.recs[q];
                if ANY {
                    self.occ[r.p.ray as usize] = true;
                    r.p.depth = f32::NEG_INFINITY;
                    continue;
                }
                let ht = h.t.lane(l);
                let best = &mut self.hits[q];
                if closer(ht, t as u32, r.t, best.prim) {
                    r.t = ht;
                    (best.prim, best.u, best.v) = (t as u32, h.u.lane(l), h.v.lane(l));
                    // `|d_k|` is the largest component: the face axis's.
                    let x = ht as f64 * Vec3::from_array(r.d).abs().max_element() as f64;
                    r.p.depth = next_up(x as f32, x);
                }
            }
        }
        // Their depth bounds lowered now, so the kept levels' walk sees them (`hidden`).
        for &b in &dirty[..nd] {
            let k = self.bk[b as usize];
            let recs = &self.recs[k.start as usize..k.live as usize];
            self.bk[b as usize].depth =
                recs.iter().fold(f32::NEG_INFINITY, |m, r| m.max(r.p.depth));
        }
    }
}
