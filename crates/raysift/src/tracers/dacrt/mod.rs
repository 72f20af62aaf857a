//! `dacrt`: Divide-And-Conquer Ray Tracing (Mora 2011, "Naive ray-tracing: a divide-and-conquer
//! approach"). No acceleration structure is stored: each call partitions a triangle index list
//! and a ray index list in place, recursing on axis-aligned halves of space until a problem is
//! small enough for the naive double loop.
//!
//! The files, the paper's first, then ours:
//!
//! | file | holds | paper |
//! |---|---|---|
//! | `mod.rs` | [`Dacrt`], a task's state `Task`, `impl Tracer` (prepare: min/max lists) | §3.5 |
//! | `config.rs` | [`Mode`], [`Config`] and its defaults | §3.2–3.6, ours |
//! | `ray_rec.rs` | Algorithm 1: in-place ray recursion, ray records, naive leaves | §3.1–3.2 |
//! | `order.rs` | which child first; when a hit is final (early termination) | §3.2, §3.4 |
//! | `partition.rs` | triangle streaming: the in-place triangle and ray partitions | §3.5 |
//! | `split.rs` | the split plane | §3.6 |
//! | `cone_rec.rs` | Algorithm 2: the cone recursion, the packets' cones, FlushCones | §3.3, App. |
//! | `packets.rs` | packets of 64 rays (pinhole tiles, shadow runs), `PackedCone` | §3.3 |
//! | `run.rs` | one call: the plan, the tasks (threads), each task's set-up, results | §3.3, ours |
//! | `screen.rs` | screen-space and pixel culling: the pixel check, the projection | ours |
//! | `tile_leaf.rs` | tile leaves | ours |
//! | `top.rs` | the top tree: the upper levels kept between calls for sparse batches | ours |
//! | `light.rs` | shadow segments to one point light traced in the light's frame | ours |
//! | `scratch.rs` | the buffers kept between calls, on huge pages | ours |
//! | `tests.rs` | unit tests of the pieces (the tracer's own: `tests/dacrt.rs`) | |
//!
//! What implements which part of the paper:
//! - **§3.1–3.2, Fig. 2–3, Algorithm 1** (`Task::ray_rec`, `ray_rec.rs`): the in-place
//!   recursion. A node is `(cell, triangle prefix [0, nt), ray range [rterm, rend))`; each child
//!   is built by partitioning the parent's prefix (children are prefixes). The second child
//!   tests only the first child's survivors: what the first child rejected lies in the second
//!   (the cell is their union) and joins it untested (`gather_block`). Naive leaf when
//!   `rays < r_limit` or `triangles < p_limit`, except that a cell whose naive leaf would test
//!   more than `leaf_pairs` pairs is divided further (ours, see `Config::leaf_pairs`).
//! - **Early ray termination** (§3.2, `order.rs`): finished rays are swapped into the global
//!   prefix `[0, rterm)` so they leave every ancestor range at once. Only legal when the hit is
//!   final; see `Order` for the exact rule (hit inside the leaf cell, and every earlier stretch
//!   of the ray already visited).
//! - **§3.5, Fig. 4** (triangle streaming, `partition.rs`): per-axis min/max lists (three arrays
//!   of `[min, max]` pairs, an SoA version of the paper's four reshuffled lists), so the
//!   split-plane test of a large stream reads 8 bytes per triangle. The paper also runs the 9
//!   edge axes of the Akenine-Möller triangle/box test on streams below 100 triangles; we do
//!   not: it was slower or no faster on every camera frame measured (BENCHMARKS.md, § Fig. 8,
//!   "SAT"), and it is not exact: its f32 cross products wrongly separate needle triangles from
//!   cells near a shared vertex (the soak's fans: thousands of lost hits per million rays), and
//!   no fixed margin covers the rounding of the hits Möller–Trumbore accepts there, while the
//!   plane test on the min/max lists is exact (see `geom::triangle`, "Why every cull is exact").
//! - **§3.6, Fig. 5** (split choice, `Task::choose_split`, `split.rs`): longest axis; for
//!   streams of at least `split_sample_threshold` triangles the mean of the clamped span
//!   midpoints of every `split_sample_stride`-th triangle, else the spatial median. Guard: when
//!   every triangle straddles the plane (no progress possible), or the cell cannot be split in
//!   f32, go naive.
//! - **§3.3, Algorithm 2, Appendix** (conic packets, `Task::cone_rec`, `cone_rec.rs`; the
//!   packets in `packets.rs`): 8×8 pixel tiles of pinhole rays, or 64 shadow rays consecutive
//!   in a Morton order of their origins with the cone from the light to the origins (cut at
//!   their distance, plus a small ball around the light because the rays end a few ulps off
//!   it), bounded by a cone (axis, f64 cos², 64 termination bits); exact cone/box test
//!   ([`crate::geom::ConeQuery`]: bounding-sphere accept/reject, axis ray, then the silhouette
//!   edges from a 64-entry table); below `c_limit` cones (or `p_limit` triangles) the
//!   non-terminated rays of the cones are flushed into the ray list (by default only those
//!   entering the cell: `flush_filter`) and Algorithm 1 continues; terminated rays set their
//!   cone's bit, and cones with every bit set leave the cone list through their own terminated
//!   prefix.
//! - **Screen-space culling** (ours, `Config::screen_cull`, `screen.rs`; the idea of Hoedt's
//!   frustum culling, in pixels): a camera batch is a pinhole image, so instead of each tile's
//!   cone, a cell is projected once onto the image ([`crate::geom::PixelProjection`], fitted to
//!   the corner rays and checked against every ray of the task) and the tiles are tested by
//!   integer rectangle overlap; a flush loads only the live rays of a tile inside the cell's
//!   pixel rectangle, and a tile stays in a cell only while one of its live (not terminated)
//!   pixels is inside. Cells reaching behind the eye keep the exact cone test (when the whole
//!   scene is in front of the eye, the cones are not built at all). It replaces most cone/box
//!   tests and shortens the flushes (measured in BENCHMARKS.md, § DACRT design measurements).
//! - **Pixel culling** (ours, `Config::pixel_cull`, `screen.rs`): before dividing, the
//!   triangles whose projection covers no pixel centre of the task's image rows are dropped: no
//!   ray of the batch can hit them (an empty rectangle from
//!   [`crate::geom::PixelProjection::triangle_rects_wide`], four or eight lanes, with a
//!   rounding bound). Meshes denser than the image are mostly such triangles, so it pays on
//!   them; elsewhere the cull costs about what it saves (measured in BENCHMARKS.md, § DACRT
//!   design measurements).
//! - **Tile leaves** (ours, `Config::pixel_leaf`, `tile_leaf.rs`): the same projection gives
//!   every triangle its pixel rectangle (`rects`), and the cone recursion ends, instead of
//!   flushing its tiles' rays into Algorithm 1, in a leaf that tests each triangle against the
//!   live pixels of its rectangle inside the cell's (`Task::tile_leaf`), read off the tiles'
//!   termination bits. A camera batch then needs no ray list at all: the rays are kept in tile
//!   order, one 16-byte record each (direction and z-buffer). The leaf costs about one
//!   rectangle check per triangle plus the pairs, not rays × triangles, so leaves are large
//!   (fewer than `pixel_leaf_c_limit` = 256 live tiles, more for tiny triangles). Front-to-back
//!   termination still works per pixel. A triangle meets its pixels four at a time, through
//!   the shared test prepared for rays from the eye
//!   ([`TriFromOrigin`](crate::geom::TriFromOrigin), bit-identical), and is set up only when
//!   its rectangle still has a live pixel; the pixels hit in a leaf are checked for
//!   termination four at a time (`final_hit4`, lane-wise the scalar test). The rays' deviation
//!   from their pixels is bounded in f32, four at a time
//!   ([`PixelProjection::deviation4`](crate::geom::PixelProjection::deviation4)), with the
//!   check that they come from the eye. Fewer ray/triangle and triangle/box tests than the
//!   flushes, and no ray/box tests (BENCHMARKS.md, § Fig. 8, and § DACRT design measurements).
//! - **§3.4** (random rays, `order.rs`, `ray_rec.rs`): z-buffer (per-ray best `t`, the hit array
//!   itself) instead of termination, children ordered by the majority sign of the split-axis
//!   direction. Occlusion is any-hit: every hit terminates its ray, in every mode.
//! - **Layout of the hot loops** (`ray_rec.rs`, `partition.rs`): the ray list holds 32-byte
//!   records (`RayRec`: origin, `tmin`, `1/d`, cut-off) swapped together with the ray ids, as
//!   potato3d's `dacrt_simd` does, so the ray filter streams one record per ray instead of
//!   gathering eight SoA arrays through an index; the ray and split-plane partitions are
//!   branch-free Lomuto loops (the ray partition decides four rays at a time,
//!   [`crate::geom::Aabb::hit_by_packed4`]), and the leaves prefetch each ray's direction and
//!   best hit a few rays ahead (BENCHMARKS.md, § DACRT: random and bounce rays); leaves of at
//!   most 64 triangles gather them once into groups of
//!   four and run the shared four-wide test ([`crate::geom::intersect_triangle4`], bit-equal
//!   to the scalar one); larger leaves (few rays, many triangles) keep the scalar loop
//!   (gathering in chunks for them measured slower; both in BENCHMARKS.md, § DACRT design
//!   measurements).
//! - **The top tree** (ours, `Config::top_below`, `top.rs`): the ray-independent upper levels
//!   of the recursion (its splits and prefix partitions depend only on the triangles), built
//!   once per scene state into a tree with triangle lists at its leaves; sparse batches walk
//!   their rays down it and start Algorithm 1 at its leaves, so a few hundred bounce rays no
//!   longer stream every triangle a dozen times (BENCHMARKS.md, § DACRT: sparse batches).
//! - **Edge tests and depth culling in tile leaves** (ours, `Config::edge_pixels`,
//!   `Config::depth_cull`, `tile_leaf.rs`; both off by default): a triangle whose pixel
//!   rectangle is large tests its three edges against each 8×8 tile
//!   ([`crate::geom::PixelEdges`]), and a tile whose pixels all hit something skips triangles
//!   that cannot reach as near ([`crate::geom::hit_reach_floor`]). They cut ray/triangle pairs
//!   (Sponza −20%, Cornell −54% with the edge test) but not time (BENCHMARKS.md, § DACRT:
//!   large triangles).
//! - **Shadow segments in the light's frame** (ours, `Config::light_space`, `light.rs`, the
//!   geometry in [`crate::geom::LightView`]; issue #21 item 1): any-hit batches of segments
//!   ending at one point light (`ToPoint`) are camera rays seen from the light. Each task
//!   sorts its segments into buckets on the six faces of a cube around the light and streams
//!   the min/max lists once: a triangle's box footprint on a face, padded so that no hit can
//!   fall outside it, selects the buckets, and the segments there whose coordinates it holds
//!   and which reach as deep go through the shared test; an occluded segment leaves its
//!   bucket. Triangles in a small ball around the light are tested against every segment;
//!   segments that do not end at the light go through the recursion (BENCHMARKS.md, § DACRT:
//!   shadow rays in light space).
//! - **Threads** (`run.rs`): as in the paper's path tracer, rayon tasks own disjoint shares of
//!   the rays (bands of tile rows for camera rays) and their own index lists. Camera batches
//!   with tile leaves (issue #21 item 3, ours) first project every triangle once onto the
//!   whole image, in parallel chunks of triangles (`screen::project_all`), instead of once per
//!   task; each task then lists the triangles whose rectangle meets its band
//!   (`Task::band_triangles`), and the bands are cut where an estimate of the work (rays plus
//!   rectangle pixels per row, `screen::balanced_bands`) is evenly shared, not at equal
//!   heights (BENCHMARKS.md, § DACRT: two threads on camera rays).
//! - **Width and pages** (ours, `screen.rs`, `scratch.rs`): the projection of every triangle is
//!   written once over [`crate::geom::lanes::Lanes`] and runs eight triangles at a time in AVX2
//!   code when the CPU has it (checked at run time; the same rectangles bit for bit), four
//!   elsewhere; the per-call buffers and min/max lists ask for transparent huge pages
//!   (`Config::huge_pages`: fewer page faults in a process's first frame). Both measured in
//!   BENCHMARKS.md, § Fig. 14.
//!
//! Correctness is bit-exact with `naive`: every candidate pair goes through the shared
//! [`intersect_triangle`](crate::geom::intersect_triangle) (or its bit-equal four-wide form)
//! and [`closer`](crate::tracer::closer), and every filter is conservative (the z-buffer cut
//! and box exits are widened by the shared rounding slack).
//!
//! **Memory** (bytes the tracer allocates; deterministic, independent of the scene's shape):
//! - made by prepare: `24·T` (per axis, each triangle's `[min, max]`);
//! - per call, for `K` tasks (kept by the tracer afterwards, so that a call allocates only
//!   what earlier calls did not: a dynamic scene's frames allocate nothing after the first):
//!   `4·T·K` (triangle indices) `+ 36·R` (ray indices and 32-byte ray records: origin,
//!   `tmin`, inverse direction, cut-off; see `RayRec`; not with tile leaves)
//!   and, in packet mode, `68` bytes per cone (64 for the prepared cone, 4 for its index), i.e.
//!   `68·⌈W/8⌉·(tile rows)` for camera rays (`= 1.0625·R` when W and H are multiples of 8 and
//!   the bands are whole tile rows) and, for shadow rays when shadow packets are on
//!   (`max_shadow_cone_deg > 0`), `68·⌈R_task/64⌉` per task plus `8·R` (the Morton order of the
//!   rays that groups them into compact packets). Camera batches with tile leaves (every
//!   ray from the eye within 2 pixels of its pixel, one `tmin`) have no ray list but
//!   `8·T + 8·(K + 1)` (pixel rectangles and band bounds, shared by the tasks) and, per tile,
//!   1036 bytes besides its cone: 64 ray records of 16 bytes, and 12 for the leaves'
//!   bookkeeping (16 with `depth_cull`).
//!
//! Any-hit `ToPoint` batches with `light_space` (the default) use none of that but, per task of
//! `R_k` rays, `64·R_k + 12·(⌊R_k / light_bucket⌋ + 7)` bytes (16 per ray in ray order, 16 + 32
//! in bucket order, three 4-byte arrays over the buckets; `tests/dacrt_memory.rs` checks it);
//! the `m` segments it leaves to the recursion (usually none) add a copy of those rays, their
//! indices and flags (37 bytes each) and the recursion's buffers for `m` rays as above.
//!
//! So with `K` tasks: `a = 24 + 4K` bytes per triangle (24 held, `4K` per call), `c = 0`, and
//! `b = 36` (ray and random modes, and shadow rays by default), `45.0625` (shadow packets,
//! task shares multiple of 64 rays); camera packets with tile leaves (the default) `a = 32 +
//! 4K`, `b = 17.25` (full tiles; `37.0625` with `pixel_leaf=false` or when the rays fail the
//! pixel check: it allocates nothing). These are the bytes a
//! first call allocates, so also a bound on its peak, and what the tracer then holds
//! ([`Tracer::bytes`]: `24·T` plus the kept buffers); `Stats::peak_bytes` reports the largest
//! task's share. The integration test `tests/dacrt_memory.rs` checks the formula exactly with a
//! counting allocator, and that a second call allocates nothing. Screen-space and pixel
//! culling allocate nothing. Batches without packets of at most `top_below` rays per triangle
//! (the default modes' bounce, random and shadow rays up to `2·T` rays) add the top tree,
//! built by the first such call after the scene changed and then held: `12·T` at the defaults
//! (`4·(1 + top_growth)·T + 16·(4·⌈(1 + top_growth)·T / top_leaf⌉ + 1)`), nothing more while
//! it is built (see `top.rs`).

