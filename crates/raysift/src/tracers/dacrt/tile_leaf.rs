//! Ours: tile leaves. The cone recursion of a camera batch ends in leaves that test each
//! triangle against the live pixels of its rectangle, with the rays kept in tile order (one
//! 16-byte record each) and no ray list.

use super::order::Order;
use super::packets::{tile_mask, Packets};
use super::partition::{prefetch, PREFETCH};
use super::Task;
use crate::geom::{hit_reach_ceil, hit_reach_floor, Aabb, TriFromOrigin};
use crate::mem::reserve_exact_huge;
use crate::rays::RayBatch;
use crate::tracer::closer;
use glam::{Mat4, Vec4};

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// A leaf over tiles (`Config::pixel_leaf`, ours): each triangle is tested against the
    /// live pixels of its rectangle
    /// ([`PixelProjection::triangle_rects4`](crate::geom::PixelProjection::triangle_rects4)
    /// holds every pixel whose ray can hit it) inside the cell's rectangle `px` (or, for a cell
    /// reaching behind the eye, `None`, of the active tiles), read off the tiles' termination
    /// bits, with no ray list. A ray that can end here has its final hit on a triangle of this
    /// cell, which was tested against it and hit, so only the rays with a hit here are checked
    /// for termination; [`closer`] makes the order of the pairs irrelevant.
    pub(super) fn tile_leaf(
        &mut self,
        cell: &Aabb,
        nt: usize,
        cend: usize,
        px: Option<[i64; 4]>,
        ord: Order,
    ) {
        self.st.leaves += 1;
        let Packets::Tiles { width, rows, tw } = self.packets else {
            unreachable!("tile leaves are for pinhole tiles only")
        };
        let tris = self.tris;
        let mut tests = 0u64;
        // The cell's pixels, clamped to the task's (the triangles' are).
        let (cx, cy) = match px {
            Some(px) => (
                [px[0].max(0), px[1].min(width as i64 - 1)],
                [px[2].max(0), px[3].min(rows as i64 - 1)],
            ),
            None => ([0, width as i64 - 1], [0, rows as i64 - 1]),
        };
        for q in 0..nt {
            let t = self.tri_idx[q] as usize;
            if let Some(&f) = self.tri_idx[..nt].get(q + PREFETCH) {
                let f = f as usize;
                prefetch(self.rects, f);
                prefetch(&tris.v0, f);
                prefetch(&tris.v1, f);
                prefetch(&tris.v2, f);
            }
            let r = self.rects[t];
            let x0 = (r[0] as i64).max(cx[0]);
            let x1 = (r[1] as i64).min(cx[1]);
            // The rectangles are in image rows (the shared projection), the cell's task-local.
            let y0 = (r[2] as i64 - self.row0).max(cy[0]);
            let y1 = (r[3] as i64 - self.row0).min(cy[1]);
            if x0 > x1 || y0 > y1 {
                continue;
            }
            let rect = [x0, x1, y0, y1];
            self.st.leaf_tris += 1;
            // Large rectangles: their pixels are edge-tested first (`PixelEdges`).
            let large = self.edge_test.is_some()
                && ((x1 - x0 + 1) * (y1 - y0 + 1)) as u64 >= self.edge_pixels;
            // Set up on the first live pixel: triangles behind finished pixels (most, late in
            // a front-to-back recursion) cost only their rectangle.
            let mut tri = None;
            let mut edges = None;
            let mut near = None;
            let mut pairs = |task: &mut Self, tile: usize| {
                let (tx, ty) = (tile % tw, tile / tw);
                let mut m = tile_mask(tx, ty, rect) & !task.cones[tile].done;
                task.st.leaf_tiles += 1;
                if m != 0 && !task.zreach.is_empty() {
                    let near = *near.get_or_insert_with(|| {
                        let (a, b, c) = (tris.v0[t], tris.v1[t], tris.v2[t]);
                        hit_reach_floor(task.apex, a.min(b).min(c), a.max(b).max(c))
                    });
                    if near > task.zreach[tile] {
                        task.st.depth_culled += m.count_ones() as u64;
                        m = 0;
                    }
                }
                if m != 0 && large {
                    let e = edges.get_or_insert_with(|| {
                        let (proj, tol) = task.edge_test.as_ref()?;
                        proj.triangle_edges([tris.v0[t], tris.v1[t], tris.v2[t]], *tol)
                    });
                    if let Some(e) = e {
                        let before = m.count_ones() as u64;
                        m = e.mask8x8(tx as i64 * 8, task.row0 + ty as i64 * 8, m);
                        task.st.edge_culled += before - m.count_ones() as u64;
                    }
                }
                if m != 0 {
                    task.st.leaf_live_tiles += 1;
                    let tri = tri.get_or_insert_with(|| {
                        TriFromOrigin::new(task.apex, tris.v0[t], tris.v1[t], tris.v2[t], task.dlow)
                    });
                    tests += task.tile_pairs(tile, m, t as u32, tri);
                }
            };
            if px.is_some() {
                // The tiles under the rectangle.
                for ty in (y0 / 8) as usize..=(y1 / 8) as usize {
                    for tx in (x0 / 8) as usize..=(x1 / 8) as usize {
                        pairs(self, ty * tw + tx);
                    }
                }
            } else {
                // No rectangle for the cell: the tiles still active in it.
                for q in self.cterm..cend {
                    pairs(self, self.cone_idx[q] as usize);
                }
            }
        }
        self.st.ray_tri += tests;
        // Termination of the rays hit here.
        let list = std::mem::take(&mut self.touched_list);
        for &tile in &list {
            let tile = tile as usize;
            let mut m = std::mem::take(&mut self.touched[tile]);
            if ANY {
                self.cones[tile].done |= m;
                continue;
            }
            // Four pixels at a time.
            while self.terminate && m != 0 {
                let (bits, lanes) = pop4(&mut m);
                let (d, bt) = self.tile_lanes(tile, bits);
                let done = Self::final_hit4(cell, self.apex, d, self.tmin0, bt, &ord);
                for (l, &b) in bits.iter().enumerate().take(lanes) {
                    self.cones[tile].done |= ((done >> l & 1) as u64) << b;
                }
            }
            if !self.zreach.is_empty() {
                // The live pixels' farthest best hit (finished pixels are never tested again).
                let recs = &self.tile_rays[tile * 64..tile * 64 + 64];
                let mut live = !self.cones[tile].done;
                let mut reach = 0.0f32;
                while live != 0 {
                    let r = recs[live.trailing_zeros() as usize];
                    live &= live - 1;
                    let h = hit_reach_ceil(r.w, r.truncate());
                    // NaN-safe: a NaN bound makes the tile's NaN, which culls nothing.
                    reach = if h > reach || h.is_nan() { h } else { reach };
                }
                self.zreach[tile] = reach;
            }
        }
        self.touched_list = list;
        self.touched_list.clear();
        let packets = self.packets;
        let mut q = self.cterm;
        while q < cend {
            let c = self.cone_idx[q] as usize;
            if self.cones[c].done == packets.full_mask(c, &[]) {
                self.cone_idx.swap(q, self.cterm);
                self.cterm += 1;
            }
            q += 1;
        }
    }

    /// The records of pixels `bits` of `tile` as four lanes: directions per axis and cut-offs
    /// (a 4×4 transpose: shuffles, not sixteen lane moves).
    #[inline(always)]
    fn tile_lanes(&self, tile: usize, bits: [usize; 4]) -> ([Vec4; 3], Vec4) {
        let recs = bits.map(|b| self.tile_rays[tile * 64 + b]);
        let r = Mat4::from_cols(recs[0], recs[1], recs[2], recs[3]).transpose();
        ([r.x_axis, r.y_axis, r.z_axis], r.w_axis)
    }

    /// The pairs of a tile leaf between triangle `t` (`tri`, seen from the eye, where every ray
    /// of the task starts, at `tmin0`: checked at set-up) and the pixels `m` of `tile` (live,
    /// in its rectangle), four at a time; marks the pixels hit in `touched`. Returns the number
    /// of pairs.
    #[inline(always)]
    fn tile_pairs(&mut self, tile: usize, mut m: u64, t: u32, tri: &TriFromOrigin) -> u64 {
        let Packets::Tiles { width, tw, .. } = self.packets else {
            return 0;
        };
        let (tx, ty) = (tile % tw, tile / tw);
        let n = m.count_ones() as u64;
        if let Some(c) = self.cost.as_mut() {
            let mut b = m;
            while b != 0 {
                let bit = b.trailing_zeros() as usize;
                b &= b - 1;
                c.add((ty * 8 + bit / 8) * width + tx * 8 + bit % 8, 0, 1, 1);
            }
        }
        while m != 0 {
            let (bits, lanes) = pop4(&mut m);
            let (d, cut) = self.tile_lanes(tile, bits);
            let h = tri.intersect4(d, self.tmin0, cut);
            let mut hit = h.mask & ((1 << lanes) - 1);
            while hit != 0 {
                let l = hit.trailing_zeros() as usize;
                hit &= hit - 1;
                let bit = bits[l];
                self.st.leaf_hits += 1;
                let k = (ty * 8 + bit / 8) * width + tx * 8 + bit % 8;
                if ANY {
                    self.occ[k] = true;
                } else if closer(h.t[l], t, cut[l], self.prim[k]) {
                    self.tile_rays[tile * 64 + bit].w = h.t[l];
                    (self.prim[k], self.u[k], self.v[k]) = (t, h.u[l], h.v[l]);
                }
                if self.touched[tile] == 0 {
                    self.touched_list.push(tile as u32);
                }
                self.touched[tile] |= 1 << bit;
            }
        }
        n
    }
}

