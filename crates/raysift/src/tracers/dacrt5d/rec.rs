//! The recursion (the post's `DACRT` over ray space): each node culls its parent's triangle
//! prefix against its rays' bound, then stops (cost rule or fixed limits), splits its rays in
//! 5D, or (the hybrid, ours) splits its triangles in space: box splits (`space.rs`) or a cut
//! along the major axis, near half first, with exact early termination; naive leaves.

use super::{Config, Counts, Cull, Space, Stop};
use crate::geom::ray5d::{axes, moved, Bound5, Cone5, Frustum5, DELTA};
use crate::geom::{intersect_triangle, intersect_triangle4, PackedRay, Tri4, Vec3};
use crate::rays::RayBatch;
use crate::scene::TriangleSoup;
use crate::tracer::{closer, CostMut};
use crate::tracers::dacrt::partition::{gather_block, prefetch};

/// A ray in the recursion (48 bytes, swapped whole): its origin, direction and `tmin` copied
/// from the batch (clips and leaves read them here, in node order, not in the batch's
/// scattered arrays), the parameter `t0` of the point its bound starts from (0: the origin;
/// below a box split, its entry into the child's triangle box: `geom::ray5d::clip`), its
/// slopes `u, v` ([`crate::geom::ray5d::classify`]), its index in the task's share and its
/// bundle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub(super) struct Rec {
    pub(super) o: [f32; 3],
    pub(super) d: [f32; 3],
    pub(super) tmin: f32,
    pub(super) t0: f32,
    pub(super) uv: [f32; 2],
    pub(super) id: u32,
    pub(super) g: u32,
}

impl Rec {
    /// The 5D point the bounds hold: `(o + t0·d, u, v)`.
    #[inline(always)]
    pub(super) fn point(&self) -> [f32; 5] {
        let c = moved(Vec3::from(self.o), Vec3::from(self.d), self.t0);
        [c.x, c.y, c.z, self.uv[0], self.uv[1]]
    }

    /// The largest coordinate magnitude of the original origin (the cull margins' scale must
    /// cover it: `geom::ray5d`, "Clipped origins").
    #[inline(always)]
    pub(super) fn scale(&self) -> f32 {
        Vec3::from(self.o).abs().max_element()
    }
}

/// What a node is handed besides its rays and triangles.
#[derive(Clone, Copy, Debug)]
pub(super) enum Given {
    /// Nothing: it bounds its rays and culls.
    Rays,
    /// The parent's rays and bound (a major-axis cut's near half): no new cull.
    Uncut(Bound5),
    /// Its rays' bound and their original origins' scale (a box split's clip pass): it culls.
    Bound(Bound5, f32),
}

/// How many records ahead a leaf asks for their answers.
const LEAF_PREFETCH: usize = 4;

/// Leaves with at most this many triangles gather them into groups of four.
pub(super) const LEAF4_MAX: usize = 64;

