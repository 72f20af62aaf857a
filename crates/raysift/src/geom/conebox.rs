//! Exact cone/box overlap for DACRT's conic packets (Mora 2011, §3.3 and Appendix).
//!
//! A one-sided cone (apex `A`, unit axis `d`, half-angle `α < 90°`) meets a closed box iff
//! 1. `A` is inside the box, or
//! 2. the axis ray `A + t·d, t ≥ 0` hits the box, or
//! 3. a **silhouette edge** of the box, as seen from `A`, enters the cone.
//!
//! Why this is exact: on the unit sphere around `A` the cone is a disk and the box (with `A`
//! outside) a convex spherical polygon bounded by the silhouette edges; they meet iff the disk's
//! centre is inside the polygon (2) or the disk reaches its boundary (3), which also covers a
//! polygon lying wholly inside the disk.
//!
//! The silhouette is read from a 64-entry table ([`SILHOUETTE`]) indexed by the apex's 6-bit
//! outcode against the box's six planes (6 comparisons); 27 entries are valid (`0b00` or one bit
//! per axis), giving 0 edges (apex inside), 4 (outside on one axis: the rim of the one visible
//! face) or 6 (outside on two or three axes). An edge is on the silhouette iff exactly one of
//! its two faces is visible; the table is built from that rule at compile time.
//!
//! Edge/cone (Appendix): the paper squares `cos∠(w, d) = cos α` into a quadratic in the edge
//! parameter and checks the roots and the positive nappe. We use the equivalent closed form that
//! avoids the near-tangent cancellation of the discriminant: along a line, `cos∠(w(s), d)` has at
//! most one stationary point `s*`, so its maximum over the segment is at `0`, `1` or `s*`, and the
//! edge enters the cone iff that maximum is `≥ cos α` (`d·w ≥ 0`, and `(d·w)² ≥ cos²α·|w|²`).
//! A test against the paper's quadratic is in the unit tests.
//!
//! Precision: everything after the outcode is done in f64. Conic packets in DACRT carry an
//! angular margin of about 1e-6 rad; in f32, `cos α` near 1 cannot resolve that margin, in f64 it
//! can, so the test is conservative for cones built by [`super::Cone::around_directions`].

use super::Aabb;
use glam::{DVec3, Vec3, Vec3A};

/// The 12 box edges, `axis * 4 + m`: the edge runs along `axis`; bit 0 of `m` picks min/max on
/// axis `(axis+1)%3`, bit 1 on axis `(axis+2)%3`.
const fn silhouette_table() -> ([[u8; 6]; 64], [u8; 64]) {
    let mut edges = [[0u8; 6]; 64];
    let mut count = [0u8; 64];
    let mut code = 0;
    while code < 64 {
        // Visible faces: bit 2k = apex below min on axis k, bit 2k+1 = above max.
        let mut valid = true;
        let mut k = 0;
        while k < 3 {
            if (code >> (2 * k)) & 3 == 3 {
                valid = false;
            }
            k += 1;
        }
        if valid && code != 0 {
            let mut n = 0;
            let mut e = 0;
            while e < 12 {
                let a = e / 4;
                let m = e % 4;
                let u = (a + 1) % 3;
                let w = (a + 2) % 3;
                let fu = (code >> (2 * u + (m & 1))) & 1;
                let fw = (code >> (2 * w + ((m >> 1) & 1))) & 1;
                if fu + fw == 1 {
                    edges[code][n] = e as u8;
                    n += 1;
                }
                e += 1;
            }
            count[code] = n as u8;
        }
        code += 1;
    }
    (edges, count)
}

const TABLE: ([[u8; 6]; 64], [u8; 64]) = silhouette_table();

/// Silhouette edges per apex outcode (see the module doc): `SILHOUETTE.0[code][..SILHOUETTE.1[code]]`.
pub const SILHOUETTE: ([[u8; 6]; 64], [u8; 64]) = TABLE;

