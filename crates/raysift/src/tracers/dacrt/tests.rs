//! Unit tests of the pieces: defaults, the block move, the packet maps, the termination rule.

use super::order::Order;
use super::packets::{for_each_tile_slot, morton_order};
use super::partition::gather_block;
use super::*;
use crate::geom::Aabb;

#[test]
fn config_defaults_are_the_papers_except_sat() {
    let c: Config = crate::tracers::config_from_opts("dacrt", &[]).unwrap();
    assert_eq!(c, Config::default());
    assert_eq!((c.r_limit, c.p_limit), (20, 16));
    // Shadow packets off by default (measured slower than rays on 3 of 4 scenes).
    assert_eq!(c.max_shadow_cone_deg, 0.0);
    assert_eq!(
        (c.split_sample_threshold, c.split_sample_stride),
        (10_000, 50)
    );
    let o = [("mode".to_string(), "random".to_string())];
    let c: Config = crate::tracers::config_from_opts("dacrt", &o).unwrap();
    assert_eq!(c.mode, Mode::Random);
}

#[test]
fn gather_block_appends_the_block() {
    // Every (k, a, e) on 12 entries: the block lands at [k, k + e − a), as a set, and the
    // whole is still a permutation.
    for a in 0..=12usize {
        for e in a..=12 {
            for k in 0..=a {
                let mut v: Vec<u32> = (0..12).collect();
                let end = gather_block(&mut v, k, a, e);
                assert_eq!(end, k + e - a);
                assert_eq!(&v[..k], &(0..k as u32).collect::<Vec<_>>()[..]);
                let mut got = v[k..end].to_vec();
                got.sort();
                assert_eq!(got, (a as u32..e as u32).collect::<Vec<_>>(), "{k} {a} {e}");
                let mut all = v.clone();
                all.sort();
                assert_eq!(all, (0..12).collect::<Vec<_>>());
            }
        }
    }
}

#[test]
fn full_mask_is_the_bits_visited() {
    let perm: Vec<u64> = (0..150u64).map(|k| k | k << 32).collect();
    let runs = Packets::Runs { len: 150 };
    for (width, rows) in [(8, 8), (13, 16), (20, 5), (3, 21), (64, 64)] {
        let tiles = Packets::Tiles {
            width,
            rows,
            tw: width.div_ceil(8),
        };
        for p in [tiles, runs] {
            for c in 0..p.count() {
                let mut m = 0u64;
                p.for_each(c, &perm, |_, b| m |= 1 << b);
                assert_eq!(p.full_mask(c, &perm), m, "{p:?} packet {c}");
            }
        }
    }
}

#[test]
fn packet_maps_are_inverse() {
    let rays = crate::rays::generate::random_in_box(&Aabb::new(Vec3::ZERO, Vec3::ONE), 1000, 1);
    let perm = morton_order(
        Vec::new(),
        &rays,
        0..1000,
        &Aabb::new(Vec3::ZERO, Vec3::ONE),
        true,
    );
    for (packets, n) in [
        (
            Packets::Tiles {
                width: 37,
                rows: 27,
                tw: 5,
            },
            37 * 27,
        ),
        (Packets::Runs { len: 1000 }, 1000),
    ] {
        let mut seen = vec![false; n];
        for c in 0..packets.count() {
            let mut n = 0;
            packets.for_each(c, &perm, |k, bit| {
                assert!(!seen[k]);
                seen[k] = true;
                assert_eq!(packets.of(k, &perm), (c, bit));
                n += 1;
            });
            assert_eq!(packets.full_mask(c, &perm).count_ones(), n);
        }
        assert!(seen.iter().all(|&s| s), "{packets:?}");
    }
    // Tile-order slots agree with the packet map, row by row.
    let (width, rows) = (37, 27);
    let packets = Packets::Tiles { width, rows, tw: 5 };
    let mut next = 0;
    for_each_tile_slot(width, rows, |k, j| {
        assert_eq!(k, next);
        next += 1;
        let (c, bit) = packets.of(k, &[]);
        assert_eq!(j, 64 * c + bit as usize);
    });
    assert_eq!(next, width * rows);
}

