//! Shafts: the four-sided pyramid, apex at a common ray origin, that bounds a small group of
//! rays, truncated by a cap plane; and its conservative box test (relevant-triangle shafts).
//!
//! A [`Shaft`] is fitted to directions: `m` is their normalised sum, `(u, v)` complete an
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
    /// Largest depth kept (`+inf`: no cap); set with [`Shaft::set_cap`].
    cap: f64,
    /// Smallest distance the tolerance is taken of: 0 when the rays start at the apex; for
    /// segments starting elsewhere, twice the largest distance from the apex to a segment end
    /// (the triangle test's rounding grows with the distance from the ray's origin).
    pub scale: f64,
    /// The box test's planes `n·(x - apex) + off >= 0`, structure-of-arrays: the four sides,
    /// "not behind the apex" (`m`, 0), the cap (`-m`, cap), and two that keep everything.
    nx: [f64; 8],
    ny: [f64; 8],
    nz: [f64; 8],
    off: [f64; 8],
}

impl Shaft {
    /// The shaft of apex `apex` around `dirs` (any lengths, non-zero and finite), uncapped;
    /// `None` when a direction is unusable or the group is too wide (some `m·e < MIN_COS`).
    pub fn fit(apex: DVec3, dirs: impl Iterator<Item = DVec3> + Clone) -> Option<Self> {
        // Any positive combination of the directions is inside their cone: their plain sum.
        let mut sum = DVec3::ZERO;
        for d in dirs.clone() {
            let l2 = d.length_squared();
            if !(l2 > 0.0 && l2.is_finite()) {
                return None;
            }
            sum += d;
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
            let z = m.dot(d);
            if !(z > 0.0 && z * z >= MIN_COS * MIN_COS * d.length_squared()) {
                return None;
            }
            let iz = 1.0 / z;
            let (pu, pv) = (u.dot(d) * iz, v.dot(d) * iz);
            (u0, u1, v0, v1) = (u0.min(pu), u1.max(pu), v0.min(pv), v1.max(pv));
        }
        Some(Self::around(apex, m, u, v, [u0, u1, v0, v1]))
    }

