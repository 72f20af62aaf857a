//! One tile: its rays, its shaft, its relevant-triangle list, and the proof that decides, ray by
//! ray, whether the list's answer is the tree's (§3 of the paper; the rule is in `mod.rs`).

use super::origin::{Origin, Runs, TileSoa};
use super::{Config, Counters};
use crate::accel::kdtree::{KdTree, MAX_DEPTH};
use crate::geom::shaft::{BoxPlanes, Shaft};
use crate::geom::{intersect_triangle, Aabb, TriFromOrigin};
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::{closer, CostMut};
use crate::tracers::kdtree::{walk, walk4, Best, Counters as KdCounters, StackEntry, Stacks};
use glam::{DMat3, DVec3, Vec4};

/// Rows of pixels sharing one origin, as laid out in the batch: ray `base + (j·width + i)·samples
/// + k` is sample `k` of pixel `(i, j)`, `j < rows`.
#[derive(Clone, Copy, Debug)]
pub struct Band {
    /// Index of the band's first ray.
    pub base: usize,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub rows: usize,
    /// Rays per pixel (`a²`: the corner rays are the outermost samples of the corner pixels).
    pub samples: usize,
}

/// What a tile's rays share, which decides its shaft.
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    /// One origin (camera tiles, grids): apex there; these four rays set the cap.
    Origin([usize; 4]),
    /// Lines meeting near one point (reflections of a camera in a planar mirror), any origins:
    /// apex at their least-squares meeting point; these four rays set the cap.
    Lines([usize; 4]),
    /// Finite segments (shadow rays to a point light): a shaft around both ends of each.
    Segments,
}

/// Per-chunk scratch (allocated once per chunk, never per ray or node).
pub struct Scratch {
    /// The tile's ray indices.
    pub(super) idx: Vec<usize>,
    /// Which of them are answered.
    done: Vec<bool>,
    /// The relevant-triangle list.
    pub(super) list: Vec<u32>,
    /// The shaft walk's stack.
    cells: Vec<(u32, Aabb, BoxPlanes)>,
    /// The single-ray walk's stack.
    stack: [StackEntry; MAX_DEPTH],
    /// The corner packet's stacks.
    packet: Box<Stacks>,
    /// List answers, per slot of `idx`.
    best: Vec<Best>,
    /// Slots still to answer.
    pending: Vec<usize>,
    /// The list's triangles prepared for the tile's origin (four rays per test).
    pub(super) tris: Vec<TriFromOrigin<f32>>,
    /// The tile's rays as structure-of-arrays (`origin.rs`).
    pub(super) soa: TileSoa,
}

impl Scratch {
    /// Scratch for tiles of up to `rays` rays and lists of up to `max_list` triangles (the
    /// tile's [`Config::list_limit`]).
    pub fn new(rays: usize, max_list: usize) -> Self {
        Self {
            idx: Vec::with_capacity(rays),
            done: Vec::with_capacity(rays),
            list: Vec::with_capacity(2 * max_list + LIST_OVERRUN),
            cells: Vec::with_capacity(MAX_DEPTH + 2),
            stack: [StackEntry::default(); MAX_DEPTH],
            packet: Box::default(),
            best: Vec::with_capacity(rays),
            pending: Vec::with_capacity(rays),
            tris: Vec::with_capacity(max_list),
            soa: TileSoa::with_capacity(rays),
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.idx.capacity() * 8
            + self.done.capacity()
            + self.list.capacity() * 4
            + self.cells.capacity() * std::mem::size_of::<(u32, Aabb, BoxPlanes)>()
            + std::mem::size_of::<[StackEntry; MAX_DEPTH]>()
            + std::mem::size_of::<Stacks>()
            + self.best.capacity() * std::mem::size_of::<Best>()
            + self.pending.capacity() * 8
            + self.tris.capacity() * std::mem::size_of::<TriFromOrigin<f32>>()
            + self.soa.bytes()
    }
}

/// The distinct rays of `corners` (a one-pixel tile's corners may coincide) and their count.
pub(super) fn distinct(corners: [usize; 4]) -> ([usize; 4], usize) {
    let mut ids = [0usize; 4];
    let mut n = 0;
    for i in corners {
        if !ids[..n].contains(&i) {
            ids[n] = i;
            n += 1;
        }
    }
    (ids, n)
}

/// Duplicate references a list may hold before it is deduplicated and checked.
const LIST_OVERRUN: usize = 16;

/// What a tile needs to read.
pub struct Ctx<'a> {
    /// The tree.
    pub tree: &'a KdTree,
    /// Its triangles.
    pub soup: &'a TriangleSoup,
    /// The batch.
    pub rays: &'a RayBatch,
    /// Options.
    pub cfg: &'a Config,
}

