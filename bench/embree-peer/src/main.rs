//! embree-peer: Embree 4.4 "at its best" as a contender for the raysift benchmark.
//!
//! ```text
//! embree-peer --tris tris.npy --rays rays.npy [--out hits.npy] [--occlusion]
//!             [--quality low|medium|high] [--threads N] [--packet 1|16]
//!             [--tile W,H [--map map.npy]] [--repeat K] [--config STR]
//! ```
//!
//! * `tris.npy`: float32 (T,9) world-space triangles in raysift primitive-id order (tri-export).
//! * `rays.npy`: float32 (N,6) or (N,8) `[ox,oy,oz,dx,dy,dz(,tmin,tmax)]`.
//! * `--packet 16` traces with rtcIntersect16/rtcOccluded16. With `--tile W,H` the packets are
//!   4×4 pixel tiles of a W×H row-major image; ray i comes from pixel `map[i]` (`--map`, e.g. the
//!   map written by `raysift rays shadow`) or pixel i. Without `--tile`, 16 consecutive rays.
//! * `--packet 1` (default) traces single rays with rtcIntersect1/rtcOccluded1.
//! * Tracing threads are pinned one per allowed CPU (the process affinity mask, which the
//!   harness sets; Embree's TBB pool sizes itself from the same mask) and run with FTZ/DAZ on.
//!
//! Output: hits.npy in raysift's format (t <f4 +inf on miss, prim <u4 u32::MAX on miss, u, v),
//! or with `--occlusion` a uint8 array (1 = occluded); and one JSON object on stdout with
//! prepare/build/trace ms (medians over `--repeat` runs, plus each run).

mod ffi;
mod npy;

use ffi::*;
use std::ffi::{CStr, CString};
use std::os::raw::{c_char, c_uint, c_void};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

const MISS: u32 = u32::MAX;

static EMBREE_ERROR: AtomicBool = AtomicBool::new(false);

unsafe extern "C" fn on_error(_user: *mut c_void, code: c_uint, message: *const c_char) {
    let msg = if message.is_null() {
        String::new()
    } else {
        CStr::from_ptr(message).to_string_lossy().into_owned()
    };
    eprintln!("embree-peer: Embree error {code}: {msg}");
    EMBREE_ERROR.store(true, Ordering::SeqCst);
}

fn die(msg: impl AsRef<str>) -> ! {
    eprintln!("embree-peer: {}", msg.as_ref());
    std::process::exit(2);
}

// ---------------------------------------------------------------------------------------------
// CPU affinity and floating-point mode

const CPUSET_WORDS: usize = 16; // cpu_set_t is 1024 bits

extern "C" {
    fn sched_getaffinity(pid: i32, size: usize, mask: *mut u64) -> i32;
    fn sched_setaffinity(pid: i32, size: usize, mask: *const u64) -> i32;
}

fn allowed_cpus() -> Vec<usize> {
    let mut mask = [0u64; CPUSET_WORDS];
    let ok = unsafe { sched_getaffinity(0, std::mem::size_of_val(&mask), mask.as_mut_ptr()) } == 0;
    if !ok {
        return (0..std::thread::available_parallelism().map_or(1, |n| n.get())).collect();
    }
    (0..CPUSET_WORDS * 64)
        .filter(|&c| mask[c / 64] >> (c % 64) & 1 == 1)
        .collect()
}

fn pin_current_thread(cpu: usize) -> bool {
    let mut mask = [0u64; CPUSET_WORDS];
    mask[cpu / 64] |= 1 << (cpu % 64);
    unsafe { sched_setaffinity(0, std::mem::size_of_val(&mask), mask.as_ptr()) == 0 }
}

/// Flush-to-zero and denormals-are-zero, as Embree asks of every thread that traces.
fn set_ftz_daz() {
    #[cfg(target_arch = "x86_64")]
    #[allow(deprecated)]
    unsafe {
        use std::arch::x86_64::{_mm_getcsr, _mm_setcsr};
        _mm_setcsr(_mm_getcsr() | 0x8040);
    }
}

// ---------------------------------------------------------------------------------------------
// Memory

