//! `raysift export`: the world-space triangles as a float32 (T, 9) .npy file, and the meshes'
//! primitive ranges as JSON.

use crate::args::{open_scene, SCENE_HELP};
use crate::report::{meshes_of, MeshesReport};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportArgs {
    #[arg(help = SCENE_HELP)]
    scene: String,
    /// Output .npy file: float32 (T, 9), world-space corners in primitive-id order.
    #[arg(long, required_unless_present = "meshes")]
    out: Option<PathBuf>,
    /// Also write the meshes (name, primitive range, triangles, vertices, bounds) as JSON.
    #[arg(long, value_name = "FILE")]
    meshes: Option<PathBuf>,
}

pub fn run(a: &ExportArgs) -> Result<()> {
    let s = open_scene(&a.scene)?;
    if let Some(out) = &a.out {
        raysift::rays::npy::write_triangles(out, &s)?;
    }
    if let Some(path) = &a.meshes {
        let report = MeshesReport {
            scene: s.name.clone(),
            triangles: s.len(),
            meshes: meshes_of(&s),
        };
        let written = raysift::output::write_atomic(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &report)?;
            w.write_all(b"\n")
        });
        if written.is_err() {
            // No half of the output: the triangles go too.
            if let Some(out) = &a.out {
                let _ = std::fs::remove_file(out);
            }
        }
        written?;
    }
    Ok(())
}
