//! Shafts: the four-sided pyramid, apex at a common ray origin, that bounds a small group of
//! rays, truncated by a cap plane; and its conservative box test (relevant-triangle shafts).
//!
//! A [`Shaft`] is fitted to unit directions: `m` is their normalised mean, `(u, v)` complete an
//! orthonormal frame, and each direction `e` projects to `(u·e, v·e) / (m·e)` on the plane one
//! unit along `m`; the bounding rectangle `[u0, u1] × [v0, v1]` of the projections gives four
//! planes through the apex with inward normals `u - u0·m`, `u1·m - u`, `v - v0·m`, `v1·m - v`.
//! Every fitted direction is inside by construction (the rectangle is padded by `PAD`, in f64).
//! The cap keeps points of depth `m·(x - apex) <= cap`; points behind the apex (depth < 0) are
//! outside: the shaft bounds rays for `t >= 0` only.
//!
//! **Exactness** ([`Shaft::box_outside`]). A box is declared outside only when it is entirely
//! beyond one plane by `TOL` times `R`, the largest distance from the apex to a box corner. Let a
//! ray inside the shaft (direction with `n·e >= 0` for every side normal) have a gated hit on a
//! triangle at `t`, at depth `<= cap`. The shared triangle test accepts `t` only inside the slab
//! interval of the triangle's box widened by `BOX_EXIT_SLACK` (about 4e-7 relative), so the hit
//! point lies within about `4e-7·|p - apex|` of that box, and the box has a point `q` with `n·(q -
//! apex) >= -TOL·R` for every plane and depth `<= cap + TOL·R`: the box is not declared outside;
//! nor is any kd-tree cell containing `q`. `TOL = 1e-5` leaves a factor 25 over the slack plus
//! f32 rounding of the inputs; all sums are in f64. For segments that start away from the apex
//! (shadow rays towards a light behind the apex) the hit's rounding grows with its distance from
//! the segment's origin instead, so the distance the tolerance is taken of is at least
//! [`Shaft::scale`], twice the largest apex-to-end distance.

use glam::{DVec3, Vec3};

/// Relative tolerance of [`Shaft::box_outside`] (see the module doc).
pub const TOL: f64 = 1e-5;

/// Padding of the fitted rectangle, in projected units.
const PAD: f64 = 1e-9;

/// Smallest `m·e` a fitted direction may have (the shaft must be well inside a half-space).
pub const MIN_COS: f64 = 0.2;

/// A shaft: apex, mean direction `m`, four inward side normals, and a cap depth along `m`.
#[derive(Clone, Copy, Debug)]
pub struct Shaft {
    /// Apex (the rays' common origin).
    pub apex: DVec3,
    /// Unit mean direction; depth is measured along it.
    pub m: DVec3,
    /// Inward side normals (unit).
    pub sides: [DVec3; 4],
    /// Largest depth kept (`+inf`: no cap).
    pub cap: f64,
    /// Smallest distance the tolerance is taken of: 0 when the rays start at the apex; for
    /// segments starting elsewhere, twice the largest distance from the apex to a segment end
    /// (the triangle test's rounding grows with the distance from the ray's origin).
    pub scale: f64,
}

