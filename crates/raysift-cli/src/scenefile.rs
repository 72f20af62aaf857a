//! Scene description files (`raysift render scene.toml` or `scene.json`): meshes with transforms
//! and material overrides, the camera, area lights and the integrator's settings, so a render is
//! reproducible from one file. Flags typed on the command line override the file. Mesh paths
//! are relative to the file. Unknown keys are refused (serde's `deny_unknown_fields`), and every
//! error is one line naming the file and the field.
//!
//! ```toml
//! [camera]                      # all optional; the default frames the scene from +z
//! eye = [0.0, 1.0, 3.4]
//! look = [0.0, 1.0, 0.0]
//! up = [0.0, 1.0, 0.0]
//! fov = 40.0                    # vertical, degrees
//! width = 256
//! height = 256
//!
//! [render]                      # all optional; the CLI's flags of the same name
//! integrator = "path"           # raycast, path, distribution, instant-radiosity
//! spp = 16
//! bounces = 5
//! seed = 1
//! tracer = "bvh"
//! out = "cornell.png"           # relative to the scene file
//!
//! [[meshes]]
//! generator = "cornell"         # or: path = "model.obj" (relative to this file)
//!
//! [[meshes]]
//! path = "../bunny.ply.gz"
//! translate = [0.3, 0.0, 0.2]
//! rotate = [0.0, 30.0, 0.0]     # degrees about x, then y, then z
//! scale = 3.0                   # or [sx, sy, sz]
//! material = { diffuse = [0.8, 0.8, 0.8], emission = [0.0, 0.0, 0.0], mirror = false }
//!
//! [[lights]]                    # square area lights facing down, as --area-light
//! centre = [0.0, 1.9, 0.0]
//! size = 0.5
//! power = 20.0
//! ```

use crate::render::{Integrator, RenderArgs};
use anyhow::{anyhow, bail, Context, Result};
use glam::{Affine3A, EulerRot, Quat, Vec3};
use raysift::scene::{procedural, Material, Scene};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// The meshes, at least one.
    #[serde(default)]
    pub meshes: Vec<MeshEntry>,
    /// The camera.
    #[serde(default)]
    pub camera: CameraEntry,
    /// Square area lights, added to the meshes' emissive materials.
    #[serde(default)]
    pub lights: Vec<LightEntry>,
    /// Integrator and settings.
    #[serde(default)]
    pub render: RenderEntry,
}

/// One mesh file or generator, placed and optionally re-materialed.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshEntry {
    /// A scene file (.obj .ply .gltf .glb .off, optionally .gz), relative to the scene file.
    pub path: Option<PathBuf>,
    /// A generator (`cornell`, `sphere:N`, `soup:N[:SEED]`).
    pub generator: Option<String>,
    /// Translation, applied last.
    pub translate: Option<[f32; 3]>,
    /// Rotation in degrees about x, then y, then z.
    pub rotate: Option<[f32; 3]>,
    /// Uniform or per-axis scale, applied first.
    pub scale: Option<Scale>,
    /// A material for all the mesh's triangles, replacing the file's.
    pub material: Option<Material>,
}

/// A scale: one number or three.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
pub enum Scale {
    /// Uniform.
    Uniform(f32),
    /// Per axis.
    Axes([f32; 3]),
}

/// The camera; what is missing comes from the CLI's defaults (framing the scene).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub eye: Option<[f32; 3]>,
    pub look: Option<[f32; 3]>,
    pub up: Option<[f32; 3]>,
    pub fov: Option<f32>,
    pub width: Option<u32>,
    pub height: Option<u32>,
}

/// A square area light (`--area-light x,y,z,size,power`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightEntry {
    pub centre: [f32; 3],
    pub size: f32,
    pub power: f32,
}

/// The render settings: the CLI's flags of the same names.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderEntry {
    pub integrator: Option<String>,
    pub tracer: Option<String>,
    pub shade: Option<String>,
    pub spp: Option<u32>,
    pub bounces: Option<u32>,
    pub seed: Option<u64>,
    pub aa: Option<u32>,
    pub light_samples: Option<u32>,
    pub bounce_samples: Option<u32>,
    pub vpls: Option<u32>,
    pub vpl_bounces: Option<u32>,
    pub vpl_subset: Option<u32>,
    pub out: Option<PathBuf>,
}

