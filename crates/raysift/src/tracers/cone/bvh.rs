//! Cone traversal of the shared BVH (§3 "BVH Traversal", Listing 2, Fig. 5 and 6).
//!
//! Both children of an interior node are tested with the cone-frustum/box test
//! ([`ConeFrustum`]; [`BoxTest::Basic`] one box at a time, [`BoxTest::Improved`] both at once),
//! which gives each a range `[t_min, t_max]` containing the `t` of every triangle the exact test
//! accepts inside it (conservative: `geom/cone_frustum/tests.rs`). A child is entered only if
//! `t_max ≥ t_near` and `t_min ≤ bound` (`t_n` once the list holds `n`, else `t_far`); both
//! rules are exact, because a triangle's `t` lies in its leaf's range and in every ancestor's.
//! - [`Traversal::Stack`]: depth first, the child with the smaller `t_min` first, the other on
//!   a fixed stack with its `t_min`, re-checked against the bound when popped.
//! - [`Traversal::Sorted`]: every entered node's children go into a min-heap on `t_min`; the
//!   walk stops at the first node beyond the bound (the exact early-out of the node-sorted
//!   traversal: nothing later can start nearer).

use super::{
    offer, walk, BoxTest, ConeBatch, ConeCounts, ConeHits, ConeTracer, Nearest, Prepared, Query,
    Traversal, Walker,
};
use crate::accel::bvh::{BuildConfig, Bvh, Node, SpatialConfig, MAX_DEPTH};
use crate::error::Result;
use crate::geom::ConeFrustum;
use crate::scene::{Scene, Stamp, TriangleSoup};
use crate::tracer::Stats;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

crate::counters! {
    /// What a prepare built.
    pub struct BuiltCounts {
        /// BVH nodes.
        nodes,
        /// BVH leaves.
        leaves,
        /// Triangle references in the leaves (more than the triangles after spatial splits).
        references,
        /// Nodes split by a plane (the SBVH build).
        spatial_splits,
    }
}

/// The paper's build: 32 bins, at most 8 triangles per leaf (§4). [`ConeBvh::new`] builds it
/// without spatial splits, [`ConeBvh::spatial`] with them (the paper's SBVH; references cut by
/// boxes, `accel/bvh/sbvh.rs`), see BENCHMARKS.md.
pub fn paper_build() -> BuildConfig {
    BuildConfig {
        bins: 32,
        max_leaf: 8,
        ..BuildConfig::default()
    }
}

/// A BVH over the scene and a way to walk it.
#[derive(Debug)]
pub struct ConeBvh {
    traversal: Traversal,
    box_test: BoxTest,
    build: BuildConfig,
    spatial: Option<SpatialConfig>,
    bvh: Bvh,
    stamp: Stamp,
}

impl ConeBvh {
    /// Walks with `traversal` and `box_test`, built with [`paper_build`].
    pub fn new(traversal: Traversal, box_test: BoxTest) -> Self {
        Self::with_build(traversal, box_test, paper_build())
    }

    /// With another build.
    pub fn with_build(traversal: Traversal, box_test: BoxTest, build: BuildConfig) -> Self {
        Self {
            traversal,
            box_test,
            build,
            spatial: None,
            bvh: Bvh::default(),
            stamp: Stamp::default(),
        }
    }

    /// The SBVH: [`paper_build`] with spatial splits (Stich et al.'s α = 10⁻⁵).
    pub fn spatial(traversal: Traversal, box_test: BoxTest) -> Self {
        Self::with_spatial(traversal, box_test, paper_build(), SpatialConfig::default())
    }

    /// With another build, with spatial splits.
    pub fn with_spatial(
        traversal: Traversal,
        box_test: BoxTest,
        build: BuildConfig,
        spatial: SpatialConfig,
    ) -> Self {
        Self {
            spatial: Some(spatial),
            ..Self::with_build(traversal, box_test, build)
        }
    }

    /// The tree.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }
}

/// The tree and the modes, borrowed for one trace.
struct Walk<'a, const SORTED: bool, const IMPROVED: bool> {
    bvh: &'a Bvh,
}

/// Stack entry: a node and its `t_min` (the node is copied: 32 bytes, one cache line's half).
type Entry = (Node, f32);

/// Per-thread scratch: the stack (depth bounded by [`MAX_DEPTH`]) and the heap.
#[derive(Default)]
pub struct BvhScratch {
    stack: Vec<Entry>,
    heap: BinaryHeap<(Reverse<u32>, u32, u8)>,
}

impl<const SORTED: bool, const IMPROVED: bool> Walk<'_, SORTED, IMPROVED> {
    /// Ranges of both children of interior node `n`.
    #[inline(always)]
    fn children(&self, f: &ConeFrustum, n: &Node, c: &mut ConeCounts) -> [Option<(f32, f32)>; 2] {
        c.box_tests += 2;
        let pair = &self.bvh.pairs[n.offset as usize];
        if IMPROVED {
            f.interval2(&pair.boxes)
        } else {
            [0, 1].map(|i| {
                let (lo, hi) = pair.boxes.get(i);
                f.interval_basic(lo, hi)
            })
        }
    }

    #[inline(always)]
    fn keep(r: Option<(f32, f32)>, list: &Nearest) -> Option<f32> {
        r.filter(|&(lo, hi)| hi >= list.t_near() && lo <= list.bound())
            .map(|r| r.0)
    }
}

