//! The binned-SAH bounding volume hierarchy, shared by every technique that walks a BVH (the
//! `bvh` tracer now; cone tracing's BVH traversal next). Built from boxes only ([`BoxSource`]:
//! a triangle soup, or any list of boxes), as madmann91/bvh's builders are: the tree stores
//! node boxes and primitive ids, never primitives, and a tracer keeps whatever primitive data it
//! wants in leaf order beside it.
//!
//! - **Build** (`build.rs`): binned SAH (Wald 2007, "On fast construction of SAH-based bounding
//!   volume hierarchies"): centroids binned into [`BuildConfig::bins`] slots per axis, the split
//!   with the lowest SAH cost taken, a leaf made when a node has at most
//!   [`BuildConfig::max_leaf`] primitives and the SAH says splitting does not pay; parallel with
//!   rayon above [`BuildConfig::parallel_threshold`]; coincident centroids, flat nodes and very
//!   deep trees fall back to object-median splits, so any input builds and the depth is bounded.
//! - **Refit** (`refit.rs`): new boxes for the same tree after the primitives moved (a deforming
//!   mesh with fixed topology), bottom-up in one pass over the pairs, O(nodes + primitives).
//! - **Spatial splits** (`sbvh.rs`, [`Bvh::build_spatial`]): the SBVH of Stich et al. 2009, where
//!   a node may cut space at a plane and reference a straddling primitive from both sides (by
//!   its box cut at the plane, so the builder still sees boxes only); ids may then repeat.
//! - **Layout**: [`NodePair`]s (two siblings in one 64-byte line, boxes as structure of arrays)
//!   in depth-first order of their parents; pair 0 holds the root in slot 0.

mod build;
mod refit;
mod sbvh;

pub use build::{MAX_BINS, MAX_DEPTH};
pub use sbvh::{SpatialConfig, SpatialStats};

use crate::error::{Error, Result};
use crate::geom::{Aabb, BoxPair};
use crate::scene::TriangleSoup;
use glam::Vec3;

/// Primitive boxes a builder sees: a count and each primitive's box.
pub trait BoxSource: Sync {
    /// Number of primitives.
    fn len(&self) -> usize;
    /// True when there are none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The box of primitive `i`.
    fn bounds(&self, i: usize) -> Aabb;
}

impl BoxSource for TriangleSoup {
    fn len(&self) -> usize {
        TriangleSoup::len(self)
    }
    #[inline]
    fn bounds(&self, i: usize) -> Aabb {
        TriangleSoup::bounds(self, i)
    }
}

impl BoxSource for [Aabb] {
    fn len(&self) -> usize {
        <[Aabb]>::len(self)
    }
    #[inline]
    fn bounds(&self, i: usize) -> Aabb {
        self[i]
    }
}

/// Build options (the `bvh` tracer's `Config` carries them). Defaults are the fields' values.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildConfig {
    /// Bins per axis for the SAH sweep (2..=32). Default 16.
    pub bins: usize,
    /// Most primitives in a leaf (1..=255). Default 4.
    pub max_leaf: usize,
    /// SAH cost of visiting an interior node, relative to `intersection_cost`. Default 1.0.
    pub traversal_cost: f32,
    /// SAH cost of one primitive test. Default 1.0.
    pub intersection_cost: f32,
    /// Nodes with at least this many primitives build their children and bin in parallel.
    /// Default 4096.
    pub parallel_threshold: usize,
}

impl Default for BuildConfig {
    fn default() -> Self {
        Self {
            bins: 16,
            max_leaf: 4,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            parallel_threshold: 4096,
        }
    }
}

impl BuildConfig {
    /// Checks the documented ranges; `who` names the caller in the message.
    pub fn check(&self, who: &str) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("{who}: {m}")));
        if !(2..=MAX_BINS).contains(&self.bins) {
            return bad(format!("bins must be in 2..={MAX_BINS}, got {}", self.bins));
        }
        if !(1..=255).contains(&self.max_leaf) {
            return bad(format!(
                "max_leaf must be in 1..=255, got {}",
                self.max_leaf
            ));
        }
        let ok_trav = self.traversal_cost >= 0.0 && self.traversal_cost.is_finite();
        let ok_isect = self.intersection_cost > 0.0 && self.intersection_cost.is_finite();
        if !ok_trav || !ok_isect {
            return bad("costs must be finite, traversal >= 0, intersection > 0".into());
        }
        Ok(())
    }
}

