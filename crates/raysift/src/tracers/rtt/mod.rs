//! `rtt`: relevant-triangle tracing with shafts over the shared SAH kd-tree (the paper of
//! `../shared/papers/relevant-triangles-tracing-shafts.md`).
//!
//! | file | holds | paper |
//! |---|---|---|
//! | `mod.rs` | [`Config`], counters, [`Rtt`], `impl Tracer`, how a batch is cut into tiles | §3 |
//! | `tile.rs` | one tile: corner rays, the shaft walk that builds the relevant-triangle list, the per-ray proof, the fallback | §3 |
//! | `origin.rs` | the vector path of closest-hit tiles from one origin (camera tiles, grids): rays gathered into structure-of-arrays, the shaft fitted in f32 lanes, the list tested 8 rays at a time, overflowing tiles split | §3 |
//! | [`crate::geom::shaft`] | the shaft (pyramid fitted to a tile's rays, capped) and its conservative box test | §3 ("five tests") |
//! | [`crate::accel::kdtree`] | the SAH kd-tree and its exactness proof | §2 (the baseline) |
//! | [`crate::tracers::kdtree`] | the single-ray walk used for corner rays and fallbacks | §2 |
//!
//! **Tiles.** A `Pinhole` batch is cut into `tile × tile` pixel tiles (the paper's 4×4; smaller
//! at the image's right and bottom edges), a `PixelSamples` batch into the same pixel tiles with
//! all their a×a samples ((4a)² rays: the paper's antialiased tiles), an `OriginGrids` batch
//! (area-light shadow samples, hemisphere grids) into `tile × tile` tiles of each grid, and a
//! `ToPoint` batch (shadow rays to a point light: §3's shadow shafts) into groups of
//! `segment_group` consecutive segments. `Unknown` batches are first recognised with
//! `RayBatch::detect_layout`; any other batch is cut into groups of `segment_group` consecutive
//! rays whose shaft's apex is the point nearest all their lines: the reflections of a camera
//! tile in a planar mirror meet at the mirrored eye (§3's reflection shafts); groups that meet
//! nowhere (random or bounce rays) fail the shaft fit and are traced ray by ray.
//!
//! **A tile** (`tile.rs`):
//! 1. Its four corner rays (the outermost samples of its corner pixels) walk the kd-tree as one
//!    4-ray packet (`kdtree`'s `packet.rs`), giving their closest hits (skipped for any-hit
//!    queries when every ray of the tile is a finite segment: shadow shafts need no corner rays).
//! 2. A shaft is fitted around *all* the tile's directions (not only the corners: jittered
//!    samples may lie outside the corners' pyramid), apex at the common origin, and capped at the
//!    depth (along the mean direction) of the deepest corner hit grown by `cap_growth`, or of
//!    the farthest segment end when that is nearer; uncapped when a corner misses. A group of
//!    segments (any origins) gets a shaft around both ends of every segment instead, its apex
//!    pulled back behind their far ends (the light) and capped at their near ends: no corner
//!    rays, every answer proven.
//! 3. The shaft walks the tree, entering every cell its box test cannot rule out, and keeps
//!    every triangle of those leaves whose box it cannot rule out (the paper's five tests per
//!    triangle: four sides and the cap; here against the triangle's box, see below): the
//!    relevant-triangle list, sorted and deduplicated.
//! 4. Every other ray of the tile tests only the list (rays from one origin `L::N` at a time,
//!    through the list's triangles prepared for that origin: `geom::TriFromOrigin`,
//!    bit-identical to the shared test). Its answer is *proven* when it found a hit
//!    no deeper than the cap (for any-hit: any hit), or no hit and its whole segment ends before
//!    the cap; otherwise the ray is traced through the tree (a "fallback").
//!
//! **Closest hits from one origin** (camera tiles, antialiased or not, and grids) take
//! `origin.rs`'s path: the tile's rays are copied row by row into structure-of-arrays, the
//! shaft is fitted in f32 lanes (padded by the bound of their rounding, `geom::shaft`), the list
//! is tested eight rays at a time in code compiled for AVX2 (four elsewhere; `geom::Lanes`), each
//! lane keeping its best hit in registers, and the depth proof runs in f32 with a margin that
//! bounds its rounding (a lane it cannot settle gets the f64 test). A tile whose list overflows
//! is traced as its four quarters, each with its own corners and shaft (down to single pixels,
//! and not into quarters of four rays or fewer, which would only walk their corners); a tile of
//! `R` rays may use a list of `max_list · R/16` triangles (at most 16 × `max_list`: a list's
//! cost and the walks it saves are both per ray). Measured in BENCHMARKS.md (§ RTT, "The vector
//! path").
//!
//! **Why it is exact.** A triangle the shared test can report on a ray inside the shaft has its
//! box within `BOX_EXIT_SLACK` of the hit point, so the shaft's box test (tolerance 1e-5
//! relative, `geom::shaft`) keeps that box and every kd-tree cell on the way to a leaf
//! referencing it (the build references a triangle in every cell its box meets). So the list
//! holds every triangle that can be hit before the cap, and a list answer that stays before the
//! cap is the tree's answer, bit for bit (same test, same tie rule). The proof is per ray and
//! does not rely on the corner rays agreeing.
//!
//! **"Coherent", decided** (the paper leaves it open: it flags a tile incoherent as soon as the
//! corner rays take different near/far decisions or visit different nodes, and then lets the
//! inner rays use the triangles of the corners' leaves). That rule is not exact in general: a
//! cell lying strictly inside the shaft but touched by no corner ray is missed (its triangles
//! can be hit by inner rays only). So here a tile is *listed* (coherent) when (a) all its rays
//! share one origin bit for bit (image and grid tiles; segment and line groups need not), with
//! `tmin >= 0`, (b) the shaft fits (every direction within `acos(0.2)` of the
//! mean), and (c) the list holds at most [`Config::list_limit`] triangles (`max_list` for a tile
//! of 16 rays); a listed tile's rays are then
//! answered from the list where step 4 proves it. Corner rays that hit different triangles or
//! different leaves do not unlist a tile; inner rays that see past the corners' depth fall back.
//!
//! **Counters** (the paper's Table 1): `list_rays / rays` is the share of rays answered without
//! traversal, `list_len / tiles_listed` the mean list length, `tiles_split` the tiles traced as
//! quarters, `nodes + leaves` the traversal
//! steps of corner and fallback rays, `ray_tri + list_tests` the triangle tests. Measured in
//! BENCHMARKS.md (§ RTT).
//!
//! **Memory**: the kd-tree's (8 bytes per node, 4 per reference; [`Rtt::bytes`] is the tree's);
//! per parallel task a scratch of one tile's slots (and their structure-of-arrays copy), the
//! list and its prepared triangles (84 bytes each), and three stacks: about 32 KiB for 4×4-pixel
//! tiles of one sample, about 144 KiB at 6×6 samples, whose lists may be 16 times longer
//! (reported as `peak_bytes`, bounded in `tests/rtt.rs`), nothing per ray.

