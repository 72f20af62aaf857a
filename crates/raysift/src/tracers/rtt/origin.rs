//! Tiles of rays from one origin (camera tiles, grids: closest or any hits): the vector path of
//! `tile.rs`'s steps 2–4, on the tile's rays gathered into structure-of-arrays.
//!
//! The shaft, list and proof rules of `tile.rs` (so the same answers); what changes is how the
//! list is tested: `L::N` rays at a time (eight in code compiled for AVX2, four elsewhere)
//! through [`TriFromOrigin::intersect_lanes`], each lane keeping its best hit in vector
//! registers (for any-hit queries its first, a group stopping once every lane has one), and the
//! depth proof run in the same pass in f32 with a margin that bounds its rounding (see
//! [`PROOF_MARGIN`]); a lane the f32 proof cannot settle gets the f64 test of `tile.rs`. Corner
//! rays are gathered last: they shape the shaft, but their answers come from the tree, so the
//! list pass skips them. Any-hit tiles of finite segments (area-light shadow grids) have no
//! corner rays: their far ends cap the shaft. The shaft is fitted in f32 lanes
//! ([`Shaft::fit_lanes`]), so its frame may differ from `tile.rs`'s by rounding.

use super::tile::{distinct, Ctx, Scratch};
use super::Counters;
#[cfg(target_arch = "x86_64")]
use crate::geom::lanes::F32x8;
use crate::geom::lanes::{self, Lanes, Width};
use crate::geom::shaft::Shaft;
use crate::geom::TriFromOrigin;
use crate::rays::MISS;
use crate::tracer::CostMut;
use crate::tracers::kdtree::Best;
use glam::{DVec3, Vec3, Vec4};

/// Relative margin of the f32 depth proof. In real numbers `depth = t · (m·d)`; computed in f32
/// with `m` rounded to f32, `m·d` is off by at most `5·2^-24·|d|` (three products, two sums and
/// the rounding of `m`, each within `2^-24` of `Σ|m_k d_k| <= |d|`), and a fitted direction has
/// `m·d >= MIN_COS·|d| = 0.2·|d|`, so the relative error is at most `25·2^-24 ≈ 1.5e-6`, plus
/// `2^-24` for the product with `t` and `2^-24` for rounding the cap to f32. A lane whose f32
/// depth is at most `cap·(1 − 4e-6)` therefore has its real depth below the cap.
pub const PROOF_MARGIN: f64 = 4e-6;

/// One tile's rays, structure-of-arrays, padded to whole vectors: slots `0..inner` are the rays
/// the list answers, the corners follow.
#[derive(Default)]
pub struct TileSoa {
    dx: Vec<f32>,
    dy: Vec<f32>,
    dz: Vec<f32>,
    tmax: Vec<f32>,
    ray: Vec<usize>,
    /// List answers per inner slot: distance, barycentrics, list position (`-1`: none).
    t: Vec<f32>,
    u: Vec<f32>,
    v: Vec<f32>,
    j: Vec<f32>,
    /// Per group of `L::N` slots, the lanes the f32 proof settles.
    proven: Vec<u32>,
}

/// Widest vector the list pass uses.
const MAX_LANES: usize = 8;

