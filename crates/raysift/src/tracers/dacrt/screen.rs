//! Ours: screen-space and pixel culling for camera batches. The check that a band's rays come
//! from the eye through their own pixels, a cell's pixel rectangle, and the passes that
//! project every triangle (four or eight lanes): for tile leaves, once per call onto the
//! whole image, shared by the tasks, with the estimate that cuts their bands
//! (`project_all`, `balanced_bands`, then each task's `band_triangles`); without them, each
//! task onto its own pixels, dropping the triangles that cover no pixel centre.

use super::packets::Packets;
use super::Task;
use crate::geom::lanes::{self, F32x8, Lanes, Width};
use crate::geom::{Aabb, PixelProjection};
use crate::rays::RayBatch;
use crate::scene::TriangleSoup;
use glam::{BVec4A, Vec3, Vec4};
use rayon::prelude::*;

/// Screen-space culling needs camera rays within this many pixels of their pixel (the
/// projection fitted to the corner rays): exact pinhole rays are within 1e-3, rays jittered
/// inside their pixels within about 1; farther, the rectangles would be loose.
pub(super) const MAX_PIXEL_DEVIATION: f64 = 2.0;

/// The deviation exact pinhole rays are checked against when they are not measured (they
/// are within a few thousandths of a pixel).
pub(super) const PINHOLE_TOL: f64 = 1.0 / 256.0;

/// Rectangles of empty pixel ranges: triangles no ray of the image can hit (degenerate, or
/// covering no pixel centre).
pub(super) const NO_RECT: [u16; 4] = [1, 0, 1, 0];

/// Triangles `t0..` in `L::N` lanes (a short last group repeats its last triangle), with the
/// mask of the lanes that are real, non-degenerate triangles (one point, as in `prepare`:
/// never hit). Shared by the task's culling pass and the call's shared projection.
#[inline(always)]
fn triangle_lanes<L: Lanes>(tris: &TriangleSoup, t0: usize, end: usize) -> ([[L; 3]; 3], u32) {
    let m = (end - t0).min(L::N);
    let at = |l: usize| (t0 + l).min(end - 1);
    let lanes = |c: &[Vec3]| {
        [
            L::from_fn(|l| c[at(l)].x),
            L::from_fn(|l| c[at(l)].y),
            L::from_fn(|l| c[at(l)].z),
        ]
    };
    let v = [lanes(&tris.v0), lanes(&tris.v1), lanes(&tris.v2)];
    let same = |a: usize| v[0][a].cmpeq(v[1][a]) & v[1][a].cmpeq(v[2][a]);
    let lane = L::from_fn(|l| l as f32);
    let live = !(same(0) & same(1) & same(2)) & lane.cmple(L::splat((m - 1) as f32));
    (v, L::bitmask(live))
}

/// The shared projection's pass over triangles `t0..t0 + out.len()`, `L::N` at a time: each
/// one's rectangle on the image (`xs`, `ys`: its pixel ranges) to `out`, [`NO_RECT`] for those
/// no ray can hit. Returns the non-degenerate count.
#[inline(always)]
fn rects_lanes<L: Lanes>(
    tris: &TriangleSoup,
    t0: usize,
    out: &mut [[u16; 4]],
    proj: &PixelProjection,
    tol: f64,
    xs: [i64; 2],
    ys: [i64; 2],
) -> u64 {
    let end = t0 + out.len();
    let mut live_count = 0;
    for (g, out) in out.chunks_mut(L::N).enumerate() {
        let (v, live) = triangle_lanes::<L>(tris, t0 + g * L::N, end);
        live_count += live.count_ones() as u64;
        let r = proj.triangle_rects_wide::<L>(v, tol, xs, ys);
        let kept = r.nonempty() & live;
        for (l, o) in out.iter_mut().enumerate() {
            // Exact small integers: the pixel ranges are below 2^16.
            *o = if kept >> l & 1 != 0 {
                r.lane(l).map(|v| v as u16)
            } else {
                NO_RECT
            };
        }
    }
    live_count
}

/// [`rects_lanes`] eight triangles at a time, compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2 ([`lanes::width`] is [`Width::Eight`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn rects_avx2(
    tris: &TriangleSoup,
    t0: usize,
    out: &mut [[u16; 4]],
    proj: &PixelProjection,
    tol: f64,
    xs: [i64; 2],
    ys: [i64; 2],
) -> u64 {
    rects_lanes::<F32x8>(tris, t0, out, proj, tol, xs, ys)
}

/// Triangles per chunk of the shared projection (each chunk one rayon job).
const RECT_CHUNK: usize = 1 << 14;

