//! `raysift info`: what a scene holds.

use crate::args::{open_scene, SCENE_HELP};
use crate::report::{print_json, InfoReport};
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
            meshes: s.meshes().len(),
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
    println!(
        "bounds     ({}, {}, {}) – ({}, {}, {})",
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
    println!("bytes      {} ({per_triangle:.1} per triangle)", s.bytes());
    Ok(())
}
