//! Tests of the projection: deviation bounds, rectangles, edge masks.

use super::*;
use crate::rays::Camera;
use rand::{Rng, SeedableRng};

fn fit_camera(c: &Camera, w: u32, h: u32) -> (PixelProjection, crate::rays::RayBatch) {
    let rays = c.rays(w, h);
    let (wu, hu) = (w as usize, h as usize);
    let corners = [0, wu - 1, (hu - 1) * wu, hu * wu - 1].map(|k| rays.dir(k));
    (
        PixelProjection::fit(c.eye, w, h, corners).expect("a camera has a projection"),
        rays,
    )
}

/// The four-wide f32 bound is never below the exact deviation, and for ordinary cameras
/// at most a hundredth of a pixel above it: exact camera rays, and random directions within
/// about a pixel of their pixel (jittered rays), a few behind the eye or NaN. The third
/// camera (120°, 4000 × 37) has a projection matrix with large cancelling entries: its
/// bound only has to stay above the deviation.
#[test]
fn deviation4_bounds_the_deviation() {
    let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
    let mut worst: f64 = 0.0;
    for (look, up, fov, w, h, tight) in [
        (
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::Y,
            60.0,
            1024u32,
            1024u32,
            true,
        ),
        (Vec3::new(3.0, -1.0, 0.5), Vec3::Z, 27.0, 1280, 800, true),
        (
            Vec3::new(-1.0, 2.0, 7.0),
            Vec3::new(0.3, 1.0, 0.0),
            120.0,
            4000,
            37,
            false,
        ),
    ] {
        let c = Camera {
            eye: Vec3::new(1.0, 2.0, 3.0),
            look: Vec3::new(1.0, 2.0, 3.0) + look,
            up,
            fov_deg: fov,
        };
        let (p, rays) = fit_camera(&c, w, h);
        for k in 0..20_000 {
            let j = rng.gen_range(0..h);
            let x0 = rng.gen_range(0..w - 3);
            let mut d = [Vec4::ZERO; 3];
            let mut dirs = [Vec3::ZERO; 4];
            for (l, dir) in dirs.iter_mut().enumerate() {
                let i = (j * w + x0) as usize + l;
                *dir = rays.dir(i);
                if k % 2 == 1 {
                    // A point up to a pixel away from the pixel, at any distance.
                    let (px, py) = (
                        x0 as f64 + l as f64 + rng.gen_range(-1.0..1.0),
                        j as f64 + rng.gen_range(-1.0..1.0),
                    );
                    let g = p.h.inverse() * DVec3::new(px, py, 1.0);
                    *dir = (g * rng.gen_range(0.01..100.0)).as_vec3();
                }
                match k % 97 {
                    5 => *dir = -*dir,
                    6 => dir.y = f32::NAN,
                    _ => {}
                }
                for a in 0..3 {
                    d[a][l] = dir[a];
                }
            }
            let bound = p.deviation4(d, x0, j);
            for (l, dir) in dirs.iter().enumerate() {
                let dev = p.deviation(*dir, x0 as usize + l, j as usize);
                let b = bound[l] as f64;
                if dir.is_nan() {
                    assert!(b.is_nan());
                } else if dev.is_infinite() || b.is_infinite() {
                    // Behind the eye: no finite bound (directions just in front may also
                    // get none, which is only conservative).
                    assert!(b.is_infinite() && b > 0.0, "{dev} {b}");
                } else {
                    assert!(b >= dev, "bound {b} below the deviation {dev}");
                    if tight {
                        worst = worst.max(b - dev);
                    }
                }
            }
        }
    }
    assert!(worst < 0.01, "bound {worst} px above the deviation");
}

