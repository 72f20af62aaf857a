//! Cone traversal of the shared SAH kd-tree (§3 "Standard Stack-based k-d Tree Traversal",
//! Listing 1, Fig. 2 and 3; Tsakok's cone/split-plane distances, Eq. 2).
//!
//! **The cone on one side of a split.** At axial distance `t` the cone's extent along axis `k`
//! is `[o_k + t·a_k, o_k + t·b_k]` with the edge slopes `a_k ≤ b_k` of Eq. 2's denominators
//! (`d_k ∓ tan α·√(1 − d_k²)`, the same conservatively rounded slopes as the cone-frustum/box
//! test, [`crate::geom::ConeFrustum::slopes`]). With `c = s − o_k` for a split at `s`, the cone
//! reaches the **below** cell (`x_k ≤ s`) exactly at the `t` with `t·a_k ≤ c`, and the **above**
//! cell (`x_k ≥ s`) at the `t` with `t·b_k ≥ c`: each is one bound on `t` (an upper one, a lower
//! one, or all-or-nothing when the slope is 0). A node carries the range `[t_min, t_max]` of the
//! axial distances of the cone's points inside its cell; a child's range is the parent's cut by
//! that one bound. This is Listing 1's `t_1, t_2` rule (front child `[t_min, min(t_max, t_2)]`,
//! back child `[max(t_1, t_min), t_max]`) written per side, which also settles the cases the
//! listing leaves open: an apex on the split plane, edges parallel to it (`d_k ± β_k = 0`: no
//! division, the slope's sign decides) and cones heading away from a plane (Listing 1 maps
//! negative plane distances to +∞; here a negative bound is simply not binding, or empties the
//! side).
//!
//! **Exact.** Each bound is `c / slope` in f32, as the box test computes a box plane's distance,
//! and the culls use the range widened by the box test's 4 ulps ([`crate::geom::ConeFrustum`]'s
//! module doc: slopes rounded outwards, two roundings per distance), so a node's widened range
//! contains the `t` the exact cone/triangle test gives any point of the cone in its cell — a
//! range built from more planes than the cell's six is only tighter, and every ancestor's plane
//! bounds the cell too. A triangle's answer point (the nearest point of it inside the cone) lies
//! in its box, and so in a leaf cell the build made reference it (every cell its box meets,
//! `accel/kdtree`): that leaf is reached unless its range starts beyond the bound, in which case
//! the triangle's `t` is beyond it too. The push/pop rule is the BVH walker's: enter when
//! `t_max ≥ t_near` and `t_min ≤ bound` (`t_n` once `n` are held, else `t_far`; inclusive for
//! ties by id). A triangle referenced by several leaves is offered again and ignored by the list.
//!
//! **Order.** Both children entered: the one whose range starts nearer first (the paper's
//! "front", the apex's side, when the apex is off the plane; below first on a tie), the other on
//! the stack as `(node, t_min, t_max)`: 12 bytes, as the paper notes (the 8-byte ray variant
//! does not apply to cones, §3). [`Traversal::Sorted`] keeps a min-heap on `t_min` instead and
//! stops at the first node beyond the bound.
//!
//! **Build.** [`paper_build`]: pbrt-v3's kd-tree cost model, the structure the paper names
//! ("similar to Pharr et al. 2016": intersection cost 80, traversal 1, empty bonus 0.5, depth
//! `8 + 1.3·log₂ N`), with the paper's stop at ≤ 8 triangles per leaf (§4, said of both of its
//! structures) where pbrt-v3 splits down to one; any [`BuildConfig`] can be given.

use super::{
    offer, walk, ConeBatch, ConeCounts, ConeHits, ConeTracer, Nearest, Prepared, Query, Traversal,
    Walker,
};
use crate::accel::kdtree::{BuildConfig, KdTree, MAX_DEPTH};
use crate::error::Result;
use crate::scene::{Scene, Stamp, TriangleSoup};
use crate::tracer::Stats;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

crate::counters! {
    /// What a prepare built.
    pub struct BuiltCounts {
        /// Interior nodes.
        interior,
        /// Leaves (empty ones included).
        leaves,
        /// Triangle references in leaves.
        refs,
        /// Deepest leaf.
        depth,
    }
}

