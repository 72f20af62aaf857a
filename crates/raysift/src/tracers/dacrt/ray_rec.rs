//! Algorithm 1 (§3.1–3.2, Fig. 2–3): the in-place recursion on a ray list and a triangle
//! list, the ray records it filters, and the naive leaves (scalar, or four triangles at a time),
//! with §3.4's z-buffer for closest hits.

use super::order::Order;
use super::partition::{gather_block, prefetch};
use super::split::{half, no_progress};
use super::{clock, ns_since, Task};
use crate::geom::{intersect_triangle, intersect_triangle4, Aabb, PackedRay, Tri4};
use crate::rays::MISS;
use crate::tracer::closer;
use glam::{Vec3, Vec4};

/// Relative widening of `t` cut-offs (z-buffer and termination), a few times the shared box
/// slack: filters must keep a ray when a triangle could tie its best hit.
#[inline(always)]
fn widen(t: f32) -> f32 {
    t + t.abs() * (4.0 * f32::EPSILON)
}

/// How many rays ahead the leaf loop asks for a ray's scattered data ([`Task::prefetch_ray`]):
/// random rays on Sponza 313 → 260 ms, the 871K dragon 487 → 444 ms (4, 8 and 16 measured;
/// BENCHMARKS.md, § DACRT: random and bounce rays).
const LEAF_RAY_PREFETCH: usize = 4;

/// How many triangles ahead a four-wide leaf's gather asks for their corners.
const LEAF_TRI_PREFETCH: usize = 8;

/// Leaves with at most this many triangles run the four-wide triangle test on a gathered copy.
const LEAF4_MAX: usize = 64;

/// A ray as the filter loops see it (32 bytes, swapped together with its id in `ray_idx`): the
/// slab test ([`Aabb::hit_by_packed`], four lanes) reads one record instead of eight scattered
/// SoA entries through an index. Its `tmax` lane is the cut-off, the end of the ray's useful
/// interval: the widened z-buffer `t` for closest hits (updated by the leaves), `tmax` for
/// any-hit. The direction itself (needed only by the leaves' exact triangle test) stays in the
/// caller's batch.
pub(super) type RayRec = PackedRay;

impl<'a, const ANY: bool> Task<'a, ANY> {
    #[inline(always)]
    fn best_cut(&self, r: usize) -> f32 {
        if ANY {
            self.rays.tmax[self.base + r]
        } else {
            widen(self.t[r])
        }
    }

    /// Writes ray `k` (local) with its record into slot `slot` of the ray list.
    #[inline(always)]
    pub(super) fn load_ray(&mut self, slot: usize, k: usize) {
        let i = self.base + k;
        // One four-lane division (lane 3 then holds the cut-off); per lane the same IEEE
        // quotient as `1.0 / d`.
        let mut inv_tmax = Vec4::ONE / self.rays.dir(i).extend(1.0);
        inv_tmax.w = self.best_cut(k);
        self.ray_idx[slot] = k as u32;
        self.recs[slot] = RayRec {
            o_tmin: self.rays.origin(i).extend(self.rays.tmin[i]),
            inv_tmax,
        };
    }

    /// Asks for ray `r`'s scattered data (its direction and, for closest hits, its best hit
    /// so far) ahead of the leaf loop: the ray list is in cell order, the arrays in ray order.
    #[inline(always)]
    fn prefetch_ray(&self, r: usize) {
        let i = self.base + r;
        prefetch(&self.rays.dx, i);
        prefetch(&self.rays.dy, i);
        prefetch(&self.rays.dz, i);
        if ANY {
            prefetch(&self.rays.tmax, i);
        } else {
            prefetch(self.t, r);
            prefetch(self.prim, r);
            prefetch(self.u, r);
            prefetch(self.v, r);
        }
    }