    /// [`Shaft::fit`] of the directions `(dx[k], dy[k], dz[k])` (equal lengths), written for
    /// the compiler to vectorise: no early exit, the sum in four partial sums (any positive
    /// combination of the directions is inside their cone, so its rounding does not matter).
    #[inline(always)]
    pub fn fit_slices(apex: DVec3, dx: &[f32], dy: &[f32], dz: &[f32]) -> Option<Self> {
        let n = dx.len();
        let (dy, dz) = (&dy[..n], &dz[..n]);
        let d = |k: usize| DVec3::new(dx[k] as f64, dy[k] as f64, dz[k] as f64);
        let mut part = [DVec3::ZERO; 4];
        for k in 0..n {
            part[k % 4] += d(k);
        }
        let m = ((part[0] + part[1]) + (part[2] + part[3])).try_normalize()?;
        let u = m.any_orthonormal_vector();
        let v = m.cross(u);
        let mut ok = true;
        let (mut u0, mut u1, mut v0, mut v1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for k in 0..n {
            let d = d(k);
            let (z, l2) = (m.dot(d), d.length_squared());
            ok &= z > 0.0 && z * z >= MIN_COS * MIN_COS * l2 && l2.is_finite();
            let iz = 1.0 / z;
            let (pu, pv) = (u.dot(d) * iz, v.dot(d) * iz);
            u0 = if pu < u0 { pu } else { u0 };
            u1 = if pu > u1 { pu } else { u1 };
            v0 = if pv < v0 { pv } else { v0 };
            v1 = if pv > v1 { pv } else { v1 };
        }
        ok.then(|| Self::around(apex, m, u, v, [u0, u1, v0, v1]))
    }

    /// The shaft of apex `apex` and frame `(m, u, v)` around the projected rectangle
    /// `[u0, u1] × [v0, v1]` (padded by `PAD`), uncapped.
    fn around(apex: DVec3, m: DVec3, u: DVec3, v: DVec3, [u0, u1, v0, v1]: [f64; 4]) -> Self {
        let (u0, u1, v0, v1) = (u0 - PAD, u1 + PAD, v0 - PAD, v1 + PAD);
        let sides = [u - u0 * m, u1 * m - u, v - v0 * m, v1 * m - v].map(|n| n.normalize());
        let planes = [
            sides[0],
            sides[1],
            sides[2],
            sides[3],
            m,
            -m,
            DVec3::ZERO,
            DVec3::ZERO,
        ];
        let mut shaft = Self {
            apex,
            m,
            sides,
            cap: f64::INFINITY,
            scale: 0.0,
            nx: planes.map(|n| n.x),
            ny: planes.map(|n| n.y),
            nz: planes.map(|n| n.z),
            off: [0.0; 8],
        };
        shaft.set_cap(f64::INFINITY);
        shaft
    }

    /// Keeps only points of depth `<= cap` (`+inf`: no cap).
    pub fn set_cap(&mut self, cap: f64) {
        self.cap = cap;
        // An infinite cap keeps everything: a plane with offset +inf (0·x + inf >= 0).
        self.off[5] = cap;
    }

    /// The cap depth.
    pub fn cap(&self) -> f64 {
        self.cap
    }

    /// Depth along `m` of the point at `t` on a ray from the apex with direction `d`.
    #[inline]
    pub fn depth(&self, d: Vec3, t: f32) -> f64 {
        t as f64 * self.m.dot(d.as_dvec3())
    }

    /// Depth along `m` of the point at `t` on the ray `o + t·d` (increasing in `t` for rays
    /// inside the shaft); [`Shaft::depth`] when `o` is the apex.
    #[inline]
    pub fn depth_from(&self, o: Vec3, d: Vec3, t: f32) -> f64 {
        self.m.dot(o.as_dvec3() - self.apex) + t as f64 * self.m.dot(d.as_dvec3())
    }

    /// True when the box `[lo, hi]` is certainly outside the shaft (see the module doc): all of
    /// it beyond one side plane, behind the apex or beyond the cap, by `TOL` times its farthest
    /// corner's distance (bounded by the L1 norm, no square root).
    #[inline]
    pub fn box_outside(&self, lo: Vec3, hi: Vec3) -> bool {
        let (l, h) = (lo.as_dvec3() - self.apex, hi.as_dvec3() - self.apex);
        let far = l.abs().max(h.abs());
        let slack = -TOL * (far.x + far.y + far.z).max(self.scale);
        let mut out = false;
        for k in 0..8 {
            // The plane's value at the box corner farthest along its normal.
            let s = (self.nx[k] * l.x).max(self.nx[k] * h.x)
                + (self.ny[k] * l.y).max(self.ny[k] * h.y)
                + (self.nz[k] * l.z).max(self.nz[k] * h.z)
                + self.off[k];
            out |= s < slack;
        }
        out
    }
}

/// The box test's eight plane values at one box, for walks that split boxes: a child differs
/// from its parent on one axis only, so [`Shaft::split`] updates one term per plane instead of
/// recomputing three ([`Shaft::box_outside`] is the same test from scratch).
#[derive(Clone, Copy, Debug)]
pub struct BoxPlanes {
    s: [f64; 8],
}

impl Shaft {
    /// The plane values at `[lo, hi]`.
    #[inline]
    pub fn planes(&self, lo: Vec3, hi: Vec3) -> BoxPlanes {
        let (l, h) = (lo.as_dvec3() - self.apex, hi.as_dvec3() - self.apex);
        let mut s = [0.0; 8];
        for (k, s) in s.iter_mut().enumerate() {
            *s = (self.nx[k] * l.x).max(self.nx[k] * h.x)
                + (self.ny[k] * l.y).max(self.ny[k] * h.y)
                + (self.nz[k] * l.z).max(self.nz[k] * h.z)
                + self.off[k];
        }
        BoxPlanes { s }
    }

    /// The slack of [`Shaft::box_outside`] for `[lo, hi]`; a walk may use its root box's for
    /// every box inside it (larger slack only keeps more).
    #[inline]
    pub fn slack(&self, lo: Vec3, hi: Vec3) -> f64 {
        let (l, h) = (lo.as_dvec3() - self.apex, hi.as_dvec3() - self.apex);
        let far = l.abs().max(h.abs());
        TOL * (far.x + far.y + far.z).max(self.scale)
    }

