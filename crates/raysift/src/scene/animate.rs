//! Animated scenes whose geometry changes every frame: the dynamic workloads of Mora 2011 §4.1
//! (Fig. 9, the Exploding Dragon) and rigidly moving parts.
//!
//! - `explode`: every triangle flies away from the scene centre along the direction from the centre
//!   to its centroid (plus a per-triangle random jitter) and tumbles about its centroid, so no
//!   acceleration structure built for one frame fits the next.
//! - `spin-parts`: every mesh (or, for a single-mesh scene, each of the 8 groups of triangles whose
//!   centroids share an octant of the bounds) rotates rigidly about its own centre at its own rate,
//!   through the meshes' transforms.
//!
//! - `gltf`: the file's own animation (keyframed nodes and skinning), played by
//!   [`playback::Playback`] from [`crate::scene::io::gltf_anim::load_animated`]; skinned meshes
//!   deform, other meshes under animated nodes move rigidly.
//!
//! Primitive ids stay those of the source scene in every motion.

pub mod playback;

use super::{Mesh, Scene};
use crate::error::{Error, Result};
use glam::{Affine3A, Quat, Vec3};
use rand::{Rng, SeedableRng};

/// The kind of motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Triangles fly apart.
    Explode,
    /// Meshes rotate rigidly.
    SpinParts,
    /// The glTF file's own animation ([`Animation::from_playback`]).
    Gltf,
}

impl Motion {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Motion::Explode => "explode",
            Motion::SpinParts => "spin-parts",
            Motion::Gltf => "gltf",
        }
    }
}

impl std::str::FromStr for Motion {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "explode" => Ok(Motion::Explode),
            "spin-parts" => Ok(Motion::SpinParts),
            "gltf" => Ok(Motion::Gltf),
            _ => Err(Error::Invalid(format!(
                "unknown motion {s:?}; expected explode, spin-parts or gltf"
            ))),
        }
    }
}

/// A scene plus what it needs to produce any frame of its motion.
pub struct Animation {
    motion: Motion,
    scene: Scene,
    /// Explode: per-triangle rest corners, velocity and spin axis.
    rest: Vec<[Vec3; 3]>,
    velocity: Vec<Vec3>,
    axis: Vec<Vec3>,
    /// Spin: per-part centre, axis, rate, and each mesh's part.
    parts: Vec<(Vec3, Vec3, f32)>,
    mesh_part: Vec<usize>,
    /// Explode: the positions buffer of the frame before last, reused for the next frame.
    spare: Vec<Vec3>,
    /// Gltf: the file's animation.
    playback: Option<playback::Playback>,
}

impl Animation {
    /// Prepares `scene` for `motion`. Explode unwelds the triangles (3 vertices each).
    pub fn new(scene: &Scene, motion: Motion) -> Result<Self> {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let size = scene.bounds().extent().length().max(1e-6);
        let centre = scene.bounds().center();
        match motion {
            Motion::Explode => {
                let tris = scene.triangles();
                let n = tris.len();
                let rest: Vec<[Vec3; 3]> = (0..n).map(|i| tris.get(i)).collect();
                let velocity = rest
                    .iter()
                    .map(|t| {
                        let c = (t[0] + t[1] + t[2]) / 3.0;
                        let out = (c - centre).normalize_or(Vec3::Y);
                        let jitter = Vec3::new(
                            rng.gen_range(-0.3..0.3),
                            rng.gen_range(-0.3..0.3),
                            rng.gen_range(-0.3..0.3),
                        );
                        (out + jitter) * size * 0.5
                    })
                    .collect();
                let axis = (0..n)
                    .map(|_| {
                        Vec3::new(
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(-1.0..1.0),
                        )
                        .normalize_or(Vec3::X)
                    })
                    .collect();
                let pos = rest.iter().flatten().copied().collect();
                let idx = (0..n as u32)
                    .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                    .collect();
                let soup = Scene::from_meshes(
                    format!("{} (explode)", scene.name),
                    vec![Mesh::new("exploding", pos, idx)],
                )?;
                Ok(Self {
                    motion,
                    scene: soup,
                    rest,
                    velocity,
                    axis,
                    parts: Vec::new(),
                    mesh_part: Vec::new(),
                    spare: Vec::new(),
                    playback: None,
                })
            }
            Motion::SpinParts => {
                let (base, mesh_part) = if scene.meshes().len() > 1 {
                    (scene.clone(), (0..scene.meshes().len()).collect())
                } else {
                    split_octants(scene)?
                };
                let nparts = mesh_part.iter().max().map_or(0, |m| m + 1);
                let (mut sum, mut count) = (vec![Vec3::ZERO; nparts], vec![0usize; nparts]);
                for (m, &part) in base.meshes().iter().zip(&mesh_part) {
                    sum[part] += m
                        .positions
                        .iter()
                        .fold(Vec3::ZERO, |a, &p| a + m.transform.transform_point3(p));
                    count[part] += m.positions.len();
                }
                let parts = (0..nparts)
                    .map(|k| {
                        let axis = Vec3::new(
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(0.2..1.0),
                            rng.gen_range(-1.0..1.0),
                        )
                        .normalize();
                        (sum[k] / count[k].max(1) as f32, axis, 0.5 + 0.37 * k as f32)
                    })
                    .collect();
                Ok(Self {
                    motion,
                    scene: base,
                    rest: Vec::new(),
                    velocity: Vec::new(),
                    axis: Vec::new(),
                    parts,
                    mesh_part,
                    spare: Vec::new(),
                    playback: None,
                })
            }
            Motion::Gltf => Err(Error::Invalid(format!(
                "{}: the gltf motion plays a glTF file's own animation (load it with scene::io::gltf_anim::load_animated)",
                scene.name
            ))),
        }
    }

