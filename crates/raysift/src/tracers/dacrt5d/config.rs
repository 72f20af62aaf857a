//! The options (`--opt key=value`): the post's choices (frustum culling, the cost stop with its
//! author's 16/16), Arvo–Kirk's cone and Mora's fixed limits as alternatives, and ours (the
//! direction weight of the ray split, spatial splits).

use crate::tracers::{OptionDoc, Preset};
use serde::{Deserialize, Serialize};

/// How geometry is culled against a node's ray bound.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Cull {
    /// The post's open frustum: 4 planes from the u/v bounds through the origin box, plus the
    /// near plane.
    #[default]
    Frustum,
    /// Arvo–Kirk's bounding cone (apex at the origin box's centre, swept by its bounding ball).
    Cone,
}

/// When a node becomes a naive leaf.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Stop {
    /// The post's cost model: leaf when `R·G < c_r·R + c_g·G`.
    #[default]
    Cost,
    /// Mora's fixed limits: leaf when `R < r_limit` or `G < p_limit`.
    Fixed,
}

/// How the hybrid splits a node in space (where its triangles outnumber its rays).
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Space {
    /// An object split of the triangles on the longest axis of their centroids (children with
    /// disjoint triangles, BVH-like, built on the fly); each child keeps the rays that enter its
    /// triangles' box before their best hit, bounds them from that entry point (clipped
    /// origins: `geom::ray5d::clip`) and culls again. Near child first.
    #[default]
    Box,
    /// The first hybrid: a cut along the bundle's major axis at the mean of the triangles' near
    /// ends; every ray goes through the near half, the rays whose hit lies before the cut
    /// leave, the rest take the far half.
    Major,
}

/// Options (`key=value` on the command line).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// `frustum` (the post) or `cone` (Arvo–Kirk). Default `frustum`.
    pub cull: Cull,
    /// `cost` (the post) or `fixed` (Mora). Default `cost`.
    pub stop: Stop,
    /// The cost stop's ray constant `C_r` (the author's code: 16). Default 16.
    pub c_r: f32,
    /// The cost stop's geometry constant `C_g` (the author's code: 16). Default 16.
    pub c_g: f32,
    /// The fixed stop's ray limit (Mora: 20). Default 20.
    pub r_limit: usize,
    /// The fixed stop's triangle limit (Mora: 16). Default 16.
    pub p_limit: usize,
    /// Weight of a direction range (`u`, `v`, slopes in [-1, 1]) against a position range
    /// divided by the scene's largest extent, when choosing the split dimension: the spread of
    /// a ray bundle across the scene is about `Δx + Δu·L`, so 1 weighs both by their footprint
    /// at the scene's size (the author's code splits u/v when their range exceeds a tenth of the
    /// spatial range, in world units: scale-dependent). Default 1.
    pub dir_weight: f32,
    /// Hybrid (ours): a node whose surviving triangles outnumber its rays `spatial_ratio` times
    /// is split in space instead, along the bundle's major axis, near half first; rays whose hit
    /// is final leave before the far half (exact early termination). Default true.
    pub spatial: bool,
    /// See `spatial`. Default 2.
    pub spatial_ratio: f32,
    /// The spatial split: `box` (object split with ray clipping, re-culled children) or
    /// `major` (the major-axis cut with early termination). Default `box`.
    pub space: Space,
    /// With `space=box`: a node the stop rule makes a leaf is split in space instead while it
    /// holds more than this many triangles (the post's rule makes every node of 16 rays or
    /// fewer a leaf, however many triangles it has). Default 32.
    pub leaf_tris: usize,
    /// With `space=box`: at the root, a bundle whose origins' box (the sum of its extents) is at
    /// most this fraction of the scene's box starts its own 5D recursion (rays from one point:
    /// a camera's, a light's); the other rays go through box splits shared by all six bundles
    /// (random rays, bounces, shadow rays from hit points). 0 keeps only rays from one point;
    /// a large value sends every bundle its own way. Default 0.25.
    pub hand_over: f32,
    /// With `space=box`: the shared splits above the bundles stop at nodes of at most this many
    /// triangles, whose leaves test every ray that reaches them. Default 8.
    pub shared_leaf: usize,
    /// With `space=box`: the upper levels of the shared splits, down to nodes of this many
    /// triangles, are made by the first call after a `prepare` and kept between calls (they
    /// depend on the triangles only); 0 makes every split per call. Default 8, `shared_leaf`'s:
    /// every shared split is kept (256, the earlier default, against 8: BENCHMARKS.md
    /// § "dacrt5d: bundles through the kept levels").
    pub top_leaf: usize,
    /// How the kept levels split: `morton` (a sort, then Morton cells) or `middle` (the
    /// per-call splits' rule on 16-bit centroids: traces 0.88–1.08× `morton`'s, a build 2.5×
    /// dearer). Default morton.
    pub top_split: super::TopSplit,
    /// With `space=box` and kept levels: a handed-over bundle walks them too, down to the
    /// first kept node holding at most `spatial_ratio` times its rays' count of triangles (or a
    /// kept leaf), each child with its rays clipped to the child's box, and starts its 5D
    /// recursion there; false starts it on every triangle. Default true.
    pub kept_bundles: bool,
    /// The eye pass (ours, `eye.rs`): a task whose rays all start at one point (a camera's
    /// eye) traces them in that point's frame, an irregular z-buffer (`dacrt`'s light-space
    /// pass with closest hits), instead of the 5D recursion. Default true.
    pub eye: bool,
    /// The eye pass's rays per bucket. Default 4 (1, 2 and 8 were slower on the bunny).
    pub eye_bucket: usize,
    /// The eye pass walks the kept levels (`top_leaf`) near to far and skips the nodes whose
    /// box lies behind every ray's best hit under it (a hierarchical z-buffer). Default true.
    pub eye_tree: bool,
    /// Without the kept levels, the eye pass streams the triangles near to far in this many bins of their distance
    /// from the eye (0: in index order; at most 1024). Default 64 (0 and 16 made more ray/triangle
    /// tests on the bunny, 512 no fewer).
    pub eye_bins: usize,
    /// The eye pass runs only on a task holding at least this many rays per live triangle of
    /// the scene (each task walks the triangles): 0.25 takes the dragon's 262K camera rays on
    /// one thread (faster than the recursion) and not its two tasks of 131K shuffled rays
    /// (slower). Default 0.25.
    pub eye_ratio: f32,
    /// The eye pass also runs when the eye is inside the scene's box. Default false.
    pub eye_inside: bool,
    /// Recursion depth cap (a guard; leaves are naive beyond it). Default 64.
    pub max_depth: u32,
    /// Parallel tasks over disjoint shares of the rays, each with its own lists; 0 = the number
    /// of rayon threads. Default 0.
    pub tasks: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            cull: Cull::Frustum,
            stop: Stop::Cost,
            c_r: 16.0,
            c_g: 16.0,
            r_limit: 20,
            p_limit: 16,
            dir_weight: 1.0,
            spatial: true,
            spatial_ratio: 2.0,
            space: Space::Box,
            leaf_tris: 32,
            hand_over: 0.25,
            shared_leaf: 8,
            top_leaf: 8,
            top_split: super::TopSplit::Morton,
            kept_bundles: true,
            eye: true,
            eye_bucket: 4,
            eye_tree: true,
            eye_bins: 64,
            eye_ratio: 0.25,
            eye_inside: false,
            max_depth: 64,
            tasks: 0,
        }
    }
}

