//! The conformance suite: every registered tracer must return exactly what `naive` returns —
//! closest hit (`t`, `prim`, `u`, `v`, bit for bit, ties to the smaller id) and occlusion — on
//! generated scenes and rays (proptest) and on hand-made edge cases, in its defaults and in every
//! configuration preset its registry entry declares (`raysift::tracers::REGISTRY`): a new tracer
//! joins by being registered, with no test code of its own. The checks themselves are
//! `raysift::testkit::check_all`.

use glam::Vec3;
use proptest::prelude::*;
use raysift::rays::{generate, Camera, Ray, RayBatch, RayLayout};
use raysift::scene::{procedural, Mesh, Scene};
use raysift::testkit::{check_all, first_difference, shared_scenes, Oracle};
use raysift::{tracers, HitBatch};

fn assert_all(scene: Scene, rays: &RayBatch) {
    if let Err(e) = check_all(&scene, rays) {
        panic!("{e}");
    }
}

// ---------------------------------------------------------------- generated cases

/// Coordinates from a coarse grid half of the time, so that axis-aligned planes, shared edges,
/// coincident and degenerate triangles and rays exactly on box faces are common.
fn coord() -> impl Strategy<Value = f32> {
    prop_oneof![(-4i32..=4).prop_map(|k| k as f32 * 0.5), -2.0f32..2.0]
}

fn point() -> impl Strategy<Value = Vec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn triangle() -> impl Strategy<Value = [Vec3; 3]> {
    prop_oneof![
        // General triangle.
        4 => (point(), point(), point()).prop_map(|(a, b, c)| [a, b, c]),
        // Small triangle near a point (dense clusters, deep trees).
        4 => (point(), point(), point()).prop_map(|(a, b, c)| [a, a + b * 0.05, a + c * 0.05]),
        // Axis-aligned: all corners share one coordinate.
        2 => (0usize..3, point(), point(), point()).prop_map(|(ax, a, mut b, mut c)| { b[ax] = a[ax]; c[ax] = a[ax]; [a, b, c] }),
        // Degenerate: repeated or collinear corners.
        1 => (point(), point()).prop_map(|(a, b)| [a, b, a + (b - a) * 2.0]),
        1 => point().prop_map(|a| [a, a, a]),
    ]
}

fn direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        3 => (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0).prop_filter_map("zero", |(x, y, z)| {
            let d = Vec3::new(x, y, z);
            (d.length() > 1e-3).then(|| d.normalize())
        }),
        // Axis-parallel, including -0.0 components.
        2 => (0usize..3, prop::bool::ANY, prop::bool::ANY).prop_map(|(ax, neg, negzero)| {
            let z = if negzero { -0.0 } else { 0.0 };
            let mut d = Vec3::splat(z);
            d[ax] = if neg { -1.0 } else { 1.0 };
            d
        }),
        // Unnormalised.
        1 => (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0).prop_filter("zero", |(x, y, z)| x.abs() + y.abs() + z.abs() > 1e-2).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
    ]
}

fn ray() -> impl Strategy<Value = Ray> {
    let interval = prop_oneof![
        3 => Just((0.0f32, f32::INFINITY)),
        2 => (0.0f32..3.0, 0.0f32..6.0).prop_map(|(a, len)| (a, a + len)),
        1 => Just((1.0f32, 1.0f32)),
    ];
    (point(), direction(), interval).prop_map(|(o, d, (tmin, tmax))| Ray {
        origin: o * 1.5,
        dir: d,
        tmin,
        tmax,
    })
}

fn scene_of(tris: Vec<[Vec3; 3]>) -> Scene {
    let pos = tris.iter().flatten().copied().collect();
    let idx = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Scene::from_meshes("proptest", vec![Mesh::new("m", pos, idx)]).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, .. ProptestConfig::default() })]

    #[test]
    fn every_tracer_equals_naive(tris in prop::collection::vec(triangle(), 0..120), rays in prop::collection::vec(ray(), 0..300)) {
        let scene = scene_of(tris);
        let batch = RayBatch::from_rays(rays);
        prop_assert_eq!(check_all(&scene, &batch), Ok(()));
    }

    #[test]
    fn every_tracer_equals_naive_on_duplicated_triangles(tris in prop::collection::vec(triangle(), 1..40), rays in prop::collection::vec(ray(), 1..200)) {
        // Every triangle twice: every hit is a tie, resolved to the smaller id.
        let doubled: Vec<_> = tris.iter().chain(tris.iter()).copied().collect();
        prop_assert_eq!(check_all(&scene_of(doubled), &RayBatch::from_rays(rays)), Ok(()));
    }
}

