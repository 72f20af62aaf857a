//! A diffuse path tracer driven in whole-bounce batches: the workload of Mora 2011 §4.2 (Fig. 10),
//! where DACRT's random-ray mode receives every ray of one bounce in one batch.
//!
//! Surfaces are Lambertian with their material's colour (grey 0.7, `PathConfig::albedo`, where
//! the scene gives none) or perfect mirrors; paths have a fixed number of bounces with no Russian
//! roulette, as in the paper, so every bounce's batch holds all still-alive paths.
//!
//! Lighting: when the scene has area lights (emissive materials, or lights passed to
//! [`path_trace_lit`]) the background is black and every diffuse vertex does **next-event
//! estimation**: one shadow ray to a point chosen on a light (light by power, point uniform by
//! area), all of one bounce's shadow rays traced as one any-hit batch. The light a diffuse
//! bounce ray hits is counted too, and the two are combined by **multiple importance sampling**
//! (power heuristic, Veach 1997): without it, surfaces close to a light (the Cornell box's
//! ceiling 1 cm above its light) get rare huge shadow-ray contributions and the image converges
//! several times slower (BENCHMARKS.md, "Mitsuba reference check"). Camera rays and rays after a
//! mirror count the emission they hit in full (no shadow ray can reach them); the last vertex's
//! bounce rays are traced too, only to find lights, so that its shadow rays are weighted as well
//! (counted in full they grow without bound as a light comes close); they are the stats' one
//! extra depth, `bounces + 1`, about 3% more rays on the Cornell box at 7 bounces. The user's
//! square lights are not geometry, so their shadow rays count in full.
//! Without lights the scene is lit by a sky (white above the horizon, darker below), as before.
//! The random numbers of a path vertex come from (seed, sample, depth, pixel), so the image does
//! not depend on the thread count or on the tracer. The renderer sees only the [`Tracer`]
//! contract, so it runs with every tracer.

use super::light::{geometry_term, power_heuristic, shadow_ray, Lights};
use super::Image;
use crate::error::{Error, Result};
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
    /// Multiple importance sampling of shadow rays and bounce rays that find a light (default
    /// on); off, lights are found by shadow rays only (plain next-event estimation: the same
    /// image in expectation, noisier next to lights).
    pub mis: bool,
}

impl Default for PathConfig {
    fn default() -> Self {
        Self {
            spp: 4,
            bounces: 7,
            albedo: 0.7,
            seed: 1,
            mis: true,
        }
    }
}

/// A window of the full image's pixels: columns `x0 .. x0 + w`, rows `y0 .. y0 + h` (a tile).
/// Rendered with [`path_trace_window`], its pixels keep their full-image index for the random
/// numbers, so tiles assembled are the full image bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub x0: u32,
    /// First row (from the top).
    pub y0: u32,
    /// Columns.
    pub w: u32,
    /// Rows.
    pub h: u32,
}

impl Window {
    /// The whole `width` × `height` image.
    pub fn full(width: u32, height: u32) -> Self {
        Self {
            x0: 0,
            y0: 0,
            w: width,
            h: height,
        }
    }

    /// The full-image index of the window's pixel `k` (row-major in the window).
    #[inline]
    fn pixel(&self, k: u32, width: u32) -> u32 {
        (self.y0 + k / self.w) * width + self.x0 + k % self.w
    }

    fn check(&self, width: u32, height: u32) -> Result<()> {
        if self.x0 as u64 + self.w as u64 > width as u64
            || self.y0 as u64 + self.h as u64 > height as u64
        {
            return Err(Error::Invalid(format!(
                "window {}x{} at ({}, {}) is not inside the {width}x{height} image",
                self.w, self.h, self.x0, self.y0
            )));
        }
        Ok(())
    }
}

/// Counters and times of one bounce depth (0 = camera rays), summed over samples. With MIS and
/// lights the last depth, `bounces + 1`, holds the rays that only look for lights.
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
    /// Next-event shadow rays traced from this depth's hits (0 without lights).
    pub shadow_rays: u64,
    /// Their tracer counters and trace time.
    pub shadow: Stats,
}

fn sky(d: Vec3) -> Vec3 {
    let d = d.normalize_or_zero();
    if d.y >= 0.0 {
        Vec3::new(0.9, 0.95, 1.0).lerp(Vec3::new(0.5, 0.7, 1.0), d.y)
    } else {
        Vec3::splat(0.15)
    }
}

/// Renders with paths of `cfg.bounces` bounces, lit by the scene's own lights (or the sky when
/// it has none); returns the image and per-depth stats.
pub fn path_trace(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    cfg: &PathConfig,
) -> Result<(Image, Vec<BounceStats>)> {
    let (sum, per_depth) = path_trace_lit(
        scene,
        tracer,
        camera,
        width,
        height,
        cfg,
        &Lights::of_scene(scene),
    )?;
    Ok((super::to_image(&sum, width, height), per_depth))
}

