//! The aligned ray-plane form (Suzuki et al. 2010, §3.2.3, Eqs. 7–8'), made exact as a cull.
//!
//! **The paper's form.** Rays from one origin shot through a grid at distance 1 along the grid
//! frame's `v_z` have directions `a_x·v_x + a_y·v_y + v_z`, and the triangle test's three
//! numbers before the division (`det`, `u·det`, `v·det`) are linear in the direction
//! ([`EdgeForms`]): `F(d) = a_x·(v_x·F) + a_y·(v_y·F) + v_z·F`. The last term is known once the
//! origin is (per triangle), the second once the row is (a row plane shares `a_y`), and a ray
//! then costs one multiply-add per number (Table 2's 71 / 6 / 6 flops).
//!
//! **Why only a cull here.** Our rays are not exactly on a grid and the contract is the shared
//! test's answer bit for bit, which this arithmetic does not reproduce. So the form is used to
//! prove refusals, and what it cannot refuse goes through the shared test:
//! - each ray of a group is written `d/|d| = g_z·(a_x·v_x + a_y·v_y + v_z) + r` with its own
//!   `a_x = g_x/g_z`, `a_y = g_y/g_z` (f32, from its grid-frame unit direction `g`) and the
//!   residual `r` measured in f64 ([`AlignedGroup`]: the group keeps the largest `|r|`, which
//!   covers the frame's rounding and its distance from orthonormal);
//! - a row keeps the midpoint `y` and half-spread `δ` of its rays' `a_y` ([`AlignedRow`]);
//! - per triangle and row, each refusal condition of [`EdgeForms::refusals`] (`u < 0`, `v < 0`,
//!   `u + v > 1`, once `det`'s sign is proven on the whole row) is a half-line of `a_x`, after
//!   bounding `a_y`'s spread by `δ·|v_y·F|`, the residual by `|r|·|F|`, and the positive factor
//!   `g_z` by the group's least; the rays outside the intersection of the three kept half-lines
//!   are refused ([`AlignedTri::span`]): two comparisons per ray instead of a test.
//!
//! The bounds are those [`super::RayCone`] uses, so the same proof holds ray by ray; the test
//! `spans_only_refuse_rays_the_test_refuses` checks it on grids around and across triangles.

use super::ray_cone::EdgeForms;
use glam::{DVec3, Vec3};

/// A group's frame and the largest residual of its rays' grid decomposition.
#[derive(Clone, Copy, Debug)]
pub struct AlignedGroup {
    v: [DVec3; 3],
    /// Largest `|d/|d| − g_z·(a_x·v_x + a_y·v_y + v_z)|` over the rays, widened.
    eps: f64,
    /// Least `g_z` over the rays (at least 0.5).
    gz: f64,
}

/// One row of a group: the midpoint and half-spread of its rays' `a_y`, and the range of their
/// `a_x`.
#[derive(Clone, Copy, Debug)]
pub struct AlignedRow {
    y: f64,
    dy: f64,
    x: [f64; 2],
}

/// Accumulates a group's decomposition ray by ray ([`AlignedGroup::add`]).
#[derive(Clone, Copy, Debug)]
pub struct AlignedFit {
    v: [DVec3; 3],
    eps: f64,
    gz: f64,
    ok: bool,
}

/// A ray's grid coordinates `(a_x, a_y)` (f32, as the cull compares them).
pub type GridPoint = (f32, f32);

impl AlignedFit {
    /// A fit in the frame `(v_x, v_y, v_z)`.
    pub fn new(frame: [Vec3; 3]) -> Self {
        Self {
            v: frame.map(|v| v.as_dvec3()),
            eps: 0.0,
            gz: f64::INFINITY,
            ok: true,
        }
    }

    /// Ray direction `d` with its grid-frame unit direction `g`: its grid point, measured into
    /// the fit. A direction more than 60° from `v_z` (`g_z < 0.5`) or not finite spoils the
    /// fit ([`Self::done`] is then `None`); it still gets a finite point.
    pub fn add(&mut self, d: Vec3, g: Vec3) -> GridPoint {
        if !(g.z >= 0.5 && d.is_finite() && g.is_finite()) {
            self.ok = false;
            return (0.0, 0.0);
        }
        let (ax, ay) = (g.x / g.z, g.y / g.z);
        let d = d.as_dvec3();
        let unit = d / d.length();
        let rebuilt = (self.v[0] * ax as f64 + self.v[1] * ay as f64 + self.v[2]) * g.z as f64;
        self.eps = self.eps.max((unit - rebuilt).length());
        self.gz = self.gz.min(g.z as f64);
        (ax, ay)
    }

    /// The group, unless a ray spoiled it.
    pub fn done(&self) -> Option<AlignedGroup> {
        (self.ok && self.eps.is_finite() && self.gz >= 0.5).then_some(AlignedGroup {
            v: self.v,
            // f64 rounding of the residuals and of the forms' projections, with room.
            eps: self.eps * (1.0 + 1e-6) + 1e-12,
            gz: self.gz,
        })
    }
}

