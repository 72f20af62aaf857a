//! One ray group as ray-planes (§2.2–2.3, Algorithm 2, §3.1–3.2): the grid frame and its row
//! and column fans, the sphere walk (part tree → parts → inner → leaves) with each sphere tested
//! by the planes its parent hit, and the rays reproduced at leaves (a hit row × a hit column),
//! each tested against the leaf's triangles with the shared triangle test, one ray at a time or
//! through its common-origin form a row's vector of rays at a time (bit-identical).

use super::{random, Config, Counts, TriTest};
use crate::accel::spheres::{Part, SphereTree, MAX_DEPTH, NO_KID, SLACK};
use crate::geom::aligned::{AlignedFit, AlignedGroup, AlignedRow, AlignedTri};
use crate::geom::lanes::{self, Width};
use crate::geom::sphere_plane::{fan_bound, wedge_misses, PlaneFan, MAX_FAN};
use crate::geom::{RayCone, TriFromOrigin};
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::{CostMut, HitsMut};
use glam::{DVec3, Vec3};

/// A group: rays `base + i·stride + j` for rows `i < rows` and columns `j < cols`, one origin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroupSpec {
    /// Index of ray (0, 0).
    pub base: usize,
    /// Index step between rows.
    pub stride: usize,
    /// Rows (row planes).
    pub rows: usize,
    /// Columns (column planes).
    pub cols: usize,
}

impl GroupSpec {
    #[inline(always)]
    pub(super) fn ray(&self, i: usize, j: usize) -> usize {
        self.base + i * self.stride + j
    }
}

/// Where a group's answers go.
pub enum Out<'a, 'b> {
    /// Closest hits.
    Hits(&'a mut HitsMut<'b>),
    /// Any-hit flags.
    Occluded(&'a mut [bool]),
}

/// A part's frame for one group: grid coordinates of a local point `p` are `M·p + b`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Frame {
    pub(super) m: [Vec3; 3],
    pub(super) b: Vec3,
    pub(super) sigma: f32,
    pub(super) e: f32,
}

impl Frame {
    /// Part `p`'s frame in the grid's (rows `r`, origin `o`): `M = R·A`, `b = R·(t − o)`, in f64.
    fn of(p: &Part, r: &[DVec3; 3], o64: DVec3, o: Vec3) -> Self {
        let a = [
            p.xf.matrix3.x_axis,
            p.xf.matrix3.y_axis,
            p.xf.matrix3.z_axis,
        ]
        .map(|c| DVec3::from(Vec3::from(c)));
        let t = DVec3::from(Vec3::from(p.xf.translation)) - o64;
        let m = r.map(|row| DVec3::new(row.dot(a[0]), row.dot(a[1]), row.dot(a[2])).as_vec3());
        let b = DVec3::new(r[0].dot(t), r[1].dot(t), r[2].dot(t)).as_vec3();
        let scale = p.sigma * p.extent
            + Vec3::from(p.xf.translation).abs().max_element()
            + o.abs().max_element();
        Frame {
            m,
            b,
            sigma: p.sigma,
            e: 2.0 * SLACK * scale,
        }
    }

    #[inline(always)]
    pub(super) fn apply(&self, p: Vec3) -> Vec3 {
        Vec3::new(self.m[0].dot(p), self.m[1].dot(p), self.m[2].dot(p)) + self.b
    }

    /// [`sphere`] for a sphere of the part (local centre `c`, local radius `r`).
    #[inline]
    pub(super) fn sphere(
        &self,
        s: &Scratch,
        c: Vec3,
        r: f32,
        parent: (u64, u64),
        cfg: &Config,
        n: &mut Counts,
    ) -> Option<(u64, u64)> {
        sphere(s, self.apply(c), r * self.sigma, self.e, parent, cfg, n)
    }
}

