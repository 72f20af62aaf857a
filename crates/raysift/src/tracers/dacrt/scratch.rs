//! Ours: each task's buffers, kept between calls in a pool (a dynamic scene's frames allocate
//! nothing after the first), allocated on transparent huge pages when asked.

use super::light::LightScratch;
use super::packets::PackedCone;
use super::ray_rec::RayRec;
use crate::mem::reserve_exact_huge;
use glam::Vec4;

/// Task slots in the pool.
pub(super) const MAX_POOLED: usize = 64;

/// One task's buffers (see [`Task`](super::Task) for their roles), between calls.
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) tri_idx: Vec<u32>,
    pub(super) ray_idx: Vec<u32>,
    pub(super) recs: Vec<RayRec>,
    pub(super) cones: Vec<PackedCone>,
    pub(super) cone_idx: Vec<u32>,
    pub(super) perm: Vec<u64>,
    pub(super) tile_rays: Vec<Vec4>,
    pub(super) touched: Vec<u64>,
    pub(super) touched_list: Vec<u32>,
    pub(super) zreach: Vec<f32>,
    /// The light-space pass's buffers (`light.rs`).
    pub(super) light: LightScratch,
}

impl Scratch {
    pub(super) fn bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.tri_idx)
            + b(&self.ray_idx)
            + b(&self.recs)
            + b(&self.cones)
            + b(&self.cone_idx)
            + b(&self.perm)
            + b(&self.tile_rays)
            + b(&self.touched)
            + b(&self.touched_list)
            + b(&self.zreach)
            + self.light.bytes()
    }
}

/// `v`, emptied, with room for `n` (allocating exactly `n` when it has less room).
pub(crate) fn reuse<T>(mut v: Vec<T>, n: usize, huge: bool) -> Vec<T> {
    reserve_exact_huge(&mut v, n, huge);
    v
}
