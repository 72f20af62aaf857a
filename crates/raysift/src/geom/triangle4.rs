//! [`intersect_triangle`] on four triangles at once ([`Tri4`]), or on `L::N` rays from one
//! origin at once ([`TriFromOrigin`], written once over [`Lanes`]: four or eight wide), for
//! tracers' leaf and list loops.
//!
//! Each lane runs exactly the f32 operations of the scalar test, in the same order (glam's
//! `Vec3::cross` and `Vec3::dot` written out: `dot = (x·x' + y·y') + z·z'`, no fused
//! multiply-add), so a lane's `t, u, v` and its accept decision are bit-identical to
//! [`intersect_triangle`] on that triangle. The edges `v1 − v0`, `v2 − v0` are computed once
//! when a lane is set (the same subtraction the scalar test does per call). The early returns of
//! the scalar test become one lane mask from vector comparisons; the arithmetic of rejected lanes
//! (divisions by zero, NaNs) is computed and ignored. Written on glam's `Vec4` (SSE2 on x86-64,
//! scalar elsewhere), without `unsafe`: the earlier `[f32; 4]` form vectorised the arithmetic but
//! compiled the seven accept tests to 28 scalar compares. The scalar test's last steps, the box
//! gate ([`box_gate`]) and the range test, run per accepted lane on the lane's own corners'
//! box (stored when the lane is set), so they too are the scalar computation; for rays from one
//! origin they run lane-wise on the triangle's one box.
//!
//! [`intersect_triangle`]: super::intersect_triangle

use super::lanes::Lanes;
use super::triangle::{box_gate, gate_scale, GATE_TOLERANCE};
use glam::{Vec3, Vec3A, Vec4};

/// Four triangles, per axis and lane (`v0[axis]` holds the four lanes' first corners' `axis`
/// coordinate), as the first corner and the two edges from it. Unused lanes may hold anything
/// (callers mask them out of the result).
#[derive(Clone, Copy, Debug, Default)]
pub struct Tri4 {
    /// First corners.
    pub v0: [Vec4; 3],
    /// `v1 − v0`.
    pub e1: [Vec4; 3],
    /// `v2 − v0`.
    pub e2: [Vec4; 3],
    /// Each lane's bounding box `[lo, hi]`, for the box gate.
    pub boxes: [[Vec3; 2]; 4],
    /// Each lane's largest corner coordinate magnitude (the gate's scale with the origin at 0).
    pub scale: Vec4,
}

impl Tri4 {
    /// Sets lane `l` to the triangle `(a, b, c)`.
    #[inline(always)]
    pub fn set(&mut self, l: usize, a: Vec3, b: Vec3, c: Vec3) {
        let (e1, e2) = (b - a, c - a);
        for k in 0..3 {
            self.v0[k][l] = a[k];
            self.e1[k][l] = e1[k];
            self.e2[k][l] = e2[k];
        }
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        self.boxes[l] = [lo, hi];
        self.scale[l] = gate_scale(Vec3::ZERO, lo, hi);
    }
}

/// The four lanes' results: bit `l` of `mask` is set when lane `l` is hit with
/// `tmin <= t <= tmax`, and then `t[l], u[l], v[l]` equal the scalar test's [`super::TriHit`].
#[derive(Clone, Copy, Debug)]
pub struct Hit4 {
    /// Accepted lanes.
    pub mask: u32,
    /// Ray parameters (meaningful in accepted lanes).
    pub t: [f32; 4],
    /// Barycentric u.
    pub u: [f32; 4],
    /// Barycentric v.
    pub v: [f32; 4],
}

/// `(a.y·b.z − b.y·a.z, a.z·b.x − b.z·a.x, a.x·b.y − b.x·a.y)`: glam's `cross`, lane-wise.
#[inline(always)]
fn cross<L: Lanes>(a: [L; 3], b: [L; 3]) -> [L; 3] {
    [
        a[1] * b[2] - b[1] * a[2],
        a[2] * b[0] - b[2] * a[0],
        a[0] * b[1] - b[0] * a[1],
    ]
}

