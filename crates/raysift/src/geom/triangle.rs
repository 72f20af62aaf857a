//! The one ray/triangle test: Möller–Trumbore (1997), the test of the DACRT, RTRPS and cone
//! papers, followed by a box gate that makes every tracer's culling provably exact.
//!
//! Policy, shared by every tracer because every tracer calls this function:
//! - a candidate is what Möller–Trumbore accepts: `tmin <= t <= tmax` (both ends inclusive) and
//!   `u >= 0, v >= 0, u + v <= 1` (edges and vertices inclusive); no epsilon on the determinant:
//!   only `det == 0` (ray parallel to the plane, or a triangle with zero edges) and non-finite
//!   values are rejected, so the answer does not depend on the scene's scale;
//! - **the box gate** ([`box_gate`]): a candidate is a hit only when the ray meets the
//!   triangle's bounding box, as the shared slab test
//!   ([`SlabRay::interval`](super::SlabRay::interval)) computes it, and its computed `t` lies in
//!   that slab interval or within [`GATE_TOLERANCE`] of it, in which case `t` is moved to the
//!   interval's nearer end. The Möller–Trumbore `t` of a ray nearly parallel to the plane is
//!   ill-conditioned: its computed point can lie far off the triangle (a "phantom" hit 30 units
//!   away was seen): refused. A ray far from `v0` hitting a triangle in an axis plane (whose box
//!   is flat) gets a `t` a few ulps off the plane: moved onto it;
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
//! `T`'s interval (the gate puts it there), hence in the interval of every box that contains `T`: a BVH node
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
    let (lo, hi) = (v0.min(v1).min(v2), v0.max(v1).max(v2));
    let reach = GATE_TOLERANCE * gate_scale(origin, lo, hi);
    let dmax = dir.abs().max_element();
    if !may_reach(t, tmin, tmax, dmax, reach) {
        return None;
    }
    let t = box_gate(origin, dir, lo, hi, t, reach)?;
    if !(t >= tmin && t <= tmax) {
        return None;
    }
    Some(TriHit { t, u, v })
}

/// The largest coordinate magnitude of the ray's origin and the triangle's box `[lo, hi]` (that
/// of its corners): the scale [`box_gate`]'s tolerance is relative to (`max` is exact, so any
/// order of evaluation gives this value).
#[inline(always)]
pub fn gate_scale(origin: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    origin.abs().max(lo.abs()).max(hi.abs()).max_element()
}

/// False only when [`box_gate`] cannot move `t` into `[tmin, tmax]`: it moves `t` by at most
/// `reach / |dir|∞` (`reach = GATE_TOLERANCE · gate_scale`), and its own check
/// `|t − moved| · |dir|∞ <= reach` implies `(t − tmax) · dmax <= reach` when `moved <= tmax < t`
/// for any `0 <= dmax <= |dir|∞` (f32 subtraction and multiplication are monotone), likewise
/// below `tmin`; `dmax` may so be a lower bound shared by many rays. So this cheap test,
/// run first, never changes a result; it spares the gate's divisions for the many candidates
/// that lie beyond the closest hit so far. A NaN product (`∞ · 0`, a NaN `t`) passes: the gate
/// decides.
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn may_reach(t: f32, tmin: f32, tmax: f32, dmax: f32, reach: f32) -> bool {
    !((t - tmax) * dmax > reach) && !((tmin - t) * dmax > reach)
}

/// How far (in coordinate units, relative to the largest coordinate of the ray's origin and the
/// triangle's corners) the Möller–Trumbore point may lie off the triangle's box and still be
/// moved into it by [`box_gate`] (measured along the ray as `|Δt| · |dir|∞`): `2^-14`, that is
/// 512 to 1024 units in the last place of the largest coordinate, room for the test's rounding
/// on rays down to a fraction of a degree from the plane, and far below the phantom hits it
/// refuses (BENCHMARKS.md, "The exact contract").
pub const GATE_TOLERANCE: f32 = 1.0 / 16384.0;

