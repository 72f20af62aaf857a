//! Ours (issue #21 item 1): shadow segments to one point light, traced in the light's frame.
//!
//! Every segment of a `ToPoint` batch ends at the light, so seen from the light it is a camera
//! ray through an irregular "pixel": its origin's direction. A task puts its segments on the
//! six faces of a cube around the light ([`crate::geom::LightView`]), sorts them into a grid
//! of buckets per face (a counting sort, about `light_bucket` segments per bucket, the grid
//! fitted to the face's segments), and streams the triangles once: each triangle's bounding
//! box gets its footprint on every face it can be seen in, and is tested against the live
//! segments of the buckets under it whose coordinates the footprint holds and which reach as
//! deep as the box (the irregular z-buffer of Johnson et al. 2005, exact: every candidate goes
//! through the shared ray/triangle test, and the footprints are conservative: see
//! `geom::light_space`). An occluded segment leaves its bucket at once (any hit), so a
//! bucket's segments cost only the triangles between them and the light that cover them.
//! Triangles in a small ball around the light have no footprint and are tested against every
//! live segment; segments that do not fit (not ending near the light, `tmin < 0`, an origin
//! on the light) go through the ordinary recursion. No spatial recursion and no ray list: one
//! pass over the min/max lists, a few buckets per triangle.

// Negated comparisons on purpose (NaN-safe); the set-up indexes several per-face arrays by face.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use super::scratch::reuse;
use super::{clock, ns_since, Counts, Dacrt};
use crate::geom::{intersect_triangle, segment_slack, segment_view, Footprint, LightView};
use crate::rays::RayBatch;
use crate::scene::TriangleSoup;
use crate::tracer::CostMut;
use glam::Vec3;
use std::ops::Range;

/// One segment (or `dacrt5d`'s eye ray) in a bucket: its face coordinates and depth bound
/// (f32, see `geom::light_space` for the pads) and its ray (task-local index): 16 bytes, what
/// the footprint check reads.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(crate) struct LightPoint {
    pub(crate) a: f32,
    pub(crate) b: f32,
    pub(crate) depth: f32,
    pub(crate) ray: u32,
}

impl LightPoint {
    /// True when footprint `fp` does not hold the point's coordinates, or starts deeper than
    /// its depth bound: no hit inside the footprint's box can be reported for its ray (any
    /// nearer than its best).
    #[inline(always)]
    pub(crate) fn outside(&self, fp: &Footprint) -> bool {
        let (a, b) = (self.a as f64, self.b as f64);
        (self.depth as f64) < fp.x0 || a < fp.a[0] || a > fp.a[1] || b < fp.b[0] || b > fp.b[1]
    }
}

/// The ray of a [`LightPoint`] (same slot), for the shared test: 32 bytes.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(super) struct LightSeg {
    o: [f32; 3],
    tmin: f32,
    d: [f32; 3],
    tmax: f32,
}

/// A segment of the share in ray order: face coordinates, depth bound, face (then bucket).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Key {
    a: f32,
    b: f32,
    depth: f32,
    face: u32,
}

/// `Key::face` of a segment the pass leaves to the recursion.
const MISFIT: u32 = u32::MAX;

impl Key {
    const MISFIT: Key = Key {
        a: 0.0,
        b: 0.0,
        depth: 0.0,
        face: MISFIT,
    };
}

/// A task's buffers for the light-space pass, kept between calls.
#[derive(Default)]
pub(super) struct LightScratch {
    /// The segments, bucket by bucket.
    pts: Vec<LightPoint>,
    segs: Vec<LightSeg>,
    /// Per ray of the share: its coordinates, depth and face, then its bucket.
    key: Vec<Key>,
    /// Bucket `b`'s live segments are `pts[start[b]..live[b]]` (`start` has one more entry).
    start: Vec<u32>,
    live: Vec<u32>,
    /// Per bucket: the largest depth of its segments.
    depth: Vec<f32>,
}

impl LightScratch {
    pub(super) fn bytes(&self) -> usize {
        self.pts.capacity() * std::mem::size_of::<LightPoint>()
            + self.segs.capacity() * std::mem::size_of::<LightSeg>()
            + 16 * self.key.capacity()
            + 4 * (self.start.capacity() + self.live.capacity() + self.depth.capacity())
    }
}

