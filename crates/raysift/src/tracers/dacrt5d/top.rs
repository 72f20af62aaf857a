//! The upper levels of the box splits shared above the bundles (`space.rs`), made by the first
//! call with box splits after a `prepare` and kept for the next calls (`top_leaf`).
//!
//! Those splits depend on the triangles only: the rays only choose which side they visit
//! first. Made per call, their upper levels cost a pass over every triangle per level, whatever
//! the number of rays: a 1,820-ray bounce on the 871K dragon took 106 ms, against the BVH's 3 ms
//! (BENCHMARKS.md § "dacrt5d: box splits"). Made once, a call walks them with its rays only
//! (the shared rays, and since `kept_bundles` the handed-over bundles too) and splits per call
//! below nodes of `top_leaf` triangles.
//!
//! Two ways to make them (`top_split`), both leaves first for the boxes and centroid bounds:
//! - `morton` (default): the centroids in Morton order (`geom::morton`, a cubic grid of 1024
//!   cells a side over their largest extent), one sort; a node's range of the sorted codes
//!   splits where its highest differing bit changes (a cut at the middle of a grid cell on that
//!   bit's axis, as a linear BVH builder makes it), down to nodes of at most `top_leaf`
//!   triangles or of one code. A sort and a pass over the leaves instead of a pass per level: 73–75 ms on the 871K
//!   dragon, where the per-call rule over ids took 105–220 ms (11M gathers of scattered boxes).
//! - `middle`: the per-call splits' rule (the middle of the centroids' longest extent,
//!   `space::split_set`) on centroids quantized to 16 bits, moving 12-byte items level by level
//!   (each read and written whole): traces 0.88–1.08× `morton`'s, batch by batch (the
//!   dragon's camera 0.95×, Sponza's shadow rays 1.08×), a build 2.5× dearer (175–199 against
//!   73–75 ms on the dragon): BENCHMARKS.md § "dacrt5d: bundles through the kept levels".
//!
//! Both use one scale on every axis (a cubic Morton grid; 16-bit centroids comparable across
//! axes): with one per axis the longest quantized extent was not the longest one, and Sponza's
//! shadow rays made 12.7 triangle tests each against 5.3 with every split made per call.
//!
//! The splits below a kept leaf are made per call from its triangles and centroid bounds. The
//! exactness argument is the box splits' (`space.rs`): each node's box is its triangles' union
//! box and the two children's triangles are disjoint.
//!
//! Memory (deterministic): the triangle order, `4·T`, and at most `4·T / (top_leaf + 1) + 1`
//! nodes of 64 bytes, reserved exactly (a spread scene needs no more: every inner node holds
//! more than `top_leaf` triangles, and the deepest inner nodes are disjoint; where splits peel a
//! few triangles at a time, the levels stop at the reservation, `Top::full`); while building,
//! the sort keys (`8·T`, `morton`) or the items (`12·T`, `middle`), freed.

use super::space::{centroid, SetBounds};
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

/// How the kept levels split a node (`Config::top_split`).
#[derive(Clone, Copy, Debug, Default, serde::Deserialize, serde::Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum TopSplit {
    /// The middle of the node's centroid bounds on their longest axis (the per-call splits'
    /// rule), centroids quantized to 16 bits per axis, items moved level by level.
    Middle,
    /// Morton order: one sort, then cuts where the highest differing bit changes.
    #[default]
    Morton,
}

/// A triangle as [`TopSplit::Middle`] moves it: its centroid quantized, its id.
#[derive(Clone, Copy)]
struct Item {
    q: [u16; 3],
    id: u32,
}

/// The scale that maps the largest extent onto `0..=65535`, the same on every axis (so the
/// longest quantized extent is the longest one).
fn quant_scale(extent: Vec3) -> Vec3 {
    Vec3::splat(65535.0 / extent.max_element().max(f32::MIN_POSITIVE))
}

