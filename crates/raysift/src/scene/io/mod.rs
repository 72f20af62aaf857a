//! Scene files: OBJ, PLY (ascii, binary little and big endian), glTF 2.0 (`.gltf`, `.glb`) and OFF,
//! each optionally gzip-compressed (`.gz`). The format is chosen by the extension under `.gz`.
//!
//! Every loader reports errors as `file: place: what` (line, element or byte offset) and never
//! panics on malformed input; index range and finiteness are checked once more by
//! [`Scene::from_meshes`].

pub mod gltf;
pub mod obj;
pub mod off;
pub mod ply;

use super::Scene;
use crate::error::{Error, Result};
use std::io::Read;
use std::path::Path;

/// Scene file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Wavefront OBJ.
    Obj,
    /// Stanford PLY.
    Ply,
    /// glTF 2.0 JSON (`.gltf`).
    Gltf,
    /// glTF 2.0 binary (`.glb`).
    Glb,
    /// Object File Format.
    Off,
}

/// The format and whether the file is gzip-compressed, from its name.
pub fn detect_format(path: &Path) -> Result<(Format, bool)> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let (stem, gz) = match name.strip_suffix(".gz") {
        Some(s) => (s.to_string(), true),
        None => (name.clone(), false),
    };
    let ext = stem.rsplit_once('.').map(|(_, e)| e).unwrap_or("");
    let f = match ext {
        "obj" => Format::Obj,
        "ply" => Format::Ply,
        "gltf" => Format::Gltf,
        "glb" => Format::Glb,
        "off" => Format::Off,
        _ => {
            return Err(Error::Invalid(format!(
                "{}: unknown scene format (expected .obj, .ply, .gltf, .glb or .off, optionally .gz; or a generator such as sphere:N)",
                path.display()
            )))
        }
    };
    Ok((f, gz))
}

/// Reads a whole file, decompressing gzip when `gz`.
pub fn read_bytes(path: &Path, gz: bool) -> Result<Vec<u8>> {
    let file = path.display().to_string();
    let raw = std::fs::read(path).map_err(|e| Error::io(&file, e))?;
    if !gz {
        return Ok(raw);
    }
    let mut out = Vec::with_capacity(raw.len() * 4);
    flate2::read::MultiGzDecoder::new(&raw[..])
        .read_to_end(&mut out)
        .map_err(|e| {
            Error::parse(
                &file,
                format!("gzip stream, decompressed byte {}", out.len()),
                e.to_string(),
            )
        })?;
    Ok(out)
}

/// Loads a scene file.
pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
    let path = path.as_ref();
    let (format, gz) = detect_format(path)?;
    let bytes = read_bytes(path, gz)?;
    let name = path.display().to_string();
    let meshes = match format {
        Format::Obj => obj::parse(&bytes, &name)?,
        Format::Ply => ply::parse(&bytes, &name)?,
        Format::Gltf | Format::Glb => gltf::parse(&bytes, &name, path.parent())?,
        Format::Off => off::parse(&bytes, &name)?,
    };
    Scene::from_meshes(name, meshes)
}
