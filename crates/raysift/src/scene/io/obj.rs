//! Wavefront OBJ loader, built on `tobj` (the project's OBJ dependency).
//!
//! Supports `v` (optional `w` divisor or RGB colour), `vt`, `vn`, `f` with `v`, `v/vt`,
//! `v//vn` and `v/vt/vn` corners, negative (relative) indices, polygons of any size, `o`/`g`
//! names, `usemtl`, CRLF line endings. Points (`p`, one-corner `f`) and lines (`l`, two-corner
//! `f`) produce no triangle.
//!
//! **Materials** ([`parse_with_materials`], which [`super::load`] uses): every `mtllib` file is
//! opened next to the OBJ and read through tobj's MTL parser: `Kd` is the diffuse colour, `Ke`
//! the emission (so the Cornell box's `light` is an area light), `illum 3` or `illum 5`
//! (reflection by ray tracing) makes a perfect mirror. A missing `.mtl`, or a `usemtl` naming a
//! material it lacks, leaves those faces without a material (renderers draw them default grey),
//! silently: OBJ files are very often shipped without their `.mtl`, and the geometry is still
//! what the user asked for. A `.mtl` that exists but is malformed is an error naming the `.mtl`
//! and its line. [`parse`] (bytes only, as the fuzz targets use it) never touches the file
//! system and reads no material.
//!
//! **Triangulation**: polygons are fanned in order, `(v0, v1, v2), (v0, v2, v3), ...`. tobj
//! 4.0's own `triangulate` gives exactly this for quads and polygons, but it also turns points
//! and lines into degenerate triangles; so tobj is asked for untriangulated faces and the fan
//! is built here from `face_arities`, which keeps the order under our control.
//!
//! **Meshes and primitive ids**: one mesh per tobj model, named after it. tobj starts a new
//! model at every `o`/`g` line that follows faces (it would also split at a `usemtl` that
//! changes the material, but materials are not loaded here, so `usemtl` never splits), and
//! appends models in file order with their faces in file order; so meshes in order, faces in
//! order, is exactly the file order of the faces. Materials do not split meshes either: the
//! pre-pass records which `usemtl` is active at each triangle, and each mesh gets the runs of
//! its triangle range. A model is named by the `o`/`g` line before
//! its faces (`unnamed_object` if none): a file that writes `g name` *after* a group's faces,
//! as `CornellBox-Original.obj` does for its boxes, gets the previous name on those faces. A file that interleaves groups (`g a`, `g b`, `g a` again) gives three
//! meshes, two of them named `a`: faces are never regrouped, so primitive id = index of the
//! triangle in file order, whatever the grouping. Each mesh holds the positions its faces use
//! (in first-use order), so a vertex shared by two groups is stored in both.
//!
//! **Errors**: tobj reports errors without a line number, and some hostile indices (a relative
//! texture index far below zero) overflow its arithmetic, i.e. panic with overflow checks on.
//! So a validating pre-pass reads every line first (cheap next to tobj) and reports `line N:`
//! for bad numbers, non-finite coordinates, malformed or out-of-range face corners and invalid
//! UTF-8; only then is tobj run, on input it is known to accept. Indices must refer to
//! elements defined earlier in the file (forward references are rejected, as relative indices
//! imply).

use crate::error::{Error, Result};
use crate::scene::{Material, Mesh};
use glam::Vec3;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

/// Parses OBJ bytes into meshes, one per tobj model (see the module doc); no materials.
pub fn parse(bytes: &[u8], file: &str) -> Result<Vec<Mesh>> {
    Ok(parse_inner(bytes, file)?.0)
}

/// [`parse`], plus the materials of the `mtllib` files found in `base` (the OBJ's folder).
pub fn parse_with_materials(bytes: &[u8], file: &str, base: &Path) -> Result<Vec<Mesh>> {
    let (mut meshes, pre) = parse_inner(bytes, file)?;
    let mut library: HashMap<String, Material> = HashMap::new();
    for lib in &pre.mtllibs {
        let path = base.join(lib);
        let Ok(text) = std::fs::read(&path) else {
            continue; // a missing .mtl: no materials (see the module doc)
        };
        for (name, m) in parse_mtl(&text, &path.display().to_string())? {
            library.entry(name).or_insert(m);
        }
    }
    if library.is_empty() {
        return Ok(meshes);
    }
    // Triangle `k` (in file order) has material `pre.usemtl[r].1` for the last run r with
    // `pre.usemtl[r].0 <= k`.
    let mut first = 0u32;
    for mesh in &mut meshes {
        let n = mesh.indices.len() as u32;
        let runs = &pre.usemtl;
        let start = runs.partition_point(|r| r.0 <= first).saturating_sub(1);
        for r in start..runs.len() {
            let (at, ref name) = runs[r];
            if at >= first + n {
                break;
            }
            let Some(&m) = library.get(name) else {
                // An unknown name after a known one: default grey from here on (faces before any
                // known material keep none).
                if !mesh.materials.is_empty() {
                    mesh.materials
                        .push((at.max(first) - first, Material::default()));
                }
                continue;
            };
            let local = at.max(first) - first;
            if mesh.materials.last().is_some_and(|l| l.0 == local) {
                mesh.materials.pop();
            }
            mesh.materials.push((local, m));
        }
        first += n;
    }
    Ok(meshes)
}