#[test]
fn camera_rays_project_to_their_pixels() {
    for (look, up, fov) in [
        (Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 60.0),
        (Vec3::new(3.0, -1.0, 0.5), Vec3::Z, 27.0),
        (Vec3::new(-1.0, 2.0, 7.0), Vec3::new(0.3, 1.0, 0.0), 120.0),
    ] {
        let c = Camera {
            eye: Vec3::new(1.0, 2.0, 3.0),
            look: Vec3::new(1.0, 2.0, 3.0) + look,
            up,
            fov_deg: fov,
        };
        let (w, h) = (97u32, 61u32);
        let (p, rays) = fit_camera(&c, w, h);
        for j in 0..h as usize {
            for i in 0..w as usize {
                let e = p.deviation(rays.dir(j * w as usize + i), i, j);
                assert!(e < 1e-3, "{i} {j}: {e}");
                assert!(p.within(rays.dir(j * w as usize + i), i, j, 1e-3));
                assert!(!p.within(rays.dir(j * w as usize + i), i + 1, j, 0.9));
                assert!(!p.within(rays.dir(j * w as usize + i), i, j + 1, 0.9));
            }
        }
        // A neighbour's direction is a pixel away.
        assert!((p.deviation(rays.dir(5), 4, 0) - 1.0).abs() < 1e-3);
        assert!((p.deviation(rays.dir(w as usize), 0, 0) - 1.0).abs() < 1e-3);
        // Behind the eye: no pixel.
        assert!(p.pixel(-rays.dir(0).as_dvec3()).is_none());
    }
}

#[test]
fn fit_refuses_what_is_no_projection() {
    let d = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
    assert!(PixelProjection::fit(Vec3::ZERO, 1, 5, d).is_none());
    assert!(PixelProjection::fit(Vec3::ZERO, 5, 5, [Vec3::X; 4]).is_none());
    let mut nan = d;
    nan[2].x = f32::NAN;
    assert!(PixelProjection::fit(Vec3::ZERO, 5, 5, nan).is_none());
}

/// No triangle that some camera ray hits (through the shared triangle test) is culled, and
/// every such ray's pixel is in the triangle's rectangle, exact or jittered rays; tiny
/// triangles between pixel centres are culled and many rectangles are single pixels (not
/// vacuous); the scalar and four-wide forms agree.
#[test]
fn culled_triangles_are_hit_by_no_ray() {
    use crate::geom::intersect_triangle;
    let c = Camera {
        eye: Vec3::new(0.3, 0.2, 4.0),
        look: Vec3::ZERO,
        up: Vec3::Y,
        fov_deg: 50.0,
    };
    let (w, h) = (40u32, 30u32);
    let (p, exact) = fit_camera(&c, w, h);
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let jittered = jitter(&exact, w, h, &mut rng);
    let tol_of = |rays: &crate::rays::RayBatch| {
        (0..rays.len())
            .map(|k| p.deviation(rays.dir(k), k % w as usize, k / w as usize))
            .fold(0.0f64, f64::max)
    };
    let (xs, ys) = ([0, w as i64 - 1], [0, h as i64 - 1]);
    for rays in [&exact, &jittered] {
        let tol = tol_of(rays);
        let (mut culled, mut hit, mut small) = (0, 0, 0);
        for _ in 0..600 {
            let tri: [[Vec3; 3]; 4] = std::array::from_fn(|_| {
                let c = Vec3::new(
                    rng.gen_range(-2.0..2.0),
                    rng.gen_range(-1.5..1.5),
                    rng.gen_range(-2.0..5.0),
                );
                let s = 10f32.powf(rng.gen_range(-3.0..-0.5));
                std::array::from_fn(|_| {
                    c + Vec3::new(
                        rng.gen_range(-s..s),
                        rng.gen_range(-s..s),
                        rng.gen_range(-s..s),
                    )
                })
            });
            let keep = p.triangles_may_cover4(tri, tol, xs, ys);
            let rects = p.triangle_rects4(tri, tol, xs, ys);
            for l in 0..4 {
                assert_eq!(keep[l], p.triangle_may_cover(tri[l], tol, xs, ys));
                let [a, b, c2] = tri[l];
                let [x0, x1, y0, y1] = rects[l].map(|v| v as usize);
                let mut hits = false;
                for k in 0..rays.len() {
                    if intersect_triangle(rays.origin(k), rays.dir(k), a, b, c2, 0.0, f32::INFINITY)
                        .is_some()
                    {
                        hits = true;
                        // Every hitting ray's pixel is in the rectangle.
                        let (i, j) = (k % w as usize, k / w as usize);
                        assert!(
                            (x0..=x1).contains(&i) && (y0..=y1).contains(&j),
                            "ray {i},{j} hits {:?} outside {:?}",
                            tri[l],
                            rects[l]
                        );
                    }
                }
                small += ((x1 + 1).saturating_sub(x0) * (y1 + 1).saturating_sub(y0) == 1) as usize;
                assert!(
                    keep[l] || !hits,
                    "culled a triangle a ray hits: {:?}",
                    tri[l]
                );
                culled += !keep[l] as usize;
                hit += hits as usize;
            }
        }
        assert!(
            culled > 300 && hit > 100 && small > 50,
            "culled {culled}, hit {hit}, one-pixel rectangles {small}"
        );
    }
}

