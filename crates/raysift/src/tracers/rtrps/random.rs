//! Random rays (§4.2, the baseline of Table 5): one ray at a time over the same sphere hierarchy:
//! the part tree's world spheres first, then, for each part reached, the ray brought into the
//! part's local frame once (world-to-local in f64 at update) and tested against the part's,
//! inner and leaf spheres (`geom::sphere_plane::ray_sphere`), near spheres
//! cut by the closest hit so far. A part whose transform cannot be inverted safely is walked
//! without sphere culls (every triangle of it tested).

use super::Counts;
use crate::accel::spheres::{Part, SphereTree, MAX_DEPTH, NO_KID, SLACK};
use crate::geom::intersect_triangle;
use crate::geom::sphere_plane::ray_sphere;
use crate::rays::{RayBatch, MISS};
use crate::scene::TriangleSoup;
use crate::tracer::{closer, CostMut, HitsMut};
use glam::Vec3;

/// The ray in a part's frame, with its sphere-test scales.
struct Local {
    o: Vec3,
    d: Vec3,
    dd: f32,
    dl: f32,
    /// Local radius multiplier (σ·σ⁻¹: 1 for rigid motions).
    k: f32,
    /// Absolute margin.
    e: f32,
}

fn local(p: &Part, o: Vec3, d: Vec3) -> Option<Local> {
    let inv = p.inv?;
    let (ol, dl) = (inv.transform_point3(o), inv.transform_vector3(d));
    let dd = dl.length_squared();
    let world = p.sigma * p.extent
        + Vec3::from(p.xf.translation).abs().max_element()
        + o.abs().max_element();
    let e = 2.0 * SLACK * (p.sigma_inv * world + ol.abs().max_element() + p.extent);
    (dd.is_finite() && dd > 0.0).then(|| Local {
        o: ol,
        d: dl,
        dd,
        dl: dd.sqrt(),
        k: p.sigma * p.sigma_inv,
        e,
    })
}

/// Walks part `p` for the ray, calling `leaf(l, tmax)` on each leaf whose sphere passes; `leaf`
/// returns the new `tmax`, or `None` to stop the whole walk.
#[inline]
#[allow(clippy::too_many_arguments)]
fn walk(
    tree: &SphereTree,
    p: &Part,
    o: Vec3,
    d: Vec3,
    tmin: f32,
    mut tmax: f32,
    n: &mut Counts,
    cost: &mut u64,
    mut leaf: impl FnMut(usize, f32) -> Option<f32>,
) -> Option<f32> {
    let Some(lr) = local(p, o, d) else {
        for l in p.leaves.clone() {
            tmax = leaf(l as usize, tmax)?;
        }
        return Some(tmax);
    };
    let mut test = |c: Vec3, r: f32, tmax: f32, n: &mut Counts| {
        n.ray_sphere += 1;
        *cost += 1;
        ray_sphere(lr.o, lr.d, lr.dd, lr.dl, c, r * lr.k + lr.e, tmin, tmax)
    };
    n.part_tests += 1;
    if !test(p.centre, p.radius, tmax, n) {
        return Some(tmax);
    }
    if p.inner.is_empty() {
        for l in p.leaves.clone() {
            let l = l as usize;
            if test(tree.leaf_c[l], tree.leaf_r[l], tmax, n) {
                tmax = leaf(l, tmax)?;
            }
        }
    } else {
        // Inner spheres depth first (flat: every top sphere is a bottom one); a fixed stack,
        // deep enough for any binary tree over u32 leaves.
        let mut stack = [0u32; MAX_DEPTH + 1];
        for top in tree.top(p) {
            stack[0] = top;
            let mut sp = 1;
            while sp > 0 {
                sp -= 1;
                let k = stack[sp] as usize;
                if !test(tree.inner_c[k], tree.inner_r[k], tmax, n) {
                    continue;
                }
                match tree.inner_kids[k] {
                    [NO_KID, _] => {
                        let [l0, l1] = tree.inner_leaves[k];
                        for l in l0 as usize..l1 as usize {
                            if test(tree.leaf_c[l], tree.leaf_r[l], tmax, n) {
                                tmax = leaf(l, tmax)?;
                            }
                        }
                    }
                    [a, b] => {
                        stack[sp] = b;
                        stack[sp + 1] = a;
                        sp += 2;
                    }
                }
            }
        }
    }
    Some(tmax)
}

