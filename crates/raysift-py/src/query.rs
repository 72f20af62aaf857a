//! One query (`cast_rays`, `test_occlusions`) from numpy rays to numpy answers.
//!
//! The rays are transposed and checked into the scene's kept ray buffers, the tracer prepared if
//! the scene changed, and the batch traced chunk by chunk into the kept hit buffers, each chunk's
//! answers written into the output arrays. Everything but the Python glue runs with the GIL
//! released, in the pool of the requested size; between chunks the GIL is taken back to check
//! for Ctrl-C (and any other pending signal).

use crate::arrays::{self, Interval, RayInput};
use crate::mem;
use crate::run;
use crate::state::{lib_err, Inner, LastStats, Normals};
use pyo3::prelude::*;
use rayon::prelude::*;
use raysift::rays::{HitBatch, RayBatch, MISS};
use raysift::scene::Scene;
use raysift::Stats;
use std::ops::Range;
use std::time::Instant;

/// Hits per block of the parallel output pass.
const BLOCK: usize = 1 << 14;

/// Which query to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// Closest hit (`cast_rays`).
    Closest,
    /// Any hit (`test_occlusions`).
    Any,
}

/// What a query asks for.
pub struct Request<'a, 'py> {
    pub input: &'a RayInput<'py>,
    pub interval: Interval,
    pub tracer: &'a str,
    pub opts: Vec<(String, String)>,
    pub threads: usize,
    pub chunk_rays: usize,
    pub query: Query,
}

/// Open3D's five closest-hit arrays, flat: t, mesh id, mesh-local primitive id, (u, v) pairs,
/// unit geometric normals (zeros on a miss).
pub struct HitArrays {
    pub t: Vec<f32>,
    pub geometry: Vec<u32>,
    pub prim: Vec<u32>,
    pub uv: Vec<f32>,
    pub normal: Vec<f32>,
}

impl HitArrays {
    fn zeroed(n: usize) -> Self {
        Self {
            t: mem::zeroed(n),
            geometry: mem::zeroed(n),
            prim: mem::zeroed(n),
            uv: mem::zeroed(2 * n),
            normal: mem::zeroed(3 * n),
        }
    }

    /// Writes the answers of rays `range` from the library's `hits` (scene-wide primitive ids),
    /// the normals from `normals` (per triangle) when given, else computed per hit.
    fn write(
        &mut self,
        scene: &Scene,
        normals: Option<&[[f32; 3]]>,
        range: Range<usize>,
        hits: &HitBatch,
    ) {
        let (a, b) = (range.start, range.end);
        (
            self.t[a..b].par_chunks_mut(BLOCK),
            self.geometry[a..b].par_chunks_mut(BLOCK),
            self.prim[a..b].par_chunks_mut(BLOCK),
            self.uv[2 * a..2 * b].par_chunks_mut(2 * BLOCK),
            self.normal[3 * a..3 * b].par_chunks_mut(3 * BLOCK),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(blk, (t, geo, prim, uv, nrm))| {
                let base = blk * BLOCK;
                t.copy_from_slice(&hits.t[base..base + t.len()]);
                for k in 0..geo.len() {
                    let p = hits.prim[base + k];
                    uv[2 * k] = hits.u[base + k];
                    uv[2 * k + 1] = hits.v[base + k];
                    if p == MISS {
                        (geo[k], prim[k]) = (MISS, MISS);
                        continue; // normals stay zero
                    }
                    let g = scene.geometry_of(p);
                    geo[k] = g;
                    prim[k] = p - scene.mesh_prims(g as usize).start as u32;
                    let nv = match normals {
                        Some(all) => all[p as usize],
                        None => scene.normal(p as usize).to_array(),
                    };
                    nrm[3 * k..3 * k + 3].copy_from_slice(&nv);
                }
            });
    }
}

