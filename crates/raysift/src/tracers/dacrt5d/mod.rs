//! `dacrt5d`: divide-and-conquer ray tracing over 5D ray hierarchies (Asger Hoedt's blog post
//! "DACRT over 5D ray hierarchies", `../shared/papers/hoedt-dacrt-5d-ray-hierarchies.md`, after
//! Arvo & Kirk 1987's ray classification). Instead of dividing space as [`super::dacrt`] does,
//! each call divides the *rays*: by origin and direction, and culls the triangles against each
//! ray group's bound. No structure is stored but each triangle's box.
//!
//! | file | holds | post / paper |
//! |---|---|---|
//! | `mod.rs` | [`Dacrt5d`], `impl Tracer`, counters, memory | |
//! | `config.rs` | [`Config`]: cull, stop, constants, presets | the post's choices, ours |
//! | `geom/ray5d.rs` (shared geometry) | 5D classification (six major-axis bundles, `(x, y, z, u, v)`), a group's 5D box, the open frustum and the cone, their exact culls, and their tests | Arvo–Kirk; the post's frustum |
//! | `rec.rs` | a bundle's recursion: cull, cost stop or fixed limits, ray-space split, the major-axis cut with early termination, naive leaves | the post's `DACRT`, termination criterion; ours |
//! | `space.rs` | box splits: inside a bundle (clipped rays, re-culled children), and shared by all bundles above them (packed rays) with the hand-over to the bundles | ours |
//! | `top.rs` | the shared splits' upper levels, made by the first sharing call after a `prepare` and kept | ours |
//! | `eye.rs` | a task whose rays all start at one point, traced in that point's frame (an irregular z-buffer) | ours |
//! | `run.rs` | one task: buffers from the pool, the eye pass or the classification into bundles (a counting sort), the shared splits or the bundles' recursions, results | |
//!
//! What implements which part of the post:
//! - **5D classification** (`geom::ray5d::classify`): major axis = largest `|d|` (ties by strict
//!   `>`: `|dx| = |dy|` goes to y), `u, v` = the minor components over `|d_major|`, in
//!   [-1, 1]; each task sorts its rays into the six bundles in place (counting sort, no extra
//!   buffer). Rays no bound can hold (negative or NaN `tmin`, zero or non-finite direction or
//!   origin: the loaders refuse these, the library does not) form a seventh group traced
//!   naively against every triangle, so they cost time, never an answer.
//! - **Ray-space subdivision** (`rec.rs`, `Task::ray_split`): the node's 5D box is rebuilt from
//!   its rays (one pass); the split dimension is the widest of the five, positions divided by
//!   the scene's largest extent and slopes weighted by `Config::dir_weight` (default 1: a ray
//!   bundle's footprint across the scene is about `Δx + Δu·L`; the author's "u/v when above a
//!   tenth of the spatial range" mixes units); the rays are partitioned in place at the middle
//!   of that range (children are disjoint sub-ranges: nothing is allocated per node). Identical
//!   rays (zero range) or a split that leaves a side empty make a leaf.
//! - **Geometry culling** (`geom::ray5d`, `Task::cull`): each node filters its parent's triangle
//!   prefix in place (children are prefixes, as in `dacrt`) against its own bound:
//!   `cull=frustum` (the post's open frustum: the 4 planes of the u/v bounds through the origin
//!   box's corners with analytic normals, plus the near plane; no NaN normals for a flat u or v
//!   range, and the near plane for every bundle, unlike the author's code) or `cull=cone`
//!   (Arvo–Kirk's cone, apex at the origin box's centre swept by its bounding ball, as the
//!   author's `SphereCone`). Both test the triangle's bounding box, conservatively against the
//!   shared test's rounding: the argument is in `geom::ray5d`; the test that would catch a cull
//!   that is not conservative is its `culls_keep_every_grazing_hit`.
//! - **Stop** (`Config::stop`): the post's cost rule, leaf when `R·G < C_r·R + C_g·G` (16/16,
//!   the author's values), or Mora's fixed limits (`R < 20` or `G < 16`); a depth cap (64).
//! - **Leaves**: naive, every ray against every triangle (groups of four through the shared
//!   four-wide test when at most 64 triangles, else the scalar test).
//! - **Order and early termination** (ours; the post has none), with the **hybrid** (ours): a
//!   node whose surviving triangles outnumber its rays (`G > spatial_ratio·R`, default 2:
//!   coherent rays, many triangles, where ray splits cannot shrink `G`) is split in *space*.
//!   Two ways (`space`):
//!   - `box` (default; `space.rs`, `Task::box_split`): the triangles are split in two disjoint
//!     sets at the middle of their centroids' longest extent (a BVH node made on the fly), the
//!     set the rays meet first taken first; each child keeps only the rays whose slab interval
//!     in its triangles' union box, clipped to `[tmin, best hit]`, is not empty (the shared slab
//!     test: every hit of the child's triangles lies in that interval, `geom::triangle`), moves
//!     their origins to the interval's entry and culls its triangles again against the bound of
//!     these clipped rays (`geom::ray5d::clip`, exact by the argument there; a child whose
//!     original origins span a smaller box, rays from one point, keeps them). Clipping is what
//!     makes incoherent rays cullable: a 5D bound of rays with origins all over the scene holds
//!     most of it, the bound of their entry points into a small box does not. With box splits
//!     the post's stop rule no longer ends the recursion at 16 rays or fewer: a would-be leaf
//!     with more than `leaf_tris` (32) triangles is split in space too. Measured against the
//!     other way in BENCHMARKS.md § "dacrt5d: box splits";
//!
//!     With `box`, the splits start **above the bundles** (`Task::top`, `Task::shared`): at the
//!     root, a bundle whose origins' box is small against the scene's (`hand_over`, a quarter
//!     of the extent sums: rays from one point, a camera's or a light's) takes its rays into its
//!     own 5D recursion at once; every other ray (random rays, bounces: origins all over the
//!     scene, whose bundle bounds cull nothing) goes through box splits shared by all six
//!     bundles, down to nodes of `shared_leaf` (8) triangles whose leaves test them all. Those rays
//!     travel as 32-byte packed records (origin, `tmin`, `1/d`, best hit so far), filtered four
//!     at a time by the shared slab test (`Aabb::hit_by_packed4`), their best hits written back
//!     by the leaves (an on-the-fly BVH, as Mora's DACRT with object splits). Without it each
//!     bundle made the same splits of the same triangles (six times the work), and before
//!     packing a clip read eight of the batch's scattered arrays. The shared splits depend on
//!     the triangles only, so their upper levels, down to nodes of `top_leaf` (8) triangles,
//!     are made by the first call after each `prepare` and kept (`top.rs`: Morton cells, made
//!     in a sort): small batches then pay for the nodes their rays reach, not for a pass over
//!     every triangle per level. The handed-over bundles walk them too (`kept_bundles`,
//!     `Task::bundle_top`): down to the first kept node holding at most `spatial_ratio` times
//!     as many triangles as the rays that reach it, each child taking the rays clipped to its
//!     box, where the bundle's 5D recursion starts; before, every bundle's root culled every
//!     triangle and its box splits made a pass over all of them per level (the dragon's 512²
//!     camera: 243 against 116 ms). BENCHMARKS.md § "dacrt5d: box splits" and § "dacrt5d:
//!     bundles through the kept levels";
//!   - `major` (the first hybrid; `Task::spatial_split`): a cut along the bundle's major axis at
//!     the mean of the triangles' near ends: the near triangles (near end at or before the
//!     plane) are traced first with all the rays, then the rays whose best hit (or `tmax`) lies
//!     before the plane by the rounding bound leave, exactly: every far triangle starts beyond
//!     the plane, and a hit on it would lie beyond it too.
//!
//!   Occlusion is any-hit: an occluded ray leaves at either split.
//! - **Rays from one point** (ours, `eye.rs`, `eye`): where the post's hierarchy degenerates
//!   (an origin box of no extent, only the slopes tell the rays apart), a task whose rays all
//!   start at one point (bitwise: a camera's, shuffled or several samples per pixel) is traced
//!   in that point's frame, as `dacrt`'s light-space pass traces shadow segments: its rays are
//!   points on the faces of a cube around the eye (their `u, v`), sorted into buckets of
//!   `eye_bucket` (4), and the triangles come once, from the kept levels walked near to far
//!   (`eye_tree`; nodes behind every ray's best hit under them are skipped whole), each
//!   tested only against the rays of the buckets under its box's footprint whose best hit is
//!   not nearer than the box (a z-buffer, exact by `geom::light_space`). Only when the eye is
//!   outside the scene's box (`eye_inside`: from inside, the recursion's culls did better on
//!   Sponza) and the task holds at least `eye_ratio` (0.25) rays per triangle (each task
//!   walks the triangles). BENCHMARKS.md § "dacrt5d: rays from one point".
//! - **Threads** (`run.rs`): rayon tasks over disjoint shares of the rays (as `dacrt`), each with
//!   its own lists, classifying its share into the bundles and recursing on each (the shared
//!   splits too are per task).
//! - **Shared code**: the block move of the far triangles to the prefix and the buffer reuse are
//!   `dacrt`'s (`partition::gather_block`, `scratch::reuse`).
//!
//! Correctness is bit-exact with `naive`: every pair goes through the shared
//! [`intersect_triangle`](crate::geom::intersect_triangle) (or its bit-equal four-wide form)
//! and [`closer`](crate::tracer::closer); every cull and termination is conservative.
//!
//! **Memory** (deterministic, independent of the scene's shape): prepare holds `24·T` (each
//! triangle's box); a call with `K` tasks allocates `4·T` per task (triangle ids) and `48·R`
//! (one 48-byte record per ray: origin, direction, `tmin`, `t0`, slopes, id, bundle) plus, with
//! box splits (`spatial`, `space=box`, the default), `36·R` (a 32-byte packed record and an id
//! for the shared splits), kept by the tracer for the next call (a second call of the same size
//! allocates nothing). The first call with box splits after a `prepare` also keeps their
//! upper levels: `4·T` (the triangle order) and at most `64·(4·T/(top_leaf + 1) + 1)` bytes of
//! nodes (at most 28.4 B per triangle with `top_leaf` 8; 25 on the dragon), and frees its
//! build's `8·T` of sort keys (`12·T` of items with `top_split=middle`). So `a = 24 + 4K`
//! bytes per triangle (`+ 4` and a fraction with kept levels), `b = 84` per ray (48 without
//! box splits). A task that takes the eye pass allocates, besides its `4·T` (the triangle
//! order), `60·R_k + 12·(⌊R_k / eye_bucket⌋ + 7)` (16 bytes per ray in ray order, 32 + 12 per
//! ray in its bucket, 12 per bucket) and no records; it makes the kept levels as box splits do. `tests/dacrt5d.rs`
//! checks both with a counting allocator.

