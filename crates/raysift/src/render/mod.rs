//! Renderers built only on the [`Tracer`] contract, so every technique renders the same image.
//!
//! [`raycast`]: primary rays with normal, depth or diffuse shading; diffuse shading adds a point
//! light with hard shadows traced as one any-hit batch (the "Conic + 1 light" workload of Mora 2011,
//! Fig. 8). When no point light is given and the scene has area lights (emissive materials),
//! diffuse shading is instead the scene's direct light: [`distribution`] with 4×4 shadow samples
//! per light and hit, surfaces in their material colours (direct light only; the path tracer
//! adds the indirect). [`path`] (path tracing with next-event estimation), [`distribution`]
//! (distribution ray tracing) and [`light`] (area lights) live beside it.

pub mod distribution;
pub mod heatmap;
pub mod light;
pub mod path;
pub mod progress;
pub mod radiosity;

use crate::error::{Error, Result};
use crate::rays::{generate, Camera, HitBatch, RayBatch};
use crate::scene::Scene;
use crate::tracer::{Stats, Tracer};
use glam::Vec3;
use rayon::prelude::*;
use std::path::Path;

/// How hits are turned into colours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Shade {
    /// Geometric normal (facing the viewer) mapped to RGB.
    Normal,
    /// Distance: near is bright.
    Depth,
    /// Lambert with a point light and hard shadows.
    #[default]
    Diffuse,
}

impl std::str::FromStr for Shade {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "normal" => Ok(Shade::Normal),
            "depth" => Ok(Shade::Depth),
            "diffuse" => Ok(Shade::Diffuse),
            _ => Err(Error::Invalid(format!(
                "unknown shading {s:?}; expected normal, depth or diffuse"
            ))),
        }
    }
}

/// An RGB8 image, rows top to bottom.
#[derive(Clone, Debug)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 · width · height` bytes.
    pub rgb: Vec<u8>,
}

impl Image {
    /// Writes a PNG atomically.
    pub fn save_png(&self, path: &Path) -> Result<()> {
        use image::ImageEncoder;
        crate::output::write_atomic(path, |w| {
            image::codecs::png::PngEncoder::new(w)
                .write_image(
                    &self.rgb,
                    self.width,
                    self.height,
                    image::ExtendedColorType::Rgb8,
                )
                .map_err(std::io::Error::other)
        })
    }
}

/// What a render did: counters and times of the primary and the shadow pass.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    /// Primary-ray pass.
    pub primary: Stats,
    /// Shadow-ray pass (diffuse shading only).
    pub shadow: Option<Stats>,
    /// Number of primary rays that hit.
    pub hits: u64,
}

/// The default light: above and to the right of the eye, at the scene's scale.
pub fn default_light(scene: &Scene, camera: &Camera) -> Vec3 {
    let (right, up, _) = camera.basis();
    let r = scene.bounds().extent().length().max(1e-6);
    camera.eye + (up * 0.8 + right * 0.5) * r
}

/// Ray casting: one primary ray per pixel, shaded.
pub fn raycast(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    shade: Shade,
    light: Option<Vec3>,
) -> Result<(Image, RenderStats)> {
    let rays = camera.rays(width, height);
    let (hits, primary) = tracer.intersect_timed(scene, &rays)?;
    let mut stats = RenderStats {
        hits: hits.hit_count() as u64,
        primary,
        shadow: None,
    };
    let n = rays.len();
    let colour: Vec<Vec3> = match shade {
        Shade::Normal => (0..n)
            .into_par_iter()
            .map(|i| {
                if hits.is_hit(i) {
                    generate::hit_frame(scene, &rays, &hits, i).1 * 0.5 + 0.5
                } else {
                    background(i, width, height)
                }
            })
            .collect(),
        Shade::Depth => {
            let (lo, hi) = hits
                .t
                .iter()
                .filter(|t| t.is_finite())
                .fold((f32::INFINITY, 0.0f32), |(a, b), &t| (a.min(t), b.max(t)));
            let span = (hi - lo).max(1e-12);
            (0..n)
                .into_par_iter()
                .map(|i| {
                    if hits.is_hit(i) {
                        Vec3::splat(1.0 - 0.85 * (hits.t[i] - lo) / span)
                    } else {
                        background(i, width, height)
                    }
                })
                .collect()
        }
        Shade::Diffuse if light.is_none() && scene.has_emission() => {
            let cfg = distribution::DistConfig::default();
            let lights = light::Lights::of_scene(scene);
            let (c, ph) =
                distribution::distribution(scene, tracer, camera, width, height, &lights, &cfg)?;
            stats.primary = ph[0].stats.clone();
            stats.hits = ph[0].hits;
            stats.shadow = Some(ph[2].stats.clone());
            c
        }
        Shade::Diffuse => {
            let light = light.unwrap_or_else(|| default_light(scene, camera));
            let (shadow_rays, from) = generate::shadow_rays(scene, &rays, &hits, light);
            let (blocked, s) = tracer.occluded_timed(scene, &shadow_rays)?;
            stats.shadow = Some(s);
            let mut lit = vec![false; n];
            for (k, &i) in from.iter().enumerate() {
                lit[i as usize] = !blocked[k];
            }
            diffuse(scene, &rays, &hits, &lit, light, width, height)
        }
    };
    Ok((to_image(&colour, width, height), stats))
}

