//! `raysift._raysift`, the native module of the Python package `raysift`: numpy in, numpy out,
//! every tracer of the registry (`raysift::tracers::REGISTRY`), so a new tracer appears in Python
//! with no code here.
//!
//! - [`scene`]: `raysift.Scene` (meshes, changes, `cast_rays`, `test_occlusions`, `render`);
//! - [`animation`]: `raysift.Animation` (a file's motion posed into a scene at any time);
//! - [`state`]: what a scene holds (prepared tracers, kept buffers, the last query's stats);
//! - [`query`]: one query, numpy rays to numpy answers, chunk by chunk, GIL released;
//! - [`arrays`]: numpy inputs to the library's types, validated, errors naming argument and index;
//! - [`run`]: thread pools and chunks (Ctrl-C is checked between them);
//! - [`mem`]: output arrays on transparent huge pages.
//!
//! The Python side (`python/raysift/`) re-exports this module, adds the trimesh adapter, and
//! carries the type stubs.

mod animation;
mod arrays;
mod mem;
mod query;
mod run;
mod scene;
mod state;

use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// JSON to the equal Python value.
fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (v.to_string(),))
}

fn counter_list<'py>(
    py: Python<'py>,
    docs: raysift::tracer::CounterDocs,
) -> PyResult<Bound<'py, PyList>> {
    PyList::new(py, docs.iter().map(|&(n, d)| (n, d)))
}

/// The registered tracers, in the order the CLI lists them: a list of dicts with ``name``,
/// ``paper``, ``summary``, ``options`` (each ``{"key", "default", "doc"}``; pass them as keywords
/// to ``cast_rays``), ``presets`` (named option sets the conformance suite proves equal to
/// ``naive``) and ``counters`` (``{"built": [(name, meaning)], "work": [...]}``, as
/// ``Scene.last_stats`` reports them).
#[pyfunction]
fn tracers(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let out = PyList::empty(py);
    for e in raysift::tracers::REGISTRY {
        let d = PyDict::new(py);
        d.set_item("name", e.name)?;
        d.set_item("paper", e.paper)?;
        d.set_item("summary", e.summary)?;
        let opts = PyList::empty(py);
        for o in e.options() {
            let od = PyDict::new(py);
            od.set_item("key", o.key)?;
            od.set_item("default", json_to_py(py, &o.default)?)?;
            od.set_item("doc", o.doc)?;
            opts.append(od)?;
        }
        d.set_item("options", opts)?;
        let presets = PyList::empty(py);
        for p in e.presets {
            let pd = PyDict::new(py);
            pd.set_item("name", p.name)?;
            let po = PyDict::new(py);
            for (k, v) in p.opts {
                po.set_item(k, v)?;
            }
            pd.set_item("options", po)?;
            presets.append(pd)?;
        }
        d.set_item("presets", presets)?;
        let counters = PyDict::new(py);
        counters.set_item("built", counter_list(py, e.built_counters)?)?;
        counters.set_item("work", counter_list(py, e.work_counters)?)?;
        d.set_item("counters", counters)?;
        out.append(d)?;
    }
    Ok(out)
}

/// Pinhole camera rays with Open3D's ``RaycastingScene.create_rays_pinhole`` signature and
/// convention: ``fov_deg`` is the *horizontal* field of view, the camera at ``eye`` looks at
/// ``center`` with ``up``; returns float32 (height_px, width_px, 6) ``[ox, oy, oz, dx, dy, dz]``
/// whose directions are not unit length: their component along the view axis is 1, so ``t_hit``
/// is the depth along that axis, as in Open3D. (``Scene.camera_rays`` makes the CLI's rays:
/// vertical field of view, unit directions.)
#[pyfunction]
fn create_rays_pinhole<'py>(
    py: Python<'py>,
    fov_deg: f64,
    center: &Bound<'py, PyAny>,
    eye: &Bound<'py, PyAny>,
    up: &Bound<'py, PyAny>,
    width_px: usize,
    height_px: usize,
) -> PyResult<Bound<'py, PyAny>> {
    if width_px == 0 || height_px == 0 {
        return Err(PyValueError::new_err(
            "width_px and height_px must be at least 1",
        ));
    }
    if !(fov_deg > 0.0 && fov_deg < 180.0) {
        return Err(PyValueError::new_err(format!(
            "fov_deg: {fov_deg}; expected a horizontal field of view in (0, 180) degrees"
        )));
    }
    let c = arrays::vec3(py, center, "center")?.as_dvec3();
    let e = arrays::vec3(py, eye, "eye")?.as_dvec3();
    let u = arrays::vec3(py, up, "up")?.as_dvec3();
    let forward = (c - e)
        .try_normalize()
        .ok_or_else(|| PyValueError::new_err("center and eye must be distinct"))?;
    let right = forward
        .cross(u)
        .try_normalize()
        .ok_or_else(|| PyValueError::new_err("up must not be parallel to center - eye"))?;
    let down = forward.cross(right);
    let focal = 0.5 * width_px as f64 / (0.5 * fov_deg.to_radians()).tan();
    let (cx, cy) = (0.5 * width_px as f64, 0.5 * height_px as f64);
    let mut out = Vec::with_capacity(6 * width_px * height_px);
    for y in 0..height_px {
        for x in 0..width_px {
            let d = forward
                + right * ((x as f64 + 0.5 - cx) / focal)
                + down * ((y as f64 + 0.5 - cy) / focal);
            out.extend_from_slice(&[
                e.x as f32, e.y as f32, e.z as f32, d.x as f32, d.y as f32, d.z as f32,
            ]);
        }
    }
    Ok(PyArray1::from_vec(py, out)
        .reshape(vec![height_px, width_px, 6])?
        .into_any())
}

/// Batch ray/triangle intersection for scenes that change every frame: numpy in, numpy out,
/// every raysift tracer (see ``raysift.tracers()``).
#[pymodule]
fn _raysift(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<scene::PyScene>()?;
    m.add_class::<animation::PyAnimation>()?;
    m.add_function(wrap_pyfunction!(tracers, m)?)?;
    m.add_function(wrap_pyfunction!(create_rays_pinhole, m)?)?;
    m.add("MISS", raysift::rays::MISS)?;
    m.add("DEFAULT_CHUNK_RAYS", run::DEFAULT_CHUNK_RAYS)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