/// One node, 32 bytes (pbrt's `LinearBVHNode` fields).
///
/// Interior nodes have `count == 0` and `offset` is the index of the [`NodePair`] holding their
/// two children (left in slot 0). Leaves hold `count` triangles at positions
/// `offset..offset + count` of the leaf-ordered arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Node {
    /// Box minimum.
    pub min: Vec3,
    /// Leaf: first triangle position; interior: index of the children's pair.
    pub offset: u32,
    /// Box maximum.
    pub max: Vec3,
    /// Triangles in a leaf, 0 for interior nodes.
    pub count: u16,
    /// Split axis (0, 1, 2) of an interior node (informational: traversal orders by distance).
    pub axis: u8,
    _pad: u8,
}

const _: () = assert!(std::mem::size_of::<Node>() == 32);

impl Node {
    pub(crate) fn leaf(b: Aabb, first: u32, count: u16) -> Self {
        Self {
            min: b.min,
            max: b.max,
            offset: first,
            count,
            axis: 0,
            _pad: 0,
        }
    }

    pub(crate) fn interior(b: Aabb, axis: u8, pair: u32) -> Self {
        Self {
            min: b.min,
            max: b.max,
            offset: pair,
            count: 0,
            axis,
            _pad: 0,
        }
    }

    /// True for leaves.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count != 0
    }

    /// The node's box.
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.min, self.max)
    }
}

/// Two sibling nodes in one 64-byte cache line, boxes as structure of arrays ([`BoxPair`]):
/// traversal tests both children of a node at once with one SIMD slab test
/// ([`SlabRay::entry2`](crate::geom::SlabRay::entry2)), so keeping siblings together means one
/// cache line and one 4-wide test per visited interior node.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct NodePair {
    /// Both children's boxes.
    pub boxes: BoxPair,
    /// Per child: leaf: first triangle position; interior: index of its children's pair.
    pub offset: [u32; 2],
    /// Per child: triangles in a leaf, 0 for interior nodes.
    pub count: [u16; 2],
    /// Per child: split axis of an interior node (informational).
    pub axis: [u8; 2],
    _pad: [u8; 2],
}

const _: () = assert!(std::mem::size_of::<NodePair>() == 64);

impl NodePair {
    /// Placeholder (also the unused second slot of pair 0): empty-box leaves.
    pub const UNUSED: NodePair = NodePair {
        boxes: BoxPair::EMPTY,
        offset: [0; 2],
        count: [0; 2],
        axis: [0; 2],
        _pad: [0; 2],
    };

    /// The pair of `nodes` (left in slot 0).
    pub fn new(nodes: [Node; 2]) -> Self {
        let mut p = Self::UNUSED;
        p.set(0, nodes[0]);
        p.set(1, nodes[1]);
        p
    }

    /// Node in slot `i` (0 or 1).
    #[inline(always)]
    pub fn node(&self, i: usize) -> Node {
        let (min, max) = self.boxes.get(i);
        Node {
            min,
            max,
            offset: self.offset[i],
            count: self.count[i],
            axis: self.axis[i],
            _pad: 0,
        }
    }

    /// Both nodes.
    pub fn nodes(&self) -> [Node; 2] {
        [self.node(0), self.node(1)]
    }

    /// Stores `n` in slot `i` (0 or 1).
    pub fn set(&mut self, i: usize, n: Node) {
        self.boxes.set(i, n.min, n.max);
        self.offset[i] = n.offset;
        self.count[i] = n.count;
        self.axis[i] = n.axis;
    }
}

/// The hierarchy: node pairs and primitive ids in leaf order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// Node pairs in depth-first order of their parents: pair 0 holds the root in slot 0 (slot 1
    /// unused); empty when there are no primitives.
    pub pairs: Vec<NodePair>,
    /// Primitive id at each leaf position (each primitive once, or, after spatial splits, at
    /// least once).
    pub ids: Vec<u32>,
    /// Number of primitives the tree was built over.
    pub prims: usize,
}