/// One face's grid: buckets `first..first + nx·ny`, row-major, over the face coordinates
/// `[a0, a0 + nx/sa] × [b0, b0 + ny/sb]` of its points.
#[derive(Clone, Copy, Debug, Default)]
struct FaceGrid {
    first: usize,
    nx: usize,
    ny: usize,
    a0: f64,
    b0: f64,
    sa: f64,
    sb: f64,
    a1: f64,
    b1: f64,
}

impl FaceGrid {
    /// The column of coordinate `a` (monotone in `a`, clamped to the grid).
    #[inline]
    fn col(&self, a: f64) -> usize {
        // `max` then the cast: the floor of a non-negative value (a NaN goes to 0), no libm call.
        (((a - self.a0) * self.sa).max(0.0) as usize).min(self.nx - 1)
    }

    #[inline]
    fn row(&self, b: f64) -> usize {
        (((b - self.b0) * self.sb).max(0.0) as usize).min(self.ny - 1)
    }
}

/// The points of each cube face: how many, and their coordinates' bounds `[a0, a1, b0, b1]`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FacePoints {
    count: [usize; 6],
    bounds: [[f32; 4]; 6],
}

impl Default for FacePoints {
    fn default() -> Self {
        Self {
            count: [0; 6],
            bounds: [[
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::INFINITY,
                f32::NEG_INFINITY,
            ]; 6],
        }
    }
}

impl FacePoints {
    /// One more point, on face `f` at `(a, b)`.
    #[inline]
    pub(crate) fn add(&mut self, f: usize, a: f32, b: f32) {
        self.count[f] += 1;
        let q = &mut self.bounds[f];
        *q = [q[0].min(a), q[1].max(a), q[2].min(b), q[3].max(b)];
    }
}

/// The bucket grids of the six cube faces around one point (a light, or the eye of
/// `dacrt5d`'s eye pass): shared by both passes.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Faces {
    grids: [FaceGrid; 6],
    used: [usize; 6],
    nused: usize,
    nb: usize,
}

impl Faces {
    /// Grids of about `per` points per bucket, each shaped like its face's points.
    pub(crate) fn fit(points: &FacePoints, per: usize) -> Self {
        let FacePoints { count, bounds } = *points;
        let mut out = Self::default();
        for f in 0..6 {
            if count[f] == 0 {
                continue;
            }
            let cells = (count[f] / per.max(1)).max(1);
            let [a0, a1, b0, b1] = bounds[f].map(f64::from);
            let (wa, wb) = ((a1 - a0).max(1e-12), (b1 - b0).max(1e-12));
            let nx = ((cells as f64 * wa / wb).sqrt().round() as usize).clamp(1, cells);
            let ny = (cells / nx).max(1);
            out.grids[f] = FaceGrid {
                first: out.nb,
                nx,
                ny,
                a0,
                b0,
                sa: nx as f64 / wa,
                sb: ny as f64 / wb,
                a1,
                b1,
            };
            out.nb += nx * ny;
            out.used[out.nused] = f;
            out.nused += 1;
        }
        out
    }

    /// The number of buckets.
    pub(crate) fn buckets(&self) -> usize {
        self.nb
    }

    /// The bucket of a point of face `f` at `(a, b)`.
    #[inline]
    pub(crate) fn bucket(&self, f: usize, a: f32, b: f32) -> usize {
        let g = &self.grids[f];
        g.first + g.row(b as f64) * g.nx + g.col(a as f64)
    }

    /// The narrowest bucket side (the footprints' pad is chosen against it).
    pub(crate) fn narrowest(&self) -> f64 {
        self.grids[..]
            .iter()
            .enumerate()
            .filter(|(f, _)| self.used[..self.nused].contains(f))
            .map(|(_, g)| (1.0 / g.sa).min(1.0 / g.sb))
            .fold(f64::INFINITY, f64::min)
    }