fn rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/statm")
        .ok()
        .and_then(|s| s.split_whitespace().nth(1).and_then(|x| x.parse::<u64>().ok()))
        .map_or(0, |p| p * 4096)
}

fn peak_rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|x| x.parse::<u64>().ok()))
        })
        .map_or(0, |kb| kb * 1024)
}

// ---------------------------------------------------------------------------------------------
// Arguments

struct Args {
    tris: String,
    rays: String,
    out: Option<String>,
    occlusion: bool,
    quality: String,
    threads: usize,
    packet: usize,
    tile: Option<(usize, usize)>,
    map: Option<String>,
    repeat: usize,
    config: String,
}

fn parse_args() -> Args {
    let mut a = Args {
        tris: String::new(),
        rays: String::new(),
        out: None,
        occlusion: false,
        quality: "medium".into(),
        threads: 1,
        packet: 1,
        tile: None,
        map: None,
        repeat: 1,
        config: String::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = || it.next().unwrap_or_else(|| die(format!("{k} needs a value")));
        match k.as_str() {
            "--tris" => a.tris = val(),
            "--rays" => a.rays = val(),
            "--out" => a.out = Some(val()),
            "--occlusion" => a.occlusion = true,
            "--quality" => a.quality = val(),
            "--threads" => a.threads = val().parse().unwrap_or_else(|_| die("--threads N")),
            "--packet" => a.packet = val().parse().unwrap_or_else(|_| die("--packet 1|16")),
            "--tile" => {
                let v = val();
                let (w, h) = v.split_once(',').unwrap_or_else(|| die("--tile W,H"));
                a.tile = Some((
                    w.parse().unwrap_or_else(|_| die("--tile W,H")),
                    h.parse().unwrap_or_else(|_| die("--tile W,H")),
                ));
            }
            "--map" => a.map = Some(val()),
            "--repeat" => a.repeat = val().parse().unwrap_or_else(|_| die("--repeat K")),
            "--config" => a.config = val(),
            "-h" | "--help" => {
                println!("{}", include_str!("main.rs").lines().take_while(|l| l.starts_with("//!")).map(|l| l.trim_start_matches("//!").trim_start_matches(' ')).collect::<Vec<_>>().join("\n"));
                std::process::exit(0);
            }
            _ => die(format!("unknown argument {k}")),
        }
    }
    if a.tris.is_empty() || a.rays.is_empty() {
        die("usage: embree-peer --tris tris.npy --rays rays.npy [--out hits.npy] ... (--help)");
    }
    if a.packet != 1 && a.packet != 16 {
        die("--packet must be 1 or 16");
    }
    a.threads = a.threads.max(1);
    a.repeat = a.repeat.max(1);
    a
}

// ---------------------------------------------------------------------------------------------
// Rays and results

struct Rays {
    n: usize,
    cols: usize,
    data: Vec<f32>,
}

impl Rays {
    #[inline(always)]
    fn get(&self, i: usize) -> ([f32; 3], [f32; 3], f32, f32) {
        let r = &self.data[i * self.cols..(i + 1) * self.cols];
        let (tmin, tmax) = if self.cols == 8 { (r[6], r[7]) } else { (0.0, f32::INFINITY) };
        ([r[0], r[1], r[2]], [r[3], r[4], r[5]], tmin, tmax)
    }
}

/// Output columns, written from several threads at disjoint indices.
#[derive(Clone, Copy)]
struct Out {
    t: *mut f32,
    prim: *mut u32,
    u: *mut f32,
    v: *mut f32,
    occ: *mut u8,
}
unsafe impl Send for Out {}
unsafe impl Sync for Out {}

impl Out {
    #[inline(always)]
    unsafe fn hit(&self, i: usize, t: f32, prim: u32, u: f32, v: f32) {
        *self.t.add(i) = t;
        *self.prim.add(i) = prim;
        *self.u.add(i) = u;
        *self.v.add(i) = v;
    }
    #[inline(always)]
    unsafe fn miss(&self, i: usize) {
        self.hit(i, f32::INFINITY, MISS, 0.0, 0.0)
    }
}

