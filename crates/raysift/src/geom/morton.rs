//! 30-bit Morton codes (10 bits per axis, x in bits 0, 3, 6, …, y in 1, 4, …, z in 2, 5, …):
//! the spatial orders of the sphere hierarchy's leaves, `dacrt`'s shadow packets and
//! `dacrt5d`'s kept levels.

use glam::Vec3;

/// `x`'s low 10 bits spread to every third bit.
#[inline(always)]
pub fn spread10(x: u32) -> u64 {
    let mut x = (x & 0x3ff) as u64;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    (x | (x << 2)) & 0x0924_9249
}

/// The code of `p` in the grid of 1024³ cells over the box from `lo` with `scale` = 1024 / extent
/// per axis (points outside, and NaN, are clamped into it).
#[inline(always)]
pub fn code30(p: Vec3, lo: Vec3, scale: Vec3) -> u64 {
    let q = ((p - lo) * scale).clamp(Vec3::ZERO, Vec3::splat(1023.0));
    spread10(q.x as u32) | (spread10(q.y as u32) << 1) | (spread10(q.z as u32) << 2)
}

/// The scale [`code30`] takes for a box of `extent` (flat axes get every point in cell 0).
pub fn scale_for(extent: Vec3) -> Vec3 {
    Vec3::splat(1024.0) / extent.max(Vec3::splat(f32::MIN_POSITIVE))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_interleave_by_axis() {
        assert_eq!(spread10(0b1011), 0b1_000_001_001);
        assert_eq!(spread10(0x3ff).count_ones(), 10);
        let (lo, s) = (Vec3::ZERO, scale_for(Vec3::ONE));
        assert_eq!(code30(Vec3::new(0.5, 0.0, 0.0), lo, s), 1 << 27);
        assert_eq!(code30(Vec3::new(0.0, 0.5, 0.0), lo, s), 1 << 28);
        assert_eq!(code30(Vec3::new(0.0, 0.0, 0.5), lo, s), 1 << 29);
        assert_eq!(code30(Vec3::ONE, lo, s), (1 << 30) - 1);
        assert_eq!(code30(Vec3::splat(f32::NAN), lo, s), 0);
        // Order along one axis is kept.
        let xs = [0.0, 0.1, 0.2, 0.7, 0.99];
        let c: Vec<u64> = xs
            .iter()
            .map(|&x| code30(Vec3::new(x, 0.3, 0.6), lo, s))
            .collect();
        assert!(c.windows(2).all(|w| w[0] < w[1]), "{c:?}");
    }
}