// ---------------------------------------------------------------- adversarial classes (issue #20)

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, .. ProptestConfig::default() })]

    /// Each adversarial class (raysift::testkit::adversarial: coplanar grids axis-aligned and
    /// tilted, rays at shared edges and vertices, near-parallel rays, needle fans, duplicated
    /// triangles, huge and tiny scales and far offsets, denormal and huge directions, grazing
    /// pinhole cameras), generated from a proptest seed, for every tracer and preset.
    #[test]
    fn adversarial_classes_equal_naive(class in 0usize..raysift::testkit::adversarial::CLASSES.len(), seed in 0u64..1_000_000) {
        let name = raysift::testkit::adversarial::CLASSES[class];
        let c = raysift::testkit::adversarial::case(name, seed, 400).unwrap();
        prop_assert_eq!(check_all(&c.scene, &c.rays), Ok(()), "{}", c.name);
    }
}

#[test]
fn every_adversarial_class_at_a_fixed_seed() {
    for name in raysift::testkit::adversarial::CLASSES {
        let c = raysift::testkit::adversarial::case(name, 7, 600).unwrap();
        if let Err(e) = check_all(&c.scene, &c.rays) {
            panic!("{}: {e}", c.name);
        }
    }
}

// ---------------------------------------------------------------- fixed cases

#[test]
fn suite_has_contenders_and_can_fail() {
    // The suite is only meaningful with at least one tracer besides naive; and the comparison
    // must see a difference when there is one.
    let mut a = HitBatch::new(2);
    let b = a.clone();
    a.prim[1] = 3;
    assert!(first_difference(&a, &b).is_some());
    a.prim[1] = raysift::rays::MISS;
    a.t[0] = -0.0;
    let mut c = b.clone();
    c.t[0] = 0.0;
    assert!(first_difference(&a, &c).is_some(), "t compared bitwise");
    let contenders: Vec<String> = raysift::testkit::contenders()
        .iter()
        .map(|e| format!("{} ({} presets)", e.name, e.presets.len()))
        .collect();
    assert!(!contenders.is_empty());
    eprintln!("conformance contenders: {contenders:?}");
}

#[test]
fn empty_batches_and_empty_scenes() {
    assert_all(procedural::icosphere(80), &RayBatch::default());
    let rays = generate::random_in_box(
        &raysift::geom::Aabb::new(Vec3::splat(-1.0), Vec3::ONE),
        100,
        1,
    );
    assert_all(Scene::from_meshes("empty", vec![]).unwrap(), &rays);
    assert_all(
        Scene::from_meshes("empty", vec![]).unwrap(),
        &RayBatch::default(),
    );
}

#[test]
fn one_triangle_scene() {
    let s = scene_of(vec![[Vec3::ZERO, Vec3::X, Vec3::Y]]);
    let cam = Camera {
        eye: Vec3::new(0.3, 0.3, 2.0),
        look: Vec3::new(0.3, 0.3, 0.0),
        up: Vec3::Y,
        fov_deg: 60.0,
    };
    assert_all(s, &cam.rays(32, 32));
}

#[test]
fn cornell_box_from_outside_and_inside() {
    let s = procedural::cornell();
    let outside = Camera::framing(&s.bounds(), 45.0, 1.0);
    assert_all(s.clone(), &outside.rays(48, 48));
    // A camera inside the box: every ray starts inside every enclosing box.
    let inside = Camera {
        eye: Vec3::new(0.0, 1.0, 0.0),
        look: Vec3::new(0.3, 0.8, -1.0),
        up: Vec3::Y,
        fov_deg: 100.0,
    };
    assert_all(s.clone(), &inside.rays(48, 48));
    // Rays along the walls' planes and axis-parallel rays through the room.
    let mut rays = RayBatch::default();
    for k in 0..200 {
        let f = k as f32 / 200.0;
        for d in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            rays.push(Ray {
                origin: Vec3::new(-1.0 + 2.0 * f, f * 1.99, 1.0 - 2.0 * f),
                dir: d,
                tmin: 0.0,
                tmax: f32::INFINITY,
            });
        }
        rays.push(Ray {
            origin: Vec3::new(-0.5 + f, 0.0, 0.5),
            dir: Vec3::X,
            tmin: 0.0,
            tmax: f32::INFINITY,
        });
    }
    assert_all(s, &rays);
}