impl TileSoa {
    /// Room for tiles of `rays` rays.
    pub fn with_capacity(rays: usize) -> Self {
        let n = rays + MAX_LANES;
        let f = || Vec::with_capacity(n);
        Self {
            dx: f(),
            dy: f(),
            dz: f(),
            tmax: f(),
            ray: Vec::with_capacity(n),
            t: f(),
            u: f(),
            v: f(),
            j: f(),
            proven: Vec::with_capacity(n.div_ceil(4)),
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        let f = |v: &Vec<f32>| v.capacity() * 4;
        f(&self.dx)
            + f(&self.dy)
            + f(&self.dz)
            + f(&self.tmax)
            + self.ray.capacity() * 8
            + f(&self.t)
            + f(&self.u)
            + f(&self.v)
            + f(&self.j)
            + self.proven.capacity() * 4
    }

    fn push(&mut self, d: Vec3, tmax: f32, ray: usize) {
        self.dx.push(d.x);
        self.dy.push(d.y);
        self.dz.push(d.z);
        self.tmax.push(tmax);
        self.ray.push(ray);
    }

    fn swap(&mut self, a: usize, b: usize) {
        for v in [&mut self.dx, &mut self.dy, &mut self.dz, &mut self.tmax] {
            v.swap(a, b);
        }
        self.ray.swap(a, b);
    }

    fn clear(&mut self) {
        for v in [&mut self.dx, &mut self.dy, &mut self.dz, &mut self.tmax] {
            v.clear();
        }
        self.ray.clear();
    }
}

/// The list pass over slots `0..n` of `soa`, `L::N` at a time: each lane's closest hit among
/// `tris` (list order is ascending primitive id, so a tie keeps the earlier triangle, as
/// [`crate::tracer::closer`] does; with `ANY`, its first hit, and a group stops once every lane
/// has one) and whether the f32 proof settles it (depth at most `cap`).
#[inline(always)]
fn list_pass<L: Lanes, const ANY: bool>(
    tris: &[TriFromOrigin<f32>],
    soa: &mut TileSoa,
    n: usize,
    tmin: f32,
    m: [f32; 3],
    cap: f32,
) {
    let groups = n.div_ceil(L::N);
    for v in [&mut soa.t, &mut soa.u, &mut soa.v, &mut soa.j] {
        v.resize(groups * L::N, 0.0);
    }
    soa.proven.clear();
    let ld = |v: &[f32], g: usize| L::from_fn(|l| v[g + l]);
    let zero = L::splat(0.0);
    for g in (0..groups * L::N).step_by(L::N) {
        let d = [ld(&soa.dx, g), ld(&soa.dy, g), ld(&soa.dz, g)];
        let mut bt = ld(&soa.tmax, g);
        let (mut bu, mut bv, mut bj) = (zero, zero, L::splat(-1.0));
        for (j, tri) in tris.iter().enumerate() {
            let h = tri.intersect_lanes(d, tmin, bt);
            if h.mask != 0 {
                let take = if ANY {
                    h.hits & zero.cmpgt(bj)
                } else {
                    h.hits & (bt.cmpgt(h.t) | zero.cmpgt(bj))
                };
                bt = L::select(take, h.t, bt);
                bu = L::select(take, h.u, bu);
                bv = L::select(take, h.v, bv);
                bj = L::select(take, L::splat(j as f32), bj);
                if ANY && L::bitmask(zero.cmpgt(bj)) == 0 {
                    break;
                }
            }
        }
        let depth = bt * (L::splat(m[0]) * d[0] + L::splat(m[1]) * d[1] + L::splat(m[2]) * d[2]);
        soa.proven.push(L::bitmask(depth.cmple(L::splat(cap))));
        for l in 0..L::N {
            soa.t[g + l] = bt.lane(l);
            soa.u[g + l] = bu.lane(l);
            soa.v[g + l] = bv.lane(l);
            soa.j[g + l] = bj.lane(l);
        }
    }
}

/// [`list_pass`] eight lanes at a time, compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2 ([`lanes::width`] is [`Width::Eight`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn list_pass_avx2<const ANY: bool>(
    tris: &[TriFromOrigin<f32>],
    soa: &mut TileSoa,
    n: usize,
    tmin: f32,
    m: [f32; 3],
    cap: f32,
) {
    list_pass::<F32x8, ANY>(tris, soa, n, tmin, m, cap)
}

/// A tile's rays as runs of consecutive rays: run `r` is `first + r·stride ..` of `len` rays,
/// `r < count` (the rows of an image tile, with all their samples).
#[derive(Clone, Copy, Debug)]
pub struct Runs {
    /// First ray of the first run.
    pub first: usize,
    /// Rays from one run's start to the next.
    pub stride: usize,
    /// Rays per run.
    pub len: usize,
    /// Runs.
    pub count: usize,
}

/// [`Shaft::fit_lanes`] of the tile's slots (a whole number of [`MAX_LANES`]), at the CPU's width.
fn fit(apex: DVec3, soa: &TileSoa) -> Option<Shaft> {
    let (dx, dy, dz) = (&soa.dx[..], &soa.dy[..], &soa.dz[..]);
    #[cfg(target_arch = "x86_64")]
    if lanes::width() == Width::Eight {
        // SAFETY: `fit_avx2` needs AVX2; `width()` is `Eight` only on CPUs that have it.
        return unsafe { fit_avx2(apex, dx, dy, dz) };
    }
    Shaft::fit_lanes::<Vec4>(apex, dx, dy, dz)
}

