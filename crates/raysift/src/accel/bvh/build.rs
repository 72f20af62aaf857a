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

use super::{BoxSource, BuildConfig, Node, NodePair};
use crate::geom::Aabb;
use glam::{BVec4A, Vec4};
use rayon::prelude::*;

/// `v` with its `w` lane zeroed, by a bit mask (no arithmetic on `w`). The build keeps the
/// triangle id's bits in `min.w`, which read as a float are subnormal for ids below 2^23, and
/// SSE arithmetic on subnormal operands can take microcode assists on x86 CPUs; so every
/// arithmetic use of a box or centroid zeroes `w` first. (x, y, z are untouched: the tree is
/// the same bit for bit. sphere:1M, one thread, 4 alternating pairs of runs: build CPU time
/// 0.87-1.05 s against 0.94-1.25 s, lower in every pair.)
#[inline(always)]
pub(super) fn xyz(v: Vec4) -> Vec4 {
    Vec4::select(BVec4A::new(true, true, true, false), v, Vec4::ZERO)
}

/// Depth below which SAH splits are allowed; deeper nodes are split at the object median,
/// which halves the count, so the depth is at most `MAX_SAH_DEPTH + log2(n) + 1`.
pub const MAX_SAH_DEPTH: usize = 64;

/// Largest possible tree depth (root at depth 0) for up to 2^32 triangles; the traversal stack
/// has this many entries.
pub const MAX_DEPTH: usize = MAX_SAH_DEPTH + 34;

/// Most bins a [`BuildConfig`] may ask for.
pub const MAX_BINS: usize = 32;

/// A box in SIMD registers (`w` lanes unused), the build's working type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Box4 {
    pub(super) min: Vec4,
    pub(super) max: Vec4,
}

impl Box4 {
    pub(super) const EMPTY: Box4 = Box4 {
        min: Vec4::INFINITY,
        max: Vec4::NEG_INFINITY,
    };

