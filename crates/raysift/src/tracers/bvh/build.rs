//! Binned SAH construction (Wald 2007), top-down, parallel with rayon.
//!
//! Each node bins the centroids of its triangles into `bins` equal slots along each of the three
//! axes of its centroid bounds, sweeps the bins to evaluate the SAH at every bin boundary, and
//! partitions its slice of primitive references in place at the best one. Children above
//! `parallel_threshold` triangles are built with `rayon::join`, and their binning is itself a
//! parallel fold. Subtrees below the threshold are built sequentially into their own node vector;
//! one final pass concatenates those fragments depth first (so the tree is copied once).
//!
//! Fallbacks that keep every input finite and terminating: a node whose centroids coincide on all
//! axes (or for which binning finds no split with both sides non-empty) is split at the object
//! median (by centroid on the longest axis, or by position in the slice when all centroids are
//! equal); below depth [`MAX_SAH_DEPTH`] only median splits are used, so the tree depth stays
//! below [`MAX_DEPTH`] whatever the input.

use super::{Config, Node};
use crate::geom::Aabb;
use crate::scene::TriangleSoup;
use glam::Vec3;
use rayon::prelude::*;

/// Depth below which SAH splits are allowed; deeper nodes are split at the object median,
/// which halves the count, so the depth is at most `MAX_SAH_DEPTH + log2(n) + 1`.
pub const MAX_SAH_DEPTH: usize = 64;

/// Largest possible tree depth (root at depth 0) for up to 2^32 triangles; the traversal stack
/// has this many entries.
pub const MAX_DEPTH: usize = MAX_SAH_DEPTH + 34;

/// Most bins a [`Config`] may ask for.
pub const MAX_BINS: usize = 64;

/// A triangle during the build: its box and id (28 bytes; sorted in place).
#[derive(Clone, Copy, Debug)]
struct PrimRef {
    min: Vec3,
    max: Vec3,
    id: u32,
}

impl PrimRef {
    /// Twice the box centre (`min + max`): the halving is skipped since only comparisons and
    /// bin positions relative to the (equally doubled) centroid bounds are needed.
    #[inline(always)]
    fn centroid2(&self) -> Vec3 {
        self.min + self.max
    }
}

/// A tree fragment: either interior nodes built in parallel, or a subtree built sequentially
/// into its own depth-first node vector (interior offsets relative to the vector's start).
enum Sub {
    Split {
        bounds: Aabb,
        axis: u8,
        left: Box<Sub>,
        right: Box<Sub>,
    },
    Flat(Vec<Node>),
}

impl Sub {
    fn node_count(&self) -> usize {
        match self {
            Sub::Split { left, right, .. } => 1 + left.node_count() + right.node_count(),
            Sub::Flat(v) => v.len(),
        }
    }

    /// Appends this fragment to `out` depth first, rebasing interior offsets.
    fn flatten(self, out: &mut Vec<Node>) {
        match self {
            Sub::Split {
                bounds,
                axis,
                left,
                right,
            } => {
                let i = out.len();
                out.push(Node::interior(bounds, axis, 0));
                left.flatten(out);
                out[i].offset = out.len() as u32;
                right.flatten(out);
            }
            Sub::Flat(v) => {
                let base = out.len() as u32;
                out.extend(v.into_iter().map(|mut n| {
                    if !n.is_leaf() {
                        n.offset += base;
                    }
                    n
                }));
            }
        }
    }
}

/// The result of a build: nodes (depth first, root at 0, empty for no triangles) and the
/// triangle ids in leaf order.
pub struct Built {
    /// Flat nodes.
    pub nodes: Vec<Node>,
    /// `ids[k]` is the triangle id stored at leaf position `k`.
    pub ids: Vec<u32>,
}

/// Builds the tree over all triangles of `soup`.
pub fn build(soup: &TriangleSoup, cfg: &Config) -> Built {
    let n = soup.len();
    if n == 0 {
        return Built {
            nodes: Vec::new(),
            ids: Vec::new(),
        };
    }
    let mut refs: Vec<PrimRef> = (0..n)
        .into_par_iter()
        .map(|i| {
            let b = soup.bounds(i);
            PrimRef {
                min: b.min,
                max: b.max,
                id: i as u32,
            }
        })
        .collect();
    let (bounds, cbounds) = refs.par_chunks(1 << 14).map(|c| bounds_of(c)).reduce(
        || (Aabb::EMPTY, Aabb::EMPTY),
        |a, b| (a.0.union(b.0), a.1.union(b.1)),
    );
    let ctx = Ctx { cfg };
    let root = ctx.build_par(&mut refs, 0, 0, bounds, cbounds);
    let mut nodes = Vec::with_capacity(root.node_count());
    root.flatten(&mut nodes);
    let ids = refs.iter().map(|r| r.id).collect();
    Built { nodes, ids }
}

