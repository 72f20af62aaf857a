//! `rtrps`: Ray Tracing based on Ray-Planes and bounding Spheres (Suzuki, Kaeriyama, Komatsu,
//! Egawa, Ohba, Kobayashi 2010, "A Fast Ray-Tracing Using Bounding Spheres and Frustum Rays for
//! Dynamic Scene Rendering", IEICE Trans. Inf. & Syst. E93-D(4)).
//!
//! | file | holds | paper |
//! |---|---|---|
//! | `mod.rs` | [`Config`], counters, [`Rtrps`], `impl Tracer` (prepare = build or update; the plan of a call) | §2.3, Alg. 1 |
//! | `group.rs` | one N×N (or R×C) group: grid frame, row and column fans, the sphere walk | §2.2–2.3, §3.1, Alg. 2 |
//! | `leaf.rs` | a leaf of the walk: its plane tests, the edge cull, the reproduced rays and their triangle forms | §2.3, §3.2 |
//! | `random.rs` | random rays: one ray at a time over the same hierarchy | §4.2 (Table 5's baseline) |
//! | [`crate::accel::spheres`] | the sphere hierarchy, rigid update and refit | §2.1, §4.1 |
//! | [`crate::geom::sphere_plane`] | fan fit, 2D line/circle test, wedge cull, sign rule, ray/sphere | §3.1.1–3.1.3 |
//! | [`crate::geom::aligned`] | the aligned ray-plane form as an exact cull (spans of `a_x` per triangle and row) | §3.2.3, Eqs. 7–8' |
//!
//! **Groups** (§2.2, §4, item 8 of issue #14): a batch laid out as `OriginGrids { side }` (area-
//! light shadow samples, hemisphere bounce grids) is cut into its side×side groups; a `Pinhole`
//! image into `packet`×`packet` tiles (rectangular at the image's right and bottom edges). A
//! group whose rays do not share one origin bit for bit, or has a zero or non-finite direction,
//! is traced as random rays; so is every batch of another layout (`Unknown` batches are first
//! recognised with `RayBatch::detect_layout`). `grid_side > 0` cuts any batch into consecutive
//! groups of that side (tests: it feeds the group path arbitrary directions).
//!
//! **The group walk** (Algorithm 2, with §3.1's techniques): the grid's frame is fitted to the
//! rays (z: mean direction, x: along the rows), each row's rays define a plane containing the
//! x-axis and each column's a plane containing the y-axis (the fans' shared lines, §3.1.1: a
//! plane/sphere test is the 2D line/circle test `|n'·c''| <= bound` after one 18-flop transform
//! of the centre per sphere, Eqs. 2–3). Real rays are not exactly on their plane: the fan's
//! slack (largest sine between a ray and its plane) widens every bound (see
//! `geom::sphere_plane`), so the planes may only cull, and a reproduced ray (a hit row × a hit
//! column) is tested against the leaf's triangles with the shared `geom::intersect_triangle`. The
//! walk is scene sphere → part tree → part spheres → inner spheres → leaves; a child tests only
//! the planes its parent hit (a ray meeting a child's triangles passes through the parent).
//! `culling` (§3.1.2): the outermost of the parent's hit planes are tested first and the exact
//! circle/double-wedge test culls the sphere (Table 1's cases 5–10). `tree` (§3.1.3): the
//! remaining planes are visited in implicit binary-tree order (centre first), a missed plane
//! sending the search to one side only, where the sign rule holds (centre in front of both
//! outer planes, or behind both); elsewhere plane by plane. Both are off in `mode=planes
//! culling=false tree=false`, the paper's "All Plane".
//!
//! **Ours, where the paper is silent** (measured in BENCHMARKS.md § RTRPS):
//! - the leaves (Morton runs of `leaf_size` triangles), inner spheres (`cluster` leaves, in a
//!   binary tree over the part's leaves by default, `levels`), leaf
//!   centre rule (`centre`), and the radii that make spheres bound what the box-gated
//!   triangle test can report: tight for the part's transform at the last fit, `√3·ρ` under
//!   any rotation from its first rigid motion on (see `accel::spheres`);
//! - the depth cull (`depth_cull`): a hit row and a hit column meet in the whole line through
//!   the origin, so the planes alone keep every sphere on a ray's backward extension (for
//!   shadow grids from a surface, the body beneath it); when every ray of a group has
//!   `tmin >= 0` and points ahead of the grid frame (`u.z > 1e-3`), a sphere wholly behind the
//!   origin or wholly past every ray's end (`tmax·|d|·u.z`) is culled before any plane test,
//!   with the frame's rounding margin (BENCHMARKS.md § RTRPS: 5.3× on the bunny's shadow grids);
//! - a part tree (world-frame spheres over the parts, rebuilt at every update, see
//!   `accel::spheres`) between the scene sphere and the parts: the paper's scenes have a few
//!   parts, ours (`animate --motion spin-parts`) thousands, each of which every group tested;
//! - the per-ray check (`ray_check`): a hit row × a hit column is the bounding square of a
//!   leaf's footprint, so each reproduced ray is first tested against the leaf's sphere (its
//!   unit direction in the grid frame against the centre, with the frame's margins), and only
//!   rays that pass go to the triangle test;
//! - groups whose fitted planes hold their rays only loosely (`max_slack`, the largest sine
//!   between a ray and its plane; hemisphere grids) are traced as random rays: every plane
//!   then meets every sphere near the origin (measured in BENCHMARKS.md § RTRPS);
//! - rigid update by frames, not by moving spheres: a part's spheres stay in its local frame, and
//!   a group's frame is brought into each part's frame (one 3×3 product per part and group); by
//!   default (`retighten`) a moved part's radii are then made tight for its new transform,
//!   linear in its triangles (without it, O(1) per moved part, with radii that hold under any
//!   rotation);
//! - §3.2's triangle forms (`tri_test`): reproduced rays go through the shared test one at a
//!   time (Table 2's "Möller" row) or through its common-origin form
//!   ([`TriFromOrigin`](crate::geom::TriFromOrigin): the parts that depend only on the triangle
//!   and the group's origin computed once per leaf visit, by the shared test's own operations,
//!   so bit-identical), a row's reproduced rays four at a time; `auto` picks by
//!   group size at the measured crossover (`group::ORIGIN_FORM_RAYS`, Fig. 10's rule). The
//!   aligned ray-plane form (Eqs. 7–8', `tri_test=aligned`, [`crate::geom::aligned`]) is a
//!   cull before the common-origin form, because its arithmetic is not the shared test's: per
//!   leaf triangle and hit row, the interval of the rays' grid coordinate `a_x` outside which
//!   the shared test provably refuses them (Eq. 8' with `a_y`'s spread over the row, the rays'
//!   distance from the grid and the test's rounding bounded), then two comparisons per ray.
//!   It removes half or more of the triangle tests on shadow grids and costs more than they
//!   did at every group size measured, so `auto` never takes it (BENCHMARKS.md § RTRPS, "The aligned
//!   ray-plane form");
//! - the hit planes of a sorted fan found as one run (`ranges`, after §3.1.3's binary tree,
//!   which tests every hit plane): where the sign rule holds the distances are monotone, so
//!   both outer planes hitting means every plane between does, and otherwise the run's two
//!   ends are found by binary search;
//! - the edge cull (`edge_cull`): before a leaf reproduces many rays (at least
//!   `group::EDGE_CULL_RAYS`), a cone holding all the group's directions is tested against
//!   each of its triangles' edge planes through the origin (`geom::RayCone`: the shared test's
//!   `det`, `u·det` and `v·det` are linear in the direction for one origin, so their signs over
//!   the whole cone, with the f32 rounding bounded, prove that every ray is refused). It removes
//!   the triangles around a shadow grid's origin, which every plane meets;
//! - an exact per-ray box check (`box_check`, off by default): the shared slab interval of the
//!   leaf's triangles' box, which the box gate puts every hit in (measured slower than the
//!   triangle tests it removes);
//! - closest hits cut the walk (`hit_cut`): a reported hit at `t` is a point of the leaf's
//!   sphere at distance `t·|d|` along the ray's unit direction, so a reproduced ray whose
//!   closest hit so far is nearer than the sphere skips the leaf, and the depth cull's far
//!   bound drops to the deepest closest hit of the group's rays once each has one (both with
//!   rounding margins, in `leaf.rs` and `Scratch::lower_depth`); closest-hit groups visit
//!   nearer children first (`near_first`: by the grid depth of the children's centres), which
//!   is what makes the cut bite (BENCHMARKS.md § RTRPS, "Closest hits cut the walk"); ties
//!   still go by [`closer`](crate::tracer::closer). Random rays keep the hierarchy's order:
//!   ordering them by direction removed 1.4% of their sphere tests and cost 30% more time
//!   (mispredicted swaps; BENCHMARKS.md, same section);
//! - any-hit groups drop a row or column plane from every later sphere test once all its
//!   rays have a hit (`live_planes`).

