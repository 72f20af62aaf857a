//! A whole group of rays from one origin rejected by one triangle at once: the proof that the
//! shared triangle test ([`super::intersect_triangle`]) refuses every ray of a circular cone of
//! directions on its barycentric signs alone.
//!
//! **Why it can be proven.** For rays from one origin `o`, the shared test's three numbers
//! before the division are linear in the direction `d`: `det = e1·(d × e2) = d·(e2 × e1)`,
//! `u·det = s·(d × e2) = d·(e2 × s)` and `v·det = d·q` with `q = s × e1` (`s = o − v0`,
//! `e1`, `e2` and `q` the f32 values the test itself computes). These are the common-origin
//! form's planes through `o` and each edge (§3.2 of Suzuki et al.). A linear form is positive
//! on a whole cone (axis `z`, half-angle `α`) when its minimum over the cone's unit directions,
//! `(a·z)·cos α − |a × z|·sin α`, is. The test computes them in f32, so each form must clear
//! its rounding bound:
//! - `det` and `u·det`: a cross product then a dot product, within
//!   `8·2⁻²⁴·|d|·Σᵢ |aᵢ|·(|e2ⱼ| + |e2ₖ|)` (`a = e1` or `s`; each cross component is within
//!   `2.01·2⁻²⁴` of its two products, the dot adds `3.01·2⁻²⁴`: 5.1 used as 8);
//! - `v·det`: one dot product, within `4·2⁻²⁴·|d|·|q|₁`.
//!
//! A ray is refused when `u < 0` (`u·det` and `det` of opposite signs; the quotient cannot
//! round to zero, checked), when `v < 0`, or when `u + v > 1`. For the last, with `det > 0`,
//! `u·det + v·det − det` must exceed the three bounds, twice the `det` bound and `10⁻⁵·|det|`.
//! That covers the two roundings of each quotient and the one of the sum.
//!
//! The cone must hold every ray: [`RayCone::of`] measures it from the rays, with a margin for
//! its own f64 rounding, and refuses groups wider than 60°.

use glam::{DVec3, Vec3};

/// f32 unit roundoff.
const U: f64 = 1.0 / (1u64 << 24) as f64;

/// A circular cone holding the directions of a group of rays: unit axis and half-angle.
#[derive(Clone, Copy, Debug)]
pub struct RayCone {
    z: DVec3,
    cos: f64,
    sin: f64,
}

impl RayCone {
    /// The cone about `axis` that holds every direction of `dirs`. `None` when the axis or a
    /// direction is zero or not finite, or a direction lies more than 60° from the axis.
    pub fn of(axis: Vec3, dirs: impl Iterator<Item = Vec3>) -> Option<Self> {
        let z = axis.as_dvec3().normalize_or_zero();
        if z == DVec3::ZERO || !z.is_finite() {
            return None;
        }
        let mut cos = 1.0f64;
        for d in dirs {
            let d = d.as_dvec3();
            let l = d.length();
            if !(l > 0.0 && l.is_finite()) {
                return None;
            }
            cos = cos.min(d.dot(z) / l);
        }
        // f64 rounding of the cosines (a few 1e-16), with room.
        Self::with_cos(axis, cos - 1e-12)
    }

    /// The cone about unit `axis` (normalised again here) with half-angle cosine `cos`, which the
    /// caller guarantees is at most that of every direction it stands for. `None` above 60°.
    // Negated comparison on purpose: it rejects a NaN cosine too.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    pub fn with_cos(axis: Vec3, cos: f64) -> Option<Self> {
        let z = axis.as_dvec3().normalize_or_zero();
        if z == DVec3::ZERO || !z.is_finite() || !(cos >= 0.5) {
            return None;
        }
        let cos = cos.min(1.0);
        Some(Self {
            z,
            cos,
            sin: (1.0 - cos * cos).max(0.0).sqrt() + 1e-12,
        })
    }

    /// The least value of `a·d` over the cone's unit directions (exact when positive), less a
    /// margin for its own f64 rounding.
    #[inline]
    fn min_of(&self, a: DVec3) -> f64 {
        let m = a.dot(self.z) * self.cos - a.cross(self.z).length() * self.sin;
        m - 1e-12 * a.length()
    }

    /// True when the shared triangle test refuses triangle `(v0, v1, v2)` for every ray from
    /// `origin` whose direction lies in the cone, whatever its `tmin` and `tmax`.
    pub fn misses(&self, origin: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> bool {
        let f = EdgeForms::new(origin, v0, v1, v2);
        // Orient so that `det > 0` on the whole cone, or give up.
        let sign = if self.min_of(f.det) > f.cd {
            1.0
        } else if self.min_of(-f.det) > f.cd {
            -1.0
        } else {
            return false;
        };
        let [_, u, v, sum] = f.refusals(sign);
        // `u < 0`, `v < 0` or `u + v > 1` on every ray.
        [u, v, sum].iter().any(|&(a, c)| self.min_of(-a) > c)
    }
}

/// The shared triangle test's barycentric numbers for rays from one origin, as linear forms of
/// the direction, with their f32 rounding bounds per unit of `|d|` (module doc): `det = d·det`,
/// `u·det = d·u`, `v·det = d·v`. Shared by [`RayCone`] and the aligned ray-plane form
/// ([`super::aligned`]).
#[derive(Clone, Copy, Debug)]
pub struct EdgeForms {
    /// `det = d·det`.
    pub det: DVec3,
    /// `u·det = d·u`.
    pub u: DVec3,
    /// `v·det = d·v`.
    pub v: DVec3,
    /// Rounding bound of `det`, per unit of `|d|`.
    pub cd: f64,
    /// Rounding bound of `u·det`.
    pub cu: f64,
    /// Rounding bound of `v·det`.
    pub cv: f64,
}

