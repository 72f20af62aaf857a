//! Reads a glTF file's animations and skins into a [`Playback`] bound to the Scene the loader
//! makes of the same file ([`gltf::parse_full`](super::gltf::parse_full): the meshes and the
//! node each came from). Accessor bytes are decoded by the loader's bounds-checked reader.
//!
//! Checked, each an error naming the file and the field: an animation with no channels, a
//! sampler with no keyframes, keyframe times negative, decreasing or not finite, an output
//! accessor whose count is not the input's (three times it for CUBICSPLINE), wrong accessor
//! types, NaN or infinite keyframe values, zero-length rotations; a skinned primitive without
//! JOINTS_n / WEIGHTS_n or whose counts differ from its POSITION count, joint indices outside
//! the skin, weights negative, non-finite or summing to zero; inverse bind matrices fewer than
//! the joints or not finite; a node with two parents or in a cycle. A channel naming a missing
//! node or a joint naming a missing node is refused (`animations[a].channels[c].target.node`).
//! Morph-target weight channels are skipped (the loader does not read morph targets).

use super::gltf::{accessor_elements, is_triangles, parse_full, read_uint};
use crate::error::{Error, Result};
use crate::scene::animate::playback::{
    Channel, Clip, Interpolation, Nodes, Playback, Property, Skin, Skinned,
};
use crate::scene::Scene;
use glam::{Mat4, Quat, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use std::path::Path;

/// Loads a `.gltf` / `.glb` (optionally `.gz`) file: its scene (the bind pose, as
/// [`load`](super::load) gives it) and, when it has animations, their player.
pub fn load_animated(path: impl AsRef<Path>) -> Result<(Scene, Option<Playback>)> {
    let path = path.as_ref();
    let (format, gz) = super::detect_format(path)?;
    let name = path.display().to_string();
    if !matches!(format, super::Format::Gltf | super::Format::Glb) {
        return Err(Error::Invalid(format!(
            "{name}: animations are read from glTF files (.gltf or .glb) only"
        )));
    }
    let bytes = super::read_bytes(path, gz)?;
    parse_animated(&bytes, &name, path.parent())
}

/// [`load_animated`] on the bytes of a file named `file` (`base` resolves external buffers).
pub fn parse_animated(
    bytes: &[u8],
    file: &str,
    base: Option<&Path>,
) -> Result<(Scene, Option<Playback>)> {
    let parsed = parse_full(bytes, file, base)?;
    let scene = Scene::from_meshes(file, parsed.meshes)?;
    let doc = &parsed.doc;
    if doc.animations().len() == 0 {
        return Ok((scene, None));
    }
    let r = Reader {
        file,
        buffers: &parsed.buffers,
    };
    r.check_node_refs(doc)?;
    let nodes = r.nodes(doc)?;
    let skins = doc.skins().map(|s| r.skin(&s)).collect::<Result<Vec<_>>>()?;
    let clips = doc
        .animations()
        .map(|a| r.clip(&a))
        .collect::<Result<Vec<_>>>()?;
    let (mut skinned, mut rigid) = (Vec::new(), Vec::new());
    for (m, &n) in parsed.nodes.iter().enumerate() {
        let node = doc.nodes().nth(n).expect("the loader's node index");
        match (node.skin(), node.mesh()) {
            (Some(skin), Some(mesh)) => {
                let bind = scene.meshes()[m].positions.clone();
                skinned.push(r.influences(&mesh, m, skin.index(), skins[skin.index()].joints.len(), bind)?);
            }
            _ => rigid.push((m, n)),
        }
    }
    let playback = Playback::new(nodes, clips, skins, skinned, rigid)?;
    Ok((scene, Some(playback)))
}

struct Reader<'a> {
    file: &'a str,
    buffers: &'a [gltf::buffer::Data],
}

fn f32_at(b: &[u8], k: usize) -> f32 {
    f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap())
}

impl<'a> Reader<'a> {
    fn err(&self, place: impl Into<String>, msg: impl Into<String>) -> Error {
        Error::parse(self.file, place, msg)
    }