mod group;
mod leaf;
mod random;

use crate::accel::spheres::{BuildConfig, Centre, Levels, SphereTree};
use crate::error::{Error, Result};
use crate::rays::{HitBatch, RayBatch, RayLayout};
use crate::scene::{Change, Scene, Stamp, TriangleSoup};
use crate::tracer::{
    par_occlusion_chunks, par_ray_chunks, CostMut, CounterDocs, CounterSet, RayCost, Stats, Tally,
    Tracer,
};
use crate::tracers::{OptionDoc, Preset};
use serde::{Deserialize, Serialize};

pub use group::GroupSpec;

/// Options (`rtrps:key=value`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// `planes` (groups as ray-planes, the rest as random rays) or `random` (every ray alone:
    /// the paper's Table 5 baseline). Default `planes`.
    pub mode: Mode,
    /// Frustum culling by the outermost planes (§3.1.2). Default true.
    pub culling: bool,
    /// Binary-tree plane order (§3.1.3). Default true.
    pub tree: bool,
    /// Where the binary tree applies (a sorted fan, the sign rule holding), find the hit planes
    /// as one run: all of them when both outer planes hit, else its two ends by binary search
    /// (ours, after §3.1.3: the tree tests every hit plane). Default true.
    pub ranges: bool,
    /// Triangles per leaf sphere (1..=64). Default 1 (BENCHMARKS.md § RTRPS: leaves of 1 and
    /// bottom spheres of 8 leaves were fastest on the bunny's shadow grids).
    pub leaf_size: usize,
    /// Leaves per inner sphere (0: leaves hang from the part, the paper's depth 3). Default 8.
    pub cluster: usize,
    /// Leaf centre: `box` (centre of its vertices' box) or `mean`. Default `box`.
    pub centre: Centre,
    /// Cull spheres wholly behind a group's origin or beyond all its rays' ends before any plane
    /// test (ours: a row plane and a column plane meet in a whole line, the ray's backward
    /// extension included). Default true.
    pub depth_cull: bool,
    /// Closest hits cut the walk (ours): a group's far bound shrinks to its rays' closest hits
    /// so far once every ray has one (the depth cull then culls what lies behind them), and a
    /// reproduced ray skips a leaf whose sphere lies wholly beyond its closest hit. Default
    /// true.
    pub hit_cut: bool,
    /// Closest-hit groups visit nearer children first (ours: the child whose centre is nearer
    /// along the grid's axis, so the hits that `hit_cut` uses come early). Default true.
    pub near_first: bool,
    /// Any-hit groups test spheres only against the rows and columns that still have a ray
    /// without a hit (ours). Default true.
    pub live_planes: bool,
    /// Inner spheres: `binary` (a binary tree over each part's leaves, bottom spheres of at most
    /// `cluster` leaves) or `flat` (one level of `cluster`-leaf spheres). Default `binary`.
    pub levels: Levels,
    /// Test each reproduced ray against the leaf's sphere before its triangles (ours: a hit row
    /// × a hit column is the bounding square of the sphere's footprint). Default true.
    pub ray_check: bool,
    /// Test each reproduced ray against the box of the leaf's triangles, with the shared slab
    /// test's arithmetic, before its triangles (ours: exact, as the box gate puts every hit in
    /// that interval). Default false (BENCHMARKS.md § RTRPS: it removes 84% of the triangle
    /// tests on the bunny's shadow grids, and costs more than they did).
    pub box_check: bool,
    /// Before reproducing rays at a leaf that would reproduce many, prove from the group's cone
    /// of directions that the shared test refuses every ray on its barycentric signs
    /// (`geom::RayCone`: the common-origin form's edge planes; ours). Default true.
    pub edge_cull: bool,
    /// The ray/triangle test of reproduced rays (§3.2, Table 2): `moller` (the shared test, one
    /// ray at a time), `origin` (its common-origin form, prepared once per leaf visit and run
    /// four rays at a time: bit-identical), `aligned` (the aligned ray-plane form as an exact
    /// cull before `origin`), or `auto` (`origin` for groups of at least
    /// `group::ORIGIN_FORM_RAYS` rays, the measured crossover; never `aligned`, measured slower
    /// at every group size). Default `auto`.
    pub tri_test: TriTest,
    /// Groups whose fitted row or column planes hold their rays only to a sine above this are
    /// traced as random rays (ours; 0..=1, 1: never). Default 0.2 (BENCHMARKS.md § RTRPS:
    /// shadow grids and camera tiles stay far below it, hemisphere grids are above).
    pub max_slack: f32,
    /// Every rigid motion makes the moved part's sphere radii tight for its new transform
    /// (linear in its triangles) instead of keeping radii that hold under any rotation (O(1)
    /// per motion; `accel::spheres`). Default true (BENCHMARKS.md § RTRPS, "Tight radii": on
    /// the bunny's `spin-parts` frames it adds 1.5 ms of update and saves 85 ms of trace).
    pub retighten: bool,
    /// Tile side for pinhole images (1..=64). Default 16.
    pub packet: usize,
    /// When > 0 (1..=64): cut every batch into consecutive groups of `grid_side²` rays whatever
    /// its layout (tests). Default 0.
    pub grid_side: usize,
}

