use super::*;
use crate::geom::intersect_triangle;
use rand::{Rng, SeedableRng};

/// A point of the unit cube around the light, mostly on the cube faces' boundaries
/// (`|a| = |b| = 1`) or on its axes half of the time, at distance `scale`.
fn around(rng: &mut impl Rng, scale: f32) -> Vec3 {
    let mut p = Vec3::new(
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    );
    match rng.gen_range(0..4) {
        // On a cube edge: two coordinates of equal magnitude (face ties).
        0 => p.y = p.x.abs() * if rng.gen() { 1.0 } else { -1.0 },
        // On an axis.
        1 => {
            let k = rng.gen_range(0..3);
            p = Vec3::ZERO;
            p[k] = if rng.gen() { 1.0 } else { -1.0 };
        }
        _ => {}
    }
    p * scale
}

/// A point (far from the origin every third round) and 80 triangles small and large around
/// it, at a scale from 1e-4 to 1e4.
fn scene_around(rng: &mut impl Rng, round: usize) -> (f32, Vec3, Vec<[Vec3; 3]>) {
    let scale = 10f32.powi(rng.gen_range(-4..=4));
    let point = if round.is_multiple_of(3) {
        Vec3::new(1e3, -2e3, 5e2) * scale
    } else {
        around(rng, scale)
    };
    let tris = (0..80)
        .map(|_| {
            let k = scale * rng.gen_range(0.0..1.5);
            let c = point + around(rng, k);
            let size = scale * 10f32.powf(rng.gen_range(-3.0..0.3));
            [0; 3].map(|_| c + around(rng, size))
        })
        .collect();
    (scale, point, tris)
}

/// Every hit the shared test reports on a segment ending at (or near) the light lies where the
/// light-space cull looks for it: the triangle is near the light, or its footprint on the
/// segment's face holds the segment's coordinates and starts no deeper than the segment's depth.
/// Segments of every construction (`d = L − o` to `t = 1`, stopping at `1 − 1e-4`, normalised
/// directions, a few ulps past the light), triangles small and large around the light (some
/// just outside the ball, some containing the light, some nearly along the segments), scales
/// from 1e-4 to 1e4 and lights far from the origin. Not vacuous: most hits are far from the
/// light, and the footprints cull most far pairs.
#[test]
fn every_hit_is_inside_its_footprint() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(21);
    let (mut hits, mut far_hits, mut far_pairs, mut culled) = (0u64, 0u64, 0u64, 0u64);
    for round in 0..300 {
        let (scale, light, mut tris) = scene_around(&mut rng, round);
        for t in &mut tris {
            if rng.gen_range(0..8) == 0 {
                // Two corners on a line through the light (grazing hits).
                let p = light + around(&mut rng, scale);
                t[0] = light + (p - light) * rng.gen_range(0.1..0.9);
                t[1] = light + (p - light) * rng.gen_range(0.1..0.9);
            }
        }
        let mut segs = Vec::new();
        for _ in 0..60 {
            // Half of them behind a triangle's corner or edge point as seen from the light
            // (hits on the box's boundary), the others anywhere.
            let o = if rng.gen() {
                let t = tris[rng.gen_range(0..tris.len())];
                let p = if rng.gen() {
                    t[rng.gen_range(0..3)]
                } else {
                    (t[0] + t[1]) * 0.5
                };
                light + (p - light) * rng.gen_range(1.0..3.0)
            } else {
                let k = scale * rng.gen_range(0.05..2.0);
                light + around(&mut rng, k)
            };
            if o == light {
                continue;
            }
            let d = light - o;
            let (d, tmax) = match rng.gen_range(0..4) {
                0 => (d, 1.0),
                1 => (d, 1.0 - 1e-4),
                2 => (d.normalize(), d.length()),
                _ => (d, 1.0 + 1e-7),
            };
            let tmin = if rng.gen() { 0.0 } else { 1e-4 * tmax };
            segs.push((o, d, tmin, tmax));
        }
        let slack = segs
            .iter()
            .map(|&(o, d, tmin, tmax)| {
                segment_slack(light, o, d, tmin, tmax)
                    .unwrap_or_else(|| panic!("fits: {light} {o} {d} {tmin} {tmax}"))
            })
            .fold(0.0, f64::max);
        let scale_all = tris
            .iter()
            .flatten()
            .chain(segs.iter().map(|s| &s.0))
            .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
        let view = LightView::new(light, slack, scale_all as f64, 0.0).unwrap();
        for &(o, d, tmin, tmax) in &segs {
            let s = view.segment(o, d, tmax).unwrap();
            assert!(s.a.abs() <= 1.0 + 1e-15 && s.b.abs() <= 1.0 + 1e-15);
            for t in &tris {
                let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                let near = view.near(lo, hi);
                let fp = (!near).then(|| view.footprint(lo, hi, s.face)).flatten();
                let inside = fp.is_some_and(|f| {
                    f.a[0] <= s.a
                        && s.a <= f.a[1]
                        && f.b[0] <= s.b
                        && s.b <= f.b[1]
                        && f.x0 <= s.depth
                });
                if !near {
                    far_pairs += 1;
                    culled += !inside as u64;
                }
                if intersect_triangle(o, d, t[0], t[1], t[2], tmin, tmax).is_some() {
                    hits += 1;
                    if !near {
                        far_hits += 1;
                        assert!(inside, "hit outside its footprint: light {light} o {o} d {d} tmax {tmax} tri {t:?} {fp:?} {s:?}");
                    }
                }
            }
        }
    }
    assert!(
        hits > 2000 && far_hits > hits / 3,
        "{hits} hits, {far_hits} far"
    );
    assert!(
        culled > far_pairs / 2,
        "{culled} of {far_pairs} far pairs culled"
    );
}

