//! The upper levels of the box splits shared above the bundles (`space.rs`), made by the first
//! call that shares splits after a `prepare` and kept for the next calls (`top_leaf`).
//!
//! Those splits depend on the triangles only: the rays only choose which side they visit
//! first. Made per call, their upper levels cost a pass over every triangle per level, whatever
//! the number of rays: a 1,820-ray bounce on the 871K dragon took 106 ms, against the BVH's 3 ms
//! (BENCHMARKS.md § "dacrt5d: box splits"). Made once, a call walks them with its rays only
//! (the shared rays, and since `kept_bundles` the handed-over bundles too) and splits per call
//! below nodes of `top_leaf` triangles.
//!
//! They are made over the triangles' centroids in Morton order (`geom::morton`, 10 bits per
//! axis over the live centroids' box): a node's range of the sorted codes splits where its
//! highest differing bit changes (a cut at the middle of a grid cell's extent on that bit's
//! axis, as a linear BVH builder makes it), down to nodes of at most `top_leaf` triangles or of
//! one code; the boxes and centroid bounds are then made leaves first. A sort and a pass over
//! the leaves replace a pass over every triangle per level: the per-call splits' rule (the
//! middle of the centroids' extent, `space::split_set`) made over 11M item moves on the 871K
//! dragon, 105–220 ms a frame. The splits below a kept leaf are made per call from its
//! triangles and centroid bounds. The exactness argument is the box splits' (`space.rs`): each
//! node's box is its triangles' union box and the two children's triangles are disjoint.
//!
//! Memory (deterministic): the triangle order, `4·T`, and at most `4·T / (top_leaf + 1) + 1`
//! nodes of 64 bytes (every inner node holds more than `top_leaf` triangles, and the deepest
//! inner nodes are disjoint), reserved exactly; while building, the sort keys (`8·T`), freed.

use super::space::SetBounds;
use crate::geom::morton;
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
        let cap = 4 * live / (leaf + 1) + 1;
        if self.nodes.capacity() < cap {
            self.nodes = Vec::with_capacity(cap);
        }
        self.nodes.clear();
        reserve_exact_huge(&mut self.order, live, true);
        self.order.clear();
        if live == 0 {
            return;
        }
        // Centroids doubled (`lo + hi`), as the per-call splits take them.
        let centroid = |b: &[f32; 6]| Vec3::new(b[0] + b[3], b[1] + b[4], b[2] + b[5]);
        let (mut clo, mut chi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for t in live_ids(boxes) {
            let c = centroid(&boxes[t as usize]);
            (clo, chi) = (clo.min(c), chi.max(c));
        }
        let scale = morton::scale_for(chi - clo);
        let mut keys: Vec<u64> = Vec::new();
        reserve_exact_huge(&mut keys, live, true);
        keys.extend(
            live_ids(boxes)
                .map(|t| morton::code30(centroid(&boxes[t as usize]), clo, scale) << 32 | t as u64),
        );
        keys.sort_unstable();
        self.order.extend(keys.iter().map(|&k| k as u32));
        self.nodes.push(TopNode {
            set: SetBounds::default(),
            start: 0,
            len: live as u32,
            kids: 0,
            axis: 0,
        });
        self.split(&keys, 0, 0, leaf, max_depth);
        drop(keys);
        // Boxes leaves first: children come after their parent.
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let set = if n.kids == 0 {
                let (s, e) = (n.start as usize, (n.start + n.len) as usize);
                self.order[s..e]
                    .iter()
                    .fold(SetBounds::default(), |set, &t| {
                        let b = &boxes[t as usize];
                        let (lo, hi) = (Vec3::new(b[0], b[1], b[2]), Vec3::new(b[3], b[4], b[5]));
                        set.grown::<true>(lo, hi, lo + hi)
                    })
            } else {
                let (a, b) = (
                    self.nodes[n.kids as usize].set,
                    self.nodes[n.kids as usize + 1].set,
                );
                SetBounds {
                    lo: a.lo.min(b.lo),
                    hi: a.hi.max(b.hi),
                    clo: a.clo.min(b.clo),
                    chi: a.chi.max(b.chi),
                }
            };
            self.nodes[i].set = set;
        }
    }

    /// Splits node `i` (at `depth`; its codes `keys[start..start + len]`, high halves) where its
    /// highest differing bit changes, and its children, depth first (no allocation but the
    /// nodes').
    fn split(&mut self, keys: &[u64], i: usize, depth: u32, leaf: usize, max_depth: u32) {
        let n = self.nodes[i];
        let (s, e) = (n.start as usize, (n.start + n.len) as usize);
        let diff = (keys[s] ^ keys[e - 1]) >> 32;
        if n.len as usize <= leaf || depth >= max_depth || diff == 0 {
            return;
        }
        let bit = 63 - diff.leading_zeros();
        // The codes are sorted and agree above `bit`: those with it clear come first.
        let n1 = keys[s..e].partition_point(|k| (k >> 32) & (1 << bit) == 0) as u32;
        let kids = self.nodes.len();
        for (start, len) in [(n.start, n1), (n.start + n1, n.len - n1)] {
            self.nodes.push(TopNode {
                set: SetBounds::default(),
                start,
                len,
                kids: 0,
                axis: 0,
            });
        }
        // Bit `3k + a` is axis `a`'s: the first child is the low side.
        (self.nodes[i].kids, self.nodes[i].axis) = (kids as u32, bit % 3);
        self.split(keys, kids, depth + 1, leaf, max_depth);
        self.split(keys, kids + 1, depth + 1, leaf, max_depth);
    }

    /// Bytes held.
    pub(super) fn bytes(&self) -> usize {
        self.order.capacity() * 4 + self.nodes.capacity() * std::mem::size_of::<TopNode>()
    }
}
