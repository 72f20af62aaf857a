//! `dacrt`: Divide-And-Conquer Ray Tracing (Mora 2011, "Naive ray-tracing: a divide-and-conquer
//! approach"). No acceleration structure is stored: each call partitions a triangle index list
//! and a ray index list in place, recursing on axis-aligned halves of space until a problem is
//! small enough for the naive double loop.
//!
//! What implements which part of the paper:
//! - **§3.1–3.2, Fig. 2–3, Algorithm 1** (`Task::ray_rec`): the in-place recursion. A node is
//!   `(cell, triangle prefix [0, nt), ray range [rterm, rend))`; each child is built by
//!   partitioning the parent's prefix (children are prefixes). The second child tests only the
//!   first child's survivors: what the first child rejected lies in the second (the cell is
//!   their union) and joins it untested (`gather_block`). Naive leaf when `rays < r_limit` or
//!   `triangles < p_limit`, except that a cell whose naive leaf would test more than
//!   `leaf_pairs` pairs is divided further (ours, see `Config::leaf_pairs`).
//! - **Early ray termination** (§3.2): finished rays are swapped into the global prefix
//!   `[0, rterm)` so they leave every ancestor range at once. Only legal when the hit is final;
//!   see `Order` for the exact rule (hit inside the leaf cell, and every earlier stretch of the
//!   ray already visited).
//! - **§3.5, Fig. 4** (triangle streaming): per-axis min/max lists (three arrays of `[min, max]`
//!   pairs, an SoA version
//!   of the paper's four reshuffled lists), so the split-plane test of a large stream reads 8 bytes
//!   per triangle. Streams below `sat_threshold` also run the 9 edge axes of the Akenine-Möller
//!   test ([`crate::geom::tri_box_edge_axes`]; face axes implied by induction, plane axis dropped
//!   as in the paper). The paper's threshold is 100; ours defaults to 0 (plane test only), by
//!   measurement: the edge-axis test costs about six four-wide ray/triangle tests per triangle
//!   and saves only the tests of the rays that reach the triangles it drops; at 1024² camera
//!   rays, 100 made the frame 1.3× slower on the 871K dragon and 1.05–1.2× on Sponza and the
//!   bunny (BENCHMARKS.md).
//! - **§3.6, Fig. 5** (split choice, `Task::choose_split`): longest axis; for streams of at least
//!   `split_sample_threshold` triangles the mean of the clamped span midpoints of every
//!   `split_sample_stride`-th triangle, else the spatial median. Guard: when every triangle
//!   straddles the plane (no progress possible), or the cell cannot be split in f32, go naive.
//! - **§3.3, Algorithm 2, Appendix** (conic packets, `Task::cone_rec`): 8×8 pixel tiles of
//!   pinhole rays, or 64 shadow rays consecutive in a Morton order of their origins with the cone
//!   from the light to the origins (cut at their distance, plus a small ball around the light
//!   because the rays end a few ulps off it), bounded by a cone (axis, f64 cos², 64 termination
//!   bits); exact cone/box test
//!   ([`crate::geom::ConeQuery`]: bounding-sphere accept/reject, axis ray, then the silhouette edges from a 64-entry
//!   table); below `c_limit` cones (or `p_limit` triangles) the non-terminated rays of the cones
//!   are flushed into the ray list (by default only those entering the cell: `flush_filter`)
//!   and Algorithm 1 continues; terminated rays set their cone's bit, and cones with every
//!   bit set leave the cone list through their own terminated prefix.
//! - **Screen-space culling** (ours, `Config::screen_cull`; the idea of Hoedt's frustum
//!   culling, in pixels): a camera batch is a pinhole image, so instead of each tile's cone,
//!   a cell is projected once onto the image ([`crate::geom::PixelProjection`], fitted to the
//!   corner rays and checked against every ray of the task) and the tiles are tested by
//!   integer rectangle overlap; a flush loads only the live rays of a tile inside the cell's
//!   pixel rectangle, and a tile stays in a cell only while one of its live (not terminated)
//!   pixels is inside. Cells reaching behind the eye keep the exact cone test (when the whole
//!   scene is in front of the eye, the cones are not built at all). Dragon, 1024²: the
//!   cone/box tests were 15% of the frame, the flush loop another 15%; the frame went from
//!   556 to 410 ms (BENCHMARKS.md).
//! - **Pixel culling** (ours, `Config::pixel_cull`): before dividing, the triangles whose
//!   projection covers no pixel centre of the task's image rows are dropped: no ray of the
//!   batch can hit them (an empty rectangle from
//!   [`crate::geom::PixelProjection::triangle_rects_wide`], four or eight lanes, with a
//!   rounding bound). Meshes denser than the image are mostly such triangles: over two
//!   thirds of the 3.5M-triangle tile of dragons at 1024² (triangle/box tests 82M → 37M; its
//!   frame through the harness went from 827 to 573 ms with this and the cone skip above),
//!   a third of the 871K dragon (about even there: the cull costs what it saves).
//! - **Tile leaves** (ours, `Config::pixel_leaf`): the same projection gives every triangle
//!   its pixel rectangle (`rects`), and the cone recursion ends, instead of flushing its
//!   tiles' rays into Algorithm 1, in a leaf that tests each triangle against the live pixels
//!   of its rectangle inside the cell's (`Task::tile_leaf`), read off the tiles' termination
//!   bits. A camera batch then needs no ray list at all: the rays are kept in tile order, one
//!   16-byte record each (direction and z-buffer). The leaf costs about one rectangle check
//!   per triangle plus the pairs, not rays × triangles, so leaves are large (fewer than
//!   `pixel_leaf_c_limit` = 256 live tiles, more for tiny triangles). Front-to-back
//!   termination still works per pixel. A triangle meets its pixels four at a time, through
//!   the shared test prepared for rays from the eye ([`TriFromOrigin`], bit-identical), and
//!   is set up only when its rectangle still has a live pixel; the pixels hit in a leaf are
//!   checked for termination four at a time (`final_hit4`, lane-wise the scalar test). The
//!   rays' deviation from their pixels is bounded in f32, four at a time
//!   ([`PixelProjection::deviation4`]), with the check that they come from the eye.
//!   Dragon, 1024²: ray/triangle tests 27.4M → 2.6M (the BVH does 2.7M), triangle/box 19.3M
//!   → 6.1M, trace 383 → about 125 ms (BENCHMARKS.md).
//! - **§3.4** (random rays): z-buffer (per-ray best `t`, the hit array itself) instead of
//!   termination, children ordered by the majority sign of the split-axis direction. Occlusion is
//!   any-hit: every hit terminates its ray, in every mode.
//! - **Layout of the hot loops**: the ray list holds 32-byte records (`RayRec`: origin, `tmin`,
//!   `1/d`, cut-off) swapped together with the ray ids, as potato3d's `dacrt_simd` does, so the
//!   ray filter streams one record per ray instead of gathering eight SoA arrays through an
//!   index (2–2.6× faster random-ray mode on 1M-triangle scenes); the ray and split-plane
//!   partitions are branch-free Lomuto loops; leaves of at most 64 triangles gather them once
//!   into groups of four and run the shared four-wide test ([`crate::geom::intersect_triangle4`],
//!   bit-equal to the scalar one); larger leaves (few rays, many triangles) keep the scalar loop
//!   (gathering in chunks for them measured ~15% slower on random rays).
//! - **Threads**: as in the paper's path tracer, rayon tasks own disjoint shares of the rays
//!   (bands of tile rows for camera rays) and their own index lists.
//! - **Width and pages** (ours): the projection of every triangle is written once over
//!   [`crate::geom::lanes::Lanes`] and runs eight triangles at a time in AVX2 code when the CPU
//!   has it (checked at run time; dragon frame 116 → 110 ms, the same rectangles bit for bit),
//!   four elsewhere; the per-call buffers and min/max lists ask for transparent huge pages
//!   (`Config::huge_pages`: a first frame's page faults, dragon 133 → 125 ms).
//!
//! Correctness is bit-exact with `naive`: every candidate pair goes through the shared
//! [`intersect_triangle`] (or its bit-equal four-wide form) and [`closer`], and every filter
//! is conservative (the z-buffer cut and box exits are widened by the shared rounding slack).
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
//!   `8·T·K` (pixel rectangles) and, per tile, 1036 bytes besides its cone: 64 ray records of
//!   16 bytes, and 12 for the leaves' bookkeeping.
//!
//! So with `K` tasks: `a = 24 + 4K` bytes per triangle (24 held, `4K` per call), `c = 0`, and
//! `b = 36` (ray and random modes, and shadow rays by default), `45.0625` (shadow packets,
//! task shares multiple of 64 rays); camera packets with tile leaves (the default) `a = 24 +
//! 12K`, `b = 17.25` (full tiles; `37.0625` with `pixel_leaf=false` or when the rays fail the
//! pixel check: it allocates nothing). These are the bytes a
//! first call allocates, so also a bound on its peak, and what the tracer then holds
//! ([`Tracer::bytes`]: `24·T` plus the kept buffers); `Stats::peak_bytes` reports the largest
//! task's share. The integration test `tests/dacrt_memory.rs` checks the formula exactly with a
//! counting allocator, and that a second call allocates nothing. Screen-space and pixel
//! culling allocate nothing.

use crate::error::Result;
use crate::geom::lanes::{self, F32x8, Lanes, Width};
use crate::geom::{
    intersect_triangle, intersect_triangle4, tri_box_edge_axes, Aabb, Cone, ConeQuery, PackedRay,
    PixelProjection, Tri4, TriFromOrigin,
};
use crate::mem::reserve_exact_huge;
use crate::rays::{HitBatch, RayBatch, RayLayout, MISS};
use crate::scene::Stamp;
use crate::scene::{Scene, TriangleSoup};
use crate::tracer::{
    closer, par_occlusion_chunks, par_ray_chunks, CounterDocs, RayCost, Stats, Tally, Tracer,
};
use crate::tracers::{OptionDoc, Preset};
use glam::{BVec4A, Mat4, Vec3, Vec4};
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::sync::Mutex;

/// Which recursion to run.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Conic packets for pinhole and shadow batches, random-ray mode otherwise.
    #[default]
    Auto,
    /// Conic packets when the batch's layout allows (falls back to `ray` otherwise).
    Packet,
    /// Rays with early termination (front-to-back when the rays share a viewpoint).
    Ray,
    /// Rays with a z-buffer and no termination (§3.4).
    Random,
}

