//! The SAH kd-tree, shared by every technique that walks one (the `kdtree` tracer now; the
//! relevant-triangle shafts and cone tracing next). Built from triangle boxes only: the tree
//! stores split planes and triangle ids, never triangles.
//!
//! - **Build** (`build.rs`): the O(N log N) event-sorted SAH build of Wald & Havran 2006 ("On
//!   building fast kd-trees for ray tracing, and on doing that in O(N log N)"): the start, end
//!   and planar events of every triangle are sorted once per axis; a node sweeps its three
//!   sorted lists to find the cheapest plane (pbrt-v3's cost model: [`BuildConfig::traversal_cost`]
//!   plus [`BuildConfig::intersection_cost`] times the area-weighted counts, the latter lowered
//!   by [`BuildConfig::empty_bonus`] when one side is empty: empty-space cutting), and splitting
//!   a node filters its lists into its children's in order, so nothing is sorted again except the
//!   few events of straddling triangles clipped to the plane, which are merged in. Triangles in
//!   the plane go to the side the SAH prefers (Wald & Havran's planar rule). A node becomes a
//!   leaf when it holds at most [`BuildConfig::max_leaf`] triangles, is at
//!   [`BuildConfig::max_depth`], or no plane is cheaper than testing all its triangles. Subtrees
//!   of at least [`BuildConfig::parallel_threshold`] triangles build in parallel (`rayon::join`).
//! - **Split clipping is by boxes, not by polygons.** A straddling triangle's box is clipped to
//!   each child's cell, which is what its later events come from. Wald & Havran's "perfect
//!   splits" clip the *polygon* instead and drop a triangle from a cell its polygon misses but
//!   its box meets; that loses hits here, because the shared test accepts a hit anywhere in the
//!   triangle's *box* slab interval (the box gate, `geom/triangle.rs`), and an ill-conditioned
//!   (grazing) ray's accepted point can lie in that box but in a cell the polygon never touches.
//!   So a triangle is referenced by every child its box meets, as the exactness argument needs.
//! - **Degenerate triangles** (collapsed to a point by the scene, so never hit) and triangles
//!   with non-finite corners are left out of the tree; flat (axis-aligned) triangles get planar
//!   events.
//!
//! **Why traversal is exact** (the proof behind [`KdTree::split_window`]). Let `T` be the
//! closest hit of a ray, at the gated distance `t*`: the gate puts `t*` inside the slab interval
//! `[eT, xT]` of `T`'s box ([`SlabRay::interval`](crate::geom::SlabRay::interval), entry lowered,
//! exit widened). The walk keeps, for the node it is in, an interval `[tn, tf]`; at the root it
//! is the slab interval of the root's box clipped to `[tmin, tmax]`, which contains `t*` (the
//! root box contains `T`'s box and the slab test is monotone in the box). At a split on axis `a`
//! at `s`, with `ts = (s - o_a)·(1/d_a)`, the walk widens `ts` to `[lo, hi] = [min(ts -
//! |ts|·BOX_ENTRY_SLACK, ts), max(ts·BOX_EXIT_SLACK, ts)]` (both infinite for a NaN `ts`: a ray
//! parallel to the plane lying in it), gives the near child (the one below `s` when `d_a` is
//! positive, +0 included) `[tn, min(tf, hi)]` and the far one `[max(tn, lo), tf]`, and visits
//! each whose interval is not empty. The build references `T` below only when `T`'s box has
//! `max_a <= s`, above only when `min_a >= s` (else in both). If `T` is only in the near child,
//! `T`'s exit on axis `a` is `(max_a - o_a)·inv_a <= ts` (f32 subtraction and multiplication
//! are monotone; mirrored for a negative direction), so `t* <= xT <= ts·BOX_EXIT_SLACK <= hi`:
//! `t*` is in the near child's interval. Only in the far child: likewise `t* >= eT >= lo`. In
//! both: the two intervals cover `[tn, tf]` (`lo <= hi`). A ray with `d_a = ±0` has `ts = ±inf`
//! (one child gets the whole interval: the side of the origin, the only side with hittable
//! triangles: a hit needs `min_a <= o_a <= max_a`) or NaN (origin in the plane: both children).
//! So by induction some leaf referencing `T` is reached with `t*` in its interval, hence with an
//! entry `<= t*`; the walk tests every triangle of a leaf against the ray's whole `[tmin,
//! best_t]` (not the cell's interval) and drops a deferred far child only when its entry
//! exceeds `best_t >= t*` (inclusive, for ties to the smaller id), so `T` is tested and found at
//! `t*` exactly. Occlusion is the same walk with `best_t = tmax` until the first hit.
//!
//! **Layout** (pbrt-v3's `KdAccelNode`): [`Node`] is 8 bytes: the split position (or a leaf's
//! first index into [`KdTree::ids`]) and one word holding the axis (3 for a leaf) in its low two
//! bits and the above child's index (or the leaf's triangle count) in the other 30. The below
//! child of an interior node is the next node (depth-first order). A traversal needs a stack of
//! at most [`MAX_DEPTH`] entries of (node, t_enter, t_exit): 12 bytes each.

