//! What a Python scene holds: the library's scene, its prepared tracers, the buffers of the last
//! query, and what that query did.

use crate::run;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use raysift::rays::{HitBatch, RayBatch};
use raysift::scene::{Scene, Stamp};
use raysift::{tracers, Stats, Tracer};
use std::sync::Arc;

/// Prepared tracers kept per scene (the least recently used goes beyond this).
const MAX_CACHED_TRACERS: usize = 8;

/// A library error as the Python exception a user expects.
pub fn lib_err(e: raysift::Error) -> PyErr {
    match &e {
        raysift::Error::Io { err, .. } if err.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        raysift::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// A tracer of the cache, with the scene version it was prepared for.
pub struct Cached {
    pub name: String,
    pub opts: Vec<(String, String)>,
    pub tracer: Box<dyn Tracer>,
    pub prepared: Option<Stamp>,
}

/// What the last query did (`Scene.last_stats`).
#[derive(Clone, Debug, Default)]
pub struct LastStats {
    pub query: &'static str,
    pub tracer: String,
    pub opts: Vec<(String, String)>,
    pub threads: usize,
    pub chunks: usize,
    pub layout: String,
    pub prepared: Option<Stats>,
    pub trace: Stats,
    pub convert_ms: f64,
    pub output_ms: f64,
    pub total_ms: f64,
}

/// Buffers kept from one query to the next, so that a query no larger than the last touches no
/// fresh memory for its rays and the tracer's hits (as `raysift trace` and a renderer keep
/// theirs): 32 bytes per ray of rays, 16 of hits (or 1 of occlusion flags).
#[derive(Default)]
pub struct Scratch {
    pub rays: RayBatch,
    pub hits: HitBatch,
    pub occluded: Vec<bool>,
}

/// Unit geometric normals of every triangle, for the scene version `stamp` (made when a query's
/// batch is large enough that one pass over the triangles costs less than a normal per hit; the
/// same arithmetic as `Scene::normal`, so the answer is the same either way).
pub struct Normals {
    pub stamp: Stamp,
    pub normals: Vec<[f32; 3]>,
}

/// A scene's state, behind the Python object's mutex.
pub struct Inner {
    pub scene: Scene,
    pub tracers: Vec<Cached>,
    pub scratch: Scratch,
    pub normals: Option<Normals>,
    pub last: Option<LastStats>,
}

impl Inner {
    pub fn new(scene: Scene) -> Self {
        Self {
            scene,
            tracers: Vec::new(),
            scratch: Scratch::default(),
            normals: None,
            last: None,
        }
    }

    /// The cache index of tracer `name` with `opts`, created when new (moved to the back: most
    /// recently used).
    pub fn tracer(&mut self, name: &str, opts: Vec<(String, String)>) -> PyResult<usize> {
        if let Some(i) = self
            .tracers
            .iter()
            .position(|c| c.name == name && c.opts == opts)
        {
            let c = self.tracers.remove(i);
            self.tracers.push(c);
        } else {
            let tracer = tracers::create(name, &opts).map_err(lib_err)?;
            if self.tracers.len() >= MAX_CACHED_TRACERS {
                self.tracers.remove(0);
            }
            self.tracers.push(Cached {
                name: name.to_string(),
                opts,
                tracer,
                prepared: None,
            });
        }
        Ok(self.tracers.len() - 1)
    }

    /// Prepares tracer `i` when the scene changed since it last did (GIL released); returns the
    /// prepare's stats when it ran.
    pub fn ready(
        &mut self,
        py: Python<'_>,
        i: usize,
        pool: &Option<Arc<rayon::ThreadPool>>,
    ) -> PyResult<Option<Stats>> {
        let stamp = self.scene.stamp();
        let (scene, c) = (&self.scene, &mut self.tracers[i]);
        if c.prepared == Some(stamp) {
            return Ok(None);
        }
        c.prepared = None;
        let tracer = &mut c.tracer;
        let s = py
            .detach(|| run::install(pool, || tracer.prepare_timed(scene)))
            .map_err(lib_err)?;
        c.prepared = Some(stamp);
        Ok(Some(s))
    }
}