/// Options (`key=value` on the command line).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Naive leaf when fewer active rays than this (paper: 20). Default 20.
    pub r_limit: usize,
    /// Naive leaf when fewer triangles than this (paper: 16). Default 16.
    pub p_limit: usize,
    /// A cell with fewer than `r_limit` rays is still divided while its naive leaf would test
    /// more than this many ray/triangle pairs (ours: the paper's rule makes a naive leaf of 19
    /// rays and thousands of triangles, which sparse incoherent batches, such as a path
    /// tracer's bounces off an open mesh, reach everywhere). `usize::MAX` is the paper's rule.
    /// Default 200: 79K diffuse bounce rays off the 871K dragon, 313 → 162 ms (ray/triangle
    /// tests 17.7M → 6.9M; 2000: 240 ms, 50: 176 ms); 1M random rays and 1M shadow rays
    /// unchanged.
    pub leaf_pairs: usize,
    /// Flush cones to rays when fewer active cones than this (the paper gives no value; 16
    /// balances ray/box savings against deeper cone recursions on dense meshes). Default 16.
    pub c_limit: usize,
    /// Run the edge-axis triangle/box test only on streams smaller than this (paper: 100;
    /// measured slower here, see the module doc). Default 0 (never).
    pub sat_threshold: usize,
    /// Sampled split position for streams of at least this many triangles, spatial median
    /// below (paper: 10 000). Default 10000.
    pub split_sample_threshold: usize,
    /// Sample every n-th triangle for the split position (paper: 50). Default 50.
    pub split_sample_stride: usize,
    /// `auto`, `packet`, `ray` or `random`. Default `auto`.
    pub mode: Mode,
    /// Recursion depth cap (a guard; leaves are made naive beyond it). Default 64.
    pub max_depth: u32,
    /// Parallel tasks, each with its own index lists over a disjoint share of the rays; 0 = the
    /// number of rayon threads. Default 0.
    pub tasks: usize,
    /// Camera packets whose cone half-angle exceeds this (degrees) are traced as rays.
    /// Default 20.
    pub max_cone_deg: f32,
    /// The same for shadow packets (§3.3's cones from the light), whose 64 rays are grouped by
    /// position and can be far apart (a wide light cone reaches many cells and floods their
    /// leaves with rays); 0 turns shadow packets off. Default 0: measured at 1024² on the
    /// camera hits, 1° packets took 1428 ms vs 551 ms for rays on the 871K dragon, 428 vs 372
    /// on the bunny, 658 vs 387 on a 202K dragon, and won only on Sponza (285 vs 379, light
    /// inside the scene): a cone from the light keeps every cell along its 64 segments alive,
    /// doubling the triangle/box tests (BENCHMARKS.md, Fig. 8).
    pub max_shadow_cone_deg: f32,
    /// When flushing cones, keep only the rays that pass a ray/box test with the cell (fewer
    /// ray/triangle tests in the leaves, one ray/box test per flushed ray). Default true.
    pub flush_filter: bool,
    /// Camera packets: bound each 8×8 tile by its pixel rectangle instead of its cone, and test
    /// a cell by projecting it onto the image (`geom::PixelProjection`; checked per ray, the
    /// cone test stays for cells reaching behind the eye and for batches that fail the check).
    /// `false` runs the paper's cone test everywhere. Default true.
    pub screen_cull: bool,
    /// Camera batches: before dividing, drop the triangles that no pixel's ray can hit (their
    /// projection covers none of the task's pixel centres: sub-pixel triangles between
    /// samples; `geom::PixelProjection::triangle_may_cover`), when every ray of the task lies
    /// on its own pixel. Default true.
    pub pixel_cull: bool,
    /// Camera batches (as `pixel_cull`): each triangle's pixel rectangle is kept, and the cone
    /// recursion ends in tile leaves that test a triangle only against the live pixels of its
    /// rectangle, with no ray list (`Task::tile_leaf`) instead of flushing the cones to rays.
    /// Default true.
    pub pixel_leaf: bool,
    /// With tile leaves: a leaf when fewer active tiles than this (`c_limit`'s role; a tile
    /// leaf's cost is about linear in pixels plus triangles, so it pays to stop earlier),
    /// scaled up to 16× for meshes whose triangles' mean pixel rectangle is small (below 16
    /// pixels; see `Task::project_triangles`). Default 256.
    pub pixel_leaf_c_limit: usize,
    /// Ask Linux for transparent huge pages (`madvise(MADV_HUGEPAGE)`, as Embree's allocator
    /// does) for the per-call buffers and the min/max lists: fewer first-touch page faults.
    /// Only a process's first call gains (warm calls reuse the buffers): with the thread pinned
    /// (`--pin`, as every benchmark runs), the dragon's first frame 133 → 125 ms, the 3.5M
    /// tile's prepare 57 → 36 ms and trace 212 → 201 ms. Unpinned, the dragon's first frame
    /// still gained (141 → 128 ms) but the tile's first trace was 282–427 ms in 3 of 4 fresh
    /// processes against 203–209 without, and both settings saw rare stalls of 100+ ms in fresh
    /// processes on this (virtual) machine. Default true.
    pub huge_pages: bool,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            r_limit: 20,
            p_limit: 16,
            leaf_pairs: 200,
            c_limit: 16,
            sat_threshold: 0,
            split_sample_threshold: 10_000,
            split_sample_stride: 50,
            mode: Mode::Auto,
            max_depth: 64,
            tasks: 0,
            max_cone_deg: 20.0,
            max_shadow_cone_deg: 0.0,
            flush_filter: true,
            screen_cull: true,
            pixel_cull: true,
            pixel_leaf: true,
            pixel_leaf_c_limit: 256,
            huge_pages: true,
        }
    }
}

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
    /// calls did not, so the frames of a dynamic scene allocate nothing after the first (the
    /// tile of dragons: 5–7% faster from the second call on, page faults spared).
    /// [`MAX_POOLED`] empty slots are made with the tracer; tasks beyond use fresh buffers.
    pool: Vec<Mutex<Scratch>>,
}

/// Task slots in the pool.
const MAX_POOLED: usize = 64;

/// One task's buffers (see [`Task`] for their roles), between calls.
#[derive(Default)]
struct Scratch {
    tri_idx: Vec<u32>,
    ray_idx: Vec<u32>,
    recs: Vec<RayRec>,
    cones: Vec<PackedCone>,
    cone_idx: Vec<u32>,
    perm: Vec<u64>,
    rects: Vec<[u16; 4]>,
    tile_rays: Vec<Vec4>,
    touched: Vec<u64>,
    touched_list: Vec<u32>,
}

impl Scratch {
    fn bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.tri_idx)
            + b(&self.ray_idx)
            + b(&self.recs)
            + b(&self.cones)
            + b(&self.cone_idx)
            + b(&self.perm)
            + b(&self.rects)
            + b(&self.tile_rays)
            + b(&self.touched)
            + b(&self.touched_list)
    }
}

/// `v`, emptied, with room for `n` (allocating exactly `n` when it has less room).
fn reuse<T>(mut v: Vec<T>, n: usize, huge: bool) -> Vec<T> {
    reserve_exact_huge(&mut v, n, huge);
    v
}