/// [`Config::tri_test`].
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum TriTest {
    /// By group size.
    #[default]
    Auto,
    /// The shared test, one reproduced ray at a time.
    Moller,
    /// The common-origin form, a row's reproduced rays a vector at a time.
    Origin,
    /// The aligned ray-plane form (Eqs. 7–8') as a cull before the common-origin form: per
    /// triangle and hit row, the interval of the rays' grid `a_x` outside which the shared test
    /// refuses them (`geom::aligned`).
    Aligned,
}

/// [`Config::mode`].
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Ray-planes for groups, random rays for the rest.
    #[default]
    Planes,
    /// Every ray alone.
    Random,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            mode: Mode::Planes,
            culling: true,
            tree: true,
            ranges: true,
            leaf_size: 1,
            cluster: 8,
            centre: Centre::Box,
            levels: Levels::Binary,
            depth_cull: true,
            hit_cut: true,
            near_first: true,
            live_planes: true,
            ray_check: true,
            box_check: false,
            edge_cull: true,
            tri_test: TriTest::Auto,
            max_slack: 0.2,
            retighten: true,
            packet: 16,
            grid_side: 0,
        }
    }
}

impl Config {
    fn check(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::Invalid(format!("tracer rtrps: {what}")));
        if !(1..=64).contains(&self.leaf_size) {
            return bad(&format!(
                "leaf_size must be in 1..=64, got {}",
                self.leaf_size
            ));
        }
        if !(1..=64).contains(&self.packet) {
            return bad(&format!("packet must be in 1..=64, got {}", self.packet));
        }
        if !(0.0..=1.0).contains(&self.max_slack) {
            return bad(&format!(
                "max_slack must be in 0..=1, got {}",
                self.max_slack
            ));
        }
        if self.grid_side > 64 {
            return bad(&format!(
                "grid_side must be in 0..=64, got {}",
                self.grid_side
            ));
        }
        Ok(())
    }

    fn build_config(&self) -> BuildConfig {
        BuildConfig {
            leaf_size: self.leaf_size,
            cluster: self.cluster,
            centre: self.centre,
            levels: self.levels,
            retighten: self.retighten,
        }
    }
}

