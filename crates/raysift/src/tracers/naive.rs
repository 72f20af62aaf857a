//! `naive`: every ray against every triangle, threaded over rays. The ground truth every other
//! tracer is checked against; no paper section, just the definition in `tracer.rs`.

use crate::error::Result;
use crate::geom::intersect_triangle;
use crate::rays::{HitBatch, RayBatch, MISS};
use crate::scene::Scene;
use crate::tracer::{closer, par_occlusion_chunks, par_ray_chunks, Stats, Tracer};
use std::sync::Arc;

/// Rays per parallel task: large enough to amortise scheduling, small enough to balance 2–64 cores.
const CHUNK: usize = 256;

/// The brute-force tracer.
#[derive(Default)]
pub struct Naive {
    scene: Option<Arc<Scene>>,
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

    fn prepare(&mut self, scene: Arc<Scene>) -> Result<Stats> {
        self.scene = Some(scene);
        Ok(Stats::default())
    }

    fn intersect(&self, rays: &RayBatch, hits: &mut HitBatch) -> Stats {
        let Some(scene) = self.scene.as_deref() else {
            hits.reset(rays.len());
            return Stats {
                rays: rays.len() as u64,
                ..Stats::default()
            };
        };
        let tris = scene.triangles();
        let ntri = tris.len();
        par_ray_chunks(rays, hits, CHUNK, |range, out| {
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
            }
            let n = range.len() as u64;
            Stats {
                rays: n,
                ray_tri: n * ntri as u64,
                leaves: n,
                ..Stats::default()
            }
        })
    }

    fn occluded(&self, rays: &RayBatch, occluded: &mut Vec<bool>) -> Stats {
        let Some(scene) = self.scene.as_deref() else {
            occluded.clear();
            occluded.resize(rays.len(), false);
            return Stats {
                rays: rays.len() as u64,
                ..Stats::default()
            };
        };
        let tris = scene.triangles();
        par_occlusion_chunks(rays, occluded, CHUNK, |range, out| {
            let mut tests = 0u64;
            for (k, i) in range.clone().enumerate() {
                let (o, d, tmin, tmax) = (rays.origin(i), rays.dir(i), rays.tmin[i], rays.tmax[i]);
                for p in 0..tris.len() {
                    tests += 1;
                    if intersect_triangle(o, d, tris.v0[p], tris.v1[p], tris.v2[p], tmin, tmax)
                        .is_some()
                    {
                        out[k] = true;
                        break;
                    }
                }
            }
            Stats {
                rays: range.len() as u64,
                ray_tri: tests,
                leaves: range.len() as u64,
                ..Stats::default()
            }
        })
    }

    fn bytes(&self) -> usize {
        0
    }
}