/// The apex outcode: bit `2k` when `p[k] < b.min[k]`, bit `2k+1` when `p[k] > b.max[k]`.
#[inline(always)]
pub fn outcode(p: Vec3, b: &Aabb) -> usize {
    let mut c = 0;
    for k in 0..3 {
        c |= ((p[k] < b.min[k]) as usize) << (2 * k);
        c |= ((p[k] > b.max[k]) as usize) << (2 * k + 1);
    }
    c
}

/// Endpoints of edge `e` of box `(lo, hi)`.
#[inline(always)]
fn edge(e: u8, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let a = (e / 4) as usize;
    let m = e % 4;
    let (u, w) = ((a + 1) % 3, (a + 2) % 3);
    let mut p0 = lo;
    if m & 1 != 0 {
        p0[u] = hi[u];
    }
    if m & 2 != 0 {
        p0[w] = hi[w];
    }
    let mut p1 = p0;
    p1[a] = hi[a];
    (p0, p1)
}

/// Relative slack on the squared-cosine comparison (f64 rounding of a handful of operations).
const COS_SLACK: f64 = 1e-12;

#[inline(always)]
fn inside_cone(w: DVec3, axis: DVec3, cos2: f64) -> bool {
    let n = axis.dot(w);
    n >= 0.0 && n * n >= cos2 * w.length_squared() * (1.0 - COS_SLACK)
}

/// True when the segment `p0 → p1` has a point inside the one-sided cone (apex, unit `axis`,
/// `cos2 = cos²α`, `α < 90°`).
#[inline]
pub fn segment_in_cone(apex: DVec3, axis: DVec3, cos2: f64, p0: DVec3, p1: DVec3) -> bool {
    let a = p0 - apex;
    let e = p1 - p0;
    if inside_cone(a, axis, cos2) || inside_cone(p1 - apex, axis, cos2) {
        return true;
    }
    let (da, de, ae, aa, ee) = (axis.dot(a), axis.dot(e), a.dot(e), a.dot(a), e.dot(e));
    let den = de * ae - da * ee;
    if den == 0.0 {
        return false;
    }
    let s = ((da * ae - de * aa) / den).clamp(0.0, 1.0);
    s.is_finite() && inside_cone(a + e * s, axis, cos2)
}

/// A cone prepared for many box tests: the per-cone constants of [`cone_box_overlap`] (unit
/// axis, `cos α`, `sin α` in f64), computed once per cone instead of once per test. The apex is
/// passed to [`ConeQuery::overlaps`] (DACRT's cones share theirs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConeQuery {
    axis: DVec3,
    cos2: f64,
    cos_a: f64,
    sin_a: f64,
    near: f32,
    reach: f32,
}

impl ConeQuery {
    /// See [`cone_box_overlap`] for the arguments.
    pub fn new(axis: Vec3, cos2: f64, near_radius: f32, reach: f32) -> Self {
        Self {
            axis: axis.as_dvec3().normalize(),
            cos2,
            cos_a: cos2.max(0.0).sqrt(),
            sin_a: (1.0 - cos2).max(0.0).sqrt(),
            near: near_radius,
            reach,
        }
    }

