//! The exact cone/triangle test against a brute-force reference: dense sampling of the
//! triangle (interior grid and edges), f64, on random cones and on the named hard cases.

use super::*;
use rand::{Rng, SeedableRng};

const M: usize = 120;

/// Dense samples of the triangle: a barycentric grid plus finer samples along each edge.
fn samples(t: [Vec3; 3]) -> Vec<DVec3> {
    let p = t.map(|v| v.as_dvec3());
    let mut out = Vec::new();
    for i in 0..=M {
        for j in 0..=M - i {
            let (u, v) = (i as f64 / M as f64, j as f64 / M as f64);
            out.push(p[0] + (p[1] - p[0]) * u + (p[2] - p[0]) * v);
        }
    }
    for e in 0..3 {
        let (a, b) = (p[e], p[(e + 1) % 3]);
        for k in 0..=8 * M {
            out.push(a + (b - a) * (k as f64 / (8 * M) as f64));
        }
    }
    out
}

/// Checks `ConeF64::triangle` against the samples: (A) any sample inside the cone ⇒ a hit whose
/// `t` is at most the least sampled axial distance; (B) a hit ⇒ some sample within the grid
/// spacing of the cone, no farther along the axis than `t` plus that spacing. Returns the hit.
fn check(apex: Vec3, axis: Vec3, alpha: f32, t: [Vec3; 3]) -> Option<f32> {
    let c = ConeF64::new(apex, axis, alpha);
    let got = c.triangle(t[0], t[1], t[2]);
    let pts = samples(t);
    let h = |q: DVec3| (q - c.apex()).dot(c.axis());
    let inside_min = pts
        .iter()
        .filter(|&&q| c.contains(q))
        .map(|&q| h(q))
        .fold(f64::INFINITY, f64::min);
    let ctx = || format!("apex {apex:?} axis {axis:?} alpha {alpha} tri {t:?}: got {got:?}");
    if inside_min.is_finite() {
        let g = got.unwrap_or_else(|| panic!("sample inside but no hit: {}", ctx()));
        assert!(
            (g as f64) <= inside_min * (1.0 + 1e-6) + 1e-7,
            "t above a sampled inside point ({inside_min}): {}",
            ctx()
        );
    }
    if let Some(g) = got {
        let ext = (t[1] - t[0])
            .length()
            .max((t[2] - t[1]).length())
            .max((t[0] - t[2]).length()) as f64;
        let step = 2.0 * ext / M as f64 + 1e-9;
        let near = pts.iter().any(|&q| {
            let w = q - c.apex();
            let l = w.length();
            let ang = w.cross(c.axis()).length().atan2(w.dot(c.axis()));
            h(q) <= g as f64 + step && (l <= step || ang <= alpha as f64 + step / l)
        });
        assert!(near, "hit with no sample near the cone: {}", ctx());
        assert!(g >= 0.0, "negative t: {}", ctx());
    }
    got
}

fn unit(rng: &mut impl Rng) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

#[test]
fn random_cones_against_sampling() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(16);
    let (mut hits, mut n) = (0, 0);
    for _ in 0..400 {
        let apex = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        let axis = unit(&mut rng);
        // Half-angles from 0.06° to 86°, log-uniform.
        let alpha = (rng.gen_range(-7.0f32..0.4)).exp();
        let d = rng.gen_range(0.2f32..3.0);
        let r = d * alpha.tan().min(3.0);
        let centre = apex + axis * d + unit(&mut rng) * (r * rng.gen_range(0.0..2.0));
        let size = r.max(0.05) * rng.gen_range(0.3..3.0);
        let tri = [0, 1, 2].map(|_| centre + unit(&mut rng) * size);
        hits += check(apex, axis, alpha, tri).is_some() as usize;
        n += 1;
    }
    assert!(
        hits > n / 4 && hits < n,
        "{hits} of {n}: the cases must mix hits and misses"
    );
}

