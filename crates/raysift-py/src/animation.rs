//! `raysift.Animation`: a scene file's motion (a glTF file's own animation, or a generated
//! motion), posed at any time into a `raysift.Scene`, so that any frame can be made on its own
//! (the frames of `raysift animate`, one per task on a cluster: `raysift.distributed`).

use crate::scene::PyScene;
use crate::state::lib_err;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::MutexExt;
use pyo3::types::PyDict;
use raysift::rays::Camera;
use raysift::scene::animate::{Animation, Motion};
use raysift::scene::io::gltf_anim::load_animated;
use raysift::scene::io::Format;
use raysift::scene::Scene;
use std::path::Path;
use std::sync::Mutex;

/// A scene file's motion, played into a ``raysift.Scene`` (``.scene``) at any time.
///
/// ``Animation.load(path)`` opens it as ``raysift animate`` does: a ``.gltf``/``.glb`` file with
/// animations plays its own (``motion="gltf"``: keyframed nodes, skinning), anything else (or
/// ``motion="explode"``/``"spin-parts"``) a generated motion. A pose is a function of the time
/// alone, so frames can be made in any order, on any machine, and equal ``raysift animate``'s.
#[pyclass(name = "Animation", module = "raysift", frozen)]
pub struct PyAnimation {
    anim: Mutex<Animation>,
    scene: Py<PyScene>,
}

fn is_gltf(spec: &str) -> bool {
    matches!(
        raysift::scene::io::detect_format(Path::new(spec)),
        Ok((Format::Gltf | Format::Glb, _))
    )
}

/// The animation `raysift animate SPEC [--motion M] [--animation A]` plays.
fn open(spec: &str, motion: Option<Motion>, which: Option<&str>) -> raysift::Result<Animation> {
    let invalid = |m: String| raysift::Error::Invalid(m);
    if is_gltf(spec) {
        if motion.is_none_or(|m| m == Motion::Gltf) {
            let (scene, playback) = load_animated(spec)?;
            match playback {
                Some(p) => {
                    let mut anim = Animation::from_playback(scene, p);
                    if let Some(w) = which {
                        anim.select(w)?;
                    }
                    return Ok(anim);
                }
                None if motion == Some(Motion::Gltf) || which.is_some() => {
                    return Err(invalid(format!("{spec}: the file has no animations")))
                }
                None => return Animation::new(&scene, Motion::Explode),
            }
        }
    } else if motion == Some(Motion::Gltf) {
        return Err(invalid(format!(
            "motion \"gltf\" plays a .gltf or .glb file's animation; {spec} is not one"
        )));
    }
    if which.is_some() {
        return Err(invalid(
            "animation: chooses a glTF file's animation; it needs the gltf motion".into(),
        ));
    }
    let base = raysift::scene::procedural::open(spec)?;
    if base.is_empty() {
        return Err(invalid(format!("{spec}: the scene has no triangles")));
    }
    Animation::new(&base, motion.unwrap_or(Motion::Explode))
}

/// Makes `dst` equal to `src`: through `set_transform` and `replace_positions` when only
/// transforms and positions differ (so the tracers take their update path), a copy otherwise.
fn sync(dst: &mut Scene, src: &Scene) -> raysift::Result<()> {
    let (a, b) = (dst.meshes(), src.meshes());
    let same_shape = a.len() == b.len()
        && a.iter().zip(b).all(|(x, y)| {
            x.positions.len() == y.positions.len() && x.indices.len() == y.indices.len()
        });
    if !same_shape || dst.name != src.name {
        *dst = src.clone();
        return Ok(());
    }
    for (m, y) in b.iter().enumerate() {
        if dst.meshes()[m].transform != y.transform {
            dst.set_transform(m, y.transform)?;
        }
        if dst.meshes()[m].positions != y.positions {
            dst.replace_positions(m, y.positions.clone())?;
        }
    }
    Ok(())
}

impl PyAnimation {
    fn lock<'a>(&'a self, py: Python<'_>) -> std::sync::MutexGuard<'a, Animation> {
        match self.anim.lock_py_attached(py) {
            Ok(g) => g,
            Err(p) => p.into_inner(),
        }
    }
}

