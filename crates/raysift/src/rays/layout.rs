//! Ray-group layouts: how a batch's rays were made, recognised from the rays themselves.
//!
//! A layout is a hint for tracers that exploit coherent groups (DACRT's conic packets and tile
//! leaves for pinhole images, ray-planes and shafts for rays from one origin through a grid);
//! every tracer that uses one validates what it relies on, so a wrong hint can cost speed but
//! never change an answer. Generators set the hint ([`crate::rays::Camera::rays`],
//! [`crate::rays::generate::shadow_rays`], the renderers); [`RayBatch::detect_layout`] recovers it
//! for batches that come without one (files, numpy arrays), whatever their array shape, so a
//! flat `(N, 8)` array of camera rays is traced as fast as the same rays image-shaped.

use super::RayBatch;
use glam::Vec3;

/// How a batch was generated: a hint tracers may exploit, never a promise they rely on for
/// correctness.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum RayLayout {
    /// Nothing known.
    #[default]
    Unknown,
    /// Pinhole camera rays from `eye`, one per pixel (exact or jittered inside it), ordered
    /// `j·width + i` (pixel row j from the top, column i from the left).
    Pinhole {
        /// Common origin.
        eye: Vec3,
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
    },
    /// Several rays per pixel from `eye` (antialiasing: `samples` = a×a stratified or jittered
    /// subpixel samples), pixel-major: ray `(j·width + i)·samples + s` is sample `s` of pixel
    /// (i, j).
    PixelSamples {
        /// Common origin.
        eye: Vec3,
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
        /// Rays per pixel.
        samples: u32,
    },
    /// Consecutive groups of `side × side` rays, each group from one origin through a regular
    /// grid of directions, row-major inside the group: an area light's N×N shadow samples from
    /// one hit point, or an N×N hemisphere grid (the groups RTRPS's ray-planes and shafts use).
    OriginGrids {
        /// Rays per grid row (and rows per group).
        side: u32,
    },
    /// Rays from surface points towards one point (shadow rays to a point light), each ending at
    /// `t = 1` on that point.
    ToPoint {
        /// The common end point.
        target: Vec3,
    },
}

/// Largest `a` of `a × a` pixel samples recognised.
const MAX_SAMPLE_SIDE: usize = 8;

impl RayBatch {
    /// Recovers a layout hint from the rays themselves (for batches read from files, which carry
    /// no hint): `image` = `(width, height)` when the batch came as an image-shaped array.
    ///
    /// - `Pinhole`: every ray starts at one point with `tmin >= 0`, and the batch is
    ///   image-shaped, or its directions, projected onto the view plane, run in rows: steady
    ///   steps along a row and one long jump back at every row's end, rows stepping down evenly.
    /// - `PixelSamples`: the same rows, where groups of a² consecutive rays (a = 2..8) move on
    ///   steadily and single rays do not (pixel-major subpixel samples).
    /// - `OriginGrids`: groups of side² rays (side ≥ 2), each from one origin, at least two
    ///   groups, the first group's directions in side rows as above.
    /// - `ToPoint`: every ray is a segment (`0 <= tmin`, `tmax <= 1`) whose end `o + d` is one
    ///   point up to f32 rounding (relative `2^-16`), as the shadow-ray generator makes them.
    ///
    /// A few passes over the batch; tracers validate what they exploit.
    pub fn detect_layout(&self, image: Option<(u32, u32)>) -> RayLayout {
        let n = self.len();
        if n == 0 {
            return RayLayout::Unknown;
        }
        let eye = self.origin(0);
        let same = |i: usize| self.ox[i] == eye.x && self.oy[i] == eye.y && self.oz[i] == eye.z;
        let one_origin = (0..n).all(|i| same(i) && self.tmin[i] >= 0.0);
        if one_origin {
            if let Some((width, height)) = image {
                if width as usize * height as usize == n {
                    return RayLayout::Pinhole { eye, width, height };
                }
            }
            if let Some(l) = self.pinhole_like(0..n) {
                return l;
            }
        } else if let Some(l) = self.origin_grids() {
            return l;
        }
        if let Some(target) = self.common_end() {
            return RayLayout::ToPoint { target };
        }
        RayLayout::Unknown
    }

