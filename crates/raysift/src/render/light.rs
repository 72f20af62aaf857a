//! Area lights: the scene's emissive triangles (one light per run of primitives with the same
//! emissive material) and square lights given by the user, sampled uniformly by area.
//!
//! Emission is two-sided (a light emits from both faces of its triangles), so the winding of a
//! file's light does not matter. A user's square light is not geometry: it lights the scene but
//! is invisible to camera rays.

use crate::error::{Error, Result};
use crate::scene::Scene;
use glam::Vec3;

/// One area light: triangles with a common emitted radiance.
#[derive(Clone, Debug)]
pub struct AreaLight {
    tris: Vec<[Vec3; 3]>,
    /// Cumulative triangle areas divided by the total, last = 1.
    cdf: Vec<f32>,
    /// Total area.
    pub area: f32,
    /// Emitted radiance (RGB), the same over the light and in every direction.
    pub radiance: Vec3,
}

impl AreaLight {
    /// A light from triangles (degenerate ones are dropped); `None` when no area remains.
    pub fn from_triangles(tris: Vec<[Vec3; 3]>, radiance: Vec3) -> Option<Self> {
        let tris: Vec<[Vec3; 3]> = tris
            .into_iter()
            .filter(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() > 0.0)
            .collect();
        let mut acc = 0.0f32;
        let mut cdf = Vec::with_capacity(tris.len());
        for t in &tris {
            acc += 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
            cdf.push(acc);
        }
        if !(acc > 0.0 && acc.is_finite()) {
            return None;
        }
        cdf.iter_mut().for_each(|c| *c /= acc);
        Some(Self {
            tris,
            cdf,
            area: acc,
            radiance,
        })
    }

    /// A horizontal square light facing down (−y), centred at `centre`, of side `size`, emitting
    /// `power` watts in total (white: radiance = power / (π · area) per channel, as a Lambertian
    /// emitter gives). `what` names the argument in errors (zero area, negative power).
    pub fn square(centre: Vec3, size: f32, power: f32, what: &str) -> Result<Self> {
        if !(size > 0.0 && size.is_finite()) {
            return Err(Error::Invalid(format!(
                "{what}: size {size} gives a light of zero area; it must be positive"
            )));
        }
        if !(power >= 0.0 && power.is_finite()) {
            return Err(Error::Invalid(format!(
                "{what}: power {power} must be finite and non-negative"
            )));
        }
        let h = 0.5 * size;
        let c = |x: f32, z: f32| centre + Vec3::new(x, 0.0, z);
        let (a, b, cc, d) = (c(-h, -h), c(h, -h), c(h, h), c(-h, h));
        let area = size * size;
        let radiance = Vec3::splat(power / (std::f32::consts::PI * area));
        Self::from_triangles(vec![[a, cc, b], [a, d, cc]], radiance).ok_or_else(|| {
            Error::Invalid(format!("{what}: the light has zero area at this position"))
        })
    }

    /// Total emitted power (luminance-weighted radiance × π × area), for choosing among lights.
    pub fn power(&self) -> f32 {
        let lum = self.radiance.dot(Vec3::new(0.2126, 0.7152, 0.0722));
        lum * std::f32::consts::PI * self.area
    }

    /// A point on the light and its unit normal from two numbers in [0,1): `u` chooses the
    /// triangle by area and is rescaled to pick the point with `v` (uniform over the area).
    #[inline]
    pub fn sample(&self, u: f32, v: f32) -> (Vec3, Vec3) {
        let k = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.tris.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let u = ((u - lo) / (self.cdf[k] - lo).max(1e-30)).clamp(0.0, 1.0);
        let [a, b, c] = self.tris[k];
        // Square to triangle (Shirley): uniform over the area.
        let su = u.sqrt();
        let p = a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v);
        (p, (b - a).cross(c - a).normalize())
    }
}

/// The lights of a render, chosen in proportion to their power.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// The lights.
    pub lights: Vec<AreaLight>,
    cdf: Vec<f32>,
    /// The scene's primitive ranges that are lights: (first, end, light index), sorted. Rays can
    /// hit these lights; the user's square lights are not geometry and are absent here.
    prims: Vec<(u32, u32, usize)>,
}

impl Lights {
    /// The scene's emissive meshes (one light per run of primitives sharing an emissive
    /// material) followed by `extra`.
    pub fn new(scene: &Scene, extra: Vec<AreaLight>) -> Self {
        let soup = scene.triangles();
        let mut lights = Vec::new();
        let mut prims = Vec::new();
        for (range, m) in scene.material_runs() {
            let Some(m) = m.filter(|m| m.is_emissive()) else {
                continue;
            };
            let (a, b) = (range.start as u32, range.end as u32);
            let tris = range.map(|i| soup.get(i)).collect();
            if let Some(l) = AreaLight::from_triangles(tris, m.emission) {
                prims.push((a, b, lights.len()));
                lights.push(l);
            }
        }
        lights.extend(extra);
        let total: f32 = lights.iter().map(AreaLight::power).sum();
        let mut acc = 0.0;
        let cdf = lights
            .iter()
            .map(|l| {
                acc += l.power() / total.max(1e-30);
                acc
            })
            .collect();
        Self { lights, cdf, prims }
    }