    /// Plays a glTF file's animation on the scene loaded with it
    /// ([`crate::scene::io::gltf_anim::load_animated`]).
    pub fn from_playback(scene: Scene, playback: playback::Playback) -> Self {
        Self {
            motion: Motion::Gltf,
            scene,
            rest: Vec::new(),
            velocity: Vec::new(),
            axis: Vec::new(),
            parts: Vec::new(),
            mesh_part: Vec::new(),
            spare: Vec::new(),
            playback: Some(playback),
        }
    }

    /// The motion.
    pub fn motion(&self) -> Motion {
        self.motion
    }

    /// The glTF animation being played (the gltf motion only).
    pub fn playback(&self) -> Option<&playback::Playback> {
        self.playback.as_ref()
    }

    /// Chooses the glTF animation by name or index (the gltf motion only).
    pub fn select(&mut self, which: &str) -> Result<()> {
        match &mut self.playback {
            Some(p) => p.select(which),
            None => Err(Error::Invalid(format!(
                "--animation {which:?}: only the gltf motion plays a file's animations"
            ))),
        }
    }

    /// The time [`Animation::at`] takes for frame `k` of `n`: `k / (n - 1)` (0 to 1 inclusive)
    /// for the generated motions, `k · duration / n` seconds for a glTF animation (the last
    /// frame stops one step short of the first, so a looping clip loops seamlessly).
    pub fn frame_time(&self, k: u32, n: u32) -> f32 {
        match &self.playback {
            Some(p) => k as f32 * p.clip().duration / n.max(1) as f32,
            None if n <= 1 => 0.0,
            None => k as f32 / (n - 1) as f32,
        }
    }

    /// The scene at time `t` (t = 0: rest pose; t = 1: a well-developed motion; for `gltf`, `t`
    /// is in seconds of the clip), changed in place: `explode` deforms its one mesh
    /// ([`Scene::replace_positions`], into a buffer kept between frames), `spin-parts` moves
    /// each mesh rigidly ([`Scene::set_transform`]), `gltf` does both (see [`playback`]); the
    /// scene's [`changes_since`](Scene::changes_since) says which.
    pub fn at(&mut self, t: f32) -> Result<&Scene> {
        match self.motion {
            Motion::Gltf => {
                let p = self.playback.as_mut().expect("made by from_playback");
                p.apply(&mut self.scene, t)?;
            }
            Motion::Explode => {
                let mut pos = std::mem::take(&mut self.spare);
                pos.clear();
                pos.reserve(3 * self.rest.len());
                for (i, tri) in self.rest.iter().enumerate() {
                    let c = (tri[0] + tri[1] + tri[2]) / 3.0;
                    let q = Quat::from_axis_angle(self.axis[i], 3.0 * t);
                    let c2 = c + self.velocity[i] * t;
                    pos.extend(tri.iter().map(|&corner| c2 + q * (corner - c)));
                }
                self.spare = self.scene.replace_positions(0, pos)?;
            }
            Motion::SpinParts => {
                let spins: Vec<Affine3A> = self
                    .parts
                    .iter()
                    .map(|&(c, axis, rate)| {
                        Affine3A::from_translation(c)
                            * Affine3A::from_quat(Quat::from_axis_angle(
                                axis,
                                rate * t * std::f32::consts::TAU,
                            ))
                            * Affine3A::from_translation(-c)
                    })
                    .collect();
                for (k, &part) in self.mesh_part.iter().enumerate() {
                    self.scene.set_transform(k, spins[part])?;
                }
            }
        }
        Ok(&self.scene)
    }