/// One line per option.
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc {
        key: "mode",
        doc: "planes (groups as ray-planes, other rays alone) or random (every ray alone)",
    },
    OptionDoc {
        key: "culling",
        doc: "frustum culling by the outermost planes (§3.1.2)",
    },
    OptionDoc {
        key: "tree",
        doc: "binary-tree plane order (§3.1.3)",
    },
    OptionDoc {
        key: "ranges",
        doc: "hit planes of a sorted fan as one run, its ends by binary search (ours)",
    },
    OptionDoc {
        key: "leaf_size",
        doc: "triangles per leaf sphere (1..=64)",
    },
    OptionDoc {
        key: "cluster",
        doc: "leaves per inner sphere (0: none, the paper's depth 3)",
    },
    OptionDoc {
        key: "centre",
        doc: "leaf sphere centre: box (of its vertices) or mean",
    },
    OptionDoc {
        key: "depth_cull",
        doc: "cull spheres behind a group's origin or past its rays' ends (ours)",
    },
    OptionDoc {
        key: "hit_cut",
        doc: "closest hits so far cut the group's far bound and each ray's leaves (ours)",
    },
    OptionDoc {
        key: "near_first",
        doc: "closest-hit groups visit nearer child spheres first (ours)",
    },
    OptionDoc {
        key: "live_planes",
        doc: "any-hit groups drop rows and columns whose rays all have a hit from the plane tests (ours)",
    },
    OptionDoc {
        key: "levels",
        doc: "inner spheres: binary (a tree over each part's leaves) or flat (one level)",
    },
    OptionDoc {
        key: "ray_check",
        doc: "test each reproduced ray against the leaf sphere before its triangles (ours)",
    },
    OptionDoc {
        key: "box_check",
        doc: "test each reproduced ray against the leaf's triangle box before its triangles (ours)",
    },
    OptionDoc {
        key: "edge_cull",
        doc: "skip a leaf when the group's cone of directions provably misses its triangles (ours)",
    },
    OptionDoc {
        key: "tri_test",
        doc: "reproduced rays' triangle test: auto, moller (one ray at a time), origin (common origin, in lanes) or aligned (aligned ray-plane cull, then origin)",
    },
    OptionDoc {
        key: "retighten",
        doc: "rigid motions make the moved part's radii tight for its new transform (linear in its triangles)",
    },
    OptionDoc {
        key: "max_slack",
        doc: "groups whose rays lie farther from their planes (sine) go as random rays (0..=1)",
    },
    OptionDoc {
        key: "packet",
        doc: "tile side for pinhole images (1..=64)",
    },
    OptionDoc {
        key: "grid_side",
        doc: "cut every batch into consecutive groups of grid_side² rays (0: by layout)",
    },
];