#[test]
fn shadow_rays_and_secondary_layouts() {
    let s = procedural::cornell();
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let primary = cam.rays(64, 64);
    let hits = Oracle::new(&s, &primary).hits;
    let (shadow, _) = generate::shadow_rays(&s, &primary, &hits, Vec3::new(0.0, 1.9, 0.0));
    assert!(matches!(shadow.layout, RayLayout::ToPoint { .. }));
    assert_all(s.clone(), &shadow);
    let (bounce, _) = generate::bounce_rays(&s, &primary, &hits, 5);
    assert_all(s, &bounce);
}

#[test]
fn camera_and_random_rays_on_generated_meshes() {
    let sphere = procedural::icosphere(5000);
    let cam = Camera::framing(&sphere.bounds(), 45.0, 1.5);
    assert_all(sphere.clone(), &cam.rays(96, 64));
    assert_all(
        sphere.clone(),
        &generate::random_in_box(&sphere.bounds(), 3000, 7),
    );
    let soup = procedural::soup(3000, 2);
    assert_all(
        soup.clone(),
        &Camera::framing(&soup.bounds(), 45.0, 1.0).rays(64, 64),
    );
    assert_all(
        soup.clone(),
        &generate::random_in_box(&soup.bounds(), 3000, 9),
    );
    let tiles = procedural::tile(&procedural::cornell(), 3).unwrap();
    assert_all(
        tiles.clone(),
        &Camera::framing(&tiles.bounds(), 45.0, 1.0).rays(64, 64),
    );
}

#[test]
fn a_large_batch() {
    // Many rays through a small scene: chunking and parallel partitions must cover every ray.
    let s = procedural::icosphere(300);
    let rays = generate::random_in_box(
        &raysift::geom::Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)),
        200_000,
        11,
    );
    assert_all(s, &rays);
}

#[test]
fn unknown_tracer_is_an_error() {
    let e = tracers::create("nope", &[])
        .err()
        .expect("unknown name must fail")
        .to_string();
    assert!(e.contains("nope") && e.contains("naive"), "{e}");
}

// ---------------------------------------------------------------- cases from the DACRT issue
// (adversarial for space-dividing tracers, run for every tracer and preset)

/// Checks `rays` on `scene` for every tracer and preset; returns naive's hits.
fn check(scene: &Scene, rays: &RayBatch, what: &str) -> HitBatch {
    if let Err(e) = check_all(scene, rays) {
        panic!("{what}: {e}");
    }
    Oracle::new(scene, rays).hits
}

/// Camera rays plus the shadow rays of their hits (towards `light`), both checked, and the
/// camera rays again without their layout hint.
fn check_camera(scene: Scene, cam: Camera, w: u32, h: u32, light: Vec3, what: &str) {
    let rays = cam.rays(w, h);
    let hits = check(&scene, &rays, &format!("{what} camera"));
    assert!(hits.hit_count() > 0, "{what}: the camera sees nothing");
    let (shadow, _) = generate::shadow_rays(&scene, &rays, &hits, light);
    check(&scene, &shadow, &format!("{what} shadow"));
    let mut plain = rays.clone();
    plain.layout = RayLayout::Unknown;
    check(&scene, &plain, &format!("{what} camera, no hint"));
}

fn scene_of_slice(tris: &[[Vec3; 3]]) -> Scene {
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
    scene_of_slice(&tris)
}

#[test]
fn soup_camera_shadow_and_random() {
    let s = procedural::soup(3000, 5);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.5);
    check_camera(s.clone(), cam, 72, 48, Vec3::new(0.3, 3.0, 2.0), "soup");
    let rays = generate::random_in_box(&s.bounds(), 3000, 9);
    check(&s, &rays, "soup random rays");
}

