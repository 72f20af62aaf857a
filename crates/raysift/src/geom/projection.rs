//! Pinhole projection of boxes to pixel rectangles: screen-space culling for DACRT's camera
//! packets (an alternative to the cone bound of Mora 2011 §3.3, in the spirit of the frustum
//! culling of Hoedt's 5D DACRT; BENCHMARKS.md compares them).
//!
//! The rays of a pinhole image are, up to rounding, `d(i, j) ∝ G·(i, j, 1)` for a 3×3 matrix `G`
//! (pixel indices to directions). [`PixelProjection::fit`] recovers `H = G⁻¹` from the four
//! corner rays (the 4-point projective basis), and [`PixelProjection::deviation`] measures, for
//! each ray, how far `H` maps its direction from its own pixel: the batch's own directions are
//! the ground truth, the model is only trusted as far as it was measured (a few thousandths of
//! a pixel for exact pinhole rays, up to about a pixel for rays jittered inside their pixels).
//!
//! Why a box's rectangle is conservative: a ray of pixel `(i, j)` that meets box `B` does so at
//! `p = eye + t·d`, `t > 0`; `H·(p − eye) = t·H·d`, so `p` projects to `d`'s pixel, within the
//! measured deviation `tol` of `(i, j)`. When every corner of `B` projects with a positive
//! depth (`(H·w).z > 0`, linear in `w`, so positive on the whole box), the projective map is
//! defined on `B` and keeps convexity: `B` projects into the hull of its projected corners,
//! inside their bounding rectangle. Boxes reaching behind the eye have no rectangle (`None`):
//! callers fall back to an exact test. The same argument for a triangle (the hull of its three
//! projected corners) gives [`PixelProjection::triangle_may_cover`]: a triangle whose
//! projection, padded, holds no pixel centre is hit by no ray of the image.

use super::lanes::Lanes;
use super::Aabb;
use glam::{DMat3, DVec2, DVec3, Mat3A, Vec3, Vec3A, Vec4};

/// World directions to pixel coordinates of one pinhole image (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelProjection {
    eye: DVec3,
    /// Direction `w` → homogeneous pixel `(x·z, y·z, z)`, `z > 0` in front.
    h: DMat3,
    /// f32 copies for the per-triangle test (`eye` is an f32 point to begin with), and the
    /// rows' 1-norms of `h`, rounded up, for its rounding bound.
    eye32: Vec3A,
    h32: Mat3A,
    rows1: Vec3A,
    /// `|h32|` entry-wise, for [`Self::deviation4`]'s rounding bound.
    h32_abs: Mat3A,
}

