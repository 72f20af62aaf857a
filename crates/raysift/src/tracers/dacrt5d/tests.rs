//! Unit tests of the pieces (the tracer itself: the conformance suite and `tests/dacrt5d.rs`).

use super::bound::{classify, Bound5, Cone5, Frustum, Rec, UNBOUNDED};
use crate::geom::intersect_triangle;
use glam::Vec3;
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
    assert_eq!(classify(Vec3::splat(f32::INFINITY), Vec3::X, 0.0).0, UNBOUNDED);
}

/// Triangles in axis planes and general ones far from the origin, and rays aimed at points on
/// and near them from far away (the gate moves their `t` onto flat boxes): every ray the shared
/// test hits must keep its triangle through both culls, with the ray alone as its node (the
/// tightest bound: a zero-width frustum, a zero-angle cone) and with a few neighbours. Red when
/// the margins or the slope widening are removed; the culls must also drop most triangles no
/// ray of the node can reach (checked, so the test is not vacuous).
#[test]
fn culls_keep_every_grazing_hit() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let (mut hits, mut culled, mut far) = (0, 0, 0);
    for case in 0..20_000 {
        let scale = 10f32.powi(rng.gen_range(-2..4));
        let c = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)) * scale;
        let e = |rng: &mut rand_pcg::Pcg64Mcg| {
            Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)) * scale * 0.1
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
        let mut dir = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
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
        let Some(_) = intersect_triangle(o, dir, a, b, cc, 0.0, f32::INFINITY) else { continue };
        hits += 1;
        let (g, p) = classify(o, dir, 0.0);
        assert!(g < UNBOUNDED);
        let s_all = o.abs().max_element().max(Vec3::from(lo).abs().max_element()).max(Vec3::from(hi).abs().max_element());
        let mut recs = vec![Rec { p, id: 0 }];
        for k in 0..=(case % 3) {
            let b1 = Bound5::of(&recs);
            assert!(Frustum::new(g, &b1, s_all).keeps(&lo, &hi), "frustum lost a hit: case {case}, {k} neighbours, {o:?} {dir:?}");
            assert!(Cone5::new(g, &b1, s_all).keeps(&lo, &hi), "cone lost a hit: case {case}, {k} neighbours, {o:?} {dir:?}");
            // A neighbour in the same bundle.
            let d2 = (dir + Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)) * 0.01).normalize();
            let (g2, p2) = classify(o + e(&mut rng) * 0.01, d2, 0.0);
            if g2 == g {
                recs.push(Rec { p: p2, id: 1 });
            }
        }
        // The same triangle moved away sideways (perpendicular to the ray by 2 sizes):
        // mostly culled by the single ray's frustum and cone.
        let side = dir.any_orthonormal_vector() * scale * 2.0;
        let (lo2, hi2) = ((Vec3::from(lo) + side).to_array(), (Vec3::from(hi) + side).to_array());
        let b1 = Bound5::of(&recs[..1]);
        far += 1;
        culled += (!Frustum::new(g, &b1, s_all * 3.0).keeps(&lo2, &hi2)) as u32;
        culled += (!Cone5::new(g, &b1, s_all * 3.0).keeps(&lo2, &hi2)) as u32;
    }
    assert!(hits > 5_000, "{hits}");
    assert!(culled as f64 > 1.8 * far as f64, "culls too weak: {culled} of {}", 2 * far);
}
