//! Planes, bounding spheres and cones: the bounding volumes of the RTRPS (spheres, ray-planes) and
//! cone-tracing papers and of DACRT's conic packets. Their ray and box tests live here so tracers
//! share them.

use glam::Vec3;

/// The plane `normal · p = offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Plane normal (not necessarily unit length).
    pub normal: Vec3,
    /// `normal · p` for points on the plane.
    pub offset: f32,
}

impl Plane {
    /// The plane through `p` with normal `n`.
    pub fn from_point_normal(p: Vec3, n: Vec3) -> Self {
        Self {
            normal: n,
            offset: n.dot(p),
        }
    }

    /// Signed distance times `|normal|` (positive on the side the normal points to).
    #[inline]
    pub fn signed(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }
}

/// A sphere, used as a bounding volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius.
    pub radius: f32,
}

impl Sphere {
    /// A sphere containing the three points: centred on their box centre (cheap, within √3/2 of
    /// the optimum radius, and stable under rigid motion of the triangle up to rounding).
    pub fn around_triangle(v0: Vec3, v1: Vec3, v2: Vec3) -> Self {
        let c = (v0.min(v1).min(v2) + v0.max(v1).max(v2)) * 0.5;
        let r = (v0 - c)
            .length()
            .max((v1 - c).length())
            .max((v2 - c).length());
        Self {
            center: c,
            radius: r,
        }
    }

    /// True when the ray's segment `[tmin, tmax]` passes within the sphere (conservative for
    /// unnormalised directions).
    #[inline]
    #[allow(clippy::neg_cmp_op_on_partial_ord)] // `!(dd > 0)` also rejects NaN directions
    pub fn hit_by_ray(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        let dd = dir.length_squared();
        if !(dd > 0.0) {
            return false;
        }
        let oc = self.center - origin;
        // Closest point of the segment to the centre.
        let t = (oc.dot(dir) / dd).clamp(tmin, tmax);
        let p = origin + dir * t;
        (p - self.center).length_squared() <= self.radius * self.radius * (1.0 + 4.0 * f32::EPSILON)
    }
}

/// A cone with apex, unit axis and half-angle, bounding a coherent group of rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    /// Apex (the rays' common origin).
    pub apex: Vec3,
    /// Unit axis.
    pub axis: Vec3,
    /// Half-angle in radians, in `[0, π/2)`.
    pub half_angle: f32,
}

impl Cone {
    /// The tightest cone around unit directions `dirs` from `apex` (normalised by the caller,
    /// `normalize_or_zero`: a zero entry counts for nothing), axis = normalised mean,
    /// half-angle from the largest `|d×a| / (d·a)` (accurate near zero, unlike `acos`; a ratio,
    /// so the few ulps by which a normalised `d` misses unit length do not change it), plus a
    /// relative margin. `None` when the directions span a half-space or more.
    pub fn around_directions(apex: Vec3, dirs: &[Vec3]) -> Option<Self> {
        let sum: Vec3 = dirs.iter().sum();
        let axis = sum.normalize_or_zero();
        if axis == Vec3::ZERO {
            return None;
        }
        // The widest angle is the largest tangent |d×a| / (d·a) (monotonic below 90°): one
        // `atan` per cone instead of one `atan2` per direction, same value up to an ulp or two,
        // far inside the margin below. A direction at 90° or more gives no cone.
        let mut tan = 0.0f32;
        for d in dirs {
            let (sin, cos) = (d.cross(axis).length(), d.dot(axis));
            if sin > 0.0 {
                // `cos` NaN (an infinite direction) gives no cone either.
                if cos.is_nan() || cos <= 0.0 {
                    return None;
                }
                tan = tan.max(sin / cos);
            }
        }
        let half_angle = tan.atan() * (1.0 + 1e-4) + 1e-6;
        (half_angle < std::f32::consts::FRAC_PI_2).then_some(Self {
            apex,
            axis,
            half_angle,
        })
    }

    /// True when point `p` lies inside the (infinite, one-sided) cone.
    #[inline]
    pub fn contains_point(&self, p: Vec3) -> bool {
        let w = p - self.apex;
        let l = w.length();
        l == 0.0 || w.dot(self.axis) >= l * self.half_angle.cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_contains_triangle_and_ray_test() {
        let (a, b, c) = (
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 3.0, 1.0),
        );
        let s = Sphere::around_triangle(a, b, c);
        for p in [a, b, c] {
            assert!((p - s.center).length() <= s.radius * 1.000_001);
        }
        assert!(s.hit_by_ray(Vec3::new(1.0, 1.0, -5.0), Vec3::Z, 0.0, f32::INFINITY));
        assert!(!s.hit_by_ray(Vec3::new(1.0, 1.0, -5.0), -Vec3::Z, 0.0, f32::INFINITY));
        assert!(!s.hit_by_ray(Vec3::new(10.0, 1.0, -5.0), Vec3::Z, 0.0, f32::INFINITY));
    }

    #[test]
    fn cone_bounds_its_directions() {
        let dirs = [
            Vec3::new(0.01, 0.0, 1.0),
            Vec3::new(-0.01, 0.01, 1.0),
            Vec3::Z,
        ];
        let c = Cone::around_directions(Vec3::ZERO, &dirs.map(|d: Vec3| d.normalize_or_zero()))
            .unwrap();
        for d in dirs {
            assert!(c.contains_point(d * 7.0));
        }
        assert!(!c.contains_point(Vec3::new(1.0, 0.0, 1.0)));
        assert!(Cone::around_directions(Vec3::ZERO, &[Vec3::X, -Vec3::X]).is_none());
    }

    #[test]
    fn plane_sides() {
        let p = Plane::from_point_normal(Vec3::new(0.0, 1.0, 0.0), Vec3::Y);
        assert!(p.signed(Vec3::new(5.0, 2.0, 0.0)) > 0.0);
        assert!(p.signed(Vec3::ZERO) < 0.0);
    }
}
