//! Times loading scene files: `cargo run --release -p raysift --example load_time -- FILE...`.
//!
//! Prints, per file, the time to read (and gunzip), the time to parse into meshes, the total
//! time of `raysift::scene::load` (which also bakes the world soup), and the counts and bounds.

use raysift::scene::io::{detect_format, read_bytes, Format};
use std::time::Instant;

fn main() {
    let files: Vec<String> = std::env::args().skip(1).collect();
    if files.is_empty() {
        eprintln!("usage: load_time FILE...");
        std::process::exit(2);
    }
    for f in files {
        let path = std::path::Path::new(&f);
        let t = Instant::now();
        let (format, gz) = match detect_format(path) {
            Ok(x) => x,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let bytes = read_bytes(path, gz).unwrap_or_else(|e| {
            eprintln!("{e}");
            std::process::exit(1)
        });
        let t_read = t.elapsed();
        let t = Instant::now();
        let parsed = match format {
            Format::Obj => raysift::scene::io::obj::parse(&bytes, &f),
            Format::Ply => raysift::scene::io::ply::parse(&bytes, &f),
            Format::Gltf | Format::Glb => {
                raysift::scene::io::gltf::parse(&bytes, &f, path.parent())
            }
            Format::Off => raysift::scene::io::off::parse(&bytes, &f),
        };
        let t_parse = t.elapsed();
        if let Err(e) = parsed {
            eprintln!("{e}");
            std::process::exit(1);
        }
        let t = Instant::now();
        let scene = raysift::scene::load(path).unwrap_or_else(|e| {
            eprintln!("{e}");
            std::process::exit(1)
        });
        let t_load = t.elapsed();
        let b = scene.bounds();
        println!(
            "{f}: read+gunzip {:.3} s, parse {:.3} s, full load (read+parse+bake) {:.3} s; {} meshes, {} triangles, {} vertices, bounds {:?} - {:?}",
            t_read.as_secs_f64(),
            t_parse.as_secs_f64(),
            t_load.as_secs_f64(),
            scene.meshes().len(),
            scene.len(),
            scene.vertex_count(),
            b.min,
            b.max
        );
    }
}
