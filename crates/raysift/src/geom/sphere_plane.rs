//! Plane/sphere tests of RTRPS (Suzuki 2010, §2.2, §3.1): a *fan* of ray-planes sharing one line
//! through the rays' origin (a grid's row planes, or its column planes), seen along that line, so
//! that a plane/sphere test is a 2D line/circle test (§3.1.1, parallel projection); the wedge the
//! fan's outermost planes bound (§3.1.2, frustum culling) and the sign rule of the binary-tree
//! order (§3.1.3). Also the conservative ray/sphere test of the random-ray mode.
//!
//! **Conservative by construction.** Every test here only culls; the shared triangle test
//! decides. A plane of real rays is not exactly a plane: its rays lie within an angle whose sine
//! is the fan's `slack` of the fitted plane, so a ray of the plane meeting a sphere `(c, r)` at a
//! point `p` has `|n·c| <= r + slack·|p| <= r + slack·(|c| + r)`; callers add an absolute margin
//! `e` for rounding (see `accel::spheres::SLACK`). The two rules that skip planes without testing
//! them (the wedge cull and the binary-tree sign rule) are used only on fans that are *sorted*:
//! planes strictly increasing in angle about the shared line, spanning less than a half-turn
//! ([`PlaneFan::sorted`]), where the signed distance of a centre to the fan's lines,
//! `f(θ) = |c|·sin(α − θ)`, obeys:
//! - **wedge** (Table 1): if `f` has the same sign at both outer lines and `|f| > bound` there,
//!   no line between them is within `bound` (on an interval shorter than π, `sin` of one sign has
//!   no zero inside and `|sin|` is concave, so its minimum is at an end) — the exact circle /
//!   double-wedge test, mirror wedge behind the apex included (a plane is both halves);
//! - **sign rule**: when the centre lies where `ℓ·c >= 0` for both outer line directions `ℓ`
//!   (or `<= 0` for both: the mirror), `f` is monotone over the fan, so a plane missed on one
//!   side rules out every plane beyond it on that side. Elsewhere the fan is tested plane by plane.

/// Most planes in a fan (groups of more rays per row or column are traced as random rays).
pub const MAX_FAN: usize = 64;

/// A fan of planes sharing a line, in its 2D projection along that line: unit normals `(np, nq)`
/// in sorted order, the plane each sorted position stands for, and the slack.
#[derive(Clone, Debug)]
pub struct PlaneFan {
    /// Number of planes.
    pub len: usize,
    /// Normal, first projected coordinate, by sorted position.
    pub np: [f32; MAX_FAN],
    /// Normal, second projected coordinate, by sorted position.
    pub nq: [f32; MAX_FAN],
    /// Plane (row or column index) at each sorted position.
    pub order: [u8; MAX_FAN],
    /// Largest sine of the angle between a ray of a plane and that plane, plus rounding margin.
    pub slack: f32,
    /// Planes strictly increasing in angle, spanning less than π (wedge cull and sign rule allowed).
    pub sorted: bool,
}

impl Default for PlaneFan {
    fn default() -> Self {
        Self {
            len: 0,
            np: [0.0; MAX_FAN],
            nq: [0.0; MAX_FAN],
            order: [0; MAX_FAN],
            slack: 0.0,
            sorted: false,
        }
    }
}

