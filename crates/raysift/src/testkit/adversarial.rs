//! Adversarial scenes and rays: the classes that break tracers which are only "usually" exact
//! (issue #20), generated from a seed so a failure is reproducible from `(class, seed)`.
//!
//! | class | scene | rays |
//! |---|---|---|
//! | `vertex` | one triangle, or a few | aimed exactly at the vertices and edge points, random directions |
//! | `grid` | a flat grid of unit quads (two triangles each) in an axis plane | aimed at the grid's vertices and edges |
//! | `tilted` | the grid rotated off the axes | nearly parallel to the grid's plane, and aimed at its vertices |
//! | `fan` | fans of needle triangles sharing a vertex | through the shared vertex and along the needles |
//! | `duplicates` | every triangle of a small mesh twice (permuted corners) | camera and random |
//! | `scale` | a mesh scaled by 1e6 or 1e-6, or moved 1e5 away | aimed at its vertices, camera rays |
//! | `directions` | a soup | denormal-small and huge direction vectors, `t` up to 1e30 |
//! | `camera` | a grid (tilted or not), a fan, or both | a pinhole camera (layout set: DACRT's packets, screen culling and tile leaves), often at grazing angles, sometimes jittered |
//! | `light` | a tilted grid and a soup, at scales 1e-4 to 1e4, sometimes far from the origin | shadow segments to one point light (layout `ToPoint`: DACRT's light-space pass): behind the grid's vertices and edges as seen from the light, from coincident origins, of zero length, ending past the light, stopping short of it, normalised; the light inside the scene, on a grid vertex, on a triangle's plane or outside; some rays not towards the light |
//! | `grids` | a tilted grid and a soup | side×side groups from one origin each (layout `OriginGrids`: RTRPS's ray-planes): cosine hemisphere grids whose rows are azimuths (their rows cancel: the grid frame's hard case) or radii, shadow grids ending on a square light, from inside and around the scene |
//!
//! Every class mixes in some ordinary rays, and intervals `[tmin, tmax]` ending exactly at the
//! hit distances. These are the inputs of the conformance suite's adversarial cases and of the
//! soak (`raysift soak`).