/// `(a.x·b.x + a.y·b.y) + a.z·b.z`: glam's `dot`, lane-wise.
#[inline(always)]
fn dot<L: Lanes>(a: [L; 3], b: [L; 3]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// [`super::intersect_triangle`] of the ray `origin + t·dir` with the four triangles of `tri`.
#[inline(always)]
pub fn intersect_triangle4(origin: Vec3, dir: Vec3, tri: &Tri4, tmin: f32, tmax: f32) -> Hit4 {
    let d = [Vec4::splat(dir.x), Vec4::splat(dir.y), Vec4::splat(dir.z)];
    let (v0, e1, e2) = (tri.v0, tri.e1, tri.e2);
    let p = cross(d, e2);
    let det = dot(e1, p);
    let inv_det = Vec4::ONE / det;
    let s = [
        Vec4::splat(origin.x) - v0[0],
        Vec4::splat(origin.y) - v0[1],
        Vec4::splat(origin.z) - v0[2],
    ];
    let u = dot(s, p) * inv_det;
    let q = cross(s, e1);
    let v = dot(d, q) * inv_det;
    let t = dot(e2, q) * inv_det;
    let mut h = Hit4 {
        mask: accept(det, u, v).bitmask(),
        t: t.to_array(),
        u: u.to_array(),
        v: v.to_array(),
    };
    if h.mask == 0 {
        return h;
    }
    let scale = tri.scale.max(Vec4::splat(origin.abs().max_element()));
    let reach = Vec4::splat(GATE_TOLERANCE) * scale;
    let dmax = dir.abs().max_element();
    h.mask &= may_reach(t, tmin, Vec4::splat(tmax), Vec4::splat(dmax), reach).bitmask();
    let mut m = h.mask;
    while m != 0 {
        let l = m.trailing_zeros() as usize;
        m &= m - 1;
        let [lo, hi] = tri.boxes[l];
        let gated = box_gate(origin, dir, lo, hi, h.t[l], reach[l]);
        gate_lane(&mut h, l, gated, tmin, tmax);
    }
    h
}

/// The scalar test's barycentric accept conditions, in its order, lane-wise; a NaN fails every
/// comparison but `!=` (as in the scalar test, whose NaN `det` then fails `u >= 0`). The box
/// gate and the range test follow per accepted lane ([`gate_lane`]), for lanes that
/// [`may_reach`] the ray's range (computed only when some lane passed).
#[inline(always)]
fn accept<L: Lanes>(det: L, u: L, v: L) -> L::Mask {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    det.cmpne(zero) & u.cmpge(zero) & u.cmple(one) & v.cmpge(zero) & (u + v).cmple(one)
}

/// Lane `l` after the scalar test's last steps: the box gate's distance `gated` (`None`: refused)
/// and the range test `tmin <= t <= tmax`.
#[inline(always)]
#[allow(clippy::manual_range_contains)]
fn gate_lane(h: &mut Hit4, l: usize, gated: Option<f32>, tmin: f32, tmax: f32) {
    match gated {
        Some(t) if t >= tmin && t <= tmax => h.t[l] = t,
        _ => h.mask &= !(1 << l),
    }
}

/// [`super::triangle::may_reach`] lane-wise (same operations, so the same decision).
#[inline(always)]
fn may_reach(t: Vec4, tmin: f32, tmax: Vec4, dmax: Vec4, reach: Vec4) -> glam::BVec4A {
    !(((t - tmax) * dmax).cmpgt(reach) | ((Vec4::splat(tmin) - t) * dmax).cmpgt(reach))
}

/// How [`TriFromOrigin`] keeps its numbers: `f32` (compact: 84 bytes a triangle, for long lists
/// tested eight wide) or [`Vec4`] splatted (312 bytes, loaded as they are by four-lane loops:
/// DACRT's tile leaves, measured 10% faster on Sponza than splatting `f32`s without AVX).
pub trait Splat: Copy + std::fmt::Debug {
    /// `v`, kept.
    fn keep(v: f32) -> Self;
    /// Every lane the kept value.
    fn lanes<L: Lanes>(self) -> L;
}

impl Splat for f32 {
    #[inline(always)]
    fn keep(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn lanes<L: Lanes>(self) -> L {
        L::splat(self)
    }
}

impl Splat for Vec4 {
    #[inline(always)]
    fn keep(v: f32) -> Self {
        Vec4::splat(v)
    }
    #[inline(always)]
    fn lanes<L: Lanes>(self) -> L {
        L::from_splat4(self)
    }
}

/// One triangle prepared for rays that share an origin (a camera's eye): the parts of
/// [`super::intersect_triangle`] that depend only on the triangle and the origin (`e1 = v1 − v0`,
/// `e2 = v2 − v0`, `s = origin − v0`, `q = s × e1` and `e2·q`) are computed once, by the scalar
/// test's own operations, so [`Self::intersect_lanes`] on `L::N` directions is bit-identical to
/// the scalar test on each (the per-ray rest is the scalar order, lane-wise). Written once over
/// [`Lanes`]: four wide ([`Self::intersect4`]) or eight in code compiled for AVX2.
#[derive(Clone, Copy, Debug)]
pub struct TriFromOrigin<S: Splat = Vec4> {
    /// The triangle's bounding box less the origin, `lo − origin` and `hi − origin` per axis
    /// (the slab test's first subtraction, the same numbers for every ray from the origin).
    lo_off: [S; 3],
    hi_off: [S; 3],
    e1: [S; 3],
    e2: [S; 3],
    s: [S; 3],
    q: [S; 3],
    tq: S,
    /// `GATE_TOLERANCE · gate_scale(origin, corners)`.
    reach: f32,
    /// How far beyond `[tmin, tmax]` a lane's `t` may lie and still be moved into it by the
    /// gate (see [`Self::new`]).
    beyond: f32,
}

/// [`TriFromOrigin::intersect_lanes`]' result: bit `l` of `mask` is set when lane `l` is hit
/// with `tmin <= t <= tmax`, and then lane `l` of `t, u, v` equals the scalar test's
/// [`super::TriHit`] (other lanes hold anything).
#[derive(Clone, Copy, Debug)]
pub struct HitLanes<L: Lanes> {
    /// Accepted lanes.
    pub mask: u32,
    /// The same, as a lane mask.
    pub hits: L::Mask,
    /// Ray parameters.
    pub t: L,
    /// Barycentric u.
    pub u: L,
    /// Barycentric v.
    pub v: L,
}

impl<S: Splat> TriFromOrigin<S> {
    /// Triangle `(v0, v1, v2)` seen from `origin`, for rays whose `|d|∞` are all at least
    /// `dlow` (0 when unknown).
    ///
    /// The gate's pre-test in [`Self::intersect_lanes`] is then a range test widened by
    /// `beyond = reach / dlow · (1 + 10^-4)`: a candidate the gate accepts into `[tmin, tmax]`
    /// from `t > tmax` has `fl(t − moved) · dmax <= reach` (within one rounding), so in real
    /// numbers `t − tmax <= t − moved <= reach · (1 + 2^-21) / dmax <= reach · (1 + 2^-21) / dlow
    /// <= beyond` (the two f32 roundings of `beyond` lose less than `10^-4` gains), hence
    /// `t <= fl(tmax + beyond)` (rounding is monotone and `t` is a float); likewise below `tmin`.
    /// So the widened test drops only lanes the gate would refuse, at the cost of one add.
    #[inline(always)]
    pub fn new(origin: Vec3, v0: Vec3, v1: Vec3, v2: Vec3, dlow: f32) -> Self {
        let (e1, e2, s) = (v1 - v0, v2 - v0, origin - v0);
        let q = s.cross(e1);
        // The box and scale with SSE min/max (a triangle is set up per tile leaf, often): the
        // same values as the scalar test's for finite corners, which a scene guarantees.
        let a = |v: Vec3| Vec3A::from(v);
        let (lo, hi) = (a(v0).min(a(v1)).min(a(v2)), a(v0).max(a(v1)).max(a(v2)));
        let scale = a(origin).abs().max(lo.abs()).max(hi.abs()).max_element();
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        let reach = GATE_TOLERANCE * scale;
        let splat = |v: Vec3| [S::keep(v.x), S::keep(v.y), S::keep(v.z)];
        Self {
            lo_off: splat(lo - origin),
            hi_off: splat(hi - origin),
            e1: splat(e1),
            e2: splat(e2),
            s: splat(s),
            q: splat(q),
            tq: S::keep(e2.dot(q)),
            reach,
            beyond: if dlow > 0.0 {
                reach / dlow * (1.0 + 1e-4)
            } else {
                f32::INFINITY
            },
        }
    }

    /// [`Self::intersect_lanes`] on four lanes, as a [`Hit4`].
    #[inline(always)]
    pub fn intersect4(&self, d: [Vec4; 3], tmin: f32, tmax: Vec4) -> Hit4 {
        let h = self.intersect_lanes(d, tmin, tmax);
        Hit4 {
            mask: h.mask,
            t: h.t.to_array(),
            u: h.u.to_array(),
            v: h.v.to_array(),
        }
    }

    /// [`super::intersect_triangle`] of the `L::N` rays `origin + t·d[·][l]` (directions per
    /// axis and lane), each with `tmin <= t <= tmax[l]` and `|d|∞` at least the `dlow` given to
    /// [`Self::new`].
    #[inline(always)]
    pub fn intersect_lanes<L: Lanes>(&self, d: [L; 3], tmin: f32, tmax: L) -> HitLanes<L> {
        let low = L::splat(tmin - self.beyond);
        self.lanes_from(d, L::splat(tmin), low, tmax)
    }

    /// [`Self::intersect_lanes`] with a `tmin` per lane (rays that share an origin but not
    /// their `tmin`): the same operations lane by lane, so the same bits.
    #[inline(always)]
    pub fn intersect_lanes_each<L: Lanes>(&self, d: [L; 3], tmin: L, tmax: L) -> HitLanes<L> {
        self.lanes_from(d, tmin, tmin - L::splat(self.beyond), tmax)
    }

    /// The lane test, given `tmin` and `low = tmin − beyond` per lane.
    #[inline(always)]
    fn lanes_from<L: Lanes>(&self, d: [L; 3], tmin: L, low: L, tmax: L) -> HitLanes<L> {
        let splat = |v: [S; 3]| v.map(S::lanes::<L>);
        let p = cross(d, splat(self.e2));
        let det = dot(splat(self.e1), p);
        let inv_det = L::splat(1.0) / det;
        let u = dot(splat(self.s), p) * inv_det;
        let v = dot(d, splat(self.q)) * inv_det;
        let t = self.tq.lanes::<L>() * inv_det;
        let range = t.cmple(tmax + L::splat(self.beyond)) & t.cmpge(low);
        let mut hits = accept(det, u, v) & range;
        let mut mask = L::bitmask(hits);
        let mut t_out = t;
        if mask != 0 {
            let (gated, ok) = self.box_gate_lanes(d, t, tmin, tmax);
            hits = hits & ok;
            mask = L::bitmask(hits);
            t_out = gated;
        }
        HitLanes {
            mask,
            hits,
            t: t_out,
            u,
            v,
        }
    }

    /// [`box_gate`] and the range test on `L::N` lanes at once: the same f32 operations in the
    /// same order as the scalar [`SlabRay::new`](super::SlabRay::new) +
    /// [`SlabRay::interval`](super::SlabRay::interval) (near plane chosen by the sign bit of the
    /// direction, which is that of its reciprocal, `−0.0` included; a NaN slab distance never
    /// moves the interval) and the gate's move, with the first subtraction precomputed. One
    /// vector pass instead of a scalar gate per candidate lane: the gate's cost in DACRT's tile
    /// leaves (BENCHMARKS.md, "The exact contract"). Returns the gated distances and the lanes
    /// that pass (callers keep only lanes that passed the barycentric tests too).
    #[inline(always)]
    fn box_gate_lanes<L: Lanes>(&self, d: [L; 3], t: L, tmin: L, tmax: L) -> (L, L::Mask) {
        let inv = d.map(|dk| L::splat(1.0) / dk);
        let (enter, exit) = slab_lanes(
            d,
            inv,
            self.lo_off.map(S::lanes::<L>),
            self.hi_off.map(S::lanes::<L>),
        );
        let nonempty = enter.cmple(exit);
        let inside = t.cmpge(enter) & t.cmple(exit);
        let moved = L::select(enter.cmpgt(t), enter, exit);
        let dmax = d[0].abs().max(d[1].abs()).max(d[2].abs());
        let near_enough = ((t - moved).abs() * dmax).cmple(L::splat(self.reach));
        let gated = L::select(inside, t, moved);
        let ok = nonempty & (inside | near_enough) & gated.cmpge(tmin) & gated.cmple(tmax);
        (gated, ok)
    }
}

/// The shared slab interval `(enter, exit)` of `L::N` rays from one origin with a box given
/// less that origin (`lo_off = lo − origin`, `hi_off = hi − origin`), `inv = 1 / d` per lane:
/// the operations and order of [`SlabRay::interval`](super::SlabRay::interval) (near plane by
/// the direction's sign bit, a NaN slab distance never moving the interval, the exit widened and
/// the entry lowered by the shared slacks). The box gate computes its interval here, so a hit
/// a triangle test reports on a lane lies in `[enter, exit]` of every box containing the
/// triangle's (the slab test is monotone in the box): a lane with `enter > exit`,
/// `enter > tmax` or `exit < tmin` for such a box has no hit there (RTRPS's per-ray check).
#[inline(always)]
pub fn slab_lanes<L: Lanes>(d: [L; 3], inv: [L; 3], lo_off: [L; 3], hi_off: [L; 3]) -> (L, L) {
    let mut enter = L::splat(f32::NEG_INFINITY);
    let mut exit = L::splat(f32::INFINITY);
    let slack = L::splat(super::BOX_EXIT_SLACK);
    for k in 0..3 {
        let neg = d[k].sign_bit();
        let near = L::select(neg, hi_off[k], lo_off[k]) * inv[k];
        let far = L::select(neg, lo_off[k], hi_off[k]) * inv[k] * slack;
        enter = L::select(near.cmpgt(enter), near, enter);
        exit = L::select(exit.cmpgt(far), far, exit);
    }
    let enter = enter - enter.abs() * L::splat(super::slab::BOX_ENTRY_SLACK);
    (enter, exit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::lanes::F32x8;
    use crate::geom::{intersect_triangle, TriHit};
    use rand::{Rng, SeedableRng};

    /// Lane `l` of `h` is the scalar result `s`, bit for bit; counts hits and misses.
    fn same_lane(s: Option<TriHit>, h: &Hit4, l: usize, n: usize, checked: &mut (u32, u32)) {
        assert_eq!(s.is_some(), h.mask >> l & 1 == 1, "case {n} lane {l}");
        if let Some(s) = s {
            assert_eq!(
                (s.t.to_bits(), s.u.to_bits(), s.v.to_bits()),
                (h.t[l].to_bits(), h.u[l].to_bits(), h.v[l].to_bits())
            );
            checked.0 += 1;
        } else {
            checked.1 += 1;
        }
    }

    /// Every lane agrees with the scalar test bit for bit, on random and on edge-hugging rays
    /// (shared vertices and edges, zero direction components, degenerate triangles, NaN).
    #[test]
    fn lanes_are_the_scalar_test() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let mut r = |s: f32| rng.gen_range(-s..s);
        let mut checked = (0, 0);
        for n in 0..200_000 {
            let base = Vec3::new(r(1.0), r(1.0), r(1.0));
            let mut tri = Tri4::default();
            let mut ts = [[Vec3::ZERO; 3]; 4];
            for (l, t) in ts.iter_mut().enumerate() {
                let a = base + Vec3::new(r(1.0), r(1.0), r(1.0)) * (l % 2) as f32;
                let b = base + Vec3::new(r(1.0), r(1.0), r(1.0));
                let c = match (n + l) % 7 {
                    0 => a,                 // degenerate (point-like edge)
                    1 => a + (b - a) * 0.5, // collinear
                    _ => base + Vec3::new(r(1.0), r(1.0), r(1.0)),
                };
                *t = if n % 11 == 0 { [a; 3] } else { [a, b, c] };
                tri.set(l, t[0], t[1], t[2]);
            }
            let o = Vec3::new(r(3.0), r(3.0), r(3.0));
            // Aim at a vertex, an edge midpoint, or a random point; sometimes zero components.
            let target = match n % 4 {
                0 => ts[0][1],
                1 => (ts[1][0] + ts[1][2]) * 0.5,
                _ => Vec3::new(r(1.0), r(1.0), r(1.0)),
            };
            let mut d = target - o;
            if n % 5 == 0 {
                d.y = 0.0;
            }
            if n % 97 == 0 {
                d.x = f32::NAN;
            }
            let (tmin, tmax) = if n % 3 == 0 {
                (r(0.5).abs(), 1.0 + r(0.5))
            } else {
                (0.0, f32::INFINITY)
            };
            let h = intersect_triangle4(o, d, &tri, tmin, tmax);
            for (l, t) in ts.iter().enumerate() {
                let s = intersect_triangle(o, d, t[0], t[1], t[2], tmin, tmax);
                same_lane(s, &h, l, n, &mut checked);
            }
        }
        // Both outcomes exercised often.
        assert!(checked.0 > 20_000 && checked.1 > 20_000, "{checked:?}");
    }

    /// Four rays from one origin against a prepared triangle: every lane is the scalar test.
    #[test]
    fn rays_from_one_origin_are_the_scalar_test() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(9);
        let mut r = |s: f32| rng.gen_range(-s..s);
        let mut checked = (0, 0);
        for n in 0..200_000 {
            let base = Vec3::new(r(1.0), r(1.0), r(1.0));
            let a = base + Vec3::new(r(1.0), r(1.0), r(1.0));
            let b = base + Vec3::new(r(1.0), r(1.0), r(1.0));
            let c = match n % 7 {
                0 => a,
                1 => a + (b - a) * 0.5,
                _ => base + Vec3::new(r(1.0), r(1.0), r(1.0)),
            };
            let mut o = Vec3::new(r(3.0), r(3.0), r(3.0));
            if n % 13 == 0 {
                // On the box's y = min plane, with some lanes' d.y = 0: the slab's 0 · ∞ = NaN.
                o.y = a.y.min(b.y).min(c.y);
            }
            let dirs: [Vec3; 4] = std::array::from_fn(|l| {
                let target = match (n + l) % 4 {
                    0 => b,
                    1 => (a + c) * 0.5,
                    _ => base + Vec3::new(r(1.0), r(1.0), r(1.0)),
                };
                let mut d = target - o;
                if (n + l) % 5 == 0 {
                    d.y = 0.0;
                }
                if (n + l) % 11 == 0 {
                    d.z = -0.0;
                }
                if (n + l) % 97 == 0 {
                    d.x = f32::NAN;
                }
                d
            });
            let tmin = if n % 3 == 0 { r(0.5).abs() } else { 0.0 };
            let tmax: [f32; 4] = std::array::from_fn(|l| match (n + l) % 3 {
                0 => 1.0 + r(0.5),
                // One float below the lane's own hit: the range test's edge.
                1 => intersect_triangle(o, dirs[l], a, b, c, tmin, f32::INFINITY)
                    .map_or(f32::INFINITY, |h| {
                        f32::from_bits(h.t.to_bits().saturating_sub(1))
                    }),
                _ => f32::INFINITY,
            });
            let d4 = [0, 1, 2].map(|k| Vec4::from_array(dirs.map(|d| d[k])));
            // The pre-test's bound: exact, or none.
            let dlow = if n % 2 == 0 {
                dirs.iter()
                    .map(|d| d.abs().max_element())
                    .fold(f32::INFINITY, f32::min)
            } else {
                0.0
            };
            let tri = TriFromOrigin::<Vec4>::new(o, a, b, c, dlow);
            let h = tri.intersect4(d4, tmin, Vec4::from_array(tmax));
            // Eight lanes (the AVX2 width) on the compact form: the four rays, then the same in
            // reverse order.
            let tri = TriFromOrigin::<f32>::new(o, a, b, c, dlow);
            let at8 = |k: usize| if k < 4 { k } else { 7 - k };
            let d8 = [0, 1, 2].map(|k| F32x8::from_fn(|l| dirs[at8(l)][k]));
            let h8 = tri.intersect_lanes(d8, tmin, F32x8::from_fn(|l| tmax[at8(l)]));
            let h8 = |half: usize| Hit4 {
                mask: h8.mask >> (4 * half) & 15,
                t: std::array::from_fn(|l| h8.t.0[4 * half + l]),
                u: std::array::from_fn(|l| h8.u.0[4 * half + l]),
                v: std::array::from_fn(|l| h8.v.0[4 * half + l]),
            };
            // A `tmin` per lane (rays from one origin that do not share it), eight wide.
            let tmins: [f32; 4] =
                std::array::from_fn(|l| if (n + l) % 2 == 0 { tmin } else { r(0.5).abs() });
            let he = tri.intersect_lanes_each(
                d8,
                F32x8::from_fn(|l| tmins[at8(l)]),
                F32x8::from_fn(|l| tmax[at8(l)]),
            );
            let he = |half: usize| Hit4 {
                mask: he.mask >> (4 * half) & 15,
                t: std::array::from_fn(|l| he.t.0[4 * half + l]),
                u: std::array::from_fn(|l| he.u.0[4 * half + l]),
                v: std::array::from_fn(|l| he.v.0[4 * half + l]),
            };
            for l in 0..4 {
                let s = intersect_triangle(o, dirs[l], a, b, c, tmin, tmax[l]);
                same_lane(s, &h, l, n, &mut checked);
                same_lane(s, &h8(0), l, n, &mut checked);
                same_lane(s, &h8(1), 3 - l, n, &mut checked);
                let s = intersect_triangle(o, dirs[l], a, b, c, tmins[l], tmax[l]);
                same_lane(s, &he(0), l, n, &mut checked);
                same_lane(s, &he(1), 3 - l, n, &mut checked);
            }
        }
        assert!(checked.0 > 20_000 && checked.1 > 20_000, "{checked:?}");
    }
    /// Rays from one origin at a triangle in an axis plane (a Sponza wall), each lane's `tmax`
    /// set to its own hit's distance where the gate moved `t` down onto the plane: the
    /// Möller–Trumbore `t` then lies beyond `tmax`, and the widened range test must still let the
    /// lane reach the gate (with or without a `dlow` bound). The case must contain such lanes.
    #[test]
    fn lanes_the_gate_moves_below_tmax_are_kept() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        let (a, b, c) = (
            Vec3::new(16.218_04, 0.093313, 7.171_489),
            Vec3::new(16.218_04, 3.892_572, 3.638_583),
            Vec3::new(16.218_04, 3.678_313, 3.495_419),
        );
        let raw_t = |o: Vec3, d: Vec3| {
            let (e1, e2) = (b - a, c - a);
            e2.dot((o - a).cross(e1)) * (1.0 / e1.dot(d.cross(e2)))
        };
        let (mut moved, mut checked) = (0, (0, 0));
        for n in 0..20_000 {
            let o = Vec3::new(
                rng.gen_range(-17.0..10.0),
                rng.gen_range(-1.0..15.0),
                rng.gen_range(-7.8..7.8),
            );
            let dirs: [Vec3; 4] = std::array::from_fn(|_| {
                let (r1, r2): (f32, f32) = (rng.gen(), rng.gen());
                let (r1, r2) = if r1 + r2 > 1.0 {
                    (1.0 - r1, 1.0 - r2)
                } else {
                    (r1, r2)
                };
                a + (b - a) * r1 + (c - a) * r2 - o
            });
            let tmax: [f32; 4] = std::array::from_fn(|l| {
                match intersect_triangle(o, dirs[l], a, b, c, 0.0, f32::INFINITY) {
                    Some(h) if raw_t(o, dirs[l]) > h.t => {
                        moved += 1;
                        h.t
                    }
                    _ => f32::INFINITY,
                }
            });
            let dlow = if n % 2 == 0 {
                dirs.iter()
                    .map(|d| d.abs().max_element())
                    .fold(f32::INFINITY, f32::min)
            } else {
                0.0
            };
            let tri = TriFromOrigin::<Vec4>::new(o, a, b, c, dlow);
            let d4 = [0, 1, 2].map(|k| Vec4::from_array(dirs.map(|d| d[k])));
            let h = tri.intersect4(d4, 0.0, Vec4::from_array(tmax));
            for l in 0..4 {
                let s = intersect_triangle(o, dirs[l], a, b, c, 0.0, tmax[l]);
                same_lane(s, &h, l, n, &mut checked);
            }
        }
        assert!(
            moved > 100,
            "the case must contain lanes moved below their tmax: {moved}"
        );
    }
}