    /// The scene as of the last [`Animation::at`] (the rest pose before any).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }
}

/// Splits a single-mesh scene into meshes, one per run of consecutive triangles whose centroids
/// lie in the same octant of the bounds (runs keep file order, so primitive ids are unchanged), and
/// returns each mesh's part (its octant). The source mesh's transform is baked into the positions.
fn split_octants(scene: &Scene) -> Result<(Scene, Vec<usize>)> {
    let c = scene.bounds().center();
    let tris = scene.triangles();
    let octant = |i: usize| {
        let [a, b, d] = tris.get(i);
        let m = (a + b + d) / 3.0;
        (m.x > c.x) as usize | ((m.y > c.y) as usize) << 1 | ((m.z > c.z) as usize) << 2
    };
    let (mut meshes, mut parts) = (Vec::new(), Vec::new());
    let mut i = 0;
    while i < tris.len() {
        let (o, start) = (octant(i), i);
        while i < tris.len() && octant(i) == o {
            i += 1;
        }
        let pos: Vec<Vec3> = (start..i).flat_map(|k| tris.get(k)).collect();
        let idx = (0..(i - start) as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        meshes.push(Mesh::new(format!("octant{o}"), pos, idx));
        parts.push(o);
    }
    Ok((
        Scene::from_meshes(format!("{} (spin-parts)", scene.name), meshes)?,
        parts,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural;

    #[test]
    fn explode_moves_triangles_apart_and_keeps_ids() {
        let s = procedural::icosphere(320);
        let mut a = Animation::new(&s, Motion::Explode).unwrap();
        let rest = a.at(0.0).unwrap().clone();
        for i in 0..s.len() {
            assert_eq!(rest.triangles().get(i), s.triangles().get(i));
        }
        let later = a.at(1.0).unwrap();
        assert_eq!(later.len(), s.len());
        assert!(later.bounds().extent().length() > 1.5 * s.bounds().extent().length());
    }

    #[test]
    fn spin_parts_splits_a_single_mesh_by_octant() {
        let s = procedural::icosphere(1280);
        let mut a = Animation::new(&s, Motion::SpinParts).unwrap();
        let f = a.at(0.25).unwrap().clone();
        assert_eq!(f.len(), s.len());
        assert_eq!(a.parts.len(), 8);
        // Each triangle moved rigidly: edge lengths kept, positions changed.
        let [p, q, _] = s.triangles().get(5);
        let [p2, q2, _] = f.triangles().get(5);
        assert!(((q - p).length() - (q2 - p2).length()).abs() < 1e-5);
        assert!((p - p2).length() > 1e-3);
    }

    #[test]
    fn spin_parts_is_rigid() {
        let s = procedural::tile(&procedural::cornell(), 2).unwrap();
        let mut a = Animation::new(&s, Motion::SpinParts).unwrap();
        let f = a.at(0.3).unwrap().clone();
        assert_eq!(f.len(), s.len());
        // Rigid motion keeps every edge length.
        for i in 0..s.len() {
            let [p, q, r] = s.triangles().get(i);
            let [p2, q2, r2] = f.triangles().get(i);
            assert!(((q - p).length() - (q2 - p2).length()).abs() < 1e-4);
            assert!(((r - p).length() - (r2 - p2).length()).abs() < 1e-4);
        }
        assert_ne!(f.triangles().v0, s.triangles().v0);
    }
}