    /// Node references `gltf` does not validate (and would unwrap): channel targets, joints.
    fn check_node_refs(&self, doc: &gltf::Document) -> Result<()> {
        let (root, n) = (doc.as_json(), doc.nodes().len());
        let bad = |place: String, k: usize| {
            Err(self.err(place, format!("refers to node {k} but there are {n} nodes")))
        };
        for (a, anim) in root.animations.iter().enumerate() {
            for (c, ch) in anim.channels.iter().enumerate() {
                let k = ch.target.node.value();
                if k >= n {
                    return bad(format!("animations[{a}].channels[{c}].target.node"), k);
                }
            }
        }
        for (s, skin) in root.skins.iter().enumerate() {
            for (j, node) in skin.joints.iter().enumerate() {
                if node.value() >= n {
                    return bad(format!("skins[{s}].joints[{j}]"), node.value());
                }
            }
        }
        Ok(())
    }

    /// Parents, an order with parents first, and each node's rest matrix and TRS.
    fn nodes(&self, doc: &gltf::Document) -> Result<Nodes> {
        let n = doc.nodes().len();
        let mut parent = vec![None; n];
        for node in doc.nodes() {
            for c in node.children() {
                if let Some(p) = parent[c.index()].replace(node.index()) {
                    return Err(self.err(
                        format!("nodes[{}].children", node.index()),
                        format!("node {} already has parent {p} (glTF nodes form trees)", c.index()),
                    ));
                }
            }
        }
        let mut order = Vec::with_capacity(n);
        let mut stack: Vec<usize> = (0..n).filter(|&k| parent[k].is_none()).collect();
        let all: Vec<gltf::Node> = doc.nodes().collect();
        while let Some(k) = stack.pop() {
            order.push(k);
            stack.extend(all[k].children().map(|c| c.index()));
        }
        if order.len() < n {
            let mut seen = vec![false; n];
            order.iter().for_each(|&k| seen[k] = true);
            let k = seen.iter().position(|s| !s).unwrap_or(0);
            return Err(self.err(format!("nodes[{k}]"), "node is in a cycle of children"));
        }
        let matrix = all
            .iter()
            .map(|node| Mat4::from_cols_array_2d(&node.transform().matrix()))
            .collect();
        let trs = all
            .iter()
            .map(|node| {
                let (t, r, s) = node.transform().decomposed();
                (Vec3::from(t), Quat::from_array(r), Vec3::from(s))
            })
            .collect();
        Ok(Nodes {
            parent,
            order,
            matrix,
            trs,
        })
    }

    fn skin(&self, skin: &gltf::Skin) -> Result<Skin> {
        let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        let place = format!("skins[{}].inverseBindMatrices", skin.index());
        let inverse_bind = match skin.inverse_bind_matrices() {
            None => vec![Mat4::IDENTITY; joints.len()],
            Some(acc) => {
                self.expect(&acc, &place, Dimensions::Mat4, &[DataType::F32])?;
                if acc.count() < joints.len() {
                    return Err(self.err(
                        place,
                        format!(
                            "accessor {} has {} matrices for {} joints",
                            acc.index(),
                            acc.count(),
                            joints.len()
                        ),
                    ));
                }
                let mut out = Vec::with_capacity(joints.len());
                for (i, e) in self.elements(&acc, 64)?.iter().take(joints.len()).enumerate() {
                    let m = Mat4::from_cols_array(&std::array::from_fn(|k| f32_at(e, k)));
                    if !m.is_finite() {
                        return Err(self.err(
                            format!("{place} (accessors[{}], element {i})", acc.index()),
                            "non-finite inverse bind matrix",
                        ));
                    }
                    out.push(m);
                }
                out
            }
        };
        Ok(Skin {
            joints,
            inverse_bind,
        })
    }