mod origin;
mod tile;

use crate::accel::kdtree::{BuildConfig, KdTree};
use crate::error::{Error, Result};
use crate::rays::{HitBatch, RayBatch, RayLayout, MISS};
use crate::scene::{Scene, Stamp};
use crate::tracer::{
    par_occlusion_chunks, par_ray_chunks, CostMut, CounterDocs, RayCost, Stats, Tracer,
};
use crate::tracers::kdtree::{prepare_tree, Built, Counters as KdCounters};
use crate::tracers::{OptionDoc, Preset};
use tile::{Band, Ctx, Scratch};

/// Options (`rtt:key=value`). Defaults are the fields' values.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Tile side in pixels (2..=16). Default 4 (the paper's 4×4 tiles).
    pub tile: usize,
    /// Longest relevant-triangle list a tile of 16 rays may use (0..=4096; 0: only tiles whose
    /// shaft holds no triangle answer rays from their list). Default 64. A tile of `R` rays may
    /// use [`Config::list_limit`]`(R)`: a list's cost and the walks it saves are both per ray.
    pub max_list: usize,
    /// Relative growth of the cap beyond the deepest corner hit (>= 0). Default 1e-3.
    pub cap_growth: f64,
    /// Consecutive segments (shadow rays to a point light) per shaft (4..=256). Default 16.
    pub segment_group: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            tile: 4,
            max_list: 64,
            cap_growth: 1e-3,
            segment_group: 16,
        }
    }
}

