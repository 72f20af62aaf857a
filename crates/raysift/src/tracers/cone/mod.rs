//! Cone tracing (Wiche & Kuri 2020, "Performance Evaluation of Acceleration Structures for
//! Cone-tracing Traversal", JCGT 9(1)): for each cone of a batch, the `n` nearest triangles.
//!
//! A cone query does not fit the ray [`Tracer`](crate::Tracer) contract (its answer is a list),
//! so it has a contract of its own, [`ConeTracer`], with the same rules: the scene is passed to
//! every call, a stale scene is an error, batch first, counters per call, and every
//! implementation equals the brute-force [`oracle`] bit for bit (same ids, same order, same `t`;
//! `tests/cone.rs`).
//!
//! | paper | here |
//! |---|---|
//! | §3 Eq. 1, the result `I = ((i₁,t₁)…(iₙ,tₙ))` | [`ConeHits`], [`list::Nearest`] |
//! | `t` "projected onto the cone axis" | [`crate::geom::cone_triangle`] (exact cone/triangle, our definition of `t`) |
//! | near/far clipping, "next n" with `t_near = t_n` | [`ConeBatch`] `t_near`, `near_id`, `t_far`; [`ConeHits::continuation`] |
//! | §3 BVH traversal, Listing 2, Fig. 5 | [`crate::geom::cone_frustum`] (basic and improved), [`bvh`] |
//! | Fig. 6 stack vs node-sorted traversal | [`Traversal`], both in [`bvh`] |
//! | §4 `n = ∞`, count encounters without intersecting | [`Query::count_only`] |
//! | §3 kd-tree traversal, Listing 1, Eq. 2 (Tsakok) | [`kdtree`] over the shared `accel/kdtree/` (pbrt-v3's build parameters) |
//!
//! **The answer.** For cone `c` the eligible triangles are those the exact test accepts with
//! `t ≤ t_far` and `(t, id) ≥ (t_near, near_id)` (lexicographic); the answer is the first `n`
//! of them by `(t, id)`. `t_near = t_n, near_id = i_n + 1` therefore continues exactly where a
//! previous answer stopped, ties included ([`ConeHits::continuation`]). Degenerate triangles
//! (which the scene collapses to a point) are never reported, as no ray hits them.

pub mod bvh;
pub mod io;
pub mod kdtree;
pub mod list;
pub mod oracle;

use crate::error::{Error, Result};
use crate::geom::{ConeF64, ConeFrustum};
use crate::rays::Camera;
use crate::scene::{Scene, TriangleSoup};
use crate::tracer::Stats;
use glam::Vec3;
use rayon::prelude::*;

pub use list::Nearest;

crate::counters! {
    /// Work of a cone trace.
    pub struct ConeCounts {
        /// Nodes entered (the paper's "nodes traversed"): popped and processed, root included.
        nodes,
        /// Cone-frustum/box tests (the kd-tree: its root box only).
        box_tests,
        /// Split-plane distances of the kd-tree walk (Eq. 2: two per split, one test).
        plane_tests,
        /// Triangles met in entered leaves (the paper's "triangle encounters").
        tri_encounters,
        /// Exact cone/triangle tests (0 in counting mode).
        cone_tri,
        /// Triangles the exact test accepted (before the list's limit).
        accepted,
    }
}

/// A batch of cones, structure of arrays: apex, unit axis, half-angle α (radians, in
/// `(0, π/2)`), and the near/far bounds of the answer (module doc).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConeBatch {
    /// Apex x, y, z.
    pub ox: Vec<f32>,
    /// Apex y.
    pub oy: Vec<f32>,
    /// Apex z.
    pub oz: Vec<f32>,
    /// Unit axis x.
    pub dx: Vec<f32>,
    /// Unit axis y.
    pub dy: Vec<f32>,
    /// Unit axis z.
    pub dz: Vec<f32>,
    /// Half-angle α in radians.
    pub alpha: Vec<f32>,
    /// Least `t` of the answer (0: from the apex).
    pub t_near: Vec<f32>,
    /// With `t_near`: a triangle at exactly `t_near` counts only from this id on.
    pub near_id: Vec<u32>,
    /// Greatest `t` of the answer (+∞: unbounded).
    pub t_far: Vec<f32>,
}

/// One cone (the batch's row type).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    /// Apex.
    pub apex: Vec3,
    /// Axis (normalised by [`ConeBatch::push`]).
    pub axis: Vec3,
    /// Half-angle α in radians, `0 < α < π/2`.
    pub alpha: f32,
    /// Least `t` of the answer.
    pub t_near: f32,
    /// First id counted at exactly `t_near`.
    pub near_id: u32,
    /// Greatest `t` of the answer.
    pub t_far: f32,
}

