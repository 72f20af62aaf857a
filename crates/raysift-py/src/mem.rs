//! Output and scratch arrays backed by transparent huge pages, through the library's
//! [`raysift::mem::advise_huge`] (as it backs DACRT's buffers).
//!
//! A 1M-ray query writes about 30 MB of fresh output arrays; on 4 KiB pages the first touches cost
//! a page fault per 4 KiB (about 20 ms on the dragon benchmark, a tenth of DACRT's trace), on
//! 2 MiB pages a few.

use raysift::mem::advise_huge;

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