impl Config {
    /// Longest list a tile of `rays` rays may use: `max_list · ⌊rays / 16⌋`, at least
    /// `max_list` and at most 16 times it (antialiased image tiles: 4×4 pixels of 4×4 samples
    /// may use 1,024 triangles by default; measured in BENCHMARKS.md § RTT).
    pub fn list_limit(&self, rays: usize) -> usize {
        self.max_list * (rays / 16).clamp(1, 16)
    }

    fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("tracer rtt: {m}")));
        if !(2..=16).contains(&self.tile) {
            return bad(format!("tile must be in 2..=16, got {}", self.tile));
        }
        if self.max_list > 4096 {
            return bad(format!(
                "max_list must be in 0..=4096, got {}",
                self.max_list
            ));
        }
        if !(self.cap_growth >= 0.0 && self.cap_growth.is_finite()) {
            return bad(format!(
                "cap_growth must be finite and >= 0, got {}",
                self.cap_growth
            ));
        }
        if !(4..=256).contains(&self.segment_group) {
            return bad(format!(
                "segment_group must be in 4..=256, got {}",
                self.segment_group
            ));
        }
        Ok(())
    }
}

/// One line per option, for `raysift tracers --verbose`.
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc {
        key: "tile",
        doc: "tile side in pixels (2..=16; the paper's 4)",
    },
    OptionDoc {
        key: "max_list",
        doc: "longest relevant-triangle list a tile of 16 rays uses, R rays: max_list·R/16, at most 16× (0..=4096; 0: only empty shafts answer rays)",
    },
    OptionDoc {
        key: "cap_growth",
        doc: "relative growth of the shaft's cap beyond the deepest corner hit (>= 0)",
    },
    OptionDoc {
        key: "segment_group",
        doc: "consecutive shadow rays to a point light per shaft (4..=256)",
    },
];

/// Configurations the conformance suite checks besides the defaults.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "2×2 tiles, no cap growth",
        opts: &[("tile", "2"), ("cap_growth", "0")],
    },
    Preset {
        name: "8×8 tiles, long lists",
        opts: &[("tile", "8"), ("max_list", "1024")],
    },
    Preset {
        name: "lists of 0 (only empty shafts answer)",
        opts: &[("max_list", "0")],
    },
    Preset {
        name: "lists of 4, deep cap",
        opts: &[("max_list", "4"), ("cap_growth", "10")],
    },
];

crate::counters! {
    /// What an `rtt` trace counts.
    pub struct Counters {
        /// Tiles formed.
        tiles,
        /// Tiles whose relevant-triangle list was built (at most `max_list` long).
        tiles_listed,
        /// Tiles of rays from one origin whose list was too long, traced as four smaller tiles
        /// (the quarters count as tiles too).
        tiles_split,
        /// Corner rays traced through the tree to set a tile's cap.
        corner_rays,
        /// Rays answered from their tile's list, without traversal.
        list_rays,
        /// Rays traced through the tree because their tile had no list or the list's answer was
        /// not proven (corner rays and rays outside tiles not included).
        fallback_rays,
        /// Sum of the lengths of the lists built.
        list_len,
        /// Ray/triangle tests against lists.
        list_tests,
        /// Kd-tree nodes the shafts entered.
        shaft_nodes,
        /// Shaft/box tests (cells and triangle boxes).
        shaft_boxes,
        /// Single-ray walks: root box tests.
        ray_box,
        /// Single-ray walks: interior nodes visited.
        nodes,
        /// Single-ray walks: leaves visited.
        leaves,
        /// Single-ray walks: ray/triangle tests.
        ray_tri,
        /// Single-ray walks: deferred subtrees dropped beyond the closest hit.
        culled,
    }
}