impl EdgeForms {
    /// The forms of triangle `(v0, v1, v2)` for rays from `origin`, from the f32 values the
    /// test itself computes.
    pub fn new(origin: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        let (e1, e2, s) = (v1 - v0, v2 - v0, origin - v0);
        let q = s.cross(e1);
        let f = |v: Vec3| v.as_dvec3();
        let (e1, e2, s, q) = (f(e1), f(e2), f(s), f(q));
        let k = |a: DVec3| {
            let (a, b) = (a.abs(), e2.abs());
            a.x * (b.y + b.z) + a.y * (b.x + b.z) + a.z * (b.x + b.y)
        };
        Self {
            det: e2.cross(e1),
            u: e2.cross(s),
            v: q,
            cd: 8.0 * U * k(e1),
            cu: 8.0 * U * k(s),
            cv: 4.0 * U * (q.x.abs() + q.y.abs() + q.z.abs()),
        }
    }

    /// With `det` of sign `sign` (±1) proven on every ray (`sign·det > cd`), the forms and
    /// bounds `(a, c)` whose value `d·a < −c` (`|d| = 1`) on a ray proves that the test refuses
    /// it: `u < 0` (the quotient well away from zero), `v < 0`, `u + v > 1` (the three bounds,
    /// twice the `det` bound and `10⁻⁵·|det|`: the two roundings of each quotient and the one of
    /// the sum). First the oriented `det` with its bound.
    pub fn refusals(&self, sign: f64) -> [(DVec3, f64); 4] {
        let (d, u, v) = (self.det * sign, self.u * sign, self.v * sign);
        // The quotient `u·det / det` must not round to zero: `|u·det| > 1e-30·|det|`.
        let most_det = d.length() + self.cd;
        let tiny = 1e-30 * most_det;
        [
            (d, self.cd),
            (u, self.cu.max(tiny)),
            (v, self.cv.max(tiny)),
            (
                d - u - v,
                self.cu + self.cv + 2.0 * self.cd + 1e-5 * d.length(),
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::intersect_triangle;
    use rand::{Rng, SeedableRng};

    /// Whenever a cone is proven to miss a triangle, no ray of it hits: directions sampled
    /// inside the cone and on its boundary, origins on, just off and far from the triangle's
    /// plane and at its vertices and edges, small and huge scales. Both outcomes must occur.
    #[test]
    fn proven_misses_are_misses() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let (mut proven, mut kept) = (0u32, 0u32);
        for n in 0..20_000 {
            let scale = [1e-3f32, 1.0, 1e4][n % 3];
            let mut r = |a: f32| rng.gen_range(-a..a);
            let v0 = Vec3::new(r(1.0), r(1.0), r(1.0)) * scale;
            let v1 = v0 + Vec3::new(r(1.0), r(1.0), r(0.1)) * scale;
            let v2 = v0 + Vec3::new(r(1.0), r(1.0), r(0.1)) * scale;
            let (a, b) = (r(1.0).abs(), r(1.0).abs());
            let on = v0 + (v1 - v0) * a * 0.5 + (v2 - v0) * b * 0.5;
            let nrm = (v1 - v0).cross(v2 - v0).normalize_or_zero();
            let origin = match n % 5 {
                0 => on,
                1 => on + nrm * 1e-4 * scale,
                2 => v1,
                3 => (v0 + v2) * 0.5,
                _ => Vec3::new(r(2.0), r(2.0), r(2.0)) * scale,
            };
            let axis = Vec3::new(r(1.0), r(1.0), r(1.0));
            let half = r(0.6).abs();
            let (t, b2) = axis.normalize().any_orthonormal_pair();
            // Rays of the cone: inside, and on its boundary.
            let dirs: Vec<Vec3> = (0..32)
                .map(|k| {
                    let phi = k as f32 * 0.196;
                    let rr = if k % 2 == 0 {
                        half.tan()
                    } else {
                        half.tan() * r(1.0).abs()
                    };
                    (axis.normalize() + (t * phi.cos() + b2 * phi.sin()) * rr) * (1.0 + r(0.5))
                })
                .collect();
            let Some(cone) = RayCone::of(axis, dirs.iter().copied()) else {
                continue;
            };
            if cone.misses(origin, v0, v1, v2) {
                proven += 1;
                for d in &dirs {
                    let h = intersect_triangle(origin, *d, v0, v1, v2, f32::MIN, f32::MAX);
                    assert!(h.is_none(), "case {n}: proven miss hit: {d} {h:?}");
                }
            } else {
                kept += 1;
            }
        }
        assert!(proven > 2_000 && kept > 2_000, "{proven} {kept}");
    }

    /// A cone around a direction that hits the triangle's interior is never proven to miss.
    #[test]
    fn cones_through_the_triangle_are_kept() {
        let (v0, v1, v2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let o = Vec3::new(0.2, 0.2, 1.0);
        for w in [1e-6f32, 1e-3, 0.3] {
            let dirs = [Vec3::new(0.0, 0.0, -1.0), Vec3::new(w, 0.0, -1.0)];
            let cone = RayCone::of(Vec3::new(0.0, 0.0, -1.0), dirs.into_iter()).unwrap();
            assert!(!cone.misses(o, v0, v1, v2));
        }
        // Wider than 60°: refused.
        assert!(RayCone::of(Vec3::Z, [Vec3::X].into_iter()).is_none());
    }
}