struct SceneHandle(RTCScene);
unsafe impl Send for SceneHandle {}
unsafe impl Sync for SceneHandle {}

/// Work items: packets of up to 16 rays, or single-ray index ranges.
enum Work {
    Packets(Packets),
    Singles(usize),
}

/// 16-ray packets laid out before timing, as a renderer generates its rays: ray indices (MISS =
/// empty lane), valid masks, and the rays already transposed to Embree's SoA order, so the timed
/// loop copies them into the RTCRayHit16 as `raysift trace` reads its SoA RayBatch before timing.
struct Packets {
    index: Vec<[u32; 16]>,
    valid: Vec<Valid16>,
    /// org_x, org_y, org_z, tnear, dir_x, dir_y, dir_z, tfar per packet.
    soa: Vec<[[f32; 16]; 8]>,
}

impl Packets {
    fn new(index: Vec<[u32; 16]>, rays: &Rays) -> Self {
        let mut valid = Vec::with_capacity(index.len());
        let mut soa = Vec::with_capacity(index.len());
        for pk in &index {
            let mut v = Valid16([0; 16]);
            let mut a = [[0f32; 16]; 8];
            for lane in 0..16 {
                if pk[lane] == MISS {
                    a[6][lane] = 1.0; // a harmless direction for the inactive lane
                    continue;
                }
                let (o, d, tmin, tmax) = rays.get(pk[lane] as usize);
                v.0[lane] = -1;
                let col = [o[0], o[1], o[2], tmin, d[0], d[1], d[2], tmax];
                for (k, x) in col.into_iter().enumerate() {
                    a[k][lane] = x;
                }
            }
            valid.push(v);
            soa.push(a);
        }
        Self { index, valid, soa }
    }
    fn len(&self) -> usize {
        self.index.len()
    }
}

fn build_packets(n: usize, tile: Option<(usize, usize)>, map: Option<Vec<u64>>) -> Vec<[u32; 16]> {
    match tile {
        None => (0..n.div_ceil(16))
            .map(|p| {
                let mut k = [MISS; 16];
                for (lane, i) in (p * 16..(p * 16 + 16).min(n)).enumerate() {
                    k[lane] = i as u32;
                }
                k
            })
            .collect(),
        Some((w, h)) => {
            let tw = w.div_ceil(4);
            let tiles = tw * h.div_ceil(4);
            let mut packets = vec![[MISS; 16]; tiles];
            let mut used = vec![false; tiles];
            for i in 0..n {
                let px = match &map {
                    Some(m) => m[i] as usize,
                    None => i,
                };
                if px >= w * h {
                    die(format!("ray {i} maps to pixel {px}, outside the {w}x{h} image"));
                }
                let (x, y) = (px % w, px / w);
                let t = (y / 4) * tw + x / 4;
                let lane = (y % 4) * 4 + x % 4;
                if packets[t][lane] != MISS {
                    die(format!("two rays map to pixel {px}; use --packet 1 or no --tile"));
                }
                packets[t][lane] = i as u32;
                used[t] = true;
            }
            packets
                .into_iter()
                .zip(used)
                .filter_map(|(p, u)| u.then_some(p))
                .collect()
        }
    }
}