impl Bvh {
    /// Builds over the boxes of `prims`.
    pub fn build(prims: &(impl BoxSource + ?Sized), cfg: &BuildConfig) -> Result<Self> {
        cfg.check("bvh")?;
        let b = build::build(prims, cfg);
        Ok(Self::new(b.pairs, b.ids, prims.len()))
    }

    /// Builds with spatial splits ([`SpatialConfig`]; the object splits as [`Bvh::build`]).
    pub fn build_spatial(
        prims: &(impl BoxSource + ?Sized),
        cfg: &BuildConfig,
        sp: &SpatialConfig,
    ) -> Result<(Self, SpatialStats)> {
        cfg.check("bvh")?;
        sp.check("bvh")?;
        let (pairs, ids, stats) = sbvh::build(prims, cfg, sp);
        Ok((Self::new(pairs, ids, prims.len()), stats))
    }

    fn new(mut pairs: Vec<NodePair>, mut ids: Vec<u32>, prims: usize) -> Self {
        // Collecting may over-allocate; the tree lives long, so hand the slack back.
        pairs.shrink_to_fit();
        ids.shrink_to_fit();
        Self { pairs, ids, prims }
    }

    /// True when some primitive is referenced from more than one leaf (spatial splits).
    pub fn has_split_references(&self) -> bool {
        self.ids.len() > self.prims
    }

    /// Recomputes every box from the primitives' current boxes, keeping the tree (the same
    /// primitives, moved). Returns the number of nodes refitted.
    pub fn refit(&mut self, prims: &(impl BoxSource + ?Sized)) -> usize {
        refit::refit(self, prims)
    }

    /// Bytes held (nodes + ids).
    pub fn bytes(&self) -> usize {
        self.pairs.capacity() * std::mem::size_of::<NodePair>() + self.ids.capacity() * 4
    }

    /// The root, if any.
    pub fn root(&self) -> Option<Node> {
        self.pairs.first().map(|p| p.node(0))
    }

    /// The two children of interior node `n`.
    #[inline(always)]
    pub fn children(&self, n: &Node) -> [Node; 2] {
        self.pairs[n.offset as usize].nodes()
    }

