//! Triangle streaming (§3.5, Fig. 4): the root triangle list and the in-place partitions of
//! the triangle and ray lists (branch-free Lomuto loops over the min/max lists and the ray
//! records), with the block move that hands the first child's rejects to the second.

use super::ray_rec::RayRec;
use super::Task;
use crate::geom::Aabb;

impl<'a, const ANY: bool> Task<'a, ANY> {
    /// Fills `tri_idx` with the ids of the non-degenerate triangles (degenerate ones have an
    /// empty span and are never hit) and returns their count. Every root list holds only
    /// triangles some box can hold: the second child takes the first child's rejects untested.
    pub(super) fn live_triangles(&mut self) -> usize {
        let span = self.span[0];
        self.tri_idx.clear();
        self.tri_idx.extend(
            span.iter()
                .enumerate()
                .filter(|(_, s)| s[0] <= s[1])
                .map(|(t, _)| t as u32),
        );
        self.tri_idx.len()
    }

    /// In-place filter of `ray_idx[rterm..rend]` against `b` (full slab test, §3.2: no stacked
    /// intervals). Returns the new end.
    ///
    /// Branch-free Lomuto partition: with `[rterm, k)` kept and `[k, p)` rejected, swapping
    /// slots `k` and `p` unconditionally keeps both invariants whatever the test says (a rejected
    /// ray at `p` trades places with a rejected one at `k`, or with itself), so only `k` depends
    /// on the test.
    pub(super) fn partition_rays(&mut self, b: &Aabb, rend: usize) -> usize {
        let start = self.rterm;
        let k = partition_packed(b, &mut self.recs[..rend], &mut self.ray_idx[..rend], start);
        self.st.ray_box += (rend - start) as u64;
        if let Some(c) = self.cost.as_mut() {
            // Every ray in the list was tested; those kept entered the cell.
            for (p, &r) in self.ray_idx[start..rend].iter().enumerate() {
                c.add(r as usize, (start + p < k) as u64, 1, 0);
            }
        }
        k
    }

    /// In-place filter of `tri_idx[..nt]` for the child on side `low` of `split`: the split-plane
    /// test on the min/max lists. Returns the new count and how many of the `nt` triangles the
    /// plane test sends to the other child (the other child's count).
    pub(super) fn partition_tris(
        &mut self,
        nt: usize,
        axis: usize,
        split: f32,
        low: bool,
    ) -> (usize, usize) {
        let (k, other) = partition_tris(self.span[axis], &mut self.tri_idx[..nt], split, low);
        self.st.tri_box += nt as u64;
        (k, other)
    }
}

/// Moves the packed rays of `recs[start..]` (and their `ids`) that [`Aabb::hit_by_packed`] keeps
/// to the front of that range, four decided at once by [`Aabb::hit_by_packed4`] (the same
/// decisions); returns the end of the kept rays. Branch-free Lomuto (see
/// `Task::partition_rays`). `dacrt`'s ray partitions and `dacrt5d`'s shared box splits.
#[inline(always)]
pub(crate) fn partition_packed(
    b: &Aabb,
    recs: &mut [RayRec],
    ids: &mut [u32],
    start: usize,
) -> usize {
    let end = recs.len();
    let (mut k, mut p) = (start, start);
    // Four rays decided at once: the swaps at `p..p + j` touch only slots below `p + j`, so the
    // records decided up front are still the ones each swap moves.
    while p + 4 <= end {
        let four: &[RayRec; 4] = recs[p..p + 4].try_into().expect("four records");
        let keep = b.hit_by_packed4(four);
        for j in 0..4 {
            recs.swap(k, p + j);
            ids.swap(k, p + j);
            k += (keep >> j & 1) as usize;
        }
        p += 4;
    }
    for p in p..end {
        let keep = b.hit_by_packed(&recs[p]);
        recs.swap(k, p);
        ids.swap(k, p);
        k += keep as usize;
    }
    k
}

/// The split-plane filter of `idx` for the child on side `low` of `split` (`span`: the axis'
/// min/max list), as a branch-free Lomuto partition (see `Task::partition_rays`: the
/// unconditional swap keeps `[0, k)` kept, `[k, p)` dropped). Returns the kept count and how
/// many of the triangles the plane test sends to the other child.
pub(super) fn partition_tris(
    span: &[[f32; 2]],
    idx: &mut [u32],
    split: f32,
    low: bool,
) -> (usize, usize) {
    let mut k = 0;
    let mut other = 0;
    for p in 0..idx.len() {
        if let Some(&f) = idx.get(p + SPLIT_PREFETCH) {
            prefetch(span, f as usize);
        }
        let t = idx[p] as usize;
        let [l, h] = span[t];
        let (inside, opposite) = if low {
            (l <= split, h >= split)
        } else {
            (h >= split, l <= split)
        };
        other += opposite as usize;
        idx.swap(k, p);
        k += inside as usize;
    }
    (k, other)
}

/// How many triangles ahead the list loops prefetch their scattered data.
pub(super) const PREFETCH: usize = 16;

/// The same distance for the split-plane filter, whose loop is a few cycles per triangle: the
/// gathered bounds must be asked for further ahead (at 16 ahead the filter waited on them;
/// measured in BENCHMARKS.md, § DACRT design measurements).
const SPLIT_PREFETCH: usize = 128;

/// Hints the CPU to bring `v[i]` into the cache: the triangle lists are walked in order but
/// the data of their triangles is scattered (prefetching [`PREFETCH`] triangles ahead made the
/// tile leaves faster: measured in BENCHMARKS.md, § DACRT design measurements). No effect on
/// any result.
#[inline(always)]
pub(crate) fn prefetch<T>(v: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if i < v.len() {
        // SAFETY: `_mm_prefetch` is a cache hint: it never dereferences the pointer for the
        // program nor faults, whatever the address (here in bounds anyway), and SSE, its
        // target feature, is part of every x86_64 target. Exercised by every tile leaf of the
        // DACRT tests.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(v.as_ptr().add(i) as *const i8);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (v, i);
}

/// Moves the block `v[a..e]` to start at `k <= a` (by swaps; the displaced entries end up after
/// it) and returns the block's new end `k + (e − a)`: after filtering `v[..a]` into `v[..k]`,
/// this appends the entries known to be kept without a test.
#[inline]
pub(crate) fn gather_block<T>(v: &mut [T], k: usize, a: usize, e: usize) -> usize {
    let (len, gap) = (e - a, a - k);
    if len <= gap {
        for i in 0..len {
            v.swap(k + i, a + i);
        }
    } else {
        // The block's last `gap` entries fill the gap; its head stays where it is.
        for i in 0..gap {
            v.swap(k + i, e - gap + i);
        }
    }
    k + len
}
