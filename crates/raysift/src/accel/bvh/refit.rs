//! Refit: the same tree over moved primitives. Leaf boxes are recomputed from their primitives'
//! boxes (in parallel), then interior boxes bottom-up as the union of their children's: a pair
//! is only referenced by a node of an earlier pair (depth-first order of parents), so one pass
//! over the pairs from last to first sees every child before its parent. The boxes are exact
//! (unions of the primitives' own boxes), so traversal stays as conservative as after a build;
//! only the tree's quality (SAH cost) degrades as primitives drift from where they were built.
//! A tree with split references (spatial splits) gets its leaves' whole primitive boxes back:
//! valid, and looser than the cut parts were.

use super::{BoxSource, Bvh};
use crate::geom::Aabb;
use rayon::prelude::*;

/// Refits `bvh` to `prims` (same count and ids as at build time); returns the nodes refitted.
pub(super) fn refit(bvh: &mut Bvh, prims: &(impl BoxSource + ?Sized)) -> usize {
    assert_eq!(
        bvh.prims,
        prims.len(),
        "refit needs the primitives the tree was built over"
    );
    if bvh.pairs.is_empty() {
        return 0;
    }
    let ids = &bvh.ids;
    // Pair 0 holds only the root (slot 1 unused).
    let slots = |p: usize| if p == 0 { 1 } else { 2 };
    bvh.pairs.par_iter_mut().enumerate().for_each(|(p, pair)| {
        for i in 0..slots(p) {
            if pair.count[i] != 0 {
                let first = pair.offset[i] as usize;
                let b = ids[first..first + pair.count[i] as usize]
                    .iter()
                    .fold(Aabb::EMPTY, |b, &id| b.union(prims.bounds(id as usize)));
                pair.boxes.set(i, b.min, b.max);
            }
        }
    });
    for p in (0..bvh.pairs.len()).rev() {
        for i in 0..slots(p) {
            let pair = bvh.pairs[p];
            if pair.count[i] == 0 {
                let c = pair.offset[i] as usize;
                debug_assert!(c > p, "children pair {c} before its parent's pair {p}");
                let (a, b) = (bvh.pairs[c].boxes.get(0), bvh.pairs[c].boxes.get(1));
                let u = Aabb::new(a.0, a.1).union(Aabb::new(b.0, b.1));
                bvh.pairs[p].boxes.set(i, u.min, u.max);
            }
        }
    }
    bvh.node_count()
}
