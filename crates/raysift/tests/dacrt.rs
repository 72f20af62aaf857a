//! DACRT against the brute-force tracer, bit for bit, in every mode (packet, ray, random, auto),
//! with one and several tasks, with the paper's limits and with tiny ones (deep recursions), on
//! the adversarial cases of the issue and references.md §8.

use glam::Vec3;
use raysift::rays::generate::{random_in_box, shadow_rays};
use raysift::rays::{Camera, Ray, RayLayout};
use raysift::scene::{procedural, Mesh, Scene};
use raysift::{tracers, HitBatch, RayBatch};
use std::sync::Arc;

fn opts(kv: &[(&str, &str)]) -> Vec<(String, String)> {
    kv.iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// The configurations every case runs: all modes, default and tiny limits, 1 and 3 tasks.
fn configs() -> Vec<Vec<(String, String)>> {
    let mut out = Vec::new();
    for mode in ["packet", "ray", "random", "auto"] {
        out.push(opts(&[("mode", mode), ("tasks", "1")]));
        out.push(opts(&[
            ("mode", mode),
            ("tasks", "3"),
            ("r_limit", "2"),
            ("p_limit", "2"),
            ("c_limit", "1"),
            ("sat_threshold", "1000"),
            ("split_sample_threshold", "64"),
            ("split_sample_stride", "3"),
            ("max_depth", "40"),
            ("leaf_pairs", "0"),
            ("max_cone_deg", "60"),
            ("max_shadow_cone_deg", "60"),
            ("pixel_leaf_c_limit", "1"),
        ]));
    }
    // Packets: wide cones allowed (small test images, scattered shadow packets), no ray filter
    // at flush time, paper limits; and one with a cone limit that flushes at once.
    out.push(opts(&[
        ("mode", "packet"),
        ("tasks", "2"),
        ("max_cone_deg", "80"),
        ("max_shadow_cone_deg", "80"),
        ("flush_filter", "false"),
        ("pixel_cull", "false"),
        ("pixel_leaf", "false"),
    ]));
    // The paper's leaf rule: any cell with fewer than `r_limit` rays is a naive leaf.
    for mode in ["ray", "random"] {
        out.push(opts(&[
            ("mode", mode),
            ("tasks", "2"),
            ("leaf_pairs", &usize::MAX.to_string()),
        ]));
    }
    out.push(opts(&[
        ("mode", "packet"),
        ("tasks", "1"),
        ("c_limit", "100000"),
        ("max_shadow_cone_deg", "30"),
    ]));
    // Camera packets bounded by the paper's cones instead of their pixel rectangles, ending in
    // tile leaves or (the paper) flushed to rays; and the pixel rectangles with flushes.
    for leaf in ["true", "false"] {
        out.push(opts(&[
            ("mode", "packet"),
            ("tasks", "2"),
            ("screen_cull", "false"),
            ("pixel_leaf", leaf),
            ("c_limit", "4"),
            ("pixel_leaf_c_limit", "4"),
            ("p_limit", "4"),
        ]));
    }
    out.push(opts(&[
        ("mode", "packet"),
        ("tasks", "1"),
        ("pixel_leaf", "false"),
        ("huge_pages", "false"),
    ]));
    out
}

fn same_hits(want: &HitBatch, got: &HitBatch, what: &str) {
    assert_eq!(want.len(), got.len(), "{what}: length");
    for i in 0..want.len() {
        let same = want.prim[i] == got.prim[i]
            && want.t[i].to_bits() == got.t[i].to_bits()
            && want.u[i].to_bits() == got.u[i].to_bits()
            && want.v[i].to_bits() == got.v[i].to_bits();
        assert!(
            same,
            "{what}: ray {i}: naive (t {}, prim {}, u {}, v {}) vs dacrt (t {}, prim {}, u {}, v {})",
            want.t[i], want.prim[i], want.u[i], want.v[i], got.t[i], got.prim[i], got.u[i], got.v[i]
        );
    }
}

/// Checks closest hits and occlusion of `rays` against naive in every configuration; returns
/// naive's hits.
fn check(scene: &Arc<Scene>, rays: &RayBatch, what: &str) -> HitBatch {
    let mut naive = tracers::create("naive", &[]).unwrap();
    naive.prepare(scene.clone()).unwrap();
    let (want, _) = naive.intersect_timed(rays);
    let (want_occ, _) = naive.occluded_timed(rays);
    for cfg in configs() {
        let mut d = tracers::create("dacrt", &cfg).unwrap();
        d.prepare(scene.clone()).unwrap();
        let label = format!("{what} {cfg:?}");
        let (got, st) = d.intersect_timed(rays);
        same_hits(&want, &got, &label);
        assert_eq!(st.rays, rays.len() as u64, "{label}");
        let (occ, _) = d.occluded_timed(rays);
        if let Some(i) = (0..occ.len()).find(|&i| occ[i] != want_occ[i]) {
            panic!(
                "{label}: occlusion of ray {i}: naive {} dacrt {}",
                want_occ[i], occ[i]
            );
        }
        assert_eq!(occ.len(), want_occ.len());
        // Re-running gives the same answer (no state leaks between calls).
        let (again, _) = d.intersect_timed(rays);
        same_hits(&want, &again, &label);
    }
    want
}

/// Camera rays plus the shadow rays of their hits (towards `light`), both checked.
fn check_camera(scene: Scene, cam: Camera, w: u32, h: u32, light: Vec3, what: &str) {
    let scene = Arc::new(scene);
    let rays = cam.rays(w, h);
    let hits = check(&scene, &rays, &format!("{what} camera"));
    assert!(hits.hit_count() > 0, "{what}: the camera sees nothing");
    let (shadow, _) = shadow_rays(&scene, &rays, &hits, light);
    check(&scene, &shadow, &format!("{what} shadow"));
    // The same rays without the layout hint.
    let mut plain = rays.clone();
    plain.layout = RayLayout::Unknown;
    check(&scene, &plain, &format!("{what} camera, no hint"));
}

fn scene_of(tris: &[[Vec3; 3]]) -> Scene {
    let pos = tris.iter().flatten().copied().collect();
    let idx = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Scene::from_meshes("test", vec![Mesh::new("m", pos, idx)]).unwrap()
}

fn merge(a: &Scene, b: &Scene) -> Scene {
    let mut tris = Vec::new();
    for s in [a, b] {
        for i in 0..s.len() {
            tris.push(s.triangles().get(i));
        }
    }
    scene_of(&tris)
}

#[test]
fn dacrt_soup_camera_shadow_and_random() {
    let s = procedural::soup(3000, 5);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.5);
    check_camera(s.clone(), cam, 72, 48, Vec3::new(0.3, 3.0, 2.0), "soup");
    let s = Arc::new(s);
    let rays = random_in_box(&s.bounds(), 3000, 9);
    check(&s, &rays, "soup random rays");
}

