//! The shared BVH on its own: boxes in, tree out; refit keeps the tree and makes it valid again.

use super::*;
use crate::scene::procedural;
use rand::{Rng, SeedableRng};

fn boxes_of(soup: &TriangleSoup) -> Vec<Aabb> {
    (0..soup.len()).map(|i| soup.bounds(i)).collect()
}

#[test]
fn builds_from_any_box_source() {
    let s = procedural::soup(3000, 4);
    let cfg = BuildConfig::default();
    let a = Bvh::build(s.triangles(), &cfg).unwrap();
    let boxes = boxes_of(s.triangles());
    let b = Bvh::build(boxes.as_slice(), &cfg).unwrap();
    assert_eq!(a, b);
    a.validate(boxes.as_slice()).unwrap();
    assert!(Bvh::build(boxes.as_slice(), &BuildConfig { bins: 1, ..cfg }).is_err());
    let empty: &[Aabb] = &[];
    let e = Bvh::build(empty, &BuildConfig::default()).unwrap();
    assert_eq!((e.node_count(), e.refit_clone(empty)), (0, 0));
}

impl Bvh {
    fn refit_clone(&self, prims: &[Aabb]) -> usize {
        self.clone().refit(prims)
    }
}

#[test]
fn refit_of_unmoved_boxes_changes_nothing() {
    let s = procedural::icosphere(5000);
    let bvh = Bvh::build(s.triangles(), &BuildConfig::default()).unwrap();
    let mut r = bvh.clone();
    assert_eq!(r.refit(s.triangles()), bvh.node_count());
    assert_eq!(r, bvh);
}

#[test]
fn refit_after_motion_is_valid_and_tight() {
    let s = procedural::soup(4000, 9);
    let cfg = BuildConfig {
        max_leaf: 2,
        parallel_threshold: 64,
        ..BuildConfig::default()
    };
    let bvh = Bvh::build(s.triangles(), &cfg).unwrap();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
    let moved: Vec<Aabb> = boxes_of(s.triangles())
        .into_iter()
        .map(|b| {
            let d = Vec3::new(rng.gen_range(-2.0..2.0), rng.gen_range(-2.0..2.0), 0.0);
            Aabb::new(b.min + d, b.max + d)
        })
        .collect();
    assert!(
        bvh.validate(moved.as_slice()).is_err(),
        "the motion must break the old boxes"
    );
    let mut r = bvh.clone();
    r.refit(moved.as_slice());
    r.validate(moved.as_slice()).unwrap();
    assert_eq!(
        (r.ids.clone(), r.node_count()),
        (bvh.ids.clone(), bvh.node_count())
    );
    // Tight: every leaf's box is exactly the union of its primitives' boxes.
    for n in r.nodes().filter(|n| n.is_leaf()) {
        let (o, c) = (n.offset as usize, n.count as usize);
        let u = r.ids[o..o + c]
            .iter()
            .fold(Aabb::EMPTY, |b, &i| b.union(moved[i as usize]));
        assert_eq!(n.bounds(), u);
    }
    // The root is the union of everything.
    let all = moved.iter().fold(Aabb::EMPTY, |b, m| b.union(*m));
    assert_eq!(r.root().unwrap().bounds(), all);
    // A refitted tree is worse than a fresh build over scattered boxes.
    let fresh = Bvh::build(moved.as_slice(), &cfg).unwrap();
    assert!(r.sah_cost() > fresh.sah_cost());
}