impl Ctx<'_> {
    /// Ray `i` through the tree alone; its cost charged to `cost` at local index `i - start`.
    pub fn walk<const ANY: bool>(
        &self,
        i: usize,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
    ) -> Best {
        let mut k = KdCounters::default();
        let best = walk::<ANY>(self.tree, self.soup, self.rays, i, &mut s.stack, &mut k);
        if let Some(cost) = cost {
            let nodes = k.nodes + k.leaves;
            cost.add(i - start, nodes, k.ray_box + k.nodes + k.ray_tri, k.ray_tri);
        }
        c.add_walk(&k);
        best
    }

    /// Rays `ids` (1 to 4) through the tree as one packet; each charged the packet's work.
    pub(super) fn walk4(
        &self,
        ids: &[usize],
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
    ) -> [Best; 4] {
        let mut k = KdCounters::default();
        let best = walk4::<false>(self.tree, self.soup, self.rays, ids, &mut s.packet, &mut k);
        if let Some(cost) = cost {
            for &i in ids {
                let nodes = k.nodes + k.leaves;
                cost.add(i - start, nodes, k.ray_box + k.nodes + k.ray_tri, k.ray_tri);
            }
        }
        c.add_walk(&k);
        best
    }

    /// Ray `i` against the list.
    #[inline]
    fn test_list<const ANY: bool>(&self, i: usize, list: &[u32]) -> Best {
        let (o, d, tmin) = (self.rays.origin(i), self.rays.dir(i), self.rays.tmin[i]);
        let (v0, v1, v2) = (&self.soup.v0, &self.soup.v1, &self.soup.v2);
        let mut best: Best = (self.rays.tmax[i], MISS, 0.0, 0.0);
        for &p in list {
            let k = p as usize;
            if let Some(h) = intersect_triangle(o, d, v0[k], v1[k], v2[k], tmin, best.0) {
                if closer(h.t, p, best.0, best.1) {
                    best = (h.t, p, h.u, h.v);
                    if ANY {
                        break;
                    }
                }
            }
        }
        best
    }

    /// Walks the tree with the shaft of a tile of `rays` rays, collecting into `s.list` (sorted,
    /// deduplicated) every triangle whose box the shaft may meet; false when the list would
    /// exceed the tile's limit ([`Config::list_limit`]).
    pub(super) fn collect(
        &self,
        shaft: &Shaft,
        rays: usize,
        s: &mut Scratch,
        c: &mut Counters,
    ) -> bool {
        let limit = self.cfg.list_limit(rays);
        let (tree, soup) = (self.tree, self.soup);
        s.list.clear();
        s.cells.clear();
        if tree.nodes.is_empty() {
            return true;
        }
        let root = tree.bounds;
        let slack = shaft.slack(root.min, root.max);
        s.cells.push((0, root, shaft.planes(root.min, root.max)));
        while let Some((node, cell, planes)) = s.cells.pop() {
            c.shaft_boxes += 1;
            if shaft.planes_outside(&planes, slack) {
                continue;
            }
            c.shaft_nodes += 1;
            let n = tree.nodes[node as usize];
            if n.is_leaf() {
                for &p in tree.leaf_ids(n) {
                    let k = p as usize;
                    let (a, b, d) = (soup.v0[k], soup.v1[k], soup.v2[k]);
                    c.shaft_boxes += 1;
                    if !shaft.box_outside(a.min(b).min(d), a.max(b).max(d)) {
                        if s.list.len() == 2 * limit + LIST_OVERRUN {
                            return false;
                        }
                        s.list.push(p);
                    }
                }
            } else {
                let (a, split) = (n.axis(), n.split());
                let (mut below, mut above) = (cell, cell);
                below.max[a] = split;
                above.min[a] = split;
                let range = (cell.min[a], cell.max[a]);
                let pa = shaft.split(&planes, a, range, (split, cell.max[a]));
                let pb = shaft.split(&planes, a, range, (cell.min[a], split));
                s.cells.push((n.above(), above, pa));
                s.cells.push((node + 1, below, pb));
            }
        }
        s.list.sort_unstable();
        s.list.dedup();
        s.list.len() <= limit
    }

    /// Traces the `tw × th` pixels at `(i0, j0)` of `band`, calling `emit(i, hit)` for every ray
    /// `i` (misses included); `start` is the chunk's first ray (the cost window's origin).
    #[allow(clippy::too_many_arguments)]
    pub fn tile<const ANY: bool>(
        &self,
        band: Band,
        (i0, j0, tw, th): (usize, usize, usize, usize),
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) {
        let ns = band.samples;
        let a = (ns as f64).sqrt().round() as usize;
        let a = if a * a == ns { a } else { 1 };
        let at = |i: usize, j: usize, k: usize| band.base + (j * band.width + i) * ns + k;
        let (r, b) = (i0 + tw - 1, j0 + th - 1);
        let corners = [
            at(i0, j0, 0),
            at(r, j0, a - 1),
            at(r, b, ns - 1),
            at(i0, b, ns - a),
        ];
        let rows = Runs {
            first: at(i0, j0, 0),
            stride: band.width * ns,
            len: tw * ns,
            count: th,
        };
        {
            // Quarters of more than four rays have inner rays to answer from lists; smaller
            // ones would only walk their corners (measured: no faster than single walks).
            let split = tw * th > 1 && tw.div_ceil(2) * th.div_ceil(2) * ns > 4;
            match self.origin_tile::<ANY>(rows, corners, split, start, s, c, cost, emit) {
                Origin::Traced => return,
                Origin::Overflow => {
                    // The quarters (halves of a one-pixel-wide tile), each a tile of its own.
                    let (w0, h0) = (tw.div_ceil(2), th.div_ceil(2));
                    for (x, w) in [(i0, w0), (i0 + w0, tw - w0)] {
                        for (y, h) in [(j0, h0), (j0 + h0, th - h0)] {
                            if w > 0 && h > 0 {
                                self.tile::<ANY>(band, (x, y, w, h), start, s, c, cost, emit);
                            }
                        }
                    }
                    return;
                }
                Origin::NotForIt => {}
            }
        }
        s.idx.clear();
        for j in j0..j0 + th {
            for i in i0..i0 + tw {
                s.idx.extend((0..ns).map(|k| at(i, j, k)));
            }
        }
        self.shaft_tile::<ANY>(Kind::Origin(corners), start, s, c, cost, emit);
    }

    /// Traces rays `group` (finite segments, any origins: shadow rays to a point light) as one
    /// tile whose shaft bounds the segments themselves.
    #[allow(clippy::too_many_arguments)]
    pub fn segments<const ANY: bool>(
        &self,
        group: std::ops::Range<usize>,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) {
        s.idx.clear();
        s.idx.extend(group);
        self.shaft_tile::<ANY>(Kind::Segments, start, s, c, cost, emit);
    }

    /// Traces rays `group` (no layout: maybe reflections off a planar mirror) as one tile whose
    /// shaft's apex is the point nearest all their lines; its first, last and two middle rays
    /// set the cap.
    #[allow(clippy::too_many_arguments)]
    pub fn lines<const ANY: bool>(
        &self,
        group: std::ops::Range<usize>,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) {
        let (a, n) = (group.start, group.len());
        let corners = [a, a + n / 3, a + (2 * n) / 3, a + n.max(1) - 1];
        s.idx.clear();
        s.idx.extend(group);
        self.shaft_tile::<ANY>(Kind::Lines(corners), start, s, c, cost, emit);
    }

    /// The shaft of rays `s.idx` whose lines meet near one point: apex at the least-squares
    /// point of the lines (or far behind the origins when the rays are nearly parallel), fitted
    /// around every origin (seen from the apex) and every direction, so that each ray, from its
    /// origin on, is inside (a convex cone holds `o + t·d` when it holds `o` and `d`).
    fn line_shaft(&self, s: &Scratch) -> Option<Shaft> {
        let rays = self.rays;
        let (mut a, mut b) = (DMat3::ZERO, DVec3::ZERO);
        let (mut sum_e, mut centre) = (DVec3::ZERO, DVec3::ZERO);
        for &i in &s.idx {
            let (o, d) = (rays.origin(i).as_dvec3(), rays.dir(i).as_dvec3());
            let l = d.length();
            if !(l > 0.0 && l.is_finite() && o.is_finite() && rays.tmin[i] >= 0.0) {
                return None;
            }
            let e = d / l;
            let p = DMat3::IDENTITY - DMat3::from_cols(e * e.x, e * e.y, e * e.z);
            a += p;
            b += p * o;
            sum_e += e;
            centre += o;
        }
        let n = s.idx.len() as f64;
        let (m, centre) = (sum_e.try_normalize()?, centre / n);
        let spread = s.idx.iter().fold(0.0f64, |r, &i| {
            r.max((rays.origin(i).as_dvec3() - centre).length())
        });
        let behind = |p: DVec3| {
            s.idx
                .iter()
                .all(|&i| m.dot(rays.origin(i).as_dvec3() - p) >= 0.0)
        };
        let meet = (a.determinant().abs() > 1e-9 * n * n * n)
            .then(|| a.inverse() * b)
            .filter(|&p| p.is_finite() && behind(p));
        let apex =
            meet.unwrap_or(centre - m * (100.0 * spread + 1e-3 * centre.abs().max_element()));
        let origins = s.idx.iter().map(move |&i| rays.origin(i).as_dvec3() - apex);
        let dirs = s.idx.iter().map(|&i| rays.dir(i).as_dvec3());
        let mut shaft = Shaft::fit(
            apex,
            origins.clone().filter(|v| *v != DVec3::ZERO).chain(dirs),
        )?;
        shaft.scale = 2.0 * origins.map(|v| v.length()).fold(0.0, f64::max);
        Some(shaft)
    }

    /// The shaft of rays `s.idx` from one origin (apex there), uncapped; `None` when they do not
    /// share the origin bit for bit, some `tmin` is negative or the directions do not fit.
    fn origin_shaft(&self, s: &Scratch) -> Option<Shaft> {
        let rays = self.rays;
        let o = rays.origin(s.idx[0]);
        // One origin bit for bit, and t >= 0 (the shaft bounds rays ahead of the apex only).
        let same = |i: usize| {
            let bits = |a: f32, b: f32| a.to_bits() == b.to_bits();
            bits(rays.ox[i], o.x)
                && bits(rays.oy[i], o.y)
                && bits(rays.oz[i], o.z)
                && rays.tmin[i] >= 0.0
        };
        if !s.idx.iter().all(|&i| same(i)) {
            return None;
        }
        let dirs = s.idx.iter().map(|&i| rays.dir(i).as_dvec3());
        Shaft::fit(o.as_dvec3(), dirs)
    }

    /// The shaft of segments `s.idx`, capped at their farthest end; `None` when a segment is
    /// infinite or they do not fit. The apex is pulled back behind the segments' far ends (by
    /// 1% of the group's extent) so that ends meeting at one point (a light) are inside.
    fn segment_shaft(&self, s: &Scratch) -> Option<Shaft> {
        let rays = self.rays;
        let end = |i: usize, t: f32| rays.origin(i).as_dvec3() + rays.dir(i).as_dvec3() * t as f64;
        let ends = || {
            s.idx
                .iter()
                .flat_map(move |&i| [end(i, rays.tmin[i]), end(i, rays.tmax[i])])
        };
        if !ends().all(|p| p.is_finite()) {
            return None;
        }
        let n = s.idx.len() as f64;
        let near = s.idx.iter().map(|&i| end(i, rays.tmin[i])).sum::<DVec3>() / n;
        let far = s.idx.iter().map(|&i| end(i, rays.tmax[i])).sum::<DVec3>() / n;
        let axis = (near - far).try_normalize()?;
        let extent = ends().map(|p| (p - far).length()).fold(0.0, f64::max);
        let apex = far - axis * (0.01 * extent);
        let mut shaft = Shaft::fit(apex, ends().map(|p| p - apex))?;
        shaft.set_cap(ends().map(|p| shaft.m.dot(p - apex)).fold(0.0, f64::max));
        shaft.scale = 2.0 * ends().map(|p| (p - apex).length()).fold(0.0, f64::max);
        Some(shaft)
    }

    /// One tile of rays `s.idx`, its shaft as `kind` says: rays from one origin or lines capped
    /// by their corners' hits (or their far ends), segments capped by their ends.
    #[allow(clippy::too_many_arguments)]
    fn shaft_tile<const ANY: bool>(
        &self,
        kind: Kind,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) {
        let rays = self.rays;
        s.done.clear();
        s.done.resize(s.idx.len(), false);
        c.tiles += 1;
        let (shaft, corners) = match kind {
            _ if s.idx.len() < 4 => (None, None),
            Kind::Origin(k) => (self.origin_shaft(s), Some(k)),
            Kind::Lines(k) => (self.line_shaft(s), Some(k)),
            Kind::Segments => (self.segment_shaft(s), None),
        };
        let Some(mut shaft) = shaft else {
            return self.fall_back::<ANY>(start, s, c, cost, emit);
        };
        // Origin shafts: capped at the segments' far ends when all are finite; for closest hits
        // (or infinite segments) also at the corners' closest hits, grown by `cap_growth`.
        let mut cap = shaft.cap();
        if let Some(corners) = corners {
            cap = s.idx.iter().fold(0.0f64, |h, &i| {
                h.max(shaft.depth_from(rays.origin(i), rays.dir(i), rays.tmax[i]))
            });
            if !ANY || cap == f64::INFINITY {
                let (ids, n) = distinct(corners);
                cap = cap.min(self.corner_cap(&ids[..n], &shaft, start, s, c, cost, emit));
                for &i in &ids[..n] {
                    let slot = s.idx.iter().position(|&x| x == i).expect("corner in tile");
                    s.done[slot] = true;
                }
            }
        }
        shaft.set_cap(cap);
        let before = (c.shaft_nodes, c.shaft_boxes);
        if !self.collect(&shaft, s.idx.len(), s, c) {
            return self.fall_back::<ANY>(start, s, c, cost, emit);
        }
        c.tiles_listed += 1;
        c.list_len += s.list.len() as u64;
        let shared = (c.shaft_nodes - before.0, c.shaft_boxes - before.1);
        self.list_answers::<ANY>(matches!(kind, Kind::Origin(_)), s);
        for n in 0..s.idx.len() {
            if s.done[n] {
                continue;
            }
            let i = s.idx[n];
            let best = s.best[n];
            let len = s.list.len() as u64;
            c.list_tests += len;
            let (o, d) = (rays.origin(i), rays.dir(i));
            let proven = if corners.is_none() {
                true // the whole segment is inside the capped shaft
            } else if best.1 != MISS {
                ANY || shaft.depth_from(o, d, best.0) <= cap
            } else {
                shaft.depth_from(o, d, rays.tmax[i]) <= cap
            };
            if let Some(cost) = cost {
                cost.add(i - start, shared.0, shared.1 + len, len);
            }
            if proven {
                c.list_rays += 1;
                emit(i, best);
            } else {
                c.fallback_rays += 1;
                let best = self.walk::<ANY>(i, start, s, c, cost);
                emit(i, best);
            }
            s.done[n] = true;
        }
    }

    /// The list's answer for every unanswered ray of the tile, into `s.best`. Rays from one
    /// origin go four at a time through the list's triangles prepared for that origin
    /// ([`TriFromOrigin`]: bit-identical to the shared test); others one at a time.
    fn list_answers<const ANY: bool>(&self, one_origin: bool, s: &mut Scratch) {
        let rays = self.rays;
        s.best.clear();
        s.best.resize(s.idx.len(), (f32::INFINITY, MISS, 0.0, 0.0));
        s.pending.clear();
        s.pending.extend((0..s.idx.len()).filter(|&n| !s.done[n]));
        let Scratch {
            idx,
            list,
            best,
            pending,
            tris,
            ..
        } = s;
        if !one_origin || list.len() < 2 || pending.len() < 4 {
            for &n in pending.iter() {
                best[n] = self.test_list::<ANY>(idx[n], list);
            }
            return;
        }
        let o = rays.origin(idx[0]);
        let dlow = pending
            .iter()
            .map(|&n| rays.dir(idx[n]).abs().max_element())
            .fold(f32::INFINITY, f32::min);
        let soup = self.soup;
        tris.clear();
        tris.extend(list.iter().map(|&p| {
            let k = p as usize;
            TriFromOrigin::new(o, soup.v0[k], soup.v1[k], soup.v2[k], dlow)
        }));
        for group in pending.chunks(4) {
            let g = group.len();
            let lane: [usize; 4] = std::array::from_fn(|k| idx[group[k.min(g - 1)]]);
            let tmin = rays.tmin[lane[0]];
            if lane.iter().any(|&i| rays.tmin[i] != tmin) {
                for &n in group {
                    best[n] = self.test_list::<ANY>(idx[n], list);
                }
                continue;
            }
            let d = [
                Vec4::from_array(lane.map(|i| rays.dx[i])),
                Vec4::from_array(lane.map(|i| rays.dy[i])),
                Vec4::from_array(lane.map(|i| rays.dz[i])),
            ];
            let mut b: [Best; 4] = lane.map(|i| (rays.tmax[i], MISS, 0.0, 0.0));
            let mut tmax = Vec4::from_array(b.map(|x| x.0));
            for (tri, &p) in tris.iter().zip(list.iter()) {
                let h = tri.intersect4(d, tmin, tmax);
                let mut m = h.mask;
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if closer(h.t[l], p, b[l].0, b[l].1) {
                        b[l] = (h.t[l], p, h.u[l], h.v[l]);
                        tmax[l] = h.t[l];
                    }
                }
            }
            for (k, &n) in group.iter().enumerate() {
                best[n] = b[k];
            }
        }
    }

    /// The corners `ids` (one to four) walked as one 4-ray packet (the paper's SIMD corners),
    /// their answers emitted; returns the cap they set: the depth of the deepest closest hit
    /// grown by `cap_growth` (infinite when one misses).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn corner_cap(
        &self,
        ids: &[usize],
        shaft: &Shaft,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) -> f64 {
        let rays = self.rays;
        let hits = self.walk4(ids, start, s, c, cost);
        let mut deepest = 0.0f64;
        for (&i, &best) in ids.iter().zip(&hits) {
            c.corner_rays += 1;
            deepest = deepest.max(if best.1 == MISS {
                f64::INFINITY
            } else {
                shaft.depth_from(rays.origin(i), rays.dir(i), best.0)
            });
            emit(i, best);
        }
        deepest * (1.0 + self.cfg.cap_growth)
    }

    /// Rays `rays` walked through the tree one by one, as fallbacks.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn walk_each<const ANY: bool>(
        &self,
        rays: impl Fn(&Scratch, usize) -> usize,
        n: usize,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) {
        for k in 0..n {
            let i = rays(s, k);
            c.fallback_rays += 1;
            let best = self.walk::<ANY>(i, start, s, c, cost);
            emit(i, best);
        }
    }

    /// Traces the tile's unanswered rays through the tree.
    fn fall_back<const ANY: bool>(
        &self,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) {
        for n in 0..s.idx.len() {
            if !s.done[n] {
                let i = s.idx[n];
                c.fallback_rays += 1;
                let best = self.walk::<ANY>(i, start, s, c, cost);
                emit(i, best);
                s.done[n] = true;
            }
        }
    }
}
