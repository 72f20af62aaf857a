//! DACRT's memory is deterministic (Mora 2011, §1 and §3.2): the bytes the tracer allocates are
//! a linear function `a·T + b·R + c` of the triangle and ray counts, identical between runs and
//! independent of the scene's shape. Checked with a counting global allocator on two very
//! different scenes of equal size (a random soup and an icosphere), in every mode. The buffers of
//! a call stay with the tracer: later calls of the same size allocate nothing.

use raysift::rays::generate::random_in_box;
use raysift::rays::{Camera, RayLayout};
use raysift::scene::{procedural, Scene};
use raysift::{tracers, HitBatch, RayBatch};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// Counts bytes requested (total, and currently live) and forwards to the system allocator.
struct Counting;

static TOTAL: AtomicUsize = AtomicUsize::new(0);
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every method forwards to `System` with the caller's layout and pointer unchanged, so
// `System`'s guarantees hold; the counters are plain atomics and never affect the allocation.
// Exercised by every allocation of this test binary (the test below checks the counts).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        TOTAL.fetch_add(l.size(), Relaxed);
        let now = LIVE.fetch_add(l.size(), Relaxed) + l.size();
        PEAK.fetch_max(now, Relaxed);
        System.alloc(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size(), Relaxed);
        System.dealloc(p, l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        TOTAL.fetch_add(new, Relaxed);
        let now = LIVE.fetch_add(new, Relaxed) + new;
        PEAK.fetch_max(now, Relaxed);
        LIVE.fetch_sub(l.size(), Relaxed);
        System.realloc(p, l, new)
    }
}

#[global_allocator]
static A: Counting = Counting;

/// The allocator counts every thread: the tests of this file take turns.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// (total bytes allocated, peak live bytes above the start) while running `f`, on a worker
/// of rayon's pool: a call made from outside the pool sends it a job, and its queue takes a
/// 1520-byte block every 63 jobs, whoever sent them (not the tracer's memory).
fn measure(f: impl FnOnce() + Send) -> (usize, usize) {
    rayon::scope(|_| {
        let (t0, l0) = (TOTAL.load(Relaxed), LIVE.load(Relaxed));
        PEAK.store(l0, Relaxed);
        f();
        (TOTAL.load(Relaxed) - t0, PEAK.load(Relaxed) - l0)
    })
}

struct Case {
    prepare: usize,
    /// First calls of fresh tracers.
    intersect: (usize, usize),
    occluded: (usize, usize),
    /// An occlusion call after the intersection call on the same tracer (buffers reused), and
    /// the bytes that tracer then holds.
    again: usize,
    held: usize,
}

fn run(scene: &Scene, rays: &RayBatch, mode: &str, tasks: usize, shadow_deg: &str) -> Case {
    // The recursion's memory (the light-space pass has its own test below).
    run_opts(
        scene,
        rays,
        &[
            ("mode", mode),
            ("tasks", &tasks.to_string()),
            ("max_shadow_cone_deg", shadow_deg),
            ("light_space", "false"),
        ],
    )
}

fn run_opts(scene: &Scene, rays: &RayBatch, opts: &[(&str, &str)]) -> Case {
    let opts: Vec<(String, String)> = opts
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let mut d = tracers::create("dacrt", &opts).unwrap();
    // Outputs are the caller's: allocate them outside the measurement.
    let mut hits = HitBatch::new(rays.len());
    let mut occ = vec![false; rays.len()];
    // Warm up rayon's pool and thread-locals.
    d.prepare(scene).unwrap();
    d.intersect(scene, rays, &mut hits, None).unwrap();
    d.occluded(scene, rays, &mut occ, None).unwrap();
    let mut d = tracers::create("dacrt", &opts).unwrap();
    let (prepare, _) = measure(|| {
        d.prepare(scene).unwrap();
    });
    let intersect = measure(|| {
        d.intersect(scene, rays, &mut hits, None).unwrap();
    });
    let (again, _) = measure(|| {
        d.occluded(scene, rays, &mut occ, None).unwrap();
    });
    let held = d.bytes();
    let mut d = tracers::create("dacrt", &opts).unwrap();
    d.prepare(scene).unwrap();
    let occluded = measure(|| {
        d.occluded(scene, rays, &mut occ, None).unwrap();
    });
    Case {
        prepare,
        intersect,
        occluded,
        again,
        held,
    }
}

