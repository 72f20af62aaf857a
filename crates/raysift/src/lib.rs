//! # raysift
//!
//! Batch ray/triangle intersection for scenes that change every frame. Several published
//! techniques (divide-and-conquer ray tracing, bounding spheres with ray-planes, relevant-triangle
//! shafts, cone tracing) and two baselines (brute force, SAH BVH) implement one [`Tracer`]
//! contract, and are proven equal to the brute-force tracer.
//!
//! ```
//! use raysift::{rays::Camera, scene::procedural, tracers, Tracer};
//!
//! let mut scene = procedural::icosphere(1000);
//! let mut tracer = tracers::create("dacrt", &[]).unwrap();
//! tracer.prepare(&scene).unwrap();
//! let camera = Camera::framing(&scene.bounds(), 45.0, 1.0);
//! let rays = camera.rays(16, 16);
//! let (hits, stats) = tracer.intersect_timed(&scene, &rays).unwrap();
//! assert!(hits.hit_count() > 80);
//! assert_eq!(stats.rays, 256);
//! println!("ray/triangle tests: {}", stats.work.get("ray_tri"));
//!
//! // A frame later the mesh has moved: the tracer updates (here DACRT re-reads its lists).
//! scene.set_transform(0, glam::Affine3A::from_rotation_y(0.3)).unwrap();
//! assert!(tracer.intersect_timed(&scene, &rays).is_err(), "stale: prepare first");
//! tracer.prepare(&scene).unwrap();
//! let (moved, _) = tracer.intersect_timed(&scene, &rays).unwrap();
//! assert_eq!(moved.len(), 256);
//! ```
//!
//! Layout: see ARCHITECTURE.md at the repository root.

#![warn(missing_docs)]

pub mod accel;
pub mod error;
pub mod geom;
pub mod mem;
pub mod output;
pub mod rays;
pub mod render;
pub mod scene;
pub mod testkit;
pub mod tracer;
pub mod tracers;

pub use error::{Error, Result};
pub use rays::{HitBatch, RayBatch};
pub use scene::Scene;
pub use tracer::{Stats, Tracer};