/// Up to four set bits of `m`, lowest first, taken out of it, and how many: a group of lanes.
/// Missing lanes repeat the first (callers ignore their results).
#[inline(always)]
fn pop4(m: &mut u64) -> ([usize; 4], usize) {
    let mut bits = [m.trailing_zeros() as usize; 4];
    let mut lanes = 0;
    while *m != 0 && lanes < 4 {
        bits[lanes] = m.trailing_zeros() as usize;
        *m &= *m - 1;
        lanes += 1;
    }
    (bits, lanes)
}

/// `v` filled with the rays of the `width × rows` band starting at ray `base`, in tile order
/// (slot `64·tile + bit`): direction and `tmax` (zero records pad the tiles of a short band).
pub(super) fn tile_ordered_rays(
    mut v: Vec<Vec4>,
    rays: &RayBatch,
    base: usize,
    width: usize,
    rows: usize,
    huge: bool,
) -> Vec<Vec4> {
    reserve_exact_huge(&mut v, width.div_ceil(8) * rows.div_ceil(8) * 64, huge);
    for ty in 0..rows.div_ceil(8) {
        for tx in 0..width.div_ceil(8) {
            for bit in 0..64 {
                let (x, y) = (tx * 8 + bit % 8, ty * 8 + bit / 8);
                v.push(if x < width && y < rows {
                    let i = base + y * width + x;
                    rays.dir(i).extend(rays.tmax[i])
                } else {
                    Vec4::ZERO
                });
            }
        }
    }
    v
}
