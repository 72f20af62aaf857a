//! Spatial splits (the SBVH of Stich, Friedrich and Dietrich 2009, "Spatial splits in bounding
//! volume hierarchies"): a node may split *space* at a plane instead of splitting its
//! primitives, referencing a primitive that straddles the plane from both children, each with
//! the part of its box on its side. Top-down over references (`PrimRef`: a box and an id).
//!
//! Per node, as the paper's Algorithm (§4):
//! 1. the object split: the binned SAH sweep of `build.rs` over the references' centroids;
//! 2. the spatial split, tried only when the object split's children overlap by more than
//!    [`SpatialConfig::alpha`] of the root's surface area (the paper's λ > α test, α = 10⁻⁵):
//!    the node's box cut into `bins` equal slabs per axis, every reference "chopped" into the
//!    slabs it meets (its box clamped to each), counted where it enters and where it leaves, and
//!    the SAH swept over the slab boundaries;
//! 3. the cheaper of the two (and of a leaf, under the same rules as `build.rs`) is taken; a
//!    spatial split partitions the references by the plane and decides for each straddler
//!    whether to split it or to put it wholly on one side (the paper's **reference
//!    unsplitting**, §4.4: the cheapest of the three SAH costs, with the chosen split's boxes and
//!    counts updated as each straddler is decided, in order).
//!
//! **Decided here** (the paper leaves them open or chooses otherwise):
//! - **References are clipped by boxes, not by polygons.** A straddler's two parts are its box
//!   with `max_a` (left) or `min_a` (right) set to the plane. Stich et al. clip the triangle
//!   polygon, which gives tighter parts on the other axes; but the shared triangle test accepts a
//!   hit anywhere in the triangle's *box* slab interval (the box gate, `geom/triangle.rs`), and a
//!   grazing ray's accepted point may lie where the polygon's parts do not reach, so polygon
//!   parts could lose a hit (the same reason the kd-tree clips by boxes, `accel/kdtree`). Box
//!   parts lose none, and the builder keeps seeing boxes only.
//! - **A reference budget**: a node may create at most its share of
//!   [`SpatialConfig::max_growth`]`·n` extra references (shared between children in proportion to
//!   their references, so the build is deterministic in parallel); Stich et al. have none. A
//!   spatial split whose straddlers exceed the node's budget is not taken.
//! - Below depth [`MAX_SAH_DEPTH`] and for nodes that cannot be split otherwise, the fallbacks of
//!   `build.rs` (object median) apply, so the depth bound [`super::MAX_DEPTH`] holds.
//!
//! **Why it stays exact.** Let a straddler's box `B` be cut at `s` on axis `a` into `L` (below)
//! and `R` (above), and let a ray's gated hit `t*` lie in `B`'s slab interval (as
//! [`SlabRay::interval`](crate::geom::SlabRay::interval) computes it: per-axis distances, exits
//! times `BOX_EXIT_SLACK`, the overall entry lowered). Both boxes compute the plane's distance
//! as the same float `ts = (s - o_a)·inv_a`: `L` as an exit (`fl(ts·S)`), `R` as an entry, and
//! all their other faces are `B`'s. If `t* <= fl(ts·S)`, `t*` is in `L`'s interval. Otherwise
//! `R`'s entry is either an entry of `B`'s other axes (lowered, so `<= t*` as `B`'s) or
//! `lower(ts)`, which is `<= ts <= fl(ts·S) < t*` for `ts >= 0` and, for `ts < 0`, is
//! `ts·(1 + E)` rounded after rounding `ts·E` first: the same real as `ts·S` up to far less than
//! an ulp, so it is `fl(ts·S)` or its neighbour, and no float lies strictly between those and
//! above `fl(ts·S)`. A zero direction component gives `ts = ±inf` (one side keeps `B`'s whole
//! interval) or NaN (dropped by the slab test: both do). By induction over repeated cuts, some
//! reference of the triangle has `t*` in its box's interval, and the slab test is monotone in
//! the box, so the leaf holding it and all its ancestors are entered.