    /// Whether the cone with apex `apex` meets box `b` (exact up to the `reach` cut; see
    /// [`cone_box_overlap`]).
    #[inline]
    pub fn overlaps(&self, apex: Vec3, b: &Aabb) -> bool {
        if self.reach < f32::INFINITY {
            let q = apex.clamp(b.min, b.max) - apex;
            // f64: the squared distance must not round below reach².
            let r = self.reach as f64;
            if q.as_dvec3().length_squared() > r * r {
                return false;
            }
        }
        let code = outcode(apex, b);
        if code == 0 {
            return true;
        }
        let (d, a) = (self.axis, apex.as_dvec3());
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        if self.near > 0.0 {
            let q = a.clamp(lo, hi);
            let r = self.near as f64;
            if (q - a).length_squared() <= r * r {
                return true;
            }
        }
        // Cheap decisions first, from the box's bounding sphere (centre `c`, radius `r`): the
        // centre is a point of the box, so the centre inside the cone means overlap; a sphere
        // farther than `r` from the (convex, α < 90°) cone means none. In the plane of the axis
        // and `w = c − A` (axial `n`, radial `m`), `gap = m·cos α − n·sin α` is the signed
        // distance to the rim line: negative only inside the cone, and never more than the
        // distance to the cone (which is `gap` when `w` projects onto the rim ray, `s = n·cos α +
        // m·sin α ≥ 0`, else `|w|`). Most of DACRT's cone/cell pairs are decided here, in f32
        // (SIMD); `margin` covers the f32 rounding of these few operations (a handful of ε of
        // the magnitudes involved: 64 ε is several times that), and only spheres within it of
        // the cone's boundary, or straddling it, go on to the exact test in f64.
        {
            let (lo, hi, a) = (Vec3A::from(b.min), Vec3A::from(b.max), Vec3A::from(apex));
            let d = Vec3A::from(d.as_vec3());
            let c = (lo + hi) * 0.5;
            let w = c - a;
            let r = ((hi - lo) * 0.5).length();
            let n = d.dot(w);
            let m = (w - d * n).length();
            let l = w.length();
            let (ca, sa) = (self.cos_a as f32, self.sin_a as f32);
            let gap = m * ca - n * sa;
            let margin =
                64.0 * f32::EPSILON * (a.abs().max_element() + c.abs().max_element() + l + r);
            if gap < -margin {
                return true;
            }
            if gap > r + margin || (n * ca + m * sa < -margin && l > r + margin) {
                return false;
            }
        }
        // The axis ray: the shared conservative slab test.
        if b.ray_interval(apex, Vec3::ONE / d.as_vec3(), 0.0, f32::INFINITY)
            .is_some()
        {
            return true;
        }
        let (edges, count) = &SILHOUETTE;
        for &e in &edges[code][..count[code] as usize] {
            let (p0, p1) = edge(e, lo, hi);
            if segment_in_cone(a, d, self.cos2, p0, p1) {
                return true;
            }
        }
        false
    }
}