/// [`path_trace`] of the pixels of `window` only: a `window.w` × `window.h` image equal bit for
/// bit to that window of the full `width` × `height` render.
pub fn path_trace_window(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    cfg: &PathConfig,
    window: Window,
) -> Result<(Image, Vec<BounceStats>)> {
    let lights = Lights::of_scene(scene);
    let (sum, per_depth) =
        path_trace_lit_window(scene, tracer, camera, width, height, cfg, &lights, window)?;
    Ok((super::to_image(&sum, window.w, window.h), per_depth))
}

/// A generator for one path vertex: independent of batch order and thread count.
#[inline]
pub(crate) fn vertex_rng(seed: u64, sample: u32, depth: u32, pixel: u32) -> rand_pcg::Pcg64Mcg {
    let k = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((sample as u64) << 40 ^ (depth as u64) << 32 ^ pixel as u64);
    rand_pcg::Pcg64Mcg::seed_from_u64(k)
}

/// Jittered primary rays, one per pixel (same convention as `Camera::rays`, plus a sub-pixel
/// offset from `vertex_rng(seed, s, u32::MAX, pixel)`).
pub(crate) fn jittered_primary(
    camera: &Camera,
    width: u32,
    height: u32,
    seed: u64,
    s: u32,
) -> RayBatch {
    jittered_primary_window(camera, width, height, Window::full(width, height), seed, s)
}