impl Shaft {
    /// The shaft of apex `apex` around `dirs` (any lengths, non-zero and finite), uncapped;
    /// `None` when a direction is unusable or the group is too wide (some `m·e < MIN_COS`).
    pub fn fit(apex: DVec3, dirs: impl Iterator<Item = DVec3> + Clone) -> Option<Self> {
        let unit = |d: DVec3| -> Option<DVec3> {
            let l = d.length();
            (l > 0.0 && l.is_finite()).then(|| d / l)
        };
        let mut sum = DVec3::ZERO;
        for d in dirs.clone() {
            sum += unit(d)?;
        }
        let m = sum.try_normalize()?;
        let u = m.any_orthonormal_vector();
        let v = m.cross(u);
        let (mut u0, mut u1, mut v0, mut v1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for d in dirs {
            let e = unit(d)?;
            let z = m.dot(e);
            if !(z >= MIN_COS) {
                return None;
            }
            let (pu, pv) = (u.dot(e) / z, v.dot(e) / z);
            (u0, u1, v0, v1) = (u0.min(pu), u1.max(pu), v0.min(pv), v1.max(pv));
        }
        let (u0, u1, v0, v1) = (u0 - PAD, u1 + PAD, v0 - PAD, v1 + PAD);
        let sides = [u - u0 * m, u1 * m - u, v - v0 * m, v1 * m - v].map(|n| n.normalize());
        Some(Self {
            apex,
            m,
            sides,
            cap: f64::INFINITY,
            scale: 0.0,
        })
    }

    /// Depth along `m` of the point at `t` on a ray from the apex with direction `d`.
    #[inline]
    pub fn depth(&self, d: Vec3, t: f32) -> f64 {
        t as f64 * self.m.dot(d.as_dvec3())
    }

    /// True when the box `[lo, hi]` is certainly outside the shaft (see the module doc): all of
    /// it beyond one side plane, behind the apex or beyond the cap, by `TOL` times its farthest
    /// corner's distance.
    #[inline]
    pub fn box_outside(&self, lo: Vec3, hi: Vec3) -> bool {
        let (lo, hi) = (lo.as_dvec3() - self.apex, hi.as_dvec3() - self.apex);
        let far = lo.abs().max(hi.abs()).length();
        let slack = TOL * far.max(self.scale);
        for n in &self.sides {
            // The corner farthest along n.
            let c = DVec3::select(n.cmpge(DVec3::ZERO), hi, lo);
            if n.dot(c) < -slack {
                return true;
            }
        }
        // Behind the apex (rays start at t >= 0), or beyond the cap.
        let deepest = DVec3::select(self.m.cmpge(DVec3::ZERO), hi, lo);
        let shallowest = DVec3::select(self.m.cmpge(DVec3::ZERO), lo, hi);
        self.m.dot(deepest) < -slack || self.m.dot(shallowest) > self.cap + slack
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shaft() -> Shaft {
        let dirs = [
            Vec3::new(-0.1, -0.1, 1.0),
            Vec3::new(0.1, -0.1, 1.0),
            Vec3::new(0.1, 0.1, 1.0),
            Vec3::new(-0.1, 0.1, 1.0),
        ];
        Shaft::fit(DVec3::ZERO, dirs.iter().map(|d| d.as_dvec3())).unwrap()
    }

    #[test]
    fn fitted_directions_are_inside_and_boxes_around_them_are_kept() {
        let s = shaft();
        for d in [Vec3::new(-0.1, -0.1, 1.0), Vec3::new(0.0, 0.05, 1.0)] {
            let e = d.as_dvec3().normalize();
            assert!(s.sides.iter().all(|n| n.dot(e) >= -1e-12));
            // A tiny box on the ray, far out, is not outside.
            let p = d * 1000.0;
            assert!(!s.box_outside(p, p));
        }
    }

    #[test]
    fn boxes_beside_behind_and_beyond_the_cap_are_outside() {
        let mut s = shaft();
        assert!(s.box_outside(Vec3::new(1.0, -1.0, 1.0), Vec3::new(2.0, 1.0, 2.0)));
        assert!(s.box_outside(Vec3::new(-1.0, -1.0, -3.0), Vec3::new(1.0, 1.0, -1.0)));
        // A box straddling the apex is kept.
        assert!(!s.box_outside(Vec3::splat(-1.0), Vec3::splat(1.0)));
        s.cap = 5.0;
        assert!(s.box_outside(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0)));
        assert!(!s.box_outside(Vec3::new(-1.0, -1.0, 4.0), Vec3::new(1.0, 1.0, 7.0)));
    }

    #[test]
    fn unusable_groups_have_no_shaft() {
        let wide = [Vec3::X, -Vec3::X, Vec3::Y];
        assert!(Shaft::fit(DVec3::ZERO, wide.iter().map(|d| d.as_dvec3())).is_none());
        let zero = [Vec3::X, Vec3::ZERO];
        assert!(Shaft::fit(DVec3::ZERO, zero.iter().map(|d| d.as_dvec3())).is_none());
        let nan = [Vec3::X, Vec3::new(f32::NAN, 0.0, 1.0)];
        assert!(Shaft::fit(DVec3::ZERO, nan.iter().map(|d| d.as_dvec3())).is_none());
    }
}
