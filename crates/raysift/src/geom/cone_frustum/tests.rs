//! Basic == improved bit for bit; both conservative against the exact cone/triangle test.

use super::*;
use crate::geom::{cone_triangle::ConeF64, Aabb};
use rand::{Rng, SeedableRng};

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

/// Axes with exact zeros and ±1 components now and then (axis-aligned cones, `d_k ± β_k`
/// exactly zero is then reachable only through rounding, so also half-angles of 45°).
fn axis(rng: &mut impl Rng) -> Vec3 {
    match rng.gen_range(0..4) {
        0 => [Vec3::X, -Vec3::Y, Vec3::Z][rng.gen_range(0..3)],
        1 => Vec3::new(rng.gen_range(-1.0..1.0), 0.0, 1.0).normalize(),
        _ => unit(rng),
    }
}

fn bits(r: Option<(f32, f32)>) -> Option<(u32, u32)> {
    r.map(|(a, b)| (a.to_bits(), b.to_bits()))
}

#[test]
fn basic_and_improved_agree_bit_for_bit() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(2);
    let mut kinds = [0usize; 2];
    for _ in 0..20000 {
        let apex = Vec3::new(
            rng.gen_range(-2.0..2.0),
            rng.gen_range(-2.0..2.0),
            rng.gen_range(-2.0..2.0),
        );
        let alpha = [0.0007, 0.02, 0.3, std::f32::consts::FRAC_PI_4, 1.5][rng.gen_range(0..5)];
        let f = ConeFrustum::new(apex, axis(&mut rng), alpha);
        let mut pair = BoxPair::EMPTY;
        for slot in 0..2 {
            let c = Vec3::new(
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
            );
            let mut e = Vec3::new(
                rng.gen_range(0.0..1.0),
                rng.gen_range(0.0..1.0),
                rng.gen_range(0.0..1.0),
            );
            // Flat boxes, and boxes with a face through the apex.
            if rng.gen_bool(0.2) {
                e[rng.gen_range(0..3)] = 0.0;
            }
            let (mut lo, mut hi) = (c - e, c + e);
            if rng.gen_bool(0.2) {
                let k = rng.gen_range(0..3);
                if rng.gen_bool(0.5) {
                    lo[k] = apex[k]
                } else {
                    hi[k] = apex[k]
                }
                lo = lo.min(hi);
            }
            pair.set(slot, lo, hi.max(lo));
        }
        let two = f.interval2(&pair);
        for slot in 0..2 {
            let (lo, hi) = pair.get(slot);
            let basic = f.interval_basic(lo, hi);
            assert_eq!(bits(basic), bits(two[slot]), "{f:?} box {lo:?} {hi:?}");
            assert_eq!(bits(basic), bits(f.interval(lo, hi)));
            kinds[basic.is_some() as usize] += 1;
        }
    }
    assert!(kinds[0] > 1000 && kinds[1] > 1000, "{kinds:?}");
    // Empty boxes are never entered.
    assert_eq!(f_empty(), [None, None]);
}

fn f_empty() -> [Option<(f32, f32)>; 2] {
    ConeFrustum::new(Vec3::ZERO, Vec3::Z, 0.3).interval2(&BoxPair::EMPTY)
}

/// Every triangle the exact test accepts lies in a box the frustum test enters, with its `t`
/// in the range: on the triangle's own (tightest) box and on larger boxes around it.
#[test]
fn conservative_against_the_exact_test() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(9);
    let (mut hits, mut culled) = (0, 0);
    for _ in 0..30000 {
        let apex = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        let ax = axis(&mut rng);
        let alpha = (rng.gen_range(-8.0f32..0.4)).exp();
        let d = rng.gen_range(0.1f32..4.0);
        let r = d * alpha.tan().min(3.0);
        let centre = apex + ax * d + unit(&mut rng) * (r * rng.gen_range(0.5..1.5));
        let size = r.max(0.01) * rng.gen_range(0.1..2.0);
        let mut tri = [0, 1, 2].map(|_| centre + unit(&mut rng) * size);
        if rng.gen_bool(0.2) {
            // Axis-aligned triangles: flat boxes.
            let k = rng.gen_range(0..3);
            for v in &mut tri {
                v[k] = centre[k];
            }
        }
        let exact = ConeF64::new(apex, ax, alpha).triangle(tri[0], tri[1], tri[2]);
        let f = ConeFrustum::new(apex, ax, alpha);
        let b = Aabb::from_points(tri);
        let big = b.union(Aabb::new(
            b.min - Vec3::splat(rng.gen_range(0.0..1.0)),
            b.max,
        ));
        for bx in [b, big] {
            let got = f.interval_basic(bx.min, bx.max);
            match exact {
                Some(t) => {
                    let (lo, hi) =
                        got.unwrap_or_else(|| panic!("culled a hit (t {t}): {f:?} {tri:?}"));
                    assert!(
                        lo <= t && t <= hi,
                        "t {t} outside [{lo}, {hi}]: {f:?} {tri:?}"
                    );
                }
                None => culled += got.is_none() as usize,
            }
        }
        hits += exact.is_some() as usize;
    }
    assert!(
        hits > 5000 && culled > 2000,
        "{hits} hits, {culled} culled boxes"
    );
}