mod config;
mod eye;
mod rec;
mod run;
mod space;
mod top;

pub use config::{Config, Cull, Space, Stop, OPTION_DOCS, PRESETS};
pub use top::TopSplit;

use crate::error::Result;
use crate::mem::reserve_exact_huge;
use crate::rays::{HitBatch, RayBatch};
use crate::scene::{Scene, Stamp};
use crate::tracer::{
    par_occlusion_chunks, par_ray_chunks, CounterDocs, RayCost, Stats, Tally, Tracer,
};
use rec::Rec;
use std::sync::Mutex;

/// Task slots kept between calls.
const MAX_POOLED: usize = 64;

/// One task's buffers between calls.
#[derive(Default)]
struct Scratch {
    tri_idx: Vec<u32>,
    recs: Vec<Rec>,
    pk: Vec<crate::geom::PackedRay>,
    pid: Vec<u32>,
    eye: eye::EyeScratch,
}

/// The tracer: the options and each triangle's box.
pub struct Dacrt5d {
    cfg: Config,
    stamp: Stamp,
    /// `[lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]` per triangle; degenerate or non-finite triangles
    /// (never hit) get `lo = +inf, hi = -inf` and never enter a root list.
    boxes: Vec<[f32; 6]>,
    /// How many triangles are live (their box is not empty).
    live: usize,
    /// The largest coordinate magnitude and extent of the scene's live triangles.
    scale: f32,
    extent: f32,
    /// The live triangles' box (`lo`, `hi`).
    bounds: [[f32; 3]; 2],
    /// The kept upper levels of the shared box splits (`top.rs`), made by the first call that
    /// shares splits after each `prepare`.
    top: std::sync::OnceLock<top::Top>,
    pool: Vec<Mutex<Scratch>>,
}

