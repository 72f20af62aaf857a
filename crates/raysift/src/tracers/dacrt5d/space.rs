//! The hybrid's box splits (`space=box`, ours): object splits of a node's triangles with each
//! child's rays clipped to its triangles' box, inside a bundle ([`Task::box_split`]) and above
//! the bundles ([`Task::top`], [`Task::shared`]), where the rays of all six bundles share them.
//!
//! Why above the bundles: rays with origins all over the scene (random rays, bounces, shadow
//! rays from hit points) have bundle bounds that hold the whole scene, so each of the six
//! bundles would make the same splits of the same triangles (six times the work of one
//! on-the-fly BVH) before its clipped bounds start to cull. At the root, the bundles whose
//! origins' box is small against the scene's (rays from one point: a camera's, a light's) start
//! their own 5D recursion; the other rays go through one shared set of box splits down to
//! leaves of `shared_leaf` triangles, as 32-byte packed records (origin, `tmin`, `1/d`, best
//! hit) that `dacrt`'s `partition_packed` filters four at a time.
//!
//! Exactness: a child keeps the rays whose slab interval in its triangles' union box, clipped
//! to `[tmin, best]`, is not empty (the gate puts every hit in that interval: `geom::triangle`),
//! and a bundle's child moves their origins to that interval's entry (`geom::ray5d::clip`,
//! "Clipped origins"); the children's triangles are disjoint, so each pair is tested in the one
//! child holding the triangle, and the z-buffer makes any order of the children exact.

use super::rec::{Given, Task, LEAF4_MAX};
use super::top::Top;
use crate::geom::ray5d::{axes, clip, Bound5, UNBOUNDED};
use crate::geom::{Aabb, PackedRay, Vec3};
use crate::tracers::dacrt::partition::{gather_block, partition_packed, prefetch};

/// How many rays ahead [`Task::clip_rays`] asks for a ray's data.
const CLIP_PREFETCH: usize = 8;

/// Bundles (the bounded groups).
const BUNDLES: usize = UNBOUNDED;

/// Per bundle: the rays' bound and original origins' scale after a clip pass (`None`: no rays).
pub(super) type Bounds = [Option<(Bound5, f32)>; BUNDLES];

/// A split of a node's triangles into two disjoint sets (the first at the front of the list).
pub(super) struct TriSplit {
    /// How many triangles the first set holds.
    pub(super) n1: usize,
    pub(super) first: SetBounds,
    pub(super) second: SetBounds,
}

/// A triangle box's centroid doubled (`lo + hi`): only the centroids' order matters to the
/// splits (`split_set` and the kept levels').
#[inline(always)]
pub(super) fn centroid(b: &[f32; 6]) -> Vec3 {
    Vec3::new(b[0] + b[3], b[1] + b[4], b[2] + b[5])
}

/// A triangle set's union box and its centroids' bounds (doubled, as `split_set` takes them).
#[derive(Clone, Copy, Debug)]
pub(super) struct SetBounds {
    pub(super) lo: Vec3,
    pub(super) hi: Vec3,
    pub(super) clo: Vec3,
    pub(super) chi: Vec3,
}

impl Default for SetBounds {
    fn default() -> Self {
        Self {
            lo: Vec3::INFINITY,
            hi: Vec3::NEG_INFINITY,
            clo: Vec3::INFINITY,
            chi: Vec3::NEG_INFINITY,
        }
    }
}

impl SetBounds {
    /// Grown by a triangle's box (and its centroid when `CB`).
    #[inline(always)]
    pub(super) fn grown<const CB: bool>(self, lo: Vec3, hi: Vec3, c: Vec3) -> Self {
        Self {
            lo: self.lo.min(lo),
            hi: self.hi.max(hi),
            clo: if CB { self.clo.min(c) } else { self.clo },
            chi: if CB { self.chi.max(c) } else { self.chi },
        }
    }

