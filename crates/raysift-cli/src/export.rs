//! `raysift export`: the world-space triangles as a float32 (T, 9) .npy file.

use crate::args::{open_scene, SCENE_HELP};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportArgs {
    #[arg(help = SCENE_HELP)]
    scene: String,
    /// Output .npy file.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: &ExportArgs) -> Result<()> {
    let s = open_scene(&a.scene)?;
    let t = s.triangles();
    raysift::output::write_atomic(&a.out, |w| {
        use npyz::WriterBuilder;
        let mut o = npyz::WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[t.len() as u64, 9])
            .writer(w)
            .begin_nd()?;
        for i in 0..t.len() {
            for v in t.get(i) {
                o.extend(v.to_array())?;
            }
        }
        o.finish()
    })?;
    Ok(())
}
