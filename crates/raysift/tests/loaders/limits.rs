//! Resource limits and fuzz regressions. Each test here failed on the code before its fix
//! (docs/fuzzing.md lists which run or review found it). "Fails quickly" is checked with a
//! deadline on a worker thread, "does not allocate" with the tracking allocator below, which
//! records the largest single allocation made by the calling thread.

use super::*;
#[allow(unused_imports)]
use super::{gltf::*, obj::*, off::*, ply::*};
use raysift::rays::npy;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::mpsc;
use std::time::Duration;

struct Tracking;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note(n: usize) {
    let _ = LARGEST.try_with(|l| {
        if n > l.get() {
            l.set(n)
        }
    });
}

unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        note(l.size());
        unsafe { System.alloc(l) }
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        note(l.size());
        unsafe { System.alloc_zeroed(l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        note(new);
        unsafe { System.realloc(p, l, new) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static ALLOC: Tracking = Tracking;

/// Runs `f` on a worker thread; fails the test if it takes more than `secs` seconds (a
/// hang) or panics. Returns `f`'s result and the largest single allocation it made.
fn quick<T: Send + 'static>(secs: u64, f: impl FnOnce() -> T + Send + 'static) -> (T, usize) {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        LARGEST.with(|l| l.set(0));
        let r = f();
        let _ = tx.send((r, LARGEST.with(|l| l.get())));
    });
    match rx.recv_timeout(Duration::from_secs(secs)) {
        Ok(r) => r,
        Err(mpsc::RecvTimeoutError::Timeout) => panic!("still running after {secs} s: a hang"),
        Err(mpsc::RecvTimeoutError::Disconnected) => panic!("panicked (see above)"),
    }
}

/// `load` on a file holding `bytes`, within 5 s; the error message and the largest allocation.
fn load_fails(dir: &Path, name: &str, bytes: &[u8]) -> (String, usize) {
    let p = write(dir, name, bytes);
    let (r, big) = quick(5, move || {
        load(&p).map(|s| s.len()).map_err(|e| e.to_string())
    });
    let e = match r {
        Ok(n) => panic!("{name}: expected an error, loaded {n} triangles"),
        Err(e) => e,
    };
    assert!(
        e.contains(&dir.join(name).display().to_string()),
        "{name}: message does not name the file: {e}"
    );
    (e, big)
}

fn npy_bytes(header: &str, data: &[u8]) -> Vec<u8> {
    let mut h = header.as_bytes().to_vec();
    while !(10 + h.len() + 1).is_multiple_of(64) {
        h.push(b' ');
    }
    h.push(b'\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(h.len() as u16).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(data);
    out
}

fn rays_header(shape: &str) -> String {
    format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}")
}

/// `read_rays` (and the hits and occlusion readers) on a file, within 5 s.
fn npy_fails(dir: &Path, name: &str, bytes: &[u8]) -> (String, usize) {
    let p = write(dir, name, bytes);
    let (r, big) = quick(5, move || {
        let a = npy::read_rays(&p).map(|_| ()).map_err(|e| e.to_string());
        let b = npy::read_hits(&p).map(|_| ());
        let c = npy::read_occlusion(&p).map(|_| ());
        assert!(b.is_err() && c.is_err());
        a
    });
    let e = r.expect_err("expected an error");
    assert!(
        e.contains(name),
        "{name}: message does not name the file: {e}"
    );
    (e, big)
}

/// A sparse file of `len` bytes starting with `head` (takes no disk space).
fn sparse_file(dir: &Path, name: &str, head: &[u8], len: u64) -> Option<PathBuf> {
    let p = dir.join(name);
    let mut f = std::fs::File::create(&p).ok()?;
    f.write_all(head).ok()?;
    f.set_len(len).ok()?;
    Some(p)
}

