//! Cone tracing conformance: every traversal × box test × n ∈ {1, 4, 16, ∞} equals the
//! brute-force oracle (same ids, same order, same `t` bits) on generated scenes (proptest), on
//! hard cases and on a real mesh, including the "next n" continuation.

use glam::Vec3;
use proptest::prelude::*;
use raysift::rays::Camera;
use raysift::scene::{procedural, Mesh, Scene};
use raysift::testkit::shared_scenes;
use raysift::tracers::cone::{
    bvh::ConeBvh, create, kdtree::ConeKd, BoxTest, Cone, ConeBatch, ConeHits, ConeTracer, Query,
    Structure, Traversal,
};

fn variants() -> Vec<Box<dyn ConeTracer>> {
    let mut v = Vec::new();
    for t in [Traversal::Stack, Traversal::Sorted] {
        for b in [BoxTest::Basic, BoxTest::Improved] {
            v.push(create(Structure::Bvh, t, b));
        }
    }
    // Small leaves: deeper trees, more culling decisions.
    let small = raysift::accel::bvh::BuildConfig {
        max_leaf: 1,
        ..Default::default()
    };
    v.push(Box::new(ConeBvh::with_build(
        Traversal::Sorted,
        BoxTest::Improved,
        small.clone(),
    )));
    // The SBVH: the paper's build with spatial splits, and planes tried everywhere with leaves
    // of one (most cut references).
    for b in [BoxTest::Basic, BoxTest::Improved] {
        v.push(create(Structure::Sbvh, Traversal::Stack, b));
    }
    v.push(Box::new(ConeBvh::with_spatial(
        Traversal::Sorted,
        BoxTest::Improved,
        small,
        raysift::accel::bvh::SpatialConfig {
            alpha: 0.0,
            max_growth: 4.0,
        },
    )));
    // The kd-tree: the paper's (pbrt-v3) build with both orders, and our default build with
    // larger leaves (fewer, shallower splits).
    for t in [Traversal::Stack, Traversal::Sorted] {
        v.push(create(Structure::Kdtree, t, BoxTest::Improved));
    }
    let coarse = raysift::accel::kdtree::BuildConfig {
        max_leaf: 6,
        ..Default::default()
    };
    v.push(Box::new(ConeKd::with_build(Traversal::Stack, coarse)));
    v
}

fn trace(t: &mut dyn ConeTracer, scene: &Scene, cones: &ConeBatch, q: Query) -> ConeHits {
    t.prepare(scene).unwrap();
    let mut out = ConeHits::default();
    t.trace(scene, cones, &q, &mut out).unwrap();
    out
}

/// First difference between two answers, bit for bit.
fn diff(want: &ConeHits, got: &ConeHits) -> Option<String> {
    if want.len() != got.len() {
        return Some(format!("{} cones vs {}", want.len(), got.len()));
    }
    for i in 0..want.len() {
        let (wp, wt) = want.cone(i);
        let (gp, gt) = got.cone(i);
        let wb: Vec<u32> = wt.iter().map(|t| t.to_bits()).collect();
        let gb: Vec<u32> = gt.iter().map(|t| t.to_bits()).collect();
        if wp != gp || wb != gb {
            return Some(format!("cone {i}: want {wp:?} {wt:?}, got {gp:?} {gt:?}"));
        }
    }
    None
}

