//! `bvh`: a static binned-SAH bounding volume hierarchy, the baseline the papers compare against.
//!
//! **Build**: the shared [`crate::accel::bvh`] builder (binned SAH (Wald 2007, "On fast construction of SAH-based bounding volume
//! hierarchies"): centroids binned into [`Config::bins`] slots on each axis, the split with the
//! lowest SAH cost taken, a leaf made when a node has at most [`Config::max_leaf`] triangles and
//! the SAH says splitting does not pay. Parallel with rayon above [`Config::parallel_threshold`]
//! triangles (see `build`). Identical centroids, flat nodes and very deep trees fall back to object
//! median splits, so any soup builds and the depth is bounded). **Update** ([`Config::update`]):
//! a scene change rebuilds the tree by default (the static baseline); `refit` keeps the tree and
//! recomputes its boxes ([`Bvh::refit`]) when the triangles moved but stayed the same
//! triangles, and `auto` refits until the tree's SAH cost has grown by
//! [`Config::rebuild_ratio`] over its last build, then rebuilds (refit vs rebuild is measured in
//! BENCHMARKS.md, § BVH refit vs rebuild). **Spatial splits** ([`Config::spatial`], off by
//! default): the SBVH build ([`Bvh::build_spatial`], Stich et al. 2009, with box-cut references,
//! exact as `accel/bvh/sbvh.rs` proves); a triangle cut across leaves is copied into each.
//!
//! **Traversal**: as pbrt's `BVHAggregate` (flat depth-first array, fixed stack, near child
//! first), except that both children's boxes are tested at their parent with one 4-wide SIMD slab
//! test ([`SlabRay::entry2`](crate::geom::SlabRay::entry2), SSE2 on x86_64, bit for bit the scalar
//! [`SlabRay::entry`](crate::geom::SlabRay::entry) on each box), the nearer hit one (by entry
//! distance) is visited next and the other pushed with its entry, and a popped node whose entry
//! lies beyond the current hit is skipped (tinybvh's BVH2 order). Ordering by the ray's sign on
//! the split axis instead gave the same work within 3% (sphere:1M, random rays) and no measurable
//! time difference, so the distance order (free once both boxes are tested) is kept.
//! The box test is conservative at both ends, and the cull is inclusive (a box entered exactly at
//! the best `t` is still visited): together with the shared triangle test and
//! [`closer`](crate::tracer::closer) this makes every answer equal to `naive`'s bit for bit
//! (without the lowered entry, the tests do find lost hits on the Cornell box's walls).
//!
//! A big scene's traversal is bound by memory latency (one dependent cache miss per level), not
//! arithmetic: the 4-wide box test alone changed nothing measurable on sphere:1M. So when the
//! tree is bigger than [`AUTO_LANES_BYTES`] each thread keeps 8 rays in flight
//! ([`Config::lanes`]), advancing each by one node per round and prefetching the node (pair or
//! leaf triangles) it will visit next, so the misses of different rays overlap (software
//! pipelining across rays; each ray's walk, work counts and answer are unchanged). On sphere:1M
//! (one thread, 2-vCPU VM shared with other jobs) this took random rays from about 0.55 to
//! 1.0–1.4 Mrays per CPU-second (occlusion 0.6 to 1.3–1.6); coherent camera rays gained little
//! (2.2–2.4 to 2.3–2.6, within noise). Smaller trees use `lanes=1`, the one-ray-at-a-time walk,
//! instantiated per ray octant so the near/far plane choice is compile-time.
//! Open: on sphere:1M camera rays this one-ray walk measured 2.1–2.5 Mrays per CPU-second
//! against 2.3–2.8 for the previous scalar-AoS walk (alternating runs, noisy shared VM): a
//! possible 5–15% regression for coherent rays that the SIMD test did not pay back; a
//! branch-mask (non-octant) variant was no better.
//!
//! **Memory layout** (bytes per triangle; [`BvhTracer::bytes`]):
//! - nodes: 32 B each (box, child-pair/first-triangle offset, count, axis), stored as sibling
//!   pairs in one 64-byte cache line ([`NodePair`]: both boxes as structure of arrays, 48 B, then
//!   both offsets, counts and axes; [`Node`] is the unpacked view), since traversal reads and
//!   tests both children together; with the defaults 1.16 nodes per triangle (leaves of 1.7 triangles on average),
//!   about 37 B per triangle (`traversal_cost=2`: 0.7 nodes, 22 B; 62 B in all);
//! - triangle ids in leaf order: 4 B;
//! - the triangles' corners copied in leaf order (`[v0, v1, v2]`, 36 B, array of structures: a leaf
//!   reads one contiguous run instead of gathering from the scene's soup);
//!
//! so about 77 B per triangle (measured on sphere:1M and soup:1M) on top of the scene's own 36 B
//! soup. The build temporarily holds 32 B per triangle of primitive references. With
//! [`Config::spatial`] the ids and copies are per reference (a cut triangle has one in each of
//! its leaves): 40 B per reference plus the nodes, at most `1 + max_growth` references per
//! triangle (`tests/memory.rs`; Sponza 69.5 → 88.7 B per triangle, BENCHMARKS.md § "Cone
//! tracing: the SBVH").