use super::build::{
    median_split, partition, BinMap, Bins, Box4, Ctx, PrimRef, MAX_BINS, MAX_SAH_DEPTH,
};
use super::{BoxSource, BuildConfig, Node, NodePair};
use crate::error::{Error, Result};

/// What spatial splits may do (with the [`BuildConfig`] of the object splits).
#[derive(Clone, Debug, PartialEq)]
pub struct SpatialConfig {
    /// Spatial splits are tried where the object split's children overlap by more than `alpha`
    /// times the root's surface area (0..=1; 1 never tries). Default 1e-5 (Stich et al.).
    pub alpha: f32,
    /// Extra references allowed, as a multiple of the primitive count (>= 0). Default 1.0: at
    /// most twice as many references as primitives.
    pub max_growth: f32,
}

impl Default for SpatialConfig {
    fn default() -> Self {
        Self {
            alpha: 1e-5,
            max_growth: 1.0,
        }
    }
}

impl SpatialConfig {
    /// Checks the documented ranges; `who` names the caller in the message.
    pub fn check(&self, who: &str) -> Result<()> {
        if !(0.0..=1.0).contains(&self.alpha) {
            return Err(Error::Invalid(format!(
                "{who}: alpha must be in 0..=1, got {}",
                self.alpha
            )));
        }
        if !(self.max_growth >= 0.0 && self.max_growth.is_finite()) {
            return Err(Error::Invalid(format!(
                "{who}: max_growth must be finite and >= 0, got {}",
                self.max_growth
            )));
        }
        Ok(())
    }
}

/// A subtree under construction (boxed children: the build allocates per node, traversal never).
enum Tree {
    Leaf(Box4, Vec<u32>),
    Inner(Box4, u8, Box<[Tree; 2]>),
}

/// What a spatial build did, for the counters and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SpatialStats {
    /// Nodes split by a plane.
    pub spatial_splits: u64,
    /// Straddlers put wholly on one side by reference unsplitting.
    pub unsplit: u64,
}

/// Builds over `prims` with spatial splits: node pairs (depth first), ids in leaf order (a
/// primitive may appear in several leaves), and what the build did.
pub(super) fn build(
    prims: &(impl BoxSource + ?Sized),
    cfg: &BuildConfig,
    sp: &SpatialConfig,
) -> (Vec<NodePair>, Vec<u32>, SpatialStats) {
    let n = prims.len();
    if n == 0 {
        return (Vec::new(), Vec::new(), SpatialStats::default());
    }
    let refs: Vec<PrimRef> = (0..n)
        .map(|i| PrimRef::new(prims.bounds(i), i as u32))
        .collect();
    let bounds = refs.iter().fold(Box4::EMPTY, |b, r| b.union(r.0));
    let b = Builder {
        ctx: Ctx { cfg },
        min_overlap: sp.alpha * bounds.area(),
    };
    let budget = (sp.max_growth as f64 * n as f64).min(u32::MAX as f64) as usize;
    let (tree, stats) = b.node(refs, bounds, 0, budget);
    let mut pairs = vec![NodePair::UNUSED];
    let mut ids = Vec::with_capacity(n);
    let root = flatten(tree, &mut pairs, &mut ids);
    pairs[0].set(0, root);
    (pairs, ids, stats)
}

fn flatten(t: Tree, pairs: &mut Vec<NodePair>, ids: &mut Vec<u32>) -> Node {
    match t {
        Tree::Leaf(b, leaf) => {
            let first = ids.len() as u32;
            ids.extend_from_slice(&leaf);
            Node::leaf(b.aabb(), first, leaf.len() as u16)
        }
        Tree::Inner(b, axis, kids) => {
            let p = pairs.len();
            pairs.push(NodePair::UNUSED);
            let [l, r] = *kids;
            let l = flatten(l, pairs, ids);
            let r = flatten(r, pairs, ids);
            pairs[p] = NodePair::new([l, r]);
            Node::interior(b.aabb(), axis, p as u32)
        }
    }
}

thread_local! {
    /// Each thread's bins for the object splits of its sequential nodes.
    static BINS: std::cell::RefCell<Box<Bins>> = std::cell::RefCell::new(Box::new(Bins::new()));
}

