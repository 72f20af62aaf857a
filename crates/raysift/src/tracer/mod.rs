//! The tracer contract: every technique (brute force, SAH BVH, DACRT, RTRPS, shafts, cones)
//! implements [`Tracer`], and everything above (CLI, renderers, benchmarks, tests) sees only it.
//!
//! Semantics every implementation must meet exactly (the conformance suite checks them against
//! `naive`):
//! - **closest hit**: for each ray, the triangle whose [`intersect_triangle`] hit has the smallest
//!   `t` in `[tmin, tmax]`; ties in `t` go to the smaller primitive id ([`closer`]), so the answer
//!   is unique and every tracer returns the same `t`, `prim`, `u`, `v` bit for bit;
//! - **occlusion**: true when any triangle is hit with `tmin <= t <= tmax`;
//! - the scene is passed to every call, as Embree's `rtcIntersect` takes its scene: a tracer
//!   holds only what it built from the scene at its last [`Tracer::prepare`] (which it may
//!   *update* rather than rebuild, asking [`Scene::changes_since`] what changed), and a trace of a
//!   scene that changed since, or of another scene, is an error ([`Stamp::check`]), never a
//!   silently wrong answer.
//!
//! **Counters.** Each tracer names its own work counters (the papers count different things:
//! plane/sphere tests, shaft tests, triangle encounters) in a struct made by [`counters!`]; a
//! call reports them in [`Stats::work`] and a prepare reports what it built in [`Stats::built`],
//! so "nodes built" and "nodes visited" never share a field.
//!
//! **Per-ray cost.** On request (a `Some(&mut RayCost)` argument) every tracer also records, per
//! ray, the nodes it entered and the tests it took part in ([`RayCost`]); heatmaps are drawn from
//! it. Tracers branch on the request once per chunk of rays, so it costs nothing when not asked.
//!
//! [`intersect_triangle`]: crate::geom::intersect_triangle
//! [`Scene::changes_since`]: crate::scene::Scene::changes_since
//! [`Stamp::check`]: crate::scene::Stamp::check

use crate::error::Result;
use crate::rays::{HitBatch, RayBatch};
use crate::scene::Scene;
use serde::ser::SerializeMap;
use serde::Serialize;
use std::time::Instant;

mod par;
pub use par::{par_occlusion_bands, par_occlusion_chunks, par_ray_bands, par_ray_chunks, SplitOut};

/// Most counters a [`Counters`] holds (a tracer's counter struct is checked against it when
/// compiled).
pub const MAX_COUNTERS: usize = 32;

/// Named counters, in the order a tracer declared them. Made from a tracer's counter struct
/// ([`CounterSet::to_counters`]) once per call, never in a hot loop; a fixed array, so reporting
/// allocates nothing (the memory tests count every byte a call allocates).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Counters {
    names: [&'static str; MAX_COUNTERS],
    values: [u64; MAX_COUNTERS],
    len: usize,
}

impl Default for Counters {
    fn default() -> Self {
        Self {
            names: [""; MAX_COUNTERS],
            values: [0; MAX_COUNTERS],
            len: 0,
        }
    }
}

impl Counters {
    /// No counters.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `value` to the counter `name` (created, at the end, when new).
    ///
    /// # Panics
    /// When a new name would make more than [`MAX_COUNTERS`] (a programming error the
    /// [`counters!`] macro rules out at compile time).
    pub fn add(&mut self, name: &'static str, value: u64) {
        match self.names[..self.len].iter().position(|&n| n == name) {
            Some(i) => self.values[i] += value,
            None => {
                assert!(self.len < MAX_COUNTERS, "more than {MAX_COUNTERS} counters");
                self.names[self.len] = name;
                self.values[self.len] = value;
                self.len += 1;
            }
        }
    }

    /// The counter `name`, 0 when absent.
    pub fn get(&self, name: &str) -> u64 {
        self.iter().find(|&(n, _)| n == name).map_or(0, |(_, v)| v)
    }

    /// `(name, value)` pairs in declaration order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, u64)> + '_ {
        self.names[..self.len]
            .iter()
            .copied()
            .zip(self.values[..self.len].iter().copied())
    }

    /// True when there are no counters.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl std::ops::AddAssign<&Counters> for Counters {
    fn add_assign(&mut self, o: &Counters) {
        for (n, v) in o.iter() {
            self.add(n, v);
        }
    }
}

impl Serialize for Counters {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.len))?;
        for (k, v) in self.iter() {
            m.serialize_entry(k, &v)?;
        }
        m.end()
    }
}

/// `(name, meaning)` of each counter of a set.
pub type CounterDocs = &'static [(&'static str, &'static str)];

