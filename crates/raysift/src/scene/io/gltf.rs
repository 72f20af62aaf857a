//! glTF 2.0 loader: `.gltf` (JSON, buffers as base64 data URIs or external files next to it)
//! and `.glb` (binary container), on the `gltf` crate.
//!
//! Loads every mesh primitive of every node of the default scene (all scenes in order when
//! there is no default; all root nodes when the file has no scene at all). Each node that has a
//! mesh gives one [`Mesh`] (its primitives concatenated in order) with the node's world
//! transform (parents composed). Modes: TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (converted
//! with the spec's vertex order: strip `i` is `(i, i+1, i+2)` for even `i` and `(i, i+2, i+1)`
//! for odd `i`, fan `i` is `(i+1, i+2, 0)`); POINTS and LINES are skipped. Indexed and
//! non-indexed primitives, sparse accessors. Skins and morph targets are ignored here (the bind
//! pose is loaded); `gltf_anim.rs` plays animations and skins on top of [`parse_full`].
//!
//! Why the crate and where not: `gltf` parses and validates the JSON (references, enums) and
//! resolves buffers (data URIs, external files, the GLB `BIN` chunk). But some of its own code
//! panics on hostile input (its accessor iterators compute `count - 1` and `offset + stride *
//! ...` unchecked; its validation indexes the POSITION accessor before checking the index; a
//! GLB header length under 12 underflows; an invalid `%xx` URI escape is unwrapped), so this
//! module splits the GLB container itself, pre-checks attribute indices and URIs, and decodes
//! accessor bytes itself with checked arithmetic, reporting byte offsets. No `catch_unwind`.
//! The node hierarchy is walked with an explicit stack (a deep chain cannot overflow the call
//! stack), a node reached twice in one scene is an error (glTF nodes form trees), and a sparse
//! accessor without a `bufferView` is bounded by the file's data size, so hostile counts fail
//! cleanly instead of exhausting memory.
//!
//! Limits: an accessor must fit in its buffer view and a view in its buffer (checked before
//! decoding); a sparse accessor without a `bufferView` (implicit zeros, nothing in the file
//! behind them) may decode to at most 16 bytes per byte of buffer data plus 64 KiB; an external
//! buffer must be a regular file (not a FIFO or a device such as `/dev/zero`, which `gltf` would
//! block on or read forever) that fits in memory. Instancing (many nodes sharing one mesh) and
//! accessors sharing bytes legitimately describe scenes far larger than the file, so the decoded
//! output is bounded by the scene's own limit (fewer than 2^32 - 1 triangles) and by the
//! available memory (12 bytes per vertex, 48 per triangle with the world soup), not by a ratio:
//! each primitive is counted before its triangles are built, and every instance before any
//! instance is copied.

use super::gltf_container::{load_buffers, precheck, split_glb};
use super::limits;
use crate::error::{Error, Result};
use crate::scene::{Material, Mesh};
use glam::{Affine3A, Mat4, Vec3};
use gltf::json;
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::Path;

/// Parses glTF (`.gltf` JSON or `.glb`) bytes into meshes; `base` resolves external buffers.
pub fn parse(bytes: &[u8], file: &str, base: Option<&Path>) -> Result<Vec<Mesh>> {
    parse_full(bytes, file, base).map(|p| p.meshes)
}

/// A parsed file as the animation reader (`gltf_anim.rs`) needs it: the meshes, the node each
/// mesh came from, the validated document and its buffers.
pub(super) struct Parsed {
    pub meshes: Vec<Mesh>,
    pub nodes: Vec<usize>,
    pub doc: gltf::Document,
    pub buffers: Vec<gltf::buffer::Data>,
}

