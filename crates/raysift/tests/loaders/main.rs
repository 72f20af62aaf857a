//! Scene loaders on small files written to a temp dir: counts, positions, fan order, primitive
//! ids, gzip, PLY binary LE/BE, glTF node hierarchies and GLB, and malformed inputs whose error
//! must name the file and the place (line, element or byte).

use glam::Vec3;
use raysift::scene::load;
use raysift::Scene;
use std::io::Write;
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn tri(s: &Scene, i: usize) -> [Vec3; 3] {
    s.triangles().get(i)
}

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Loads `bytes` as `name`; returns the error message, asserting it names the file and `place`.
fn load_err(dir: &Path, name: &str, bytes: &[u8], place: &str) -> String {
    let p = write(dir, name, bytes);
    let e = match load(&p) {
        Ok(s) => panic!("{name}: expected an error, loaded {} triangles", s.len()),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains(&p.display().to_string()),
        "{name}: message does not name the file: {e}"
    );
    assert!(
        e.contains(place),
        "{name}: message does not name the place {place:?}: {e}"
    );
    e
}

// The unit square's corners, counter-clockwise, used by most tests.
const SQ: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];

fn sq(i: usize) -> Vec3 {
    Vec3::from_array(SQ[i])
}

mod gltf;
mod obj;
mod off;
mod ply;

#[test]
fn unknown_extension_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "a.stl", b"solid");
    assert!(load(&p)
        .unwrap_err()
        .to_string()
        .contains("unknown scene format"));
}

// Robustness (no_panic.rs: truncated and byte-flipped files never panic) and resource limits
// with fuzz regressions (limits.rs).
mod limits;
mod no_panic;