impl Dacrt5d {
    /// A tracer with options.
    pub fn new(cfg: Config) -> Self {
        Self {
            cfg,
            stamp: Stamp::default(),
            boxes: Vec::new(),
            live: 0,
            scale: 0.0,
            extent: 0.0,
            bounds: [[0.0; 3]; 2],
            top: std::sync::OnceLock::new(),
            pool: (0..MAX_POOLED).map(|_| Mutex::default()).collect(),
        }
    }

    /// The options.
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    fn tasks(&self) -> usize {
        if self.cfg.tasks == 0 {
            rayon::current_num_threads().max(1)
        } else {
            self.cfg.tasks
        }
    }
}

crate::counters! {
    /// What a `dacrt5d` trace counts.
    pub struct Counts {
        /// Nodes entered (culled or not).
        nodes,
        /// Naive leaves.
        leaves,
        /// Ray-space splits.
        ray_splits,
        /// Spatial splits (the hybrid, front to back along the major axis, `space=major`).
        spatial_splits,
        /// Box splits inside a bundle (the hybrid, `space=box`: object splits, rays clipped to
        /// each child).
        box_splits,
        /// Box splits above the bundles (the rays of every bundle together).
        top_splits,
        /// Kept nodes a handed-over bundle went through to its children (`kept_bundles`).
        kept_descents,
        /// Nodes of the kept upper levels this call made (`top.rs`; the first call with box
        /// splits after a `prepare` makes them).
        top_built,
        /// Ray/box clips (each box split clips its rays against both children's boxes).
        ray_clips,
        /// Rays a box split's child dropped (no hit possible in its box before their best).
        clipped_out,
        /// Box split children bounding their rays from the clipped origins (the others keep
        /// the original origins, whose box was smaller).
        clips,
        /// Nodes that culled their parent's triangles against their own bound.
        culls,
        /// Triangle/frustum tests.
        frustum_tests,
        /// Triangle/cone tests.
        cone_tests,
        /// Ray/triangle tests.
        ray_tri,
        /// Rays traced by the eye pass (`eye.rs`: a task's rays all from one point).
        eye_rays,
        /// Eye pass: triangles near the eye (tested against every live ray).
        eye_near,
        /// Eye pass: triangle footprints made (one per face holding rays).
        eye_footprints,
        /// Eye pass: buckets under the footprints.
        eye_buckets,
        /// Eye pass: rays of those buckets checked against the footprint.
        eye_checks,
        /// Eye pass: triangles skipped in kept nodes behind every ray's best hit (`eye_tree`).
        eye_hidden,
        /// Rays that left early at a spatial split (hit or `tmax` before the far half).
        terminated,
        /// Triangles surviving the culls at depth 0 (the bundles' roots).
        surv_d0,
        /// ... at depth 1.
        surv_d1,
        /// ... at depth 2.
        surv_d2,
        /// ... at depth 3.
        surv_d3,
        /// ... at depths 4 to 7.
        surv_d4_7,
        /// ... at depths 8 to 15.
        surv_d8_15,
        /// ... at depths 16 to 31.
        surv_d16_31,
        /// ... at depth 32 and beyond.
        surv_d32,
    }
}

