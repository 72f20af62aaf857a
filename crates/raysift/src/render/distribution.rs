//! Distribution ray tracing as RTRPS §4 / Table 4 evaluates it: a×a antialiasing samples per
//! pixel, and from every primary hit N×N stratified shadow samples on each area light, the N²
//! rays of one hit and one light handed to the tracer as one group (`RayLayout::OriginGrids`,
//! the ray-plane / shaft workload); optionally one diffuse bounce with N_b×N_b stratified
//! cosine-weighted directions per hit (RTRPS's "Cubes"), also as origin grids, whose hits are lit
//! by one shadow ray each. Mirrors reflect camera rays (up to [`MAX_MIRROR_DEPTH`] times) before
//! shading, the reflection rays of one level traced as one batch.
//!
//! Every primary hit gets all N² samples of every light (a sample behind the surface carries
//! zero), so the shadow-ray count is exactly N² × lights × primary hits, RTRPS's count form.
//! Stratification: cell (i, j) of the grid is sampled at ((i + ξ)/N, (j + η)/N) with one (ξ, η)
//! per hit (a shifted regular grid, so the group stays a grid). Hits are shaded in chunks so a
//! trace batch stays under about 2²⁰ rays whatever N.

use super::light::{geometry_term, shadow_ray, Lights};
use super::path::vertex_rng;
use crate::error::Result;
use crate::rays::{generate, Camera, HitBatch, Ray, RayBatch, RayLayout};
use crate::scene::{Material, Scene};
use crate::tracer::{Stats, Tracer};
use glam::Vec3;
use rand::Rng;
use rayon::prelude::*;
use std::f32::consts::FRAC_1_PI;

/// Mirror reflections followed per camera ray.
pub const MAX_MIRROR_DEPTH: u32 = 4;

/// Distribution ray tracing parameters.
#[derive(Clone, Copy, Debug)]
pub struct DistConfig {
    /// a: a×a stratified antialiasing samples per pixel (default 1).
    pub aa: u32,
    /// N: N×N shadow samples per light per hit (default 4; RTRPS uses 16).
    pub light_side: u32,
    /// N_b: N_b×N_b diffuse bounce samples per hit, 0 for none (default 0).
    pub bounce_side: u32,
    /// Random seed.
    pub seed: u64,
}

impl Default for DistConfig {
    fn default() -> Self {
        Self {
            aa: 1,
            light_side: 4,
            bounce_side: 0,
            seed: 1,
        }
    }
}

/// Rays and tracer stats of one phase.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Phase {
    /// Phase name.
    pub name: &'static str,
    /// Rays traced.
    pub rays: u64,
    /// Rays that hit (closest-hit phases) or were blocked (shadow phases).
    pub hits: u64,
    /// Counters and trace time.
    pub stats: Stats,
}

impl Phase {
    fn add(&mut self, rays: usize, hits: usize, st: &Stats) {
        self.rays += rays as u64;
        self.hits += hits as u64;
        self.stats += st;
    }
}

const CHUNK_RAYS: usize = 1 << 20;

