//! `bvh`: a static binned-SAH bounding volume hierarchy, the baseline the papers compare against.
//!
//! **Build**: binned SAH (Wald 2007, "On fast construction of SAH-based bounding volume
//! hierarchies"): centroids binned into [`Config::bins`] slots on each axis, the split with the
//! lowest SAH cost taken, a leaf made when a node has at most [`Config::max_leaf`] triangles and
//! the SAH says splitting does not pay. Parallel with rayon above [`Config::parallel_threshold`]
//! triangles (see `build`). Identical centroids, flat nodes and very deep trees fall back to object
//! median splits, so any soup builds and the depth is bounded.
//!
//! **Traversal**: as pbrt's `BVHAggregate` (flat depth-first array, fixed stack, near child
//! first), except that both children's boxes are tested at their parent with one 4-wide SIMD slab
//! test ([`SlabRay::entry2`](crate::geom::SlabRay::entry2), SSE2 on x86_64, bit for bit the scalar
//! [`SlabRay::entry`](crate::geom::SlabRay::entry) on each box), the nearer hit one (by entry
//! distance) is visited next and the other pushed with its entry, and a popped node whose entry
//! lies beyond the current hit is skipped (tinybvh's BVH2 order). Ordering by the ray's sign on
//! the split axis instead gave the same work within 3% (sphere:1M, random rays) and no measurable
//! time difference, so the distance order (free once both boxes are tested) is kept.
//! The box test is conservative at both ends, and the cull is inclusive (a box entered exactly at
//! the best `t` is still visited): together with the shared triangle test and
//! [`closer`](crate::tracer::closer) this makes every answer equal to `naive`'s bit for bit
//! (without the lowered entry, the tests do find lost hits on the Cornell box's walls).
//!
//! A big scene's traversal is bound by memory latency (one dependent cache miss per level), not
//! arithmetic: the 4-wide box test alone changed nothing measurable on sphere:1M. So when the
//! tree is bigger than [`AUTO_LANES_BYTES`] each thread keeps 8 rays in flight
//! ([`Config::lanes`]), advancing each by one node per round and prefetching the node (pair or
//! leaf triangles) it will visit next, so the misses of different rays overlap (software
//! pipelining across rays; each ray's walk, work counts and answer are unchanged). On sphere:1M
//! (one thread, 2-vCPU VM shared with other jobs) this took random rays from about 0.55 to
//! 1.0–1.4 Mrays per CPU-second (occlusion 0.6 to 1.3–1.6); coherent camera rays gained little
//! (2.2–2.4 to 2.3–2.6, within noise). Smaller trees use `lanes=1`, the one-ray-at-a-time walk,
//! instantiated per ray octant so the near/far plane choice is compile-time.
//! Open: on sphere:1M camera rays this one-ray walk measured 2.1–2.5 Mrays per CPU-second
//! against 2.3–2.8 for the previous scalar-AoS walk (alternating runs, noisy shared VM): a
//! possible 5–15% regression for coherent rays that the SIMD test did not pay back; a
//! branch-mask (non-octant) variant was no better.
//!
//! **Memory layout** (bytes per triangle; [`Bvh::bytes`]):
//! - nodes: 32 B each (box, child-pair/first-triangle offset, count, axis), stored as sibling
//!   pairs in one 64-byte cache line ([`NodePair`]: both boxes as structure of arrays, 48 B, then
//!   both offsets, counts and axes; [`Node`] is the unpacked view), since traversal reads and
//!   tests both children together; with the defaults 1.16 nodes per triangle (leaves of 1.7 triangles on average),
//!   about 37 B per triangle (`traversal_cost=2`: 0.7 nodes, 22 B; 62 B in all);
//! - triangle ids in leaf order: 4 B;
//! - the triangles' corners copied in leaf order (`[v0, v1, v2]`, 36 B, array of structures: a leaf
//!   reads one contiguous run instead of gathering from the scene's soup);
//!
//! so about 77 B per triangle (measured on sphere:1M and soup:1M) on top of the scene's own 36 B
//! soup. The build temporarily holds 32 B per triangle of primitive references.

mod build;
#[cfg(test)]
mod tests;
mod traverse;

pub use build::{MAX_BINS, MAX_DEPTH};

