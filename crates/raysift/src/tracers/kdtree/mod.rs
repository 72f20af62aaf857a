//! `kdtree`: the SAH kd-tree of the relevant-triangle shafts paper's baseline (and the cone
//! tracing paper's pbrt-v3 kd-tree), traversed one ray at a time.
//!
//! **Build**: the shared [`crate::accel::kdtree`] (event-sorted O(N log N) SAH build of Wald &
//! Havran 2006, box split clipping, empty-space bonus, threaded; its module doc proves the walk
//! exact). Rebuilt whenever the scene changes.
//!
//! **Packets** (`packet.rs`, `packets=4`): 2×2 pixels of a pinhole image (4 consecutive rays
//! otherwise) walk the tree together, the relevant-triangle shafts paper's SIMD baseline (Wald et
//! al. 2001); each ray's decisions are its single-ray walk's, so the answers are too.
//!
//! **Traversal** (`traverse.rs`): pbrt-v3's front-to-back stack walk with 12-byte stack entries;
//! the split distance is widened to [`KdTree::split_window`] so that every gated hit is found
//! (triangles in split planes, axis-parallel rays in a plane, ties to the smaller id included).
//! There is no mailbox: a triangle referenced by several leaves on a ray's path is tested once
//! per leaf (the `ray_tri` counter includes the repeats).
//!
//! **Memory** ([`KdTracer::bytes`]): 8 bytes per node and 4 per triangle reference; the
//! triangles are read from the scene's soup by id. Measured per scene in BENCHMARKS.md
//! (§ kd-tree); `tests/kdtree.rs` checks the formula and a bound.

mod packet;
mod traverse;

pub use crate::accel::kdtree::{BuildConfig, KdTree};
pub use packet::{walk4, Stacks};
pub use traverse::{walk, Best, Counters, StackEntry};

use crate::error::Result;
use crate::rays::{HitBatch, RayBatch, MISS};
use crate::scene::{Change, Scene, Stamp};
use crate::tracer::{par_occlusion_chunks, par_ray_chunks, CounterDocs, RayCost, Stats, Tracer};
use crate::tracers::{OptionDoc, Preset};

/// Rays per parallel task (as `bvh`).
const CHUNK: usize = 256;

/// Options (`kdtree:key=value`): the builder's (documented on [`BuildConfig`]'s fields, same
/// defaults) and the walk's. Defaults are the fields' values.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// [`BuildConfig::traversal_cost`].
    pub traversal_cost: f32,
    /// [`BuildConfig::intersection_cost`].
    pub intersection_cost: f32,
    /// [`BuildConfig::empty_bonus`].
    pub empty_bonus: f32,
    /// [`BuildConfig::max_leaf`].
    pub max_leaf: usize,
    /// [`BuildConfig::max_depth`].
    pub max_depth: usize,
    /// [`BuildConfig::parallel_threshold`].
    pub parallel_threshold: usize,
    /// Rays walked together: 1 (single rays) or 4 (packets of 2×2 pixels for a pinhole image,
    /// of 4 consecutive rays otherwise; `packet.rs`). Default 1.
    pub packets: usize,
}

impl Default for Config {
    fn default() -> Self {
        let b = BuildConfig::default();
        Self {
            traversal_cost: b.traversal_cost,
            intersection_cost: b.intersection_cost,
            empty_bonus: b.empty_bonus,
            max_leaf: b.max_leaf,
            max_depth: b.max_depth,
            parallel_threshold: b.parallel_threshold,
            packets: 1,
        }
    }
}

impl Config {
    /// The builder's part.
    pub fn build(&self) -> BuildConfig {
        BuildConfig {
            traversal_cost: self.traversal_cost,
            intersection_cost: self.intersection_cost,
            empty_bonus: self.empty_bonus,
            max_leaf: self.max_leaf,
            max_depth: self.max_depth,
            parallel_threshold: self.parallel_threshold,
        }
    }

    fn check(&self) -> Result<()> {
        self.build().check("tracer kdtree")?;
        if !matches!(self.packets, 1 | 4) {
            return Err(crate::error::Error::Invalid(format!(
                "tracer kdtree: packets must be 1 or 4, got {}",
                self.packets
            )));
        }
        Ok(())
    }
}

/// One line per option, for `raysift tracers --verbose`.
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc {
        key: "traversal_cost",
        doc: "SAH cost of an interior node, relative to a triangle test",
    },
    OptionDoc {
        key: "intersection_cost",
        doc: "SAH cost of a ray/triangle test",
    },
    OptionDoc {
        key: "empty_bonus",
        doc: "share of the intersection cost saved when a side is empty, in [0, 1)",
    },
    OptionDoc {
        key: "max_leaf",
        doc: "nodes with at most this many triangles become leaves (1..=255)",
    },
    OptionDoc {
        key: "max_depth",
        doc: "deepest leaf (0..=64; 0: 8 + 1.3 log2 N)",
    },
    OptionDoc {
        key: "parallel_threshold",
        doc: "nodes with at least this many triangles build in parallel",
    },
    OptionDoc {
        key: "packets",
        doc:
            "rays walked together: 1 or 4 (2×2 pixels of a pinhole image, else 4 consecutive rays)",
    },
];

