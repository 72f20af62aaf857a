//! Packets (§3.3): how a task's rays map to packets of 64 (8×8 pinhole tiles, or runs of
//! shadow rays in a Morton order of their origins) and the 64-byte packed cone of each.

use crate::geom::{Aabb, ConeQuery};
use crate::mem::reserve_exact_huge;
use crate::rays::RayBatch;
use glam::Vec3;
use std::ops::Range;

/// Bytes per conic packet: the cone and its index in the cone list.
pub(super) const CONE_BYTES: usize = std::mem::size_of::<PackedCone>() + 4;
const _: () = assert!(
    CONE_BYTES == 68,
    "the memory formula in the module doc says 68"
);

/// One conic packet: 64 bytes.
#[derive(Clone, Copy, Debug)]
pub(super) struct PackedCone {
    /// The cone, prepared for box tests (f64 unit axis, cos² of the half-angle, cos and sin:
    /// f32 cannot resolve the angular margin near 1). Near radius: boxes this close to the apex
    /// count as hit (shadow cones; 0 for camera cones). Reach: the packet's rays lie within this
    /// distance of the apex (shadow cones: their origins; +inf for camera cones).
    pub(super) q: ConeQuery,
    /// Termination bits, one per ray of the packet.
    pub(super) done: u64,
}

/// How the rays of a task map to packets.
#[derive(Clone, Copy, Debug)]
pub(super) enum Packets {
    /// No packets.
    None,
    /// Pinhole band: `width` pixels per row, `rows` rows, 8×8 tiles, `tw` tiles per row.
    Tiles {
        width: usize,
        rows: usize,
        tw: usize,
    },
    /// Shadow rays: 64 consecutive rays per cone.
    Runs { len: usize },
}

impl Packets {
    pub(super) fn count(&self) -> usize {
        match *self {
            Packets::None => 0,
            Packets::Tiles { rows, tw, .. } => tw * rows.div_ceil(8),
            Packets::Runs { len } => len.div_ceil(64),
        }
    }

    /// Local ray `k` → (packet, bit). `perm` is the shadow-ray order (see
    /// [`Task::perm`](super::Task::perm)).
    #[inline]
    pub(super) fn of(&self, k: usize, perm: &[u64]) -> (usize, u32) {
        match *self {
            Packets::None => (0, 0),
            Packets::Tiles { width, tw, .. } => {
                let (y, x) = (k / width, k % width);
                ((y / 8) * tw + x / 8, ((y % 8) * 8 + x % 8) as u32)
            }
            Packets::Runs { .. } => {
                let j = (perm[k] >> 32) as usize;
                (j / 64, (j % 64) as u32)
            }
        }
    }

    /// Calls `f(k, bit)` for every ray of packet `c`.
    #[inline]
    pub(super) fn for_each(&self, c: usize, perm: &[u64], mut f: impl FnMut(usize, u32)) {
        match *self {
            Packets::None => {}
            Packets::Tiles { width, rows, tw } => {
                let (ty, tx) = (c / tw, c % tw);
                for y in ty * 8..(ty * 8 + 8).min(rows) {
                    for x in tx * 8..(tx * 8 + 8).min(width) {
                        f(y * width + x, ((y % 8) * 8 + x % 8) as u32);
                    }
                }
            }
            Packets::Runs { len } => {
                let (a, b) = (c * 64, (c * 64 + 64).min(len));
                for (bit, &e) in perm[a..b].iter().enumerate() {
                    f(e as u32 as usize, bit as u32);
                }
            }
        }
    }

    /// Bits of the rays packet `c` has (closed form of the bits [`Self::for_each`] visits).
    pub(super) fn full_mask(&self, c: usize, _perm: &[u64]) -> u64 {
        let low = |n: usize| if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        match *self {
            Packets::None => 0,
            Packets::Tiles { width, rows, tw } => {
                let (ty, tx) = (c / tw, c % tw);
                let (w, h) = ((width - tx * 8).min(8), (rows - ty * 8).min(8));
                // `w` low bits in each of the first `h` bytes.
                low(w) * (low(8 * h) / 0xff)
            }
            Packets::Runs { len } => low(len.min(c * 64 + 64) - c * 64),
        }
    }
}

/// The shadow-packet order of rays `range` (see [`Task::perm`](super::Task::perm)): sorted by a
/// 30-bit Morton code of the origin in `bounds` (in place, no further allocation), then each
/// entry's high half is overwritten with the inverse permutation.
pub(super) fn morton_order(
    mut v: Vec<u64>,
    rays: &RayBatch,
    range: Range<usize>,
    bounds: &Aabb,
    huge: bool,
) -> Vec<u64> {
    use crate::geom::morton::spread10 as spread;
    let scale = Vec3::splat(1023.0) / bounds.extent().max(Vec3::splat(f32::MIN_POSITIVE));
    reserve_exact_huge(&mut v, range.len(), huge);
    v.extend(range.clone().enumerate().map(|(k, i)| {
        let q = ((rays.origin(i) - bounds.min) * scale).clamp(Vec3::ZERO, Vec3::splat(1023.0));
        let code = spread(q.x as u32) | spread(q.y as u32) << 1 | spread(q.z as u32) << 2;
        code << 32 | k as u64
    }));
    v.sort_unstable();
    for j in 0..v.len() {
        let k = v[j] as u32 as usize;
        v[k] = (v[k] & 0xffff_ffff) | (j as u64) << 32;
    }
    v
}

/// The bits (`8·row + column`) of tile `(tx, ty)` inside the inclusive pixel rectangle
/// `[x0, x1] × [y0, y1]`.
#[inline]
pub(super) fn tile_mask(tx: usize, ty: usize, [x0, x1, y0, y1]: [i64; 4]) -> u64 {
    let low = |n: i64| if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
    let (bx, by) = (tx as i64 * 8, ty as i64 * 8);
    // Half-open column and row ranges inside the tile.
    let (c0, c1) = ((x0 - bx).clamp(0, 8), (x1 - bx + 1).clamp(0, 8));
    let (r0, r1) = ((y0 - by).clamp(0, 8), (y1 - by + 1).clamp(0, 8));
    if c0 >= c1 || r0 >= r1 {
        return 0;
    }
    let cols = low(c1) & !low(c0);
    // One 0x01 byte per row of the range.
    let rows = (low(8 * r1) & !low(8 * r0)) / 0xff;
    cols * rows
}

/// Calls `f(k, j)` for every pixel of a `width × rows` band: `k` its index in the band (row
/// by row), `j` its slot in tile order (`64·tile + bit`, as [`Packets::of`]).
#[inline]
pub(super) fn for_each_tile_slot(width: usize, rows: usize, mut f: impl FnMut(usize, usize)) {
    let tw = width.div_ceil(8);
    for y in 0..rows {
        let row = (y / 8) * tw * 64 + (y % 8) * 8;
        for x in 0..width {
            f(y * width + x, row + (x / 8) * 64 + x % 8);
        }
    }
}