use crate::error::{Error, Result};
use crate::geom::{Aabb, BoxPair};
use crate::rays::{HitBatch, RayBatch};
use crate::scene::Scene;
use crate::tracer::{par_occlusion_chunks, par_ray_chunks, Stats, Tracer};
use glam::Vec3;
use serde::Deserialize;
use std::sync::Arc;

/// Rays per parallel task (as `naive`): amortises scheduling, balances 2–64 cores.
const CHUNK: usize = 256;

/// Tree size (bytes, [`Bvh::bytes`]) above which `lanes=0` traces 8 rays in flight.
pub const AUTO_LANES_BYTES: usize = 4 << 20;

/// Build options (`bvh:key=value` on the command line). Defaults are the fields' documented values.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Bins per axis for the SAH sweep (2..=32). Default 16: within about 1% of the cost of a full
    /// sweep on our scenes at a fraction of the build time (Wald 2007 uses 16–32).
    pub bins: usize,
    /// Most triangles in a leaf (1..=255); nodes at or below it become leaves when the SAH says
    /// splitting costs more. Default 4.
    pub max_leaf: usize,
    /// SAH cost of visiting an interior node (two box tests), relative to `intersection_cost`.
    /// Default 1.0.
    pub traversal_cost: f32,
    /// SAH cost of one ray/triangle test. Default 1.0.
    pub intersection_cost: f32,
    /// Nodes with at least this many triangles build their children in parallel and bin in
    /// parallel. Default 4096: below it, task overhead outweighs the work.
    pub parallel_threshold: usize,
    /// Rays traced in flight per thread (0..=16): each round advances each by one node and
    /// prefetches its next node, so their cache misses overlap (see the module doc). 1 traces
    /// one ray at a time with a walk specialised per ray octant. Default 0, automatic: 8 when
    /// the tree is bigger than [`AUTO_LANES_BYTES`] (it no longer fits in cache, so misses
    /// dominate), else 1 (in cache the interleaving's bookkeeping and mixed branch history cost
    /// more than it saves: sphere:10k camera rays 5.0 vs 3.9 Mrays per CPU-second).
    pub lanes: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            bins: 16,
            max_leaf: 4,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            parallel_threshold: 4096,
            lanes: 0,
        }
    }
}

