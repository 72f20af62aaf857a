//! The `rtt` tracer's own cases (beyond the conformance suite, which checks it through the
//! registry in its defaults and presets): tiles straddling silhouettes, tiles whose corners all
//! miss, corners hitting one triangle in different leaves, antialiased tiles of 2×2 … 6×6
//! samples (and overflowing ones, split), a camera inside the scene, coplanar grids whose
//! triangles lie in split planes, area-light shadow shafts, and the paper's own check (hit ids
//! identical to the kd-tree baseline's). Every case equals `naive` bit for bit in every
//! configuration, and the counters show the lists answering the rays they should.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use raysift::accel::kdtree::{BuildConfig, KdTree};
use raysift::rays::{generate, Camera, Ray, RayBatch, RayLayout};
use raysift::scene::{procedural, Mesh, Scene};
use raysift::testkit::{check_tracer, first_difference, Oracle};
use raysift::tracer::Counters;
use raysift::tracers;

/// `rtt` in its defaults and every preset equals `naive`; returns the defaults' counters of the
/// closest-hit and the any-hit trace.
fn check(scene: &Scene, rays: &RayBatch) -> (Counters, Counters) {
    let entry = tracers::entry("rtt").unwrap();
    let want = Oracle::new(scene, rays);
    let mut s = scene.clone();
    check_tracer(entry, &[], &mut s, rays, &want).unwrap();
    for p in entry.presets {
        check_tracer(entry, &tracers::preset_opts(p), &mut s, rays, &want)
            .unwrap_or_else(|e| panic!("preset {}: {e}", p.name));
    }
    let mut t = tracers::create("rtt", &[]).unwrap();
    t.prepare(scene).unwrap();
    let (_, closest) = t.intersect_timed(scene, rays).unwrap();
    let (_, any) = t.occluded_timed(scene, rays).unwrap();
    (closest.work, any.work)
}

/// Share of the batch's rays answered from lists.
fn listed(c: &Counters, rays: &RayBatch) -> f64 {
    c.get("list_rays") as f64 / rays.len() as f64
}

fn camera(eye: Vec3, look: Vec3) -> Camera {
    Camera {
        eye,
        look,
        up: Vec3::Y,
        fov_deg: 45.0,
    }
}

#[test]
fn sphere_image_is_answered_mostly_from_lists() {
    let scene = procedural::icosphere(1280);
    let rays = camera(Vec3::new(0.0, 0.3, 3.0), Vec3::ZERO).rays(64, 48);
    let (c, any) = check(&scene, &rays);
    assert_eq!(c.get("tiles"), 16 * 12);
    // The silhouette's tiles have a missing corner (uncapped shaft): their lists hold the
    // sphere's front and back in the shaft; interior tiles' lists the few front triangles.
    assert!(listed(&c, &rays) > 0.6, "{c:?}");
    assert!(c.get("list_len") > 0 && c.get("list_tests") > 0, "{c:?}");
    // Any-hit needs the corners too (infinite rays), then the same lists.
    assert!(listed(&any, &rays) > 0.6, "{any:?}");
}

#[test]
fn tiles_whose_corners_all_miss() {
    let scene = procedural::icosphere(320);
    // Looking away from the sphere: every tile's shaft is empty.
    let rays = camera(Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.0, 0.0, 10.0)).rays(32, 24);
    let (c, _) = check(&scene, &rays);
    assert_eq!(c.get("tiles_listed"), c.get("tiles"));
    assert_eq!(c.get("list_len"), 0);
    assert_eq!(c.get("list_rays") + c.get("corner_rays"), rays.len() as u64);
}

