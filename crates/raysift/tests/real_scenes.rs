//! Loads every mesh in the shared scene folder (`/work/shared/scenes`, i.e. `../shared/scenes`
//! from the workspace root) and checks the triangle counts, vertex counts and bounding boxes of
//! its README table (counts exact, bounds to 1e-5 relative to the scene's size). Skipped, with a
//! clear message, when the folder is absent.

use raysift::scene::load;
use std::io::Read;
use std::path::{Path, PathBuf};

struct Expected {
    file: &'static str,
    triangles: usize,
    /// README "Vertices": position entries in the file (PLY/OFF `vertex` element, OBJ `v` lines).
    file_vertices: usize,
    /// What `Scene::vertex_count` reports: for PLY/OFF the same; for OBJ the positions each
    /// mesh (tobj model) references, since a mesh stores only the positions its faces use.
    loaded_vertices: usize,
    min: [f32; 3],
    max: [f32; 3],
}

/// The README table, copied. One deliberate difference, an erratum of the README: it gives
/// `CornellBox-Original.obj` 24 vertices, but the file has 72 `v` lines (48 of them written
/// `v<TAB>...`, which the README's counter evidently missed); 64 of them are referenced by faces.
const TABLE: &[Expected] = &[
    Expected {
        file: "bun_zipper.ply",
        triangles: 69_451,
        file_vertices: 35_947,
        loaded_vertices: 35_947,
        min: [-0.0946899, 0.0329874, -0.0618736],
        max: [0.0610091, 0.187321, 0.0587997],
    },
    Expected {
        file: "bun_zipper_res2.ply",
        triangles: 16_301,
        file_vertices: 8_171,
        loaded_vertices: 8_171,
        min: [-0.0945716, 0.0333891, -0.0618736],
        max: [0.0609346, 0.186643, 0.0586895],
    },
    Expected {
        file: "bun_zipper_res3.ply",
        triangles: 3_851,
        file_vertices: 1_889,
        loaded_vertices: 1_889,
        min: [-0.0943643, 0.0334143, -0.0616721],
        max: [0.0609346, 0.184813, 0.0584651],
    },
    Expected {
        file: "bun_zipper_res4.ply",
        triangles: 948,
        file_vertices: 453,
        loaded_vertices: 453,
        min: [-0.0931466, 0.0336204, -0.056644],
        max: [0.0581591, 0.181897, 0.0578008],
    },
    Expected {
        file: "dragon_vrip.ply.gz",
        triangles: 871_414,
        file_vertices: 437_645,
        loaded_vertices: 437_645,
        min: [-0.108324, 0.0527295, -0.0504143],
        max: [0.0965662, 0.197173, 0.0412075],
    },
    Expected {
        file: "dragon_vrip_res2.ply.gz",
        triangles: 202_520,
        file_vertices: 100_250,
        loaded_vertices: 100_250,
        min: [-0.108188, 0.0527392, -0.0503454],
        max: [0.0964062, 0.197139, 0.0411367],
    },
    Expected {
        file: "dragon_vrip_res3.ply",
        triangles: 47_794,
        file_vertices: 22_998,
        loaded_vertices: 22_998,
        min: [-0.107673, 0.0527743, -0.050051],
        max: [0.0959825, 0.196644, 0.0408262],
    },
    Expected {
        file: "dragon_vrip_res4.ply",
        triangles: 11_102,
        file_vertices: 5_205,
        loaded_vertices: 5_205,
        min: [-0.107585, 0.0528441, -0.049836],
        max: [0.0952357, 0.196343, 0.0408262],
    },
    Expected {
        file: "teapot.obj",
        triangles: 6_320,
        file_vertices: 3_644,
        loaded_vertices: 3_644,
        min: [-3.0, 0.0, -2.0],
        max: [3.434, 3.15, 2.0],
    },
    Expected {
        file: "sponza.obj.gz",
        triangles: 66_454,
        file_vertices: 39_999,
        loaded_vertices: 39_999,
        min: [-17.4028, -0.906689, -7.79851],
        max: [17.4172, 15.6533, 7.80149],
    },
    // README says 24 vertices: see the erratum above.
    Expected {
        file: "CornellBox-Original.obj",
        triangles: 36,
        file_vertices: 72,
        loaded_vertices: 64,
        min: [-1.02, 0.0, -1.04],
        max: [1.0, 1.99, 0.99],
    },
    Expected {
        file: "armadillo.off",
        triangles: 52_000,
        file_vertices: 26_002,
        loaded_vertices: 26_002,
        min: [-63.5004, -54.2018, -57.7043],
        max: [63.5176, 97.1076, 57.7187],
    },
];

fn scenes_dir() -> Option<PathBuf> {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    d.is_dir().then_some(d)
}

/// Number of OBJ `v` statements, counted independently of the loader.
fn obj_v_lines(path: &Path) -> usize {
    let raw = std::fs::read(path).unwrap();
    let mut text = Vec::new();
    if path.extension().is_some_and(|e| e == "gz") {
        flate2::read::MultiGzDecoder::new(&raw[..])
            .read_to_end(&mut text)
            .unwrap();
    } else {
        text = raw;
    }
    String::from_utf8_lossy(&text)
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count()
}

#[test]
fn real_scenes_match_the_readme() {
    let Some(dir) = scenes_dir() else {
        println!("SKIPPED: ../shared/scenes not found");
        return;
    };
    // Every mesh file in the folder must be in the table (so a new file is not silently skipped).
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        let is_mesh = [".ply", ".obj", ".off", ".gltf", ".glb"]
            .iter()
            .any(|e| name.ends_with(e) || name.ends_with(&format!("{e}.gz")));
        if is_mesh {
            assert!(
                TABLE.iter().any(|t| t.file == name),
                "{name} is not in the test's table"
            );
        }
    }
    let mut failures = Vec::new();
    for t in TABLE {
        let path = dir.join(t.file);
        let start = std::time::Instant::now();
        let scene = match load(&path) {
            Ok(s) => s,
            Err(e) => {
                failures.push(format!("{}: {e}", t.file));
                continue;
            }
        };
        println!(
            "{}: {} triangles, {} vertices, {} meshes, loaded in {:.3} s",
            t.file,
            scene.len(),
            scene.vertex_count(),
            scene.meshes().len(),
            start.elapsed().as_secs_f64()
        );
        if scene.len() != t.triangles {
            failures.push(format!(
                "{}: {} triangles, README says {}",
                t.file,
                scene.len(),
                t.triangles
            ));
        }
        if scene.vertex_count() != t.loaded_vertices {
            failures.push(format!(
                "{}: {} vertices loaded, expected {}",
                t.file,
                scene.vertex_count(),
                t.loaded_vertices
            ));
        }
        if t.file.contains(".obj") {
            let n = obj_v_lines(&path);
            if n != t.file_vertices {
                failures.push(format!(
                    "{}: {n} v lines, expected {}",
                    t.file, t.file_vertices
                ));
            }
        } else if t.loaded_vertices != t.file_vertices {
            failures.push(format!("{}: table inconsistent", t.file));
        }
        let b = scene.bounds();
        let scale = t.min.iter().chain(&t.max).fold(0f32, |m, x| m.max(x.abs()));
        let tol = 1e-5 * scale;
        for (got, want, what) in [(b.min, t.min, "min"), (b.max, t.max, "max")] {
            for k in 0..3 {
                if (got[k] - want[k]).abs() > tol {
                    failures.push(format!(
                        "{}: bounds {what}[{k}] = {}, README says {} (tolerance {tol:e})",
                        t.file, got[k], want[k]
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