/// One line per option, for `raysift tracers --verbose` (details on [`Config`]'s fields).
pub const OPTION_DOCS: &[OptionDoc] = &[
    OptionDoc { key: "cull", doc: "geometry cull against a node's rays: frustum (the post's 5 planes) or cone (Arvo-Kirk)" },
    OptionDoc { key: "stop", doc: "leaf rule: cost (R*G < c_r*R + c_g*G, the post) or fixed (r_limit, p_limit: Mora)" },
    OptionDoc { key: "c_r", doc: "cost stop: ray constant (author's code: 16)" },
    OptionDoc { key: "c_g", doc: "cost stop: geometry constant (author's code: 16)" },
    OptionDoc { key: "r_limit", doc: "fixed stop: leaf when fewer rays than this (Mora: 20)" },
    OptionDoc { key: "p_limit", doc: "fixed stop: leaf when fewer triangles than this (Mora: 16)" },
    OptionDoc { key: "dir_weight", doc: "weight of a u/v range against a position range over the scene's extent, for the split dimension" },
    OptionDoc { key: "spatial", doc: "hybrid: spatial splits along the major axis (front to back, early termination) where triangles outnumber rays" },
    OptionDoc { key: "spatial_ratio", doc: "spatial split when triangles > spatial_ratio * rays" },
    OptionDoc { key: "space", doc: "spatial split: box (object split, rays clipped to each child's box, re-culled) or major (major-axis cut, early termination)" },
    OptionDoc { key: "hand_over", doc: "space=box: at the root, bundles whose origins' box is at most this fraction of the scene's start their own 5D recursion; the rest share box splits" },
    OptionDoc { key: "top_leaf", doc: "space=box: shared splits above nodes of this many triangles are made by the first call after prepare and kept (0: none)" },
    OptionDoc { key: "kept_bundles", doc: "space=box: handed-over bundles walk the kept levels (children's rays clipped) before their 5D recursion; false: it starts on every triangle" },
    OptionDoc { key: "top_split", doc: "space=box: kept levels split at the middle of the centroids' longest extent (middle) or at Morton cells (morton)" },
    OptionDoc { key: "shared_leaf", doc: "space=box: leaf size of the box splits shared by all bundles" },
    OptionDoc { key: "leaf_tris", doc: "space=box: split a would-be leaf in space while it holds more triangles than this" },
    OptionDoc { key: "eye", doc: "a task whose rays all start at one point is traced in that point's frame (an irregular z-buffer) instead of the 5D recursion" },
    OptionDoc { key: "eye_bucket", doc: "eye pass: rays per bucket" },
    OptionDoc { key: "eye_tree", doc: "eye pass: walk the kept levels near to far, skipping nodes behind every ray's best hit" },
    OptionDoc { key: "eye_bins", doc: "eye pass: triangles streamed near to far in this many distance bins (0: index order)" },
    OptionDoc { key: "eye_ratio", doc: "eye pass only for tasks of at least eye_ratio rays per live triangle" },
    OptionDoc { key: "eye_inside", doc: "eye pass also when the eye is inside the scene's box" },
    OptionDoc { key: "max_depth", doc: "recursion depth cap (leaves are naive beyond it)" },
    OptionDoc { key: "tasks", doc: "parallel tasks over disjoint shares of the rays (0: rayon threads)" },
];

