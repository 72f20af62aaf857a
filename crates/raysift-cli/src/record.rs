//! `render --record-rays DIR`: every ray a render hands to the tracer, and the tracer's answers,
//! written as files another engine can trace (the Embree peer, `bench/renderers_embree.py`), so
//! a renderer's workload is compared on exactly the same rays.
//!
//! In DIR, after the render succeeds:
//! * `intersect-rays.npy` (float32 N×8) and `intersect-hits.npy` (hits.npy): the closest-hit
//!   calls, concatenated in call order;
//! * `occluded-rays.npy` and `occluded.npy` (uint8, 1 = blocked): the any-hit calls;
//! * `calls.json`: one record per call, `{kind, start, rays, hits, layout}` (`start` is the
//!   call's first row in its kind's files; `layout` is the batch's ray layout, e.g.
//!   `origin-grids 16`), so a reader can cut out one phase.
//!
//! Recording copies each batch inside the traced call, so a recorded render's times are not
//! for tables; time a second, unrecorded run.

use anyhow::{Context, Result};
use raysift::rays::npy;
use raysift::rays::RayLayout;
use raysift::render::progress::{Answer, Call, CallKind};
use raysift::{HitBatch, RayBatch, Scene};
use std::path::Path;
use std::sync::Mutex;

#[derive(Default)]
struct Log {
    intersect: RayBatch,
    hits: HitBatch,
    occluded: RayBatch,
    blocked: Vec<bool>,
    calls: Vec<serde_json::Value>,
}

/// The rays and answers of one render, gathered call by call.
#[derive(Default)]
pub struct Recorder {
    log: Mutex<Log>,
}

/// A layout as one short string (`unknown`, `pinhole 640x480`, `pixel-samples 640x480x16`,
/// `origin-grids 16`, `to-point`).
fn layout_name(l: &RayLayout) -> String {
    match l {
        RayLayout::Unknown => "unknown".into(),
        RayLayout::Pinhole { width, height, .. } => format!("pinhole {width}x{height}"),
        RayLayout::PixelSamples {
            width,
            height,
            samples,
            ..
        } => format!("pixel-samples {width}x{height}x{samples}"),
        RayLayout::OriginGrids { side } => format!("origin-grids {side}"),
        RayLayout::ToPoint { .. } => "to-point".into(),
    }
}

fn append(to: &mut RayBatch, from: &RayBatch) {
    for i in 0..from.len() {
        to.push(from.get(i));
    }
}

impl Recorder {
    /// Records one trace call (the hook of `render::progress::Watched`).
    pub fn on(&self, c: Call) {
        let mut log = self.log.lock().expect("recorder log");
        let log = &mut *log;
        let start = match c.kind {
            CallKind::Intersect => log.intersect.len(),
            CallKind::Occluded => log.occluded.len(),
        };
        match c.answer {
            Answer::Hits(h) => {
                append(&mut log.intersect, c.batch);
                log.hits.t.extend_from_slice(&h.t);
                log.hits.prim.extend_from_slice(&h.prim);
                log.hits.u.extend_from_slice(&h.u);
                log.hits.v.extend_from_slice(&h.v);
            }
            Answer::Occluded(b) => {
                append(&mut log.occluded, c.batch);
                log.blocked.extend_from_slice(b);
            }
        }
        log.calls.push(serde_json::json!({
            "kind": match c.kind { CallKind::Intersect => "intersect", CallKind::Occluded => "occluded" },
            "start": start,
            "rays": c.rays,
            "hits": c.hits,
            "layout": layout_name(&c.batch.layout),
        }));
    }

    /// Writes the files into `dir` (created if missing), each file whole or not at all.
    pub fn write(&self, dir: &Path, scene: &Scene) -> Result<()> {
        let log = self.log.lock().expect("recorder log");
        std::fs::create_dir_all(dir).with_context(|| {
            format!("--record-rays {}: cannot create the folder", dir.display())
        })?;
        npy::write_rays(dir.join("intersect-rays.npy"), &log.intersect)?;
        npy::write_hits(dir.join("intersect-hits.npy"), &log.hits, scene, false)?;
        npy::write_rays(dir.join("occluded-rays.npy"), &log.occluded)?;
        npy::write_occlusion(dir.join("occluded.npy"), &log.blocked)?;
        let calls = serde_json::to_string_pretty(&log.calls)?;
        let p = dir.join("calls.json");
        std::fs::write(&p, calls + "\n")
            .with_context(|| format!("{}: cannot write", p.display()))?;
        Ok(())
    }
}