    #[inline(always)]
    pub(super) fn union(self, o: Box4) -> Box4 {
        Box4 {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    #[inline(always)]
    pub(super) fn grow(self, p: Vec4) -> Box4 {
        Box4 {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub(super) fn aabb(self) -> Aabb {
        Aabb::new(self.min.truncate(), self.max.truncate())
    }

    /// Surface area (0 when empty), as [`Aabb::surface_area`].
    #[inline(always)]
    pub(super) fn area(self) -> f32 {
        let e = xyz(self.max) - xyz(self.min);
        if !(e.x >= 0.0 && e.y >= 0.0 && e.z >= 0.0) {
            return 0.0;
        }
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

/// A triangle during the build: its box, with the id's bits in `min.w` (32 bytes; moved in
/// place by the partitions). The scene guarantees finite coordinates, so the SIMD min/max never
/// see a NaN in x, y, z; whatever `w` becomes in unions is never read.
#[derive(Clone, Copy, Debug)]
pub(super) struct PrimRef(pub(super) Box4);

impl PrimRef {
    pub(super) fn new(b: Aabb, id: u32) -> Self {
        PrimRef(Box4 {
            min: b.min.extend(f32::from_bits(id)),
            max: b.max.extend(0.0),
        })
    }

    #[inline(always)]
    pub(super) fn id(&self) -> u32 {
        self.0.min.w.to_bits()
    }

    /// Twice the box centre (`min + max`): the halving is skipped since only comparisons and
    /// bin positions relative to the (equally doubled) centroid bounds are needed. `w` is 0
    /// (the id in `min.w` masked out, see [`xyz`]; `max.w` is 0), so centroid bounds and bin
    /// maps never hold a subnormal either.
    #[inline(always)]
    pub(super) fn centroid2(&self) -> Vec4 {
        xyz(self.0.min) + self.0.max
    }
}

/// A tree fragment: either an interior node built in parallel, or a subtree built sequentially:
/// its root node plus the pairs below it (interior offsets relative to that vector's start).
enum Sub {
    Split {
        bounds: Aabb,
        axis: u8,
        left: Box<Sub>,
        right: Box<Sub>,
    },
    Flat {
        root: Node,
        pairs: Vec<NodePair>,
    },
}

impl Sub {
    fn pair_count(&self) -> usize {
        match self {
            Sub::Split { left, right, .. } => 1 + left.pair_count() + right.pair_count(),
            Sub::Flat { pairs, .. } => pairs.len(),
        }
    }

    /// Appends the pairs below this fragment's root to `out` depth first and returns the
    /// root, its offsets rebased.
    fn flatten(self, out: &mut Vec<NodePair>) -> Node {
        match self {
            Sub::Split {
                bounds,
                axis,
                left,
                right,
            } => {
                let p = out.len();
                out.push(NodePair::UNUSED);
                let l = left.flatten(out);
                let r = right.flatten(out);
                out[p] = NodePair::new([l, r]);
                Node::interior(bounds, axis, p as u32)
            }
            Sub::Flat { root, pairs } => {
                let base = out.len() as u32;
                out.extend(pairs.into_iter().map(|mut p| {
                    for i in 0..2 {
                        if p.count[i] == 0 {
                            p.offset[i] += base;
                        }
                    }
                    p
                }));
                let mut root = root;
                if !root.is_leaf() {
                    root.offset += base;
                }
                root
            }
        }
    }
}

/// The result of a build: node pairs (pair 0 holds the root in slot 0; empty for no triangles)
/// and the triangle ids in leaf order.
pub struct Built {
    /// Node pairs, depth first.
    pub pairs: Vec<NodePair>,
    /// `ids[k]` is the triangle id stored at leaf position `k`.
    pub ids: Vec<u32>,
}

/// Builds the tree over the boxes of all primitives of `prims`.
pub fn build(prims: &(impl BoxSource + ?Sized), cfg: &BuildConfig) -> Built {
    let n = prims.len();
    if n == 0 {
        return Built {
            pairs: Vec::new(),
            ids: Vec::new(),
        };
    }
    let mut refs: Vec<PrimRef> = (0..n)
        .into_par_iter()
        .map(|i| PrimRef::new(prims.bounds(i), i as u32))
        .collect();
    let (bounds, cbounds) = refs.par_chunks(1 << 14).map(bounds_of).reduce(
        || (Box4::EMPTY, Box4::EMPTY),
        |a, b| (a.0.union(b.0), a.1.union(b.1)),
    );
    let ctx = Ctx { cfg };
    let root = ctx.build_par(&mut refs, 0, 0, bounds, cbounds);
    let mut pairs = Vec::with_capacity(1 + root.pair_count());
    pairs.push(NodePair::UNUSED);
    let root = root.flatten(&mut pairs);
    pairs[0].set(0, root);
    let ids = refs.iter().map(|r| r.id()).collect();
    Built { pairs, ids }
}

/// Box of the triangles and box of their (doubled) centroids.
pub(super) fn bounds_of(refs: &[PrimRef]) -> (Box4, Box4) {
    let (mut b, mut c) = (Box4::EMPTY, Box4::EMPTY);
    for r in refs {
        b = b.union(r.0);
        c = c.grow(r.centroid2());
    }
    (b, c)
}

/// Bins for the three axes: box and count of the triangles whose centroid falls in each.
#[derive(Clone)]
pub(super) struct Bins {
    bounds: [[Box4; MAX_BINS]; 3],
    count: [[u32; MAX_BINS]; 3],
}

impl Bins {
    pub(super) fn new() -> Self {
        Self {
            bounds: [[Box4::EMPTY; MAX_BINS]; 3],
            count: [[0; MAX_BINS]; 3],
        }
    }

    fn merge(mut self: Box<Self>, o: &Bins, nbins: usize) -> Box<Self> {
        for a in 0..3 {
            for k in 0..nbins {
                self.bounds[a][k] = self.bounds[a][k].union(o.bounds[a][k]);
                self.count[a][k] += o.count[a][k];
            }
        }
        self
    }
}

/// Maps doubled centroids to bin indices; the same arithmetic is used for binning and
/// partitioning, so both agree on every triangle's side.
#[derive(Clone, Copy)]
pub(super) struct BinMap {
    lo: Vec4,
    scale: Vec4,
    last: u32,
}

impl BinMap {
    pub(super) fn new(cbounds: Box4, nbins: usize) -> Self {
        let ext = cbounds.max - cbounds.min;
        // Slightly below nbins / extent so the max centroid maps inside the last bin; axes with
        // zero extent get scale 0 (everything in bin 0, never chosen since one side is empty).
        let k = nbins as f32 * (1.0 - 1e-6);
        let scale = Vec4::select(ext.cmpgt(Vec4::ZERO), Vec4::splat(k) / ext, Vec4::ZERO);
        Self {
            lo: cbounds.min,
            scale,
            last: nbins as u32 - 1,
        }
    }

    /// Bin indices on the three axes (`w` meaningless).
    #[inline(always)]
    pub(super) fn bins(&self, c: Vec4) -> [usize; 3] {
        // `as u32` saturates (NaN to 0), and min() keeps rounding at the top inside the range.
        let t = (c - self.lo) * self.scale;
        [
            (t.x as u32).min(self.last) as usize,
            (t.y as u32).min(self.last) as usize,
            (t.z as u32).min(self.last) as usize,
        ]
    }
}

/// The chosen split of a node.
pub(super) struct Split {
    pub(super) axis: usize,
    /// Triangles in bins `<= bin` go left.
    pub(super) bin: usize,
    pub(super) left_bounds: Box4,
    pub(super) right_bounds: Box4,
    pub(super) left_count: usize,
}

pub(super) struct Ctx<'a> {
    pub(super) cfg: &'a BuildConfig,
}

impl Ctx<'_> {
    /// Builds the subtree over `refs` (which start at leaf position `first`), in parallel when
    /// large.
    fn build_par(
        &self,
        refs: &mut [PrimRef],
        first: usize,
        depth: usize,
        bounds: Box4,
        cbounds: Box4,
    ) -> Sub {
        let n = refs.len();
        if n < self.cfg.parallel_threshold.max(2) {
            let mut pairs = Vec::with_capacity(n.div_ceil(self.cfg.max_leaf.max(1)));
            // One set of bins for the whole sequential subtree, reset per node.
            let mut scratch = Box::new(Bins::new());
            let root = self.build_seq(
                refs,
                first,
                depth,
                bounds,
                cbounds,
                &mut pairs,
                &mut scratch,
            );
            return Sub::Flat { root, pairs };
        }
        match self.split(refs, depth, bounds, cbounds, None) {
            None => Sub::Flat {
                root: Node::leaf(bounds.aabb(), first as u32, n as u16),
                pairs: Vec::new(),
            },
            Some((axis, mid, lb, lc, rb, rc)) => {
                let (l, r) = refs.split_at_mut(mid);
                let (left, right) = rayon::join(
                    || self.build_par(l, first, depth + 1, lb, lc),
                    || self.build_par(r, first + mid, depth + 1, rb, rc),
                );
                Sub::Split {
                    bounds: bounds.aabb(),
                    axis: axis as u8,
                    left: Box::new(left),
                    right: Box::new(right),
                }
            }
        }
    }

    /// Builds the subtree over `refs`, appending the pairs below its root to `out` (offsets
    /// relative to `out`'s start), and returns the root.
    #[allow(clippy::too_many_arguments)]
    fn build_seq(
        &self,
        refs: &mut [PrimRef],
        first: usize,
        depth: usize,
        bounds: Box4,
        cbounds: Box4,
        out: &mut Vec<NodePair>,
        scratch: &mut Bins,
    ) -> Node {
        match self.split(refs, depth, bounds, cbounds, Some(&mut *scratch)) {
            None => Node::leaf(bounds.aabb(), first as u32, refs.len() as u16),
            Some((axis, mid, lb, lc, rb, rc)) => {
                let p = out.len();
                out.push(NodePair::UNUSED);
                let (l, r) = refs.split_at_mut(mid);
                let left = self.build_seq(l, first, depth + 1, lb, lc, out, scratch);
                let right = self.build_seq(r, first + mid, depth + 1, rb, rc, out, scratch);
                out[p] = NodePair::new([left, right]);
                Node::interior(bounds.aabb(), axis as u8, p as u32)
            }
        }
    }

    /// Decides leaf (`None`) or split (binning in parallel when there is no `scratch`); on a split, reorders `refs` so the left child's triangles
    /// come first and returns (axis, left count, left bounds, left centroid bounds, right bounds,
    /// right centroid bounds).
    #[allow(clippy::type_complexity)]
    fn split(
        &self,
        refs: &mut [PrimRef],
        depth: usize,
        bounds: Box4,
        cbounds: Box4,
        scratch: Option<&mut Bins>,
    ) -> Option<(usize, usize, Box4, Box4, Box4, Box4)> {
        let n = refs.len();
        let cfg = self.cfg;
        if n <= 1 {
            return None;
        }
        let can_leaf = n <= cfg.max_leaf;
        if depth < MAX_SAH_DEPTH && (cbounds.max - cbounds.min).truncate().max_element() > 0.0 {
            if let Some(s) = self.best_split(refs, bounds, cbounds, scratch) {
                let (cost, split) = s;
                let leaf_cost = cfg.intersection_cost * n as f32;
                if can_leaf && leaf_cost <= cost {
                    return None;
                }
                let map = BinMap::new(cbounds, cfg.bins.min(n.max(4)));
                let (mid, lc, rc) =
                    partition(refs, |r| map.bins(r.centroid2())[split.axis] <= split.bin);
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
    pub(super) fn best_split(
        &self,
        refs: &[PrimRef],
        bounds: Box4,
        cbounds: Box4,
        scratch: Option<&mut Bins>,
    ) -> Option<(f32, Split)> {
        // Small nodes get fewer bins (as many as triangles, at least 4): the sweep over empty
        // bins would cost more than the binning itself.
        let nb = self.cfg.bins.min(refs.len().max(4));
        let map = BinMap::new(cbounds, nb);
        // Filled in place: the bins are a few KB, too big to move around per node.
        let fill = |bins: &mut Bins, chunk: &[PrimRef]| {
            for r in chunk {
                let k = map.bins(r.centroid2());
                for (a, &ka) in k.iter().enumerate() {
                    bins.bounds[a][ka] = bins.bounds[a][ka].union(r.0);
                    bins.count[a][ka] += 1;
                }
            }
        };
        let bins_par;
        let bins = if let Some(b) = scratch {
            for a in 0..3 {
                b.bounds[a][..nb].fill(Box4::EMPTY);
                b.count[a][..nb].fill(0);
            }
            fill(b, refs);
            &*b
        } else {
            bins_par = refs
                .par_chunks(1 << 13)
                .map(|c| {
                    let mut b = Box::new(Bins::new());
                    fill(&mut b, c);
                    b
                })
                .reduce(|| Box::new(Bins::new()), |a, b| a.merge(&b, nb));
            &*bins_par
        };
        let inv_area = 1.0 / bounds.area();
        let mut best: Option<(f32, Split)> = None;
        for a in 0..3 {
            if map.scale[a] == 0.0 {
                continue;
            }
            let (bb, bc) = (&bins.bounds[a][..nb], &bins.count[a][..nb]);
            // Right-to-left sweep: area·count of the bins above each boundary.
            let mut right_cost = [0f32; MAX_BINS];
            let mut acc = Box4::EMPTY;
            let mut cnt = 0u32;
            for k in (1..nb).rev() {
                acc = acc.union(bb[k]);
                cnt += bc[k];
                right_cost[k - 1] = acc.area() * cnt as f32;
            }
            let mut acc = Box4::EMPTY;
            let mut cnt = 0u32;
            for k in 0..nb - 1 {
                acc = acc.union(bb[k]);
                cnt += bc[k];
                if cnt == 0 || cnt as usize == refs.len() {
                    continue;
                }
                let cost = self.cfg.traversal_cost
                    + self.cfg.intersection_cost
                        * (acc.area() * cnt as f32 + right_cost[k])
                        * inv_area;
                if best.as_ref().is_none_or(|(c, _)| cost < *c) {
                    best = Some((
                        cost,
                        Split {
                            axis: a,
                            bin: k,
                            left_bounds: acc,
                            right_bounds: Box4::EMPTY,
                            left_count: cnt as usize,
                        },
                    ));
                }
            }
        }
        // The right box only for the winner.
        if let Some((_, s)) = best.as_mut() {
            s.right_bounds = bins.bounds[s.axis][s.bin + 1..nb]
                .iter()
                .fold(Box4::EMPTY, |x, y| x.union(*y));
        }
        // A flat node (zero area, e.g. all triangles in one plane) makes costs NaN or inf: any
        // split found is still valid, so keep it (the leaf test then compares against NaN and
        // splits when the node is too big, which is what we want).
        best
    }
}

/// In-place partition: elements for which `left` holds come first. Returns the left count and the
/// centroid bounds of both sides.
pub(super) fn partition(
    refs: &mut [PrimRef],
    left: impl Fn(&PrimRef) -> bool,
) -> (usize, Box4, Box4) {
    let (mut lc, mut rc) = (Box4::EMPTY, Box4::EMPTY);
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
pub(super) fn median_split(
    refs: &mut [PrimRef],
    cbounds: Box4,
) -> (usize, usize, Box4, Box4, Box4, Box4) {
    let mid = refs.len() / 2;
    let axis = cbounds.aabb().longest_axis();
    if (cbounds.max - cbounds.min)[axis] > 0.0 {
        refs.select_nth_unstable_by(mid, |a, b| {
            a.centroid2()[axis].total_cmp(&b.centroid2()[axis])
        });
    }
    let (l, r) = refs.split_at(mid);
    let (lb, lc) = bounds_of(l);
    let (rb, rc) = bounds_of(r);
    (axis, mid, lb, lc, rb, rc)
}
