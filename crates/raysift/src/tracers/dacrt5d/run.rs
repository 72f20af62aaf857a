//! One task: its share of the rays classified into the bundles (a counting sort into the
//! record list), each bundle's recursion, the unbounded group's naive leaf, the results.

use super::eye::Out;
use super::rec::{Given, Rec, Task};
use super::top::live_ids;
use super::{Counts, Dacrt5d, Scratch, Space};
use crate::geom::ray5d::{classify, GROUPS, UNBOUNDED};
use crate::geom::Vec3;
use crate::rays::{RayBatch, MISS};
use crate::scene::Scene;
use crate::tracer::{CostMut, Tally};
use crate::tracers::dacrt::scratch::reuse;
use std::ops::Range;

impl Dacrt5d {
    /// Runs one task over rays `range` (outputs already reset to misses); `chunk` is the share
    /// size (the pool slot is `range.start / chunk`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn run_task<const ANY: bool>(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        range: Range<usize>,
        chunk: usize,
        t: &mut [f32],
        prim: &mut [u32],
        u: &mut [f32],
        v: &mut [f32],
        occ: &mut [bool],
        mut cost: Option<CostMut<'_>>,
    ) -> Tally<Counts> {
        let (ntri, len, base) = (scene.len(), range.len(), range.start);
        let slot = self.pool.get(base / chunk);
        let mut sc = slot
            .and_then(|m| m.lock().ok().map(|mut g| std::mem::take(&mut *g)))
            .unwrap_or_default();
        // Rays all from one point: the eye pass (`eye.rs`), when they fit it.
        if self.cfg.eye {
            let mut st = Counts::default();
            let out = Out {
                t: &mut *t,
                prim: &mut *prim,
                u: &mut *u,
                v: &mut *v,
                occ: &mut *occ,
            };
            if self.eye_task::<ANY>(
                scene.triangles(),
                rays,
                range.clone(),
                &mut sc.eye,
                &mut sc.tri_idx,
                out,
                cost.as_mut(),
                &mut st,
            ) {
                let peak = sc.eye.bytes() as u64;
                if let Some(Ok(mut g)) = slot.map(|m| m.lock()) {
                    *g = sc;
                }
                return Tally {
                    counts: st,
                    peak_bytes: peak,
                };
            }
        }
        // Box splits above the bundles (`space.rs`) pack the rays they share.
        let shared = self.cfg.spatial && self.cfg.space == Space::Box;
        let mut task = Task::<ANY> {
            cfg: &self.cfg,
            tris: scene.triangles(),
            boxes: &self.boxes,
            top: &self.top,
            rays,
            base,
            t,
            prim,
            u,
            v,
            occ,
            tri_idx: reuse(sc.tri_idx, ntri, true),
            recs: reuse(sc.recs, len, true),
            pk: reuse(sc.pk, if shared { len } else { 0 }, true),
            pid: reuse(sc.pid, if shared { len } else { 0 }, true),
            scale: self.scale,
            inv_extent: if self.extent > 0.0 {
                1.0 / self.extent
            } else {
                0.0
            },
            st: Counts::default(),
            cost,
        };
        if !ANY {
            // The z-buffer starts at `tmax`.
            for k in 0..len {
                task.t[k] = rays.tmax[base + k];
            }
        }
        // Counting sort into the groups: count, then place (classifying twice costs less than a
        // second buffer).
        let mut start = [0usize; GROUPS + 1];
        for i in range.clone() {
            start[classify(rays.origin(i), rays.dir(i), rays.tmin[i]).0 + 1] += 1;
        }
        for g in 0..GROUPS {
            start[g + 1] += start[g];
        }
        let mut next = start;
        task.recs.resize(len, Rec::default());
        for i in range.clone() {
            let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
            let (g, p) = classify(o, d, tmin);
            task.recs[next[g]] = Rec {
                o: o.to_array(),
                d: d.to_array(),
                tmin,
                t0: 0.0,
                uv: [p[3], p[4]],
                id: (i - base) as u32,
                g: g as u32,
            };
            next[g] += 1;
        }
        let nlive = self.live;
        // Every bounded ray starts from the kept levels, which load their nodes' triangles:
        // the list of every live triangle (a pass over all boxes) only for the other ways.
        let from_kept = shared && self.cfg.top_leaf > 0 && self.cfg.kept_bundles;
        if !from_kept || start[UNBOUNDED] < len {
            task.tri_idx.extend(live_ids(&self.boxes));
        }
        if nlive > 0 {
            // The unbounded group first: below the kept levels the list holds a kept node's
            // triangles only (`space.rs`, `Task::shared_top`).
            if start[UNBOUNDED] < len {
                task.leaf(start[UNBOUNDED], len, nlive);
            }
            if shared {
                // Box splits above the bundles first (`space.rs`).
                let scene_box = (Vec3::from(self.bounds[0]), Vec3::from(self.bounds[1]));
                let up = [0, 1, 2].map(|a| {
                    start[2 * a + 1] - start[2 * a] >= start[2 * a + 2] - start[2 * a + 1]
                });
                task.top(0, start[UNBOUNDED], nlive, up, scene_box.0, scene_box.1);
            } else {
                for g in 0..UNBOUNDED {
                    if start[g] < start[g + 1] {
                        task.node(g, start[g], start[g + 1], nlive, 0, Given::Rays);
                    }
                }
            }
        }
        if !ANY {
            for k in 0..len {
                if task.prim[k] == MISS {
                    task.t[k] = f32::INFINITY;
                }
            }
        }
        let packed = if shared { 36 * len } else { 0 };
        let peak = (4 * ntri + std::mem::size_of::<Rec>() * len + packed) as u64;
        let st = task.st;
        if let Some(Ok(mut g)) = slot.map(|m| m.lock()) {
            *g = Scratch {
                tri_idx: task.tri_idx,
                recs: task.recs,
                pk: task.pk,
                pid: task.pid,
                eye: sc.eye,
            };
        }
        Tally {
            counts: st,
            peak_bytes: peak,
        }
    }
}