impl PixelProjection {
    /// The projection whose pixels `(0, 0)`, `(w−1, 0)`, `(0, h−1)` and `(w−1, h−1)` have the
    /// directions `corners` (in that order), or `None` when they do not determine one (an image
    /// less than 2 pixels wide or high, parallel or non-finite corner rays).
    pub fn fit(eye: Vec3, width: u32, height: u32, corners: [Vec3; 4]) -> Option<Self> {
        if width < 2 || height < 2 || !eye.is_finite() {
            return None;
        }
        let (x1, y1) = ((width - 1) as f64, (height - 1) as f64);
        let p = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(x1, 0.0, 1.0),
            DVec3::new(0.0, y1, 1.0),
            DVec3::new(x1, y1, 1.0),
        ];
        let d = corners.map(|c| c.as_dvec3());
        // The matrix sending the basis vectors to multiples of q[0..3] and (1, 1, 1) to q[3].
        let basis = |q: [DVec3; 4]| -> Option<DMat3> {
            let m = DMat3::from_cols(q[0], q[1], q[2]);
            let det = m.determinant();
            if !det.is_finite() || det.abs() < 1e-300 {
                return None;
            }
            let s = m.inverse() * q[3];
            Some(DMat3::from_cols(q[0] * s.x, q[1] * s.y, q[2] * s.z))
        };
        let a = basis(p)?;
        let b = basis(d)?;
        let det = b.determinant();
        if !det.is_finite() || det.abs() < 1e-300 {
            return None;
        }
        // G = B·A⁻¹ (pixels to directions), H = G⁻¹ = A·B⁻¹.
        let mut h = a * b.inverse();
        if (h * d[0]).z < 0.0 {
            h = -h;
        }
        let rows1 = DVec3::new(
            h.row(0).abs().element_sum(),
            h.row(1).abs().element_sum(),
            h.row(2).abs().element_sum(),
        ) * (1.0 + 1e-6);
        let h32 = Mat3A::from_cols(
            h.x_axis.as_vec3().into(),
            h.y_axis.as_vec3().into(),
            h.z_axis.as_vec3().into(),
        );
        let pp = Self {
            eye: eye.as_dvec3(),
            h,
            eye32: eye.into(),
            h32,
            rows1: rows1.as_vec3().into(),
            h32_abs: Mat3A::from_cols(h32.x_axis.abs(), h32.y_axis.abs(), h32.z_axis.abs()),
        };
        h.is_finite().then_some(pp)
    }

    /// The pixel coordinates of direction `w`, `None` behind the eye (or on its plane).
    #[inline]
    pub fn pixel(&self, w: DVec3) -> Option<DVec2> {
        let u = self.h * w;
        (u.z > 0.0).then(|| DVec2::new(u.x / u.z, u.y / u.z))
    }

    /// How far (in pixels, per coordinate) direction `d` projects from pixel `(i, j)`; +inf
    /// behind the eye, NaN for a NaN direction.
    #[inline]
    pub fn deviation(&self, d: Vec3, i: usize, j: usize) -> f64 {
        match self.pixel(d.as_dvec3()) {
            Some(q) => (q.x - i as f64).abs().max((q.y - j as f64).abs()),
            None => f64::INFINITY,
        }
    }

    /// Whether direction `d` projects within `tol` of pixel `(i, j)` ([`Self::deviation`]
    /// `≤ tol` up to f64 rounding, which [`Self::box_pixels`] pads for), without divisions.
    #[inline]
    pub fn within(&self, d: Vec3, i: usize, j: usize, tol: f64) -> bool {
        let u = self.h * d.as_dvec3();
        let r = tol * u.z;
        u.z > 0.0 && (u.x - i as f64 * u.z).abs() <= r && (u.y - j as f64 * u.z).abs() <= r
    }

    /// Upper bounds on [`Self::deviation`] for the four directions `(dx, dy, dz)` (per lane) of
    /// pixels `(x0 + l, j)`, in f32: each lane's exact deviation is at most its bound (+inf
    /// behind the eye or on its plane, NaN for NaN directions). The f32 rounding is charged to
    /// the bound: a dot product of three f32 products with `H` rounded to f32 is within
    /// `2ε·Σ|h||d|` of the exact one, taken twice over, and the differences and the division
    /// carry a relative `4ε` each. Ordinary cameras: a few thousandths of a pixel above the
    /// exact deviation.
    #[inline]
    pub fn deviation4(&self, d: [Vec4; 3], x0: u32, j: u32) -> Vec4 {
        const E: f32 = f32::EPSILON;
        let (h, a) = (&self.h32, &self.h32_abs);
        let [dx, dy, dz] = d;
        let (ax, ay, az) = (dx.abs(), dy.abs(), dz.abs());
        let row = |r: usize| dx * h.x_axis[r] + dy * h.y_axis[r] + dz * h.z_axis[r];
        let err = |r: usize| (ax * a.x_axis[r] + ay * a.y_axis[r] + az * a.z_axis[r]) * (4.0 * E);
        let (ux, uy, uz) = (row(0), row(1), row(2));
        let (ex, ey, ez) = (err(0), err(1), err(2));
        // Exact small integers (images are far below 2^24 pixels wide).
        let x = Vec4::new(0.0, 1.0, 2.0, 3.0) + Vec4::splat(x0 as f32);
        let y = Vec4::splat(j as f32);
        // |u.x − x·u.z| (exact) ≤ |computed| + its rounding + |error of u.x| + x·|error of u.z|,
        // over a depth of at least `u.z − its error`.
        let num = |u: Vec4, c: Vec4, e: Vec4| {
            let cz = c * uz;
            ((u - cz).abs() + (u.abs() + cz.abs()) * (4.0 * E) + e + c * ez) * (1.0 + 8.0 * E)
        };
        let depth = uz - ez;
        let dev = num(ux, x, ex).max(num(uy, y, ey)) / depth * (1.0 + 4.0 * E);
        // Behind the eye (or unknown): +inf; NaN stays NaN (`max` above would drop it).
        let nan = dx.is_nan_mask() | dy.is_nan_mask() | dz.is_nan_mask();
        let dev = Vec4::select(depth.cmpgt(Vec4::ZERO), dev, Vec4::INFINITY);
        Vec4::select(nan, Vec4::NAN, dev)
    }

    /// The pixels `(i, j)` whose rays can meet `b`, for rays with [`Self::deviation`] at most
    /// `tol`: inclusive integer ranges `[x0, x1]`, `[y0, y1]` (possibly empty, possibly outside
    /// the image), or `None` when part of `b` is not in front of the eye.
    pub fn box_pixels(&self, b: &Aabb, tol: f64) -> Option<[i64; 4]> {
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for k in 0..8 {
            let q = self.pixel(b.corner(k).as_dvec3() - self.eye)?;
            x0 = x0.min(q.x);
            x1 = x1.max(q.x);
            y0 = y0.min(q.y);
            y1 = y1.max(q.y);
        }
        // The rays' deviation, plus the f64 rounding of the corners' projections and of the
        // deviation itself (relative 1e-12 is thousands of ulps; plus an absolute 1e-6 pixel).
        let pad = |v: f64| tol + 1e-6 + v.abs() * 1e-12;
        let (x0, x1, y0, y1) = (x0 - pad(x0), x1 + pad(x1), y0 - pad(y0), y1 + pad(y1));
        if !(x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite()) {
            return None;
        }
        // Clamp far outside any image (i64 range; a box near the eye's plane projects far out).
        const BIG: f64 = 1e15;
        Some([
            x0.clamp(-BIG, BIG).ceil() as i64,
            x1.clamp(-BIG, BIG).floor() as i64,
            y0.clamp(-BIG, BIG).ceil() as i64,
            y1.clamp(-BIG, BIG).floor() as i64,
        ])
    }
}

