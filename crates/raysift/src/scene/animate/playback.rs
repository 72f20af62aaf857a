//! Playing a glTF animation on a [`Scene`]: keyframed node translation / rotation / scale, the
//! node hierarchy at time `t`, and skinning (glTF 2.0 specification, "Animations" and "Skins").
//!
//! Per frame ([`Playback::apply`]):
//! 1. every channel of the chosen clip is sampled at `t` (STEP, LINEAR with rotations slerped,
//!    CUBICSPLINE Hermite with rotations normalised; clamped before the first and after the last
//!    keyframe) into its node's TRS; nodes no channel targets keep their file matrix;
//! 2. node globals, parents before children (`global = global(parent) · local`, as the loader
//!    composes them, so an unanimated chain is bit for bit the loader's);
//! 3. each skin's joint matrices `global(joint) · inverseBind`;
//! 4. each skinned Scene mesh gets `Σ_k w_k · M_jk · p` per bind-pose vertex (weights normalised
//!    when loaded) through [`Scene::replace_positions`] (a deformation; its transform is made the
//!    identity once, since glTF ignores a skinned mesh's node transform), but only when one of
//!    its skin's joint matrices changed; each other mesh gets its node's global through
//!    [`Scene::set_transform`] (a rigid motion), only when it changed. So
//!    [`Scene::changes_since`] lists the skinned meshes as deformed and the rigid ones as moved.
//!
//! Cost per frame: O(channels · log keyframes + nodes + joints + Σ skinned vertices · influences),
//! skinning in parallel over meshes (rayon). Buffers (node TRS and globals, joint matrices, the
//! positions handed to the scene, which hands the previous ones back) are allocated by the
//! first frame and reused: no allocation per frame after it. Held: [`Playback::bytes`], 48 bytes
//! per skinned vertex with one joint set (bind position 12, joints 8, weights 16, spare
//! positions 12) plus per-node and per-keyframe data. Morph-target weights are not played.

use crate::error::{Error, Result};
use crate::scene::Scene;
use glam::{Affine3A, Mat4, Quat, Vec3, Vec3A, Vec4};
use rayon::prelude::*;

/// How a channel's values vary between keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the keyframe at or before `t`.
    Step,
    /// Linear (slerp for rotations).
    Linear,
    /// Cubic Hermite with per-keyframe in- and out-tangents.
    CubicSpline,
}

/// Which part of a node's TRS a channel drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    /// Translation (xyz).
    Translation,
    /// Rotation, a unit quaternion (xyzw).
    Rotation,
    /// Scale (xyz).
    Scale,
}

/// One keyframed property of one node.
#[derive(Clone, Debug)]
pub struct Channel {
    /// The node index.
    pub node: usize,
    /// What it drives.
    pub property: Property,
    /// How values vary between keyframes.
    pub interpolation: Interpolation,
    /// Keyframe times in seconds: at least one, non-negative, non-decreasing.
    pub times: Vec<f32>,
    /// One value per keyframe (xyz or quaternion xyzw; w unused for vectors); for CUBICSPLINE
    /// three per keyframe: in-tangent, value, out-tangent. Rotations are unit quaternions.
    pub values: Vec<Vec4>,
}

impl Channel {
    /// The value at time `t` (seconds).
    pub fn sample(&self, t: f32) -> Vec4 {
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let value = |k: usize| {
            if cubic {
                self.values[3 * k + 1]
            } else {
                self.values[k]
            }
        };
        let n = self.times.len();
        if t <= self.times[0] || n == 1 {
            return value(0);
        }
        if t >= self.times[n - 1] {
            return value(n - 1);
        }
        // times[k] <= t < times[k + 1], so the segment has positive length.
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let s = (t - t0) / (t1 - t0);
        let rotation = self.property == Property::Rotation;
        match self.interpolation {
            Interpolation::Step => value(k),
            Interpolation::Linear if rotation => {
                Vec4::from(Quat::from_vec4(value(k)).slerp(Quat::from_vec4(value(k + 1)), s))
            }
            Interpolation::Linear => value(k).lerp(value(k + 1), s),
            Interpolation::CubicSpline => {
                let td = t1 - t0;
                let (v0, b0) = (self.values[3 * k + 1], self.values[3 * k + 2]);
                let (a1, v1) = (self.values[3 * k + 3], self.values[3 * k + 4]);
                let (s2, s3) = (s * s, s * s * s);
                let p = (2.0 * s3 - 3.0 * s2 + 1.0) * v0
                    + td * (s3 - 2.0 * s2 + s) * b0
                    + (-2.0 * s3 + 3.0 * s2) * v1
                    + td * (s3 - s2) * a1;
                if rotation {
                    p.normalize_or(value(k))
                } else {
                    p
                }
            }
        }
    }
}