#[test]
fn triangle_enclosing_the_axis() {
    // No vertex and no edge inside the cone: only the generator candidates find it.
    let tri = [
        Vec3::new(-10.0, -10.0, 5.0),
        Vec3::new(10.0, -10.0, 5.0),
        Vec3::new(0.0, 10.0, 5.0),
    ];
    let t = check(Vec3::ZERO, Vec3::Z, 0.1, tri).unwrap();
    assert!((t - 5.0).abs() < 1e-6, "{t}");
    // Tilted plane z = 5 + 0.5 x: the lowest point is on the generator leaning to −x.
    let tilt = tri.map(|v| Vec3::new(v.x, v.y, 5.0 + 0.5 * v.x));
    let t = check(Vec3::ZERO, Vec3::Z, 0.1, tilt).unwrap();
    let (s, c) = 0.1f64.sin_cos();
    let want = 5.0 * c / (c + 0.5 * s); // the −x generator (−s, c) meets z = 5 + 0.5x
    assert!((t as f64 - want).abs() < 1e-5, "{t} vs {want}");
}

#[test]
fn apex_in_the_triangles_plane() {
    let tri = [
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(2.0, -1.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
    ];
    // Apex inside the triangle: t = 0 whatever the axis.
    assert_eq!(
        check(Vec3::new(0.1, 0.2, 0.0), unit_dir(0.3, 0.1, 1.0), 0.2, tri),
        Some(0.0)
    );
    // Apex in the plane, outside the triangle, cone grazing into it.
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
    for _ in 0..40 {
        let apex = Vec3::new(rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0), 0.0);
        let axis = (Vec3::new(0.0, 0.0, 0.0) - apex
            + unit(&mut rng) * 0.5
            + Vec3::Z * rng.gen_range(-0.5..0.5))
        .normalize();
        check(apex, axis, rng.gen_range(0.05..1.2), tri);
    }
}

fn unit_dir(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z).normalize()
}

#[test]
fn degenerate_triangles() {
    let (a, b) = (Vec3::new(-1.0, 0.05, 4.0), Vec3::new(1.0, -0.05, 4.0));
    // A segment crossing the cone: hit, t from the segment alone.
    let t = check(Vec3::ZERO, Vec3::Z, 0.05, [a, b, (a + b) * 0.5]).unwrap();
    assert!((t - 4.0).abs() < 1e-3, "{t}");
    // A segment beside the cone, and a point inside and outside.
    assert_eq!(
        check(
            Vec3::ZERO,
            Vec3::Z,
            0.05,
            [a + Vec3::X * 3.0, b + Vec3::X * 3.0, b + Vec3::X * 3.0]
        ),
        None
    );
    let p = Vec3::new(0.01, 0.0, 2.0);
    assert_eq!(check(Vec3::ZERO, Vec3::Z, 0.05, [p, p, p]), Some(2.0));
    assert_eq!(check(Vec3::ZERO, Vec3::Z, 0.001, [p, p, p]), None);
}

#[test]
fn half_angles_near_zero_and_ninety() {
    let tri = [
        Vec3::new(-1.0, -1.0, 3.0),
        Vec3::new(1.0, -1.0, 3.5),
        Vec3::new(0.0, 1.0, 3.2),
    ];
    // α → 0: t tends to the axis ray's hit distance.
    let t = check(Vec3::ZERO, Vec3::Z, 1e-5, tri).unwrap();
    let ray = crate::geom::intersect_triangle(
        Vec3::ZERO,
        Vec3::Z,
        tri[0],
        tri[1],
        tri[2],
        0.0,
        f32::INFINITY,
    );
    let rt = ray.expect("the axis hits").t;
    assert!((t - rt).abs() < 1e-3 && t <= rt + 1e-6, "{t} vs ray {rt}");
    // α → 90°: almost everything in front of the apex's plane is inside.
    let wide = 89.9f32.to_radians();
    let below = tri.map(|v| v * Vec3::new(1.0, 1.0, 0.0) + Vec3::new(5.0, 0.0, 0.01));
    let t = check(Vec3::ZERO, Vec3::Z, wide, below).unwrap();
    assert!(t <= 0.01 + 1e-6);
    let behind = tri.map(|v| v - Vec3::Z * 10.0);
    assert_eq!(check(Vec3::ZERO, Vec3::Z, wide, behind), None);
}
