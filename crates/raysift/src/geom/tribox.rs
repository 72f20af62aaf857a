//! Triangle/box overlap by separating axes (Akenine-Möller 2001), made conservative against
//! rounding: a test may keep a triangle that only touches the box within a few ulps, never drop
//! one that overlaps it.
//!
//! Two entry points:
//! - [`tri_box_edge_axes`]: only the 9 axes `edge_i × unit_k`. DACRT (Mora 2011, §3.5) uses it on
//!   small streams, after the split-plane test; the three box-face axes are implied by the
//!   recursion (every ancestor's split test kept the triangle's bounds overlapping the cell on
//!   that axis) and the triangle-plane axis is dropped as in the paper (it needs the normal and
//!   rarely separates).
//! - [`tri_box_overlap`]: all 13 axes, the full test (reference and tests).
//!
//! Robustness: instead of the usual centre/half-size form (which can shrink the box by an ulp),
//! each axis compares the triangle's projection interval with the box's, both computed from the
//! original coordinates, and only declares a separation when the gap exceeds a bound on the
//! rounding error of the two 3-term dot products. Any axis `a` proves separation when the exact
//! projections are disjoint, whatever rounding went into computing `a` itself, so only the dot
//! products need the bound.

use super::Aabb;
use glam::Vec3;

/// Relative error bound of a 3-term dot product in f32 (γ₃ ≈ 3ε), doubled for the two sides and
/// with room to spare.
const DOT_ERR: f32 = 8.0 * f32::EPSILON;

/// True unless axis `a` separates the triangle from the box (with the rounding margin).
#[inline(always)]
fn axis_overlaps(a: Vec3, v: [Vec3; 3], b: &Aabb) -> bool {
    let p0 = a.dot(v[0]);
    let p1 = a.dot(v[1]);
    let p2 = a.dot(v[2]);
    let tmin = p0.min(p1).min(p2);
    let tmax = p0.max(p1).max(p2);
    // Box projection: per component, the corner coordinate that minimises / maximises a_k·x_k.
    let lo = a * b.min;
    let hi = a * b.max;
    let bmin = lo.min(hi).element_sum();
    let bmax = lo.max(hi).element_sum();
    // Magnitude bound: Σ_k |a_k|·max(|x_k|) over all points involved.
    let m = b
        .min
        .abs()
        .max(b.max.abs())
        .max(v[0].abs())
        .max(v[1].abs())
        .max(v[2].abs());
    let tol = a.abs().dot(m) * DOT_ERR;
    // NaN anywhere (not expected: scenes are finite) keeps the triangle.
    !(tmax < bmin - tol || tmin > bmax + tol)
}

/// The 9 cross-product axes `(v1−v0, v2−v1, v0−v2) × (x, y, z)`: false only when one of them
/// separates the triangle from the box.
#[inline]
pub fn tri_box_edge_axes(v0: Vec3, v1: Vec3, v2: Vec3, b: &Aabb) -> bool {
    let v = [v0, v1, v2];
    let edges = [v1 - v0, v2 - v1, v0 - v2];
    for e in edges {
        // e × x = (0, e.z, −e.y), e × y = (−e.z, 0, e.x), e × z = (e.y, −e.x, 0).
        if !axis_overlaps(Vec3::new(0.0, e.z, -e.y), v, b)
            || !axis_overlaps(Vec3::new(-e.z, 0.0, e.x), v, b)
            || !axis_overlaps(Vec3::new(e.y, -e.x, 0.0), v, b)
        {
            return false;
        }
    }
    true
}