    /// Calls `f(rect)` with the buckets under the footprint of box `[lo, hi]` (not
    /// [`LightView::near`]) on each face holding points, when the footprint meets its grid;
    /// returns the footprints made.
    #[inline]
    pub(crate) fn rects(
        &self,
        view: &LightView,
        lo: Vec3,
        hi: Vec3,
        mut f: impl FnMut(Rect),
    ) -> u64 {
        let mut fps = 0;
        for &face in &self.used[..self.nused] {
            let Some(fp) = view.footprint(lo, hi, face) else {
                continue;
            };
            fps += 1;
            let g = &self.grids[face];
            if fp.a[1] < g.a0 || fp.a[0] > g.a1 || fp.b[1] < g.b0 || fp.b[0] > g.b1 {
                continue;
            }
            let (x0, x1) = (g.col(fp.a[0]), g.col(fp.a[1]));
            let (y0, y1) = (g.row(fp.b[0]), g.row(fp.b[1]));
            f(Rect {
                fp,
                first: g.first + y0 * g.nx + x0,
                w: x1 - x0 + 1,
                h: y1 - y0 + 1,
                stride: g.nx,
            });
        }
        fps
    }

    /// Calls `f(bucket, footprint)` for every bucket of [`Self::rects`]; returns the
    /// footprints made and the buckets visited.
    #[inline]
    pub(crate) fn cover(
        &self,
        view: &LightView,
        lo: Vec3,
        hi: Vec3,
        mut f: impl FnMut(usize, &Footprint),
    ) -> (u64, u64) {
        let mut nbk = 0;
        let fps = self.rects(view, lo, hi, |r| {
            nbk += r.buckets() as u64;
            r.for_each(|b| f(b, &r.fp));
        });
        (fps, nbk)
    }
}

/// The buckets under one footprint on one face: `h` rows of `w` buckets, the first at
/// `first`, rows `stride` apart (row-major grids).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rect {
    pub(crate) fp: Footprint,
    pub(crate) first: usize,
    pub(crate) w: usize,
    pub(crate) h: usize,
    pub(crate) stride: usize,
}

impl Rect {
    /// How many buckets.
    pub(crate) fn buckets(&self) -> usize {
        self.w * self.h
    }

    /// The first bucket of each row.
    #[inline]
    pub(crate) fn rows(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.h).map(|y| self.first + y * self.stride)
    }

    /// Calls `f` on each bucket, row by row.
    #[inline]
    pub(crate) fn for_each(&self, mut f: impl FnMut(usize)) {
        for r in self.rows() {
            for b in r..r + self.w {
                f(b);
            }
        }
    }
}

/// The buckets of a share of `n` points at `per` points per bucket: at most this many (each
/// face has at most `max(1, n_f / per)`), plus one for `start`'s end.
pub(crate) fn bucket_cap(n: usize, per: usize) -> usize {
    n / per.max(1) + 6 + 1
}

/// What a light-space task returns: its counters and the rays left to the recursion
/// (global indices).
#[derive(Default)]
pub(super) struct LightOut {
    pub(super) counts: Counts,
    pub(super) peak: u64,
    pub(super) misfits: Vec<u32>,
}

impl std::ops::Add for LightOut {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self.counts += o.counts;
        self.peak = self.peak.max(o.peak);
        self.misfits.extend(o.misfits);
        self
    }
}

