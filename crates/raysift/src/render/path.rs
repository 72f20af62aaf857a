//! A diffuse path tracer driven in whole-bounce batches: the workload of Mora 2011 §4.2 (Fig. 10),
//! where DACRT's random-ray mode receives every ray of one bounce in one batch.
//!
//! Scene: every surface is grey Lambertian (albedo 0.7) under a sky light (white above the
//! horizon, darker below); paths have a fixed number of bounces with no Russian roulette, as in the
//! paper, so every bounce's batch holds all still-alive paths. The renderer sees only the
//! [`Tracer`] contract, so it runs with every tracer.

use super::Image;
use crate::error::Result;
use crate::rays::{generate, Camera, HitBatch, Ray, RayBatch};
use crate::scene::Scene;
use crate::tracer::{Stats, Tracer};
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Path-tracing parameters.
#[derive(Clone, Copy, Debug)]
pub struct PathConfig {
    /// Samples per pixel (default 4).
    pub spp: u32,
    /// Bounces after the primary hit (default 7, the paper's).
    pub bounces: u32,
    /// Diffuse albedo of every surface (default 0.7).
    pub albedo: f32,
    /// Random seed.
    pub seed: u64,
}

impl Default for PathConfig {
    fn default() -> Self {
        Self {
            spp: 4,
            bounces: 7,
            albedo: 0.7,
            seed: 1,
        }
    }
}

/// Counters and times of one bounce depth (0 = camera rays), summed over samples.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BounceStats {
    /// Depth (0 = primary).
    pub depth: u32,
    /// Rays traced at this depth.
    pub rays: u64,
    /// Rays that hit.
    pub hits: u64,
    /// Tracer counters and trace time.
    pub stats: Stats,
    /// Rays per microsecond (= Mrays/s) of the trace calls.
    pub mrays_per_s: f64,
}

fn sky(d: Vec3) -> Vec3 {
    let d = d.normalize_or_zero();
    if d.y >= 0.0 {
        Vec3::new(0.9, 0.95, 1.0).lerp(Vec3::new(0.5, 0.7, 1.0), d.y)
    } else {
        Vec3::splat(0.15)
    }
}

/// Renders with paths of `cfg.bounces` diffuse bounces; returns the image and per-depth stats.
pub fn path_trace(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    cfg: &PathConfig,
) -> Result<(Image, Vec<BounceStats>)> {
    let n = width as usize * height as usize;
    let mut sum = vec![Vec3::ZERO; n];
    let mut per_depth: Vec<BounceStats> = (0..=cfg.bounces)
        .map(|d| BounceStats {
            depth: d,
            ..Default::default()
        })
        .collect();
    let eps = generate::surface_offset(scene);
    let (right, up, forward) = camera.basis();
    let tan = (camera.fov_deg.to_radians() * 0.5).tan();
    for s in 0..cfg.spp {
        // Jittered primary rays (same convention as Camera::rays, plus a sub-pixel offset).
        let mut rays = {
            let dirs: Vec<Vec3> = (0..n)
                .into_par_iter()
                .map(|k| {
                    let mut rng =
                        rand_pcg::Pcg64Mcg::seed_from_u64(cfg.seed ^ ((s as u64) << 40) ^ k as u64);
                    let (i, j) = (
                        (k % width as usize) as f32 + rng.gen::<f32>(),
                        (k / width as usize) as f32 + rng.gen::<f32>(),
                    );
                    let x = (2.0 * i / width as f32 - 1.0) * tan * width as f32 / height as f32;
                    let y = (1.0 - 2.0 * j / height as f32) * tan;
                    (x * right + y * up + forward).normalize()
                })
                .collect();
            let mut b = RayBatch::from_rays(dirs.into_iter().map(|d| Ray {
                origin: camera.eye,
                dir: d,
                tmin: 0.0,
                tmax: f32::INFINITY,
            }));
            b.layout = crate::rays::RayLayout::Pinhole {
                eye: camera.eye,
                width,
                height,
            };
            b
        };
        let mut pixel: Vec<u32> = (0..n as u32).collect();
        let mut throughput = vec![Vec3::ONE; n];
        let mut hits = HitBatch::new(0);
        for depth in 0..=cfg.bounces {
            if rays.is_empty() {
                break;
            }
            let t0 = std::time::Instant::now();
            let mut st = tracer.intersect(scene, &rays, &mut hits, None)?;
            st.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
            let b = &mut per_depth[depth as usize];
            b.rays += rays.len() as u64;
            b.hits += hits.hit_count() as u64;
            b.stats += &st;
            // Escaped paths collect the sky; the others continue with a cosine-weighted bounce
            // (whose pdf cancels the cosine, leaving albedo as the weight).
            let mut next = RayBatch::with_capacity(hits.hit_count());
            let mut next_pixel = Vec::with_capacity(hits.hit_count());
            let mut next_tp = Vec::with_capacity(hits.hit_count());
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(
                cfg.seed.wrapping_mul(31) ^ ((s as u64) << 32) ^ depth as u64,
            );
            for i in 0..rays.len() {
                let px = pixel[i] as usize;
                if !hits.is_hit(i) {
                    sum[px] += throughput[i] * sky(rays.dir(i));
                    continue;
                }
                if depth == cfg.bounces {
                    continue;
                }
                next.push(generate::bounce_ray(
                    scene,
                    &rays,
                    &hits,
                    i,
                    eps,
                    rng.gen(),
                    rng.gen(),
                ));
                next_pixel.push(px as u32);
                next_tp.push(throughput[i] * cfg.albedo);
            }
            rays = next;
            pixel = next_pixel;
            throughput = next_tp;
        }
    }
    for b in &mut per_depth {
        b.mrays_per_s = b.rays as f64 / (b.stats.trace_ms * 1e3).max(1e-9);
    }
    let inv = 1.0 / cfg.spp.max(1) as f32;
    let rgb = sum
        .iter()
        .flat_map(|c| {
            (*c * inv)
                .to_array()
                .map(|x| (x.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0 + 0.5) as u8)
        })
        .collect();
    Ok((Image { width, height, rgb }, per_depth))
}
