//! DACRT's own claims, beyond the answers (every DACRT mode and preset is checked against
//! `naive` by the conformance suite, from its registry entry): which culling ran on which
//! batches, what the leaf rule saves, what packets save. The cases are the adversarial ones of
//! the issue and references.md §8.

use glam::Vec3;
use raysift::rays::generate::{random_in_box, shadow_rays};
use raysift::rays::{Camera, Ray, RayBatch};
use raysift::scene::{procedural, Scene};
use raysift::testkit::{first_difference, Oracle};
use raysift::{tracers, Stats};

fn opts(kv: &[(&str, &str)]) -> Vec<(String, String)> {
    kv.iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// Traces `rays` with DACRT configured by `kv`, checks the answer against naive, returns stats.
fn run(scene: &Scene, rays: &RayBatch, kv: &[(&str, &str)]) -> Stats {
    let want = Oracle::new(scene, rays);
    let mut d = tracers::create("dacrt", &opts(kv)).unwrap();
    d.prepare(scene).unwrap();
    let (got, st) = d.intersect_timed(scene, rays).unwrap();
    if let Some(diff) = first_difference(&want.hits, &got) {
        panic!("{kv:?}: {diff}");
    }
    st
}

/// Screen-space culling and tile leaves run on pinhole batches whose rays lie on their pixels
/// (exact, or jittered within a pixel as the path tracer's primary rays), and not on rays
/// shuffled among pixels (the projection is refused, cones bound the tiles): they change the
/// work counts exactly when they run.
#[test]
fn dacrt_pinhole_culling_runs_where_the_rays_allow() {
    use rand::{Rng, SeedableRng};
    let s = procedural::icosphere(3000);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.3);
    let (w, h) = (48usize, 40usize);
    let exact = cam.rays(w as u32, h as u32);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let jittered = RayBatch::from_rays((0..w * h).map(|k| {
        let (i, j) = (k % w, k / w);
        let d = exact.dir(k);
        let di = exact.dir(if i + 1 < w { k + 1 } else { k - 1 }) - d;
        let dj = exact.dir(if j + 1 < h { k + w } else { k - w }) - d;
        let (a, b): (f32, f32) = (rng.gen(), rng.gen());
        Ray {
            origin: cam.eye,
            dir: (d + a * di + b * dj).normalize(),
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }));
    let mut perm: Vec<usize> = (0..w * h).collect();
    for k in (1..perm.len()).rev() {
        perm.swap(k, rng.gen_range(0..=k));
    }
    let shuffled = RayBatch::from_rays(perm.iter().map(|&k| exact.get(k)));
    for (mut rays, what, culls) in [
        (exact.clone(), "exact", true),
        (jittered, "jittered", true),
        (shuffled, "shuffled", false),
    ] {
        rays.layout = exact.layout;
        let stats = |key: &str, on: &str, leaf: &str| {
            let st = run(
                &s,
                &rays,
                &[
                    ("mode", "packet"),
                    ("tasks", "1"),
                    (key, on),
                    ("pixel_leaf", leaf),
                ],
            );
            let w = &st.work;
            (
                w.get("cone_box"),
                w.get("ray_box"),
                w.get("ray_tri"),
                w.get("nodes"),
            )
        };
        let screen = |on| stats("screen_cull", on, "false");
        assert_eq!(screen("true") != screen("false"), culls, "{what}");
        let leaf = |on| stats("screen_cull", "true", on);
        assert_eq!(leaf("true") != leaf("false"), culls, "{what}");
    }
}

#[test]
fn dacrt_options_are_checked_and_stale_scenes_refused() {
    assert!(tracers::create("dacrt", &opts(&[("bogus", "1")])).is_err());
    assert!(tracers::create("dacrt", &opts(&[("mode", "sideways")])).is_err());
    let s = procedural::soup(100, 1);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let d = tracers::create("dacrt", &[]).unwrap();
    let e = d
        .intersect_timed(&s, &cam.rays(4, 4))
        .unwrap_err()
        .to_string();
    assert!(e.contains("dacrt") && e.contains("not prepared"), "{e}");
}

/// Few incoherent rays against many triangles: the paper's rule ends the recursion at once
/// (fewer than `r_limit` rays) in a naive leaf of every triangle; `leaf_pairs` divides on and
/// tests a small fraction of the pairs, with the same hits. (The paper has no top tree either.)
#[test]
fn dacrt_sparse_rays_divide_on() {
    let s = procedural::icosphere(20_000);
    let rays = random_in_box(&s.bounds(), 15, 5);
    for mode in ["ray", "random"] {
        let max = usize::MAX.to_string();
        let paper = [("mode", mode), ("leaf_pairs", &max), ("top_below", "0")];
        let paper = run(&s, &rays, &paper).work;
        let ours = run(&s, &rays, &[("mode", mode)]).work;
        assert_eq!(paper.get("ray_tri"), 15 * s.len() as u64, "{paper:?}");
        assert!(
            ours.get("ray_tri") * 20 < paper.get("ray_tri"),
            "{ours:?} vs {paper:?}"
        );
        assert!(
            ours.get("nodes") > paper.get("nodes"),
            "{ours:?} vs {paper:?}"
        );
    }
}

/// Conic packets cut ray/box tests; ray mode terminates early; every counter moves.
#[test]
fn dacrt_counters_and_packets_help() {
    let s = procedural::icosphere(20_000);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let rays = cam.rays(256, 256);
    let w = |mode: &str| run(&s, &rays, &[("mode", mode), ("tasks", "1")]).work;
    let (ray, packet, random) = (w("ray"), w("packet"), w("random"));
    assert!(
        packet.get("cone_box") > 0 && packet.get("ray_box") * 2 < ray.get("ray_box"),
        "{packet:?} vs {ray:?}"
    );
    assert!(ray.get("tri_box") > 0 && ray.get("nodes") > 0);
    assert!(ray.get("ray_tri") > 0 && ray.get("leaves") > 0);
    assert_eq!(ray.get("cone_box"), 0);
    // Shadow packets (light cones) are used when allowed.
    let mut d = tracers::create(
        "dacrt",
        &opts(&[
            ("mode", "packet"),
            ("max_shadow_cone_deg", "30"),
            ("light_space", "false"),
        ]),
    )
    .unwrap();
    d.prepare(&s).unwrap();
    let (hits, _) = d.intersect_timed(&s, &rays).unwrap();
    let (shadow, _) = shadow_rays(&s, &rays, &hits, Vec3::new(2.0, 3.0, 2.0));
    let (_, st) = d.occluded_timed(&s, &shadow).unwrap();
    assert!(st.work.get("cone_box") > 0, "{st:?}");
    // Early termination saves ray/box tests over the z-buffer alone.
    assert!(
        ray.get("ray_box") < random.get("ray_box"),
        "{ray:?} vs {random:?}"
    );
    assert!(
        ray.get("ray_tri") <= random.get("ray_tri"),
        "{ray:?} vs {random:?}"
    );
}

/// The per-ray cost adds up to the work counters: every ray/triangle and ray/box test charged to
/// one ray, in every mode (tile leaves, flushed packets, rays, random rays), and packet tests to
/// the packets' live rays.
#[test]
fn dacrt_per_ray_cost_adds_up() {
    use raysift::tracer::RayCost;
    let s = procedural::icosphere(5000);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0);
    let camera = cam.rays(64, 48);
    let random = random_in_box(&s.bounds(), 3000, 2);
    for (rays, what) in [(&camera, "camera"), (&random, "random")] {
        for kv in [
            &[("mode", "packet")][..],
            &[("mode", "packet"), ("pixel_leaf", "false")],
            &[
                ("mode", "packet"),
                ("screen_cull", "false"),
                ("pixel_leaf", "false"),
            ],
            &[("mode", "ray")],
            &[("mode", "random")],
        ] {
            let mut d = tracers::create("dacrt", &opts(kv)).unwrap();
            d.prepare(&s).unwrap();
            let mut hits = raysift::HitBatch::new(0);
            let mut cost = RayCost::default();
            let st = d.intersect(&s, rays, &mut hits, Some(&mut cost)).unwrap();
            let sum = |v: &[u32]| v.iter().map(|&x| x as u64).sum::<u64>();
            assert_eq!(
                sum(&cost.triangles),
                st.work.get("ray_tri"),
                "{what} {kv:?}"
            );
            assert!(
                sum(&cost.tests) >= st.work.get("ray_tri") + st.work.get("ray_box"),
                "{what} {kv:?}"
            );
            let hit = (0..rays.len()).filter(|&i| hits.is_hit(i));
            assert!(hit.clone().count() > 100);
            for i in hit {
                assert!(
                    cost.nodes[i] > 0 && cost.triangles[i] > 0,
                    "{what} {kv:?} ray {i}"
                );
            }
        }
    }
}