/// One animation of the file.
#[derive(Clone, Debug)]
pub struct Clip {
    /// Its name (`animation N` when the file gives none).
    pub name: String,
    /// The last keyframe time over its channels, seconds.
    pub duration: f32,
    /// Its channels (at least one).
    pub channels: Vec<Channel>,
}

/// A skin: joint nodes and their inverse bind matrices (one per joint).
#[derive(Clone, Debug)]
pub struct Skin {
    /// Joint node indices.
    pub joints: Vec<usize>,
    /// Inverse bind matrices, one per joint (identity when the file gives none).
    pub inverse_bind: Vec<Mat4>,
}

/// A Scene mesh deformed by a skin.
#[derive(Clone, Debug)]
pub struct Skinned {
    /// The Scene mesh index.
    pub mesh: usize,
    /// The skin index.
    pub skin: usize,
    /// Bind-pose positions (the mesh's POSITION data, as the loader read it).
    pub bind: Vec<Vec3>,
    /// Influences per vertex (4 per JOINTS_n / WEIGHTS_n set).
    pub per_vertex: usize,
    /// Joint indices into the skin, `per_vertex` per vertex.
    pub joints: Vec<u16>,
    /// Weights, `per_vertex` per vertex, summing to 1 per vertex.
    pub weights: Vec<f32>,
}

/// The node hierarchy at rest, as the file gives it.
#[derive(Clone, Debug)]
pub struct Nodes {
    /// Each node's parent, `None` for roots.
    pub parent: Vec<Option<usize>>,
    /// Node indices, every parent before its children.
    pub order: Vec<usize>,
    /// Each node's local matrix as the loader composes it.
    pub matrix: Vec<Mat4>,
    /// Each node's local translation, rotation, scale (decomposed when given as a matrix).
    pub trs: Vec<(Vec3, Quat, Vec3)>,
}

/// A glTF file's animations and skins, bound to the Scene the loader made of the same file
/// (`scene::io::gltf_anim`); plays a chosen clip on that scene in place.
#[derive(Clone, Debug)]
pub struct Playback {
    nodes: Nodes,
    clips: Vec<Clip>,
    clip: usize,
    skins: Vec<Skin>,
    skinned: Vec<Skinned>,
    /// Scene meshes moved rigidly: (mesh, node).
    rigid: Vec<(usize, usize)>,
    /// Per node: does the chosen clip drive it.
    animated: Vec<bool>,
    // Reused per-frame buffers.
    trs: Vec<(Vec3, Quat, Vec3)>,
    global: Vec<Mat4>,
    /// Per skin: joint matrices of this frame and of the last one applied.
    joint: Vec<Vec<Affine3A>>,
    joint_prev: Vec<Vec<Affine3A>>,
    skin_changed: Vec<bool>,
    /// Per skinned mesh: the positions buffer to fill next.
    spare: Vec<Vec<Vec3>>,
    /// The scene written last, as it was after the write: a pose applied to another scene (or
    /// to this one after someone else changed it) writes every mesh, not just what moved.
    last: crate::scene::Stamp,
}

impl Playback {
    /// Binds the parts (checked by the reader) into a player of clip 0.
    pub fn new(
        nodes: Nodes,
        clips: Vec<Clip>,
        skins: Vec<Skin>,
        skinned: Vec<Skinned>,
        rigid: Vec<(usize, usize)>,
    ) -> Result<Self> {
        if clips.is_empty() {
            return Err(Error::Invalid("a playback needs at least one animation".into()));
        }
        let n = nodes.matrix.len();
        let mut p = Self {
            trs: nodes.trs.clone(),
            global: vec![Mat4::IDENTITY; n],
            joint: skins
                .iter()
                .map(|s| vec![Affine3A::IDENTITY; s.joints.len()])
                .collect(),
            joint_prev: skins
                .iter()
                .map(|s| vec![Affine3A::IDENTITY; s.joints.len()])
                .collect(),
            skin_changed: vec![true; skins.len()],
            spare: skinned.iter().map(|s| Vec::with_capacity(s.bind.len())).collect(),
            animated: vec![false; n],
            nodes,
            clips,
            clip: 0,
            skins,
            skinned,
            rigid,
            last: crate::scene::Stamp::default(),
        };
        p.select_index(0);
        Ok(p)
    }