/// [`jittered_primary`] for the pixels of `win` (row-major in it; full-image pixel indices).
fn jittered_primary_window(
    camera: &Camera,
    width: u32,
    height: u32,
    win: Window,
    seed: u64,
    s: u32,
) -> RayBatch {
    let n = win.w as usize * win.h as usize;
    let (right, up, forward) = camera.basis();
    let tan = (camera.fov_deg.to_radians() * 0.5).tan();
    let dirs: Vec<Vec3> = (0..n)
        .into_par_iter()
        .map(|k| {
            let k = win.pixel(k as u32, width) as usize;
            let mut rng = vertex_rng(seed, s, u32::MAX, k as u32);
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
    if win == Window::full(width, height) {
        b.layout = crate::rays::RayLayout::Pinhole {
            eye: camera.eye,
            width,
            height,
        };
    }
    b
}

/// What one path vertex gives: radiance to add now, the next ray (with its throughput and the
/// solid-angle density it was sampled with, +∞ for a mirror's), and a shadow ray with the
/// radiance it carries if unblocked.
struct Vertex {
    add: Vec3,
    next: Option<(Ray, Vec3, f32)>,
    shadow: Option<(Ray, Vec3)>,
}

/// [`path_trace`] with explicit lights; returns the linear radiance per pixel (row-major) and
/// per-depth stats.
pub fn path_trace_lit(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    cfg: &PathConfig,
    lights: &Lights,
) -> Result<(Vec<Vec3>, Vec<BounceStats>)> {
    let full = Window::full(width, height);
    path_trace_lit_window(scene, tracer, camera, width, height, cfg, lights, full)
}

/// [`path_trace_lit`] of the pixels of `win` (row-major in the window; see [`Window`]).
#[allow(clippy::too_many_arguments)]
pub fn path_trace_lit_window(
    scene: &Scene,
    tracer: &dyn Tracer,
    camera: &Camera,
    width: u32,
    height: u32,
    cfg: &PathConfig,
    lights: &Lights,
    win: Window,
) -> Result<(Vec<Vec3>, Vec<BounceStats>)> {
    win.check(width, height)?;
    let n = win.w as usize * win.h as usize;
    let mut sum = vec![Vec3::ZERO; n];
    // With MIS, the last vertex's bounce rays are traced too, only to find lights (`tail`):
    // without them its shadow rays would count in full, unbounded as a light comes close.
    let tail = cfg.mis && !lights.is_empty();
    let depths = cfg.bounces + tail as u32;
    let mut per_depth: Vec<BounceStats> = (0..=depths)
        .map(|d| BounceStats {
            depth: d,
            ..Default::default()
        })
        .collect();
    let eps = generate::surface_offset(scene);
    let default = crate::scene::Material {
        diffuse: Vec3::splat(cfg.albedo),
        ..Default::default()
    };
    for s in 0..cfg.spp {
        let mut rays = jittered_primary_window(camera, width, height, win, cfg.seed, s);
        let mut pixel: Vec<u32> = (0..n as u32).collect();
        let mut throughput = vec![Vec3::ONE; n];
        // The density each ray was sampled with: +∞ for camera rays and mirror bounces, which
        // count the emission they hit in full (no shadow ray covers them).
        let mut ray_pdf = vec![f32::INFINITY; n];
        let mut hits = HitBatch::new(0);
        for depth in 0..=depths {
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
            // No ray follows this depth's vertices; `lights_only`: these rays only find lights.
            let last = depth == depths;
            let lights_only = depth > cfg.bounces;
            let verts: Vec<Vertex> = (0..rays.len())
                .into_par_iter()
                .map(|i| {
                    let tp = throughput[i];
                    if !hits.is_hit(i) {
                        let add = if lights.is_empty() {
                            tp * sky(rays.dir(i))
                        } else {
                            Vec3::ZERO
                        };
                        return Vertex {
                            add,
                            next: None,
                            shadow: None,
                        };
                    }
                    let prim = hits.prim[i];
                    let m = scene.material(prim).unwrap_or(&default);
                    let add = if !m.is_emissive() {
                        Vec3::ZERO
                    } else if ray_pdf[i] == f32::INFINITY {
                        tp * m.emission
                    } else if let Some(k) = lights.of_primitive(prim).filter(|_| cfg.mis) {
                        // A bounce ray found a light the previous vertex's shadow ray could
                        // also have chosen: weigh the two.
                        let d = rays.dir(i);
                        let len = d.length();
                        let cos_light = scene.normal(prim as usize).dot(d / len);
                        let pl = lights.solid_angle_pdf(k, hits.t[i] * len, cos_light);
                        tp * m.emission * power_heuristic(ray_pdf[i], pl)
                    } else {
                        Vec3::ZERO
                    };
                    if lights_only {
                        return Vertex {
                            add,
                            next: None,
                            shadow: None,
                        };
                    }
                    let (p, nrm) = generate::hit_frame(scene, &rays, &hits, i);
                    let mut rng = vertex_rng(cfg.seed, s, depth, win.pixel(pixel[i], width));
                    let o = p + nrm * eps;
                    if m.mirror {
                        let d = rays.dir(i).normalize();
                        let r = d - 2.0 * d.dot(nrm) * nrm;
                        let next = (!last).then(|| {
                            (
                                Ray {
                                    origin: o,
                                    dir: r,
                                    tmin: 0.0,
                                    tmax: f32::INFINITY,
                                },
                                tp * m.diffuse,
                                f32::INFINITY,
                            )
                        });
                        return Vertex {
                            add,
                            next,
                            shadow: None,
                        };
                    }
                    let f = tp * scene.albedo(prim, hits.u[i], hits.v[i], &default);
                    let shadow = (!lights.is_empty())
                        .then(|| {
                            let (k, pl, u) = lights.pick(rng.gen());
                            let l = &lights.lights[k];
                            let (y, ny) = l.sample(u, rng.gen());
                            let g = geometry_term(o, nrm, y, ny, l.radiance);
                            let mut c = f * std::f32::consts::FRAC_1_PI * g * (l.area / pl);
                            if cfg.mis && !last && lights.is_geometry(k) && c.max_element() > 0.0 {
                                // The bounce ray could have found this point too.
                                let d = y - o;
                                let dist = d.length();
                                let w = d / dist;
                                let pl = lights.solid_angle_pdf(k, dist, ny.dot(w));
                                let pb = nrm.dot(w).max(0.0) * std::f32::consts::FRAC_1_PI;
                                c *= power_heuristic(pl, pb);
                            }
                            (shadow_ray(o, y), c)
                        })
                        .filter(|(_, c)| c.max_element() > 0.0);
                    let next = (!last).then(|| {
                        let dir = generate::cosine_direction(nrm, rng.gen(), rng.gen());
                        let pdf = nrm.dot(dir).max(0.0) * std::f32::consts::FRAC_1_PI;
                        (
                            Ray {
                                origin: o,
                                dir,
                                tmin: 0.0,
                                tmax: f32::INFINITY,
                            },
                            f,
                            pdf,
                        )
                    });
                    Vertex { add, next, shadow }
                })
                .collect();
            let mut next = RayBatch::with_capacity(verts.len());
            let (mut next_pixel, mut next_tp, mut next_pdf) = (Vec::new(), Vec::new(), Vec::new());
            let mut shadows = RayBatch::with_capacity(verts.len());
            let mut carried = Vec::new();
            for (i, v) in verts.into_iter().enumerate() {
                let px = pixel[i];
                sum[px as usize] += v.add;
                if let Some((r, t, pdf)) = v.next {
                    next.push(r);
                    next_pixel.push(px);
                    next_tp.push(t);
                    next_pdf.push(pdf);
                }
                if let Some((r, c)) = v.shadow {
                    shadows.push(r);
                    carried.push((px, c));
                }
            }
            if !shadows.is_empty() {
                let (blocked, st) = tracer.occluded_timed(scene, &shadows)?;
                let b = &mut per_depth[depth as usize];
                b.shadow_rays += shadows.len() as u64;
                b.shadow += &st;
                for (k, &(px, c)) in carried.iter().enumerate() {
                    if !blocked[k] {
                        sum[px as usize] += c;
                    }
                }
            }
            rays = next;
            pixel = next_pixel;
            throughput = next_tp;
            ray_pdf = next_pdf;
        }
    }
    for b in &mut per_depth {
        b.mrays_per_s = b.rays as f64 / (b.stats.trace_ms * 1e3).max(1e-9);
    }
    let inv = 1.0 / cfg.spp.max(1) as f32;
    sum.iter_mut().for_each(|c| *c *= inv);
    Ok((sum, per_depth))
}