    fn clip(&self, anim: &gltf::Animation) -> Result<Clip> {
        let a = anim.index();
        let name = anim
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("animation {a}"));
        if anim.channels().next().is_none() {
            return Err(self.err(
                format!("animations[{a}].channels"),
                "the animation has no channels (no keyframes to play)",
            ));
        }
        let mut channels = Vec::new();
        for ch in anim.channels() {
            let property = match ch.target().property() {
                gltf::animation::Property::Translation => Property::Translation,
                gltf::animation::Property::Rotation => Property::Rotation,
                gltf::animation::Property::Scale => Property::Scale,
                gltf::animation::Property::MorphTargetWeights => continue,
            };
            let sampler = ch.sampler();
            let sp = format!("animations[{a}].samplers[{}]", sampler.index());
            let interpolation = match sampler.interpolation() {
                gltf::animation::Interpolation::Step => Interpolation::Step,
                gltf::animation::Interpolation::Linear => Interpolation::Linear,
                gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
            };
            let times = self.times(&sampler.input(), &format!("{sp}.input"))?;
            let values = self.values(
                &sampler.output(),
                &format!("{sp}.output"),
                property,
                times.len(),
                interpolation == Interpolation::CubicSpline,
            )?;
            channels.push(Channel {
                node: ch.target().node().index(),
                property,
                interpolation,
                times,
                values,
            });
        }
        let duration = channels
            .iter()
            .map(|c| *c.times.last().unwrap())
            .fold(0.0f32, f32::max);
        Ok(Clip {
            name,
            duration,
            channels,
        })
    }

    fn times(&self, acc: &gltf::Accessor, place: &str) -> Result<Vec<f32>> {
        if acc.count() == 0 {
            return Err(self.err(
                place,
                format!("accessor {} has no keyframes (count 0)", acc.index()),
            ));
        }
        self.expect(acc, place, Dimensions::Scalar, &[DataType::F32])?;
        let mut out: Vec<f32> = Vec::with_capacity(acc.count());
        for (i, e) in self.elements(acc, 4)?.iter().enumerate() {
            let t = f32_at(e, 0);
            let bad = if !t.is_finite() {
                Some(format!("keyframe time {t} is not finite"))
            } else if t < 0.0 {
                Some(format!("keyframe time {t} is negative"))
            } else if out.last().is_some_and(|&p| t < p) {
                Some(format!("keyframe time {t} is before the previous one ({})", out[i - 1]))
            } else {
                None
            };
            if let Some(msg) = bad {
                return Err(self.err(format!("{place} (accessors[{}], element {i})", acc.index()), msg));
            }
            out.push(t);
        }
        Ok(out)
    }

    fn values(
        &self,
        acc: &gltf::Accessor,
        place: &str,
        property: Property,
        keys: usize,
        cubic: bool,
    ) -> Result<Vec<Vec4>> {
        let want = if cubic { 3 * keys } else { keys };
        let (dims, n) = match property {
            Property::Rotation => (Dimensions::Vec4, 4),
            _ => (Dimensions::Vec3, 3),
        };
        let types: &[DataType] = match property {
            Property::Rotation => &[DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16],
            _ => &[DataType::F32],
        };
        self.expect(acc, place, dims, types)?;
        if acc.count() != want {
            return Err(self.err(
                place,
                format!(
                    "accessor {} has {} values, {want} expected (one per keyframe of the input, three for CUBICSPLINE)",
                    acc.index(),
                    acc.count()
                ),
            ));
        }
        let ty = acc.data_type();
        let size = ty.size();
        let mut out = Vec::with_capacity(want);
        for (i, e) in self.elements(acc, n * size)?.iter().enumerate() {
            let c = |k: usize| normalized(ty, &e[k * size..(k + 1) * size]);
            let v = Vec4::new(c(0), c(1), c(2), if n == 4 { c(3) } else { 0.0 });
            let at = || format!("{place} (accessors[{}], element {i})", acc.index());
            if !v.is_finite() {
                return Err(self.err(at(), format!("non-finite keyframe value {v}")));
            }
            // Tangents of a CUBICSPLINE rotation are not unit quaternions; values are.
            let tangent = cubic && i % 3 != 1;
            if property == Property::Rotation && !tangent {
                if v.length() < 1e-6 {
                    return Err(self.err(at(), format!("rotation {v} has zero length")));
                }
                out.push(v.normalize());
            } else {
                out.push(v);
            }
        }
        Ok(out)
    }

    /// Reads JOINTS_n / WEIGHTS_n of a skinned mesh's triangle primitives, in the loader's order,
    /// normalising each vertex's weights.
    fn influences(
        &self,
        mesh: &gltf::Mesh,
        scene_mesh: usize,
        skin: usize,
        njoints: usize,
        bind: Vec<Vec3>,
    ) -> Result<Skinned> {
        let prims: Vec<gltf::Primitive> = mesh.primitives().filter(|p| is_triangles(p.mode())).collect();
        let sets = prims
            .first()
            .map_or(0, |p| (0..).take_while(|&k| p.get(&gltf::Semantic::Joints(k)).is_some()).count());
        let mplace = |p: &gltf::Primitive, what: &str| {
            format!("meshes[{}].primitives[{}].attributes.{what}", mesh.index(), p.index())
        };
        if sets == 0 {
            let p = prims.first().map_or(0, |p| p.index());
            return Err(self.err(
                format!("meshes[{}].primitives[{p}].attributes", mesh.index()),
                format!("the mesh is skinned (skins[{skin}]) but has no JOINTS_0"),
            ));
        }
        let per = 4 * sets;
        let (mut joints, mut weights) = (vec![0u16; per * bind.len()], vec![0f32; per * bind.len()]);
        let mut first = 0usize;
        for p in &prims {
            let nv = p.get(&gltf::Semantic::Positions).map_or(0, |a| a.count());
            for k in 0..sets as u32 {
                let (jn, wn) = (format!("JOINTS_{k}"), format!("WEIGHTS_{k}"));
                let ja = p
                    .get(&gltf::Semantic::Joints(k))
                    .ok_or_else(|| self.err(mplace(p, &jn), format!("missing ({} sets in the first primitive)", sets)))?;
                let wa = p
                    .get(&gltf::Semantic::Weights(k))
                    .ok_or_else(|| self.err(mplace(p, &wn), format!("missing ({jn} is given)")))?;
                self.expect(&ja, &mplace(p, &jn), Dimensions::Vec4, &[DataType::U8, DataType::U16])?;
                self.expect(&wa, &mplace(p, &wn), Dimensions::Vec4, &[DataType::F32, DataType::U8, DataType::U16])?;
                for (a, name) in [(&ja, &jn), (&wa, &wn)] {
                    if a.count() != nv {
                        return Err(self.err(
                            mplace(p, name),
                            format!("accessor {} has {} elements but POSITION has {nv}", a.index(), a.count()),
                        ));
                    }
                }
                let (js, ws) = (ja.data_type().size(), wa.data_type().size());
                let je = self.elements(&ja, 4 * js)?;
                let we = self.elements(&wa, 4 * ws)?;
                for (i, (jb, wb)) in je.iter().zip(&we).enumerate() {
                    for c in 0..4 {
                        let j = read_uint(&jb[c * js..(c + 1) * js]);
                        let w = normalized(wa.data_type(), &wb[c * ws..(c + 1) * ws]);
                        let at = |name: &str, a: &gltf::Accessor| {
                            format!("{} (accessors[{}], element {i})", mplace(p, name), a.index())
                        };
                        if !w.is_finite() || w < 0.0 {
                            return Err(self.err(at(&wn, &wa), format!("weight {w} (must be finite and >= 0)")));
                        }
                        if w != 0.0 && j as usize >= njoints {
                            return Err(self.err(at(&jn, &ja), format!("joint {j} out of range (skins[{skin}] has {njoints} joints)")));
                        }
                        let slot = (first + i) * per + 4 * k as usize + c;
                        joints[slot] = if w != 0.0 { j as u16 } else { 0 };
                        weights[slot] = w;
                    }
                }
            }
            first += nv;
        }
        debug_assert_eq!(first, bind.len());
        for (v, w) in weights.chunks_exact_mut(per).enumerate() {
            let sum: f32 = w.iter().sum();
            if sum <= 0.0 {
                return Err(self.err(
                    format!("meshes[{}] (Scene mesh {scene_mesh}), vertex {v}", mesh.index()),
                    "skin weights sum to 0",
                ));
            }
            w.iter_mut().for_each(|x| *x /= sum);
        }
        Ok(Skinned {
            mesh: scene_mesh,
            skin,
            bind,
            per_vertex: per,
            joints,
            weights,
        })
    }

    fn expect(&self, acc: &gltf::Accessor, place: &str, dims: Dimensions, types: &[DataType]) -> Result<()> {
        if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
            return Err(self.err(
                place,
                format!(
                    "accessor {} is {:?} {:?}; {dims:?} of {types:?} expected",
                    acc.index(),
                    acc.dimensions(),
                    acc.data_type()
                ),
            ));
        }
        Ok(())
    }

    fn elements(&self, acc: &gltf::Accessor, elem: usize) -> Result<Vec<&'a [u8]>> {
        accessor_elements(self.file, self.buffers, acc, elem)
    }
}

/// A component as f32: floats as they are, integers as glTF's normalised values.
fn normalized(ty: DataType, b: &[u8]) -> f32 {
    match ty {
        DataType::F32 => f32::from_le_bytes(b[..4].try_into().unwrap()),
        DataType::I8 => (b[0] as i8 as f32 / 127.0).max(-1.0),
        DataType::U8 => b[0] as f32 / 255.0,
        DataType::I16 => (i16::from_le_bytes([b[0], b[1]]) as f32 / 32767.0).max(-1.0),
        DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as f32 / 65535.0,
        DataType::U32 => u32::from_le_bytes(b[..4].try_into().unwrap()) as f32,
    }
}