impl Dacrt {
    /// A tracer with options.
    pub fn new(cfg: Config) -> Self {
        Self {
            cfg,
            stamp: Stamp::default(),
            span: Default::default(),
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

/// Relative widening of `t` cut-offs (z-buffer and termination), a few times the shared box
/// slack: filters must keep a ray when a triangle could tie its best hit.
#[inline(always)]
fn widen(t: f32) -> f32 {
    t + t.abs() * (4.0 * f32::EPSILON)
}

/// Screen-space culling needs camera rays within this many pixels of their pixel (the
/// projection fitted to the corner rays): exact pinhole rays are within 1e-3, rays jittered
/// inside their pixels within about 1; farther, the rectangles would be loose.
const MAX_PIXEL_DEVIATION: f64 = 2.0;

/// The deviation exact pinhole rays are checked against when they are not measured (they
/// are within a few thousandths of a pixel).
const PINHOLE_TOL: f64 = 1.0 / 256.0;

/// Leaves with at most this many triangles run the four-wide triangle test on a gathered copy.
const LEAF4_MAX: usize = 64;

/// Relative gap a hit must keep from its leaf's exit to terminate the ray: generous, because a
/// ray that is not terminated only costs time, and a ray terminated too early is wrong.
const TERM_GAP: f32 = 1.0 / 16384.0;

/// Front-to-back bookkeeping for early termination (§3.2 and references.md §1.4).
///
/// A ray may leave the recursion at a leaf when no unvisited cell can hold a closer or tying
/// hit. Along every ancestor where the current node is the **first** visited child, the ray's
/// points in the second child must come after its points here. With the first child on the low
/// side of plane `s` on axis `a`, that holds when `d[a] ≥ 0` (the ray crosses low → high) or when
/// the ray's segment starts at or below `s` (it never enters the high side). Over all such
/// ancestors this folds into one bound per axis and side: `lo_min[a]` (smallest such `s`) and
/// `hi_max[a]` (largest for high-first ancestors). Second children add nothing: the first
/// child's cells were all visited before. Together with "hit at or before the leaf's exit" this
/// makes termination valid for any ray set and any visiting order (the order only decides how
/// often it applies).
#[derive(Clone, Copy, Debug)]
struct Order {
    lo_min: [f32; 3],
    hi_max: [f32; 3],
}

impl Order {
    const NONE: Order = Order {
        lo_min: [f32::INFINITY; 3],
        hi_max: [f32::NEG_INFINITY; 3],
    };

    fn child(self, axis: usize, split: f32, first: bool, low: bool) -> Order {
        let mut o = self;
        if first {
            if low {
                o.lo_min[axis] = o.lo_min[axis].min(split);
            } else {
                o.hi_max[axis] = o.hi_max[axis].max(split);
            }
        }
        o
    }

    /// `start`: the segment's first point `o + tmin·d`; `err`: a bound on its rounding error.
    #[inline]
    fn allows(&self, start: Vec3, err: f32, d: Vec3) -> bool {
        for a in 0..3 {
            if !(d[a] >= 0.0 || start[a] + err <= self.lo_min[a]) {
                return false;
            }
            if !(d[a] <= 0.0 || start[a] - err >= self.hi_max[a]) {
                return false;
            }
        }
        true
    }
}

/// Bytes per conic packet: the cone and its index in the cone list.
const CONE_BYTES: usize = std::mem::size_of::<PackedCone>() + 4;
const _: () = assert!(
    CONE_BYTES == 68,
    "the memory formula in the module doc says 68"
);

/// One conic packet: 64 bytes.
#[derive(Clone, Copy, Debug)]
struct PackedCone {
    /// The cone, prepared for box tests (f64 unit axis, cos² of the half-angle, cos and sin:
    /// f32 cannot resolve the angular margin near 1). Near radius: boxes this close to the apex
    /// count as hit (shadow cones; 0 for camera cones). Reach: the packet's rays lie within this
    /// distance of the apex (shadow cones: their origins; +inf for camera cones).
    q: ConeQuery,
    /// Termination bits, one per ray of the packet.
    done: u64,
}

/// A ray as the filter loops see it (32 bytes, swapped together with its id in `ray_idx`): the
/// slab test ([`Aabb::hit_by_packed`], four lanes) reads one record instead of eight scattered
/// SoA entries through an index. Its `tmax` lane is the cut-off, the end of the ray's useful
/// interval: the widened z-buffer `t` for closest hits (updated by the leaves), `tmax` for
/// any-hit. The direction itself (needed only by the leaves' exact triangle test) stays in the
/// caller's batch.
type RayRec = PackedRay;

/// How the rays of a task map to packets.
#[derive(Clone, Copy, Debug)]
enum Packets {
    /// No packets.
    None,
    /// Pinhole band: `width` pixels per row, `rows` rows, 8×8 tiles, `tw` tiles per row.
    Tiles {
        width: usize,
        rows: usize,
        tw: usize,
    },
    /// Shadow rays: 64 consecutive rays per cone.
    Runs { len: usize },
}

impl Packets {
    fn count(&self) -> usize {
        match *self {
            Packets::None => 0,
            Packets::Tiles { rows, tw, .. } => tw * rows.div_ceil(8),
            Packets::Runs { len } => len.div_ceil(64),
        }
    }

    /// Local ray `k` → (packet, bit). `perm` is the shadow-ray order (see [`Task::perm`]).
    #[inline]
    fn of(&self, k: usize, perm: &[u64]) -> (usize, u32) {
        match *self {
            Packets::None => (0, 0),
            Packets::Tiles { width, tw, .. } => {
                let (y, x) = (k / width, k % width);
                ((y / 8) * tw + x / 8, ((y % 8) * 8 + x % 8) as u32)
            }
            Packets::Runs { .. } => {
                let j = (perm[k] >> 32) as usize;
                (j / 64, (j % 64) as u32)
            }
        }
    }

    /// Calls `f(k, bit)` for every ray of packet `c`.
    #[inline]
    fn for_each(&self, c: usize, perm: &[u64], mut f: impl FnMut(usize, u32)) {
        match *self {
            Packets::None => {}
            Packets::Tiles { width, rows, tw } => {
                let (ty, tx) = (c / tw, c % tw);
                for y in ty * 8..(ty * 8 + 8).min(rows) {
                    for x in tx * 8..(tx * 8 + 8).min(width) {
                        f(y * width + x, ((y % 8) * 8 + x % 8) as u32);
                    }
                }
            }
            Packets::Runs { len } => {
                let (a, b) = (c * 64, (c * 64 + 64).min(len));
                for (bit, &e) in perm[a..b].iter().enumerate() {
                    f(e as u32 as usize, bit as u32);
                }
            }
        }
    }

    /// Bits of the rays packet `c` has (closed form of the bits [`Self::for_each`] visits).
    fn full_mask(&self, c: usize, _perm: &[u64]) -> u64 {
        let low = |n: usize| if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        match *self {
            Packets::None => 0,
            Packets::Tiles { width, rows, tw } => {
                let (ty, tx) = (c / tw, c % tw);
                let (w, h) = ((width - tx * 8).min(8), (rows - ty * 8).min(8));
                // `w` low bits in each of the first `h` bytes.
                low(w) * (low(8 * h) / 0xff)
            }
            Packets::Runs { len } => low(len.min(c * 64 + 64) - c * 64),
        }
    }
}

/// How to choose the first child.
#[derive(Clone, Copy, Debug)]
enum View {
    /// Majority sign of the split-axis direction (§3.4).
    Majority,
    /// Rays leave this point (camera): its side first.
    From(Vec3),
    /// Rays go to this point (light): the other side first.
    To(Vec3),
}

/// The per-call plan shared by all tasks.
#[derive(Clone, Copy, Debug)]
struct Plan {
    terminate: bool,
    packets: bool,
    view: View,
    chunk: usize,
    /// Camera batches: the image's pixel projection (checked per ray by each task).
    proj: Option<PixelProjection>,
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
    /// `[x0, x1, y0, y1]` (task-local rows); `touched[c]`, the pixels of tile `c` some triangle
    /// of the current leaf hit, and `touched_list` the tiles with any (capacity: the tile
    /// count, never exceeded). All empty otherwise.
    tile_leaves: bool,
    /// Tile leaves: a leaf below this many live tiles (see `project_triangles`).
    leaf_tiles: usize,
    rects: Vec<[u16; 4]>,
    /// Tile leaves: the rays in tile order (pixel `bit` of tile `c` at `64·c + bit`): the
    /// direction, and in `w` the cut-off (closest hit: the best `t` so far, the z-buffer;
    /// any-hit: `tmax`), so a pair reads one 16-byte record; `tmin0` is every ray's `tmin`.
    tile_rays: Vec<Vec4>,
    tmin0: f32,
    touched: Vec<u64>,
    touched_list: Vec<u32>,
    st: Counts,
    /// Bytes this task allocated (see the module doc's formula).
    peak: u64,
}

impl<'a, const ANY: bool> Task<'a, ANY> {
    #[inline(always)]
    fn best_cut(&self, r: usize) -> f32 {
        if ANY {
            self.rays.tmax[self.base + r]
        } else {
            widen(self.t[r])
        }
    }

    /// Writes ray `k` (local) with its record into slot `slot` of the ray list.
    #[inline(always)]
    fn load_ray(&mut self, slot: usize, k: usize) {
        let i = self.base + k;
        // One four-lane division (lane 3 then holds the cut-off); per lane the same IEEE
        // quotient as `1.0 / d`.
        let mut inv_tmax = Vec4::ONE / self.rays.dir(i).extend(1.0);
        inv_tmax.w = self.best_cut(k);
        self.ray_idx[slot] = k as u32;
        self.recs[slot] = RayRec {
            o_tmin: self.rays.origin(i).extend(self.rays.tmin[i]),
            inv_tmax,
        };
    }

    /// Fills `tri_idx` with the ids of the non-degenerate triangles (degenerate ones have an
    /// empty span and are never hit) and returns their count. Every root list holds only
    /// triangles some box can hold: the second child takes the first child's rejects untested.
    fn live_triangles(&mut self) -> usize {
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

    /// [`Self::project_lanes`] eight triangles at a time, compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2 ([`lanes::width`] is [`Width::Eight`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn project_avx2(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
        cull: bool,
    ) -> (usize, f64) {
        self.project_lanes::<F32x8>(proj, tol, xs, ys, cull)
    }

    /// [`Self::project_triangles`]' pass over the triangles, `L::N` at a time: pushes the kept
    /// triangles to `tri_idx` and (tile leaves) every triangle's rectangle to `rects`; returns
    /// the non-degenerate count and the kept rectangles' total area.
    #[inline(always)]
    fn project_lanes<L: Lanes>(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        xs: [i64; 2],
        ys: [i64; 2],
        cull: bool,
    ) -> (usize, f64) {
        let tris = self.tris;
        let n = tris.len();
        let idx = &mut self.tri_idx;
        let rects = &mut self.rects;
        let tile_leaves = self.tile_leaves;
        let mut area = 0.0f64;
        let mut live_count = 0;
        let row0 = ys[0] as f32;
        let lane = L::from_fn(|l| l as f32);
        // `L::N` at a time (a short last group repeats its last triangle).
        for t0 in (0..n).step_by(L::N) {
            let m = (n - t0).min(L::N);
            let at = |l: usize| (t0 + l).min(n - 1);
            let lanes = |c: &[Vec3]| {
                [
                    L::from_fn(|l| c[at(l)].x),
                    L::from_fn(|l| c[at(l)].y),
                    L::from_fn(|l| c[at(l)].z),
                ]
            };
            let v = [lanes(&tris.v0), lanes(&tris.v1), lanes(&tris.v2)];
            // Degenerate (one point, as in `prepare`): never hit.
            let same = |a: usize| v[0][a].cmpeq(v[1][a]) & v[1][a].cmpeq(v[2][a]);
            let live = !(same(0) & same(1) & same(2)) & lane.cmple(L::splat((m - 1) as f32));
            let live = L::bitmask(live);
            live_count += live.count_ones() as usize;
            let r = proj.triangle_rects_wide::<L>(v, tol, xs, ys);
            let kept = r.nonempty() & live;
            // Lane by lane: a vector transpose and select here made the AVX2 loop 10% slower.
            for l in 0..m {
                let q = r.lane(l);
                if kept >> l & 1 != 0 {
                    // Exact small integers: the pixel ranges are below 2^16.
                    area += (q[1] - q[0] + 1.0) as f64 * (q[3] - q[2] + 1.0) as f64;
                }
                if tile_leaves {
                    // Task-local rows; the ranges fit in u16 (tile leaves need both image
                    // dimensions at most 2^16). Pushed in triangle order (`rects[t]`), no zero
                    // fill first.
                    rects.push(if kept >> l & 1 != 0 {
                        [q[0], q[1], q[2] - row0, q[3] - row0].map(|v| v as u16)
                    } else {
                        [1, 0, 1, 0]
                    });
                }
            }
            let mut keep = if cull { kept } else { live };
            while keep != 0 {
                idx.push(t0 as u32 + keep.trailing_zeros());
                keep &= keep - 1;
            }
        }
        (live_count, area)
    }

    /// [`Self::live_triangles`] for a task with a projection: fills `tri_idx` with the
    /// non-degenerate triangles, projected onto the task's pixels (rows `ys`) on the way,
    /// scene order: with `cull` (`Config::pixel_cull`), only the triangles some pixel's ray of
    /// the task can hit; with pixel leaves, each one's rectangle goes to `rects`. Returns the
    /// count. One pass over the vertices in order (a list pass, then reads through the list,
    /// made the 871K dragon's frame about 5% slower).
    fn project_triangles(
        &mut self,
        proj: &PixelProjection,
        tol: f64,
        ys: [i64; 2],
        cull: bool,
    ) -> usize {
        let Packets::Tiles { width, .. } = self.packets else {
            return self.live_triangles();
        };
        let xs = [0, width as i64 - 1];
        self.tri_idx.clear();
        #[cfg(target_arch = "x86_64")]
        let (live_count, area) = match lanes::width() {
            // SAFETY: `project_avx2` needs AVX2; `width()` is `Eight` only on CPUs that have it.
            Width::Eight => unsafe { self.project_avx2(proj, tol, xs, ys, cull) },
            Width::Four => self.project_lanes::<Vec4>(proj, tol, xs, ys, cull),
        };
        #[cfg(not(target_arch = "x86_64"))]
        let (live_count, area) = self.project_lanes::<Vec4>(proj, tol, xs, ys, cull);
        let idx = &self.tri_idx;
        let k = idx.len();
        self.st.tri_box += live_count as u64;
        // Leaves of tiny triangles cost about one pair per pixel they cover, so they can be
        // larger than those of triangles covering many pixels (where a leaf tests each one
        // against every live pixel of its rectangle, occluded or not): `pixel_leaf_c_limit`
        // tiles for rectangles of 16 pixels or more on average, up to 16× that for one pixel
        // (3.5M-triangle tile of dragons: 8% faster at 4096 tiles than at 256; Sponza's large
        // triangles twice as slow at 1024).
        let mean = area / (k.max(1) as f64);
        let scale = (16.0 / mean.max(1.0)).clamp(1.0, 16.0);
        self.leaf_tiles = (self.cfg.pixel_leaf_c_limit as f64 * scale) as usize;
        k
    }

    /// In-place filter of `ray_idx[rterm..rend]` against `b` (full slab test, §3.2: no stacked
    /// intervals). Returns the new end.
    ///
    /// Branch-free Lomuto partition: with `[rterm, k)` kept and `[k, p)` rejected, swapping
    /// slots `k` and `p` unconditionally keeps both invariants whatever the test says (a rejected
    /// ray at `p` trades places with a rejected one at `k`, or with itself), so only `k` depends
    /// on the test.
    fn partition_rays(&mut self, b: &Aabb, rend: usize) -> usize {
        let start = self.rterm;
        let recs = &mut self.recs[..rend];
        let ids = &mut self.ray_idx[..rend];
        let mut k = start;
        for p in start..rend {
            let keep = b.hit_by_packed(&recs[p]);
            recs.swap(k, p);
            ids.swap(k, p);
            k += keep as usize;
        }
        self.st.ray_box += (rend - start) as u64;
        k
    }

    /// In-place filter of `tri_idx[..nt]` for the child on side `low` of `split`: the split-plane
    /// test on the min/max lists, plus the edge axes on small streams. Returns the new count and
    /// how many triangles the plane test would also send to the other child.
    fn partition_tris(
        &mut self,
        nt: usize,
        axis: usize,
        split: f32,
        low: bool,
        child: &Aabb,
    ) -> (usize, usize) {
        let span = self.span[axis];
        let sat = nt < self.cfg.sat_threshold;
        let mut k = 0;
        let mut other = 0;
        if !sat {
            // Large streams: the plane test only, as a branch-free Lomuto partition (see
            // `partition_rays`: the unconditional swap keeps `[0, k)` kept, `[k, p)` dropped).
            let idx = &mut self.tri_idx[..nt];
            for p in 0..nt {
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
            self.st.tri_box += nt as u64;
            return (k, other);
        }
        let mut sat_tests = 0u64;
        for p in 0..nt {
            let t = self.tri_idx[p] as usize;
            let [l, h] = span[t];
            let (inside, opposite) = if low {
                (l <= split, h >= split)
            } else {
                (h >= split, l <= split)
            };
            other += opposite as usize;
            let keep = inside
                && (!sat || {
                    sat_tests += 1;
                    tri_box_edge_axes(self.tris.v0[t], self.tris.v1[t], self.tris.v2[t], child)
                });
            if keep {
                self.tri_idx.swap(k, p);
                k += 1;
            }
        }
        self.st.tri_box += nt as u64 + sat_tests;
        (k, other)
    }

    /// §3.6: the split axis and position, or `None` when the cell cannot be split.
    fn choose_split(&self, cell: &Aabb, nt: usize) -> Option<(usize, f32)> {
        let axis = cell.longest_axis();
        let (mn, mx) = (cell.min[axis], cell.max[axis]);
        let median = mn + (mx - mn) * 0.5;
        let mut s = median;
        let stride = self.cfg.split_sample_stride.max(1);
        if nt >= self.cfg.split_sample_threshold {
            let span = self.span[axis];
            let (mut sum, mut n) = (0.0f64, 0u32);
            for p in (0..nt).step_by(stride) {
                let t = self.tri_idx[p] as usize;
                let [l, h] = span[t];
                if l <= h {
                    sum += 0.5 * (l.clamp(mn, mx) as f64 + h.clamp(mn, mx) as f64);
                    n += 1;
                }
            }
            if n > 0 {
                s = (sum / n as f64) as f32;
            }
        }
        if !(s > mn && s < mx) {
            s = median;
        }
        (s > mn && s < mx).then_some((axis, s))
    }

    /// Whether the low child goes first at a node of ray range `[rterm, rend)`.
    fn low_first(&self, axis: usize, split: f32, rend: usize) -> bool {
        match self.view {
            View::From(p) if p[axis] != split => p[axis] < split,
            View::To(p) if p[axis] != split => p[axis] > split,
            _ => {
                // Majority of the split-axis direction signs over (a sample of) the rays.
                let n = rend - self.rterm;
                let step = (n / 64).max(1);
                let (mut pos, mut neg) = (0, 0);
                for p in (self.rterm..rend).step_by(step) {
                    // 1/d has d's sign (±0 gives ±inf); only the order depends on it.
                    let dx = self.recs[p].inv_tmax[axis];
                    pos += (dx > 0.0) as u32;
                    neg += (dx < 0.0) as u32;
                }
                pos >= neg
            }
        }
    }

    /// Algorithm 1 on rays `ray_idx[rterm..rend]` and triangles `tri_idx[..nt]` in `cell`;
    /// `filtered`: every ray of the list passed a box test against `cell`.
    fn ray_rec(
        &mut self,
        cell: Aabb,
        nt: usize,
        rend: usize,
        depth: u32,
        ord: Order,
        filtered: bool,
    ) {
        self.st.nodes += 1;
        let nr = rend - self.rterm;
        if nr == 0 || nt == 0 {
            return;
        }
        if (nr < self.cfg.r_limit && nr.saturating_mul(nt) <= self.cfg.leaf_pairs)
            || nt < self.cfg.p_limit
            || depth >= self.cfg.max_depth
        {
            return self.leaf(&cell, nt, rend, ord);
        }
        let Some((axis, split)) = self.choose_split(&cell, nt) else {
            return self.leaf(&cell, nt, rend, ord);
        };
        let low_first = self.low_first(axis, split, rend);
        // First child: both lists filtered; what it rejects stays behind its prefixes.
        let child = half(&cell, axis, split, low_first);
        let (nt0, other) = self.partition_tris(nt, axis, split, low_first, &child);
        if nt0 == nt && other == nt {
            // No progress: every triangle straddles the plane (§3.6 guard).
            return self.leaf(&cell, nt, rend, ord);
        }
        let rend0 = self.partition_rays(&child, rend);
        let ord0 = ord.child(axis, split, true, low_first);
        self.ray_rec(child, nt0, rend0, depth + 1, ord0, true);
        // Second child. A triangle or ray of this cell that the first child's (conservative)
        // test rejected lies in the second child without a test (the cell is their union); the
        // first child's recursion only reordered `[0, nt0)` and `[rterm, rend0)` (terminated
        // rays leave through the `rterm` prefix), so the rejected ones are still at
        // `[nt0, nt)` and `[rend0, rend)`. Only the first child's survivors are tested. Rays
        // count as known only when this cell's list was filtered against it.
        let child = half(&cell, axis, split, !low_first);
        let (k, _) = self.partition_tris(nt0, axis, split, !low_first, &child);
        let nt1 = gather_block(&mut self.tri_idx, k, nt0, nt);
        let rend1 = if filtered {
            let k = self.partition_rays(&child, rend0);
            gather_block(&mut self.ray_idx, k, rend0, rend);
            gather_block(&mut self.recs, k, rend0, rend)
        } else {
            self.partition_rays(&child, rend)
        };
        let ord1 = ord.child(axis, split, false, !low_first);
        self.ray_rec(child, nt1, rend1, depth + 1, ord1, true);
    }

    /// The naive leaf (§3.2): every active ray against every triangle, then early termination.
    fn leaf(&mut self, cell: &Aabb, nt: usize, rend: usize, ord: Order) {
        if nt <= LEAF4_MAX {
            return self.leaf4(cell, nt, rend, ord);
        }
        let tris = self.tris;
        // The ray loop needs `self`; the index list is lent out meanwhile (no allocation).
        let idx = std::mem::take(&mut self.tri_idx);
        let ids = &idx[..nt];
        self.leaf_rays(
            cell,
            rend,
            ord,
            |o, d, tmin, tmax| {
                let mut tests = 0;
                for &t in ids {
                    let t = t as usize;
                    tests += 1;
                    if intersect_triangle(o, d, tris.v0[t], tris.v1[t], tris.v2[t], tmin, tmax)
                        .is_some()
                    {
                        return (true, tests);
                    }
                }
                (false, tests)
            },
            |o, d, tmin, (mut bt, mut bp, mut bu, mut bv)| {
                for &t in ids {
                    let tu = t as usize;
                    if let Some(h) =
                        intersect_triangle(o, d, tris.v0[tu], tris.v1[tu], tris.v2[tu], tmin, bt)
                    {
                        if closer(h.t, t, bt, bp) {
                            (bt, bp, bu, bv) = (h.t, t, h.u, h.v);
                        }
                    }
                }
                ((bt, bp, bu, bv), nt as u64)
            },
        );
        self.tri_idx = idx;
    }

    /// [`Self::leaf`] for up to [`LEAF4_MAX`] triangles: they are gathered once into groups of
    /// four ([`Tri4`], padding lanes are point triangles, never hit) and each ray runs the
    /// four-wide shared test. Same answers as the scalar loop: a group is tested against the
    /// best `t` at its start, then its lanes go through [`closer`] in triangle order, and a lane
    /// beyond the running best fails `closer` just as it would have failed the scalar `tmax`.
    fn leaf4(&mut self, cell: &Aabb, nt: usize, rend: usize, ord: Order) {
        let tris = self.tris;
        let mut buf = [Tri4::default(); LEAF4_MAX / 4];
        let mut ids = [0u32; LEAF4_MAX];
        for q in 0..nt {
            let t = self.tri_idx[q];
            let tu = t as usize;
            ids[q] = t;
            buf[q / 4].set(q % 4, tris.v0[tu], tris.v1[tu], tris.v2[tu]);
        }
        let groups = &buf[..nt.div_ceil(4)];
        self.leaf_rays(
            cell,
            rend,
            ord,
            |o, d, tmin, tmax| {
                let mut tests = 0;
                for g in groups {
                    tests += 4;
                    if intersect_triangle4(o, d, g, tmin, tmax).mask != 0 {
                        return (true, tests);
                    }
                }
                (false, tests)
            },
            |o, d, tmin, (mut bt, mut bp, mut bu, mut bv)| {
                for (gi, g) in groups.iter().enumerate() {
                    let h = intersect_triangle4(o, d, g, tmin, bt);
                    let mut m = h.mask;
                    while m != 0 {
                        let l = m.trailing_zeros() as usize;
                        m &= m - 1;
                        let t = ids[gi * 4 + l];
                        if closer(h.t[l], t, bt, bp) {
                            (bt, bp, bu, bv) = (h.t[l], t, h.u[l], h.v[l]);
                        }
                    }
                }
                ((bt, bp, bu, bv), nt as u64)
            },
        );
    }

    /// The ray loop both leaves share: each active ray runs `any_hit(o, d, tmin, tmax)` (any-hit
    /// tasks) or `closest(o, d, tmin, best)` (closest-hit tasks: the best `(t, prim, u, v)` so
    /// far in, the new best out), each also returning its ray/triangle test count; then the
    /// result is written back and finished rays move behind the terminated-ray pivot.
    #[inline(always)]
    fn leaf_rays(
        &mut self,
        cell: &Aabb,
        rend: usize,
        ord: Order,
        any_hit: impl Fn(Vec3, Vec3, f32, f32) -> (bool, u64),
        closest: impl Fn(Vec3, Vec3, f32, (f32, u32, f32, f32)) -> ((f32, u32, f32, f32), u64),
    ) {
        self.st.leaves += 1;
        let mut tests = 0u64;
        let mut p = self.rterm;
        while p < rend {
            let r = self.ray_idx[p] as usize;
            let i = self.base + r;
            let rec = self.recs[p].o_tmin;
            let (o, d, tmin) = (rec.truncate(), self.rays.dir(i), rec.w);
            let done = if ANY {
                let (hit, n) = any_hit(o, d, tmin, self.rays.tmax[i]);
                tests += n;
                if hit {
                    self.occ[r] = true;
                }
                // Any hit is final, in any order.
                hit
            } else {
                let best = (self.t[r], self.prim[r], self.u[r], self.v[r]);
                let ((bt, bp, bu, bv), n) = closest(o, d, tmin, best);
                tests += n;
                (self.t[r], self.prim[r], self.u[r], self.v[r]) = (bt, bp, bu, bv);
                self.recs[p].inv_tmax.w = widen(bt);
                self.terminate && bp != MISS && Self::final_hit(cell, o, d, tmin, bt, &ord)
            };
            if done {
                self.ray_idx.swap(p, self.rterm);
                self.recs.swap(p, self.rterm);
                self.rterm += 1;
            }
            p += 1;
        }
        self.st.ray_tri += tests;
    }

    /// True when the hit at `bt` is final: the hit point lies inside this leaf cell, away from
    /// its faces by a margin (so no triangle of a later cell can tie it after rounding), and
    /// every earlier stretch of the ray was visited ([`Order`]). Inside the (convex) cell means
    /// `t_enter ≤ bt ≤ t_exit`; testing the point costs no ray/box test (as in the paper, whose
    /// packet mode reports almost no ray/box tests).
    #[inline]
    fn final_hit(cell: &Aabb, o: Vec3, d: Vec3, tmin: f32, bt: f32, ord: &Order) -> bool {
        let (start, err) = if tmin == 0.0 {
            (o, 0.0)
        } else {
            let s = o + d * tmin;
            (
                s,
                (o.abs() + (d * tmin).abs()).max_element() * (4.0 * f32::EPSILON),
            )
        };
        if !ord.allows(start, err, d) {
            return false;
        }
        let step = d * bt;
        let p = o + step;
        // Per axis: rounding of p, plus a gap of 2·TERM_GAP·|bt| in t along that axis.
        let m = (o.abs() + step.abs()) * (8.0 * f32::EPSILON) + step.abs() * (2.0 * TERM_GAP);
        (p - m).cmpge(cell.min).all() && (p + m).cmple(cell.max).all()
    }

    /// [`Self::final_hit`] for four rays from `o` (directions and hits per lane), the same f32
    /// operations lane-wise, so each lane's answer is the scalar one: bit `l` set when final.
    #[inline]
    fn final_hit4(cell: &Aabb, o: Vec3, d: [Vec4; 3], tmin: f32, bt: Vec4, ord: &Order) -> u32 {
        let (zero, tm) = (Vec4::ZERO, Vec4::splat(tmin));
        let mut ok = BVec4A::splat(true);
        let mut err = zero;
        let mut start = [zero; 3];
        if tmin != 0.0 {
            // `(o.abs() + (d·tmin).abs()).max_element()`, lane-wise.
            for (a, s) in start.iter_mut().enumerate() {
                let dt = d[a] * tm;
                *s = Vec4::splat(o[a]) + dt;
                err = err.max(Vec4::splat(o[a].abs()) + dt.abs());
            }
            err *= 4.0 * f32::EPSILON;
        } else {
            start = [o.x, o.y, o.z].map(Vec4::splat);
        }
        for (a, s) in start.iter().enumerate() {
            // `Order::allows`, axis `a`.
            ok &= d[a].cmpge(zero) | (*s + err).cmple(Vec4::splat(ord.lo_min[a]));
            ok &= d[a].cmple(zero) | (*s - err).cmpge(Vec4::splat(ord.hi_max[a]));
            // The hit point inside the cell by its margin, axis `a`.
            let step = d[a] * bt;
            let p = Vec4::splat(o[a]) + step;
            let m = (Vec4::splat(o[a].abs()) + step.abs()) * (8.0 * f32::EPSILON)
                + step.abs() * (2.0 * TERM_GAP);
            ok &= (p - m).cmpge(Vec4::splat(cell.min[a])) & (p + m).cmple(Vec4::splat(cell.max[a]));
        }
        ok.bitmask()
    }

    /// In-place filter of the active cones `cone_idx[cterm..cend]` against `b`.
    fn partition_cones(&mut self, b: &Aabb, cend: usize) -> usize {
        let mut k = self.cterm;
        self.st.cone_box += (cend - self.cterm) as u64;
        if let (Some([x0, x1, y0, y1]), Packets::Tiles { tw, .. }) = (self.pixels(b), self.packets)
        {
            // A tile stays when one of its live (not terminated) pixels is inside the cell's
            // pixel rectangle: a branch-free Lomuto partition (see `partition_rays`). Pixel
            // granularity is what makes front-to-back termination cull: a cone stays alive in
            // every cell it meets while one of its 64 rays is, a pixel only where it is.
            let ids = &mut self.cone_idx[..cend];
            for p in self.cterm..cend {
                let c = ids[p] as usize;
                let live = tile_mask(c % tw, c / tw, [x0, x1, y0, y1]) & !self.cones[c].done;
                ids.swap(k, p);
                k += (live != 0) as usize;
            }
            return k;
        }
        if !self.cones_built {
            // Unreachable in exact arithmetic (every cell is inside the root, in front of the
            // eye); kept conservative should rounding make a cell's rectangle fail.
            return cend;
        }
        for p in self.cterm..cend {
            let c = &self.cones[self.cone_idx[p] as usize];
            if c.q.overlaps(self.apex, b) {
                self.cone_idx.swap(k, p);
                k += 1;
            }
        }
        k
    }

    /// The task's pixels (task-local rows) whose rays can meet `b`, when screen-space culling
    /// is on and `b` lies in front of the eye: inclusive `[x0, x1, y0, y1]`.
    #[inline]
    fn pixels(&self, b: &Aabb) -> Option<[i64; 4]> {
        let [x0, x1, y0, y1] = self.proj?.box_pixels(b, self.tol)?;
        Some([x0, x1, y0 - self.row0, y1 - self.row0])
    }

    /// Algorithm 2 on cones `cone_idx[cterm..cend]`.
    fn cone_rec(&mut self, cell: Aabb, nt: usize, cend: usize, depth: u32, ord: Order) {
        self.st.nodes += 1;
        let nc = cend - self.cterm;
        if nc == 0 || nt == 0 {
            return;
        }
        let c_limit = if self.tile_leaves {
            self.leaf_tiles
        } else {
            self.cfg.c_limit
        };
        if nc < c_limit || nt < self.cfg.p_limit || depth >= self.cfg.max_depth {
            return self.cone_leaf(cell, nt, cend, depth, ord);
        }
        let Some((axis, split)) = self.choose_split(&cell, nt) else {
            return self.cone_leaf(cell, nt, cend, depth, ord);
        };
        let low_first = match self.view {
            View::From(p) => p[axis] <= split,
            View::To(p) => p[axis] >= split,
            View::Majority => true,
        };
        // As in `ray_rec`: what the first child rejects goes to the second without a test.
        let child = half(&cell, axis, split, low_first);
        let (nt0, other) = self.partition_tris(nt, axis, split, low_first, &child);
        if nt0 == nt && other == nt {
            return self.cone_leaf(cell, nt, cend, depth, ord);
        }
        let cend0 = self.partition_cones(&child, cend);
        let ord0 = ord.child(axis, split, true, low_first);
        self.cone_rec(child, nt0, cend0, depth + 1, ord0);
        let child = half(&cell, axis, split, !low_first);
        let (k, _) = self.partition_tris(nt0, axis, split, !low_first, &child);
        let nt1 = gather_block(&mut self.tri_idx, k, nt0, nt);
        let k = self.partition_cones(&child, cend0);
        let cend1 = gather_block(&mut self.cone_idx, k, cend0, cend);
        let ord1 = ord.child(axis, split, false, !low_first);
        self.cone_rec(child, nt1, cend1, depth + 1, ord1);
    }

    /// The end of a cone recursion: a tile leaf or FlushCones.
    fn cone_leaf(&mut self, cell: Aabb, nt: usize, cend: usize, depth: u32, ord: Order) {
        if self.tile_leaves {
            let px = self.pixels(&cell);
            return self.tile_leaf(&cell, nt, cend, px, ord);
        }
        self.flush(cell, nt, cend, depth, ord)
    }

    /// A leaf over tiles (`Config::pixel_leaf`, ours): each triangle is tested against the
    /// live pixels of its rectangle ([`PixelProjection::triangle_rects4`] holds every pixel
    /// whose ray can hit it) inside the cell's rectangle `px` (or, for a cell reaching behind
    /// the eye, `None`, of the active tiles), read off the tiles' termination bits, with no
    /// ray list. A ray that can end here has its final hit on a triangle of this cell, which
    /// was tested against it and hit, so only the rays with a hit here are checked for
    /// termination; [`closer`] makes the order of the pairs irrelevant.
    fn tile_leaf(&mut self, cell: &Aabb, nt: usize, cend: usize, px: Option<[i64; 4]>, ord: Order) {
        self.st.leaves += 1;
        let Packets::Tiles { width, rows, tw } = self.packets else {
            unreachable!("tile leaves are for pinhole tiles only")
        };
        let tris = self.tris;
        let mut tests = 0u64;
        // The cell's pixels, clamped to the task's (the triangles' are).
        let (cx, cy) = match px {
            Some(px) => (
                [px[0].max(0), px[1].min(width as i64 - 1)],
                [px[2].max(0), px[3].min(rows as i64 - 1)],
            ),
            None => ([0, width as i64 - 1], [0, rows as i64 - 1]),
        };
        for q in 0..nt {
            let t = self.tri_idx[q] as usize;
            if let Some(&f) = self.tri_idx[..nt].get(q + PREFETCH) {
                let f = f as usize;
                prefetch(&self.rects, f);
                prefetch(&tris.v0, f);
                prefetch(&tris.v1, f);
                prefetch(&tris.v2, f);
            }
            let r = self.rects[t];
            let x0 = (r[0] as i64).max(cx[0]);
            let x1 = (r[1] as i64).min(cx[1]);
            let y0 = (r[2] as i64).max(cy[0]);
            let y1 = (r[3] as i64).min(cy[1]);
            if x0 > x1 || y0 > y1 {
                continue;
            }
            let rect = [x0, x1, y0, y1];
            // Set up on the first live pixel: triangles behind finished pixels (most, late in
            // a front-to-back recursion) cost only their rectangle.
            let mut tri = None;
            let mut pairs = |task: &mut Self, tile: usize| {
                let m = tile_mask(tile % tw, tile / tw, rect) & !task.cones[tile].done;
                if m != 0 {
                    let tri = tri.get_or_insert_with(|| {
                        TriFromOrigin::new(task.apex, tris.v0[t], tris.v1[t], tris.v2[t])
                    });
                    tests += task.tile_pairs(tile, m, t as u32, tri);
                }
            };
            if px.is_some() {
                // The tiles under the rectangle.
                for ty in (y0 / 8) as usize..=(y1 / 8) as usize {
                    for tx in (x0 / 8) as usize..=(x1 / 8) as usize {
                        pairs(self, ty * tw + tx);
                    }
                }
            } else {
                // No rectangle for the cell: the tiles still active in it.
                for q in self.cterm..cend {
                    pairs(self, self.cone_idx[q] as usize);
                }
            }
        }
        self.st.ray_tri += tests;
        // Termination of the rays hit here.
        let list = std::mem::take(&mut self.touched_list);
        for &tile in &list {
            let tile = tile as usize;
            let mut m = std::mem::take(&mut self.touched[tile]);
            if ANY {
                self.cones[tile].done |= m;
                continue;
            }
            if !self.terminate {
                continue;
            }
            // Four pixels at a time.
            while m != 0 {
                let (bits, lanes) = pop4(&mut m);
                let (d, bt) = self.tile_lanes(tile, bits);
                let done = Self::final_hit4(cell, self.apex, d, self.tmin0, bt, &ord);
                for (l, &b) in bits.iter().enumerate().take(lanes) {
                    self.cones[tile].done |= ((done >> l & 1) as u64) << b;
                }
            }
        }
        self.touched_list = list;
        self.touched_list.clear();
        let packets = self.packets;
        let mut q = self.cterm;
        while q < cend {
            let c = self.cone_idx[q] as usize;
            if self.cones[c].done == packets.full_mask(c, &[]) {
                self.cone_idx.swap(q, self.cterm);
                self.cterm += 1;
            }
            q += 1;
        }
    }

    /// The records of pixels `bits` of `tile` as four lanes: directions per axis and cut-offs
    /// (a 4×4 transpose: shuffles, not sixteen lane moves).
    #[inline(always)]
    fn tile_lanes(&self, tile: usize, bits: [usize; 4]) -> ([Vec4; 3], Vec4) {
        let recs = bits.map(|b| self.tile_rays[tile * 64 + b]);
        let r = Mat4::from_cols(recs[0], recs[1], recs[2], recs[3]).transpose();
        ([r.x_axis, r.y_axis, r.z_axis], r.w_axis)
    }

    /// The pairs of a tile leaf between triangle `t` (`tri`, seen from the eye, where every ray
    /// of the task starts, at `tmin0`: checked at set-up) and the pixels `m` of `tile` (live,
    /// in its rectangle), four at a time; marks the pixels hit in `touched`. Returns the number
    /// of pairs.
    #[inline(always)]
    fn tile_pairs(&mut self, tile: usize, mut m: u64, t: u32, tri: &TriFromOrigin) -> u64 {
        let Packets::Tiles { width, tw, .. } = self.packets else {
            return 0;
        };
        let (tx, ty) = (tile % tw, tile / tw);
        let n = m.count_ones() as u64;
        while m != 0 {
            let (bits, lanes) = pop4(&mut m);
            let (d, cut) = self.tile_lanes(tile, bits);
            let h = tri.intersect4(d, self.tmin0, cut);
            let mut hit = h.mask & ((1 << lanes) - 1);
            while hit != 0 {
                let l = hit.trailing_zeros() as usize;
                hit &= hit - 1;
                let bit = bits[l];
                let k = (ty * 8 + bit / 8) * width + tx * 8 + bit % 8;
                if ANY {
                    self.occ[k] = true;
                } else if closer(h.t[l], t, cut[l], self.prim[k]) {
                    self.tile_rays[tile * 64 + bit].w = h.t[l];
                    (self.prim[k], self.u[k], self.v[k]) = (t, h.u[l], h.v[l]);
                }
                if self.touched[tile] == 0 {
                    self.touched_list.push(tile as u32);
                }
                self.touched[tile] |= 1 << bit;
            }
        }
        n
    }

    /// FlushCones (Algorithm 2): the active cones' live rays that enter `cell` go to the ray
    /// list after `rterm`, Algorithm 1 runs, then terminated rays set their cone bits and fully
    /// terminated cones move behind the terminated-cone pivot.
    fn flush(&mut self, cell: Aabb, nt: usize, cend: usize, depth: u32, ord: Order) {
        let start = self.rterm;
        let mut rend = start;
        let packets = self.packets;
        let filter = self.cfg.flush_filter;
        if let (Some(px), Packets::Tiles { width, tw, .. }) = (self.pixels(&cell), packets) {
            // Screen-space culling: only the live rays of the tile inside the cell's pixels.
            for q in self.cterm..cend {
                let c = self.cone_idx[q] as usize;
                let (tx, ty) = (c % tw, c / tw);
                let mut m = tile_mask(tx, ty, px) & packets.full_mask(c, &[]) & !self.cones[c].done;
                while m != 0 {
                    let bit = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let k = (ty * 8 + bit / 8) * width + tx * 8 + bit % 8;
                    rend += self.flush_ray(&cell, rend, k, filter) as usize;
                }
            }
            return self.flushed(cell, nt, start, rend, cend, depth, ord);
        }
        for q in self.cterm..cend {
            let c = self.cone_idx[q] as usize;
            let done = self.cones[c].done;
            let perm = std::mem::take(&mut self.perm);
            packets.for_each(c, &perm, |k, bit| {
                // Live rays only, and (optionally) only those entering the cell; unfiltered
                // rays are still correct (Algorithm 1 filters them if it divides further, and
                // a naive leaf is correct for any ray).
                if done & (1u64 << bit) == 0 {
                    rend += self.flush_ray(&cell, rend, k, filter) as usize;
                }
            });
            self.perm = perm;
        }
        self.flushed(cell, nt, start, rend, cend, depth, ord)
    }

    /// Loads ray `k` into list slot `slot` for a flush of `cell`; true when it stays there (it
    /// passes the ray/box test, or `filter` is off).
    #[inline(always)]
    fn flush_ray(&mut self, cell: &Aabb, slot: usize, k: usize, filter: bool) -> bool {
        self.load_ray(slot, k);
        if !filter {
            return true;
        }
        self.st.ray_box += 1;
        cell.hit_by_packed(&self.recs[slot])
    }

    /// The rest of [`Self::flush`], once the rays `ray_idx[start..rend]` are loaded.
    #[allow(clippy::too_many_arguments)]
    fn flushed(
        &mut self,
        cell: Aabb,
        nt: usize,
        start: usize,
        rend: usize,
        cend: usize,
        depth: u32,
        ord: Order,
    ) {
        let packets = self.packets;
        self.ray_rec(cell, nt, rend, depth, ord, self.cfg.flush_filter);
        for p in start..self.rterm {
            let (c, bit) = packets.of(self.ray_idx[p] as usize, &self.perm);
            self.cones[c].done |= 1u64 << bit;
        }
        let mut q = self.cterm;
        while q < cend {
            let c = self.cone_idx[q] as usize;
            if self.cones[c].done == packets.full_mask(c, &self.perm) {
                self.cone_idx.swap(q, self.cterm);
                self.cterm += 1;
            }
            q += 1;
        }
    }

    /// Builds the cone of packet `c`, or `None` when its rays are not coherent enough.
    fn build_cone(&self, c: usize, max_angle: f32) -> Option<PackedCone> {
        let apex = self.apex;
        let rays = self.rays;
        let base = self.base;
        let mut ok = true;
        let mut far = 0.0f64;
        let mut reach = 0.0f64;
        let shadow = matches!(self.packets, Packets::Runs { .. });
        self.packets.for_each(c, &self.perm, |k, _| {
            let i = base + k;
            let (o, d) = (rays.origin(i), rays.dir(i));
            if shadow {
                // Segment o → o + d with t in [0, 1] must end (up to rounding) at the light.
                ok &= rays.tmin[i] >= 0.0 && rays.tmax[i] <= 1.0 && o != apex;
                far = far.max((o.as_dvec3() + d.as_dvec3() - apex.as_dvec3()).length());
                reach = reach.max((o.as_dvec3() - apex.as_dvec3()).length());
            } else {
                ok &= o == apex && rays.tmin[i] >= 0.0;
            }
            ok &= d.is_finite() && d != Vec3::ZERO;
        });
        if !ok {
            return None;
        }
        let dirs = |k: usize| {
            let i = base + k;
            if shadow {
                rays.origin(i) - apex
            } else {
                rays.dir(i)
            }
        };
        // Collect the packet's directions without allocating: iterate twice via for_each.
        let mut buf = [Vec3::ZERO; 64];
        let mut n = 0;
        self.packets.for_each(c, &self.perm, |k, _| {
            buf[n] = dirs(k);
            n += 1;
        });
        let cone = Cone::around_directions(apex, buf[..n].iter().copied())?;
        let (mut half, mut near, mut cut) = (cone.half_angle, 0.0f32, f32::INFINITY);
        if shadow {
            // The rays end `far` away from the light, not on it: points farther than
            // `near = 2^14·far` from the light deviate from the ideal direction by less than
            // 2^-14 rad, covered by widening the angle; boxes closer than `near` count as hit.
            let scale = apex.abs().max_element() as f64 * (f32::EPSILON as f64);
            near = ((far + 4.0 * scale) * 16384.0) as f32;
            half += 2.0 / 16384.0;
            // Segments end at their origins: nothing beyond `reach` (+ the rounding `far`).
            cut = ((reach + 2.0 * far) * (1.0 + 1e-6)) as f32 + near;
        }
        // NaN angles are refused too.
        if half.is_nan() || half > max_angle || half >= std::f32::consts::FRAC_PI_2 {
            return None;
        }
        let cos = (half as f64).cos();
        Some(PackedCone {
            q: ConeQuery::new(cone.axis, cos * cos, near, cut),
            done: 0,
        })
    }
}

/// The shadow-packet order of rays `range` (see [`Task::perm`]): sorted by a 30-bit Morton code
/// of the origin in `bounds` (in place, no further allocation), then each entry's high half is
/// overwritten with the inverse permutation.
fn morton_order(
    mut v: Vec<u64>,
    rays: &RayBatch,
    range: Range<usize>,
    bounds: &Aabb,
    huge: bool,
) -> Vec<u64> {
    fn spread(x: u32) -> u64 {
        let mut x = (x & 0x3ff) as u64;
        x = (x | x << 16) & 0x0300_00ff;
        x = (x | x << 8) & 0x0300_f00f;
        x = (x | x << 4) & 0x030c_30c3;
        (x | x << 2) & 0x0924_9249
    }
    let scale = Vec3::splat(1023.0) / bounds.extent().max(Vec3::splat(f32::MIN_POSITIVE));
    reserve_exact_huge(&mut v, range.len(), huge);
    v.extend(range.clone().enumerate().map(|(k, i)| {
        let q = ((rays.origin(i) - bounds.min) * scale).clamp(Vec3::ZERO, Vec3::splat(1023.0));
        let code = spread(q.x as u32) | spread(q.y as u32) << 1 | spread(q.z as u32) << 2;
        code << 32 | k as u64
    }));
    v.sort_unstable();
    for j in 0..v.len() {
        let k = v[j] as u32 as usize;
        v[k] = (v[k] & 0xffff_ffff) | (j as u64) << 32;
    }
    v
}

/// The bits (`8·row + column`) of tile `(tx, ty)` inside the inclusive pixel rectangle
/// `[x0, x1] × [y0, y1]`.
#[inline]
fn tile_mask(tx: usize, ty: usize, [x0, x1, y0, y1]: [i64; 4]) -> u64 {
    let low = |n: i64| if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
    let (bx, by) = (tx as i64 * 8, ty as i64 * 8);
    // Half-open column and row ranges inside the tile.
    let (c0, c1) = ((x0 - bx).clamp(0, 8), (x1 - bx + 1).clamp(0, 8));
    let (r0, r1) = ((y0 - by).clamp(0, 8), (y1 - by + 1).clamp(0, 8));
    if c0 >= c1 || r0 >= r1 {
        return 0;
    }
    let cols = low(c1) & !low(c0);
    // One 0x01 byte per row of the range.
    let rows = (low(8 * r1) & !low(8 * r0)) / 0xff;
    cols * rows
}

/// Up to four set bits of `m`, lowest first, taken out of it, and how many: a group of lanes.
/// Missing lanes repeat the first (callers ignore their results).
#[inline(always)]
fn pop4(m: &mut u64) -> ([usize; 4], usize) {
    let mut bits = [m.trailing_zeros() as usize; 4];
    let mut lanes = 0;
    while *m != 0 && lanes < 4 {
        bits[lanes] = m.trailing_zeros() as usize;
        *m &= *m - 1;
        lanes += 1;
    }
    (bits, lanes)
}

/// How many triangles ahead the list loops prefetch their scattered data.
const PREFETCH: usize = 16;

/// The same distance for the split-plane filter, whose loop is a few cycles per triangle: the
/// gathered bounds must be asked for further ahead (perf put 40% of the filter on the first
/// use of a bound at 16 ahead; the dragon's filters took 13 instead of 18 ms at 128).
const SPLIT_PREFETCH: usize = 128;

/// Hints the CPU to bring `v[i]` into the cache: the triangle lists are walked in order but
/// the data of their triangles is scattered (on the 871K dragon's tile leaves, prefetching
/// [`PREFETCH`] triangles ahead measured 10% faster). No effect on any result.
#[inline(always)]
fn prefetch<T>(v: &[T], i: usize) {
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

/// `v` filled with the rays of the `width × rows` band starting at ray `base`, in tile order
/// (slot `64·tile + bit`): direction and `tmax` (zero records pad the tiles of a short band).
fn tile_ordered_rays(
    mut v: Vec<Vec4>,
    rays: &RayBatch,
    base: usize,
    width: usize,
    rows: usize,
    huge: bool,
) -> Vec<Vec4> {
    reserve_exact_huge(&mut v, width.div_ceil(8) * rows.div_ceil(8) * 64, huge);
    for ty in 0..rows.div_ceil(8) {
        for tx in 0..width.div_ceil(8) {
            for bit in 0..64 {
                let (x, y) = (tx * 8 + bit % 8, ty * 8 + bit / 8);
                v.push(if x < width && y < rows {
                    let i = base + y * width + x;
                    rays.dir(i).extend(rays.tmax[i])
                } else {
                    Vec4::ZERO
                });
            }
        }
    }
    v
}

/// The largest deviation of the rays of a pinhole band (first row: image row `base / width`)
/// from their pixels, an upper bound ([`PixelProjection::deviation4`], f32, four rays at a
/// time), when every ray starts at `eye` with the first ray's `tmin` (at least 0) and the bound
/// is at most [`MAX_PIXEL_DEVIATION`]; `None` otherwise. Read-only, so a batch that fails
/// allocates nothing for tile leaves. Memory-bound like the exact f64 check of a fixed
/// tolerance it replaces (about 9 ms each on 1024² rays, measured in one run), but it measures
/// the bound, so jittered rays need no second, per-ray f64 pass.
fn pinhole_deviation(
    rays: &RayBatch,
    base: usize,
    width: usize,
    rows: usize,
    proj: &PixelProjection,
    eye: Vec3,
) -> Option<f64> {
    let tmin0 = rays.tmin[base];
    // NaN-safe: a NaN `tmin` fails too.
    if tmin0.is_nan() || tmin0 < 0.0 {
        return None;
    }
    let row0 = base / width;
    let (ex, ey, ez, et) = (
        Vec4::splat(eye.x),
        Vec4::splat(eye.y),
        Vec4::splat(eye.z),
        Vec4::splat(tmin0),
    );
    let mut dev = Vec4::ZERO;
    for y in 0..rows {
        for x in (0..width).step_by(4) {
            // A short last group repeats the row's last ray (a bound for another pixel: only
            // the valid lanes count).
            let valid = (width - x).min(4);
            let i = base + y * width + x;
            let load = |a: &[f32]| -> Vec4 {
                if valid == 4 {
                    Vec4::from_slice(&a[i..i + 4])
                } else {
                    Vec4::from_array(std::array::from_fn(|l| a[i + l.min(valid - 1)]))
                }
            };
            let d = [&rays.dx, &rays.dy, &rays.dz].map(|a| load(a));
            let from_eye = load(&rays.ox).cmpeq(ex)
                & load(&rays.oy).cmpeq(ey)
                & load(&rays.oz).cmpeq(ez)
                & load(&rays.tmin).cmpeq(et);
            let e = proj.deviation4(d, x as u32, (row0 + y) as u32);
            // NaN-safe: a NaN bound fails the comparison.
            let ok = from_eye & e.cmple(Vec4::splat(MAX_PIXEL_DEVIATION as f32));
            let want = (1 << valid) - 1;
            if ok.bitmask() & want != want {
                return None;
            }
            let lanes = BVec4A::from_array(std::array::from_fn(|l| l < valid));
            dev = dev.max(Vec4::select(lanes, e, Vec4::ZERO));
        }
    }
    Some(dev.max_element() as f64)
}

/// Calls `f(k, j)` for every pixel of a `width × rows` band: `k` its index in the band (row
/// by row), `j` its slot in tile order (`64·tile + bit`, as [`Packets::of`]).
#[inline]
fn for_each_tile_slot(width: usize, rows: usize, mut f: impl FnMut(usize, usize)) {
    let tw = width.div_ceil(8);
    for y in 0..rows {
        let row = (y / 8) * tw * 64 + (y % 8) * 8;
        for x in 0..width {
            f(y * width + x, row + (x / 8) * 64 + x % 8);
        }
    }
}

/// Moves the block `v[a..e]` to start at `k <= a` (by swaps; the displaced entries end up after
/// it) and returns the block's new end `k + (e − a)`: after filtering `v[..a]` into `v[..k]`,
/// this appends the entries known to be kept without a test.
#[inline]
fn gather_block<T>(v: &mut [T], k: usize, a: usize, e: usize) -> usize {
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

/// The low or high half of `cell` at `split` on `axis` (both closed, sharing the plane).
#[inline]
fn half(cell: &Aabb, axis: usize, split: f32, low: bool) -> Aabb {
    let mut c = *cell;
    if low {
        c.max[axis] = split;
    } else {
        c.min[axis] = split;
    }
    c
}

impl Dacrt {
    fn plan(&self, rays: &RayBatch) -> (Plan, Packets) {
        let k = self.tasks();
        let n = rays.len();
        let mode = self.cfg.mode;
        let packets_ok = matches!(mode, Mode::Auto | Mode::Packet);
        match rays.layout {
            RayLayout::Pinhole { eye, width, height }
                if width as usize * height as usize == n && n > 0 =>
            {
                let (w, h) = (width as usize, height as usize);
                // Bands of whole tile rows.
                let rows = h.div_ceil(8).div_ceil(k) * 8;
                let corners = [0, w - 1, (h - 1) * w, h * w - 1].map(|k| rays.dir(k));
                let plan = Plan {
                    terminate: mode != Mode::Random,
                    packets: packets_ok,
                    view: View::From(eye),
                    chunk: rows * w,
                    proj: (packets_ok && (self.cfg.screen_cull || self.cfg.pixel_cull))
                        .then(|| PixelProjection::fit(eye, width, height, corners))
                        .flatten(),
                };
                (
                    plan,
                    Packets::Tiles {
                        width: w,
                        rows,
                        tw: w.div_ceil(8),
                    },
                )
            }
            RayLayout::ToPoint { target } => {
                let chunk = n.div_ceil(64).div_ceil(k).max(1) * 64;
                let plan = Plan {
                    terminate: mode != Mode::Random,
                    packets: packets_ok && self.cfg.max_shadow_cone_deg > 0.0,
                    view: View::To(target),
                    chunk,
                    proj: None,
                };
                (plan, Packets::Runs { len: chunk })
            }
            _ => {
                let plan = Plan {
                    terminate: mode == Mode::Ray || mode == Mode::Packet,
                    packets: false,
                    view: View::Majority,
                    chunk: n.div_ceil(k).max(1),
                    proj: None,
                };
                (plan, Packets::None)
            }
        }
    }

    /// Runs one task over rays `range` (outputs already reset to misses).
    #[allow(clippy::too_many_arguments)]
    fn run_task<const ANY: bool>(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        range: Range<usize>,
        plan: &Plan,
        packets: Packets,
        t: &mut [f32],
        prim: &mut [u32],
        u: &mut [f32],
        v: &mut [f32],
        occ: &mut [bool],
    ) -> Tally<Counts> {
        let ntri = scene.len();
        let len = range.len();
        let huge = self.cfg.huge_pages;
        // Restrict the packet layout to this task's share (the last band may be shorter).
        let packets = match (plan.packets, packets) {
            (true, Packets::Tiles { width, tw, .. }) => Packets::Tiles {
                width,
                rows: len / width,
                tw,
            },
            (true, Packets::Runs { .. }) => Packets::Runs { len },
            _ => Packets::None,
        };
        let apex = match plan.view {
            View::From(p) | View::To(p) => p,
            View::Majority => Vec3::ZERO,
        };
        let ncones = packets.count();
        // This share's pool slot (shares are `plan.chunk` rays, in order).
        let slot = self.pool.get(range.start / plan.chunk.max(1));
        let sc = slot
            .and_then(|m| m.lock().ok().map(|mut g| std::mem::take(&mut *g)))
            .unwrap_or_default();
        // Filled by `live_triangles`.
        let tri_idx = reuse(sc.tri_idx, ntri, huge);
        let mut cones = reuse(sc.cones, ncones, huge);
        cones.resize(
            ncones,
            PackedCone {
                q: ConeQuery::default(),
                done: 0,
            },
        );
        let mut perm = reuse(sc.perm, 0, huge);
        if let Packets::Runs { .. } = packets {
            perm = morton_order(perm, rays, range.clone(), &scene.bounds(), huge);
        }
        let mut task = Task::<ANY> {
            cfg: &self.cfg,
            tris: scene.triangles(),
            span: [&self.span[0], &self.span[1], &self.span[2]],
            rays,
            base: range.start,
            t,
            prim,
            u,
            v,
            occ,
            tri_idx,
            ray_idx: reuse(sc.ray_idx, 0, huge),
            recs: reuse(sc.recs, 0, huge),
            rterm: 0,
            terminate: plan.terminate,
            view: plan.view,
            packets,
            apex,
            proj: None,
            tol: 0.0,
            row0: 0,
            cones_built: true,
            cones,
            cone_idx: reuse(sc.cone_idx, ncones, huge),
            perm,
            cterm: 0,
            tile_leaves: false,
            leaf_tiles: self.cfg.pixel_leaf_c_limit,
            // Filled by the projection pass, in triangle order.
            rects: reuse(sc.rects, 0, huge),
            tile_rays: reuse(sc.tile_rays, 0, huge),
            tmin0: 0.0,
            touched: reuse(sc.touched, 0, huge),
            touched_list: reuse(sc.touched_list, 0, huge),
            st: Counts::default(),
            peak: 0,
        };
        let root = scene.bounds();
        let max_angle = match packets {
            Packets::Runs { .. } => self.cfg.max_shadow_cone_deg,
            _ => self.cfg.max_cone_deg,
        }
        .to_radians();
        let mut cull = None;
        if let (Some(proj), Packets::Tiles { width, rows, .. }) = (plan.proj, packets) {
            // Screen-space culling with the largest deviation of a ray from its pixel (rounding
            // for exact pinhole rays; up to about a pixel for jittered ones), for rays from the
            // eye (the layout is only a hint).
            let row0 = range.start / width;
            let tiles_fit = width <= 1 << 16 && rows <= 1 << 16;
            // With tile leaves, the rays' deviation is bounded in f32, four at a time, with
            // their origins and `tmin`. Otherwise, or when that fails, exact pinhole rays pass
            // a fixed tolerance without a division per ray, and other rays have their largest
            // deviation measured.
            let mut tol = PINHOLE_TOL;
            let mut pinhole = false;
            if self.cfg.pixel_leaf && tiles_fit {
                if let Some(dev) = pinhole_deviation(rays, range.start, width, rows, &proj, apex) {
                    (pinhole, tol) = (true, dev);
                }
            }
            let mut from_eye = true;
            if !pinhole {
                for (y, row) in range.clone().step_by(width).enumerate() {
                    for (x, i) in (row..row + width).enumerate() {
                        from_eye &= rays.origin(i) == apex && rays.tmin[i] >= 0.0;
                        if !proj.within(rays.dir(i), x, row0 + y, tol) {
                            tol = -1.0;
                        }
                    }
                }
            }
            if tol < 0.0 {
                tol = 0.0;
                for (y, row) in range.clone().step_by(width).enumerate() {
                    for (x, i) in (row..row + width).enumerate() {
                        let e = proj.deviation(rays.dir(i), x, row0 + y);
                        // NaN-safe: a NaN deviation makes `tol` NaN, refused below.
                        tol = if e > tol || e.is_nan() { e } else { tol };
                    }
                }
            }
            if from_eye && tol <= MAX_PIXEL_DEVIATION {
                if self.cfg.screen_cull {
                    (task.proj, task.tol, task.row0) = (Some(proj), tol, row0 as i64);
                    // Every cell lies in front of the eye when the root does: the cones would
                    // never be tested, and are not built (see `partition_cones`).
                    task.cones_built = task.pixels(&scene.bounds()).is_none();
                }
                let tmin0 = rays.tmin[range.start];
                let uniform = pinhole || rays.tmin[range.clone()].iter().all(|&t| t == tmin0);
                if self.cfg.pixel_leaf && uniform && tiles_fit {
                    task.tile_leaves = true;
                    task.tmin0 = tmin0;
                    let tr = std::mem::take(&mut task.tile_rays);
                    task.tile_rays = tile_ordered_rays(tr, rays, range.start, width, rows, huge);
                    reserve_exact_huge(&mut task.rects, ntri, huge);
                    reserve_exact_huge(&mut task.touched, ncones, huge);
                    task.touched.resize(ncones, 0);
                    reserve_exact_huge(&mut task.touched_list, ncones, huge);
                }
                if self.cfg.pixel_cull || task.tile_leaves {
                    let ys = [row0 as i64, (row0 + rows) as i64 - 1];
                    cull = Some((proj, tol, ys, self.cfg.pixel_cull));
                }
            }
        }
        if !ANY && !task.tile_leaves {
            // The z-buffer starts at `tmax` (tile leaves keep theirs in `tile_rays`).
            for k in 0..len {
                task.t[k] = rays.tmax[range.start + k];
            }
        }
        if !task.tile_leaves {
            reserve_exact_huge(&mut task.ray_idx, len, huge);
            task.ray_idx.resize(len, 0);
            reserve_exact_huge(&mut task.recs, len, huge);
            task.recs.resize(len, RayRec::default());
        }
        task.peak = (4 * ntri + CONE_BYTES * ncones + 8 * task.perm.len()) as u64
            + if task.tile_leaves {
                (8 * ntri + (12 + 1024) * ncones) as u64
            } else {
                36 * len as u64
            };
        // Packets first: coherent ones become cones, the rays of the others go to the ray list
        // (with tile leaves, which need no cones to be correct, they stay tiles with a cone
        // that meets every box).
        let mut rend = 0;
        for c in 0..ncones {
            if !task.cones_built {
                task.cone_idx.push(c as u32);
                continue;
            }
            match task.build_cone(c, max_angle) {
                Some(cone) => {
                    task.cones[c] = cone;
                    task.cone_idx.push(c as u32);
                }
                None if task.tile_leaves => {
                    task.cones[c].q = ConeQuery::new(Vec3::Z, 0.0, f32::INFINITY, f32::INFINITY);
                    task.cone_idx.push(c as u32);
                }
                None => {
                    let perm = std::mem::take(&mut task.perm);
                    packets.for_each(c, &perm, |k, _| {
                        task.load_ray(rend, k);
                        rend += 1;
                    });
                    task.perm = perm;
                }
            }
        }
        if ncones == 0 {
            for k in 0..len {
                task.load_ray(k, k);
            }
            rend = len;
        }
        // Rays (all of them, or those of incoherent packets): Algorithm 1 from the root.
        let rend = task.partition_rays(&root, rend);
        let nlive = match cull {
            Some((proj, tol, ys, cull)) => task.project_triangles(&proj, tol, ys, cull),
            None => task.live_triangles(),
        };
        task.ray_rec(root, nlive, rend, 0, Order::NONE, true);
        if !task.cone_idx.is_empty() {
            // Cones: Algorithm 2 from the root; the ray list is free again, and the recursion
            // only permuted the triangle list's prefix `[0, nlive)`.
            task.rterm = 0;
            let cend = task.cone_idx.len();
            let cend = task.partition_cones(&root, cend);
            task.cone_rec(root, nlive, cend, 0, Order::NONE);
        }
        if !ANY && task.tile_leaves {
            let Packets::Tiles { width, rows, .. } = packets else {
                unreachable!("tile leaves are for pinhole tiles only")
            };
            for_each_tile_slot(width, rows, |k, j| {
                task.t[k] = if task.prim[k] == MISS {
                    f32::INFINITY
                } else {
                    task.tile_rays[j].w
                };
            });
        } else if !ANY {
            for k in 0..len {
                if task.prim[k] == MISS {
                    task.t[k] = f32::INFINITY;
                }
            }
        }
        // The buffers go back to this share's slot for the next call.
        if let Some(Ok(mut g)) = slot.map(|m| m.lock()) {
            *g = Scratch {
                tri_idx: task.tri_idx,
                ray_idx: task.ray_idx,
                recs: task.recs,
                cones: task.cones,
                cone_idx: task.cone_idx,
                perm: task.perm,
                rects: task.rects,
                tile_rays: task.tile_rays,
                touched: task.touched,
                touched_list: task.touched_list,
            };
        }
        Tally {
            counts: task.st,
            peak_bytes: task.peak,
        }
    }
}

crate::counters! {
    /// What a `dacrt` trace counts.
    pub struct Counts {
        /// Ray/box tests (a ray filtered against a cell).
        ray_box,
        /// Ray/triangle tests.
        ray_tri,
        /// Triangle/box tests (a triangle filtered against a cell: split plane, and edge axes below `sat_threshold`).
        tri_box,
        /// Cone/box tests (a conic packet against a cell).
        cone_box,
        /// Cells divided (interior steps of the recursion).
        nodes,
        /// Naive leaves (and tile leaves).
        leaves,
    }
}

crate::counters! {
    /// What a `dacrt` prepare makes.
    pub struct Built {
        /// Triangles whose per-axis min/max lists were written.
        triangles,
    }
}

/// One line per option, for `raysift tracers --verbose` (details on [`Config`]'s fields).
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc { key: "r_limit", doc: "naive leaf when fewer active rays than this (paper: 20)" },
    OptionDoc { key: "p_limit", doc: "naive leaf when fewer triangles than this (paper: 16)" },
    OptionDoc { key: "leaf_pairs", doc: "divide a small cell on while its naive leaf would test more pairs than this (ours; usize::MAX: the paper's rule)" },
    OptionDoc { key: "c_limit", doc: "flush cones to rays when fewer active cones than this" },
    OptionDoc { key: "sat_threshold", doc: "edge-axis triangle/box test on streams smaller than this (paper: 100; 0: never)" },
    OptionDoc { key: "split_sample_threshold", doc: "sampled split position for streams of at least this many triangles (paper: 10000)" },
    OptionDoc { key: "split_sample_stride", doc: "sample every n-th triangle for the split position (paper: 50)" },
    OptionDoc { key: "mode", doc: "auto, packet, ray or random" },
    OptionDoc { key: "max_depth", doc: "recursion depth cap (leaves are naive beyond it)" },
    OptionDoc { key: "tasks", doc: "parallel tasks over disjoint shares of the rays (0: rayon threads)" },
    OptionDoc { key: "max_cone_deg", doc: "camera packets with a wider cone half-angle (degrees) are traced as rays" },
    OptionDoc { key: "max_shadow_cone_deg", doc: "the same for shadow packets from a light (0: no shadow packets)" },
    OptionDoc { key: "flush_filter", doc: "flushed cones keep only the rays entering the cell" },
    OptionDoc { key: "screen_cull", doc: "camera packets: cull cells by their projection onto the image instead of the tiles' cones (ours)" },
    OptionDoc { key: "pixel_cull", doc: "camera batches: drop triangles that cover no pixel centre (ours)" },
    OptionDoc { key: "pixel_leaf", doc: "camera batches: tile leaves testing each triangle against the pixels of its rectangle (ours)" },
    OptionDoc { key: "pixel_leaf_c_limit", doc: "tile leaf when fewer active tiles than this" },
    OptionDoc { key: "huge_pages", doc: "ask Linux for transparent huge pages for the per-call buffers" },
];

/// The paper's small limits and ours pushed to their extremes (deep recursions everywhere),
/// over three tasks.
macro_rules! tiny {
    ($mode:literal) => {
        &[
            ("mode", $mode),
            ("tasks", "3"),
            ("r_limit", "2"),
            ("p_limit", "2"),
            ("c_limit", "1"),
            ("sat_threshold", "1000"),
            ("split_sample_threshold", "64"),
            ("split_sample_stride", "3"),
            ("max_depth", "40"),
            ("leaf_pairs", "0"),
            ("max_cone_deg", "60"),
            ("max_shadow_cone_deg", "60"),
            ("pixel_leaf_c_limit", "1"),
        ]
    };
}

/// Configurations the conformance suite checks besides the defaults: every mode with one task
/// and with tiny limits over three tasks, the paper's cones and leaf rule, flushes, shadow
/// packets, and no huge pages.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "packet",
        opts: &[("mode", "packet"), ("tasks", "1")],
    },
    Preset {
        name: "ray",
        opts: &[("mode", "ray"), ("tasks", "1")],
    },
    Preset {
        name: "random",
        opts: &[("mode", "random"), ("tasks", "1")],
    },
    Preset {
        name: "auto",
        opts: &[("mode", "auto"), ("tasks", "1")],
    },
    Preset {
        name: "packet tiny",
        opts: tiny!("packet"),
    },
    Preset {
        name: "ray tiny",
        opts: tiny!("ray"),
    },
    Preset {
        name: "random tiny",
        opts: tiny!("random"),
    },
    Preset {
        name: "auto tiny",
        opts: tiny!("auto"),
    },
    Preset {
        name: "wide cones, no flush filter, no pixel culling or tile leaves",
        opts: &[
            ("mode", "packet"),
            ("tasks", "2"),
            ("max_cone_deg", "80"),
            ("max_shadow_cone_deg", "80"),
            ("flush_filter", "false"),
            ("pixel_cull", "false"),
            ("pixel_leaf", "false"),
        ],
    },
    Preset {
        name: "paper's leaf rule, ray",
        opts: &[
            ("mode", "ray"),
            ("tasks", "2"),
            ("leaf_pairs", "18446744073709551615"),
        ],
    },
    Preset {
        name: "paper's leaf rule, random",
        opts: &[
            ("mode", "random"),
            ("tasks", "2"),
            ("leaf_pairs", "18446744073709551615"),
        ],
    },
    Preset {
        name: "cones never flushed, shadow packets",
        opts: &[
            ("mode", "packet"),
            ("tasks", "1"),
            ("c_limit", "100000"),
            ("max_shadow_cone_deg", "30"),
        ],
    },
    Preset {
        name: "paper's cones with tile leaves",
        opts: &[
            ("mode", "packet"),
            ("tasks", "2"),
            ("screen_cull", "false"),
            ("pixel_leaf", "true"),
            ("c_limit", "4"),
            ("pixel_leaf_c_limit", "4"),
            ("p_limit", "4"),
        ],
    },
    Preset {
        name: "paper's cones flushed to rays",
        opts: &[
            ("mode", "packet"),
            ("tasks", "2"),
            ("screen_cull", "false"),
            ("pixel_leaf", "false"),
            ("c_limit", "4"),
            ("pixel_leaf_c_limit", "4"),
            ("p_limit", "4"),
        ],
    },
    Preset {
        name: "flushes, no huge pages",
        opts: &[
            ("mode", "packet"),
            ("tasks", "1"),
            ("pixel_leaf", "false"),
            ("huge_pages", "false"),
        ],
    },
];

/// Counter docs, for the registry: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (
    <Built as crate::tracer::CounterSet>::DOCS,
    <Counts as crate::tracer::CounterSet>::DOCS,
);

impl Tracer for Dacrt {
    fn name(&self) -> &'static str {
        "dacrt"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        self.stamp = Stamp::default();
        let tris = scene.triangles();
        let n = tris.len();
        let huge = self.cfg.huge_pages;
        for v in &mut self.span {
            reserve_exact_huge(v, n, huge);
        }
        for t in 0..n {
            let [a, b, c] = tris.get(t);
            let degenerate = a == b && b == c;
            let (mn, mx) = if degenerate {
                (Vec3::INFINITY, Vec3::NEG_INFINITY)
            } else {
                (a.min(b).min(c), a.max(b).max(c))
            };
            for k in 0..3 {
                self.span[k].push([mn[k], mx[k]]);
            }
        }
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
        if scene.is_empty() || rays.is_empty() {
            hits.reset(rays.len());
            if let Some(c) = cost {
                c.reset(rays.len());
            }
            return Ok(Stats::traced(rays.len(), &Counts::default()));
        }
        let (plan, packets) = self.plan(rays);
        let tally: Tally<Counts> =
            par_ray_chunks(rays, hits, cost, plan.chunk, |range, out, _cost| {
                self.run_task::<false>(
                    scene,
                    rays,
                    range,
                    &plan,
                    packets,
                    out.t,
                    out.prim,
                    out.u,
                    out.v,
                    &mut [],
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
        if scene.is_empty() || rays.is_empty() {
            occluded.clear();
            occluded.resize(rays.len(), false);
            if let Some(c) = cost {
                c.reset(rays.len());
            }
            return Ok(Stats::traced(rays.len(), &Counts::default()));
        }
        let (plan, packets) = self.plan(rays);
        let tally: Tally<Counts> =
            par_occlusion_chunks(rays, occluded, cost, plan.chunk, |range, out, _cost| {
                self.run_task::<true>(
                    scene,
                    rays,
                    range,
                    &plan,
                    packets,
                    &mut [],
                    &mut [],
                    &mut [],
                    &mut [],
                    out,
                )
            });
        Ok(tally.into_stats(rays.len()))
    }

    fn bytes(&self) -> usize {
        let pool: usize = self
            .pool
            .iter()
            .map(|m| m.lock().map_or(0, |g| g.bytes()))
            .sum();
        self.span.iter().map(|v| v.capacity() * 8).sum::<usize>() + pool
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_defaults_are_the_papers_except_sat() {
        let c: Config = crate::tracers::config_from_opts("dacrt", &[]).unwrap();
        assert_eq!(c, Config::default());
        assert_eq!((c.r_limit, c.p_limit, c.sat_threshold), (20, 16, 0));
        // Shadow packets off by default (measured slower than rays on 3 of 4 scenes).
        assert_eq!(c.max_shadow_cone_deg, 0.0);
        assert_eq!(
            (c.split_sample_threshold, c.split_sample_stride),
            (10_000, 50)
        );
        let o = [("mode".to_string(), "random".to_string())];
        let c: Config = crate::tracers::config_from_opts("dacrt", &o).unwrap();
        assert_eq!(c.mode, Mode::Random);
    }

    #[test]
    fn gather_block_appends_the_block() {
        // Every (k, a, e) on 12 entries: the block lands at [k, k + e − a), as a set, and the
        // whole is still a permutation.
        for a in 0..=12usize {
            for e in a..=12 {
                for k in 0..=a {
                    let mut v: Vec<u32> = (0..12).collect();
                    let end = gather_block(&mut v, k, a, e);
                    assert_eq!(end, k + e - a);
                    assert_eq!(&v[..k], &(0..k as u32).collect::<Vec<_>>()[..]);
                    let mut got = v[k..end].to_vec();
                    got.sort();
                    assert_eq!(got, (a as u32..e as u32).collect::<Vec<_>>(), "{k} {a} {e}");
                    let mut all = v.clone();
                    all.sort();
                    assert_eq!(all, (0..12).collect::<Vec<_>>());
                }
            }
        }
    }

    #[test]
    fn full_mask_is_the_bits_visited() {
        let perm: Vec<u64> = (0..150u64).map(|k| k | k << 32).collect();
        let runs = Packets::Runs { len: 150 };
        for (width, rows) in [(8, 8), (13, 16), (20, 5), (3, 21), (64, 64)] {
            let tiles = Packets::Tiles {
                width,
                rows,
                tw: width.div_ceil(8),
            };
            for p in [tiles, runs] {
                for c in 0..p.count() {
                    let mut m = 0u64;
                    p.for_each(c, &perm, |_, b| m |= 1 << b);
                    assert_eq!(p.full_mask(c, &perm), m, "{p:?} packet {c}");
                }
            }
        }
    }

    #[test]
    fn packet_maps_are_inverse() {
        let rays = crate::rays::generate::random_in_box(&Aabb::new(Vec3::ZERO, Vec3::ONE), 1000, 1);
        let perm = morton_order(
            Vec::new(),
            &rays,
            0..1000,
            &Aabb::new(Vec3::ZERO, Vec3::ONE),
            true,
        );
        for (packets, n) in [
            (
                Packets::Tiles {
                    width: 37,
                    rows: 27,
                    tw: 5,
                },
                37 * 27,
            ),
            (Packets::Runs { len: 1000 }, 1000),
        ] {
            let mut seen = vec![false; n];
            for c in 0..packets.count() {
                let mut n = 0;
                packets.for_each(c, &perm, |k, bit| {
                    assert!(!seen[k]);
                    seen[k] = true;
                    assert_eq!(packets.of(k, &perm), (c, bit));
                    n += 1;
                });
                assert_eq!(packets.full_mask(c, &perm).count_ones(), n);
            }
            assert!(seen.iter().all(|&s| s), "{packets:?}");
        }
        // Tile-order slots agree with the packet map, row by row.
        let (width, rows) = (37, 27);
        let packets = Packets::Tiles { width, rows, tw: 5 };
        let mut next = 0;
        for_each_tile_slot(width, rows, |k, j| {
            assert_eq!(k, next);
            next += 1;
            let (c, bit) = packets.of(k, &[]);
            assert_eq!(j, 64 * c + bit as usize);
        });
        assert_eq!(next, width * rows);
    }

    /// The four-lane termination test answers as the scalar one on every lane: random rays
    /// and hits around random cells and orders, with and without `tmin`, zero components.
    #[test]
    fn final_hit4_is_final_hit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        let (mut yes, mut no) = (0, 0);
        for n in 0..50_000 {
            let mut r = |s: f32| rng.gen_range(-s..s);
            let lo = Vec3::new(r(1.0), r(1.0), r(1.0));
            let cell = Aabb::new(lo, lo + Vec3::new(r(1.0), r(1.0), r(1.0)).abs());
            let mut ord = Order::NONE;
            for _ in 0..(n % 4) {
                let a = (r(3.0).abs() as usize).min(2);
                ord = ord.child(a, r(1.5), true, r(1.0) > 0.0);
            }
            let o = Vec3::new(r(2.0), r(2.0), r(2.0));
            let tmin = if n % 3 == 0 { r(0.1).abs() } else { 0.0 };
            let mut d = [Vec4::ZERO; 3];
            let mut bt = Vec4::ZERO;
            for l in 0..4 {
                // Aim at a point in or near the cell, hit at about that distance.
                let target =
                    cell.min + (cell.max - cell.min) * Vec3::new(r(1.3), r(1.3), r(1.3)).abs();
                let mut dir = target - o;
                if n % 5 == 0 {
                    dir[l % 3] = 0.0;
                }
                for a in 0..3 {
                    d[a][l] = dir[a];
                }
                bt[l] = 1.0 + r(0.05);
            }
            let mask = Task::<false>::final_hit4(&cell, o, d, tmin, bt, &ord);
            for l in 0..4 {
                let dir = Vec3::new(d[0][l], d[1][l], d[2][l]);
                let f = Task::<false>::final_hit(&cell, o, dir, tmin, bt[l], &ord);
                assert_eq!(f, mask >> l & 1 == 1, "case {n} lane {l}");
                if f {
                    yes += 1
                } else {
                    no += 1
                }
            }
        }
        assert!(yes > 10_000 && no > 10_000, "{yes} final, {no} not");
    }

    #[test]
    fn order_rule() {
        // Low child first at x = 0: rays must go +x, or start at or below the plane.
        let o = Order::NONE.child(0, 0.0, true, true);
        assert!(o.allows(Vec3::new(-1.0, 0.0, 0.0), 0.0, Vec3::X));
        assert!(o.allows(Vec3::new(-1.0, 0.0, 0.0), 0.0, -Vec3::X));
        assert!(o.allows(Vec3::ZERO, 0.0, -Vec3::X));
        assert!(!o.allows(Vec3::new(1.0, 0.0, 0.0), 0.0, -Vec3::X));
        assert!(!o.allows(Vec3::ZERO, 1e-3, -Vec3::X));
        // Second children add nothing.
        let o = Order::NONE.child(1, 0.0, false, true);
        assert!(o.allows(Vec3::new(0.0, 5.0, 0.0), 0.0, -Vec3::Y));
        // High first: rays must go −y, or start at or above the plane.
        let o = Order::NONE.child(1, 0.5, true, false);
        assert!(o.allows(Vec3::new(0.0, 0.7, 0.0), 0.0, Vec3::Y));
        assert!(!o.allows(Vec3::new(0.0, 0.2, 0.0), 0.0, Vec3::Y));
        assert!(!o.allows(Vec3::NAN, 0.0, Vec3::NAN));
    }
}
