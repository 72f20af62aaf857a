//! Acceleration structures shared by several techniques, built apart from the tracers that
//! traverse them (Embree's split of builders from traversal kernels): a builder sees primitive
//! boxes and centroids, never rays or tracers.
//!
//! | structure | used by | module |
//! |---|---|---|
//! | binned-SAH BVH, with refit | `bvh` (and cone tracing's BVH walk, next) | [`bvh`] |
//! | SAH kd-tree (event-sorted build) | `kdtree` (and the shafts and cone tracing, next) | [`kdtree`] |
//! | bounding-sphere hierarchy, per-part rigid update and refit | `rtrps` | [`spheres`] |

pub mod bvh;
pub mod kdtree;
pub mod spheres;