/// A tracer's counter struct: plain `u64` fields incremented in its hot loops, summed over
/// chunks, turned into [`Counters`] once per call. Made by [`counters!`].
pub trait CounterSet: Copy + Default + Send + std::ops::Add<Output = Self> {
    /// `(name, meaning)` of every field, in declaration order.
    const DOCS: &'static [(&'static str, &'static str)];
    /// The values, named.
    fn to_counters(&self) -> Counters;
}

/// Declares a tracer's counter struct: `u64` fields, each with a doc line that becomes its
/// documented meaning ([`CounterSet::DOCS`], listed by `raysift tracers --verbose`).
///
/// ```
/// raysift::counters! {
///     /// Work of my tracer.
///     pub struct MyCounts {
///         /// Ray/box tests.
///         ray_box,
///         /// Ray/triangle tests.
///         ray_tri,
///     }
/// }
/// use raysift::tracer::CounterSet;
/// let c = MyCounts { ray_box: 2, ray_tri: 1 } + MyCounts { ray_box: 1, ray_tri: 0 };
/// assert_eq!(c.to_counters().get("ray_box"), 3);
/// assert_eq!(MyCounts::DOCS[1], ("ray_tri", "Ray/triangle tests."));
/// ```
#[macro_export]
macro_rules! counters {
    ($(#[$m:meta])* $vis:vis struct $name:ident { $( $(#[doc = $doc:literal])+ $field:ident ),* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        $vis struct $name { $( $(#[doc = $doc])+ pub $field: u64 ),* }
        impl ::std::ops::Add for $name {
            type Output = Self;
            #[inline]
            fn add(self, o: Self) -> Self {
                Self { $( $field: self.$field + o.$field ),* }
            }
        }
        impl ::std::ops::AddAssign for $name {
            #[inline]
            fn add_assign(&mut self, o: Self) {
                $( self.$field += o.$field; )*
            }
        }
        const _: () = assert!(
            [$(stringify!($field)),*].len() <= $crate::tracer::MAX_COUNTERS,
            "too many counters"
        );
        impl $crate::tracer::CounterSet for $name {
            const DOCS: &'static [(&'static str, &'static str)] =
                &[ $( (stringify!($field), concat!($($doc),+).trim_ascii()) ),* ];
            fn to_counters(&self) -> $crate::tracer::Counters {
                let mut c = $crate::tracer::Counters::new();
                $( c.add(stringify!($field), self.$field); )*
                c
            }
        }
    };
}

/// What a prepare or a trace did: rays, wall times, peak bytes, and the tracer's named counters.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Rays traced.
    pub rays: u64,
    /// Wall time of prepare (build or update), in ms (set by [`Tracer::prepare_timed`]).
    pub prepare_ms: f64,
    /// Wall time of tracing, in ms (set by [`Tracer::intersect_timed`] and friends).
    pub trace_ms: f64,
    /// Peak bytes the tracer itself allocated for the work (acceleration structure or scratch).
    pub peak_bytes: u64,
    /// What a prepare built or updated (nodes, leaves, spheres, refitted boxes...).
    pub built: Counters,
    /// What a trace did (tests, nodes or cells visited...).
    pub work: Counters,
}

impl Stats {
    /// The stats of a trace of `rays` rays that did `work`.
    pub fn traced(rays: usize, work: &impl CounterSet) -> Self {
        Self {
            rays: rays as u64,
            work: work.to_counters(),
            ..Self::default()
        }
    }

    /// The stats of a prepare that built `built`, holding `peak_bytes`.
    pub fn prepared(built: &impl CounterSet, peak_bytes: usize) -> Self {
        Self {
            peak_bytes: peak_bytes as u64,
            built: built.to_counters(),
            ..Self::default()
        }
    }
}

impl std::ops::AddAssign<&Stats> for Stats {
    fn add_assign(&mut self, o: &Stats) {
        self.rays += o.rays;
        self.prepare_ms += o.prepare_ms;
        self.trace_ms += o.trace_ms;
        self.peak_bytes = self.peak_bytes.max(o.peak_bytes);
        self.built += &o.built;
        self.work += &o.work;
    }
}

impl std::ops::Add for Stats {
    type Output = Stats;
    fn add(mut self, o: Stats) -> Stats {
        self += &o;
        self
    }
}

/// Per-ray cost, filled by every tracer when asked (all three arrays resized to the batch):
/// - `nodes`: acceleration nodes the ray entered (tree nodes whose box it hit, DACRT cells it
///   was filtered into, spheres, kd-tree cells);
/// - `tests`: every test the ray took part in (ray/box, ray/triangle, cone or plane tests of a
///   packet it belongs to: a test shared by a group counts for each of its live rays);
/// - `triangles`: its ray/triangle tests.
///
/// Counts saturate at `u32::MAX`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RayCost {
    /// Nodes entered per ray.
    pub nodes: Vec<u32>,
    /// Tests per ray.
    pub tests: Vec<u32>,
    /// Ray/triangle tests per ray.
    pub triangles: Vec<u32>,
}

