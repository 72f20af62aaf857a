//! Shadow segments seen from their light: the cube-map coordinates of segments that end at (or
//! a few ulps off) one point, and the light-space footprint of a box, with the bounds that make
//! a footprint cull exact. DACRT's light-space shadow pass (`tracers/dacrt/light.rs`, issue
//! #21 item 1) is built on it: a segment to the light is a camera ray seen from the light, so
//! each segment becomes a point of a light-space image and each triangle a rectangle of it
//! (the irregular z-buffer idea).
//!
//! **Faces.** Face `f` looks along axis `f / 2` (positive for even `f`); a direction `w` from
//! the light belongs to the face of its largest `|w_k|` (the first on ties) and has the face
//! coordinates `(a, b) = (w_{k1}, w_{k2}) / x` with `x = ±w_k > 0` and `k1 < k2` the other
//! two axes, so `|a|, |b| <= 1` (up to a rounding).
//!
//! **Why a footprint is conservative.** A hit of the shared test lies in the triangle's
//! bounding box: the box gate puts its `t` inside the box's f32 slab interval, whose ends are
//! the planes' crossings up to a few ulps relative to the coordinates' magnitude, so the exact
//! point `o + t·d` is within `16ε·S` of the box, `S` the largest coordinate magnitude of the
//! ray's origin and the box; boxes are padded by `1e-5·S` (over 80 times that). A segment
//! `o + t·d`, `t ∈ [0, tmax]`, that ends near the light `L` stays close, seen from `L`, to the
//! direction `w = o − L` of its origin: let `c` be the point of its line closest to `L` and
//! `δ = |c − L|`. Points between `o` and `c` see the line at an angle `asin(δ/|p − L|)` on the
//! same side as `o`, so two of them differ by at most `asin(δ/r)` when both are at least `r`
//! from `L`; points beyond `c` are within `|e − L|` of `L` (`e = o + tmax·d`, the distance
//! to `L` is convex along the line). So with the segment's **slack** `ε = δ` when it does not
//! pass `c`, else `|e − L|`, every point at least `r > ε` from `L` is within
//! `θ = asin(ε/r)` of `w`'s direction. A triangle whose padded box keeps a distance above `r`
//! from `L` (every triangle but those in a small ball around the light) can only be hit at such
//! points; the hit's direction is then within `θ` of `w`, so inside `w`'s face region widened
//! by `θ`, where the face axis `x` is at least `0.57·r` (the region is within 54.74° of the
//! axis) and the face coordinates move by at most `θ / (x̂·x̂')`, under `3.1·θ` (`x̂, x̂' >=
//! 1/√3 − θ` the unit directions' axis components): the footprint (the range of `a` and `b`
//! over the padded box with `x >= 0.57·r`, which a box reaches at its corners since
//! `y/x` is monotone in `x` and in `y` there) widened by `τ = 4·θ` holds the point's `(a, b)`.
//! And the hit's `x` is at most the larger of the segment ends' (`x` is linear along it): a
//! triangle whose box starts deeper than a point's `depth` cannot shadow it. The arithmetic is
//! f64 on f32 data (relative errors near 1e-16), padded by a relative 1e-12.

// Negated comparisons on purpose: each `!(a <= b)` also takes the NaN case the safe way.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::{DVec3, Vec3};

/// A segment fits the light-space pass when its slack is at most this fraction of
/// `|o − L|∞ + |L|∞`: segments built as `d = L − o` in f32 have about `1e-7`.
pub const FIT_SLACK: f64 = 1e-6;

/// The ball around the light is at least this many times the largest slack of the batch (the
/// angular bound `θ = asin(ε/r)` is then at most `1e-4` rad), and at most [`BALL_MAX`] times.
const BALL_OVER_SLACK: f64 = 1e4;
const BALL_MAX: f64 = 1e7;

/// Relative padding of the f64 arithmetic (its errors are near `1e-16`).
const REL: f64 = 1e-12;

