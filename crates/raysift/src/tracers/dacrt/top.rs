//! Ours: the top tree, the recursion's upper levels kept between calls for sparse batches.
//!
//! A call's cost has a floor that does not depend on its rays: the upper levels of the
//! recursion stream every triangle through a split-plane test, and a batch of incoherent rays
//! (a path tracer's deep bounces: a few hundred rays spread over the whole scene) keeps rays in
//! almost every cell down to about `1.5·log2(R)` levels, so it streams all `T` triangles about
//! that many times, whatever `R` is (657 bounce rays on the 871K dragon: 17.5M triangle/box
//! tests, 26 000 per ray). The splits of those levels (§3.6: the longest axis at the sampled
//! mean) depend only on the triangles, so they can be made once per scene state and reused:
//! the first ray batch without packets after a prepare that changed the scene (and of at most
//! `Config::top_below` rays per triangle) builds a tree of them down to lists of at most
//! `Config::top_leaf` triangles; every such call then filters its rays down this tree (ray/box
//! tests only: the same `Task::partition_rays`, the same visiting order and termination
//! bookkeeping as `Task::ray_rec`) and runs Algorithm 1 from each leaf its rays reach, on a
//! copy of the leaf's list.
//!
//! Exact for the same reason as the recursion itself: a leaf's list is what the recursion's
//! prefix partitions (`partition::partition_tris`, the same plane tests on the min/max lists,
//! the second child taking the first's rejects untested) would give that cell, the cells are
//! made by the same halvings of the same root box, and the rays reaching a leaf are those the
//! recursion would hand it. Only the shape changes: above the leaves no cell ends in a naive
//! leaf for having few rays, which costs ray/box tests, never answers.
//!
//! Memory, deterministic in `T` (the live, non-degenerate triangles): the lists get exactly
//! `⌊(1 + top_growth)·T⌋` entries of 4 bytes (a split whose children would overflow their
//! budget ends in a leaf; the budget is shared in proportion to the children's triangles, so
//! the leaves' lists sum to at most the root's), and the nodes exactly `4·⌈B / top_leaf⌉ + 1`
//! of 16 bytes for that budget `B` (shared the same way: a subtree given fewer than three
//! nodes is a leaf), so `4·(1 + g) + 64·(1 + g) / top_leaf` bytes per triangle: 12 at the
//! defaults, and nothing else: the build works inside the lists (each subtree in the stretch
//! of the budget it will own), so the two children of a large subtree are built at once on
//! `rayon`'s threads, into the same tree whatever their number (BENCHMARKS.md, § DACRT: random
//! and bounce rays). The depth is capped by `Config::max_depth`.

use super::partition::{gather_block, partition_tris};
use super::split::{choose_split, half, no_progress};
use super::{Config, Task};
use crate::geom::Aabb;
use crate::mem::reserve_exact_huge;

use super::order::Order;

/// A node: `axis < 3` is a split of `cell` on `axis` at `split`, children `a` (low) and `b`
/// (high); `axis == LEAF`: the list `lists[a..b]`.
#[derive(Clone, Copy, Debug, Default)]
struct Node {
    axis: u32,
    split: f32,
    a: u32,
    b: u32,
}

const LEAF: u32 = 3;

/// The top tree of one scene state (see the module doc).
#[derive(Debug, Default)]
pub(super) struct TopTree {
    nodes: Vec<Node>,
    lists: Vec<u32>,
    /// The box the build started from (the scene's bounds); every walk starts from it.
    pub(super) root: Aabb,
    /// Triangle/box tests the build spent (charged to the call that built it).
    pub(super) tests: u64,
}

impl TopTree {
    /// The tree over the live triangles of `span` in `root`.
    pub(super) fn build(cfg: &Config, span: [&[[f32; 2]]; 3], root: Aabb) -> TopTree {
        let huge = cfg.huge_pages;
        let n = span[0].iter().filter(|s| s[0] <= s[1]).count();
        let leaf = cfg.top_leaf.max(1);
        let budget = ((1.0 + cfg.top_growth.max(0.0)) * n as f64) as usize;
        let budget = budget.max(n);
        let node_cap = 4 * budget.div_ceil(leaf) + 1;
        let mut tree = TopTree {
            root,
            ..TopTree::default()
        };
        // The lists are also the build's working space: each subtree works in the stretch it
        // will own (see `Builder::node`), so the build needs nothing beside the tree.
        reserve_exact_huge(&mut tree.lists, budget, huge);
        tree.lists.extend(
            span[0]
                .iter()
                .enumerate()
                .filter(|(_, s)| s[0] <= s[1])
                .map(|(t, _)| t as u32),
        );
        tree.lists.resize(budget, 0);
        reserve_exact_huge(&mut tree.nodes, node_cap, huge);
        tree.nodes.resize(node_cap, Node::default());
        let b = Builder {
            cfg,
            span,
            leaf,
            depth_cap: cfg.max_depth,
        };
        tree.tests = b.node(&mut tree.nodes, 0, &mut tree.lists, 0, n, root, 0);
        tree
    }

