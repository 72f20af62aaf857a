//! Output and scratch arrays backed by transparent huge pages, as the library backs DACRT's
//! buffers (`raysift::mem`, private to the library; the same 20 lines here rather than a public
//! library API for one caller).
//!
//! A 1M-ray query writes about 30 MB of fresh output arrays; on 4 KiB pages the first touches cost
//! a page fault per 4 KiB (about 20 ms on the dragon benchmark, a tenth of DACRT's trace), on
//! 2 MiB pages a few.

/// The huge page size (x86-64 and most aarch64 kernels): only whole, aligned ones are advised.
const HUGE: usize = 2 << 20;

/// `n` zeros (a zeroed allocation: fresh memory is not written), its aligned 2 MiB pages advised
/// huge before anything touches them.
pub fn zeroed<T: Copy + Default + IsZero>(n: usize) -> Vec<T> {
    let mut v = vec![T::default(); n];
    advise_huge(&mut v);
    v
}

/// Resizes `v` to `n` elements, reusing its allocation (contents unspecified: the caller writes
/// every element); a new allocation is advised huge.
pub fn reuse<T: Copy + Default>(v: &mut Vec<T>, n: usize) {
    if v.capacity() < n {
        *v = Vec::with_capacity(n);
        advise_huge(v);
    }
    if v.len() > n {
        v.truncate(n);
    } else if v.len() < n {
        v.resize(n, T::default());
    }
}

/// Types whose default is all zero bits (so `vec![T::default(); n]` is a zeroed allocation).
pub trait IsZero {}
impl IsZero for f32 {}
impl IsZero for u32 {}
impl IsZero for bool {}

/// Asks the kernel to back `v`'s whole allocation with huge pages (best effort: errors are
/// ignored, the buffer keeps its ordinary pages).
fn advise_huge<T>(v: &mut Vec<T>) {
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
            // the call. MADV_HUGEPAGE only changes how the kernel backs the range; it never
            // changes its contents or whether it is mapped, so no Rust reference can observe it.
            // Exercised by every query of the test suite (tests/test_api.py, test_errors.py).
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}
