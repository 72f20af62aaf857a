//! Arvo–Kirk's 5D ray classification (1987) and the two bounds Hoedt's "DACRT over 5D ray
//! hierarchies" compares (`tracers::dacrt5d`): a group of rays as a 5D box `(x, y, z, u, v)`
//! within one of six major-axis bundles, turned into the post's open frustum of 5 planes
//! ([`Frustum5`]) or into Arvo–Kirk's cone ([`Cone5`]), and their conservative box culls.
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
//! **Clipped origins** ([`clip`], [`moved`]). A node whose triangles all lie in a box `B` (their union)
//! may bound its rays from their entry into `B` instead of their origins: the gate puts every
//! hit's `t` in the slab interval of its triangle's box, which lies inside `B`'s (the slab test
//! is monotone in the box: `geom::triangle`), so `t ≥ t0`, the entry of `B`'s interval, and every
//! argument above holds with `o + t0·d` for `o` (`h(o + t·d) ≤ h(o + t0·d)` for `t ≥ t0`). The
//! stored point `o' = fl(o + fl(t0·d))` is off the exact one by at most `2ε·S` per coordinate
//! when `S` covers `|o|` and `|o'|` (so a node's `S` covers its rays' *original* origins too):
//! `(|α| + |β|)·2ε·S ≤ 2^-20·S` more for the frustum and `√3·2ε·S` for the cone, both inside
//! their margins. A ray whose interval in `B` is empty (clipped to `[tmin, best]`) has no hit in
//! the node closer than its best (ties included: the interval is inclusive) and leaves it.
//!
//! `S` is a node-wide bound (not per triangle), so a scene far from the origin culls less,
//! never wrongly. Non-finite values make the comparisons false: nothing is culled.
//! The test `culls_keep_every_grazing_hit` (below) checks both culls against the shared test on
//! rays made to graze triangle boxes.

use glam::Vec3;

/// The hit point's distance bound from its triangle's box, relative to `S` (see the module doc).
pub const DELTA: f32 = 1.0 / 131072.0;
/// The frustum's margin, relative to `S`.
const FRUSTUM_MARGIN: f32 = 1.0 / 16384.0;
/// The cone's margin, relative to `S`.
const CONE_MARGIN: f32 = 1.0 / 8192.0;

/// Ray groups: six major-axis bundles (`2k` for `+k`, `2k + 1` for `−k`) and one of
/// rays no bound holds (negative or NaN `tmin`, a zero or non-finite direction, a non-finite
/// origin), traced against every triangle.
pub const GROUPS: usize = 7;
/// The unbounded group.
pub const UNBOUNDED: usize = 6;

/// The axes of bundle `g`: major `k`, sign `s`, minors `i, j` (u is `d_i/|d_k|`, v `d_j/|d_k|`).
#[inline(always)]
pub fn axes(g: usize) -> (usize, f32, usize, usize) {
    let k = g / 2;
    (
        k,
        if g.is_multiple_of(2) { 1.0 } else { -1.0 },
        (k + 1) % 3,
        (k + 2) % 3,
    )
}

/// Arvo–Kirk's classification: the group and the 5D point of a ray. The major axis is the
/// largest `|d|` component with ties by strict `>` (x only if larger than both, else y if larger
/// than z, else z), so `|dx| = |dy|` goes to y and `u = dx/|dy| = ±1`.
#[inline(always)]
pub fn classify(o: Vec3, d: Vec3, tmin: f32) -> (usize, [f32; 5]) {
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
    // Written positively so that NaN (every comparison false) lands in the unbounded group.
    let good = tmin >= 0.0 && a[k] > 0.0 && u.is_finite() && v.is_finite() && o.is_finite();
    if !good {
        (UNBOUNDED, p)
    } else {
        (2 * k + (d[k] < 0.0) as usize, p)
    }
}