/// [`parse`], keeping what [`Parsed`] holds.
pub(super) fn parse_full(bytes: &[u8], file: &str, base: Option<&Path>) -> Result<Parsed> {
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(Error::parse(file, "byte 0", "empty file"));
    }
    let (json_bytes, blob, glb) = if bytes.starts_with(b"glTF") {
        let (j, b) = split_glb(bytes, file)?;
        (j, b, true)
    } else {
        (bytes, None, false)
    };
    let root: json::Root = json::deserialize::from_slice(json_bytes).map_err(|e| {
        let where_ = if glb { "JSON chunk, " } else { "" };
        Error::parse(
            file,
            format!("{where_}line {}, column {}", e.line(), e.column()),
            format!("invalid glTF JSON: {e}"),
        )
    })?;
    precheck(&root, file)?;
    let doc = gltf::Document::from_json(root).map_err(|e| match e {
        gltf::Error::Validation(errs) => {
            let (path, err) = &errs[0];
            let more = if errs.len() > 1 {
                format!(" (and {} more problems)", errs.len() - 1)
            } else {
                String::new()
            };
            Error::parse(file, path.to_string(), format!("invalid glTF: {err}{more}"))
        }
        other => Error::parse(file, "document", other.to_string()),
    })?;
    let buffers = load_buffers(&doc, base, blob, file)?;

    let mut builder = Builder {
        file,
        buffers: &buffers,
        cache: HashMap::new(),
        materials: HashMap::new(),
        pending: Vec::new(),
        mem: limits::mem_available(),
        vertices: 0,
        triangles: 0,
    };
    // One list of root nodes per traversal (a node may appear in several scenes).
    let traversals: Vec<Vec<gltf::Node>> = if let Some(scene) = doc.default_scene() {
        vec![scene.nodes().collect()]
    } else if doc.scenes().len() > 0 {
        doc.scenes().map(|s| s.nodes().collect()).collect()
    } else {
        // No scene: every node that is nobody's child.
        let mut is_child = vec![false; doc.nodes().len()];
        for n in doc.nodes() {
            for c in n.children() {
                is_child[c.index()] = true;
            }
        }
        vec![doc.nodes().filter(|n| !is_child[n.index()]).collect()]
    };
    for roots in traversals {
        builder.traverse(roots, doc.nodes().len())?;
    }
    let (meshes, nodes) = builder.finish();
    Ok(Parsed {
        meshes,
        nodes,
        doc,
        buffers,
    })
}

/// The modes the loader turns into triangles (the others are skipped).
pub(super) fn is_triangles(mode: Mode) -> bool {
    matches!(
        mode,
        Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
    )
}

/// The bytes of every element of `acc` (`elem` bytes each, sparse substitution applied), each
/// bounds-checked as the mesh decoder's are; for the animation reader.
pub(super) fn accessor_elements<'a>(
    file: &'a str,
    buffers: &'a [gltf::buffer::Data],
    acc: &gltf::Accessor,
    elem: usize,
) -> Result<Vec<&'a [u8]>> {
    let b = Builder {
        file,
        buffers,
        cache: HashMap::new(),
        materials: HashMap::new(),
        pending: Vec::new(),
        mem: None,
        vertices: 0,
        triangles: 0,
    };
    Ok(b.gather(acc, elem)?.iter().map(|e| e.bytes).collect())
}

struct Builder<'a> {
    file: &'a str,
    buffers: &'a [gltf::buffer::Data],
    /// Decoded meshes by glTF mesh index, so instances decode once.
    cache: HashMap<usize, (Vec<Vec3>, Vec<[u32; 3]>)>,
    /// Material runs of each decoded mesh (see [`Builder::record_material`]).
    materials: HashMap<usize, Vec<(u32, Material)>>,
    /// Instances to build: mesh name, glTF mesh index, world transform, node index.
    pending: Vec<(String, usize, Mat4, usize)>,
    /// Available memory, read once ([`limits::mem_available`]).
    mem: Option<u64>,
    /// Vertices and triangles decoded or instanced so far (the budget in the module doc).
    vertices: u64,
    triangles: u64,
}

impl<'a> Builder<'a> {
    /// Counts `vertices` and `triangles` more against the budget (see the module doc), before
    /// they are allocated.
    fn spend(&mut self, place: &str, vertices: u64, triangles: u64) -> Result<()> {
        self.vertices += vertices;
        self.triangles += triangles;
        if self.triangles >= u32::MAX as u64 {
            return Err(Error::parse(
                self.file,
                place,
                format!(
                    "the scene reaches {} triangles; at most {} are supported",
                    self.triangles,
                    u32::MAX - 1
                ),
            ));
        }
        limits::check_memory_with(
            self.mem,
            self.file,
            place,
            &format!(
                "the {} vertices and {} triangles decoded so far",
                self.vertices, self.triangles
            ),
            self.vertices * 12 + self.triangles * 48,
        )
    }