impl Dacrt {
    /// The light-space pass over rays `range` of a batch ending at `light` (occlusion into
    /// `occ`, task-local); returns the rays it left to the recursion.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn light_task(
        &self,
        tris: &TriangleSoup,
        rays: &RayBatch,
        range: Range<usize>,
        chunk: usize,
        light: Vec3,
        occ: &mut [bool],
        mut cost: Option<CostMut<'_>>,
    ) -> LightOut {
        let n = range.len();
        let per = self.cfg.light_bucket.max(1);
        let huge = self.cfg.huge_pages;
        let slot = self.pool.get(range.start / chunk.max(1));
        let mut sc = slot
            .and_then(|m| m.lock().ok().map(|mut g| std::mem::take(&mut g.light)))
            .unwrap_or_default();
        let mut out = LightOut::default();
        let mut st = Counts::default();
        let c_setup = clock(self.cfg.phase_times);
        // Which rays fit, the largest slack and the scale of the boxes' pad; each fitting
        // segment's face, coordinates (f32: the footprints' pad covers their rounding, and
        // the buckets are taken from these same values) and depth (raised to f32); the faces'
        // bounds and counts.
        let mut slack = 0.0f64;
        let mut scale = self.scale as f64;
        let mut key = reuse(std::mem::take(&mut sc.key), n, huge);
        let mut points = FacePoints::default();
        for i in range.clone() {
            let (o, d) = (rays.origin(i), rays.dir(i));
            let fit = segment_slack(light, o, d, rays.tmin[i], rays.tmax[i])
                .and_then(|e| Some((e, segment_view(light, o, d, rays.tmax[i])?)));
            key.push(match fit {
                Some((e, s)) => {
                    slack = slack.max(e);
                    scale = scale.max(o.abs().max_element() as f64);
                    let (a, b) = (s.a as f32, s.b as f32);
                    points.add(s.face, a, b);
                    Key {
                        a,
                        b,
                        depth: next_up(s.depth as f32, s.depth),
                        face: s.face as u32,
                    }
                }
                None => Key::MISFIT,
            });
        }
        // The grids: about `per` segments per bucket, shaped like the face's segments; the
        // frame: a ball around the light large enough that the footprints' pad is a tenth of
        // the narrowest bucket or less (within `geom::light_space`'s range).
        let faces = Faces::fit(&points, per);
        let nb = faces.buckets();
        let narrow = faces.narrowest();
        let Some(view) = LightView::new(light, slack, scale, 0.1 * narrow) else {
            out.misfits.extend(range.map(|i| i as u32));
            return self.light_done(slot, sc, key, out);
        };
        // The counting sort into buckets (`face` becomes the bucket).
        let cap = bucket_cap(n, per);
        let mut start = reuse(std::mem::take(&mut sc.start), cap, huge);
        let mut live = reuse(std::mem::take(&mut sc.live), cap, huge);
        let mut depth = reuse(std::mem::take(&mut sc.depth), cap, huge);
        start.resize(nb + 1, 0);
        depth.resize(nb, f32::NEG_INFINITY);
        let mut pts = reuse(std::mem::take(&mut sc.pts), n, huge);
        let mut segs = reuse(std::mem::take(&mut sc.segs), n, huge);
        for (j, i) in range.clone().enumerate() {
            let k = &mut key[j];
            if k.face == MISFIT {
                out.misfits.push(i as u32);
                continue;
            }
            let b = faces.bucket(k.face as usize, k.a, k.b);
            k.face = b as u32;
            start[b + 1] += 1;
            depth[b] = depth[b].max(k.depth);
        }
        for b in 0..nb {
            start[b + 1] += start[b];
        }
        live.extend_from_slice(&start[..nb]);
        pts.resize(start[nb] as usize, LightPoint::default());
        segs.resize(start[nb] as usize, LightSeg::default());
        for (j, i) in range.clone().enumerate() {
            let k = key[j];
            if k.face == MISFIT {
                continue;
            }
            let at = live[k.face as usize] as usize;
            live[k.face as usize] += 1;
            pts[at] = LightPoint {
                a: k.a,
                b: k.b,
                depth: k.depth,
                ray: j as u32,
            };
            segs[at] = LightSeg {
                o: rays.origin(i).to_array(),
                tmin: rays.tmin[i],
                d: rays.dir(i).to_array(),
                tmax: rays.tmax[i],
            };
        }
        st.ns_setup += ns_since(c_setup);
        let c_pass = clock(self.cfg.phase_times);
        st.light_rays += pts.len() as u64;
        // The triangles, once.
        let span = &self.span;
        let mut pass = Pass {
            tris,
            pts: &mut pts,
            segs: &mut segs,
            start: &start,
            live: &mut live,
            depth: &depth,
            occ,
            cost: cost.as_mut(),
            st: &mut st,
        };
        for t in 0..tris.len() {
            let lo = Vec3::new(span[0][t][0], span[1][t][0], span[2][t][0]);
            let hi = Vec3::new(span[0][t][1], span[1][t][1], span[2][t][1]);
            // Degenerate (an empty span): never hit.
            if !(lo.x <= hi.x) {
                continue;
            }
            if view.near(lo, hi) {
                pass.st.light_near += 1;
                pass.everywhere(t, nb);
                continue;
            }
            let (fps, nbk) = faces.cover(&view, lo, hi, |b, fp| pass.bucket(t, b, fp));
            pass.st.tri_box += fps;
            pass.st.light_buckets += nbk;
        }
        st.ns_leaves += ns_since(c_pass);
        out.counts = st;
        sc.pts = pts;
        sc.segs = segs;
        sc.start = start;
        sc.live = live;
        sc.depth = depth;
        self.light_done(slot, sc, key, out)
    }

    /// Puts a task's buffers back into its pool slot.
    fn light_done(
        &self,
        slot: Option<&std::sync::Mutex<super::Scratch>>,
        mut sc: LightScratch,
        mut key: Vec<Key>,
        mut out: LightOut,
    ) -> LightOut {
        key.clear();
        sc.key = key;
        out.peak = sc.bytes() as u64;
        if let Some(m) = slot {
            if let Ok(mut g) = m.lock() {
                g.light = sc;
            }
        }
        out
    }
}

