//! The cone-frustum/AABB test of cone tracing's BVH traversal (Wiche & Kuri 2020, §3, Listing 2,
//! Fig. 5): does the cone's bounding frustum meet a box, and over which axial range `[t_min, t_max]`.
//!
//! **The frustum.** At axial distance `t` the cone's cross-section is a disk of radius
//! `t·tan α` centred on `o + t·d`; its extent along axis `k` is `o_k + t·(d_k ± β_k)` with
//! `β_k = tan α·√(1 − d_k²)` (Tsakok's cone/plane distances, Eq. 2, are the `t` where these two
//! edges reach a plane). Per axis the test keeps the `t ≥ 0` where that extent overlaps the
//! box's slab `[lo_k, hi_k]`: `t·b_k ≥ lo_k − o_k` and `t·a_k ≤ hi_k − o_k`, with
//! `a_k = d_k − β_k ≤ b_k = d_k + β_k`; the three axes' ranges are intersected, as in the
//! ray-slab test. A point of the cone inside the box has its axial distance in the result, so
//! culling with it is conservative (false positives only, where the per-axis extents are not
//! reached together).
//!
//! **Two versions, equal bit for bit** (`tests.rs` checks it):
//! - [`ConeFrustum::interval_basic`]: Listing 2 as printed, branching per axis on the apex
//!   between the planes (case a.1: both planes reached by different edges → `[0, ∞)`; a.2:
//!   `[0, max t4]`) or outside (b.1: no plane reached → miss; b.2: both edges reach both
//!   planes → `[min t4, max t4]`; b.3: one edge reaches both → `[min positive t4, ∞)`), with
//!   `t4` the four plane distances of the axis.
//! - [`ConeFrustum::interval2`]: the improved, branchless version, both boxes of a BVH
//!   [`BoxPair`] at once: per axis one 4-lane division of `[lo_a, lo_b, hi_a, hi_b] − o_k` by
//!   `[b, b, a, a]`, each lane a lower or an upper bound by the sign of its denominator
//!   (decided once per cone), then max/min across axes. The authors' improved HLSL returns
//!   `tMax <= tMin`, true for a **miss** while documented as a hit (see BENCHMARKS.md, cone
//!   section); here a hit is `t_min ≤ t_max` (inclusive: a flat box, the box of an
//!   axis-aligned triangle, is touched over a single `t`), in both versions.
//!
//! **Conservative against rounding.** The exact cone/triangle test
//! ([`super::cone_triangle`]) is evaluated in f64; this test runs in f32 on a slightly wider
//! frustum: `a_k` is computed in f64 with `β_k·(1 + 1e-9) + 1e-12` and rounded down to f32,
//! `b_k` likewise up, and the final range is widened by `4ε` relative (each plane distance has
//! two roundings, `≤ ε`). So a box containing a point the exact test accepts is never culled
//! and its range contains the point's `t` (property-tested in `tests.rs`).

use super::BoxPair;
use glam::{BVec4A, Vec3, Vec4};

/// Relative widening of the final range (4 ulps; see the module doc).
const WIDEN: f32 = 4.0 * f32::EPSILON;

/// A cone prepared for box tests: apex and the two edge slopes per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeFrustum {
    o: [f32; 3],
    /// Lower edge slope `a_k` (rounded down) and upper `b_k` (rounded up) per axis.
    a: [f32; 3],
    b: [f32; 3],
    /// Per axis, the lane denominators `[b, b, a, a]`, the lanes that give a lower bound
    /// (`den > 0` on a lo plane, `den < 0` on a hi plane), an upper bound (the opposite), and
    /// the zero-denominator lanes' verdict (`true`: every `t`, `false`: none) — all per cone.
    den: [Vec4; 3],
    lower: [BVec4A; 3],
    upper: [BVec4A; 3],
    flat_ok_sign: [Vec4; 3],
}

fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

impl ConeFrustum {
    /// The frustum of the cone (apex, axis normalised here in f64, half-angle in radians,
    /// `0 < half_angle < π/2`).
    pub fn new(apex: Vec3, axis: Vec3, half_angle: f32) -> Self {
        let d = axis.as_dvec3().normalize();
        let tan = (half_angle as f64).tan();
        let mut a = [0f32; 3];
        let mut b = [0f32; 3];
        for k in 0..3 {
            let beta = tan * (1.0 - d[k] * d[k]).max(0.0).sqrt() * (1.0 + 1e-9) + 1e-12;
            a[k] = round_down(d[k] - beta);
            b[k] = round_up(d[k] + beta);
        }
        let mut f = Self {
            o: apex.to_array(),
            a,
            b,
            den: [Vec4::ZERO; 3],
            lower: [BVec4A::FALSE; 3],
            upper: [BVec4A::FALSE; 3],
            flat_ok_sign: [Vec4::ZERO; 3],
        };
        for k in 0..3 {
            let den = Vec4::new(b[k], b[k], a[k], a[k]);
            // s = +1 on lo lanes (t·den ≥ c), −1 on hi lanes (t·den ≤ c): lower bound where
            // s·den > 0, upper where s·den < 0.
            let s = Vec4::new(1.0, 1.0, -1.0, -1.0);
            f.den[k] = den;
            f.lower[k] = (s * den).cmpgt(Vec4::ZERO);
            f.upper[k] = (s * den).cmplt(Vec4::ZERO);
            f.flat_ok_sign[k] = s;
        }
        f
    }

