//! What several commands share: the view (camera) and tracer arguments, and opening scenes,
//! cameras and tracers from them.

use crate::progress::spinner;
use anyhow::{bail, Result};
use clap::Args;
use glam::Vec3;
use raysift::rays::Camera;
use raysift::scene::{self, procedural, Scene};
use raysift::tracers;
use raysift::Tracer;

/// The scene argument's help: a file or a generator.
pub const SCENE_HELP: &str = "Scene file (.obj .ply .gltf .glb .off, optionally .gz) or generator (sphere:N, soup:N[:SEED], cornell, tile:K:FILE)";

/// Image size and camera.
#[derive(Args, Clone)]
pub struct ViewArgs {
    /// Image width in pixels.
    #[arg(long, default_value_t = 512)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 512)]
    pub height: u32,
    /// Eye position x,y,z (default: framing the scene bounds from +z).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// Point looked at x,y,z (default: centre of the bounds).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub look: Option<Vec3>,
    /// Up vector x,y,z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, default_value = "0,1,0")]
    pub up: Vec3,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = Camera::DEFAULT_FOV)]
    pub fov: f32,
}

/// Which tracer, with which options, on how many threads; and the report's form.
#[derive(Args, Clone)]
pub struct TracerArgs {
    /// Tracer name (see `raysift tracers`).
    #[arg(long, default_value = "bvh")]
    pub tracer: String,
    /// Tracer option key=value (repeatable; `raysift tracers --verbose` lists them).
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    pub opts: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Pin worker thread k to core k (mod the cores this process may use), for steady benchmarks.
    #[arg(long)]
    pub pin: bool,
    /// Print one JSON object with scene, tracer, counts, times and counters.
    #[arg(long)]
    pub json: bool,
}

/// Parses `x,y,z`.
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected x,y,z numbers, got {s:?}"))?;
    match v[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got {s:?}")),
    }
}

/// Loads a scene file or generator; a scene without triangles is an error.
pub fn open_scene(spec: &str) -> Result<Scene> {
    let pb = spinner(format!("loading {spec}"));
    let s = procedural::open(spec);
    pb.finish_and_clear();
    let s = s?;
    if s.is_empty() {
        bail!("{spec}: the scene has no triangles");
    }
    Ok(s)
}

/// [`open_scene`], or the embedded bunny when no scene is given.
pub fn open_scene_or_default(spec: Option<&str>) -> Result<Scene> {
    match spec {
        Some(s) => open_scene(s),
        None => Ok(scene::default_scene()?),
    }
}

/// The camera of the view: framing `bounds` unless `--eye`/`--look` say otherwise.
pub fn camera_for(bounds: &raysift::geom::Aabb, v: &ViewArgs) -> Result<Camera> {
    if v.width == 0 || v.height == 0 {
        bail!("--width and --height must be positive");
    }
    let mut cam = Camera::framing(bounds, v.fov, v.width as f32 / v.height as f32);
    if let Some(eye) = v.eye {
        cam.eye = eye;
    }
    if let Some(look) = v.look {
        cam.look = look;
    }
    cam.up = v.up;
    cam.validate()?;
    Ok(cam)
}

/// The tracer `--tracer` with its `--opt`s.
pub fn make_tracer(args: &TracerArgs) -> Result<Box<dyn Tracer>> {
    let opts = tracers::parse_opts(&args.opts)?;
    Ok(tracers::create(&args.tracer, &opts)?)
}