mod cone_rec;
mod config;
pub(crate) mod light;
mod order;
mod packets;
pub(crate) mod partition;
mod ray_rec;
mod run;
pub(crate) mod scratch;
mod screen;
mod split;
#[cfg(test)]
mod tests;
mod tile_leaf;
mod top;

pub use config::{Config, Mode, OPTION_DOCS, PRESETS};

use crate::error::Result;
use crate::geom::PixelProjection;
use crate::mem::reserve_exact_huge;
use crate::rays::{HitBatch, RayBatch, RayLayout};
use crate::scene::{Change, Scene, Stamp, TriangleSoup};
use crate::tracer::{
    par_occlusion_bands, par_occlusion_chunks, par_ray_bands, par_ray_chunks, CostMut, CounterDocs,
    HitsMut, RayCost, Stats, Tally, Tracer,
};
use glam::{Vec3, Vec4};
use order::View;
use packets::{PackedCone, Packets};
use ray_rec::RayRec;
use rayon::prelude::*;
use scratch::{Scratch, MAX_POOLED};
use std::sync::{Mutex, OnceLock};
use top::TopTree;

/// The DACRT tracer: the scene plus its per-axis triangle bounds (rebuilt by every prepare, O(T)).
pub struct Dacrt {
    cfg: Config,
    stamp: Stamp,
    /// `span[a][t] = [lo, hi]`: triangle `t`'s bounds on axis `a` (§3.5's min/max lists, each
    /// pair side by side: the split-plane test gathers both through the triangle index, and one
    /// cache line instead of two measured faster on the 871K dragon).
    /// Degenerate triangles get `lo = +inf, hi = -inf` so the first split drops them (exact:
    /// the shared triangle test never hits them).
    span: [Vec<[f32; 2]>; 3],
    /// The tasks' index lists and buffers, kept between calls (the task on the `c`-th share of
    /// the rays uses slot `c`, whatever thread runs it): a call allocates only what earlier
    /// calls did not, so the frames of a dynamic scene allocate nothing after the first (no
    /// page faults after it: measured in BENCHMARKS.md, § DACRT design measurements).
    /// [`MAX_POOLED`] empty slots are made with the tracer; tasks beyond use fresh buffers.
    pool: Vec<Mutex<Scratch>>,
    /// Camera batches with tile leaves: every triangle's pixel rectangle on the image, made
    /// once per call for all its tasks (`screen::project_all`) and kept for the next call.
    rects: Mutex<run::ShareBufs>,
    /// The top tree of the prepared scene (`top.rs`), built by the first call that wants it
    /// and dropped by a prepare that changes a triangle.
    top: OnceLock<TopTree>,
    /// The largest coordinate magnitude of the prepared triangles (the light-space pass pads
    /// boxes relative to it).
    scale: f32,
}