    /// The unit axis is not kept; the apex is.
    pub fn apex(&self) -> Vec3 {
        Vec3::from_array(self.o)
    }

    /// The edge slopes `(a_k, b_k)` of axis `k` (module doc; rounded outwards): the cone's
    /// extent along `k` at axial distance `t` lies in `[o_k + t·a_k, o_k + t·b_k]`. The kd-tree
    /// cone walk cuts its ranges with them at each split (`tracers/cone/kdtree.rs`).
    #[inline(always)]
    pub fn slopes(&self, k: usize) -> (f32, f32) {
        (self.a[k], self.b[k])
    }

    /// Widened final verdict shared by both versions.
    #[inline(always)]
    fn finish(tmin: f32, tmax: f32) -> Option<(f32, f32)> {
        // `+ 0.0` turns a −0 into +0, whatever max/min picked.
        let lo = (tmin + 0.0) * (1.0 - WIDEN);
        let hi = tmax * (1.0 + WIDEN);
        (lo <= hi).then_some((lo, hi))
    }

    /// Listing 2 with the cases of Fig. 5, branching (module doc). `None`: culled.
    pub fn interval_basic(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        let (mut tmin, mut tmax) = (0.0f32, f32::INFINITY);
        for k in 0..3 {
            let (lo, hi, o, a, b) = (min[k], max[k], self.o[k], self.a[k], self.b[k]);
            if !(lo <= hi) {
                return None; // an empty box
            }
            let t4 = [(lo - o) / a, (lo - o) / b, (hi - o) / a, (hi - o) / b];
            let (lo_ax, hi_ax);
            if lo <= o && o <= hi {
                if a <= 0.0 && b >= 0.0 {
                    // a.1: the edges head to different planes (or along them).
                    (lo_ax, hi_ax) = (0.0, f32::INFINITY);
                } else {
                    // a.2: both edges reach the one plane they head to.
                    lo_ax = 0.0;
                    hi_ax = t4.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                }
            } else {
                let below = o < lo;
                let never = if below { b <= 0.0 } else { a >= 0.0 };
                let both = if below { a > 0.0 } else { b < 0.0 };
                if never {
                    return None; // b.1
                } else if both {
                    // b.2
                    lo_ax = t4.iter().copied().fold(f32::INFINITY, f32::min);
                    hi_ax = t4.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                } else {
                    // b.3: the nearer plane distance of the one edge that reaches the slab
                    // (positive: `+0` counts, `−0` from an edge heading away does not).
                    lo_ax = t4
                        .iter()
                        .copied()
                        .filter(|t| *t > 0.0 || (*t == 0.0 && t.is_sign_positive()))
                        .fold(f32::INFINITY, f32::min);
                    hi_ax = f32::INFINITY;
                }
            }
            tmin = tmin.max(lo_ax);
            tmax = tmax.min(hi_ax);
        }
        Self::finish(tmin, tmax)
    }

    /// The improved test (branchless, 4 lanes) on both boxes of `pair`: per box `Some(range)`
    /// or `None` (culled). Equal to [`Self::interval_basic`] bit for bit on each box.
    #[inline]
    pub fn interval2(&self, pair: &BoxPair) -> [Option<(f32, f32)>; 2] {
        let mut lo4 = Vec4::ZERO;
        let mut hi4 = Vec4::INFINITY;
        for (k, planes) in [pair.x, pair.y, pair.z].into_iter().enumerate() {
            let c = Vec4::from_array(planes) - Vec4::splat(self.o[k]);
            let q = c / self.den[k];
            // Zero denominators: every t when s·c ≤ 0, else none.
            let flat = self.den[k].cmpeq(Vec4::ZERO);
            let flat_ok = (self.flat_ok_sign[k] * c).cmple(Vec4::ZERO);
            let lower = Vec4::select(
                self.lower[k],
                q,
                Vec4::select(flat & !flat_ok, Vec4::INFINITY, Vec4::NEG_INFINITY),
            );
            let upper = Vec4::select(self.upper[k], q, Vec4::INFINITY);
            lo4 = lo4.max(lower);
            hi4 = hi4.min(upper);
        }
        // Lanes 0, 2 are box a's lo/hi planes, 1, 3 box b's.
        let tmin = [lo4.x.max(lo4.z), lo4.y.max(lo4.w)];
        let tmax = [hi4.x.min(hi4.z), hi4.y.min(hi4.w)];
        [
            Self::finish(tmin[0], tmax[0]),
            Self::finish(tmin[1], tmax[1]),
        ]
    }

    /// The improved test on one box (the pair's second slot empty).
    pub fn interval(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        let mut p = BoxPair::EMPTY;
        p.set(0, min, max);
        self.interval2(&p)[0]
    }
}

#[cfg(test)]
mod tests;