/// Row buckets of [`Cover`]: one per image row up to this height, 2, 4, … rows above it.
const COVER_BUCKETS: usize = 1024;

/// How many rectangle pixels cover each image row (rows grouped in at most
/// [`COVER_BUCKETS`] buckets), as a difference array: the estimate of each row's work that
/// [`balanced_bands`] divides. Integer sums, so the same whatever the chunking.
#[derive(Clone, Copy)]
pub(super) struct Cover {
    /// Rows `y` go to bucket `y >> shift`.
    shift: u32,
    d: [i64; COVER_BUCKETS + 1],
}

impl Cover {
    pub(super) fn new(height: usize) -> Self {
        let mut shift = 0;
        while (height.max(1) - 1) >> shift >= COVER_BUCKETS {
            shift += 1;
        }
        Self {
            shift,
            d: [0; COVER_BUCKETS + 1],
        }
    }

    /// The bucket of image row `y` (a shift, not a division: it runs twice per triangle).
    #[inline(always)]
    fn bucket(&self, y: usize) -> usize {
        y >> self.shift
    }

    /// Adds the rectangles of `rects` (inclusive, image rows).
    pub(super) fn add(&mut self, rects: &[[u16; 4]]) {
        for r in rects {
            if r[0] <= r[1] {
                let w = (r[1] - r[0] + 1) as i64;
                self.d[self.bucket(r[2] as usize)] += w;
                self.d[self.bucket(r[3] as usize) + 1] -= w;
            }
        }
    }
}

impl std::ops::Add for Cover {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        for (a, b) in self.d.iter_mut().zip(o.d) {
            *a += b;
        }
        self
    }
}