impl Counters {
    /// Adds a single-ray walk's counters.
    fn add_walk(&mut self, k: &KdCounters) {
        self.ray_box += k.ray_box;
        self.nodes += k.nodes;
        self.leaves += k.leaves;
        self.ray_tri += k.ray_tri;
        self.culled += k.culled;
    }
}

/// Counter docs, for the registry: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (
    <Built as crate::tracer::CounterSet>::DOCS,
    <Counters as crate::tracer::CounterSet>::DOCS,
);

/// Rays per parallel task for groups of consecutive rays.
const CHUNK: usize = 256;
/// Rays per parallel task, at least, for grids.
const GRID_CHUNK: usize = 1024;

/// How a batch is cut.
#[derive(Clone, Copy, Debug)]
enum Plan {
    /// One image of `width × height` pixels of `samples` rays; tasks are bands of `tile` rows.
    Image {
        width: usize,
        height: usize,
        samples: usize,
    },
    /// Consecutive `side × side` grids; tasks are runs of whole grids.
    Grids { side: usize },
    /// Segments towards one point (shadow rays to a point light): tiles of `segment_group` consecutive
    /// rays.
    Segments,
    /// Groups of `segment_group` consecutive rays whose lines may meet near one point
    /// (reflections off a planar mirror; anything else falls back ray by ray).
    Lines,
}

/// The `rtt` tracer: a [`KdTree`] rebuilt when the scene changes, traced in shafts.
#[derive(Default)]
pub struct Rtt {
    cfg: Config,
    tree: KdTree,
    stamp: Stamp,
}

impl Rtt {
    /// A tracer with `cfg` (checked) and no scene yet.
    pub fn new(cfg: Config) -> Result<Self> {
        cfg.check()?;
        Ok(Self {
            cfg,
            tree: KdTree::default(),
            stamp: Stamp::default(),
        })
    }

    fn plan(&self, rays: &RayBatch) -> Plan {
        let n = rays.len();
        let layout = match rays.layout {
            RayLayout::Unknown => rays.detect_layout(None),
            l => l,
        };
        match layout {
            RayLayout::Pinhole { width, height, .. } if width as usize * height as usize == n => {
                Plan::Image {
                    width: width as usize,
                    height: height as usize,
                    samples: 1,
                }
            }
            RayLayout::PixelSamples {
                width,
                height,
                samples,
                ..
            } if (width as usize * height as usize * samples as usize) == n && samples > 0 => {
                Plan::Image {
                    width: width as usize,
                    height: height as usize,
                    samples: samples as usize,
                }
            }
            RayLayout::OriginGrids { side }
                if side >= 2 && n.is_multiple_of((side * side) as usize) =>
            {
                Plan::Grids {
                    side: side as usize,
                }
            }
            RayLayout::ToPoint { .. } => Plan::Segments,
            _ => Plan::Lines,
        }
    }

    fn chunk_of(&self, plan: Plan) -> usize {
        match plan {
            Plan::Image { width, samples, .. } => self.cfg.tile * width * samples,
            Plan::Grids { side } => side * side * (GRID_CHUNK / (side * side)).max(1),
            Plan::Segments | Plan::Lines => {
                CHUNK.div_ceil(self.cfg.segment_group) * self.cfg.segment_group
            }
        }
    }