/// Eight lanes give the rectangles four do, bit for bit, also when compiled for AVX2 (the
/// path `dacrt` takes on such CPUs): ordinary, tiny, huge, degenerate, behind-the-eye,
/// eye-plane and NaN triangles.
#[test]
fn rect_lanes_agree_at_every_width() {
    use crate::geom::lanes::{F32x8, Lanes, Wide};
    let c = Camera {
        eye: Vec3::new(0.3, 0.2, 4.0),
        look: Vec3::ZERO,
        up: Vec3::Y,
        fov_deg: 50.0,
    };
    let (p, _) = fit_camera(&c, 64, 48);
    let (xs, ys) = ([0, 63], [8, 23]);
    let lanes = |tri: &[[Vec3; 3]], k: usize, a: usize| Wide(std::array::from_fn(|l| tri[l][k][a]));
    let wide = |tri: &[[Vec3; 3]]| -> [[F32x8; 3]; 3] {
        std::array::from_fn(|k| std::array::from_fn(|a| lanes(tri, k, a)))
    };
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn avx2(p: &PixelProjection, v: [[F32x8; 3]; 3], ys: [i64; 2]) -> RectLanes<F32x8> {
        p.triangle_rects_wide(v, 0.01, [0, 63], ys)
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(12);
    let mut kinds = [0usize; 3];
    for round in 0..4000 {
        let tri: [[Vec3; 3]; 8] = std::array::from_fn(|_| {
            let mid = Vec3::new(
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..3.0),
                rng.gen_range(-3.0..6.0),
            );
            let s = 10f32.powf(rng.gen_range(-6.0..1.0));
            let mut t: [Vec3; 3] = std::array::from_fn(|_| {
                mid + s * Vec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                )
            });
            match rng.gen_range(0..12) {
                0 => t = [mid; 3],
                1 => t[1] = t[0],
                2 => t[2].z = c.eye.z,
                3 => t[0] = Vec3::splat(1e30),
                4 if round % 50 == 0 => t[1].y = f32::NAN,
                _ => {}
            }
            t
        });
        let four: [RectLanes; 2] = std::array::from_fn(|h| {
            p.triangle_rects_lanes(std::array::from_fn(|l| tri[4 * h + l]), 0.01, xs, ys)
        });
        let mut eights = vec![p.triangle_rects_wide(wide(&tri), 0.01, xs, ys)];
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked on the line above).
            eights.push(unsafe { avx2(&p, wide(&tri), ys) });
        }
        for e in &eights {
            for l in 0..8 {
                let f = &four[l / 4];
                assert_eq!(e.lane(l), f.lane(l % 4), "{:?}", tri[l]);
                assert_eq!(e.behind >> l & 1, f.behind >> (l % 4) & 1);
            }
            assert_eq!(e.nonempty(), four[0].nonempty() | four[1].nonempty() << 4);
        }
        for l in 0..8 {
            let f = &four[l / 4];
            let k = if f.behind >> (l % 4) & 1 != 0 {
                0
            } else if f.nonempty() >> (l % 4) & 1 != 0 {
                1
            } else {
                2
            };
            kinds[k] += 1;
        }
    }
    // Every outcome occurs often: behind the eye, a rectangle, culled.
    assert!(kinds.iter().all(|&k| k > 1000), "{kinds:?}");
    let _ = F32x8::N;
}