/// Box of the triangles and box of their (doubled) centroids.
fn bounds_of(refs: &[PrimRef]) -> (Aabb, Aabb) {
    let (mut b, mut c) = (Aabb::EMPTY, Aabb::EMPTY);
    for r in refs {
        b = b.union(Aabb::new(r.min, r.max));
        c = c.grow(r.centroid2());
    }
    (b, c)
}

/// One bin: box of its triangles and their count.
#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    count: 0,
};

/// Bins for the three axes.
#[derive(Clone)]
struct Bins {
    b: [[Bin; MAX_BINS]; 3],
}

impl Bins {
    fn new() -> Self {
        Self {
            b: [[EMPTY_BIN; MAX_BINS]; 3],
        }
    }

    fn merge(mut self, o: &Bins, nbins: usize) -> Self {
        for a in 0..3 {
            for k in 0..nbins {
                let (x, y) = (&mut self.b[a][k], &o.b[a][k]);
                x.bounds = x.bounds.union(y.bounds);
                x.count += y.count;
            }
        }
        self
    }
}

/// Maps doubled centroids to bin indices; the same arithmetic is used for binning and
/// partitioning, so both agree on every triangle's side.
#[derive(Clone, Copy)]
struct BinMap {
    lo: Vec3,
    scale: Vec3,
    last: usize,
}

impl BinMap {
    fn new(cbounds: Aabb, nbins: usize) -> Self {
        let ext = cbounds.extent();
        // Slightly below nbins / extent so the max centroid maps inside the last bin; axes with
        // zero extent get scale 0 (everything in bin 0, never chosen since one side is empty).
        let k = nbins as f32 * (1.0 - 1e-6);
        let scale = Vec3::select(ext.cmpgt(Vec3::ZERO), Vec3::splat(k) / ext, Vec3::ZERO);
        Self {
            lo: cbounds.min,
            scale,
            last: nbins - 1,
        }
    }

    #[inline(always)]
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        // `as usize` saturates (NaN to 0), and min() keeps rounding at the top inside the range.
        (((c[axis] - self.lo[axis]) * self.scale[axis]) as usize).min(self.last)
    }
}

/// The chosen split of a node.
struct Split {
    axis: usize,
    /// Triangles in bins `<= bin` go left.
    bin: usize,
    left_bounds: Aabb,
    right_bounds: Aabb,
    left_count: usize,
}

struct Ctx<'a> {
    cfg: &'a Config,
}