    /// Depth-first, children in order, with an explicit stack: a hostile file with a very deep
    /// hierarchy must not overflow the call stack. glTF nodes form disjoint trees, so a node
    /// reached twice in one scene (two parents, a cycle, or listed twice) is an error; that
    /// also bounds the work by the node count.
    fn traverse(&mut self, roots: Vec<gltf::Node>, node_count: usize) -> Result<()> {
        let mut seen = vec![false; node_count];
        let mut stack: Vec<(gltf::Node, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::IDENTITY))
            .collect();
        while let Some((node, parent)) = stack.pop() {
            if std::mem::replace(&mut seen[node.index()], true) {
                return Err(Error::parse(
                    self.file,
                    format!("nodes[{}]", node.index()),
                    "node reached twice in one scene (more than one parent, a cycle, or listed twice)",
                ));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            self.instance(&node, world)?;
            let children: Vec<gltf::Node> = node.children().collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
        Ok(())
    }

    /// Records the node's mesh, if any, as one instance with the node's world transform (made a
    /// [`Mesh`] by [`Self::finish`]), decoding the mesh the first time.
    fn instance(&mut self, node: &gltf::Node, world: Mat4) -> Result<()> {
        let Some(mesh) = node.mesh() else {
            return Ok(());
        };
        if !self.cache.contains_key(&mesh.index()) {
            let decoded = self.decode_mesh(&mesh)?;
            self.cache.insert(mesh.index(), decoded);
        }
        let (nv, nt) = {
            let (p, i) = &self.cache[&mesh.index()];
            (p.len() as u64, i.len() as u64)
        };
        if nt > 0 {
            self.spend(&format!("nodes[{}]", node.index()), nv, nt)?;
        }
        if nt > 0 {
            let node_name = node
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("node {}", node.index()));
            let mesh_name = mesh
                .name()
                .map(str::to_string)
                .unwrap_or_else(|| format!("mesh {}", mesh.index()));
            self.pending
                .push((format!("{node_name}/{mesh_name}"), mesh.index(), world, node.index()));
        }
        Ok(())
    }

    /// The instances as meshes, in traversal order. Called after every instance has been
    /// counted against the budget, so nothing is copied for a scene that is refused.
    fn finish(mut self) -> (Vec<Mesh>, Vec<usize>) {
        let mut out = Vec::with_capacity(self.pending.len());
        let mut nodes = Vec::with_capacity(self.pending.len());
        for (name, mesh, world, node) in std::mem::take(&mut self.pending) {
            let (positions, indices) = &self.cache[&mesh];
            let mut m = Mesh::new(name, positions.clone(), indices.clone());
            m.transform = Affine3A::from_mat4(world);
            m.materials = self.materials.get(&mesh).cloned().unwrap_or_default();
            // A trailing run past the last triangle (a material on a primitive with none).
            m.materials.retain(|r| (r.0 as usize) < m.indices.len());
            out.push(m);
            nodes.push(node);
        }
        (out, nodes)
    }

