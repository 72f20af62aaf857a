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
            Some(enter)
        } else {
            None
        }
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
}
