//! The pinhole camera and its exact convention (README, "Camera"):
//!
//! fov is vertical in degrees; `forward = normalize(look − eye)`, `right = normalize(forward × up)`,
//! `up' = right × forward`; for pixel column `i` (left to right) and row `j` (top to bottom) of a
//! W×H image, `x = (2(i+0.5)/W − 1)·tan(fov/2)·W/H`, `y = (1 − 2(j+0.5)/H)·tan(fov/2)`,
//! `direction = normalize(x·right + y·up' + forward)`; rays are ordered `j·W + i`, `tmin = 0`,
//! `tmax = +inf`.

use super::{RayBatch, RayLayout};
use crate::error::{Error, Result};
use crate::geom::Aabb;
use glam::Vec3;
use rayon::prelude::*;

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub look: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_deg: f32,
}

impl Camera {
    /// Default vertical field of view (degrees).
    pub const DEFAULT_FOV: f32 = 45.0;

    /// The default framing for a scene: look at the centre of `bounds` from a point on the +z axis
    /// through that centre, at the smallest distance where all eight corners of the box are inside
    /// both fields of view (plus 2%), so the bounds fill the view; up = +y.
    pub fn framing(bounds: &Aabb, fov_deg: f32, aspect: f32) -> Self {
        let (center, half) = if bounds.is_empty() {
            (Vec3::ZERO, Vec3::ONE)
        } else {
            (
                bounds.center(),
                (bounds.extent() * 0.5).max(Vec3::splat(1e-6)),
            )
        };
        let tan_v = (fov_deg.to_radians() * 0.5).clamp(1e-3, 1.5).tan();
        let tan_h = tan_v * aspect;
        // A corner at lateral offset x and depth offset z is inside when x / (dist − z) <= tan.
        let dist = half.z + (half.x / tan_h).max(half.y / tan_v) * 1.02;
        Self {
            eye: center + Vec3::Z * dist,
            look: center,
            up: Vec3::Y,
            fov_deg,
        }
    }

    /// Checks the camera is usable: finite, eye ≠ look, up not parallel to the view, 0 < fov < 180.
    pub fn validate(&self) -> Result<()> {
        let f = self.look - self.eye;
        let ok = self.eye.is_finite()
            && self.look.is_finite()
            && self.up.is_finite()
            && f.length_squared() > 0.0;
        if !ok {
            return Err(Error::Invalid(
                "camera: eye and look must be finite and distinct".into(),
            ));
        }
        if f.normalize().cross(self.up).length_squared() < 1e-12 {
            return Err(Error::Invalid(
                "camera: up must not be parallel to look − eye".into(),
            ));
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(Error::Invalid(format!(
                "camera: fov must be in (0, 180) degrees, got {}",
                self.fov_deg
            )));
        }
        Ok(())
    }