impl<const SORTED: bool, const IMPROVED: bool> Walker for Walk<'_, SORTED, IMPROVED> {
    type Scratch = BvhScratch;

    fn walk(
        &self,
        soup: &TriangleSoup,
        cone: &Prepared,
        list: &mut Nearest,
        count_only: bool,
        s: &mut BvhScratch,
        c: &mut ConeCounts,
    ) {
        let Some(root) = self.bvh.root() else {
            return;
        };
        c.box_tests += 1;
        let rr = if IMPROVED {
            cone.frustum.interval(root.min, root.max)
        } else {
            cone.frustum.interval_basic(root.min, root.max)
        };
        let Some(root_lo) = Self::keep(rr, list) else {
            return;
        };
        let leaf = |n: &Node, list: &mut Nearest, c: &mut ConeCounts| {
            for k in n.offset..n.offset + n.count as u32 {
                offer(soup, self.bvh.ids[k as usize], cone, list, count_only, c);
            }
        };
        if SORTED {
            // Heap of (t_min bits, pair, slot): t_min ≥ 0, so its bits order like the value.
            s.heap.clear();
            s.heap.push((Reverse(root_lo.to_bits()), 0, 0));
            while let Some((Reverse(lo), pair, slot)) = s.heap.pop() {
                if f32::from_bits(lo) > list.bound() {
                    break; // every node left starts at least as far
                }
                let n = self.bvh.pairs[pair as usize].node(slot as usize);
                c.nodes += 1;
                if n.is_leaf() {
                    leaf(&n, list, c);
                    continue;
                }
                let r = self.children(&cone.frustum, &n, c);
                for (i, ri) in r.into_iter().enumerate() {
                    if let Some(lo) = Self::keep(ri, list) {
                        s.heap.push((Reverse(lo.to_bits()), n.offset, i as u8));
                    }
                }
            }
            return;
        }
        s.stack.clear();
        if s.stack.capacity() < 2 * MAX_DEPTH {
            s.stack.reserve(2 * MAX_DEPTH);
        }
        let mut node = root;
        loop {
            c.nodes += 1;
            let mut next = None;
            if node.is_leaf() {
                leaf(&node, list, c);
            } else {
                let r = self.children(&cone.frustum, &node, c);
                let [a, b] = self.bvh.children(&node);
                match (Self::keep(r[0], list), Self::keep(r[1], list)) {
                    (Some(la), Some(lb)) => {
                        let (near, far) = if lb < la {
                            ((b, lb), (a, la))
                        } else {
                            ((a, la), (b, lb))
                        };
                        s.stack.push(far);
                        next = Some(near.0);
                    }
                    (Some(_), None) => next = Some(a),
                    (None, Some(_)) => next = Some(b),
                    (None, None) => {}
                }
            }
            if next.is_none() {
                while let Some((n, lo)) = s.stack.pop() {
                    if lo <= list.bound() {
                        next = Some(n);
                        break;
                    }
                }
            }
            match next {
                Some(n) => node = n,
                None => return,
            }
        }
    }
}

impl ConeTracer for ConeBvh {
    fn name(&self) -> String {
        let t = match self.traversal {
            Traversal::Stack => "stack",
            Traversal::Sorted => "sorted",
        };
        let b = match self.box_test {
            BoxTest::Basic => "basic",
            BoxTest::Improved => "improved",
        };
        let s = if self.spatial.is_some() {
            "sbvh"
        } else {
            "bvh"
        };
        format!("{s}/{t}/{b}")
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        let mut spatial_splits = 0;
        self.bvh = match &self.spatial {
            None => Bvh::build(scene.triangles(), &self.build)?,
            Some(sp) => {
                let (t, st) = Bvh::build_spatial(scene.triangles(), &self.build, sp)?;
                spatial_splits = st.spatial_splits;
                t
            }
        };
        self.stamp = scene.stamp();
        let built = BuiltCounts {
            nodes: self.bvh.node_count() as u64,
            leaves: self.bvh.leaf_count() as u64,
            references: self.bvh.ids.len() as u64,
            spatial_splits,
        };
        Ok(Stats::prepared(&built, self.bvh.bytes()))
    }

    fn trace(
        &self,
        scene: &Scene,
        cones: &ConeBatch,
        q: &Query,
        out: &mut ConeHits,
    ) -> Result<Stats> {
        self.stamp.check(scene, "cone bvh")?;
        let soup = scene.triangles();
        let bvh = &self.bvh;
        Ok(match (self.traversal, self.box_test) {
            (Traversal::Stack, BoxTest::Basic) => {
                walk(&Walk::<false, false> { bvh }, soup, cones, q, out)
            }
            (Traversal::Stack, BoxTest::Improved) => {
                walk(&Walk::<false, true> { bvh }, soup, cones, q, out)
            }
            (Traversal::Sorted, BoxTest::Basic) => {
                walk(&Walk::<true, false> { bvh }, soup, cones, q, out)
            }
            (Traversal::Sorted, BoxTest::Improved) => {
                walk(&Walk::<true, true> { bvh }, soup, cones, q, out)
            }
        })
    }

    fn bytes(&self) -> usize {
        self.bvh.bytes()
    }
}