    /// All nodes in use (the root and every pair after the first).
    pub fn nodes(&self) -> impl Iterator<Item = Node> + '_ {
        self.root()
            .into_iter()
            .chain(self.pairs.iter().skip(1).flat_map(|p| p.nodes()))
    }

    /// Number of nodes in use.
    pub fn node_count(&self) -> usize {
        if self.pairs.is_empty() {
            0
        } else {
            2 * self.pairs.len() - 1
        }
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes().filter(|n| n.is_leaf()).count()
    }

    /// SAH cost of the tree (traversal cost 1 per interior node, 1 per triangle, weighted by
    /// area relative to the root): a deterministic quality measure for comparing builds.
    pub fn sah_cost(&self) -> f64 {
        let Some(root) = self.root() else {
            return 0.0;
        };
        let ra = root.bounds().surface_area() as f64;
        // Also catches NaN (flat or empty root).
        if ra.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return 0.0;
        }
        self.nodes()
            .map(|n| {
                let a = n.bounds().surface_area() as f64 / ra;
                if n.is_leaf() {
                    a * n.count as f64
                } else {
                    a
                }
            })
            .sum()
    }

    /// Maximum depth (root at 0).
    pub fn depth(&self) -> usize {
        fn rec(bvh: &Bvh, n: &Node) -> usize {
            if n.is_leaf() {
                0
            } else {
                let [l, r] = bvh.children(n);
                1 + rec(bvh, &l).max(rec(bvh, &r))
            }
        }
        self.root().map_or(0, |r| rec(self, &r))
    }

    /// Checks the invariants against the primitives it was built from: pair offsets in range
    /// and in depth-first order (every pair reached exactly once from the root, a node's
    /// children's pair allocated before its left subtree's); every box contains its children's
    /// boxes; depth below [`MAX_DEPTH`]; leaf ranges tile the ids in order. Without split
    /// references every primitive id appears exactly once and every leaf box contains its
    /// primitives' boxes; with them, every primitive appears at least once, each of its leaves'
    /// boxes meets its box, and those leaves' boxes cover its box: the bounding box of their
    /// parts inside it is its box, and every point of a 5×5×5 lattice over its box (corners and
    /// faces included) lies in one of them (a lost part shows as a gap).
    pub fn validate(&self, prims: &(impl BoxSource + ?Sized)) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("bvh invalid: {m}")));
        let n = prims.len();
        let split = self.has_split_references();
        if self.prims != n || self.ids.len() < n {
            return bad(format!(
                "{} ids for {n} primitives (built over {})",
                self.ids.len(),
                self.prims
            ));
        }
        let Some(root) = self.root() else {
            return if n == 0 {
                Ok(())
            } else {
                bad("no nodes".into())
            };
        };
        let mut seen = vec![false; n];
        for (k, &id) in self.ids.iter().enumerate() {
            let id = id as usize;
            if id >= n || (std::mem::replace(&mut seen[id], true) && !split) {
                return bad(format!("id {id} at position {k} out of range or repeated"));
            }
        }
        if let Some(id) = seen.iter().position(|s| !s) {
            return bad(format!("primitive {id} is in no leaf"));
        }
        // With split references: per primitive, its leaves' boxes clipped to its box.
        let mut parts: Vec<Vec<Aabb>> = if split {
            vec![Vec::new(); n]
        } else {
            Vec::new()
        };
        let mut next_pair = 1usize;
        let mut next_pos = 0usize;
        let mut stack = vec![(root, 0usize)];
        while let Some((node, depth)) = stack.pop() {
            if depth >= MAX_DEPTH {
                return bad(format!("node at depth {depth} >= {MAX_DEPTH}"));
            }
            let b = node.bounds();
            if node.is_leaf() {
                let (o, c) = (node.offset as usize, node.count as usize);
                if o != next_pos || o + c > self.ids.len() {
                    return bad(format!("leaf range {o}+{c}, expected start {next_pos}"));
                }
                next_pos += c;
                for k in o..o + c {
                    let id = self.ids[k] as usize;
                    let tb = prims.bounds(id);
                    if split {
                        let part = b.intersection(tb);
                        if part.is_empty() {
                            return bad(format!("leaf box {b:?} misses primitive box {tb:?}"));
                        }
                        parts[id].push(part);
                    } else if !b.contains_box(&tb) {
                        return bad(format!("leaf box {b:?} misses primitive box {tb:?}"));
                    }
                }
            } else {
                let p = node.offset as usize;
                if p != next_pair || p >= self.pairs.len() {
                    return bad(format!("children at pair {p}, expected {next_pair}"));
                }
                next_pair += 1;
                let [l, r] = self.pairs[p].nodes();
                for c in [l, r] {
                    if !b.contains_box(&c.bounds()) {
                        return bad(format!("pair {p}: a child's box is outside its parent's"));
                    }
                }
                stack.push((r, depth + 1));
                stack.push((l, depth + 1));
            }
        }
        if next_pair != self.pairs.len() || next_pos != self.ids.len() {
            return bad(format!(
                "reached {next_pair} of {} pairs, {next_pos} of {} ids",
                self.pairs.len(),
                self.ids.len()
            ));
        }
        for (id, ps) in parts.iter().enumerate() {
            let b = prims.bounds(id);
            let hull = ps.iter().fold(Aabb::EMPTY, |u, p| u.union(*p));
            if hull != b {
                return bad(format!("the leaves of primitive {id} reach only {hull:?}"));
            }
            if ps.len() > 1 {
                const K: usize = 5;
                let at = |i: usize, a: usize| {
                    let f = i as f32 / (K - 1) as f32;
                    (b.min[a] + (b.max[a] - b.min[a]) * f).clamp(b.min[a], b.max[a])
                };
                for (i, j, k) in (0..K * K * K).map(|x| (x % K, x / K % K, x / (K * K))) {
                    let q = Vec3::new(at(i, 0), at(j, 1), at(k, 2));
                    if !ps.iter().any(|p| p.contains(q)) {
                        return bad(format!("the leaves of primitive {id} leave {q} uncovered"));
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
