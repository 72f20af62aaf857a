//! Arvo–Kirk's 5D ray classification and the two bounds the post compares: a node's rays as a
//! 5D box `(x, y, z, u, v)` within one of six major-axis bundles, turned into the post's open
//! frustum (5 planes) or into Arvo–Kirk's cone, and the conservative triangle-box culls.
//!
//! **Why the culls are exact** (keep every triangle a ray can hit by the shared test). A hit of
//! the shared test ([`crate::geom::intersect_triangle`]) has its `t` inside the f32 slab
//! interval of the triangle's box `T` (the box gate). Per axis the slab bound is
//! `(lo_a − o_a)·(1/d_a)`, each operation rounded, then lowered (raised) by the box slack
//! (`≈ 3ε`), so the exact point `p* = o + t·d` (real arithmetic on the f32 `o, d, t`) lies
//! within `δ_a ≤ 8ε·|lo_a − o_a| ≤ 16ε·S` of `T` on every axis (`ε = 2^-23`, `S` the largest
//! coordinate magnitude of the node's origins and of the scene; a zero `d_a` gives
//! `p*_a = o_a ∈ [lo_a, hi_a]`). We use `δ = 2^-17·S`. The rays of a node have `t ≥ tmin ≥ 0`
//! (other rays go to the unbounded group) and exact slopes `d_i/|d_k|` inside the stored `u, v`
//! bounds widened by [`widen_up`]/[`widen_down`] (each stored slope is one rounded division), so:
//! - **frustum**: every plane `h(x) = α·x_m + β·x_k ≤ c` (the 4 side planes, `α = ±1`,
//!   `β = ∓U·s`, and the near plane `−s·x_k ≤ max(−s·o_k)`) holds exactly at `p*`, because
//!   `h(o + t·d) = h(o) + t·|d_k|·(slope − U)` (side) or `h(o) − t·|d_k|` (near), and `c` is the
//!   maximum of `h` over the origin box. `p*` within `δ` of `T` gives
//!   `h(p*) ≥ min_T h − (|α| + |β|)·δ`. The f32 evaluations of `c` and `min_T h` err by at most
//!   `2ε·(|α| + |β|)·S` each. So culling when `min_T h > c + 2^-14·S` (which exceeds the sum:
//!   `|α| + |β| ≤ 2 + 2^-19`) never drops a triangle with a hit;
//! - **cone**: every point of a ray is in `ball(C, R) ⊕ cone(C, a, θ)` (`C` the origin box's
//!   centre, `R` its half-diagonal rounded up; `θ`, computed in f64 from the four widened corner
//!   directions, widened by `2^-20` rad, holds every direction with slopes in the rectangle: a
//!   circular cone under 90° is convex). `p*` is within `r_T + √3·δ` of the triangle box's
//!   centre `c_T`; the distance from `c_T` to the cone is 1-Lipschitz in the angle and the
//!   point, so culling when `dist(c_T, cone) > R + r_T + 2^-13·S` (covering `√3·δ`, the f32
//!   rounding of `c_T`, `r_T`, the axis and `cos θ, sin θ`, each a few `ε·S` or `2^-20·|w|`,
//!   `|w| ≤ 2S`) never drops a triangle with a hit.
//!
//! `S` is a node-wide bound (not per triangle), so a scene far from the origin culls less,
//! never wrongly. Non-finite values make the comparisons false: nothing is culled.
//! `tests.rs` checks both culls against the shared test on rays made to graze triangle boxes.

use glam::Vec3;

/// The hit point's distance bound from its triangle's box, relative to `S` (see the module doc).
pub(super) const DELTA: f32 = 1.0 / 131072.0;
/// The frustum's margin, relative to `S`.
const FRUSTUM_MARGIN: f32 = 1.0 / 16384.0;
/// The cone's margin, relative to `S`.
const CONE_MARGIN: f32 = 1.0 / 8192.0;

/// Ray groups per task: six major-axis bundles (`2k` for `+k`, `2k + 1` for `−k`) and one of
/// rays no bound holds (negative or NaN `tmin`, a zero or non-finite direction, a non-finite
/// origin), traced against every triangle.
pub(super) const GROUPS: usize = 7;
/// The unbounded group.
pub(super) const UNBOUNDED: usize = 6;

