//! Where and how a trace runs: rayon pools of the requested size, the GIL released while the
//! library works, and batches cut into chunks between which Ctrl-C is honoured.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use raysift::rays::RayLayout;
use std::ops::Range;
use std::sync::{Arc, Mutex};

/// Rays per uninterruptible chunk unless the caller says otherwise: 2^20, so a 1024×1024 image
/// is one library call, exactly what `raysift trace` makes (DACRT pays an O(triangles) pass per
/// call, so smaller chunks would cost it time).
pub const DEFAULT_CHUNK_RAYS: usize = 1 << 20;

/// A pool of the requested size, or `None` for rayon's global pool.
pub type Pool = Option<Arc<rayon::ThreadPool>>;

/// Worker pools by size, made once (starting threads per call would cost small batches).
static POOLS: Mutex<Vec<(usize, Arc<rayon::ThreadPool>)>> = Mutex::new(Vec::new());

/// The pool for `threads` workers; `None` for 0 (rayon's global pool: one worker per core, as
/// the CLI without `--threads`).
pub fn pool(threads: usize) -> PyResult<Option<Arc<rayon::ThreadPool>>> {
    if threads == 0 {
        return Ok(None);
    }
    let mut pools = POOLS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, p)) = pools.iter().find(|(n, _)| *n == threads) {
        return Ok(Some(p.clone()));
    }
    let p = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|k| format!("raysift-{k}"))
        .build()
        .map_err(|e| PyValueError::new_err(format!("threads={threads}: {e}")))?;
    let p = Arc::new(p);
    pools.push((threads, p.clone()));
    Ok(Some(p))
}

/// Runs `f` inside `pool` (or the global pool).
pub fn install<T: Send>(pool: &Option<Arc<rayon::ThreadPool>>, f: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(p) => p.install(f),
        None => f(),
    }
}

/// Workers of `pool` (no trip into it).
pub fn threads_of(pool: &Pool) -> usize {
    match pool {
        Some(p) => p.current_num_threads(),
        None => rayon::current_num_threads(),
    }
}

/// Cuts a batch of `n` rays with `layout` into chunks of about `chunk` rays, each with the layout
/// its rays keep: camera images by whole rows (a multiple of 8 rows when a chunk holds more than
/// 8, so DACRT's 8×8 pixel packets stay whole), pixel samples by whole rows, origin grids by
/// whole groups; any cut of shadow-ray or unknown batches.
pub fn chunks(n: usize, layout: RayLayout, chunk: usize) -> Vec<(Range<usize>, RayLayout)> {
    let chunk = chunk.max(1);
    if n <= chunk {
        return vec![(0..n, layout)];
    }
    let (unit, rows_of) = match layout {
        RayLayout::Pinhole { width, height, .. } if width as usize * height as usize == n => {
            (width as usize, true)
        }
        RayLayout::PixelSamples {
            width,
            height,
            samples,
            ..
        } if width as usize * height as usize * samples as usize == n => {
            (width as usize * samples as usize, true)
        }
        RayLayout::OriginGrids { side } => ((side * side) as usize, false),
        _ => (1, false),
    };
    let mut per = (chunk / unit).max(1);
    if rows_of && per > 8 {
        per -= per % 8;
    }
    let step = per * unit;
    (0..n)
        .step_by(step)
        .map(|s| {
            let r = s..(s + step).min(n);
            let rows = (r.len() / unit) as u32;
            let l = match layout {
                RayLayout::Pinhole { eye, width, .. } if rows_of => RayLayout::Pinhole {
                    eye,
                    width,
                    height: rows,
                },
                RayLayout::PixelSamples {
                    eye,
                    width,
                    samples,
                    ..
                } if rows_of => RayLayout::PixelSamples {
                    eye,
                    width,
                    height: rows,
                    samples,
                },
                RayLayout::OriginGrids { .. } | RayLayout::ToPoint { .. } => layout,
                _ => RayLayout::Unknown,
            };
            (r, l)
        })
        .collect()
}