crate::counters! {
    /// What a `dacrt5d` prepare makes.
    pub struct Built {
        /// Triangle boxes written.
        triangles,

    }
}

/// Counter docs, for the registry: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (
    <Built as crate::tracer::CounterSet>::DOCS,
    <Counts as crate::tracer::CounterSet>::DOCS,
);

impl Tracer for Dacrt5d {
    fn name(&self) -> &'static str {
        "dacrt5d"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        let tris = scene.triangles();
        let n = tris.len();
        if self.boxes.capacity() < n {
            reserve_exact_huge(&mut self.boxes, n, true);
        }
        self.boxes.clear();
        let (mut scale, mut lo_all, mut hi_all) =
            (0.0f32, [f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for t in 0..n {
            let [a, b, c] = tris.get(t);
            let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
            let live = !(a == b && b == c) && lo.is_finite() && hi.is_finite();
            self.boxes.push(if live {
                scale = scale
                    .max(lo.abs().max_element())
                    .max(hi.abs().max_element());
                for k in 0..3 {
                    lo_all[k] = lo_all[k].min(lo[k]);
                    hi_all[k] = hi_all[k].max(hi[k]);
                }
                [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]
            } else {
                [
                    f32::INFINITY,
                    f32::INFINITY,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                ]
            });
        }
        self.live = self.boxes.iter().filter(|b| b[0] <= b[3]).count();
        self.scale = scale;
        self.extent = (0..3).map(|k| hi_all[k] - lo_all[k]).fold(0.0f32, f32::max);
        self.bounds = [lo_all, hi_all];
        // The kept levels of the previous scene are stale.
        self.top = std::sync::OnceLock::new();
        self.stamp = scene.stamp();
        Ok(Stats::prepared(
            &Built {
                triangles: n as u64,
            },
            self.bytes(),
        ))
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let chunk = rays.len().div_ceil(self.tasks()).max(1);
        let tally: Tally<Counts> = par_ray_chunks(rays, hits, cost, chunk, |range, out, cost| {
            self.run_task::<false>(
                scene,
                rays,
                range,
                chunk,
                out.t,
                out.prim,
                out.u,
                out.v,
                &mut [],
                cost,
            )
        });
        Ok(tally.into_stats(rays.len()))
    }

    fn occluded(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let chunk = rays.len().div_ceil(self.tasks()).max(1);
        let tally: Tally<Counts> =
            par_occlusion_chunks(rays, occluded, cost, chunk, |range, out, cost| {
                self.run_task::<true>(
                    scene,
                    rays,
                    range,
                    chunk,
                    &mut [],
                    &mut [],
                    &mut [],
                    &mut [],
                    out,
                    cost,
                )
            });
        Ok(tally.into_stats(rays.len()))
    }

    fn bytes(&self) -> usize {
        let pool: usize = self
            .pool
            .iter()
            .map(|m| {
                m.lock().map_or(0, |g| {
                    g.tri_idx.capacity() * 4
                        + g.recs.capacity() * std::mem::size_of::<Rec>()
                        + g.pk.capacity() * std::mem::size_of::<crate::geom::PackedRay>()
                        + g.pid.capacity() * 4
                        + g.eye.bytes()
                })
            })
            .sum();
        self.boxes.capacity() * 24 + self.top.get().map_or(0, top::Top::bytes) + pool
    }
}