/// Exact one-sided cone/box overlap (see the module doc). `axis` need not be unit length;
/// `cos2 = cos²(half-angle)`, half-angle in `[0, 90°)`. For many boxes per cone, prepare a
/// [`ConeQuery`] once.
///
/// `near_radius`: boxes within this distance of the apex also count as hit. DACRT's shadow cones
/// use it because their rays end a few ulps away from the light, not exactly on it.
///
/// `reach`: the cone is cut at this distance from the apex (`f32::INFINITY` for none); a box
/// farther than `reach` from the apex misses. This part is conservative rather than exact (the
/// box must meet both the cone and the ball of radius `reach`, not their intersection).
#[inline]
pub fn cone_box_overlap(
    apex: Vec3,
    axis: Vec3,
    cos2: f64,
    near_radius: f32,
    reach: f32,
    b: &Aabb,
) -> bool {
    ConeQuery::new(axis, cos2, near_radius, reach).overlaps(apex, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn table_has_27_valid_entries_with_4_or_6_edges() {
        let (edges, count) = &SILHOUETTE;
        let mut valid = 0;
        for code in 0..64usize {
            let ok = (0..3).all(|k| (code >> (2 * k)) & 3 != 3);
            if !ok {
                assert_eq!(count[code], 0);
                continue;
            }
            valid += 1;
            let axes_out = (0..3).filter(|k| (code >> (2 * k)) & 3 != 0).count();
            let want = [0, 4, 6, 6][axes_out];
            assert_eq!(count[code] as usize, want, "code {code:06b}");
            // No edge twice.
            let mut seen = [false; 12];
            for &e in &edges[code][..count[code] as usize] {
                assert!(!seen[e as usize]);
                seen[e as usize] = true;
            }
        }
        assert_eq!(valid, 27);
        // Apex below x only: the rim of face x = min, i.e. the 4 edges with x = min that run
        // along y or z: y-edges (axis 1, m bit 1 = x side) and z-edges (axis 2, m bit 0 = x side).
        let code = 0b000001;
        let mut e: Vec<u8> = edges[code][..4].to_vec();
        e.sort();
        assert_eq!(e, vec![4, 5, 8, 10]);
    }

    /// Reference: dense sampling of the box (surface and inside) for a point in the cone.
    fn sampled(apex: Vec3, axis: Vec3, half: f32, b: &Aabb, n: usize) -> bool {
        let c = (half as f64).cos();
        let d = axis.as_dvec3().normalize();
        let a = apex.as_dvec3();
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        for i in 0..=n {
            for j in 0..=n {
                for k in 0..=n {
                    let t = DVec3::new(i as f64, j as f64, k as f64) / n as f64;
                    let p = lo + (hi - lo) * t;
                    let w = p - a;
                    let l = w.length();
                    if l == 0.0 || d.dot(w) >= c * l {
                        return true;
                    }
                }
            }
        }
        false
    }

    #[test]
    fn agrees_with_sampling_and_is_conservative() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let b = Aabb::new(Vec3::new(-1.0, -0.5, 0.0), Vec3::new(1.0, 0.5, 0.4));
        let (mut hits, mut extra) = (0, 0);
        for _ in 0..3000 {
            let apex = Vec3::new(
                rng.gen_range(-4.0..4.0),
                rng.gen_range(-4.0..4.0),
                rng.gen_range(-4.0..4.0),
            );
            let axis = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            )
            .normalize();
            let half: f32 = rng.gen_range(0.001..0.6);
            let got = cone_box_overlap(
                apex,
                axis,
                (half as f64).cos().powi(2),
                0.0,
                f32::INFINITY,
                &b,
            );
            let want = sampled(apex, axis, half, &b, 24);
            // Sampling can only miss overlaps, never invent them.
            if want {
                assert!(got, "false negative: apex {apex} axis {axis} half {half}");
                hits += 1;
            } else if got {
                extra += 1;
            }
        }
        assert!(hits > 200, "{hits}");
        // "Extra" are real overlaps too thin for the sample grid: few.
        assert!(extra < hits / 5, "{extra} vs {hits}");
    }

    /// Cones aimed just beside a random edge from random outside apexes (all 26 outcodes):
    /// a cone slightly wider than the angle to the box (dense sampling of all 12 edges) hits,
    /// a slightly narrower one misses. Exercises every silhouette-table entry.
    #[test]
    fn grazing_cones_from_every_side() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let b = Aabb::new(Vec3::new(-0.5, 0.0, 0.2), Vec3::new(0.5, 0.7, 1.0));
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        let mut codes = [0u32; 64];
        let mut tested = 0;
        while tested < 600 {
            let apex = Vec3::new(
                rng.gen_range(-2.5..2.5),
                rng.gen_range(-2.0..2.7),
                rng.gen_range(-1.8..3.0),
            );
            let code = outcode(apex, &b);
            if code == 0 {
                continue;
            }
            let (p0, p1) = edge(rng.gen_range(0..12), lo, hi);
            let p = p0 + (p1 - p0) * rng.gen_range(0.0..1.0);
            let off = DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ) * 0.03;
            let axis = ((p + off).as_vec3() - apex).normalize();
            if b.ray_interval(apex, Vec3::ONE / axis, 0.0, f32::INFINITY)
                .is_some()
            {
                continue;
            }
            // Smallest angle from the axis to the box: on its boundary, so on an edge.
            let (a, d) = (apex.as_dvec3(), axis.as_dvec3().normalize());
            let mut best = -1.0f64;
            for e in 0..12 {
                let (q0, q1) = edge(e, lo, hi);
                for k in 0..=4000 {
                    let w = q0 + (q1 - q0) * (k as f64 / 4000.0) - a;
                    best = best.max(d.dot(w) / w.length());
                }
            }
            let theta = best.clamp(-1.0, 1.0).acos();
            if !(theta > 1e-3 && theta < 1.2) {
                continue;
            }
            let wide = (theta * 1.01).cos().powi(2);
            let narrow = (theta * 0.99).cos().powi(2);
            assert!(
                cone_box_overlap(apex, axis, wide, 0.0, f32::INFINITY, &b),
                "apex {apex} axis {axis} θ {theta}"
            );
            assert!(
                !cone_box_overlap(apex, axis, narrow, 0.0, f32::INFINITY, &b),
                "apex {apex} axis {axis} θ {theta}"
            );
            codes[code] += 1;
            tested += 1;
        }
        let seen = codes.iter().filter(|&&c| c > 0).count();
        assert_eq!(seen, 26, "{codes:?}");
    }

    /// The Appendix quadratic and our stationary-point form agree on random segments.
    #[test]
    fn matches_the_papers_quadratic() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let mut agree = 0;
        for _ in 0..20_000 {
            let r = |rng: &mut rand_pcg::Pcg64Mcg| {
                DVec3::new(
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-2.0..2.0),
                )
            };
            let (c, p0, p1) = (r(&mut rng), r(&mut rng), r(&mut rng));
            let dir = r(&mut rng).normalize();
            let cos: f64 = rng.gen_range(0.2..0.999);
            let ours = segment_in_cone(c, dir, cos * cos, p0, p1);
            // Paper: ((co + v t)·dir)² = cos²α·|co + v t|², roots and the positive nappe.
            let (co, v) = (p0 - c, p1 - p0);
            let inside = |t: f64| {
                let w = co + v * t;
                let n = w.dot(dir);
                n >= 0.0 && n * n >= cos * cos * w.length_squared()
            };
            let qa = v.dot(dir).powi(2) - cos * cos * v.length_squared();
            let qb = 2.0 * (co.dot(dir) * v.dot(dir) - cos * cos * co.dot(v));
            let qc = co.dot(dir).powi(2) - cos * cos * co.length_squared();
            let mut theirs = inside(0.0) || inside(1.0);
            let disc = qb * qb - 4.0 * qa * qc;
            if disc >= 0.0 && qa != 0.0 {
                for t in [
                    (-qb - disc.sqrt()) / (2.0 * qa),
                    (-qb + disc.sqrt()) / (2.0 * qa),
                ] {
                    if (0.0..=1.0).contains(&t) && (co + v * t).dot(dir) >= 0.0 {
                        theirs = true;
                    }
                }
            }
            if ours == theirs {
                agree += 1;
            } else {
                // Disagreements only at tangency (both within rounding of the cone surface).
                assert!(ours, "ours missed a crossing");
            }
        }
        assert!(agree > 19_900, "{agree}");
    }

    #[test]
    fn apex_inside_and_near_radius() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert!(cone_box_overlap(
            Vec3::splat(0.5),
            Vec3::X,
            0.99,
            0.0,
            f32::INFINITY,
            &b
        ));
        // Pointing away, just outside the box: only the near radius keeps it.
        let apex = Vec3::new(1.0 + 1e-4, 0.5, 0.5);
        assert!(!cone_box_overlap(
            apex,
            Vec3::X,
            0.99,
            0.0,
            f32::INFINITY,
            &b
        ));
        assert!(cone_box_overlap(
            apex,
            Vec3::X,
            0.99,
            1e-3,
            f32::INFINITY,
            &b
        ));
        // Reach: a cone cut short of the box misses it.
        let apex = Vec3::new(-1.0, 0.5, 0.5);
        assert!(cone_box_overlap(apex, Vec3::X, 0.99, 0.0, 1.0, &b));
        assert!(!cone_box_overlap(apex, Vec3::X, 0.99, 0.0, 0.999, &b));
    }
}