/// The rectangle holds the pixel of every ray that meets the box (brute force over random
/// boxes, through the shared slab test), and `None` exactly when a corner is behind the eye.
#[test]
fn box_pixels_hold_every_ray_that_meets_the_box() {
    let c = Camera {
        eye: Vec3::new(0.2, -0.1, 4.0),
        look: Vec3::ZERO,
        up: Vec3::Y,
        fov_deg: 50.0,
    };
    let (w, h) = (64u32, 48u32);
    let (p, rays) = fit_camera(&c, w, h);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let (mut met, mut tight, mut none) = (0, 0, 0);
    for _ in 0..400 {
        let a = Vec3::new(
            rng.gen_range(-3.0..3.0),
            rng.gen_range(-3.0..3.0),
            rng.gen_range(-2.0..5.0),
        );
        let s = Vec3::new(
            rng.gen_range(0.0..1.5),
            rng.gen_range(0.0..1.5),
            rng.gen_range(0.0..1.5),
        );
        let b = Aabb::new(a, a + s);
        let r = p.box_pixels(&b, 1e-3);
        let behind = (0..8).any(|k| (b.corner(k) - c.eye).dot(c.look - c.eye) <= 0.0);
        assert_eq!(r.is_none(), behind, "{b:?}");
        let Some([x0, x1, y0, y1]) = r else {
            none += 1;
            continue;
        };
        let mut inside = 0;
        for j in 0..h as usize {
            for i in 0..w as usize {
                let k = j * w as usize + i;
                let (o, d) = (rays.origin(k), rays.dir(k));
                let hit = b
                    .ray_interval(o, Vec3::ONE / d, 0.0, f32::INFINITY)
                    .is_some();
                let inr = (x0..=x1).contains(&(i as i64)) && (y0..=y1).contains(&(j as i64));
                if hit {
                    met += 1;
                    assert!(inr, "ray {i},{j} meets {b:?} outside {:?}", r);
                }
                inside += inr as usize;
            }
        }
        // Not vacuous: some rectangles are smaller than the image.
        tight += (inside < (w * h) as usize) as usize;
    }
    assert!(
        met > 1000 && tight > 50 && none > 10,
        "{met} {tight} {none}"
    );
}