/// Every variant equals the oracle for n ∈ {1, 4, 16, ∞}; the answers are sorted and free of
/// duplicates; n = 4 continued once equals the oracle's first 8. Returns the oracle's total of
/// reported triangles for n = ∞ (so callers can check the case is not empty).
fn check(scene: &Scene, cones: &ConeBatch) -> usize {
    let mut oracle = create(Structure::Oracle, Traversal::Stack, BoxTest::Basic);
    let mut vs = variants();
    let mut total = 0;
    for q in [
        Query::nearest(1),
        Query::nearest(4),
        Query::nearest(16),
        Query::all(),
    ] {
        let want = trace(oracle.as_mut(), scene, cones, q);
        for i in 0..want.len() {
            let (p, t) = want.cone(i);
            for k in 1..p.len() {
                assert!(
                    (t[k - 1], p[k - 1]) < (t[k], p[k]),
                    "oracle cone {i} not sorted/unique"
                );
            }
            if let Some(n) = q.n {
                assert!(p.len() <= n);
            }
        }
        if q.n.is_none() {
            total = want.prim.len();
        }
        for v in vs.iter_mut() {
            let got = trace(v.as_mut(), scene, cones, q);
            if let Some(d) = diff(&want, &got) {
                panic!("{} {q:?} on {}: {d}", v.name(), scene.name);
            }
        }
    }
    // "The next n": 4, then the next 4, equal the first 8 of the full answer.
    let all = trace(oracle.as_mut(), scene, cones, Query::all());
    for v in vs.iter_mut() {
        let first = trace(v.as_mut(), scene, cones, Query::nearest(4));
        let (next_cones, which) = first.continuation(cones, 4);
        let next = trace(v.as_mut(), scene, &next_cones, Query::nearest(4));
        for (k, &i) in which.iter().enumerate() {
            let (p1, t1) = first.cone(i);
            let (p2, t2) = next.cone(k);
            let (pa, ta) = all.cone(i);
            let m = (8).min(pa.len());
            let joined: Vec<(u32, u32)> = p1
                .iter()
                .chain(p2)
                .zip(t1.iter().chain(t2))
                .map(|(&p, t)| (p, t.to_bits()))
                .collect();
            let want: Vec<(u32, u32)> = pa[..m]
                .iter()
                .zip(&ta[..m])
                .map(|(&p, t)| (p, t.to_bits()))
                .collect();
            assert_eq!(joined, want, "{}: continuation of cone {i}", v.name());
        }
    }
    total
}

fn camera_cones(scene: &Scene, w: u32, deg: f32) -> ConeBatch {
    let cam = Camera::framing(&scene.bounds(), 45.0, 1.0);
    ConeBatch::from_camera(&cam, w, w, deg.to_radians()).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Random soups seen through camera cones of random apertures.
    #[test]
    fn soups_through_camera_cones(n in 1usize..300, seed in 0u64..1000, deg in 0.05f32..8.0) {
        let scene = procedural::soup(n, seed);
        check(&scene, &camera_cones(&scene, 12, deg));
    }

    /// Random cones from anywhere (inside the scene too), any direction, wide and narrow.
    #[test]
    fn soups_with_random_cones(n in 1usize..200, seed in 0u64..1000, cones in prop::collection::vec(
        ((-2.0f32..2.0, -2.0f32..2.0, -2.0f32..2.0), (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0), 0.01f32..1.5), 1..40)) {
        let scene = procedural::soup(n, seed);
        let mut b = ConeBatch::default();
        for ((ox, oy, oz), (dx, dy, dz), a) in cones {
            let d = Vec3::new(dx, dy, dz);
            if d.length() > 0.05 {
                b.push(Cone::new(Vec3::new(ox, oy, oz), d, a)).unwrap();
            }
        }
        check(&scene, &b);
    }
}

fn grid_scene(k: usize, dup: usize) -> Scene {
    // A coplanar grid of axis-aligned quads (flat boxes, shared edges) at z = 0, each triangle
    // repeated `dup` times (exact ties in t, broken by id).
    let (mut pos, mut idx) = (vec![], vec![]);
    for i in 0..k {
        for j in 0..k {
            let b = pos.len() as u32;
            let (x, y) = (i as f32, j as f32);
            pos.extend([
                Vec3::new(x, y, 0.0),
                Vec3::new(x + 1.0, y, 0.0),
                Vec3::new(x, y + 1.0, 0.0),
                Vec3::new(x + 1.0, y + 1.0, 0.0),
            ]);
            for _ in 0..dup {
                idx.push([b, b + 1, b + 2]);
                idx.push([b + 1, b + 3, b + 2]);
            }
        }
    }
    Scene::from_meshes("grid", vec![Mesh::new("grid", pos, idx)]).unwrap()
}

