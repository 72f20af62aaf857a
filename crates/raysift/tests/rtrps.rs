//! The `rtrps` tracer's own cases (issue #14), beyond the conformance suite: ray groups whose
//! planes are tangent to spheres or pass through vertices and edges, grid origins inside
//! spheres, packets of one ray, grids crossing the scene's bounds (hemispheres from surface
//! points), rigid motion of one part of a multi-mesh scene and deformation every frame, the
//! hierarchy's bounds after updates, many moving parts through the part tree, and the counters (culling and the binary tree remove plane
//! tests without changing answers). Every case compares with `naive` bit for bit, in the
//! defaults and every preset.

use glam::{Affine3A, Quat, Vec3};
use raysift::rays::{generate, Camera, Ray, RayBatch, RayLayout};
use raysift::scene::{procedural, Mesh, Scene};
use raysift::testkit::{check_animation, check_tracer, Oracle};
use raysift::tracer::Tracer;
use raysift::tracers::{self, rtrps::Rtrps};

fn check(scene: &Scene, rays: &RayBatch) {
    let entry = tracers::entry("rtrps").unwrap();
    let want = Oracle::new(scene, rays);
    let mut scene = scene.clone();
    check_tracer(entry, &[], &mut scene, rays, &want).unwrap();
    for p in entry.presets {
        check_tracer(entry, &tracers::preset_opts(p), &mut scene, rays, &want)
            .unwrap_or_else(|e| panic!("preset {}: {e}", p.name));
    }
}