impl PixelProjection {
    /// False only when no pixel `(i, j)` with `i ∈ [xs[0], xs[1]]`, `j ∈ [ys[0], ys[1]]` has a
    /// ray (from the eye, [`Self::deviation`] at most `tol`) that the shared ray/triangle test
    /// can report as a hit on triangle `v`: every such hit point projects within `tol` of its
    /// pixel and lies in the triangle, which projects onto the triangle of its projected
    /// corners. Conservative: triangles reaching behind the eye, near-degenerate projections
    /// (slivers, edge-on triangles: the triangle test's barycentric rounding grows as they
    /// thin) and those whose padded rectangle holds more than two pixels are kept without the
    /// edge test (the rectangle alone culls those holding none).
    pub fn triangle_may_cover(&self, v: [Vec3; 3], tol: f64, xs: [i64; 2], ys: [i64; 2]) -> bool {
        self.triangles_may_cover4([v; 4], tol, xs, ys)[0]
    }

    /// [`Self::triangle_may_cover`] for four triangles (the same computation, lane by lane).
    pub fn triangles_may_cover4(
        &self,
        tri: [[Vec3; 3]; 4],
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
    ) -> [bool; 4] {
        let m = self.triangle_rects_lanes(tri, tol, xs, ys).nonempty();
        std::array::from_fn(|l| m >> l & 1 != 0)
    }