    /// The clips (the file's animations, in file order).
    pub fn clips(&self) -> &[Clip] {
        &self.clips
    }

    /// The clip being played.
    pub fn clip(&self) -> &Clip {
        &self.clips[self.clip]
    }

    /// Chooses the clip by name or index (`--animation NAME|INDEX`).
    pub fn select(&mut self, which: &str) -> Result<()> {
        let k = self
            .clips
            .iter()
            .position(|c| c.name == which)
            .or_else(|| which.parse::<usize>().ok().filter(|&k| k < self.clips.len()))
            .ok_or_else(|| {
                let names: Vec<String> = self
                    .clips
                    .iter()
                    .enumerate()
                    .map(|(k, c)| format!("{k} ({:?})", c.name))
                    .collect();
                Error::Invalid(format!(
                    "--animation {which:?}: no such animation; the file has {}",
                    names.join(", ")
                ))
            })?;
        self.select_index(k);
        Ok(())
    }

    fn select_index(&mut self, k: usize) {
        self.clip = k;
        self.animated.iter_mut().for_each(|a| *a = false);
        for c in &self.clips[k].channels {
            self.animated[c.node] = true;
        }
    }

    /// The skinned meshes.
    pub fn skinned(&self) -> &[Skinned] {
        &self.skinned
    }

    /// The rigidly moving meshes as (Scene mesh, node).
    pub fn rigid(&self) -> &[(usize, usize)] {
        &self.rigid
    }

    /// Node globals of the last pose computed.
    pub fn globals(&self) -> &[Mat4] {
        &self.global
    }

    /// Bytes held (bind poses, influences, spare position buffers, keyframes, node data).
    pub fn bytes(&self) -> usize {
        use std::mem::size_of;
        let skinned: usize = self
            .skinned
            .iter()
            .zip(&self.spare)
            .map(|(s, sp)| {
                s.bind.capacity() * 12
                    + s.joints.capacity() * 2
                    + s.weights.capacity() * 4
                    + sp.capacity() * 12
            })
            .sum();
        let keys: usize = self
            .clips
            .iter()
            .flat_map(|c| &c.channels)
            .map(|c| c.times.capacity() * 4 + c.values.capacity() * 16)
            .sum();
        let joints: usize = self
            .skins
            .iter()
            .map(|s| s.joints.len() * (size_of::<usize>() + 64 + 2 * size_of::<Affine3A>()))
            .sum();
        let nodes = self.global.len()
            * (2 * 64 + 2 * size_of::<(Vec3, Quat, Vec3)>() + size_of::<Option<usize>>() + 9);
        skinned + keys + joints + nodes
    }

    /// Poses the scene at time `t` seconds of the chosen clip (see the module doc).
    pub fn apply(&mut self, scene: &mut Scene, t: f32) -> Result<()> {
        self.pose(Some(t));
        self.write(scene)
    }

    /// Poses the scene in the file's rest pose (every node at its file TRS, skins applied).
    pub fn apply_rest(&mut self, scene: &mut Scene) -> Result<()> {
        self.pose(None);
        self.write(scene)
    }

    /// Node globals and joint matrices at `t` (the rest pose for `None`).
    fn pose(&mut self, t: Option<f32>) {
        self.trs.copy_from_slice(&self.nodes.trs);
        if let Some(t) = t {
            for c in &self.clips[self.clip].channels {
                let v = c.sample(t);
                let trs = &mut self.trs[c.node];
                match c.property {
                    Property::Translation => trs.0 = v.truncate(),
                    Property::Rotation => trs.1 = Quat::from_vec4(v),
                    Property::Scale => trs.2 = v.truncate(),
                }
            }
        }
        for &n in &self.nodes.order {
            let local = if t.is_some() && self.animated[n] {
                let (tr, r, s) = self.trs[n];
                Mat4::from_scale_rotation_translation(s, r, tr)
            } else {
                self.nodes.matrix[n]
            };
            self.global[n] = match self.nodes.parent[n] {
                Some(p) => self.global[p] * local,
                None => Mat4::IDENTITY * local,
            };
        }
        for (s, skin) in self.skins.iter().enumerate() {
            let joint = &mut self.joint[s];
            for (j, (&node, ibm)) in skin.joints.iter().zip(&skin.inverse_bind).enumerate() {
                joint[j] = Affine3A::from_mat4(self.global[node] * *ibm);
            }
            self.skin_changed[s] = joint != &self.joint_prev[s];
            self.joint_prev[s].copy_from_slice(joint);
        }
    }