#[pymethods]
impl PyAnimation {
    /// Opens ``path`` (a scene file or generator spec, as ``Scene.load``) with ``motion``
    /// (``"gltf"``, ``"explode"``, ``"spin-parts"``; default: the file's own animation for a
    /// glTF file that has one, ``"explode"`` otherwise) and, for glTF, ``animation`` (name or
    /// index; default the first). ``.scene`` starts in the rest pose of the motion.
    ///
    /// Raises ``FileNotFoundError`` for a missing file and ``ValueError`` for an unknown motion,
    /// animation or malformed file.
    #[staticmethod]
    #[pyo3(signature = (path, motion=None, animation=None))]
    fn load(
        py: Python<'_>,
        path: std::path::PathBuf,
        motion: Option<&str>,
        animation: Option<&str>,
    ) -> PyResult<Self> {
        let spec = path.to_string_lossy().to_string();
        let motion = motion
            .map(|m| m.parse::<Motion>())
            .transpose()
            .map_err(|e| PyValueError::new_err(format!("motion: {e}")))?;
        let anim = py
            .detach(|| open(&spec, motion, animation))
            .map_err(lib_err)?;
        let scene = Py::new(py, PyScene::from_library(anim.scene().clone()))?;
        Ok(Self {
            anim: Mutex::new(anim),
            scene,
        })
    }

    /// The posed scene (the same object every time): trace or render it after ``set_time``.
    #[getter]
    fn scene(&self, py: Python<'_>) -> Py<PyScene> {
        self.scene.clone_ref(py)
    }

    /// ``"gltf"``, ``"explode"`` or ``"spin-parts"``.
    #[getter]
    fn motion(&self, py: Python<'_>) -> &'static str {
        self.lock(py).motion().name()
    }

    /// The glTF animation played (its name), or None for a generated motion.
    #[getter]
    fn clip(&self, py: Python<'_>) -> Option<String> {
        self.lock(py).playback().map(|p| p.clip().name.clone())
    }

    /// The glTF animation's duration in seconds, or None for a generated motion.
    #[getter]
    fn duration(&self, py: Python<'_>) -> Option<f32> {
        self.lock(py).playback().map(|p| p.clip().duration)
    }

    /// The time of frame ``k`` of ``frames``, as ``raysift animate`` takes it: ``k / (frames -
    /// 1)`` for a generated motion, ``k · duration / frames`` seconds for a glTF animation.
    fn frame_time(&self, py: Python<'_>, k: u32, frames: u32) -> f32 {
        self.lock(py).frame_time(k, frames)
    }

    /// Poses ``.scene`` at time ``t`` (see ``frame_time``): moved meshes through
    /// ``set_transform``, deformed ones through ``set_vertices``, so its tracers update.
    fn set_time(&self, py: Python<'_>, t: f32) -> PyResult<()> {
        if !t.is_finite() {
            return Err(PyValueError::new_err(format!(
                "t: {t}; expected a finite time"
            )));
        }
        let mut guard = self.lock(py);
        let a: &mut Animation = &mut guard;
        let scene = self.scene.get();
        let mut g = scene.lock_inner(py);
        let dst = &mut g.scene;
        py.detach(|| a.at(t).and_then(|src| sync(dst, src)))
            .map_err(lib_err)
    }

    /// The camera ``raysift animate --frames FRAMES --width W --height H --fov FOV`` uses: the
    /// default framing of the union of the bounds of 9 frames across the motion. A dict
    /// ``eye``, ``look``, ``up`` (lists of 3 floats) and ``fov``: pass them to ``Scene.render``.
    /// Leaves ``.scene`` as it was.
    #[pyo3(signature = (frames, width=512, height=512, fov=45.0))]
    fn camera<'py>(
        &self,
        py: Python<'py>,
        frames: u32,
        width: u32,
        height: u32,
        fov: f32,
    ) -> PyResult<Bound<'py, PyDict>> {
        if frames == 0 {
            return Err(PyValueError::new_err("frames must be at least 1"));
        }
        if width == 0 || height == 0 {
            return Err(PyValueError::new_err("width and height must be at least 1"));
        }
        let mut guard = self.lock(py);
        let a: &mut Animation = &mut guard;
        let bounds = py
            .detach(|| -> raysift::Result<_> {
                let t0 = a.frame_time(0, frames);
                let mut b = a.at(t0)?.bounds();
                for k in 1..=8 {
                    let t = a.frame_time(k * frames.saturating_sub(1) / 8, frames);
                    b = b.union(a.at(t)?.bounds());
                }
                Ok(b)
            })
            .map_err(lib_err)?;
        let cam = Camera::framing(&bounds, fov, width as f32 / height as f32);
        cam.validate().map_err(lib_err)?;
        let d = PyDict::new(py);
        d.set_item("eye", cam.eye.to_array().to_vec())?;
        d.set_item("look", cam.look.to_array().to_vec())?;
        d.set_item("up", cam.up.to_array().to_vec())?;
        d.set_item("fov", cam.fov_deg)?;
        Ok(d)
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let a = self.lock(py);
        let s = a.scene();
        format!(
            "raysift.Animation({:?}: {} {}, {} triangles in {} meshes)",
            s.name,
            a.motion().name(),
            a.playback().map_or(String::new(), |p| format!(
                "{:?} ({} s)",
                p.clip().name,
                p.clip().duration
            )),
            s.len(),
            s.meshes().len()
        )
    }
}