    pub(super) fn aabb(&self) -> Aabb {
        Aabb::new(self.lo, self.hi)
    }
}

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// The hybrid's box split inside bundle `g`: the triangles are split at the middle of their
    /// centroids' longest extent into two disjoint sets, the one the rays meet first (by the
    /// bundle's sign on that axis, or the sign of the middle slope) taken first; each child
    /// keeps the rays that can hit one of its triangles before their best hit, bounded from
    /// their entry into its triangles' box, and culls its triangles against that bound. The
    /// second child re-clips from the batch's rays, so the first child's clips never reach it.
    /// False when the centroids do not spread.
    pub(super) fn box_split(
        &mut self,
        g: usize,
        r0: usize,
        r1: usize,
        nt: usize,
        depth: u32,
        b: &Bound5,
    ) -> bool {
        let (k, s, i, _) = axes(g);
        let Some(sp) = self.split_tris::<false>(nt, None, |a| {
            if a == k {
                s > 0.0
            } else {
                let d = if a == i { 3 } else { 4 };
                b.lo[d] + b.hi[d] >= 0.0
            }
        }) else {
            return false;
        };
        self.st.box_splits += 1;
        let k1 = self.clip_rays(r0, r1, sp.first.lo, sp.first.hi);
        if let Some((b1, s1)) = self.bound_rays(r0, k1)[g] {
            self.node(g, r0, k1, sp.n1, depth + 1, Given::Bound(b1, s1));
        }
        // The first child permuted only `[0, n1)`: the second's triangles are still `[n1, nt)`.
        let n2 = gather_block(&mut self.tri_idx, 0, sp.n1, nt);
        let k2 = self.clip_rays(r0, r1, sp.second.lo, sp.second.hi);
        if let Some((b2, s2)) = self.bound_rays(r0, k2)[g] {
            self.node(g, r0, k2, n2, depth + 1, Given::Bound(b2, s2));
        }
        true
    }

    /// Above the bundles: rays `recs[r0..r1]` of any bundle, triangles `tri_idx[..nt]` inside
    /// the box `[lo, hi]` (the scene's); `up[a]`: most rays move towards `+a` (the near child
    /// first). Each bundle whose origins' box is small against the scene's (extent sums,
    /// `hand_over`: rays from one point) takes its rays into its own recursion on every
    /// triangle. The other rays share box splits ([`Task::shared`]) down to nodes of
    /// `shared_leaf` triangles (or `max_depth`), whose leaves test them all. (Handing a bundle
    /// over deeper too, when the triangles no longer outnumber its rays `spatial_ratio` times,
    /// was measured and dropped: BENCHMARKS.md § "dacrt5d: box splits".)
    pub(super) fn top(
        &mut self,
        r0: usize,
        r1: usize,
        nt: usize,
        up: [bool; 3],
        lo: Vec3,
        hi: Vec3,
    ) {
        let bounds = self.bound_rays(r0, r1);
        let reach = self.cfg.hand_over * (hi - lo).element_sum();
        let mut hand = [false; BUNDLES];
        for g in 0..BUNDLES {
            if let Some((b, _)) = bounds[g] {
                #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN extents hand over
                let small = !(b.origin_extent() > reach);
                hand[g] = small;
            }
        }
        let kept = self.kept();
        let start = self.hand_over(&hand, &bounds, r0, r1, nt, kept);
        if start == r1 {
            return;
        }
        // The shared rays, packed (`pk`, `pid`: their records stay where they are).
        self.pk.clear();
        self.pid.clear();
        for p in start..r1 {
            let r = &self.recs[p];
            let (o, d) = (Vec3::from(r.o), Vec3::from(r.d));
            let best = self.best(r.id as usize);
            self.pk.push(PackedRay::new(o, Vec3::ONE / d, r.tmin, best));
            self.pid.push(p as u32);
        }
        let n = self.pk.len();
        match kept {
            Some(top) => self.shared_top(top, 0, 0, n, up),
            None => self.shared(0, n, nt, None, 0, up),
        }
    }

    /// The kept levels (`top.rs`), made by the first call that asks after a `prepare`; `None`
    /// without them (`top_leaf = 0`, or no live triangle).
    fn kept(&mut self) -> Option<&'a Top> {
        if self.cfg.top_leaf == 0 {
            return None;
        }
        let (boxes, cfg, cell) = (self.boxes, self.cfg, self.top);
        let mut built = 0;
        let top = cell.get_or_init(|| {
            let top = Top::new(boxes, cfg.top_leaf, cfg.max_depth, cfg.top_split);
            built = top.nodes.len() as u64;
            top
        });
        self.st.top_built += built;
        (!top.nodes.is_empty()).then_some(top)
    }

    /// Kept node `i`'s triangles as the whole list (which then no longer holds every triangle:
    /// the ways that need them all come first); returns their count.
    fn load_kept(&mut self, top: &Top, i: usize) -> usize {
        let n = top.nodes[i];
        let (start, len) = (n.start as usize, n.len as usize);
        self.tri_idx.clear();
        self.tri_idx
            .extend_from_slice(&top.order[start..start + len]);
        len
    }

    /// A handed-over bundle `g` in kept node `i` (`kept_bundles`), its rays `recs[r0..r1]`
    /// (bound by `bound` at the root; below, clipped to the node's box): where the node is a
    /// kept leaf or holds at most `spatial_ratio` times as many triangles as rays, its
    /// triangles (copied into the list's prefix) start the bundle's recursion, bound from the
    /// rays' entries into its box; otherwise each child, near one first as in
    /// [`Task::box_split`] (by `order_by`'s slopes), takes the rays clipped to its box. The kept
    /// splits are box splits made once: the same exactness argument (module doc), without a
    /// pass over the node's triangles per call.
    #[allow(clippy::too_many_arguments)]
    fn bundle_top(
        &mut self,
        top: &Top,
        i: usize,
        g: usize,
        r0: usize,
        r1: usize,
        bound: Option<(Bound5, f32)>,
        order_by: &Bound5,
        depth: u32,
    ) {
        let n = top.nodes[i];
        let len = n.len as usize;
        if n.kids == 0 || len as f32 <= self.cfg.spatial_ratio * (r1 - r0) as f32 {
            // The rays' bound from their entries into this node's box (the last clip).
            let Some((b, s)) = bound.or_else(|| self.bound_rays(r0, r1)[g]) else {
                return;
            };
            self.load_kept(top, i);
            return self.node(g, r0, r1, len, depth, Given::Bound(b, s));
        }
        self.st.kept_descents += 1;
        let (k, sign, i_axis, _) = axes(g);
        let a = n.axis as usize;
        let low_first = if a == k {
            sign > 0.0
        } else {
            let d = if a == i_axis { 3 } else { 4 };
            order_by.lo[d] + order_by.hi[d] >= 0.0
        };
        let low = n.kids as usize;
        let order = if low_first {
            [low, low + 1]
        } else {
            [low + 1, low]
        };
        for c in order {
            let set = top.nodes[c].set;
            // Clipped from the batch's rays: the first child's clips never reach the second.
            // Their bound is made where the recursion starts (the order below uses the slopes
            // of an ancestor's: only the order, never an answer, depends on it).
            let kc = self.clip_rays(r0, r1, set.lo, set.hi);
            if kc > r0 {
                self.bundle_top(top, c, g, r0, kc, None, order_by, depth + 1);
            }
        }
    }

    /// The kept levels (`top.rs`): node `i` of them with packed rays `pk[a..b]`; below a kept
    /// leaf, the splits are made per call from its triangles, copied into the list's prefix
    /// (so the list no longer holds every triangle: the hand-over and the unbounded group's
    /// leaf come before).
    fn shared_top(&mut self, top: &Top, i: usize, a: usize, b: usize, up: [bool; 3]) {
        let n = top.nodes[i];
        if n.kids == 0 {
            let len = self.load_kept(top, i);
            return self.shared(a, b, len, Some((n.set.clo, n.set.chi)), 0, up);
        }
        self.st.top_splits += 1;
        let low = n.kids as usize;
        let order = if up[n.axis as usize] {
            [low, low + 1]
        } else {
            [low + 1, low]
        };
        for c in order {
            let k = self.filter_packed(a, b, &top.nodes[c].set.aabb());
            if k > a {
                self.shared_top(top, c, a, k, up);
            }
        }
    }

    /// Shared box splits: packed rays `pk[a..b]` (of any bundle), triangles `tri_idx[..nt]`.
    /// `cb`: the triangles' centroid bounds, when the parent's split made them.
    fn shared(
        &mut self,
        a: usize,
        b: usize,
        nt: usize,
        cb: Option<(Vec3, Vec3)>,
        depth: u32,
        up: [bool; 3],
    ) {
        let split = if depth < self.cfg.max_depth && nt > self.cfg.shared_leaf {
            self.split_tris::<true>(nt, cb, |ax| up[ax])
        } else {
            None
        };
        let Some(sp) = split else {
            return self.shared_leaf(a, b, nt);
        };
        self.st.top_splits += 1;
        let (s1, s2) = (sp.first, sp.second);
        let k1 = self.filter_packed(a, b, &s1.aabb());
        if k1 > a {
            self.shared(a, k1, sp.n1, Some((s1.clo, s1.chi)), depth + 1, up);
        }
        // The first child permuted only `[0, n1)`: the second's triangles are still `[n1, nt)`.
        let n2 = gather_block(&mut self.tri_idx, 0, sp.n1, nt);
        let k2 = self.filter_packed(a, b, &s2.aabb());
        if k2 > a {
            self.shared(a, k2, n2, Some((s2.clo, s2.chi)), depth + 1, up);
        }
    }

    /// Moves the packed rays of `pk[a..b]` whose slab interval in `bx`, clipped to
    /// `[tmin, best]`, is not empty to the front (`dacrt`'s `partition_packed`: the shared slab
    /// test's decision bit for bit, four at a time); returns the end of the kept rays. Every hit on
    /// a triangle inside `bx` lies in that interval (`geom::triangle`), so the others have none
    /// closer than their best.
    fn filter_packed(&mut self, a: usize, b: usize, bx: &Aabb) -> usize {
        let k = partition_packed(bx, &mut self.pk[..b], &mut self.pid[..b], a);
        self.st.ray_clips += (b - a) as u64;
        self.st.clipped_out += (b - k) as u64;
        if let Some(c) = self.cost.as_mut() {
            // Every ray was tested against the box; those kept entered the node.
            for (j, &p) in self.pid[a..b].iter().enumerate() {
                c.add(self.recs[p as usize].id as usize, (a + j < k) as u64, 1, 0);
            }
        }
        k
    }

    /// The leaf of the shared splits: packed rays `pk[a..b]` against `tri_idx[..nt]`, their
    /// best hits written back into the packed records (an occluded ray's as `-inf`: no box
    /// keeps it).
    fn shared_leaf(&mut self, a: usize, b: usize, nt: usize) {
        self.st.leaves += 1;
        let (groups, ng) = self.leaf_groups(nt);
        let groups = (nt <= LEAF4_MAX).then_some(&groups[..ng]);
        let mut tests = 0u64;
        for j in a..b {
            // The records two steps ahead, their best hits one step ahead (read from records
            // asked for a step earlier).
            if j + 2 * CLIP_PREFETCH < b {
                prefetch(&self.recs, self.pid[j + 2 * CLIP_PREFETCH] as usize);
            }
            if j + CLIP_PREFETCH < b {
                let r = &self.recs[self.pid[j + CLIP_PREFETCH] as usize];
                self.prefetch_best(r.id as usize);
            }
            let rec = self.recs[self.pid[j] as usize];
            tests += self.leaf_ray(&rec, groups, nt);
            self.pk[j].inv_tmax.w = self.best(rec.id as usize);
        }
        self.st.ray_tri += tests;
    }

    /// Starts the recursion of each bundle `g` with `hand[g]` on its rays of `recs[r0..r1]`
    /// (moved to the front, bundle by bundle): through the kept levels when there are some and
    /// `kept_bundles` ([`Task::bundle_top`]), else on the triangles `tri_idx[..nt]`; returns
    /// where the other rays start.
    fn hand_over(
        &mut self,
        hand: &[bool; BUNDLES],
        bounds: &Bounds,
        r0: usize,
        r1: usize,
        nt: usize,
        kept: Option<&Top>,
    ) -> usize {
        let mut start = r0;
        for g in 0..BUNDLES {
            let Some((b, s)) = bounds[g].filter(|_| hand[g]) else {
                continue;
            };
            let recs = &mut self.recs[start..r1];
            let mut q = 0;
            for p in 0..recs.len() {
                let here = recs[p].g as usize == g;
                recs.swap(q, p);
                q += here as usize;
            }
            match kept.filter(|_| self.cfg.kept_bundles) {
                Some(top) => self.bundle_top(top, 0, g, start, start + q, Some((b, s)), &b, 0),
                None => self.node(g, start, start + q, nt, 0, Given::Bound(b, s)),
            }
            start += q;
        }
        start
    }

    /// [`split_set`] of `tri_idx[..nt]`.
    fn split_tris<const CB: bool>(
        &mut self,
        nt: usize,
        cb: Option<(Vec3, Vec3)>,
        up: impl Fn(usize) -> bool,
    ) -> Option<TriSplit> {
        split_set::<CB>(&mut self.tri_idx[..nt], self.boxes, cb, up)
    }

    /// Moves the rays of `recs[r0..r1]` that can hit a triangle inside the box `[lo, hi]`
    /// before their best hit to the front of the range, with their entry into the box as `t0`
    /// (`geom::ray5d::clip`); returns the end of the kept rays. [`Task::bound_rays`] bounds
    /// them.
    pub(super) fn clip_rays(&mut self, r0: usize, r1: usize, lo: Vec3, hi: Vec3) -> usize {
        let mut q = r0;
        for p in r0..r1 {
            if p + CLIP_PREFETCH < r1 {
                self.prefetch_best(self.recs[p + CLIP_PREFETCH].id as usize);
            }
            // The record is written whole, by the swap: a 4-byte store of `t0` into it before the
            // swap's 16-byte loads stalled them (no store forwarding; the dragon's 512² camera,
            // 140 against 133 ms).
            let mut r = self.recs[p];
            let t0 = clip(
                Vec3::from(r.o),
                Vec3::from(r.d),
                lo,
                hi,
                r.tmin,
                self.best(r.id as usize),
            );
            r.t0 = t0.unwrap_or(0.0);
            self.recs[p] = self.recs[q];
            self.recs[q] = r;
            q += t0.is_some() as usize;
        }
        self.st.clipped_out += (r1 - q) as u64;
        self.st.ray_clips += (r1 - r0) as u64;
        if let Some(c) = self.cost.as_mut() {
            // One box test per ray (the child node counts the visits of those it keeps).
            for r in &self.recs[r0..r1] {
                c.add(r.id as usize, 0, 1, 0);
            }
        }
        q
    }

    /// The bounds per bundle of clipped rays `recs[r0..r1]`: a bundle keeps its clipped
    /// origins only when their box is smaller (the sum of its extents) than its original
    /// origins' (rays from one point, a camera's, are bound tighter by their apex than by their
    /// entry points); otherwise its records go back to `t0 = 0`.
    pub(super) fn bound_rays(&mut self, r0: usize, r1: usize) -> Bounds {
        let (mut orig, mut clipped) = ([Bound5::EMPTY; BUNDLES], [Bound5::EMPTY; BUNDLES]);
        let mut s_rays = [0.0f32; BUNDLES];
        for r in &self.recs[r0..r1] {
            let g = r.g as usize;
            clipped[g].add(&r.point());
            orig[g].add(&[r.o[0], r.o[1], r.o[2], r.uv[0], r.uv[1]]);
            s_rays[g] = s_rays[g].max(r.scale());
        }
        let mut restore = [false; BUNDLES];
        let mut out: Bounds = [None; BUNDLES];
        for g in 0..BUNDLES {
            if orig[g].lo[0] > orig[g].hi[0] {
                continue;
            }
            restore[g] = orig[g].origin_extent() <= clipped[g].origin_extent();
            out[g] = Some((if restore[g] { orig[g] } else { clipped[g] }, s_rays[g]));
            self.st.clips += (!restore[g]) as u64;
        }
        if restore.iter().any(|&r| r) {
            for r in &mut self.recs[r0..r1] {
                if restore[r.g as usize] {
                    r.t0 = 0.0;
                }
            }
        }
        out
    }

    /// How far ray `id` may still find a hit: its best hit so far (closest hit), or `tmax`, or
    /// `-inf` once occluded (any hit: no box keeps it).
    #[inline(always)]
    fn best(&self, id: usize) -> f32 {
        if ANY {
            if self.occ[id] {
                f32::NEG_INFINITY
            } else {
                self.rays.tmax[self.base + id]
            }
        } else {
            self.t[id]
        }
    }

    /// Asks for the best hit so far of ray `id` (the z-buffer is in ray order, the records in
    /// node order).
    #[inline(always)]
    pub(super) fn prefetch_best(&self, id: usize) {
        if ANY {
            prefetch(self.occ, id);
            prefetch(&self.rays.tmax, self.base + id);
        } else {
            prefetch(self.t, id);
        }
    }
}

