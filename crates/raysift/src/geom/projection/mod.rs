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

mod edges;

pub use edges::PixelEdges;

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
        let c = L::splat;
        let p = self.project_corners(v, tol);
        let pad = p.pad;
        // The candidate pixels, clamped to the ranges (exact small integers in f32).
        let x0 = (p.lo[0] - pad).ceil().max(c(xs[0] as f32));
        let x1 = (p.hi[0] + pad).floor().min(c(xs[1] as f32));
        let y0 = (p.lo[1] - pad).ceil().max(c(ys[0] as f32));
        let y1 = (p.hi[1] + pad).floor().min(c(ys[1] as f32));
        // Lanes with a candidate (NaN compares false: no candidate, but such lanes are behind).
        let some = x0.cmple(x1) & y0.cmple(y1);
        // The edge test (`Edges`), lane-wise, for lanes with one or two candidate pixels,
        // `(x0, y0)` and `(x1, y1)` (tiny triangles: the case that matters); lanes with more
        // are kept untested (tile leaves test their pixels: `edges::PixelEdges`), as are
        // near-degenerate projections.
        let few = ((x1 - x0) + (y1 - y0)).cmple(c(1.0));
        let e = Edges::of(&p);
        let (in0, in1) = (e.inside(x0, y0), e.inside(x1, y1));
        // Lanes whose one or two candidates were edge-tested keep those that passed (the two
        // candidates of a two-pixel rectangle are its ends); lanes without a candidate, or
        // whose candidates all failed, are empty `(1, 0, 1, 0)`; lanes behind, the ranges.
        let tested = some & few & !e.thin;
        let only0 = tested & in0 & !in1;
        let only1 = tested & in1 & !in0;
        let none = !some | (tested & !in0 & !in1);
        let behind = p.behind;
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

    /// The projected corners of `L::N` triangles, with the bound `pad` on how far (in pixels)
    /// the pixel of a ray the shared triangle test reports as a hit can lie from the
    /// triangle of the projected corners (see [`Self::triangle_may_cover`]).
    #[inline(always)]
    pub(crate) fn project_corners<L: Lanes>(&self, v: [[L; 3]; 3], tol: f64) -> Corners<L> {
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
        // the f32 rounding of the differences in the edge test (at pixels within `pad` of the
        // corners' bounding rectangle).
        let mag = lx.abs().max(hx.abs()).max(ly.abs()).max(hy.abs());
        // Every vertex's projection bound, each factor at its largest (`mag` bounds every |p|).
        let err = smax * (c(r1.x.max(r1.y)) + mag * c(r1.z)) + mag * c(2.0 * f32::EPSILON);
        let pad = err + c(tol as f32 + 1e-3) + ext * c(1e-4) + mag * c(8.0 * f32::EPSILON);
        // The edge test measures distances to the edge lines (Euclidean), and a ray within
        // `tol` of its pixel per coordinate can be `tol·√2` from it: the rest of `pad` plus
        // `tol·√2` (0.415 > √2 − 1).
        let pad_edge = pad + c(tol as f32 * 0.415);
        Corners {
            qx,
            qy,
            lo: [lx, ly],
            hi: [hx, hy],
            ext,
            pad,
            pad_edge,
            behind,
        }
    }
}

/// [`PixelProjection::project_corners`]' result, per lane: the projected corners, their
/// bounding rectangle and its larger side, the bound `pad` per coordinate and `pad_edge` as a
/// distance (for the edge test); `behind`, lanes reaching
/// behind the eye (or NaN), whose other fields mean nothing.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Corners<L: Lanes> {
    pub(crate) qx: [L; 3],
    pub(crate) qy: [L; 3],
    pub(crate) lo: [L; 2],
    pub(crate) hi: [L; 2],
    pub(crate) ext: L,
    pub(crate) pad: L,
    pub(crate) pad_edge: L,
    pub(crate) behind: L::Mask,
}

/// The edge test of projected triangles, per lane: inward edge normals `n` (counter-clockwise
/// after orienting by the area's sign), so that pixel `p` is within `pad_edge` of edge line
/// `k` iff `s = n·(p − q_k) ≥ 0` or `s² ≤ pad_edge²·|n|²`. A pixel failing it for some edge
/// is more than `pad_edge` outside the projected triangle: no ray of it is reported as a hit. Only valid
/// for lanes not `thin` (near-degenerate projections, area below 1% of the extent squared,
/// NaN: the triangle test's barycentric rounding grows as they thin), at pixels within `pad`
/// of the corners' bounding rectangle (the rounding bound in `pad` assumes it).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Edges<L: Lanes> {
    pub(crate) nx: [L; 3],
    pub(crate) ny: [L; 3],
    pub(crate) ax: [L; 3],
    pub(crate) ay: [L; 3],
    pub(crate) r2: [L; 3],
    pub(crate) thin: L::Mask,
}

impl<L: Lanes> Edges<L> {
    /// The edges of projected corners `p`.
    #[inline(always)]
    pub(crate) fn of(p: &Corners<L>) -> Self {
        let c = L::splat;
        let (qx, qy, ext) = (p.qx, p.qy, p.ext);
        let area2 = (qx[1] - qx[0]) * (qy[2] - qy[0]) - (qy[1] - qy[0]) * (qx[2] - qx[0]);
        let thin = !area2.abs().cmpge(ext * ext * c(0.01)) | ext.cmpeq(c(0.0));
        let sgn = area2.signum();
        let pad2 = p.pad_edge * p.pad_edge;
        let mut e = Self {
            nx: [c(0.0); 3],
            ny: [c(0.0); 3],
            ax: qx,
            ay: qy,
            r2: [c(0.0); 3],
            thin,
        };
        for k in 0..3 {
            let (bx, by) = (qx[(k + 1) % 3], qy[(k + 1) % 3]);
            let (nx, ny) = ((qy[k] - by) * sgn, (bx - qx[k]) * sgn);
            (e.nx[k], e.ny[k], e.r2[k]) = (nx, ny, pad2 * (nx * nx + ny * ny));
        }
        e
    }

    /// Lanes whose pixel `(x, y)` passes the test for every edge.
    #[inline(always)]
    pub(crate) fn inside(&self, x: L, y: L) -> L::Mask {
        let mut inside = L::mask_splat(true);
        for k in 0..3 {
            let s = self.nx[k] * (x - self.ax[k]) + self.ny[k] * (y - self.ay[k]);
            inside = inside & (s.cmpge(L::splat(0.0)) | (s * s).cmple(self.r2[k]));
        }
        inside
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
mod tests;