/// Whether `spec` names a scene description file (.toml or .json).
pub fn is_scene_file(spec: &str) -> bool {
    let ext = Path::new(spec).extension().and_then(|e| e.to_str());
    ext.is_some_and(|e| e.eq_ignore_ascii_case("toml") || e.eq_ignore_ascii_case("json"))
}

/// Reads and parses a scene file; syntax errors and unknown keys give one line with the file,
/// the line and what is wrong.
pub fn read(path: &Path) -> Result<SceneFile> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if json {
        return serde_json::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()));
    }
    toml::from_str(&text).map_err(|e| {
        let line = e
            .span()
            .map(|s| text[..s.start.min(text.len())].lines().count().max(1));
        let msg = e.message().replace('\n', " ");
        match line {
            Some(l) => anyhow!("{}: line {l}: {}", path.display(), msg.trim()),
            None => anyhow!("{}: {}", path.display(), msg.trim()),
        }
    })
}

fn v3(a: [f32; 3]) -> Vec3 {
    Vec3::from_array(a)
}

/// Folds the file's settings into `a` where the command line did not give them (`given`: the
/// ids of the arguments typed), and checks the lights; returns the arguments to render with.
pub fn apply(file: &Path, f: &SceneFile, a: &RenderArgs, given: &[String]) -> Result<RenderArgs> {
    let at = |field: &str| format!("{}: {field}", file.display());
    let typed = |id: &str| given.iter().any(|g| g == id);
    let mut a = a.clone();
    let c = &f.camera;
    macro_rules! take {
        ($id:literal, $dst:expr, $src:expr) => {
            if !typed($id) {
                if let Some(v) = $src {
                    $dst = v;
                }
            }
        };
    }
    take!("width", a.view.width, c.width);
    take!("height", a.view.height, c.height);
    take!("fov", a.view.fov, c.fov);
    take!("up", a.view.up, c.up.map(v3));
    take!("eye", a.view.eye, c.eye.map(|e| Some(v3(e))));
    take!("look", a.view.look, c.look.map(|e| Some(v3(e))));
    for (name, v) in [
        ("camera.eye", c.eye),
        ("camera.look", c.look),
        ("camera.up", c.up),
    ] {
        if v.is_some_and(|v| !v3(v).is_finite()) {
            bail!("{}: must be three finite numbers", at(name));
        }
    }
    let r = &f.render;
    if !typed("integrator") {
        if let Some(i) = &r.integrator {
            a.integrator = <Integrator as clap::ValueEnum>::from_str(i, false).map_err(|_| {
                anyhow!(
                    "{}: unknown integrator {i:?}; expected raycast, path, distribution or instant-radiosity",
                    at("render.integrator")
                )
            })?;
        }
    }
    if !typed("shade") {
        if let Some(s) = &r.shade {
            a.shade = Some(
                s.parse()
                    .map_err(|e| anyhow!("{}: {e}", at("render.shade")))?,
            );
        }
    }
    take!("tracer", a.tracer.tracer, r.tracer.clone());
    take!("spp", a.spp, r.spp.map(Some));
    take!("bounces", a.bounces, r.bounces.map(Some));
    take!("seed", a.seed, r.seed.map(Some));
    take!("aa", a.aa, r.aa.map(Some));
    take!("light_samples", a.light_samples, r.light_samples.map(Some));
    take!(
        "bounce_samples",
        a.bounce_samples,
        r.bounce_samples.map(Some)
    );
    take!("vpls", a.vpls, r.vpls.map(Some));
    take!("vpl_bounces", a.vpl_bounces, r.vpl_bounces.map(Some));
    take!("vpl_subset", a.vpl_subset, r.vpl_subset.map(Some));
    let base = file.parent().unwrap_or(Path::new(""));
    take!("out", a.out, r.out.as_ref().map(|o| base.join(o)));
    for (field, v, lo, hi) in [
        ("render.spp", r.spp, 1, u32::MAX),
        ("render.aa", r.aa, 1, 16),
        ("render.light_samples", r.light_samples, 1, 64),
        ("render.bounce_samples", r.bounce_samples, 0, 64),
        ("render.vpls", r.vpls, 1, 10_000_000),
        ("render.vpl_bounces", r.vpl_bounces, 1, 64),
        ("render.vpl_subset", r.vpl_subset, 1, u32::MAX),
    ] {
        if let Some(v) = v.filter(|v| !(lo..=hi).contains(v)) {
            bail!("{}: {v} is outside {lo}..={hi}", at(field));
        }
    }
    for (k, l) in f.lights.iter().enumerate() {
        let what = at(&format!("lights[{k}]"));
        if !v3(l.centre).is_finite() {
            bail!("{what}.centre: must be three finite numbers");
        }
        raysift::render::light::AreaLight::square(v3(l.centre), l.size, l.power, &what)?;
        let [x, y, z] = l.centre;
        a.area_light
            .push(format!("{x},{y},{z},{},{}", l.size, l.power));
    }
    if f.meshes.is_empty() {
        bail!(
            "{}: the scene has no meshes (add a [[meshes]] entry)",
            at("meshes")
        );
    }
    for (k, m) in f.meshes.iter().enumerate() {
        match (&m.path, &m.generator) {
            (Some(p), None) => {
                let p = base.join(p);
                if !p.is_file() {
                    bail!(
                        "{}: {} does not exist",
                        at(&format!("meshes[{k}].path")),
                        p.display()
                    );
                }
            }
            (None, Some(_)) => {}
            _ => bail!(
                "{}: give exactly one of path and generator",
                at(&format!("meshes[{k}]"))
            ),
        }
        if let Some(mat) = &m.material {
            mat.validate()
                .map_err(|e| anyhow!("{}: {e}", at(&format!("meshes[{k}].material"))))?;
        }
    }
    Ok(a)
}