/// A ray in the recursion (24 bytes, swapped with its id): its 5D point `(x, y, z, u, v)` and
/// its local index.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(super) struct Rec {
    pub(super) p: [f32; 5],
    pub(super) id: u32,
}

/// The axes of bundle `g`: major `k`, sign `s`, minors `i, j` (u is `d_i/|d_k|`, v `d_j/|d_k|`).
#[inline(always)]
pub(super) fn axes(g: usize) -> (usize, f32, usize, usize) {
    let k = g / 2;
    (k, if g % 2 == 0 { 1.0 } else { -1.0 }, (k + 1) % 3, (k + 2) % 3)
}

/// Arvo–Kirk's classification: the group and the 5D point of a ray. The major axis is the
/// largest `|d|` component with ties by strict `>` (x only if larger than both, else y if larger
/// than z, else z), so `|dx| = |dy|` goes to y and `u = dx/|dy| = ±1`.
#[inline(always)]
pub(super) fn classify(o: Vec3, d: Vec3, tmin: f32) -> (usize, [f32; 5]) {
    let a = d.abs();
    let k = if a.x > a.y && a.x > a.z {
        0
    } else if a.y > a.z {
        1
    } else {
        2
    };
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let (u, v) = (d[i] / a[k], d[j] / a[k]);
    let p = [o.x, o.y, o.z, u, v];
    // `!(x >= 0)` also catches NaN.
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    let bad = !(tmin >= 0.0) || !(a[k] > 0.0) || !(u.is_finite() && v.is_finite()) || !o.is_finite();
    if bad {
        (UNBOUNDED, p)
    } else {
        (2 * k + (d[k] < 0.0) as usize, p)
    }
}

/// `x` raised past the exact slope its rounded division stands for.
#[inline]
pub(super) fn widen_up(x: f32) -> f32 {
    x + x.abs() * f32::EPSILON + f32::MIN_POSITIVE
}

/// `x` lowered past the exact slope its rounded division stands for.
#[inline]
pub(super) fn widen_down(x: f32) -> f32 {
    x - x.abs() * f32::EPSILON - f32::MIN_POSITIVE
}

/// The 5D box of a node's rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Bound5 {
    pub(super) lo: [f32; 5],
    pub(super) hi: [f32; 5],
}

impl Bound5 {
    pub(super) fn of(recs: &[Rec]) -> Self {
        let mut b = Bound5 { lo: [f32::INFINITY; 5], hi: [f32::NEG_INFINITY; 5] };
        for r in recs {
            for d in 0..5 {
                b.lo[d] = b.lo[d].min(r.p[d]);
                b.hi[d] = b.hi[d].max(r.p[d]);
            }
        }
        b
    }

    /// The largest coordinate magnitude of the origin box.
    pub(super) fn origin_scale(&self) -> f32 {
        (0..3).fold(0.0f32, |m, d| m.max(self.lo[d].abs()).max(self.hi[d].abs()))
    }
}

/// A plane `α·x_m + β·x_k ≤ c` of the open frustum, with the margin folded into `c`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Plane5 {
    m: usize,
    alpha: f32,
    beta: f32,
    thr: f32,
}

/// The post's open frustum of a node: 4 side planes and the near plane.
#[derive(Clone, Copy, Debug)]
pub(super) struct Frustum {
    k: usize,
    planes: [Plane5; 5],
}

