//! `raysift rays`: camera, random, shadow and bounce rays, written as rays.npy.

use crate::args::{camera_for, open_scene, open_scene_or_default, parse_vec3, ViewArgs};
use anyhow::{bail, Result};
use clap::Subcommand;
use glam::Vec3;
use raysift::rays::{generate, npy, RayBatch};
use raysift::{HitBatch, Scene};
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum RaysCmd {
    /// Pinhole camera rays, ordered j·W+i (see README, "Camera").
    Camera {
        /// Scene (for the default framing); the embedded bunny when omitted.
        scene: Option<String>,
        #[command(flatten)]
        view: ViewArgs,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
    },
    /// Uniformly random rays: origins in the scene bounds, directions on the sphere.
    Random {
        /// Scene (for its bounds).
        scene: String,
        /// Number of rays.
        #[arg(long)]
        count: usize,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
    },
    /// Shadow rays from the hits of a batch to a point light (t = 1 at the light).
    Shadow {
        /// Scene the hits refer to.
        scene: String,
        /// The rays that produced the hits.
        #[arg(long)]
        rays: PathBuf,
        /// Their hits.npy.
        #[arg(long)]
        hits: PathBuf,
        /// Light position x,y,z.
        #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
        light: Vec3,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
        /// Also write, for each output ray, the index of its source ray (uint32 .npy).
        #[arg(long)]
        map: Option<PathBuf>,
    },
    /// Cosine-weighted diffuse bounce rays from the hits of a batch.
    Bounce {
        /// Scene the hits refer to.
        scene: String,
        /// The rays that produced the hits.
        #[arg(long)]
        rays: PathBuf,
        /// Their hits.npy.
        #[arg(long)]
        hits: PathBuf,
        /// Random seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output rays.npy.
        #[arg(long)]
        out: PathBuf,
        /// Also write, for each output ray, the index of its source ray (uint32 .npy).
        #[arg(long)]
        map: Option<PathBuf>,
    },
}

pub fn run(cmd: RaysCmd) -> Result<()> {
    match cmd {
        RaysCmd::Camera { scene, view, out } => {
            let s = open_scene_or_default(scene.as_deref())?;
            let cam = camera_for(&s.bounds(), &view)?;
            npy::write_rays(&out, &cam.rays(view.width, view.height))?;
        }
        RaysCmd::Random {
            scene,
            count,
            seed,
            out,
        } => {
            if count == 0 {
                bail!("--count must be at least 1");
            }
            let s = open_scene(&scene)?;
            npy::write_rays(&out, &generate::random_in_box(&s.bounds(), count, seed))?;
        }
        RaysCmd::Shadow {
            scene,
            rays,
            hits,
            light,
            out,
            map,
        } => {
            let s = open_scene(&scene)?;
            let (r, h) = secondary_inputs(&s, &rays, &hits)?;
            let (sr, from) = generate::shadow_rays(&s, &r, &h, light);
            write_with_map(&out, &sr, map.as_deref(), &from)?;
        }
        RaysCmd::Bounce {
            scene,
            rays,
            hits,
            seed,
            out,
            map,
        } => {
            let s = open_scene(&scene)?;
            let (r, h) = secondary_inputs(&s, &rays, &hits)?;
            let (br, from) = generate::bounce_rays(&s, &r, &h, seed);
            write_with_map(&out, &br, map.as_deref(), &from)?;
        }
    }
    Ok(())
}

/// The rays and hits a secondary batch starts from, checked against each other and the scene.
fn secondary_inputs(scene: &Scene, rays: &Path, hits: &Path) -> Result<(RayBatch, HitBatch)> {
    let r = npy::read_rays(rays)?;
    let h = npy::read_hits(hits)?;
    if r.len() != h.len() {
        bail!(
            "{}: {} hits for {} rays in {}",
            hits.display(),
            h.len(),
            r.len(),
            rays.display()
        );
    }
    if let Some(i) = (0..h.len()).find(|&i| h.is_hit(i) && h.prim[i] as usize >= scene.len()) {
        bail!(
            "{}: record {i}: primitive {} is out of range for {} ({} triangles)",
            hits.display(),
            h.prim[i],
            scene.name,
            scene.len()
        );
    }
    Ok((r, h))
}

/// Writes the rays, and the map from each to its source ray when asked; when the map cannot be
/// written, the rays file is removed again, so a failed command leaves no output.
fn write_with_map(out: &Path, rays: &RayBatch, map: Option<&Path>, from: &[u32]) -> Result<()> {
    npy::write_rays(out, rays)?;
    let Some(p) = map else { return Ok(()) };
    let written = raysift::output::write_atomic(p, |w| {
        use npyz::WriterBuilder;
        let mut o = npyz::WriteOptions::<u32>::new()
            .default_dtype()
            .shape(&[from.len() as u64])
            .writer(w)
            .begin_nd()?;
        o.extend(from.iter().copied())?;
        o.finish()
    });
    if written.is_err() {
        let _ = std::fs::remove_file(out);
    }
    Ok(written?)
}