/// Groups of `side²` rays from each origin through a grid of directions about `axis`
/// (half-angle `spread` in tangent units), row-major, laid out as `OriginGrids`.
fn grids(origins: &[Vec3], axis: Vec3, side: usize, spread: f32) -> RayBatch {
    let (t, s) = axis.normalize().any_orthonormal_pair();
    let mut rays = Vec::new();
    for &o in origins {
        for i in 0..side {
            for j in 0..side {
                let f = |k: usize| {
                    if side == 1 {
                        0.0
                    } else {
                        (k as f32 / (side - 1) as f32 * 2.0 - 1.0) * spread
                    }
                };
                rays.push(Ray {
                    origin: o,
                    dir: axis.normalize() + t * f(j) + s * f(i),
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
        }
    }
    let mut b = RayBatch::from_rays(rays);
    b.layout = RayLayout::OriginGrids { side: side as u32 };
    b
}

/// A side×side cosine hemisphere grid about `n` from `o` (rows: azimuths, columns: radii), as
/// the renderers make bounce grids.
fn cosine_grid(o: Vec3, n: Vec3, side: usize, rays: &mut Vec<Ray>) {
    for c in 0..side * side {
        let (a, b) = ((c % side) as f32 + 0.5, (c / side) as f32 + 0.5);
        rays.push(Ray {
            origin: o,
            dir: generate::cosine_direction(n, a / side as f32, b / side as f32),
            tmin: 0.0,
            tmax: f32::INFINITY,
        });
    }
}

/// Closest hits and work counters of `rtrps` with `opts` on `rays`.
fn closest_with(
    scene: &Scene,
    rays: &RayBatch,
    opts: &[(&str, &str)],
) -> (raysift::HitBatch, raysift::tracer::Counters) {
    let opts: Vec<(String, String)> = opts
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let mut t = tracers::create("rtrps", &opts).unwrap();
    t.prepare(scene).unwrap();
    let (h, st) = t.intersect_timed(scene, rays).unwrap();
    (h, st.work)
}

fn scene_of(name: &str, tris: &[[Vec3; 3]]) -> Scene {
    let positions = tris.iter().flatten().copied().collect();
    let indices = (0..tris.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    Scene::from_meshes(name, vec![Mesh::new("m", positions, indices)]).unwrap()
}

/// Axis-aligned grid rays from the origin whose row and column planes are the integer planes
/// through a lattice of small triangles' vertices and edges: planes pass exactly through
/// vertices, along edges and tangent to the leaf spheres' contents.
#[test]
fn planes_through_vertices_edges_and_tangent() {
    let mut tris = Vec::new();
    for x in -3..=3 {
        for y in -3..=3 {
            let (x, y) = (x as f32, y as f32);
            tris.push([
                Vec3::new(x, y, 4.0),
                Vec3::new(x + 1.0, y, 4.0),
                Vec3::new(x, y + 1.0, 4.0),
            ]);
            tris.push([
                Vec3::new(x, y, 6.0),
                Vec3::new(x + 0.5, y + 0.5, 6.5),
                Vec3::new(x, y + 1.0, 6.0),
            ]);
        }
    }
    let scene = scene_of("lattice", &tris);
    let mut rays = Vec::new();
    for side in [4usize, 7] {
        for i in 0..side {
            for j in 0..side {
                // Directions through lattice points at z = 4: x, y integers.
                let (x, y) = (j as f32 - (side / 2) as f32, i as f32 - (side / 2) as f32);
                rays.push(Ray {
                    origin: Vec3::ZERO,
                    dir: Vec3::new(x, y, 4.0),
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
        }
        let mut b = RayBatch::from_rays(std::mem::take(&mut rays));
        b.layout = RayLayout::OriginGrids { side: side as u32 };
        check(&scene, &b);
    }
}

/// Grid origins inside spheres: at the centre of an icosphere, on its surface and at a vertex.
#[test]
fn grid_origin_inside_spheres() {
    let scene = procedural::icosphere(500);
    let v = scene.triangles().v0[7];
    let origins = [
        Vec3::ZERO,
        v,
        v * 0.999,
        v * 1.001,
        Vec3::new(0.3, -0.2, 0.1),
    ];
    for axis in [Vec3::X, Vec3::new(1.0, 2.0, -0.5)] {
        check(&scene, &grids(&origins, axis, 8, 0.9));
        check(&scene, &grids(&origins, axis, 5, 3.0));
    }
}

/// The triangle-test forms (`tri_test`: Möller one ray at a time, the common-origin form in
/// lanes, and the box check) on what tells them apart: duplicated triangles (equal `t`: the
/// smaller id must win, whatever order the leaves come in), a coplanar overlapping layer, rays
/// of one group with different `tmin` (a lane each) and `tmax` ending on the wall, groups of
/// 1–9 columns (partial lane vectors, padded rows), and origins `0.0` against `-0.0` (not one
/// origin bit for bit: traced as random rays). Every preset runs too (`check`).
#[test]
fn triangle_test_forms_on_ties_tmin_per_ray_and_signed_zero_origins() {
    let mut tris = Vec::new();
    for x in -4..4 {
        for y in -4..4 {
            let (x, y) = (x as f32 * 0.5, y as f32 * 0.5);
            let t = [
                Vec3::new(x, y, 3.0),
                Vec3::new(x + 0.5, y, 3.0),
                Vec3::new(x, y + 0.5, 3.0),
            ];
            tris.push(t);
            tris.push(t); // duplicate: ties in t
            tris.push([t[1], t[0], t[2]]); // same plane, other winding
            tris.push([
                Vec3::new(x + 0.25, y, 3.0),
                Vec3::new(x + 0.75, y + 0.25, 3.0),
                Vec3::new(x + 0.25, y + 0.5, 3.0),
            ]);
        }
    }
    let scene = scene_of("ties", &tris);
    for side in [1usize, 3, 8, 9] {
        let origins = [
            Vec3::new(0.1, 0.2, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(-0.0, 0.0, 0.0),
            Vec3::new(-0.3, 0.05, 1.0),
        ];
        let mut b = grids(&origins, Vec3::Z, side, 0.5);
        for k in 0..b.len() {
            match k % 5 {
                1 => b.tmin[k] = 0.5,
                2 => b.tmin[k] = 4.0,           // past the wall: no hit
                3 => b.tmax[k] = 3.0 / b.dz[k], // ends on the wall
                _ => {}
            }
        }
        // The second and third origins differ only in the sign of a zero: each group has one.
        for k in 0..side * side {
            b.ox[2 * side * side + k] = if k % 2 == 0 { -0.0 } else { 0.0 };
        }
        check(&scene, &b);
        let opts = [
            [("tri_test", "moller"), ("box_check", "false")],
            [("tri_test", "origin"), ("box_check", "false")],
            [("tri_test", "origin"), ("box_check", "true")],
            [("tri_test", "aligned"), ("box_check", "false")],
        ];
        let results: Vec<_> = opts.iter().map(|o| closest_with(&scene, &b, o).0).collect();
        for r in &results[1..] {
            assert_eq!(r.prim, results[0].prim, "side {side}");
            assert_eq!(r.t, results[0].t, "side {side}");
        }
        assert!(results[0].prim.iter().any(|&p| p != u32::MAX));
    }
}

/// The aligned ray-plane form (`tri_test=aligned`) only removes triangle tests: with leaves of
/// one triangle, every reproduced ray it refuses is one the common-origin form tests and finds
/// no hit in, so the counts add up exactly and the answers are equal, for closest hits and
/// occlusion, from jittered grids of 16×16 and 5×5 around an icosphere, from inside it, and
/// from its surface (a body beneath each origin). Every preset runs too (`check`).
#[test]
fn aligned_form_only_removes_tests() {
    let scene = procedural::icosphere(3000);
    let mut origins: Vec<Vec3> = (0..8)
        .map(|k| Vec3::new(2.5, k as f32 * 0.2 - 0.7, 0.3))
        .collect();
    origins.push(Vec3::new(0.2, 0.1, 0.0));
    origins.push(Vec3::new(0.0, 0.0, 1.0));
    for (side, spread) in [(16usize, 0.4f32), (5, 0.05)] {
        let mut rays = grids(&origins, -Vec3::X + Vec3::Z * 0.2, side, spread);
        // Jittered by up to a third of a cell: the rows' `a_y` spread, which the spans bound.
        let cell = 2.0 * spread / side as f32;
        for k in 0..rays.len() {
            let h = |s: u32| ((k as u32).wrapping_mul(2654435761).wrapping_add(s) >> 8) as f32;
            rays.dy[k] += cell * 0.33 * ((h(1) / 16777216.0) * 2.0 - 1.0);
            rays.dz[k] += cell * 0.33 * ((h(977) / 16777216.0) * 2.0 - 1.0);
        }
        let (h_o, o) = closest_with(&scene, &rays, &[("tri_test", "origin")]);
        let (h_a, a) = closest_with(&scene, &rays, &[("tri_test", "aligned")]);
        assert_eq!(raysift::testkit::first_difference(&h_o, &h_a), None);
        assert_eq!(o.get("span_culled") + o.get("spans"), 0, "{o:?}");
        assert!(a.get("span_culled") > 0 && a.get("spans") > 0, "{a:?}");
        assert_eq!(
            a.get("tri_tests") + a.get("span_culled"),
            o.get("tri_tests"),
            "side {side}: {a:?} vs {o:?}"
        );
        assert!(
            6 * a.get("tri_tests") < 5 * o.get("tri_tests"),
            "{a:?} vs {o:?}"
        );
        let any = |opts: &[(&str, &str)]| {
            let opts: Vec<(String, String)> = opts
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            let mut t = tracers::create("rtrps", &opts).unwrap();
            t.prepare(&scene).unwrap();
            t.occluded_timed(&scene, &rays).unwrap()
        };
        let (occ_o, st_o) = any(&[("tri_test", "origin")]);
        let (occ_a, st_a) = any(&[("tri_test", "aligned")]);
        assert_eq!(occ_o, occ_a);
        assert!(occ_a.iter().any(|&b| b) && occ_a.iter().any(|&b| !b));
        assert!(st_a.work.get("span_culled") > 0, "{:?}", st_a.work);
        assert!(st_a.work.get("tri_tests") < st_o.work.get("tri_tests"));
        check(&scene, &rays);
    }
}

/// The scratch of a chunk is a fixed set of per-group arrays: for 16×16 grids it stays between
/// 12 and 32 KiB (per ray of a group: 12 B of frame directions and 4 B in each of 8 arrays for
/// any hits, 12 for closest hits; the fans and the leaf's prepared triangles besides), and does
/// not grow with the batch.
#[test]
fn scratch_is_per_group_not_per_batch() {
    let scene = procedural::icosphere(2000);
    let mut t = Rtrps::new(Default::default()).unwrap();
    t.prepare(&scene).unwrap();
    let origins = |n: usize| -> Vec<Vec3> {
        (0..n)
            .map(|k| {
                Vec3::new(
                    3.0,
                    (k % 20) as f32 * 0.05 - 0.5,
                    (k / 20) as f32 * 0.05 - 0.5,
                )
            })
            .collect()
    };
    let mut peaks = Vec::new();
    for n in [40, 400] {
        let b = grids(&origins(n), -Vec3::X, 16, 0.2);
        let (_, closest) = t.intersect_timed(&scene, &b).unwrap();
        let (_, any) = t.occluded_timed(&scene, &b).unwrap();
        assert!(closest.work.get("groups") > 0);
        for (what, p) in [("closest", closest.peak_bytes), ("any", any.peak_bytes)] {
            assert!((12 << 10..=32 << 10).contains(&p), "{what}: {p} B");
        }
        assert!(closest.peak_bytes > any.peak_bytes);
        peaks.push((closest.peak_bytes, any.peak_bytes));
    }
    assert_eq!(peaks[0], peaks[1], "the scratch grew with the batch");
}

/// Packets of one ray: `OriginGrids { side: 1 }` and a 1×N image.
#[test]
fn packets_of_one_ray() {
    let scene = procedural::icosphere(200);
    let origins: Vec<Vec3> = (0..40)
        .map(|k| Vec3::new(3.0, k as f32 * 0.05 - 1.0, 0.2))
        .collect();
    check(&scene, &grids(&origins, -Vec3::X, 1, 0.0));
    let cam = Camera::framing(&scene.bounds(), 40.0, 1.0).rays(1, 9);
    check(&scene, &cam);
}

/// The depth cull (`depth_cull`): layers of triangles behind a grid's origin, through it, just
/// ahead and at the rays' ends: segments ending exactly on a layer (t = tmax), one ulp short
/// of it, and grids with a negative `tmin` that reach the layer behind (the cull must switch
/// off), each grid pointing forwards and backwards.
#[test]
fn depth_cull_keeps_hits_at_both_ends_and_behind() {
    let mut tris = Vec::new();
    for z in [-1.0f32, 0.0, 2.0, 2.000_001] {
        for x in -4..4 {
            for y in -4..4 {
                let (x, y) = (x as f32 * 0.5, y as f32 * 0.5);
                tris.push([
                    Vec3::new(x, y, z),
                    Vec3::new(x + 0.5, y, z),
                    Vec3::new(x, y + 0.5, z + 0.01),
                ]);
            }
        }
    }
    let scene = scene_of("layers", &tris);
    let origins = [
        Vec3::new(0.1, 0.2, 0.5),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::ZERO,
    ];
    for axis in [Vec3::Z, -Vec3::Z, Vec3::new(0.2, -0.1, 1.0)] {
        let base = grids(&origins, axis, 6, 0.4);
        let mut ends = base.clone();
        let mut short = base.clone();
        let mut behind = base.clone();
        for i in 0..base.len() {
            // t at which the ray meets the plane z = 2 (or z = -1 going backwards).
            let (oz, dz) = (base.oz[i], base.dz[i]);
            let t = if dz > 0.0 {
                (2.0 - oz) / dz
            } else {
                (-1.0 - oz) / dz
            };
            ends.tmax[i] = t;
            short.tmax[i] = t.next_down();
            behind.tmin[i] = -2.0;
            behind.tmax[i] = t;
        }
        for b in [&base, &ends, &short, &behind] {
            check(&scene, b);
        }
    }
}

/// The depth cull, the binary levels and the per-ray check remove work without changing
/// answers: grids from inside an icosphere see half of it behind their origin.
#[test]
fn depth_cull_and_binary_levels_remove_work() {
    let scene = procedural::icosphere(3000);
    let origins: Vec<Vec3> = (0..12)
        .map(|k| Vec3::new(0.5, k as f32 * 0.05 - 0.3, 0.1))
        .collect();
    let rays = grids(&origins, -Vec3::X, 16, 0.3);
    let run = |opts: &[(&str, &str)]| closest_with(&scene, &rays, opts);
    // Without the hit cut, which would take some of the rays the check drops.
    let (h_off, off) = run(&[("depth_cull", "false"), ("hit_cut", "false")]);
    let (h_on, on) = run(&[("hit_cut", "false")]);
    let (h_flat, flat) = run(&[("levels", "flat"), ("hit_cut", "false")]);
    let (h_nocheck, nocheck) = run(&[("ray_check", "false"), ("hit_cut", "false")]);
    // The per-ray check drops reproduced rays that miss the leaf sphere before their triangles.
    assert_eq!(nocheck.get("ray_culled"), 0);
    assert!(on.get("ray_culled") > 0, "{on:?}");
    assert_eq!(
        on.get("tri_tests") + on.get("ray_culled"),
        nocheck.get("tri_tests"),
        "{on:?} vs {nocheck:?}"
    );
    assert_eq!(raysift::testkit::first_difference(&h_nocheck, &h_on), None);
    assert_eq!(off.get("depth_culled"), 0);
    assert!(on.get("depth_culled") > 0, "{on:?}");
    assert!(
        on.get("rays_reproduced") < off.get("rays_reproduced"),
        "{on:?} vs {off:?}"
    );
    assert!(
        on.get("spheres_visited") < flat.get("spheres_visited"),
        "{on:?} vs {flat:?}"
    );
    assert_eq!(raysift::testkit::first_difference(&h_off, &h_on), None);
    assert_eq!(raysift::testkit::first_difference(&h_off, &h_flat), None);
    check(&scene, &rays);
}

/// Closest hits cut the walk (`hit_cut`, `near_first`): a camera looking through a stack of
/// 16 layers, the even ones present twice (the duplicate has the larger id: ties must go to the
/// first), the front one bent towards the camera, with directions of length 1e-3, 1 and 1e3 (the cut
/// compares `t·|d|` with distances along the unit direction). The cut removes triangle tests,
/// culls spheres behind the front layer, and answers stay equal to `naive`'s in every preset.
#[test]
fn closest_hits_cut_the_walk() {
    let mut tris = Vec::new();
    for copy in 0..2 {
        for layer in 0..16 {
            let z = -(layer as f32) * 0.25;
            for x in -6..6 {
                for y in -6..6 {
                    let (x, y) = (x as f32 * 0.5, y as f32 * 0.5);
                    // Layer 0 is bent: its triangles come nearer the camera to the right.
                    let lift = if layer == 0 { 0.05 * x } else { 0.0 };
                    if copy == 1 && layer % 2 == 1 {
                        continue;
                    }
                    tris.push([
                        Vec3::new(x, y, z + lift),
                        Vec3::new(x + 0.5, y, z + lift),
                        Vec3::new(x, y + 0.5, z + lift),
                    ]);
                    tris.push([
                        Vec3::new(x + 0.5, y, z + lift),
                        Vec3::new(x + 0.5, y + 0.5, z + lift),
                        Vec3::new(x, y + 0.5, z + lift),
                    ]);
                }
            }
        }
    }
    let scene = scene_of("stack", &tris);
    let cam = Camera::framing(&scene.bounds(), 50.0, 1.0).rays(48, 40);
    for len in [1e3f32, 1.0, 1e-3] {
        let mut rays = cam.clone();
        for i in 0..rays.len() {
            let d = rays.dir(i).normalize() * len;
            (rays.dx[i], rays.dy[i], rays.dz[i]) = (d.x, d.y, d.z);
        }
        let run = |opts: &[(&str, &str)]| closest_with(&scene, &rays, opts);
        let (h_on, on) = run(&[]);
        let (h_off, off) = run(&[("hit_cut", "false"), ("near_first", "false")]);
        let (h_order, order) = run(&[("near_first", "false")]);
        assert_eq!(raysift::testkit::first_difference(&h_off, &h_on), None);
        assert_eq!(raysift::testkit::first_difference(&h_off, &h_order), None);
        assert_eq!(off.get("hit_culled") + off.get("depth_culled"), 0);
        assert!(
            on.get("hit_culled") > 0 && on.get("depth_culled") > 0,
            "{on:?}"
        );
        assert!(
            2 * on.get("tri_tests") < off.get("tri_tests")
                && on.get("spheres_visited") < off.get("spheres_visited"),
            "{on:?} vs {off:?}"
        );
        // Nearer children first find the front layer before the layers behind it.
        assert!(
            on.get("tri_tests") < order.get("tri_tests"),
            "{on:?} vs {order:?}"
        );
        check(&scene, &rays);
    }
}

/// Cosine hemisphere grids whose rows are azimuths and whose columns are radii (the renderers'
/// bounce grids): each row's last ray minus its first cancels against the opposite row's, so
/// the rows' mean "along" direction is (almost) the grids' mean direction; the grid frame must
/// still come out orthonormal (it did not: a skewed frame lost hits on the bunny's bounce
/// grids). Arbitrary normals, origins inside an icosphere and near a soup.
#[test]
fn hemisphere_grids_whose_rows_cancel() {
    let mut meshes = vec![procedural::icosphere(2000).meshes()[0].clone()];
    let mut soup = procedural::soup(300, 5).meshes()[0].clone();
    soup.transform = Affine3A::from_scale(Vec3::splat(0.4));
    meshes.push(soup);
    let scene = Scene::from_meshes("sphere and soup", meshes).unwrap();
    let side = 8;
    let mut rays = Vec::new();
    for k in 0..40u32 {
        let f = k as f32;
        let n = Vec3::new((f * 1.7).sin(), (f * 2.3).cos(), (f * 0.9).sin() + 0.1).normalize();
        let o = Vec3::new((f * 0.37).sin(), (f * 0.53).cos(), (f * 0.71).sin()) * 0.45;
        cosine_grid(o, n, side, &mut rays);
    }
    let mut batch = RayBatch::from_rays(rays);
    batch.layout = RayLayout::OriginGrids { side: side as u32 };
    check(&scene, &batch);
    // The defaults send such loose grids to random rays (`max_slack`): as ray-planes too.
    let (_, loose) = closest_with(&scene, &batch, &[]);
    assert_eq!(loose.get("slack_groups"), 40, "{loose:?}");
    let entry = tracers::entry("rtrps").unwrap();
    let want = Oracle::new(&scene, &batch);
    let mut sc = scene.clone();
    for extra in [&[][..], &[("levels", "flat"), ("ray_check", "false")][..]] {
        let mut opts = vec![("max_slack".to_string(), "1".to_string())];
        opts.extend(extra.iter().map(|(k, v)| (k.to_string(), v.to_string())));
        check_tracer(entry, &opts, &mut sc, &batch, &want).unwrap();
    }
    let (_, tight) = closest_with(&scene, &batch, &[("max_slack", "1")]);
    assert_eq!((tight.get("groups"), tight.get("slack_groups")), (40, 0));
}

/// Hemisphere grids (a diffuse bounce) from surface points of the Cornell box, inside and out:
/// the grids cross the scene's bounds; and area-light shadow grids (16×16).
#[test]
fn grids_crossing_the_scene_bounds() {
    let scene = procedural::cornell();
    let b = scene.bounds();
    let cam = Camera::framing(&b, 40.0, 1.0).rays(16, 16);
    let mut t = tracers::create("naive", &[]).unwrap();
    t.prepare(&scene).unwrap();
    let (hits, _) = t.intersect_timed(&scene, &cam).unwrap();
    let eps = generate::surface_offset(&scene);
    let mut rays = Vec::new();
    let side = 6;
    for i in (0..cam.len()).filter(|&i| hits.is_hit(i)).step_by(7) {
        let (p, n) = generate::hit_frame(&scene, &cam, &hits, i);
        cosine_grid(p + n * eps, n, side, &mut rays);
    }
    let mut batch = RayBatch::from_rays(rays);
    batch.layout = RayLayout::OriginGrids { side: side as u32 };
    check(&scene, &batch);
    // Shadow grids towards a square light below the ceiling, as segments ending on it.
    let top = b.max.y - 0.01 * (b.max.y - b.min.y);
    let centre = Vec3::new((b.min.x + b.max.x) * 0.5, top, (b.min.z + b.max.z) * 0.5);
    let mut rays = Vec::new();
    for i in (0..cam.len()).filter(|&i| hits.is_hit(i)).step_by(11) {
        let (p, n) = generate::hit_frame(&scene, &cam, &hits, i);
        let o = p + n * eps;
        for r in 0..16 {
            for c in 0..16 {
                let y = centre + Vec3::new(c as f32 - 7.5, 0.0, r as f32 - 7.5) * 0.02;
                rays.push(Ray {
                    origin: o,
                    dir: y - o,
                    tmin: 0.0,
                    tmax: 1.0,
                });
            }
        }
    }
    let mut batch = RayBatch::from_rays(rays);
    batch.layout = RayLayout::OriginGrids { side: 16 };
    check(&scene, &batch);
}

/// Three parts; one spins and rises every frame (rigid), another deforms; answers equal
/// `naive` on the moved scene every frame, on grids, camera tiles and random rays.
#[test]
fn rigid_motion_of_one_part_of_a_multi_mesh_scene() {
    let parts = [
        procedural::icosphere(300),
        procedural::soup(200, 4),
        procedural::icosphere(80),
    ];
    let meshes: Vec<Mesh> = parts
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let mut m = p.meshes()[0].clone();
            m.transform = Affine3A::from_translation(Vec3::new(k as f32 * 1.5 - 1.5, 0.0, 0.0));
            m
        })
        .collect();
    let scene = Scene::from_meshes("three parts", meshes).unwrap();
    let cam = Camera::framing(&scene.bounds(), 50.0, 1.0).rays(40, 40);
    let origins: Vec<Vec3> = (0..12)
        .map(|k| Vec3::new(k as f32 * 0.3 - 1.8, 0.2, 3.0))
        .collect();
    let g = grids(&origins, -Vec3::Z, 8, 0.5);
    let random = generate::random_in_box(&scene.bounds(), 600, 3);
    let step = |s: &mut Scene, f: usize| {
        let spin = Quat::from_rotation_y(0.4 * f as f32) * Quat::from_rotation_x(0.3);
        s.set_transform(
            1,
            Affine3A::from_rotation_translation(spin, Vec3::new(0.0, 0.1 * f as f32, 0.0)),
        )
        .unwrap();
        if f.is_multiple_of(2) {
            let pos: Vec<Vec3> = s.meshes()[2]
                .positions
                .iter()
                .map(|p| *p * (1.0 + 0.1 * f as f32))
                .collect();
            s.replace_positions(2, pos).unwrap();
        }
    };
    for rays in [&cam, &g, &random] {
        if let Err(e) = check_animation(&scene, 5, step, rays) {
            panic!("{e}");
        }
    }
    // The hierarchy bounds the moved triangles, and a rigid frame rewrites only one part.
    let mut scene = scene;
    let mut t = Rtrps::new(raysift::tracers::rtrps::Config {
        retighten: false,
        ..Default::default()
    })
    .unwrap();
    t.prepare(&scene).unwrap();
    for f in 1..5 {
        scene
            .set_transform(
                1,
                Affine3A::from_rotation_translation(
                    Quat::from_rotation_z(f as f32),
                    Vec3::Y * f as f32,
                ),
            )
            .unwrap();
        let st = t.prepare(&scene).unwrap();
        // Without `retighten`, the first motion trades the part's tight radii for the
        // any-rotation ones (a refit of its leaves, once); later motions touch no leaf.
        let refit = if f == 1 {
            t.spheres().parts[1].leaves.len() as u64
        } else {
            0
        };
        assert_eq!(
            (
                st.built.get("rebuilt"),
                st.built.get("parts_moved"),
                st.built.get("leaves_refit")
            ),
            (0, 1, refit)
        );
        assert!(!t.spheres().parts[1].tight && t.spheres().parts[0].tight);
        t.spheres().validate(&scene).unwrap();
    }
    // `retighten` (the default): every motion refits the moved part to tight radii for its
    // new transform.
    let mut tt = Rtrps::new(Default::default()).unwrap();
    tt.prepare(&scene).unwrap();
    for f in 5..8 {
        scene
            .set_transform(1, Affine3A::from_rotation_x(f as f32 * 0.7))
            .unwrap();
        let st = tt.prepare(&scene).unwrap();
        assert_eq!(
            st.built.get("leaves_refit"),
            tt.spheres().parts[1].leaves.len() as u64
        );
        assert!(tt.spheres().parts[1].tight);
        tt.spheres().validate(&scene).unwrap();
    }
    let pos: Vec<Vec3> = scene.meshes()[0]
        .positions
        .iter()
        .map(|p| *p * 2.0 + Vec3::X)
        .collect();
    scene.replace_positions(0, pos).unwrap();
    let st = t.prepare(&scene).unwrap();
    assert_eq!(
        st.built.get("leaves_refit"),
        t.spheres().parts[0].leaves.len() as u64
    );
    assert!(t.spheres().parts[0].tight);
    t.spheres().validate(&scene).unwrap();
}

/// Sixty parts in a lattice, every one spinning about its own axis and drifting each frame, a
/// few deforming: the part tree (rebuilt at every update) has many levels, answers equal
/// `naive` every frame on camera tiles, grids and random rays, its spheres bound the moved
/// parts, and a group visits fewer spheres than a walk over every part would test.
#[test]
fn many_moving_parts_through_the_part_tree() {
    let mut meshes = Vec::new();
    for k in 0..60u32 {
        let base = if k % 3 == 0 {
            procedural::soup(12, k as u64)
        } else {
            procedural::icosphere(20 + k as usize)
        };
        let mut m = base.meshes()[0].clone();
        let (x, y, z) = ((k % 5) as f32, (k / 5 % 4) as f32, (k / 20) as f32);
        m.transform = Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.3),
            Quat::IDENTITY,
            Vec3::new(x, y, z) * 2.5,
        );
        meshes.push(m);
    }
    let scene = Scene::from_meshes("lattice of parts", meshes).unwrap();
    let cam = Camera::framing(&scene.bounds(), 50.0, 1.0).rays(48, 40);
    let origins: Vec<Vec3> = (0..10)
        .map(|k| Vec3::new(k as f32 * 1.1, 3.7, 9.0))
        .collect();
    let g = grids(&origins, Vec3::new(0.1, 0.0, -1.0), 8, 0.6);
    let random = generate::random_in_box(&scene.bounds(), 500, 9);
    let step = |s: &mut Scene, f: usize| {
        for m in 0..s.meshes().len() {
            let xf = s.meshes()[m].transform;
            let axis = Vec3::new(1.0, m as f32, 2.0).normalize();
            let spin = Quat::from_axis_angle(axis, 0.3 + 0.01 * m as f32);
            let drift = Vec3::new(0.05, -0.03 * (m % 3) as f32, 0.02) * f as f32;
            let t = Affine3A::from_translation(Vec3::from(xf.translation) + drift);
            s.set_transform(
                m,
                t * Affine3A::from_quat(spin) * Affine3A::from_mat3(xf.matrix3.into()),
            )
            .unwrap();
        }
        if f.is_multiple_of(2) {
            let pos: Vec<Vec3> = s.meshes()[7].positions.iter().map(|p| *p * 1.2).collect();
            s.replace_positions(7, pos).unwrap();
        }
    };
    for rays in [&cam, &g, &random] {
        if let Err(e) = check_animation(&scene, 4, step, rays) {
            panic!("{e}");
        }
    }
    // Narrow grids, each of which sees a few parts.
    let narrow = grids(&origins, Vec3::new(0.1, 0.0, -1.0), 8, 0.03);
    let mut scene = scene;
    let mut t = Rtrps::new(Default::default()).unwrap();
    for f in 0..3 {
        step(&mut scene, f);
        t.prepare(&scene).unwrap();
        let tree = t.spheres();
        tree.validate(&scene).unwrap();
        assert!(
            tree.pnode_c.len() >= 15,
            "{} part tree nodes",
            tree.pnode_c.len()
        );
        let (_, st) = t.intersect_timed(&scene, &narrow).unwrap();
        // Without the tree each of the 10 groups tests all 60 part spheres.
        let tested = st.work.get("part_tests");
        assert_eq!(st.work.get("groups"), 10);
        assert!(
            tested > 0 && tested < 10 * 60 / 2,
            "{tested} part spheres tested"
        );
    }
}

/// Culling and the binary tree remove plane tests (and never add reproduced rays); the group
/// path serves the grids; random mode reproduces nothing.
#[test]
fn counters_split_plane_tests() {
    let scene = procedural::icosphere(2000);
    let origins: Vec<Vec3> = (0..20)
        .map(|k| Vec3::new(3.0, k as f32 * 0.1 - 1.0, 0.5))
        .collect();
    let rays = grids(&origins, -Vec3::X, 16, 0.4);
    let run = |opts: &[(&str, &str)]| closest_with(&scene, &rays, opts);
    let (h_all, all) = run(&[("culling", "false"), ("tree", "false")]);
    let (h_cull, cull) = run(&[("tree", "false")]);
    let (h_both, both) = run(&[]);
    let (h_rand, rand) = run(&[("mode", "random")]);
    assert_eq!(all.get("groups"), 20);
    assert_eq!(all.get("outline_tests"), 0);
    let total = |c: &raysift::tracer::Counters| c.get("outline_tests") + c.get("internal_tests");
    assert!(total(&cull) < total(&all), "{cull:?} vs {all:?}");
    assert!(total(&both) < total(&cull), "{both:?} vs {cull:?}");
    assert!(both.get("rays_reproduced") <= all.get("rays_reproduced"));
    assert_eq!(rand.get("rays_reproduced"), 0);
    assert_eq!(rand.get("random_rays"), rays.len() as u64);
    for h in [&h_cull, &h_both, &h_rand] {
        assert_eq!(raysift::testkit::first_difference(&h_all, h), None);
    }
}

/// Unknown options are refused.
#[test]
fn bad_options_are_errors() {
    assert!(tracers::create("rtrps", &[("leafsize".into(), "2".into())]).is_err());
    assert!(tracers::create("rtrps", &[("leaf_size".into(), "0".into())]).is_err());
    assert!(tracers::create("rtrps", &[("packet".into(), "65".into())]).is_err());
    assert!(tracers::create("rtrps", &[("centre".into(), "middle".into())]).is_err());
    for bad in ["1.5", "-0.1", "NaN"] {
        let e = tracers::create("rtrps", &[("max_slack".into(), bad.into())]);
        assert!(
            e.is_err_and(|e| e.to_string().contains("max_slack")),
            "{bad}"
        );
    }
}