#[cfg(test)]
mod tests;
mod traverse;

pub use crate::accel::bvh::{BuildConfig, Bvh, Node, NodePair, SpatialConfig, MAX_BINS, MAX_DEPTH};

use crate::error::{Error, Result};
use crate::rays::{HitBatch, RayBatch};
use crate::scene::{Change, Scene, Stamp, TriangleSoup};
use crate::tracer::{par_occlusion_chunks, par_ray_chunks, CounterDocs, RayCost, Stats, Tracer};
use crate::tracers::{OptionDoc, Preset};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Rays per parallel task (as `naive`): amortises scheduling, balances 2–64 cores.
const CHUNK: usize = 256;

/// Tree size (bytes, [`LeafBvh::bytes`]) above which `lanes=0` traces 8 rays in flight.
pub const AUTO_LANES_BYTES: usize = 4 << 20;

/// Build options (`bvh:key=value` on the command line). Defaults are the fields' documented values.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Bins per axis for the SAH sweep (2..=32). Default 16: within about 1% of the cost of a full
    /// sweep on our scenes at a fraction of the build time (Wald 2007 uses 16–32).
    pub bins: usize,
    /// Most triangles in a leaf (1..=255); nodes at or below it become leaves when the SAH says
    /// splitting costs more. Default 4.
    pub max_leaf: usize,
    /// SAH cost of visiting an interior node (two box tests), relative to `intersection_cost`.
    /// Default 1.0.
    pub traversal_cost: f32,
    /// SAH cost of one ray/triangle test. Default 1.0.
    pub intersection_cost: f32,
    /// Nodes with at least this many triangles build their children in parallel and bin in
    /// parallel. Default 4096: below it, task overhead outweighs the work.
    pub parallel_threshold: usize,
    /// Rays traced in flight per thread (0..=16): each round advances each by one node and
    /// prefetches its next node, so their cache misses overlap (see the module doc). 1 traces
    /// one ray at a time with a walk specialised per ray octant. Default 0, automatic: 8 when
    /// the tree is bigger than [`AUTO_LANES_BYTES`] (it no longer fits in cache, so misses
    /// dominate), else 1 (in cache the interleaving's bookkeeping and mixed branch history cost
    /// more than it saves: sphere:10k camera rays 5.0 vs 3.9 Mrays per CPU-second).
    pub lanes: usize,
    /// What a prepare does when the scene changed but kept its triangles (meshes moved or
    /// deformed): `rebuild` (build from scratch, as for a new scene), `refit` (same tree, new
    /// boxes: O(T), quality degrades as triangles drift) or `auto` (refit while the SAH cost
    /// stays within `rebuild_ratio` of the last build's, else rebuild). Default `rebuild`.
    pub update: Update,
    /// With `update=auto`: rebuild once the refitted tree's SAH cost exceeds this multiple of
    /// the last build's (>= 1). Default 1.5.
    pub rebuild_ratio: f32,
    /// Build with spatial splits (the SBVH: a node may cut space at a plane and reference a
    /// straddling triangle from both sides). Default false: the plain binned SAH.
    pub spatial: bool,
    /// With `spatial`: try a plane where the object split's children overlap by more than this
    /// fraction of the root's area (0..=1). Default 1e-5 (Stich et al.).
    pub alpha: f32,
    /// With `spatial`: extra references allowed, times the triangle count (>= 0). Default 1.
    pub max_growth: f32,
}

