//! `bvh` against `naive`, bit for bit, on the scenes and rays where BVHs go wrong, plus
//! `validate()` on every tree built.

use super::*;
use crate::geom::Aabb;
use crate::rays::generate::random_in_box;
use crate::rays::{Camera, Ray, RayBatch};
use crate::scene::{procedural, Mesh};
use crate::tracers::naive::Naive;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use std::sync::Arc;

fn tracers(scene: &Scene, cfg: Config) -> (Naive, BvhTracer) {
    let mut naive = Naive::new();
    naive.prepare(scene).unwrap();
    let mut bvh = BvhTracer::new(cfg).unwrap();
    bvh.prepare(scene).unwrap();
    bvh.bvh().validate(scene).unwrap();
    (naive, bvh)
}

/// Closest hits and occlusion of `rays` equal naive's exactly; returns the hit count.
fn assert_same(scene: &Scene, cfg: Config, rays: &RayBatch) -> usize {
    let (naive, bvh) = tracers(scene, cfg);
    let (want, _) = naive.intersect_timed(scene, rays).unwrap();
    let (got, stats) = bvh.intersect_timed(scene, rays).unwrap();
    assert_eq!(stats.rays, rays.len() as u64);
    for i in 0..rays.len() {
        assert_eq!(
            (
                got.t[i].to_bits(),
                got.prim[i],
                got.u[i].to_bits(),
                got.v[i].to_bits()
            ),
            (
                want.t[i].to_bits(),
                want.prim[i],
                want.u[i].to_bits(),
                want.v[i].to_bits()
            ),
            "{}: ray {i} {:?}: bvh t={} prim={} vs naive t={} prim={}",
            scene.name,
            rays.get(i),
            got.t[i],
            got.prim[i],
            want.t[i],
            want.prim[i]
        );
    }
    let (want_o, _) = naive.occluded_timed(scene, rays).unwrap();
    let (got_o, _) = bvh.occluded_timed(scene, rays).unwrap();
    for i in 0..rays.len() {
        assert_eq!(
            got_o[i],
            want_o[i],
            "{}: occlusion of ray {i} {:?}",
            scene.name,
            rays.get(i)
        );
    }
    want.hit_count()
}

/// Small leaves and a low parallel threshold so the tests exercise deep trees and the parallel
/// build path even on small scenes; one ray at a time (the octant-specialised walk).
fn small_cfg() -> Config {
    Config {
        max_leaf: 2,
        parallel_threshold: 64,
        lanes: 1,
        ..Config::default()
    }
}

fn cfgs() -> [Config; 4] {
    [
        Config::default(),
        Config {
            lanes: 8,
            ..Config::default()
        },
        small_cfg(),
        Config {
            bins: 2,
            max_leaf: 1,
            parallel_threshold: 8,
            lanes: 3,
            ..Config::default()
        },
    ]
}

fn camera_rays(scene: &Scene, w: u32) -> RayBatch {
    Camera::framing(&scene.bounds(), 45.0, 1.0).rays(w, w)
}

/// Rays along ±x, ±y, ±z (with ±0 in the other components) through a grid over the scene,
/// starting outside and inside, some on the bounding box faces.
fn axis_rays(b: Aabb) -> RayBatch {
    let mut out = RayBatch::default();
    let ext = b.extent();
    for a in 0..3 {
        for sign in [1.0f32, -1.0] {
            for zero in [0.0f32, -0.0] {
                let mut d = Vec3::splat(zero);
                d[a] = sign;
                for i in 0..=8 {
                    for j in 0..=8 {
                        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
                        let mut o = b.center();
                        o[u] = b.min[u] + ext[u] * i as f32 / 8.0;
                        o[v] = b.min[v] + ext[v] * j as f32 / 8.0;
                        // From outside, from the middle, and from exactly the box face.
                        let outside = if sign > 0.0 {
                            b.min[a] - 0.5 * ext[a] - 1.0
                        } else {
                            b.max[a] + 0.5 * ext[a] + 1.0
                        };
                        let face = if sign > 0.0 { b.min[a] } else { b.max[a] };
                        for start in [outside, b.center()[a], face] {
                            let mut oo = o;
                            oo[a] = start;
                            out.push(Ray {
                                origin: oo,
                                dir: d,
                                tmin: 0.0,
                                tmax: f32::INFINITY,
                            });
                        }
                    }
                }
            }
        }
    }
    out
}