impl Dacrt {
    /// A tracer with options.
    pub fn new(cfg: Config) -> Self {
        Self {
            cfg,
            stamp: Stamp::default(),
            span: Default::default(),
            pool: (0..MAX_POOLED).map(|_| Mutex::default()).collect(),
            rects: Mutex::default(),
            top: OnceLock::new(),
            scale: 0.0,
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

/// One task: a disjoint share of the rays with its own index lists.
struct Task<'a, const ANY: bool> {
    cfg: &'a Config,
    tris: &'a TriangleSoup,
    span: [&'a [[f32; 2]]; 3],
    rays: &'a RayBatch,
    /// First ray of the share.
    base: usize,
    // Closest-hit outputs (empty for ANY); `t` doubles as the z-buffer: it holds `tmax` until
    // a hit is found and is reset to +inf for misses at the end.
    t: &'a mut [f32],
    prim: &'a mut [u32],
    u: &'a mut [f32],
    v: &'a mut [f32],
    // Any-hit output (empty for closest).
    occ: &'a mut [bool],
    tri_idx: Vec<u32>,
    /// Local ray ids; `recs[p]` is the record of ray `ray_idx[p]` (both permuted together).
    ray_idx: Vec<u32>,
    recs: Vec<RayRec>,
    /// Terminated-ray pivot (§3.2): `ray_idx[..rterm]` are final.
    rterm: usize,
    terminate: bool,
    view: View,
    packets: Packets,
    apex: Vec3,
    /// Screen-space culling of camera tiles (`Config::screen_cull`), when every ray of the
    /// task starts at the eye and projects within `tol` pixels of its own pixel; `row0` is the
    /// image row of the task's first.
    proj: Option<PixelProjection>,
    tol: f64,
    row0: i64,
    /// False when screen-space culling decides every cell (the cones are then not built).
    cones_built: bool,
    cones: Vec<PackedCone>,
    cone_idx: Vec<u32>,
    /// Shadow packets: rays grouped by a Morton code of their origin so that 64 consecutive
    /// slots are close together (compact cones). Entry `x`: low 32 bits = the ray in slot `x`,
    /// high 32 bits = the slot of ray `x`. Empty otherwise.
    perm: Vec<u64>,
    /// Terminated-cone pivot.
    cterm: usize,
    /// Tile leaves (`Config::pixel_leaf`): the cone recursion ends in [`Task::tile_leaf`] and
    /// there is no ray list. `rects[t]` is triangle `t`'s inclusive pixel rectangle
    /// `[x0, x1, y0, y1]` (image rows: the call's shared projection); `touched[c]`, the
    /// pixels of tile `c` some triangle of the current leaf hit, and `touched_list` the tiles
    /// with any (capacity: the tile count, never exceeded). All empty otherwise.
    tile_leaves: bool,
    /// Tile leaves: a leaf below this many live tiles (see `band_triangles`).
    leaf_tiles: usize,
    rects: &'a [[u16; 4]],
    /// Tile leaves: the projection and tolerance the rectangles were made with, for the edge
    /// test of the pixels of rectangles of at least `edge_pixels` pixels
    /// (`Config::edge_pixels`; `None`: off).
    edge_test: Option<(PixelProjection, f64)>,
    edge_pixels: u64,
    /// Tile leaves: the rays in tile order (pixel `bit` of tile `c` at `64·c + bit`): the
    /// direction, and in `w` the cut-off (closest hit: the best `t` so far, the z-buffer;
    /// any-hit: `tmax`), so a pair reads one 16-byte record; `tmin0` is every ray's `tmin`.
    tile_rays: Vec<Vec4>,
    tmin0: f32,
    /// Tile leaves: the smallest `|d|∞` of the task's rays (the box gate's pre-test bound).
    dlow: f32,
    touched: Vec<u64>,
    touched_list: Vec<u32>,
    /// Tile leaves, closest hits, with `depth_cull` (`Config::depth_cull`): per tile, an upper
    /// bound on the distance `t·|d|` of its live pixels' best hits so far
    /// ([`hit_reach_ceil`](crate::geom::hit_reach_ceil); +inf until each has one), lowered at
    /// the end of every leaf that hit it: a triangle farther from the eye
    /// ([`hit_reach_floor`](crate::geom::hit_reach_floor)) skips the tile. Empty otherwise.
    zreach: Vec<f32>,
    depth_cull: bool,
    st: Counts,
    /// Per-ray cost, when asked (local ray indices, as `t`/`occ`); see [`Task::charge`].
    cost: Option<CostMut<'a>>,
    /// Bytes this task allocated (see the module doc's formula).
    peak: u64,
}

crate::counters! {
    /// What a `dacrt` trace counts.
    pub struct Counts {
        /// Ray/box tests (a ray filtered against a cell).
        ray_box,
        /// Ray/triangle tests.
        ray_tri,
        /// Triangle/box tests (a triangle's min/max list filtered against a split plane).
        tri_box,
        /// Cone/box tests (a conic packet against a cell).
        cone_box,
        /// Cells divided (interior steps of the recursion).
        nodes,
        /// Naive leaves (and tile leaves).
        leaves,
        /// Tile leaves: triangles whose rectangle met the leaf cell's pixels (once per leaf).
        leaf_tris,
        /// Tile leaves: (triangle, tile) pairs visited under those rectangles.
        leaf_tiles,
        /// Tile leaves: of those, the pairs with live pixels (sent to the ray/triangle test).
        leaf_live_tiles,
        /// Tile leaves: pixels hit (each hit a ray/triangle test reported, a z-buffer write
        /// when closer).
        leaf_hits,
        /// Tile leaves: live pixels of triangles' rectangles the edge test dropped before the
        /// ray/triangle test (`Config::edge_pixels`).
        edge_culled,
        /// Tile leaves: live pixels of triangles' rectangles skipped because the triangle lies
        /// beyond every best hit of the tile (`Config::depth_cull`).
        depth_culled,
        /// Light-space pass (`light.rs`): segments traced in the light's frame.
        light_rays,
        /// Light-space pass: triangles near the light (tested against every live segment).
        light_near,
        /// Light-space pass: buckets under the triangles' footprints.
        light_buckets,
        /// 1 when this call built the top tree (its triangle/box tests are in `tri_box`).
        top_built,
        /// With `phase_times`: nanoseconds (summed over tasks) of set-up and write-back (ray
        /// records, cones, pixel checks, z-buffer, results).
        ns_setup,
        /// With `phase_times`: nanoseconds of the triangle-list pass (live triangles, or the
        /// projection with pixel culling) and of the top tree's build.
        ns_lists,
        /// With `phase_times`: nanoseconds of the dividing steps (ray, cone and triangle
        /// filtering, splits, the top tree's walk), leaves excluded.
        ns_divide,
        /// With `phase_times`: nanoseconds inside naive and tile leaves.
        ns_leaves,
    }
}

crate::counters! {
    /// What a `dacrt` prepare makes.
    pub struct Built {
        /// Triangles whose per-axis min/max lists were written (all of them for a new scene,
        /// those of the moved or deformed meshes after a change, none when nothing changed).
        triangles,
    }
}

impl Dacrt {
    /// Any hits by the recursion (camera, shadow packets, rays).
    fn occluded_rec(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Tally<Counts> {
        let (plan, packets) = self.plan(rays);
        let (top, built) = self.top_tree(scene, rays, &plan);
        // One job sent to the pool for the whole call (the shared projection and the tasks
        // inside it), as many as before it had a shared pass.
        let mut tally: Tally<Counts> = rayon::scope(|_| {
            let shared = self.shared_rects(scene, rays, &plan, packets);
            let task = |band, range, out: &mut [bool], cost: Option<CostMut<'_>>| {
                self.run_task::<true>(
                    scene,
                    rays,
                    range,
                    band,
                    &plan,
                    packets,
                    top,
                    shared.as_ref(),
                    &mut [],
                    &mut [],
                    &mut [],
                    &mut [],
                    out,
                    cost,
                )
            };
            let chunk = plan.chunk.max(1);
            let mut tally: Tally<Counts> = match &shared {
                Some(s) => par_occlusion_bands(rays, occluded, cost, &s.bufs.bounds, task),
                None => par_occlusion_chunks(rays, occluded, cost, chunk, |range, out, cost| {
                    task(range.start / chunk, range, out, cost)
                }),
            };
            self.keep_rects(shared, &mut tally.counts);
            tally
        });
        charge_top(&mut tally.counts, built);
        tally
    }

    /// Any hits of segments to `light` by the light-space pass (`light.rs`), one task per
    /// share of the rays; the segments it cannot take go through [`Self::occluded_rec`].
    fn occluded_light(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        light: Vec3,
        occluded: &mut Vec<bool>,
        mut cost: Option<&mut RayCost>,
    ) -> Tally<Counts> {
        let chunk = rays.len().div_ceil(self.tasks()).max(1);
        let tris = scene.triangles();
        let out: light::LightOut = par_occlusion_chunks(
            rays,
            occluded,
            cost.as_deref_mut(),
            chunk,
            |range, occ, c| self.light_task(tris, rays, range, chunk, light, occ, c),
        );
        let mut tally = Tally {
            counts: out.counts,
            peak_bytes: out.peak,
        };
        if out.misfits.is_empty() {
            return tally;
        }
        let sub = RayBatch::from_rays(out.misfits.iter().map(|&i| rays.get(i as usize)));
        let mut occ = Vec::new();
        let mut sub_cost = cost.as_ref().map(|_| RayCost::default());
        tally = tally + self.occluded_rec(scene, &sub, &mut occ, sub_cost.as_mut());
        for (j, &i) in out.misfits.iter().enumerate() {
            let i = i as usize;
            occluded[i] = occ[j];
            if let (Some(c), Some(s)) = (cost.as_deref_mut(), sub_cost.as_ref()) {
                c.nodes[i] = c.nodes[i].saturating_add(s.nodes[j]);
                c.tests[i] = c.tests[i].saturating_add(s.tests[j]);
                c.triangles[i] = c.triangles[i].saturating_add(s.triangles[j]);
            }
        }
        tally
    }
}

/// A call that built the top tree pays for it: `built` is its (triangle/box tests, ns).
fn charge_top(c: &mut Counts, built: Option<(u64, u64)>) {
    if let Some((tests, ns)) = built {
        c.top_built += 1;
        c.tri_box += tests;
        c.ns_lists += ns;
    }
}

/// A clock for `phase_times`: `None` when off (then [`ns_since`] is 0 and nothing is read).
#[inline(always)]
fn clock(on: bool) -> Option<std::time::Instant> {
    on.then(std::time::Instant::now)
}

/// Nanoseconds since a [`clock`] reading (0 without one).
#[inline(always)]
fn ns_since(c: Option<std::time::Instant>) -> u64 {
    c.map_or(0, |c| c.elapsed().as_nanos() as u64)
}

/// Counter docs, for the registry: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (
    <Built as crate::tracer::CounterSet>::DOCS,
    <Counts as crate::tracer::CounterSet>::DOCS,
);

/// Triangle `t`'s box as (min, max); degenerate triangles get an empty one, dropped by the
/// first split. Inlined by hand: as a closure, `prepare` lost it (and a third of its speed) to
/// an unrelated change elsewhere in the crate.
#[inline(always)]
fn span_of(tris: &TriangleSoup, t: usize) -> (Vec3, Vec3) {
    let [a, b, c] = tris.get(t);
    if a == b && b == c {
        (Vec3::INFINITY, Vec3::NEG_INFINITY)
    } else {
        (a.min(b).min(c), a.max(b).max(c))
    }
}

/// Scenes of at least this many triangles get their min/max lists written in parallel.
const PAR_PREPARE: usize = 1 << 16;

impl Tracer for Dacrt {
    fn name(&self) -> &'static str {
        "dacrt"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        let tris = scene.triangles();
        let n = tris.len();
        let span_of = |t: usize| span_of(tris, t);
        // The scene prepared before, changed in some meshes (same triangles): only their ranges
        // of the min/max lists are rewritten. Otherwise all of them, pushed once.
        let partial = match scene.changes_since(self.stamp) {
            Change::None => Some(Vec::new()),
            Change::Meshes { moved, deformed } if self.span[0].len() == n => Some(
                moved
                    .iter()
                    .chain(&deformed)
                    .map(|&m| scene.mesh_prims(m))
                    .collect::<Vec<_>>(),
            ),
            _ => None,
        };
        self.stamp = Stamp::default();
        let written = match partial {
            Some(ranges) => {
                let mut written = 0;
                for t in ranges.into_iter().flatten() {
                    let (mn, mx) = span_of(t);
                    for k in 0..3 {
                        self.span[k][t] = [mn[k], mx[k]];
                    }
                    written += 1;
                }
                written
            }
            None => {
                let huge = self.cfg.huge_pages;
                for v in &mut self.span {
                    reserve_exact_huge(v, n, huge);
                    v.resize(n, [0.0; 2]);
                }
                // In chunks of triangles, each writing its own stretch of the lists: in
                // parallel for large scenes (small ones would spend more waking threads).
                const CHUNK: usize = 1 << 14;
                let [sx, sy, sz] = &mut self.span;
                type Stretch<'s> = &'s mut [[f32; 2]];
                let fill = |(c, ((sx, sy), sz)): (usize, ((Stretch, Stretch), Stretch))| {
                    for j in 0..sx.len() {
                        let (mn, mx) = span_of(c * CHUNK + j);
                        (sx[j], sy[j], sz[j]) = ([mn.x, mx.x], [mn.y, mx.y], [mn.z, mx.z]);
                    }
                };
                if n >= PAR_PREPARE {
                    sx.par_chunks_mut(CHUNK)
                        .zip(sy.par_chunks_mut(CHUNK))
                        .zip(sz.par_chunks_mut(CHUNK))
                        .enumerate()
                        .for_each(fill);
                } else {
                    sx.chunks_mut(CHUNK)
                        .zip(sy.chunks_mut(CHUNK))
                        .zip(sz.chunks_mut(CHUNK))
                        .enumerate()
                        .for_each(fill);
                }
                n
            }
        };
        if written > 0 {
            self.top = OnceLock::new();
            // NaN-safe: `max` skips NaN; degenerate triangles' infinite spans are skipped.
            // (The maximum of the same numbers in any order: the same for any thread count.)
            let pair = |p: &[f32; 2]| {
                p.iter()
                    .filter(|v| v.is_finite())
                    .fold(0.0f32, |m, v| m.max(v.abs()))
            };
            let largest = |s: &Vec<[f32; 2]>| {
                if s.len() >= PAR_PREPARE {
                    s.par_iter().map(pair).reduce(|| 0.0, f32::max)
                } else {
                    s.iter().map(pair).fold(0.0, f32::max)
                }
            };
            self.scale = self.span.iter().map(largest).fold(0.0, f32::max);
        }
        self.stamp = scene.stamp();
        Ok(Stats::prepared(
            &Built {
                triangles: written as u64,
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
        if scene.is_empty() || rays.is_empty() {
            hits.reset(rays.len());
            if let Some(c) = cost {
                c.reset(rays.len());
            }
            return Ok(Stats::traced(rays.len(), &Counts::default()));
        }
        let (plan, packets) = self.plan(rays);
        let (top, built) = self.top_tree(scene, rays, &plan);
        // One job sent to the pool for the whole call (the shared projection and the tasks
        // inside it), as many as before it had a shared pass.
        let mut tally: Tally<Counts> = rayon::scope(|_| {
            let shared = self.shared_rects(scene, rays, &plan, packets);
            let task = |band, range, out: HitsMut<'_>, cost: Option<CostMut<'_>>| {
                self.run_task::<false>(
                    scene,
                    rays,
                    range,
                    band,
                    &plan,
                    packets,
                    top,
                    shared.as_ref(),
                    out.t,
                    out.prim,
                    out.u,
                    out.v,
                    &mut [],
                    cost,
                )
            };
            let chunk = plan.chunk.max(1);
            let mut tally: Tally<Counts> = match &shared {
                Some(s) => par_ray_bands(rays, hits, cost, &s.bufs.bounds, task),
                None => par_ray_chunks(rays, hits, cost, chunk, |range, out, cost| {
                    task(range.start / chunk, range, out, cost)
                }),
            };
            self.keep_rects(shared, &mut tally.counts);
            tally
        });
        charge_top(&mut tally.counts, built);
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
        if scene.is_empty() || rays.is_empty() {
            occluded.clear();
            occluded.resize(rays.len(), false);
            if let Some(c) = cost {
                c.reset(rays.len());
            }
            return Ok(Stats::traced(rays.len(), &Counts::default()));
        }
        let tally = match rays.layout {
            RayLayout::ToPoint { target } if self.cfg.light_space => {
                self.occluded_light(scene, rays, target, occluded, cost)
            }
            _ => self.occluded_rec(scene, rays, occluded, cost),
        };
        Ok(tally.into_stats(rays.len()))
    }

    fn bytes(&self) -> usize {
        let pool: usize = self
            .pool
            .iter()
            .map(|m| m.lock().map_or(0, |g| g.bytes()))
            .sum();
        self.span.iter().map(|v| v.capacity() * 8).sum::<usize>()
            + pool
            + self
                .rects
                .lock()
                .map_or(0, |r| r.rects.capacity() * 8 + r.bounds.capacity() * 8)
            + self.top.get().map_or(0, TopTree::bytes)
    }
}