/// [`Shaft::fit_lanes`] eight lanes at a time, compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2 ([`lanes::width`] is [`Width::Eight`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fit_avx2(apex: DVec3, dx: &[f32], dy: &[f32], dz: &[f32]) -> Option<Shaft> {
    Shaft::fit_lanes::<F32x8>(apex, dx, dy, dz)
}

impl Ctx<'_> {
    /// Traces the tile of rays `rows` (closest hits, or any hits with `ANY`) whose corners are
    /// `corners` on the vector path. [`Origin::NotForIt`] (nothing traced) when its rays do not
    /// share one origin and one `tmin >= 0` bit for bit, or it has fewer than four rays. The
    /// shaft, the list and the proof are `tile.rs`'s (the shaft's mean direction may differ by
    /// rounding: any direction inside the rays' cone serves). When the list is too long, the
    /// inner rays are walked through the tree, or, with `split`, left to the caller
    /// ([`Origin::Overflow`]: only the corners are answered), which traces the tile's quarters as
    /// tiles of their own.
    #[allow(clippy::too_many_arguments)]
    pub fn origin_tile<const ANY: bool>(
        &self,
        rows: Runs,
        corners: [usize; 4],
        split: bool,
        start: usize,
        s: &mut Scratch,
        c: &mut Counters,
        cost: &mut Option<CostMut<'_>>,
        emit: &mut impl FnMut(usize, Best),
    ) -> Origin {
        let rays = self.rays;
        if rows.len * rows.count < 4 {
            return Origin::NotForIt;
        }
        let (o, tmin) = (rays.origin(rows.first), rays.tmin[rows.first]);
        if tmin.is_nan() || tmin < 0.0 {
            return Origin::NotForIt;
        }
        let soa = &mut s.soa;
        soa.clear();
        let mut same = true;
        for r in 0..rows.count {
            let run = rows.first + r * rows.stride..rows.first + r * rows.stride + rows.len;
            // Bit for bit: `-0.0` and `0.0` would give the triangle test different zeros.
            let all_eq = |v: &[f32], x: f32| {
                v.iter()
                    .fold(true, |a, &y| a & (y.to_bits() == x.to_bits()))
            };
            same &= all_eq(&rays.ox[run.clone()], o.x)
                & all_eq(&rays.oy[run.clone()], o.y)
                & all_eq(&rays.oz[run.clone()], o.z)
                & all_eq(&rays.tmin[run.clone()], tmin);
            soa.dx.extend_from_slice(&rays.dx[run.clone()]);
            soa.dy.extend_from_slice(&rays.dy[run.clone()]);
            soa.dz.extend_from_slice(&rays.dz[run.clone()]);
            soa.tmax.extend_from_slice(&rays.tmax[run.clone()]);
            soa.ray.extend(run);
        }
        if !same {
            return Origin::NotForIt;
        }
        // Any-hit tiles of finite segments need no corners: the segments' far ends cap the
        // shaft, and every answer is proven.
        let far = soa.tmax.iter().fold(0.0f32, |a, &t| a.max(t));
        let walk_corners = !ANY || far == f32::INFINITY;
        // The distinct corners, moved to the end (slots beyond `inner`), largest slot first so
        // that each swap takes an inner ray.
        let slot = |i: usize| {
            let (r, k) = (
                (i - rows.first) / rows.stride,
                (i - rows.first) % rows.stride,
            );
            r * rows.len + k
        };
        let (mut ids, nc) = if walk_corners {
            distinct(corners)
        } else {
            ([0; 4], 0)
        };
        ids[..nc].sort_unstable_by(|a, b| b.cmp(a));
        let all = soa.ray.len();
        let mut inner = all;
        for &i in &ids[..nc] {
            inner -= 1;
            soa.swap(slot(i), inner);
        }
        debug_assert!(ids[..nc].iter().all(|i| soa.ray[inner..all].contains(i)));
        let dlow = (0..inner).fold(f32::INFINITY, |m, k| {
            m.min(soa.dx[k].abs().max(soa.dy[k].abs()).max(soa.dz[k].abs()))
        });
        c.tiles += 1;
        // Whole vectors: pad lanes repeat slot 0 (they change neither the fit nor an answer).
        while soa.dx.len() < all.next_multiple_of(MAX_LANES) {
            soa.push(
                Vec3::new(soa.dx[0], soa.dy[0], soa.dz[0]),
                soa.tmax[0],
                soa.ray[0],
            );
        }
        let Some(mut shaft) = fit(o.as_dvec3(), soa) else {
            self.walk_each::<ANY>(|s, k| s.soa.ray[k], all, start, s, c, cost, emit);
            return Origin::Traced;
        };
        // Capped at the segments' far ends, and at the corners' closest hits grown by
        // `cap_growth`.
        let mut cap = if far == f32::INFINITY {
            f64::INFINITY
        } else {
            (0..all).fold(0.0f64, |h, k| {
                h.max(shaft.depth(Vec3::new(soa.dx[k], soa.dy[k], soa.dz[k]), soa.tmax[k]))
            })
        };
        if nc > 0 {
            cap = cap.min(self.corner_cap(&ids[..nc], &shaft, start, s, c, cost, emit));
        }
        shaft.set_cap(cap);
        let before = (c.shaft_nodes, c.shaft_boxes);
        if inner == 0 {
            return Origin::Traced;
        }
        if !self.collect(&shaft, all, s, c) {
            if split {
                c.tiles_split += 1;
                return Origin::Overflow;
            }
            self.walk_each::<ANY>(|s, k| s.soa.ray[k], inner, start, s, c, cost, emit);
            return Origin::Traced;
        }
        c.tiles_listed += 1;
        let len = s.list.len() as u64;
        c.list_len += len;
        let shared = (c.shaft_nodes - before.0, c.shaft_boxes - before.1);
        let soup = self.soup;
        s.tris.clear();
        s.tris.extend(s.list.iter().map(|&p| {
            let k = p as usize;
            TriFromOrigin::new(o, soup.v0[k], soup.v1[k], soup.v2[k], dlow)
        }));
        let soa = &mut s.soa;
        let m = shaft.m.as_vec3().to_array();
        let cap32 = if cap == f64::INFINITY {
            f32::INFINITY
        } else {
            (cap * (1.0 - PROOF_MARGIN)) as f32
        };
        #[cfg(target_arch = "x86_64")]
        let w = match lanes::width() {
            Width::Eight => {
                // SAFETY: `list_pass_avx2` needs AVX2; `width()` is `Eight` only on CPUs that
                // have it.
                unsafe { list_pass_avx2::<ANY>(&s.tris, soa, inner, tmin, m, cap32) };
                8
            }
            Width::Four => {
                list_pass::<Vec4, ANY>(&s.tris, soa, inner, tmin, m, cap32);
                4
            }
        };
        #[cfg(not(target_arch = "x86_64"))]
        let w = {
            list_pass::<Vec4, ANY>(&s.tris, soa, inner, tmin, m, cap32);
            4
        };
        for k in 0..inner {
            let soa = &s.soa;
            let i = soa.ray[k];
            c.list_tests += len;
            if let Some(cost) = cost {
                cost.add(i - start, shared.0, shared.1 + len, len);
            }
            let j = soa.j[k];
            let best: Best = if j < 0.0 {
                (soa.tmax[k], MISS, 0.0, 0.0)
            } else {
                (soa.t[k], s.list[j as usize], soa.u[k], soa.v[k])
            };
            // Any hit answers an any-hit query; else the f32 proof, or `tile.rs`'s f64 one for
            // lanes it cannot settle.
            let settled = (ANY && j >= 0.0) || soa.proven[k / w] >> (k % w) & 1 != 0;
            if settled || shaft.depth(rays.dir(i), best.0) <= cap {
                c.list_rays += 1;
                emit(i, best);
            } else {
                c.fallback_rays += 1;
                let best = self.walk::<ANY>(i, start, s, c, cost);
                emit(i, best);
            }
        }
        Origin::Traced
    }
}

/// What [`Ctx::origin_tile`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// Every ray answered.
    Traced,
    /// The corners answered; the list was too long for the rest.
    Overflow,
    /// Nothing: the tile is not one of rays from one origin.
    NotForIt,
}