mod build;
#[cfg(test)]
mod tests;

use crate::error::{Error, Result};
use crate::geom::slab::BOX_ENTRY_SLACK;
use crate::geom::{Aabb, BOX_EXIT_SLACK};
use crate::scene::TriangleSoup;

/// Hard depth limit (the traversal stacks are this deep).
pub const MAX_DEPTH: usize = 64;

/// Build options; also the `kdtree` tracer's `Config` (`kdtree:key=value`). Defaults are the
/// fields' values.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct BuildConfig {
    /// SAH cost of visiting an interior node (one split-plane distance), relative to
    /// `intersection_cost`. Default 1.0.
    pub traversal_cost: f32,
    /// SAH cost of one ray/triangle test. Default 1.5 (Wald & Havran's K_T = 15, K_I = 20
    /// ratio; pbrt-v3's 1 : 80 builds far deeper trees).
    pub intersection_cost: f32,
    /// Fraction of the intersection term saved when one side of a split is empty (empty-space
    /// cutting), in [0, 1). Default 0.2 (Wald & Havran's λ = 0.8; pbrt-v3 uses 0.5).
    pub empty_bonus: f32,
    /// Nodes with at most this many triangles become leaves without trying a split (1..=255).
    /// Default 1: the SAH alone decides (pbrt-v3's `maxPrims`).
    pub max_leaf: usize,
    /// Deepest leaf (0..=[`MAX_DEPTH`]); 0 is automatic: `8 + 1.3·log2(N)` rounded (pbrt-v3's
    /// rule), capped at [`MAX_DEPTH`]. Default 0.
    pub max_depth: usize,
    /// Nodes with at least this many triangles build their two children in parallel. Default 4096.
    pub parallel_threshold: usize,
}

impl Default for BuildConfig {
    fn default() -> Self {
        Self {
            traversal_cost: 1.0,
            intersection_cost: 1.5,
            empty_bonus: 0.2,
            max_leaf: 1,
            max_depth: 0,
            parallel_threshold: 4096,
        }
    }
}

impl BuildConfig {
    /// Checks the ranges documented on the fields; `who` names the caller in the message.
    pub fn check(&self, who: &str) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("{who}: {m}")));
        let ok_trav = self.traversal_cost >= 0.0 && self.traversal_cost.is_finite();
        let ok_isect = self.intersection_cost > 0.0 && self.intersection_cost.is_finite();
        if !ok_trav || !ok_isect {
            return bad(format!(
                "costs must be finite, traversal_cost >= 0 and intersection_cost > 0, got {} and {}",
                self.traversal_cost, self.intersection_cost
            ));
        }
        if !(self.empty_bonus >= 0.0 && self.empty_bonus < 1.0) {
            return bad(format!("empty_bonus must be in [0, 1), got {}", self.empty_bonus));
        }
        if !(1..=255).contains(&self.max_leaf) {
            return bad(format!("max_leaf must be in 1..=255, got {}", self.max_leaf));
        }
        if self.max_depth > MAX_DEPTH {
            return bad(format!(
                "max_depth must be in 0..={MAX_DEPTH} (0: automatic), got {}",
                self.max_depth
            ));
        }
        Ok(())
    }

    /// The depth limit for `n` triangles ([`BuildConfig::max_depth`], 0 resolved).
    pub fn depth_limit(&self, n: usize) -> usize {
        match self.max_depth {
            0 => ((8.0 + 1.3 * (n.max(1) as f64).log2()).round() as usize).min(MAX_DEPTH),
            d => d,
        }
    }
}

/// Leaf tag in [`Node`]'s low two bits (0, 1, 2 are the split axes).
const LEAF: u32 = 3;

/// One node, 8 bytes (pbrt-v3's `KdAccelNode`). Interior: the split position and, in `flags`,
/// the axis and the index of the above child (the below child is the next node). Leaf: the first
/// index into [`KdTree::ids`] and, in `flags`, tag 3 and the triangle count.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Node {
    /// Split position's bits (interior) or first id index (leaf).
    data: u32,
    /// Axis or leaf tag (low 2 bits), above-child index or count (high 30 bits).
    flags: u32,
}

/// Largest node index or leaf count a [`Node`] can hold.
pub const MAX_INDEX: usize = (1 << 30) - 1;

