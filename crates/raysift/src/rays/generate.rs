//! Ray generators besides the camera: uniform random rays (the incoherent workload), shadow rays
//! to a point light and cosine-weighted diffuse bounce rays from a batch's hits.
//!
//! Secondary rays start on a surface; to keep them from re-hitting it through rounding, their
//! origin is pushed off the surface along the geometric normal by [`surface_offset`] of the scene.

use super::{HitBatch, Ray, RayBatch, RayLayout};
use crate::geom::Aabb;
use crate::scene::Scene;
use glam::Vec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Distance secondary rays start off the surface: `1e-5 ×` the scene's bounding-box diagonal
/// (so it scales with the scene), and at least 1e-7.
pub fn surface_offset(scene: &Scene) -> f32 {
    let b = scene.bounds();
    if b.is_empty() {
        return 1e-7;
    }
    (b.extent().length() * 1e-5).max(1e-7)
}

/// Uniform direction on the unit sphere from two uniform numbers in [0,1).
#[inline]
pub fn sphere_direction(a: f32, b: f32) -> Vec3 {
    let z = 1.0 - 2.0 * a;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * b;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// `n` rays with origins uniform in `bounds` and directions uniform on the sphere; deterministic
/// for a seed (rays are drawn in blocks of 4096 from per-block generators, so the result does not
/// depend on the thread count).
pub fn random_in_box(bounds: &Aabb, n: usize, seed: u64) -> RayBatch {
    const BLOCK: usize = 4096;
    let (lo, ext) = (bounds.min, bounds.extent().max(Vec3::ZERO));
    let blocks: Vec<Vec<Ray>> = (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(
                seed ^ (b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
            );
            let m = BLOCK.min(n - b * BLOCK);
            (0..m)
                .map(|_| {
                    let o = lo + ext * Vec3::new(rng.gen(), rng.gen(), rng.gen());
                    let d = sphere_direction(rng.gen(), rng.gen());
                    Ray {
                        origin: o,
                        dir: d,
                        tmin: 0.0,
                        tmax: f32::INFINITY,
                    }
                })
                .collect()
        })
        .collect();
    let mut out = RayBatch::with_capacity(n);
    for r in blocks.into_iter().flatten() {
        out.push(r);
    }
    out
}

/// The hit point of ray `i` and the unit geometric normal facing the ray's origin side.
#[inline]
pub fn hit_frame(scene: &Scene, rays: &RayBatch, hits: &HitBatch, i: usize) -> (Vec3, Vec3) {
    let p = rays.origin(i) + rays.dir(i) * hits.t[i];
    let n = scene.normal(hits.prim[i] as usize);
    let n = if n.dot(rays.dir(i)) > 0.0 { -n } else { n };
    (p, n)
}

/// Shadow rays from every hit of `hits` towards `light`: origin = hit point pushed off the surface
/// towards the viewer side, direction = light − origin (unnormalised, so the light is at `t = 1`),
/// `tmin = 0`, `tmax = 1`. Returns the rays and, for each, the index of the ray it came from.
/// Hits whose surface faces away from the light get no shadow ray (they are in shadow by their own
/// surface).
pub fn shadow_rays(
    scene: &Scene,
    rays: &RayBatch,
    hits: &HitBatch,
    light: Vec3,
) -> (RayBatch, Vec<u32>) {
    let eps = surface_offset(scene);
    let mut out = RayBatch::with_capacity(hits.hit_count());
    let mut from = Vec::with_capacity(hits.hit_count());
    for i in 0..hits.len() {
        if !hits.is_hit(i) {
            continue;
        }
        let (p, n) = hit_frame(scene, rays, hits, i);
        if n.dot(light - p) <= 0.0 {
            continue;
        }
        let o = p + n * eps;
        out.push(Ray {
            origin: o,
            dir: light - o,
            tmin: 0.0,
            tmax: 1.0,
        });
        from.push(i as u32);
    }
    out.layout = RayLayout::ToPoint { target: light };
    (out, from)
}

/// Cosine-weighted diffuse bounce rays from every hit (on the viewer's side of the surface).
/// Returns the rays and the index of the ray each came from. Deterministic for a seed.
pub fn bounce_rays(
    scene: &Scene,
    rays: &RayBatch,
    hits: &HitBatch,
    seed: u64,
) -> (RayBatch, Vec<u32>) {
    let eps = surface_offset(scene);
    let mut out = RayBatch::with_capacity(hits.hit_count());
    let mut from = Vec::with_capacity(hits.hit_count());
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    for i in 0..hits.len() {
        if !hits.is_hit(i) {
            continue;
        }
        out.push(bounce_ray(scene, rays, hits, i, eps, rng.gen(), rng.gen()));
        from.push(i as u32);
    }
    (out, from)
}

/// The cosine-weighted diffuse bounce of hit `i` (on the viewer's side of the surface, its origin
/// pushed off by `eps`), from two uniform numbers in [0,1).
#[inline]
pub fn bounce_ray(
    scene: &Scene,
    rays: &RayBatch,
    hits: &HitBatch,
    i: usize,
    eps: f32,
    a: f32,
    b: f32,
) -> Ray {
    let (p, n) = hit_frame(scene, rays, hits, i);
    Ray {
        origin: p + n * eps,
        dir: cosine_direction(n, a, b),
        tmin: 0.0,
        tmax: f32::INFINITY,
    }
}

/// Cosine-weighted direction about unit normal `n` from two uniform numbers in [0,1).
#[inline]
pub fn cosine_direction(n: Vec3, a: f32, b: f32) -> Vec3 {
    let r = a.sqrt();
    let phi = std::f32::consts::TAU * b;
    let (t, s) = n.any_orthonormal_pair();
    (t * (r * phi.cos()) + s * (r * phi.sin()) + n * (1.0 - a).max(0.0).sqrt()).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_rays_are_in_the_box_unit_and_reproducible() {
        let b = Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.5, 3.0));
        let r = random_in_box(&b, 10_000, 42);
        assert_eq!(r.len(), 10_000);
        for i in 0..r.len() {
            assert!(b.contains(r.origin(i)));
            assert!((r.dir(i).length() - 1.0).abs() < 1e-5);
        }
        let again = random_in_box(&b, 10_000, 42);
        assert_eq!(r.dx, again.dx);
        assert_ne!(r.dx, random_in_box(&b, 10_000, 43).dx);
        // Directions cover both signs on every axis about equally.
        let pos = r.dz.iter().filter(|&&z| z > 0.0).count();
        assert!((4500..5500).contains(&pos), "{pos}");
    }

    #[test]
    fn cosine_directions_are_in_the_hemisphere() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let mut sum = 0.0;
        for k in 0..1000 {
            let d = cosine_direction(
                n,
                (k as f32 + 0.5) / 1000.0,
                ((k * 7919) % 1000) as f32 / 1000.0,
            );
            assert!(d.dot(n) >= 0.0);
            sum += d.dot(n);
        }
        // E[cos θ] = 2/3 for a cosine-weighted hemisphere.
        assert!((sum / 1000.0 - 2.0 / 3.0).abs() < 0.02);
    }
}