#[test]
fn icosphere_outside_and_inside() {
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
fn cornell_outside_and_inside() {
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
fn pinhole_layout_with_jittered_and_shuffled_rays() {
    use rand::{Rng, SeedableRng};
    let s = procedural::icosphere(3000);
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
        let _ = culls;
    }
}

/// Axis-parallel rays exactly on the median planes (x, y, z ∈ {−1, −0.5, 0, 0.5, 1}) and
/// triangles lying in those planes.
#[test]
fn rays_and_triangles_on_split_planes() {
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
    let base = merge(&scene_of_slice(&tris), &procedural::soup(400, 3));
    let s = base;
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
        s.clone(),
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
fn coincident_fans_and_degenerates() {
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
    let s = scene_of_slice(&tris);
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
    check(
        &s,
        &generate::random_in_box(&s.bounds(), 2000, 4),
        "coincident random",
    );
}

/// A wall in front of everything: every camera ray terminates in the first leaves.
#[test]
fn all_rays_terminated_early() {
    let wall = scene_of_slice(&[
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
fn empty_batches_and_scenes() {
    let empty = Scene::from_meshes("e", vec![]).unwrap();
    let full = procedural::soup(100, 1);
    let cam = Camera::framing(&full.bounds(), 45.0, 1.0);
    for s in [&empty, &full] {
        check(s, &RayBatch::default(), "empty batch");
        check(s, &cam.rays(16, 8), "camera");
    }
}

/// Random tmin/tmax windows (including negative tmin), on camera rays that keep their pinhole
/// hint and on random rays.
#[test]
fn tmin_tmax_clipping() {
    let s = merge(&procedural::icosphere(1280), &procedural::soup(1500, 2));
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let mut rays = cam.rays(48, 48);
    let mut random = generate::random_in_box(&s.bounds(), 2000, 3);
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
fn axis_parallel_rays_and_grazing_cones() {
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
    let mut rays = generate::random_in_box(&b, 1500, 6);
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

/// A larger scene (above DACRT's sampled-split threshold; deep BVHs).
#[test]
fn sampled_split_on_a_large_soup() {
    let s = merge(
        &procedural::soup(30_000, 11),
        &procedural::icosphere(20_000),
    );
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    check(&s, &cam.rays(96, 96), "large soup camera");
}

// ---------------------------------------------------------------- real scenes

#[test]
fn real_scenes_camera_and_random_rays() {
    let Some(dir) = shared_scenes("real-scene conformance") else {
        return;
    };
    // Small and mid-size meshes (naive is the oracle, so the ray counts are kept modest).
    for (file, w) in [
        ("bun_zipper_res4.ply", 64),
        ("CornellBox-Original.obj", 64),
        ("teapot.obj", 48),
        ("dragon_vrip_res4.ply", 48),
        ("bun_zipper_res2.ply", 32),
        ("armadillo.off", 24),
        ("sponza.obj.gz", 24),
    ] {
        let path = dir.join(file);
        let s = raysift::scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
        assert_all(s.clone(), &cam.rays(w, w));
        assert_all(
            s.clone(),
            &generate::random_in_box(&s.bounds(), (w * w) as usize, 3),
        );
        eprintln!(
            "real scene {file}: {} triangles, all tracers equal naive",
            s.len()
        );
    }
}

// ---------------------------------------------------------------- animated scenes

/// Rigid motion of one mesh of several, a deformation of another, and frames where nothing
/// changes: every tracer, prepared again each frame (updating where it can: DACRT rewrites only
/// the moved meshes' lists, the BVH refits in its refit presets), equals naive on every frame.
#[test]
fn animated_multi_mesh_scenes_stay_exact() {
    use glam::{Affine3A, Quat};
    let parts = [
        procedural::icosphere(300),
        procedural::soup(200, 4),
        procedural::icosphere(80),
    ];
    let meshes: Vec<Mesh> = parts
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let mut m = p.meshes()[0].clone();
            m.transform = Affine3A::from_translation(Vec3::new(k as f32 * 1.5 - 1.5, 0.0, 0.0));
            m
        })
        .collect();
    let scene = Scene::from_meshes("three parts", meshes).unwrap();
    let rays = generate::random_in_box(&scene.bounds(), 1500, 21);
    let cam = Camera::framing(&scene.bounds(), 50.0, 1.0).rays(40, 40);
    for rays in [&rays, &cam] {
        let r = raysift::testkit::check_animation(
            &scene,
            5,
            |s, f| {
                match f {
                    2 => {} // a frame where nothing changed
                    _ => {
                        let spin = Quat::from_rotation_y(0.4 * f as f32);
                        s.set_transform(
                            1,
                            Affine3A::from_rotation_translation(
                                spin,
                                Vec3::new(0.0, 0.1 * f as f32, 0.0),
                            ),
                        )
                        .unwrap();
                        let pos: Vec<Vec3> = s.meshes()[2]
                            .positions
                            .iter()
                            .map(|p| *p * (1.0 + 0.1 * f as f32))
                            .collect();
                        s.replace_positions(2, pos).unwrap();
                    }
                }
            },
            rays,
        );
        if let Err(e) = r {
            panic!("{e}");
        }
    }
}