#[test]
fn slack_refuses_what_the_pass_cannot_use() {
    let l = Vec3::new(1.0, 2.0, 3.0);
    let o = Vec3::new(-1.0, 0.5, 0.0);
    assert!(segment_slack(l, o, l - o, 0.0, 1.0).is_some());
    // Not towards the light, negative tmin, NaN, an origin on the light, tmin > tmax.
    assert!(segment_slack(l, o, Vec3::X, 0.0, 1.0).is_none());
    assert!(segment_slack(l, o, l - o, -0.5, 1.0).is_none());
    assert!(segment_slack(l, o, Vec3::NAN, 0.0, 1.0).is_none());
    assert!(segment_slack(l, l, Vec3::X, 0.0, 1.0).is_none());
    assert!(segment_slack(l, o, l - o, 0.6, 0.5).is_none());
    // Far past the light: refused; stopping short: fine.
    assert!(segment_slack(l, o, l - o, 0.0, 1.5).is_none());
    assert!(segment_slack(l, o, l - o, 0.0, 0.5).is_some());
    // The ball grows with the slack, and a segment's coordinates are its origin's.
    let v = LightView::new(l, 1e-6, 3.0, 0.0).unwrap();
    assert!((v.ball() - 1e-2).abs() < 1e-12);
    let s = v.segment(o, l - o, 1.0).unwrap();
    // o − l = (−2, −1.5, −3): face −z (5), (a, b) = (−2, −1.5) / 3.
    assert_eq!(s.face, 5);
    assert!((s.a + 2.0 / 3.0).abs() < 1e-12 && (s.b + 0.5).abs() < 1e-12);
    assert!((s.depth - 3.0).abs() < 1e-9);
}

/// Rays from the frame's point itself (the eye pass of `dacrt5d`): every hit the shared test
/// reports lies where the eye pass looks for it. The triangle is near the point, or its
/// footprint on the ray's face holds the direction's coordinates and starts no deeper than
/// the hit's face-axis coordinate `t·|d_k|` (so a ray whose best hit is nearer than `x0` skips
/// the triangle exactly). Rays through the triangles' corners and edge midpoints (hits on the
/// boxes' boundaries), directions on cube edges and axes (face ties), lengths from 1e-3 to 1e3,
/// scales from 1e-4 to 1e4, eyes far from the origin. Not vacuous: most pairs are culled.
#[test]
fn every_eye_ray_hit_is_inside_its_footprint() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(17);
    let (mut hits, mut far_hits, mut far_pairs, mut culled) = (0u64, 0u64, 0u64, 0u64);
    for round in 0..300 {
        let (_, eye, tris) = scene_around(&mut rng, round);
        let scale_all = tris
            .iter()
            .flatten()
            .chain([&eye])
            .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
        let view = LightView::new(eye, 0.0, scale_all as f64, 0.0).unwrap();
        for _ in 0..60 {
            let d = if rng.gen() {
                let t = tris[rng.gen_range(0..tris.len())];
                let p = if rng.gen() {
                    t[rng.gen_range(0..3)]
                } else {
                    (t[0] + t[1]) * 0.5
                };
                p - eye
            } else {
                around(&mut rng, 1.0)
            } * 10f32.powi(rng.gen_range(-3..=3));
            let Some(r) = ray_view(d) else {
                continue;
            };
            assert!(r.a.abs() <= 1.0 && r.b.abs() <= 1.0);
            let tmin = if rng.gen() { 0.0 } else { 1e-3 };
            for t in &tris {
                let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                let near = view.near(lo, hi);
                let fp = (!near).then(|| view.footprint(lo, hi, r.face)).flatten();
                let holds = |f: &Footprint| {
                    f.a[0] <= r.a && r.a <= f.a[1] && f.b[0] <= r.b && r.b <= f.b[1]
                };
                if !near {
                    far_pairs += 1;
                    culled += !fp.as_ref().is_some_and(holds) as u64;
                }
                if let Some(h) = intersect_triangle(eye, d, t[0], t[1], t[2], tmin, f32::INFINITY) {
                    hits += 1;
                    if !near {
                        far_hits += 1;
                        let x = h.t as f64 * r.axis;
                        assert!(
                            fp.as_ref().is_some_and(|f| holds(f) && f.x0 <= x),
                            "hit outside its footprint: eye {eye} d {d} tri {t:?} {fp:?} {r:?} x {x}"
                        );
                    }
                }
            }
        }
    }
    assert!(
        hits > 2000 && far_hits > hits / 2,
        "{hits} hits, {far_hits} far"
    );
    assert!(
        culled > far_pairs / 2,
        "{culled} of {far_pairs} far pairs culled"
    );
}
