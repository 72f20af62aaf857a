//! The options (`--opt key=value`): the paper's limits (§3.2, §3.3, §3.5, §3.6) with its
//! values where it gives them, and the switches of our extensions.

use crate::tracers::{OptionDoc, Preset};
use serde::{Deserialize, Serialize};

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
    /// Default 200, the fastest value tried on a path tracer's bounce rays, and no change on
    /// random or shadow rays (BENCHMARKS.md, § Fig. 9 and Fig. 10, and § DACRT design
    /// measurements).
    pub leaf_pairs: usize,
    /// Flush cones to rays when fewer active cones than this (the paper gives no value; 16
    /// balances ray/box savings against deeper cone recursions on dense meshes). Default 16.
    pub c_limit: usize,
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
    /// leaves with rays); 0 turns shadow packets off. Default 0: a cone from the light keeps
    /// every cell along its 64 segments alive, doubling the triangle/box tests, and 1° packets
    /// were slower than rays on every scene measured but Sponza (light inside the scene;
    /// BENCHMARKS.md, § Fig. 8).
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
    /// pixels; see `Task::band_triangles`). Default 256.
    pub pixel_leaf_c_limit: usize,
    /// With tile leaves, closest hits (ours): a tile keeps a bound on the distance of its live
    /// pixels' best hits so far (updated at the end of each leaf that hit it), and a triangle
    /// beyond it skips the tile without a ray/triangle test: a z-buffer cull across the
    /// front-to-back leaves. Exact, but it culled 1% of the pairs on Sponza from inside (a
    /// tile stays open while one live pixel has no hit: sky) and gained nothing, so default
    /// false (BENCHMARKS.md, § DACRT: large triangles). Adds 4 bytes per tile.
    pub depth_cull: bool,
    /// With tile leaves (ours): a triangle whose pixel rectangle in a leaf holds at least
    /// this many pixels has them edge-tested against its projection first
    /// (`geom::PixelEdges`), so that the ray/triangle test runs only on pixels near the
    /// triangle (a large triangle covers about half its rectangle). `usize::MAX`: off. It
    /// drops 20% of the pairs on Sponza and 54% on the Cornell box, but the pairs are not
    /// where those leaves spend their time: no faster, so default off (BENCHMARKS.md, § DACRT:
    /// large triangles).
    pub edge_pixels: usize,
    /// Ask Linux for transparent huge pages (`madvise(MADV_HUGEPAGE)`, as Embree's allocator
    /// does) for the per-call buffers and the min/max lists: fewer first-touch page faults.
    /// Only a process's first call gains (warm calls reuse the buffers); pinned (`--pin`, as
    /// every benchmark runs) it gained on the dragon and the tile of dragons, unpinned the
    /// tile's first trace was often slower, and fresh processes with either setting saw rare
    /// long stalls on this (virtual) machine (BENCHMARKS.md, § Fig. 14). Default true.
    pub huge_pages: bool,
    /// Ours (`top.rs`): ray batches without packets of at most this many rays per triangle
    /// walk a top tree kept between calls (built by the first such call after a prepare that
    /// changed the scene: the recursion's upper levels, ray-independent, with their
    /// triangle lists at its leaves) instead of streaming every triangle through the upper
    /// levels of each call. 0 turns it off. Default 2 (BENCHMARKS.md, § DACRT: sparse
    /// batches).
    pub top_below: f64,
    /// The top tree's leaves: at most this many triangles (smaller ones only where the list
    /// budget or the progress guard stops the split). Default 32.
    pub top_leaf: usize,
    /// The top tree's leaf lists hold at most `(1 + top_growth)` times the live triangles
    /// (straddling triangles are in both children); the budget is shared between children in
    /// proportion to their triangles. Default 1.
    pub top_growth: f64,
    /// Ours: time the phases of each call into the `ns_*` counters (set-up, the triangle-list
    /// or projection pass and the top tree's build, the dividing steps, the leaves). Off by
    /// default: a clock read per leaf costs a few percent of a camera call.
    pub phase_times: bool,
    /// Ours (`light.rs`): any-hit batches of segments to one point light (layout `ToPoint`)
    /// are traced in the light's frame, each triangle tested against the segments its
    /// light-space footprint covers, instead of by the recursion. Default true
    /// (BENCHMARKS.md, § DACRT: shadow rays in light space).
    pub light_space: bool,
    /// The light-space pass's buckets hold about this many segments. Default 2.
    pub light_bucket: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            r_limit: 20,
            p_limit: 16,
            leaf_pairs: 200,
            c_limit: 16,
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
            edge_pixels: usize::MAX,
            depth_cull: false,
            huge_pages: true,
            top_below: 2.0,
            top_leaf: 32,
            top_growth: 1.0,
            phase_times: false,
            light_space: true,
            light_bucket: 2,
        }
    }
}