#[test]
fn dacrt_memory_is_a_deterministic_linear_function() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    // Equal triangle counts, very different shapes: 20·4^5 = 20480.
    let t = 20_480;
    let soup = procedural::soup(t, 3);
    let sphere = procedural::icosphere(t);
    assert_eq!((soup.len(), sphere.len()), (t, t));
    let (w, h) = (64u32, 48u32);
    let r = (w * h) as usize;
    for tasks in [1usize, 2] {
        let mut seen = Vec::new();
        for scene in [&soup, &sphere] {
            let cam = Camera::framing(&scene.bounds(), 45.0, w as f32 / h as f32).rays(w, h);
            let random = random_in_box(&scene.bounds(), r, 5);
            // Shadow rays to a point light (segments ending on it).
            let light = scene.bounds().max + glam::Vec3::ONE;
            let mut shadow = random.clone();
            for i in 0..r {
                let d = light - shadow.origin(i);
                (shadow.dx[i], shadow.dy[i], shadow.dz[i]) = (d.x, d.y, d.z);
                shadow.tmax[i] = 1.0;
            }
            shadow.layout = RayLayout::ToPoint { target: light };
            // Camera rays in another order, still labelled pinhole: the pixel check fails, no
            // tile leaves (7919 is prime to R = 2^10·3, so i ↦ 7919·i mod R permutes).
            let mut shuffled = RayBatch::from_rays((0..r).map(|i| cam.get(i * 7919 % r)));
            shuffled.layout = cam.layout;
            for (mode, rays) in [
                ("ray", &cam),
                ("random", &random),
                ("packet", &cam),
                ("packet shuffled", &shuffled),
                ("auto", &random),
                ("shadow", &shadow),
                ("shadow rays", &shadow),
            ] {
                // Shadow packets are off by default ("shadow rays"); "shadow" turns them on.
                let c = run(
                    scene,
                    rays,
                    if mode.starts_with("shadow") || mode.starts_with("packet") {
                        "packet"
                    } else {
                        mode
                    },
                    tasks,
                    if mode == "shadow" { "1" } else { "0" },
                );
                // Held between calls: per axis, a [min, max] pair per triangle.
                assert_eq!(c.prepare, 24 * t, "prepare {mode}");
                // Per call: K triangle index lists, one ray index list and 32-byte ray records
                // (36 bytes per ray), and for packets 68
                // bytes per 8×8 tile or per 64 shadow rays (here R/64 either way), plus the
                // shadow rays' 8-byte Morton order. Camera packets end in tile leaves: no ray
                // list, but per tile 1036
                // bytes (its 64 rays' 16-byte records, the pixels hit in a leaf, a list of
                // such tiles); the tasks share one 8-byte pixel rectangle per triangle and the
                // bounds of their bands (8 bytes per task plus one). Shuffled camera rays fail
                // the pixel check: flushes to rays, and nothing allocated for tile leaves.
                let cones = if mode.starts_with("packet") || mode == "shadow" {
                    r / 64
                } else {
                    0
                };
                let order = if mode == "shadow" { 8 * r } else { 0 };
                let want = if mode == "packet" {
                    4 * t * tasks + 8 * t + 8 * (tasks + 1) + (68 + 1036) * cones
                } else {
                    4 * t * tasks + 36 * r + 68 * cones + order
                };
                // Batches without packets (R ≤ 2·T here) build the top tree in their first
                // call and keep it: lists of 2·T entries (also the build's working space) and
                // 4·⌈2·T / 32⌉ + 1 nodes of 16 bytes.
                let top = if matches!(mode, "ray" | "random" | "auto" | "shadow rays") {
                    4 * 2 * t + 16 * (4 * (2 * t).div_ceil(32) + 1)
                } else {
                    0
                };
                assert_eq!(c.intersect.0, want + top, "intersect {mode} tasks {tasks}");
                assert_eq!(c.occluded.0, want + top, "occluded {mode} tasks {tasks}");
                assert!(c.intersect.1 <= want + top && c.occluded.1 <= want + top);
                // The buffers stay with the tracer: a second call of the same size allocates
                // nothing, and the tracer holds the min/max lists, one call's buffers and the
                // top tree.
                assert_eq!(c.again, 0, "second call {mode} tasks {tasks}");
                assert_eq!(c.held, 24 * t + want + top, "held {mode} tasks {tasks}");
                seen.push((mode, c.intersect.0));
            }
        }
        // Same numbers for both scenes (shape-independent).
        let (a, b) = seen.split_at(seen.len() / 2);
        assert_eq!(a, b);
    }
}

/// The light-space pass (shadow segments to one light, any hit): per task of `R_k` rays, 16
/// bytes per ray in ray order (coordinates, depth, bucket), 16 + 32 in bucket order (the
/// footprint check's record and the ray for the shared test), and three 4-byte arrays over
/// at most `R_k / light_bucket + 7` buckets; nothing per triangle, nothing on a second call,
/// the same for every scene shape.
#[test]
fn light_space_memory_is_a_deterministic_linear_function() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let t = 20_480;
    let soup = procedural::soup(t, 3);
    let sphere = procedural::icosphere(t);
    let r = 3000;
    for (tasks, per) in [(1usize, 2usize), (2, 2), (3, 5)] {
        let mut seen = Vec::new();
        for scene in [&soup, &sphere] {
            let light = scene.bounds().max + glam::Vec3::ONE;
            let mut shadow = random_in_box(&scene.bounds(), r, 5);
            for i in 0..r {
                let d = light - shadow.origin(i);
                (shadow.dx[i], shadow.dy[i], shadow.dz[i]) = (d.x, d.y, d.z);
                shadow.tmax[i] = 1.0;
            }
            shadow.layout = RayLayout::ToPoint { target: light };
            let (ts, ps) = (tasks.to_string(), per.to_string());
            let c = run_opts(scene, &shadow, &[("tasks", &ts), ("light_bucket", &ps)]);
            let chunk = r.div_ceil(tasks);
            let want: usize = (0..tasks)
                .map(|k| {
                    let rk = chunk.min(r - k * chunk);
                    64 * rk + 12 * (rk / per + 7)
                })
                .sum();
            assert_eq!(c.occluded.0, want, "occluded tasks {tasks}");
            assert!(c.occluded.1 <= want);
            // The intersection call before it used the recursion; its buffers are another's.
            let mut d = tracers::create(
                "dacrt",
                &[
                    ("tasks".to_string(), ts.clone()),
                    ("light_bucket".to_string(), ps.clone()),
                ],
            )
            .unwrap();
            d.prepare(scene).unwrap();
            let mut occ = vec![false; r];
            d.occluded(scene, &shadow, &mut occ, None).unwrap();
            let (again, _) = measure(|| {
                d.occluded(scene, &shadow, &mut occ, None).unwrap();
            });
            assert_eq!(again, 0, "second call tasks {tasks}");
            assert_eq!(d.bytes(), 24 * t + want, "held tasks {tasks}");
            seen.push(c.occluded.0);
        }
        assert_eq!(seen[0], seen[1]);
    }
}