    /// Algorithm 1 on rays `ray_idx[rterm..rend]` and triangles `tri_idx[..nt]` in `cell`;
    /// `filtered`: every ray of the list passed a box test against `cell`.
    pub(super) fn ray_rec(
        &mut self,
        cell: Aabb,
        nt: usize,
        rend: usize,
        depth: u32,
        ord: Order,
        filtered: bool,
    ) {
        self.st.nodes += 1;
        let nr = rend - self.rterm;
        if nr == 0 || nt == 0 {
            return;
        }
        if (nr < self.cfg.r_limit && nr.saturating_mul(nt) <= self.cfg.leaf_pairs)
            || nt < self.cfg.p_limit
            || depth >= self.cfg.max_depth
        {
            return self.leaf(&cell, nt, rend, ord);
        }
        let Some((axis, split)) = self.choose_split(&cell, nt) else {
            return self.leaf(&cell, nt, rend, ord);
        };
        let low_first = self.low_first(axis, split, rend);
        // Each child's rays are filtered before its triangles: a child no ray enters costs no
        // triangle stream (sparse batches, whose rays leave most cells empty, spend most of
        // their time streaming triangles; BENCHMARKS.md, § DACRT: sparse batches).
        let child = half(&cell, axis, split, low_first);
        let rend0 = self.partition_rays(&child, rend);
        if rend0 == self.rterm {
            // No ray in the first child: the second holds every ray of the cell the first
            // rejected (all of them, when the list was filtered against the cell).
            let child = half(&cell, axis, split, !low_first);
            let (nt1, other) = self.partition_tris(nt, axis, split, !low_first);
            if no_progress(nt, nt1, other) {
                return self.leaf(&cell, nt, rend, ord);
            }
            let rend1 = if filtered {
                rend
            } else {
                self.partition_rays(&child, rend)
            };
            let ord1 = ord.child(axis, split, false, !low_first);
            return self.ray_rec(child, nt1, rend1, depth + 1, ord1, true);
        }
        // First child: both lists filtered; what it rejects stays behind its prefixes.
        let (nt0, other) = self.partition_tris(nt, axis, split, low_first);
        if no_progress(nt, nt0, other) {
            // Little progress: (nearly) every triangle straddles the plane (§3.6 guard, ours
            // widened from "every" to nine in ten).
            return self.leaf(&cell, nt, rend, ord);
        }
        let ord0 = ord.child(axis, split, true, low_first);
        self.ray_rec(child, nt0, rend0, depth + 1, ord0, true);
        // Second child. A triangle or ray of this cell that the first child's (conservative)
        // test rejected lies in the second child without a test (the cell is their union); the
        // first child's recursion only reordered `[0, nt0)` and `[rterm, rend0)` (terminated
        // rays leave through the `rterm` prefix), so the rejected ones are still at
        // `[nt0, nt)` and `[rend0, rend)`. Only the first child's survivors are tested. Rays
        // count as known only when this cell's list was filtered against it.
        let child = half(&cell, axis, split, !low_first);
        let rend1 = if filtered {
            let k = self.partition_rays(&child, rend0);
            gather_block(&mut self.ray_idx, k, rend0, rend);
            gather_block(&mut self.recs, k, rend0, rend)
        } else {
            self.partition_rays(&child, rend)
        };
        if rend1 == self.rterm {
            return;
        }
        let (k, _) = self.partition_tris(nt0, axis, split, !low_first);
        let nt1 = gather_block(&mut self.tri_idx, k, nt0, nt);
        let ord1 = ord.child(axis, split, false, !low_first);
        self.ray_rec(child, nt1, rend1, depth + 1, ord1, true);
    }

    /// The naive leaf (§3.2): every active ray against every triangle, then early termination.
    fn leaf(&mut self, cell: &Aabb, nt: usize, rend: usize, ord: Order) {
        let c = clock(self.cfg.phase_times);
        if nt <= LEAF4_MAX {
            self.leaf4(cell, nt, rend, ord);
        } else {
            self.leaf_scalar(cell, nt, rend, ord);
        }
        self.st.ns_leaves += ns_since(c);
    }

    /// [`Self::leaf`] for more than [`LEAF4_MAX`] triangles: the scalar loop.
    fn leaf_scalar(&mut self, cell: &Aabb, nt: usize, rend: usize, ord: Order) {
        let tris = self.tris;
        // The ray loop needs `self`; the index list is lent out meanwhile (no allocation).
        let idx = std::mem::take(&mut self.tri_idx);
        let ids = &idx[..nt];
        self.leaf_rays(
            cell,
            rend,
            ord,
            |o, d, tmin, tmax| {
                let mut tests = 0;
                for &t in ids {
                    let t = t as usize;
                    tests += 1;
                    if intersect_triangle(o, d, tris.v0[t], tris.v1[t], tris.v2[t], tmin, tmax)
                        .is_some()
                    {
                        return (true, tests);
                    }
                }
                (false, tests)
            },
            |o, d, tmin, (mut bt, mut bp, mut bu, mut bv)| {
                for &t in ids {
                    let tu = t as usize;
                    if let Some(h) =
                        intersect_triangle(o, d, tris.v0[tu], tris.v1[tu], tris.v2[tu], tmin, bt)
                    {
                        if closer(h.t, t, bt, bp) {
                            (bt, bp, bu, bv) = (h.t, t, h.u, h.v);
                        }
                    }
                }
                ((bt, bp, bu, bv), nt as u64)
            },
        );
        self.tri_idx = idx;
    }

