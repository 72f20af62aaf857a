//! A leaf of one ray group's walk (§2.3, §3.2): the leaf sphere's plane tests, the edge cull,
//! and the rays it reproduces (a hit row × a hit column) against its triangles, one at a time
//! through the shared test or a row's vector of rays at a time through its common-origin form.

use super::group::{Frame, Out, Scratch, Walk, EDGE_CULL_RAYS};
use super::Counts;
use crate::geom::aligned::{AlignedTri, ALL, NONE};
use crate::geom::lanes::{Lanes, Width};
use crate::geom::{intersect_triangle, slab_lanes, TriFromOrigin};
use crate::tracer::{closer, CostMut};
use glam::{Vec3, Vec4};

impl Walk<'_> {
    /// Leaf `l`: its sphere against the planes `pm`, then the rays it reproduces (a hit row × a
    /// hit column) against its triangles, a row's columns `L::N` at a time ([`Self::rows`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn leaf(
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
        let tree = self.tree;
        let Some((rm, cm)) = f.sphere(s, tree.leaf_c[l], tree.leaf_r[l], pm, self.cfg, n) else {
            return;
        };
        // The hit columns by column index (the fan's bits are plane positions).
        let mut cols = 0u64;
        let mut bits = cm;
        while bits != 0 {
            cols |= 1 << s.cols.order[bits.trailing_zeros() as usize];
            bits &= bits - 1;
        }
        // The edge cull (`edge_cull`): a leaf that would reproduce many rays is first tested
        // against the group's whole cone of directions; when the shared test provably refuses
        // every ray of the cone for each of its triangles, nothing is reproduced.
        if let Some(cone) = s.cone {
            let many = rm.count_ones() * cols.count_ones() >= EDGE_CULL_RAYS;
            let [t0, t1] = tree.leaf_tris[l];
            let (soup, o) = (self.soup, self.rays.origin(self.g.base));
            if many
                && tree.tris[t0 as usize..t1 as usize].iter().all(|&p| {
                    let p = p as usize;
                    cone.misses(o, soup.v0[p], soup.v1[p], soup.v2[p])
                })
            {
                n.edge_culled += 1;
                return;
            }
        }
        // The per-ray check (`ray_check`): a reproduced ray whose line passes farther from the
        // leaf's centre than its radius cannot report a hit there. In the grid frame every ray
        // leaves the origin with unit direction `g`; the frame is orthonormal to a few 1e-7 and
        // the centre off by at most `f.e`, so the radius is widened by `f.e` and 1e-5 relative
        // of the centre's distance and of the radius (which also covers the rounding of
        // `|c × g|²` in any order of evaluation).
        let closest = matches!(out, Out::Hits(_));
        let sph = (self.cfg.ray_check || self.cfg.hit_cut && closest).then(|| {
            let c = f.apply(tree.leaf_c[l]);
            let r = (tree.leaf_r[l] * f.sigma + f.e) * (1.0 + 1e-5) + c.length() * 1e-5;
            (c, r)
        });
        let check = sph.filter(|_| self.cfg.ray_check).map(|(c, r)| (c, r * r));
        // The hit cut (`hit_cut`, closest hits): a hit at `t` is a point `t·|d|·g` of the sphere
        // (`g` the ray's grid-frame unit direction), so `t·|d| >= g·c − r` whatever the sign of
        // `t`; a ray whose closest hit so far is nearer than that has nothing to gain here. The
        // radius is widened by 2e-5 of the centre's distance more (the f32 dot product and
        // `g`'s rounding), the hit's `t·|d|` by 1e-5 relative.
        let near = sph
            .filter(|_| self.cfg.hit_cut && closest)
            .map(|(c, r)| (c, r + c.length() * 2e-5));
        s.tris.clear();
        s.atris.clear();
        let leaf = Leaf {
            rm,
            cols,
            check,
            near,
            tris: tree.leaf_tris[l],
        };
        if !self.origin_form {
            // One reproduced ray at a time through the shared test (Table 2's "Möller" row:
            // nothing is prepared per leaf, which pays for small groups, BENCHMARKS.md § RTRPS;
            // the box check does not apply here).
            let (g, rays, soup, start) = (self.g, self.rays, self.soup, self.start);
            let ids = &self.tree.tris[leaf.tris[0] as usize..leaf.tris[1] as usize];
            let mut rbits = leaf.rm;
            while rbits != 0 {
                let i = s.rows.order[rbits.trailing_zeros() as usize] as usize;
                rbits &= rbits - 1;
                let mut cbits = leaf.cols & !s.done[i];
                while cbits != 0 {
                    let j = cbits.trailing_zeros() as usize;
                    cbits &= cbits - 1;
                    let (r, k, x) = (g.ray(i, j), i * g.cols + j, i * s.rs + j);
                    n.rays_reproduced += 1;
                    if let Some((c, r2)) = leaf.check {
                        if c.cross(s.g[k]).length_squared() > r2 {
                            n.ray_culled += 1;
                            continue;
                        }
                    }
                    if let Some((c, r)) = leaf.near {
                        let b = s.bt[x] * s.dl[x];
                        if c.dot(s.g[k]) - r > b + b.abs() * 1e-5 {
                            n.hit_culled += 1;
                            continue;
                        }
                    }
                    let (ro, rd, tmin) = (rays.origin(r), rays.dir(r), rays.tmin[r]);
                    n.tri_tests += ids.len() as u64;
                    if let Some(c) = cost.as_deref_mut() {
                        c.add(r - start, 1, ids.len() as u64, ids.len() as u64);
                    }
                    for &p in ids {
                        let pu = p as usize;
                        let (v0, v1, v2) = (soup.v0[pu], soup.v1[pu], soup.v2[pu]);
                        match out {
                            Out::Hits(_) => {
                                if let Some(h) =
                                    intersect_triangle(ro, rd, v0, v1, v2, tmin, s.bt[x])
                                {
                                    if closer(h.t, p, s.bt[x], s.bp[x]) {
                                        s.dirty |= 1 << i;
                                        (s.bt[x], s.bp[x], s.bu[x], s.bv[x]) = (h.t, p, h.u, h.v);
                                    }
                                }
                            }
                            Out::Occluded(o) => {
                                if intersect_triangle(ro, rd, v0, v1, v2, tmin, rays.tmax[r])
                                    .is_some()
                                {
                                    o[r - start] = true;
                                    s.finish(i, 1 << j, g.rows, g.cols);
                                    *live -= 1;
                                    break;
                                }
                            }
                        }
                    }
                }
            }
        } else {
            match self.w {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: `rows_avx2` needs AVX2 and POPCNT; `width()` is `Eight` only on CPUs
                // that have both.
                Width::Eight => unsafe { self.rows_avx2(&leaf, s, out, cost, n, live) },
                _ => self.rows::<Vec4>(&leaf, s, out, cost, n, live),
            }
        }
        // The far bounds follow the closest hits (`hit_cut`).
        if s.cut && s.dirty != 0 {
            s.lower_depth(self.g.rows, self.g.cols);
            n.depth_lowered += 1;
        }
    }

    /// [`Self::rows`] four lanes at a time, compiled for AVX2 and POPCNT (VEX encoding; lane
    /// masks are counted). Eight lanes ([`crate::geom::lanes::F32x8`]) measured 1.25× slower
    /// on the bunny's area-light shadow grids: a row chunk's live lanes are few, and LLVM
    /// keeps the eight-lane test's operands on the stack (BENCHMARKS.md § RTRPS, "Closest
    /// hits cut the walk").
    ///
    /// # Safety
    /// The CPU must support AVX2 and POPCNT ([`lanes::width`] is [`Width::Eight`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,popcnt")]
    unsafe fn rows_avx2(
        &self,
        leaf: &Leaf,
        s: &mut Scratch,
        out: &mut Out<'_, '_>,
        cost: Option<&mut CostMut<'_>>,
        n: &mut Counts,
        live: &mut usize,
    ) {
        self.rows::<Vec4>(leaf, s, out, cost, n, live)
    }

    /// A leaf's reproduced rays, row by row and `L::N` columns at a time: the per-ray check,
    /// then each triangle of the leaf through the common-origin form of the shared test
    /// ([`TriFromOrigin`], §3.2's "common origin" row of Table 2: bit-identical to
    /// [`crate::geom::intersect_triangle`], so it is exact), built once per leaf visit and only
    /// when a ray survives the check.
    #[inline(always)]
    fn rows<L: Lanes>(
        &self,
        leaf: &Leaf,
        s: &mut Scratch,
        out: &mut Out<'_, '_>,
        mut cost: Option<&mut CostMut<'_>>,
        n: &mut Counts,
        live: &mut usize,
    ) {
        let (g, soup, start) = (self.g, self.soup, self.start);
        let ids = &self.tree.tris[leaf.tris[0] as usize..leaf.tris[1] as usize];
        let ld = |v: &[f32], at: usize| {
            let v = &v[at..at + L::N];
            L::from_fn(|k| v[k])
        };
        let lane_bits = (1u64 << L::N) - 1;
        let o = self.rays.origin(g.base);
        let mut bounds: Option<([f32; 3], [f32; 3])> = None;
        // The aligned form (`self.aligned`): each triangle's span of `a_x` on the current row,
        // and each triangle's lanes in the current chunk (all lanes without it).
        let nt = ids.len();
        let spanned = self.aligned && nt <= MAX_SPANS;
        let mut spans = [ALL; MAX_SPANS];
        let mut tm = [u32::MAX; MAX_SPANS];
        let mut rbits = leaf.rm;
        while rbits != 0 {
            let a = rbits.trailing_zeros() as usize;
            rbits &= rbits - 1;
            let i = s.rows.order[a] as usize;
            let want = leaf.cols & !s.done[i];
            // The row's spans, made when a first chunk of it passes the checks below; `None`
            // once they refuse the whole row.
            let mut row_spans = Some(false);
            for ch in (0..g.cols).step_by(L::N) {
                let bits = (want >> ch & lane_bits) as u32;
                if bits == 0 {
                    continue;
                }
                let at = i * s.rs + ch;
                n.rays_reproduced += u64::from(bits.count_ones());
                let mut keep = bits;
                if let Some((c, r2)) = leaf.check {
                    let (gx, gy, gz) = (ld(&s.gx, at), ld(&s.gy, at), ld(&s.gz, at));
                    let (cx, cy, cz) = (L::splat(c.x), L::splat(c.y), L::splat(c.z));
                    let x = cy * gz - cz * gy;
                    let y = cz * gx - cx * gz;
                    let z = cx * gy - cy * gx;
                    keep &= L::bitmask((x * x + y * y + z * z).cmple(L::splat(r2)));
                    n.ray_culled += u64::from((bits & !keep).count_ones());
                    if keep == 0 {
                        continue;
                    }
                }
                if let Some((c, r)) = leaf.near {
                    let (gx, gy, gz) = (ld(&s.gx, at), ld(&s.gy, at), ld(&s.gz, at));
                    let along = gx * L::splat(c.x) + gy * L::splat(c.y) + gz * L::splat(c.z);
                    let b = ld(&s.bt, at) * ld(&s.dl, at);
                    let lim = b + b.abs() * L::splat(1e-5);
                    let before = keep;
                    keep &= L::bitmask((along - L::splat(r)).cmple(lim));
                    n.hit_culled += u64::from((before & !keep).count_ones());
                    if keep == 0 {
                        continue;
                    }
                }
                if spanned {
                    // The paper's second stage (per row plane), made a cull: the interval of
                    // the row's `a_x` outside which the shared test refuses (`geom::aligned`).
                    if row_spans == Some(false) {
                        if s.atris.is_empty() {
                            let grid = s.align.expect("aligned walks have a fit");
                            s.atris.extend(ids.iter().map(|&p| {
                                let p = p as usize;
                                AlignedTri::new(&grid, o, soup.v0[p], soup.v1[p], soup.v2[p])
                            }));
                        }
                        let row = s.arows[i];
                        let mut none = true;
                        for (sp, t) in spans.iter_mut().zip(&s.atris) {
                            *sp = t.span(&row);
                            none &= *sp == NONE;
                        }
                        n.spans += nt as u64;
                        row_spans = if none { None } else { Some(true) };
                    }
                    if row_spans.is_none() {
                        n.span_culled += u64::from(keep.count_ones());
                        continue;
                    }
                    // The third stage: a ray's `a_x` against each span.
                    let (ax, before) = (ld(&s.ax, at), keep);
                    let mut any = 0;
                    for (m, sp) in tm.iter_mut().zip(&spans[..nt]) {
                        *m = L::bitmask(ax.cmpge(L::splat(sp.0)) & ax.cmple(L::splat(sp.1)));
                        any |= *m;
                    }
                    keep &= any;
                    n.span_culled += u64::from((before & !keep).count_ones());
                    if keep == 0 {
                        continue;
                    }
                }
                let d = [ld(&s.dx, at), ld(&s.dy, at), ld(&s.dz, at)];
                let tmin = ld(&s.tmin, at);
                if self.cfg.box_check {
                    // The leaf's triangles' box less the origin, built with the prepared
                    // triangles when a first lane needs them.
                    let (lo, hi) = match bounds {
                        Some(b) => b,
                        None => {
                            let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                            for &p in ids {
                                let p = p as usize;
                                lo = lo.min(soup.v0[p]).min(soup.v1[p]).min(soup.v2[p]);
                                hi = hi.max(soup.v0[p]).max(soup.v1[p]).max(soup.v2[p]);
                            }
                            let b = ((lo - o).to_array(), (hi - o).to_array());
                            bounds = Some(b);
                            b
                        }
                    };
                    // The shared slab interval of the triangles' box: a lane whose interval is
                    // empty or outside `[tmin, tmax]` (the closest hit so far) has no hit here.
                    let inv = [ld(&s.ix, at), ld(&s.iy, at), ld(&s.iz, at)];
                    let (enter, exit) = slab_lanes(d, inv, lo.map(L::splat), hi.map(L::splat));
                    let far = match out {
                        Out::Hits(_) => ld(&s.bt, at),
                        Out::Occluded(_) => ld(&s.tmax, at),
                    };
                    let ok = enter.cmple(exit) & enter.cmple(far) & exit.cmpge(tmin);
                    let before = keep;
                    keep &= L::bitmask(ok);
                    n.box_culled += u64::from((before & !keep).count_ones());
                    if keep == 0 {
                        continue;
                    }
                }
                if s.tris.is_empty() {
                    let dlow = s.dlow;
                    s.tris.extend(ids.iter().map(|&p| {
                        let p = p as usize;
                        TriFromOrigin::new(o, soup.v0[p], soup.v1[p], soup.v2[p], dlow)
                    }));
                }
                // Each lane's tests: the triangles whose span holds it.
                let tests = |k: usize| {
                    if spanned {
                        tm[..nt].iter().filter(|&&m| m >> k & 1 == 1).count() as u64
                    } else {
                        nt as u64
                    }
                };
                let mut m = keep;
                while m != 0 {
                    let k = m.trailing_zeros() as usize;
                    m &= m - 1;
                    n.tri_tests += tests(k);
                    if let Some(c) = cost.as_deref_mut() {
                        c.add(g.ray(i, ch + k) - start, 1, tests(k), tests(k));
                    }
                }
                match out {
                    Out::Hits(_) => {
                        let mut bt = ld(&s.bt, at);
                        for (q, tri) in s.tris.iter().enumerate() {
                            let lanes = keep & tm[q.min(MAX_SPANS - 1)];
                            if lanes == 0 {
                                continue;
                            }
                            let h = tri.intersect_lanes_each(d, tmin, bt);
                            let mut m = h.mask & lanes;
                            if m == 0 {
                                continue;
                            }
                            let p = ids[q];
                            while m != 0 {
                                let k = m.trailing_zeros() as usize;
                                m &= m - 1;
                                let x = at + k;
                                let t = h.t.lane(k);
                                if closer(t, p, s.bt[x], s.bp[x]) {
                                    s.dirty |= 1 << i;
                                    (s.bt[x], s.bp[x], s.bu[x], s.bv[x]) =
                                        (t, p, h.u.lane(k), h.v.lane(k));
                                }
                            }
                            bt = ld(&s.bt, at);
                        }
                    }
                    Out::Occluded(oc) => {
                        let tmax = ld(&s.tmax, at);
                        let mut fin = 0u32;
                        for (q, tri) in s.tris.iter().enumerate() {
                            let lanes = keep & tm[q.min(MAX_SPANS - 1)];
                            if lanes == 0 {
                                continue;
                            }
                            let m = tri.intersect_lanes_each(d, tmin, tmax).mask & lanes;
                            if m == 0 {
                                continue;
                            }
                            let mut b = m;
                            while b != 0 {
                                let k = b.trailing_zeros() as usize;
                                b &= b - 1;
                                oc[g.ray(i, ch + k) - start] = true;
                            }
                            fin |= m;
                            *live -= m.count_ones() as usize;
                            keep &= !m;
                            if keep == 0 {
                                break;
                            }
                        }
                        if fin != 0 {
                            s.finish(i, u64::from(fin) << ch, g.rows, g.cols);
                        }
                    }
                }
            }
        }
    }
}

/// Leaves of more triangles than this skip the aligned form (`leaf_size` is at most 64).
const MAX_SPANS: usize = 64;

/// What [`Walk::rows`] needs of a leaf that passed its sphere test.
pub(super) struct Leaf {
    /// Hit rows (plane positions).
    pub(super) rm: u64,
    /// Hit columns (column indices).
    pub(super) cols: u64,
    /// Grid-frame centre and squared radius for the per-ray sphere check.
    pub(super) check: Option<(Vec3, f32)>,
    /// Grid-frame centre and widened radius for the hit cut (closest hits).
    pub(super) near: Option<(Vec3, f32)>,
    /// The leaf's range in the tree's triangle order.
    pub(super) tris: [u32; 2],
}