    /// Decodes a mesh's triangle primitives. Its triangles are counted against the budget as
    /// they are decoded and given back afterwards: the instances (in [`Self::instance`]) are
    /// what the scene keeps.
    fn decode_mesh(&mut self, mesh: &gltf::Mesh) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
        let (v0, t0) = (self.vertices, self.triangles);
        let r = self.decode_mesh_counted(mesh);
        (self.vertices, self.triangles) = (v0, t0);
        r
    }

    /// Materials (the material part of the loader): a primitive's `baseColorFactor` (RGB) is
    /// its diffuse colour, `emissiveFactor` its emission, and a metallic factor of 1 with a
    /// roughness of 0 makes a perfect mirror. Textures and `KHR_materials_emissive_strength`
    /// are not read. A primitive without a material after one with gets the default grey; one
    /// before any gets none.
    fn record_material(&mut self, mesh: usize, first: u32, prim: &gltf::Primitive) {
        let runs = self.materials.entry(mesh).or_default();
        let m = prim.material();
        let mat = if m.index().is_none() {
            if runs.is_empty() {
                return;
            }
            Material::default()
        } else {
            let pbr = m.pbr_metallic_roughness();
            let [r, g, b, _] = pbr.base_color_factor();
            let finite = |v: Vec3| if v.is_finite() { v } else { Vec3::ZERO };
            Material {
                diffuse: finite(Vec3::new(r, g, b)).clamp(Vec3::ZERO, Vec3::ONE),
                emission: finite(Vec3::from_array(m.emissive_factor())).max(Vec3::ZERO),
                mirror: pbr.metallic_factor() >= 1.0 && pbr.roughness_factor() <= 0.0,
            }
        };
        if runs.last().is_some_and(|l| l.0 == first) {
            runs.pop();
        }
        if runs.last().is_none_or(|l| l.1 != mat) {
            runs.push((first, mat));
        }
    }

    fn decode_mesh_counted(&mut self, mesh: &gltf::Mesh) -> Result<(Vec<Vec3>, Vec<[u32; 3]>)> {
        let mut positions = Vec::new();
        let mut tris = Vec::new();
        for prim in mesh.primitives() {
            let mode = prim.mode();
            if !is_triangles(mode) {
                continue;
            }
            let place = |what: &str| {
                format!(
                    "meshes[{}].primitives[{}]{what}",
                    mesh.index(),
                    prim.index()
                )
            };
            let pos_acc = prim
                .get(&gltf::Semantic::Positions)
                .ok_or_else(|| Error::parse(self.file, place(""), "no POSITION attribute"))?;
            let base = positions.len() as u64;
            let first_new = positions.len();
            self.read_positions(&pos_acc, &mut positions)?;
            let nv = (positions.len() - first_new) as u64;
            if base + nv > u32::MAX as u64 {
                return Err(Error::parse(self.file, place(""), "too many vertices"));
            }
            let idx: Vec<u32> = match prim.indices() {
                Some(acc) => self.read_indices(&acc, nv)?,
                None => (0..nv as u32).collect(),
            };
            let n = idx.len();
            let b = base as u32;
            self.record_material(mesh.index(), tris.len() as u32, &prim);
            let new_tris = match mode {
                Mode::Triangles => n / 3,
                _ => n.saturating_sub(2),
            };
            self.spend(&place(""), nv, new_tris as u64)?;
            match mode {
                Mode::Triangles => {
                    if !n.is_multiple_of(3) {
                        return Err(Error::parse(
                            self.file,
                            place(""),
                            format!("TRIANGLES primitive with {n} vertices (not a multiple of 3)"),
                        ));
                    }
                    tris.extend(idx.chunks_exact(3).map(|c| [b + c[0], b + c[1], b + c[2]]));
                }
                Mode::TriangleStrip => {
                    for i in 0..n.saturating_sub(2) {
                        let t = if i % 2 == 0 {
                            [idx[i], idx[i + 1], idx[i + 2]]
                        } else {
                            [idx[i], idx[i + 2], idx[i + 1]]
                        };
                        tris.push(t.map(|v| b + v));
                    }
                }
                Mode::TriangleFan => {
                    for i in 0..n.saturating_sub(2) {
                        tris.push([idx[i + 1], idx[i + 2], idx[0]].map(|v| b + v));
                    }
                }
                _ => unreachable!("filtered above"),
            }
        }
        Ok((positions, tris))
    }

    fn read_positions(&self, acc: &gltf::Accessor, out: &mut Vec<Vec3>) -> Result<()> {
        use gltf::accessor::{DataType, Dimensions};
        if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 {
            return Err(Error::parse(
                self.file,
                format!("accessors[{}]", acc.index()),
                format!(
                    "POSITION must be VEC3 FLOAT, found {:?} {:?} (quantized positions are not supported)",
                    acc.dimensions(),
                    acc.data_type()
                ),
            ));
        }
        let data = self.gather(acc, 12)?;
        out.reserve(acc.count());
        for (i, e) in data.iter().enumerate() {
            let f = |k: usize| f32::from_le_bytes(e.bytes[4 * k..4 * k + 4].try_into().unwrap());
            let p = Vec3::new(f(0), f(1), f(2));
            if !p.is_finite() {
                return Err(Error::parse(
                    self.file,
                    format!(
                        "accessors[{}], element {i} (buffer {}, byte {})",
                        acc.index(),
                        e.buffer,
                        e.offset
                    ),
                    format!("non-finite position {p:?}"),
                ));
            }
            out.push(p);
        }
        Ok(())
    }

    fn read_indices(&self, acc: &gltf::Accessor, nv: u64) -> Result<Vec<u32>> {
        use gltf::accessor::{DataType, Dimensions};
        let size = match acc.data_type() {
            DataType::U8 => 1,
            DataType::U16 => 2,
            DataType::U32 => 4,
            t => {
                return Err(Error::parse(
                    self.file,
                    format!("accessors[{}]", acc.index()),
                    format!("indices must be unsigned integers, found {t:?}"),
                ))
            }
        };
        if acc.dimensions() != Dimensions::Scalar {
            return Err(Error::parse(
                self.file,
                format!("accessors[{}]", acc.index()),
                "indices must be SCALAR",
            ));
        }
        let data = self.gather(acc, size)?;
        let mut out = Vec::with_capacity(data.len());
        for (i, e) in data.iter().enumerate() {
            let v = read_uint(e.bytes);
            if v as u64 >= nv {
                return Err(Error::parse(
                    self.file,
                    format!(
                        "accessors[{}], element {i} (buffer {}, byte {})",
                        acc.index(),
                        e.buffer,
                        e.offset
                    ),
                    format!("vertex index {v} out of range (the primitive has {nv} vertices)"),
                ));
            }
            out.push(v);
        }
        Ok(out)
    }

    /// The bytes of every element of `acc` (`elem` bytes each), sparse substitution applied,
    /// as a lazy view (nothing is allocated per element).
    fn gather(&self, acc: &gltf::Accessor, elem: usize) -> Result<Gathered<'a>> {
        let count = acc.count();
        let place = format!("accessors[{}]", acc.index());
        if count == 0 {
            // The spec's minimum; `gltf` 1.4 does not validate it (and its own reader underflows).
            return Err(Error::parse(
                self.file,
                place,
                "count is 0 (glTF requires at least 1)",
            ));
        }
        let base = match acc.view() {
            Some(view) => Some(self.strided(&view, acc.offset(), count, elem, &place)?),
            // Sparse accessor without a view: base values are zeros.
            None => {
                // Nothing in the file backs `count` here, so bound it by the file's data: a
                // hostile count must be an error, not a large allocation downstream.
                let data: usize = self.buffers.iter().map(|b| b.len()).sum();
                let limit = data.saturating_mul(16).saturating_add(64 << 10);
                if count.saturating_mul(elem) > limit {
                    return Err(Error::parse(
                        self.file,
                        place,
                        format!(
                            "sparse accessor without bufferView has count {count} ({} bytes of implicit zeros), implausibly large for {data} bytes of buffers (at most 16 bytes per buffer byte + 64 KiB)",
                            count.saturating_mul(elem)
                        ),
                    ));
                }
                None
            }
        };
        // Up to a MAT4 of f32 (the animation reader's inverse bind matrices).
        const ZEROS: [u8; 64] = [0; 64];
        let mut g = Gathered {
            base,
            count,
            zeros: &ZEROS[..elem],
            sparse: Vec::new(),
        };
        if let Some(sparse) = acc.sparse() {
            let sc = sparse.count();
            let ind = sparse.indices();
            let isize_ = match ind.index_type() {
                gltf::accessor::sparse::IndexType::U8 => 1,
                gltf::accessor::sparse::IndexType::U16 => 2,
                gltf::accessor::sparse::IndexType::U32 => 4,
            };
            let iv = ind.view();
            // Sparse indices and values are tightly packed (no byteStride allowed).
            let is = self.strided_packed(&iv, ind.offset(), sc, isize_, &place)?;
            let vals = sparse.values();
            let vs = self.strided_packed(&vals.view(), vals.offset(), sc, elem, &place)?;
            // `sc` elements fit in the views (checked above), so this is bounded by the file.
            g.sparse.reserve_exact(sc);
            for k in 0..sc {
                let target = read_uint(is.get(k).bytes) as usize;
                if target >= count {
                    let e = is.get(k);
                    return Err(Error::parse(
                        self.file,
                        format!(
                            "{place}, sparse index {k} (buffer {}, byte {})",
                            e.buffer, e.offset
                        ),
                        format!("sparse index {target} out of range (count {count})"),
                    ));
                }
                g.sparse.push((target, vs.get(k)));
            }
            // Stable: of repeated targets (invalid glTF, tolerated), the last one wins.
            g.sparse.sort_by_key(|&(t, _)| t);
        }
        Ok(g)
    }

    fn strided_packed(
        &self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        elem: usize,
        place: &str,
    ) -> Result<Strided<'a>> {
        self.strided_with(view, offset, count, elem, place, Some(elem))
    }

    fn strided(
        &self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        elem: usize,
        place: &str,
    ) -> Result<Strided<'a>> {
        self.strided_with(view, offset, count, elem, place, None)
    }

    fn strided_with(
        &self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        elem: usize,
        place: &str,
        stride: Option<usize>,
    ) -> Result<Strided<'a>> {
        let b = view.buffer().index();
        let buffers: &'a [gltf::buffer::Data] = self.buffers;
        let data = &buffers[b];
        let v_start = view.offset();
        let v_len = view.length();
        if v_start.checked_add(v_len).is_none_or(|e| e > data.len()) {
            return Err(Error::parse(
                self.file,
                format!("bufferViews[{}]", view.index()),
                format!(
                    "bytes {v_start}..{} are outside buffer {b} ({} bytes)",
                    v_start.saturating_add(v_len),
                    data.len()
                ),
            ));
        }
        let stride = stride.or(view.stride()).unwrap_or(elem);
        if stride < elem {
            return Err(Error::parse(
                self.file,
                format!("bufferViews[{}]", view.index()),
                format!("byteStride {stride} is smaller than the element size {elem}"),
            ));
        }
        let s = Strided {
            view: &data[v_start..v_start + v_len],
            view_index: view.index(),
            buffer: b,
            view_start: v_start,
            offset,
            stride,
            elem,
        };
        s.check(count, self.file, place)?;
        Ok(s)
    }
}