impl Config {
    /// Checks the ranges documented on the fields.
    pub fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("tracer bvh: {m}")));
        if !(2..=MAX_BINS).contains(&self.bins) {
            return bad(format!("bins must be in 2..={MAX_BINS}, got {}", self.bins));
        }
        if !(1..=255).contains(&self.max_leaf) {
            return bad(format!(
                "max_leaf must be in 1..=255, got {}",
                self.max_leaf
            ));
        }
        if self.lanes > traverse::MAX_LANES {
            return bad(format!(
                "lanes must be in 0..={}, got {}",
                traverse::MAX_LANES,
                self.lanes
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
    fn leaf(b: Aabb, first: u32, count: u16) -> Self {
        Self {
            min: b.min,
            max: b.max,
            offset: first,
            count,
            axis: 0,
            _pad: 0,
        }
    }

    fn interior(b: Aabb, axis: u8, pair: u32) -> Self {
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

/// The built hierarchy: node pairs, ids and triangle copies in leaf order.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// Node pairs in depth-first order of their parents: pair 0 holds the root in slot 0 (slot 1
    /// unused); empty when the scene has no triangles.
    pub pairs: Vec<NodePair>,
    /// Triangle id at each leaf position.
    pub ids: Vec<u32>,
    /// Corners of the triangle at each leaf position (a copy of the scene's soup).
    pub tris: Vec<[Vec3; 3]>,
}

impl Bvh {
    /// Builds over the scene's world soup.
    pub fn build(scene: &Scene, cfg: &Config) -> Result<Self> {
        cfg.check()?;
        let soup = scene.triangles();
        let b = build::build(soup, cfg);
        let tris = {
            use rayon::prelude::*;
            b.ids.par_iter().map(|&i| soup.get(i as usize)).collect()
        };
        let mut bvh = Self {
            pairs: b.pairs,
            ids: b.ids,
            tris,
        };
        // Collecting may over-allocate; the tree lives long, so hand the slack back.
        bvh.pairs.shrink_to_fit();
        bvh.ids.shrink_to_fit();
        bvh.tris.shrink_to_fit();
        Ok(bvh)
    }

    /// Bytes held (nodes + ids + triangle copies).
    pub fn bytes(&self) -> usize {
        self.pairs.capacity() * std::mem::size_of::<NodePair>()
            + self.ids.capacity() * 4
            + self.tris.capacity() * std::mem::size_of::<[Vec3; 3]>()
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

    /// Checks the invariants against the scene it was built from: pair offsets in range and in
    /// depth-first order (every pair reached exactly once from the root, a node's children's
    /// pair allocated before its left subtree's); every box contains its children's boxes and its
    /// triangles' boxes; depth below [`MAX_DEPTH`]; leaf ranges tile `0..n` in order, so every
    /// triangle id appears exactly once; the triangle copies equal the scene's corners.
    pub fn validate(&self, scene: &Scene) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("bvh invalid: {m}")));
        let soup = scene.triangles();
        let n = soup.len();
        if self.ids.len() != n || self.tris.len() != n {
            return bad(format!(
                "{} ids, {} copies for {n} triangles",
                self.ids.len(),
                self.tris.len()
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
            if id >= n || std::mem::replace(&mut seen[id], true) {
                return bad(format!("id {id} at position {k} out of range or repeated"));
            }
            if self.tris[k] != soup.get(id) {
                return bad(format!("copy at position {k} differs from triangle {id}"));
            }
        }
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
                if o != next_pos || o + c > n {
                    return bad(format!("leaf range {o}+{c}, expected start {next_pos}"));
                }
                next_pos += c;
                for k in o..o + c {
                    let tb = soup.bounds(self.ids[k] as usize);
                    if !b.contains_box(&tb) {
                        return bad(format!("leaf box {b:?} misses triangle box {tb:?}"));
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
        if next_pair != self.pairs.len() || next_pos != n {
            return bad(format!(
                "reached {next_pair} of {} pairs, {next_pos} of {n} triangles",
                self.pairs.len()
            ));
        }
        Ok(())
    }
}

/// The `bvh` tracer: a [`Bvh`] rebuilt from scratch at every prepare.
#[derive(Default)]
pub struct BvhTracer {
    cfg: Config,
    bvh: Bvh,
}

impl BvhTracer {
    /// A tracer with `cfg` and no scene yet (every ray misses until prepare).
    pub fn new(cfg: Config) -> Result<Self> {
        cfg.check()?;
        Ok(Self {
            cfg,
            bvh: Bvh::default(),
        })
    }

    /// The current hierarchy.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Rays in flight per thread for the current tree ([`Config::lanes`], 0 resolved).
    pub fn lanes(&self) -> usize {
        match self.cfg.lanes {
            0 if self.bvh.bytes() > AUTO_LANES_BYTES => 8,
            0 => 1,
            l => l,
        }
    }
}

impl Tracer for BvhTracer {
    fn name(&self) -> &'static str {
        "bvh"
    }

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<Stats> {
        // Drop the old tree first so peak memory is one tree, not two.
        self.bvh = Bvh::default();
        self.bvh = Bvh::build(&scene, &self.cfg)?;
        Ok(Stats {
            nodes: self.bvh.node_count() as u64,
            leaves: self.bvh.leaf_count() as u64,
            peak_bytes: self.bvh.bytes() as u64,
            ..Stats::default()
        })
    }

    fn intersect(&self, rays: &RayBatch, hits: &mut HitBatch) -> Stats {
        let lanes = self.lanes();
        par_ray_chunks(rays, hits, CHUNK, |range, out| {
            if lanes == 1 {
                traverse::closest_chunk(&self.bvh, rays, range, out)
            } else {
                traverse::closest_chunk_interleaved(&self.bvh, rays, range, lanes, out)
            }
        })
    }

    fn occluded(&self, rays: &RayBatch, occluded: &mut Vec<bool>) -> Stats {
        let lanes = self.lanes();
        par_occlusion_chunks(rays, occluded, CHUNK, |range, out| {
            if lanes == 1 {
                traverse::occluded_chunk(&self.bvh, rays, range, out)
            } else {
                traverse::occluded_chunk_interleaved(&self.bvh, rays, range, lanes, out)
            }
        })
    }

    fn bytes(&self) -> usize {
        self.bvh.bytes()
    }
}