    /// The orthonormal basis `(right, up', forward)`.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.look - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        (right, up, forward)
    }

    /// Direction of the ray through pixel `(i, j)` of a `w × h` image.
    #[inline]
    pub fn direction(&self, basis: (Vec3, Vec3, Vec3), i: u32, j: u32, w: u32, h: u32) -> Vec3 {
        let (right, up, forward) = basis;
        let tan = (self.fov_deg.to_radians() * 0.5).tan();
        let x = (2.0 * (i as f32 + 0.5) / w as f32 - 1.0) * tan * w as f32 / h as f32;
        let y = (1.0 - 2.0 * (j as f32 + 0.5) / h as f32) * tan;
        (x * right + y * up + forward).normalize()
    }

    /// `a × a` stratified samples per pixel of a `w × h` image, each jittered in its stratum
    /// (seeded), pixel-major (ray `(j·w + i)·a² + s`, `s = sy·a + sx`), laid out as
    /// `PixelSamples` (`a = 1`: one jittered ray per pixel, `Pinhole`).
    pub fn sample_rays(&self, w: u32, h: u32, a: u32, seed: u64) -> RayBatch {
        use rand::{Rng, SeedableRng};
        let (right, up, fwd) = self.basis();
        let tan = (self.fov_deg.to_radians() * 0.5).tan();
        let (wf, hf) = (w as f32, h as f32);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let n = (w * h * a * a) as usize;
        let mut b = RayBatch::with_capacity(n);
        for j in 0..h {
            for i in 0..w {
                for s in 0..a * a {
                    let x = i as f32 + ((s % a) as f32 + rng.gen::<f32>()) / a as f32;
                    let y = j as f32 + ((s / a) as f32 + rng.gen::<f32>()) / a as f32;
                    let px = (2.0 * x / wf - 1.0) * tan * wf / hf;
                    let py = (1.0 - 2.0 * y / hf) * tan;
                    b.push(crate::rays::Ray {
                        origin: self.eye,
                        dir: (px * right + py * up + fwd).normalize(),
                        tmin: 0.0,
                        tmax: f32::INFINITY,
                    });
                }
            }
        }
        b.layout = if a == 1 {
            RayLayout::Pinhole {
                eye: self.eye,
                width: w,
                height: h,
            }
        } else {
            RayLayout::PixelSamples {
                eye: self.eye,
                width: w,
                height: h,
                samples: a * a,
            }
        };
        b
    }

    /// All primary rays of a `w × h` image, ordered `j·w + i`.
    pub fn rays(&self, w: u32, h: u32) -> RayBatch {
        let n = w as usize * h as usize;
        let basis = self.basis();
        let dirs: Vec<Vec3> = (0..n)
            .into_par_iter()
            .map(|k| self.direction(basis, k as u32 % w, k as u32 / w, w, h))
            .collect();
        let mut b = RayBatch::with_capacity(n);
        for d in dirs {
            b.ox.push(self.eye.x);
            b.oy.push(self.eye.y);
            b.oz.push(self.eye.z);
            b.dx.push(d.x);
            b.dy.push(d.y);
            b.dz.push(d.z);
        }
        b.tmin.resize(n, 0.0);
        b.tmax.resize(n, f32::INFINITY);
        b.layout = RayLayout::Pinhole {
            eye: self.eye,
            width: w,
            height: h,
        };
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-6
    }

    #[test]
    fn corner_pixels_follow_the_convention() {
        // Looking down -z with up +y: right = +x, up' = +y.
        let c = Camera {
            eye: Vec3::ZERO,
            look: -Vec3::Z,
            up: Vec3::Y,
            fov_deg: 90.0,
        };
        let (w, h) = (4, 2);
        let rays = c.rays(w, h);
        assert_eq!(rays.len(), 8);
        // tan(45°) = 1, aspect 2: pixel (0,0): x = (2·0.5/4 − 1)·2 = −1.5, y = (1 − 2·0.5/2) = 0.5.
        assert!(close(rays.dir(0), Vec3::new(-1.5, 0.5, -1.0).normalize()));
        // Last pixel of the first row (i = 3, j = 0): x = +1.5.
        assert!(close(rays.dir(3), Vec3::new(1.5, 0.5, -1.0).normalize()));
        // First pixel of the last row (i = 0, j = 1): y = −0.5.
        assert!(close(rays.dir(4), Vec3::new(-1.5, -0.5, -1.0).normalize()));
        assert!(close(rays.dir(7), Vec3::new(1.5, -0.5, -1.0).normalize()));
        assert_eq!(rays.origin(5), Vec3::ZERO);
        assert_eq!((rays.tmin[2], rays.tmax[2]), (0.0, f32::INFINITY));
        assert_eq!(
            rays.layout,
            RayLayout::Pinhole {
                eye: Vec3::ZERO,
                width: 4,
                height: 2
            }
        );
    }

    #[test]
    fn basis_is_right_handed_with_up_prime() {
        let c = Camera {
            eye: Vec3::new(0.0, 0.0, 5.0),
            look: Vec3::ZERO,
            up: Vec3::new(0.0, 1.0, 0.3),
            fov_deg: 45.0,
        };
        let (r, u, f) = c.basis();
        assert!(close(f, -Vec3::Z));
        assert!(close(r, Vec3::X));
        assert!(close(u, Vec3::Y));
    }

    #[test]
    fn framing_sees_the_whole_box() {
        let b = Aabb::new(Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 1.0, 0.0));
        let c = Camera::framing(&b, 45.0, 1.5);
        assert!(close(c.look, b.center()));
        assert!(c.eye.z > b.max.z);
        let (r, u, f) = c.basis();
        let tan_v = (22.5f32).to_radians().tan();
        for k in 0..8 {
            let d = b.corner(k) - c.eye;
            let z = d.dot(f);
            assert!(z > 0.0);
            assert!((d.dot(u) / z).abs() <= tan_v * 1.0001);
            assert!((d.dot(r) / z).abs() <= tan_v * 1.5 * 1.0001);
        }
        assert!(c.validate().is_ok());
        let bad = Camera { up: Vec3::Z, ..c };
        assert!(bad.validate().is_err());
    }
}