    /// [`Self::leaf`] for up to [`LEAF4_MAX`] triangles: they are gathered once into groups of
    /// four ([`Tri4`], padding lanes are point triangles, never hit) and each ray runs the
    /// four-wide shared test. Same answers as the scalar loop: a group is tested against the
    /// best `t` at its start, then its lanes go through [`closer`] in triangle order, and a lane
    /// beyond the running best fails `closer` just as it would have failed the scalar `tmax`.
    fn leaf4(&mut self, cell: &Aabb, nt: usize, rend: usize, ord: Order) {
        let tris = self.tris;
        let mut buf = [Tri4::default(); LEAF4_MAX / 4];
        let mut ids = [0u32; LEAF4_MAX];
        for q in 0..nt {
            if let Some(&f) = self.tri_idx[..nt].get(q + LEAF_TRI_PREFETCH) {
                prefetch(&tris.v0, f as usize);
                prefetch(&tris.v1, f as usize);
                prefetch(&tris.v2, f as usize);
            }
            let t = self.tri_idx[q];
            let tu = t as usize;
            ids[q] = t;
            buf[q / 4].set(q % 4, tris.v0[tu], tris.v1[tu], tris.v2[tu]);
        }
        let groups = &buf[..nt.div_ceil(4)];
        self.leaf_rays(
            cell,
            rend,
            ord,
            |o, d, tmin, tmax| {
                let mut tests = 0;
                for g in groups {
                    tests += 4;
                    if intersect_triangle4(o, d, g, tmin, tmax).mask != 0 {
                        return (true, tests);
                    }
                }
                (false, tests)
            },
            |o, d, tmin, (mut bt, mut bp, mut bu, mut bv)| {
                for (gi, g) in groups.iter().enumerate() {
                    let h = intersect_triangle4(o, d, g, tmin, bt);
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
                ((bt, bp, bu, bv), nt as u64)
            },
        );
    }

    /// The ray loop both leaves share: each active ray runs `any_hit(o, d, tmin, tmax)` (any-hit
    /// tasks) or `closest(o, d, tmin, best)` (closest-hit tasks: the best `(t, prim, u, v)` so
    /// far in, the new best out), each also returning its ray/triangle test count; then the
    /// result is written back and finished rays move behind the terminated-ray pivot.
    #[inline(always)]
    fn leaf_rays(
        &mut self,
        cell: &Aabb,
        rend: usize,
        ord: Order,
        any_hit: impl Fn(Vec3, Vec3, f32, f32) -> (bool, u64),
        closest: impl Fn(Vec3, Vec3, f32, (f32, u32, f32, f32)) -> ((f32, u32, f32, f32), u64),
    ) {
        self.st.leaves += 1;
        let mut tests = 0u64;
        let mut p = self.rterm;
        while p < rend {
            if let Some(&f) = self.ray_idx[..rend].get(p + LEAF_RAY_PREFETCH) {
                self.prefetch_ray(f as usize);
            }
            let r = self.ray_idx[p] as usize;
            let i = self.base + r;
            let rec = self.recs[p].o_tmin;
            let (o, d, tmin) = (rec.truncate(), self.rays.dir(i), rec.w);
            let done = if ANY {
                let (hit, n) = any_hit(o, d, tmin, self.rays.tmax[i]);
                tests += n;
                if let Some(c) = self.cost.as_mut() {
                    c.add(r, 0, n, n);
                }
                if hit {
                    self.occ[r] = true;
                }
                // Any hit is final, in any order.
                hit
            } else {
                let best = (self.t[r], self.prim[r], self.u[r], self.v[r]);
                let ((bt, bp, bu, bv), n) = closest(o, d, tmin, best);
                tests += n;
                if let Some(c) = self.cost.as_mut() {
                    c.add(r, 0, n, n);
                }
                (self.t[r], self.prim[r], self.u[r], self.v[r]) = (bt, bp, bu, bv);
                self.recs[p].inv_tmax.w = widen(bt);
                self.terminate && bp != MISS && Self::final_hit(cell, o, d, tmin, bt, &ord)
            };
            if done {
                self.ray_idx.swap(p, self.rterm);
                self.recs.swap(p, self.rterm);
                self.rterm += 1;
            }
            p += 1;
        }
        self.st.ray_tri += tests;
    }
}