    /// Hands the pose to the scene: skinned meshes deformed, rigid meshes moved, each only when
    /// it changed.
    fn write(&mut self, scene: &mut Scene) -> Result<()> {
        // Another scene than the one written last, or this one changed since by someone else:
        // everything is written (a pose is a function of the time alone, whatever the scene held).
        let fresh = self.last.check(scene, "playback").is_err();
        let (joint, changed) = (&self.joint, &self.skin_changed);
        let write = |s: &Skinned| fresh || changed[s.skin];
        self.skinned
            .par_iter()
            .zip(self.spare.par_iter_mut())
            .filter(|(s, _)| write(s))
            .for_each(|(s, out)| skin_into(s, &joint[s.skin], out));
        for (s, out) in self.skinned.iter().zip(self.spare.iter_mut()) {
            if !write(s) {
                continue;
            }
            if scene.meshes()[s.mesh].transform != Affine3A::IDENTITY {
                scene.set_transform(s.mesh, Affine3A::IDENTITY)?;
            }
            *out = scene.replace_positions(s.mesh, std::mem::take(out))?;
        }
        for &(m, node) in &self.rigid {
            let xf = Affine3A::from_mat4(self.global[node]);
            if scene.meshes()[m].transform != xf {
                scene.set_transform(m, xf)?;
            }
        }
        self.last = scene.stamp();
        Ok(())
    }
}

/// `out[i] = Σ_k w_ik · (M_jik · bind[i])`, zero weights skipped.
fn skin_into(s: &Skinned, joint: &[Affine3A], out: &mut Vec<Vec3>) {
    out.clear();
    let per = s.per_vertex;
    out.extend(s.bind.iter().enumerate().map(|(i, &p)| {
        let p = Vec3A::from(p);
        let mut acc = Vec3A::ZERO;
        for k in i * per..(i + 1) * per {
            let w = s.weights[k];
            if w != 0.0 {
                acc += w * joint[s.joints[k] as usize].transform_point3a(p);
            }
        }
        Vec3::from(acc)
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(interpolation: Interpolation, property: Property, values: Vec<Vec4>) -> Channel {
        Channel {
            node: 0,
            property,
            interpolation,
            times: vec![1.0, 3.0],
            values,
        }
    }

    #[test]
    fn step_linear_and_clamping() {
        let v = vec![Vec4::new(0.0, 2.0, 0.0, 0.0), Vec4::new(4.0, 2.0, -2.0, 0.0)];
        let lin = channel(Interpolation::Linear, Property::Translation, v.clone());
        assert_eq!(lin.sample(2.0), Vec4::new(2.0, 2.0, -1.0, 0.0));
        assert_eq!(lin.sample(0.0), v[0]);
        assert_eq!(lin.sample(9.0), v[1]);
        let step = channel(Interpolation::Step, Property::Translation, v.clone());
        assert_eq!(step.sample(2.9), v[0]);
        assert_eq!(step.sample(3.0), v[1]);
    }

    #[test]
    fn cubic_spline_follows_the_hermite_basis() {
        // Value 0 -> 1 with out-tangent 2 at key 0 and in-tangent 0 at key 1; td = 2, s = 0.5:
        // p = 0.5 * 0 + td * 0.125 * 2 + 0.5 * 1 + td * (-0.125) * 0 = 1.0.
        let x = |v: f32| Vec4::new(v, 0.0, 0.0, 0.0);
        let c = channel(
            Interpolation::CubicSpline,
            Property::Translation,
            vec![x(9.0), x(0.0), x(2.0), x(0.0), x(1.0), x(9.0)],
        );
        assert!((c.sample(2.0).x - 1.0).abs() < 1e-6);
        assert_eq!(c.sample(1.0).x, 0.0);
        assert_eq!(c.sample(3.0).x, 1.0);
    }

    #[test]
    fn rotation_slerps_the_short_way() {
        let a = Quat::IDENTITY;
        // 90 degrees about z, given with a negative w: the short way is still 45 degrees at s=0.5.
        let b = -Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let c = channel(Interpolation::Linear, Property::Rotation, vec![a.into(), b.into()]);
        let q = Quat::from_vec4(c.sample(2.0));
        let want = Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
        assert!(q.angle_between(want) < 1e-4, "{q:?}");
    }
}