/// Configurations the conformance suite checks besides the defaults.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "leaves of 4, no empty bonus",
        opts: &[("max_leaf", "4"), ("empty_bonus", "0")],
    },
    Preset {
        name: "free traversal, deep tree, threaded from 8",
        opts: &[("traversal_cost", "0"), ("parallel_threshold", "8")],
    },
    Preset {
        name: "depth 2 (big leaves)",
        opts: &[("max_depth", "2")],
    },
    Preset {
        name: "costly traversal, pbrt-v3 bonus",
        opts: &[("traversal_cost", "4"), ("empty_bonus", "0.5")],
    },
    Preset {
        name: "4-ray packets",
        opts: &[("packets", "4")],
    },
    Preset {
        name: "4-ray packets, leaves of 4",
        opts: &[("packets", "4"), ("max_leaf", "4")],
    },
];

/// The `kdtree` tracer: a [`KdTree`] rebuilt when the scene changes.
#[derive(Default)]
pub struct KdTracer {
    cfg: Config,
    tree: KdTree,
    stamp: Stamp,
}

impl KdTracer {
    /// A tracer with `cfg` (checked) and no scene yet.
    pub fn new(cfg: Config) -> Result<Self> {
        cfg.check()?;
        Ok(Self {
            cfg,
            tree: KdTree::default(),
            stamp: Stamp::default(),
        })
    }

    /// The current tree.
    pub fn tree(&self) -> &KdTree {
        &self.tree
    }
}

impl Tracer for KdTracer {
    fn name(&self) -> &'static str {
        "kdtree"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        prepare_tree(&mut self.tree, &mut self.stamp, &self.cfg.build(), scene)
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let soup = scene.triangles();
        if self.cfg.packets == 4 {
            let plan = packet::plan(rays);
            let c: Counters = par_ray_chunks(rays, hits, cost, plan.chunk(), |range, out, cost| {
                let start = range.start;
                packet::chunk::<false>(&self.tree, soup, rays, plan, range, cost, &mut |i, b| {
                    if b.1 != MISS {
                        let k = i - start;
                        (out.t[k], out.prim[k], out.u[k], out.v[k]) = b;
                    }
                })
            });
            return Ok(Stats::traced(rays.len(), &c));
        }
        let c: Counters = par_ray_chunks(rays, hits, cost, CHUNK, |range, out, cost| {
            traverse::closest_chunk(&self.tree, soup, rays, range, out, cost)
        });
        Ok(Stats::traced(rays.len(), &c))
    }

    fn occluded(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        let soup = scene.triangles();
        if self.cfg.packets == 4 {
            let plan = packet::plan(rays);
            let c: Counters =
                par_occlusion_chunks(rays, occluded, cost, plan.chunk(), |range, out, cost| {
                    let start = range.start;
                    packet::chunk::<true>(&self.tree, soup, rays, plan, range, cost, &mut |i, b| {
                        out[i - start] = b.1 != MISS;
                    })
                });
            return Ok(Stats::traced(rays.len(), &c));
        }
        let c: Counters = par_occlusion_chunks(rays, occluded, cost, CHUNK, |range, out, cost| {
            traverse::occluded_chunk(&self.tree, soup, rays, range, out, cost)
        });
        Ok(Stats::traced(rays.len(), &c))
    }

    fn bytes(&self) -> usize {
        self.tree.bytes()
    }
}

/// Rebuilds `tree` from `scene` when it changed since `stamp` (dropping the old tree first, so
/// peak memory is one tree), and reports what it holds (the `kdtree` and `rtt` prepares).
pub fn prepare_tree(
    tree: &mut KdTree,
    stamp: &mut Stamp,
    cfg: &BuildConfig,
    scene: &Scene,
) -> Result<Stats> {
    let mut built = Built::default();
    if scene.changes_since(*stamp) != Change::None {
        *stamp = Stamp::default();
        *tree = KdTree::default();
        *tree = KdTree::build(scene.triangles(), cfg)?;
        built.builds = 1;
    }
    *stamp = scene.stamp();
    let s = tree.shape();
    built.nodes = (s.interior + s.leaves) as u64;
    built.leaves = s.leaves as u64;
    built.empty_leaves = s.empty_leaves as u64;
    built.refs = s.refs as u64;
    built.depth = tree.depth as u64;
    Ok(Stats::prepared(&built, tree.bytes()))
}

crate::counters! {
    /// What a `kdtree` prepare builds.
    pub struct Built {
        /// Full builds (0 when the scene had not changed).
        builds,
        /// Nodes (interior and leaves).
        nodes,
        /// Leaves.
        leaves,
        /// Leaves with no triangle (empty space cut off).
        empty_leaves,
        /// Triangle references in leaves (a triangle straddling planes counts once per leaf).
        refs,
        /// Deepest leaf.
        depth,
    }
}

/// Counter docs, for the registry: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (
    <Built as crate::tracer::CounterSet>::DOCS,
    <Counters as crate::tracer::CounterSet>::DOCS,
);