fn mem_available() -> Option<u64> {
    let t = std::fs::read_to_string("/proc/meminfo").ok()?;
    let l = t.lines().find(|l| l.starts_with("MemAvailable:"))?;
    Some(l.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

// ---- found by fuzzing and review (docs/fuzzing.md, "Crashes found")
#[test]
fn fuzz_npy_header_length_of_2gb_is_refused_before_allocating() {
    // From the npy target's first run: a version 2.0 header declaring 2070151284 bytes made
    // npyz allocate that much before reading it.
    let mut b = b"\x93NUMPY\x02\x00".to_vec();
    b.extend_from_slice(&2_070_151_284u32.to_le_bytes());
    b.extend_from_slice(b"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 8), }\n");
    let dir = tempfile::tempdir().unwrap();
    let (e, big) = npy_fails(dir.path(), "hdr.npy", &b);
    assert!(e.contains("header") && e.contains("2070151284"), "{e}");
    assert!(big < 1 << 20, "allocated {big} bytes");
}

#[test]
fn fuzz_npy_shape_product_overflow_is_an_error_not_a_panic() {
    // npyz multiplies the shape unchecked (overflow panics with overflow checks on, as in
    // the test profile and the fuzz builds) and so do its strides, even when a zero makes
    // the product 0.
    let dir = tempfile::tempdir().unwrap();
    for (name, shape) in [
        ("product.npy", "(4294967296, 4294967296, 8)"),
        ("strides.npy", "(0, 4294967296, 4294967296, 8)"),
    ] {
        let (e, _) = npy_fails(dir.path(), name, &npy_bytes(&rays_header(shape), &[]));
        assert!(e.contains("header"), "{e}");
    }
}

#[test]
fn fuzz_npy_deeply_nested_header_fails_quickly() {
    // py_literal (npyz's header parser) backtracks exponentially on nested brackets.
    let dir = tempfile::tempdir().unwrap();
    let shape = format!("{}{}", "[".repeat(3000), "]".repeat(3000));
    let (e, _) = npy_fails(
        dir.path(),
        "deep.npy",
        &npy_bytes(&rays_header(&shape), &[]),
    );
    assert!(e.contains("header") && e.contains("nested"), "{e}");
}

#[test]
fn fuzz_ply_binary_element_without_properties_does_not_hang() {
    // A binary element with no properties takes no bytes, so a count of 10^18 looped 10^18
    // times doing nothing.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
element nothing 1000000000000000000\nend_header\n"
        .to_vec();
    for c in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        b.extend_from_slice(&c.to_le_bytes());
    }
    b.push(3);
    for i in [0i32, 1, 2] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "noprops.ply", &b);
    let (s, _) = quick(5, move || {
        load(&p).map(|s| s.len()).map_err(|e| e.to_string())
    });
    assert_eq!(s, Ok(1));
    // The same in ascii.
    let mut a = String::from_utf8(b[..b.len() - 49].to_vec()).unwrap();
    a = a.replace("binary_little_endian", "ascii");
    a.push_str("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    let p = write(dir.path(), "noprops_ascii.ply", a.as_bytes());
    let (s, _) = quick(5, move || {
        load(&p).map(|s| s.len()).map_err(|e| e.to_string())
    });
    assert_eq!(s, Ok(1));
}

#[test]
fn fuzz_gltf_sparse_accessor_without_view_does_not_allocate_hundreds_of_mb() {
    // A 712-byte file: a sparse u8 index accessor of count 16,000,000 with no bufferView
    // (all zeros) passed the old bound (16 x buffer bytes + 16 MiB) and made a 512 MB
    // element list.
    let mut buf = Vec::new();
    for c in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        buf.extend_from_slice(&c.to_le_bytes());
    }
    buf.extend_from_slice(&[0, 0, 0, 0]);
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "mode": 5}}]}}],
  "buffers": [{{"byteLength": 40, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 1}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
{{"componentType": 5121, "count": 16000000, "type": "SCALAR",
  "sparse": {{"count": 1, "indices": {{"bufferView": 1, "componentType": 5121}}, "values": {{"bufferView": 1}}}}}}]}}"#,
        base64(&buf)
    );
    let dir = tempfile::tempdir().unwrap();
    let (e, big) = load_fails(dir.path(), "sparse.gltf", json.as_bytes());
    assert!(
        e.contains("accessors[1]") && e.contains("implausibly large"),
        "{e}"
    );
    assert!(big < 4 << 20, "allocated {big} bytes");
}