/// One line per option, for `raysift tracers --verbose` (details on [`Config`]'s fields).
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc { key: "r_limit", doc: "naive leaf when fewer active rays than this (paper: 20)" },
    OptionDoc { key: "p_limit", doc: "naive leaf when fewer triangles than this (paper: 16)" },
    OptionDoc { key: "leaf_pairs", doc: "divide a small cell on while its naive leaf would test more pairs than this (ours; usize::MAX: the paper's rule)" },
    OptionDoc { key: "c_limit", doc: "flush cones to rays when fewer active cones than this" },
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
    OptionDoc { key: "depth_cull", doc: "tile leaves: skip a tile for triangles beyond its live pixels' best hits (ours)" },
    OptionDoc { key: "edge_pixels", doc: "tile leaves: edge-test the pixels of rectangles of at least this many pixels before the ray/triangle test (ours; usize::MAX: off)" },
    OptionDoc { key: "huge_pages", doc: "ask Linux for transparent huge pages for the per-call buffers" },
    OptionDoc { key: "top_below", doc: "batches without packets of at most this many rays per triangle walk a top tree kept between calls (ours; 0: off)" },
    OptionDoc { key: "top_leaf", doc: "the top tree's leaves hold at most this many triangles" },
    OptionDoc { key: "top_growth", doc: "the top tree's lists hold at most (1 + this) times the triangles" },
    OptionDoc { key: "phase_times", doc: "time each call's phases into the ns_* counters (ours)" },
    OptionDoc { key: "light_space", doc: "any-hit segments to one point light: traced in the light's frame, triangles against the segments under their footprint (ours)" },
    OptionDoc { key: "light_bucket", doc: "the light-space pass's buckets hold about this many segments" },
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
            ("split_sample_threshold", "64"),
            ("split_sample_stride", "3"),
            ("max_depth", "40"),
            ("leaf_pairs", "0"),
            ("max_cone_deg", "60"),
            ("max_shadow_cone_deg", "60"),
            ("pixel_leaf_c_limit", "1"),
            ("light_space", "false"),
        ]
    };
}

/// Configurations the conformance suite checks besides the defaults: every mode with one task
/// and with tiny limits over three tasks (those without the light-space pass), the paper's
/// cones and leaf rule, flushes, shadow packets, the light-space pass's buckets, and no huge
/// pages.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "packet",
        opts: &[("mode", "packet"), ("tasks", "1"), ("phase_times", "true")],
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
            ("light_space", "false"),
            ("flush_filter", "false"),
            ("pixel_cull", "false"),
            ("pixel_leaf", "false"),
            ("phase_times", "true"),
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
            ("light_space", "false"),
        ],
    },
    Preset {
        name: "light space, one segment per bucket, three tasks",
        opts: &[("tasks", "3"), ("light_bucket", "1")],
    },
    Preset {
        name: "light space, large buckets, ray mode",
        opts: &[("mode", "ray"), ("tasks", "2"), ("light_bucket", "50")],
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
        name: "top tree everywhere, leaves of two, tiny limits",
        opts: &[
            ("mode", "random"),
            ("tasks", "3"),
            ("r_limit", "2"),
            ("p_limit", "2"),
            ("leaf_pairs", "0"),
            ("split_sample_threshold", "64"),
            ("split_sample_stride", "3"),
            ("top_below", "1e300"),
            ("top_leaf", "2"),
        ],
    },
    Preset {
        name: "top tree, ray mode, no spare budget",
        opts: &[
            ("mode", "ray"),
            ("tasks", "2"),
            ("top_below", "1e300"),
            ("top_leaf", "1"),
            ("top_growth", "0"),
        ],
    },
    Preset {
        name: "top tree, auto, large leaves",
        opts: &[
            ("mode", "auto"),
            ("tasks", "1"),
            ("top_below", "1e300"),
            ("top_leaf", "200"),
            ("top_growth", "3"),
            ("phase_times", "true"),
        ],
    },
    Preset {
        name: "tile leaves with edge tests and depth culling, tiny leaves",
        opts: &[
            ("mode", "packet"),
            ("tasks", "2"),
            ("edge_pixels", "0"),
            ("depth_cull", "true"),
            ("pixel_leaf_c_limit", "2"),
            ("p_limit", "2"),
            ("c_limit", "1"),
        ],
    },
    Preset {
        name: "tile leaves with edge tests of large rectangles and depth culling",
        opts: &[
            ("mode", "auto"),
            ("tasks", "1"),
            ("edge_pixels", "6"),
            ("depth_cull", "true"),
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