/// pbrt-v3's kd-tree build (module doc), the paper's.
pub fn paper_build() -> BuildConfig {
    BuildConfig {
        traversal_cost: 1.0,
        intersection_cost: 80.0,
        empty_bonus: 0.5,
        max_leaf: 8,
        max_depth: 0,
        ..BuildConfig::default()
    }
}

/// Relative widening of a range before it is compared (the box test's, module doc).
const WIDEN: f32 = 4.0 * f32::EPSILON;

/// A raw range `[lo, hi]` (unwidened, `lo ≥ +0`).
#[derive(Clone, Copy, Debug)]
struct Range {
    lo: f32,
    hi: f32,
}

impl Range {
    const ALL: Range = Range {
        lo: 0.0,
        hi: f32::INFINITY,
    };

    /// Cut by `t·e ≤ g` (below a plane: `e = a_k, g = c`; above: `e = −b_k, g = −c`, so the
    /// division is the box test's `c / b_k` bit for bit).
    #[inline(always)]
    fn cut(self, e: f32, g: f32) -> Range {
        let mut r = self;
        if e > 0.0 {
            r.hi = r.hi.min(g / e);
        } else if e < 0.0 {
            // `+ 0.0`: a −0 bound becomes +0, so `lo`'s bits order like its value.
            r.lo = r.lo.max(g / e) + 0.0;
        } else if g < 0.0 {
            // The cone never reaches this side: empty (and stays empty under later cuts).
            (r.lo, r.hi) = (f32::INFINITY, f32::NEG_INFINITY);
        }
        r
    }

    /// The widened `t_min` if the range may hold an eligible triangle of `list`.
    #[inline(always)]
    fn keep(self, list: &Nearest) -> Option<f32> {
        let (lo, hi) = (self.lo * (1.0 - WIDEN), self.hi * (1.0 + WIDEN));
        (lo <= hi && hi >= list.t_near() && lo <= list.bound()).then_some(lo)
    }
}

/// A kd-tree over the scene and a way to walk it.
#[derive(Debug)]
pub struct ConeKd {
    traversal: Traversal,
    build: BuildConfig,
    tree: KdTree,
    stamp: Stamp,
}

impl ConeKd {
    /// Walks with `traversal`, built with [`paper_build`].
    pub fn new(traversal: Traversal) -> Self {
        Self::with_build(traversal, paper_build())
    }

    /// With another build.
    pub fn with_build(traversal: Traversal, build: BuildConfig) -> Self {
        Self {
            traversal,
            build,
            tree: KdTree::default(),
            stamp: Stamp::default(),
        }
    }

    /// The tree.
    pub fn tree(&self) -> &KdTree {
        &self.tree
    }
}

/// Stack entry: node index and its raw range (12 bytes).
type Entry = (u32, Range);

/// Per-thread scratch: the stack (at most one entry per level) and the heap of
/// `(widened t_min bits, node, raw t_min bits, raw t_max bits)`.
#[derive(Default)]
pub struct KdScratch {
    stack: Vec<Entry>,
    heap: BinaryHeap<(Reverse<u32>, u32, u32, u32)>,
}

struct Walk<'a, const SORTED: bool> {
    tree: &'a KdTree,
}

impl<const SORTED: bool> Walk<'_, SORTED> {
    /// The ranges of the below and above children of interior node `i` (range `r`).
    #[inline(always)]
    fn children(&self, i: usize, r: Range, cone: &Prepared, c: &mut ConeCounts) -> [Range; 2] {
        let n = self.tree.nodes[i];
        let k = n.axis();
        let (a, b) = cone.frustum.slopes(k);
        let cc = n.split() - cone.frustum.apex()[k];
        c.plane_tests += 1;
        [r.cut(a, cc), r.cut(-b, -cc)]
    }
}