impl Node {
    /// An interior node splitting `axis` at `split`, its above child at `above`.
    pub fn interior(axis: usize, split: f32, above: u32) -> Self {
        debug_assert!(axis < 3 && above as usize <= MAX_INDEX);
        Self {
            data: split.to_bits(),
            flags: axis as u32 | (above << 2),
        }
    }

    /// A leaf of `count` ids starting at `offset` in [`KdTree::ids`].
    pub fn leaf(offset: u32, count: u32) -> Self {
        debug_assert!(count as usize <= MAX_INDEX);
        Self {
            data: offset,
            flags: LEAF | (count << 2),
        }
    }

    /// True for a leaf.
    #[inline(always)]
    pub fn is_leaf(self) -> bool {
        self.flags & 3 == LEAF
    }

    /// Split axis (interior nodes).
    #[inline(always)]
    pub fn axis(self) -> usize {
        (self.flags & 3) as usize
    }

    /// Split position (interior nodes).
    #[inline(always)]
    pub fn split(self) -> f32 {
        f32::from_bits(self.data)
    }

    /// Index of the above child (interior nodes); the below child is this node's index + 1.
    #[inline(always)]
    pub fn above(self) -> u32 {
        self.flags >> 2
    }

    /// First index into [`KdTree::ids`] (leaves).
    #[inline(always)]
    pub fn offset(self) -> u32 {
        self.data
    }

    /// Number of triangles (leaves).
    #[inline(always)]
    pub fn count(self) -> u32 {
        self.flags >> 2
    }

    /// This node with its above child (interior) or its offset (leaf) moved by the given amounts
    /// (appending a subtree built on its own).
    fn shifted(self, nodes: u32, ids: u32) -> Self {
        if self.is_leaf() {
            Self::leaf(self.data + ids, self.count())
        } else {
            Self::interior(self.axis(), self.split(), self.above() + nodes)
        }
    }
}

/// An SAH kd-tree over a triangle soup: nodes in depth-first order (root at 0), the leaves'
/// triangle ids, and the box of every triangle it holds.
#[derive(Clone, Debug, Default)]
pub struct KdTree {
    /// Nodes, root first; the below child of node `i` is `i + 1`.
    pub nodes: Vec<Node>,
    /// Triangle ids of the leaves, each leaf's run sorted.
    pub ids: Vec<u32>,
    /// Box of the triangles in the tree (the root cell); empty when it holds none.
    pub bounds: Aabb,
    /// Deepest leaf's depth (the root is at 0).
    pub depth: usize,
    /// Triangles in the soup it was built from (ids are below it).
    pub triangles: usize,
}

/// Sizes of a tree, for counters and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Shape {
    /// Interior nodes.
    pub interior: usize,
    /// Leaves.
    pub leaves: usize,
    /// Leaves with no triangle.
    pub empty_leaves: usize,
    /// Triangle references (ids in leaves).
    pub refs: usize,
}

impl KdTree {
    /// Builds the tree over `soup` with `cfg` (checked first).
    pub fn build(soup: &TriangleSoup, cfg: &BuildConfig) -> Result<Self> {
        cfg.check("kd-tree build")?;
        build::build(soup, cfg)
    }