    /// Traces rays `range` as `plan` says, emitting every ray's answer.
    fn run<const ANY: bool>(
        &self,
        ctx: &Ctx<'_>,
        plan: Plan,
        range: std::ops::Range<usize>,
        mut cost: Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, crate::tracers::kdtree::Best),
    ) -> Counters {
        let mut c = Counters::default();
        let t = self.cfg.tile;
        let (bands, samples) = match plan {
            Plan::Image {
                width,
                height,
                samples,
            } => {
                let per_row = width * samples;
                let row0 = range.start / per_row;
                let rows = (height - row0).min(t);
                let band = Band {
                    base: range.start,
                    width,
                    rows,
                    samples,
                };
                (vec![band], samples)
            }
            Plan::Grids { side } => {
                let g = side * side;
                let bands = range
                    .clone()
                    .step_by(g)
                    .map(|base| Band {
                        base,
                        width: side,
                        rows: side,
                        samples: 1,
                    })
                    .collect();
                (bands, 1)
            }
            Plan::Segments | Plan::Lines => {
                let g = self.cfg.segment_group;
                let mut s = Scratch::new(g, self.cfg.list_limit(g));
                for first in range.clone().step_by(g) {
                    let group = first..(first + g).min(range.end);
                    if matches!(plan, Plan::Segments) {
                        ctx.segments::<ANY>(group, range.start, &mut s, &mut c, &mut cost, emit);
                    } else {
                        ctx.lines::<ANY>(group, range.start, &mut s, &mut c, &mut cost, emit);
                    }
                }
                return c;
            }
        };
        let mut s = Scratch::new(t * t * samples, self.cfg.list_limit(t * t * samples));
        for band in bands {
            for j0 in (0..band.rows).step_by(t) {
                for i0 in (0..band.width).step_by(t) {
                    let (tw, th) = (t.min(band.width - i0), t.min(band.rows - j0));
                    ctx.tile::<ANY>(
                        band,
                        (i0, j0, tw, th),
                        range.start,
                        &mut s,
                        &mut c,
                        &mut cost,
                        emit,
                    );
                }
            }
        }
        c
    }

    /// Bytes of one task's scratch under `plan` (reported as peak bytes).
    fn scratch_bytes(&self, plan: Plan) -> usize {
        let rays = match plan {
            Plan::Image { samples, .. } => self.cfg.tile * self.cfg.tile * samples,
            Plan::Grids { .. } => self.cfg.tile * self.cfg.tile,
            Plan::Segments | Plan::Lines => self.cfg.segment_group,
        };
        Scratch::new(rays, self.cfg.list_limit(rays)).bytes()
    }
}

impl Tracer for Rtt {
    fn name(&self) -> &'static str {
        "rtt"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        prepare_tree(
            &mut self.tree,
            &mut self.stamp,
            &BuildConfig::default(),
            scene,
        )
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let ctx = Ctx {
            tree: &self.tree,
            soup: scene.triangles(),
            rays,
            cfg: &self.cfg,
        };
        let plan = self.plan(rays);
        let c: Counters =
            par_ray_chunks(rays, hits, cost, self.chunk_of(plan), |range, out, cost| {
                let start = range.start;
                self.run::<false>(&ctx, plan, range, cost, &mut |i, (t, p, u, v)| {
                    if p != MISS {
                        let k = i - start;
                        (out.t[k], out.prim[k], out.u[k], out.v[k]) = (t, p, u, v);
                    }
                })
            });
        Ok(Stats {
            peak_bytes: self.scratch_bytes(plan) as u64,
            ..Stats::traced(rays.len(), &c)
        })
    }

    fn occluded(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let ctx = Ctx {
            tree: &self.tree,
            soup: scene.triangles(),
            rays,
            cfg: &self.cfg,
        };
        let plan = self.plan(rays);
        let c: Counters = par_occlusion_chunks(
            rays,
            occluded,
            cost,
            self.chunk_of(plan),
            |range, out, cost| {
                let start = range.start;
                self.run::<true>(&ctx, plan, range, cost, &mut |i, best| {
                    out[i - start] = best.1 != MISS;
                })
            },
        );
        Ok(Stats {
            peak_bytes: self.scratch_bytes(plan) as u64,
            ..Stats::traced(rays.len(), &c)
        })
    }

    fn bytes(&self) -> usize {
        self.tree.bytes()
    }
}