impl Cone {
    /// A cone from the apex with the whole range.
    pub fn new(apex: Vec3, axis: Vec3, alpha: f32) -> Self {
        Self {
            apex,
            axis,
            alpha,
            t_near: 0.0,
            near_id: 0,
            t_far: f32::INFINITY,
        }
    }
}

impl ConeBatch {
    /// Bytes per cone (10 f32/u32 columns).
    pub const BYTES_PER_CONE: usize = 40;

    /// Number of cones.
    pub fn len(&self) -> usize {
        self.ox.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.ox.is_empty()
    }

    /// Appends `c`, normalising its axis; an error names what is wrong (non-finite apex or
    /// axis, zero axis, α outside `(0, π/2)`, NaN or negative `t_near`, `t_far < t_near`).
    pub fn push(&mut self, c: Cone) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("cone {}: {m}", self.len())));
        if !c.apex.is_finite() || !c.axis.is_finite() {
            return bad(format!("non-finite apex {} or axis {}", c.apex, c.axis));
        }
        let axis = c.axis.normalize_or_zero();
        if axis == Vec3::ZERO {
            return bad("zero axis".into());
        }
        if !(c.alpha > 0.0 && c.alpha < std::f32::consts::FRAC_PI_2) {
            return bad(format!(
                "half-angle {} rad ({}°) is not in (0, 90°)",
                c.alpha,
                c.alpha.to_degrees()
            ));
        }
        if !(c.t_near >= 0.0) || c.t_near.is_infinite() || !(c.t_far >= c.t_near) {
            return bad(format!(
                "t_near {} / t_far {}: need 0 <= t_near <= t_far, t_near finite",
                c.t_near, c.t_far
            ));
        }
        self.push_row(Cone { axis, ..c });
        Ok(())
    }

    /// Appends a cone of a valid batch as it is (no second normalisation of its axis, which
    /// could move it by an ulp and change its answer).
    fn push_row(&mut self, c: Cone) {
        self.ox.push(c.apex.x);
        self.oy.push(c.apex.y);
        self.oz.push(c.apex.z);
        self.dx.push(c.axis.x);
        self.dy.push(c.axis.y);
        self.dz.push(c.axis.z);
        self.alpha.push(c.alpha);
        self.t_near.push(c.t_near);
        self.near_id.push(c.near_id);
        self.t_far.push(c.t_far);
    }

    /// Cone `i`.
    pub fn get(&self, i: usize) -> Cone {
        Cone {
            apex: Vec3::new(self.ox[i], self.oy[i], self.oz[i]),
            axis: Vec3::new(self.dx[i], self.dy[i], self.dz[i]),
            alpha: self.alpha[i],
            t_near: self.t_near[i],
            near_id: self.near_id[i],
            t_far: self.t_far[i],
        }
    }

    /// One cone per pixel of `camera` at `w × h` (pixel `(i, j)` is cone `j·w + i`, axis
    /// through the pixel centre as [`Camera::rays`]), half-angle `alpha` radians.
    pub fn from_camera(camera: &Camera, w: u32, h: u32, alpha: f32) -> Result<Self> {
        let rays = camera.rays(w, h);
        let mut b = Self::default();
        for k in 0..rays.len() {
            let r = rays.get(k);
            b.push(Cone::new(r.origin, r.dir, alpha))?;
        }
        Ok(b)
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.len() * Self::BYTES_PER_CONE
    }
}

/// How many triangles per cone, and whether to test them at all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Query {
    /// Most triangles per cone; `None` is the paper's `n = ∞` (every eligible triangle).
    pub n: Option<usize>,
    /// The paper's measuring mode (§4): `n = ∞`, triangles met in leaves are counted
    /// ([`ConeCounts::tri_encounters`]) but not tested, and the answer lists stay empty.
    pub count_only: bool,
}

impl Query {
    /// The `n` nearest.
    pub fn nearest(n: usize) -> Self {
        Self {
            n: Some(n),
            count_only: false,
        }
    }

    /// Every eligible triangle.
    pub fn all() -> Self {
        Self {
            n: None,
            count_only: false,
        }
    }

    /// The paper's counting mode.
    pub fn count() -> Self {
        Self {
            n: None,
            count_only: true,
        }
    }
}