    fn common_end(&self) -> Option<Vec3> {
        let target = self.origin(0) + self.dir(0);
        let ends_at_target = |i: usize| {
            let (o, d) = (self.origin(i), self.dir(i));
            let scale = o.abs().max(d.abs()).max(target.abs()).max_element();
            self.tmin[i] >= 0.0
                && self.tmax[i] <= 1.0
                && ((o + d) - target).abs().max_element() <= scale * (1.0 / 65536.0)
        };
        (target.is_finite() && (0..self.len()).all(ends_at_target)).then_some(target)
    }

    /// Rays `range` (one origin) as a pinhole image or pixel samples, if their directions run
    /// in rows.
    fn pinhole_like(&self, range: std::ops::Range<usize>) -> Option<RayLayout> {
        let eye = self.origin(range.start);
        let (rows, len) = self.rows(range.clone())?;
        let n = range.len();
        for a in 1..=MAX_SAMPLE_SIDE {
            let s = a * a;
            if len % s != 0 || len / s < 2 {
                continue;
            }
            if self.groups_advance(range.start, len, s) {
                let (width, height) = ((len / s) as u32, rows as u32);
                debug_assert_eq!(width as usize * height as usize * s, n);
                return Some(if s == 1 {
                    RayLayout::Pinhole { eye, width, height }
                } else {
                    RayLayout::PixelSamples {
                        eye,
                        width,
                        height,
                        samples: s as u32,
                    }
                });
            }
        }
        None
    }

    /// Unit direction of ray `i` (`None` for a zero or non-finite direction).
    fn unit(&self, i: usize) -> Option<Vec3> {
        let d = self.dir(i);
        let l = d.length();
        (l > 0.0 && l.is_finite()).then(|| d / l)
    }

    /// Splits rays `range` into rows of equal length by the view-plane positions of their
    /// directions: returns (rows, rays per row) when there are at least 2 rows of at least 4
    /// rays, every row's steps are short, every row ends in a long jump back, and the rows step
    /// evenly.
    fn rows(&self, range: std::ops::Range<usize>) -> Option<(usize, usize)> {
        let (first, last) = (range.start, range.end - 1);
        let n = range.len();
        let (d0, d1) = (self.unit(first)?, self.unit(last)?);
        let f = (d0 + d1).normalize_or_zero();
        if f == Vec3::ZERO {
            return None;
        }
        // Position on the plane one unit along f (central projection, as the image plane).
        let proj = |i: usize| -> Option<Vec3> {
            let d = self.unit(i)?;
            let z = d.dot(f);
            (z > 1e-3).then(|| d / z - f)
        };
        // Row length: the row ends are the longest steps (a jump back across the image), so
        // the first step over half the longest one ends the first row.
        let mut longest = 0.0f32;
        let mut prev = proj(first)?;
        for k in 1..n {
            let p = proj(first + k)?;
            longest = longest.max((p - prev).length());
            prev = p;
        }
        let mut prev = proj(first)?;
        for k in 1..n {
            let p = proj(first + k)?;
            if (p - prev).length() > 0.5 * longest {
                return self.verify_rows(first, n, k, &proj);
            }
            prev = p;
        }
        None
    }

