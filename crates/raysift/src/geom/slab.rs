//! A ray prepared once for many slab tests (the hot loop of tree traversals), conservative on
//! both ends of the interval.
//!
//! [`Aabb::ray_interval`](super::Aabb::ray_interval) widens only the exit. A traversal that culls
//! a box when its entry lies beyond the current closest hit (or the ray's `tmax`) also needs the
//! entry to be a lower bound: a triangle lying in the plane of its box's face (the walls of the
//! Cornell box) can be hit at a computed `t` a few ulps *before* the computed box entry, and a
//! ray whose `tmax` is exactly that `t` (or a tie at the best `t` with a smaller primitive id)
//! would then be lost. So [`SlabRay::entry`] lowers the entry by [`BOX_ENTRY_SLACK`] relative,
//! mirroring [`BOX_EXIT_SLACK`](super::BOX_EXIT_SLACK) on the exit.

use glam::Vec3;

/// Relative amount the entry distance is lowered by: the same size as the exit's slack
/// (`BOX_EXIT_SLACK - 1`).
pub const BOX_ENTRY_SLACK: f32 = super::BOX_EXIT_SLACK - 1.0;

/// A ray with its reciprocal direction and direction signs, for [`SlabRay::entry`].
#[derive(Clone, Copy, Debug)]
pub struct SlabRay {
    /// Origin.
    pub origin: Vec3,
    /// `1 / dir` per component (±inf for ±0 components).
    pub inv_dir: Vec3,
    /// Per axis, true when the direction component is negative (including -0.0): the near slab
    /// plane is then the box's max.
    pub neg: [bool; 3],
}

impl SlabRay {
    /// Prepares `origin + t·dir`.
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let inv_dir = Vec3::ONE / dir;
        Self {
            origin,
            inv_dir,
            // The sign of the reciprocal: -0.0 gives -inf, whose near plane is the max.
            neg: [
                inv_dir.x.is_sign_negative(),
                inv_dir.y.is_sign_negative(),
                inv_dir.z.is_sign_negative(),
            ],
        }
    }

    /// Slab test against the box `[min, max]` clipped to `[tmin, tmax]`: the (slightly lowered)
    /// entry distance when the interval is not empty, else `None`.
    ///
    /// Same semantics as [`Aabb::ray_interval`](super::Aabb::ray_interval) (zero direction
    /// components give infinite slabs; the NaN of `0 · inf` for an origin exactly on a slab plane
    /// is dropped, keeping the ray; the exit is widened by `BOX_EXIT_SLACK`), plus the entry lowered
    /// by `|entry| · BOX_ENTRY_SLACK`. Faster than the general test: the near and far planes are
    /// chosen by the precomputed signs instead of a min/max per axis.
    #[inline(always)]
    pub fn entry(&self, min: Vec3, max: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
        self.interval(min, max, tmin, tmax).map(|(enter, _)| enter)
    }

    /// [`SlabRay::entry`] with the exit too: the interval `[entry, exit]` (entry lowered, exit
    /// widened), or `None` when it is empty.
    #[inline(always)]
    pub fn interval(&self, min: Vec3, max: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32)> {
        let pick = |neg: bool, lo: f32, hi: f32| if neg { (hi, lo) } else { (lo, hi) };
        let (nx, fx) = pick(self.neg[0], min.x, max.x);
        let (ny, fy) = pick(self.neg[1], min.y, max.y);
        let (nz, fz) = pick(self.neg[2], min.z, max.z);
        let o = self.origin;
        let inv = self.inv_dir;
        let s = super::BOX_EXIT_SLACK;
        // `if a > b { a } else { b }` keeps `b` when `a` is NaN: NaN slabs never shrink the
        // interval (and it compiles to a single maxss/minss).
        let mut enter = tmin;
        for t in [(nx - o.x) * inv.x, (ny - o.y) * inv.y, (nz - o.z) * inv.z] {
            enter = if t > enter { t } else { enter };
        }
        let mut exit = tmax;
        for t in [(fx - o.x) * inv.x, (fy - o.y) * inv.y, (fz - o.z) * inv.z] {
            let t = t * s;
            exit = if t < exit { t } else { exit };
        }
        let enter = enter - enter.abs() * BOX_ENTRY_SLACK;
        if enter <= exit {
            Some((enter, exit))
        } else {
            None
        }
    }
}

/// Two boxes side by side, structure of arrays, for [`SlabRay::entry2`]: per axis
/// `[min_a, min_b, max_a, max_b]` (one 16-byte SIMD lane group per axis, 48 bytes in all).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct BoxPair {
    /// `[min_a.x, min_b.x, max_a.x, max_b.x]`.
    pub x: [f32; 4],
    /// `[min_a.y, min_b.y, max_a.y, max_b.y]`.
    pub y: [f32; 4],
    /// `[min_a.z, min_b.z, max_a.z, max_b.z]`.
    pub z: [f32; 4],
}

