//! `raysift info`: what a scene holds.

use crate::args::{open_scene, SCENE_HELP};
use crate::report::{meshes_of, print_json, InfoReport};
use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct InfoArgs {
    #[arg(help = SCENE_HELP)]
    scene: String,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(a: &InfoArgs) -> Result<()> {
    let s = open_scene(&a.scene)?;
    let b = s.bounds();
    let per_triangle = s.bytes() as f64 / s.len().max(1) as f64;
    if a.json {
        return print_json(&InfoReport {
            scene: s.name.clone(),
            triangles: s.len(),
            vertices: s.vertex_count(),
            degenerate_triangles: s.degenerate_count(),
            meshes: meshes_of(&s),
            bounds: b.into(),
            bytes: s.bytes(),
            bytes_per_triangle: per_triangle,
        });
    }
    println!("scene      {}", s.name);
    println!(
        "triangles  {} ({} degenerate)",
        s.len(),
        s.degenerate_count()
    );
    println!("vertices   {}", s.vertex_count());
    println!("meshes     {}", s.meshes().len());
    // Each mesh's primitive ids (the `geom` of hits.npy is the mesh's index), the first few.
    const SHOWN: usize = 16;
    for (m, mesh) in s.meshes().iter().enumerate().take(SHOWN) {
        let r = s.mesh_prims(m);
        println!(
            "  {m:>4}  prims {}..{} ({} triangles)  {}",
            r.start,
            r.end,
            r.len(),
            mesh.name
        );
    }
    if s.meshes().len() > SHOWN {
        println!(
            "  ... {} more (info --json lists them all)",
            s.meshes().len() - SHOWN
        );
    }
    println!(
        "bounds     ({}, {}, {}) – ({}, {}, {})",
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
    println!("bytes      {} ({per_triangle:.1} per triangle)", s.bytes());
    Ok(())
}
