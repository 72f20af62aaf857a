//! The visiting order and early ray termination (§3.2; §3.4 for rays with no common point):
//! which child goes first, and when a hit is final so that its ray can leave the recursion.

use super::Task;
use crate::geom::Aabb;
use glam::{BVec4A, Vec3, Vec4};

/// Relative gap a hit must keep from its leaf's exit to terminate the ray: generous, because a
/// ray that is not terminated only costs time, and a ray terminated too early is wrong.
const TERM_GAP: f32 = 1.0 / 16384.0;

/// Front-to-back bookkeeping for early termination (§3.2 and references.md §1.4).
///
/// A ray may leave the recursion at a leaf when no unvisited cell can hold a closer or tying
/// hit. Along every ancestor where the current node is the **first** visited child, the ray's
/// points in the second child must come after its points here. With the first child on the low
/// side of plane `s` on axis `a`, that holds when `d[a] ≥ 0` (the ray crosses low → high) or when
/// the ray's segment starts at or below `s` (it never enters the high side). Over all such
/// ancestors this folds into one bound per axis and side: `lo_min[a]` (smallest such `s`) and
/// `hi_max[a]` (largest for high-first ancestors). Second children add nothing: the first
/// child's cells were all visited before. Together with "hit at or before the leaf's exit" this
/// makes termination valid for any ray set and any visiting order (the order only decides how
/// often it applies).
#[derive(Clone, Copy, Debug)]
pub(super) struct Order {
    lo_min: [f32; 3],
    hi_max: [f32; 3],
}

impl Order {
    pub(super) const NONE: Order = Order {
        lo_min: [f32::INFINITY; 3],
        hi_max: [f32::NEG_INFINITY; 3],
    };

    pub(super) fn child(self, axis: usize, split: f32, first: bool, low: bool) -> Order {
        let mut o = self;
        if first {
            if low {
                o.lo_min[axis] = o.lo_min[axis].min(split);
            } else {
                o.hi_max[axis] = o.hi_max[axis].max(split);
            }
        }
        o
    }

    /// `start`: the segment's first point `o + tmin·d`; `err`: a bound on its rounding error.
    #[inline]
    pub(super) fn allows(&self, start: Vec3, err: f32, d: Vec3) -> bool {
        for a in 0..3 {
            if !(d[a] >= 0.0 || start[a] + err <= self.lo_min[a]) {
                return false;
            }
            if !(d[a] <= 0.0 || start[a] - err >= self.hi_max[a]) {
                return false;
            }
        }
        true
    }
}

/// How to choose the first child.
#[derive(Clone, Copy, Debug)]
pub(super) enum View {
    /// Majority sign of the split-axis direction (§3.4).
    Majority,
    /// Rays leave this point (camera): its side first.
    From(Vec3),
    /// Rays go to this point (light): the other side first.
    To(Vec3),
}

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// Whether the low child goes first at a node of ray range `[rterm, rend)`.
    pub(super) fn low_first(&self, axis: usize, split: f32, rend: usize) -> bool {
        match self.view {
            View::From(p) if p[axis] != split => p[axis] < split,
            View::To(p) if p[axis] != split => p[axis] > split,
            _ => {
                // Majority of the split-axis direction signs over (a sample of) the rays.
                let n = rend - self.rterm;
                let step = (n / 64).max(1);
                let (mut pos, mut neg) = (0, 0);
                for p in (self.rterm..rend).step_by(step) {
                    // 1/d has d's sign (±0 gives ±inf); only the order depends on it.
                    let dx = self.recs[p].inv_tmax[axis];
                    pos += (dx > 0.0) as u32;
                    neg += (dx < 0.0) as u32;
                }
                pos >= neg
            }
        }
    }

    /// True when the hit at `bt` is final: the hit point lies inside this leaf cell, away from
    /// its faces by a margin (so no triangle of a later cell can tie it after rounding), and
    /// every earlier stretch of the ray was visited ([`Order`]). Inside the (convex) cell means
    /// `t_enter ≤ bt ≤ t_exit`; testing the point costs no ray/box test (as in the paper, whose
    /// packet mode reports almost no ray/box tests).
    #[inline]
    pub(super) fn final_hit(
        cell: &Aabb,
        o: Vec3,
        d: Vec3,
        tmin: f32,
        bt: f32,
        ord: &Order,
    ) -> bool {
        let (start, err) = if tmin == 0.0 {
            (o, 0.0)
        } else {
            let s = o + d * tmin;
            (
                s,
                (o.abs() + (d * tmin).abs()).max_element() * (4.0 * f32::EPSILON),
            )
        };
        if !ord.allows(start, err, d) {
            return false;
        }
        let step = d * bt;
        let p = o + step;
        // Per axis: rounding of p, plus a gap of 2·TERM_GAP·|bt| in t along that axis.
        let m = (o.abs() + step.abs()) * (8.0 * f32::EPSILON) + step.abs() * (2.0 * TERM_GAP);
        (p - m).cmpge(cell.min).all() && (p + m).cmple(cell.max).all()
    }

    /// [`Self::final_hit`] for four rays from `o` (directions and hits per lane), the same f32
    /// operations lane-wise, so each lane's answer is the scalar one: bit `l` set when final.
    #[inline]
    pub(super) fn final_hit4(
        cell: &Aabb,
        o: Vec3,
        d: [Vec4; 3],
        tmin: f32,
        bt: Vec4,
        ord: &Order,
    ) -> u32 {
        let (zero, tm) = (Vec4::ZERO, Vec4::splat(tmin));
        let mut ok = BVec4A::splat(true);
        let mut err = zero;
        let mut start = [zero; 3];
        if tmin != 0.0 {
            // `(o.abs() + (d·tmin).abs()).max_element()`, lane-wise.
            for (a, s) in start.iter_mut().enumerate() {
                let dt = d[a] * tm;
                *s = Vec4::splat(o[a]) + dt;
                err = err.max(Vec4::splat(o[a].abs()) + dt.abs());
            }
            err *= 4.0 * f32::EPSILON;
        } else {
            start = [o.x, o.y, o.z].map(Vec4::splat);
        }
        for (a, s) in start.iter().enumerate() {
            // `Order::allows`, axis `a`.
            ok &= d[a].cmpge(zero) | (*s + err).cmple(Vec4::splat(ord.lo_min[a]));
            ok &= d[a].cmple(zero) | (*s - err).cmpge(Vec4::splat(ord.hi_max[a]));
            // The hit point inside the cell by its margin, axis `a`.
            let step = d[a] * bt;
            let p = Vec4::splat(o[a]) + step;
            let m = (Vec4::splat(o[a].abs()) + step.abs()) * (8.0 * f32::EPSILON)
                + step.abs() * (2.0 * TERM_GAP);
            ok &= (p - m).cmpge(Vec4::splat(cell.min[a])) & (p + m).cmple(Vec4::splat(cell.max[a]));
        }
        ok.bitmask()
    }
}
