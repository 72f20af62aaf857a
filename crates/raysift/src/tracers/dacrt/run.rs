//! One call: the plan shared by the tasks (packets or rays, termination, bands of tile rows
//! for the threads), and each task's set-up (buffers from the pool, cones built, the pixel
//! check of our screen-space culling and tile leaves), recursions and results.

use super::order::{Order, View};
use super::packets::{for_each_tile_slot, morton_order, PackedCone, Packets, CONE_BYTES};
use super::ray_rec::RayRec;
use super::scratch::{reuse, Scratch};
use super::screen::{
    balanced_bands, pinhole_deviation, project_all, MAX_PIXEL_DEVIATION, NO_RECT, PINHOLE_TOL,
};
use super::tile_leaf::tile_ordered_rays;
use super::top::TopTree;
use super::{clock, ns_since, Counts, Dacrt, Mode, Task};
use crate::geom::{ConeQuery, PixelProjection};
use crate::mem::reserve_exact_huge;
use crate::rays::{RayBatch, RayLayout, MISS};
use crate::scene::Scene;
use crate::tracer::{CostMut, Tally};
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;

/// The per-call plan shared by all tasks.
#[derive(Clone, Copy, Debug)]
pub(super) struct Plan {
    terminate: bool,
    packets: bool,
    view: View,
    pub(super) chunk: usize,
    /// Camera batches: the image's pixel projection (checked per ray by each task).
    proj: Option<PixelProjection>,
}

impl Dacrt {
    pub(super) fn plan(&self, rays: &RayBatch) -> (Plan, Packets) {
        let k = self.tasks();
        let n = rays.len();
        let mode = self.cfg.mode;
        let packets_ok = matches!(mode, Mode::Auto | Mode::Packet);
        match rays.layout {
            RayLayout::Pinhole { eye, width, height }
                if width as usize * height as usize == n && n > 0 =>
            {
                let (w, h) = (width as usize, height as usize);
                // Bands of whole tile rows.
                let rows = h.div_ceil(8).div_ceil(k) * 8;
                let corners = [0, w - 1, (h - 1) * w, h * w - 1].map(|k| rays.dir(k));
                let plan = Plan {
                    terminate: mode != Mode::Random,
                    packets: packets_ok,
                    view: View::From(eye),
                    chunk: rows * w,
                    proj: (packets_ok && (self.cfg.screen_cull || self.cfg.pixel_cull))
                        .then(|| PixelProjection::fit(eye, width, height, corners))
                        .flatten(),
                };
                (
                    plan,
                    Packets::Tiles {
                        width: w,
                        rows,
                        tw: w.div_ceil(8),
                    },
                )
            }
            RayLayout::ToPoint { target } => {
                let chunk = n.div_ceil(64).div_ceil(k).max(1) * 64;
                let plan = Plan {
                    terminate: mode != Mode::Random,
                    packets: packets_ok && self.cfg.max_shadow_cone_deg > 0.0,
                    view: View::To(target),
                    chunk,
                    proj: None,
                };
                (plan, Packets::Runs { len: chunk })
            }
            _ => {
                let plan = Plan {
                    terminate: mode == Mode::Ray || mode == Mode::Packet,
                    packets: false,
                    view: View::Majority,
                    chunk: n.div_ceil(k).max(1),
                    proj: None,
                };
                (plan, Packets::None)
            }
        }
    }