/// [`Config::update`].
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Update {
    /// Build from scratch at every change.
    #[default]
    Rebuild,
    /// Keep the tree, recompute its boxes.
    Refit,
    /// Refit until the SAH cost has grown by `rebuild_ratio`, then rebuild.
    Auto,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            bins: 16,
            max_leaf: 4,
            traversal_cost: 1.0,
            intersection_cost: 1.0,
            parallel_threshold: 4096,
            lanes: 0,
            update: Update::Rebuild,
            rebuild_ratio: 1.5,
            spatial: false,
            alpha: 1e-5,
            max_growth: 1.0,
        }
    }
}

impl Config {
    /// The builder's part of the options.
    pub fn build_config(&self) -> BuildConfig {
        BuildConfig {
            bins: self.bins,
            max_leaf: self.max_leaf,
            traversal_cost: self.traversal_cost,
            intersection_cost: self.intersection_cost,
            parallel_threshold: self.parallel_threshold,
        }
    }

    /// The spatial splits' part, when [`Config::spatial`] is on.
    pub fn spatial_config(&self) -> Option<SpatialConfig> {
        self.spatial.then_some(SpatialConfig {
            alpha: self.alpha,
            max_growth: self.max_growth,
        })
    }

    /// Checks the ranges documented on the fields.
    pub fn check(&self) -> Result<()> {
        self.build_config().check("tracer bvh")?;
        SpatialConfig {
            alpha: self.alpha,
            max_growth: self.max_growth,
        }
        .check("tracer bvh")?;
        if self.lanes > traverse::MAX_LANES {
            return Err(Error::Invalid(format!(
                "tracer bvh: lanes must be in 0..={}, got {}",
                traverse::MAX_LANES,
                self.lanes
            )));
        }
        if !(self.rebuild_ratio >= 1.0 && self.rebuild_ratio.is_finite()) {
            return Err(Error::Invalid(format!(
                "tracer bvh: rebuild_ratio must be finite and >= 1, got {}",
                self.rebuild_ratio
            )));
        }
        Ok(())
    }
}

/// One line per option, for `raysift tracers --verbose` (details on the fields above).
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc { key: "bins", doc: "bins per axis for the SAH sweep (2..=32)" },
    OptionDoc { key: "max_leaf", doc: "most triangles in a leaf (1..=255)" },
    OptionDoc { key: "traversal_cost", doc: "SAH cost of an interior node, relative to a triangle test" },
    OptionDoc { key: "intersection_cost", doc: "SAH cost of a ray/triangle test" },
    OptionDoc { key: "parallel_threshold", doc: "nodes with at least this many triangles build in parallel" },
    OptionDoc { key: "lanes", doc: "rays in flight per thread (0: 8 when the tree exceeds 4 MiB, else 1)" },
    OptionDoc { key: "update", doc: "on a scene change: rebuild, refit, or auto (refit until the SAH grows by rebuild_ratio)" },
    OptionDoc { key: "rebuild_ratio", doc: "update=auto: rebuild when the SAH cost exceeds this multiple of the last build's" },
    OptionDoc { key: "spatial", doc: "SBVH build: spatial splits, straddling triangles referenced from both sides" },
    OptionDoc { key: "alpha", doc: "spatial: try a plane where object-split children overlap by more than this fraction of the root's area" },
    OptionDoc { key: "max_growth", doc: "spatial: extra references allowed, times the triangle count" },
];