    /// For four triangles, the pixels `(i, j)` of the ranges `xs`, `ys` whose rays (from the eye,
    /// [`Self::deviation`] at most `tol`) the shared ray/triangle test can report as hitting
    /// the triangle: an inclusive rectangle `[x0, x1, y0, y1]` holding them all, empty
    /// (`x0 > x1` or `y0 > y1`) when there are none, the whole ranges for triangles reaching
    /// behind the eye. The argument is [`Self::triangle_may_cover`]'s; a rectangle of one or
    /// two pixels is shrunk to those whose centres pass the edge test.
    pub fn triangle_rects4(
        &self,
        tri: [[Vec3; 3]; 4],
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
    ) -> [[i32; 4]; 4] {
        let r = self.triangle_rects_lanes(tri, tol, xs, ys);
        std::array::from_fn(|l| {
            if r.behind >> l & 1 != 0 {
                [xs[0], xs[1], ys[0], ys[1]]
                    .map(|v| v.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
            } else {
                r.lane(l).map(|v| v as i32)
            }
        })
    }

    /// [`Self::triangle_rects4`] as four lanes, without leaving SIMD registers.
    #[inline]
    pub fn triangle_rects_lanes(
        &self,
        tri: [[Vec3; 3]; 4],
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
    ) -> RectLanes {
        let v = std::array::from_fn(|k| std::array::from_fn(|a| Vec4::from_fn(|l| tri[l][k][a])));
        self.triangle_rects_wide(v, tol, xs, ys)
    }

    /// [`Self::triangle_rects4`] for `L::N` triangles (`v[k]` holds corner `k`'s x, y and z
    /// lanes), as lanes: the form the tracers' projection loops use, at the width the CPU runs
    /// best (see [`super::lanes`]; every width gives the same rectangles).
    #[inline(always)]
    pub fn triangle_rects_wide<L: Lanes>(
        &self,
        v: [[L; 3]; 3],
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
    ) -> RectLanes<L> {
        // In f32, with a rounding bound per vertex: `w = v − eye`, `u = H·w` (f32 copy of H)
        // differ from the exact `H·(v − eye)` by at most γ·(row 1-norm of H)·max|w| per
        // coordinate, γ = 8ε being over twice the γ₆ of these operations (including the
        // rounding of H to f32); the division adds a relative ε and, with `u.z` at least twice
        // its error, at most doubles the numerator's.
        const G: f32 = 8.0 * f32::EPSILON;
        let c = L::splat;
        let h = &self.h32;
        let (r1, e) = (self.rows1, self.eye32);
        let mut behind = L::mask_splat(false);
        let (mut qx, mut qy) = ([c(0.0); 3], [c(0.0); 3]);
        let mut smax = c(0.0);
        for k in 0..3 {
            let (wx, wy, wz) = (v[k][0] - c(e.x), v[k][1] - c(e.y), v[k][2] - c(e.z));
            let row = |r: usize| wx * c(h.x_axis[r]) + wy * c(h.y_axis[r]) + wz * c(h.z_axis[r]);
            let (ux, uy, uz) = (row(0), row(1), row(2));
            let m = wx.abs().max(wy.abs()).max(wz.abs());
            // NaN-safe: a NaN `uz` fails the comparison, the lane counts as behind.
            behind = behind | !uz.cmpgt(m * c(2.0 * G * r1.z));
            let inv = c(1.0) / uz;
            let (px, py) = (ux * inv, uy * inv);
            // The vertex's bound per coordinate `p` is `scale·(row 1-norm + |p|·r1.z) +
            // |p|·2ε`; only `scale` is kept, the bound is taken at the maxima below.
            smax = smax.max(m * inv * c(2.0 * G));
            (qx[k], qy[k]) = (px, py);
        }
        let (lx, hx) = (qx[0].min(qx[1]).min(qx[2]), qx[0].max(qx[1]).max(qx[2]));
        let (ly, hy) = (qy[0].min(qy[1]).min(qy[2]), qy[0].max(qy[1]).max(qy[2]));
        let ext = (hx - lx).max(hy - ly);
        // The projection's rounding; the rays' deviation; the triangle test's slack (a hit may
        // lie outside the exact triangle by its barycentric rounding: for projections at least
        // 1% as wide as long, well under 1e-4 of the extent); a thousandth of a pixel; and
        // the f32 rounding of the differences in the edge test.
        let mag = lx.abs().max(hx.abs()).max(ly.abs()).max(hy.abs());
        // Every vertex's projection bound, each factor at its largest (`mag` bounds every |p|).
        let err = smax * (c(r1.x.max(r1.y)) + mag * c(r1.z)) + mag * c(2.0 * f32::EPSILON);
        let pad = err + c(tol as f32 + 1e-3) + ext * c(1e-4) + mag * c(8.0 * f32::EPSILON);
        // The candidate pixels, clamped to the ranges (exact small integers in f32).
        let x0 = (lx - pad).ceil().max(c(xs[0] as f32));
        let x1 = (hx + pad).floor().min(c(xs[1] as f32));
        let y0 = (ly - pad).ceil().max(c(ys[0] as f32));
        let y1 = (hy + pad).floor().min(c(ys[1] as f32));
        // Lanes with a candidate (NaN compares false: no candidate, but such lanes are behind).
        let some = x0.cmple(x1) & y0.cmple(y1);
        // The edge test, lane-wise, for lanes with one or two candidate pixels, `(x0, y0)` and
        // `(x1, y1)` (tiny triangles: the case that matters); lanes with more are kept
        // untested, as are near-degenerate projections (area below 1% of the extent squared,
        // and NaN). Inward edge normals `n` (counter-clockwise after orienting by the area's
        // sign); `p` is within `pad` of edge line `k` iff `s = n·(p − a) ≥ 0` or
        // `s² ≤ pad²·|n|²`.
        let few = ((x1 - x0) + (y1 - y0)).cmple(c(1.0));
        let area2 = (qx[1] - qx[0]) * (qy[2] - qy[0]) - (qy[1] - qy[0]) * (qx[2] - qx[0]);
        let thin = !area2.abs().cmpge(ext * ext * c(0.01)) | ext.cmpeq(c(0.0));
        let sgn = area2.signum();
        let pad2 = pad * pad;
        let (mut in0, mut in1) = (L::mask_splat(true), L::mask_splat(true));
        for k in 0..3 {
            let (ax, ay) = (qx[k], qy[k]);
            let (bx, by) = (qx[(k + 1) % 3], qy[(k + 1) % 3]);
            let (nx, ny) = ((ay - by) * sgn, (bx - ax) * sgn);
            let r2 = pad2 * (nx * nx + ny * ny);
            let s0 = nx * (x0 - ax) + ny * (y0 - ay);
            in0 = in0 & (s0.cmpge(c(0.0)) | (s0 * s0).cmple(r2));
            let s1 = nx * (x1 - ax) + ny * (y1 - ay);
            in1 = in1 & (s1.cmpge(c(0.0)) | (s1 * s1).cmple(r2));
        }
        // Lanes whose one or two candidates were edge-tested keep those that passed (the two
        // candidates of a two-pixel rectangle are its ends); lanes without a candidate, or
        // whose candidates all failed, are empty `(1, 0, 1, 0)`; lanes behind, the ranges.
        let tested = some & few & !thin;
        let only0 = tested & in0 & !in1;
        let only1 = tested & in1 & !in0;
        let none = !some | (tested & !in0 & !in1);
        let pick = L::select;
        let (one, zero) = (c(1.0), c(0.0));
        let full = |v: i64| c(v as f32);
        RectLanes {
            x0: pick(behind, full(xs[0]), pick(none, one, pick(only1, x1, x0))),
            x1: pick(behind, full(xs[1]), pick(none, zero, pick(only0, x0, x1))),
            y0: pick(behind, full(ys[0]), pick(none, one, pick(only1, y1, y0))),
            y1: pick(behind, full(ys[1]), pick(none, zero, pick(only0, y0, y1))),
            behind: L::bitmask(behind),
        }
    }
}

/// [`PixelProjection::triangle_rects_wide`]'s result: the rectangles' bounds per lane, exact
/// small integers in f32 (empty when `x0 > x1` or `y0 > y1`); lanes behind the eye, in
/// `behind`, hold the ranges (as f32: exact up to 2^24).
#[derive(Clone, Copy, Debug)]
pub struct RectLanes<L = Vec4> {
    /// Lowest column.
    pub x0: L,
    /// Highest column.
    pub x1: L,
    /// Lowest row.
    pub y0: L,
    /// Highest row.
    pub y1: L,
    /// Lanes reaching behind the eye (bit per lane).
    pub behind: u32,
}

impl<L: Lanes> RectLanes<L> {
    /// Bit `l` set when lane `l`'s rectangle is not empty.
    #[inline(always)]
    pub fn nonempty(&self) -> u32 {
        L::bitmask(self.x0.cmple(self.x1) & self.y0.cmple(self.y1))
    }