    /// The light that primitive `prim` of the scene belongs to, if it is one.
    #[inline]
    pub fn of_primitive(&self, prim: u32) -> Option<usize> {
        let k = self.prims.partition_point(|&(_, end, _)| end <= prim);
        self.prims
            .get(k)
            .filter(|&&(start, _, _)| start <= prim)
            .map(|&(_, _, l)| l)
    }

    /// True when light `k` is scene geometry, so that rays can hit it (not a user's square).
    #[inline]
    pub fn is_geometry(&self, k: usize) -> bool {
        // The scene's lights come first, in the order of `prims`.
        k < self.prims.len()
    }

    /// The probability that [`Lights::pick`] chooses light `k`.
    #[inline]
    pub fn probability(&self, k: usize) -> f32 {
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        (self.cdf[k] - lo).max(1e-30)
    }

    /// The solid-angle density with which [`Lights::pick`] and [`AreaLight::sample`] choose the
    /// direction from a point to a point of light `k` at distance `dist`, whose normal makes
    /// `|cos_light|` with the direction: `p(k) / area · dist² / |cos_light|`.
    #[inline]
    pub fn solid_angle_pdf(&self, k: usize, dist: f32, cos_light: f32) -> f32 {
        self.probability(k) / self.lights[k].area * dist * dist / cos_light.abs().max(1e-30)
    }

    /// The scene's own lights.
    pub fn of_scene(scene: &Scene) -> Self {
        Self::new(scene, Vec::new())
    }

    /// True when there is no light.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Chooses a light by power from `u` in [0,1): (light index, its probability, `u` rescaled
    /// to [0,1) for reuse).
    #[inline]
    pub fn pick(&self, u: f32) -> (usize, f32, f32) {
        let k = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.lights.len() - 1);
        let lo = if k == 0 { 0.0 } else { self.cdf[k - 1] };
        let p = self.probability(k);
        (k, p, ((u - lo) / p).clamp(0.0, 1.0 - f32::EPSILON))
    }
}

/// Radiance arriving from a light sample `y` (normal `ny`, radiance `le`) at `x` (normal `nx`),
/// times the geometry term, per unit area of the light: `le · cos θx · |cos θy| / d²` (zero
/// when the light is behind `x`'s surface).
#[inline]
pub fn geometry_term(x: Vec3, nx: Vec3, y: Vec3, ny: Vec3, le: Vec3) -> Vec3 {
    let d = y - x;
    let d2 = d.length_squared().max(1e-30);
    let w = d / d2.sqrt();
    let cx = nx.dot(w);
    if cx <= 0.0 {
        return Vec3::ZERO;
    }
    le * (cx * ny.dot(w).abs() / d2)
}

/// The power heuristic (β = 2) weight of a strategy of density `a` against one of density `b`
/// (Veach 1997): `a² / (a² + b²)`; 1 when `b` is zero, 0 when `a` is.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if b2 == 0.0 {
        1.0
    } else if !a2.is_finite() {
        if b2.is_finite() {
            1.0
        } else {
            0.5
        }
    } else {
        a2 / (a2 + b2)
    }
}

/// A shadow ray from `o` to `y`: direction `y − o` (the light at t = 1), ending just short of it
/// (`tmax = 1 − 1e-4`) so the light's own triangle does not block it.
#[inline]
pub fn shadow_ray(o: Vec3, y: Vec3) -> crate::rays::Ray {
    crate::rays::Ray {
        origin: o,
        dir: y - o,
        tmin: 0.0,
        tmax: 1.0 - 1e-4,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_weights_sum_to_one() {
        for (a, b) in [(1.0f32, 1.0f32), (0.3, 80.0), (5.0, 0.01), (1e-20, 1e-20)] {
            let s = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((s - 1.0).abs() < 1e-6, "{a} {b}: {s}");
        }
        assert_eq!(power_heuristic(f32::INFINITY, 2.0), 1.0);
        assert_eq!(power_heuristic(2.0, f32::INFINITY), 0.0);
        assert_eq!(power_heuristic(2.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 2.0), 0.0);
    }

    #[test]
    fn samples_cover_the_light_uniformly() {
        let l = AreaLight::square(Vec3::new(0.0, 2.0, 0.0), 2.0, 10.0, "--area-light").unwrap();
        assert!((l.area - 4.0).abs() < 1e-6);
        assert!((l.power() - 10.0).abs() < 1e-4);
        let (mut sum, n) = (Vec3::ZERO, 64);
        let mut quadrant = [0u32; 4];
        for i in 0..n {
            for j in 0..n {
                let (p, nn) = l.sample((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                assert!((p.y - 2.0).abs() < 1e-6 && p.x.abs() <= 1.0 && p.z.abs() <= 1.0);
                assert!((nn.y.abs() - 1.0).abs() < 1e-6);
                sum += p;
                quadrant[(p.x > 0.0) as usize * 2 + (p.z > 0.0) as usize] += 1;
            }
        }
        let mean = sum / (n * n) as f32;
        assert!(mean.x.abs() < 0.02 && mean.z.abs() < 0.02, "{mean}");
        for q in quadrant {
            assert!(
                (q as f32 / (n * n) as f32 - 0.25).abs() < 0.02,
                "{quadrant:?}"
            );
        }
        let e = AreaLight::square(Vec3::ZERO, 0.0, 1.0, "--area-light").unwrap_err();
        assert!(e.to_string().contains("zero area"));
        let e = AreaLight::square(Vec3::ZERO, 1.0, -1.0, "--area-light").unwrap_err();
        assert!(e.to_string().contains("non-negative"));
    }
}