/// `phase_times`: off, every `ns_*` counter is 0; on, the phases of camera packets (tile
/// leaves), of a sparse batch down the top tree (its build charged to the call that built it)
/// and of shadow rays all get time, and the answers are unchanged (`run` checks them).
#[test]
fn dacrt_phase_times() {
    let s = procedural::icosphere(20_000);
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0).rays(64, 64);
    let sparse = random_in_box(&s.bounds(), 300, 9);
    let phases = ["ns_setup", "ns_lists", "ns_divide", "ns_leaves"];
    for rays in [&cam, &sparse] {
        let off = run(&s, rays, &[]).work;
        assert!(phases.iter().all(|p| off.get(p) == 0), "{off:?}");
        let on = run(&s, rays, &[("phase_times", "true")]).work;
        assert!(phases.iter().all(|p| on.get(p) > 0), "{on:?}");
        // The time counters leave the work counters alone.
        for w in [
            "ray_box",
            "ray_tri",
            "tri_box",
            "nodes",
            "leaves",
            "top_built",
        ] {
            assert_eq!(on.get(w), off.get(w), "{w}: {on:?} vs {off:?}");
        }
    }
    let mut d = tracers::create(
        "dacrt",
        &opts(&[("phase_times", "true"), ("light_space", "false")]),
    )
    .unwrap();
    d.prepare(&s).unwrap();
    let (hits, _) = d.intersect_timed(&s, &cam).unwrap();
    let (shadow, _) = shadow_rays(&s, &cam, &hits, Vec3::new(2.0, 3.0, 2.0));
    let (_, st) = d.occluded_timed(&s, &shadow).unwrap();
    assert!(phases.iter().all(|p| st.work.get(p) > 0), "{st:?}");
    // The light-space pass has a set-up and a triangle pass (its "leaves"), nothing else.
    let mut d = tracers::create("dacrt", &opts(&[("phase_times", "true")])).unwrap();
    d.prepare(&s).unwrap();
    let (_, st) = d.occluded_timed(&s, &shadow).unwrap();
    let w = &st.work;
    assert!(w.get("light_rays") > 0 && w.get("ns_setup") > 0 && w.get("ns_leaves") > 0);
    assert_eq!((w.get("ns_lists"), w.get("ns_divide")), (0, 0), "{st:?}");
}