/// The edge test keeps the pixel of every camera ray (exact or jittered by up to half a pixel)
/// that the shared test reports as a hit on the triangle, for large, small, slanted and
/// grazing triangles, and it drops many pixels of the rectangles (not vacuous); a triangle
/// reaching behind the eye gets no test.
#[test]
fn edge_masks_keep_every_hit_pixel() {
    use crate::geom::intersect_triangle;
    let c = Camera {
        eye: Vec3::new(0.2, -0.1, 3.0),
        look: Vec3::ZERO,
        up: Vec3::Y,
        fov_deg: 55.0,
    };
    let (w, h) = (48u32, 40u32);
    let (p, exact) = fit_camera(&c, w, h);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let jittered = jitter(&exact, w, h, &mut rng);
    let (xs, ys) = ([0, w as i64 - 1], [0, h as i64 - 1]);
    let (mut tested, mut dropped, mut kept_hits) = (0u64, 0u64, 0u64);
    for rays in [&exact, &jittered] {
        let tol = (0..rays.len())
            .map(|k| p.deviation(rays.dir(k), k % w as usize, k / w as usize))
            .fold(0.0f64, f64::max);
        for n in 0..400 {
            let centre = Vec3::new(
                rng.gen_range(-1.5..1.5),
                rng.gen_range(-1.2..1.2),
                rng.gen_range(-2.0..1.5),
            );
            let s = 10f32.powf(rng.gen_range(-1.5..0.3));
            let mut tri: [Vec3; 3] = std::array::from_fn(|_| {
                centre
                    + Vec3::new(
                        rng.gen_range(-s..s),
                        rng.gen_range(-s..s),
                        rng.gen_range(-s..s),
                    )
            });
            if n % 5 == 0 {
                // Nearly edge-on to the eye.
                let d = (centre - c.eye).normalize();
                tri[2] = tri[0] + (tri[1] - tri[0]) * 0.5 + d * s * 3.0;
            }
            let rect = p.triangle_rects4([tri; 4], tol, xs, ys)[0];
            let Some(e) = p.triangle_edges(tri, tol) else {
                continue;
            };
            let [x0, x1, y0, y1] = rect.map(|v| v as i64);
            for ty in (y0.max(0) / 8)..=(y1.max(0) / 8) {
                for tx in (x0.max(0) / 8)..=(x1.max(0) / 8) {
                    // The rectangle's pixels in this tile.
                    let mut m = 0u64;
                    for b in 0..64 {
                        let (x, y) = (tx * 8 + b % 8, ty * 8 + b / 8);
                        if (x0..=x1).contains(&x) && (y0..=y1).contains(&y) {
                            m |= 1 << b;
                        }
                    }
                    let kept = e.mask8x8(tx * 8, ty * 8, m);
                    assert_eq!(kept & !m, 0, "bits outside the input mask");
                    tested += m.count_ones() as u64;
                    dropped += (m & !kept).count_ones() as u64;
                    for b in 0..64 {
                        let (x, y) = ((tx * 8 + b % 8) as usize, (ty * 8 + b / 8) as usize);
                        if m >> b & 1 == 0 || x >= w as usize || y >= h as usize {
                            continue;
                        }
                        let k = y * w as usize + x;
                        let hit = intersect_triangle(
                            rays.origin(k),
                            rays.dir(k),
                            tri[0],
                            tri[1],
                            tri[2],
                            0.0,
                            f32::INFINITY,
                        );
                        if hit.is_some() {
                            assert!(kept >> b & 1 != 0, "dropped hit pixel {x},{y} of {tri:?}");
                            kept_hits += 1;
                        }
                    }
                }
            }
        }
    }
    assert!(
        kept_hits > 10_000 && dropped * 5 > tested,
        "hits {kept_hits}, dropped {dropped} of {tested}"
    );
    // Behind the eye: no edge test.
    let behind = [c.eye + Vec3::new(0.0, 0.0, 1.0), Vec3::ZERO, Vec3::X];
    assert!(p.triangle_edges(behind, 0.01).is_none());
}

/// The camera rays with each direction moved up to half a pixel towards its neighbours.
fn jitter(
    exact: &crate::rays::RayBatch,
    w: u32,
    h: u32,
    rng: &mut impl Rng,
) -> crate::rays::RayBatch {
    let mut jittered = exact.clone();
    for k in 0..exact.len() {
        let (i, j) = (k % w as usize, k / w as usize);
        let d = exact.dir(k);
        let di = exact.dir(if i + 1 < w as usize { k + 1 } else { k - 1 }) - d;
        let dj = exact.dir(if j + 1 < h as usize {
            k + w as usize
        } else {
            k - w as usize
        }) - d;
        let (a, b): (f32, f32) = (rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5));
        let n = (d + a * di + b * dj).normalize();
        (jittered.dx[k], jittered.dy[k], jittered.dz[k]) = (n.x, n.y, n.z);
    }
    jittered
}
