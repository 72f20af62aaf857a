//! Scene files: OBJ, PLY (ascii, binary little and big endian), glTF 2.0 (`.gltf`, `.glb`) and OFF,
//! each optionally gzip-compressed (`.gz`). The format is chosen by the extension under `.gz`.
//!
//! Every loader reports errors as `file: place: what` (line, element or byte offset) and never
//! panics on malformed input; index range and finiteness are checked once more by
//! [`Scene::from_meshes`]. Counts a file cannot back, gzip bombs and files larger than memory
//! fail before allocating ([`limits`]). Every loader is fuzzed (`fuzz/`, `docs/fuzzing.md`)
//! through [`load_bytes`].

pub mod gltf;
pub mod gltf_anim;
mod gltf_container;
pub mod limits;
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

/// Reads a whole file, decompressing gzip when `gz` (see [`gunzip`]). A file that is not a
/// regular file (a device, a FIFO), or larger than the available memory, is refused before
/// reading ([`limits`]).
pub fn read_bytes(path: &Path, gz: bool) -> Result<Vec<u8>> {
    let file = path.display().to_string();
    let meta = std::fs::metadata(path).map_err(|e| Error::io(&file, e))?;
    if !meta.is_file() {
        return Err(Error::parse(&file, "file", "not a regular file"));
    }
    limits::check_memory(&file, "file", "its bytes", meta.len())?;
    let raw = std::fs::read(path).map_err(|e| Error::io(&file, e))?;
    if !gz {
        return Ok(raw);
    }
    gunzip(&raw, &file)
}

/// Decompresses a gzip stream (several members are concatenated, as `gunzip` does); `file`
/// names the input in errors. Inflates as a stream and stops once the output passes
/// [`limits::gzip_cap`] of the input's size ([`limits::GZ_MAX_RATIO`] times it plus
/// [`limits::GZ_SLACK`]), or the available memory, whichever is smaller: a decompression bomb
/// is an error after at most that much work and memory.
pub fn gunzip(raw: &[u8], file: &str) -> Result<Vec<u8>> {
    let cap = limits::gzip_cap(raw.len() as u64);
    let mem = limits::mem_available();
    let limit = mem.map_or(cap, |m| m.min(cap));
    let mut out = Vec::with_capacity(raw.len().saturating_mul(4).min(limit as usize));
    flate2::read::MultiGzDecoder::new(raw)
        .take(limit.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| {
            Error::parse(
                file,
                format!("gzip stream, decompressed byte {}", out.len()),
                e.to_string(),
            )
        })?;
    if out.len() as u64 > limit {
        let place = format!("gzip stream, decompressed byte {limit}");
        return Err(if limit == cap {
            Error::parse(
                file,
                place,
                format!(
                    "inflates to more than {cap} bytes ({} x its {} compressed bytes + {}); refused as a likely decompression bomb (gunzip it first to load it anyway)",
                    limits::GZ_MAX_RATIO,
                    raw.len(),
                    limits::GZ_SLACK
                ),
            )
        } else {
            Error::parse(
                file,
                place,
                format!(
                    "inflates to more than the {} of memory available (MemAvailable); refused rather than run out of memory",
                    limits::human(limit)
                ),
            )
        });
    }
    Ok(out)
}

/// Parses the bytes of a scene file of `format` (already decompressed) into meshes; `file` names
/// it in errors, `base` is the folder that glTF external buffers and OBJ `mtllib` files are
/// resolved from (`None`: external buffers are an error, only embedded and GLB buffers load, and
/// OBJ files get no materials).
pub fn parse_meshes(
    format: Format,
    bytes: &[u8],
    file: &str,
    base: Option<&Path>,
) -> Result<Vec<super::Mesh>> {
    match format {
        Format::Obj => match base {
            Some(dir) => obj::parse_with_materials(bytes, file, dir),
            None => obj::parse(bytes, file),
        },
        Format::Ply => ply::parse(bytes, file),
        Format::Gltf | Format::Glb => gltf::parse(bytes, file, base),
        Format::Off => off::parse(bytes, file),
    }
}

/// Loads a scene from the bytes of a file named `name`, without touching the file system
/// (unless `base` is given, for glTF external buffers): the format and gzip come from the name's
/// extension, as in [`load`], and the result is the same as loading a file with that content.
/// This is the entry point the fuzz targets use (`fuzz/`).
pub fn load_bytes(bytes: &[u8], name: &str, base: Option<&Path>) -> Result<Scene> {
    let (format, gz) = detect_format(Path::new(name))?;
    let inflated;
    let bytes = if gz {
        inflated = gunzip(bytes, name)?;
        &inflated[..]
    } else {
        bytes
    };
    let meshes = parse_meshes(format, bytes, name, base)?;
    Scene::from_meshes(name, meshes)
}

/// Loads a scene file.
pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
    let path = path.as_ref();
    let (format, gz) = detect_format(path)?;
    let bytes = read_bytes(path, gz)?;
    let name = path.display().to_string();
    let meshes = parse_meshes(format, &bytes, &name, path.parent())?;
    Scene::from_meshes(name, meshes)
}