/// The light-space pass takes the segments that end at the light and leaves the others to the
/// recursion; on dense meshes it needs far fewer ray/triangle tests than the recursion, and
/// its footprints visit a few buckets per triangle.
#[test]
fn light_space_pass_takes_shadow_segments() {
    // Spheres that shadow each other.
    let s = procedural::tile(&procedural::icosphere(5_000), 3).unwrap();
    let cam = Camera::framing(&s.bounds(), 45.0, 1.0).rays(128, 128);
    let run_occ = |rays: &RayBatch, o: &[(&str, &str)]| {
        let mut d = tracers::create("dacrt", &opts(o)).unwrap();
        d.prepare(&s).unwrap();
        d.occluded_timed(&s, rays).unwrap()
    };
    let mut d = tracers::create("naive", &[]).unwrap();
    d.prepare(&s).unwrap();
    let (hits, _) = d.intersect_timed(&s, &cam).unwrap();
    let (shadow, _) = shadow_rays(&s, &cam, &hits, Vec3::new(2.0, 3.0, 2.0));
    let n = shadow.len() as u64;
    let ((on_occ, on), (off_occ, off)) = (
        run_occ(&shadow, &[]),
        run_occ(&shadow, &[("light_space", "false")]),
    );
    assert_eq!(on_occ, off_occ);
    assert!(on_occ.iter().any(|&o| o) && !on_occ.iter().all(|&o| o));
    assert_eq!(on.work.get("light_rays"), n);
    assert!(
        on.work.get("ray_tri") * 2 < off.work.get("ray_tri"),
        "{on:?} vs {off:?}"
    );
    assert!(on.work.get("light_buckets") < 20 * s.len() as u64, "{on:?}");
    // A quarter of the segments turned off the light (their directions' components rotated;
    // still labelled `ToPoint`): those go through the recursion, with the same answers as
    // naive. (Segments turned straight away from it still fit: their line passes the light.)
    let mut mixed = shadow.clone();
    for i in (0..mixed.len()).step_by(4) {
        (mixed.dx[i], mixed.dy[i], mixed.dz[i]) = (mixed.dy[i], mixed.dz[i], mixed.dx[i]);
    }
    let (occ, st) = run_occ(&mixed, &[]);
    assert_eq!(
        st.work.get("light_rays"),
        n - mixed.len().div_ceil(4) as u64
    );
    assert!(st.work.get("nodes") + st.work.get("leaves") > 0, "{st:?}");
    let mut naive = tracers::create("naive", &[]).unwrap();
    naive.prepare(&s).unwrap();
    assert_eq!(occ, naive.occluded_timed(&s, &mixed).unwrap().0);
}

/// Tile leaves take one `tmin` for all of a task's rays, and the tasks' bands are cut by the
/// work estimate, not where the rays were checked: an image whose lower rows start farther out
/// (two `tmin`s, each uniform over the rows the check sees as one band) must not reach tile
/// leaves with the upper rows' `tmin`. The object sits low in the image so that the balanced
/// bands do not fall on the change.
#[test]
fn camera_bands_with_two_tmins() {
    let s = procedural::icosphere(3000);
    let b = s.bounds();
    let mut cam = Camera::framing(&b, 45.0, 1.0);
    // Look above the sphere: it fills the lower part of the image.
    cam.look += Vec3::Y * (b.max.y - b.min.y) * 0.35;
    let (w, h) = (64u32, 64u32);
    let cut = (b.center() - cam.eye).length();
    for change in [16usize, 24, 32, 40] {
        let mut rays = cam.rays(w, h);
        for k in change * w as usize..rays.len() {
            rays.tmin[k] = cut;
        }
        for tasks in ["1", "2", "3", "4"] {
            run(&s, &rays, &[("tasks", tasks)]);
        }
    }
}