#[test]
fn gltf_external_buffer_must_be_a_regular_file() {
    // A buffer URI naming a FIFO (or a device such as /dev/zero) blocked or read forever.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.bin");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        eprintln!("SKIPPED: mkfifo not available");
        return;
    }
    let json = gltf_json(r#"{"byteLength": 60, "uri": "pipe.bin"}"#);
    let (e, _) = load_fails(dir.path(), "fifo.gltf", json.as_bytes());
    assert!(
        e.contains("buffers[0]") && e.contains("regular file"),
        "{e}"
    );
}

#[test]
fn gltf_instances_beyond_memory_are_refused_before_copying() {
    // Instancing legitimately multiplies a file's triangles, so the bound is memory: one
    // TRIANGLE_FAN mesh of 65536 vertices (65534 triangles, all at the origin) in a GLB's
    // BIN chunk, and enough nodes instancing it to need twice the available memory. Before
    // the budget, every instance was copied until memory ran out.
    let Some(avail) = mem_available() else {
        eprintln!("SKIPPED: no /proc/meminfo");
        return;
    };
    let nv = 65536u64;
    let per = nv * 12 + (nv - 2) * 48;
    let nodes = (2 * avail / per + 1) as usize;
    let list: Vec<String> = (0..nodes).map(|i| i.to_string()).collect();
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scenes": [{{"nodes": [{}]}}],
  "nodes": [{}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "mode": 6}}]}}],
  "buffers": [{{"byteLength": {b}}}], "bufferViews": [{{"buffer": 0, "byteLength": {b}}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": {nv}, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0]}}]}}"#,
        list.join(","),
        vec![r#"{"mesh": 0}"#; nodes].join(","),
        b = nv * 12
    );
    let g = glb(&json, &vec![0u8; (nv * 12) as usize]);
    let dir = tempfile::tempdir().unwrap();
    let (e, big) = load_fails(dir.path(), "instances.glb", &g);
    assert!(e.contains("nodes[") && e.contains("MemAvailable"), "{e}");
    assert!(big < 64 << 20, "allocated {big} bytes");
}

// ---- limits: counts against bytes
#[test]
fn ply_header_claiming_1e12_vertices_fails_at_the_header() {
    let dir = tempfile::tempdir().unwrap();
    for fmt in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let mut b = format!(
            "ply\nformat {fmt} 1.0\nelement vertex 1000000000000\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes();
        b.resize(200, b'0');
        let (e, big) = load_fails(dir.path(), &format!("{fmt}.ply"), &b);
        assert!(
            e.contains("header, element 0 (vertex)") && e.contains("1000000000000"),
            "{e}"
        );
        assert!(e.contains("can hold"), "{e}");
        assert!(big < 1 << 16, "allocated {big} bytes");
    }
    // Any element, not only vertices: 10^15 edges of two ints in a small binary file.
    let b = b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
property float y\nproperty float z\nelement edge 1000000000000000\nproperty int a\nproperty int b\nend_header\n";
    let (e, _) = load_fails(dir.path(), "edges.ply", b);
    assert!(
        e.contains("element 1 (edge)") && e.contains("can hold"),
        "{e}"
    );
}

#[test]
fn ply_binary_list_size_beyond_the_file_fails_without_allocating() {
    // Already bounded before this work (the list's bytes are taken from the input before any
    // item is stored); kept as a check of the rule.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n"
        .to_vec();
    let at = b.len() + 36;
    b.extend_from_slice(&[0; 36]);
    b.extend_from_slice(&u32::MAX.to_le_bytes());
    b.extend_from_slice(&[0; 12]);
    let dir = tempfile::tempdir().unwrap();
    let (e, big) = load_fails(dir.path(), "list.ply", &b);
    assert!(
        e.contains(&format!("byte {}", at + 4)) && e.contains("face 0"),
        "{e}"
    );
    assert!(big < 1 << 16, "allocated {big} bytes");
}

#[test]
fn off_counts_beyond_the_file_fail_at_the_counts_line() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("v.off", "OFF\n3000000000 1 0\n0 0 0\n"),
        (
            "f.off",
            "OFF 3 1000000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        ),
    ] {
        let (e, big) = load_fails(dir.path(), name, text.as_bytes());
        assert!(e.contains("can hold"), "{e}");
        let line = if name == "v.off" { "line 2" } else { "line 1" };
        assert!(e.contains(line), "{e}");
        assert!(big < 1 << 16, "allocated {big} bytes");
    }
}