    /// Checks that `n` rays from `first` run in rows of `len`: short steps inside every row, a
    /// long jump back at every row's end, every row start advancing the same way.
    fn verify_rows(
        &self,
        first: usize,
        n: usize,
        len: usize,
        proj: &impl Fn(usize) -> Option<Vec3>,
    ) -> Option<(usize, usize)> {
        if len < 4 || !n.is_multiple_of(len) || n / len < 2 {
            return None;
        }
        let rows = n / len;
        let mut max_inside = 0.0f32;
        let mut min_jump = f32::INFINITY;
        // The mean advance from one row's start to the next; each advance must go its way
        // (rays jittered inside their pixels keep that sign).
        let down = (proj(first + n - len)? - proj(first)?) / (rows - 1) as f32;
        let mut prev = proj(first)?;
        for k in 1..n {
            let p = proj(first + k)?;
            let step = (p - prev).length();
            if k % len == 0 {
                min_jump = min_jump.min(step);
                let adv = p - proj(first + k - len)?;
                if adv.dot(down) <= 0.0 {
                    return None;
                }
            } else {
                max_inside = max_inside.max(step);
            }
            prev = p;
        }
        (min_jump > 2.0 * max_inside && down.length() > 0.0).then_some((rows, len))
    }

    /// True when, along the first row of `len` rays from `start`, the means of groups of `s`
    /// consecutive rays move strictly forward, and for `s > 1` steadily (no step over three
    /// times another: groups that straddle pixels move unevenly).
    fn groups_advance(&self, start: usize, len: usize, s: usize) -> bool {
        let (Some(a), Some(b)) = (self.unit(start), self.unit(start + len - 1)) else {
            return false;
        };
        let axis = b - a;
        let mean = |g: usize| -> f32 {
            (0..s)
                .map(|k| self.dir(start + g * s + k).normalize_or_zero().dot(axis))
                .sum::<f32>()
                / s as f32
        };
        let mut prev = mean(0);
        let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
        for g in 1..len / s {
            let m = mean(g);
            if m <= prev {
                return false;
            }
            (lo, hi) = (lo.min(m - prev), hi.max(m - prev));
            prev = m;
        }
        s == 1 || hi <= 3.0 * lo
    }

