//! The glTF container and its buffers, for the [`gltf`](super::gltf) loader: the GLB chunks,
//! the checks made before `gltf` touches the JSON (it would unwrap), and the buffers, external
//! ones read only below the file's folder and within the memory budget.

use super::limits;
use crate::error::{Error, Result};
use gltf::json;
use std::path::Path;

/// Splits a GLB container into its JSON chunk and optional BIN chunk (spec section 4.4).
pub(super) fn split_glb<'a>(bytes: &'a [u8], file: &str) -> Result<(&'a [u8], Option<Vec<u8>>)> {
    let err = |at: usize, msg: String| Error::parse(file, format!("byte {at}"), msg);
    let u32_at = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
    };
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err(err(
            bytes.len(),
            "truncated GLB header (12 bytes needed)".into(),
        ));
    };
    if version != 2 {
        return Err(err(
            4,
            format!("unsupported GLB version {version} (2 expected)"),
        ));
    }
    if length as usize != bytes.len() {
        return Err(err(
            8,
            format!(
                "GLB header declares {length} bytes but the file has {} (truncated or padded)",
                bytes.len()
            ),
        ));
    }
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    while at < bytes.len() {
        let (Some(len), Some(ty)) = (u32_at(at), u32_at(at + 4)) else {
            return Err(err(at, "truncated GLB chunk header".into()));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| {
                err(
                    at,
                    format!(
                        "GLB chunk of {len} bytes runs past the end of the file ({} bytes)",
                        bytes.len()
                    ),
                )
            })?;
        match ty {
            0x4E4F_534A if json.is_none() && at == 12 => json = Some(&bytes[start..end]),
            0x004E_4942 if bin.is_none() && json.is_some() => {
                bin = Some(bytes[start..end].to_vec())
            }
            0x4E4F_534A | 0x004E_4942 => {
                return Err(err(at, "unexpected or repeated JSON/BIN chunk".into()))
            }
            // Unknown chunk types must be ignored (spec).
            _ => {}
        }
        if json.is_none() {
            return Err(err(at, "the first GLB chunk must be JSON".into()));
        }
        at = end;
    }
    let json = json.ok_or_else(|| err(12, "GLB has no JSON chunk".into()))?;
    Ok((json, bin))
}

/// Checks what `gltf`'s validation would otherwise panic on.
pub(super) fn precheck(root: &json::Root, file: &str) -> Result<()> {
    let na = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (sem, idx) in &prim.attributes {
                if idx.value() >= na {
                    return Err(Error::parse(
                        file,
                        format!("meshes[{m}].primitives[{p}].attributes"),
                        format!(
                            "attribute {:?} refers to accessor {} but there are {na} accessors",
                            sem,
                            idx.value()
                        ),
                    ));
                }
            }
        }
    }
    for (b, buf) in root.buffers.iter().enumerate() {
        if let Some(uri) = &buf.uri {
            if !uri.contains(':') && !percent_decodes(uri) {
                return Err(Error::parse(
                    file,
                    format!("buffers[{b}].uri"),
                    format!("invalid percent-encoding in {uri:?}"),
                ));
            }
        }
    }
    Ok(())
}

/// True when `%xx` escapes in `s` decode to valid UTF-8.
fn percent_decodes(s: &str) -> bool {
    percent_decode(s).is_some()
}

/// `s` with its `%xx` escapes decoded (a `%` not followed by two hex digits stays as it is, as
/// `gltf`'s decoder does), or `None` when the result is not UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok());
            match hex {
                Some(v) => {
                    out.push(v);
                    i += 3;
                    continue;
                }
                None => {
                    out.push(b'%');
                }
            }
        } else {
            out.push(b[i]);
        }
        i += 1;
    }
    String::from_utf8(out).ok()
}

pub(super) fn load_buffers(
    doc: &gltf::Document,
    base: Option<&Path>,
    mut blob: Option<Vec<u8>>,
    file: &str,
) -> Result<Vec<gltf::buffer::Data>> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let place = format!("buffers[{}]", buffer.index());
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            check_external(uri, base, file, &place)?;
        }
        let data = gltf::buffer::Data::from_source_and_blob(buffer.source(), base, &mut blob)
            .map_err(|e| Error::parse(file, &place, format!("cannot load buffer: {e}")))?;
        if data.len() < buffer.length() {
            return Err(Error::parse(
                file,
                &place,
                format!(
                    "buffer declares {} bytes but its data has {}",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Guards `gltf`'s reading of an external buffer (which reads whatever the path names to its
/// end): the file, resolved as `gltf` resolves it, must be a regular file that fits in memory.
/// Data URIs, and any URI when `base` is `None` (`gltf` then refuses external files), pass.
fn check_external(uri: &str, base: Option<&Path>, file: &str, place: &str) -> Result<()> {
    let Some(base) = base else { return Ok(()) };
    let path = if uri.contains(':') {
        match uri
            .strip_prefix("file://")
            .or_else(|| uri.strip_prefix("file:"))
        {
            Some(p) => std::path::PathBuf::from(p),
            // data: URIs are decoded from the file itself; other schemes are refused by gltf.
            None => return Ok(()),
        }
    } else {
        match percent_decode(uri) {
            Some(rel) => base.join(rel),
            None => return Ok(()), // reported by `precheck`
        }
    };
    let meta = std::fs::metadata(&path).map_err(|e| {
        Error::parse(
            file,
            place,
            format!("cannot load buffer {}: {e}", path.display()),
        )
    })?;
    if !meta.is_file() {
        return Err(Error::parse(
            file,
            place,
            format!("buffer {} is not a regular file", path.display()),
        ));
    }
    limits::check_memory(
        file,
        place,
        &format!("the bytes of buffer {}", path.display()),
        meta.len(),
    )
}
