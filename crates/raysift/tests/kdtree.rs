//! The `kdtree` tracer's own cases (beyond the conformance suite, which checks it through the
//! registry): triangles lying in split planes hit by rays in and across those planes, trees the
//! depth limit stops (duplicates, needle clusters), a camera inside the scene, its counters and
//! its bytes. Every case compares with `naive` bit for bit, in the defaults and every preset.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use raysift::rays::{Camera, Ray, RayBatch};
use raysift::scene::{procedural, Mesh, Scene};
use raysift::testkit::{check_tracer, Oracle};
use raysift::tracer::Tracer;
use raysift::tracers::{self, kdtree::KdTracer};

fn scene_of(name: &str, tris: &[[Vec3; 3]]) -> Scene {
    let positions = tris.iter().flatten().copied().collect();
    let indices = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Scene::from_meshes(name, vec![Mesh::new("m", positions, indices)]).unwrap()
}

/// `kdtree` in its defaults and every preset equals `naive` on `scene` and `rays`.
fn check(scene: &Scene, rays: &RayBatch) {
    let entry = tracers::entry("kdtree").unwrap();
    let want = Oracle::new(scene, rays);
    let mut scene = scene.clone();
    check_tracer(entry, &[], &mut scene, rays, &want).unwrap();
    for p in entry.presets {
        check_tracer(entry, &tracers::preset_opts(p), &mut scene, rays, &want)
            .unwrap_or_else(|e| panic!("preset {}: {e}", p.name));
    }
}

/// Axis-aligned unit squares (two triangles each) on the integer planes of a 4-cube: the
/// builder splits in their planes. Rays: axis-parallel ones lying exactly in a plane
/// (`o_a == s`, `d_a = ±0`: the NaN split distance), ones through grid points and edges, and
/// random ones; ties between the two triangles of a square and between squares sharing edges
/// are everywhere.
#[test]
fn triangles_in_split_planes() {
    let mut tris = Vec::new();
    for ax in 0..3 {
        let (u, v) = ((ax + 1) % 3, (ax + 2) % 3);
        for k in 0..=4 {
            for i in 0..4 {
                for j in 0..4 {
                    let corner = |di: f32, dj: f32| {
                        let mut p = Vec3::ZERO;
                        p[ax] = k as f32;
                        p[u] = i as f32 + di;
                        p[v] = j as f32 + dj;
                        p
                    };
                    if (i + j + k + ax) % 3 != 0 {
                        tris.push([corner(0.0, 0.0), corner(1.0, 0.0), corner(1.0, 1.0)]);
                        tris.push([corner(0.0, 0.0), corner(1.0, 1.0), corner(0.0, 1.0)]);
                    }
                }
            }
        }
    }
    let scene = scene_of("planes", &tris);
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
    let mut rays = RayBatch::default();
    for _ in 0..3000 {
        let grid = |rng: &mut rand_pcg::Pcg64Mcg| (rng.gen_range(-2..=12) as f32) * 0.5;
        let o = Vec3::new(grid(&mut rng), grid(&mut rng), grid(&mut rng));
        let dir = match rng.gen_range(0..3) {
            0 => {
                let mut d = Vec3::splat(if rng.gen() { 0.0 } else { -0.0 });
                d[rng.gen_range(0..3)] = if rng.gen() { 1.0 } else { -1.0 };
                d
            }
            1 => Vec3::new(grid(&mut rng), grid(&mut rng), grid(&mut rng)) - o,
            _ => Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ),
        };
        let tmax = if rng.gen_range(0..4) == 0 {
            rng.gen_range(0..8) as f32 * 0.5
        } else {
            f32::INFINITY
        };
        rays.push(Ray {
            origin: o,
            dir,
            tmin: 0.0,
            tmax,
        });
    }
    check(&scene, &rays);
    // The case exercises what it is about: splits in the squares' planes, and rays in them.
    let mut t = KdTracer::new(Default::default()).unwrap();
    t.prepare(&scene).unwrap();
    let in_plane = t
        .tree()
        .nodes
        .iter()
        .filter(|n| !n.is_leaf() && n.split().fract() == 0.0)
        .count();
    assert!(in_plane >= 3, "{in_plane} splits in the squares' planes");
}

/// 400 copies of one triangle, a fan of needles around one point and a cluster of tiny
/// triangles: the depth limit, not the SAH, ends these trees.
#[test]
fn deep_and_degenerate_trees() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let mut tris = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 400];
    for k in 0..400 {
        let a = k as f32 * 0.0157;
        let tip = Vec3::new(a.cos(), a.sin(), 0.3) * 2.0;
        tris.push([Vec3::splat(0.25), tip, tip + Vec3::Z * 1e-4]);
    }
    for _ in 0..600 {
        let c = Vec3::new(rng.gen(), rng.gen(), rng.gen()) * 1e-3 + Vec3::splat(0.5);
        tris.push([c, c + Vec3::X * 1e-5, c + Vec3::Y * 1e-5]);
    }
    tris.push([Vec3::ONE, Vec3::ONE, Vec3::ONE]);
    let scene = scene_of("deep", &tris);
    let mut rays = RayBatch::default();
    for _ in 0..2000 {
        let o = Vec3::new(
            rng.gen_range(-3.0..3.0),
            rng.gen_range(-3.0..3.0),
            rng.gen_range(-3.0..3.0),
        );
        let target = if rng.gen() {
            Vec3::splat(0.5)
        } else {
            Vec3::splat(0.25)
        } + Vec3::new(rng.gen(), rng.gen(), rng.gen()) * 1e-3;
        rays.push(Ray {
            origin: o,
            dir: target - o,
            tmin: 0.0,
            tmax: f32::INFINITY,
        });
    }
    check(&scene, &rays);
    let mut t = KdTracer::new(Default::default()).unwrap();
    t.prepare(&scene).unwrap();
    t.tree().validate(scene.triangles()).unwrap();
    assert!(t.tree().depth >= 10, "depth {}", t.tree().depth);
}