/// Splits the triangle set `idx` at the middle of its centroids' longest extent into two
/// disjoint sets, the first moved to the front; `up(axis)` tells whether the rays move towards
/// `+axis` (then the low side is the first set); `cb`: the centroids' bounds when the caller has
/// them (doubled: `lo + hi`), else a first pass makes them; with `CB` the sets' centroid bounds
/// are made too, for the children's splits (the bundles' splits, whose children cull first, do
/// without: making them anyway cost the dragon's camera rays 14% in one A/B). `None` when the
/// centroids do not spread or one side is empty. The sets depend on the triangles only (`up`
/// only says which is first). (The kept levels, [`super::top`], are made once by their own
/// rules: Morton cells, or this one on 16-bit centroids.)
#[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(ext > 0)`: NaN extents do not split
pub(super) fn split_set<const CB: bool>(
    idx: &mut [u32],
    boxes: &[[f32; 6]],
    cb: Option<(Vec3, Vec3)>,
    up: impl Fn(usize) -> bool,
) -> Option<TriSplit> {
    let nt = idx.len();
    let (clo, chi) = cb.unwrap_or_else(|| {
        let (mut clo, mut chi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for &t in idx.iter() {
            let c = centroid(&boxes[t as usize]);
            (clo, chi) = (clo.min(c), chi.max(c));
        }
        (clo, chi)
    });
    let ext = chi - clo;
    let a = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    if !(ext[a] > 0.0) {
        return None;
    }
    let plane = clo[a] + ext[a] * 0.5;
    let up = up(a);
    let (mut n1, mut first_set, mut second_set) = (0, SetBounds::default(), SetBounds::default());
    for p in 0..nt {
        let bx = &boxes[idx[p] as usize];
        let (lo, hi, c) = (
            Vec3::new(bx[0], bx[1], bx[2]),
            Vec3::new(bx[3], bx[4], bx[5]),
            centroid(bx),
        );
        let first = (c[a] <= plane) == up;
        if first {
            first_set = first_set.grown::<CB>(lo, hi, c);
        } else {
            second_set = second_set.grown::<CB>(lo, hi, c);
        }
        idx.swap(n1, p);
        n1 += first as usize;
    }
    (n1 > 0 && n1 < nt).then_some(TriSplit {
        n1,
        first: first_set,
        second: second_set,
    })
}