    /// Runs one task over rays `range` (outputs already reset to misses).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn run_task<const ANY: bool>(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        range: Range<usize>,
        band: usize,
        plan: &Plan,
        packets: Packets,
        top: Option<&TopTree>,
        shared: Option<&SharedRects>,
        t: &mut [f32],
        prim: &mut [u32],
        u: &mut [f32],
        v: &mut [f32],
        occ: &mut [bool],
        cost: Option<CostMut<'_>>,
    ) -> Tally<Counts> {
        let c_setup = clock(self.cfg.phase_times);
        let ntri = scene.len();
        let len = range.len();
        let huge = self.cfg.huge_pages;
        // Restrict the packet layout to this task's share (the last band may be shorter).
        let packets = match (plan.packets, packets) {
            (true, Packets::Tiles { width, tw, .. }) => Packets::Tiles {
                width,
                rows: len / width,
                tw,
            },
            (true, Packets::Runs { .. }) => Packets::Runs { len },
            _ => Packets::None,
        };
        let apex = match plan.view {
            View::From(p) | View::To(p) => p,
            View::Majority => Vec3::ZERO,
        };
        let ncones = packets.count();
        // This share's pool slot (the `band`-th share of the rays).
        let slot = self.pool.get(band);
        let sc = slot
            .and_then(|m| m.lock().ok().map(|mut g| std::mem::take(&mut *g)))
            .unwrap_or_default();
        // Filled by `live_triangles`.
        let tri_idx = reuse(sc.tri_idx, ntri, huge);
        let mut cones = reuse(sc.cones, ncones, huge);
        cones.resize(
            ncones,
            PackedCone {
                q: ConeQuery::default(),
                done: 0,
            },
        );
        let mut perm = reuse(sc.perm, 0, huge);
        if let Packets::Runs { .. } = packets {
            perm = morton_order(perm, rays, range.clone(), &scene.bounds(), huge);
        }
        let mut task = Task::<ANY> {
            cfg: &self.cfg,
            tris: scene.triangles(),
            span: [&self.span[0], &self.span[1], &self.span[2]],
            rays,
            base: range.start,
            t,
            prim,
            u,
            v,
            occ,
            tri_idx,
            ray_idx: reuse(sc.ray_idx, 0, huge),
            recs: reuse(sc.recs, 0, huge),
            rterm: 0,
            terminate: plan.terminate,
            view: plan.view,
            packets,
            apex,
            proj: None,
            tol: 0.0,
            row0: 0,
            cones_built: true,
            cones,
            cone_idx: reuse(sc.cone_idx, ncones, huge),
            perm,
            cterm: 0,
            tile_leaves: false,
            leaf_tiles: self.cfg.pixel_leaf_c_limit,
            edge_test: None,
            edge_pixels: u64::MAX,
            rects: shared.map_or(&[], |s| &s.bufs.rects[..]),
            tile_rays: reuse(sc.tile_rays, 0, huge),
            tmin0: 0.0,
            dlow: 0.0,
            touched: reuse(sc.touched, 0, huge),
            touched_list: reuse(sc.touched_list, 0, huge),
            zreach: reuse(sc.zreach, 0, huge),
            depth_cull: self.cfg.depth_cull,
            st: Counts::default(),
            cost,
            peak: 0,
        };
        let root = scene.bounds();
        let max_angle = match packets {
            Packets::Runs { .. } => self.cfg.max_shadow_cone_deg,
            _ => self.cfg.max_cone_deg,
        }
        .to_radians();
        let mut cull = None;
        if let (Some(proj), Packets::Tiles { width, rows, .. }) = (plan.proj, packets) {
            // Screen-space culling with the largest deviation of a ray from its pixel (rounding
            // for exact pinhole rays; up to about a pixel for jittered ones), for rays from the
            // eye (the layout is only a hint).
            let row0 = range.start / width;
            // With tile leaves, the rays' deviation was bounded by the call (the shared
            // projection's). Otherwise exact pinhole rays pass a fixed tolerance without a
            // division per ray, and other rays have their largest deviation measured.
            let mut tol = PINHOLE_TOL;
            let mut pinhole = false;
            if let Some(s) = shared {
                (pinhole, tol) = (true, s.tol);
            }
            let mut from_eye = true;
            if !pinhole {
                for (y, row) in range.clone().step_by(width).enumerate() {
                    for (x, i) in (row..row + width).enumerate() {
                        from_eye &= rays.origin(i) == apex && rays.tmin[i] >= 0.0;
                        if !proj.within(rays.dir(i), x, row0 + y, tol) {
                            tol = -1.0;
                        }
                    }
                }
            }
            if tol < 0.0 {
                tol = 0.0;
                for (y, row) in range.clone().step_by(width).enumerate() {
                    for (x, i) in (row..row + width).enumerate() {
                        let e = proj.deviation(rays.dir(i), x, row0 + y);
                        // NaN-safe: a NaN deviation makes `tol` NaN, refused below.
                        tol = if e > tol || e.is_nan() { e } else { tol };
                    }
                }
            }
            if from_eye && tol <= MAX_PIXEL_DEVIATION {
                task.row0 = row0 as i64;
                if self.cfg.screen_cull {
                    (task.proj, task.tol) = (Some(proj), tol);
                    // Every cell lies in front of the eye when the root does: the cones would
                    // never be tested, and are not built (see `partition_cones`).
                    task.cones_built = task.pixels(&scene.bounds()).is_none();
                }
                let tmin0 = rays.tmin[range.start];
                if pinhole {
                    task.tile_leaves = true;
                    if self.cfg.edge_pixels != usize::MAX {
                        task.edge_test = Some((proj, tol));
                        task.edge_pixels = self.cfg.edge_pixels as u64;
                    }
                    task.tmin0 = tmin0;
                    task.dlow = (range.clone())
                        .map(|i| rays.dx[i].abs().max(rays.dy[i].abs()).max(rays.dz[i].abs()))
                        .fold(f32::INFINITY, f32::min);
                    let tr = std::mem::take(&mut task.tile_rays);
                    task.tile_rays = tile_ordered_rays(tr, rays, range.start, width, rows, huge);
                    reserve_exact_huge(&mut task.touched, ncones, huge);
                    task.touched.resize(ncones, 0);
                    reserve_exact_huge(&mut task.touched_list, ncones, huge);
                    if !ANY && task.depth_cull {
                        reserve_exact_huge(&mut task.zreach, ncones, huge);
                        task.zreach.resize(ncones, f32::INFINITY);
                    }
                }
                if self.cfg.pixel_cull || task.tile_leaves {
                    let ys = [row0 as i64, (row0 + rows) as i64 - 1];
                    cull = Some((proj, tol, ys, self.cfg.pixel_cull));
                }
            }
        }
        if !ANY && !task.tile_leaves {
            // The z-buffer starts at `tmax` (tile leaves keep theirs in `tile_rays`).
            for k in 0..len {
                task.t[k] = rays.tmax[range.start + k];
            }
        }
        if !task.tile_leaves {
            reserve_exact_huge(&mut task.ray_idx, len, huge);
            task.ray_idx.resize(len, 0);
            reserve_exact_huge(&mut task.recs, len, huge);
            task.recs.resize(len, RayRec::default());
        }
        task.peak = (4 * ntri + CONE_BYTES * ncones + 8 * task.perm.len()) as u64
            + if task.tile_leaves {
                (8 * ntri + (12 + 1024) * ncones) as u64
            } else {
                36 * len as u64
            };
        // Packets first: coherent ones become cones, the rays of the others go to the ray list
        // (with tile leaves, which need no cones to be correct, they stay tiles with a cone
        // that meets every box).
        let mut rend = 0;
        for c in 0..ncones {
            if !task.cones_built {
                task.cone_idx.push(c as u32);
                continue;
            }
            match task.build_cone(c, max_angle) {
                Some(cone) => {
                    task.cones[c] = cone;
                    task.cone_idx.push(c as u32);
                }
                None if task.tile_leaves => {
                    task.cones[c].q = ConeQuery::new(Vec3::Z, 0.0, f32::INFINITY, f32::INFINITY);
                    task.cone_idx.push(c as u32);
                }
                None => {
                    let perm = std::mem::take(&mut task.perm);
                    packets.for_each(c, &perm, |k, _| {
                        task.load_ray(rend, k);
                        rend += 1;
                    });
                    task.perm = perm;
                }
            }
        }
        if ncones == 0 {
            for k in 0..len {
                task.load_ray(k, k);
            }
            rend = len;
        }
        // Rays (all of them, or those of incoherent packets): Algorithm 1 from the root, or
        // (batches without packets) down the top tree to Algorithm 1 from its leaves.
        task.st.ns_setup += ns_since(c_setup);
        let (leaves_before, mut lists) = (task.st.ns_leaves, 0);
        let c_divide = clock(self.cfg.phase_times);
        let rend = task.partition_rays(&root, rend);
        if let Some(top) = top.filter(|t| ncones == 0 && t.root == root) {
            task.top_rec(top, 0, root, rend, 0, Order::NONE, true);
        } else {
            let c_lists = clock(self.cfg.phase_times);
            let nlive = match cull {
                Some((_, _, ys, cull)) if task.tile_leaves => task.band_triangles(ys, cull),
                Some((proj, tol, ys, _)) => task.project_triangles(&proj, tol, ys),
                None => task.live_triangles(),
            };
            lists = ns_since(c_lists);
            task.ray_rec(root, nlive, rend, 0, Order::NONE, true);
            if !task.cone_idx.is_empty() {
                // Cones: Algorithm 2 from the root; the ray list is free again, and the
                // recursion only permuted the triangle list's prefix `[0, nlive)`.
                task.rterm = 0;
                let cend = task.cone_idx.len();
                let cend = task.partition_cones(&root, cend);
                task.cone_rec(root, nlive, cend, 0, Order::NONE);
            }
        }
        // The dividing steps: the recursion's time less its leaves' and the list pass'.
        let leaves = task.st.ns_leaves - leaves_before;
        task.st.ns_lists += lists;
        task.st.ns_divide += ns_since(c_divide).saturating_sub(leaves + lists);
        let c_back = clock(self.cfg.phase_times);
        if !ANY && task.tile_leaves {
            let Packets::Tiles { width, rows, .. } = packets else {
                unreachable!("tile leaves are for pinhole tiles only")
            };
            for_each_tile_slot(width, rows, |k, j| {
                task.t[k] = if task.prim[k] == MISS {
                    f32::INFINITY
                } else {
                    task.tile_rays[j].w
                };
            });
        } else if !ANY {
            for k in 0..len {
                if task.prim[k] == MISS {
                    task.t[k] = f32::INFINITY;
                }
            }
        }
        task.st.ns_setup += ns_since(c_back);
        // The buffers go back to this share's slot for the next call.
        if let Some(Ok(mut g)) = slot.map(|m| m.lock()) {
            let light = std::mem::take(&mut g.light);
            *g = Scratch {
                tri_idx: task.tri_idx,
                ray_idx: task.ray_idx,
                recs: task.recs,
                cones: task.cones,
                cone_idx: task.cone_idx,
                perm: task.perm,
                tile_rays: task.tile_rays,
                touched: task.touched,
                touched_list: task.touched_list,
                zreach: task.zreach,
                light,
            };
        }
        Tally {
            counts: task.st,
            peak_bytes: task.peak,
        }
    }
}