impl Frustum {
    /// The frustum of bundle `g`'s node bound `b`; `s_all` is the node's `S`.
    pub(super) fn new(g: usize, b: &Bound5, s_all: f32) -> Self {
        let (k, s, i, j) = axes(g);
        let margin = FRUSTUM_MARGIN * s_all;
        let plane = |m: usize, alpha: f32, beta: f32| {
            // c = max over the origin box of α·x_m + β·x_k (exact maximum, f32 evaluation).
            let xm = if alpha > 0.0 { b.hi[m] } else { b.lo[m] };
            let xk = if beta > 0.0 { b.hi[k] } else { b.lo[k] };
            Plane5 { m, alpha, beta, thr: alpha * xm + beta * xk + margin }
        };
        let (uh, ul) = (widen_up(b.hi[3]), widen_down(b.lo[3]));
        let (vh, vl) = (widen_up(b.hi[4]), widen_down(b.lo[4]));
        Frustum {
            k,
            planes: [
                plane(i, 1.0, -uh * s),
                plane(i, -1.0, ul * s),
                plane(j, 1.0, -vh * s),
                plane(j, -1.0, vl * s),
                plane(i, 0.0, -s),
            ],
        }
    }

    /// False when the box `[lo, hi]` lies wholly outside one plane (by the margin).
    #[inline(always)]
    pub(super) fn keeps(&self, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
        let k = self.k;
        let mut out = false;
        for p in &self.planes {
            let xm = if p.alpha > 0.0 { lo[p.m] } else { hi[p.m] };
            let xk = if p.beta > 0.0 { lo[k] } else { hi[k] };
            out |= p.alpha * xm + p.beta * xk > p.thr;
        }
        !out
    }
}

/// Arvo–Kirk's cone of a node, swept by the origin box's bounding ball.
#[derive(Clone, Copy, Debug)]
pub(super) struct Cone5 {
    apex: Vec3,
    axis: Vec3,
    cos: f32,
    sin: f32,
    /// `R` plus the margin.
    reach: f32,
}

impl Cone5 {
    pub(super) fn new(g: usize, b: &Bound5, s_all: f32) -> Self {
        let (k, s, i, j) = axes(g);
        let dir = |u: f64, v: f64| {
            let mut d = [0.0f64; 3];
            (d[k], d[i], d[j]) = (s as f64, u, v);
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            [d[0] / n, d[1] / n, d[2] / n]
        };
        let (uh, ul) = (widen_up(b.hi[3]) as f64, widen_down(b.lo[3]) as f64);
        let (vh, vl) = (widen_up(b.hi[4]) as f64, widen_down(b.lo[4]) as f64);
        let a = dir(0.5 * (uh + ul), 0.5 * (vh + vl));
        let mut theta = 0.0f64;
        for (u, v) in [(ul, vl), (ul, vh), (uh, vl), (uh, vh)] {
            let c = dir(u, v);
            let dot = a[0] * c[0] + a[1] * c[1] + a[2] * c[2];
            let cr = [
                a[1] * c[2] - a[2] * c[1],
                a[2] * c[0] - a[0] * c[2],
                a[0] * c[1] - a[1] * c[0],
            ];
            let cross = (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
            theta = theta.max(cross.atan2(dot));
        }
        let theta = (theta + 1.0 / 1_048_576.0).min(89.0f64.to_radians());
        let lo = Vec3::new(b.lo[0], b.lo[1], b.lo[2]);
        let hi = Vec3::new(b.hi[0], b.hi[1], b.hi[2]);
        let apex = (lo + hi) * 0.5;
        let r = (hi - apex).abs().max(apex - lo).length() * (1.0 + 1.0 / 1_048_576.0);
        Cone5 {
            apex,
            axis: Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32),
            cos: theta.cos() as f32,
            sin: theta.sin() as f32,
            reach: r + CONE_MARGIN * s_all,
        }
    }

    /// False when the box `[lo, hi]`'s bounding ball lies outside the swept cone (by the margin).
    #[inline(always)]
    pub(super) fn keeps(&self, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
        let (lo, hi) = (Vec3::from_array(*lo), Vec3::from_array(*hi));
        let c = (lo + hi) * 0.5;
        let rt = (hi - lo).length() * 0.5;
        let w = c - self.apex;
        let h = w.dot(self.axis);
        let rho = (w - self.axis * h).length();
        let dist = if rho * self.cos <= h * self.sin {
            0.0
        } else if rho * self.sin + h * self.cos < 0.0 {
            w.length()
        } else {
            rho * self.cos - h * self.sin
        };
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        let keep = !(dist > self.reach + rt);
        keep
    }
}