/// Camera rays whose `tmax` (or `tmin`) is set exactly to naive's hit distance, and a few
/// just before/after it: the inclusive clip ends must give the same answers.
fn clipped_rays(scene: &Scene, base: &RayBatch) -> RayBatch {
    let mut naive = Naive::new();
    naive.prepare(scene).unwrap();
    let (h, _) = naive.intersect_timed(scene, base).unwrap();
    let mut out = RayBatch::default();
    for i in 0..base.len() {
        let r = base.get(i);
        if !h.is_hit(i) {
            out.push(Ray { tmax: 1.0, ..r });
            continue;
        }
        let t = h.t[i];
        let (below, above) = (t.next_down(), t.next_up());
        for (tmin, tmax) in [
            (0.0, t),
            (t, t),
            (t, f32::INFINITY),
            (0.0, below),
            (above, f32::INFINITY),
            (0.5 * t, 1.5 * t),
        ] {
            out.push(Ray { tmin, tmax, ..r });
        }
    }
    out
}

#[test]
fn random_soup_camera_and_random_rays() {
    for (n, seed) in [(1, 1), (2, 2), (7, 3), (100, 4), (3000, 5)] {
        let scene = Arc::new(procedural::soup(n, seed));
        let b = scene.bounds();
        for cfg in cfgs() {
            assert_same(&scene, cfg.clone(), &camera_rays(&scene, 48));
            // Random rays from a box a bit larger than the scene: some start inside, some outside.
            let big = Aabb::new(b.min - b.extent() * 0.2, b.max + b.extent() * 0.2);
            let hits = assert_same(&scene, cfg, &random_in_box(&big, 4000, seed));
            assert!(n < 100 || hits > 100, "{n}: {hits}");
        }
    }
}

#[test]
fn icosphere_from_outside_and_inside() {
    let scene = Arc::new(procedural::icosphere(5000));
    for cfg in cfgs() {
        let hits = assert_same(&scene, cfg.clone(), &camera_rays(&scene, 64));
        assert!(hits > 1000, "{hits}");
        // Rays from inside the sphere hit it all.
        let inside = Aabb::new(Vec3::splat(-0.5), Vec3::splat(0.5));
        let hits = assert_same(&scene, cfg.clone(), &random_in_box(&inside, 3000, 9));
        assert!(hits > 2990, "{hits}");
        assert_same(&scene, cfg, &axis_rays(scene.bounds()));
    }
}

#[test]
fn cornell_box_axis_aligned_walls() {
    let scene = Arc::new(procedural::cornell());
    for cfg in cfgs() {
        let cam = camera_rays(&scene, 64);
        assert!(assert_same(&scene, cfg.clone(), &cam) > 2000);
        assert_same(&scene, cfg.clone(), &axis_rays(scene.bounds()));
        let inside = scene.bounds();
        assert_same(&scene, cfg.clone(), &random_in_box(&inside, 4000, 3));
        assert_same(&scene, cfg, &clipped_rays(&scene, &cam));
    }
}

#[test]
fn clipped_intervals_on_soup_and_sphere() {
    for scene in [procedural::soup(2000, 11), procedural::icosphere(2000)] {
        let scene = Arc::new(scene);
        let cam = camera_rays(&scene, 40);
        let rnd = random_in_box(&scene.bounds(), 1000, 12);
        for cfg in cfgs() {
            assert_same(&scene, cfg.clone(), &clipped_rays(&scene, &cam));
            assert_same(&scene, cfg, &clipped_rays(&scene, &rnd));
        }
    }
}