/// `v` (the f32 rounding of `exact`) raised to a bound of `exact`.
#[inline]
pub(crate) fn next_up(v: f32, exact: f64) -> f32 {
    if (v as f64) >= exact {
        v
    } else {
        v.next_up()
    }
}

/// The triangle pass's state.
struct Pass<'p, 'c> {
    tris: &'p TriangleSoup,
    pts: &'p mut [LightPoint],
    segs: &'p mut [LightSeg],
    start: &'p [u32],
    live: &'p mut [u32],
    depth: &'p [f32],
    occ: &'p mut [bool],
    cost: Option<&'p mut CostMut<'c>>,
    st: &'p mut Counts,
}

impl Pass<'_, '_> {
    /// Triangle `t` against the live segments of bucket `b` that its footprint `fp` holds.
    #[inline]
    fn bucket(&mut self, t: usize, b: usize, fp: &crate::geom::Footprint) {
        if (self.depth[b] as f64) < fp.x0 {
            return;
        }
        let mut q = self.start[b] as usize;
        let mut end = self.live[b] as usize;
        let mut tri = None;
        while q < end {
            let p = self.pts[q];
            self.st.ray_box += 1;
            if p.outside(fp) {
                if let Some(c) = self.cost.as_deref_mut() {
                    c.add(p.ray as usize, 0, 1, 0);
                }
                q += 1;
                continue;
            }
            let v = *tri.get_or_insert_with(|| self.tris.get(t));
            q = self.step(q, &mut end, v);
        }
        self.live[b] = end as u32;
    }

    /// Triangle `t` (near the light) against every live segment.
    fn everywhere(&mut self, t: usize, nb: usize) {
        let v = self.tris.get(t);
        for b in 0..nb {
            let mut q = self.start[b] as usize;
            let mut end = self.live[b] as usize;
            while q < end {
                q = self.step(q, &mut end, v);
            }
            self.live[b] = end as u32;
        }
    }

    /// Tests the segment in slot `q` of a bucket whose live slots end at `end` against
    /// triangle `v`: an occluded one is swapped out of the live range. Returns the next slot.
    #[inline(always)]
    fn step(&mut self, q: usize, end: &mut usize, v: [Vec3; 3]) -> usize {
        if self.test(q, self.pts[q].ray, v[0], v[1], v[2]) {
            *end -= 1;
            self.pts.swap(q, *end);
            self.segs.swap(q, *end);
            q
        } else {
            q + 1
        }
    }

    /// The shared test of the segment in slot `q` (ray `ray`) and a triangle; records an
    /// occlusion.
    #[inline(always)]
    fn test(&mut self, q: usize, ray: u32, v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
        self.st.ray_tri += 1;
        if let Some(c) = self.cost.as_deref_mut() {
            c.add(ray as usize, 0, 1, 1);
        }
        let p = &self.segs[q];
        let hit = intersect_triangle(
            Vec3::from_array(p.o),
            Vec3::from_array(p.d),
            v0,
            v1,
            v2,
            p.tmin,
            p.tmax,
        )
        .is_some();
        if hit {
            self.occ[ray as usize] = true;
        }
        hit
    }
}
