//! The one ray/triangle test: Möller–Trumbore (1997), the test of the DACRT, RTRPS and cone
//! papers, followed by a box gate that makes every tracer's culling provably exact.
//!
//! Policy, shared by every tracer because every tracer calls this function:
//! - a candidate is what Möller–Trumbore accepts: `tmin <= t <= tmax` (both ends inclusive) and
//!   `u >= 0, v >= 0, u + v <= 1` (edges and vertices inclusive); no epsilon on the determinant:
//!   only `det == 0` (ray parallel to the plane, or a triangle with zero edges) and non-finite
//!   values are rejected, so the answer does not depend on the scene's scale;
//! - **the box gate** ([`in_box_at`]): a candidate is a hit only when the ray at its computed
//!   `t` lies in the triangle's bounding box, as the shared slab test
//!   ([`SlabRay::entry`](super::SlabRay::entry), on the interval `[t, t]`) computes it. The
//!   Möller–Trumbore `t` of a ray nearly parallel to the plane is ill-conditioned: its computed
//!   point can lie far off the triangle (a "phantom" hit 30 units away was seen), and rounding
//!   accepts rays passing just outside an edge or vertex; neither is then inside the box;
//! - degenerate triangles (zero or near-zero area) are collapsed to a point by the scene
//!   ([`is_degenerate`]), which makes both edges exactly zero and so `det == 0`: they keep their id but
//!   are never hit;
//! - the arithmetic is a fixed sequence of f32 operations (no fused multiply-add), so a given ray
//!   and triangle give bit-identical `t, u, v` in every tracer; SIMD versions must keep the order.
//!
//! **Why every cull is exact.** The slab test is monotone in the box: for a box `N` containing
//! the box `T` (every component of `N.min <= T.min`, `N.max >= T.max`), each per-axis entry
//! `(near - o)·(1/d)` of `N` is at most `T`'s and each exit at least `T`'s (f32 subtraction and
//! multiplication are monotone), and the max, min, widening and lowering that follow are
//! monotone too; so the slab interval of `N` contains that of `T`. A hit at `t` has `t` in
//! `T`'s interval (the gate), hence in the interval of every box that contains `T`: a BVH node
//! holding the triangle is entered whenever the ray's clip interval contains `t`, with an entry
//! distance `<= t`, so neither the visit nor the ordered-traversal cut (`entry <= best t`, ties
//! included) can lose it. Space-dividing tracers (DACRT) keep the pair in one child of every
//! split: the slab interval of `T ∩ C` is the intersection of `T`'s and `C`'s (per-axis
//! entries and exits are the same numbers), and splitting `C` by an axis plane splits it into
//! two intervals whose union is the parent's (the plane's `(s - o)·(1/d)` is one number), so `t`
//! lies in the slab interval of `T ∩ L` or of `T ∩ R`, and the child whose interval holds it
//! keeps both the triangle (its box meets that child exactly) and the ray.
//!
//! The test is not watertight: a ray through a shared edge can, rarely, pass between two
//! triangles. All tracers then miss together, which is what the conformance suite checks.

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
    if !in_box_at(origin, dir, v0, v1, v2, t) {
        return None;
    }
    Some(TriHit { t, u, v })
}

/// The box gate: true when the ray at `t` is inside the triangle's bounding box as the shared
/// slab test computes it ([`SlabRay::entry`](super::SlabRay::entry) on the box with the interval
/// `[t, t]`). A hit counts only where this holds, so every box cull that uses the same slab
/// arithmetic on a box containing the triangle's box keeps every hit: the slab test is monotone in
/// the box (see the module doc). Evaluated only for candidates that passed the rest of the test.
#[inline(always)]
pub fn in_box_at(origin: Vec3, dir: Vec3, v0: Vec3, v1: Vec3, v2: Vec3, t: f32) -> bool {
    let (lo, hi) = (v0.min(v1).min(v2), v0.max(v1).max(v2));
    super::SlabRay::new(origin, dir)
        .entry(lo, hi, t, t)
        .is_some()
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
    use rand::{Rng, SeedableRng};

    /// Rays nearly in the plane of a triangle far from their origin: Möller–Trumbore alone
    /// accepts some whose computed point lies far off the triangle (the phantom hits); the gate
    /// refuses every one whose point is outside the box, and keeps the well-conditioned ones.
    #[test]
    fn the_box_gate_refuses_phantom_hits() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let (a, b, c) = (
            Vec3::ZERO,
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.2, 1.0, 0.05),
        );
        let lo = a.min(b).min(c) - Vec3::splat(1e-5);
        let hi = a.max(b).max(c) + Vec3::splat(1e-5);
        let (mut phantoms, mut hits) = (0, 0);
        for _ in 0..200_000 {
            let target = a + (b - a) * rng.gen::<f32>() + (c - a) * rng.gen::<f32>() * 0.5;
            let n = (b - a).cross(c - a).normalize();
            let inplane = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), 0.0)
                .reject_from(n)
                .normalize_or(Vec3::X);
            let d = (inplane + n * 10f32.powf(rng.gen_range(-8.0..-2.0))).normalize();
            let o = target - d * 30.0;
            let e1 = b - a;
            let e2 = c - a;
            let p = d.cross(e2);
            let det = e1.dot(p);
            // Möller–Trumbore without the gate.
            let mt = det != 0.0 && {
                let inv = 1.0 / det;
                let s = o - a;
                let u = s.dot(p) * inv;
                let q = s.cross(e1);
                let v = d.dot(q) * inv;
                let t = e2.dot(q) * inv;
                let pt = o + d * t;
                let ok = (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t >= 0.0;
                if ok && !(pt.cmpge(lo).all() && pt.cmple(hi).all()) {
                    phantoms += 1;
                }
                ok
            };
            if let Some(h) = intersect_triangle(o, d, a, b, c, 0.0, f32::INFINITY) {
                hits += 1;
                let pt = o + d * h.t;
                assert!(
                    pt.cmpge(lo).all() && pt.cmple(hi).all(),
                    "{o:?} {d:?} {h:?}: {pt:?}"
                );
                assert!(mt);
            }
        }
        assert!(
            phantoms > 100,
            "the case must exercise phantoms: {phantoms}"
        );
        assert!(hits > 100_000, "well-conditioned hits are kept: {hits}");
    }

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