impl<const SORTED: bool> Walker for Walk<'_, SORTED> {
    type Scratch = KdScratch;

    fn walk(
        &self,
        soup: &TriangleSoup,
        cone: &Prepared,
        list: &mut Nearest,
        count_only: bool,
        s: &mut KdScratch,
        c: &mut ConeCounts,
    ) {
        let tree = self.tree;
        if tree.bounds.is_empty() {
            return;
        }
        // The root cell: above its min planes, below its max planes.
        c.box_tests += 1;
        let mut root = Range::ALL;
        let o = cone.frustum.apex();
        for k in 0..3 {
            let (a, b) = cone.frustum.slopes(k);
            root = root
                .cut(-b, -(tree.bounds.min[k] - o[k]))
                .cut(a, tree.bounds.max[k] - o[k]);
        }
        let Some(root_lo) = root.keep(list) else {
            return;
        };
        let leaf = |i: usize, list: &mut Nearest, c: &mut ConeCounts| {
            for &id in tree.leaf_ids(tree.nodes[i]) {
                offer(soup, id, cone, list, count_only, c);
            }
        };
        if SORTED {
            s.heap.clear();
            s.heap.push((
                Reverse(root_lo.to_bits()),
                0,
                root.lo.to_bits(),
                root.hi.to_bits(),
            ));
            while let Some((Reverse(lo), i, rlo, rhi)) = s.heap.pop() {
                if f32::from_bits(lo) > list.bound() {
                    break; // every node left starts at least as far
                }
                c.nodes += 1;
                let i = i as usize;
                if tree.nodes[i].is_leaf() {
                    leaf(i, list, c);
                    continue;
                }
                let r = Range {
                    lo: f32::from_bits(rlo),
                    hi: f32::from_bits(rhi),
                };
                let kids = [i as u32 + 1, tree.nodes[i].above()];
                for (child, cr) in kids.into_iter().zip(self.children(i, r, cone, c)) {
                    if let Some(lo) = cr.keep(list) {
                        s.heap.push((
                            Reverse(lo.to_bits()),
                            child,
                            cr.lo.to_bits(),
                            cr.hi.to_bits(),
                        ));
                    }
                }
            }
            return;
        }
        s.stack.clear();
        if s.stack.capacity() < MAX_DEPTH + 1 {
            s.stack.reserve(MAX_DEPTH + 1);
        }
        let (mut i, mut r) = (0usize, root);
        loop {
            c.nodes += 1;
            let mut next = None;
            let n = tree.nodes[i];
            if n.is_leaf() {
                leaf(i, list, c);
            } else {
                let [rb, ra] = self.children(i, r, cone, c);
                let (below, above) = (i as u32 + 1, n.above());
                match (rb.keep(list), ra.keep(list)) {
                    (Some(lb), Some(la)) => {
                        let (near, far) = if la < lb {
                            ((above, ra), (below, rb))
                        } else {
                            ((below, rb), (above, ra))
                        };
                        s.stack.push(far);
                        next = Some(near);
                    }
                    (Some(_), None) => next = Some((below, rb)),
                    (None, Some(_)) => next = Some((above, ra)),
                    (None, None) => {}
                }
            }
            if next.is_none() {
                while let Some(e) = s.stack.pop() {
                    if e.1.keep(list).is_some() {
                        next = Some(e);
                        break;
                    }
                }
            }
            match next {
                Some((ni, nr)) => (i, r) = (ni as usize, nr),
                None => return,
            }
        }
    }
}

impl ConeTracer for ConeKd {
    fn name(&self) -> String {
        match self.traversal {
            Traversal::Stack => "kdtree/stack".into(),
            Traversal::Sorted => "kdtree/sorted".into(),
        }
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        self.tree = KdTree::build(scene.triangles(), &self.build)?;
        self.stamp = scene.stamp();
        let shape = self.tree.shape();
        let built = BuiltCounts {
            interior: shape.interior as u64,
            leaves: shape.leaves as u64,
            refs: shape.refs as u64,
            depth: self.tree.depth as u64,
        };
        Ok(Stats::prepared(&built, self.tree.bytes()))
    }

    fn trace(
        &self,
        scene: &Scene,
        cones: &ConeBatch,
        q: &Query,
        out: &mut ConeHits,
    ) -> Result<Stats> {
        self.stamp.check(scene, "cone kdtree")?;
        let soup = scene.triangles();
        let tree = &self.tree;
        Ok(match self.traversal {
            Traversal::Stack => walk(&Walk::<false> { tree }, soup, cones, q, out),
            Traversal::Sorted => walk(&Walk::<true> { tree }, soup, cones, q, out),
        })
    }

    fn bytes(&self) -> usize {
        self.tree.bytes()
    }
}