impl RayCost {
    /// Resets to `n` zero records, reusing storage.
    pub fn reset(&mut self, n: usize) {
        for v in [&mut self.nodes, &mut self.tests, &mut self.triangles] {
            v.clear();
            v.resize(n, 0);
        }
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The array named `what` (`nodes`, `tests` or `triangles`).
    pub fn by_name(&self, what: &str) -> Option<&[u32]> {
        match what {
            "nodes" => Some(&self.nodes),
            "tests" => Some(&self.tests),
            "triangles" => Some(&self.triangles),
            _ => None,
        }
    }
}

/// A mutable window of a [`RayCost`] (one chunk of rays).
pub struct CostMut<'a> {
    /// Nodes entered.
    pub nodes: &'a mut [u32],
    /// Tests.
    pub tests: &'a mut [u32],
    /// Ray/triangle tests.
    pub triangles: &'a mut [u32],
}

impl CostMut<'_> {
    /// Adds to ray `k`'s record (saturating).
    #[inline]
    pub fn add(&mut self, k: usize, nodes: u64, tests: u64, triangles: u64) {
        let sat = |x: u64| x.min(u32::MAX as u64) as u32;
        self.nodes[k] = self.nodes[k].saturating_add(sat(nodes));
        self.tests[k] = self.tests[k].saturating_add(sat(tests));
        self.triangles[k] = self.triangles[k].saturating_add(sat(triangles));
    }
}

/// A ray/triangle intersection engine.
pub trait Tracer: Send + Sync {
    /// The registry name (`naive`, `bvh`, ...).
    fn name(&self) -> &'static str;

    /// Builds or updates whatever the tracer needs for `scene` as it is now (call again after
    /// the scene changes; [`Scene::changes_since`](crate::scene::Scene::changes_since) tells a
    /// tracer that updates what moved). Returns what it built; [`Tracer::prepare_timed`] adds the
    /// wall time.
    fn prepare(&mut self, scene: &Scene) -> Result<Stats>;

    /// Closest hits of all rays of `scene` (the scene last prepared); `hits` is resized to
    /// `rays.len()`, and `cost`, when given, gets one record per ray.
    fn intersect(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        hits: &mut HitBatch,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats>;

    /// Any-hit of all rays; `occluded` is resized to `rays.len()`, and `cost`, when given, gets
    /// one record per ray.
    fn occluded(
        &self,
        scene: &Scene,
        rays: &RayBatch,
        occluded: &mut Vec<bool>,
        cost: Option<&mut RayCost>,
    ) -> Result<Stats>;

    /// Bytes the tracer holds between calls (its acceleration structure; 0 for none).
    fn bytes(&self) -> usize;

    /// [`Tracer::prepare`], timed.
    fn prepare_timed(&mut self, scene: &Scene) -> Result<Stats> {
        let t0 = Instant::now();
        let mut s = self.prepare(scene)?;
        s.prepare_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(s)
    }

    /// [`Tracer::intersect`] into a new batch, timed.
    fn intersect_timed(&self, scene: &Scene, rays: &RayBatch) -> Result<(HitBatch, Stats)> {
        let mut hits = HitBatch::new(0);
        let t0 = Instant::now();
        let mut s = self.intersect(scene, rays, &mut hits, None)?;
        s.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok((hits, s))
    }

    /// [`Tracer::occluded`] into a new vector, timed.
    fn occluded_timed(&self, scene: &Scene, rays: &RayBatch) -> Result<(Vec<bool>, Stats)> {
        let mut occ = Vec::new();
        let t0 = Instant::now();
        let mut s = self.occluded(scene, rays, &mut occ, None)?;
        s.trace_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok((occ, s))
    }
}

/// The closest-hit order: smaller `t`, then smaller primitive id.
#[inline(always)]
pub fn closer(t: f32, prim: u32, best_t: f32, best_prim: u32) -> bool {
    t < best_t || (t == best_t && prim < best_prim)
}

/// A mutable window of a [`HitBatch`].
pub struct HitsMut<'a> {
    /// Hit distances.
    pub t: &'a mut [f32],
    /// Triangle ids.
    pub prim: &'a mut [u32],
    /// Barycentric u.
    pub u: &'a mut [f32],
    /// Barycentric v.
    pub v: &'a mut [f32],
}

/// Per-chunk results summed over chunks: a tracer's counters plus its largest peak bytes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tally<C> {
    /// Summed counters.
    pub counts: C,
    /// Largest peak of a chunk.
    pub peak_bytes: u64,
}

impl<C: CounterSet> std::ops::Add for Tally<C> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            counts: self.counts + o.counts,
            peak_bytes: self.peak_bytes.max(o.peak_bytes),
        }
    }
}

