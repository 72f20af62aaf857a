//! Writing a render: PNG (8-bit sRGB, clamped) or OpenEXR (linear radiance, 32-bit float
//! RGB, through the `exr` crate). The format comes from the extension, checked before any work;
//! both are written to a temporary file beside the target and renamed, so a failed write
//! leaves nothing behind.

use anyhow::{bail, Context, Result};
use glam::Vec3;
use std::path::Path;

/// An image format raysift writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// 8-bit sRGB PNG (clamped to [0, 1], the sRGB transfer function).
    Png,
    /// Linear radiance, float RGB.
    Exr,
}

/// The format of `path` by its extension (`.png` or `.exr`); anything else is refused.
pub fn format_of(path: &Path) -> Result<Format> {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("png") => Ok(Format::Png),
        Some(e) if e.eq_ignore_ascii_case("exr") => Ok(Format::Exr),
        Some(e) => bail!(
            "{}: cannot write .{e} images; raysift writes .png (tone-mapped) or .exr (linear radiance)",
            path.display()
        ),
        None => bail!(
            "{}: no extension; name the image .png (tone-mapped) or .exr (linear radiance)",
            path.display()
        ),
    }
}

/// Writes linear radiance (row-major, rows top to bottom) in the format of `path`'s extension.
pub fn write_radiance(path: &Path, rad: &[Vec3], width: u32, height: u32) -> Result<()> {
    match format_of(path)? {
        Format::Png => Ok(raysift::render::to_image(rad, width, height).save_png(path)?),
        Format::Exr => write_exr(path, rad, width, height),
    }
}

/// Writes a float RGB OpenEXR atomically (temporary file in the same folder, then renamed).
pub fn write_exr(path: &Path, rad: &[Vec3], width: u32, height: u32) -> Result<()> {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(rad.len(), w * h, "one radiance per pixel");
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".raysift-")
        .suffix(".exr")
        .tempfile_in(dir)
        .with_context(|| format!("{}: cannot create a file there", path.display()))?;
    exr::prelude::write_rgb_file(tmp.path(), w, h, |x, y| {
        let c = rad[y * w + x];
        (c.x, c.y, c.z)
    })
    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // A temporary file is private (0600); an image is not.
        let _ = std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o644));
    }
    tmp.persist(path)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.error))?;
    Ok(())
}