/// Configurations the conformance suite checks besides the defaults.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "eight lanes",
        opts: &[("lanes", "8")],
    },
    Preset {
        name: "small leaves, one lane",
        opts: &[
            ("max_leaf", "2"),
            ("parallel_threshold", "64"),
            ("lanes", "1"),
        ],
    },
    Preset {
        name: "two bins, leaves of one, three lanes",
        opts: &[
            ("bins", "2"),
            ("max_leaf", "1"),
            ("parallel_threshold", "8"),
            ("lanes", "3"),
        ],
    },
    Preset {
        name: "no traversal cost",
        opts: &[("max_leaf", "1"), ("traversal_cost", "0")],
    },
    Preset {
        name: "refit",
        opts: &[("update", "refit")],
    },
    Preset {
        name: "spatial splits everywhere, leaves of one",
        opts: &[
            ("spatial", "true"),
            ("alpha", "0"),
            ("max_leaf", "1"),
            ("parallel_threshold", "64"),
        ],
    },
    Preset {
        name: "spatial splits, refit",
        opts: &[("spatial", "true"), ("alpha", "0"), ("update", "refit")],
    },
    Preset {
        name: "auto update",
        opts: &[("update", "auto"), ("rebuild_ratio", "1")],
    },
];

/// The tree with the triangles' corners copied in leaf order: what traversal reads (a leaf's
/// triangles are one contiguous run instead of a gather from the scene's soup).
#[derive(Clone, Debug, Default)]
pub struct LeafBvh {
    /// The hierarchy.
    pub tree: Bvh,
    /// Corners of the triangle at each leaf position.
    pub tris: Vec<[Vec3; 3]>,
}

impl std::ops::Deref for LeafBvh {
    type Target = Bvh;
    fn deref(&self) -> &Bvh {
        &self.tree
    }
}

impl LeafBvh {
    /// Bytes held (nodes + ids + triangle copies).
    pub fn bytes(&self) -> usize {
        self.tree.bytes() + self.tris.capacity() * std::mem::size_of::<[Vec3; 3]>()
    }

    /// (Re)writes the leaf-ordered copies from the soup.
    fn copy_triangles(&mut self, soup: &TriangleSoup) {
        use rayon::prelude::*;
        self.tris.clear();
        self.tris
            .par_extend(self.tree.ids.par_iter().map(|&i| soup.get(i as usize)));
        self.tris.shrink_to_fit();
    }

    /// [`Bvh::validate`] against the scene's triangles, and the copies equal its corners.
    pub fn validate(&self, scene: &Scene) -> Result<()> {
        let soup = scene.triangles();
        self.tree.validate(soup)?;
        if self.tris.len() != self.tree.ids.len() {
            return Err(Error::Invalid(format!(
                "bvh invalid: {} copies for {} references",
                self.tris.len(),
                self.tree.ids.len()
            )));
        }
        for (k, &id) in self.tree.ids.iter().enumerate() {
            if self.tris[k] != soup.get(id as usize) {
                return Err(Error::Invalid(format!(
                    "bvh invalid: copy at position {k} differs from triangle {id}"
                )));
            }
        }
        Ok(())
    }
}

/// The `bvh` tracer: a [`Bvh`] built at the first prepare and rebuilt (or refitted, see
/// [`Config::update`]) when the scene changes.
#[derive(Default)]
pub struct BvhTracer {
    cfg: Config,
    bvh: LeafBvh,
    stamp: Stamp,
    /// SAH cost of the last full build (`update=auto`).
    built_sah: f64,
}

impl BvhTracer {
    /// A tracer with `cfg` and no scene yet (every ray misses until prepare).
    pub fn new(cfg: Config) -> Result<Self> {
        cfg.check()?;
        Ok(Self {
            cfg,
            bvh: LeafBvh::default(),
            stamp: Stamp::default(),
            built_sah: 0.0,
        })
    }

    /// The current hierarchy and its triangle copies.
    pub fn bvh(&self) -> &LeafBvh {
        &self.bvh
    }