/// The four-lane termination test answers as the scalar one on every lane: random rays
/// and hits around random cells and orders, with and without `tmin`, zero components.
#[test]
fn final_hit4_is_final_hit() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
    let (mut yes, mut no) = (0, 0);
    for n in 0..50_000 {
        let mut r = |s: f32| rng.gen_range(-s..s);
        let lo = Vec3::new(r(1.0), r(1.0), r(1.0));
        let cell = Aabb::new(lo, lo + Vec3::new(r(1.0), r(1.0), r(1.0)).abs());
        let mut ord = Order::NONE;
        for _ in 0..(n % 4) {
            let a = (r(3.0).abs() as usize).min(2);
            ord = ord.child(a, r(1.5), true, r(1.0) > 0.0);
        }
        let o = Vec3::new(r(2.0), r(2.0), r(2.0));
        let tmin = if n % 3 == 0 { r(0.1).abs() } else { 0.0 };
        let mut d = [Vec4::ZERO; 3];
        let mut bt = Vec4::ZERO;
        for l in 0..4 {
            // Aim at a point in or near the cell, hit at about that distance.
            let target = cell.min + (cell.max - cell.min) * Vec3::new(r(1.3), r(1.3), r(1.3)).abs();
            let mut dir = target - o;
            if n % 5 == 0 {
                dir[l % 3] = 0.0;
            }
            for a in 0..3 {
                d[a][l] = dir[a];
            }
            bt[l] = 1.0 + r(0.05);
        }
        let mask = Task::<false>::final_hit4(&cell, o, d, tmin, bt, &ord);
        for l in 0..4 {
            let dir = Vec3::new(d[0][l], d[1][l], d[2][l]);
            let f = Task::<false>::final_hit(&cell, o, dir, tmin, bt[l], &ord);
            assert_eq!(f, mask >> l & 1 == 1, "case {n} lane {l}");
            if f {
                yes += 1
            } else {
                no += 1
            }
        }
    }
    assert!(yes > 10_000 && no > 10_000, "{yes} final, {no} not");
}

#[test]
fn order_rule() {
    // Low child first at x = 0: rays must go +x, or start at or below the plane.
    let o = Order::NONE.child(0, 0.0, true, true);
    assert!(o.allows(Vec3::new(-1.0, 0.0, 0.0), 0.0, Vec3::X));
    assert!(o.allows(Vec3::new(-1.0, 0.0, 0.0), 0.0, -Vec3::X));
    assert!(o.allows(Vec3::ZERO, 0.0, -Vec3::X));
    assert!(!o.allows(Vec3::new(1.0, 0.0, 0.0), 0.0, -Vec3::X));
    assert!(!o.allows(Vec3::ZERO, 1e-3, -Vec3::X));
    // Second children add nothing.
    let o = Order::NONE.child(1, 0.0, false, true);
    assert!(o.allows(Vec3::new(0.0, 5.0, 0.0), 0.0, -Vec3::Y));
    // High first: rays must go −y, or start at or above the plane.
    let o = Order::NONE.child(1, 0.5, true, false);
    assert!(o.allows(Vec3::new(0.0, 0.7, 0.0), 0.0, Vec3::Y));
    assert!(!o.allows(Vec3::new(0.0, 0.2, 0.0), 0.0, Vec3::Y));
    assert!(!o.allows(Vec3::NAN, 0.0, Vec3::NAN));
}

#[test]
fn balanced_bands_follow_the_cover() {
    use super::screen::{balanced_bands, Cover};
    let mut bounds = Vec::new();
    // (width, height, rectangles) -> bounds for k = 1..=5.
    let check = |w: usize, h: usize, rects: &[[u16; 4]], k: usize, bounds: &mut Vec<usize>| {
        let mut cover = Cover::new(h);
        cover.add(rects);
        balanced_bands(&cover, w, h, k, bounds);
        assert_eq!((bounds[0], *bounds.last().unwrap()), (0, w * h));
        assert!(bounds.len() <= k + 1 && bounds.len() >= 2);
        assert!(bounds.windows(2).all(|p| p[0] < p[1]), "{bounds:?}");
        // Whole tile rows, but for the image's end.
        assert!(bounds[..bounds.len() - 1].iter().all(|b| b % (8 * w) == 0));
    };
    // No triangles: bands of equal height.
    check(64, 1024, &[], 2, &mut bounds);
    assert_eq!(bounds, [0, 512 * 64, 1024 * 64]);
    // Wide rectangles over the bottom quarter: the first band takes more rows.
    let bottom = vec![[0u16, 63, 768, 1023]; 100];
    check(64, 1024, &bottom, 2, &mut bounds);
    assert!(bounds[1] > 768 * 64, "{bounds:?}");
    for k in 1..=5 {
        check(64, 1024, &bottom, k, &mut bounds);
        check(100, 100, &[[0, 99, 0, 9]], k, &mut bounds);
        // More rows than buckets.
        check(8, 5000, &[[0, 7, 4000, 4999], [0, 3, 0, 0]], k, &mut bounds);
    }
    // Fewer tile rows than tasks: fewer bands.
    check(16, 16, &[], 5, &mut bounds);
    assert_eq!(bounds, [0, 128, 256]);
}
