//! The one ray/triangle test: Möller–Trumbore (1997), the test of the DACRT, RTRPS and cone papers.
//!
//! Policy, shared by every tracer because every tracer calls this function:
//! - a hit counts when `tmin <= t <= tmax` (both ends inclusive) and `u >= 0, v >= 0, u + v <= 1`
//!   (edges and vertices inclusive);
//! - no epsilon on the determinant: only `det == 0` (ray parallel to the plane, or a triangle with
//!   zero edges) and non-finite values are rejected, so the answer does not depend on the scene's
//!   scale;
//! - degenerate triangles (zero or near-zero area) are collapsed to a point by the scene
//!   ([`is_degenerate`]), which makes both edges exactly zero and so `det == 0`: they keep their id but
//!   are never hit;
//! - the arithmetic is a fixed sequence of f32 operations (no fused multiply-add), so a given ray
//!   and triangle give bit-identical `t, u, v` in every tracer; SIMD versions must keep the order.
//!
//! The test is not watertight: a ray through a shared edge can, rarely, pass between two triangles.
//! All tracers then miss together, which is what the conformance suite checks.

use glam::Vec3;

/// Where a ray meets a triangle: distance `t` along the (unnormalised) direction and barycentric
/// `u, v` (the hit point is `(1-u-v)·v0 + u·v1 + v·v2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weight of `v1`.
    pub u: f32,
    /// Barycentric weight of `v2`.
    pub v: f32,
}

/// Intersects the ray `origin + t·dir` with triangle `(v0, v1, v2)`, accepting `tmin <= t <= tmax`.
// Negated comparisons on purpose: each `!(x >= a && ...)` rejects NaN too.
#[allow(clippy::neg_cmp_op_on_partial_ord, clippy::manual_range_contains)]
#[inline(always)]
pub fn intersect_triangle(
    origin: Vec3,
    dir: Vec3,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<TriHit> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    // `!(det != 0)` also rejects NaN.
    if !(det != 0.0) {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = origin - v0;
    let u = s.dot(p) * inv_det;
    if !(u >= 0.0 && u <= 1.0) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv_det;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv_det;
    if !(t >= tmin && t <= tmax) {
        return None;
    }
    Some(TriHit { t, u, v })
}

/// True when the triangle has (nearly) zero area: `|e1 × e2|² <= 1e-14 · |e1|²·|e2|²`, i.e. the
/// sine of its angle at `v0` is below about 1e-7, the f32 resolution (this includes coincident
/// vertices and collinear ones up to rounding), or when a coordinate is not finite.
#[allow(clippy::neg_cmp_op_on_partial_ord, clippy::nonminimal_bool)] // `!(n2 > ..)` also catches NaN
pub fn is_degenerate(v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let n2 = e1.cross(e2).length_squared();
    !(n2 > 1e-14 * e1.length_squared() * e2.length_squared())
        || !(v0.is_finite() && v1.is_finite() && v2.is_finite())
}

/// Geometric normal (not normalised, `(v1 - v0) × (v2 - v0)`).
#[inline]
pub fn normal(v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    (v1 - v0).cross(v2 - v0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const V0: Vec3 = Vec3::new(0.0, 0.0, 0.0);
    const V1: Vec3 = Vec3::new(1.0, 0.0, 0.0);
    const V2: Vec3 = Vec3::new(0.0, 1.0, 0.0);

    #[test]
    fn hits_inside_with_barycentrics() {
        let h = intersect_triangle(
            Vec3::new(0.25, 0.5, 1.0),
            -Vec3::Z,
            V0,
            V1,
            V2,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert_eq!(h.t, 1.0);
        assert_eq!(h.u, 0.25);
        assert_eq!(h.v, 0.5);
        // Back faces are hit too (no culling).
        let h = intersect_triangle(
            Vec3::new(0.25, 0.5, -2.0),
            Vec3::Z,
            V0,
            V1,
            V2,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert_eq!(h.t, 2.0);
    }

    #[test]
    fn interval_is_inclusive() {
        let o = Vec3::new(0.25, 0.25, 1.0);
        assert!(intersect_triangle(o, -Vec3::Z, V0, V1, V2, 1.0, 1.0).is_some());
        assert!(intersect_triangle(o, -Vec3::Z, V0, V1, V2, 0.0, 0.999_999).is_none());
        assert!(intersect_triangle(o, -Vec3::Z, V0, V1, V2, 1.000_001, 5.0).is_none());
    }

    #[test]
    fn misses_outside_parallel_and_degenerate() {
        assert!(intersect_triangle(
            Vec3::new(0.8, 0.8, 1.0),
            -Vec3::Z,
            V0,
            V1,
            V2,
            0.0,
            f32::INFINITY
        )
        .is_none());
        assert!(intersect_triangle(
            Vec3::new(0.2, 0.2, 1.0),
            Vec3::X,
            V0,
            V1,
            V2,
            0.0,
            f32::INFINITY
        )
        .is_none());
        // A point triangle (how the scene stores degenerate ones) is never hit.
        assert!(intersect_triangle(
            Vec3::new(0.0, 0.0, 1.0),
            -Vec3::Z,
            V0,
            V0,
            V0,
            0.0,
            f32::INFINITY
        )
        .is_none());
        // NaN direction: no hit, no panic.
        assert!(
            intersect_triangle(Vec3::ZERO, Vec3::NAN, V0, V1, V2, 0.0, f32::INFINITY).is_none()
        );
    }

    #[test]
    fn degeneracy() {
        assert!(!is_degenerate(V0, V1, V2));
        assert!(is_degenerate(V0, V0, V2));
        assert!(is_degenerate(V0, V1, Vec3::new(2.0, 0.0, 0.0)));
        assert!(is_degenerate(V0, V1, Vec3::new(0.5, 1e-9, 0.0)));
        assert!(is_degenerate(V0, V1, Vec3::new(f32::NAN, 0.0, 0.0)));
        // Tiny but well-shaped triangles are not degenerate: the test is scale-free.
        let s = 1e-6;
        assert!(!is_degenerate(V0 * s, V1 * s, V2 * s));
    }
}