#[test]
fn empty_batch_and_empty_scene() {
    let scene = Arc::new(procedural::soup(50, 1));
    let (_, bvh) = tracers(&scene, Config::default());
    let (h, s) = bvh.intersect_timed(&scene, &RayBatch::default()).unwrap();
    assert!(h.is_empty());
    assert_eq!(s.rays, 0);
    let (o, _) = bvh.occluded_timed(&scene, &RayBatch::default()).unwrap();
    assert!(o.is_empty());

    let empty = Arc::new(Scene::from_meshes("empty", vec![]).unwrap());
    let rays = random_in_box(&Aabb::new(Vec3::splat(-1.0), Vec3::ONE), 100, 1);
    assert_eq!(assert_same(&empty, Config::default(), &rays), 0);
    let (_, bvh) = tracers(&empty, Config::default());
    assert!(bvh.bvh().pairs.is_empty());

    // Before any prepare, and after the scene changed: an error, not an answer.
    let fresh = BvhTracer::new(Config::default()).unwrap();
    let e = fresh
        .intersect_timed(&scene, &rays)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not prepared"), "{e}");
    let (_, bvh) = tracers(&scene, Config::default());
    let mut moved = (*scene).clone();
    let e = bvh.occluded_timed(&moved, &rays).unwrap_err().to_string();
    assert!(e.contains("another scene"), "{e}");
    let mut bvh = bvh;
    bvh.prepare(&moved).unwrap();
    moved
        .set_transform(0, glam::Affine3A::from_translation(Vec3::X))
        .unwrap();
    let e = bvh.intersect_timed(&moved, &rays).unwrap_err().to_string();
    assert!(e.contains("changed since prepare"), "{e}");
}

/// `copies` copies of the same triangles (same or permuted corners): the tie rule must pick the
/// smallest id at equal `t`, even when copies land in different leaves.
#[test]
fn coincident_triangles_tie_to_the_smallest_id() {
    let base = procedural::icosphere(80);
    let soup = base.triangles();
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for copy in 0..6u32 {
        for t in 0..soup.len() {
            let [a, b, c] = soup.get(t);
            let k = pos.len() as u32;
            // Odd copies rotate the corners: same plane, maybe different rounding.
            if copy % 2 == 0 {
                pos.extend([a, b, c]);
            } else {
                pos.extend([b, c, a]);
            }
            idx.push([k, k + 1, k + 2]);
        }
    }
    let mut meshes = vec![Mesh::new("copies", pos, idx)];
    meshes.push(procedural::cornell().meshes()[0].clone());
    let scene = Arc::new(Scene::from_meshes("coincident", meshes).unwrap());
    for cfg in cfgs() {
        let cam = camera_rays(&scene, 48);
        assert!(assert_same(&scene, cfg.clone(), &cam) > 500);
        assert_same(
            &scene,
            cfg.clone(),
            &random_in_box(&scene.bounds(), 2000, 5),
        );
        assert_same(&scene, cfg, &clipped_rays(&scene, &cam));
    }
}

/// Every triangle with the same centroid (rotated copies of one triangle around its centre), and
/// many identical triangles: the build must terminate with bounded depth.
#[test]
fn identical_centroids_terminate() {
    let n = 5000;
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for i in 0..n {
        let a = i as f32 * 0.001;
        let (s, c) = a.sin_cos();
        let k = pos.len() as u32;
        // Corners at 120° around the origin, rotated by `a` about z: centroid exactly 0? Close
        // to it; the identical copies below have exactly equal centroids.
        for j in 0..3 {
            let b = j as f32 * std::f32::consts::TAU / 3.0;
            pos.push(Vec3::new((a + b).cos(), (a + b).sin(), 0.1 * s * c));
        }
        idx.push([k, k + 1, k + 2]);
    }
    let rotated = Scene::from_meshes("rotated", vec![Mesh::new("r", pos, idx)]).unwrap();
    let same: Vec<[u32; 3]> = vec![[0, 1, 2]; n];
    let identical = Scene::from_meshes(
        "identical",
        vec![Mesh::new(
            "i",
            vec![Vec3::ZERO, Vec3::X, Vec3::new(0.3, 1.0, 0.2)],
            same,
        )],
    )
    .unwrap();
    for scene in [rotated, identical] {
        let scene = Arc::new(scene);
        for cfg in cfgs() {
            let (_, bvh) = tracers(&scene, cfg.clone());
            assert!(bvh.bvh().depth() < MAX_DEPTH);
            let rays = random_in_box(&scene.bounds(), 2000, 2);
            assert_same(&scene, cfg.clone(), &rays);
            assert_same(&scene, cfg, &camera_rays(&scene, 32));
        }
    }
}