/// The box gate: the candidate distance `t` moved into the triangle's slab interval (the shared
/// slab test [`SlabRay::interval`](super::SlabRay::interval) on the triangle's bounding box,
/// unclipped), or `None` when the ray misses the box or `t` lies farther off it than
/// [`GATE_TOLERANCE`] allows. A hit's distance is therefore always inside the interval every box
/// cull computes for a box containing the triangle's (the slab test is monotone in the box, see
/// the module doc), so no cull can lose it. Moving `t` matters for triangles in an axis plane
/// (walls, floors): their box is flat, its slab interval is the plane crossing to within a few
/// ulps, and the Möller–Trumbore `t` of a ray far from `v0` is off by more than that; the moved
/// `t` is the better one (one subtraction and one multiplication from the plane). The result
/// does not depend on the ray's `[tmin, tmax]`, so every traversal order sees the same hit.
/// Evaluated only for candidates that passed the barycentric tests and [`may_reach`]; `[lo, hi]`
/// is the triangle's box and `reach = GATE_TOLERANCE · gate_scale(origin, lo, hi)` (passed in:
/// four-wide tests compute it once per triangle). A `t` inside the interval is kept as it is
/// (most candidates: `|dir|∞` is then not needed).
#[inline(always)]
pub fn box_gate(origin: Vec3, dir: Vec3, lo: Vec3, hi: Vec3, t: f32, reach: f32) -> Option<f32> {
    let (enter, exit) =
        super::SlabRay::new(origin, dir).interval(lo, hi, f32::NEG_INFINITY, f32::INFINITY)?;
    if t >= enter && t <= exit {
        return Some(t);
    }
    let moved = if t < enter { enter } else { exit };
    // A NaN `t` (or scale) fails this comparison.
    if (t - moved).abs() * dir.abs().max_element() <= reach {
        Some(moved)
    } else {
        None
    }
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

/// A lower bound on the length `t·|dir|` of every hit the shared test reports, for any ray
/// from `origin` (with `tmin >= 0`), on a triangle with box `[lo, hi]`: the distance from
/// `origin` to the box, lowered by `1e-5` relative. Why: the gate puts `t` in the slab
/// interval, whose entry is at least every axis's `(near − o)·(1/d)`, computed and then lowered
/// (six roundings of `ε/2`, and `BOX_ENTRY_SLACK`), so on each axis `|t·d_a|` is within a
/// relative `6ε` of the origin's gap `g_a` to the box or beyond it; the point's distance
/// `t·|dir|` is then at least `|g|·(1 − 6ε)`, and `|g|` computed in f32 is within `3ε` of
/// the exact one. (Rays moving away from the box on an axis where the origin is outside it
/// have an empty interval, or one below 0: no hit.) With [`hit_reach_ceil`], a z-buffer cull
/// for rays from one point: the front-to-back tile leaves of `dacrt`.
#[inline]
pub fn hit_reach_floor(origin: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    let g = (lo - origin).max(origin - hi).max(Vec3::ZERO);
    g.length() * (1.0 - 1e-5)
}

/// An upper bound on `t·|dir|` (exact) for f32 `t >= 0` and `dir`: the computed product raised
/// by `8ε` relative (the squares, their sum, the root and the product round by `ε/2` each).
/// A triangle whose [`hit_reach_floor`] exceeds it has no hit at a `t` up to this one.
#[inline]
pub fn hit_reach_ceil(t: f32, dir: Vec3) -> f32 {
    t * dir.length() * (1.0 + 8.0 * f32::EPSILON)
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

    /// Every hit the shared test reports lies at least `hit_reach_floor` from the origin, and
    /// `hit_reach_ceil` bounds `t·|d|` from above: random rays at scales from 1e-3 to 1e4,
    /// axis-plane triangles (flat boxes, where the gate moves `t`), grazing rays, origins inside
    /// the box; not vacuous (on most triangles some hit is within twice the floor).
    #[test]
    fn hit_reach_bounds_every_hit() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let (mut hits, mut tight) = (0, 0);
        for n in 0..20_000 {
            let scale = 10f32.powf(rng.gen_range(-3.0..4.0));
            let r = |rng: &mut rand_pcg::Pcg64Mcg| {
                Vec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                )
            };
            let mut v = [r(&mut rng), r(&mut rng), r(&mut rng)].map(|p| p * scale);
            if n % 3 == 0 {
                // In an axis plane.
                let z = v[0].z;
                v[1].z = z;
                v[2].z = z;
            }
            let o = if n % 7 == 0 {
                (v[0] + v[1] + v[2]) / 3.0 + r(&mut rng) * 0.01 * scale
            } else {
                r(&mut rng) * 3.0 * scale
            };
            let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
            let floor = hit_reach_floor(o, lo, hi);
            let mut best = f32::INFINITY;
            for _ in 0..20 {
                let (a, b) = (rng.gen::<f32>(), rng.gen::<f32>());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let target = v[0] + (v[1] - v[0]) * a + (v[2] - v[0]) * b;
                let d = (target - o) * rng.gen_range(0.1..10.0);
                if let Some(h) = intersect_triangle(o, d, v[0], v[1], v[2], 0.0, f32::INFINITY) {
                    hits += 1;
                    let exact = h.t as f64 * d.as_dvec3().length();
                    assert!(
                        floor as f64 <= exact,
                        "floor {floor} > {exact} for {v:?} from {o}"
                    );
                    assert!(hit_reach_ceil(h.t, d) as f64 >= exact);
                    best = best.min(exact as f32);
                }
            }
            tight += (best.is_finite() && best <= 2.0 * floor) as usize;
        }
        assert!(
            hits > 100_000 && tight > 5_000,
            "hits {hits}, tight {tight}"
        );
    }

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
                // The slab's slack at distance 30 is 30 · 3.6e-7 = 1.1e-5, plus the rounding of
                // `o + d·t` (ulp(30) = 1.9e-6).
                let slack = Vec3::splat(2e-5);
                assert!(
                    pt.cmpge(lo - slack).all() && pt.cmple(hi + slack).all(),
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

    /// A triangle in the plane x = 16.218 (a Sponza wall) and rays from a box around it aimed at it:
    /// every ray that hits it well inside (f64 barycentrics at least 1e-3 from an edge, not
    /// grazing) is hit, at the f64 distance to 1e-5 relative. Without moving `t` onto the flat box,
    /// the gate refused some of them (counted: the case must contain them).
    #[test]
    fn axis_plane_triangles_are_hit_where_f64_hits_them() {
        let (a, b, c) = (
            Vec3::new(16.218_04, 0.093313, 7.171_489),
            Vec3::new(16.218_04, 3.892_572, 3.638_583),
            Vec3::new(16.218_04, 3.678_313, 3.495_419),
        );
        let f = |v: Vec3| glam::DVec3::new(v.x as f64, v.y as f64, v.z as f64);
        let (lo, hi) = (Vec3::new(-17.4, -0.9, -7.8), Vec3::new(17.4, 15.6, 7.8));
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
        let (mut inside, mut unmoved_refused) = (0, 0);
        for _ in 0..100_000 {
            let o = lo + (hi - lo) * Vec3::new(rng.gen(), rng.gen(), rng.gen());
            // Aimed at a random point of the triangle (and beyond or short of it by up to 2x).
            let (r1, r2): (f32, f32) = (rng.gen(), rng.gen());
            let (r1, r2) = if r1 + r2 > 1.0 {
                (1.0 - r1, 1.0 - r2)
            } else {
                (r1, r2)
            };
            let target = a + (b - a) * r1 + (c - a) * r2;
            let d = (target - o) * rng.gen_range(0.5..2.0);
            // f64 Möller–Trumbore.
            let (o64, d64, a64) = (f(o), f(d), f(a));
            let (e1, e2) = (f(b) - a64, f(c) - a64);
            let p = d64.cross(e2);
            let det = e1.dot(p);
            let s = o64 - a64;
            let (u, q) = (s.dot(p) / det, s.cross(e1));
            let (v, t) = (d64.dot(q) / det, e2.dot(q) / det);
            let cos = d64.normalize().dot(e1.cross(e2).normalize()).abs();
            if !(u > 1e-3 && v > 1e-3 && u + v < 1.0 - 1e-3 && t > 1e-3 && cos > 1e-2) {
                continue;
            }
            inside += 1;
            let h = intersect_triangle(o, d, a, b, c, 0.0, f32::INFINITY)
                .unwrap_or_else(|| panic!("{o:?} {d:?} misses, f64 t = {t}"));
            assert!(
                ((h.t as f64) - t).abs() <= 1e-5 * t,
                "{o:?} {d:?}: {} vs {t}",
                h.t
            );
            let slab = crate::geom::SlabRay::new(o, d);
            let (lo_t, hi_t) = (a.min(b).min(c), a.max(b).max(c));
            let t_mt = {
                let (e1, e2) = (b - a, c - a);
                let det = e1.dot(d.cross(e2));
                e2.dot((o - a).cross(e1)) * (1.0 / det)
            };
            if slab.entry(lo_t, hi_t, t_mt, t_mt).is_none() {
                unmoved_refused += 1;
            }
        }
        assert!(inside > 10_000, "the case must hit the wall: {inside}");
        assert!(
            unmoved_refused > 10,
            "the case must contain rays the unmoved gate refused: {unmoved_refused}"
        );
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