impl PlaneFan {
    /// Fits `planes` planes, plane `i` holding the rays whose unit directions, projected along the
    /// shared line, are `dir(i, j)` for `j < members` (2D `(p, q)`). Each plane's line is the
    /// normalised sum of its rays' projections (any line is correct: the slack measures the fit).
    pub fn fit(&mut self, planes: usize, members: usize, dir: impl Fn(usize, usize) -> (f32, f32)) {
        assert!(planes <= MAX_FAN && planes > 0);
        self.len = planes;
        let mut lines = [(0.0f32, 1.0f32); MAX_FAN];
        let mut slack = 0.0f32;
        for (i, line) in lines.iter_mut().enumerate().take(planes) {
            let (mut sp, mut sq) = (0.0f32, 0.0f32);
            for j in 0..members {
                let (p, q) = dir(i, j);
                sp += p;
                sq += q;
            }
            let l = (sp * sp + sq * sq).sqrt();
            if l > 1e-6 && l.is_finite() {
                *line = (sp / l, sq / l);
            }
            let (np, nq) = (-line.1, line.0);
            for j in 0..members {
                let (p, q) = dir(i, j);
                slack = slack.max((np * p + nq * q).abs());
            }
        }
        // Rounding of the unit directions, their projection and this sum: 1e-6 covers them.
        self.slack = slack + 1e-6;
        // Angles in f64; sorted ascending, or descending (then stored reversed).
        let ang: Vec<f64> = lines[..planes]
            .iter()
            .map(|&(p, q)| (q as f64).atan2(p as f64))
            .collect();
        let unwrap = |from: usize, to: usize| -> Option<f64> {
            let (a, b) = (ang[from], ang[to]);
            let mut d = b - a;
            while d <= -std::f64::consts::PI {
                d += 2.0 * std::f64::consts::PI;
            }
            while d > std::f64::consts::PI {
                d -= 2.0 * std::f64::consts::PI;
            }
            Some(d)
        };
        let steps: Vec<f64> = (1..planes).filter_map(|i| unwrap(i - 1, i)).collect();
        let up = steps.iter().all(|&d| d > 1e-9);
        let down = steps.iter().all(|&d| d < -1e-9);
        let span: f64 = steps.iter().map(|d| d.abs()).sum();
        self.sorted = (up || down) && span < std::f64::consts::PI - 1e-6;
        for k in 0..planes {
            let i = if down { planes - 1 - k } else { k };
            self.order[k] = i as u8;
            self.np[k] = -lines[i].1;
            self.nq[k] = lines[i].0;
        }
    }

    /// Signed distance (times the normal's length, 1 up to rounding) of the 2D point `c` from
    /// the plane at sorted position `k`.
    #[inline(always)]
    pub fn signed(&self, k: usize, c: (f32, f32)) -> f32 {
        self.np[k] * c.0 + self.nq[k] * c.1
    }

    /// The line direction at sorted position `k` (the normal turned back a quarter).
    #[inline(always)]
    fn line(&self, k: usize) -> (f32, f32) {
        (self.nq[k], -self.np[k])
    }

    /// For a sorted fan: `Some(1.0)` when `c` lies where the signed distances decrease over
    /// sorted positions `lo..=hi` (both outer lines point towards `c` by more than `e`),
    /// `Some(-1.0)` in the mirror region (distances increase), `None` elsewhere.
    #[inline]
    pub fn monotone(&self, lo: usize, hi: usize, c: (f32, f32), e: f32) -> Option<f32> {
        if !self.sorted {
            return None;
        }
        let (a, b) = (self.line(lo), self.line(hi));
        let (da, db) = (a.0 * c.0 + a.1 * c.1, b.0 * c.0 + b.1 * c.1);
        if da >= e && db >= e {
            Some(1.0)
        } else if da <= -e && db <= -e {
            Some(-1.0)
        } else {
            None
        }
    }
}

/// The exact circle/wedge cull of a sorted fan: true when the signed distances `f_lo`, `f_hi` at
/// its two outer planes have the same sign and both exceed `bound` in magnitude, so no plane of
/// the fan between them (nor the mirror wedge) comes within `bound` (Table 1, cases 5–10).
#[inline(always)]
pub fn wedge_misses(f_lo: f32, f_hi: f32, bound: f32) -> bool {
    (f_lo > bound && f_hi > bound) || (f_lo < -bound && f_hi < -bound)
}

/// The plane bound of a sphere for a fan: radius, plus the fan's slack over the farthest point
/// of the sphere from the apex, plus the absolute rounding margin `e`.
#[inline(always)]
pub fn fan_bound(r: f32, dist: f32, slack: f32, e: f32) -> f32 {
    r + slack * (dist + r) + e
}