/// The answers of a batch: cone `i`'s triangles are `prim[start[i]..start[i+1]]` with their
/// `t`, sorted by `(t, id)`, no duplicates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConeHits {
    /// Start of each cone's answer, plus the end (`len() + 1` entries).
    pub start: Vec<usize>,
    /// Triangle ids.
    pub prim: Vec<u32>,
    /// Their `t` (module doc of [`crate::geom::cone_triangle`]).
    pub t: Vec<f32>,
    /// Per cone, its nodes entered plus triangles met (the paper's Fig. 1 heatmaps: "the total
    /// computational complexity of node traversal and primitive intersection per pixel").
    pub cost: Vec<u32>,
}

impl ConeHits {
    /// Number of cones.
    pub fn len(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// True when there are no cones.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Cone `i`'s ids and `t`s.
    pub fn cone(&self, i: usize) -> (&[u32], &[f32]) {
        let r = self.start[i]..self.start[i + 1];
        (&self.prim[r.clone()], &self.t[r])
    }

    /// Bytes held (8 per reported triangle + 12 per cone).
    pub fn bytes(&self) -> usize {
        self.start.capacity() * 8
            + self.prim.capacity() * 4
            + self.t.capacity() * 4
            + self.cost.capacity() * 4
    }

    /// The cones that continue these answers ("the next n"), with their indices in
    /// `cones`: each cone whose answer is full (`n` triangles) again, with `t_near = t_n` and
    /// `near_id = i_n + 1` (or just above `t_n` when `i_n = u32::MAX`); cones with fewer than
    /// `n` are finished and left out.
    pub fn continuation(&self, cones: &ConeBatch, n: usize) -> (ConeBatch, Vec<usize>) {
        let mut next = ConeBatch::default();
        let mut which = Vec::new();
        for i in 0..self.len() {
            let (ids, ts) = self.cone(i);
            if n == 0 || ids.len() < n {
                continue;
            }
            let mut c = cones.get(i);
            (c.t_near, c.near_id) = match ids[n - 1].checked_add(1) {
                Some(id) => (ts[n - 1], id),
                None => (ts[n - 1].next_up(), 0),
            };
            next.push_row(c);
            which.push(i);
        }
        (next, which)
    }
}

/// A cone with its prepared tests: the exact one (f64) and the frustum (f32), and its bounds.
#[derive(Clone, Copy, Debug)]
pub struct Prepared {
    /// The exact cone/triangle test's constants.
    pub exact: ConeF64,
    /// The cone-frustum/box test's constants.
    pub frustum: ConeFrustum,
}

impl Prepared {
    /// Both tests of cone `c` (axis normalised by the batch).
    pub fn new(c: &Cone) -> Self {
        Self {
            exact: ConeF64::new(c.apex, c.axis, c.alpha),
            frustum: ConeFrustum::new(c.apex, c.axis, c.alpha),
        }
    }
}

/// Tests triangle `id` of `soup` against `cone` and offers it to `list` (counts included); in
/// counting mode only counts it. The one place a triangle enters an answer, for every walker.
#[inline(always)]
pub fn offer(
    soup: &TriangleSoup,
    id: u32,
    cone: &Prepared,
    list: &mut Nearest,
    count_only: bool,
    c: &mut ConeCounts,
) {
    c.tri_encounters += 1;
    if count_only {
        return;
    }
    let i = id as usize;
    let (v0, v1, v2) = (soup.v0[i], soup.v1[i], soup.v2[i]);
    if v0 == v1 && v1 == v2 {
        return; // degenerate, collapsed by the scene (module doc)
    }
    c.cone_tri += 1;
    if let Some(t) = cone.exact.triangle(v0, v1, v2) {
        c.accepted += 1;
        list.offer(t, id);
    }
}

/// Per-thread scratch a walker keeps between cones (stacks, heaps): allocated once per chunk.
pub trait Scratch: Default + Send {}
impl<T: Default + Send> Scratch for T {}

/// One structure's traversal of one cone: everything a walker (BVH, kd-tree) must
/// provide; [`walk`] runs it over a batch in parallel and gathers the answers.
pub trait Walker: Sync {
    /// Its per-thread scratch.
    type Scratch: Scratch;
    /// Offers every triangle that may be eligible for `cone` to `list` through [`offer`],
    /// culling only what cannot be (module doc of [`bvh`] for the rules).
    fn walk(
        &self,
        soup: &TriangleSoup,
        cone: &Prepared,
        list: &mut Nearest,
        count_only: bool,
        scratch: &mut Self::Scratch,
        c: &mut ConeCounts,
    );
}

/// Cones per parallel chunk.
const CHUNK: usize = 64;

/// Runs `w` over every cone of `cones` (rayon, chunks of 64) and fills `out`.
pub fn walk<W: Walker>(
    w: &W,
    soup: &TriangleSoup,
    cones: &ConeBatch,
    q: &Query,
    out: &mut ConeHits,
) -> Stats {
    let n = cones.len();
    let limit = if q.count_only { None } else { q.n };
    type Part = (Vec<usize>, Vec<u32>, Vec<f32>, Vec<u32>, ConeCounts);
    let parts: Vec<Part> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let range = c * CHUNK..((c + 1) * CHUNK).min(n);
            let mut scratch = W::Scratch::default();
            let mut list = Nearest::new(limit);
            let mut counts = ConeCounts::default();
            let (mut lens, mut prim, mut t) = (Vec::with_capacity(range.len()), vec![], vec![]);
            let mut cost = Vec::with_capacity(range.len());
            for i in range {
                let cone = cones.get(i);
                list.reset(cone.t_near, cone.near_id, cone.t_far);
                let p = Prepared::new(&cone);
                let work = counts.nodes + counts.tri_encounters;
                w.walk(soup, &p, &mut list, q.count_only, &mut scratch, &mut counts);
                let work = counts.nodes + counts.tri_encounters - work;
                cost.push(work.min(u32::MAX as u64) as u32);
                let before = prim.len();
                list.drain_into(&mut prim, &mut t);
                lens.push(prim.len() - before);
            }
            (lens, prim, t, cost, counts)
        })
        .collect();
    out.start.clear();
    out.prim.clear();
    out.t.clear();
    out.cost.clear();
    out.cost.reserve(n);
    out.start.reserve(n + 1);
    out.start.push(0);
    let mut total = ConeCounts::default();
    for (lens, prim, t, cost, counts) in parts {
        out.cost.extend_from_slice(&cost);
        for l in lens {
            let last = *out.start.last().expect("start has its 0");
            out.start.push(last + l);
        }
        out.prim.extend_from_slice(&prim);
        out.t.extend_from_slice(&t);
        total += counts;
    }
    let mut s = Stats::traced(n, &total);
    s.peak_bytes = out.bytes() as u64;
    s
}