/// Renders; returns linear radiance per pixel and the phases (primary, reflection, shadow,
/// bounce, bounce shadow).
pub fn distribution(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    lights: &Lights,
    cfg: &DistConfig,
) -> Result<(Vec<Vec3>, Vec<Phase>)> {
    let a = cfg.aa.max(1);
    let spp = (a * a) as usize;
    let np = width as usize * height as usize;
    let mut phases: Vec<Phase> = ["primary", "reflection", "shadow", "bounce", "bounce shadow"]
        .map(|name| Phase {
            name,
            ..Default::default()
        })
        .into();
    // Primary rays, pixel-major a×a stratified samples.
    let (right, up, forward) = camera.basis();
    let tan = (camera.fov_deg.to_radians() * 0.5).tan();
    let (w, h) = (width as f32, height as f32);
    let dirs: Vec<Vec3> = (0..np * spp)
        .into_par_iter()
        .map(|k| {
            let (px, s) = (k / spp, (k % spp) as u32);
            let mut rng = vertex_rng(cfg.seed, s, u32::MAX, px as u32);
            let i = (px % width as usize) as f32 + ((s % a) as f32 + rng.gen::<f32>()) / a as f32;
            let j = (px / width as usize) as f32 + ((s / a) as f32 + rng.gen::<f32>()) / a as f32;
            let x = (2.0 * i / w - 1.0) * tan * w / h;
            let y = (1.0 - 2.0 * j / h) * tan;
            (x * right + y * up + forward).normalize()
        })
        .collect();
    let mut rays = RayBatch::from_rays(dirs.into_iter().map(|d| Ray {
        origin: camera.eye,
        dir: d,
        tmin: 0.0,
        tmax: f32::INFINITY,
    }));
    rays.layout = if spp == 1 {
        RayLayout::Pinhole {
            eye: camera.eye,
            width,
            height,
        }
    } else {
        RayLayout::PixelSamples {
            eye: camera.eye,
            width,
            height,
            samples: spp as u32,
        }
    };
    let (mut hits, st) = tracer.intersect_timed(scene, &rays)?;
    phases[0].add(rays.len(), hits.hit_count(), &st);
    let eps = generate::surface_offset(scene);
    // Per sample: its sample index, the weight (mirror tints) and the final (non-mirror) hit.
    let mut weight = vec![Vec3::ONE; rays.len()];
    let mut sample_of: Vec<u32> = (0..rays.len() as u32).collect();
    let mut radiance = vec![Vec3::ZERO; rays.len()];
    let default = Material::default();
    let mat = |hits: &HitBatch, i: usize| *scene.material(hits.prim[i]).unwrap_or(&default);
    let albedo =
        |hits: &HitBatch, i: usize| scene.albedo(hits.prim[i], hits.u[i], hits.v[i], &default);
    // Mirror levels: reflected rays of one level in one batch.
    let mut final_rays = RayBatch::with_capacity(rays.len());
    let mut final_hits = HitBatch::new(0);
    let (mut f_sample, mut f_weight) = (Vec::new(), Vec::new());
    let (mut ft, mut fp) = (Vec::new(), Vec::new());
    for level in 0..=MAX_MIRROR_DEPTH {
        let mut refl = RayBatch::with_capacity(0);
        let (mut r_sample, mut r_weight) = (Vec::new(), Vec::new());
        for i in 0..rays.len() {
            if !hits.is_hit(i) {
                continue;
            }
            let m = mat(&hits, i);
            radiance[sample_of[i] as usize] += weight[i] * m.emission;
            if m.mirror && level < MAX_MIRROR_DEPTH {
                let (p, n) = generate::hit_frame(scene, &rays, &hits, i);
                let d = rays.dir(i).normalize();
                refl.push(Ray {
                    origin: p + n * eps,
                    dir: d - 2.0 * d.dot(n) * n,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
                r_sample.push(sample_of[i]);
                r_weight.push(weight[i] * m.diffuse);
            } else if !m.mirror {
                final_rays.push(rays.get(i));
                f_sample.push(sample_of[i]);
                f_weight.push(weight[i]);
                ft.push(hits.t[i]);
                fp.push(hits.prim[i]);
            }
        }
        if refl.is_empty() {
            break;
        }
        let (h2, st) = tracer.intersect_timed(scene, &refl)?;
        phases[1].add(refl.len(), h2.hit_count(), &st);
        (rays, hits, sample_of, weight) = (refl, h2, r_sample, r_weight);
    }
    final_hits.reset(ft.len());
    final_hits.t.copy_from_slice(&ft);
    final_hits.prim.copy_from_slice(&fp);
    let nl = lights.lights.len();
    let ls = cfg.light_side.max(1) as usize;
    let bs = cfg.bounce_side as usize;
    let per_hit = (nl * ls * ls).max(bs * bs).max(1);
    let chunk = (CHUNK_RAYS / per_hit).max(1);
    let nh = final_rays.len();
    for c0 in (0..nh).step_by(chunk) {
        let range = c0..(c0 + chunk).min(nh);
        // Shadow grids: hit k, light l, cell (i, j) at ((k·nl + l)·N + j)·N + i.
        let frames: Vec<(Vec3, Vec3, Vec3, [f32; 2])> = range
            .clone()
            .into_par_iter()
            .map(|k| {
                let (p, n) = generate::hit_frame(scene, &final_rays, &final_hits, k);
                let rho = albedo(&final_hits, k);
                let mut rng = vertex_rng(cfg.seed ^ 0x5A5A, f_sample[k], 0, 0);
                (p + n * eps, n, rho, [rng.gen(), rng.gen()])
            })
            .collect();
        if nl > 0 {
            let (sh, carried): (Vec<Ray>, Vec<Vec3>) = frames
                .par_iter()
                .flat_map_iter(|&(o, n, albedo, [xi, eta])| {
                    lights.lights.iter().flat_map(move |l| {
                        (0..ls * ls).map(move |c| {
                            let (i, j) = ((c % ls) as f32, (c / ls) as f32);
                            let (y, ny) = l.sample((i + xi) / ls as f32, (j + eta) / ls as f32);
                            let g = geometry_term(o, n, y, ny, l.radiance);
                            (
                                shadow_ray(o, y),
                                albedo * FRAC_1_PI * g * (l.area / (ls * ls) as f32),
                            )
                        })
                    })
                })
                .unzip();
            let mut batch = RayBatch::from_rays(sh);
            batch.layout = RayLayout::OriginGrids { side: ls as u32 };
            let (blocked, st) = tracer.occluded_timed(scene, &batch)?;
            phases[2].add(batch.len(), blocked.iter().filter(|&&b| b).count(), &st);
            let group = nl * ls * ls;
            for (q, k) in range.clone().enumerate() {
                let s = f_sample[k] as usize;
                for g in q * group..(q + 1) * group {
                    if !blocked[g] {
                        radiance[s] += f_weight[k] * carried[g];
                    }
                }
            }
        }
        if bs > 0 {
            let bounce: Vec<Ray> = frames
                .par_iter()
                .flat_map_iter(|&(o, n, _, [xi, eta])| {
                    (0..bs * bs).map(move |c| {
                        let (i, j) = ((c % bs) as f32, (c / bs) as f32);
                        let u = ((i + xi) / bs as f32).min(1.0 - f32::EPSILON);
                        let v = ((j + eta) / bs as f32).min(1.0 - f32::EPSILON);
                        Ray {
                            origin: o,
                            dir: generate::cosine_direction(n, u, v),
                            tmin: 0.0,
                            tmax: f32::INFINITY,
                        }
                    })
                })
                .collect();
            let mut batch = RayBatch::from_rays(bounce);
            batch.layout = RayLayout::OriginGrids { side: bs as u32 };
            let (bh, st) = tracer.intersect_timed(scene, &batch)?;
            phases[3].add(batch.len(), bh.hit_count(), &st);
            // Bounce hits: emission is left to the shadow rays (NEE), one per bounce hit.
            let lit: Vec<Option<(Ray, Vec3)>> = (0..batch.len())
                .into_par_iter()
                .map(|b| {
                    if !bh.is_hit(b) || nl == 0 {
                        return None;
                    }
                    let (p, n) = generate::hit_frame(scene, &batch, &bh, b);
                    let rho = albedo(&bh, b);
                    let k = range.start + b / (bs * bs);
                    let mut rng =
                        vertex_rng(cfg.seed ^ 0xB0B0, f_sample[k], 1, (b % (bs * bs)) as u32);
                    let (li, pl, u) = lights.pick(rng.gen());
                    let l = &lights.lights[li];
                    let (y, ny) = l.sample(u, rng.gen());
                    let o = p + n * eps;
                    let g = geometry_term(o, n, y, ny, l.radiance);
                    let c = rho * FRAC_1_PI * g * (l.area / pl);
                    (c.max_element() > 0.0).then(|| (shadow_ray(o, y), c))
                })
                .collect();
            let mut sb = RayBatch::with_capacity(lit.len());
            let mut carried = Vec::new();
            for (b, x) in lit.into_iter().enumerate() {
                if let Some((r, c)) = x {
                    sb.push(r);
                    carried.push((b, c));
                }
            }
            let (blocked, st) = tracer.occluded_timed(scene, &sb)?;
            phases[4].add(sb.len(), blocked.iter().filter(|&&b| b).count(), &st);
            let norm = 1.0 / (bs * bs) as f32;
            for (q, &(b, c)) in carried.iter().enumerate() {
                if !blocked[q] {
                    let k = range.start + b / (bs * bs);
                    // Cosine-weighted directions: estimator albedo · L_in averaged.
                    radiance[f_sample[k] as usize] +=
                        f_weight[k] * frames[b / (bs * bs)].2 * c * norm;
                }
            }
        }
    }
    let inv = 1.0 / spp as f32;
    let out = (0..np)
        .into_par_iter()
        .map(|p| radiance[p * spp..(p + 1) * spp].iter().sum::<Vec3>() * inv)
        .collect();
    Ok((out, phases))
}