/// Walks the part tree for the ray (world spheres, cut by the current `tmax`), calling
/// `part(p, tmax)` on each part of a bottom node it meets; `part` returns the new `tmax`, or
/// `None` to stop the whole walk; `tests` counts the node spheres tested. A direction whose
/// squared length is not a normal f32 tests no node sphere (every part is visited).
#[inline]
#[allow(clippy::too_many_arguments)]
fn parts(
    tree: &SphereTree,
    o: Vec3,
    d: Vec3,
    tmin: f32,
    mut tmax: f32,
    tests: &mut u64,
    mut part: impl FnMut(&Part, f32) -> Option<f32>,
) -> Option<f32> {
    let dd = d.length_squared();
    let cull = dd.is_finite() && dd >= f32::MIN_POSITIVE;
    let dl = dd.sqrt();
    let om = o.abs().max_element();
    let mut stack = [0u32; MAX_DEPTH + 1];
    let mut sp = usize::from(!tree.parts.is_empty());
    while sp > 0 {
        sp -= 1;
        let k = stack[sp] as usize;
        if cull {
            let (c, r) = (tree.pnode_c[k], tree.pnode_r[k]);
            *tests += 1;
            let e = 2.0 * SLACK * (c.abs().max_element() + r + om);
            if !ray_sphere(o, d, dd, dl, c, r + e, tmin, tmax) {
                continue;
            }
        }
        match tree.pnode_kids[k] {
            [NO_KID, _] => {
                let [a, b] = tree.pnode_parts[k];
                for &p in &tree.part_order[a as usize..b as usize] {
                    tmax = part(&tree.parts[p as usize], tmax)?;
                }
            }
            [x, y] => {
                stack[sp] = y;
                stack[sp + 1] = x;
                sp += 2;
            }
        }
    }
    Some(tmax)
}

/// Closest hit of ray `i` (window slot `k`) into `out`.
#[allow(clippy::too_many_arguments)]
pub fn closest(
    tree: &SphereTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    i: usize,
    k: usize,
    out: &mut HitsMut<'_>,
    cost: Option<&mut CostMut<'_>>,
    n: &mut Counts,
) {
    let (o, d, tmin) = (rays.origin(i), rays.dir(i), rays.tmin[i]);
    let (mut bt, mut bp, mut bu, mut bv) = (rays.tmax[i], MISS, 0.0, 0.0);
    n.random_rays += 1;
    let (mut tests, mut tris, mut leaves) = (0u64, 0u64, 0u64);
    let mut node_tests = 0;
    let _ = parts(tree, o, d, tmin, bt, &mut node_tests, |p, tmax| {
        walk(tree, p, o, d, tmin, tmax, n, &mut tests, |l, _| {
            let [t0, t1] = tree.leaf_tris[l];
            leaves += 1;
            for &q in &tree.tris[t0 as usize..t1 as usize] {
                tris += 1;
                let qu = q as usize;
                if let Some(h) =
                    intersect_triangle(o, d, soup.v0[qu], soup.v1[qu], soup.v2[qu], tmin, bt)
                {
                    if closer(h.t, q, bt, bp) {
                        (bt, bp, bu, bv) = (h.t, q, h.u, h.v);
                    }
                }
            }
            Some(bt)
        })
    });
    n.ray_sphere += node_tests;
    tests += node_tests;
    n.tri_tests += tris;
    if bp != MISS {
        (out.t[k], out.prim[k], out.u[k], out.v[k]) = (bt, bp, bu, bv);
    }
    if let Some(c) = cost {
        c.add(k, leaves, tests + tris, tris);
    }
}

/// Any hit of ray `i` (window slot `k`).
#[allow(clippy::too_many_arguments)]
pub fn any(
    tree: &SphereTree,
    soup: &TriangleSoup,
    rays: &RayBatch,
    i: usize,
    k: usize,
    cost: Option<&mut CostMut<'_>>,
    n: &mut Counts,
) -> bool {
    let (o, d, tmin, tmax) = (rays.origin(i), rays.dir(i), rays.tmin[i], rays.tmax[i]);
    n.random_rays += 1;
    let (mut tests, mut tris, mut leaves) = (0u64, 0u64, 0u64);
    let mut node_tests = 0;
    let hit = parts(tree, o, d, tmin, tmax, &mut node_tests, |p, tmax| {
        walk(tree, p, o, d, tmin, tmax, n, &mut tests, |l, tmax| {
            let [t0, t1] = tree.leaf_tris[l];
            leaves += 1;
            for &q in &tree.tris[t0 as usize..t1 as usize] {
                tris += 1;
                let qu = q as usize;
                if intersect_triangle(o, d, soup.v0[qu], soup.v1[qu], soup.v2[qu], tmin, tmax)
                    .is_some()
                {
                    return None;
                }
            }
            Some(tmax)
        })
    })
    .is_none();
    n.ray_sphere += node_tests;
    tests += node_tests;
    n.tri_tests += tris;
    if let Some(c) = cost {
        c.add(k, leaves, tests + tris, tris);
    }
    hit
}