/// Buffers reused by every group of a chunk.
pub struct Scratch {
    /// Unit directions in the grid frame, row-major (`i·cols + j`).
    pub(super) g: Vec<Vec3>,
    /// The group's rays as structure-of-arrays, row `i` at `i·rs ..`, padded to whole vectors
    /// (`rs` is `cols` rounded up to [`MAX_LANES`]; pad slots repeat the row's first ray and
    /// are never in a mask): raw directions (for the exact test), `tmin`, `tmax`, grid-frame
    /// unit directions (for the sphere check), reciprocal directions (for the box check, as
    /// the shared slab test computes them), and closest hits so far.
    pub(super) rs: usize,
    pub(super) dx: Vec<f32>,
    pub(super) dy: Vec<f32>,
    pub(super) dz: Vec<f32>,
    pub(super) tmin: Vec<f32>,
    pub(super) tmax: Vec<f32>,
    pub(super) gx: Vec<f32>,
    pub(super) gy: Vec<f32>,
    pub(super) gz: Vec<f32>,
    pub(super) ix: Vec<f32>,
    pub(super) iy: Vec<f32>,
    pub(super) iz: Vec<f32>,
    pub(super) bt: Vec<f32>,
    pub(super) bp: Vec<u32>,
    pub(super) bu: Vec<f32>,
    pub(super) bv: Vec<f32>,
    /// `|d|` of each ray (`hit_cut`: a hit at `t` lies `t·|d|` along the unit direction).
    pub(super) dl: Vec<f32>,
    /// `hit_cut` (closest hits under the depth cull): the far bound of each row's rays (by
    /// index) from their closest hits so far, and the rows whose hits improved since.
    pub(super) cut: bool,
    pub(super) rowz: [f32; MAX_FAN],
    pub(super) dirty: u64,
    /// Smallest `|d|∞` of the group's rays (the common-origin test's pre-test bound).
    pub(super) dlow: f32,
    /// The current leaf's triangles prepared for the group's origin (built on first use).
    pub(super) tris: Vec<TriFromOrigin<f32>>,
    /// A cone holding the group's directions (`edge_cull`).
    pub(super) cone: Option<RayCone>,
    /// The aligned ray-plane form (`tri_test=aligned`): the group's fit, each ray's grid
    /// coordinate `a_x` (padded as the rays) and `a_y`, each row's spread (by index), and the
    /// current leaf's triangles projected on the frame (built on first use).
    pub(super) align: Option<AlignedGroup>,
    pub(super) ax: Vec<f32>,
    pub(super) ay: Vec<f32>,
    pub(super) arows: Vec<AlignedRow>,
    pub(super) atris: Vec<AlignedTri>,
    /// Any hit: each row's finished columns (by index).
    pub(super) done: [u64; MAX_FAN],
    /// Any hit: finished rays per column (by index).
    pub(super) col_done: [u8; MAX_FAN],
    /// The rows and columns (by plane position) with a ray not yet finished: a sphere is
    /// tested only by their planes (ours; all of them for closest hits).
    pub(super) live: (u64, u64),
    /// Plane positions of rows and columns, by index.
    pub(super) pos: ([u8; MAX_FAN], [u8; MAX_FAN]),
    pub(super) rows: PlaneFan,
    pub(super) cols: PlaneFan,
    /// Depth cull of the current group: every ray has `tmin >= 0` and a direction `u.z > 0` in
    /// the grid frame, so every point a ray can report lies in `0 <= z <= zmax`.
    pub(super) depth: Option<f32>,
}

