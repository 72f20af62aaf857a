//! Progress of a render, seen through the [`Tracer`] contract: [`Watched`] wraps a prepared
//! tracer and calls a hook after every trace call with what was traced, so a progress bar can
//! show rays/s, the phase or bounce and the time left without the renderers knowing about it.
//! The renderers hand every ray to the tracer, so the hook sees all the work; it adds one
//! counter update per batch and changes no result.

use crate::error::{Error, Result};
use crate::rays::{HitBatch, RayBatch, RayLayout};
use crate::scene::Scene;
use crate::tracer::{RayCost, Stats, Tracer};

/// Which query a trace call was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CallKind {
    /// Closest hit ([`Tracer::intersect`]).
    Intersect,
    /// Any hit ([`Tracer::occluded`]).
    Occluded,
}

/// What a trace call answered.
#[derive(Clone, Copy, Debug)]
pub enum Answer<'a> {
    /// Closest hits, one per ray.
    Hits(&'a HitBatch),
    /// Any-hit flags, one per ray.
    Occluded(&'a [bool]),
}

/// One trace call, reported to the hook after it returns.
#[derive(Clone, Copy, Debug)]
pub struct Call<'a> {
    /// Closest or any hit.
    pub kind: CallKind,
    /// True for camera rays (a [`RayLayout::Pinhole`] or [`RayLayout::PixelSamples`] batch):
    /// a path tracer's new sample, a renderer's primary pass.
    pub camera: bool,
    /// Rays in the batch.
    pub rays: u64,
    /// Rays that hit (closest hit) or were blocked (any hit).
    pub hits: u64,
    /// The rays traced (for a hook that records the workload, e.g. `render --record-rays`).
    pub batch: &'a RayBatch,
    /// The tracer's answers to them.
    pub answer: Answer<'a>,
}

/// The hook [`Watched`] calls after every trace call.
pub type Hook<'a> = dyn for<'c> Fn(Call<'c>) + Send + Sync + 'a;

/// A prepared tracer whose trace calls are reported to `hook`. Prepare the inner tracer first:
/// [`Watched::prepare`] refuses, since the wrapper only borrows it.
pub struct Watched<'a> {
    inner: &'a dyn Tracer,
    hook: &'a Hook<'a>,
}

impl<'a> Watched<'a> {
    /// Wraps `inner` (already prepared for the scene it will trace).
    pub fn new(inner: &'a dyn Tracer, hook: &'a Hook<'a>) -> Self {
        Self { inner, hook }
    }
}

fn is_camera(rays: &RayBatch) -> bool {
    matches!(
        rays.layout,
        RayLayout::Pinhole { .. } | RayLayout::PixelSamples { .. }
    )
}

impl Tracer for Watched<'_> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn prepare(&mut self, _scene: &Scene) -> Result<Stats> {
        Err(Error::Invalid(
            "a watched tracer cannot be prepared: prepare the tracer it wraps".into(),
        ))
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        let s = self.inner.intersect(scene, rays, hits, cost)?;
        (self.hook)(Call {
            kind: CallKind::Intersect,
            camera: is_camera(rays),
            rays: rays.len() as u64,
            hits: hits.hit_count() as u64,
            batch: rays,
            answer: Answer::Hits(hits),
        });
        Ok(s)
    }

    fn occluded(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        let s = self.inner.occluded(scene, rays, occluded, cost)?;
        (self.hook)(Call {
            kind: CallKind::Occluded,
            camera: false,
            rays: rays.len() as u64,
            hits: occluded.iter().filter(|&&b| b).count() as u64,
            batch: rays,
            answer: Answer::Occluded(occluded),
        });
        Ok(s)
    }

    fn bytes(&self) -> usize {
        self.inner.bytes()
    }
}