/// The entry of the ray `o + t·d` into the box `[lo, hi]`: the parameter `t0 ≥ 0` where the
/// shared slab test's interval, clipped to `[tmin, tmax]`, starts
/// ([`crate::geom::SlabRay::interval`]), or `None` when that interval is empty. No hit of the
/// shared test on a triangle whose box lies in `[lo, hi]` has its `t` before `t0` or outside
/// `[tmin, tmax]` (module doc, "Clipped origins"); [`moved`] gives the point to bound from.
#[inline(always)]
pub fn clip(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
    let (t0, _) = crate::geom::SlabRay::new(o, d).interval(lo, hi, tmin, tmax)?;
    // `t0 < 0` only from a negative `tmin` (unbounded group, never clipped) or a lowered 0.
    Some(if t0 > 0.0 { t0 } else { 0.0 })
}

/// The point `o + t0·d` a clipped ray is bound from (`o` itself for `t0 = 0`), the same f32
/// operations wherever it is computed.
#[inline(always)]
pub fn moved(o: Vec3, d: Vec3, t0: f32) -> Vec3 {
    if t0 > 0.0 {
        o + d * t0
    } else {
        o
    }
}

/// `x` raised past the exact slope its rounded division stands for.
#[inline]
pub fn widen_up(x: f32) -> f32 {
    x + x.abs() * f32::EPSILON + f32::MIN_POSITIVE
}

/// `x` lowered past the exact slope its rounded division stands for.
#[inline]
pub fn widen_down(x: f32) -> f32 {
    x - x.abs() * f32::EPSILON - f32::MIN_POSITIVE
}

/// The 5D box of a node's rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound5 {
    /// Lower corner: origin on the two plane axes, then the two slopes (see [`classify`]).
    pub lo: [f32; 5],
    /// Upper corner, in the same coordinates.
    pub hi: [f32; 5],
}

impl Bound5 {
    /// The box of the points `ps` (empty: `lo = +inf, hi = -inf`).
    pub fn of<'a>(ps: impl IntoIterator<Item = &'a [f32; 5]>) -> Self {
        let mut b = Self::EMPTY;
        for p in ps {
            b.add(p);
        }
        b
    }

    /// No points.
    pub const EMPTY: Bound5 = Bound5 {
        lo: [f32::INFINITY; 5],
        hi: [f32::NEG_INFINITY; 5],
    };

    /// Grows the box to hold `p`.
    #[inline(always)]
    pub fn add(&mut self, p: &[f32; 5]) {
        for (d, &x) in p.iter().enumerate() {
            self.lo[d] = self.lo[d].min(x);
            self.hi[d] = self.hi[d].max(x);
        }
    }

    /// The sum of the origin box's three extents.
    pub fn origin_extent(&self) -> f32 {
        (0..3).map(|d| self.hi[d] - self.lo[d]).sum()
    }

    /// The largest coordinate magnitude of the origin box.
    pub fn origin_scale(&self) -> f32 {
        (0..3).fold(0.0f32, |m, d| m.max(self.lo[d].abs()).max(self.hi[d].abs()))
    }
}

/// A plane `α·x_m + β·x_k ≤ c` of the open frustum, with the margin folded into `c`.
#[derive(Clone, Copy, Debug)]
pub struct Plane5 {
    m: usize,
    alpha: f32,
    beta: f32,
    thr: f32,
}

/// The post's open frustum of a node: 4 side planes and the near plane.
#[derive(Clone, Copy, Debug)]
pub struct Frustum5 {
    k: usize,
    planes: [Plane5; 5],
}