    /// Bytes held: 8 per node and 4 per reference.
    pub fn bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.ids.capacity() * std::mem::size_of::<u32>()
    }

    /// Node counts and references.
    pub fn shape(&self) -> Shape {
        let mut s = Shape {
            refs: self.ids.len(),
            ..Shape::default()
        };
        for n in &self.nodes {
            if n.is_leaf() {
                s.leaves += 1;
                s.empty_leaves += (n.count() == 0) as usize;
            } else {
                s.interior += 1;
            }
        }
        s
    }

    /// The triangle ids of leaf `n`.
    #[inline(always)]
    pub fn leaf_ids(&self, n: Node) -> &[u32] {
        let first = n.offset() as usize;
        &self.ids[first..first + n.count() as usize]
    }

    /// The window `[lo, hi]` a traversal gives the split distance `ts` (see the module doc): `ts`
    /// lowered by `BOX_ENTRY_SLACK` relative and raised by `BOX_EXIT_SLACK`, as the slab test
    /// moves a box's entry and exit; both infinite for a NaN `ts`.
    #[inline(always)]
    pub fn split_window(ts: f32) -> (f32, f32) {
        if ts.is_nan() {
            return (f32::NEG_INFINITY, f32::INFINITY);
        }
        // `inf - inf` is NaN: the comparisons keep `ts` then.
        let lo = ts - ts.abs() * BOX_ENTRY_SLACK;
        let hi = ts * BOX_EXIT_SLACK;
        (if lo < ts { lo } else { ts }, if hi > ts { hi } else { ts })
    }

    /// Checks the structure and the reference rule the exactness argument rests on: node
    /// indices and leaf runs in range, depth within [`MAX_DEPTH`], each split strictly inside its
    /// cell, every triangle with a finite non-point box in the tree (inside the root's box), and
    /// at every split a triangle referenced only below has `max <= s` on the axis, only above
    /// `min >= s`. Costs O(references × depth); for tests and `--validate`.
    pub fn validate(&self, soup: &TriangleSoup) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("kd-tree invalid: {m}")));
        if soup.len() != self.triangles {
            return bad(format!(
                "built for {} triangles, soup has {}",
                self.triangles,
                soup.len()
            ));
        }
        if self.nodes.is_empty() {
            return bad("no root".into());
        }
        let mut walk = Validator {
            tree: self,
            soup,
            depth: 0,
        };
        let all = walk.node(0, self.bounds, 0)?;
        if walk.depth != self.depth {
            return bad(format!("depth {} recorded, {} found", self.depth, walk.depth));
        }
        let expected: Vec<u32> = (0..soup.len() as u32)
            .filter(|&i| build::in_tree(&soup.bounds(i as usize)))
            .collect();
        if all != expected {
            return bad(format!(
                "{} triangles referenced, {} should be",
                all.len(),
                expected.len()
            ));
        }
        for &i in &all {
            if !self.bounds.contains_box(&soup.bounds(i as usize)) {
                return bad(format!("triangle {i} outside the root box"));
            }
        }
        Ok(())
    }
}

/// [`KdTree::validate`]'s walk.
struct Validator<'a> {
    tree: &'a KdTree,
    soup: &'a TriangleSoup,
    depth: usize,
}

impl Validator<'_> {
    /// Checks the subtree at `i` (cell `cell`, depth `d`); returns its triangle ids, sorted.
    fn node(&mut self, i: usize, cell: Aabb, d: usize) -> Result<Vec<u32>> {
        let bad = |m: String| Err(Error::Invalid(format!("kd-tree invalid: node {i}: {m}")));
        let Some(&n) = self.tree.nodes.get(i) else {
            return bad("index out of range".into());
        };
        if d > MAX_DEPTH {
            return bad(format!("deeper than {MAX_DEPTH}"));
        }
        self.depth = self.depth.max(d);
        if n.is_leaf() {
            let (first, count) = (n.offset() as usize, n.count() as usize);
            let Some(ids) = self.tree.ids.get(first..first + count) else {
                return bad("leaf run out of range".into());
            };
            let mut ids = ids.to_vec();
            if ids.windows(2).any(|w| w[0] >= w[1]) {
                return bad("leaf ids not sorted or repeated".into());
            }
            for &t in &ids {
                if t as usize >= self.soup.len() {
                    return bad(format!("triangle id {t} out of range"));
                }
                if cell.intersection(self.soup.bounds(t as usize)).is_empty() {
                    return bad(format!("triangle {t}'s box misses the leaf's cell"));
                }
            }
            ids.dedup();
            return Ok(ids);
        }
        let (a, s, above) = (n.axis(), n.split(), n.above() as usize);
        if !(cell.min[a] < s && s < cell.max[a]) {
            return bad(format!("split {s} on axis {a} not inside the cell"));
        }
        if above <= i + 1 {
            return bad(format!("above child {above} not after the below one"));
        }
        let (mut lcell, mut rcell) = (cell, cell);
        lcell.max[a] = s;
        rcell.min[a] = s;
        let below = self.node(i + 1, lcell, d + 1)?;
        let above_ids = self.node(above, rcell, d + 1)?;
        let (mut x, mut y) = (0, 0);
        let mut all = Vec::with_capacity(below.len() + above_ids.len());
        while x < below.len() || y < above_ids.len() {
            let (l, r) = (below.get(x).copied(), above_ids.get(y).copied());
            let t = match (l, r) {
                (Some(l), Some(r)) if l == r => {
                    x += 1;
                    y += 1;
                    l
                }
                (Some(l), r) if r.is_none_or(|r| l < r) => {
                    x += 1;
                    if !(self.soup.bounds(l as usize).max[a] <= s) {
                        return bad(format!("triangle {l} only below {s} but reaches above"));
                    }
                    l
                }
                (_, Some(r)) => {
                    y += 1;
                    if !(self.soup.bounds(r as usize).min[a] >= s) {
                        return bad(format!("triangle {r} only above {s} but reaches below"));
                    }
                    r
                }
                _ => unreachable!("loop condition"),
            };
            all.push(t);
        }
        Ok(all)
    }
}