/// Configurations the conformance suite checks besides the defaults: both culls, both stops,
/// deep recursions (tiny limits), ray splits only, spatial splits everywhere (box and
/// major-axis), box splits down to single triangles, positions only: all with the eye pass off
/// (so rays from one point go through them too); then the eye pass: buckets of one ray and of
/// many, the kept levels' walk, index order and distance bins, in several tasks.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "eye pass, buckets of one ray, kept levels of 2 triangles",
        opts: &[
            ("eye_bucket", "1"),
            ("eye_ratio", "0"),
            ("eye_inside", "true"),
            ("top_leaf", "2"),
            ("tasks", "3"),
        ],
    },
    Preset {
        name: "eye pass, buckets of 64 rays, triangles in index order",
        opts: &[
            ("eye_bucket", "64"),
            ("eye_ratio", "0"),
            ("eye_inside", "true"),
            ("eye_tree", "false"),
            ("eye_bins", "0"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "eye pass, triangles in distance bins",
        opts: &[
            ("eye_ratio", "0"),
            ("eye_inside", "true"),
            ("eye_tree", "false"),
        ],
    },
    Preset {
        name: "frustum",
        opts: &[("eye", "false"), ("cull", "frustum"), ("tasks", "1")],
    },
    Preset {
        name: "cone",
        opts: &[("eye", "false"), ("cull", "cone"), ("tasks", "1")],
    },
    Preset {
        name: "frustum fixed tiny",
        opts: &[
            ("eye", "false"),
            ("cull", "frustum"),
            ("stop", "fixed"),
            ("r_limit", "2"),
            ("p_limit", "2"),
            ("tasks", "3"),
        ],
    },
    Preset {
        name: "cone fixed tiny",
        opts: &[
            ("eye", "false"),
            ("cull", "cone"),
            ("stop", "fixed"),
            ("r_limit", "2"),
            ("p_limit", "2"),
            ("tasks", "3"),
        ],
    },
    Preset {
        name: "frustum cost tiny, ray splits only",
        opts: &[
            ("eye", "false"),
            ("c_r", "1"),
            ("c_g", "1"),
            ("spatial", "false"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "cone cost tiny, spatial everywhere",
        opts: &[
            ("eye", "false"),
            ("cull", "cone"),
            ("c_r", "1"),
            ("c_g", "1"),
            ("spatial_ratio", "0"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "major-axis cuts, frustum",
        opts: &[("eye", "false"), ("space", "major"), ("tasks", "2")],
    },
    Preset {
        name: "major-axis cuts everywhere, cone, tiny",
        opts: &[
            ("eye", "false"),
            ("space", "major"),
            ("cull", "cone"),
            ("c_r", "1"),
            ("c_g", "1"),
            ("spatial_ratio", "0"),
        ],
    },
    Preset {
        name: "shared box splits only (no hand-over by size), leaves of one",
        opts: &[
            ("eye", "false"),
            ("hand_over", "0"),
            ("shared_leaf", "1"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "kept levels down to 2 triangles, shared leaves of 1",
        opts: &[
            ("eye", "false"),
            ("top_leaf", "2"),
            ("shared_leaf", "1"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "kept levels at the centroids' middle, down to 2 triangles",
        opts: &[
            ("eye", "false"),
            ("top_split", "middle"),
            ("top_leaf", "2"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "every bundle on its own (hand-over at the root)",
        opts: &[("eye", "false"), ("hand_over", "1e30"), ("tasks", "3")],
    },
    Preset {
        name: "every bundle on its own through kept levels of 2, spatial everywhere",
        opts: &[
            ("eye", "false"),
            ("hand_over", "1e30"),
            ("top_leaf", "2"),
            ("spatial_ratio", "0"),
            ("tasks", "2"),
        ],
    },
    Preset {
        name: "bundles start on every triangle (no kept levels for them)",
        opts: &[("eye", "false"), ("kept_bundles", "false"), ("tasks", "2")],
    },
    Preset {
        name: "box splits down to one triangle",
        opts: &[
            ("eye", "false"),
            ("leaf_tris", "1"),
            ("spatial_ratio", "0.5"),
            ("tasks", "3"),
        ],
    },
    Preset {
        name: "frustum, spatial everywhere, positions only, shallow",
        opts: &[
            ("eye", "false"),
            ("spatial_ratio", "0"),
            ("dir_weight", "0"),
            ("stop", "fixed"),
            ("r_limit", "1"),
            ("p_limit", "1"),
            ("max_depth", "12"),
        ],
    },
];