#[test]
fn silhouettes_against_a_far_wall() {
    // A sphere before a wall: silhouette tiles see both; rays seeing past the corners' depth
    // fall back, all others come from lists.
    let sphere = procedural::icosphere(1280);
    let wall = Mesh::new(
        "wall",
        vec![
            Vec3::new(-6.0, -6.0, -4.0),
            Vec3::new(6.0, -6.0, -4.0),
            Vec3::new(6.0, 6.0, -4.0),
            Vec3::new(-6.0, 6.0, -4.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    let mut meshes = sphere.meshes().to_vec();
    meshes.push(wall);
    let scene = Scene::from_meshes("sphere+wall", meshes).unwrap();
    let rays = camera(Vec3::new(0.2, 0.1, 4.0), Vec3::ZERO).rays(80, 60);
    let (c, _) = check(&scene, &rays);
    assert!(listed(&c, &rays) > 0.6, "{c:?}");
    assert!(c.get("fallback_rays") > 0, "{c:?}");
}

#[test]
fn antialiased_tiles() {
    let scene = procedural::icosphere(1280);
    let cam = camera(Vec3::new(0.0, 0.3, 3.0), Vec3::ZERO);
    for a in 2..=6 {
        let rays = cam.sample_rays(48, 32, a, a as u64);
        let (c, _) = check(&scene, &rays);
        assert_eq!(c.get("tiles"), 12 * 8, "{a}x{a}");
        // (4a)² rays per tile, 4 of them corners.
        assert!(listed(&c, &rays) > 0.6, "{a}x{a}: {c:?}");
    }
}

#[test]
fn overflowing_antialiased_tiles_are_split() {
    // Lists of at most 2 triangles per 16 rays: most 4×4-pixel tiles overflow and are traced as
    // quarters (and their quarters), down to single pixels; every ray still equals `naive`.
    let scene = procedural::icosphere(1280);
    let cam = camera(Vec3::new(0.0, 0.3, 3.0), Vec3::ZERO);
    for (a, side) in [(2, 4), (3, 4), (4, 4), (4, 3)] {
        let rays = cam.sample_rays(37, 29, a, a as u64);
        let opts = [("max_list", "2".to_string()), ("tile", side.to_string())];
        let opts: Vec<(String, String)> = opts
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect();
        let want = Oracle::new(&scene, &rays);
        let mut s = scene.clone();
        check_tracer(tracers::entry("rtt").unwrap(), &opts, &mut s, &rays, &want).unwrap();
        let mut t = tracers::create("rtt", &opts).unwrap();
        t.prepare(&scene).unwrap();
        let (_, st) = t.intersect_timed(&scene, &rays).unwrap();
        let c = &st.work;
        assert!(c.get("tiles_split") > 20, "{a}x{a}: {c:?}");
        assert!(listed(c, &rays) > 0.3, "{a}x{a}: {c:?}");
    }
}

#[test]
fn camera_inside_the_scene() {
    let scene = procedural::cornell();
    let b = scene.bounds();
    let eye = b.min.lerp(b.max, 0.5) + Vec3::new(0.01, 0.02, 0.03) * (b.max - b.min);
    for look in [
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(1.0, 0.3, 0.2),
        Vec3::new(-0.2, -1.0, 0.1),
    ] {
        let rays = camera(eye, eye + look).rays(48, 40);
        let (c, _) = check(&scene, &rays);
        assert!(listed(&c, &rays) > 0.3, "{c:?}");
    }
}

#[test]
fn coplanar_grids_in_split_planes() {
    // A grid of unit squares in z = 0 (every edge shared, every square's plane a split plane of
    // the cells beside it), seen head-on and at a grazing angle.
    let n = 16;
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(Vec3::new(i as f32 - 8.0, j as f32 - 8.0, 0.0));
        }
    }
    for j in 0..n {
        for i in 0..n {
            let k = j * (n + 1) + i;
            indices.push([k, k + 1, k + n + 2]);
            indices.push([k, k + n + 2, k + n + 1]);
        }
    }
    let scene = Scene::from_meshes("grid", vec![Mesh::new("g", positions, indices)]).unwrap();
    for eye in [
        Vec3::new(0.0, 0.0, 12.0),
        Vec3::new(0.5, -9.0, 0.7),
        Vec3::new(0.0, 0.0, 0.0),
    ] {
        let look = if eye == Vec3::ZERO {
            Vec3::new(0.3, 0.2, 1.0)
        } else {
            Vec3::ZERO
        };
        check(&scene, &camera(eye, look).rays(40, 32));
    }
}

/// The kd-tree leaf holding point `p` (below a split plane when on it).
fn leaf_of(tree: &KdTree, p: Vec3) -> u32 {
    let mut node = 0u32;
    loop {
        let n = tree.nodes[node as usize];
        if n.is_leaf() {
            return node;
        }
        node = if p[n.axis()] <= n.split() {
            node + 1
        } else {
            n.above()
        };
    }
}

#[test]
fn corners_hitting_one_triangle_in_different_leaves() {
    // One large floor triangle under a lattice of small ones: the kd-tree's splits between the
    // small triangles cut the floor into many leaves, so a tile's four corners hit the same
    // floor triangle in different leaves (the paper's "different node sequences").
    let mut positions = vec![
        Vec3::new(-10.0, 0.0, -10.0),
        Vec3::new(10.0, 0.0, -10.0),
        Vec3::new(0.0, 0.0, 10.0),
    ];
    let mut indices = vec![[0, 1, 2]];
    for i in 0..20 {
        for k in 0..20 {
            let (x, z) = (-1.0 + 0.1 * i as f32, -1.0 + 0.1 * k as f32);
            let base = positions.len() as u32;
            positions.extend([
                Vec3::new(x, 0.5, z),
                Vec3::new(x + 0.02, 0.5, z),
                Vec3::new(x, 0.52, z + 0.02),
            ]);
            indices.push([base, base + 1, base + 2]);
        }
    }
    let scene = Scene::from_meshes("posts", vec![Mesh::new("p", positions, indices)]).unwrap();
    let tree = KdTree::build(scene.triangles(), &BuildConfig::default()).unwrap();
    let cam = camera(Vec3::new(0.05, 3.0, 0.3), Vec3::new(0.0, 0.0, 0.0));
    let rays = cam.rays(48, 40);
    let (c, _) = check(&scene, &rays);
    assert!(listed(&c, &rays) > 0.5, "{c:?}");
    // Tiles whose four corners all hit the floor, in more than one leaf.
    let naive = Oracle::new(&scene, &rays);
    let (w, mut split_tiles) = (48, 0);
    for j0 in (0..40).step_by(4) {
        for i0 in (0..w).step_by(4) {
            let corners = [(i0, j0), (i0 + 3, j0), (i0 + 3, j0 + 3), (i0, j0 + 3)];
            let leaves: Vec<u32> = corners
                .iter()
                .filter_map(|&(i, j)| {
                    let r = j * w + i;
                    (naive.hits.prim[r] == 0)
                        .then(|| leaf_of(&tree, rays.origin(r) + rays.dir(r) * naive.hits.t[r]))
                })
                .collect();
            if leaves.len() == 4 && leaves.iter().any(|&l| l != leaves[0]) {
                split_tiles += 1;
            }
        }
    }
    assert!(split_tiles > 20, "{split_tiles}");
}

#[test]
fn area_light_shadow_shafts() {
    // 8×8 shadow samples from points on the floor of the Cornell box to its ceiling light
    // square: `OriginGrids` of finite segments, answered from lists without corner rays.
    let scene = procedural::cornell();
    let b = scene.bounds();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let side = 8;
    let mut rays = RayBatch::default();
    let size = b.max - b.min;
    for _ in 0..40 {
        let o = b.min + size * Vec3::new(rng.gen_range(0.1..0.9), 0.001, rng.gen_range(0.1..0.9));
        for j in 0..side {
            for i in 0..side {
                let p = b.min
                    + size
                        * Vec3::new(
                            0.4 + 0.2 * (i as f32 + 0.5) / side as f32,
                            0.999,
                            0.4 + 0.2 * (j as f32 + 0.5) / side as f32,
                        );
                rays.push(Ray {
                    origin: o,
                    dir: p - o,
                    tmin: 1e-4,
                    tmax: 1.0,
                });
            }
        }
    }
    rays.layout = RayLayout::OriginGrids { side };
    let (_, any) = check(&scene, &rays);
    assert_eq!(any.get("corner_rays"), 0, "{any:?}");
    assert!(listed(&any, &rays) > 0.9, "{any:?}");
}

#[test]
fn point_light_shadow_shafts() {
    // Shadow rays from the camera hits to a point light (`ToPoint`): 16 consecutive segments
    // make a tile whose shaft bounds the segments themselves (apex behind the light).
    for (scene, eye, light) in [
        (procedural::cornell(), None, Vec3::new(0.0, 1.5, 0.2)),
        (
            procedural::icosphere(1280),
            Some(Vec3::new(0.0, 0.3, 3.0)),
            Vec3::new(2.0, 3.0, 2.0),
        ),
    ] {
        let b = scene.bounds();
        let eye =
            eye.unwrap_or(b.min.lerp(b.max, 0.5) + Vec3::new(0.0, 0.0, 0.45) * (b.max - b.min));
        let light = b.min.lerp(b.max, 0.5) + light * (b.max - b.min) * 0.4;
        let cam = camera(eye, b.min.lerp(b.max, 0.5)).rays(128, 96);
        let want = Oracle::new(&scene, &cam);
        let (shadow, _) = generate::shadow_rays(&scene, &cam, &want.hits, light);
        assert!(matches!(shadow.layout, RayLayout::ToPoint { .. }));
        let (closest, any) = check(&scene, &shadow);
        assert_eq!(any.get("corner_rays") + closest.get("corner_rays"), 0);
        assert!(listed(&any, &shadow) > 0.5, "{}: {any:?}", scene.name);
        assert!(
            listed(&closest, &shadow) > 0.5,
            "{}: {closest:?}",
            scene.name
        );
    }
}

#[test]
fn planar_mirror_reflection_shafts() {
    // A mirror square behind a sphere; the camera's rays that hit the mirror are reflected
    // (origin nudged off the plane, as the renderers do) and traced as one batch without a
    // layout: groups of 16 meet near the mirrored eye, the apex of their shaft.
    let sphere = procedural::icosphere(1280);
    let mirror = Mesh::new(
        "mirror",
        vec![
            Vec3::new(-4.0, -4.0, -2.0),
            Vec3::new(4.0, -4.0, -2.0),
            Vec3::new(4.0, 4.0, -2.0),
            Vec3::new(-4.0, 4.0, -2.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    let mut meshes = sphere.meshes().to_vec();
    meshes.push(mirror);
    let scene = Scene::from_meshes("sphere+mirror", meshes).unwrap();
    let cam = camera(Vec3::new(1.5, 0.5, 4.0), Vec3::new(0.0, 0.0, -2.0)).rays(96, 72);
    let hits = Oracle::new(&scene, &cam).hits;
    let first_mirror = scene.len() as u32 - 2;
    let mut refl = RayBatch::default();
    for i in 0..cam.len() {
        if hits.prim[i] >= first_mirror && hits.prim[i] != raysift::rays::MISS {
            let (o, d) = (cam.origin(i), cam.dir(i));
            let p = o + d * hits.t[i];
            refl.push(Ray {
                origin: p + Vec3::Z * 1e-4,
                dir: Vec3::new(d.x, d.y, -d.z),
                tmin: 0.0,
                tmax: f32::INFINITY,
            });
        }
    }
    assert_eq!(refl.layout, RayLayout::Unknown);
    assert!(refl.len() > 2000, "{} reflected rays", refl.len());
    let (c, any) = check(&scene, &refl);
    assert!(c.get("corner_rays") > 0);
    assert!(listed(&c, &refl) > 0.5, "{c:?}");
    assert!(listed(&any, &refl) > 0.5, "{any:?}");
    // Random rays meet nowhere: every group falls back, the answers stay exact.
    let random = generate::random_in_box(&scene.bounds(), 3000, 9);
    let (c, _) = check(&scene, &random);
    assert!(listed(&c, &random) < 0.05, "{c:?}");
}

#[test]
fn thin_triangle_soup_with_lists() {
    // Thousands of small triangles at all depths (the paper's foliage): many tiles' lists hold
    // triangles near the cap, so a cap or box test a hair too tight gives wrong hits here.
    for seed in [5, 6] {
        let scene = procedural::soup(3000, seed);
        let rays = Camera::framing(&scene.bounds(), 45.0, 1.5).rays(72, 48);
        let (c, _) = check(&scene, &rays);
        assert!(listed(&c, &rays) > 0.5, "{c:?}");
    }
}

#[test]
fn hit_ids_equal_the_kdtree_baseline() {
    // The paper's check: the image's hit triangle ids equal the baseline's, here with every
    // field of every hit, on a soup of thin triangles (the paper's foliage) and a sphere.
    let mut kd = tracers::create("kdtree", &[]).unwrap();
    let mut rtt = tracers::create("rtt", &[]).unwrap();
    for scene in [procedural::soup(3000, 7), procedural::icosphere(20000)] {
        let b = scene.bounds();
        let c = b.min.lerp(b.max, 0.5);
        let rays = camera(c + Vec3::new(0.1, 0.2, 2.5) * (b.max - b.min).length(), c).rays(96, 72);
        kd.prepare(&scene).unwrap();
        rtt.prepare(&scene).unwrap();
        let (want, _) = kd.intersect_timed(&scene, &rays).unwrap();
        let (got, st) = rtt.intersect_timed(&scene, &rays).unwrap();
        assert_eq!(first_difference(&want, &got), None, "{}", scene.name);
        assert!(
            st.work.get("list_rays") > 0,
            "{}: {:?}",
            scene.name,
            st.work
        );
    }
}

#[test]
fn bytes_are_the_kdtrees_and_options_are_checked() {
    let scene = procedural::icosphere(1280);
    let mut kd = tracers::create("kdtree", &[]).unwrap();
    let mut rtt = tracers::create("rtt", &[]).unwrap();
    kd.prepare(&scene).unwrap();
    rtt.prepare(&scene).unwrap();
    assert_eq!(rtt.bytes(), kd.bytes());
    // Per-task scratch, nothing per ray: the same peak for a 4× larger image.
    let cam = camera(Vec3::new(0.0, 0.3, 3.0), Vec3::ZERO);
    let (_, small) = rtt.intersect_timed(&scene, &cam.rays(64, 48)).unwrap();
    let (_, large) = rtt.intersect_timed(&scene, &cam.rays(128, 96)).unwrap();
    assert_eq!(small.peak_bytes, large.peak_bytes);
    assert!(
        (16 << 10..48 << 10).contains(&small.peak_bytes),
        "{}",
        small.peak_bytes
    );
    // 6×6 samples: tiles of 576 rays may use lists of 16 × 64 triangles (`Config::list_limit`),
    // prepared at 84 bytes each: about 144 KiB.
    let (_, aa) = rtt
        .intersect_timed(&scene, &cam.sample_rays(32, 24, 6, 1))
        .unwrap();
    assert!(
        (128 << 10..160 << 10).contains(&aa.peak_bytes),
        "{}",
        aa.peak_bytes
    );
    for bad in [
        ("tile", "1"),
        ("tile", "17"),
        ("max_list", "5000"),
        ("cap_growth", "-1"),
        ("nope", "1"),
    ] {
        let opts = vec![(bad.0.to_string(), bad.1.to_string())];
        let e = tracers::create("rtt", &opts)
            .err()
            .expect("refused")
            .to_string();
        assert!(e.contains("rtt"), "{e}");
    }
}