/// Degenerate triangles (collapsed to points by the scene) mixed with real ones, including a
/// scene of points only.
#[test]
fn degenerate_triangles() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for i in 0..2000u32 {
        let c = Vec3::new(rng.gen(), rng.gen(), rng.gen());
        let k = pos.len() as u32;
        match i % 3 {
            0 => pos.extend([c, c, c]),
            1 => pos.extend([c, c + Vec3::X * 0.1, c + Vec3::X * 0.2]),
            _ => pos.extend([c, c + Vec3::X * 0.05, c + Vec3::Y * 0.05]),
        }
        idx.push([k, k + 1, k + 2]);
    }
    let points = Scene::from_meshes(
        "points",
        vec![Mesh::new(
            "p",
            pos[..30].to_vec(),
            vec![[0, 1, 2], [3, 4, 5], [6, 7, 8]],
        )],
    )
    .unwrap();
    let mixed = Scene::from_meshes("mixed", vec![Mesh::new("m", pos, idx)]).unwrap();
    assert!(mixed.degenerate_count() > 1000);
    for scene in [mixed, points] {
        let scene = Arc::new(scene);
        for cfg in cfgs() {
            assert_same(
                &scene,
                cfg.clone(),
                &random_in_box(&scene.bounds(), 3000, 4),
            );
            assert_same(&scene, cfg, &camera_rays(&scene, 32));
        }
    }
}

/// A deep, badly balanced tree (triangles at exponentially shrinking scales) stays within the
/// stack, and the median fallback below `MAX_SAH_DEPTH` keeps answers exact.
#[test]
fn nested_scales_stay_within_depth() {
    let mut pos = Vec::new();
    let mut idx = Vec::new();
    for i in 0..120 {
        let s = 0.7f32.powi(i);
        let k = pos.len() as u32;
        pos.extend([
            Vec3::new(s, 0.0, 0.0),
            Vec3::new(0.0, s, 0.0),
            Vec3::new(0.0, 0.0, s),
        ]);
        idx.push([k, k + 1, k + 2]);
    }
    let scene = Arc::new(Scene::from_meshes("nested", vec![Mesh::new("n", pos, idx)]).unwrap());
    let cfg = Config {
        max_leaf: 1,
        traversal_cost: 0.0,
        ..Config::default()
    };
    let (_, bvh) = tracers(&scene, cfg.clone());
    assert!(bvh.bvh().depth() < MAX_DEPTH, "{}", bvh.bvh().depth());
    let mut rays = RayBatch::default();
    for i in 0..120 {
        let s = 0.7f32.powi(i) / 3.0;
        rays.push(Ray {
            origin: Vec3::splat(-1.0),
            dir: Vec3::splat(s + 1.0),
            tmin: 0.0,
            tmax: f32::INFINITY,
        });
    }
    assert_same(&scene, cfg, &rays);
}

#[test]
fn one_triangle_and_stats() {
    let scene = Arc::new(
        Scene::from_meshes(
            "one",
            vec![Mesh::new(
                "t",
                vec![Vec3::ZERO, Vec3::X, Vec3::Y],
                vec![[0, 1, 2]],
            )],
        )
        .unwrap(),
    );
    let (_, bvh) = tracers(&scene, Config::default());
    assert_eq!(bvh.bvh().node_count(), 1);
    assert_eq!(bvh.bytes(), 64 + 4 + 36);
    let rays = RayBatch::from_rays([
        Ray {
            origin: Vec3::new(0.2, 0.2, 1.0),
            dir: -Vec3::Z,
            tmin: 0.0,
            tmax: f32::INFINITY,
        },
        Ray {
            origin: Vec3::new(2.0, 2.0, 1.0),
            dir: -Vec3::Z,
            tmin: 0.0,
            tmax: f32::INFINITY,
        },
    ]);
    let (h, s) = bvh.intersect_timed(&scene, &rays).unwrap();
    assert_eq!(h.prim, vec![0, crate::rays::MISS]);
    assert_eq!(
        (
            s.rays,
            s.work.get("ray_box"),
            s.work.get("ray_tri"),
            s.work.get("leaves"),
            s.work.get("nodes")
        ),
        (2, 2, 1, 1, 0)
    );
    assert_same(&scene, Config::default(), &rays);
}