impl Scratch {
    /// Empty buffers (grown on first use).
    pub fn new() -> Self {
        Self {
            g: Vec::new(),
            rs: 0,
            dx: Vec::new(),
            dy: Vec::new(),
            dz: Vec::new(),
            tmin: Vec::new(),
            tmax: Vec::new(),
            gx: Vec::new(),
            gy: Vec::new(),
            gz: Vec::new(),
            ix: Vec::new(),
            iy: Vec::new(),
            iz: Vec::new(),
            bt: Vec::new(),
            bp: Vec::new(),
            bu: Vec::new(),
            bv: Vec::new(),
            dl: Vec::new(),
            cut: false,
            rowz: [f32::INFINITY; MAX_FAN],
            dirty: 0,
            dlow: 0.0,
            tris: Vec::new(),
            cone: None,
            done: [0; MAX_FAN],
            col_done: [0; MAX_FAN],
            live: (0, 0),
            pos: ([0; MAX_FAN], [0; MAX_FAN]),
            rows: PlaneFan::default(),
            cols: PlaneFan::default(),
            depth: None,
            align: None,
            ax: Vec::new(),
            ay: Vec::new(),
            arows: Vec::new(),
            atris: Vec::new(),
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        let f = [
            &self.dx, &self.dy, &self.dz, &self.tmin, &self.tmax, &self.gx, &self.gy, &self.gz,
            &self.ix, &self.iy, &self.iz, &self.bt, &self.bu, &self.bv, &self.dl, &self.ax,
            &self.ay,
        ];
        self.g.capacity() * 12
            + f.iter().map(|v| v.capacity() * 4).sum::<usize>()
            + self.bp.capacity() * 4
            + self.tris.capacity() * std::mem::size_of::<TriFromOrigin<f32>>()
            + self.arows.capacity() * std::mem::size_of::<AlignedRow>()
            + self.atris.capacity() * std::mem::size_of::<AlignedTri>()
            + std::mem::size_of::<Self>()
    }

    /// The structure-of-arrays of group `g` (after [`setup`]: `self.g` holds its grid-frame
    /// directions), closest-hit slots reset when `closest`, reciprocal directions only with
    /// `inverse` (the box check).
    fn load(&mut self, rays: &RayBatch, g: GroupSpec, closest: bool, inverse: bool) {
        let rs = g.cols.next_multiple_of(MAX_LANES);
        self.rs = rs;
        let n = g.rows * rs;
        for v in [
            &mut self.dx,
            &mut self.dy,
            &mut self.dz,
            &mut self.tmin,
            &mut self.tmax,
            &mut self.gx,
            &mut self.gy,
            &mut self.gz,
            &mut self.dl,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        for v in [&mut self.ix, &mut self.iy, &mut self.iz] {
            v.clear();
            v.resize(if inverse { n } else { 0 }, 0.0);
        }
        let mut dlow = f32::INFINITY;
        for i in 0..g.rows {
            for k in 0..rs {
                // Pad slots repeat the row's first ray.
                let j = if k < g.cols { k } else { 0 };
                let (r, at, u) = (g.ray(i, j), i * rs + k, self.g[i * g.cols + j]);
                let d = rays.dir(r);
                dlow = dlow.min(d.abs().max_element());
                (self.dx[at], self.dy[at], self.dz[at]) = (d.x, d.y, d.z);
                (self.tmin[at], self.tmax[at]) = (rays.tmin[r], rays.tmax[r]);
                (self.gx[at], self.gy[at], self.gz[at]) = (u.x, u.y, u.z);
                self.dl[at] = d.length();
                if inverse {
                    (self.ix[at], self.iy[at], self.iz[at]) = (1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
                }
            }
        }
        self.dlow = dlow;
        if closest {
            self.bt.clear();
            self.bt.extend_from_slice(&self.tmax);
            self.bp.clear();
            self.bp.resize(n, MISS);
            self.bu.clear();
            self.bu.resize(n, 0.0);
            self.bv.clear();
            self.bv.resize(n, 0.0);
        }
    }

    /// The aligned form's data of group `g` in `frame` (after [`Self::load`]): each ray's grid
    /// point (pads repeat their row's first), each row's spread, and the group's fit; `None`
    /// when a ray lies more than 60° from the frame's `z`.
    fn align(&mut self, g: GroupSpec, frame: [Vec3; 3]) {
        let n = g.rows * self.rs;
        self.ax.clear();
        self.ax.resize(n, 0.0);
        self.ay.clear();
        self.ay.resize(n, 0.0);
        self.arows.clear();
        let mut fit = AlignedFit::new(frame);
        for i in 0..g.rows {
            let row = i * self.rs;
            for k in 0..self.rs {
                let at = row + k;
                if k >= g.cols {
                    (self.ax[at], self.ay[at]) = (self.ax[row], self.ay[row]);
                    continue;
                }
                let d = Vec3::new(self.dx[at], self.dy[at], self.dz[at]);
                let u = Vec3::new(self.gx[at], self.gy[at], self.gz[at]);
                (self.ax[at], self.ay[at]) = fit.add(d, u);
            }
            let (ax, ay) = (&self.ax[row..row + g.cols], &self.ay[row..row + g.cols]);
            self.arows
                .push(AlignedRow::of(ax.iter().copied().zip(ay.iter().copied())));
        }
        self.align = fit.done();
    }

    /// Any hit: the rays of row `i` in columns `m` (by index) are finished; a row or column
    /// whose rays are all finished leaves the live planes.
    pub(super) fn finish(&mut self, i: usize, m: u64, rows: usize, cols: usize) {
        self.done[i] |= m;
        if self.done[i] == mask(cols) {
            self.live.0 &= !(1 << self.pos.0[i]);
        }
        let mut b = m;
        while b != 0 {
            let j = b.trailing_zeros() as usize;
            b &= b - 1;
            self.col_done[j] += 1;
            if usize::from(self.col_done[j]) == rows {
                self.live.1 &= !(1 << self.pos.1[j]);
            }
        }
    }

    /// Recomputes the far bounds of the rows whose hits improved, and lowers the group's
    /// (`hit_cut`): [`depth_range`]'s bound with each ray's closest hit `t` for its `tmax` (the
    /// same margins: a hit nearer than or tied with the closest so far lies at most that deep).
    pub(super) fn lower_depth(&mut self, rows: usize, cols: usize) {
        let mut dirty = std::mem::take(&mut self.dirty);
        while dirty != 0 {
            let i = dirty.trailing_zeros() as usize;
            dirty &= dirty - 1;
            let at = i * self.rs;
            self.rowz[i] = (at..at + cols).fold(0.0, |m, x| {
                let far = self.bt[x] * self.dl[x] * (self.gz[x] + 1e-6);
                m.max(far * (1.0 + 1e-5))
            });
        }
        let all = self.rowz[..rows].iter().fold(0.0f32, |m, &v| m.max(v));
        self.depth = self.depth.map(|d| d.min(all));
    }
}

/// Groups of at least this many rays test reproduced rays through the common-origin form when
/// `tri_test=auto` (the crossover measured in BENCHMARKS.md § RTRPS, "Table 2 / Fig. 10": with
/// four lanes, the form is no slower from 2×2 groups on).
pub const ORIGIN_FORM_RAYS: usize = 4;

/// Leaves whose hit rows × hit columns cover at least this many rays go through the edge cull
/// first (BENCHMARKS.md § RTRPS).
pub const EDGE_CULL_RAYS: u32 = 16;

/// Widest vector the leaves use (the group's rows are padded to it).
pub(super) const MAX_LANES: usize = 4;

pub(super) fn mask(n: usize) -> u64 {
    if n >= 64 {
        u64::MAX
    } else {
        (1u64 << n) - 1
    }
}

/// The fitted frame `(v_x, v_y, v_z)` of the group and each ray's unit direction in it (into
/// `s.g`); `None` when the rays do not share one origin or a direction is zero or not finite.
fn setup(rays: &RayBatch, g: GroupSpec, s: &mut Scratch) -> Option<(Vec3, [Vec3; 3])> {
    let o = rays.origin(g.base);
    let n = g.rows * g.cols;
    s.g.clear();
    let (mut sum, mut along) = (Vec3::ZERO, Vec3::ZERO);
    for i in 0..g.rows {
        for j in 0..g.cols {
            let r = g.ray(i, j);
            // Bit for bit: the common-origin triangle test computes `origin − v0` once, and
            // `-0.0` and `0.0` can give it different zeros.
            if rays.origin(r).to_array().map(f32::to_bits) != o.to_array().map(f32::to_bits) {
                return None;
            }
            let d = rays.dir(r);
            let l = d.length();
            if !(l > 0.0 && l.is_finite() && o.is_finite()) {
                return None;
            }
            let u = d / l;
            sum += u;
            s.g.push(u);
        }
        if g.cols > 1 {
            along += s.g[i * g.cols + g.cols - 1] - s.g[i * g.cols];
        }
    }
    if g.cols == 1 && g.rows > 1 {
        // One column: the rows run along y; x is then across them.
        along = (s.g[n - 1] - s.g[0]).cross(sum);
    }
    // Any orthonormal frame is correct (the fans' slack measures the fit); a good one makes
    // thin planes.
    let vz = {
        let z = sum.normalize_or_zero();
        if z == Vec3::ZERO || !z.is_finite() {
            Vec3::Z
        } else {
            z
        }
    };
    // The frame must be orthonormal: sphere distances and the fans' slack are measured in it.
    // x is `along` made orthogonal to z by two Gram–Schmidt passes; when `along` is (nearly)
    // parallel to z, what is left of it is rounding noise that one pass leaves far from
    // orthogonal (hemisphere grids whose rows are azimuths: 0.70 from z measured, which lost
    // hits), so x then comes from z alone.
    let vx = {
        let orth = |a: Vec3| a - vz * vz.dot(a);
        let o1 = orth(along);
        let x = orth(o1).normalize_or_zero();
        if x.is_finite()
            && x != Vec3::ZERO
            && o1.length() > 1e-3 * along.length()
            && x.dot(vz).abs() <= 1e-6
        {
            x
        } else {
            vz.any_orthonormal_vector()
        }
    };
    let vy = vz.cross(vx);
    for u in s.g.iter_mut() {
        *u = Vec3::new(u.dot(vx), u.dot(vy), u.dot(vz));
    }
    Some((o, [vx, vy, vz]))
}

/// The depth cull's far bound: the largest grid-frame depth `tmax · |d| · u.z` a ray of the
/// group reaches (infinite for unbounded rays), or `None` when a ray has `tmin < 0` or a
/// direction not clearly ahead (`u.z <= 1e-3`), where depth says nothing. `u.z` is an f32
/// component of a unit vector in an f32 frame, off by a few 1e-7 at most: the bound takes
/// `u.z + 1e-6` (then true `u.z > 0` too), and `1e-5` relative for `|d|` and the products.
fn depth_range(rays: &RayBatch, g: GroupSpec, units: &[Vec3]) -> Option<f32> {
    let mut zmax = 0.0f32;
    for i in 0..g.rows {
        for j in 0..g.cols {
            let r = g.ray(i, j);
            let uz = units[i * g.cols + j].z;
            if !(rays.tmin[r] >= 0.0 && uz > 1e-3) {
                return None;
            }
            let far = rays.tmax[r] * rays.dir(r).length() * (uz + 1e-6);
            zmax = zmax.max(far * (1.0 + 1e-5));
        }
    }
    Some(zmax)
}

/// Tests one fan against a circle (2D centre `c`, plane bound `bound`), testing only planes of
/// `parent` or, with the sign rule, planes whose answer decides where to look; returns the hit
/// planes (sorted positions) among `parent`'s.
#[inline]
fn family(
    fan: &PlaneFan,
    c: (f32, f32),
    bound: f32,
    e: f32,
    parent: u64,
    cfg: &Config,
    n: &mut Counts,
) -> u64 {
    if parent == 0 {
        return 0;
    }
    // A circle around the fan's shared line meets every plane.
    if c.0 * c.0 + c.1 * c.1 <= bound * bound {
        return parent;
    }
    let lo = parent.trailing_zeros() as usize;
    let hi = 63 - parent.leading_zeros() as usize;
    let mut hit = 0u64;
    let (mut a, mut b) = (lo as isize, hi as isize);
    if cfg.culling && fan.sorted {
        let fl = fan.signed(lo, c);
        let fh = fan.signed(hi, c);
        n.outline_tests += if lo == hi { 1 } else { 2 };
        if wedge_misses(fl, fh, bound) {
            n.spheres_culled += 1;
            return 0;
        }
        if fl.abs() <= bound {
            hit |= 1 << lo;
        }
        if fh.abs() <= bound {
            hit |= 1 << hi;
        }
        (a, b) = (lo as isize + 1, hi as isize - 1);
    }
    if a <= b {
        match fan.monotone(lo, hi, c, e).filter(|_| cfg.tree) {
            Some(sign) if cfg.ranges => {
                // Distances `sign·f` decrease with position, so the hit planes are one run: if
                // both outer planes hit, every plane between does; else its ends are found by
                // two binary searches (ours; claiming the whole run only adds reproduced rays,
                // which are tested exactly).
                let both = a > lo as isize && hit >> lo & 1 == 1 && hit >> hi & 1 == 1;
                let run = if both {
                    Some((a, b))
                } else {
                    let sf = |k: isize, n: &mut Counts| {
                        n.internal_tests += 1;
                        sign * fan.signed(k as usize, c)
                    };
                    // First position with `sf <= bound`, then the last with `sf >= -bound`.
                    let (mut x, mut y) = (a, b + 1);
                    while x < y {
                        let m = (x + y) / 2;
                        if sf(m, n) <= bound {
                            y = m;
                        } else {
                            x = m + 1;
                        }
                    }
                    let first = x;
                    let mut y = b + 1;
                    while x < y {
                        let m = (x + y) / 2;
                        if sf(m, n) >= -bound {
                            x = m + 1;
                        } else {
                            y = m;
                        }
                    }
                    (first < x).then_some((first, x - 1))
                };
                if let Some((f, l)) = run {
                    hit |= mask(l as usize + 1) & !mask(f as usize);
                }
            }
            Some(sign) => {
                // Binary-tree order: centre plane first; a miss sends the search one way.
                let mut stack = [(0isize, 0isize); 64];
                let mut top = 1;
                stack[0] = (a, b);
                while top > 0 {
                    top -= 1;
                    let (x, y) = stack[top];
                    if x > y {
                        continue;
                    }
                    let m = (x + y) / 2;
                    let f = sign * fan.signed(m as usize, c);
                    n.internal_tests += 1;
                    if f.abs() <= bound {
                        hit |= 1 << m;
                        stack[top] = (x, m - 1);
                        stack[top + 1] = (m + 1, y);
                        top += 2;
                    } else if f > bound {
                        // Distances decrease with position: every plane before m misses too.
                        stack[top] = (m + 1, y);
                        top += 1;
                    } else {
                        stack[top] = (x, m - 1);
                        top += 1;
                    }
                }
            }
            None => {
                let mut bits = parent & mask(b as usize + 1) & !mask(a as usize);
                while bits != 0 {
                    let k = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    n.internal_tests += 1;
                    if fan.signed(k, c).abs() <= bound {
                        hit |= 1 << k;
                    }
                }
            }
        }
    }
    hit & parent
}

/// Both fans against a sphere (grid-frame centre `c`, radius `r`, margin `e`): the hit rows and
/// columns among `parent`'s, or `None` when either family misses.
#[inline]
fn sphere(
    s: &Scratch,
    c: Vec3,
    r: f32,
    e: f32,
    parent: (u64, u64),
    cfg: &Config,
    n: &mut Counts,
) -> Option<(u64, u64)> {
    // Planes whose rays are all finished (any hit, `live_planes`) test nothing.
    let parent = if cfg.live_planes {
        (parent.0 & s.live.0, parent.1 & s.live.1)
    } else {
        parent
    };
    if parent.0 == 0 || parent.1 == 0 {
        return None;
    }
    n.spheres_visited += 1;
    if let Some(zmax) = s.depth {
        // Grid-frame depth of what the sphere holds, widened by the frame's rounding margin.
        if c.z + r + e < 0.0 || c.z - r - e > zmax {
            n.depth_culled += 1;
            return None;
        }
    }
    let dist = c.length();
    let rb = fan_bound(r, dist, s.rows.slack, e);
    let rm = family(&s.rows, (c.y, c.z), rb, e, parent.0, cfg, n);
    if rm == 0 {
        return None;
    }
    let cb = fan_bound(r, dist, s.cols.slack, e);
    let cm = family(&s.cols, (c.x, c.z), cb, e, parent.1, cfg, n);
    (cm != 0).then_some((rm, cm))
}

/// What the walk of one group reads besides its scratch.
pub(super) struct Walk<'a> {
    pub(super) tree: &'a SphereTree,
    pub(super) cfg: &'a Config,
    pub(super) soup: &'a TriangleSoup,
    pub(super) rays: &'a RayBatch,
    pub(super) g: GroupSpec,
    pub(super) start: usize,
    /// The lane width of the leaves' ray tests.
    pub(super) w: Width,
    /// Reproduced rays go through the common-origin form ([`Walk::rows`]), else one at a time
    /// through the shared test (in [`Walk::leaf`]).
    pub(super) origin_form: bool,
    /// The aligned ray-plane form culls reproduced rays before the common-origin form
    /// (`s.align` is set).
    pub(super) aligned: bool,
}

impl Walk<'_> {
    /// Part `part` (frame `f`) for the rows and columns `pm` its part tree node hit: its sphere,
    /// then its inner spheres and leaves. True when every ray of the group is done (any hit).
    #[allow(clippy::too_many_arguments)]
    fn part(
        &self,
        part: &Part,
        f: &Frame,
        pm: (u64, u64),
        s: &mut Scratch,
        out: &mut Out<'_, '_>,
        mut cost: Option<&mut CostMut<'_>>,
        n: &mut Counts,
        live: &mut usize,
    ) -> bool {
        let (tree, cfg) = (self.tree, self.cfg);
        n.part_tests += 1;
        let Some(pm) = f.sphere(s, part.centre, part.radius, pm, cfg, n) else {
            return false;
        };
        // Closest hits visit nearer spheres first (`near_first`): by the grid depth of the
        // children's centres, and a run of leaves (Morton order) from its nearer end.
        let near = cfg.near_first && matches!(out, Out::Hits(_));
        let depth = |c: Vec3| f.m[2].dot(c);
        let run = |r: std::ops::Range<u32>| {
            let (a, b) = (r.start, r.end);
            let back = near
                && b > a + 1
                && depth(tree.leaf_c[b as usize - 1]) < depth(tree.leaf_c[a as usize]);
            r.map(move |k| if back { a + b - 1 - k } else { k })
        };
        if part.inner.is_empty() {
            for l in run(part.leaves.clone()) {
                self.leaf(l as usize, f, pm, s, out, cost.as_deref_mut(), n, live);
                if *live == 0 {
                    return true;
                }
            }
            return false;
        }
        // Inner spheres depth first, each tested by the planes its parent hit (flat: every top
        // sphere is a bottom one); a fixed stack, deep enough for any binary tree over u32
        // leaves. (Nearer children first measured no faster on the bunny's shadow grids:
        // BENCHMARKS.md § RTRPS.)
        let mut stack = [(0u32, (0u64, 0u64)); MAX_DEPTH + 1];
        for top in tree.top(part) {
            stack[0] = (top, pm);
            let mut sp = 1;
            while sp > 0 {
                sp -= 1;
                let (k, mk) = stack[sp];
                let k = k as usize;
                let Some(km) = f.sphere(s, tree.inner_c[k], tree.inner_r[k], mk, cfg, n) else {
                    continue;
                };
                match tree.inner_kids[k] {
                    [NO_KID, _] => {
                        let [l0, l1] = tree.inner_leaves[k];
                        for l in run(l0..l1) {
                            self.leaf(l as usize, f, km, s, out, cost.as_deref_mut(), n, live);
                        }
                        if *live == 0 {
                            return true;
                        }
                    }
                    [a, b] => {
                        let (a, b) = if near
                            && depth(tree.inner_c[b as usize]) < depth(tree.inner_c[a as usize])
                        {
                            (b, a)
                        } else {
                            (a, b)
                        };
                        stack[sp] = (b, km);
                        stack[sp + 1] = (a, km);
                        sp += 2;
                    }
                }
            }
        }
        false
    }
}

/// Traces group `g` (rays of the chunk starting at `start`) into `out`.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    tree: &SphereTree,
    cfg: &Config,
    soup: &TriangleSoup,
    rays: &RayBatch,
    g: GroupSpec,
    start: usize,
    s: &mut Scratch,
    mut out: Out<'_, '_>,
    mut cost: Option<&mut CostMut<'_>>,
    n: &mut Counts,
) {
    let alone = |out: &mut Out<'_, '_>, cost: &mut Option<&mut CostMut<'_>>, n: &mut Counts| {
        for i in 0..g.rows {
            for j in 0..g.cols {
                let r = g.ray(i, j);
                match out {
                    Out::Hits(h) => {
                        random::closest(tree, soup, rays, r, r - start, h, cost.as_deref_mut(), n)
                    }
                    Out::Occluded(b) => {
                        b[r - start] =
                            random::any(tree, soup, rays, r, r - start, cost.as_deref_mut(), n)
                    }
                }
            }
        }
    };
    let Some((o, frame)) = setup(rays, g, s) else {
        alone(&mut out, &mut cost, n);
        return;
    };
    let cols = g.cols;
    let gd = std::mem::take(&mut s.g);
    s.rows.fit(g.rows, cols, |i, j| {
        let u = gd[i * cols + j];
        (u.y, u.z)
    });
    s.cols.fit(cols, g.rows, |j, i| {
        let u = gd[i * cols + j];
        (u.x, u.z)
    });
    s.g = gd;
    if s.rows.slack.max(s.cols.slack) > cfg.max_slack {
        // Rays far from their planes (hemisphere grids): every plane meets the spheres near the
        // origin, and random rays are faster (BENCHMARKS.md § RTRPS, bounce grids).
        n.slack_groups += 1;
        alone(&mut out, &mut cost, n);
        return;
    }
    n.groups += 1;
    n.group_rays += (g.rows * g.cols) as u64;
    s.depth = if cfg.depth_cull {
        depth_range(rays, g, &s.g)
    } else {
        None
    };
    let r64 = frame.map(|v| v.as_dvec3());
    let o64 = o.as_dvec3();
    let nr = g.rows * cols;
    s.load(rays, g, matches!(out, Out::Hits(_)), cfg.box_check);
    // `auto` never takes the aligned form: it removes half or more of the triangle tests and
    // costs more than they did at every group size measured (BENCHMARKS.md § RTRPS, "The
    // aligned ray-plane form").
    let aligned = cfg.tri_test == TriTest::Aligned;
    s.align = None;
    if aligned {
        s.align(g, frame);
    }
    s.cut = cfg.hit_cut && matches!(out, Out::Hits(_)) && s.depth.is_some();
    if s.cut {
        s.dirty = mask(g.rows);
        s.lower_depth(g.rows, cols);
    }
    // The group's cone about the frame's z: the rays' grid-frame unit directions `s.g` are
    // within a few 1e-7 of the true ones (normalised and rotated in f32), so their least `z`
    // less 1e-6 bounds every true cosine.
    s.cone = if cfg.edge_cull {
        let least = s.g.iter().fold(f32::INFINITY, |m, u| m.min(u.z));
        RayCone::with_cos(frame[2], f64::from(least) - 1e-6)
    } else {
        None
    };
    s.done[..g.rows].fill(0);
    s.col_done[..cols].fill(0);
    s.live = (mask(g.rows), mask(cols));
    for p in 0..g.rows {
        s.pos.0[usize::from(s.rows.order[p])] = p as u8;
    }
    for p in 0..cols {
        s.pos.1[usize::from(s.cols.order[p])] = p as u8;
    }
    let mut live = nr;
    let full = (mask(g.rows), mask(cols));
    let w = Walk {
        tree,
        cfg,
        soup,
        rays,
        g,
        start,
        w: lanes::width(),
        origin_form: match cfg.tri_test {
            TriTest::Origin | TriTest::Aligned => true,
            TriTest::Moller => false,
            TriTest::Auto => nr >= ORIGIN_FORM_RAYS,
        },
        aligned: aligned && s.align.is_some(),
    };
    // The part tree depth first (its root is the scene sphere), world spheres brought into the
    // grid frame; a bottom node's parts each get their own frame. A fixed stack, deep enough for
    // any binary tree over u32 parts.
    let near = cfg.near_first && matches!(out, Out::Hits(_));
    let mut stack = [(0u32, full); MAX_DEPTH + 1];
    let mut sp = usize::from(!tree.parts.is_empty());
    'walk: while sp > 0 {
        sp -= 1;
        let (k, mk) = stack[sp];
        let k = k as usize;
        let (wc, wr) = (tree.pnode_c[k], tree.pnode_r[k]);
        let d = (wc.as_dvec3() - o64).as_vec3();
        let c = Vec3::new(frame[0].dot(d), frame[1].dot(d), frame[2].dot(d));
        let e = 2.0 * SLACK * (wc.abs().max_element() + wr + o.abs().max_element());
        let Some(km) = sphere(s, c, wr, e, mk, cfg, n) else {
            continue;
        };
        match tree.pnode_kids[k] {
            [NO_KID, _] => {
                let [a, b] = tree.pnode_parts[k];
                for &pi in &tree.part_order[a as usize..b as usize] {
                    let part = &tree.parts[pi as usize];
                    let f = Frame::of(part, &r64, o64, o);
                    if w.part(part, &f, km, s, &mut out, cost.as_deref_mut(), n, &mut live) {
                        break 'walk;
                    }
                }
            }
            [x, y] => {
                // Nearer node first for closest hits (`near_first`), by world centres along the
                // grid's axis.
                let (x, y) = if near
                    && frame[2].dot(tree.pnode_c[y as usize])
                        < frame[2].dot(tree.pnode_c[x as usize])
                {
                    (y, x)
                } else {
                    (x, y)
                };
                stack[sp] = (y, km);
                stack[sp + 1] = (x, km);
                sp += 2;
            }
        }
    }
    if let Out::Hits(h) = out {
        for i in 0..g.rows {
            for j in 0..cols {
                let k = i * s.rs + j;
                if s.bp[k] != MISS {
                    let r = g.ray(i, j) - start;
                    (h.t[r], h.prim[r], h.u[r], h.v[r]) = (s.bt[k], s.bp[k], s.bu[k], s.bv[k]);
                }
            }
        }
    }
}