/// Linear radiance to an 8-bit sRGB image: clamped to [0, 1], then the sRGB transfer function
/// (IEC 61966-2-1: linear below 0.0031308, a 2.4 power above), rounded to nearest.
pub fn to_image(colour: &[Vec3], width: u32, height: u32) -> Image {
    let rgb = colour
        .iter()
        .flat_map(|c| c.to_array().map(|x| (srgb_encode(x) * 255.0 + 0.5) as u8))
        .collect();
    Image { width, height, rgb }
}

/// The sRGB transfer function of a linear value, clamped to [0, 1] (NaN gives 0).
pub fn srgb_encode(x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tone_tests {
    use super::srgb_encode;

    #[test]
    fn srgb_transfer_function() {
        // The standard's reference points: the ends, the linear segment, the knee, and
        // mid-grey (0.214 linear is 50% sRGB up to the standard's own rounding).
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(srgb_encode(-1.0), 0.0);
        assert_eq!(srgb_encode(7.0), srgb_encode(1.0));
        let white = super::to_image(&[glam::Vec3::ONE], 1, 1);
        assert_eq!(white.rgb, vec![255; 3]);
        assert_eq!(srgb_encode(f32::NAN), 0.0);
        assert!((srgb_encode(0.001) - 0.012_92).abs() < 1e-7);
        let knee = 0.003_130_8_f32;
        assert!(
            (srgb_encode(knee) - srgb_encode(knee * 1.000_01)).abs() < 1e-5,
            "continuous"
        );
        assert!((srgb_encode(0.214_041_1) - 0.5).abs() < 1e-4);
        let mut last = 0.0;
        for k in 0..=1000 {
            let v = srgb_encode(k as f32 / 1000.0);
            assert!(v >= last, "monotone at {k}");
            last = v;
        }
    }
}

fn diffuse(
    scene: &Scene,
    rays: &RayBatch,
    hits: &HitBatch,
    lit: &[bool],
    light: Vec3,
    w: u32,
    h: u32,
) -> Vec<Vec3> {
    // The scene's colours (materials, vertex colours), warm grey where it has none.
    let default = crate::scene::Material {
        diffuse: Vec3::new(0.85, 0.8, 0.7),
        ..Default::default()
    };
    (0..rays.len())
        .into_par_iter()
        .map(|i| {
            if !hits.is_hit(i) {
                return background(i, w, h);
            }
            let (p, n) = generate::hit_frame(scene, rays, hits, i);
            let ambient = 0.08 + 0.07 * n.y.max(0.0);
            let direct = if lit[i] {
                n.dot((light - p).normalize()).max(0.0)
            } else {
                0.0
            };
            let albedo = scene.albedo(hits.prim[i], hits.u[i], hits.v[i], &default);
            albedo * (ambient + 0.9 * direct)
        })
        .collect()
}

/// A dark vertical gradient, so misses are visible but quiet.
fn background(i: usize, w: u32, h: u32) -> Vec3 {
    let y = (i / w as usize) as f32 / h.max(1) as f32;
    Vec3::new(0.10, 0.11, 0.14).lerp(Vec3::new(0.02, 0.02, 0.03), y)
}
