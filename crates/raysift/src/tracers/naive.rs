//! `naive`: every ray against every triangle, threaded over rays. The ground truth every other
//! tracer is checked against; no paper section, just the definition in `tracer/mod.rs`.

use crate::error::Result;
use crate::geom::intersect_triangle;
use crate::rays::{HitBatch, RayBatch, MISS};
use crate::scene::{Scene, Stamp};
use crate::tracer::{
    closer, par_occlusion_chunks, par_ray_chunks, CounterDocs, CounterSet, RayCost, Stats, Tracer,
};

/// Rays per parallel task: large enough to amortise scheduling, small enough to balance 2–64 cores.
const CHUNK: usize = 256;

crate::counters! {
    /// What `naive` counts.
    pub struct Counts {
        /// Ray/triangle tests (rays × triangles for closest hits; fewer for occlusion, which stops at the first hit).
        ray_tri,
    }
}

/// The brute-force tracer.
#[derive(Default)]
pub struct Naive {
    stamp: Stamp,
}

impl Naive {
    /// A naive tracer with no scene yet.
    pub fn new() -> Self {
        Self::default()
    }
}

impl Tracer for Naive {
    fn name(&self) -> &'static str {
        "naive"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        self.stamp = scene.stamp();
        Ok(Stats::default())
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let tris = scene.triangles();
        let ntri = tris.len();
        let c: Counts = par_ray_chunks(rays, hits, cost, CHUNK, |range, out, mut cost| {
            for (k, i) in range.clone().enumerate() {
                let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
                let (mut best_t, mut best_p, mut bu, mut bv) = (rays.tmax[i], MISS, 0.0, 0.0);
                for p in 0..ntri {
                    if let Some(h) =
                        intersect_triangle(o, d, tris.v0[p], tris.v1[p], tris.v2[p], tmin, best_t)
                    {
                        if closer(h.t, p as u32, best_t, best_p) {
                            (best_t, best_p, bu, bv) = (h.t, p as u32, h.u, h.v);
                        }
                    }
                }
                if best_p != MISS {
                    (out.t[k], out.prim[k], out.u[k], out.v[k]) = (best_t, best_p, bu, bv);
                }
                if let Some(c) = cost.as_mut() {
                    c.add(k, 0, ntri as u64, ntri as u64);
                }
            }
            Counts {
                ray_tri: (range.len() * ntri) as u64,
            }
        });
        Ok(Stats::traced(rays.len(), &c))
    }

    fn occluded(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let tris = scene.triangles();
        let c: Counts =
            par_occlusion_chunks(rays, occluded, cost, CHUNK, |range, out, mut cost| {
                let mut tests = 0u64;
                for (k, i) in range.clone().enumerate() {
                    let (o, d, tmin, tmax) =
                        (rays.origin(i), rays.dir(i), rays.tmin[i], rays.tmax[i]);
                    let before = tests;
                    for p in 0..tris.len() {
                        tests += 1;
                        if intersect_triangle(o, d, tris.v0[p], tris.v1[p], tris.v2[p], tmin, tmax)
                            .is_some()
                        {
                            out[k] = true;
                            break;
                        }
                    }
                    if let Some(c) = cost.as_mut() {
                        c.add(k, 0, tests - before, tests - before);
                    }
                }
                Counts { ray_tri: tests }
            });
        Ok(Stats::traced(rays.len(), &c))
    }

    fn bytes(&self) -> usize {
        0
    }
}

/// Counter docs, for the registry.
pub const COUNTERS: CounterDocs = Counts::DOCS;
