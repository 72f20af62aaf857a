//! Axis-aligned bounding boxes and the slab ray/box test shared by all box-based tracers.

use glam::{BVec4A, Mat4, Vec3, Vec4};
use serde::Serialize;

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so growing it by any point
/// gives that point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The box containing nothing.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The box from two corners (no ordering check).
    #[inline]
    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// The smallest box around the points.
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.grow(p))
    }

    /// True when the box contains no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// This box grown to contain `p`.
    #[inline]
    pub fn grow(self, p: Vec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The smallest box containing both.
    #[inline]
    pub fn union(self, o: Aabb) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// The overlap of both (possibly empty).
    #[inline]
    pub fn intersection(self, o: Aabb) -> Self {
        Self {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    /// `max - min` (negative components for the empty box).
    #[inline]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// The centre point.
    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Corner `k` of 8: bit 0 of `k` picks `max.x` over `min.x`, bit 1 the y side, bit 2 z.
    #[inline]
    pub fn corner(&self, k: usize) -> Vec3 {
        Vec3::new(
            if k & 1 == 0 { self.min.x } else { self.max.x },
            if k & 2 == 0 { self.min.y } else { self.max.y },
            if k & 4 == 0 { self.min.z } else { self.max.z },
        )
    }

    /// Index of the longest axis (0 = x, 1 = y, 2 = z); ties go to the lower axis.
    #[inline]
    pub fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Surface area, 0 for the empty box (the SAH's measure).
    #[inline]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// True when `p` is inside or on the boundary.
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// True when `o` lies wholly inside this box.
    #[inline]
    pub fn contains_box(&self, o: &Aabb) -> bool {
        o.min.cmpge(self.min).all() && o.max.cmple(self.max).all()
    }

    /// Slab test: the parametric interval `[t_enter, t_exit]` of the ray inside the box, clipped
    /// to `[tmin, tmax]`, or `None` when it is empty.
    ///
    /// `inv_dir` is `1 / dir` per component (±inf for zero components, which the IEEE rules turn
    /// into the right infinite slabs; a zero component with the origin exactly on a slab plane
    /// gives `0 * inf = NaN`, which `min`/`max` below drop, keeping the ray: conservative).
    /// The exit is widened by [`super::BOX_EXIT_SLACK`] and the entry lowered by
    /// [`BOX_ENTRY_SLACK`](super::slab::BOX_ENTRY_SLACK) relative, exactly as
    /// [`SlabRay::entry`](super::SlabRay::entry) does (the same decision, bit for bit): every box
    /// test in raysift is this one function of the box, so the triangle test's box gate makes each
    /// of them conservative (see `geom::triangle`).
    #[inline(always)]
    pub fn ray_interval(
        &self,
        origin: Vec3,
        inv_dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<(f32, f32)> {
        let t0 = (self.min - origin) * inv_dir;
        let t1 = (self.max - origin) * inv_dir;
        // Near and far planes are picked by the sign of `inv_dir` (-0.0 gives -inf: near = max), not
        // by min/max of t0 and t1: for a ray parallel to a slab with its origin exactly on one of
        // its planes, that plane's t is 0·inf = NaN, and `f32::min(NaN, inf)` would return inf and
        // reject the ray. With the planes picked by sign, the NaN falls into a comparison below
        // that ignores it (`NaN > e` is false), and the other plane's ±inf leaves the interval
        // open: the ray, lying in the box's face plane, is kept (conservative).
        let mut t_enter = tmin;
        let mut t_exit = tmax;
        for a in 0..3 {
            let (near, far) = if inv_dir[a].is_sign_negative() {
                (t1[a], t0[a])
            } else {
                (t0[a], t1[a])
            };
            if near > t_enter {
                t_enter = near;
            }
            let far = far * super::BOX_EXIT_SLACK;
            if far < t_exit {
                t_exit = far;
            }
        }
        let t_enter = t_enter - t_enter.abs() * super::slab::BOX_ENTRY_SLACK;
        if t_enter <= t_exit {
            Some((t_enter, t_exit))
        } else {
            None
        }
    }
}

/// A ray packed for [`Aabb::hit_by_packed`]: `(origin, tmin)` and `(1 / dir, tmax)`, 32 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PackedRay {
    /// Origin in lanes 0–2, `tmin` in lane 3.
    pub o_tmin: Vec4,
    /// `1 / dir` in lanes 0–2 (never ±0 or NaN: the inverse of a finite direction), `tmax` in
    /// lane 3.
    pub inv_tmax: Vec4,
}

impl PackedRay {
    /// Packs a ray (`inv_dir = 1 / dir` of a finite direction).
    #[inline(always)]
    pub fn new(origin: Vec3, inv_dir: Vec3, tmin: f32, tmax: f32) -> Self {
        Self {
            o_tmin: origin.extend(tmin),
            inv_tmax: inv_dir.extend(tmax),
        }
    }
}

impl Aabb {
    /// [`Aabb::ray_interval`]`.is_some()` for a packed ray, four lanes at once (SSE on x86-64):
    /// the same products, the same near/far choice by the sign of `1/d`, the same exit slack,
    /// and NaN slabs (`0·inf`) dropped the same way, so the decision is the scalar one bit for
    /// bit (tested). For the filter loops that run it once per ray per node.
    #[inline(always)]
    pub fn hit_by_packed(&self, r: &PackedRay) -> bool {
        const W: BVec4A = BVec4A::new(false, false, false, true);
        let t0 = (self.min.extend(0.0) - r.o_tmin) * r.inv_tmax;
        let t1 = (self.max.extend(0.0) - r.o_tmin) * r.inv_tmax;
        // `1/d` is never ±0, so `< 0` is its sign.
        let neg = r.inv_tmax.cmplt(Vec4::ZERO);
        let near = Vec4::select(neg, t1, t0);
        let far = Vec4::select(neg, t0, t1) * super::BOX_EXIT_SLACK;
        // Lane 3: tmin and tmax (unscaled, as the scalar test starts from them).
        let near = Vec4::select(W, r.o_tmin, near);
        let far = Vec4::select(W, r.inv_tmax, far);
        // NaN slabs never move the interval (the scalar comparisons are false for them).
        let near = Vec4::select(near.is_nan_mask(), Vec4::NEG_INFINITY, near);
        let far = Vec4::select(far.is_nan_mask(), Vec4::INFINITY, far);
        let enter = near.max_element();
        enter - enter.abs() * super::slab::BOX_ENTRY_SLACK <= far.min_element()
    }

    /// [`Aabb::hit_by_packed`] for four rays at once, one ray per lane (bit `j` of the result
    /// for `r[j]`): the records are transposed and each axis' slab is the same products, sign
    /// choice, exit slack and NaN drop, lane by lane, so each decision is the one-ray one bit
    /// for bit (tested). The one-ray test spends most of its time in the horizontal max and min;
    /// here they are three lane-wise ones.
    #[inline(always)]
    pub fn hit_by_packed4(&self, r: &[PackedRay; 4]) -> u32 {
        let o = Mat4::from_cols(r[0].o_tmin, r[1].o_tmin, r[2].o_tmin, r[3].o_tmin).transpose();
        let inv =
            Mat4::from_cols(r[0].inv_tmax, r[1].inv_tmax, r[2].inv_tmax, r[3].inv_tmax).transpose();
        let drop_nan = |v: Vec4, to: f32| Vec4::select(v.is_nan_mask(), Vec4::splat(to), v);
        let mut enter = drop_nan(o.w_axis, f32::NEG_INFINITY);
        let mut exit = drop_nan(inv.w_axis, f32::INFINITY);
        for a in 0..3 {
            let (o, inv) = (o.col(a), inv.col(a));
            let t0 = (Vec4::splat(self.min[a]) - o) * inv;
            let t1 = (Vec4::splat(self.max[a]) - o) * inv;
            let neg = inv.cmplt(Vec4::ZERO);
            let near = Vec4::select(neg, t1, t0);
            let far = Vec4::select(neg, t0, t1) * super::BOX_EXIT_SLACK;
            // No NaN is left, so the order of the maxima and minima does not matter (up to the
            // sign of a zero, which the comparison below does not see).
            enter = enter.max(drop_nan(near, f32::NEG_INFINITY));
            exit = exit.min(drop_nan(far, f32::INFINITY));
        }
        (enter - enter.abs() * super::slab::BOX_ENTRY_SLACK)
            .cmple(exit)
            .bitmask()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_test_inside_outside_and_parallel() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let inv = |d: Vec3| Vec3::ONE / d;
        // From inside: enters at tmin.
        let (te, tx) = b
            .ray_interval(Vec3::splat(0.5), inv(Vec3::X), 0.0, f32::INFINITY)
            .unwrap();
        assert_eq!(te, 0.0);
        assert!((tx - 0.5).abs() < 1e-6);
        // Axis-parallel ray outside the slab misses.
        assert!(b
            .ray_interval(Vec3::new(-1.0, 2.0, 0.5), inv(Vec3::X), 0.0, f32::INFINITY)
            .is_none());
        // Axis-parallel rays exactly on a face plane are kept (conservative), on the min and on the
        // max plane, whatever the sign of the zero components.
        for o in [
            Vec3::new(-1.0, 0.0, 0.5),
            Vec3::new(-1.0, 1.0, 0.5),
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(-1.0, 1.0, 1.0),
        ] {
            for d in [
                Vec3::X,
                Vec3::new(1.0, -0.0, 0.0),
                Vec3::new(1.0, 0.0, -0.0),
            ] {
                assert!(
                    b.ray_interval(o, inv(d), 0.0, f32::INFINITY).is_some(),
                    "{o} {d}"
                );
            }
        }
        // Axis-parallel ray exactly on a face plane is kept (conservative).
        assert!(b
            .ray_interval(Vec3::new(-1.0, 1.0, 0.5), inv(Vec3::X), 0.0, f32::INFINITY)
            .is_some());
        // Box behind the origin misses.
        assert!(b
            .ray_interval(Vec3::new(2.0, 0.5, 0.5), inv(Vec3::X), 0.0, f32::INFINITY)
            .is_none());
        // tmax clipping.
        assert!(b
            .ray_interval(Vec3::new(-2.0, 0.5, 0.5), inv(Vec3::X), 0.0, 1.5)
            .is_none());
        // Negative zero direction components behave like positive zero.
        let d = Vec3::new(1.0, -0.0, 0.0);
        assert!(b
            .ray_interval(Vec3::new(-1.0, 0.5, 0.5), inv(d), 0.0, f32::INFINITY)
            .is_some());
    }

    #[test]
    fn packed_test_decides_as_the_scalar_one() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let mut r = |s: f32| rng.gen_range(-s..s);
        let (mut hit, mut miss) = (0, 0);
        let mut last = PackedRay::default();
        for n in 0..300_000 {
            let c = Vec3::new(r(1.0), r(1.0), r(1.0));
            let e = Vec3::new(r(1.0).abs(), r(1.0).abs(), r(1.0).abs()) * (n % 3) as f32;
            let b = Aabb::new(c - e, c + e);
            // Origins on the box's planes and directions with zero (±0) components are the
            // cases where the slabs give 0·inf = NaN.
            let mut o = Vec3::new(r(2.0), r(2.0), r(2.0));
            let plane = (n / 4) % 3;
            if n % 4 == 0 {
                o[plane] = if n % 8 == 0 {
                    b.min[plane]
                } else {
                    b.max[plane]
                };
            }
            // Half the rays aimed into the box (hits), half anywhere.
            let mut d = Vec3::new(r(1.0), r(1.0), r(1.0));
            if n % 2 == 0 {
                d = c + Vec3::new(r(1.0), r(1.0), r(1.0)) * e - o;
            }
            match n % 5 {
                0 => d.x = 0.0,
                1 => d.y = -0.0,
                2 => (d.x, d.z) = (-0.0, 0.0),
                // On a plane and parallel to it: that slab is 0·inf = NaN.
                _ if n % 4 == 0 => d[plane] = if n % 3 == 0 { -0.0 } else { 0.0 },
                _ => {}
            }
            if d == Vec3::ZERO {
                d.y = 1.0;
            }
            let inv = Vec3::ONE / d;
            let (tmin, tmax) = match n % 3 {
                0 => (0.0, f32::INFINITY),
                1 => (r(1.0).abs(), r(3.0).abs() + 1.0),
                _ => (r(1.0), r(1.0)),
            };
            let want = b.ray_interval(o, inv, tmin, tmax).is_some();
            let ray = PackedRay::new(o, inv, tmin, tmax);
            let got = b.hit_by_packed(&ray);
            assert_eq!(got, want, "case {n}: {b:?} o {o} d {d} [{tmin}, {tmax}]");
            // The four-ray test, this ray in lane `n % 4` beside earlier rays of other cases.
            let lane = n % 4;
            let mut four = [last; 4];
            four[lane] = ray;
            let bits = b.hit_by_packed4(&four);
            let others = b.hit_by_packed(&last);
            for j in 0..4 {
                let w = if j == lane { want } else { others };
                assert_eq!(
                    bits >> j & 1 == 1,
                    w,
                    "case {n}, lane {j}: {b:?} o {o} d {d}"
                );
            }
            last = ray;
            if want {
                hit += 1;
            } else {
                miss += 1;
            }
        }
        assert!(hit > 40_000 && miss > 40_000, "{hit} {miss}");
    }

    #[test]
    fn flat_box_is_hit() {
        let b = Aabb::new(Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
        let d = Vec3::new(0.3, 1.0, 0.2).normalize();
        assert!(b
            .ray_interval(Vec3::new(0.2, 0.0, 0.3), Vec3::ONE / d, 0.0, f32::INFINITY)
            .is_some());
    }

    #[test]
    fn empty_and_area() {
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
        let b = Aabb::from_points([Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)]);
        assert_eq!(b.surface_area(), 22.0);
        assert_eq!(b.longest_axis(), 2);
    }
}
