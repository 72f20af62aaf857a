//! The split plane (§3.6, Fig. 5): the cell's longest axis at the mean of sampled triangle
//! midpoints, or at the spatial median.

use super::{Config, Task};
use crate::geom::Aabb;

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// §3.6: the split axis and position, or `None` when the cell cannot be split.
    pub(super) fn choose_split(&self, cell: &Aabb, nt: usize) -> Option<(usize, f32)> {
        choose_split(self.cfg, self.span, &self.tri_idx[..nt], cell)
    }
}

/// §3.6 for the triangles `ids` in `cell` (the task's recursion and the top tree's build).
pub(super) fn choose_split(
    cfg: &Config,
    span: [&[[f32; 2]]; 3],
    ids: &[u32],
    cell: &Aabb,
) -> Option<(usize, f32)> {
    let axis = cell.longest_axis();
    let (mn, mx) = (cell.min[axis], cell.max[axis]);
    let median = mn + (mx - mn) * 0.5;
    let mut s = median;
    let stride = cfg.split_sample_stride.max(1);
    if ids.len() >= cfg.split_sample_threshold {
        let span = span[axis];
        let (mut sum, mut n) = (0.0f64, 0u32);
        for &t in ids.iter().step_by(stride) {
            let [l, h] = span[t as usize];
            if l <= h {
                sum += 0.5 * (l.clamp(mn, mx) as f64 + h.clamp(mn, mx) as f64);
                n += 1;
            }
        }
        if n > 0 {
            s = (sum / n as f64) as f32;
        }
    }
    if !(s > mn && s < mx) {
        s = median;
    }
    (s > mn && s < mx).then_some((axis, s))
}

/// The low or high half of `cell` at `split` on `axis` (both closed, sharing the plane).
#[inline]
pub(super) fn half(cell: &Aabb, axis: usize, split: f32, low: bool) -> Aabb {
    let mut c = *cell;
    if low {
        c.max[axis] = split;
    } else {
        c.min[axis] = split;
    }
    c
}

/// True when a split makes too little progress to pay: the first child keeps `nt0` of the
/// cell's `nt` triangles and the second `nt1` (`partition_tris`' second result), and more than
/// nine in ten of the triangles are in both (they straddle the plane), so a ray in both children
/// tests them twice. §3.6's guard stops only when every triangle straddles; fans of needles
/// around a shared vertex (the soak's `fan` class) then recursed to the depth limit testing 3.8×
/// naive's pairs (a 508-triangle fan, 2000 rays: 112 ms against naive's 30); with this guard,
/// one leaf (BENCHMARKS.md, § The exact contract).
#[inline]
pub(super) fn no_progress(nt: usize, nt0: usize, nt1: usize) -> bool {
    (nt0 + nt1).saturating_sub(nt) * 10 > nt * 9
}