#[test]
fn hard_cases_coplanar_ties_axis_aligned_apex_on_surface() {
    let scene = grid_scene(8, 2);
    let mut b = ConeBatch::default();
    let c = Vec3::new(4.0, 4.0, 0.0);
    for (apex, axis, a) in [
        (c + Vec3::Z * 5.0, -Vec3::Z, 0.3), // straight down onto shared vertices
        (c + Vec3::Z * 5.0, -Vec3::Z, 0.0007), // a pixel-sized cone
        (c, Vec3::Z, 0.5),                  // apex on the surface, looking away
        (c, Vec3::new(1.0, 0.0, 0.2), 0.4), // apex on the surface, grazing
        (Vec3::new(-3.0, 4.0, 0.0), Vec3::X, 0.2), // in the plane, along it
        (Vec3::new(-3.0, 4.5, 1.0), Vec3::new(1.0, 0.0, -0.3), 1.3), // wide
        (c + Vec3::Z * 2.0, Vec3::new(0.3, 0.2, -1.0), 1.5), // nearly a half-space
    ] {
        b.push(Cone::new(apex, axis, a)).unwrap();
    }
    assert!(check(&scene, &b) > 100);
}

#[test]
fn sphere_from_inside_and_outside() {
    let scene = procedural::icosphere(2000);
    let mut b = camera_cones(&scene, 8, 1.5);
    for i in 0..20 {
        let d = Vec3::new((i as f32).sin(), (i as f32 * 0.7).cos(), 0.3);
        b.push(Cone::new(Vec3::ZERO, d, 0.05 + i as f32 * 0.05))
            .unwrap();
    }
    assert!(check(&scene, &b) > 100);
}

#[test]
fn real_mesh() {
    let Some(dir) = shared_scenes("cone conformance on the bunny") else {
        return;
    };
    let scene = procedural::open(dir.join("bun_zipper_res4.ply").to_str().unwrap()).unwrap();
    for deg in [0.04, 0.5, 2.5] {
        let total = check(&scene, &camera_cones(&scene, 24, deg));
        assert!(total > 100, "{deg}°: {total}");
    }
}

/// The culling pays and the counting mode counts: n = 1 enters far fewer nodes than the
/// complete traversal of the counting mode, which tests no triangle and reports none; the
/// sorted traversal enters no more nodes than the stack for n = 1.
#[test]
fn early_out_and_counting_mode() {
    let scene = procedural::icosphere(5000);
    let cones = camera_cones(&scene, 16, 0.5);
    let mut s = create(Structure::Bvh, Traversal::Stack, BoxTest::Improved);
    let mut o = create(Structure::Bvh, Traversal::Sorted, BoxTest::Improved);
    s.prepare(&scene).unwrap();
    o.prepare(&scene).unwrap();
    let mut out = ConeHits::default();
    let count = s.trace(&scene, &cones, &Query::count(), &mut out).unwrap();
    assert!(out.prim.is_empty() && out.len() == cones.len());
    assert_eq!(count.work.get("cone_tri"), 0);
    let one = s
        .trace(&scene, &cones, &Query::nearest(1), &mut out)
        .unwrap();
    let sorted = o
        .trace(&scene, &cones, &Query::nearest(1), &mut out)
        .unwrap();
    let (nc, n1, ns) = (
        count.work.get("nodes"),
        one.work.get("nodes"),
        sorted.work.get("nodes"),
    );
    assert!(
        n1 * 2 < nc,
        "n = 1 entered {n1} nodes, the full traversal {nc}"
    );
    assert!(ns <= n1, "sorted {ns} > stack {n1}");
    assert!(count.work.get("tri_encounters") > one.work.get("tri_encounters"));
}