/// Configurations the conformance suite checks besides the defaults.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "random rays",
        opts: &[("mode", "random")],
    },
    Preset {
        name: "all planes",
        opts: &[
            ("culling", "false"),
            ("tree", "false"),
            ("depth_cull", "false"),
            ("hit_cut", "false"),
            ("near_first", "false"),
            ("live_planes", "false"),
            ("ray_check", "false"),
            ("edge_cull", "false"),
            ("max_slack", "1"),
        ],
    },
    Preset {
        name: "culling only, flat inner spheres",
        opts: &[("tree", "false"), ("levels", "flat")],
    },
    Preset {
        name: "the paper's tree only, mean centres, no inner spheres",
        opts: &[
            ("culling", "false"),
            ("ranges", "false"),
            ("centre", "mean"),
            ("cluster", "0"),
        ],
    },
    Preset {
        name: "any batch as 3x3 groups, leaves of two",
        opts: &[("grid_side", "3"), ("leaf_size", "2")],
    },
    Preset {
        name: "any batch as 8x8 groups",
        opts: &[("grid_side", "8"), ("cluster", "4")],
    },
    Preset {
        name: "packets of one ray",
        opts: &[("grid_side", "1"), ("packet", "1")],
    },
    Preset {
        name: "4x4 tiles, big leaves, runs without culling",
        opts: &[("packet", "4"), ("leaf_size", "7"), ("culling", "false")],
    },
    Preset {
        name: "any batch as 3x3 groups, common-origin form, box check",
        opts: &[
            ("grid_side", "3"),
            ("tri_test", "origin"),
            ("box_check", "true"),
        ],
    },
    Preset {
        name: "any batch as 5x5 groups, aligned form, leaves of three, no ray check",
        opts: &[
            ("grid_side", "5"),
            ("tri_test", "aligned"),
            ("leaf_size", "3"),
            ("ray_check", "false"),
        ],
    },
    Preset {
        name: "any-rotation radii after a rigid motion",
        opts: &[("retighten", "false")],
    },
    Preset {
        name: "aligned form for every group",
        opts: &[("tri_test", "aligned")],
    },
    Preset {
        name: "Möller form for every group",
        opts: &[("tri_test", "moller")],
    },
    Preset {
        name: "hit cut in the hierarchy's order, Möller form",
        opts: &[("near_first", "false"), ("tri_test", "moller")],
    },
    Preset {
        name: "near first without the hit cut",
        opts: &[("hit_cut", "false")],
    },
];

