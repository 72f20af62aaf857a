//! One ray group as ray-planes (§2.2–2.3, Algorithm 2, §3.1): the grid frame and its row and
//! column fans, the sphere walk (part tree → parts → inner → leaves) with each sphere tested by the
//! planes its parent hit, and the rays reproduced at leaves (a hit row × a hit column), each
//! tested against the leaf's triangles with the shared triangle test.

use super::{random, Config, Counts};
use crate::accel::spheres::{Part, SphereTree, MAX_DEPTH, NO_KID, SLACK};
use crate::geom::intersect_triangle;
use crate::geom::sphere_plane::{fan_bound, wedge_misses, PlaneFan, MAX_FAN};
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::{closer, CostMut, HitsMut};
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
    fn ray(&self, i: usize, j: usize) -> usize {
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
struct Frame {
    m: [Vec3; 3],
    b: Vec3,
    sigma: f32,
    e: f32,
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
    fn apply(&self, p: Vec3) -> Vec3 {
        Vec3::new(self.m[0].dot(p), self.m[1].dot(p), self.m[2].dot(p)) + self.b
    }

    /// [`sphere`] for a sphere of the part (local centre `c`, local radius `r`).
    #[inline]
    fn sphere(
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
    g: Vec<Vec3>,
    bt: Vec<f32>,
    bp: Vec<u32>,
    bu: Vec<f32>,
    bv: Vec<f32>,
    done: [u64; MAX_FAN],
    rows: PlaneFan,
    cols: PlaneFan,
    /// Depth cull of the current group: every ray has `tmin >= 0` and a direction `u.z > 0` in
    /// the grid frame, so every point a ray can report lies in `0 <= z <= zmax`.
    depth: Option<f32>,
}

impl Scratch {
    /// Empty buffers (grown on first use).
    pub fn new() -> Self {
        Self {
            g: Vec::new(),
            bt: Vec::new(),
            bp: Vec::new(),
            bu: Vec::new(),
            bv: Vec::new(),
            done: [0; MAX_FAN],
            rows: PlaneFan::default(),
            cols: PlaneFan::default(),
            depth: None,
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.g.capacity() * 12
            + (self.bt.capacity() + self.bp.capacity() + self.bu.capacity() + self.bv.capacity())
                * 4
            + std::mem::size_of::<Self>()
    }
}

fn mask(n: usize) -> u64 {
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
            if rays.origin(r) != o {
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
struct Walk<'a> {
    tree: &'a SphereTree,
    cfg: &'a Config,
    soup: &'a TriangleSoup,
    rays: &'a RayBatch,
    g: GroupSpec,
    start: usize,
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
        if part.inner.is_empty() {
            for l in part.leaves.clone() {
                self.leaf(l as usize, f, pm, s, out, cost.as_deref_mut(), n, live);
                if *live == 0 {
                    return true;
                }
            }
            return false;
        }
        // Inner spheres depth first, each tested by the planes its parent hit (flat: every top
        // sphere is a bottom one); a fixed stack, deep enough for any binary tree over u32
        // leaves.
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
                        for l in l0..l1 {
                            self.leaf(l as usize, f, km, s, out, cost.as_deref_mut(), n, live);
                        }
                        if *live == 0 {
                            return true;
                        }
                    }
                    [a, b] => {
                        stack[sp] = (b, km);
                        stack[sp + 1] = (a, km);
                        sp += 2;
                    }
                }
            }
        }
        false
    }

    /// Leaf `l`: its sphere against the planes `pm`, then each reproduced ray (a hit row × a hit
    /// column) against its triangles with the shared test.
    #[allow(clippy::too_many_arguments)]
    fn leaf(
        &self,
        l: usize,
        f: &Frame,
        pm: (u64, u64),
        s: &mut Scratch,
        out: &mut Out<'_, '_>,
        mut cost: Option<&mut CostMut<'_>>,
        n: &mut Counts,
        live: &mut usize,
    ) {
        let (tree, g, rays, soup, start) = (self.tree, self.g, self.rays, self.soup, self.start);
        let Some((rm, cm)) = f.sphere(s, tree.leaf_c[l], tree.leaf_r[l], pm, self.cfg, n) else {
            return;
        };
        // The per-ray check (`ray_check`): a reproduced ray whose line passes farther from the
        // leaf's centre than its radius cannot report a hit there. In the grid frame every ray
        // leaves the origin with unit direction `s.g[k]`; the frame is orthonormal to a few
        // 1e-7 and the centre off by at most `f.e`, so the radius is widened by `f.e` and 1e-5
        // relative of the centre's distance and of the radius.
        let check = self.cfg.ray_check.then(|| {
            let c = f.apply(tree.leaf_c[l]);
            let r = (tree.leaf_r[l] * f.sigma + f.e) * (1.0 + 1e-5) + c.length() * 1e-5;
            (c, r * r)
        });
        let cols = g.cols;
        let [t0, t1] = tree.leaf_tris[l];
        let ids = &tree.tris[t0 as usize..t1 as usize];
        let mut rbits = rm;
        while rbits != 0 {
            let a = rbits.trailing_zeros() as usize;
            rbits &= rbits - 1;
            let i = s.rows.order[a] as usize;
            let mut cbits = cm;
            while cbits != 0 {
                let b = cbits.trailing_zeros() as usize;
                cbits &= cbits - 1;
                let j = s.cols.order[b] as usize;
                if s.done[i] >> j & 1 == 1 {
                    continue;
                }
                let r = g.ray(i, j);
                let k = i * cols + j;
                n.rays_reproduced += 1;
                if let Some((c, r2)) = check {
                    if c.cross(s.g[k]).length_squared() > r2 {
                        n.ray_culled += 1;
                        continue;
                    }
                }
                let (ro, rd, tmin) = (rays.origin(r), rays.dir(r), rays.tmin[r]);
                n.tri_tests += ids.len() as u64;
                if let Some(c) = cost.as_deref_mut() {
                    c.add(r - start, 1, ids.len() as u64, ids.len() as u64);
                }
                match out {
                    Out::Hits(_) => {
                        for &p in ids {
                            let pu = p as usize;
                            if let Some(h) = intersect_triangle(
                                ro,
                                rd,
                                soup.v0[pu],
                                soup.v1[pu],
                                soup.v2[pu],
                                tmin,
                                s.bt[k],
                            ) {
                                if closer(h.t, p, s.bt[k], s.bp[k]) {
                                    (s.bt[k], s.bp[k], s.bu[k], s.bv[k]) = (h.t, p, h.u, h.v);
                                }
                            }
                        }
                    }
                    Out::Occluded(o) => {
                        let tmax = rays.tmax[r];
                        for &p in ids {
                            let pu = p as usize;
                            if intersect_triangle(
                                ro,
                                rd,
                                soup.v0[pu],
                                soup.v1[pu],
                                soup.v2[pu],
                                tmin,
                                tmax,
                            )
                            .is_some()
                            {
                                o[r - start] = true;
                                s.done[i] |= 1 << j;
                                *live -= 1;
                                break;
                            }
                        }
                    }
                }
            }
        }
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
    let closest = matches!(out, Out::Hits(_));
    if closest {
        s.bt.clear();
        s.bp.clear();
        s.bu.clear();
        s.bv.clear();
        for i in 0..g.rows {
            for j in 0..cols {
                s.bt.push(rays.tmax[g.ray(i, j)]);
            }
        }
        s.bp.resize(nr, MISS);
        s.bu.resize(nr, 0.0);
        s.bv.resize(nr, 0.0);
    }
    s.done[..g.rows].fill(0);
    let mut live = nr;
    let full = (mask(g.rows), mask(cols));
    let w = Walk {
        tree,
        cfg,
        soup,
        rays,
        g,
        start,
    };
    // The part tree depth first (its root is the scene sphere), world spheres brought into the
    // grid frame; a bottom node's parts each get their own frame. A fixed stack, deep enough for
    // any binary tree over u32 parts.
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
                stack[sp] = (y, km);
                stack[sp + 1] = (x, km);
                sp += 2;
            }
        }
    }
    if let Out::Hits(h) = out {
        for i in 0..g.rows {
            for j in 0..cols {
                let k = i * cols + j;
                if s.bp[k] != MISS {
                    let r = g.ray(i, j) - start;
                    (h.t[r], h.prim[r], h.u[r], h.v[r]) = (s.bt[k], s.bp[k], s.bu[k], s.bv[k]);
                }
            }
        }
    }
}