fn trace(
    scene: &SceneHandle,
    rays: &Rays,
    work: &Work,
    occlusion: bool,
    cpus: &[usize],
    threads: usize,
    out: Out,
) {
    let next = AtomicUsize::new(0);
    let flags = if matches!(work, Work::Packets(_)) {
        RTC_RAY_QUERY_FLAG_COHERENT
    } else {
        RTC_RAY_QUERY_FLAG_INCOHERENT
    };
    std::thread::scope(|s| {
        for k in 0..threads {
            let next = &next;
            let cpu = cpus[k % cpus.len()];
            s.spawn(move || {
                pin_current_thread(cpu);
                set_ftz_daz();
                let mut args = RTCQueryArguments::new(flags);
                match work {
                    Work::Packets(packets) => {
                        const CHUNK: usize = 16;
                        let mut rh: Box<RTCRayHit16> = Box::new(unsafe { std::mem::zeroed() });
                        // fields Embree only reads, set once
                        rh.ray.time = [0.0; 16];
                        rh.ray.mask = [u32::MAX; 16];
                        rh.ray.flags = [0; 16];
                        rh.ray.id = std::array::from_fn(|k| k as u32);
                        loop {
                            let start = next.fetch_add(CHUNK, Ordering::Relaxed);
                            if start >= packets.len() {
                                break;
                            }
                            for p in start..(start + CHUNK).min(packets.len()) {
                                unsafe { trace16(scene.0, packets, p, occlusion, &mut rh, &mut args, out) };
                            }
                        }
                    }
                    Work::Singles(n) => {
                        const CHUNK: usize = 256;
                        let mut rh: RTCRayHit = unsafe { std::mem::zeroed() };
                        loop {
                            let start = next.fetch_add(CHUNK, Ordering::Relaxed);
                            if start >= *n {
                                break;
                            }
                            for i in start..(start + CHUNK).min(*n) {
                                unsafe { trace1(scene.0, rays, i, occlusion, &mut rh, &mut args, out) };
                            }
                        }
                    }
                }
            });
        }
    });
}

#[inline(always)]
unsafe fn trace1(
    scene: RTCScene,
    rays: &Rays,
    i: usize,
    occlusion: bool,
    rh: &mut RTCRayHit,
    args: &mut RTCQueryArguments,
    out: Out,
) {
    let (o, d, tmin, tmax) = rays.get(i);
    rh.ray = RTCRay {
        org_x: o[0],
        org_y: o[1],
        org_z: o[2],
        tnear: tmin,
        dir_x: d[0],
        dir_y: d[1],
        dir_z: d[2],
        time: 0.0,
        tfar: tmax,
        mask: u32::MAX,
        id: i as u32,
        flags: 0,
    };
    if occlusion {
        rtcOccluded1(scene, &mut rh.ray, args);
        *out.occ.add(i) = (rh.ray.tfar == f32::NEG_INFINITY) as u8;
    } else {
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.inst[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, rh, args);
        if rh.hit.geomID != RTC_INVALID_GEOMETRY_ID {
            out.hit(i, rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v);
        } else {
            out.miss(i);
        }
    }
}

#[inline(always)]
unsafe fn trace16(
    scene: RTCScene,
    packets: &Packets,
    p: usize,
    occlusion: bool,
    rh: &mut RTCRayHit16,
    args: &mut RTCQueryArguments,
    out: Out,
) {
    let pk = &packets.index[p];
    let a = &packets.soa[p];
    let valid = &packets.valid[p];
    let r = &mut rh.ray;
    r.org_x = a[0];
    r.org_y = a[1];
    r.org_z = a[2];
    r.tnear = a[3];
    r.dir_x = a[4];
    r.dir_y = a[5];
    r.dir_z = a[6];
    r.tfar = a[7];
    if occlusion {
        rtcOccluded16(valid, scene, &mut rh.ray, args);
        for lane in 0..16 {
            let i = pk[lane];
            if i != MISS {
                *out.occ.add(i as usize) = (rh.ray.tfar[lane] == f32::NEG_INFINITY) as u8;
            }
        }
    } else {
        rh.hit.geomID = [RTC_INVALID_GEOMETRY_ID; 16];
        rh.hit.primID = [RTC_INVALID_GEOMETRY_ID; 16];
        rh.hit.inst[0] = [RTC_INVALID_GEOMETRY_ID; 16];
        rtcIntersect16(valid, scene, rh, args);
        for lane in 0..16 {
            let i = pk[lane];
            if i == MISS {
                continue;
            }
            if rh.hit.geomID[lane] != RTC_INVALID_GEOMETRY_ID {
                out.hit(i as usize, rh.ray.tfar[lane], rh.hit.primID[lane], rh.hit.u[lane], rh.hit.v[lane]);
            } else {
                out.miss(i as usize);
            }
        }
    }
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = s.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

fn json_list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(","))
}