/// The shared projection (issue #21 item 3): every triangle's inclusive pixel rectangle
/// `[x0, x1, y0, y1]` on the whole `width`×`height` image (image rows) in `rects[t]`, in
/// parallel chunks of triangles, so that the tasks (bands of tile rows) need not each project
/// every triangle; [`NO_RECT`] for triangles no ray can hit. Returns the non-degenerate
/// count and, `with_cover` (for more than one band), the rectangles' [`Cover`] (each chunk's
/// counted while its rectangles are in cache: 2.7 ms of a one-thread 871K-dragon frame,
/// not paid when there is nothing to balance). Same results whatever the chunking (each
/// rectangle is one triangle's).
pub(super) fn project_all(
    tris: &TriangleSoup,
    rects: &mut [[u16; 4]],
    proj: &PixelProjection,
    tol: f64,
    width: usize,
    height: usize,
    with_cover: bool,
) -> (u64, Cover) {
    let (xs, ys) = ([0, width as i64 - 1], [0, height as i64 - 1]);
    let chunk = |(c, out): (usize, &mut [[u16; 4]])| -> (u64, Cover) {
        let t0 = c * RECT_CHUNK;
        #[cfg(target_arch = "x86_64")]
        let live = if lanes::width() == Width::Eight {
            // SAFETY: `rects_avx2` needs AVX2; `width()` is `Eight` only on CPUs that have it.
            unsafe { rects_avx2(tris, t0, out, proj, tol, xs, ys) }
        } else {
            rects_lanes::<Vec4>(tris, t0, out, proj, tol, xs, ys)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let live = rects_lanes::<Vec4>(tris, t0, out, proj, tol, xs, ys);
        let mut cover = Cover::new(height);
        if with_cover {
            cover.add(out);
        }
        (live, cover)
    };
    let zero = || (0, Cover::new(height));
    let sum = |a: (u64, Cover), b: (u64, Cover)| (a.0 + b.0, a.1 + b.1);
    if rects.len() >= 4 * RECT_CHUNK {
        (rects.par_chunks_mut(RECT_CHUNK).enumerate())
            .map(chunk)
            .reduce(zero, sum)
    } else {
        (rects.chunks_mut(RECT_CHUNK).enumerate())
            .map(chunk)
            .fold(zero(), sum)
    }
}

/// Rays of a row weigh this much against one pixel of a triangle's rectangle in
/// [`balanced_bands`]' estimate of a band's work.
const RAY_WEIGHT: i64 = 1;

/// Bands of whole tile rows for `k` tasks with about equal work (issue #21 item 3: bands of
/// equal height left one of two threads idle for a third of a dragon frame), estimated per
/// image row from its rays (times [`RAY_WEIGHT`]) and the rectangle pixels that cover it
/// (`cover`, from the shared projection). Writes the bounds in rays, from 0 to the image's,
/// strictly increasing, to `bounds` (at most `k + 1`; it keeps its capacity). The same for any
/// thread count.
pub(super) fn balanced_bands(
    cover: &Cover,
    width: usize,
    height: usize,
    k: usize,
    bounds: &mut Vec<usize>,
) {
    bounds.clear();
    bounds.push(0);
    // Each row's estimate: its bucket's running cover.
    let mut row = [0i64; COVER_BUCKETS];
    let mut run = 0;
    for (b, d) in cover.d[..COVER_BUCKETS].iter().enumerate() {
        run += d;
        row[b] = run + RAY_WEIGHT * width as i64;
    }
    let total: i128 = (0..height).map(|y| row[cover.bucket(y)] as i128).sum();
    let mut acc = 0i128;
    for y in 0..height {
        acc += row[cover.bucket(y)] as i128;
        let (b, end) = (bounds.len(), y + 1);
        if b < k && end % 8 == 0 && end < height && acc * k as i128 >= total * b as i128 {
            bounds.push(end * width);
        }
    }
    bounds.push(height * width);
}

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// [`Self::project_lanes`] eight triangles at a time, compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2 ([`lanes::width`] is [`Width::Eight`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn project_avx2(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
    ) -> usize {
        self.project_lanes::<F32x8>(proj, tol, xs, ys)
    }

    /// [`Self::project_triangles`]' pass over the triangles, `L::N` at a time: pushes the kept
    /// triangles to `tri_idx`; returns the non-degenerate count.
    #[inline(always)]
    fn project_lanes<L: Lanes>(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
    ) -> usize {
        let tris = self.tris;
        let n = tris.len();
        let idx = &mut self.tri_idx;
        let mut live_count = 0;
        for t0 in (0..n).step_by(L::N) {
            let (v, live) = triangle_lanes::<L>(tris, t0, n);
            live_count += live.count_ones() as usize;
            let mut keep = proj.triangle_rects_wide::<L>(v, tol, xs, ys).nonempty() & live;
            while keep != 0 {
                idx.push(t0 as u32 + keep.trailing_zeros());
                keep &= keep - 1;
            }
        }
        live_count
    }

    /// Pixel culling without tile leaves (`Config::pixel_cull`): fills `tri_idx` with the
    /// triangles some pixel's ray of the task (rows `ys`) can hit, scene order, projecting
    /// each one onto the task's pixels. Returns the count. One pass over the vertices in order
    /// (a list pass, then reads through the list, measured slower: BENCHMARKS.md, § DACRT
    /// design measurements).
    pub(super) fn project_triangles(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        ys: [i64; 2],
    ) -> usize {
        let Packets::Tiles { width, .. } = self.packets else {
            return self.live_triangles();
        };
        let xs = [0, width as i64 - 1];
        self.tri_idx.clear();
        #[cfg(target_arch = "x86_64")]
        let live_count = match lanes::width() {
            // SAFETY: `project_avx2` needs AVX2; `width()` is `Eight` only on CPUs that have it.
            Width::Eight => unsafe { self.project_avx2(proj, tol, xs, ys) },
            Width::Four => self.project_lanes::<Vec4>(proj, tol, xs, ys),
        };
        #[cfg(not(target_arch = "x86_64"))]
        let live_count = self.project_lanes::<Vec4>(proj, tol, xs, ys);
        self.st.tri_box += live_count as u64;
        self.tri_idx.len()
    }

    /// Tile leaves: fills `tri_idx` from the shared projection's rectangles (`self.rects`) with
    /// the triangles whose rectangle meets the task's rows `ys` (image rows), scene order;
    /// without `cull`, with every non-degenerate triangle. Sets the leaf size from their
    /// rectangles' mean area. Returns the count.
    pub(super) fn band_triangles(&mut self, ys: [i64; 2], cull: bool) -> usize {
        let (y0, y1) = (ys[0] as u16, ys[1] as u16);
        let rects = self.rects;
        let mut area = 0u64;
        // The rectangle's pixels in the band (0 when it has none), without a branch.
        let band_area = |r: &[u16; 4]| {
            let (a, b) = (r[2].max(y0) as i64, r[3].min(y1) as i64);
            let (w, h) = (r[1] as i64 - r[0] as i64 + 1, b - a + 1);
            (w.max(0) * h.max(0)) as u64
        };
        if cull {
            // Branch-free: every id is written at the end of the list, which grows only when
            // its triangle is kept.
            self.tri_idx.clear();
            let spare = self.tri_idx.spare_capacity_mut();
            assert!(spare.len() >= rects.len(), "tri_idx holds every triangle");
            let mut k = 0;
            for (t, r) in rects.iter().enumerate() {
                let a = band_area(r);
                spare[k].write(t as u32);
                area += a;
                k += (a > 0) as usize;
            }
            // SAFETY: entries `0..k` were written: `k` grows by one only after entry `k` was
            // written, and never past `spare.len()` (at most one per rectangle, asserted).
            unsafe { self.tri_idx.set_len(k) };
        } else {
            self.live_triangles();
            area = self
                .tri_idx
                .iter()
                .map(|&t| band_area(&rects[t as usize]))
                .sum();
        }
        let kept = self.tri_idx.len();
        // Leaves of tiny triangles cost about one pair per pixel they cover, so they can be
        // larger than those of triangles covering many pixels (where a leaf tests each one
        // against every live pixel of its rectangle, occluded or not): `pixel_leaf_c_limit`
        // tiles for rectangles of 16 pixels or more on average, up to 16× that for one pixel
        // (large leaves gain on tiny triangles and lose on large ones: measured in
        // BENCHMARKS.md, § DACRT design measurements).
        let mean = area as f64 / (kept.max(1) as f64);
        let scale = (16.0 / mean.max(1.0)).clamp(1.0, 16.0);
        self.leaf_tiles = (self.cfg.pixel_leaf_c_limit as f64 * scale) as usize;
        self.tri_idx.len()
    }

    /// The task's pixels (task-local rows) whose rays can meet `b`, when screen-space culling
    /// is on and `b` lies in front of the eye: inclusive `[x0, x1, y0, y1]`.
    #[inline]
    pub(super) fn pixels(&self, b: &Aabb) -> Option<[i64; 4]> {
        let [x0, x1, y0, y1] = self.proj?.box_pixels(b, self.tol)?;
        Some([x0, x1, y0 - self.row0, y1 - self.row0])
    }
}