impl AlignedRow {
    /// The row of the grid points `pts` (at least one).
    pub fn of(pts: impl Iterator<Item = GridPoint>) -> Self {
        let (mut x, mut y) = (
            [f64::INFINITY, f64::NEG_INFINITY],
            [f64::INFINITY, f64::NEG_INFINITY],
        );
        for (a, b) in pts {
            x = [x[0].min(a as f64), x[1].max(a as f64)];
            y = [y[0].min(b as f64), y[1].max(b as f64)];
        }
        let mid = 0.5 * (y[0] + y[1]);
        Self {
            y: mid,
            // The midpoint's rounding, with room.
            dy: (y[1] - mid).max(mid - y[0]) + 1e-12 * (y[0].abs() + y[1].abs()),
            x,
        }
    }
}

/// One triangle's forms projected on a group's frame (the paper's first stage, per triangle).
#[derive(Clone, Copy, Debug)]
pub struct AlignedTri {
    /// `(v_x·F, v_y·F, v_z·F)` of `det`, `u·det`, `v·det` and `det − u·det − v·det`
    /// ([`EdgeForms::refusals`] with sign +1).
    h: [[f64; 3]; 4],
    /// Their bounds `(c + eps·|F|)/g_z` (`g_z` the group's least).
    c: [f64; 4],
    /// `1/(v_x·F)` of the three refusal forms (the spans' quotients as products).
    inv: [f64; 3],
}

/// A span that keeps every ray.
pub const ALL: (f32, f32) = (f32::NEG_INFINITY, f32::INFINITY);
/// A span that keeps none.
pub const NONE: (f32, f32) = (f32::INFINITY, f32::NEG_INFINITY);

impl AlignedTri {
    /// Triangle `(v0, v1, v2)` for the group's rays from `origin`.
    pub fn new(g: &AlignedGroup, origin: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        let f = EdgeForms::new(origin, v0, v1, v2).refusals(1.0);
        let v = &g.v;
        let h = f.map(|(a, _)| [v[0].dot(a), v[1].dot(a), v[2].dot(a)]);
        Self {
            h,
            // `|F|₁ ≥ |F|`, and the f64 rounding of the projections.
            c: f.map(|(a, c)| (c + (g.eps + 1e-12) * a.abs().element_sum()) / g.gz),
            inv: [1, 2, 3].map(|k| 1.0 / h[k][0]),
        }
    }