/// An accessor's elements: its view (or zeros) with sparse substitutions, read lazily.
struct Gathered<'a> {
    base: Option<Strided<'a>>,
    count: usize,
    zeros: &'static [u8],
    /// Sparse substitutions `(target, value)`, sorted by target.
    sparse: Vec<(usize, Elem<'a>)>,
}

impl<'a> Gathered<'a> {
    fn len(&self) -> usize {
        self.count
    }

    fn iter(&self) -> impl Iterator<Item = Elem<'a>> + '_ {
        let mut p = 0;
        (0..self.count).map(move |i| {
            let mut v = None;
            while p < self.sparse.len() && self.sparse[p].0 == i {
                v = Some(self.sparse[p].1);
                p += 1;
            }
            v.unwrap_or_else(|| match &self.base {
                Some(s) => s.get(i),
                None => Elem {
                    bytes: self.zeros,
                    buffer: 0,
                    offset: 0,
                },
            })
        })
    }
}

#[derive(Clone, Copy)]
struct Elem<'a> {
    bytes: &'a [u8],
    buffer: usize,
    /// Byte offset in the buffer.
    offset: usize,
}

struct Strided<'a> {
    view: &'a [u8],
    view_index: usize,
    buffer: usize,
    view_start: usize,
    offset: usize,
    stride: usize,
    elem: usize,
}