    /// Rays in flight per thread for the current tree ([`Config::lanes`], 0 resolved).
    pub fn lanes(&self) -> usize {
        match self.cfg.lanes {
            0 if self.bvh.bytes() > AUTO_LANES_BYTES => 8,
            0 => 1,
            l => l,
        }
    }
}

impl Tracer for BvhTracer {
    fn name(&self) -> &'static str {
        "bvh"
    }

    fn prepare(&mut self, scene: &Scene) -> Result<Stats> {
        let soup = scene.triangles();
        let change = scene.changes_since(self.stamp);
        let mut built = Built::default();
        if change == Change::None {
            // Nothing moved: the tree stands.
        } else {
            self.stamp = Stamp::default();
            let kept = matches!(change, Change::Meshes { .. });
            let mut refitted = false;
            let mut n = 0;
            if kept && self.cfg.update != Update::Rebuild {
                n = self.bvh.tree.refit(soup) as u64;
                // `auto`: keep the refitted tree while it is not much worse than a fresh build
                // was (the refit is wasted when it is, about a twentieth of a build).
                refitted = self.cfg.update == Update::Refit
                    || self.bvh.tree.sah_cost() <= self.cfg.rebuild_ratio as f64 * self.built_sah;
            }
            if refitted {
                built.refitted = n;
                self.bvh.copy_triangles(soup);
            } else {
                // Drop the old tree first so peak memory is one tree, not two.
                self.bvh = LeafBvh::default();
                self.bvh.tree = match self.cfg.spatial_config() {
                    None => Bvh::build(soup, &self.cfg.build_config())?,
                    Some(sp) => {
                        let (t, st) = Bvh::build_spatial(soup, &self.cfg.build_config(), &sp)?;
                        built.spatial_splits = st.spatial_splits;
                        t
                    }
                };
                self.bvh.copy_triangles(soup);
                self.built_sah = self.bvh.tree.sah_cost();
                built.builds = 1;
            }
        }
        self.stamp = scene.stamp();
        built.nodes = self.bvh.node_count() as u64;
        built.leaves = self.bvh.leaf_count() as u64;
        built.references = self.bvh.ids.len() as u64;
        Ok(Stats::prepared(&built, self.bvh.bytes()))
    }

    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats> {
        self.stamp.check(scene, self.name())?;
        // Per-ray cost is recorded by the one-ray walk (the same walk and counts, ray by ray).
        let lanes = if cost.is_some() { 1 } else { self.lanes() };
        let c: traverse::Counters = par_ray_chunks(rays, hits, cost, CHUNK, |range, out, cost| {
            if lanes == 1 {
                traverse::closest_chunk(&self.bvh, rays, range, out, cost)
            } else {
                traverse::closest_chunk_interleaved(&self.bvh, rays, range, lanes, out)
            }
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
        let lanes = if cost.is_some() { 1 } else { self.lanes() };
        let c: traverse::Counters =
            par_occlusion_chunks(rays, occluded, cost, CHUNK, |range, out, cost| {
                if lanes == 1 {
                    traverse::occluded_chunk(&self.bvh, rays, range, out, cost)
                } else {
                    traverse::occluded_chunk_interleaved(&self.bvh, rays, range, lanes, out)
                }
            });
        Ok(Stats::traced(rays.len(), &c))
    }

    fn bytes(&self) -> usize {
        self.bvh.bytes()
    }
}

crate::counters! {
    /// What a `bvh` prepare builds.
    pub struct Built {
        /// Full builds (0 when the tree was refitted or kept).
        builds,
        /// Nodes refitted (0 after a build).
        refitted,
        /// Nodes of the tree (interior and leaves).
        nodes,
        /// Leaves.
        leaves,
        /// Triangle references in the leaves (the triangle count, or more after spatial splits).
        references,
        /// Nodes split by a plane (`spatial`; 0 after a refit or a plain build).
        spatial_splits,
    }
}

/// Counter docs, for the registry: (built, work).
pub const COUNTERS: (CounterDocs, CounterDocs) = (
    <Built as crate::tracer::CounterSet>::DOCS,
    <traverse::Counters as crate::tracer::CounterSet>::DOCS,
);