struct Builder<'a> {
    ctx: Ctx<'a>,
    /// `alpha` times the root's area: spatial splits only above this overlap.
    min_overlap: f32,
}

/// A spatial split found by the sweep.
struct Plane {
    cost: f32,
    axis: usize,
    pos: f32,
    left: Box4,
    right: Box4,
    n_left: usize,
    n_right: usize,
}

impl Builder<'_> {
    fn node(
        &self,
        mut refs: Vec<PrimRef>,
        bounds: Box4,
        depth: usize,
        budget: usize,
    ) -> (Tree, SpatialStats) {
        let cfg = self.ctx.cfg;
        let n = refs.len();
        let leaf = |refs: &[PrimRef]| Tree::Leaf(bounds, refs.iter().map(|r| r.id()).collect());
        if n <= 1 {
            return (leaf(&refs), SpatialStats::default());
        }
        let can_leaf = n <= cfg.max_leaf;
        let leaf_cost = cfg.intersection_cost * n as f32;
        let cbounds = refs.iter().fold(Box4::EMPTY, |c, r| c.grow(r.centroid2()));
        let spread = (cbounds.max - cbounds.min).truncate().max_element() > 0.0;
        let sah = depth < MAX_SAH_DEPTH;
        let object = match (sah && spread, n >= cfg.parallel_threshold.max(2)) {
            (false, _) => None,
            // Large nodes bin in parallel; the others reuse their thread's bins (no
            // allocation, no task per node; the same bins either way).
            (true, true) => self.ctx.best_split(&refs, bounds, cbounds, None),
            (true, false) => BINS.with(|b| {
                self.ctx
                    .best_split(&refs, bounds, cbounds, Some(&mut b.borrow_mut()))
            }),
        };
        let overlap = object.as_ref().map_or(f32::INFINITY, |(_, s)| {
            let i = Box4 {
                min: s.left_bounds.min.max(s.right_bounds.min),
                max: s.left_bounds.max.min(s.right_bounds.max),
            };
            i.area()
        });
        let plane = if sah && budget > 0 && overlap > self.min_overlap {
            self.best_plane(&refs, bounds, budget)
        } else {
            None
        };
        let object_cost = object.as_ref().map_or(f32::INFINITY, |o| o.0);
        let mut stats = SpatialStats::default();
        let (axis, l, r) = match plane {
            Some(p) if p.cost < object_cost => {
                if can_leaf && leaf_cost <= p.cost {
                    return (leaf(&refs), stats);
                }
                stats.spatial_splits = 1;
                let (mut l, mut r, mut unsplit) = split_at_plane(&refs, &p, true);
                if l.is_empty() || r.is_empty() {
                    // Unsplitting moved every straddler to one side: cut them all instead
                    // (both sides then hold what the sweep counted, at least one each).
                    (l, r, unsplit) = split_at_plane(&refs, &p, false);
                }
                stats.unsplit = unsplit;
                (p.axis, l, r)
            }
            _ => match object {
                Some((cost, s)) => {
                    if can_leaf && leaf_cost <= cost {
                        return (leaf(&refs), stats);
                    }
                    let map = BinMap::new(cbounds, cfg.bins.min(n.max(4)));
                    let (mid, _, _) =
                        partition(&mut refs, |r| map.bins(r.centroid2())[s.axis] <= s.bin);
                    let r = refs.split_off(mid);
                    (s.axis, refs, r)
                }
                None if can_leaf => return (leaf(&refs), stats),
                None => {
                    let (axis, mid, ..) = median_split(&mut refs, cbounds);
                    let r = refs.split_off(mid);
                    (axis, refs, r)
                }
            },
        };
        let made = (l.len() + r.len()).saturating_sub(n);
        let rest = budget.saturating_sub(made);
        let lb = rest * l.len() / (l.len() + r.len());
        let (bl, br) = (box_of(&l), box_of(&r));
        let ((lt, ls), (rt, rs)) = if n >= cfg.parallel_threshold.max(2) {
            rayon::join(
                || self.node(l, bl, depth + 1, lb),
                || self.node(r, br, depth + 1, rest - lb),
            )
        } else {
            (
                self.node(l, bl, depth + 1, lb),
                self.node(r, br, depth + 1, rest - lb),
            )
        };
        stats.spatial_splits += ls.spatial_splits + rs.spatial_splits;
        stats.unsplit += ls.unsplit + rs.unsplit;
        (Tree::Inner(bounds, axis as u8, Box::new([lt, rt])), stats)
    }

    /// The cheapest plane over the three axes' slab boundaries whose straddlers fit in
    /// `budget`, or `None`.
    fn best_plane(&self, refs: &[PrimRef], bounds: Box4, budget: usize) -> Option<Plane> {
        let cfg = self.ctx.cfg;
        let nb = cfg.bins.min(refs.len().max(4));
        let inv_area = 1.0 / bounds.area();
        let mut best: Option<Plane> = None;
        for a in 0..3 {
            let (lo, hi) = (bounds.min[a], bounds.max[a]);
            if hi <= lo {
                continue;
            }
            // Slab boundaries P[0] = lo < ... <= P[nb] = hi (non-decreasing in f32).
            let mut planes = [0f32; MAX_BINS + 1];
            planes[0] = lo;
            for k in 1..nb {
                let p = lo + (hi - lo) * (k as f32 / nb as f32);
                planes[k] = p.clamp(planes[k - 1], hi);
            }
            planes[nb] = hi;
            let inner = &planes[1..nb];
            let mut boxes = [Box4::EMPTY; MAX_BINS];
            let mut enter = [0u32; MAX_BINS];
            let mut exit = [0u32; MAX_BINS];
            for r in refs {
                let (k0, k1) = slabs(inner, r.0.min[a], r.0.max[a]);
                enter[k0] += 1;
                exit[k1] += 1;
                for (k, b) in boxes.iter_mut().enumerate().take(k1 + 1).skip(k0) {
                    let mut part = r.0;
                    part.min[a] = part.min[a].max(planes[k]);
                    part.max[a] = part.max[a].min(planes[k + 1]);
                    *b = b.union(part);
                }
            }
            // Right-to-left: boxes and counts of the slabs at or above each boundary j.
            let mut right = [(Box4::EMPTY, 0u32); MAX_BINS];
            let (mut acc, mut cnt) = (Box4::EMPTY, 0u32);
            for j in (1..nb).rev() {
                acc = acc.union(boxes[j]);
                cnt += exit[j];
                right[j] = (acc, cnt);
            }
            let (mut acc, mut cnt) = (Box4::EMPTY, 0u32);
            for j in 1..nb {
                acc = acc.union(boxes[j - 1]);
                cnt += enter[j - 1];
                let (rb, rc) = right[j];
                let (nl, nr) = (cnt as usize, rc as usize);
                if nl == 0 || nr == 0 || nl + nr - refs.len() > budget {
                    continue;
                }
                let cost = cfg.traversal_cost
                    + cfg.intersection_cost
                        * (acc.area() * nl as f32 + rb.area() * nr as f32)
                        * inv_area;
                if best.as_ref().is_none_or(|b| cost < b.cost) {
                    best = Some(Plane {
                        cost,
                        axis: a,
                        pos: planes[j],
                        left: acc,
                        right: rb,
                        n_left: nl,
                        n_right: nr,
                    });
                }
            }
        }
        best
    }
}