impl Ctx<'_> {
    /// Builds the subtree over `refs` (which start at leaf position `first`), in parallel when
    /// large.
    fn build_par(
        &self,
        refs: &mut [PrimRef],
        first: usize,
        depth: usize,
        bounds: Aabb,
        cbounds: Aabb,
    ) -> Sub {
        let n = refs.len();
        if n < self.cfg.parallel_threshold.max(2) {
            let mut out = Vec::with_capacity(2 * n.div_ceil(self.cfg.max_leaf.max(1)));
            self.build_seq(refs, first, depth, bounds, cbounds, &mut out);
            return Sub::Flat(out);
        }
        match self.split(refs, depth, bounds, cbounds, true) {
            None => Sub::Flat(vec![Node::leaf(bounds, first as u32, n as u16)]),
            Some((axis, mid, lb, lc, rb, rc)) => {
                let (l, r) = refs.split_at_mut(mid);
                let (left, right) = rayon::join(
                    || self.build_par(l, first, depth + 1, lb, lc),
                    || self.build_par(r, first + mid, depth + 1, rb, rc),
                );
                Sub::Split {
                    bounds,
                    axis: axis as u8,
                    left: Box::new(left),
                    right: Box::new(right),
                }
            }
        }
    }

    /// Builds the subtree over `refs` into `out` (offsets relative to `out`'s start).
    fn build_seq(
        &self,
        refs: &mut [PrimRef],
        first: usize,
        depth: usize,
        bounds: Aabb,
        cbounds: Aabb,
        out: &mut Vec<Node>,
    ) {
        let i = out.len();
        match self.split(refs, depth, bounds, cbounds, false) {
            None => out.push(Node::leaf(bounds, first as u32, refs.len() as u16)),
            Some((axis, mid, lb, lc, rb, rc)) => {
                out.push(Node::interior(bounds, axis as u8, 0));
                let (l, r) = refs.split_at_mut(mid);
                self.build_seq(l, first, depth + 1, lb, lc, out);
                out[i].offset = out.len() as u32;
                self.build_seq(r, first + mid, depth + 1, rb, rc, out);
            }
        }
    }

    /// Decides leaf (`None`) or split; on a split, reorders `refs` so the left child's triangles
    /// come first and returns (axis, left count, left bounds, left centroid bounds, right bounds,
    /// right centroid bounds).
    #[allow(clippy::type_complexity)]
    fn split(
        &self,
        refs: &mut [PrimRef],
        depth: usize,
        bounds: Aabb,
        cbounds: Aabb,
        parallel: bool,
    ) -> Option<(usize, usize, Aabb, Aabb, Aabb, Aabb)> {
        let n = refs.len();
        let cfg = self.cfg;
        if n <= 1 {
            return None;
        }
        let can_leaf = n <= cfg.max_leaf;
        if depth < MAX_SAH_DEPTH && cbounds.extent().max_element() > 0.0 {
            if let Some(s) = self.best_split(refs, bounds, cbounds, parallel) {
                let (cost, split) = s;
                let leaf_cost = cfg.intersection_cost * n as f32;
                if can_leaf && leaf_cost <= cost {
                    return None;
                }
                let map = BinMap::new(cbounds, cfg.bins);
                let (mid, lc, rc) =
                    partition(refs, |r| map.bin(r.centroid2(), split.axis) <= split.bin);
                debug_assert_eq!(mid, split.left_count);
                return Some((
                    split.axis,
                    mid,
                    split.left_bounds,
                    lc,
                    split.right_bounds,
                    rc,
                ));
            }
        }
        if can_leaf {
            return None;
        }
        Some(median_split(refs, cbounds))
    }

    /// Best SAH split over all axes and bin boundaries: (cost, split), or `None` when every
    /// boundary leaves a side empty.
    fn best_split(
        &self,
        refs: &[PrimRef],
        bounds: Aabb,
        cbounds: Aabb,
        parallel: bool,
    ) -> Option<(f32, Split)> {
        let nb = self.cfg.bins;
        let map = BinMap::new(cbounds, nb);
        let fill = |mut bins: Bins, chunk: &[PrimRef]| {
            for r in chunk {
                let c = r.centroid2();
                let rb = Aabb::new(r.min, r.max);
                for (a, axis_bins) in bins.b.iter_mut().enumerate() {
                    let bin = &mut axis_bins[map.bin(c, a)];
                    bin.bounds = bin.bounds.union(rb);
                    bin.count += 1;
                }
            }
            bins
        };
        let bins = if parallel {
            refs.par_chunks(1 << 13)
                .fold(Bins::new, fill)
                .reduce(Bins::new, |a, b| a.merge(&b, nb))
        } else {
            fill(Bins::new(), refs)
        };
        let inv_area = 1.0 / bounds.surface_area();
        let mut best: Option<(f32, Split)> = None;
        for a in 0..3 {
            if map.scale[a] == 0.0 {
                continue;
            }
            let b = &bins.b[a][..nb];
            // Right-to-left sweep: area·count of the bins above each boundary.
            let mut right_cost = [0f32; MAX_BINS];
            let mut acc = Aabb::EMPTY;
            let mut cnt = 0u32;
            for k in (1..nb).rev() {
                acc = acc.union(b[k].bounds);
                cnt += b[k].count;
                right_cost[k - 1] = acc.surface_area() * cnt as f32;
            }
            let mut acc = Aabb::EMPTY;
            let mut cnt = 0u32;
            for k in 0..nb - 1 {
                acc = acc.union(b[k].bounds);
                cnt += b[k].count;
                if cnt == 0 || cnt as usize == refs.len() {
                    continue;
                }
                let cost = self.cfg.traversal_cost
                    + self.cfg.intersection_cost
                        * (acc.surface_area() * cnt as f32 + right_cost[k])
                        * inv_area;
                if best.as_ref().is_none_or(|(c, _)| cost < *c) {
                    let right_bounds = b[k + 1..]
                        .iter()
                        .fold(Aabb::EMPTY, |x, y| x.union(y.bounds));
                    best = Some((
                        cost,
                        Split {
                            axis: a,
                            bin: k,
                            left_bounds: acc,
                            right_bounds,
                            left_count: cnt as usize,
                        },
                    ));
                }
            }
        }
        // A flat node (zero area, e.g. all triangles in one plane) makes costs NaN or inf: any
        // split found is still valid, so keep it (the leaf test then compares against NaN and
        // splits when the node is too big, which is what we want).
        best
    }
}

/// In-place partition: elements for which `left` holds come first. Returns the left count and the
/// centroid bounds of both sides.
fn partition(refs: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> (usize, Aabb, Aabb) {
    let (mut lc, mut rc) = (Aabb::EMPTY, Aabb::EMPTY);
    let mut i = 0;
    let mut j = refs.len();
    while i < j {
        if left(&refs[i]) {
            lc = lc.grow(refs[i].centroid2());
            i += 1;
        } else {
            j -= 1;
            rc = rc.grow(refs[i].centroid2());
            refs.swap(i, j);
        }
    }
    (i, lc, rc)
}

/// Object-median split: by centroid along the longest centroid axis, or (all centroids equal)
/// by position, which always terminates since both halves are non-empty.
fn median_split(refs: &mut [PrimRef], cbounds: Aabb) -> (usize, usize, Aabb, Aabb, Aabb, Aabb) {
    let mid = refs.len() / 2;
    let axis = cbounds.longest_axis();
    if cbounds.extent()[axis] > 0.0 {
        refs.select_nth_unstable_by(mid, |a, b| {
            a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
        });
    }
    let (l, r) = refs.split_at(mid);
    let (lb, lc) = bounds_of(l);
    let (rb, rc) = bounds_of(r);
    (axis, mid, lb, lc, rb, rc)
}