impl BoxPair {
    /// Two empty boxes (`min = +inf`, `max = -inf`): never entered.
    pub const EMPTY: BoxPair = BoxPair {
        x: [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ],
        y: [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ],
        z: [
            f32::INFINITY,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NEG_INFINITY,
        ],
    };

    /// Box `i` (0 or 1) as `(min, max)`.
    #[inline(always)]
    pub fn get(&self, i: usize) -> (Vec3, Vec3) {
        (
            Vec3::new(self.x[i], self.y[i], self.z[i]),
            Vec3::new(self.x[i + 2], self.y[i + 2], self.z[i + 2]),
        )
    }

    /// Sets box `i` (0 or 1).
    #[inline(always)]
    pub fn set(&mut self, i: usize, min: Vec3, max: Vec3) {
        (self.x[i], self.y[i], self.z[i]) = (min.x, min.y, min.z);
        (self.x[i + 2], self.y[i + 2], self.z[i + 2]) = (max.x, max.y, max.z);
    }
}

impl SlabRay {
    /// [`SlabRay::entry`] of both boxes of `b` at once: `(mask, entries)` where bit `i` of
    /// `mask` is set when box `i` is entered and `entries[i]` is then its (lowered) entry,
    /// bit for bit what `entry` returns (`entries[i]` is meaningless when the bit is clear).
    ///
    /// The const parameters are the ray's octant ([`SlabRay::neg`], checked in debug builds),
    /// so the near/far plane choice is fixed at compile time: on x86_64 each axis is one SSE
    /// subtract, multiply and (for negative directions) half swap for both boxes, then the same
    /// max/min chain as the scalar test (`maxps(t, e)` is exactly `if t > e { t } else { e }`,
    /// so NaN slabs are dropped the same way). Elsewhere it calls `entry` twice.
    #[inline(always)]
    pub fn entry2<const NX: bool, const NY: bool, const NZ: bool>(
        &self,
        b: &BoxPair,
        tmin: f32,
        tmax: f32,
    ) -> (u32, [f32; 2]) {
        debug_assert_eq!(self.neg, [NX, NY, NZ]);
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        {
            self.entry2_sse::<NX, NY, NZ>(b, tmin, tmax)
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        {
            self.entry2_scalar(b, tmin, tmax)
        }
    }

    /// [`SlabRay::entry2`] for any octant (dispatches on [`SlabRay::neg`]; for tests and cold
    /// paths, the traversal instantiates its loop per octant instead).
    pub fn entry2_dyn(&self, b: &BoxPair, tmin: f32, tmax: f32) -> (u32, [f32; 2]) {
        match self.neg {
            [false, false, false] => self.entry2::<false, false, false>(b, tmin, tmax),
            [false, false, true] => self.entry2::<false, false, true>(b, tmin, tmax),
            [false, true, false] => self.entry2::<false, true, false>(b, tmin, tmax),
            [false, true, true] => self.entry2::<false, true, true>(b, tmin, tmax),
            [true, false, false] => self.entry2::<true, false, false>(b, tmin, tmax),
            [true, false, true] => self.entry2::<true, false, true>(b, tmin, tmax),
            [true, true, false] => self.entry2::<true, true, false>(b, tmin, tmax),
            [true, true, true] => self.entry2::<true, true, true>(b, tmin, tmax),
        }
    }

    /// [`SlabRay::entry2`] for any octant without branching on it: the near/far planes are
    /// chosen by bit masks built from [`SlabRay::neg`] (for loops that interleave rays of
    /// different octants). Same results bit for bit.
    #[inline(always)]
    pub fn entry2_masked(&self, b: &BoxPair, tmin: f32, tmax: f32) -> (u32, [f32; 2]) {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        {
            // SAFETY: as in `entry2_sse`: SSE/SSE2 only (compiled for them), no raw pointers;
            // checked against the scalar reference by `entry2_is_entry_bit_for_bit`.
            unsafe { self.entry2_sse_inner::<false, false, false, true>(b, tmin, tmax) }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        {
            self.entry2_scalar(b, tmin, tmax)
        }
    }

    /// The reference for [`SlabRay::entry2`]: [`SlabRay::entry`] on each box.
    #[inline(always)]
    pub fn entry2_scalar(&self, b: &BoxPair, tmin: f32, tmax: f32) -> (u32, [f32; 2]) {
        let (a0, a1) = b.get(0);
        let (b0, b1) = b.get(1);
        let ea = self.entry(a0, a1, tmin, tmax);
        let eb = self.entry(b0, b1, tmin, tmax);
        (
            ea.is_some() as u32 | (eb.is_some() as u32) << 1,
            [ea.unwrap_or(0.0), eb.unwrap_or(0.0)],
        )
    }

    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[inline(always)]
    fn entry2_sse<const NX: bool, const NY: bool, const NZ: bool>(
        &self,
        b: &BoxPair,
        tmin: f32,
        tmax: f32,
    ) -> (u32, [f32; 2]) {
        // SAFETY: the only requirement of these intrinsics is that the CPU supports SSE and
        // SSE2, which this function is compiled only for (`cfg(target_feature = "sse2")`, part
        // of the x86_64 baseline). No raw pointers: the loads go through glam's Vec4 (an __m128
        // on this target). Exercised against the scalar reference by
        // `entry2_is_entry_bit_for_bit`.
        unsafe { self.entry2_sse_inner::<NX, NY, NZ, false>(b, tmin, tmax) }
    }

    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[inline(always)]
    /// With `MASKED`, the octant comes from `self.neg` at run time (the const signs unused).
    unsafe fn entry2_sse_inner<
        const NX: bool,
        const NY: bool,
        const NZ: bool,
        const MASKED: bool,
    >(
        &self,
        b: &BoxPair,
        tmin: f32,
        tmax: f32,
    ) -> (u32, [f32; 2]) {
        use glam::Vec4;
        use std::arch::x86_64::*;
        let o = self.origin;
        let inv = self.inv_dir;
        // Lanes of `t`: [t(min_a), t(min_b), t(max_a), t(max_b)]; after the octant swap lanes
        // 0, 1 are the near planes' distances and lanes 2, 3 the far planes'.
        #[inline(always)]
        unsafe fn axis<const NEG: bool, const MASKED: bool>(
            v: [f32; 4],
            o: f32,
            inv: f32,
            neg: bool,
        ) -> __m128 {
            let t = _mm_mul_ps(
                _mm_sub_ps(Vec4::from_array(v).into(), _mm_set1_ps(o)),
                _mm_set1_ps(inv),
            );
            if MASKED {
                let m = _mm_set1_ps(f32::from_bits(0u32.wrapping_sub(neg as u32)));
                let swapped = _mm_shuffle_ps::<0b01_00_11_10>(t, t);
                _mm_or_ps(_mm_and_ps(m, swapped), _mm_andnot_ps(m, t))
            } else if NEG {
                _mm_shuffle_ps::<0b01_00_11_10>(t, t)
            } else {
                t
            }
        }
        let neg = self.neg;
        let tx = axis::<NX, MASKED>(b.x, o.x, inv.x, neg[0]);
        let ty = axis::<NY, MASKED>(b.y, o.y, inv.y, neg[1]);
        let tz = axis::<NZ, MASKED>(b.z, o.z, inv.z, neg[2]);
        // Same order and operand roles as `entry`: `maxps(t, e)` = `if t > e { t } else { e }`.
        let mut enter = _mm_set1_ps(tmin);
        enter = _mm_max_ps(tx, enter);
        enter = _mm_max_ps(ty, enter);
        enter = _mm_max_ps(tz, enter);
        let s = _mm_set1_ps(super::BOX_EXIT_SLACK);
        let mut exit = _mm_set1_ps(tmax);
        exit = _mm_min_ps(_mm_mul_ps(tx, s), exit);
        exit = _mm_min_ps(_mm_mul_ps(ty, s), exit);
        exit = _mm_min_ps(_mm_mul_ps(tz, s), exit);
        // enter - |enter| * slack (abs clears the sign bit, as f32::abs).
        let abs = _mm_andnot_ps(_mm_set1_ps(-0.0), enter);
        let enter = _mm_sub_ps(enter, _mm_mul_ps(abs, _mm_set1_ps(BOX_ENTRY_SLACK)));
        // Exits (lanes 2, 3) down to lanes 0, 1.
        let exit = _mm_movehl_ps(exit, exit);
        let mask = (_mm_movemask_ps(_mm_cmple_ps(enter, exit)) & 3) as u32;
        let e0 = _mm_cvtss_f32(enter);
        let e1 = _mm_cvtss_f32(_mm_shuffle_ps::<0b01_01_01_01>(enter, enter));
        (mask, [e0, e1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Aabb;
    use rand::{Rng, SeedableRng};

    #[test]
    fn agrees_with_the_general_slab_test_and_is_never_narrower() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let mut r = |k: i32| -> f32 {
            // Mostly random, sometimes exactly on a grid so origins land on slab planes and
            // direction components are ±0.
            match rng.gen_range(0..6) {
                0 => 0.0,
                1 => -0.0,
                2 => rng.gen_range(-k..=k) as f32,
                _ => rng.gen_range(-2.0..2.0),
            }
        };
        let mut both = 0;
        for _ in 0..200_000 {
            let a = Vec3::new(r(1), r(1), r(1));
            let b = Vec3::new(r(1), r(1), r(1));
            let bx = Aabb::new(a.min(b), a.max(b));
            let o = Vec3::new(r(2), r(2), r(2));
            let d = Vec3::new(r(1), r(1), r(1));
            let (tmin, tmax) = if r(1) > 0.0 {
                (0.0, f32::INFINITY)
            } else {
                (0.5, 1.5)
            };
            let sr = SlabRay::new(o, d);
            let general = bx.ray_interval(o, Vec3::ONE / d, tmin, tmax);
            let fast = sr.entry(bx.min, bx.max, tmin, tmax);
            // (An entry at +inf, from a zero direction, cannot hold a hit: not compared.)
            if let Some((te, _)) = general.filter(|g| g.0.is_finite()) {
                let e = fast.unwrap_or_else(|| panic!("fast test lost {bx:?} {o} {d}"));
                assert!(e <= te, "entry not lowered: {e} > {te}");
                both += 1;
            }
        }
        assert!(both > 10_000, "{both}");
    }

    #[test]
    fn entry_is_lowered_and_signs_follow_negative_zero() {
        let b = Aabb::new(Vec3::new(1.0, -1.0, -1.0), Vec3::new(2.0, 1.0, 1.0));
        let r = SlabRay::new(Vec3::ZERO, Vec3::X);
        let e = r.entry(b.min, b.max, 0.0, f32::INFINITY).unwrap();
        assert!(e < 1.0 && e > 0.999_999);
        // tmax exactly at the entry still visits (the box face might hold the hit).
        assert!(r.entry(b.min, b.max, 0.0, 1.0).is_some());
        assert!(r.entry(b.min, b.max, 0.0, 0.99).is_none());
        let r = SlabRay::new(Vec3::new(3.0, 0.0, 0.0), Vec3::new(-1.0, -0.0, 0.0));
        assert_eq!(r.neg, [true, true, false]);
        assert!(r.entry(b.min, b.max, 0.0, f32::INFINITY).is_some());
        // Origin on a slab plane with a zero component: kept (NaN dropped).
        let r = SlabRay::new(Vec3::new(0.0, 1.0, 0.0), Vec3::X);
        assert!(r.entry(b.min, b.max, 0.0, f32::INFINITY).is_some());
        // Outside the slab, parallel: missed.
        let r = SlabRay::new(Vec3::new(0.0, 1.5, 0.0), Vec3::X);
        assert!(r.entry(b.min, b.max, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn entry2_is_entry_bit_for_bit() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let mut r = |k: i32| -> f32 {
            match rng.gen_range(0..6) {
                0 => 0.0,
                1 => -0.0,
                2 => rng.gen_range(-k..=k) as f32,
                _ => rng.gen_range(-2.0..2.0),
            }
        };
        let mut hits = 0;
        for _ in 0..300_000 {
            let mut bp = BoxPair::EMPTY;
            for i in 0..2 {
                let a = Vec3::new(r(1), r(1), r(1));
                let b = Vec3::new(r(1), r(1), r(1));
                if r(1) != 1.0 {
                    bp.set(i, a.min(b), a.max(b));
                }
            }
            let o = Vec3::new(r(2), r(2), r(2));
            let d = Vec3::new(r(1), r(1), r(1));
            let (tmin, tmax) = match r(1) as i32 {
                1 => (0.5, 1.5),
                -1 => (0.0, 0.25),
                _ => (0.0, f32::INFINITY),
            };
            let sr = SlabRay::new(o, d);
            let (m, e) = sr.entry2_dyn(&bp, tmin, tmax);
            let (ms, es) = sr.entry2_scalar(&bp, tmin, tmax);
            assert_eq!(m, ms, "{bp:?} {o} {d} {tmin} {tmax}");
            let (mm, em) = sr.entry2_masked(&bp, tmin, tmax);
            assert_eq!(mm, ms, "masked: {bp:?} {o} {d} {tmin} {tmax}");
            for i in 0..2 {
                if mm >> i & 1 == 1 {
                    assert_eq!(em[i].to_bits(), es[i].to_bits(), "masked: {bp:?} {o} {d}");
                }
            }
            for i in 0..2 {
                if m >> i & 1 == 1 {
                    assert_eq!(e[i].to_bits(), es[i].to_bits(), "{bp:?} {o} {d}");
                    hits += 1;
                }
            }
        }
        assert!(hits > 10_000, "{hits}");
    }
}