/// The full 13-axis test: box faces, triangle plane and the 9 edge axes.
pub fn tri_box_overlap(v0: Vec3, v1: Vec3, v2: Vec3, b: &Aabb) -> bool {
    let tmin = v0.min(v1).min(v2);
    let tmax = v0.max(v1).max(v2);
    // Face axes: exact comparisons of coordinates.
    if tmax.cmplt(b.min).any() || tmin.cmpgt(b.max).any() {
        return false;
    }
    let n = (v1 - v0).cross(v2 - v0);
    axis_overlaps(n, [v0, v1, v2], b) && tri_box_edge_axes(v0, v1, v2, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn unit() -> Aabb {
        Aabb::new(Vec3::ZERO, Vec3::ONE)
    }

    #[test]
    fn obvious_cases() {
        let b = unit();
        // Inside.
        let (a, c, d) = (
            Vec3::splat(0.2),
            Vec3::new(0.8, 0.2, 0.2),
            Vec3::new(0.2, 0.8, 0.5),
        );
        assert!(tri_box_overlap(a, c, d, &b));
        // Far away.
        assert!(!tri_box_overlap(a + 5.0, c + 5.0, d + 5.0, &b));
        // Touching a face exactly (lying in the plane x = 1) is kept.
        let t = [
            Vec3::new(1.0, 0.2, 0.2),
            Vec3::new(1.0, 0.8, 0.2),
            Vec3::new(1.0, 0.5, 0.9),
        ];
        assert!(tri_box_overlap(t[0], t[1], t[2], &b));
        assert!(tri_box_edge_axes(t[0], t[1], t[2], &b));
    }

    #[test]
    fn edge_axis_separates_a_corner_cutter() {
        // A triangle near the corner (1,1,·) whose bounds overlap the box but which passes
        // outside the edge x = y = 1: only an edge axis separates it.
        let b = unit();
        let t = [
            Vec3::new(2.1, 0.9, 0.5),
            Vec3::new(0.9, 2.1, 0.5),
            Vec3::new(2.1, 2.1, 0.5),
        ];
        assert!(!tri_box_overlap(t[0], t[1], t[2], &b));
        assert!(!tri_box_edge_axes(t[0], t[1], t[2], &b));
        // Moved to cut the corner, it overlaps.
        let s = Vec3::new(-0.6, -0.6, 0.0);
        assert!(tri_box_edge_axes(t[0] + s, t[1] + s, t[2] + s, &b));
    }

    /// Conservativeness: a triangle that contains a point of the box (sampled) is never rejected.
    #[test]
    fn never_rejects_a_triangle_through_the_box() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let b = Aabb::new(Vec3::new(-0.3, 0.1, 2.0), Vec3::new(0.4, 0.15, 2.5));
        let mut kept = 0;
        for _ in 0..20_000 {
            // A point in the box (often on its boundary) and a triangle around it.
            let mut p = b.min + b.extent() * Vec3::new(rng.gen(), rng.gen(), rng.gen());
            let k = rng.gen_range(0..6);
            if k < 3 {
                p[k] = if rng.gen() { b.min[k] } else { b.max[k] };
            }
            let mut r = || {
                Vec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                )
            };
            let (e1, e2, w) = (r(), r(), r().abs());
            let (wa, wb) = (w.x * 0.5, w.y * 0.5);
            // p = v0 + wa·e1 + wb·e2 (up to rounding, which the margin covers).
            let v0 = p - e1 * wa - e2 * wb;
            let (v1, v2) = (v0 + e1, v0 + e2);
            assert!(tri_box_overlap(v0, v1, v2, &b), "{v0} {v1} {v2}");
            assert!(tri_box_edge_axes(v0, v1, v2, &b));
            kept += 1;
        }
        assert_eq!(kept, 20_000);
    }

    /// Separated triangles (all vertices beyond a plane through an edge of the box) are
    /// rejected by the full test most of the time: the margin is small.
    #[test]
    fn rejects_clearly_separated() {
        let b = unit();
        for k in 0..100 {
            let o = Vec3::new(2.0 + k as f32 * 0.01, 0.5, 0.5);
            assert!(!tri_box_overlap(o, o + Vec3::Y, o + Vec3::Z, &b));
        }
    }
}