    /// Lane `l` as `[x0, x1, y0, y1]`.
    #[inline(always)]
    pub fn lane(&self, l: usize) -> [f32; 4] {
        [
            self.x0.lane(l),
            self.x1.lane(l),
            self.y0.lane(l),
            self.y1.lane(l),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rays::Camera;
    use rand::{Rng, SeedableRng};

    fn fit_camera(c: &Camera, w: u32, h: u32) -> (PixelProjection, crate::rays::RayBatch) {
        let rays = c.rays(w, h);
        let (wu, hu) = (w as usize, h as usize);
        let corners = [0, wu - 1, (hu - 1) * wu, hu * wu - 1].map(|k| rays.dir(k));
        (
            PixelProjection::fit(c.eye, w, h, corners).expect("a camera has a projection"),
            rays,
        )
    }

    /// The four-wide f32 bound is never below the exact deviation, and for ordinary cameras
    /// at most a hundredth of a pixel above it: exact camera rays, and random directions within
    /// about a pixel of their pixel (jittered rays), a few behind the eye or NaN. The third
    /// camera (120°, 4000 × 37) has a projection matrix with large cancelling entries: its
    /// bound only has to stay above the deviation.
    #[test]
    fn deviation4_bounds_the_deviation() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let mut worst: f64 = 0.0;
        for (look, up, fov, w, h, tight) in [
            (
                Vec3::new(0.0, 0.0, -1.0),
                Vec3::Y,
                60.0,
                1024u32,
                1024u32,
                true,
            ),
            (Vec3::new(3.0, -1.0, 0.5), Vec3::Z, 27.0, 1280, 800, true),
            (
                Vec3::new(-1.0, 2.0, 7.0),
                Vec3::new(0.3, 1.0, 0.0),
                120.0,
                4000,
                37,
                false,
            ),
        ] {
            let c = Camera {
                eye: Vec3::new(1.0, 2.0, 3.0),
                look: Vec3::new(1.0, 2.0, 3.0) + look,
                up,
                fov_deg: fov,
            };
            let (p, rays) = fit_camera(&c, w, h);
            for k in 0..20_000 {
                let j = rng.gen_range(0..h);
                let x0 = rng.gen_range(0..w - 3);
                let mut d = [Vec4::ZERO; 3];
                let mut dirs = [Vec3::ZERO; 4];
                for (l, dir) in dirs.iter_mut().enumerate() {
                    let i = (j * w + x0) as usize + l;
                    *dir = rays.dir(i);
                    if k % 2 == 1 {
                        // A point up to a pixel away from the pixel, at any distance.
                        let (px, py) = (
                            x0 as f64 + l as f64 + rng.gen_range(-1.0..1.0),
                            j as f64 + rng.gen_range(-1.0..1.0),
                        );
                        let g = p.h.inverse() * DVec3::new(px, py, 1.0);
                        *dir = (g * rng.gen_range(0.01..100.0)).as_vec3();
                    }
                    match k % 97 {
                        5 => *dir = -*dir,
                        6 => dir.y = f32::NAN,
                        _ => {}
                    }
                    for a in 0..3 {
                        d[a][l] = dir[a];
                    }
                }
                let bound = p.deviation4(d, x0, j);
                for (l, dir) in dirs.iter().enumerate() {
                    let dev = p.deviation(*dir, x0 as usize + l, j as usize);
                    let b = bound[l] as f64;
                    if dir.is_nan() {
                        assert!(b.is_nan());
                    } else if dev.is_infinite() || b.is_infinite() {
                        // Behind the eye: no finite bound (directions just in front may also
                        // get none, which is only conservative).
                        assert!(b.is_infinite() && b > 0.0, "{dev} {b}");
                    } else {
                        assert!(b >= dev, "bound {b} below the deviation {dev}");
                        if tight {
                            worst = worst.max(b - dev);
                        }
                    }
                }
            }
        }
        assert!(worst < 0.01, "bound {worst} px above the deviation");
    }

    #[test]
    fn camera_rays_project_to_their_pixels() {
        for (look, up, fov) in [
            (Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 60.0),
            (Vec3::new(3.0, -1.0, 0.5), Vec3::Z, 27.0),
            (Vec3::new(-1.0, 2.0, 7.0), Vec3::new(0.3, 1.0, 0.0), 120.0),
        ] {
            let c = Camera {
                eye: Vec3::new(1.0, 2.0, 3.0),
                look: Vec3::new(1.0, 2.0, 3.0) + look,
                up,
                fov_deg: fov,
            };
            let (w, h) = (97u32, 61u32);
            let (p, rays) = fit_camera(&c, w, h);
            for j in 0..h as usize {
                for i in 0..w as usize {
                    let e = p.deviation(rays.dir(j * w as usize + i), i, j);
                    assert!(e < 1e-3, "{i} {j}: {e}");
                    assert!(p.within(rays.dir(j * w as usize + i), i, j, 1e-3));
                    assert!(!p.within(rays.dir(j * w as usize + i), i + 1, j, 0.9));
                    assert!(!p.within(rays.dir(j * w as usize + i), i, j + 1, 0.9));
                }
            }
            // A neighbour's direction is a pixel away.
            assert!((p.deviation(rays.dir(5), 4, 0) - 1.0).abs() < 1e-3);
            assert!((p.deviation(rays.dir(w as usize), 0, 0) - 1.0).abs() < 1e-3);
            // Behind the eye: no pixel.
            assert!(p.pixel(-rays.dir(0).as_dvec3()).is_none());
        }
    }

    #[test]
    fn fit_refuses_what_is_no_projection() {
        let d = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
        assert!(PixelProjection::fit(Vec3::ZERO, 1, 5, d).is_none());
        assert!(PixelProjection::fit(Vec3::ZERO, 5, 5, [Vec3::X; 4]).is_none());
        let mut nan = d;
        nan[2].x = f32::NAN;
        assert!(PixelProjection::fit(Vec3::ZERO, 5, 5, nan).is_none());
    }

    /// No triangle that some camera ray hits (through the shared triangle test) is culled, and
    /// every such ray's pixel is in the triangle's rectangle, exact or jittered rays; tiny
    /// triangles between pixel centres are culled and many rectangles are single pixels (not
    /// vacuous); the scalar and four-wide forms agree.
    #[test]
    fn culled_triangles_are_hit_by_no_ray() {
        use crate::geom::intersect_triangle;
        let c = Camera {
            eye: Vec3::new(0.3, 0.2, 4.0),
            look: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 50.0,
        };
        let (w, h) = (40u32, 30u32);
        let (p, exact) = fit_camera(&c, w, h);
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        // Jittered: each direction moved up to half a pixel towards its neighbours.
        let mut jittered = exact.clone();
        for k in 0..exact.len() {
            let (i, j) = (k % w as usize, k / w as usize);
            let d = exact.dir(k);
            let di = exact.dir(if i + 1 < w as usize { k + 1 } else { k - 1 }) - d;
            let dj = exact.dir(if j + 1 < h as usize {
                k + w as usize
            } else {
                k - w as usize
            }) - d;
            let (a, b): (f32, f32) = (rng.gen_range(0.0..0.5), rng.gen_range(0.0..0.5));
            let n = (d + a * di + b * dj).normalize();
            (jittered.dx[k], jittered.dy[k], jittered.dz[k]) = (n.x, n.y, n.z);
        }
        let tol_of = |rays: &crate::rays::RayBatch| {
            (0..rays.len())
                .map(|k| p.deviation(rays.dir(k), k % w as usize, k / w as usize))
                .fold(0.0f64, f64::max)
        };
        let (xs, ys) = ([0, w as i64 - 1], [0, h as i64 - 1]);
        for rays in [&exact, &jittered] {
            let tol = tol_of(rays);
            let (mut culled, mut hit, mut small) = (0, 0, 0);
            for _ in 0..600 {
                let tri: [[Vec3; 3]; 4] = std::array::from_fn(|_| {
                    let c = Vec3::new(
                        rng.gen_range(-2.0..2.0),
                        rng.gen_range(-1.5..1.5),
                        rng.gen_range(-2.0..5.0),
                    );
                    let s = 10f32.powf(rng.gen_range(-3.0..-0.5));
                    std::array::from_fn(|_| {
                        c + Vec3::new(
                            rng.gen_range(-s..s),
                            rng.gen_range(-s..s),
                            rng.gen_range(-s..s),
                        )
                    })
                });
                let keep = p.triangles_may_cover4(tri, tol, xs, ys);
                let rects = p.triangle_rects4(tri, tol, xs, ys);
                for l in 0..4 {
                    assert_eq!(keep[l], p.triangle_may_cover(tri[l], tol, xs, ys));
                    let [a, b, c2] = tri[l];
                    let [x0, x1, y0, y1] = rects[l].map(|v| v as usize);
                    let mut hits = false;
                    for k in 0..rays.len() {
                        if intersect_triangle(
                            rays.origin(k),
                            rays.dir(k),
                            a,
                            b,
                            c2,
                            0.0,
                            f32::INFINITY,
                        )
                        .is_some()
                        {
                            hits = true;
                            // Every hitting ray's pixel is in the rectangle.
                            let (i, j) = (k % w as usize, k / w as usize);
                            assert!(
                                (x0..=x1).contains(&i) && (y0..=y1).contains(&j),
                                "ray {i},{j} hits {:?} outside {:?}",
                                tri[l],
                                rects[l]
                            );
                        }
                    }
                    small +=
                        ((x1 + 1).saturating_sub(x0) * (y1 + 1).saturating_sub(y0) == 1) as usize;
                    assert!(
                        keep[l] || !hits,
                        "culled a triangle a ray hits: {:?}",
                        tri[l]
                    );
                    culled += !keep[l] as usize;
                    hit += hits as usize;
                }
            }
            assert!(
                culled > 300 && hit > 100 && small > 50,
                "culled {culled}, hit {hit}, one-pixel rectangles {small}"
            );
        }
    }

    /// Eight lanes give the rectangles four do, bit for bit, also when compiled for AVX2 (the
    /// path `dacrt` takes on such CPUs): ordinary, tiny, huge, degenerate, behind-the-eye,
    /// eye-plane and NaN triangles.
    #[test]
    fn rect_lanes_agree_at_every_width() {
        use crate::geom::lanes::{F32x8, Lanes, Wide};
        let c = Camera {
            eye: Vec3::new(0.3, 0.2, 4.0),
            look: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 50.0,
        };
        let (p, _) = fit_camera(&c, 64, 48);
        let (xs, ys) = ([0, 63], [8, 23]);
        let lanes =
            |tri: &[[Vec3; 3]], k: usize, a: usize| Wide(std::array::from_fn(|l| tri[l][k][a]));
        let wide = |tri: &[[Vec3; 3]]| -> [[F32x8; 3]; 3] {
            std::array::from_fn(|k| std::array::from_fn(|a| lanes(tri, k, a)))
        };
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        fn avx2(p: &PixelProjection, v: [[F32x8; 3]; 3], ys: [i64; 2]) -> RectLanes<F32x8> {
            p.triangle_rects_wide(v, 0.01, [0, 63], ys)
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let mut kinds = [0usize; 3];
        for round in 0..4000 {
            let tri: [[Vec3; 3]; 8] = std::array::from_fn(|_| {
                let mid = Vec3::new(
                    rng.gen_range(-3.0..3.0),
                    rng.gen_range(-3.0..3.0),
                    rng.gen_range(-3.0..6.0),
                );
                let s = 10f32.powf(rng.gen_range(-6.0..1.0));
                let mut t: [Vec3; 3] = std::array::from_fn(|_| {
                    mid + s * Vec3::new(
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                    )
                });
                match rng.gen_range(0..12) {
                    0 => t = [mid; 3],
                    1 => t[1] = t[0],
                    2 => t[2].z = c.eye.z,
                    3 => t[0] = Vec3::splat(1e30),
                    4 if round % 50 == 0 => t[1].y = f32::NAN,
                    _ => {}
                }
                t
            });
            let four: [RectLanes; 2] = std::array::from_fn(|h| {
                p.triangle_rects_lanes(std::array::from_fn(|l| tri[4 * h + l]), 0.01, xs, ys)
            });
            let mut eights = vec![p.triangle_rects_wide(wide(&tri), 0.01, xs, ys)];
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked on the line above).
                eights.push(unsafe { avx2(&p, wide(&tri), ys) });
            }
            for e in &eights {
                for l in 0..8 {
                    let f = &four[l / 4];
                    assert_eq!(e.lane(l), f.lane(l % 4), "{:?}", tri[l]);
                    assert_eq!(e.behind >> l & 1, f.behind >> (l % 4) & 1);
                }
                assert_eq!(e.nonempty(), four[0].nonempty() | four[1].nonempty() << 4);
            }
            for l in 0..8 {
                let f = &four[l / 4];
                let k = if f.behind >> (l % 4) & 1 != 0 {
                    0
                } else if f.nonempty() >> (l % 4) & 1 != 0 {
                    1
                } else {
                    2
                };
                kinds[k] += 1;
            }
        }
        // Every outcome occurs often: behind the eye, a rectangle, culled.
        assert!(kinds.iter().all(|&k| k > 1000), "{kinds:?}");
        let _ = F32x8::N;
    }