/// The first and last slab a reference spanning `[lo, hi]` on the axis has a part in, given the
/// inner boundaries `inner` (`P[1..nb]`): it is left of boundary `j` (1-based) exactly when the
/// first is `< j`, and right of it exactly when the last is `>= j`, as [`sides`] decides.
#[inline]
fn slabs(inner: &[f32], lo: f32, hi: f32) -> (usize, usize) {
    let last = inner.partition_point(|&p| p < hi);
    let first = inner.partition_point(|&p| p <= lo).min(last);
    (first, last)
}

/// Which sides of the plane `pos` on `axis` a reference has a part on: (left, right). Left when
/// it reaches below the plane or lies wholly at or below it, right when it reaches above it:
/// both only for a box that straddles the plane strictly.
#[inline]
fn sides(r: &PrimRef, axis: usize, pos: f32) -> (bool, bool) {
    let (lo, hi) = (r.0.min[axis], r.0.max[axis]);
    (lo < pos || hi <= pos, hi > pos)
}

/// Partitions `refs` by the plane, cutting straddlers or (with `unsplitting`) putting them on one
/// side where that is cheaper; returns the two sides and the number of straddlers unsplit.
fn split_at_plane(
    refs: &[PrimRef],
    p: &Plane,
    unsplitting: bool,
) -> (Vec<PrimRef>, Vec<PrimRef>, u64) {
    let (mut bl, mut br) = (p.left, p.right);
    let (mut nl, mut nr) = (p.n_left as f32, p.n_right as f32);
    let mut l = Vec::with_capacity(p.n_left);
    let mut r = Vec::with_capacity(p.n_right);
    let mut unsplit = 0;
    for &x in refs {
        match sides(&x, p.axis, p.pos) {
            (true, false) => l.push(x),
            (false, true) => r.push(x),
            _ => {
                let split = bl.area() * nl + br.area() * nr;
                let all_left = bl.union(x.0).area() * nl + br.area() * (nr - 1.0);
                let all_right = bl.area() * (nl - 1.0) + br.union(x.0).area() * nr;
                if unsplitting && all_left < split && all_left <= all_right {
                    bl = bl.union(x.0);
                    nr -= 1.0;
                    unsplit += 1;
                    l.push(x);
                } else if unsplitting && all_right < split {
                    br = br.union(x.0);
                    nl -= 1.0;
                    unsplit += 1;
                    r.push(x);
                } else {
                    let (mut a, mut b) = (x, x);
                    a.0.max[p.axis] = p.pos;
                    b.0.min[p.axis] = p.pos;
                    l.push(a);
                    r.push(b);
                }
            }
        }
    }
    (l, r, unsplit)
}