/// A camera inside the Cornell box (walls in the root box's faces and in split planes).
#[test]
fn camera_inside_the_scene() {
    let scene = procedural::cornell();
    let b = scene.bounds();
    let cam = Camera {
        eye: b.center(),
        look: b.center() + Vec3::new(0.3, -0.2, 1.0),
        up: Vec3::Y,
        fov_deg: 100.0,
    };
    check(&scene, &cam.rays(48, 36));
}

/// The walk does less than brute force and its counters add up: on a sphere seen from outside,
/// camera rays test a small share of the triangles, far children are culled, and the per-ray
/// cost sums to the counters.
#[test]
fn counters_and_cost() {
    let scene = procedural::icosphere(20_000);
    let cam = Camera::framing(&scene.bounds(), 45.0, 1.0);
    let rays = cam.rays(64, 64);
    let mut t = KdTracer::new(Default::default()).unwrap();
    t.prepare(&scene).unwrap();
    let mut hits = raysift::HitBatch::new(0);
    let mut cost = raysift::tracer::RayCost::default();
    let s = t
        .intersect(&scene, &rays, &mut hits, Some(&mut cost))
        .unwrap();
    let tri = s.work.get("ray_tri");
    assert!(
        tri > 0 && tri < rays.len() as u64 * 200,
        "{tri} triangle tests"
    );
    assert!(s.work.get("culled") > 0);
    assert_eq!(cost.triangles.iter().map(|&x| x as u64).sum::<u64>(), tri);
    let nodes = s.work.get("nodes") + s.work.get("leaves");
    assert_eq!(cost.nodes.iter().map(|&x| x as u64).sum::<u64>(), nodes);
}

/// Bytes: what the tracer reports is 8 per node plus 4 per reference, and on a 20k-triangle
/// sphere and a 20k random soup it stays within a bound per triangle (figures in BENCHMARKS.md).
#[test]
fn bytes_per_triangle() {
    for scene in [procedural::icosphere(20_000), procedural::soup(20_000, 2)] {
        let mut t = KdTracer::new(Default::default()).unwrap();
        let s = t.prepare(&scene).unwrap();
        let tree = t.tree();
        assert_eq!(t.bytes(), 8 * tree.nodes.len() + 4 * tree.ids.len());
        assert_eq!(s.peak_bytes as usize, t.bytes());
        let per = t.bytes() as f64 / scene.len() as f64;
        assert!(per < 120.0, "{}: {per:.1} bytes per triangle", scene.name);
    }
}

/// Bad options name the tracer and the option.
#[test]
fn bad_options_are_clear_errors() {
    for (k, v) in [
        ("max_depth", "65"),
        ("empty_bonus", "1"),
        ("max_leaf", "0"),
        ("intersection_cost", "-1"),
    ] {
        let e = tracers::create("kdtree", &[(k.into(), v.into())])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("kdtree") && e.contains(k), "{e}");
    }
    let e = tracers::create("kdtree", &[("leaf".into(), "1".into())])
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("max_leaf"), "{e}");
}

/// 4-ray packets (`packets=4`): 2×2 pixel packets of a camera image and runs of four random
/// rays (mixed direction signs: walked ray by ray) equal the single-ray walk, field for field,
/// and the image's packets share their nodes (fewer interior-node visits than single rays).
#[test]
fn four_ray_packets_equal_single_rays_and_share_nodes() {
    let scene = procedural::icosphere(5000);
    let cam = Camera {
        eye: Vec3::new(0.2, 0.3, 3.0),
        look: Vec3::ZERO,
        up: Vec3::Y,
        fov_deg: 40.0,
    };
    let opts = |p: &str| vec![("packets".to_string(), p.to_string())];
    let mut single = tracers::create("kdtree", &opts("1")).unwrap();
    let mut packets = tracers::create("kdtree", &opts("4")).unwrap();
    single.prepare(&scene).unwrap();
    packets.prepare(&scene).unwrap();
    let image = cam.rays(65, 47); // odd sides: short packets at the right and bottom edges
    let random = raysift::rays::generate::random_in_box(&scene.bounds(), 4001, 3);
    for (rays, shared) in [(&image, true), (&random, false)] {
        let (want, s1) = single.intersect_timed(&scene, rays).unwrap();
        let (got, s4) = packets.intersect_timed(&scene, rays).unwrap();
        assert_eq!(raysift::testkit::first_difference(&want, &got), None);
        let (wo, _) = single.occluded_timed(&scene, rays).unwrap();
        let (go, _) = packets.occluded_timed(&scene, rays).unwrap();
        assert_eq!(wo, go);
        let (n1, n4) = (s1.work.get("nodes"), s4.work.get("nodes"));
        if shared {
            assert!(
                n4 * 10 < n1 * 6,
                "packets visit {n4} nodes, single rays {n1}"
            );
        }
    }
    assert!(tracers::create("kdtree", &opts("2")).is_err());
}