/// The largest deviation of the rays of a pinhole band (first row: image row `base / width`)
/// from their pixels, an upper bound ([`PixelProjection::deviation4`], f32, four rays at a
/// time), when every ray starts at `eye` with the first ray's `tmin` (at least 0) and the bound
/// is at most [`MAX_PIXEL_DEVIATION`]; `None` otherwise. Read-only, so a batch that fails
/// allocates nothing for tile leaves. Memory-bound, and as fast as the exact f64 check of a
/// fixed tolerance it replaces (measured in BENCHMARKS.md, § DACRT design measurements), but it
/// measures the bound, so jittered rays need no second, per-ray f64 pass.
pub(super) fn pinhole_deviation(
    rays: &RayBatch,
    base: usize,
    width: usize,
    rows: usize,
    proj: &PixelProjection,
    eye: Vec3,
) -> Option<f64> {
    let tmin0 = rays.tmin[base];
    // NaN-safe: a NaN `tmin` fails too.
    if tmin0.is_nan() || tmin0 < 0.0 {
        return None;
    }
    let row0 = base / width;
    let (ex, ey, ez, et) = (
        Vec4::splat(eye.x),
        Vec4::splat(eye.y),
        Vec4::splat(eye.z),
        Vec4::splat(tmin0),
    );
    let mut dev = Vec4::ZERO;
    for y in 0..rows {
        for x in (0..width).step_by(4) {
            // A short last group repeats the row's last ray (a bound for another pixel: only
            // the valid lanes count).
            let valid = (width - x).min(4);
            let i = base + y * width + x;
            let load = |a: &[f32]| -> Vec4 {
                if valid == 4 {
                    Vec4::from_slice(&a[i..i + 4])
                } else {
                    Vec4::from_array(std::array::from_fn(|l| a[i + l.min(valid - 1)]))
                }
            };
            let d = [&rays.dx, &rays.dy, &rays.dz].map(|a| load(a));
            let from_eye = load(&rays.ox).cmpeq(ex)
                & load(&rays.oy).cmpeq(ey)
                & load(&rays.oz).cmpeq(ez)
                & load(&rays.tmin).cmpeq(et);
            let e = proj.deviation4(d, x as u32, (row0 + y) as u32);
            // NaN-safe: a NaN bound fails the comparison.
            let ok = from_eye & e.cmple(Vec4::splat(MAX_PIXEL_DEVIATION as f32));
            let want = (1 << valid) - 1;
            if ok.bitmask() & want != want {
                return None;
            }
            let lanes = BVec4A::from_array(std::array::from_fn(|l| l < valid));
            dev = dev.max(Vec4::select(lanes, e, Vec4::ZERO));
        }
    }
    Some(dev.max_element() as f64)
}