crate::counters! {
    /// Work of `rtrps`, split as the paper's Fig. 11 does.
    pub struct Counts {
        /// Ray groups traced as ray-planes.
        groups,
        /// Groups traced as random rays because their planes' slack exceeds `max_slack`.
        slack_groups,
        /// Rays in those groups.
        group_rays,
        /// Rays traced alone (random rays).
        random_rays,
        /// Plane/sphere tests of a fan's outermost planes (frustum culling, Fig. 11 "outside").
        outline_tests,
        /// Plane/sphere tests of the other planes (Fig. 11 "internal").
        internal_tests,
        /// Spheres a group tested (scene, part, inner and leaf spheres).
        spheres_visited,
        /// Part spheres tested (groups and random rays): the part tree keeps it below one
        /// test per part and group.
        part_tests,
        /// Spheres the wedge test culled before any inner plane was tested.
        spheres_culled,
        /// Spheres wholly behind the group's origin or beyond every ray's end (`depth_cull`).
        depth_culled,
        /// Rays reproduced from a hit row and a hit column at a leaf.
        rays_reproduced,
        /// Reproduced rays whose line misses the leaf sphere (`ray_check`): no triangle test.
        ray_culled,
        /// Reproduced rays whose closest hit so far is nearer than the leaf sphere
        /// (`hit_cut`): no triangle test.
        hit_culled,
        /// Times a closest-hit group's far bound was lowered to its rays' hits (`hit_cut`).
        depth_lowered,
        /// Reproduced rays that passed the sphere check but miss the leaf's triangle box
        /// within their `[tmin, tmax]` (`box_check`): no triangle test.
        box_culled,
        /// Leaves skipped because the group's cone of directions provably misses their
        /// triangles (`edge_cull`).
        edge_culled,
        /// Reproduced rays outside every span of the leaf's triangles on their row (the aligned
        /// ray-plane form, `tri_test=aligned`): no triangle test.
        span_culled,
        /// Triangle spans computed (one per triangle and hit row of a leaf, aligned form).
        spans,
        /// Ray/sphere tests of random rays.
        ray_sphere,
        /// Ray/triangle tests (shared test).
        tri_tests,
    }
}

crate::counters! {
    /// What a prepare built or updated.
    pub struct Built {
        /// Spheres in all (scene, parts, inner, leaves).
        spheres,
        /// Part spheres.
        parts,
        /// Inner spheres.
        inner,
        /// Leaf spheres.
        leaves,
        /// Triangles.
        triangles,
        /// 1 when the hierarchy was built from scratch.
        rebuilt,
        /// Parts whose transform was rewritten (rigid update).
        parts_moved,
        /// Leaves re-centred (deformed parts).
        leaves_refit,
    }
}

/// Counter docs: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (Built::DOCS, Counts::DOCS);

/// The `rtrps` tracer.
#[derive(Default)]
pub struct Rtrps {
    cfg: Config,
    tree: SphereTree,
    stamp: Stamp,
}

impl Rtrps {
    /// A tracer with `cfg` and no scene yet.
    pub fn new(cfg: Config) -> Result<Self> {
        cfg.check()?;
        Ok(Self {
            cfg,
            ..Self::default()
        })
    }

    /// The current hierarchy.
    pub fn spheres(&self) -> &SphereTree {
        &self.tree
    }

    /// How a call cuts `rays`.
    fn plan(&self, rays: &RayBatch) -> Plan {
        let n = rays.len();
        if self.cfg.mode == Mode::Random || n == 0 {
            return Plan::Random;
        }
        if self.cfg.grid_side > 0 {
            return Plan::Grids(self.cfg.grid_side);
        }
        let layout = match rays.layout {
            RayLayout::Unknown => rays.detect_layout(None),
            l => l,
        };
        match layout {
            RayLayout::OriginGrids { side } if (1..=64).contains(&side) => {
                Plan::Grids(side as usize)
            }
            RayLayout::Pinhole { width, height, .. } if width as usize * height as usize == n => {
                Plan::Tiles(width as usize)
            }
            _ => Plan::Random,
        }
    }

    fn chunk(&self, plan: Plan) -> usize {
        match plan {
            Plan::Random => 256,
            Plan::Grids(s) => s * s * (1024 / (s * s)).max(1),
            Plan::Tiles(w) => w * self.cfg.packet,
        }
    }