fn box_of(refs: &[PrimRef]) -> Box4 {
    refs.iter().fold(Box4::EMPTY, |b, r| b.union(r.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Aabb;

    #[test]
    fn slabs_agree_with_sides_at_every_boundary() {
        // Boundaries with repeats (a tiny extent rounds planes together).
        let inner = [1.0f32, 2.0, 2.0, 3.0, 4.0];
        let vals = [0.5f32, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 4.5];
        for &lo in &vals {
            for &hi in vals.iter().filter(|&&h| h >= lo) {
                let r = PrimRef::new(
                    Aabb::new(glam::Vec3::new(lo, 0.0, 0.0), glam::Vec3::new(hi, 1.0, 1.0)),
                    7,
                );
                let (first, last) = slabs(&inner, lo, hi);
                for (j, &pos) in inner.iter().enumerate() {
                    let j = j + 1;
                    assert_eq!(
                        sides(&r, 0, pos),
                        (first < j, last >= j),
                        "[{lo}, {hi}] at {pos}"
                    );
                }
            }
        }
    }

    #[test]
    fn cut_parts_keep_the_id_and_tile_the_box() {
        let x = PrimRef::new(
            Aabb::new(glam::Vec3::ZERO, glam::Vec3::new(4.0, 1.0, 1.0)),
            u32::MAX >> 9,
        );
        let p = Plane {
            cost: 0.0,
            axis: 0,
            pos: 1.0,
            left: Box4::EMPTY,
            right: Box4::EMPTY,
            n_left: 1,
            n_right: 1,
        };
        let (l, r, unsplit) = split_at_plane(&[x], &p, true);
        assert_eq!((l.len(), r.len(), unsplit), (1, 1, 0));
        assert_eq!((l[0].id(), r[0].id()), (x.id(), x.id()));
        assert_eq!(l[0].0.aabb().union(r[0].0.aabb()), x.0.aabb());
        assert_eq!((l[0].0.max.x, r[0].0.min.x), (1.0, 1.0));
    }
}
