//! The upper levels of the box splits shared above the bundles (`space.rs`), made by the first
//! call that shares splits after a `prepare` and kept for the next calls (`top_leaf`).
//!
//! Those splits depend on the triangles only: a split divides a set at the middle of its
//! centroids' longest extent, and the rays only choose which side they visit first. Made
//! per call, their upper levels cost a pass over every triangle per level, whatever the number of
//! rays: a 1,820-ray bounce on the 871K dragon took 106 ms, against the BVH's 3 ms
//! (BENCHMARKS.md § "dacrt5d: box splits"). Made once, a call walks them with its rays only and
//! splits per call below nodes of `top_leaf` triangles, starting from the same sets: the same
//! splits, so the same answers.
//!
//! Memory (deterministic): the triangle order, `4·T`, and at most `4·T / (top_leaf + 1) + 1`
//! nodes of 64 bytes (every inner node holds more than `top_leaf` triangles, and the deepest
//! inner nodes are disjoint), reserved exactly.

use super::space::{split_set, SetBounds};
use crate::geom::Vec3;
use crate::mem::reserve_exact_huge;

/// A node of the kept levels.
#[derive(Clone, Copy, Debug)]
pub(super) struct TopNode {
    /// Its triangles' union box and centroid bounds.
    pub(super) set: SetBounds,
    /// Its triangles: `order[start..start + len]`.
    pub(super) start: u32,
    pub(super) len: u32,
    /// Its low-side child (the high side's is next); 0: the splits below are made per call.
    pub(super) kids: u32,
    /// The split axis.
    pub(super) axis: u32,
}

/// The kept levels.
#[derive(Default)]
pub(super) struct Top {
    /// Live triangle ids, each node's a range.
    pub(super) order: Vec<u32>,
    /// The root first.
    pub(super) nodes: Vec<TopNode>,
}

/// The ids of the live triangles (boxes with `lo <= hi`; degenerate ones have an empty box),
/// in order.
pub(super) fn live_ids(boxes: &[[f32; 6]]) -> impl Iterator<Item = u32> + '_ {
    (boxes.iter().enumerate())
        .filter(|(_, b)| b[0] <= b[3])
        .map(|(t, _)| t as u32)
}

impl Top {
    /// The levels over the live triangles (boxes with `lo <= hi`) down to nodes of at most
    /// `leaf` triangles (or `max_depth`).
    pub(super) fn new(boxes: &[[f32; 6]], leaf: usize, max_depth: u32) -> Self {
        let mut top = Self::default();
        top.build(boxes, leaf, max_depth);
        top
    }

    fn build(&mut self, boxes: &[[f32; 6]], leaf: usize, max_depth: u32) {
        let live = boxes.iter().filter(|b| b[0] <= b[3]).count();
        reserve_exact_huge(&mut self.order, live, true);
        self.order.clear();
        self.order.extend(live_ids(boxes));
        let cap = 4 * live / (leaf + 1) + 1;
        if self.nodes.capacity() < cap {
            self.nodes = Vec::with_capacity(cap);
        }
        self.nodes.clear();
        if live == 0 {
            return;
        }
        let mut set = SetBounds::default();
        for &t in &self.order {
            let b = &boxes[t as usize];
            let (lo, hi) = (Vec3::new(b[0], b[1], b[2]), Vec3::new(b[3], b[4], b[5]));
            set = set.grown::<true>(lo, hi, lo + hi);
        }
        self.nodes.push(TopNode {
            set,
            start: 0,
            len: live as u32,
            kids: 0,
            axis: 0,
        });
        self.split(boxes, 0, 0, leaf, max_depth);
    }

    /// Splits node `i` (at `depth`) and its children, depth first (no allocation but the
    /// nodes').
    fn split(&mut self, boxes: &[[f32; 6]], i: usize, depth: u32, leaf: usize, max_depth: u32) {
        let n = self.nodes[i];
        if n.len as usize <= leaf || depth >= max_depth {
            return;
        }
        let (s, e) = (n.start as usize, (n.start + n.len) as usize);
        let cb = Some((n.set.clo, n.set.chi));
        let Some(sp) = split_set::<true>(&mut self.order[s..e], boxes, cb, |_| true) else {
            return;
        };
        let kids = self.nodes.len();
        let n1 = sp.n1 as u32;
        self.nodes.push(TopNode {
            set: sp.first,
            start: n.start,
            len: n1,
            kids: 0,
            axis: 0,
        });
        self.nodes.push(TopNode {
            set: sp.second,
            start: n.start + n1,
            len: n.len - n1,
            kids: 0,
            axis: 0,
        });
        (self.nodes[i].kids, self.nodes[i].axis) = (kids as u32, sp.axis as u32);
        self.split(boxes, kids, depth + 1, leaf, max_depth);
        self.split(boxes, kids + 1, depth + 1, leaf, max_depth);
    }

    /// Bytes held.
    pub(super) fn bytes(&self) -> usize {
        self.order.capacity() * 4 + self.nodes.capacity() * std::mem::size_of::<TopNode>()
    }
}