/// Reads a `.mtl` file's materials (see the module doc): validates every line first, so that
/// errors name the line, then parses with tobj.
pub fn parse_mtl(bytes: &[u8], file: &str) -> Result<Vec<(String, Material)>> {
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let at = |msg: String| Error::parse(file, format!("line {}", i + 1), msg);
        let line = std::str::from_utf8(raw).map_err(|_| at("not valid UTF-8 text".into()))?;
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let numbers = |n: usize, words: std::str::SplitWhitespace| -> Result<()> {
            let vals: Vec<&str> = words.take(n).collect();
            if vals.len() < n {
                return Err(at(format!("{key} needs {n} numbers, found {}", vals.len())));
            }
            for v in vals {
                match v.parse::<f32>() {
                    Ok(x) if x.is_finite() => {}
                    _ => return Err(at(format!("{key}: bad number {:?}", short(v)))),
                }
            }
            Ok(())
        };
        match key {
            "Ka" | "Kd" | "Ks" | "Ke" => numbers(3, words)?,
            "Ns" | "Ni" | "d" => numbers(1, words)?,
            "illum" => {
                if words.next().and_then(|w| w.parse::<u8>().ok()).is_none() {
                    return Err(at("illum needs an illumination model number 0..10".into()));
                }
            }
            "newmtl" if words.next().is_none() => {
                return Err(at("newmtl without a material name".into()))
            }
            k if k.starts_with("map_") || k == "bump" => {
                if words.next().is_none() {
                    return Err(at(format!("{k} without a file name")));
                }
            }
            _ => {}
        }
    }
    let (mats, _) = tobj::load_mtl_buf(&mut &bytes[..])
        .map_err(|e| Error::parse(file, "MTL data", format!("tobj: {e}")))?;
    let out = mats
        .into_iter()
        .map(|m| {
            let c = |v: Option<[f32; 3]>, d: Vec3| v.map_or(d, Vec3::from_array);
            let d = Material::default();
            let mat = Material {
                diffuse: c(m.diffuse, d.diffuse).clamp(Vec3::ZERO, Vec3::ONE),
                emission: c(m.emissive, Vec3::ZERO).max(Vec3::ZERO),
                mirror: matches!(m.illumination_model, Some(3 | 5)),
            };
            (m.name, mat)
        })
        .collect();
    Ok(out)
}

