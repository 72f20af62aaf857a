//! Ours: the edge test of one triangle at the pixels of 8×8 tiles, for DACRT's tile leaves on
//! triangles that cover many pixels. A triangle's pixel rectangle
//! ([`PixelProjection::triangle_rects_wide`]) holds every pixel whose ray can hit it, and for
//! a large triangle also many that cannot (about half of the rectangle for any triangle, more
//! for slanted ones); the leaves would run the ray/triangle test on each. The same argument as
//! the rectangle's, per pixel: a pixel more than `pad_edge` outside the triangle of the projected
//! corners, across any of its edges, has no ray the shared triangle test reports as a hit, so
//! it is dropped without one.

use super::{Edges, PixelProjection};
use crate::geom::lanes::{F32x8, Lanes, Wide};
use glam::Vec3;

/// One triangle's edge test, for whole rows of eight pixels (see the module doc).
#[derive(Clone, Copy, Debug)]
pub struct PixelEdges {
    /// The edges, each lane the same (rows of eight pixels are tested at once).
    e: Edges<F32x8>,
    /// The pixels the test is valid at: within `pad` of the corners' bounding rectangle (its
    /// rounding bound assumes it), `[x0, x1, y0, y1]` inclusive.
    valid: [f32; 4],
}

impl PixelProjection {
    /// The edge test of triangle `v` for rays from the eye within `tol` pixels of their own
    /// pixel, or `None` where it would cull nothing safely: triangles reaching behind the eye
    /// and near-degenerate projections (see [`Self::triangle_may_cover`]).
    pub fn triangle_edges(&self, v: [Vec3; 3], tol: f64) -> Option<PixelEdges> {
        let lanes = v.map(|p| [Wide([p.x]), Wide([p.y]), Wide([p.z])]);
        let p = self.project_corners::<Wide<1>>(lanes, tol);
        let e = Edges::of(&p);
        if Wide::<1>::bitmask(p.behind | e.thin) != 0 {
            return None;
        }
        let s = |v: [Wide<1>; 3]| v.map(|x| F32x8::splat(x.0[0]));
        let pad = p.pad.0[0];
        Some(PixelEdges {
            e: Edges {
                nx: s(e.nx),
                ny: s(e.ny),
                ax: s(e.ax),
                ay: s(e.ay),
                r2: s(e.r2),
                thin: F32x8::mask_splat(false),
            },
            valid: [
                p.lo[0].0[0] - pad,
                p.hi[0].0[0] + pad,
                p.lo[1].0[0] - pad,
                p.hi[1].0[0] + pad,
            ],
        })
    }
}

impl PixelEdges {
    /// The bits of `m` whose pixels pass the test, bit `b` standing for pixel `(x0 + b % 8,
    /// y0 + b / 8)`. Bits of pixels outside the region the test is valid at are kept.
    #[inline]
    pub fn mask8x8(&self, x0: i64, y0: i64, m: u64) -> u64 {
        let [vx0, vx1, vy0, vy1] = self.valid;
        let (fx, fy) = (x0 as f32, y0 as f32);
        // Exact small integers (images are far below 2^24 pixels).
        let x = F32x8::from_fn(|l| fx + l as f32);
        let valid_x = F32x8::bitmask(x.cmpge(F32x8::splat(vx0)) & x.cmple(F32x8::splat(vx1)));
        let mut out = 0u64;
        for r in 0..8 {
            let row = (m >> (8 * r)) as u32 & 0xff;
            if row == 0 {
                continue;
            }
            let y = fy + r as f32;
            let keep = if y >= vy0 && y <= vy1 {
                F32x8::bitmask(self.e.inside(x, F32x8::splat(y))) | !valid_x
            } else {
                0xff
            };
            out |= ((row & keep) as u64) << (8 * r);
        }
        out
    }
}