    /// The groups of chunk `range` under `plan`, and (through `alone`) the rays left out.
    /// One parallel chunk of either query: its groups through `group::trace`, then the rays
    /// left alone (no group, or a partial one at the chunk's end) one at a time.
    fn run_chunk(
        &self,
        plan: Plan,
        soup: &TriangleSoup,
        rays: &RayBatch,
        range: std::ops::Range<usize>,
        mut out: group::Out<'_, '_>,
        mut cost: Option<CostMut<'_>>,
    ) -> Tally<Counts> {
        let mut c = Counts::default();
        let mut scratch = group::Scratch::new();
        let start = range.start;
        let mut lone = Vec::new();
        self.groups(
            plan,
            range,
            |g| {
                let out = match &mut out {
                    group::Out::Hits(h) => group::Out::Hits(&mut **h),
                    group::Out::Occluded(o) => group::Out::Occluded(&mut **o),
                };
                group::trace(
                    &self.tree,
                    &self.cfg,
                    soup,
                    rays,
                    g,
                    start,
                    &mut scratch,
                    out,
                    cost.as_mut(),
                    &mut c,
                )
            },
            |i| lone.push(i),
        );
        for i in lone {
            let (tree, k) = (&self.tree, i - start);
            match &mut out {
                group::Out::Hits(h) => {
                    random::closest(tree, soup, rays, i, k, h, cost.as_mut(), &mut c)
                }
                group::Out::Occluded(o) => {
                    o[k] = random::any(tree, soup, rays, i, k, cost.as_mut(), &mut c)
                }
            }
        }
        Tally {
            counts: c,
            peak_bytes: scratch.bytes() as u64,
        }
    }

    fn groups(
        &self,
        plan: Plan,
        range: std::ops::Range<usize>,
        mut f: impl FnMut(GroupSpec),
        mut alone: impl FnMut(usize),
    ) {
        match plan {
            Plan::Random => range.for_each(alone),
            Plan::Grids(s) => {
                let mut b = range.start;
                while b + s * s <= range.end {
                    f(GroupSpec {
                        base: b,
                        stride: s,
                        rows: s,
                        cols: s,
                    });
                    b += s * s;
                }
                (b..range.end).for_each(&mut alone);
            }
            Plan::Tiles(w) => {
                let rows = range.len() / w;
                let p = self.cfg.packet;
                for tx in (0..w).step_by(p) {
                    f(GroupSpec {
                        base: range.start + tx,
                        stride: w,
                        rows,
                        cols: p.min(w - tx),
                    });
                }
            }
        }
    }
}

#[derive(Clone, Copy, Debug)]
enum Plan {
    Random,
    Grids(usize),
    Tiles(usize),
}

impl Tracer for Rtrps {
    fn name(&self) -> &'static str {
        "rtrps"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        let change = scene.changes_since(self.stamp);
        let mut built = Built::default();
        match change {
            Change::None => {}
            ref c => match self.tree.update(scene, c) {
                Some(u) => {
                    built.parts_moved = u.moved as u64;
                    built.leaves_refit = u.refit_leaves as u64;
                }
                None => {
                    self.tree = SphereTree::build(scene, self.cfg.build_config());
                    built.rebuilt = 1;
                }
            },
        }
        self.stamp = scene.stamp();
        let t = &self.tree;
        built.spheres = t.spheres() as u64;
        built.parts = t.parts.len() as u64;
        built.inner = t.inner_c.len() as u64;
        built.leaves = t.leaf_c.len() as u64;
        built.triangles = t.tris.len() as u64;
        Ok(Stats::prepared(&built, t.bytes()))
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let plan = self.plan(rays);
        let soup = scene.triangles();
        let tally: Tally<Counts> = par_ray_chunks(
            rays,
            hits,
            cost,
            self.chunk(plan),
            |range, mut out, cost| {
                self.run_chunk(plan, soup, rays, range, group::Out::Hits(&mut out), cost)
            },
        );
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
        let plan = self.plan(rays);
        let soup = scene.triangles();
        let tally: Tally<Counts> = par_occlusion_chunks(
            rays,
            occluded,
            cost,
            self.chunk(plan),
            |range, out, cost| {
                self.run_chunk(plan, soup, rays, range, group::Out::Occluded(out), cost)
            },
        );
        Ok(tally.into_stats(rays.len()))
    }

    fn bytes(&self) -> usize {
        self.tree.bytes()
    }
}