/// Loads the file's meshes, placed and re-materialed, as one scene; a light or mirror material
/// on a mesh of no area is refused.
pub fn load(file: &Path, f: &SceneFile) -> Result<Scene> {
    let at = |field: String| format!("{}: {field}", file.display());
    let base = file.parent().unwrap_or(Path::new(""));
    let mut meshes = Vec::new();
    for (k, m) in f.meshes.iter().enumerate() {
        let (spec, field) = match (&m.path, &m.generator) {
            (Some(p), _) => (base.join(p).display().to_string(), "path"),
            (None, Some(g)) => (g.clone(), "generator"),
            (None, None) => bail!("{}: give path or generator", at(format!("meshes[{k}]"))),
        };
        let s = procedural::open(&spec)
            .map_err(|e| anyhow!("{}: {e}", at(format!("meshes[{k}].{field}"))))?;
        if s.is_empty() {
            bail!(
                "{}: {spec} has no triangles",
                at(format!("meshes[{k}].{field}"))
            );
        }
        let scale = match m.scale {
            None => Vec3::ONE,
            Some(Scale::Uniform(s)) => Vec3::splat(s),
            Some(Scale::Axes(a)) => v3(a),
        };
        if !scale.is_finite() || scale.min_element().abs() == 0.0 {
            bail!(
                "{}: must be finite and non-zero",
                at(format!("meshes[{k}].scale"))
            );
        }
        let [rx, ry, rz] = m.rotate.unwrap_or_default().map(f32::to_radians);
        let t = v3(m.translate.unwrap_or_default());
        if !t.is_finite() || !Vec3::new(rx, ry, rz).is_finite() {
            bail!(
                "{}: translate and rotate must be finite",
                at(format!("meshes[{k}]"))
            );
        }
        let place = Affine3A::from_scale_rotation_translation(
            scale,
            Quat::from_euler(EulerRot::ZYX, rz, ry, rx),
            t,
        );
        for mut mesh in s.meshes().iter().cloned() {
            mesh.transform = place * mesh.transform;
            if let Some(mat) = m.material {
                mesh.materials = vec![(0, mat)];
            }
            meshes.push(mesh);
        }
        if let Some(mat) = m.material {
            let area: f32 = s
                .meshes()
                .iter()
                .map(|mesh| {
                    let tf = place * mesh.transform;
                    mesh.indices
                        .iter()
                        .map(|t| {
                            let [a, b, c] =
                                t.map(|i| tf.transform_point3(mesh.positions[i as usize]));
                            0.5 * (b - a).cross(c - a).length()
                        })
                        .sum::<f32>()
                })
                .sum();
            if area.is_nan() || area <= 0.0 {
                if mat.is_emissive() {
                    bail!(
                        "{}: the mesh has zero area, so it cannot be a light",
                        at(format!("meshes[{k}].material.emission"))
                    );
                }
                if mat.mirror {
                    bail!(
                        "{}: the mesh has no surface of non-zero area to reflect",
                        at(format!("meshes[{k}].material.mirror"))
                    );
                }
            }
        }
    }
    let name = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    Ok(Scene::from_meshes(name, meshes)?)
}
