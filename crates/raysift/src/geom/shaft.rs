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

use super::lanes::Lanes;
use glam::{DVec3, Vec3};

/// Relative tolerance of [`Shaft::box_outside`] (see the module doc).
pub const TOL: f64 = 1e-5;

/// Padding of the fitted rectangle, in projected units.
const PAD: f64 = 1e-9;

/// Relative padding of [`Shaft::fit_lanes`]' rectangle (its f32 rounding, with a factor 3).
pub const FIT32_PAD: f64 = 4e-6;

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

    /// [`Shaft::fit`] of the directions `(dx[k], dy[k], dz[k])` (equal lengths, a multiple of
    /// `L::N`), `L::N` at a time in f32, for tiles of many rays.
    ///
    /// The frame `(m, u, v)` is f64 as in [`Shaft::fit`] (`m` from an f32 sum: any positive
    /// combination of the directions is inside their cone); the projections are computed with
    /// the frame rounded to f32, and the rectangle is padded by their error bound. Each f32 dot
    /// product with a frame vector is within `4·2^-24·|d|` of the f64 frame's (`2^-24` for
    /// rounding the frame, `3·2^-24` for the products and sums), and a kept direction has
    /// `m·d >= MIN_COS·|d|` (checked as `z² >= 1.0025·MIN_COS²·|d|²` in f32, a margin far above
    /// the rounding), so each projection `(u·d)/(m·d)` is within `1.3e-6·(1 + |p|)`, plus one
    /// rounding of the quotient: [`FIT32_PAD`]` = 4e-6·(1 + max |p|)` covers it.
    #[inline(always)]
    pub fn fit_lanes<L: Lanes>(apex: DVec3, dx: &[f32], dy: &[f32], dz: &[f32]) -> Option<Self> {
        let n = dx.len();
        assert!(n.is_multiple_of(L::N) && dy.len() == n && dz.len() == n);
        let ld = |v: &[f32], k: usize| L::from_fn(|l| v[k + l]);
        let zero = L::splat(0.0);
        let mut sum = [zero; 3];
        for k in (0..n).step_by(L::N) {
            sum = [sum[0] + ld(dx, k), sum[1] + ld(dy, k), sum[2] + ld(dz, k)];
        }
        let total = |v: L| (0..L::N).map(|l| v.lane(l) as f64).sum::<f64>();
        let m = DVec3::new(total(sum[0]), total(sum[1]), total(sum[2])).try_normalize()?;
        let u = m.any_orthonormal_vector();
        let v = m.cross(u);
        let f = |a: DVec3| {
            [
                L::splat(a.x as f32),
                L::splat(a.y as f32),
                L::splat(a.z as f32),
            ]
        };
        let (m32, u32, v32) = (f(m), f(u), f(v));
        let dot = |a: &[L; 3], d: &[L; 3]| a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
        let cos2 = L::splat((1.0025 * MIN_COS * MIN_COS) as f32);
        let big = L::splat(f32::MAX);
        let mut ok = L::mask_splat(true);
        let (mut lo_u, mut hi_u) = (L::splat(f32::INFINITY), L::splat(f32::NEG_INFINITY));
        let (mut lo_v, mut hi_v) = (lo_u, hi_u);
        for k in (0..n).step_by(L::N) {
            let d = [ld(dx, k), ld(dy, k), ld(dz, k)];
            let (z, l2) = (dot(&m32, &d), dot(&d, &d));
            ok = ok & z.cmpgt(zero) & (z * z).cmpge(cos2 * l2) & l2.cmple(big);
            let iz = L::splat(1.0) / z;
            let (pu, pv) = (dot(&u32, &d) * iz, dot(&v32, &d) * iz);
            (lo_u, hi_u) = (lo_u.min(pu), hi_u.max(pu));
            (lo_v, hi_v) = (lo_v.min(pv), hi_v.max(pv));
        }
        if L::bitmask(ok) != (1u32 << L::N) - 1 || n == 0 {
            return None;
        }
        let lanes = |v: L| (0..L::N).map(move |l| v.lane(l) as f64);
        let rect = [
            lanes(lo_u).fold(f64::INFINITY, f64::min),
            lanes(hi_u).fold(f64::NEG_INFINITY, f64::max),
            lanes(lo_v).fold(f64::INFINITY, f64::min),
            lanes(hi_v).fold(f64::NEG_INFINITY, f64::max),
        ];
        let pad = FIT32_PAD * (1.0 + rect.iter().fold(0.0f64, |a, r| a.max(r.abs())));
        let [u0, u1, v0, v1] = rect;
        Some(Self::around(
            apex,
            m,
            u,
            v,
            [u0 - pad, u1 + pad, v0 - pad, v1 + pad],
        ))
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
    fn lanes_fit_like_the_iterator() {
        use crate::geom::lanes::F32x8;
        use glam::Vec4;
        // Tiles of a narrow camera (the pad must not lose a direction on the rectangle's edge),
        // wide groups, and far-off-axis ones.
        for (spread, centre) in [(1e-4f32, 0.0f32), (0.003, 0.5), (0.3, -1.5), (1.0, 0.0)] {
            let dirs: Vec<Vec3> = (0..40)
                .map(|k| {
                    let (a, b) = ((k % 8) as f32 / 7.0 - 0.5, (k / 8) as f32 / 4.0 - 0.5);
                    Vec3::new(centre + spread * a, 0.3 * centre + spread * b, -1.0)
                })
                .collect();
            let soa = |a: usize| dirs.iter().map(|d| d[a]).collect::<Vec<f32>>();
            let (dx, dy, dz) = (soa(0), soa(1), soa(2));
            let apex = DVec3::new(1.0, 2.0, 3.0);
            let a = Shaft::fit(apex, dirs.iter().map(|d| d.as_dvec3())).unwrap();
            let b4 = Shaft::fit_lanes::<Vec4>(apex, &dx, &dy, &dz).unwrap();
            let b8 = Shaft::fit_lanes::<F32x8>(apex, &dx, &dy, &dz).unwrap();
            for d in &dirs {
                let e = d.as_dvec3();
                let sides = a.sides.iter().chain(&b4.sides).chain(&b8.sides);
                assert!(sides.clone().all(|n| n.dot(e) >= 0.0), "{spread} {d}");
            }
            assert!((a.m - b8.m).length() < 1e-6);
        }
        // Unusable directions: zero, NaN, infinite, too wide.
        let dirs = [Vec3::new(0.01, 0.0, -1.0); 8];
        for bad in [
            Vec3::ZERO,
            Vec3::NAN,
            Vec3::new(0.0, f32::INFINITY, -1.0),
            Vec3::X,
        ] {
            let mut d = dirs;
            d[5] = bad;
            let soa = |a: usize| d.iter().map(|d| d[a]).collect::<Vec<f32>>();
            let fit = Shaft::fit_lanes::<Vec4>(DVec3::ZERO, &soa(0), &soa(1), &soa(2));
            assert!(fit.is_none(), "{bad}");
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