/// One task: a share of the rays with its own lists.
pub(super) struct Task<'a, const ANY: bool> {
    pub(super) cfg: &'a Config,
    pub(super) tris: &'a TriangleSoup,
    pub(super) boxes: &'a [[f32; 6]],
    /// The kept upper levels of the shared box splits, once made (`top.rs`).
    pub(super) top: &'a std::sync::OnceLock<super::top::Top>,
    pub(super) rays: &'a RayBatch,
    /// First ray of the share.
    pub(super) base: usize,
    // Closest-hit outputs (empty for ANY); `t` is the z-buffer (starts at `tmax`).
    pub(super) t: &'a mut [f32],
    pub(super) prim: &'a mut [u32],
    pub(super) u: &'a mut [f32],
    pub(super) v: &'a mut [f32],
    pub(super) occ: &'a mut [bool],
    /// Triangle ids; a node's are a prefix.
    pub(super) tri_idx: Vec<u32>,
    /// The share's rays, grouped by bundle; a node's are a range.
    pub(super) recs: Vec<Rec>,
    /// The rays of the box splits above the bundles, packed for the slab test (origin, `tmin`,
    /// `1/d`, best hit so far), and their records' places in `recs` (`space.rs`).
    pub(super) pk: Vec<PackedRay>,
    pub(super) pid: Vec<u32>,
    /// The scene's largest coordinate magnitude and 1 / its largest extent.
    pub(super) scale: f32,
    pub(super) inv_extent: f32,
    pub(super) st: Counts,
    pub(super) cost: Option<CostMut<'a>>,
}

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// Node of bundle `g`: rays `recs[r0..r1]`, the parent's triangles `tri_idx[..ntp]`, and
    /// what the parent hands down ([`Given`]).
    pub(super) fn node(
        &mut self,
        g: usize,
        r0: usize,
        r1: usize,
        ntp: usize,
        depth: u32,
        given: Given,
    ) {
        self.st.nodes += 1;
        let rays_scale = |recs: &[Rec]| recs.iter().fold(0.0f32, |m, r| m.max(r.scale()));
        let (b, s_rays, culls) = match given {
            Given::Rays => {
                let recs = &self.recs[r0..r1];
                let mut b = Bound5::EMPTY;
                for r in recs {
                    b.add(&r.point());
                }
                (b, rays_scale(recs), true)
            }
            Given::Uncut(b) => (b, rays_scale(&self.recs[r0..r1]), false),
            Given::Bound(b, s) => (b, s, true),
        };
        let s_all = self.scale.max(b.origin_scale()).max(s_rays);
        let nt = if culls {
            self.cull(g, &b, s_all, ntp, depth)
        } else {
            ntp
        };
        if let Some(c) = self.cost.as_mut() {
            let tests = if culls { ntp as u64 } else { 0 };
            for r in &self.recs[r0..r1] {
                c.add(r.id as usize, 1, tests, 0);
            }
        }
        let nr = r1 - r0;
        if nt == 0 {
            return;
        }
        let leaf = match self.cfg.stop {
            Stop::Cost => {
                (nr as f64) * (nt as f64)
                    < self.cfg.c_r as f64 * nr as f64 + self.cfg.c_g as f64 * nt as f64
            }
            Stop::Fixed => nr < self.cfg.r_limit || nt < self.cfg.p_limit,
        };
        let boxes = self.cfg.spatial && self.cfg.space == Space::Box;
        if depth >= self.cfg.max_depth || (leaf && !(boxes && nt > self.cfg.leaf_tris)) {
            return self.leaf(r0, r1, nt);
        }
        if self.cfg.spatial && (leaf || nt as f32 > self.cfg.spatial_ratio * nr as f32) {
            let split = match self.cfg.space {
                Space::Box => self.box_split(g, r0, r1, nt, depth, &b),
                Space::Major => self.spatial_split(g, r0, r1, nt, depth, &b, s_all),
            };
            if split {
                return;
            }
            if leaf {
                return self.leaf(r0, r1, nt);
            }
        }
        if !self.ray_split(g, r0, r1, nt, depth, &b) {
            self.leaf(r0, r1, nt);
        }
    }

    /// Filters `tri_idx[..ntp]` in place (branch-free Lomuto) against the node's frustum or
    /// cone; returns the survivors' count.
    fn cull(&mut self, g: usize, b: &Bound5, s_all: f32, ntp: usize, depth: u32) -> usize {
        let (boxes, idx) = (self.boxes, &mut self.tri_idx[..ntp]);
        let k = match self.cfg.cull {
            Cull::Frustum => {
                let f = Frustum5::new(g, b, s_all);
                self.st.frustum_tests += ntp as u64;
                filter(idx, boxes, |lo, hi| f.keeps(lo, hi))
            }
            Cull::Cone => {
                let c = Cone5::new(g, b, s_all);
                self.st.cone_tests += ntp as u64;
                filter(idx, boxes, |lo, hi| c.keeps(lo, hi))
            }
        };
        self.st.culls += 1;
        let surv = match depth {
            0 => &mut self.st.surv_d0,
            1 => &mut self.st.surv_d1,
            2 => &mut self.st.surv_d2,
            3 => &mut self.st.surv_d3,
            4..=7 => &mut self.st.surv_d4_7,
            8..=15 => &mut self.st.surv_d8_15,
            16..=31 => &mut self.st.surv_d16_31,
            _ => &mut self.st.surv_d32,
        };
        *surv += k as u64;
        k
    }

    /// Splits the rays at the middle of their widest weighted dimension; false when they
    /// cannot be split (identical in every weighted dimension, or one side empty).
    fn ray_split(
        &mut self,
        g: usize,
        r0: usize,
        r1: usize,
        nt: usize,
        depth: u32,
        b: &Bound5,
    ) -> bool {
        let (mut dim, mut best) = (0, 0.0f32);
        for d in 0..5 {
            let w = if d < 3 {
                self.inv_extent
            } else {
                self.cfg.dir_weight
            };
            let score = (b.hi[d] - b.lo[d]) * w;
            if score > best {
                (dim, best) = (d, score);
            }
        }
        if !(best > 0.0) {
            return false;
        }
        let mid = b.lo[dim] + (b.hi[dim] - b.lo[dim]) * 0.5;
        let recs = &mut self.recs[r0..r1];
        let mut k = 0;
        for p in 0..recs.len() {
            let low = recs[p].point()[dim] <= mid;
            recs.swap(k, p);
            k += low as usize;
        }
        if k == 0 || k == recs.len() {
            return false;
        }
        self.st.ray_splits += 1;
        self.node(g, r0, r0 + k, nt, depth + 1, Given::Rays);
        self.node(g, r0 + k, r1, nt, depth + 1, Given::Rays);
        true
    }

    /// The hybrid's spatial split along bundle `g`'s major axis `k` (sign `s`): triangles whose
    /// near end `key = s·(near corner)_k` is at most the plane `P` (the keys' mean) are traced
    /// first with every ray; then a ray leaves when its z-buffer (best hit, or `tmax`) lies
    /// before `P` along `s·x_k` by the rounding bound: a far triangle's every gated hit point
    /// has `s·x_k ≥ key − δ > P − δ` (`geom::ray5d`), and a hit at `t' ≤ z` on the ray would have
    /// `s·x_k = s·o_k + t'·|d_k| ≤ s·o_k + z·|d_k|` (`t' ≥ 0`). False when `P` separates nothing.
    #[allow(clippy::too_many_arguments)]
    fn spatial_split(
        &mut self,
        g: usize,
        r0: usize,
        r1: usize,
        nt: usize,
        depth: u32,
        b: &Bound5,
        s_all: f32,
    ) -> bool {
        let (k, s, _, _) = axes(g);
        let boxes = self.boxes;
        let key = |t: u32| {
            let bx = &boxes[t as usize];
            if s > 0.0 {
                bx[k]
            } else {
                -bx[3 + k]
            }
        };
        let sum: f64 = self.tri_idx[..nt].iter().map(|&t| key(t) as f64).sum();
        let plane = (sum / nt as f64) as f32;
        let idx = &mut self.tri_idx[..nt];
        let mut nn = 0;
        for p in 0..nt {
            let near = key(idx[p]) <= plane;
            idx.swap(nn, p);
            nn += near as usize;
        }
        if nn == 0 || nn == nt {
            return false;
        }
        self.st.spatial_splits += 1;
        self.node(g, r0, r1, nn, depth + 1, Given::Uncut(*b));
        // The near recursion permuted only `[0, nn)`: the far triangles are still `[nn, nt)`.
        let nf = gather_block(&mut self.tri_idx, 0, nn, nt);
        // Final rays to the front of the range.
        let gap = DELTA * s_all;
        let mut q = r0;
        for p in r0..r1 {
            let id = self.recs[p].id as usize;
            let i = self.base + id;
            let (ok, dk) = (s * self.rays.origin(i)[k], self.rays.dir(i)[k].abs());
            let z = if ANY { self.rays.tmax[i] } else { self.t[id] };
            let along = ok + z * dk;
            let err = (ok.abs() + (z * dk).abs()) * (1.0 / 1_048_576.0);
            let done = (ANY && self.occ[id]) || along + err + gap < plane;
            self.recs.swap(q, p);
            q += done as usize;
        }
        self.st.terminated += (q - r0) as u64;
        if q < r1 {
            self.node(g, q, r1, nf, depth + 1, Given::Rays);
        }
        true
    }

    /// The naive leaf: rays `recs[r0..r1]` against triangles `tri_idx[..nt]`.
    pub(super) fn leaf(&mut self, r0: usize, r1: usize, nt: usize) {
        self.st.leaves += 1;
        let (groups, ng) = self.leaf_groups(nt);
        let groups = (nt <= LEAF4_MAX).then_some(&groups[..ng]);
        let mut tests = 0u64;
        for p in r0..r1 {
            if p + LEAF_PREFETCH < r1 {
                self.prefetch_answer(self.recs[p + LEAF_PREFETCH].id as usize);
            }
            let rec = self.recs[p];
            tests += self.leaf_ray(&rec, groups, nt);
        }
        self.st.ray_tri += tests;
    }

    /// Asks for ray `id`'s answer so far (in ray order, scattered when the batch's order is not
    /// coherent: shuffled camera rays, BENCHMARKS.md § "dacrt5d: leaves prefetch their rays'
    /// answers").
    #[inline(always)]
    fn prefetch_answer(&self, id: usize) {
        self.prefetch_best(id);
        if !ANY {
            prefetch(self.prim, id);
            prefetch(self.u, id);
            prefetch(self.v, id);
        }
    }

    /// A leaf's triangles in groups of four, when they are at most [`LEAF4_MAX`] (else `0`
    /// groups: the scalar test).
    pub(super) fn leaf_groups(&self, nt: usize) -> ([Tri4; LEAF4_MAX / 4], usize) {
        let tris = self.tris;
        let mut groups = [Tri4::default(); LEAF4_MAX / 4];
        if nt > LEAF4_MAX {
            return (groups, 0);
        }
        for (q, &t) in self.tri_idx[..nt].iter().enumerate() {
            let t = t as usize;
            groups[q / 4].set(q % 4, tris.v0[t], tris.v1[t], tris.v2[t]);
        }
        (groups, nt.div_ceil(4))
    }

    /// One ray of a leaf against triangles `tri_idx[..nt]` (four at a time when `groups` holds
    /// them); updates its answer and returns the pair tests made.
    #[inline(always)]
    pub(super) fn leaf_ray(&mut self, rec: &Rec, groups: Option<&[Tri4]>, nt: usize) -> u64 {
        let tris = self.tris;
        let ids = &self.tri_idx[..nt];
        let id = rec.id as usize;
        let i = self.base + id;
        let (o, d, tmin) = (Vec3::from(rec.o), Vec3::from(rec.d), rec.tmin);
        let mut n = 0u64;
        if ANY {
            if self.occ[id] {
                return 0;
            }
            let tmax = self.rays.tmax[i];
            let hit = match groups {
                Some(groups) => groups.iter().any(|g4| {
                    n += 4;
                    intersect_triangle4(o, d, g4, tmin, tmax).mask != 0
                }),
                None => ids.iter().any(|&t| {
                    n += 1;
                    let t = t as usize;
                    intersect_triangle(o, d, tris.v0[t], tris.v1[t], tris.v2[t], tmin, tmax)
                        .is_some()
                }),
            };
            self.occ[id] = hit;
        } else {
            let (mut bt, mut bp, mut bu, mut bv) =
                (self.t[id], self.prim[id], self.u[id], self.v[id]);
            match groups {
                Some(groups) => {
                    for (gi, g4) in groups.iter().enumerate() {
                        let h = intersect_triangle4(o, d, g4, tmin, bt);
                        let mut m = h.mask;
                        while m != 0 {
                            let l = m.trailing_zeros() as usize;
                            m &= m - 1;
                            let t = ids[gi * 4 + l];
                            if closer(h.t[l], t, bt, bp) {
                                (bt, bp, bu, bv) = (h.t[l], t, h.u[l], h.v[l]);
                            }
                        }
                    }
                    n = 4 * groups.len() as u64;
                }
                None => {
                    for &t in ids {
                        let tu = t as usize;
                        if let Some(h) = intersect_triangle(
                            o,
                            d,
                            tris.v0[tu],
                            tris.v1[tu],
                            tris.v2[tu],
                            tmin,
                            bt,
                        ) {
                            if closer(h.t, t, bt, bp) {
                                (bt, bp, bu, bv) = (h.t, t, h.u, h.v);
                            }
                        }
                    }
                    n = nt as u64;
                }
            }
            (self.t[id], self.prim[id], self.u[id], self.v[id]) = (bt, bp, bu, bv);
        }
        if let Some(c) = self.cost.as_mut() {
            c.add(id, 0, n, n);
        }
        n
    }
}

/// Keeps (moves to the front of `idx`, branch-free Lomuto) the triangles whose boxes `keeps`
/// accepts; returns how many.
#[inline(always)]
fn filter(
    idx: &mut [u32],
    boxes: &[[f32; 6]],
    keeps: impl Fn(&[f32; 3], &[f32; 3]) -> bool,
) -> usize {
    let mut k = 0;
    for p in 0..idx.len() {
        let bx = &boxes[idx[p] as usize];
        let keep = keeps(&[bx[0], bx[1], bx[2]], &[bx[3], bx[4], bx[5]]);
        idx.swap(k, p);
        k += keep as usize;
    }
    k
}
