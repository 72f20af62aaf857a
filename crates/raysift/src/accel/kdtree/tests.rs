//! The shared kd-tree on its own: builds valid trees (the reference rule traversal relies on),
//! deterministic whether threaded or not, within its limits, at a known size.

use super::*;
use crate::scene::{procedural, Mesh, Scene};
use glam::Vec3;

fn scene_of(tris: &[[Vec3; 3]]) -> Scene {
    let positions = tris.iter().flatten().copied().collect();
    let indices = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    Scene::from_meshes("t", vec![Mesh::new("m", positions, indices)]).unwrap()
}

#[test]
fn builds_valid_trees_and_threads_change_nothing() {
    for s in [procedural::soup(3000, 4), procedural::icosphere(5000), procedural::cornell()] {
        let soup = s.triangles();
        let seq = KdTree::build(soup, &BuildConfig { parallel_threshold: usize::MAX, ..Default::default() }).unwrap();
        let par = KdTree::build(soup, &BuildConfig { parallel_threshold: 16, ..Default::default() }).unwrap();
        seq.validate(soup).unwrap();
        assert_eq!((&seq.nodes, &seq.ids, seq.depth), (&par.nodes, &par.ids, par.depth));
        let shape = seq.shape();
        assert!(shape.interior > 0 && shape.leaves == shape.interior + 1, "{shape:?}");
        assert!(seq.depth <= BuildConfig::default().depth_limit(soup.len()));
    }
}

/// A grid of axis-aligned squares at integer planes: planar events everywhere, splits in the
/// triangles' planes. Every triangle is held once per side it may be hit from, and validate's
/// reference rule holds; breaking the rule (moving a planar triangle's only reference across
/// its plane is what a wrong `side` would do) is caught.
#[test]
fn triangles_in_split_planes_and_the_reference_rule() {
    let mut tris = Vec::new();
    for ax in 0..3 {
        let (u, v) = ((ax + 1) % 3, (ax + 2) % 3);
        for k in 0..=4 {
            for (i, j) in (0..4).flat_map(|i| (0..4).map(move |j| (i, j))) {
                let corner = |di: f32, dj: f32| {
                    let mut p = Vec3::ZERO;
                    p[ax] = k as f32;
                    p[u] = i as f32 + di;
                    p[v] = j as f32 + dj;
                    p
                };
                tris.push([corner(0.0, 0.0), corner(1.0, 0.0), corner(1.0, 1.0)]);
                tris.push([corner(0.0, 0.0), corner(1.0, 1.0), corner(0.0, 1.0)]);
            }
        }
    }
    let s = scene_of(&tris);
    let t = KdTree::build(s.triangles(), &BuildConfig::default()).unwrap();
    t.validate(s.triangles()).unwrap();
    let planar_splits = t
        .nodes
        .iter()
        .filter(|n| !n.is_leaf() && n.split().fract() == 0.0)
        .count();
    assert!(planar_splits > 0, "the case must split in the triangles' planes: {:?}", t.nodes);
    // Corrupt: find an interior node splitting at s and make it split a little below, so a
    // planar triangle at s sent below now reaches above... the rule must reject it.
    let mut bad = t.clone();
    let i = bad.nodes.iter().position(|n| !n.is_leaf() && n.split().fract() == 0.0).unwrap();
    let n = bad.nodes[i];
    bad.nodes[i] = Node::interior(n.axis(), n.split() - 0.25, n.above());
    assert!(bad.validate(s.triangles()).is_err());
}

#[test]
fn degenerate_triangles_are_left_out_and_empty_scenes_build() {
    let p = Vec3::new(1.0, 2.0, 3.0);
    let tris = [
        [Vec3::ZERO, Vec3::X, Vec3::Y],
        [p, p, p],
        [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        [Vec3::Z, Vec3::Z + Vec3::X, Vec3::Z + Vec3::Y],
    ];
    let s = scene_of(&tris);
    let t = KdTree::build(s.triangles(), &BuildConfig::default()).unwrap();
    t.validate(s.triangles()).unwrap();
    let mut held = t.ids.clone();
    held.sort_unstable();
    held.dedup();
    assert_eq!(held, vec![0, 3]);
    let e = KdTree::build(&crate::scene::TriangleSoup::default(), &BuildConfig::default()).unwrap();
    assert_eq!((e.nodes.len(), e.ids.len()), (1, 0));
    e.validate(&crate::scene::TriangleSoup::default()).unwrap();
}

/// Many copies of one triangle cannot be separated: the depth limit (and the SAH) stop the
/// build; a tiny depth limit makes big leaves.
#[test]
fn limits_bound_the_tree() {
    let tris = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 500];
    let s = scene_of(&tris);
    let t = KdTree::build(s.triangles(), &BuildConfig { traversal_cost: 0.0, ..Default::default() }).unwrap();
    t.validate(s.triangles()).unwrap();
    assert!(t.depth <= BuildConfig::default().depth_limit(500));
    let s = procedural::soup(2000, 1);
    let t = KdTree::build(s.triangles(), &BuildConfig { max_depth: 2, ..Default::default() }).unwrap();
    t.validate(s.triangles()).unwrap();
    assert!(t.depth <= 2 && t.shape().leaves <= 4);
    let t = KdTree::build(s.triangles(), &BuildConfig { max_leaf: 255, ..Default::default() }).unwrap();
    assert!(t.nodes[0].is_leaf() || t.shape().leaves < 2000 / 8);
    for bad in [
        BuildConfig { max_leaf: 0, ..Default::default() },
        BuildConfig { max_depth: MAX_DEPTH + 1, ..Default::default() },
        BuildConfig { empty_bonus: 1.0, ..Default::default() },
        BuildConfig { intersection_cost: 0.0, ..Default::default() },
        BuildConfig { traversal_cost: f32::NAN, ..Default::default() },
    ] {
        let e = KdTree::build(s.triangles(), &bad).unwrap_err().to_string();
        assert!(e.contains("kd-tree build"), "{e}");
    }
}

/// Bytes: 8 per node, 4 per reference, nothing else; on a sphere of 20k triangles that is
/// about 80 bytes per triangle with the defaults (figures per scene in BENCHMARKS.md).
#[test]
fn bytes_per_triangle() {
    let s = procedural::icosphere(20_000);
    let t = KdTree::build(s.triangles(), &BuildConfig::default()).unwrap();
    assert_eq!(t.bytes(), 8 * t.nodes.len() + 4 * t.ids.len());
    let per = t.bytes() as f64 / s.len() as f64;
    // Measured 80.6 (7.7 nodes and 5.3 references per triangle, depth 27).
    assert!((8.0..120.0).contains(&per), "{per} bytes per triangle");
    assert_eq!(std::mem::size_of::<Node>(), 8);
}

#[test]
fn the_split_window_brackets_the_distance() {
    for ts in [0.0f32, 1.0, -1.0, 1e30, -1e-30, f32::INFINITY, f32::NEG_INFINITY] {
        let (lo, hi) = KdTree::split_window(ts);
        assert!(lo <= ts && ts <= hi, "{ts}: {lo} {hi}");
    }
    assert_eq!(KdTree::split_window(f32::NAN), (f32::NEG_INFINITY, f32::INFINITY));
    let (lo, hi) = KdTree::split_window(100.0);
    assert!(lo < 100.0 && hi > 100.0);
}