    /// Groups of side² rays sharing an origin, at least two, the first a side × side grid.
    fn origin_grids(&self) -> Option<RayLayout> {
        let n = self.len();
        let o0 = self.origin(0);
        let g = (1..n).find(|&i| self.origin(i) != o0)?;
        let side = (g as f64).sqrt().round() as usize;
        if side < 2 || side * side != g || !n.is_multiple_of(g) || n / g < 2 {
            return None;
        }
        for start in (0..n).step_by(g) {
            let o = self.origin(start);
            if (start..start + g).any(|i| self.origin(i) != o) {
                return None;
            }
        }
        let (rows, len) = self.rows(0..g)?;
        (rows == side && len == side).then_some(RayLayout::OriginGrids { side: side as u32 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rays::{Camera, Ray};
    use rand::{Rng, SeedableRng};

    fn cam() -> Camera {
        Camera {
            eye: Vec3::new(0.3, -0.2, 4.0),
            look: Vec3::new(0.1, 0.2, 0.0),
            up: Vec3::Y,
            fov_deg: 50.0,
        }
    }

    fn flat(mut b: RayBatch) -> RayBatch {
        b.layout = RayLayout::Unknown;
        b
    }

    #[test]
    fn flat_camera_rays_are_a_pinhole_image() {
        for (w, h) in [(64, 48), (7, 5), (4, 2), (300, 4), (5, 300)] {
            let rays = cam().rays(w, h);
            let want = rays.layout;
            assert_eq!(flat(rays).detect_layout(None), want, "{w}x{h}");
        }
        // Supersampled images written in row order of the fine grid are images too.
        let fine = cam().rays(128, 96);
        assert_eq!(flat(fine.clone()).detect_layout(None), fine.layout);
    }

    #[test]
    fn jittered_and_multisampled_camera_rays() {
        let c = cam();
        let (w, h) = (40u32, 30u32);
        let (right, up, fwd) = c.basis();
        let tan = (c.fov_deg.to_radians() * 0.5).tan();
        let dir = |x: f32, y: f32| {
            let px = (2.0 * x / w as f32 - 1.0) * tan * w as f32 / h as f32;
            let py = (1.0 - 2.0 * y / h as f32) * tan;
            (px * right + py * up + fwd).normalize()
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
        let ray = |d| Ray {
            origin: c.eye,
            dir: d,
            tmin: 0.0,
            tmax: f32::INFINITY,
        };
        // One jittered ray per pixel.
        let jit = RayBatch::from_rays((0..w * h).map(|k| {
            let (i, j) = ((k % w) as f32, (k / w) as f32);
            ray(dir(i + rng.gen::<f32>(), j + rng.gen::<f32>()))
        }));
        assert_eq!(
            jit.detect_layout(None),
            RayLayout::Pinhole {
                eye: c.eye,
                width: w,
                height: h
            }
        );
        // a×a stratified samples per pixel, pixel-major, jittered in their strata.
        for a in [2u32, 3, 4] {
            let b = RayBatch::from_rays((0..w * h).flat_map(|k| {
                {
                    let (i, j) = ((k % w) as f32, (k / w) as f32);
                    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(k as u64);
                    (0..a * a)
                        .map(move |s| {
                            let (sx, sy) = ((s % a) as f32, (s / a) as f32);
                            let x = i + (sx + rng.gen::<f32>()) / a as f32;
                            let y = j + (sy + rng.gen::<f32>()) / a as f32;
                            (x, y)
                        })
                        .collect::<Vec<_>>()
                }
                .into_iter()
                .map(|(x, y)| ray(dir(x, y)))
            }));
            assert_eq!(
                b.detect_layout(None),
                RayLayout::PixelSamples {
                    eye: c.eye,
                    width: w,
                    height: h,
                    samples: a * a
                },
                "{a}x{a}"
            );
        }
    }

    #[test]
    fn origin_grids_of_light_samples() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(2);
        let side = 8u32;
        let mut b = RayBatch::default();
        for _ in 0..50 {
            let o = Vec3::new(rng.gen(), rng.gen(), rng.gen());
            for j in 0..side {
                for i in 0..side {
                    // Towards the (i, j) sample of a square light at y = 3.
                    let p = Vec3::new(
                        -0.5 + (i as f32 + 0.5) / side as f32,
                        3.0,
                        -0.5 + (j as f32 + 0.5) / side as f32,
                    );
                    b.push(Ray {
                        origin: o,
                        dir: p - o,
                        tmin: 1e-4,
                        tmax: 1.0,
                    });
                }
            }
        }
        assert_eq!(b.detect_layout(None), RayLayout::OriginGrids { side });
    }

    #[test]
    fn what_is_not_a_layout_stays_unknown() {
        let c = cam();
        let exact = flat(c.rays(32, 24));
        // Shuffled among pixels.
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        let mut perm: Vec<usize> = (0..exact.len()).collect();
        for k in (1..perm.len()).rev() {
            perm.swap(k, rng.gen_range(0..=k));
        }
        let shuffled = RayBatch::from_rays(perm.iter().map(|&k| exact.get(k)));
        assert_eq!(shuffled.detect_layout(None), RayLayout::Unknown);
        // Random directions from one point (a point light's photons).
        let photons = RayBatch::from_rays((0..1000).map(|_| Ray {
            origin: Vec3::ZERO,
            dir: Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            ),
            tmin: 0.0,
            tmax: f32::INFINITY,
        }));
        assert_eq!(photons.detect_layout(None), RayLayout::Unknown);
        // Moved origins.
        let mut moved = exact.clone();
        moved.ox[5] += 1.0;
        assert_eq!(moved.detect_layout(None), RayLayout::Unknown);
        // Negative tmin: not from the eye only.
        let mut back = exact.clone();
        back.tmin[0] = -1.0;
        assert_eq!(back.detect_layout(Some((32, 24))), RayLayout::Unknown);
        // A zero direction (refused elsewhere) is not a layout.
        let mut zero = exact;
        zero.dx[7] = 0.0;
        zero.dy[7] = 0.0;
        zero.dz[7] = 0.0;
        assert_eq!(zero.detect_layout(None), RayLayout::Unknown);
        assert_eq!(RayBatch::default().detect_layout(None), RayLayout::Unknown);
    }
}