#[test]
fn build_is_sane_and_counts_work() {
    let scene = Arc::new(procedural::soup(20_000, 3));
    let (_, bvh) = tracers(&scene, Config::default());
    let t = bvh.bvh();
    assert!(t.node_count() < 2 * scene.len());
    assert!(t.depth() < 40, "{}", t.depth());
    // A BVH visits a tiny fraction of what brute force does.
    let rays = camera_rays(&scene, 64);
    let (_, s) = bvh.intersect_timed(&scene, &rays).unwrap();
    let w = &s.work;
    assert!(w.get("ray_tri") < rays.len() as u64 * 60, "{s:?}");
    assert!(w.get("nodes") > 0 && w.get("leaves") > 0 && w.get("ray_box") > w.get("nodes"));
    // The parallel and the sequential build give the same tree.
    let seq = Bvh::build(
        scene.triangles(),
        &Config {
            parallel_threshold: usize::MAX,
            ..Config::default()
        }
        .build_config(),
    )
    .unwrap();
    assert_eq!(seq.pairs, t.pairs);
    assert_eq!(seq.ids, t.ids);
}

#[test]
fn config_from_options() {
    let opts = crate::tracers::parse_opts(&["bins=8".into(), "max_leaf=2".into()]).unwrap();
    let t = crate::tracers::create("bvh", &opts).unwrap();
    assert_eq!(t.name(), "bvh");
    assert!(crate::tracers::create("bvh", &[("nope".into(), "1".into())]).is_err());
    assert!(crate::tracers::create("bvh", &[("bins".into(), "1".into())]).is_err());
    assert!(crate::tracers::create("bvh", &[("max_leaf".into(), "0".into())]).is_err());
}

/// `validate()` must be able to fail: corrupt a good tree in each invariant it checks.
#[test]
fn validate_catches_corruption() {
    let scene = Arc::new(procedural::soup(500, 8));
    let (_, t) = tracers(&scene, small_cfg());
    let good = t.bvh().clone();
    good.validate(&scene).unwrap();
    let leaf_pair = (1..good.pairs.len())
        .find(|&p| good.pairs[p].count[0] != 0)
        .unwrap();

    let mut b = good.clone();
    b.tree.pairs[leaf_pair].boxes.x[2] -= 1e-3; // leaf box no longer contains its triangles
    assert!(b.validate(&scene).is_err());

    let mut b = good.clone();
    b.tree.ids.swap(0, 1); // copies no longer match ids
    assert!(b.validate(&scene).is_err());

    let mut b = good.clone();
    b.tree.ids[1] = b.ids[0];
    b.tris[1] = b.tris[0]; // a triangle twice, another lost
    assert!(b.validate(&scene).is_err());

    let mut b = good.clone();
    b.tree.pairs[leaf_pair].count[0] += 1; // leaf ranges overlap
    assert!(b.validate(&scene).is_err());

    let mut b = good.clone();
    b.tree.pairs[0].offset[0] = good.pairs.len() as u32; // child pair out of range
    assert!(b.validate(&scene).is_err());

    let mut b = good.clone();
    b.tree.pairs[0].boxes.y[0] += 0.5; // root does not contain its children
    assert!(b.validate(&scene).is_err());
}

#[test]
fn automatic_lanes_follow_the_tree_size() {
    let small = Arc::new(procedural::icosphere(2000));
    let (_, t) = tracers(&small, Config::default());
    assert!(t.bvh().bytes() <= AUTO_LANES_BYTES);
    assert_eq!(t.lanes(), 1);
    // About 80 B per triangle: 100k triangles is well above 4 MiB.
    let big = Arc::new(procedural::soup(100_000, 3));
    let (naive, t) = tracers(&big, Config::default());
    assert!(t.bvh().bytes() > AUTO_LANES_BYTES);
    assert_eq!(t.lanes(), 8);
    let rays = random_in_box(&big.bounds(), 2000, 5);
    let (want, _) = naive.intersect_timed(&big, &rays).unwrap();
    let (got, _) = t.intersect_timed(&big, &rays).unwrap();
    assert_eq!(want.t, got.t);
    assert_eq!(want.prim, got.prim);
    let (_, t) = tracers(
        &small,
        Config {
            lanes: 5,
            ..Config::default()
        },
    );
    assert_eq!(t.lanes(), 5);
    assert!(Config {
        lanes: 17,
        ..Config::default()
    }
    .check()
    .is_err());
}
