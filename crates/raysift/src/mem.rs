//! Large per-call buffers backed by transparent huge pages.
//!
//! DACRT's buffers (the per-axis min/max lists of Mora 2011 §3.5, the ray and tile records) are
//! tens of megabytes written once per call. Backed by 4 KiB pages, the first call pays a page
//! fault per 4 KiB (about 10 ms of the dragon's 140 ms first frame); 2 MiB pages cut that.
//! Linux gives them to a range on request (`madvise(MADV_HUGEPAGE)`, under the THP mode most
//! distributions ship, "madvise"), as Embree asks for its own build memory. The price: on a fragmented machine
//! the kernel may compact memory synchronously at first touch (DACRT's `huge_pages` option turns
//! the request off). Elsewhere than Linux this is a no-op.

/// The huge page size (x86-64 and most aarch64 kernels): only whole, aligned ones are advised.
const HUGE: usize = 2 << 20;

/// Empties `v` and gives it room for exactly `n` more elements (keeping a larger allocation),
/// then, with `huge`, asks that the room be backed by huge pages before anything touches it.
pub(crate) fn reserve_exact_huge<T>(v: &mut Vec<T>, n: usize, huge: bool) {
    v.clear();
    v.reserve_exact(n);
    if huge {
        advise_huge(v);
    }
}

/// Asks the kernel to back `v`'s whole allocation with huge pages (best effort: errors are ignored,
/// the buffer simply keeps its ordinary pages). Public for the Python package's output arrays.
pub fn advise_huge<T>(v: &mut Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        let bytes = v.capacity() * std::mem::size_of::<T>();
        let start = v.as_mut_ptr() as usize;
        // The huge-page-aligned part of the allocation; advice outside it would cover a
        // neighbour's memory.
        let lo = start.next_multiple_of(HUGE);
        let hi = (start + bytes) / HUGE * HUGE;
        if hi > lo {
            // SAFETY: [lo, hi) lies inside `v`'s allocation, which `v` owns and keeps alive for
            // the call. MADV_HUGEPAGE only changes how the kernel backs the range; it never changes
            // its contents or whether it is mapped, so no Rust reference can observe it.
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_reservation_keeps_contents_usable() {
        // Exercises the madvise path (8 MiB) and the small path; the buffers must behave as
        // ordinary vectors afterwards.
        for n in [0usize, 10, 1 << 21] {
            let mut v: Vec<u32> = vec![7; 3];
            reserve_exact_huge(&mut v, n, n % 2 == 0);
            assert!(v.is_empty() && v.capacity() >= n);
            v.extend((0..n as u32).map(|i| i ^ 0x5a5a));
            assert!(v.iter().enumerate().all(|(i, &x)| x == i as u32 ^ 0x5a5a));
        }
    }
}
