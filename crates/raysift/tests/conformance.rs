//! The conformance suite: every registered tracer must return exactly what `naive` returns —
//! closest hit (`t`, `prim`, `u`, `v`, bit for bit, ties to the smaller id) and occlusion — on
//! generated scenes and rays (proptest) and on hand-made edge cases. A new tracer joins by being
//! listed in `raysift::tracers::NAMES`.

use glam::Vec3;
use proptest::prelude::*;
use raysift::rays::{generate, Camera, Ray, RayBatch, RayLayout};
use raysift::scene::{procedural, Mesh, Scene};
use raysift::{tracers, HitBatch, Tracer};
use std::sync::Arc;

/// Every tracer but the oracle.
fn contenders() -> Vec<&'static str> {
    tracers::NAMES
        .iter()
        .copied()
        .filter(|&n| n != "naive")
        .collect()
}

fn oracle(scene: &Arc<Scene>) -> Box<dyn Tracer> {
    let mut t = tracers::create("naive", &[]).unwrap();
    t.prepare(scene.clone()).unwrap();
    t
}

/// First index where two hit batches differ, with a description.
fn first_difference(want: &HitBatch, got: &HitBatch) -> Option<String> {
    if want.len() != got.len() {
        return Some(format!("length {} vs {}", want.len(), got.len()));
    }
    (0..want.len()).find_map(|i| {
        let same = want.t[i].to_bits() == got.t[i].to_bits()
            && want.prim[i] == got.prim[i]
            && want.u[i].to_bits() == got.u[i].to_bits()
            && want.v[i].to_bits() == got.v[i].to_bits();
        (!same).then(|| {
            format!(
                "ray {i}: naive (t {}, prim {}, u {}, v {}) vs (t {}, prim {}, u {}, v {})",
                want.t[i],
                want.prim[i],
                want.u[i],
                want.v[i],
                got.t[i],
                got.prim[i],
                got.u[i],
                got.v[i]
            )
        })
    })
}

/// Checks every contender against naive on one scene and batch; returns the first failure.
fn check_all(scene: Scene, rays: &RayBatch) -> Result<(), String> {
    let scene = Arc::new(scene);
    let naive = oracle(&scene);
    let (want, _) = naive.intersect_timed(rays);
    let (want_occ, _) = naive.occluded_timed(rays);
    for name in contenders() {
        let mut t = tracers::create(name, &[]).unwrap();
        t.prepare(scene.clone())
            .map_err(|e| format!("{name}: prepare failed: {e}"))?;
        let (got, stats) = t.intersect_timed(rays);
        if let Some(d) = first_difference(&want, &got) {
            return Err(format!("{name} closest hit on {}: {d}", scene.name));
        }
        if stats.rays != rays.len() as u64 {
            return Err(format!(
                "{name}: stats.rays = {} for {} rays",
                stats.rays,
                rays.len()
            ));
        }
        let (occ, _) = t.occluded_timed(rays);
        if let Some(i) = (0..rays.len()).find(|&i| occ.get(i) != want_occ.get(i)) {
            return Err(format!(
                "{name} occlusion on {}: ray {i}: naive {:?} vs {:?}",
                scene.name,
                want_occ.get(i),
                occ.get(i)
            ));
        }
        if occ.len() != rays.len() {
            return Err(format!(
                "{name}: {} occlusion flags for {} rays",
                occ.len(),
                rays.len()
            ));
        }
        // Preparing again (a new frame of the same scene) must give the same answer.
        t.prepare(scene.clone())
            .map_err(|e| format!("{name}: second prepare failed: {e}"))?;
        if let Some(d) = first_difference(&want, &t.intersect_timed(rays).0) {
            return Err(format!("{name} after re-prepare on {}: {d}", scene.name));
        }
    }
    Ok(())
}

fn assert_all(scene: Scene, rays: &RayBatch) {
    if let Err(e) = check_all(scene, rays) {
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
        prop_assert_eq!(check_all(scene, &batch), Ok(()));
    }

    #[test]
    fn every_tracer_equals_naive_on_duplicated_triangles(tris in prop::collection::vec(triangle(), 1..40), rays in prop::collection::vec(ray(), 1..200)) {
        // Every triangle twice: every hit is a tie, resolved to the smaller id.
        let doubled: Vec<_> = tris.iter().chain(tris.iter()).copied().collect();
        prop_assert_eq!(check_all(scene_of(doubled), &RayBatch::from_rays(rays)), Ok(()));
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
    eprintln!("conformance contenders: {:?}", contenders());
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
    let (hits, _) = oracle(&Arc::new(s.clone())).intersect_timed(&primary);
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

// ---------------------------------------------------------------- real scenes

fn shared_scenes() -> Option<std::path::PathBuf> {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!(
            "SKIPPED: real-scene conformance: {} not found (CI has it)",
            p.display()
        );
        None
    }
}

#[test]
fn real_scenes_camera_and_random_rays() {
    let Some(dir) = shared_scenes() else { return };
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