#[test]
fn npy_shape_1e12_rows_fails_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let (e, big) = npy_fails(
        dir.path(),
        "huge.npy",
        &npy_bytes(&rays_header("(1000000000000, 8)"), &[0; 64]),
    );
    assert!(
        e.contains("data") && e.contains("32000000000000 bytes") && e.contains("64"),
        "{e}"
    );
    assert!(big < 1 << 16, "allocated {big} bytes");
    // Trailing bytes after the data the shape declares are an error too.
    let mut row = Vec::new();
    for c in [0f32, 0., 0., 1., 0., 0., 0., 1.] {
        row.extend_from_slice(&c.to_le_bytes());
    }
    let ok = npy_bytes(&rays_header("(1, 8)"), &row);
    assert_eq!(npy::parse_rays(&ok, "ok.npy").unwrap().len(), 1);
    let mut extra = ok.clone();
    extra.extend_from_slice(&[0; 4]);
    let e = npy::parse_rays(&extra, "extra.npy")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("extra.npy: data") && e.contains("4 bytes after"),
        "{e}"
    );
}

// ---- limits: gzip
#[test]
fn gzip_bomb_is_refused_at_the_cap() {
    // About 1 KB of gzip inflating to 1 MB of OBJ comment lines: above the cap
    // (64 x 1 KB + 64 KiB), so refused while inflating, naming the file.
    let text = format!("v 0 0 0\n{}", "#".repeat(1 << 20));
    let gz = gzip(text.as_bytes());
    assert!(gz.len() < 1500, "{}", gz.len());
    let dir = tempfile::tempdir().unwrap();
    let (e, big) = load_fails(dir.path(), "bomb.obj.gz", &gz);
    let cap = 64 * gz.len() + (64 << 10);
    assert!(
        e.contains("gzip") && e.contains(&format!("more than {cap} bytes")),
        "{e}"
    );
    assert!(big <= 2 * cap, "allocated {big} bytes for a cap of {cap}");
    // A real mesh's ratio (3-6x) is far below the cap.
    let ok = gzip(ply_ascii().as_bytes());
    assert!(load(write(dir.path(), "ok.ply.gz", &ok)).is_ok());
}

// ---- limits: memory
#[test]
fn rays_file_larger_than_memory_is_refused() {
    let Some(avail) = mem_available() else {
        eprintln!("SKIPPED: no /proc/meminfo");
        return;
    };
    // A consistent file (shape and length agree) whose rays need twice the available memory.
    let n = avail / 16; // 32 bytes per ray in memory
    let head = npy_bytes(&rays_header(&format!("({n}, 8)")), &[]);
    let dir = tempfile::tempdir().unwrap();
    let Some(p) = sparse_file(dir.path(), "big.npy", &head, head.len() as u64 + n * 32) else {
        eprintln!("SKIPPED: cannot make a sparse file");
        return;
    };
    let (r, big) = quick(5, move || {
        npy::read_rays(&p).map(|_| ()).map_err(|e| e.to_string())
    });
    let e = r.unwrap_err();
    assert!(
        e.contains("big.npy") && e.contains("MemAvailable") && e.contains("rays"),
        "{e}"
    );
    assert!(big < 1 << 20, "allocated {big} bytes");
}

#[test]
fn scene_file_larger_than_memory_is_refused() {
    let Some(avail) = mem_available() else {
        eprintln!("SKIPPED: no /proc/meminfo");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let Some(p) = sparse_file(dir.path(), "big.ply", b"ply\n", avail * 2) else {
        eprintln!("SKIPPED: cannot make a sparse file");
        return;
    };
    let (r, big) = quick(5, move || load(&p).map(|_| ()).map_err(|e| e.to_string()));
    let e = r.unwrap_err();
    assert!(e.contains("big.ply") && e.contains("MemAvailable"), "{e}");
    assert!(big < 1 << 20, "allocated {big} bytes");
}