/// The slack of segment `o + t·d`, `t ∈ [tmin, tmax]`, towards `light` (see the module doc),
/// or `None` when the segment cannot use the light-space pass: a non-finite value, `tmin < 0`,
/// `tmin > tmax`, an origin on the light, or a slack above [`FIT_SLACK`].
pub fn segment_slack(light: Vec3, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<f64> {
    if !(o.is_finite() && d.is_finite() && light.is_finite() && tmax.is_finite()) {
        return None;
    }
    // NaN-safe: a NaN `tmin` fails.
    if !(tmin >= 0.0 && tmin <= tmax) {
        return None;
    }
    let (l, o64, d64) = (light.as_dvec3(), o.as_dvec3(), d.as_dvec3());
    let w = o64 - l;
    let dd = d64.length_squared();
    if w.abs().max_element() == 0.0 || dd == 0.0 {
        return None;
    }
    let tmax = tmax as f64;
    // The closest point of the line to the light, at `tc`.
    let tc = -w.dot(d64) / dd;
    let e = w + d64 * tmax;
    let eps = if tc >= tmax || tc <= 0.0 {
        (w + d64 * tc).length()
    } else {
        e.length()
    };
    // 1-norms bound the lengths (no square roots).
    let l1 = |v: DVec3| v.abs().element_sum();
    let eps = eps + REL * (l1(w) + l1(d64) * tmax);
    (eps <= FIT_SLACK * (w.abs().max_element() + l.abs().max_element())).then_some(eps)
}

/// Segment `o + t·d`, `t ∈ [0, tmax]`, towards `light`, in the light's frame (for a frame
/// whose slack bounds the segment's), or `None` for an origin on the light.
pub fn segment_view(light: Vec3, o: Vec3, d: Vec3, tmax: f32) -> Option<SegmentView> {
    let w = o.as_dvec3() - light.as_dvec3();
    let e = w + d.as_dvec3() * tmax as f64;
    let (k, x) = face_axis(w)?;
    let s = if w[k] > 0.0 { 1.0 } else { -1.0 };
    let (k1, k2) = others(k);
    let face = 2 * k + (s < 0.0) as usize;
    // The depth: the larger end, raised.
    let depth = (x.max(s * e[k])) * (1.0 + REL) + REL * (x + e.abs().max_element());
    // One division (the product's extra rounding is far inside the footprints' pad).
    let inv = 1.0 / x;
    Some(SegmentView {
        face,
        a: w[k1] * inv,
        b: w[k2] * inv,
        depth,
    })
}

/// A ray starting at the frame's point itself (its origin bitwise the light, or the eye of
/// `dacrt5d`'s eye pass, and `tmin >= 0`): every point of it lies exactly along `d` from the
/// point, so it is a segment of slack 0 seen in the direction of `d` rather than of its
/// origin. Its face and face coordinates (those of `d`, the face of the largest `|d_k|`,
/// the first on ties, as [`segment_view`]) and `|d_k|`: a hit at `t` has the face-axis
/// coordinate `t·|d_k|`, exact in f64 (a product of two f32). `None` for a zero or
/// non-finite direction.
pub fn ray_view(d: Vec3) -> Option<RayView> {
    if !d.is_finite() {
        return None;
    }
    let w = d.as_dvec3();
    let (k, x) = face_axis(w)?;
    let (k1, k2) = others(k);
    let inv = 1.0 / x;
    Some(RayView {
        face: 2 * k + (w[k] < 0.0) as usize,
        a: w[k1] * inv,
        b: w[k2] * inv,
        axis: x,
    })
}

/// A ray from the frame's point, in its frame ([`ray_view`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayView {
    /// Cube face (`0..6`).
    pub face: usize,
    /// Face coordinates of the direction, in `[-1, 1]`.
    pub a: f64,
    /// Second face coordinate.
    pub b: f64,
    /// `|d_k|` along the face's axis: a point at `t` has the face-axis coordinate `t·axis`.
    pub axis: f64,
}

/// A segment in the light's frame: its face, face coordinates (of its origin's direction) and
/// an upper bound on the face-axis coordinate (from the light) of every point of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentView {
    /// Cube face (`0..6`).
    pub face: usize,
    /// Face coordinates, in `[-1, 1]`.
    pub a: f64,
    /// Second face coordinate.
    pub b: f64,
    /// Upper bound on `x` (the face axis, from the light) along the segment.
    pub depth: f64,
}

/// A box's footprint on one face: the face-coordinate ranges of the points where a segment of
/// the face can hit what lies in the box (padded: see the module doc), and the box's smallest
/// face-axis coordinate there (a lower bound on a hit's `x`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footprint {
    /// `[a0, a1]`: the first coordinate's range.
    pub a: [f64; 2],
    /// `[b0, b1]`: the second's.
    pub b: [f64; 2],
    /// The least `x` of a hit in the box.
    pub x0: f64,
}

/// The light's frame for one batch: the light, the ball around it, the face-coordinate pad and
/// the boxes' pad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightView {
    light: DVec3,
    r: f64,
    tau: f64,
    pad: f64,
}

/// The axis of `w`'s largest magnitude (the first on ties) and that magnitude, `None` when it
/// is zero or NaN.
#[inline]
fn face_axis(w: DVec3) -> Option<(usize, f64)> {
    let m = w.abs();
    let k = if m.x >= m.y && m.x >= m.z {
        0
    } else if m.y >= m.z {
        1
    } else {
        2
    };
    (m[k] > 0.0).then_some((k, m[k]))
}