impl<'a> Strided<'a> {
    /// Checks that `count` elements fit in the view; `get` is then in bounds.
    fn check(&self, count: usize, file: &str, place: &str) -> Result<()> {
        if count == 0 {
            return Ok(());
        }
        let end = (count - 1)
            .checked_mul(self.stride)
            .and_then(|x| x.checked_add(self.offset))
            .and_then(|x| x.checked_add(self.elem));
        match end {
            Some(e) if e <= self.view.len() => Ok(()),
            _ => Err(Error::parse(
                file,
                format!(
                    "{place} (buffer {}, byte {})",
                    self.buffer,
                    self.view_start.saturating_add(self.offset)
                ),
                format!(
                    "{count} elements of {} bytes (stride {}) from byte {} do not fit in buffer view {} ({} bytes)",
                    self.elem,
                    self.stride,
                    self.offset,
                    self.view_index,
                    self.view.len()
                ),
            )),
        }
    }

    #[inline]
    fn get(&self, i: usize) -> Elem<'a> {
        let o = self.offset + i * self.stride;
        Elem {
            bytes: &self.view[o..o + self.elem],
            buffer: self.buffer,
            offset: self.view_start + o,
        }
    }
}

#[inline]
pub(super) fn read_uint(b: &[u8]) -> u32 {
    match b.len() {
        1 => b[0] as u32,
        2 => u16::from_le_bytes([b[0], b[1]]) as u32,
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}