fn parse_inner(bytes: &[u8], file: &str) -> Result<(Vec<Mesh>, Prepass)> {
    let (bytes, pre) = prepass(bytes, file)?;
    // `..Default::default()` covers tobj's feature-gated fields (merging, reordering) should
    // another crate in the build enable those features.
    #[allow(clippy::needless_update)]
    let opts = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let (models, _materials) = tobj::load_obj_buf(&mut &bytes[..], &opts, |_| {
        // Materials are not used: never touch the file system for them.
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| {
        // The pre-pass rejects everything tobj 4.0 is known to reject; this is a safety net.
        Error::parse(file, "OBJ data", format!("tobj: {e}"))
    })?;

    let mut meshes = Vec::with_capacity(models.len());
    for (m_idx, model) in models.into_iter().enumerate() {
        let mesh = model.mesh;
        let positions: Vec<Vec3> = mesh
            .positions
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect();
        let idx = &mesh.indices;
        let mut tris = Vec::with_capacity(idx.len() / 3);
        if mesh.face_arities.is_empty() {
            // tobj leaves `face_arities` empty when every face is a triangle.
            tris.extend(idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        } else {
            let mut start = 0usize;
            for &n in &mesh.face_arities {
                let n = n as usize;
                let Some(face) = idx.get(start..start + n) else {
                    return Err(Error::parse(
                        file,
                        format!("model {m_idx} ({})", model.name),
                        "tobj returned inconsistent face arities",
                    ));
                };
                if n >= 3 {
                    for w in face[1..].windows(2) {
                        tris.push([face[0], w[0], w[1]]);
                    }
                }
                start += n;
            }
        }
        if tris.is_empty() {
            // A model without faces (vertices only, or a trailing `g`): nothing to trace.
            continue;
        }
        meshes.push(Mesh::new(model.name, positions, tris));
    }
    Ok((meshes, pre))
}

/// What the pre-pass learns besides validity: the `mtllib` names and the material runs
/// (`(first triangle in file order, usemtl name)`).
#[derive(Default)]
struct Prepass {
    mtllibs: Vec<String>,
    usemtl: Vec<(u32, String)>,
}

/// Validates every line (see the module doc). Returns the input, or a copy in which `l`
/// (polyline) lines are blanked out as comments: tobj parses `l a b c` as a polygon face, which
/// no other reader does.
fn prepass<'a>(bytes: &'a [u8], file: &str) -> Result<(Cow<'a, [u8]>, Prepass)> {
    let mut pre = Prepass::default();
    let mut tris = 0u64; // triangles so far (fanned faces of 3+ corners)
    let mut np = 0i64; // positions so far
    let mut nt = 0i64; // texture coordinates so far
    let mut nn = 0i64; // normals so far
    let mut polylines: Vec<usize> = Vec::new(); // byte offsets of `l` keywords
    let mut offset = 0usize;
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_start = offset;
        offset += raw.len() + 1;
        let ln = i + 1;
        let at = |msg: String| Error::parse(file, format!("line {ln}"), msg);
        let line = std::str::from_utf8(raw).map_err(|_| at("not valid UTF-8 text".into()))?;
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        match key {
            "v" => {
                let vals: Vec<&str> = words.collect();
                if !matches!(vals.len(), 3 | 4 | 6) {
                    return Err(at(format!(
                        "vertex needs x y z [w] or x y z r g b, found {} values",
                        vals.len()
                    )));
                }
                let mut f = [0f32; 6];
                for (k, t) in vals.iter().enumerate() {
                    f[k] = t
                        .parse()
                        .map_err(|_| at(format!("bad number {:?}", short(t))))?;
                }
                let mut p = Vec3::new(f[0], f[1], f[2]);
                if vals.len() == 4 {
                    if f[3] == 0.0 {
                        return Err(at("vertex w is zero".into()));
                    }
                    p /= f[3];
                }
                if !p.is_finite() {
                    return Err(at(format!("non-finite coordinate {p:?}")));
                }
                np += 1;
            }
            "vt" | "vn" => {
                let need = if key == "vt" { 2 } else { 3 };
                let mut k = 0;
                for t in words.take(need) {
                    t.parse::<f32>()
                        .map_err(|_| at(format!("bad number {:?}", short(t))))?;
                    k += 1;
                }
                if k < need {
                    return Err(at(format!("{key} needs {need} values, found {k}")));
                }
                if key == "vt" {
                    nt += 1;
                } else {
                    nn += 1;
                }
            }
            "f" | "l" => {
                let mut corners = 0;
                for w in words {
                    corners += 1;
                    let mut parts = w.split('/');
                    for (k, (part, count, what)) in [
                        (parts.next(), np, "vertex"),
                        (parts.next(), nt, "texture coordinate"),
                        (parts.next(), nn, "normal"),
                    ]
                    .into_iter()
                    .enumerate()
                    {
                        let Some(part) = part.filter(|p| !p.is_empty()) else {
                            if k == 0 {
                                return Err(at(format!("face corner {w:?} has no vertex index")));
                            }
                            continue;
                        };
                        let x: i64 = part
                            .parse()
                            .map_err(|_| at(format!("bad {what} index {:?}", short(part))))?;
                        let resolved = if x < 0 { count + x } else { x - 1 };
                        if x == 0 || resolved < 0 || resolved >= count {
                            return Err(at(format!(
                                "{what} index {x} out of range ({count} defined so far)"
                            )));
                        }
                    }
                    if parts.next().is_some() {
                        return Err(at(format!("face corner {w:?} has more than 3 parts")));
                    }
                }
                if key == "l" {
                    polylines.push(line_start + line.len() - line.trim_start().len());
                } else if corners == 0 {
                    return Err(at("face without vertices".into()));
                } else if corners >= 3 {
                    tris += corners as u64 - 2;
                }
            }
            // tobj needs a name after a single space.
            "usemtl"
                if line
                    .split_once(' ')
                    .map(|(_, n)| n.trim())
                    .unwrap_or("")
                    .is_empty() =>
            {
                return Err(at("usemtl without a material name".into()));
            }
            "usemtl" => {
                let name = line.split_once(' ').map(|(_, n)| n.trim()).unwrap_or("");
                let at_tri = tris.min(u32::MAX as u64) as u32;
                if pre.usemtl.last().is_some_and(|r| r.0 == at_tri) {
                    pre.usemtl.pop();
                }
                pre.usemtl.push((at_tri, name.to_string()));
            }
            "mtllib" => pre.mtllibs.extend(words.map(str::to_string)),
            _ => {}
        }
        if np > u32::MAX as i64 {
            return Err(at("too many vertices".into()));
        }
    }
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(Error::parse(file, "line 1", "empty file"));
    }
    if polylines.is_empty() {
        return Ok((Cow::Borrowed(bytes), pre));
    }
    let mut copy = bytes.to_vec();
    for o in polylines {
        copy[o] = b'#';
    }
    Ok((Cow::Owned(copy), pre))
}

fn short(s: &str) -> String {
    s.chars().take(40).collect()
}
