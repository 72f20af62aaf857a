//! Ours: screen-space and pixel culling for camera batches. The check that a task's rays come
//! from the eye through their own pixels, a cell's pixel rectangle, and the one pass that
//! projects every triangle onto the task's pixels (four or eight lanes), dropping those that
//! cover no pixel centre and keeping the rectangles for tile leaves.

use super::packets::Packets;
use super::Task;
use crate::geom::lanes::{self, F32x8, Lanes, Width};
use crate::geom::{Aabb, PixelProjection};
use crate::rays::RayBatch;
use glam::{BVec4A, Vec3, Vec4};

/// Screen-space culling needs camera rays within this many pixels of their pixel (the
/// projection fitted to the corner rays): exact pinhole rays are within 1e-3, rays jittered
/// inside their pixels within about 1; farther, the rectangles would be loose.
pub(super) const MAX_PIXEL_DEVIATION: f64 = 2.0;

/// The deviation exact pinhole rays are checked against when they are not measured (they
/// are within a few thousandths of a pixel).
pub(super) const PINHOLE_TOL: f64 = 1.0 / 256.0;

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
        cull: bool,
    ) -> (usize, f64) {
        self.project_lanes::<F32x8>(proj, tol, xs, ys, cull)
    }

    /// [`Self::project_triangles`]' pass over the triangles, `L::N` at a time: pushes the kept
    /// triangles to `tri_idx` and (tile leaves) every triangle's rectangle to `rects`; returns
    /// the non-degenerate count and the kept rectangles' total area.
    #[inline(always)]
    fn project_lanes<L: Lanes>(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
        cull: bool,
    ) -> (usize, f64) {
        let tris = self.tris;
        let n = tris.len();
        let idx = &mut self.tri_idx;
        let rects = &mut self.rects;
        let tile_leaves = self.tile_leaves;
        let mut area = 0.0f64;
        let mut live_count = 0;
        let row0 = ys[0] as f32;
        let lane = L::from_fn(|l| l as f32);
        // `L::N` at a time (a short last group repeats its last triangle).
        for t0 in (0..n).step_by(L::N) {
            let m = (n - t0).min(L::N);
            let at = |l: usize| (t0 + l).min(n - 1);
            let lanes = |c: &[Vec3]| {
                [
                    L::from_fn(|l| c[at(l)].x),
                    L::from_fn(|l| c[at(l)].y),
                    L::from_fn(|l| c[at(l)].z),
                ]
            };
            let v = [lanes(&tris.v0), lanes(&tris.v1), lanes(&tris.v2)];
            // Degenerate (one point, as in `prepare`): never hit.
            let same = |a: usize| v[0][a].cmpeq(v[1][a]) & v[1][a].cmpeq(v[2][a]);
            let live = !(same(0) & same(1) & same(2)) & lane.cmple(L::splat((m - 1) as f32));
            let live = L::bitmask(live);
            live_count += live.count_ones() as usize;
            let r = proj.triangle_rects_wide::<L>(v, tol, xs, ys);
            let kept = r.nonempty() & live;
            // Lane by lane: a vector transpose and select here made the AVX2 loop slower
            // (BENCHMARKS.md, § Fig. 14, "Tried and not kept").
            for l in 0..m {
                let q = r.lane(l);
                if kept >> l & 1 != 0 {
                    // Exact small integers: the pixel ranges are below 2^16.
                    area += (q[1] - q[0] + 1.0) as f64 * (q[3] - q[2] + 1.0) as f64;
                }
                if tile_leaves {
                    // Task-local rows; the ranges fit in u16 (tile leaves need both image
                    // dimensions at most 2^16). Pushed in triangle order (`rects[t]`), no zero
                    // fill first.
                    rects.push(if kept >> l & 1 != 0 {
                        [q[0], q[1], q[2] - row0, q[3] - row0].map(|v| v as u16)
                    } else {
                        [1, 0, 1, 0]
                    });
                }
            }
            let mut keep = if cull { kept } else { live };
            while keep != 0 {
                idx.push(t0 as u32 + keep.trailing_zeros());
                keep &= keep - 1;
            }
        }
        (live_count, area)
    }

    /// [`Self::live_triangles`] for a task with a projection: fills `tri_idx` with the
    /// non-degenerate triangles, projected onto the task's pixels (rows `ys`) on the way,
    /// scene order: with `cull` (`Config::pixel_cull`), only the triangles some pixel's ray of
    /// the task can hit; with pixel leaves, each one's rectangle goes to `rects`. Returns the
    /// count. One pass over the vertices in order (a list pass, then reads through the list,
    /// measured slower: BENCHMARKS.md, § DACRT design measurements).
    pub(super) fn project_triangles(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        ys: [i64; 2],
        cull: bool,
    ) -> usize {
        let Packets::Tiles { width, .. } = self.packets else {
            return self.live_triangles();
        };
        let xs = [0, width as i64 - 1];
        self.tri_idx.clear();
        #[cfg(target_arch = "x86_64")]
        let (live_count, area) = match lanes::width() {
            // SAFETY: `project_avx2` needs AVX2; `width()` is `Eight` only on CPUs that have it.
            Width::Eight => unsafe { self.project_avx2(proj, tol, xs, ys, cull) },
            Width::Four => self.project_lanes::<Vec4>(proj, tol, xs, ys, cull),
        };
        #[cfg(not(target_arch = "x86_64"))]
        let (live_count, area) = self.project_lanes::<Vec4>(proj, tol, xs, ys, cull);
        let idx = &self.tri_idx;
        let k = idx.len();
        self.st.tri_box += live_count as u64;
        // Leaves of tiny triangles cost about one pair per pixel they cover, so they can be
        // larger than those of triangles covering many pixels (where a leaf tests each one
        // against every live pixel of its rectangle, occluded or not): `pixel_leaf_c_limit`
        // tiles for rectangles of 16 pixels or more on average, up to 16× that for one pixel
        // (large leaves gain on tiny triangles and lose on large ones: measured in
        // BENCHMARKS.md, § DACRT design measurements).
        let mean = area / (k.max(1) as f64);
        let scale = (16.0 / mean.max(1.0)).clamp(1.0, 16.0);
        self.leaf_tiles = (self.cfg.pixel_leaf_c_limit as f64 * scale) as usize;
        k
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