/// Conservative ray/sphere test: false only when the line `o + t·d` passes farther than `r`
/// from `c` (`|(c − o) × d|² > r²·|d|²`, with `r` already holding the caller's rounding margin),
/// or when the sphere lies entirely before `tmin` or after `tmax` along the ray (with a relative
/// margin of `2^-12` on `t`). `dd = d·d`, `dl = |d|`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn ray_sphere(
    o: glam::Vec3,
    d: glam::Vec3,
    dd: f32,
    dl: f32,
    c: glam::Vec3,
    r: f32,
    tmin: f32,
    tmax: f32,
) -> bool {
    let w = c - o;
    let x = w.cross(d);
    if x.length_squared() > r * r * dd {
        return false;
    }
    // Along the ray, the sphere spans t in [(s - r·|d|)/|d|², (s + r·|d|)/|d|²].
    let s = w.dot(d);
    let (near, far) = (s - r * dl, s + r * dl);
    let m = 1.0 + 1.0 / 4096.0;
    if far < 0.0 && far * m < tmin * dd && tmin >= 0.0 {
        return false;
    }
    if near > 0.0 && near > tmax * dd * m {
        return false;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fan_of(angles: &[f32]) -> PlaneFan {
        let mut f = PlaneFan::default();
        f.fit(angles.len(), 1, |i, _| (angles[i].cos(), angles[i].sin()));
        f
    }

    #[test]
    fn sorted_fans_and_their_order() {
        let f = fan_of(&[0.1, 0.2, 0.3]);
        assert!(f.sorted && f.order[..3] == [0, 1, 2] && f.slack < 1e-5);
        let f = fan_of(&[0.3, 0.2, 0.1]);
        assert!(f.sorted && f.order[..3] == [2, 1, 0]);
        assert!(!fan_of(&[0.1, 0.3, 0.2]).sorted);
        assert!(
            !fan_of(&[0.0, 1.5, 3.0, 4.0]).sorted,
            "span over a half-turn"
        );
    }

    #[test]
    fn wedge_and_sign_rule_agree_with_plane_by_plane_tests() {
        let angles: Vec<f32> = (0..9).map(|i| -0.6 + 0.15 * i as f32).collect();
        let f = fan_of(&angles);
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 40) as f32 / (1u64 << 24) as f32) * 8.0 - 4.0
        };
        for _ in 0..20000 {
            let c = (next(), next());
            let r = next().abs() * 0.3;
            let hits: Vec<bool> = (0..9).map(|k| f.signed(k, c).abs() <= r).collect();
            if wedge_misses(f.signed(0, c), f.signed(8, c), r) {
                assert!(hits.iter().all(|h| !h), "{c:?} {r}");
            }
            if let Some(s) = f.monotone(0, 8, c, 1e-6) {
                // Hits are contiguous and every miss's sign points towards them.
                let first = hits.iter().position(|&h| h);
                #[allow(clippy::needless_range_loop)]
                for k in 0..9 {
                    let v = s * f.signed(k, c);
                    if !hits[k] {
                        if let Some(first) = first {
                            assert_eq!(v > 0.0, k < first, "{c:?} {r} plane {k}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn ray_sphere_is_conservative_on_tangent_and_behind() {
        use glam::Vec3;
        // A unit ray along +x from the origin against unit spheres: (centre, tmax, expected).
        let cases = [
            (Vec3::new(5.0, 1.0, 0.0), f32::INFINITY, true), // tangent: kept
            (Vec3::new(5.0, 1.01, 0.0), f32::INFINITY, false), // just off
            (Vec3::new(-5.0, 0.0, 0.0), f32::INFINITY, false), // behind the origin
            (Vec3::new(-0.5, 0.0, 0.0), f32::INFINITY, true), // the origin inside
            (Vec3::new(5.0, 0.0, 0.0), 3.0, false),          // beyond tmax
        ];
        for (c, tmax, want) in cases {
            let got = ray_sphere(Vec3::ZERO, Vec3::X, 1.0, 1.0, c, 1.0, 0.0, tmax);
            assert_eq!(got, want, "centre {c} tmax {tmax}");
        }
    }
}
