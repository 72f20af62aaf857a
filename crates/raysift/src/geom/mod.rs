//! Shared geometry: vectors (glam), axis-aligned boxes, planes, spheres, cones, and **the one
//! ray/triangle test** every tracer calls.
//!
//! Tracers never carry their own copy of a geometric test: correctness is proven by comparing every
//! tracer with the brute-force one bit for bit, which only holds when they all evaluate the same
//! function on the same data (see `triangle`).

pub mod aabb;
pub mod aligned;
pub mod cone_frustum;
pub mod cone_triangle;
pub mod conebox;
pub mod lanes;
pub mod light_space;
pub mod morton;
pub mod projection;
pub mod ray5d;
pub mod ray_cone;
pub mod shaft;
pub mod shapes;
pub mod slab;
pub mod sphere_plane;
pub mod triangle;
pub mod triangle4;
pub mod tribox;

pub use aabb::{Aabb, PackedRay};
pub use cone_frustum::ConeFrustum;
pub use cone_triangle::{cone_triangle, ConeF64};
pub use conebox::{cone_box_overlap, ConeQuery};
pub use glam::{Vec3, Vec3A};
pub use light_space::{
    ray_view, segment_slack, segment_view, Footprint, LightView, RayView, SegmentView,
};
pub use projection::{PixelEdges, PixelProjection, RectLanes};
pub use ray_cone::RayCone;
pub use shapes::{Cone, Plane, Sphere};
pub use slab::{BoxPair, SlabRay};
pub use sphere_plane::PlaneFan;
pub use triangle::{hit_reach_ceil, hit_reach_floor, intersect_triangle, TriHit};
pub use triangle4::{intersect_triangle4, slab_lanes, Hit4, HitLanes, Splat, Tri4, TriFromOrigin};
pub use tribox::{tri_box_edge_axes, tri_box_overlap};

/// `1 + 3 * 2^-24`-style slack used to make box tests conservative against the rounding of the
/// triangle test: a hit computed by [`intersect_triangle`] may lie a few ulps outside the exact box of
/// its triangle, so box exits are pushed out by this relative factor (Ize 2013; pbrt's `gamma(3)`).
pub const BOX_EXIT_SLACK: f32 =
    1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);