/// A query's answer.
pub enum Answer {
    Closest(HitArrays),
    Any(Vec<bool>),
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Why a query stopped inside the pool.
enum Fail {
    /// Ray `.0` is bad.
    Ray(usize, arrays::BadRay),
    /// The library refused (prepare or trace).
    Lib(raysift::Error),
}

/// What the worker side of a query measured.
#[derive(Default)]
struct Times {
    convert_ms: f64,
    output_ms: f64,
    trace: Stats,
}

/// Unit normals of every triangle (the arithmetic of `Scene::normal`).
fn triangle_normals(scene: &Scene) -> Vec<[f32; 3]> {
    (0..scene.len())
        .into_par_iter()
        .map(|p| scene.normal(p).to_array())
        .collect()
}

/// Traces chunk `range` (rays `rays`) into the kept hit buffers and writes its answers.
#[allow(clippy::too_many_arguments)]
fn trace_chunk(
    scene: &Scene,
    tracer: &dyn raysift::Tracer,
    rays: &RayBatch,
    scratch: (&mut HitBatch, &mut Vec<bool>),
    normals: Option<&[[f32; 3]]>,
    range: Range<usize>,
    answer: &mut Answer,
    times: &mut Times,
) -> Result<(), Fail> {
    let (hits, occluded) = scratch;
    let t0 = Instant::now();
    let mut s = match answer {
        Answer::Closest(_) => tracer.intersect(scene, rays, hits, None),
        Answer::Any(_) => tracer.occluded(scene, rays, occluded, None),
    }
    .map_err(Fail::Lib)?;
    s.trace_ms = ms_since(t0);
    times.trace += &s;
    let t1 = Instant::now();
    match answer {
        Answer::Closest(a) => a.write(scene, normals, range, hits),
        Answer::Any(o) => o[range].copy_from_slice(occluded),
    }
    times.output_ms += ms_since(t1);
    Ok(())
}

impl Inner {
    /// Runs `req` and records what it did in `self.last` (all but `total_ms`, which the caller
    /// sets when its arrays are made).
    ///
    /// A batch of one chunk makes one trip into the pool (transpose and check, prepare when the
    /// scene changed, trace, write the answers): every trip wakes the pool's workers, which on a
    /// busy machine costs milliseconds. Each further chunk is one more trip, after a check for
    /// Ctrl-C with the GIL held.
    pub fn query(&mut self, py: Python<'_>, req: Request<'_, '_>) -> PyResult<Answer> {
        let pool = run::pool(req.threads)?;
        let input = req.input;
        let (data, cols, image) = (input.array.as_slice()?, input.cols, input.image());
        let n = data.len() / cols;
        let i = self.tracer(req.tracer, req.opts.clone())?;
        let stamp = self.scene.stamp();
        let Inner {
            scene,
            tracers,
            scratch,
            normals,
            ..
        } = self;
        let cached = &mut tracers[i];
        let (query, chunk_rays, interval) = (req.query, req.chunk_rays, req.interval);
        // The first trip: everything up to and including the first chunk.
        let first = py.detach(|| {
            run::install(&pool, || {
                let mut times = Times::default();
                let t0 = Instant::now();
                arrays::fill_batch(&mut scratch.rays, data, cols, interval)
                    .map_err(|(i, bad)| Fail::Ray(i, bad))?;
                scratch.rays.layout = scratch.rays.detect_layout(image);
                times.convert_ms = ms_since(t0);
                // No rays: nothing to prepare or trace (the tracer was still made, so a bad name
                // or option is reported whatever the batch).
                let parts = if n == 0 {
                    vec![]
                } else {
                    run::chunks(n, scratch.rays.layout, chunk_rays)
                };
                let mut prepared = None;
                if n > 0 && cached.prepared != Some(stamp) {
                    cached.prepared = None;
                    prepared = Some(cached.tracer.prepare_timed(scene).map_err(Fail::Lib)?);
                    cached.prepared = Some(stamp);
                }
                let t1 = Instant::now();
                let mut answer = match query {
                    Query::Closest => Answer::Closest(HitArrays::zeroed(n)),
                    Query::Any => Answer::Any(mem::zeroed(n)),
                };
                // Normals per triangle when the batch is large enough that one pass over the
                // triangles costs less than a normal per hit (at least half as many rays as
                // triangles); kept while the scene is unchanged.
                if normals.as_ref().is_some_and(|c| c.stamp != stamp) {
                    *normals = None;
                }
                if query == Query::Closest && normals.is_none() && n > 0 && n >= scene.len() / 2 {
                    *normals = Some(Normals {
                        stamp,
                        normals: triangle_normals(scene),
                    });
                }
                times.output_ms = ms_since(t1);
                if parts.len() == 1 {
                    let table = normals.as_ref().map(|c| c.normals.as_slice());
                    let hits = (&mut scratch.hits, &mut scratch.occluded);
                    trace_chunk(
                        scene,
                        cached.tracer.as_ref(),
                        &scratch.rays,
                        hits,
                        table,
                        0..n,
                        &mut answer,
                        &mut times,
                    )?;
                }
                Ok((answer, parts, prepared, times))
            })
        });
        let (mut answer, parts, prepared, mut times) = first.map_err(|f| match f {
            Fail::Ray(i, bad) => bad.to_err(input, "rays", i),
            Fail::Lib(e) => lib_err(e),
        })?;
        let layout = format!("{:?}", scratch.rays.layout);
        if parts.len() > 1 {
            let table = normals.as_ref().map(|c| c.normals.as_slice());
            let tracer = cached.tracer.as_ref();
            for (range, chunk_layout) in &parts {
                py.check_signals()?;
                let mut sub = scratch.rays.slice(range.clone());
                sub.layout = *chunk_layout;
                let hits = (&mut scratch.hits, &mut scratch.occluded);
                let (answer, times) = (&mut answer, &mut times);
                py.detach(|| {
                    run::install(&pool, || {
                        trace_chunk(
                            scene,
                            tracer,
                            &sub,
                            hits,
                            table,
                            range.clone(),
                            answer,
                            times,
                        )
                    })
                })
                .map_err(|f| match f {
                    Fail::Ray(i, bad) => bad.to_err(input, "rays", i),
                    Fail::Lib(e) => lib_err(e),
                })?;
            }
        }
        py.check_signals()?;
        self.last = Some(LastStats {
            query: match req.query {
                Query::Closest => "cast_rays",
                Query::Any => "test_occlusions",
            },
            tracer: req.tracer.to_string(),
            opts: req.opts,
            threads: run::threads_of(&pool),
            chunks: parts.len(),
            layout,
            prepared,
            trace: times.trace,
            convert_ms: times.convert_ms,
            output_ms: times.output_ms,
            total_ms: 0.0,
        });
        Ok(answer)
    }
}