#[test]
fn dacrt_icosphere_outside_and_inside() {
    let s = procedural::icosphere(5000);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    check_camera(
        s.clone(),
        cam,
        64,
        64,
        Vec3::new(2.0, 2.0, 2.0),
        "sphere outside",
    );
    // From the centre: every ray hits the inside; the light is inside too.
    let cam = Camera {
        eye: Vec3::new(0.01, -0.02, 0.03),
        look: Vec3::new(0.5, 0.2, -1.0),
        up: Vec3::Y,
        fov_deg: 100.0,
    };
    check_camera(s, cam, 40, 40, Vec3::new(0.1, 0.3, 0.0), "sphere inside");
}

#[test]
fn dacrt_cornell_outside_and_inside() {
    let s = procedural::cornell();
    let b = s.bounds();
    let cam = Camera::framing(&b, 40.0, 1.0);
    let light = Vec3::new(0.0, b.max.y * 0.95, 0.0);
    check_camera(s.clone(), cam, 56, 56, light, "cornell outside");
    // Eye exactly at the box centre: on the first (median) split plane of several axes.
    let c = b.center();
    let cam = Camera {
        eye: c,
        look: c - Vec3::Z,
        up: Vec3::Y,
        fov_deg: 90.0,
    };
    check_camera(s.clone(), cam, 48, 40, light, "cornell inside");
    let cam = Camera {
        eye: c,
        look: c + Vec3::new(0.3, -0.2, 1.0),
        up: Vec3::Y,
        fov_deg: 120.0,
    };
    check_camera(s, cam, 33, 27, light, "cornell inside, odd size");
}