fn main() {
    let args = parse_args();
    set_ftz_daz();

    // --- inputs (not timed) ---
    let tris = npy::read(&args.tris).unwrap_or_else(|e| die(e));
    if tris.shape.len() != 2 || tris.shape[1] != 9 {
        die(format!("{}: expected float32 (T,9), got shape {:?}", args.tris, tris.shape));
    }
    let ntri = tris.shape[0];
    // Vertex buffer shared with Embree: 3 vertices per triangle, plus 16 bytes of padding
    // (Embree reads the last vertex with a 16-byte load).
    let mut vertices = tris.f32s().unwrap_or_else(|e| die(format!("{}: {e}", args.tris)));
    drop(tris);
    vertices.extend_from_slice(&[0.0; 4]);
    let indices: Vec<u32> = (0..3 * ntri as u32).chain([0, 0, 0, 0]).collect();

    let ra = npy::read(&args.rays).unwrap_or_else(|e| die(e));
    // (N, 6|8), or image-shaped (H, W, 6|8) camera rays as `raysift rays camera` writes them.
    let cols = ra.shape.last().copied().unwrap_or(0);
    if !(ra.shape.len() == 2 || ra.shape.len() == 3) || !(cols == 6 || cols == 8) {
        die(format!("{}: expected float32 (N,6|8) or (H,W,6|8), got shape {:?}", args.rays, ra.shape));
    }
    let rays = Rays {
        n: ra.shape[..ra.shape.len() - 1].iter().product(),
        cols,
        data: ra.f32s().unwrap_or_else(|e| die(format!("{}: {e}", args.rays))),
    };
    drop(ra);
    let n = rays.n;
    let map = args.map.as_ref().map(|p| {
        let m = npy::read(p).and_then(|a| a.indices()).unwrap_or_else(|e| die(format!("{p}: {e}")));
        if m.len() != n {
            die(format!("{p}: {} entries for {n} rays", m.len()));
        }
        m
    });
    let work = if args.packet == 16 {
        Work::Packets(Packets::new(build_packets(n, args.tile, map), &rays))
    } else {
        Work::Singles(n)
    };
    let cpus = allowed_cpus();

    let quality = match args.quality.as_str() {
        "low" => RTC_BUILD_QUALITY_LOW,
        "medium" => RTC_BUILD_QUALITY_MEDIUM,
        "high" => RTC_BUILD_QUALITY_HIGH,
        q => die(format!("--quality low|medium|high, got {q}")),
    };

    // --- device (not timed: one-off start-up, like a thread pool) ---
    let mut config = format!("threads={}", args.threads);
    if !args.config.is_empty() {
        config = format!("{config},{}", args.config);
    }
    let cconfig = CString::new(config.clone()).unwrap();
    let device = unsafe { rtcNewDevice(cconfig.as_ptr()) };
    if device.is_null() {
        die("rtcNewDevice failed");
    }
    unsafe { rtcSetDeviceErrorFunction(device, on_error, std::ptr::null_mut()) };
    let prop = |p| unsafe { rtcGetDeviceProperty(device, p) };
    let version = prop(RTC_DEVICE_PROPERTY_VERSION);
    let native16 = prop(RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED);
    let native8 = prop(RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED);

    // Output buffers, allocated once and touched (non-zero fill, so the pages are really mapped)
    // before any timing, as a renderer reuses its buffers from frame to frame.
    let nh = if args.occlusion { 0 } else { n };
    let mut t_out = vec![f32::INFINITY; nh];
    let mut p_out = vec![MISS; nh];
    let mut u_out = vec![-1f32; nh];
    let mut v_out = vec![-1f32; nh];
    let mut occ = vec![0xFFu8; if args.occlusion { n } else { 0 }];
    let out = Out {
        t: t_out.as_mut_ptr(),
        prim: p_out.as_mut_ptr(),
        u: u_out.as_mut_ptr(),
        v: v_out.as_mut_ptr(),
        occ: occ.as_mut_ptr(),
    };

    let mut prepare_runs = Vec::new();
    let mut build_runs = Vec::new();
    let mut trace_runs = Vec::new();
    let mut bvh_bytes = 0u64;
    for run in 0..args.repeat {
        let rss0 = rss_bytes();
        // --- prepare: scene + geometry over the application's buffers, then the BVH build ---
        let t0 = Instant::now();
        let scene = unsafe {
            let scene = rtcNewScene(device);
            rtcSetSceneFlags(scene, RTC_SCENE_FLAG_NONE);
            rtcSetSceneBuildQuality(scene, quality);
            let geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
            rtcSetGeometryBuildQuality(geom, quality);
            rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                vertices.as_ptr() as *const c_void, 0, 12, 3 * ntri);
            rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                indices.as_ptr() as *const c_void, 0, 12, ntri);
            rtcCommitGeometry(geom);
            let id = rtcAttachGeometry(scene, geom);
            if id != 0 {
                die(format!("geometry id {id}, expected 0"));
            }
            rtcReleaseGeometry(geom);
            scene
        };
        let t1 = Instant::now();
        unsafe { rtcCommitScene(scene) };
        let t2 = Instant::now();
        if run == 0 {
            bvh_bytes = rss_bytes().saturating_sub(rss0);
        }
        if EMBREE_ERROR.load(Ordering::SeqCst) {
            die("Embree reported an error while building");
        }
        // --- trace ---
        let handle = SceneHandle(scene);
        let t3 = Instant::now();
        trace(&handle, &rays, &work, args.occlusion, &cpus, args.threads, out);
        let t4 = Instant::now();
        if EMBREE_ERROR.load(Ordering::SeqCst) {
            die("Embree reported an error while tracing");
        }
        unsafe { rtcReleaseScene(scene) };
        prepare_runs.push((t2 - t0).as_secs_f64() * 1e3);
        build_runs.push((t2 - t1).as_secs_f64() * 1e3);
        trace_runs.push((t4 - t3).as_secs_f64() * 1e3);
    }
    unsafe { rtcReleaseDevice(device) };

    let hits = if args.occlusion {
        occ.iter().filter(|&&o| o != 0).count()
    } else {
        p_out.iter().filter(|&&p| p != MISS).count()
    };
    if let Some(path) = &args.out {
        let r = if args.occlusion {
            npy::write_u8(path, &occ)
        } else {
            npy::write_hits(path, &t_out, &p_out, &u_out, &v_out)
        };
        r.unwrap_or_else(|e| die(e));
    }
    let prepare_ms = median(&prepare_runs);
    let trace_ms = median(&trace_runs);
    let packets = match &work {
        Work::Packets(p) => p.len(),
        Work::Singles(_) => 0,
    };
    println!(
        concat!(
            "{{\"tracer\":\"embree\",\"embree_version\":{},\"library\":\"{}\",\"config\":\"{}\",",
            "\"quality\":\"{}\",\"packet\":{},\"packets\":{},\"tiled\":{},\"native_ray16\":{},\"native_ray8\":{},",
            "\"triangles\":{},\"rays\":{},\"threads\":{},\"cpus\":[{}],\"occlusion\":{},",
            "\"prepare_ms\":{:.4},\"build_ms\":{:.4},\"trace_ms\":{:.4},\"mrays_per_s\":{:.4},\"hits\":{},",
            "\"bvh_rss_bytes\":{},\"bytes_per_triangle\":{:.2},\"peak_rss_bytes\":{},",
            "\"prepare_ms_runs\":{},\"build_ms_runs\":{},\"trace_ms_runs\":{}}}"
        ),
        version,
        env!("EMBREE_LIB_PATH"),
        config,
        args.quality,
        args.packet,
        packets,
        args.tile.is_some(),
        native16,
        native8,
        ntri,
        n,
        args.threads,
        cpus.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(","),
        args.occlusion,
        prepare_ms,
        median(&build_runs),
        trace_ms,
        if trace_ms > 0.0 { n as f64 / (trace_ms * 1e3) } else { 0.0 },
        hits,
        bvh_bytes,
        if ntri > 0 { bvh_bytes as f64 / ntri as f64 } else { 0.0 },
        peak_rss_bytes(),
        json_list(&prepare_runs),
        json_list(&build_runs),
        json_list(&trace_runs),
    );
}
