//! Exact cone/triangle test for cone tracing (Wiche & Kuri 2020, Eq. 1): does a one-sided solid
//! cone (apex `A`, unit axis `d`, half-angle `0 < α < 90°`) meet a triangle, and if so, the
//! cone query's `t`.
//!
//! **What `t` is (our choice; the paper says only "a representative position on the triangle
//! projected onto the cone-direction axis"):** `t = min { (p − A)·d : p ∈ triangle ∩ cone }`, the
//! axial distance of the triangle's nearest point inside the cone. It is `≥ 0` (every point of
//! the cone is), it is a lower bound of the axial distance of everything of the triangle inside
//! the cone (so a box range bounding the cone's part in a box bounds it, which is what makes
//! culling by `t_n` exact), and it is the ray's hit distance when `α → 0`.
//!
//! **How.** `h(p) = (p − A)·d` is linear and `triangle ∩ cone` is convex and compact (α < 90°),
//! so the minimum is at one of finitely many candidate points, each tested for membership:
//! 1. a vertex inside the cone;
//! 2. a point where an edge crosses the cone's surface (the roots in `[0, 1]` of the quadratic
//!    `(w·d)² − cos²α·|w|² = 0` along the edge, on the nappe `w·d ≥ 0`): `h` is linear along an
//!    edge, so an edge's minimum is at a vertex or at such a crossing;
//! 3. the apex, when it lies in the triangle (`t = 0`);
//! 4. inside the triangle, on the conic where the plane cuts the cone's surface: by Lagrange,
//!    `d = λ·n + μ·∇F(w)` with `F(w) = (w·d)² − cos²α·|w|²` forces `w ∈ span(d, n)`, so the
//!    minimum lies on one of the two generators of the cone in the plane through the axis and
//!    the triangle's normal `n`; each generator ray is intersected with the triangle's plane
//!    and the point kept when it is inside the triangle. (If `n ∥ d`, `h` is constant on the
//!    plane and any generator will do.)
//!
//! A non-empty `triangle ∩ cone` has its minimum among these, and every candidate is in it, so
//! the test is exact up to rounding; `t` is the least candidate, rounded to f32 (nearest).
//! Degenerate triangles (segments, points) use 1 and 2 only.
//!
//! **Rounding.** Everything is evaluated in f64 from the f32 inputs (their products are exact
//! in f64); membership comparisons have no slack. The test is the *definition* of the cone
//! query's answer: the oracle and every traversal call this one function on the same data, so
//! they agree bit for bit whatever its rounding; near-tangent contacts (within ~1e-15 relative)
//! may go either way, identically everywhere. Box culling must then include everything this
//! test accepts: [`super::cone_frustum`] widens its cone and its range for that.

use glam::{DVec3, Vec3};

/// A cone prepared for many triangle tests (f64 constants, computed once per cone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeF64 {
    apex: DVec3,
    axis: DVec3,
    cos: f64,
    sin: f64,
    cos2: f64,
}

impl ConeF64 {
    /// The cone with `apex`, `axis` (normalised here in f64) and `half_angle` in radians,
    /// `0 < half_angle < π/2` (the caller checks; see `tracers::cone::ConeBatch::push`).
    pub fn new(apex: Vec3, axis: Vec3, half_angle: f32) -> Self {
        let a = half_angle as f64;
        let (sin, cos) = a.sin_cos();
        Self {
            apex: apex.as_dvec3(),
            axis: axis.as_dvec3().normalize(),
            cos,
            sin,
            cos2: cos * cos,
        }
    }

    /// The apex.
    pub fn apex(&self) -> DVec3 {
        self.apex
    }

    /// The unit axis (f64).
    pub fn axis(&self) -> DVec3 {
        self.axis
    }

    /// True when `p` is inside the solid cone (boundary included; the apex is inside).
    #[inline(always)]
    pub fn contains(&self, p: DVec3) -> bool {
        let w = p - self.apex;
        let h = w.dot(self.axis);
        h >= 0.0 && h * h >= self.cos2 * w.length_squared()
    }

    /// Least axial distance of the points of segment `p0 → p1` where it crosses the cone's
    /// surface on the forward nappe (candidates 2), folded into `best`.
    #[inline(always)]
    fn edge_crossings(&self, p0: DVec3, p1: DVec3, best: &mut f64) {
        let a = p0 - self.apex;
        let e = p1 - p0;
        let (ha, he) = (a.dot(self.axis), e.dot(self.axis));
        // F(s) = qa s² + 2 qb s + qc.
        let qa = he * he - self.cos2 * e.length_squared();
        let qb = ha * he - self.cos2 * a.dot(e);
        let qc = ha * ha - self.cos2 * a.length_squared();
        let mut root = |s: f64| {
            if (0.0..=1.0).contains(&s) {
                let h = ha + s * he;
                if h >= 0.0 && h < *best {
                    *best = h;
                }
            }
        };
        if qa == 0.0 {
            if qb != 0.0 {
                root(-qc / (2.0 * qb));
            }
            return;
        }
        let disc = qb * qb - qa * qc;
        if disc < 0.0 {
            return;
        }
        // Stable roots: q = −(qb + sign(qb)·√disc), s = q/qa and qc/q.
        let q = -(qb + disc.sqrt().copysign(qb));
        root(q / qa);
        if q != 0.0 {
            root(qc / q);
        }
    }

    /// The cone query's `t` for triangle `(v0, v1, v2)` (module doc), or `None` when they do
    /// not meet.
    #[inline]
    pub fn triangle(&self, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<f32> {
        let p = [v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3()];
        let mut best = f64::INFINITY;
        // 1. Vertices.
        for &q in &p {
            if self.contains(q) {
                best = best.min((q - self.apex).dot(self.axis));
            }
        }
        // 2. Edge/surface crossings.
        for i in 0..3 {
            self.edge_crossings(p[i], p[(i + 1) % 3], &mut best);
        }
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        if n != DVec3::ZERO && best > 0.0 {
            let inside =
                |q: DVec3| (0..3).all(|i| (p[(i + 1) % 3] - p[i]).cross(q - p[i]).dot(n) >= 0.0);
            let off = n.dot(p[0] - self.apex);
            // 3. The apex in the triangle.
            if off == 0.0 && inside(self.apex) {
                return Some(0.0);
            }
            // 4. The two generators in the plane of the axis and the normal.
            // u: unit, perpendicular to the axis, in span(d, n).
            let nn = n / n.length();
            let g = nn - self.axis * nn.dot(self.axis);
            let u = if g.length_squared() > 1e-24 {
                g.normalize()
            } else {
                self.axis.any_orthonormal_vector()
            };
            for side in [1.0, -1.0] {
                let r = self.axis * self.cos + u * (side * self.sin);
                let s = off / n.dot(r);
                if s.is_finite() && s >= 0.0 && s * self.cos < best && inside(self.apex + r * s) {
                    best = s * self.cos;
                }
            }
        }
        best.is_finite().then_some(best as f32)
    }
}

/// [`ConeF64::triangle`] for a cone given by apex, axis and half-angle (radians).
pub fn cone_triangle(apex: Vec3, axis: Vec3, half_angle: f32, tri: [Vec3; 3]) -> Option<f32> {
    ConeF64::new(apex, axis, half_angle).triangle(tri[0], tri[1], tri[2])
}

#[cfg(test)]
mod tests;