    /// The `a_x` interval `[lo, hi]` of row `row` outside which the shared test refuses every
    /// ray of the row ([`ALL`] when `det`'s sign is not proven on the whole row, [`NONE`] when
    /// every ray is refused). The bounds are rounded outwards to f32.
    pub fn span(&self, row: &AlignedRow) -> (f32, f32) {
        // `F(d)/g_z` over the row's rays lies within `a_x·h_x + y·h_y + h_z ± δ·|h_y|`, give or
        // take the residual's `eps·|F|/g_z` (in `c`); `det` must clear its bound with one sign
        // at both ends of the row (it is linear in `a_x`).
        let at = |h: &[f64; 3], x: f64| x * h[0] + row.y * h[1] + h[2];
        let (hd, need) = (&self.h[0], self.c[0] + row.dy * self.h[0][1].abs());
        let (d0, d1) = (at(hd, row.x[0]), at(hd, row.x[1]));
        let sign = if d0 > need && d1 > need {
            1.0
        } else if -d0 > need && -d1 > need {
            -1.0
        } else {
            return ALL;
        };
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for ((h, c), inv) in self.h[1..].iter().zip(&self.c[1..]).zip(&self.inv) {
            // The refusal form is `sign·F`: refused where `a_x·sign·h_x < k`, every value of
            // the row's rays then being below `−c`.
            let k = -c - sign * (row.y * h[1] + h[2]) - row.dy * h[1].abs();
            let hx = sign * h[0];
            if hx > 0.0 {
                lo = lo.max(k * sign * inv);
            } else if hx < 0.0 {
                hi = hi.min(k * sign * inv);
            } else if k > 0.0 {
                return NONE;
            }
        }
        if lo.is_nan() || hi.is_nan() {
            return ALL;
        }
        if lo > hi {
            return NONE;
        }
        // The quotients' f64 rounding (a reciprocal, then a product), then outwards to f32.
        let lo = lo - 1e-12 * lo.abs();
        let hi = hi + 1e-12 * hi.abs();
        let (mut l, mut h) = (lo as f32, hi as f32);
        if l as f64 > lo {
            l = l.next_down();
        }
        if (h as f64) < hi {
            h = h.next_up();
        }
        (l, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::intersect_triangle;
    use rand::{Rng, SeedableRng};

    /// A grid of `n`×`n` rays from `o` around `axis` (half-width `w` on the grid at distance 1),
    /// jittered by `jit` of a cell and scaled by random lengths, with its fitted frame.
    fn grid(
        rng: &mut rand_pcg::Pcg32,
        axis: Vec3,
        n: usize,
        w: f32,
        jit: f32,
    ) -> ([Vec3; 3], Vec<Vec<Vec3>>) {
        let vz = axis.normalize();
        let (vx, vy) = vz.any_orthonormal_pair();
        let cell = 2.0 * w / n as f32;
        let rows = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let x = -w + (j as f32 + 0.5 + rng.gen_range(-jit..=jit)) * cell;
                        let y = -w + (i as f32 + 0.5 + rng.gen_range(-jit..=jit)) * cell;
                        (vx * x + vy * y + vz) * rng.gen_range(0.1f32..10.0)
                    })
                    .collect()
            })
            .collect();
        ([vx, vy, vz], rows)
    }

    /// Every ray outside a span is refused by the shared test, on grids aimed at triangles
    /// (through their interiors, edges and vertices) from near and far, at small and huge
    /// scales; spans must both keep and refuse rays, and whole rows must be refused too.
    #[test]
    fn spans_only_refuse_rays_the_test_refuses() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(23);
        let (mut refused, mut kept, mut rows_none, mut hits) = (0u64, 0u64, 0u64, 0u64);
        for case in 0..3_000 {
            let scale = [1e-3f32, 1.0, 1e4][case % 3];
            let mut r = |a: f32| rng.gen_range(-a..a);
            let v0 = Vec3::new(r(1.0), r(1.0), r(1.0)) * scale;
            let v1 = v0 + Vec3::new(r(1.0), r(1.0), r(0.3)) * scale;
            let v2 = v0 + Vec3::new(r(1.0), r(1.0), r(0.3)) * scale;
            let target = match case % 4 {
                0 => v1,
                1 => (v0 + v2) * 0.5,
                _ => v0 + (v1 - v0) * r(1.0).abs() * 0.5 + (v2 - v0) * r(1.0).abs() * 0.5,
            };
            let o = target + Vec3::new(r(3.0), r(3.0), r(3.0)) * scale;
            let (w, jit) = ([0.01f32, 0.2, 0.6][case % 3], [0.0f32, 0.3][case % 2]);
            let (mut frame, rows) = grid(&mut rng, target - o, 16, w, jit);
            // A frame off orthonormal (the tracer's is within 1e-6): the residual must cover it.
            if case % 5 == 4 {
                frame[0] = (frame[0] + Vec3::new(1e-3, -2e-3, 1e-3)).normalize();
            }
            // Grid-frame unit directions as the tracer computes them (f32).
            let mut fit = AlignedFit::new(frame);
            let pts: Vec<Vec<GridPoint>> = rows
                .iter()
                .map(|row| {
                    row.iter()
                        .map(|&d| {
                            let u = d / d.length();
                            fit.add(
                                d,
                                Vec3::new(u.dot(frame[0]), u.dot(frame[1]), u.dot(frame[2])),
                            )
                        })
                        .collect()
                })
                .collect();
            let Some(g) = fit.done() else { continue };
            let tri = AlignedTri::new(&g, o, v0, v1, v2);
            for (row, p) in rows.iter().zip(&pts) {
                let span = tri.span(&AlignedRow::of(p.iter().copied()));
                rows_none += u64::from(span == NONE);
                for (&d, &(ax, _)) in row.iter().zip(p) {
                    let h = intersect_triangle(o, d, v0, v1, v2, f32::MIN, f32::MAX);
                    hits += u64::from(h.is_some());
                    if ax >= span.0 && ax <= span.1 {
                        kept += 1;
                    } else {
                        refused += 1;
                        assert!(
                            h.is_none(),
                            "case {case}: refused ray hits: {d} {h:?} {span:?}"
                        );
                    }
                }
            }
        }
        assert!(refused > 100_000 && kept > 20_000, "{refused} {kept}");
        assert!(rows_none > 1_000 && hits > 5_000, "{rows_none} {hits}");
    }

    /// A span keeps every ray of a row that hits the triangle's interior.
    #[test]
    fn rows_through_the_interior_are_kept() {
        let (v0, v1, v2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let o = Vec3::new(0.25, 0.25, 1.0);
        let frame = [Vec3::X, Vec3::NEG_Y, Vec3::NEG_Z];
        let mut fit = AlignedFit::new(frame);
        let row: Vec<Vec3> = (0..8)
            .map(|j| Vec3::new(-0.6 + 0.2 * j as f32, 0.0, -1.0))
            .collect();
        let pts: Vec<GridPoint> = row
            .iter()
            .map(|&d| {
                let u = d.normalize();
                fit.add(
                    d,
                    Vec3::new(u.dot(frame[0]), u.dot(frame[1]), u.dot(frame[2])),
                )
            })
            .collect();
        let span = AlignedTri::new(&fit.done().unwrap(), o, v0, v1, v2)
            .span(&AlignedRow::of(pts.iter().copied()));
        for (d, (ax, _)) in row.iter().zip(&pts) {
            if intersect_triangle(o, *d, v0, v1, v2, 0.0, f32::MAX).is_some() {
                assert!(*ax >= span.0 && *ax <= span.1, "{ax} {span:?}");
            }
        }
        // The row crosses the triangle: some rays are outside (a real cull), some inside.
        assert!(pts.iter().any(|p| p.0 < span.0 || p.0 > span.1), "{span:?}");
        assert!(span != ALL && span != NONE);
    }
}