    /// Bytes the tree holds (its capacities, as allocated).
    pub(super) fn bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>() + self.lists.capacity() * 4
    }
}

/// Subtrees of at least this many triangles build their two children in parallel (`rayon`;
/// the same tree whatever the number of threads: only who builds it changes).
const PAR_MIN: usize = 1 << 15;

struct Builder<'b> {
    cfg: &'b Config,
    span: [&'b [[f32; 2]]; 3],
    leaf: usize,
    depth_cap: u32,
}

impl Builder<'_> {
    /// The subtree of the triangles `list[..nt]` in `cell`, written into `nodes` (its node
    /// budget, `nodes[0]` itself, global index `node0`) and `list` (its list budget, global
    /// offset `list0`); returns the triangle/box tests it spent. The prefix scheme of
    /// `Task::ray_rec`, without rays.
    ///
    /// In place: the first child's list is the plane test's survivors `list[..nt0]`, and the
    /// second child's (the first's rejects, then the survivors that also lie on its side) is
    /// written at the start of its own budget `list[b0..]`, rejects first, moved right to end
    /// at `b0 + nt1` (`b0 ≥ nt0` and `nt1 ≥ nt − nt0`, so that is past `nt`), and the two-sided
    /// survivors before them (from `list[..nt0]` into `list[b0..]`: no overlap). Both
    /// children then own disjoint stretches and can be built at once.
    #[allow(clippy::too_many_arguments)]
    fn node(
        &self,
        nodes: &mut [Node],
        node0: usize,
        list: &mut [u32],
        list0: usize,
        nt: usize,
        cell: Aabb,
        depth: u32,
    ) -> u64 {
        let budget = list.len();
        let split = (nt > self.leaf && depth < self.depth_cap && nodes.len() >= 3)
            .then(|| choose_split(self.cfg, self.span, &list[..nt], &cell))
            .flatten();
        let Some((axis, split)) = split else {
            return self.leaf(nodes, list0, nt);
        };
        let (nt0, nt1) = partition_tris(self.span[axis], &mut list[..nt], split, true);
        if no_progress(nt, nt0, nt1) || nt0 + nt1 > budget {
            return self.leaf(nodes, list0, nt);
        }
        // The spare budget shared in proportion to the children's triangles (both ≥ their
        // counts, summing to `budget`).
        let spare = budget - nt0 - nt1;
        let share = |x: usize| (x as u128 * nt0 as u128 / (nt0 + nt1) as u128) as usize;
        let b0 = nt0 + share(spare);
        // The same for the nodes: this one, and at least one per child.
        let n0 = 1 + share(nodes.len() - 3);
        // The second child's list (see the doc): the rejects to the end of its stretch, then
        // the two-sided survivors before them, in their order.
        let rejects = nt - nt0;
        let end = b0 + nt1;
        list.copy_within(nt0..nt, end - rejects);
        let mut w = b0;
        for q in 0..nt0 {
            let t = list[q];
            // The high side's plane test (`partition_tris` with `low = false`).
            if self.span[axis][t as usize][1] >= split {
                list[w] = t;
                w += 1;
            }
        }
        debug_assert_eq!(w, end - rejects, "the second child's count");
        let (me, below) = nodes
            .split_first_mut()
            .expect("a node budget of at least 3");
        let (nodes_a, nodes_b) = below.split_at_mut(n0);
        let (list_a, list_b) = list.split_at_mut(b0);
        let (a, b) = (node0 + 1, node0 + 1 + n0);
        let (ca, cb) = (
            half(&cell, axis, split, true),
            half(&cell, axis, split, false),
        );
        let mut first = move || self.node(nodes_a, a, list_a, list0, nt0, ca, depth + 1);
        let mut second = move || self.node(nodes_b, b, list_b, list0 + b0, nt1, cb, depth + 1);
        let (ta, tb) = if nt >= PAR_MIN {
            rayon::join(first, second)
        } else {
            (first(), second())
        };
        *me = Node {
            axis: axis as u32,
            split,
            a: a as u32,
            b: b as u32,
        };
        // This node's plane test, and the second side's test of its survivors.
        nt as u64 + nt0 as u64 + ta + tb
    }

    fn leaf(&self, nodes: &mut [Node], list0: usize, nt: usize) -> u64 {
        nodes[0] = Node {
            axis: LEAF,
            split: 0.0,
            a: list0 as u32,
            b: (list0 + nt) as u32,
        };
        0
    }
}

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// The rays `ray_idx[rterm..rend]` (each passed a box test against `cell` when
    /// `filtered`) down node `n` of `top`, whose cell is `cell`: `Task::ray_rec`'s visiting
    /// order and ray lists, with the triangle lists read off the leaves.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn top_rec(
        &mut self,
        top: &TopTree,
        n: u32,
        cell: Aabb,
        rend: usize,
        depth: u32,
        ord: Order,
        filtered: bool,
    ) {
        if rend == self.rterm {
            return;
        }
        let node = top.nodes[n as usize];
        if node.axis == LEAF {
            let list = &top.lists[node.a as usize..node.b as usize];
            self.tri_idx.clear();
            self.tri_idx.extend_from_slice(list);
            return self.ray_rec(cell, list.len(), rend, depth, ord, filtered);
        }
        self.st.nodes += 1;
        let (axis, split) = (node.axis as usize, node.split);
        let low_first = self.low_first(axis, split, rend);
        let (first, second) = if low_first {
            (node.a, node.b)
        } else {
            (node.b, node.a)
        };
        let child = half(&cell, axis, split, low_first);
        let rend0 = self.partition_rays(&child, rend);
        let ord0 = ord.child(axis, split, true, low_first);
        self.top_rec(top, first, child, rend0, depth + 1, ord0, true);
        // The second child: as in `ray_rec`, the first child's rejects join untested when this
        // cell's list was filtered against it.
        let child = half(&cell, axis, split, !low_first);
        let rend1 = if filtered {
            let k = self.partition_rays(&child, rend0);
            gather_block(&mut self.ray_idx, k, rend0, rend);
            gather_block(&mut self.recs, k, rend0, rend)
        } else {
            self.partition_rays(&child, rend)
        };
        let ord1 = ord.child(axis, split, false, !low_first);
        self.top_rec(top, second, child, rend1, depth + 1, ord1, true);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural;

    fn spans(scene: &crate::scene::Scene) -> [Vec<[f32; 2]>; 3] {
        let tris = scene.triangles();
        let mut s: [Vec<[f32; 2]>; 3] = Default::default();
        for t in 0..tris.len() {
            let [a, b, c] = tris.get(t);
            let (mn, mx) = (a.min(b).min(c), a.max(b).max(c));
            for k in 0..3 {
                s[k].push([mn[k], mx[k]]);
            }
        }
        s
    }

    /// Every leaf's list holds every triangle whose box meets the leaf's (closed) cell: what
    /// exactness needs (a ray reaching the cell can meet only those). Walks the cells by the
    /// same halvings as `Task::top_rec`; also checks the budgets.
    fn check(tree: &TopTree, span: [&[[f32; 2]]; 3], n: u32, cell: Aabb, leaves: &mut usize) {
        let node = tree.nodes[n as usize];
        if node.axis == LEAF {
            *leaves += 1;
            let list = &tree.lists[node.a as usize..node.b as usize];
            for t in 0..span[0].len() {
                let meets = span.iter().zip(0..3).all(|(s, k)| {
                    let [l, h] = s[t];
                    l <= h && l <= cell.max[k] && h >= cell.min[k]
                });
                if meets {
                    assert!(list.contains(&(t as u32)), "triangle {t} lost from a leaf");
                }
            }
            return;
        }
        let (axis, split) = (node.axis as usize, node.split);
        check(tree, span, node.a, half(&cell, axis, split, true), leaves);
        check(tree, span, node.b, half(&cell, axis, split, false), leaves);
    }

    #[test]
    fn leaves_keep_every_triangle_meeting_their_cell_within_budget() {
        for (scene, leaf, growth) in [
            (procedural::soup(3000, 7), 8, 1.0),
            (procedural::soup(3000, 7), 1, 0.0),
            (procedural::icosphere(1280), 4, 0.5),
            (procedural::icosphere(1280), 64, 3.0),
            // Past `PAR_MIN`: the children of the upper nodes are built at once.
            (procedural::soup(2 * PAR_MIN, 3), 256, 1.0),
        ] {
            let s = spans(&scene);
            let span = [&s[0][..], &s[1][..], &s[2][..]];
            let cfg = Config {
                top_leaf: leaf,
                top_growth: growth,
                split_sample_threshold: 500,
                ..Config::default()
            };
            let tree = TopTree::build(&cfg, span, scene.bounds());
            // The same tree on one thread as on several.
            let one = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap();
            let serial = one.install(|| TopTree::build(&cfg, span, scene.bounds()));
            assert_eq!(format!("{:?}", serial.nodes), format!("{:?}", tree.nodes));
            assert_eq!(serial.lists, tree.lists);
            assert_eq!(serial.tests, tree.tests);
            let n = scene.len();
            let budget = ((1.0 + growth) * n as f64) as usize;
            assert!(tree.lists.len() <= budget);
            assert_eq!(tree.lists.capacity(), budget);
            assert_eq!(tree.nodes.capacity(), 4 * budget.div_ceil(leaf) + 1);
            assert!(tree.nodes.len() <= tree.nodes.capacity());
            let mut leaves = 0;
            check(&tree, span, 0, scene.bounds(), &mut leaves);
            // It did divide (not one leaf of everything), except without spare budget, where
            // a split with one straddling triangle ends in a leaf (the soup's root).
            assert!(leaves > 8 || growth == 0.0, "{leaves} leaves");
        }
    }
}