/// Which structure a [`ConeTracer`] walks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Structure {
    /// Every triangle, exact test (the ground truth).
    Oracle,
    /// The shared binned-SAH BVH (`accel/bvh`).
    Bvh,
    /// The same BVH built with spatial splits (the paper's SBVH, `accel/bvh/sbvh.rs`).
    Sbvh,
    /// The shared SAH kd-tree (`accel/kdtree`).
    Kdtree,
}

/// Traversal order (Fig. 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Traversal {
    /// Depth first, nearer child first, a stack; culls popped nodes against `t_n`.
    Stack,
    /// Nodes in order of their `t_min` (a binary heap); stops at the first beyond `t_n`.
    Sorted,
}

/// Which cone-frustum/box test (both give the same ranges).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BoxTest {
    /// Listing 2, branching per axis, one box at a time.
    Basic,
    /// Branchless, both children at once in 4 lanes.
    Improved,
}

/// The cone-query contract (module doc).
pub trait ConeTracer: Send + Sync {
    /// Name with its mode, e.g. `bvh/sorted/improved`.
    fn name(&self) -> String;
    /// Build (or rebuild) for `scene`.
    fn prepare(&mut self, scene: &Scene) -> Result<Stats>;
    /// The answers for `cones` into `out`; a scene changed since `prepare` is an error.
    fn trace(
        &self,
        scene: &Scene,
        cones: &ConeBatch,
        q: &Query,
        out: &mut ConeHits,
    ) -> Result<Stats>;
    /// Bytes held between calls.
    fn bytes(&self) -> usize;
}

/// A cone tracer for `structure` with `traversal` and `box_test` (the BVH's; the oracle
/// ignores both, the kd-tree the box test).
pub fn create(
    structure: Structure,
    traversal: Traversal,
    box_test: BoxTest,
) -> Box<dyn ConeTracer> {
    match structure {
        Structure::Oracle => Box::new(oracle::Oracle::default()),
        Structure::Bvh => Box::new(bvh::ConeBvh::new(traversal, box_test)),
        Structure::Sbvh => Box::new(bvh::ConeBvh::spatial(traversal, box_test)),
        Structure::Kdtree => Box::new(kdtree::ConeKd::new(traversal)),
    }
}
