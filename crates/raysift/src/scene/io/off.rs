//! OFF (Object File Format) loader, ASCII.
//!
//! Supports the `OFF` header and its `C`/`N`/`ST` variants (`COFF`, `NOFF`, `CNOFF`, `STOFF`,
//! ...: extra per-vertex values after x y z are ignored), the counts on the header line or on
//! their own line (`nv nf [ne]`), `#` comments anywhere, blank lines, one vertex per line, then
//! faces as `n i1 ... in [colour...]` with 0-based indices, fanned in order
//! `(i1, i2, i3), (i1, i3, i4), ...`. Faces with fewer than 3 vertices produce no triangle.
//! `4OFF`, `nOFF` and `OFF BINARY` are rejected with a clear message. One mesh named after the
//! file.
//!
//! Limits: counts that the file's size cannot hold (at 6 bytes per vertex line and 2 per face
//! line at least) fail at the counts line, before anything is read or reserved.
//!
//! No crate: OFF is a few lines of text, and a hand-written reader gives the line numbers the
//! project's error convention asks for.

use crate::error::{Error, Result};
use crate::scene::Mesh;
use glam::Vec3;

/// Parses OFF bytes into one mesh.
pub fn parse(bytes: &[u8], file: &str) -> Result<Vec<Mesh>> {
    let at = |line: usize, msg: String| Error::parse(file, format!("line {line}"), msg);
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => {
            let line = 1 + bytes[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            return Err(at(line, "not valid UTF-8 text".into()));
        }
    };
    // Non-blank lines with comments stripped, numbered from 1.
    let mut lines = text
        .split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, l.split('#').next().unwrap_or("").trim_ascii()))
        .filter(|(_, l)| !l.is_empty());
    // The last line with content, for "unexpected end of file" (a final newline starts no line).
    let last_line = text.lines().count().max(1);

    let Some((hl, head)) = lines.next() else {
        return Err(at(1, "empty file (expected an OFF header)".into()));
    };
    let mut words = head.split_ascii_whitespace();
    let keyword = words.next().unwrap_or("");
    let Some(prefix) = keyword.strip_suffix("OFF") else {
        return Err(at(
            hl,
            format!("not an OFF file (expected \"OFF\", found {keyword:?})"),
        ));
    };
    if prefix.contains('4') || prefix.contains('n') {
        return Err(at(
            hl,
            format!("{keyword}: only 3-dimensional OFF is supported"),
        ));
    }
    if !prefix.chars().all(|c| matches!(c, 'C' | 'N' | 'S' | 'T')) {
        return Err(at(hl, format!("unknown OFF variant {keyword:?}")));
    }
    let rest: Vec<&str> = words.collect();
    if rest.first() == Some(&"BINARY") {
        return Err(at(hl, "binary OFF is not supported".into()));
    }
    // Counts may follow the keyword on the same line.
    let (cl, counts) = if rest.is_empty() {
        match lines.next() {
            Some((l, c)) => (l, c.split_ascii_whitespace().collect::<Vec<_>>()),
            None => {
                return Err(at(
                    last_line,
                    "unexpected end of file: expected the counts line \"nv nf ne\"".into(),
                ))
            }
        }
    } else {
        (hl, rest)
    };
    if counts.len() < 2 || counts.len() > 3 {
        return Err(at(
            cl,
            format!(
                "expected the counts \"nv nf [ne]\", found {} values",
                counts.len()
            ),
        ));
    }
    let count = |s: &str, what: &str| -> Result<usize> {
        s.parse::<usize>()
            .map_err(|_| at(cl, format!("bad {what} count {s:?}")))
    };
    let nv = count(counts[0], "vertex")?;
    let nf = count(counts[1], "face")?;
    if let Some(ne) = counts.get(2) {
        count(ne, "edge")?;
    }
    // Before reading or reserving anything: a vertex line takes at least 6 bytes ("0 0 0" and a
    // newline), a face line 2 ("0" and a newline; the last line may lack its newline).
    let need = nv as u128 * 6 + nf as u128 * 2;
    if need > text.len() as u128 + 1 {
        return Err(at(
            cl,
            format!(
                "the header declares {nv} vertices and {nf} faces, more than the {} bytes of the file can hold (at least 6 bytes per vertex, 2 per face)",
                text.len()
            ),
        ));
    }
    if nv > u32::MAX as usize {
        return Err(at(
            cl,
            format!("{nv} vertices; at most {} are supported", u32::MAX),
        ));
    }

    // Cap reservations by what the text could hold (a hostile count must not allocate GBs).
    let mut positions = Vec::with_capacity(nv.min(text.len() / 6));
    for i in 0..nv {
        let Some((ln, l)) = lines.next() else {
            return Err(at(
                last_line,
                format!("unexpected end of file: the header declares {nv} vertices, found {i}"),
            ));
        };
        let mut xyz = [0f32; 3];
        let mut toks = l.split_ascii_whitespace();
        for (a, c) in xyz.iter_mut().enumerate() {
            let t = toks
                .next()
                .ok_or_else(|| at(ln, format!("vertex {i}: expected 3 coordinates, found {a}")))?;
            *c = t
                .parse()
                .map_err(|_| at(ln, format!("vertex {i}: bad number {t:?}")))?;
        }
        // Extra values (colours, normals, texture coordinates) must still be numbers.
        for t in toks {
            if t.parse::<f64>().is_err() {
                return Err(at(ln, format!("vertex {i}: bad number {t:?}")));
            }
        }
        let p = Vec3::from_array(xyz);
        if !p.is_finite() {
            return Err(at(ln, format!("vertex {i}: non-finite coordinate {p:?}")));
        }
        positions.push(p);
    }

    let mut indices = Vec::with_capacity(nf.min(text.len() / 8));
    let mut face = Vec::new();
    for f in 0..nf {
        let Some((ln, l)) = lines.next() else {
            return Err(at(
                last_line,
                format!("unexpected end of file: the header declares {nf} faces, found {f}"),
            ));
        };
        let mut toks = l.split_ascii_whitespace();
        let nt = toks.next().unwrap_or("");
        let n: usize = nt
            .parse()
            .map_err(|_| at(ln, format!("face {f}: bad vertex count {nt:?}")))?;
        face.clear();
        for k in 0..n {
            let t = toks.next().ok_or_else(|| {
                at(
                    ln,
                    format!("face {f}: declares {n} vertices, found {k} indices"),
                )
            })?;
            let v: u64 = t
                .parse()
                .map_err(|_| at(ln, format!("face {f}: bad vertex index {t:?}")))?;
            if v >= nv as u64 {
                return Err(at(
                    ln,
                    format!("face {f}: vertex index {v} out of range (the file has {nv} vertices)"),
                ));
            }
            face.push(v as u32);
        }
        // Anything after the indices is a face colour; it must be numeric.
        for t in toks {
            if t.parse::<f64>().is_err() {
                return Err(at(
                    ln,
                    format!("face {f}: bad number {t:?} after the indices"),
                ));
            }
        }
        if face.len() >= 3 {
            for w in face[1..].windows(2) {
                indices.push([face[0], w[0], w[1]]);
            }
        }
    }
    if let Some((ln, _)) = lines.next() {
        return Err(at(
            ln,
            format!("data after the {nf} faces the header declares (wrong counts?)"),
        ));
    }
    let name = std::path::Path::new(file)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| file.to_string());
    Ok(vec![Mesh::new(name, positions, indices)])
}