    /// The rectangle holds the pixel of every ray that meets the box (brute force over random
    /// boxes, through the shared slab test), and `None` exactly when a corner is behind the eye.
    #[test]
    fn box_pixels_hold_every_ray_that_meets_the_box() {
        let c = Camera {
            eye: Vec3::new(0.2, -0.1, 4.0),
            look: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 50.0,
        };
        let (w, h) = (64u32, 48u32);
        let (p, rays) = fit_camera(&c, w, h);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (mut met, mut tight, mut none) = (0, 0, 0);
        for _ in 0..400 {
            let a = Vec3::new(
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-2.0..5.0),
            );
            let s = Vec3::new(
                rng.gen_range(0.0..1.5),
                rng.gen_range(0.0..1.5),
                rng.gen_range(0.0..1.5),
            );
            let b = Aabb::new(a, a + s);
            let r = p.box_pixels(&b, 1e-3);
            let behind = (0..8).any(|k| (b.corner(k) - c.eye).dot(c.look - c.eye) <= 0.0);
            assert_eq!(r.is_none(), behind, "{b:?}");
            let Some([x0, x1, y0, y1]) = r else {
                none += 1;
                continue;
            };
            let mut inside = 0;
            for j in 0..h as usize {
                for i in 0..w as usize {
                    let k = j * w as usize + i;
                    let (o, d) = (rays.origin(k), rays.dir(k));
                    let hit = b
                        .ray_interval(o, Vec3::ONE / d, 0.0, f32::INFINITY)
                        .is_some();
                    let inr = (x0..=x1).contains(&(i as i64)) && (y0..=y1).contains(&(j as i64));
                    if hit {
                        met += 1;
                        assert!(inr, "ray {i},{j} meets {b:?} outside {:?}", r);
                    }
                    inside += inr as usize;
                }
            }
            // Not vacuous: some rectangles are smaller than the image.
            tight += (inside < (w * h) as usize) as usize;
        }
        assert!(
            met > 1000 && tight > 50 && none > 10,
            "{met} {tight} {none}"
        );
    }
}
