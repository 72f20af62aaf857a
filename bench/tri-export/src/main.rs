//! tri-export SCENE OUT.npy
//!
//! Loads SCENE exactly as `raysift` does (a file, or a generator spec such as `sphere:N`,
//! `soup:N[:SEED]`, `cornell`, `tile:K:FILE`) and writes its world-space triangles as a float32
//! (T,9) .npy `[v0x,v0y,v0z,v1x,..,v2z]`, row i = raysift primitive id i. Prints one JSON line
//! with the triangle count and bounds.

use std::io::Write;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() != 2 {
        eprintln!("usage: tri-export SCENE OUT.npy");
        std::process::exit(2);
    }
    let scene = raysift::scene::procedural::open(&args[0]).unwrap_or_else(|e| {
        eprintln!("tri-export: {}: {e}", args[0]);
        std::process::exit(1);
    });
    let soup = scene.triangles();
    let n = soup.len();
    let mut payload = Vec::with_capacity(n * 36);
    for i in 0..n {
        for v in soup.get(i) {
            for c in [v.x, v.y, v.z] {
                payload.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({n}, 9), }}");
    let pad = (64 - (10 + header.len() + 1) % 64) % 64;
    header.push_str(&" ".repeat(pad));
    header.push('\n');
    let mut f = std::io::BufWriter::new(std::fs::File::create(&args[1]).unwrap_or_else(|e| {
        eprintln!("tri-export: {}: {e}", args[1]);
        std::process::exit(1);
    }));
    f.write_all(b"\x93NUMPY\x01\x00").unwrap();
    f.write_all(&(header.len() as u16).to_le_bytes()).unwrap();
    f.write_all(header.as_bytes()).unwrap();
    f.write_all(&payload).unwrap();
    f.flush().unwrap();
    let b = scene.bounds();
    println!(
        "{{\"scene\":\"{}\",\"triangles\":{n},\"bounds\":[[{},{},{}],[{},{},{}]]}}",
        args[0].replace('\\', "\\\\").replace('"', "\\\""),
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
}
