//! Algorithm 2 (§3.3, Appendix): the recursion on conic packets, the cones built around each
//! packet's rays, and FlushCones, which hands a cell's live rays to Algorithm 1.

use super::order::{Order, View};
use super::packets::{tile_mask, PackedCone, Packets};
use super::partition::gather_block;
use super::split::half;
use super::{clock, ns_since, Task};
use crate::geom::{Aabb, Cone, ConeQuery};
use glam::Vec3;

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// In-place filter of the active cones `cone_idx[cterm..cend]` against `b`.
    pub(super) fn partition_cones(&mut self, b: &Aabb, cend: usize) -> usize {
        if self.cost.is_some() {
            let start = self.cterm;
            let k = self.partition_cones_inner(b, cend);
            // A packet's test is charged to each of its live rays; kept, they entered the cell.
            for p in start..cend {
                self.charge_packet(self.cone_idx[p] as usize, 1, (p < k) as u64);
            }
            return k;
        }
        self.partition_cones_inner(b, cend)
    }

    /// Adds `tests` and `nodes` to the cost of every live ray of packet `c`.
    fn charge_packet(&mut self, c: usize, tests: u64, nodes: u64) {
        let done = self.cones[c].done;
        let packets = self.packets;
        let perm = std::mem::take(&mut self.perm);
        if let Some(cost) = self.cost.as_mut() {
            packets.for_each(c, &perm, |k, bit| {
                if done >> bit & 1 == 0 {
                    cost.add(k, nodes, tests, 0);
                }
            });
        }
        self.perm = perm;
    }

    fn partition_cones_inner(&mut self, b: &Aabb, cend: usize) -> usize {
        let mut k = self.cterm;
        self.st.cone_box += (cend - self.cterm) as u64;
        if let (Some([x0, x1, y0, y1]), Packets::Tiles { tw, .. }) = (self.pixels(b), self.packets)
        {
            // A tile stays when one of its live (not terminated) pixels is inside the cell's
            // pixel rectangle: a branch-free Lomuto partition (see `partition_rays`). Pixel
            // granularity is what makes front-to-back termination cull: a cone stays alive in
            // every cell it meets while one of its 64 rays is, a pixel only where it is.
            let ids = &mut self.cone_idx[..cend];
            for p in self.cterm..cend {
                let c = ids[p] as usize;
                let live = tile_mask(c % tw, c / tw, [x0, x1, y0, y1]) & !self.cones[c].done;
                ids.swap(k, p);
                k += (live != 0) as usize;
            }
            return k;
        }
        if !self.cones_built {
            // Unreachable in exact arithmetic (every cell is inside the root, in front of the
            // eye); kept conservative should rounding make a cell's rectangle fail.
            return cend;
        }
        for p in self.cterm..cend {
            let c = &self.cones[self.cone_idx[p] as usize];
            if c.q.overlaps(self.apex, b) {
                self.cone_idx.swap(k, p);
                k += 1;
            }
        }
        k
    }

    /// Algorithm 2 on cones `cone_idx[cterm..cend]`.
    pub(super) fn cone_rec(&mut self, cell: Aabb, nt: usize, cend: usize, depth: u32, ord: Order) {
        self.st.nodes += 1;
        let nc = cend - self.cterm;
        if nc == 0 || nt == 0 {
            return;
        }
        let c_limit = if self.tile_leaves {
            self.leaf_tiles
        } else {
            self.cfg.c_limit
        };
        if nc < c_limit || nt < self.cfg.p_limit || depth >= self.cfg.max_depth {
            return self.cone_leaf(cell, nt, cend, depth, ord);
        }
        let Some((axis, split)) = self.choose_split(&cell, nt) else {
            return self.cone_leaf(cell, nt, cend, depth, ord);
        };
        let low_first = match self.view {
            View::From(p) => p[axis] <= split,
            View::To(p) => p[axis] >= split,
            View::Majority => true,
        };
        // As in `ray_rec`: what the first child rejects goes to the second without a test.
        let child = half(&cell, axis, split, low_first);
        let (nt0, other) = self.partition_tris(nt, axis, split, low_first);
        if super::split::no_progress(nt, nt0, other) {
            return self.cone_leaf(cell, nt, cend, depth, ord);
        }
        let cend0 = self.partition_cones(&child, cend);
        let ord0 = ord.child(axis, split, true, low_first);
        self.cone_rec(child, nt0, cend0, depth + 1, ord0);
        let child = half(&cell, axis, split, !low_first);
        let (k, _) = self.partition_tris(nt0, axis, split, !low_first);
        let nt1 = gather_block(&mut self.tri_idx, k, nt0, nt);
        let k = self.partition_cones(&child, cend0);
        let cend1 = gather_block(&mut self.cone_idx, k, cend0, cend);
        let ord1 = ord.child(axis, split, false, !low_first);
        self.cone_rec(child, nt1, cend1, depth + 1, ord1);
    }

    /// The end of a cone recursion: a tile leaf or FlushCones.
    fn cone_leaf(&mut self, cell: Aabb, nt: usize, cend: usize, depth: u32, ord: Order) {
        if self.tile_leaves {
            let c = clock(self.cfg.phase_times);
            let px = self.pixels(&cell);
            self.tile_leaf(&cell, nt, cend, px, ord);
            self.st.ns_leaves += ns_since(c);
            return;
        }
        self.flush(cell, nt, cend, depth, ord)
    }

    /// FlushCones (Algorithm 2): the active cones' live rays that enter `cell` go to the ray
    /// list after `rterm`, Algorithm 1 runs, then terminated rays set their cone bits and fully
    /// terminated cones move behind the terminated-cone pivot.
    fn flush(&mut self, cell: Aabb, nt: usize, cend: usize, depth: u32, ord: Order) {
        let start = self.rterm;
        let mut rend = start;
        let packets = self.packets;
        let filter = self.cfg.flush_filter;
        if let (Some(px), Packets::Tiles { width, tw, .. }) = (self.pixels(&cell), packets) {
            // Screen-space culling: only the live rays of the tile inside the cell's pixels.
            for q in self.cterm..cend {
                let c = self.cone_idx[q] as usize;
                let (tx, ty) = (c % tw, c / tw);
                let mut m = tile_mask(tx, ty, px) & packets.full_mask(c, &[]) & !self.cones[c].done;
                while m != 0 {
                    let bit = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let k = (ty * 8 + bit / 8) * width + tx * 8 + bit % 8;
                    rend += self.flush_ray(&cell, rend, k, filter) as usize;
                }
            }
            return self.flushed(cell, nt, start, rend, cend, depth, ord);
        }
        for q in self.cterm..cend {
            let c = self.cone_idx[q] as usize;
            let done = self.cones[c].done;
            let perm = std::mem::take(&mut self.perm);
            packets.for_each(c, &perm, |k, bit| {
                // Live rays only, and (optionally) only those entering the cell; unfiltered
                // rays are still correct (Algorithm 1 filters them if it divides further, and
                // a naive leaf is correct for any ray).
                if done & (1u64 << bit) == 0 {
                    rend += self.flush_ray(&cell, rend, k, filter) as usize;
                }
            });
            self.perm = perm;
        }
        self.flushed(cell, nt, start, rend, cend, depth, ord)
    }

    /// Loads ray `k` into list slot `slot` for a flush of `cell`; true when it stays there (it
    /// passes the ray/box test, or `filter` is off).
    #[inline(always)]
    fn flush_ray(&mut self, cell: &Aabb, slot: usize, k: usize, filter: bool) -> bool {
        self.load_ray(slot, k);
        if !filter {
            return true;
        }
        self.st.ray_box += 1;
        let keep = cell.hit_by_packed(&self.recs[slot]);
        if let Some(c) = self.cost.as_mut() {
            c.add(k, keep as u64, 1, 0);
        }
        keep
    }

    /// The rest of [`Self::flush`], once the rays `ray_idx[start..rend]` are loaded.
    #[allow(clippy::too_many_arguments)]
    fn flushed(
        &mut self,
        cell: Aabb,
        nt: usize,
        start: usize,
        rend: usize,
        cend: usize,
        depth: u32,
        ord: Order,
    ) {
        let packets = self.packets;
        self.ray_rec(cell, nt, rend, depth, ord, self.cfg.flush_filter);
        for p in start..self.rterm {
            let (c, bit) = packets.of(self.ray_idx[p] as usize, &self.perm);
            self.cones[c].done |= 1u64 << bit;
        }
        let mut q = self.cterm;
        while q < cend {
            let c = self.cone_idx[q] as usize;
            if self.cones[c].done == packets.full_mask(c, &self.perm) {
                self.cone_idx.swap(q, self.cterm);
                self.cterm += 1;
            }
            q += 1;
        }
    }

    /// Builds the cone of packet `c`, or `None` when its rays are not coherent enough.
    pub(super) fn build_cone(&self, c: usize, max_angle: f32) -> Option<PackedCone> {
        let apex = self.apex;
        let rays = self.rays;
        let base = self.base;
        let mut ok = true;
        let mut far = 0.0f64;
        let mut reach = 0.0f64;
        let shadow = matches!(self.packets, Packets::Runs { .. });
        // One pass: the checks, and the packet's unit directions (from the light to the
        // origins for shadow rays), collected without allocating.
        let mut buf = [Vec3::ZERO; 64];
        let mut n = 0;
        self.packets.for_each(c, &self.perm, |k, _| {
            let i = base + k;
            let (o, d) = (rays.origin(i), rays.dir(i));
            if shadow {
                // Segment o → o + d with t in [0, 1] must end (up to rounding) at the light.
                ok &= rays.tmin[i] >= 0.0 && rays.tmax[i] <= 1.0 && o != apex;
                far = far.max((o.as_dvec3() + d.as_dvec3() - apex.as_dvec3()).length());
                reach = reach.max((o.as_dvec3() - apex.as_dvec3()).length());
                buf[n] = (o - apex).normalize_or_zero();
            } else {
                ok &= o == apex && rays.tmin[i] >= 0.0;
                buf[n] = d.normalize_or_zero();
            }
            ok &= d.is_finite() && d != Vec3::ZERO;
            n += 1;
        });
        if !ok {
            return None;
        }
        let cone = Cone::around_directions(apex, &buf[..n])?;
        let (mut half, mut near, mut cut) = (cone.half_angle, 0.0f32, f32::INFINITY);
        if shadow {
            // The rays end `far` away from the light, not on it: points farther than
            // `near = 2^14·far` from the light deviate from the ideal direction by less than
            // 2^-14 rad, covered by widening the angle; boxes closer than `near` count as hit.
            let scale = apex.abs().max_element() as f64 * (f32::EPSILON as f64);
            near = ((far + 4.0 * scale) * 16384.0) as f32;
            half += 2.0 / 16384.0;
            // Segments end at their origins: nothing beyond `reach` (+ the rounding `far`).
            cut = ((reach + 2.0 * far) * (1.0 + 1e-6)) as f32 + near;
        }
        // NaN angles are refused too.
        if half.is_nan() || half > max_angle || half >= std::f32::consts::FRAC_PI_2 {
            return None;
        }
        let cos = (half as f64).cos();
        Some(PackedCone {
            q: ConeQuery::new(cone.axis, cos * cos, near, cut),
            done: 0,
        })
    }
}