impl Frustum5 {
    /// The frustum of bundle `g`'s node bound `b`; `s_all` is the node's `S`.
    pub fn new(g: usize, b: &Bound5, s_all: f32) -> Self {
        let (k, s, i, j) = axes(g);
        let margin = FRUSTUM_MARGIN * s_all;
        let plane = |m: usize, alpha: f32, beta: f32| {
            // c = max over the origin box of α·x_m + β·x_k (exact maximum, f32 evaluation).
            let xm = if alpha > 0.0 { b.hi[m] } else { b.lo[m] };
            let xk = if beta > 0.0 { b.hi[k] } else { b.lo[k] };
            Plane5 {
                m,
                alpha,
                beta,
                thr: alpha * xm + beta * xk + margin,
            }
        };
        let (uh, ul) = (widen_up(b.hi[3]), widen_down(b.lo[3]));
        let (vh, vl) = (widen_up(b.hi[4]), widen_down(b.lo[4]));
        Frustum5 {
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
    pub fn keeps(&self, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
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
pub struct Cone5 {
    apex: Vec3,
    axis: Vec3,
    cos: f32,
    sin: f32,
    /// `R` plus the margin.
    reach: f32,
}

impl Cone5 {
    /// The cone of bundle `g`'s node bound `b`; `s_all` is the node's `S` (the margin).
    pub fn new(g: usize, b: &Bound5, s_all: f32) -> Self {
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
    pub fn keeps(&self, lo: &[f32; 3], hi: &[f32; 3]) -> bool {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::intersect_triangle;
    use rand::{Rng, SeedableRng};

    #[test]
    fn classification_by_strict_major_axis() {
        let o = Vec3::ZERO;
        // |dx| = |dy|: y by the strict `>`; u = dz/|dy|, v = dx/|dy| (minors k+1, k+2).
        let (g, p) = classify(o, Vec3::new(-2.0, 2.0, 1.0), 0.0);
        assert_eq!((g, p[3], p[4]), (2, 0.5, -1.0));
        let (g, p) = classify(o, Vec3::new(0.0, -0.0, -3.0), 0.0);
        assert_eq!((g, p[3], p[4]), (5, 0.0, -0.0));
        assert_eq!(classify(o, Vec3::new(1.0, 0.5, 0.5), 0.0).0, 0);
        assert_eq!(classify(o, Vec3::ZERO, 0.0).0, UNBOUNDED);
        assert_eq!(classify(o, Vec3::new(f32::NAN, 1.0, 0.0), 0.0).0, UNBOUNDED);
        assert_eq!(classify(o, Vec3::X, -1.0).0, UNBOUNDED);
        assert_eq!(classify(o, Vec3::X, f32::NAN).0, UNBOUNDED);
        assert_eq!(
            classify(Vec3::splat(f32::INFINITY), Vec3::X, 0.0).0,
            UNBOUNDED
        );
    }

    /// Triangles in axis planes and general ones far from the origin, and rays aimed at points on
    /// and near them from far away (the gate moves their `t` onto flat boxes): every ray the shared
    /// test hits must keep its triangle through both culls, with the ray alone as its node (the
    /// tightest bound: a zero-width frustum, a zero-angle cone) and with a few neighbours. Red when
    /// the margins or the slope widening are removed; the culls must also drop most triangles no
    /// ray of the node can reach (checked, so the test is not vacuous). The ray clipped to a
    /// box around the triangle ([`clip`]) must keep it too.
    #[test]
    fn culls_keep_every_grazing_hit() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let (mut hits, mut culled, mut far, mut clipped) = (0, 0, 0, 0);
        for case in 0..20_000 {
            let scale = 10f32.powi(rng.gen_range(-2..4));
            let c = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ) * scale;
            let e = |rng: &mut rand_pcg::Pcg64Mcg| {
                Vec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                ) * scale
                    * 0.1
            };
            let (mut a, mut b, mut cc) = (c + e(&mut rng), c + e(&mut rng), c + e(&mut rng));
            if case % 2 == 0 {
                // An axis plane: a flat box.
                let ax = rng.gen_range(0..3);
                (b[ax], cc[ax]) = (a[ax], a[ax]);
            }
            // A point on the triangle, often on an edge or a vertex.
            let (mut s, mut t) = (rng.gen::<f32>(), rng.gen::<f32>());
            if s + t > 1.0 {
                (s, t) = (1.0 - s, 1.0 - t);
            }
            match case % 5 {
                0 => t = 0.0,
                1 => (s, t) = (0.0, 0.0),
                _ => {}
            }
            let target = a + (b - a) * s + (cc - a) * t;
            let dist = scale * 10f32.powi(rng.gen_range(0..3));
            let mut dir = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            if case % 7 == 0 {
                // Grazing: nearly in the triangle's plane.
                let n = (b - a).cross(cc - a).normalize_or(Vec3::Z);
                dir = dir.reject_from(n) + n * 1e-4;
            }
            let dir = dir.normalize_or(Vec3::X);
            let o = target - dir * dist;
            if case % 3 == 0 {
                std::mem::swap(&mut a, &mut b);
            }
            let lo = a.min(b).min(cc).to_array();
            let hi = a.max(b).max(cc).to_array();
            let Some(_) = intersect_triangle(o, dir, a, b, cc, 0.0, f32::INFINITY) else {
                continue;
            };
            hits += 1;
            let (g, p) = classify(o, dir, 0.0);
            assert!(g < UNBOUNDED);
            let s_all = o
                .abs()
                .max_element()
                .max(Vec3::from(lo).abs().max_element())
                .max(Vec3::from(hi).abs().max_element());
            let mut pts = vec![p];
            for k in 0..=(case % 3) {
                let b1 = Bound5::of(&pts);
                assert!(
                    Frustum5::new(g, &b1, s_all).keeps(&lo, &hi),
                    "frustum lost a hit: case {case}, {k} neighbours, {o:?} {dir:?}"
                );
                assert!(
                    Cone5::new(g, &b1, s_all).keeps(&lo, &hi),
                    "cone lost a hit: case {case}, {k} neighbours, {o:?} {dir:?}"
                );
                // A neighbour in the same bundle.
                let d2 = (dir
                    + Vec3::new(
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                    ) * 0.01)
                    .normalize();
                let (g2, p2) = classify(o + e(&mut rng) * 0.01, d2, 0.0);
                if g2 == g {
                    pts.push(p2);
                }
            }
            // Clipped to a box holding the triangle's (and a random neighbour's): the frustum
            // and the cone from the ray's entry point must keep it too.
            let other = c + e(&mut rng) * 5.0;
            let (blo, bhi) = (
                Vec3::from(lo).min(other),
                Vec3::from(hi).max(other + e(&mut rng).abs()),
            );
            let t0 = clip(o, dir, blo, bhi, 0.0, f32::INFINITY).expect("the hit is in the box");
            let oc = moved(o, dir, t0);
            clipped += (oc != o) as u32;
            let (_, pc) = classify(oc, dir, 0.0);
            let bc = Bound5::of([&pc]);
            let sc = s_all.max(oc.abs().max_element());
            assert!(
                Frustum5::new(g, &bc, sc).keeps(&lo, &hi),
                "clipped frustum lost a hit: case {case}, {o:?} {dir:?}"
            );
            assert!(
                Cone5::new(g, &bc, sc).keeps(&lo, &hi),
                "clipped cone lost a hit: case {case}, {o:?} {dir:?}"
            );
            // The same triangle moved away sideways (perpendicular to the ray by 2 sizes):
            // mostly culled by the single ray's frustum and cone.
            let side = dir.any_orthonormal_vector() * scale * 2.0;
            let (lo2, hi2) = (
                (Vec3::from(lo) + side).to_array(),
                (Vec3::from(hi) + side).to_array(),
            );
            let b1 = Bound5::of(&pts[..1]);
            far += 1;
            culled += (!Frustum5::new(g, &b1, s_all * 3.0).keeps(&lo2, &hi2)) as u32;
            culled += (!Cone5::new(g, &b1, s_all * 3.0).keeps(&lo2, &hi2)) as u32;
        }
        assert!(hits > 5_000, "{hits}");
        assert!(
            clipped > hits / 2,
            "clips that moved the origin: {clipped} of {hits}"
        );
        assert!(
            culled as f64 > 1.8 * far as f64,
            "culls too weak: {culled} of {}",
            2 * far
        );
    }
}
