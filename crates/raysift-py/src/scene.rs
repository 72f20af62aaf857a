//! `raysift.Scene`: meshes, their changes, and queries through any registered tracer.
//!
//! A scene keeps one prepared tracer per (name, options) and prepares it again only when the
//! scene changed since ([`Scene::stamp`]), so an animation that calls `set_transform` or
//! `set_vertices` between casts gets the tracers' update path (refit, DACRT's re-read), not a
//! fresh build.

use crate::arrays::{self, Interval};
use crate::query::{Answer, Query, Request};
use crate::run::{self, DEFAULT_CHUNK_RAYS};
use crate::state::{lib_err, Inner};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::{PyNotImplementedError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use pyo3::types::PyDict;
use rayon::prelude::*;
use raysift::rays::Camera;
use raysift::scene::{Mesh, Scene};
use raysift::Stats;
use std::sync::{Mutex, MutexGuard};
use std::time::Instant;

/// A triangle scene: meshes with rigid transforms, traced by any tracer of `raysift.tracers()`.
///
/// Make one empty (``Scene()``) and add meshes with ``add_triangles``, or load a file with
/// ``Scene.load(path)``. Query it with ``cast_rays`` (closest hit) and ``test_occlusions`` (any
/// hit); animate it with ``set_transform`` and ``set_vertices``, after which the next query
/// updates its tracer (refit, re-read) instead of building it anew.
///
/// Names follow Open3D's ``RaycastingScene`` where the concept is the same. A scene serves one
/// query at a time: a second thread's call waits for the first to finish. It keeps its prepared
/// tracers (one per tracer name and options, at most 8) and the ray and hit buffers of its last
/// query (48 bytes per ray), so repeated queries touch no fresh memory for them.
#[pyclass(name = "Scene", module = "raysift", frozen)]
pub struct PyScene {
    inner: Mutex<Inner>,
}

fn new_scene(scene: Scene) -> PyScene {
    PyScene {
        inner: Mutex::new(Inner::new(scene)),
    }
}

/// Tracer options from Python keywords, as the `key=value` strings of `--opt` (sorted, so equal
/// options find the same cached tracer).
fn options_of(options: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<(String, String)>> {
    let mut out = Vec::new();
    if let Some(d) = options {
        for (k, v) in d.iter() {
            let key: String = k.extract()?;
            let val = if let Ok(b) = v.cast::<pyo3::types::PyBool>() {
                b.is_true().to_string()
            } else if let Ok(i) = v.extract::<i64>() {
                i.to_string()
            } else if let Ok(x) = v.extract::<f64>() {
                x.to_string()
            } else if let Ok(s) = v.extract::<String>() {
                s
            } else {
                return Err(PyValueError::new_err(format!(
                    "tracer option {key}: expected a bool, a number or a string, got {}",
                    v.get_type().name()?
                )));
            };
            out.push((key, val));
        }
    }
    out.sort();
    Ok(out)
}

fn stats_dict<'py>(py: Python<'py>, s: &Stats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rays", s.rays)?;
    d.set_item("prepare_ms", s.prepare_ms)?;
    d.set_item("trace_ms", s.trace_ms)?;
    d.set_item("peak_bytes", s.peak_bytes)?;
    let built = PyDict::new(py);
    for (k, v) in s.built.iter() {
        built.set_item(k, v)?;
    }
    let work = PyDict::new(py);
    for (k, v) in s.work.iter() {
        work.set_item(k, v)?;
    }
    d.set_item("built", built)?;
    d.set_item("work", work)?;
    Ok(d)
}

fn shape_with(lead: &[usize], last: usize) -> Vec<usize> {
    let mut s = lead.to_vec();
    s.push(last);
    s
}

/// A camera as `raysift rays camera` makes it: the default framing of the scene's bounds, then
/// the given eye, look and up.
#[allow(clippy::too_many_arguments)]
fn camera_for(
    py: Python<'_>,
    scene: &Scene,
    width: u32,
    height: u32,
    eye: Option<&Bound<'_, PyAny>>,
    look: Option<&Bound<'_, PyAny>>,
    up: Option<&Bound<'_, PyAny>>,
    fov: f32,
) -> PyResult<Camera> {
    if width == 0 || height == 0 {
        return Err(PyValueError::new_err("width and height must be at least 1"));
    }
    let mut cam = Camera::framing(&scene.bounds(), fov, width as f32 / height as f32);
    if let Some(e) = eye {
        cam.eye = arrays::vec3(py, e, "eye")?;
    }
    if let Some(l) = look {
        cam.look = arrays::vec3(py, l, "look")?;
    }
    if let Some(u) = up {
        cam.up = arrays::vec3(py, u, "up")?;
    }
    cam.validate().map_err(lib_err)?;
    Ok(cam)
}

impl PyScene {
    /// A Python scene of a library scene.
    pub(crate) fn from_library(scene: Scene) -> Self {
        new_scene(scene)
    }

    /// The scene's state, locked (for `raysift.Animation`, which poses it).
    pub(crate) fn lock_inner<'a>(&'a self, py: Python<'_>) -> MutexGuard<'a, Inner> {
        self.lock(py)
    }

    fn lock<'a>(&'a self, py: Python<'_>) -> MutexGuard<'a, Inner> {
        match self.inner.lock_py_attached(py) {
            Ok(g) => g,
            // A panic inside a tracer left the cache in an unknown state: drop the tracers (the
            // scene itself is only changed by methods that complete before they return).
            Err(poisoned) => {
                let mut g = poisoned.into_inner();
                g.tracers.clear();
                g
            }
        }
    }

    fn rebuild(&self, py: Python<'_>, meshes: Vec<Mesh>) -> PyResult<()> {
        let mut g = self.lock(py);
        let name = g.scene.name.clone();
        g.scene = Scene::from_meshes(name, meshes).map_err(lib_err)?;
        Ok(())
    }
}

#[pymethods]
impl PyScene {
    /// An empty scene; add meshes with ``add_triangles``.
    #[new]
    fn py_new() -> PyResult<Self> {
        Ok(new_scene(
            Scene::from_meshes("python", vec![]).map_err(lib_err)?,
        ))
    }

    /// Loads a scene file, as the ``raysift`` command does: ``.obj``, ``.ply`` (ascii, binary
    /// little/big endian), ``.gltf``/``.glb``, ``.off``, each optionally gzipped (``.gz``), or a
    /// generator spec (``sphere:N``, ``soup:N[:SEED]``, ``cornell``, ``tile:K:FILE``). Each
    /// object, group or glTF primitive becomes one mesh (geometry id in load order); primitive
    /// ids are in file order, so the CLI and other programs agree.
    ///
    /// Raises ``FileNotFoundError`` for a missing file and ``ValueError`` (naming the file and
    /// the place) for malformed content or a scene without triangles.
    #[staticmethod]
    fn load(py: Python<'_>, path: std::path::PathBuf) -> PyResult<Self> {
        let spec = path.to_string_lossy().to_string();
        let scene = py
            .detach(|| raysift::scene::procedural::open(&spec))
            .map_err(lib_err)?;
        if scene.is_empty() {
            return Err(PyValueError::new_err(format!(
                "{spec}: the scene has no triangles"
            )));
        }
        Ok(new_scene(scene))
    }

    /// The embedded Stanford bunny (16,301 triangles), the CLI's default scene.
    #[staticmethod]
    fn bunny() -> PyResult<Self> {
        Ok(new_scene(raysift::scene::default_scene().map_err(lib_err)?))
    }

    /// Adds a triangle mesh and returns its geometry id (0, 1, ... in the order added).
    ///
    /// ``vertices``: (V, 3) positions; ``triangles``: (T, 3) integer vertex indices; or pass one
    /// object with ``.vertices`` and ``.faces`` (a ``trimesh.Trimesh``) as ``vertices``.
    /// ``transform``: optional (4, 4) or (3, 4) local-to-world affine matrix (``set_transform``
    /// replaces it). float32 C-contiguous arrays are read in place; others are converted once.
    ///
    /// Raises ``ValueError`` naming the argument and the first bad index for a wrong shape, a
    /// non-finite coordinate or an index out of range.
    #[pyo3(signature = (vertices, triangles=None, transform=None, name=None))]
    fn add_triangles(
        &self,
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: Option<&Bound<'_, PyAny>>,
        transform: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<usize> {
        let (vobj, tobj) = match triangles {
            Some(t) => (vertices.clone(), t.clone()),
            None => match (vertices.getattr("vertices"), vertices.getattr("faces")) {
                (Ok(v), Ok(f)) => (v, f),
                _ => return Err(PyValueError::new_err(
                    "triangles: missing (pass (T, 3) indices, or a mesh with .vertices and .faces)",
                )),
            },
        };
        let positions = arrays::vertices(py, &vobj, "vertices")?;
        let indices = arrays::triangles(py, &tobj, "triangles", positions.len())?;
        let xf = match transform {
            Some(t) if !t.is_none() => arrays::affine(py, t, "transform")?,
            _ => glam::Affine3A::IDENTITY,
        };
        let mut meshes = self.lock(py).scene.meshes().to_vec();
        let id = meshes.len();
        let mut mesh = Mesh::new(
            name.unwrap_or_else(|| format!("mesh{id}")),
            positions,
            indices,
        );
        mesh.transform = xf;
        meshes.push(mesh);
        self.rebuild(py, meshes)?;
        Ok(id)
    }

    /// Sets mesh ``mesh_id``'s local-to-world transform, a (4, 4) or (3, 4) affine matrix (a rigid
    /// motion keeps the tracers' update path: BVH refit, DACRT re-read).
    fn set_transform(
        &self,
        py: Python<'_>,
        mesh_id: usize,
        transform: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let xf = arrays::affine(py, transform, "transform")?;
        let mut g = self.lock(py);
        let scene = &mut g.scene;
        py.detach(|| scene.set_transform(mesh_id, xf))
            .map_err(lib_err)
    }

    /// Replaces mesh ``mesh_id``'s local vertex positions (same count; the triangles stay): a
    /// deformation.
    fn set_vertices(
        &self,
        py: Python<'_>,
        mesh_id: usize,
        vertices: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let positions = arrays::vertices(py, vertices, "vertices")?;
        let mut g = self.lock(py);
        let scene = &mut g.scene;
        py.detach(|| scene.replace_positions(mesh_id, positions))
            .map(|_| ())
            .map_err(lib_err)
    }

    /// Closest hits of ``rays``, an array of shape (..., 6) ``[ox, oy, oz, dx, dy, dz]`` (then
    /// tmin = 0, tmax = inf) or (..., 8) ``[..., tmin, tmax]``, traced by ``tracer`` (any name of
    /// ``raysift.tracers()``) on ``threads`` worker threads (0: one per core), with tracer
    /// options as keywords (e.g. ``max_leaf=2`` for ``bvh``, ``mode="ray"`` for ``dacrt``).
    ///
    /// Returns a dict of arrays of the rays' leading shape, as Open3D's ``cast_rays``:
    /// ``t_hit`` float32 (inf on a miss; in units of the direction's length), ``geometry_ids``
    /// uint32 (the mesh; 4294967295 on a miss), ``primitive_ids`` uint32 (the triangle's index
    /// within its mesh; 4294967295 on a miss; the scene-wide id is
    /// ``primitive_offsets[geometry_ids] + primitive_ids``), ``primitive_uvs`` float32 (..., 2)
    /// (hit = (1-u-v)·v0 + u·v1 + v·v2) and ``primitive_normals`` float32 (..., 3) (unit
    /// geometric normal, (v1-v0)×(v2-v0) normalised; zeros on a miss). Every tracer returns the
    /// same answer bit for bit (ties in t go to the smaller primitive id).
    ///
    /// float32 C-contiguous rays are read in place; float64, Fortran-ordered, strided arrays and
    /// lists are converted once. Image-shaped (H, W, C) camera rays, or flat ones in row order,
    /// are recognised as a pinhole image (DACRT's camera packets). The GIL is released while
    /// tracing; batches of more than ``chunk_rays`` rays (default 2**20; image rays by whole rows)
    /// are traced in chunks, and Ctrl-C raises ``KeyboardInterrupt`` between chunks.
    ///
    /// Raises ``ValueError`` for a wrong shape, a NaN or infinite origin or direction, a zero
    /// direction or a NaN interval, naming the first bad ray (``rays[i, j]``), and for an unknown
    /// tracer or option.
    #[pyo3(signature = (rays, tracer="dacrt", threads=0, chunk_rays=None, **options))]
    fn cast_rays<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        tracer: &str,
        threads: usize,
        chunk_rays: Option<usize>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let t0 = Instant::now();
        let input = arrays::ray_input(py, rays, "rays")?;
        let opts = options_of(options)?;
        let mut g = self.lock(py);
        let answer = g.query(
            py,
            Request {
                input: &input,
                interval: Interval::default(),
                tracer,
                opts,
                threads,
                chunk_rays: chunk_rays.unwrap_or(DEFAULT_CHUNK_RAYS),
                query: Query::Closest,
            },
        )?;
        let Answer::Closest(a) = answer else {
            unreachable!("a closest-hit query answers with hits")
        };
        let lead = &input.lead;
        let d = PyDict::new(py);
        d.set_item("t_hit", PyArray1::from_vec(py, a.t).reshape(lead.clone())?)?;
        d.set_item(
            "geometry_ids",
            PyArray1::from_vec(py, a.geometry).reshape(lead.clone())?,
        )?;
        d.set_item(
            "primitive_ids",
            PyArray1::from_vec(py, a.prim).reshape(lead.clone())?,
        )?;
        d.set_item(
            "primitive_uvs",
            PyArray1::from_vec(py, a.uv).reshape(shape_with(lead, 2))?,
        )?;
        d.set_item(
            "primitive_normals",
            PyArray1::from_vec(py, a.normal).reshape(shape_with(lead, 3))?,
        )?;
        if let Some(st) = g.last.as_mut() {
            st.total_ms = t0.elapsed().as_secs_f64() * 1e3;
        }
        Ok(d)
    }

    /// Any-hit test of ``rays`` ((..., 6) or (..., 8), as ``cast_rays``): a bool array of their
    /// leading shape, True where some triangle is hit with tmin <= t <= tmax. ``tnear`` and
    /// ``tfar`` (as Open3D's) set the interval of 6-column rays (default [0, inf)) and narrow the
    /// columns of 8-column rays. Tracer, threads, chunks, options, GIL and Ctrl-C as
    /// ``cast_rays``.
    #[pyo3(signature = (rays, tnear=None, tfar=None, tracer="dacrt", threads=0, chunk_rays=None, **options))]
    #[allow(clippy::too_many_arguments)]
    fn test_occlusions<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        tnear: Option<f32>,
        tfar: Option<f32>,
        tracer: &str,
        threads: usize,
        chunk_rays: Option<usize>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let t0 = Instant::now();
        for (name, x) in [("tnear", tnear), ("tfar", tfar)] {
            if x.is_some_and(f32::is_nan) {
                return Err(PyValueError::new_err(format!("{name}: NaN")));
            }
        }
        let input = arrays::ray_input(py, rays, "rays")?;
        let opts = options_of(options)?;
        let mut g = self.lock(py);
        let answer = g.query(
            py,
            Request {
                input: &input,
                interval: Interval { tnear, tfar },
                tracer,
                opts,
                threads,
                chunk_rays: chunk_rays.unwrap_or(DEFAULT_CHUNK_RAYS),
                query: Query::Any,
            },
        )?;
        let Answer::Any(occ) = answer else {
            unreachable!("an any-hit query answers with flags")
        };
        let out = PyArray1::from_vec(py, occ)
            .reshape(input.lead.clone())?
            .into_any();
        if let Some(st) = g.last.as_mut() {
            st.total_ms = t0.elapsed().as_secs_f64() * 1e3;
        }
        Ok(out)
    }

    /// Not provided: no tracer enumerates every hit along a ray exactly (the contract gives the
    /// closest hit and any hit). ``raysift.trimesh.RayMeshIntersector(...).intersects_id(...,
    /// multiple_hits=True)`` lists successive surfaces, as trimesh's Embree backend does.
    #[pyo3(signature = (*_args, **_kwargs))]
    fn count_intersections(
        &self,
        _args: &Bound<'_, pyo3::types::PyTuple>,
        _kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        Err(PyNotImplementedError::new_err(
            "count_intersections: no raysift tracer enumerates every hit along a ray exactly (the tracer contract gives the closest hit and any hit); see raysift.trimesh.RayMeshIntersector.intersects_id(multiple_hits=True) for successive surfaces",
        ))
    }

    /// Not provided, for the reason given under ``count_intersections``.
    #[pyo3(signature = (*_args, **_kwargs))]
    fn list_intersections(
        &self,
        _args: &Bound<'_, pyo3::types::PyTuple>,
        _kwargs: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<()> {
        Err(PyNotImplementedError::new_err(
            "list_intersections: no raysift tracer enumerates every hit along a ray exactly (the tracer contract gives the closest hit and any hit); see raysift.trimesh.RayMeshIntersector.intersects_id(multiple_hits=True) for successive surfaces",
        ))
    }

    /// Pinhole camera rays exactly as ``raysift rays camera`` writes them: float32 (height,
    /// width, 8) ``[ox, oy, oz, dx, dy, dz, tmin=0, tmax=inf]``, unit directions, vertical field
    /// of view ``fov`` in degrees, pixel row j from the top, column i from the left. Without
    /// ``eye``/``look`` the camera frames the scene's bounds from +z (README, "Camera").
    #[pyo3(signature = (width=512, height=512, *, eye=None, look=None, up=None, fov=45.0))]
    #[allow(clippy::too_many_arguments)]
    fn camera_rays<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        eye: Option<&Bound<'py, PyAny>>,
        look: Option<&Bound<'py, PyAny>>,
        up: Option<&Bound<'py, PyAny>>,
        fov: f32,
    ) -> PyResult<Bound<'py, PyAny>> {
        let cam = {
            let g = self.lock(py);
            camera_for(py, &g.scene, width, height, eye, look, up, fov)?
        };
        let flat = py.detach(|| {
            let b = cam.rays(width, height);
            let mut out = vec![0.0f32; 8 * b.len()];
            out.par_chunks_mut(8).enumerate().for_each(|(i, r)| {
                r.copy_from_slice(&[
                    b.ox[i], b.oy[i], b.oz[i], b.dx[i], b.dy[i], b.dz[i], b.tmin[i], b.tmax[i],
                ]);
            });
            out
        });
        Ok(PyArray1::from_vec(py, flat)
            .reshape(vec![height as usize, width as usize, 8])?
            .into_any())
    }

    /// Renders the scene with any tracer: float32 (height, width, 3) RGB in [0, 1], the 8-bit
    /// image the ``raysift render`` command writes, divided by 255 (gamma 2.2 encoded).
    ///
    /// ``integrator``: ``"raycast"`` (one ray per pixel; ``shade`` ``"diffuse"`` with a point
    /// light ``light`` and hard shadows, ``"normal"`` or ``"depth"``) or ``"path"`` (diffuse path
    /// tracing under a sky, ``spp`` samples per pixel, ``bounces`` bounces, ``seed``). Camera as
    /// ``camera_rays``. ``window``: ``(x0, y0, w, h)``, the path integrator renders only those
    /// pixels of the ``width`` × ``height`` image (columns x0 .. x0+w, rows y0 .. y0+h from the
    /// top) and returns (h, w, 3): equal bit for bit to that window of the full render, since a
    /// pixel's random numbers come from its index in the full image (tiles on a cluster:
    /// ``raysift.distributed.render_tiles``). One library call: the GIL is released throughout,
    /// and Ctrl-C is honoured when it returns.
    #[pyo3(signature = (width=512, height=512, *, eye=None, look=None, up=None, fov=45.0,
                        integrator="raycast", shade="diffuse", light=None, spp=4, bounces=7,
                        seed=1, tracer="dacrt", threads=0, window=None, **options))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        eye: Option<&Bound<'py, PyAny>>,
        look: Option<&Bound<'py, PyAny>>,
        up: Option<&Bound<'py, PyAny>>,
        fov: f32,
        integrator: &str,
        shade: &str,
        light: Option<&Bound<'py, PyAny>>,
        spp: u32,
        bounces: u32,
        seed: u64,
        tracer: &str,
        threads: usize,
        window: Option<(u32, u32, u32, u32)>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let win = match window {
            None => None,
            Some(_) if integrator != "path" => {
                return Err(PyValueError::new_err(
                    "window: only the \"path\" integrator renders a window of the image",
                ))
            }
            Some((x0, y0, w, h)) => {
                if w == 0
                    || h == 0
                    || x0 as u64 + w as u64 > width as u64
                    || y0 as u64 + h as u64 > height as u64
                {
                    return Err(PyValueError::new_err(format!(
                        "window: ({x0}, {y0}, {w}, {h}) is not a non-empty window of the {width}x{height} image"
                    )));
                }
                Some(raysift::render::path::Window { x0, y0, w, h })
            }
        };
        let (out_w, out_h) = win.map_or((width, height), |w| (w.w, w.h));
        let shade: raysift::render::Shade = shade.parse().map_err(lib_err)?;
        if !matches!(integrator, "raycast" | "path") {
            return Err(PyValueError::new_err(format!(
                "integrator: {integrator:?}; expected \"raycast\" or \"path\""
            )));
        }
        let light = light.map(|l| arrays::vec3(py, l, "light")).transpose()?;
        let opts = options_of(options)?;
        let pool = run::pool(threads)?;
        let mut g = self.lock(py);
        let cam = camera_for(py, &g.scene, width, height, eye, look, up, fov)?;
        let i = g.tracer(tracer, opts)?;
        g.ready(py, i, &pool)?;
        let (scene, tr) = (&g.scene, g.tracers[i].tracer.as_ref());
        let img = py
            .detach(|| {
                run::install(&pool, || {
                    if integrator == "path" {
                        let cfg = raysift::render::path::PathConfig {
                            spp: spp.max(1),
                            bounces,
                            seed,
                            ..Default::default()
                        };
                        let full = raysift::render::path::Window::full(width, height);
                        raysift::render::path::path_trace_window(
                            scene,
                            tr,
                            &cam,
                            width,
                            height,
                            &cfg,
                            win.unwrap_or(full),
                        )
                        .map(|(img, _)| img)
                    } else {
                        raysift::render::raycast(scene, tr, &cam, width, height, shade, light)
                            .map(|(img, _)| img)
                    }
                })
            })
            .map_err(lib_err)?;
        drop(g);
        py.check_signals()?;
        let rgb: Vec<f32> = img.rgb.iter().map(|&c| c as f32 / 255.0).collect();
        Ok(PyArray1::from_vec(py, rgb)
            .reshape(vec![out_h as usize, out_w as usize, 3])?
            .into_any())
    }

    /// World-space triangles, float32 (T, 3, 3): corners in primitive-id order (what ``raysift
    /// export`` writes as (T, 9); degenerate triangles collapsed to their first corner).
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let g = self.lock(py);
        let soup = g.scene.triangles();
        let mut out = Vec::with_capacity(9 * soup.len());
        for i in 0..soup.len() {
            for c in soup.get(i) {
                out.extend_from_slice(&c.to_array());
            }
        }
        Ok(PyArray1::from_vec(py, out)
            .reshape(vec![soup.len(), 3, 3])?
            .into_any())
    }

    /// uint32 (meshes + 1,): the scene-wide id of each mesh's first triangle, then the triangle
    /// count (scene-wide id = ``primitive_offsets[geometry_id] + primitive_id``).
    #[getter]
    fn primitive_offsets<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        let g = self.lock(py);
        let s = &g.scene;
        let mut v: Vec<u32> = (0..s.meshes().len())
            .map(|m| s.mesh_prims(m).start as u32)
            .collect();
        v.push(s.len() as u32);
        PyArray1::from_vec(py, v)
    }

    /// World bounds, float32 (2, 3): ``[min, max]`` (inf, -inf when empty).
    #[getter]
    fn bounds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let b = self.lock(py).scene.bounds();
        let v = [b.min.to_array(), b.max.to_array()].concat();
        Ok(PyArray1::from_vec(py, v).reshape(vec![2, 3])?.into_any())
    }

    /// Number of triangles.
    #[getter]
    fn triangle_count(&self, py: Python<'_>) -> usize {
        self.lock(py).scene.len()
    }

    /// Number of meshes (geometry ids are 0 .. mesh_count - 1).
    #[getter]
    fn mesh_count(&self, py: Python<'_>) -> usize {
        self.lock(py).scene.meshes().len()
    }

    /// Mesh names, by geometry id.
    #[getter]
    fn mesh_names(&self, py: Python<'_>) -> Vec<String> {
        self.lock(py)
            .scene
            .meshes()
            .iter()
            .map(|m| m.name.clone())
            .collect()
    }

    /// The scene's name (file name, generator spec, or "python").
    #[getter]
    fn name(&self, py: Python<'_>) -> String {
        self.lock(py).scene.name.clone()
    }

    /// The version: bumped by every ``set_transform`` and ``set_vertices``.
    #[getter]
    fn version(&self, py: Python<'_>) -> u64 {
        self.lock(py).scene.version()
    }

    /// What the last ``cast_rays`` or ``test_occlusions`` did, or None: ``query``, ``tracer``,
    /// ``options``, ``threads``, ``chunks``, ``rays``, ``prepare`` (the tracer's prepare stats
    /// when this call prepared it, else None), ``layout`` (the ray groups recognised, e.g.
    /// ``Pinhole { .. }``: DACRT's camera packets), ``trace_ms`` (the library's intersect calls alone,
    /// as ``raysift trace`` times them), ``convert_ms`` (input transposition, validation and
    /// layout recognition), ``output_ms`` (the output arrays), ``total_ms`` (the whole call), and
    /// the tracer's ``work`` counters.
    #[getter]
    fn last_stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let g = self.lock(py);
        let Some(s) = g.last.clone() else {
            return Ok(None);
        };
        drop(g);
        let d = PyDict::new(py);
        d.set_item("query", s.query)?;
        d.set_item("tracer", &s.tracer)?;
        let o = PyDict::new(py);
        for (k, v) in &s.opts {
            o.set_item(k, v)?;
        }
        d.set_item("options", o)?;
        d.set_item("threads", s.threads)?;
        d.set_item("chunks", s.chunks)?;
        d.set_item("layout", &s.layout)?;
        d.set_item("rays", s.trace.rays)?;
        d.set_item(
            "prepare",
            s.prepared.as_ref().map(|p| stats_dict(py, p)).transpose()?,
        )?;
        d.set_item("trace_ms", s.trace.trace_ms)?;
        d.set_item("convert_ms", s.convert_ms)?;
        d.set_item("output_ms", s.output_ms)?;
        d.set_item("total_ms", s.total_ms)?;
        d.set_item("work", stats_dict(py, &s.trace)?.get_item("work")?)?;
        Ok(Some(d))
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.lock(py).scene.len()
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let g = self.lock(py);
        format!(
            "raysift.Scene({:?}: {} triangles in {} meshes, version {})",
            g.scene.name,
            g.scene.len(),
            g.scene.meshes().len(),
            g.scene.version()
        )
    }
}