use crate::rays::{Ray, RayBatch};
use crate::scene::{procedural, Mesh, Scene};
use glam::{Affine3A, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// The adversarial classes, in the order [`case`] numbers them.
pub const CLASSES: &[&str] = &[
    "vertex",
    "grid",
    "tilted",
    "fan",
    "duplicates",
    "scale",
    "directions",
    "camera",
    "grids",
    "light",
];

/// One generated case.
pub struct Case {
    /// `class:seed`, enough to regenerate it.
    pub name: String,
    /// The scene.
    pub scene: Scene,
    /// The rays.
    pub rays: RayBatch,
}

fn unit(rng: &mut Pcg64Mcg) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

fn soup_scene(name: &str, tris: &[[Vec3; 3]]) -> Scene {
    let pos = tris.iter().flatten().copied().collect();
    let idx = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Scene::from_meshes(name, vec![Mesh::new("m", pos, idx)]).expect("finite by construction")
}

/// A ray through `target` from `dist` away along `-dir` (so it reaches the target at `t = dist`
/// for a unit `dir`), with one of a few intervals: open, ending at the target, starting at it.
fn through(rng: &mut Pcg64Mcg, target: Vec3, dir: Vec3, dist: f32) -> Ray {
    let origin = target - dir * dist;
    let (tmin, tmax) = match rng.gen_range(0..6) {
        0 => (0.0, dist),
        1 => (dist, f32::INFINITY),
        2 => (dist, dist),
        _ => (0.0, f32::INFINITY),
    };
    Ray {
        origin,
        dir,
        tmin,
        tmax,
    }
}

/// A `k × k` grid of unit quads in the plane z = 0 (two triangles each, sharing the diagonal), and
/// the grid points (vertices, edge midpoints, centres) rays are aimed at.
fn grid(k: usize) -> (Vec<[Vec3; 3]>, Vec<Vec3>) {
    let mut tris = Vec::with_capacity(2 * k * k);
    for j in 0..k {
        for i in 0..k {
            let p = |a: usize, b: usize| Vec3::new(a as f32, b as f32, 0.0);
            tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
            tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    let mut targets = Vec::new();
    for j in 0..=2 * k {
        for i in 0..=2 * k {
            targets.push(Vec3::new(i as f32 * 0.5, j as f32 * 0.5, 0.0));
        }
    }
    (tris, targets)
}

/// A [`grid`] of `k × k` quads moved to a random pose and a soup of `soup` triangles over it:
/// the triangles, the grid's target points (posed) and the pose.
fn grid_and_soup(
    rng: &mut Pcg64Mcg,
    k: usize,
    soup: usize,
    seed: u64,
) -> (Vec<[Vec3; 3]>, Vec<Vec3>, Affine3A) {
    let (tris, targets) = grid(k);
    let xf = Affine3A::from_rotation_translation(
        Quat::from_axis_angle(unit(rng), rng.gen_range(0.0..1.5)),
        unit(rng) * rng.gen_range(0.0..3.0),
    );
    let mut tris: Vec<[Vec3; 3]> = tris
        .iter()
        .map(|t| t.map(|p| xf.transform_point3(p)))
        .collect();
    let targets = targets.iter().map(|&p| xf.transform_point3(p)).collect();
    let soup = procedural::soup(soup, seed);
    for i in 0..soup.len() {
        tris.push(soup.triangles().get(i).map(|p| p * k as f32 * 0.5));
    }
    (tris, targets, xf)
}

/// Case `seed` of `class` with about `rays` rays.
pub fn case(class: &str, seed: u64, rays: usize) -> Option<Case> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x5eed_u64.wrapping_mul(seed + 1));
    let mut out = RayBatch::with_capacity(rays);
    let scene = match class {
        "vertex" => {
            let mut tris = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]];
            for _ in 0..rng.gen_range(0..4) {
                let a = unit(&mut rng) * 2.0;
                tris.push([a, a + unit(&mut rng), a + unit(&mut rng)]);
            }
            let mut targets: Vec<Vec3> = tris.iter().flatten().copied().collect();
            for t in &tris {
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    targets.push((a + b) * 0.5);
                    targets.push(a + (b - a) * rng.gen::<f32>());
                }
            }
            for _ in 0..rays {
                let target = targets[rng.gen_range(0..targets.len())];
                let (d, dist) = (unit(&mut rng), rng.gen_range(0.5..50.0));
                out.push(through(&mut rng, target, d, dist));
            }
            soup_scene(&format!("vertex:{seed}"), &tris)
        }
        "grid" | "tilted" => {
            let k = rng.gen_range(4..40);
            let (tris, targets) = grid(k);
            let xf = if class == "tilted" {
                Affine3A::from_rotation_translation(
                    Quat::from_axis_angle(unit(&mut rng), rng.gen_range(0.1..1.5)),
                    unit(&mut rng) * rng.gen_range(0.0..30.0),
                )
            } else {
                Affine3A::IDENTITY
            };
            let tris: Vec<[Vec3; 3]> = tris
                .iter()
                .map(|t| t.map(|p| xf.transform_point3(p)))
                .collect();
            let normal = xf.transform_vector3(Vec3::Z).normalize();
            for _ in 0..rays {
                let target = xf.transform_point3(targets[rng.gen_range(0..targets.len())]);
                let dir = match rng.gen_range(0..4) {
                    // Nearly parallel to the plane (angles down to 1e-7 rad).
                    0 | 1 if class == "tilted" => {
                        let inplane = unit(&mut rng).reject_from(normal).normalize_or(Vec3::X);
                        let eps = 10f32.powf(rng.gen_range(-7.0..-1.0));
                        (inplane + normal * eps * if rng.gen() { 1.0 } else { -1.0 }).normalize()
                    }
                    0 => {
                        // Exactly parallel, in the plane.
                        unit(&mut rng).reject_from(normal).normalize_or(Vec3::X)
                    }
                    _ => unit(&mut rng),
                };
                let dist = rng.gen_range(0.5..2.0 * k as f32);
                out.push(through(&mut rng, target, dir, dist));
            }
            soup_scene(&format!("{class}:{seed}"), &tris)
        }
        "fan" => {
            let mut tris = Vec::new();
            let centre = unit(&mut rng);
            let spokes = rng.gen_range(50..600);
            let axis = unit(&mut rng);
            let (b1, b2) = axis.any_orthonormal_pair();
            for s in 0..spokes {
                let a0 = s as f32 / spokes as f32 * std::f32::consts::TAU;
                let a1 = a0 + rng.gen_range(1e-4..0.05);
                let r = rng.gen_range(0.5..3.0);
                let (w0, w1) = (rng.gen_range(-0.01..0.01), rng.gen_range(-0.01..0.01));
                let p = |a: f32, w: f32| centre + (b1 * a.cos() + b2 * a.sin()) * r + axis * w;
                let (q0, q1) = (p(a0, w0), p(a1, w1));
                tris.push([centre, q0, q1]);
            }
            for _ in 0..rays {
                let target = if rng.gen_bool(0.5) {
                    centre
                } else {
                    let t = tris[rng.gen_range(0..tris.len())];
                    t[0] + (t[1] - t[0]) * rng.gen::<f32>()
                };
                let (d, dist) = (unit(&mut rng), rng.gen_range(0.5..10.0));
                out.push(through(&mut rng, target, d, dist));
            }
            soup_scene(&format!("fan:{seed}"), &tris)
        }
        "duplicates" => {
            let base = procedural::icosphere(rng.gen_range(20..500));
            let mut tris = Vec::new();
            for k in 0..2 {
                for i in 0..base.len() {
                    let [a, b, c] = base.triangles().get(i);
                    tris.push(if k == 0 { [a, b, c] } else { [b, c, a] });
                }
            }
            for i in 0..rays {
                let target = if i % 2 == 0 {
                    tris[rng.gen_range(0..tris.len())][rng.gen_range(0..3)]
                } else {
                    unit(&mut rng) * rng.gen_range(0.0..1.0)
                };
                let (d, dist) = (unit(&mut rng), rng.gen_range(1.5..5.0));
                out.push(through(&mut rng, target, d, dist));
            }
            soup_scene(&format!("duplicates:{seed}"), &tris)
        }
        "scale" => {
            let (scale, offset) = match rng.gen_range(0..3) {
                0 => (1e6f32, Vec3::ZERO),
                1 => (1e-6, Vec3::ZERO),
                _ => (1.0, unit(&mut rng) * 1e5),
            };
            let base = procedural::icosphere(rng.gen_range(80..2000));
            let tris: Vec<[Vec3; 3]> = (0..base.len())
                .map(|i| base.triangles().get(i).map(|p| p * scale + offset))
                .collect();
            for _ in 0..rays {
                let t = tris[rng.gen_range(0..tris.len())];
                let target = if rng.gen_bool(0.5) {
                    t[rng.gen_range(0..3)]
                } else {
                    t[0] + (t[1] - t[0]) * rng.gen::<f32>()
                };
                let (d, dist) = (unit(&mut rng), scale * rng.gen_range(1.5..4.0));
                out.push(through(&mut rng, target, d, dist));
            }
            soup_scene(&format!("scale:{seed}"), &tris)
        }
        "directions" => {
            let base = procedural::soup(rng.gen_range(100..4000), seed);
            for _ in 0..rays {
                let o = unit(&mut rng) * rng.gen_range(0.0..3.0);
                let target = base.triangles().get(rng.gen_range(0..base.len()))[0];
                let d = (target - o).normalize_or(Vec3::X);
                let m = match rng.gen_range(0..4) {
                    0 => 1e-38f32 * rng.gen_range(0.01..10.0), // denormal range
                    1 => 1e30 * rng.gen_range(0.1..10.0),
                    2 => 1e-30,
                    _ => 1.0,
                };
                out.push(Ray {
                    origin: o,
                    dir: d * m,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
            let mut s = base;
            s.name = format!("directions:{seed}");
            s
        }
        "camera" => {
            let k = rng.gen_range(4..30);
            let (mut tris, _) = grid(k);
            if rng.gen_bool(0.5) {
                let xf = Affine3A::from_rotation_translation(
                    Quat::from_axis_angle(unit(&mut rng), rng.gen_range(0.1..1.5)),
                    unit(&mut rng) * rng.gen_range(0.0..5.0),
                );
                tris = tris
                    .iter()
                    .map(|t| t.map(|p| xf.transform_point3(p)))
                    .collect();
            }
            if let Some(fan) = case("fan", seed, 1) {
                for i in 0..fan.scene.len() {
                    tris.push(fan.scene.triangles().get(i).map(|p| p * k as f32 * 0.3));
                }
            }
            let scene = soup_scene(&format!("camera:{seed}"), &tris);
            let b = scene.bounds();
            let c = b.center();
            let r = b.extent().length().max(1e-3);
            // From anywhere around, down to grazing elevations over the grid's plane.
            let elev = 10f32.powf(rng.gen_range(-4.0..0.0)) * if rng.gen() { 1.0 } else { -1.0 };
            let az = rng.gen_range(0.0..std::f32::consts::TAU);
            let eye =
                c + Vec3::new(az.cos(), az.sin(), elev).normalize() * r * rng.gen_range(0.6..2.0);
            let cam = crate::rays::Camera {
                eye,
                look: c + unit(&mut rng) * r * 0.1,
                up: if rng.gen() { Vec3::Z } else { Vec3::Y },
                fov_deg: rng.gen_range(20.0..100.0),
            };
            if cam.validate().is_err() {
                return case(class, seed + 1_000_003, rays);
            }
            let side = (rays as f32).sqrt().max(8.0) as u32;
            let (w, h) = (side, (side * 3 / 4).max(8));
            out = cam.rays(w, h);
            if rng.gen_bool(0.3) {
                // Jittered within a pixel: still labelled pinhole (the path tracer's rays).
                for i in 0..out.len() {
                    let d = out.dir(i);
                    let j = unit(&mut rng) * (cam.fov_deg.to_radians() / h as f32) * 0.4;
                    let d = (d + j).normalize();
                    (out.dx[i], out.dy[i], out.dz[i]) = (d.x, d.y, d.z);
                }
            }
            scene
        }
        "grids" => {
            let k = rng.gen_range(3..20);
            let (tris, _, _) = grid_and_soup(&mut rng, k, 150, seed);
            let scene = soup_scene(&format!("grids:{seed}"), &tris);
            let b = scene.bounds();
            let (c, r) = (b.center(), b.extent().length().max(1e-3));
            let side = rng
                .gen_range(2..=16usize)
                .min((rays as f32).sqrt() as usize)
                .max(1);
            let f = side as f32;
            while out.len() + side * side <= rays {
                let o = c + unit(&mut rng) * r * rng.gen_range(0.0..0.8);
                let n = unit(&mut rng);
                let light = c + unit(&mut rng) * r * 1.5;
                let (lt, ls) = unit(&mut rng).any_orthonormal_pair();
                let kind = rng.gen_range(0..3);
                for i in 0..side {
                    for j in 0..side {
                        let (a, bb) = ((j as f32 + 0.5) / f, (i as f32 + 0.5) / f);
                        let (dir, tmax) = match kind {
                            0 => (
                                crate::rays::generate::cosine_direction(n, a, bb),
                                f32::INFINITY,
                            ),
                            1 => (
                                crate::rays::generate::cosine_direction(n, bb, a),
                                f32::INFINITY,
                            ),
                            _ => (
                                light + (lt * (a - 0.5) + ls * (bb - 0.5)) * r * 0.3 - o,
                                1.0,
                            ),
                        };
                        out.push(Ray {
                            origin: o,
                            dir,
                            tmin: 0.0,
                            tmax,
                        });
                    }
                }
            }
            // The rest (fewer than a group) as ordinary rays: trailing rays of a grid batch.
            while out.len() < rays {
                out.push(Ray {
                    origin: c + unit(&mut rng) * r,
                    dir: unit(&mut rng),
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
            out.layout = crate::rays::RayLayout::OriginGrids { side: side as u32 };
            scene
        }
        "light" => {
            let k = rng.gen_range(3..16);
            let (tris, targets, xf) = grid_and_soup(&mut rng, k, 120, seed);
            // Scale and offset (huge and tiny scenes, far from the origin).
            let (m, off) = match rng.gen_range(0..5) {
                0 => (1e-4, Vec3::ZERO),
                1 => (1e4, Vec3::ZERO),
                2 => (1.0, Vec3::new(1e4, -3e3, 2e3)),
                _ => (1.0, Vec3::ZERO),
            };
            let at = |p: Vec3| p * m + off;
            let tris: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(at)).collect();
            let targets: Vec<Vec3> = targets.into_iter().map(at).collect();
            let scene = soup_scene(&format!("light:{seed}"), &tris);
            let b = scene.bounds();
            let (c, r) = (b.center(), b.extent().length().max(1e-30));
            let light = match rng.gen_range(0..4) {
                // On a grid vertex (on two triangles' planes and corners).
                0 => targets[rng.gen_range(0..targets.len())],
                // Inside the bounds.
                1 => c + unit(&mut rng) * r * 0.2,
                // On the grid's plane, off its vertices.
                2 => at(xf.transform_point3(Vec3::new(
                    rng.gen_range(-1.0..k as f32 + 1.0),
                    rng.gen_range(-1.0..k as f32 + 1.0),
                    0.0,
                ))),
                _ => c + unit(&mut rng) * r * 1.5,
            };
            let mut prev = c;
            while out.len() < rays {
                let o = match rng.gen_range(0..8) {
                    // Behind a grid point as seen from the light.
                    0..=2 => {
                        let t = targets[rng.gen_range(0..targets.len())];
                        light + (t - light) * rng.gen_range(1.0..3.0)
                    }
                    // The previous origin again (coincident end points).
                    3 => prev,
                    // On the light (zero length).
                    4 if rng.gen_range(0..4) == 0 => light,
                    _ => c + unit(&mut rng) * r * rng.gen_range(0.0..0.8),
                };
                prev = o;
                let d = light - o;
                let (dir, tmin, tmax) = match rng.gen_range(0..8) {
                    0 => (d, 0.0, 1.0 - 1e-4),
                    1 => (d.normalize_or_zero(), 0.0, d.length()),
                    // Past the light.
                    2 => (d, 0.0, 1.5),
                    3 => (d, 0.25, 1.0),
                    // Not towards the light.
                    4 if rng.gen_range(0..3) == 0 => (unit(&mut rng), 0.0, f32::INFINITY),
                    _ => (d, 0.0, 1.0),
                };
                out.push(Ray {
                    origin: o,
                    dir,
                    tmin,
                    tmax,
                });
            }
            out.layout = crate::rays::RayLayout::ToPoint { target: light };
            scene
        }
        _ => return None,
    };
    Some(Case {
        name: format!("{class}:{seed}"),
        scene,
        rays: out,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_class_generates_reproducibly() {
        for c in CLASSES {
            let a = case(c, 3, 200).unwrap();
            let b = case(c, 3, 200).unwrap();
            if *c != "camera" {
                assert_eq!(a.rays.len(), 200, "{c}");
            }
            assert_eq!(a.rays.dx, b.rays.dx, "{c}");
            assert_eq!(a.scene.triangles().v0, b.scene.triangles().v0, "{c}");
            assert!(!a.scene.is_empty());
        }
        assert!(case("nope", 1, 10).is_none());
    }
}