/// Batches labelled pinhole whose rays are not exactly on their pixels: jittered within a pixel
/// (the path tracer's primary rays: screen-space culling pads the rectangles by the measured
/// deviation) and shuffled among pixels (the projection is refused, cones bound the tiles).
#[test]
fn dacrt_pinhole_layout_with_jittered_and_shuffled_rays() {
    use rand::{Rng, SeedableRng};
    let s = Arc::new(procedural::icosphere(3000));
    let cam = Camera::framing(&s.bounds(), 45.0, 1.3);
    let (w, h) = (48usize, 40usize);
    let exact = cam.rays(w as u32, h as u32);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let jittered = RayBatch::from_rays((0..w * h).map(|k| {
        let (i, j) = (k % w, k / w);
        let d = exact.dir(k);
        let di = exact.dir(if i + 1 < w { k + 1 } else { k - 1 }) - d;
        let dj = exact.dir(if j + 1 < h { k + w } else { k - w }) - d;
        let (a, b): (f32, f32) = (rng.gen(), rng.gen());
        Ray {
            origin: cam.eye,
            dir: (d + a * di + b * dj).normalize(),
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }));
    let mut perm: Vec<usize> = (0..w * h).collect();
    for k in (1..perm.len()).rev() {
        perm.swap(k, rng.gen_range(0..=k));
    }
    let shuffled = RayBatch::from_rays(perm.iter().map(|&k| exact.get(k)));
    for (mut rays, what, culls) in [
        (exact.clone(), "exact", true),
        (jittered, "jittered", true),
        (shuffled, "shuffled", false),
    ] {
        rays.layout = exact.layout;
        let hits = check(&s, &rays, what);
        assert!(hits.hit_count() > 100, "{what}");
        // Whether screen-space culling and tile leaves ran: they change the work counts.
        let stats = |key: &str, on: &str, leaf: &str| {
            let cfg = opts(&[
                ("mode", "packet"),
                ("tasks", "1"),
                (key, on),
                ("pixel_leaf", leaf),
            ]);
            let mut d = tracers::create("dacrt", &cfg).unwrap();
            d.prepare(s.clone()).unwrap();
            let st = d.intersect_timed(&rays).1;
            (st.cone_box, st.ray_box, st.ray_tri, st.nodes)
        };
        let screen = |on| stats("screen_cull", on, "false");
        assert_eq!(screen("true") != screen("false"), culls, "{what}");
        let leaf = |on| stats("screen_cull", "true", on);
        assert_eq!(leaf("true") != leaf("false"), culls, "{what}");
    }
}

/// Axis-parallel rays exactly on the median planes (x, y, z ∈ {−1, −0.5, 0, 0.5, 1}) and
/// triangles lying in those planes.
#[test]
fn dacrt_rays_and_triangles_on_split_planes() {
    let mut tris = Vec::new();
    for &p in &[-1.0f32, -0.5, 0.0, 0.5, 1.0] {
        // A triangle in the plane x = p, one in y = p, one in z = p.
        tris.push([
            Vec3::new(p, -0.9, -0.9),
            Vec3::new(p, 0.8, -0.7),
            Vec3::new(p, -0.6, 0.9),
        ]);
        tris.push([
            Vec3::new(-0.8, p, -0.9),
            Vec3::new(0.9, p, -0.5),
            Vec3::new(0.1, p, 0.95),
        ]);
        tris.push([
            Vec3::new(-0.95, -0.9, p),
            Vec3::new(0.9, -0.2, p),
            Vec3::new(-0.3, 0.9, p),
        ]);
    }
    let base = merge(&scene_of(&tris), &procedural::soup(400, 3));
    let s = Arc::new(base);
    let mut rays = RayBatch::default();
    let planes = [-1.0f32, -0.5, 0.0, 0.5, 1.0];
    for &a in &planes {
        for &b in &planes {
            for (o, d) in [
                (Vec3::new(-2.0, a, b), Vec3::X),
                (Vec3::new(2.0, a, b), -Vec3::X),
                (Vec3::new(a, -2.0, b), Vec3::Y),
                (Vec3::new(a, b, 2.0), -Vec3::Z),
                (Vec3::new(a, b, 0.0), Vec3::Z),
                (Vec3::new(a, 0.0, b), Vec3::new(1.0, 0.0, 1.0)),
            ] {
                rays.push(Ray {
                    origin: o,
                    dir: d,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
        }
    }
    check(&s, &rays, "split planes");
    // A camera whose eye is on three planes and whose view contains plane-lying triangles.
    let cam = Camera {
        eye: Vec3::new(0.0, 0.0, 0.5),
        look: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        fov_deg: 90.0,
    };
    check_camera(
        (*s).clone(),
        cam,
        40,
        40,
        Vec3::new(0.5, 0.5, 0.5),
        "split planes camera",
    );
}

/// Coincident triangles (ties in t go to the smaller id), a fan of 1000 triangles sharing a
/// vertex (everything straddles every plane near it) and degenerate triangles.
#[test]
fn dacrt_coincident_fans_and_degenerates() {
    let mut tris = Vec::new();
    let sphere = procedural::icosphere(320);
    for k in 0..4 {
        for i in 0..sphere.len() {
            let [a, b, c] = sphere.triangles().get(i);
            // The same triangle four times, the copies with rotated vertex order.
            tris.push(match k {
                0 | 2 => [a, b, c],
                1 => [b, c, a],
                _ => [c, a, b],
            });
        }
    }
    for i in 0..1000 {
        let ang = i as f32 / 1000.0 * std::f32::consts::TAU;
        let ang2 = (i + 1) as f32 / 1000.0 * std::f32::consts::TAU;
        tris.push([
            Vec3::new(0.2, 0.1, 0.0),
            Vec3::new(0.2 + ang.cos(), 0.1 + ang.sin(), 0.3),
            Vec3::new(0.2 + ang2.cos(), 0.1 + ang2.sin(), -0.3),
        ]);
    }
    for i in 0..50 {
        let p = Vec3::new(i as f32 * 0.01, 0.0, 0.2);
        tris.push([p, p, p]);
        tris.push([p, p + Vec3::X, p + 2.0 * Vec3::X]);
    }
    let s = scene_of(&tris);
    assert!(s.degenerate_count() >= 100);
    let cam = Camera::framing(&s.bounds(), 50.0, 1.0);
    check_camera(
        s.clone(),
        cam,
        48,
        48,
        Vec3::new(0.0, 3.0, 1.0),
        "coincident",
    );
    let s = Arc::new(s);
    check(
        &s,
        &random_in_box(&s.bounds(), 2000, 4),
        "coincident random",
    );
}

/// A wall in front of everything: every camera ray terminates in the first leaves.
#[test]
fn dacrt_all_rays_terminated_early() {
    let wall = scene_of(&[
        [
            Vec3::new(-5.0, -5.0, 1.5),
            Vec3::new(5.0, -5.0, 1.5),
            Vec3::new(5.0, 5.0, 1.5),
        ],
        [
            Vec3::new(-5.0, -5.0, 1.5),
            Vec3::new(5.0, 5.0, 1.5),
            Vec3::new(-5.0, 5.0, 1.5),
        ],
    ]);
    let s = merge(&procedural::soup(2000, 8), &wall);
    let cam = Camera {
        eye: Vec3::new(0.0, 0.0, 3.0),
        look: Vec3::ZERO,
        up: Vec3::Y,
        fov_deg: 60.0,
    };
    check_camera(s, cam, 64, 40, Vec3::new(0.0, 0.0, 2.5), "wall");
}

#[test]
fn dacrt_empty_batches_and_scenes() {
    let empty = Arc::new(Scene::from_meshes("e", vec![]).unwrap());
    let full = Arc::new(procedural::soup(100, 1));
    let cam = Camera::framing(&full.bounds(), 45.0, 1.0);
    for s in [&empty, &full] {
        check(s, &RayBatch::default(), "empty batch");
        check(s, &cam.rays(16, 8), "camera");
    }
    // A tracer that was never prepared misses everything.
    let d = tracers::create("dacrt", &[]).unwrap();
    let (h, _) = d.intersect_timed(&cam.rays(4, 4));
    assert_eq!(h.hit_count(), 0);
    // Options are checked.
    assert!(tracers::create("dacrt", &opts(&[("bogus", "1")])).is_err());
    assert!(tracers::create("dacrt", &opts(&[("mode", "sideways")])).is_err());
}

/// Random tmin/tmax windows (including negative tmin), on camera rays that keep their pinhole
/// hint and on random rays.
#[test]
fn dacrt_tmin_tmax_clipping() {
    let s = Arc::new(merge(
        &procedural::icosphere(1280),
        &procedural::soup(1500, 2),
    ));
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let mut rays = cam.rays(48, 48);
    let mut random = random_in_box(&s.bounds(), 2000, 3);
    for b in [&mut rays, &mut random] {
        for i in 0..b.len() {
            let h = (i as u32).wrapping_mul(2_654_435_761);
            let (x, y) = (
                (h >> 8 & 255) as f32 / 255.0,
                (h >> 16 & 255) as f32 / 255.0,
            );
            match h % 5 {
                0 => b.tmin[i] = x * 3.0,
                1 => b.tmax[i] = 1.0 + y * 3.0,
                2 => {
                    b.tmin[i] = x * 2.0;
                    b.tmax[i] = b.tmin[i] + y * 2.0;
                }
                3 => b.tmin[i] = -x,
                _ => {}
            }
        }
    }
    check(&s, &rays, "clipped camera");
    check(&s, &random, "clipped random");
}

/// A camera looking exactly down an axis (the centre rays are axis-parallel) at a scene of
/// axis-aligned boxes (cones graze box edges), and random rays with zero direction components.
#[test]
fn dacrt_axis_parallel_rays_and_grazing_cones() {
    let s = procedural::cornell();
    let b = s.bounds();
    let c = b.center();
    let cam = Camera {
        eye: Vec3::new(c.x, c.y, b.max.z + 2.0),
        look: Vec3::new(c.x, c.y, b.min.z),
        up: Vec3::Y,
        fov_deg: 30.0,
    };
    check_camera(
        s.clone(),
        cam,
        64,
        64,
        Vec3::new(c.x, b.max.y - 0.05, c.z),
        "axis camera",
    );
    let s = Arc::new(s);
    let mut rays = random_in_box(&b, 1500, 6);
    for i in 0..rays.len() {
        match i % 4 {
            0 => rays.dx[i] = 0.0,
            1 => {
                rays.dy[i] = 0.0;
                rays.dz[i] = -0.0;
            }
            2 => {
                rays.dx[i] = 0.0;
                rays.dy[i] = 0.0;
            }
            _ => {}
        }
    }
    check(&s, &rays, "axis-parallel random");
}

/// A larger scene above the sampled-split threshold, with the paper's constants.
#[test]
fn dacrt_sampled_split_on_a_large_soup() {
    let s = Arc::new(merge(
        &procedural::soup(30_000, 11),
        &procedural::icosphere(20_000),
    ));
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let rays = cam.rays(96, 96);
    let mut naive = tracers::create("naive", &[]).unwrap();
    naive.prepare(s.clone()).unwrap();
    let (want, _) = naive.intersect_timed(&rays);
    for mode in ["packet", "ray", "random"] {
        let mut d = tracers::create("dacrt", &opts(&[("mode", mode)])).unwrap();
        d.prepare(s.clone()).unwrap();
        let (got, st) = d.intersect_timed(&rays);
        same_hits(&want, &got, mode);
        assert!(
            st.ray_tri < rays.len() as u64 * s.len() as u64 / 50,
            "{mode}: {st:?}"
        );
    }
}

/// Few incoherent rays against many triangles: the paper's rule ends the recursion at once
/// (fewer than `r_limit` rays) in a naive leaf of every triangle; `leaf_pairs` divides on and
/// tests a small fraction of the pairs, with the same hits.
#[test]
fn dacrt_sparse_rays_divide_on() {
    let s = Arc::new(procedural::icosphere(20_000));
    let rays = random_in_box(&s.bounds(), 15, 5);
    let mut naive = tracers::create("naive", &[]).unwrap();
    naive.prepare(s.clone()).unwrap();
    let (want, _) = naive.intersect_timed(&rays);
    let run = |kv: &[(&str, &str)]| {
        let mut d = tracers::create("dacrt", &opts(kv)).unwrap();
        d.prepare(s.clone()).unwrap();
        let (got, st) = d.intersect_timed(&rays);
        same_hits(&want, &got, &format!("{kv:?}"));
        st
    };
    for mode in ["ray", "random"] {
        let paper = run(&[("mode", mode), ("leaf_pairs", &usize::MAX.to_string())]);
        let ours = run(&[("mode", mode)]);
        assert_eq!(paper.ray_tri, 15 * s.len() as u64, "{paper:?}");
        assert!(ours.ray_tri * 20 < paper.ray_tri, "{ours:?} vs {paper:?}");
        assert!(ours.nodes > paper.nodes, "{ours:?} vs {paper:?}");
    }
}

/// Conic packets cut ray/box tests; ray mode terminates early; every counter moves.
#[test]
fn dacrt_counters_and_packets_help() {
    let s = Arc::new(procedural::icosphere(20_000));
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let rays = cam.rays(256, 256);
    let run = |mode: &str| {
        let mut d = tracers::create("dacrt", &opts(&[("mode", mode), ("tasks", "1")])).unwrap();
        d.prepare(s.clone()).unwrap();
        d.intersect_timed(&rays).1
    };
    let (ray, packet, random) = (run("ray"), run("packet"), run("random"));
    assert!(
        packet.cone_box > 0 && packet.ray_box * 2 < ray.ray_box,
        "{packet:?} vs {ray:?}"
    );
    assert!(ray.tri_box > 0 && ray.nodes > 0 && ray.ray_tri > 0 && ray.leaves > 0);
    assert_eq!(ray.cone_box, 0);
    // Shadow packets (light cones) are used when allowed.
    let mut d = tracers::create(
        "dacrt",
        &opts(&[("mode", "packet"), ("max_shadow_cone_deg", "30")]),
    )
    .unwrap();
    d.prepare(s.clone()).unwrap();
    let (hits, _) = d.intersect_timed(&rays);
    let (shadow, _) = shadow_rays(&s, &rays, &hits, Vec3::new(2.0, 3.0, 2.0));
    let (_, st) = d.occluded_timed(&shadow);
    assert!(st.cone_box > 0, "{st:?}");
    // Early termination saves ray/box tests over the z-buffer alone.
    assert!(ray.ray_box < random.ray_box, "{ray:?} vs {random:?}");
    assert!(ray.ray_tri <= random.ray_tri, "{ray:?} vs {random:?}");
}