    /// True when the box of `p` is outside by more than `slack`.
    #[inline]
    pub fn planes_outside(&self, p: &BoxPlanes, slack: f64) -> bool {
        p.s.iter().fold(false, |out, &s| out | (s < -slack))
    }

    /// The plane values of a box whose `axis` range `[lo, hi]` becomes `[nlo, nhi]`.
    #[inline]
    pub fn split(
        &self,
        p: &BoxPlanes,
        axis: usize,
        (lo, hi): (f32, f32),
        (nlo, nhi): (f32, f32),
    ) -> BoxPlanes {
        let a = self.apex[axis];
        let (l, h) = (lo as f64 - a, hi as f64 - a);
        let (nl, nh) = (nlo as f64 - a, nhi as f64 - a);
        let n = match axis {
            0 => &self.nx,
            1 => &self.ny,
            _ => &self.nz,
        };
        let mut s = p.s;
        for k in 0..8 {
            s[k] += (n[k] * nl).max(n[k] * nh) - (n[k] * l).max(n[k] * h);
        }
        BoxPlanes { s }
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
        s.set_cap(5.0);
        assert!(s.box_outside(Vec3::new(-1.0, -1.0, 6.0), Vec3::new(1.0, 1.0, 7.0)));
        assert!(!s.box_outside(Vec3::new(-1.0, -1.0, 4.0), Vec3::new(1.0, 1.0, 7.0)));
    }

    #[test]
    fn split_planes_equal_the_full_test() {
        let mut s = shaft();
        s.set_cap(8.0);
        let (lo, hi) = (Vec3::new(-3.0, -2.0, 1.0), Vec3::new(4.0, 2.5, 9.0));
        let root = s.planes(lo, hi);
        let slack = s.slack(lo, hi);
        for (axis, cut) in [(0, 1.0f32), (1, -0.5), (2, 7.5), (0, -0.9)] {
            let (mut blo, mut bhi) = (lo, hi);
            bhi[axis] = cut;
            let below = s.split(&root, axis, (lo[axis], hi[axis]), (lo[axis], cut));
            let full = s.planes(blo, bhi);
            for k in 0..8 {
                assert!((below.s[k] - full.s[k]).abs() <= 1e-12, "{axis} {k}");
            }
            assert_eq!(
                s.planes_outside(&full, slack),
                s.planes_outside(&below, slack)
            );
            blo[axis] = cut;
            bhi[axis] = hi[axis];
            let above = s.split(&root, axis, (lo[axis], hi[axis]), (cut, hi[axis]));
            let full = s.planes(blo, bhi);
            assert_eq!(
                s.planes_outside(&full, slack),
                s.planes_outside(&above, slack)
            );
            assert_eq!(
                s.box_outside(blo, bhi),
                s.planes_outside(&full, s.slack(blo, bhi))
            );
        }
    }

    #[test]
    fn slices_fit_like_the_iterator() {
        let dirs: Vec<Vec3> = (0..37)
            .map(|k| Vec3::new(0.01 * (k % 7) as f32 - 0.03, 0.002 * k as f32 - 0.04, -1.0))
            .collect();
        let soa = |a: usize| dirs.iter().map(|d| d[a]).collect::<Vec<f32>>();
        let (dx, dy, dz) = (soa(0), soa(1), soa(2));
        let apex = DVec3::new(1.0, 2.0, 3.0);
        let a = Shaft::fit(apex, dirs.iter().map(|d| d.as_dvec3())).unwrap();
        let b = Shaft::fit_slices(apex, &dx, &dy, &dz).unwrap();
        // Every direction inside both (the sums' rounding may move `m` by an ulp or so).
        for d in &dirs {
            let e = d.as_dvec3();
            assert!(a.sides.iter().chain(&b.sides).all(|n| n.dot(e) >= 0.0));
        }
        assert!((a.m - b.m).length() < 1e-12);
        // Unusable directions: zero, NaN, infinite, too wide.
        for bad in [Vec3::ZERO, Vec3::NAN, Vec3::new(0.0, f32::INFINITY, -1.0), Vec3::X] {
            let (mut x, mut y, mut z) = (dx.clone(), dy.clone(), dz.clone());
            (x[5], y[5], z[5]) = (bad.x, bad.y, bad.z);
            assert!(Shaft::fit_slices(apex, &x, &y, &z).is_none(), "{bad}");
        }
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