impl<C: CounterSet> Tally<C> {
    /// The stats of a trace of `rays` rays.
    pub fn into_stats(self, rays: usize) -> Stats {
        Stats {
            peak_bytes: self.peak_bytes,
            ..Stats::traced(rays, &self.counts)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::counters! {
        /// Test counters.
        struct Two {
            /// First.
            a,
            /// Second.
            b,
        }
    }

    #[test]
    fn counters_sum_by_name_and_keep_order() {
        let x = Two { a: 1, b: 2 } + Two { a: 3, b: 0 };
        let c = x.to_counters();
        assert_eq!(c.iter().collect::<Vec<_>>(), vec![("a", 4), ("b", 2)]);
        let mut s = Stats::traced(5, &x);
        s += &Stats::traced(2, &Two { a: 1, b: 1 });
        assert_eq!((s.rays, s.work.get("a"), s.work.get("b")), (7, 5, 3));
        assert_eq!(s.work.get("missing"), 0);
        assert_eq!(Two::DOCS, &[("a", "First."), ("b", "Second.")]);
        let json = serde_json::to_value(&s).unwrap();
        assert_eq!(json["work"]["a"], 5);
    }

    #[test]
    fn bands_of_any_size_get_their_windows_reset() {
        let rays = RayBatch::from_rays((0..11).map(|i| crate::rays::Ray {
            origin: glam::Vec3::new(i as f32, 0.0, 0.0),
            dir: glam::Vec3::X,
            tmin: 0.0,
            tmax: 1.0,
        }));
        // Stale answers of an earlier call, and a batch of another size.
        let mut hits = HitBatch::new(11);
        hits.t.fill(1.0);
        hits.prim.fill(7);
        let mut occ = vec![true; 11];
        let mut cost = RayCost::default();
        let bounds = [0, 3, 10, 11];
        let seen = std::sync::Mutex::new(Vec::new());
        let n: Tally<Two> = par_ray_bands(
            &rays,
            &mut hits,
            Some(&mut cost),
            &bounds,
            |b, r, out, c| {
                assert!(out.t.iter().all(|&t| t == f32::INFINITY));
                assert!(out.prim.iter().all(|&p| p == crate::rays::MISS));
                assert_eq!(
                    (out.t.len(), out.u.len(), c.unwrap().nodes.len()),
                    (r.len(), r.len(), r.len())
                );
                out.prim.fill(b as u32);
                seen.lock().unwrap().push((b, r));
                Tally {
                    counts: Two { a: 1, b: 0 },
                    peak_bytes: 0,
                }
            },
        );
        assert_eq!(n.counts.a, 3);
        let mut seen = seen.into_inner().unwrap();
        seen.sort_by_key(|s| s.0);
        assert_eq!(seen, [(0, 0..3), (1, 3..10), (2, 10..11)]);
        assert_eq!(hits.prim, [0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 2]);
        let n: Tally<Two> = par_occlusion_bands(&rays, &mut occ, None, &bounds, |b, r, out, _| {
            assert!(out.iter().all(|&o| !o) && out.len() == r.len());
            out.fill(b == 1);
            Tally {
                counts: Two { a: 1, b: 0 },
                peak_bytes: 0,
            }
        });
        assert_eq!(n.counts.a, 3);
        assert_eq!(occ.iter().filter(|&&o| o).count(), 7);
    }

    #[test]
    fn cost_windows_cover_every_ray() {
        let rays = RayBatch::from_rays((0..1000).map(|i| crate::rays::Ray {
            origin: glam::Vec3::new(i as f32, 0.0, 0.0),
            dir: glam::Vec3::X,
            tmin: 0.0,
            tmax: 1.0,
        }));
        let mut hits = HitBatch::new(0);
        let mut cost = RayCost::default();
        let n: Tally<Two> = par_ray_chunks(&rays, &mut hits, Some(&mut cost), 64, |r, _, c| {
            let mut c = c.expect("cost asked");
            for k in 0..r.len() {
                c.add(k, (r.start + k) as u64, 1, u64::MAX);
            }
            Tally {
                counts: Two {
                    a: r.len() as u64,
                    b: 0,
                },
                peak_bytes: r.start as u64,
            }
        });
        assert_eq!(n.counts.a, 1000);
        assert_eq!(n.peak_bytes, 960);
        assert_eq!(cost.len(), 1000);
        assert!(cost.nodes.iter().enumerate().all(|(i, &x)| x == i as u32));
        assert!(cost.triangles.iter().all(|&x| x == u32::MAX));
        let none: Tally<Two> = par_ray_chunks(&rays, &mut hits, None, 64, |_, _, c| {
            assert!(c.is_none());
            Tally::default()
        });
        assert_eq!(none.counts.a, 0);
    }
}