/// The two other axes of face `f`'s axis, in increasing order.
#[inline]
fn others(k: usize) -> (usize, usize) {
    match k {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

impl LightView {
    /// The frame of segments to `light` whose slack is at most `slack`, against boxes whose
    /// coordinates and the segments' origins are at most `scale` in magnitude, with a
    /// footprint pad of about `want_tau` if the ball's range allows (a larger ball gives a
    /// smaller pad: more triangles near the light, tighter footprints). `None` when the
    /// inputs are not finite.
    pub fn new(light: Vec3, slack: f64, scale: f64, want_tau: f64) -> Option<Self> {
        let l = light.as_dvec3();
        let scale = scale.max(l.abs().max_element());
        if !(l.is_finite() && slack.is_finite() && scale.is_finite() && slack >= 0.0) {
            return None;
        }
        // Never zero: a floor far above the f32 rounding of the coordinates near the light.
        // τ ≈ 4.04·ε/r.
        let want = if want_tau > 0.0 {
            4.04 * slack / want_tau
        } else {
            0.0
        };
        let r = want
            .clamp(slack * BALL_OVER_SLACK, slack * BALL_MAX)
            .max(1e-7 * scale)
            .max(f64::MIN_POSITIVE);
        // θ = asin(ε/r) <= 1.01·ε/r for ε/r <= 1e-4; a floor for the f32 copies of the
        // points' coordinates (|a| <= 1: their rounding is below 6e-8).
        let theta = 1.01 * slack / r;
        // The module doc's bounds need θ below about 0.007.
        if !(theta <= 1e-3) {
            return None;
        }
        let tau = 4.0 * theta + 1e-6;
        Some(Self {
            light: l,
            r,
            tau,
            pad: 1e-5 * scale,
        })
    }

    /// The light.
    pub fn light(&self) -> Vec3 {
        self.light.as_vec3()
    }

    /// The radius of the ball around the light whose boxes get no footprint ([`Self::near`]).
    pub fn ball(&self) -> f64 {
        self.r
    }

    /// The face-coordinate pad of every footprint.
    pub fn tau(&self) -> f64 {
        self.tau
    }

    /// [`segment_view`] towards this frame's light.
    pub fn segment(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<SegmentView> {
        segment_view(self.light(), o, d, tmax)
    }

    /// True when the padded box `[lo, hi]` comes within the ball around the light: a hit in it
    /// may lie anywhere in the light's frame (such triangles are tested against every
    /// segment).
    pub fn near(&self, lo: Vec3, hi: Vec3) -> bool {
        let (lo, hi) = (lo.as_dvec3() - self.pad, hi.as_dvec3() + self.pad);
        let g = (lo - self.light).max(self.light - hi).max(DVec3::ZERO);
        // NaN-safe: a NaN box is near (tested against everything).
        !(g.length() * (1.0 - REL) > self.r)
    }

    /// The footprint of the padded box `[lo, hi]` (not [`Self::near`]) on `face`, `None` when
    /// no segment of the face can hit inside it.
    #[inline]
    pub fn footprint(&self, lo: Vec3, hi: Vec3, face: usize) -> Option<Footprint> {
        let k = face / 2;
        let (k1, k2) = others(k);
        let (lo, hi) = (
            lo.as_dvec3() - self.pad - self.light,
            hi.as_dvec3() + self.pad - self.light,
        );
        let (x_lo, x_hi) = if face.is_multiple_of(2) {
            (lo[k], hi[k])
        } else {
            (-hi[k], -lo[k])
        };
        // A hit of the face's segments has `x >= 0.57·r` (see the module doc).
        let x0 = x_lo.max(0.57 * self.r);
        if !(x_hi >= x0) {
            return None;
        }
        let range = |a: usize| {
            let (y0, y1) = (lo[a], hi[a]);
            let lo = (y0 / x0).min(y0 / x_hi);
            let hi = (y1 / x0).max(y1 / x_hi);
            [
                lo - self.tau - REL * lo.abs(),
                hi + self.tau + REL * hi.abs(),
            ]
        };
        let (a, b) = (range(k1), range(k2));
        // Every segment of the face has |a|, |b| <= 1.
        if a[0] > 1.0 || a[1] < -1.0 || b[0] > 1.0 || b[1] < -1.0 {
            return None;
        }
        Some(Footprint {
            a,
            b,
            x0: x0 * (1.0 - REL),
        })
    }
}

#[cfg(test)]
mod tests;
