//! Ray batches and hit batches, structure-of-arrays, and their generators and file formats.
//!
//! A [`RayBatch`] is eight `f32` arrays (origin, direction, `tmin`, `tmax`: 32 bytes per ray) plus a
//! [`RayLayout`] hint telling coherence-exploiting tracers (DACRT's conic packets, shafts,
//! ray-planes) how the rays were made. A [`HitBatch`] is four arrays (`t`, `prim`, `u`, `v`: 16 bytes
//! per ray) and starts all-miss.

pub mod camera;
pub mod generate;
mod layout;
pub mod npy;

use glam::Vec3;

pub use camera::Camera;
pub use layout::RayLayout;

/// Primitive id of a miss.
pub const MISS: u32 = u32::MAX;

/// One ray (for convenience outside hot loops).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction (need not be unit length; `t` is measured in its units).
    pub dir: Vec3,
    /// Smallest accepted `t`.
    pub tmin: f32,
    /// Largest accepted `t`.
    pub tmax: f32,
}

/// Rays as structure-of-arrays.
#[derive(Clone, Debug, Default)]
pub struct RayBatch {
    /// Origin x.
    pub ox: Vec<f32>,
    /// Origin y.
    pub oy: Vec<f32>,
    /// Origin z.
    pub oz: Vec<f32>,
    /// Direction x.
    pub dx: Vec<f32>,
    /// Direction y.
    pub dy: Vec<f32>,
    /// Direction z.
    pub dz: Vec<f32>,
    /// Interval start (inclusive).
    pub tmin: Vec<f32>,
    /// Interval end (inclusive).
    pub tmax: Vec<f32>,
    /// Generation hint.
    pub layout: RayLayout,
}

impl RayBatch {
    /// An empty batch with room for `n` rays.
    pub fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Self {
            ox: v(),
            oy: v(),
            oz: v(),
            dx: v(),
            dy: v(),
            dz: v(),
            tmin: v(),
            tmax: v(),
            layout: RayLayout::Unknown,
        }
    }

    /// A batch from rays.
    pub fn from_rays(rays: impl IntoIterator<Item = Ray>) -> Self {
        let mut b = Self::default();
        for r in rays {
            b.push(r);
        }
        b
    }

    /// Appends a ray.
    pub fn push(&mut self, r: Ray) {
        self.ox.push(r.origin.x);
        self.oy.push(r.origin.y);
        self.oz.push(r.origin.z);
        self.dx.push(r.dir.x);
        self.dy.push(r.dir.y);
        self.dz.push(r.dir.z);
        self.tmin.push(r.tmin);
        self.tmax.push(r.tmax);
    }

    /// Number of rays.
    #[inline]
    pub fn len(&self) -> usize {
        self.ox.len()
    }

    /// True when there are no rays.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.ox.is_empty()
    }

    /// Origin of ray `i`.
    #[inline(always)]
    pub fn origin(&self, i: usize) -> Vec3 {
        Vec3::new(self.ox[i], self.oy[i], self.oz[i])
    }

    /// Direction of ray `i`.
    #[inline(always)]
    pub fn dir(&self, i: usize) -> Vec3 {
        Vec3::new(self.dx[i], self.dy[i], self.dz[i])
    }

    /// Ray `i`.
    #[inline(always)]
    pub fn get(&self, i: usize) -> Ray {
        Ray {
            origin: self.origin(i),
            dir: self.dir(i),
            tmin: self.tmin[i],
            tmax: self.tmax[i],
        }
    }

    /// The rays `range` as a new batch (layout becomes `Unknown`).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Self {
        let c = |v: &Vec<f32>| v[range.clone()].to_vec();
        Self {
            ox: c(&self.ox),
            oy: c(&self.oy),
            oz: c(&self.oz),
            dx: c(&self.dx),
            dy: c(&self.dy),
            dz: c(&self.dz),
            tmin: c(&self.tmin),
            tmax: c(&self.tmax),
            layout: RayLayout::Unknown,
        }
    }

    /// Bytes held (32 per ray at full capacity use).
    pub fn bytes(&self) -> usize {
        8 * self.ox.capacity() * 4
    }
}

/// Closest hits as structure-of-arrays; a miss has `t = +inf`, `prim = MISS`, `u = v = 0`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HitBatch {
    /// Hit distance in units of the ray's direction.
    pub t: Vec<f32>,
    /// Triangle id (`MISS` for none).
    pub prim: Vec<u32>,
    /// Barycentric weight of the triangle's second corner.
    pub u: Vec<f32>,
    /// Barycentric weight of the triangle's third corner.
    pub v: Vec<f32>,
}

impl HitBatch {
    /// `n` misses.
    pub fn new(n: usize) -> Self {
        Self {
            t: vec![f32::INFINITY; n],
            prim: vec![MISS; n],
            u: vec![0.0; n],
            v: vec![0.0; n],
        }
    }

    /// Resets to `n` misses, reusing storage.
    pub fn reset(&mut self, n: usize) {
        for (v, x) in [
            (&mut self.t, f32::INFINITY),
            (&mut self.u, 0.0),
            (&mut self.v, 0.0),
        ] {
            v.clear();
            v.resize(n, x);
        }
        self.prim.clear();
        self.prim.resize(n, MISS);
    }

    /// Number of entries.
    #[inline]
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when empty.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// True when entry `i` is a hit.
    #[inline]
    pub fn is_hit(&self, i: usize) -> bool {
        self.prim[i] != MISS
    }

    /// Number of hits.
    pub fn hit_count(&self) -> usize {
        self.prim.iter().filter(|&&p| p != MISS).count()
    }

    /// Bytes held (16 per ray).
    pub fn bytes(&self) -> usize {
        4 * self.t.capacity() * 4
    }
}