/// A camera call's shared projection (`screen::project_all`): the rays' largest deviation from
/// their pixels (every band's bound), every triangle's rectangle with that tolerance, the
/// tasks' bands balanced by the rectangles (`screen::balanced_bands`), and the pass's
/// non-degenerate triangles and time, counted once for the call.
pub(super) struct SharedRects {
    tol: f64,
    pub(super) bufs: ShareBufs,
    pub(super) live: u64,
    pub(super) ns: u64,
}

/// The shared projection's buffers, kept between calls: the rectangles (8 bytes per
/// triangle) and the band bounds (8 bytes per task plus one).
#[derive(Default)]
pub(super) struct ShareBufs {
    pub(super) rects: Vec<[u16; 4]>,
    pub(super) bounds: Vec<usize>,
}

impl Dacrt {
    /// The shared projection for tile leaves (`Config::pixel_leaf`), when the batch is a
    /// pinhole image whose rays all come from the eye with one `tmin`, within
    /// [`MAX_PIXEL_DEVIATION`] of their pixels (bounded in f32, four at a time, band by band
    /// in parallel: [`pinhole_deviation`]), and both image dimensions are at most 2^16; `None`
    /// otherwise (no tile leaves in this call). Hand it back with [`Self::keep_rects`].
    pub(super) fn shared_rects(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        plan: &Plan,
        packets: Packets,
    ) -> Option<SharedRects> {
        let c = clock(self.cfg.phase_times);
        let (Some(proj), Packets::Tiles { width, .. }, View::From(eye)) =
            (plan.proj, packets, plan.view)
        else {
            return None;
        };
        let (n, height) = (rays.len(), rays.len() / width);
        if !(plan.packets && self.cfg.pixel_leaf && width <= 1 << 16 && height <= 1 << 16) {
            return None;
        }
        let chunk = plan.chunk.max(1);
        let tol = (0..n.div_ceil(chunk))
            .into_par_iter()
            .map(|b| {
                let start = b * chunk;
                let rows = (n - start).min(chunk) / width;
                // One `tmin` for the whole image: the tasks' bands are not these, and a task
                // takes its first ray's `tmin` for all of its rays (NaN-safe: NaN fails).
                if rays.tmin[start] != rays.tmin[0] {
                    return None;
                }
                pinhole_deviation(rays, start, width, rows, &proj, eye)
            })
            .try_reduce(|| 0.0, |a, b| Some(a.max(b)))?;
        let tris = scene.triangles();
        let huge = self.cfg.huge_pages;
        let mut bufs = (self.rects.lock())
            .map(|mut g| std::mem::take(&mut *g))
            .unwrap_or_default();
        if bufs.rects.len() != tris.len() {
            bufs.rects.clear();
            reserve_exact_huge(&mut bufs.rects, tris.len(), huge);
            bufs.rects.resize(tris.len(), NO_RECT);
        }
        let k = self.tasks();
        let (live, cover) = project_all(tris, &mut bufs.rects, &proj, tol, width, height, k > 1);
        reserve_exact_huge(&mut bufs.bounds, k + 1, huge);
        balanced_bands(&cover, width, height, k, &mut bufs.bounds);
        Some(SharedRects {
            tol,
            bufs,
            live,
            ns: ns_since(c),
        })
    }

    /// Keeps the shared projection's buffer for the next call, and counts its pass in `c`.
    pub(super) fn keep_rects(&self, shared: Option<SharedRects>, c: &mut Counts) {
        if let Some(s) = shared {
            c.tri_box += s.live;
            c.ns_lists += s.ns;
            if let Ok(mut g) = self.rects.lock() {
                *g = s.bufs;
            }
        }
    }

    /// The top tree for this call (built now if it is wanted and not there yet), and the
    /// triangle/box tests of its build when this call built it.
    pub(super) fn top_tree(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        plan: &Plan,
    ) -> (Option<&TopTree>, Option<(u64, u64)>) {
        let wanted = !plan.packets
            && self.cfg.top_below > 0.0
            && rays.len() as f64 <= self.cfg.top_below * scene.len() as f64;
        if !wanted {
            return (None, None);
        }
        let mut built = None;
        let top = self.top.get_or_init(|| {
            let c = clock(self.cfg.phase_times);
            let span = [&self.span[0][..], &self.span[1][..], &self.span[2][..]];
            let t = TopTree::build(&self.cfg, span, scene.bounds());
            built = Some((t.tests, ns_since(c)));
            t
        });
        (Some(top), built)
    }
}