/// The same for the kd-tree walk, whose culls are per split plane (Eq. 2).
#[test]
fn kdtree_early_out_and_counting_mode() {
    let scene = procedural::icosphere(5000);
    let cones = camera_cones(&scene, 16, 0.5);
    let mut s = create(Structure::Kdtree, Traversal::Stack, BoxTest::Improved);
    let mut o = create(Structure::Kdtree, Traversal::Sorted, BoxTest::Improved);
    s.prepare(&scene).unwrap();
    o.prepare(&scene).unwrap();
    let mut out = ConeHits::default();
    let count = s.trace(&scene, &cones, &Query::count(), &mut out).unwrap();
    assert!(out.prim.is_empty());
    let one = s
        .trace(&scene, &cones, &Query::nearest(1), &mut out)
        .unwrap();
    let sorted = o
        .trace(&scene, &cones, &Query::nearest(1), &mut out)
        .unwrap();
    let (nc, n1, ns) = (
        count.work.get("nodes"),
        one.work.get("nodes"),
        sorted.work.get("nodes"),
    );
    assert!(n1 * 2 < nc, "n = 1 entered {n1} nodes, the full walk {nc}");
    assert!(ns <= n1, "sorted {ns} > stack {n1}");
    // One plane test per interior node entered, one box test (the root's) per cone that meets
    // the scene at most.
    assert!(count.work.get("plane_tests") < nc && count.work.get("plane_tests") > nc / 3);
    assert!(count.work.get("box_tests") <= cones.len() as u64);
    // The per-cone costs (heatmaps) add up to the counters.
    s.trace(&scene, &cones, &Query::count(), &mut out).unwrap();
    let sum: u64 = out.cost.iter().map(|&c| c as u64).sum();
    assert_eq!(sum, nc + count.work.get("tri_encounters"));
}

#[test]
fn stale_scene_and_bad_cones_are_errors() {
    let mut scene = procedural::icosphere(100);
    let mut t = create(Structure::Bvh, Traversal::Stack, BoxTest::Basic);
    t.prepare(&scene).unwrap();
    scene.touch();
    let mut out = ConeHits::default();
    let cones = camera_cones(&scene, 2, 1.0);
    assert!(t.trace(&scene, &cones, &Query::all(), &mut out).is_err());
    let mut b = ConeBatch::default();
    for (axis, a) in [
        (Vec3::ZERO, 0.1),
        (Vec3::Z, 0.0),
        (Vec3::Z, 1.6),
        (Vec3::Z, f32::NAN),
        (Vec3::new(f32::NAN, 0.0, 1.0), 0.1),
    ] {
        let e = b
            .push(Cone::new(Vec3::ZERO, axis, a))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("cone 0:"), "{e}");
    }
    let mut c = Cone::new(Vec3::ZERO, Vec3::Z, 0.1);
    c.t_near = -1.0;
    assert!(b.push(c).is_err());
    assert!(b.is_empty());
}

/// Bytes: the tree is the shared BVH's (64 bytes per node pair + 4 per triangle id); a cone
/// costs 40 bytes in a batch; an answer 8 bytes per reported triangle plus 12 per cone (its
/// start and its cost).
#[test]
fn memory() {
    let scene = procedural::icosphere(20000);
    let mut t = ConeBvh::new(Traversal::Stack, BoxTest::Improved);
    t.prepare(&scene).unwrap();
    let bvh = t.bvh();
    assert_eq!(
        t.bytes(),
        bvh.pairs.capacity() * 64 + bvh.ids.capacity() * 4
    );
    let per_tri = t.bytes() as f64 / scene.len() as f64;
    assert!(per_tri < 48.0, "{per_tri} bytes per triangle");
    let cones = camera_cones(&scene, 10, 0.5);
    assert_eq!(cones.bytes(), 100 * 40);
    let mut out = ConeHits::default();
    t.trace(&scene, &cones, &Query::nearest(4), &mut out)
        .unwrap();
    assert!(
        out.bytes() <= out.prim.capacity() * 8 + out.start.capacity() * 8 + out.cost.capacity() * 4
    );
    assert_eq!(out.cost.len(), cones.len());
    // The kd-tree: 8 bytes per node and 4 per triangle reference.
    let mut k = ConeKd::new(Traversal::Stack);
    k.prepare(&scene).unwrap();
    let tree = k.tree();
    assert_eq!(
        k.bytes(),
        tree.nodes.capacity() * 8 + tree.ids.capacity() * 4
    );
    assert!(tree.validate(scene.triangles()).is_ok());
}