#[inline(always)]
fn quantize(c: Vec3, lo: Vec3, scale: Vec3) -> [u16; 3] {
    let q = ((c - lo) * scale).clamp(Vec3::ZERO, Vec3::splat(65535.0));
    [q.x as u16, q.y as u16, q.z as u16]
}

impl Top {
    /// The levels over the live triangles (boxes with `lo <= hi`) down to nodes of at most
    /// `leaf` triangles (or `max_depth`), split by `rule`.
    pub(super) fn new(boxes: &[[f32; 6]], leaf: usize, max_depth: u32, rule: TopSplit) -> Self {
        let mut top = Self::default();
        let live = boxes.iter().filter(|b| b[0] <= b[3]).count();
        let cap = 4 * live / (leaf + 1) + 1;
        top.nodes = Vec::with_capacity(cap);
        reserve_exact_huge(&mut top.order, live, true);
        if live == 0 {
            return top;
        }
        // Centroids doubled (`lo + hi`), as the per-call splits take them.
        let (mut clo, mut chi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for t in live_ids(boxes) {
            let c = centroid(&boxes[t as usize]);
            (clo, chi) = (clo.min(c), chi.max(c));
        }
        top.nodes.push(TopNode {
            set: SetBounds::default(),
            start: 0,
            len: live as u32,
            kids: 0,
            axis: 0,
        });
        match rule {
            TopSplit::Middle => {
                let scale = quant_scale(chi - clo);
                let mut items: Vec<Item> = Vec::new();
                reserve_exact_huge(&mut items, live, true);
                let (mut qlo, mut qhi) = ([u16::MAX; 3], [0u16; 3]);
                items.extend(live_ids(boxes).map(|id| {
                    let q = quantize(centroid(&boxes[id as usize]), clo, scale);
                    for a in 0..3 {
                        (qlo[a], qhi[a]) = (qlo[a].min(q[a]), qhi[a].max(q[a]));
                    }
                    Item { q, id }
                }));
                top.split_middle(&mut items, 0, (qlo, qhi), 0, leaf, max_depth);
                top.order.extend(items.iter().map(|it| it.id));
            }
            TopSplit::Morton => {
                // A cubic grid: cells as long on every axis, so a cut halves the longest side.
                let scale = morton::scale_for(Vec3::splat((chi - clo).max_element()));
                let mut keys: Vec<u64> = Vec::new();
                reserve_exact_huge(&mut keys, live, true);
                keys.extend(live_ids(boxes).map(|t| {
                    morton::code30(centroid(&boxes[t as usize]), clo, scale) << 32 | t as u64
                }));
                keys.sort_unstable();
                top.order.extend(keys.iter().map(|&k| k as u32));
                top.split_morton(&keys, 0, 0, leaf, max_depth);
            }
        }
        // Boxes leaves first: children come after their parent.
        for i in (0..top.nodes.len()).rev() {
            let n = top.nodes[i];
            let set = if n.kids == 0 {
                let (s, e) = (n.start as usize, (n.start + n.len) as usize);
                top.order[s..e]
                    .iter()
                    .fold(SetBounds::default(), |set, &t| {
                        let b = &boxes[t as usize];
                        let (lo, hi) = (Vec3::new(b[0], b[1], b[2]), Vec3::new(b[3], b[4], b[5]));
                        set.grown::<true>(lo, hi, lo + hi)
                    })
            } else {
                let (a, b) = (
                    top.nodes[n.kids as usize].set,
                    top.nodes[n.kids as usize + 1].set,
                );
                SetBounds {
                    lo: a.lo.min(b.lo),
                    hi: a.hi.max(b.hi),
                    clo: a.clo.min(b.clo),
                    chi: a.chi.max(b.chi),
                }
            };
            top.nodes[i].set = set;
        }
        top
    }

    /// Whether the reserved nodes are used up: splits that peel a few triangles at a time (a
    /// chain of inner nodes, each with a small leaf) could need up to `2·T − 1` nodes; past the
    /// reservation the node stays a kept leaf and its splits are made per call (as exact), so
    /// the bound holds for every scene.
    fn full(&self) -> bool {
        self.nodes.len() + 2 > self.nodes.capacity()
    }

    /// Adds node `i`'s two children (`n1` items first); returns the index of the first.
    fn push_kids(&mut self, i: usize, n1: u32, axis: u32) -> usize {
        let n = self.nodes[i];
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
        (self.nodes[i].kids, self.nodes[i].axis) = (kids as u32, axis);
        kids
    }

    /// Splits node `i` (at `depth`; its items `items[start..start + len]`, their quantized
    /// centroid bounds `q`) at the middle of the bounds' longest axis (`space::split_set`'s
    /// rule on quantized centroids), low side first, and its children, depth first. Each item
    /// is read once and written once per level (a whole 12-byte record: no partial store
    /// before its load).
    fn split_middle(
        &mut self,
        items: &mut [Item],
        i: usize,
        (qlo, qhi): ([u16; 3], [u16; 3]),
        depth: u32,
        leaf: usize,
        max_depth: u32,
    ) {
        let n = self.nodes[i];
        let ext = [0, 1, 2].map(|a| qhi[a] - qlo[a]);
        let a = if ext[0] >= ext[1] && ext[0] >= ext[2] {
            0
        } else if ext[1] >= ext[2] {
            1
        } else {
            2
        };
        if n.len as usize <= leaf || depth >= max_depth || ext[a] == 0 || self.full() {
            return;
        }
        // `lo <= mid < hi`: both sides hold an item.
        let mid = qlo[a] + ext[a] / 2;
        let (s, e) = (n.start as usize, (n.start + n.len) as usize);
        let part = &mut items[s..e];
        let (mut b1, mut b2) = (([u16::MAX; 3], [0u16; 3]), ([u16::MAX; 3], [0u16; 3]));
        let mut n1 = 0;
        for p in 0..part.len() {
            let it = part[p];
            let low = it.q[a] <= mid;
            let b = if low { &mut b1 } else { &mut b2 };
            for k in 0..3 {
                (b.0[k], b.1[k]) = (b.0[k].min(it.q[k]), b.1[k].max(it.q[k]));
            }
            part[p] = part[n1];
            part[n1] = it;
            n1 += low as usize;
        }
        let kids = self.push_kids(i, n1 as u32, a as u32);
        self.split_middle(items, kids, b1, depth + 1, leaf, max_depth);
        self.split_middle(items, kids + 1, b2, depth + 1, leaf, max_depth);
    }

    /// Splits node `i` (at `depth`; its codes `keys[start..start + len]`, high halves) where its
    /// highest differing bit changes, and its children, depth first.
    fn split_morton(&mut self, keys: &[u64], i: usize, depth: u32, leaf: usize, max_depth: u32) {
        let n = self.nodes[i];
        let (s, e) = (n.start as usize, (n.start + n.len) as usize);
        let diff = (keys[s] ^ keys[e - 1]) >> 32;
        if n.len as usize <= leaf || depth >= max_depth || diff == 0 || self.full() {
            return;
        }
        let bit = 63 - diff.leading_zeros();
        // The codes are sorted and agree above `bit`: those with it clear come first, the low
        // side of axis `bit % 3` (bit `3k + a` is axis `a`'s).
        let n1 = keys[s..e].partition_point(|k| (k >> 32) & (1 << bit) == 0) as u32;
        let kids = self.push_kids(i, n1, bit % 3);
        self.split_morton(keys, kids, depth + 1, leaf, max_depth);
        self.split_morton(keys, kids + 1, depth + 1, leaf, max_depth);
    }

    /// Bytes held.
    pub(super) fn bytes(&self) -> usize {
        self.order.capacity() * 4 + self.nodes.capacity() * std::mem::size_of::<TopNode>()
    }
}
