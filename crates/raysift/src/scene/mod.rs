//! Scenes: triangle meshes, each with a rigid transform, baked into one world-space triangle soup
//! that every tracer reads.
//!
//! Storage (bytes per triangle, documented in ARCHITECTURE.md):
//! - the **source meshes**, indexed: local positions (12 B per vertex) and `[u32; 3]` indices
//!   (12 B per triangle), vertex colours where the file has them (12 B per vertex), plus one
//!   `Affine3A` per mesh;
//! - the **world soup**, structure-of-arrays by corner: `v0`, `v1`, `v2` arrays of `Vec3`
//!   (36 B per triangle), rebuilt by [`Scene::rebake`] after a transform or a vertex changes.
//!
//! Primitive ids are the triangle's index in load order (meshes in order, each mesh's faces in
//! file order, polygons fanned in order), so another program loading the same file agrees.
//! Degenerate triangles keep their id but are collapsed to their first vertex in the soup, so
//! the shared triangle test never hits them (see `geom::triangle`).

pub mod animate;
mod check;
pub mod io;
mod mesh;
pub mod procedural;

use crate::error::{Error, Result};
use crate::geom::{triangle::is_degenerate, Aabb};
use glam::{Affine3A, Vec3};

use check::{check_colors, check_materials, check_positions, check_transform};
pub use io::load;
pub use mesh::{Material, Mesh};

/// World-space triangles, structure-of-arrays by corner. Index `i` is primitive id `i`.
#[derive(Clone, Debug, Default)]
pub struct TriangleSoup {
    /// First corners.
    pub v0: Vec<Vec3>,
    /// Second corners.
    pub v1: Vec<Vec3>,
    /// Third corners.
    pub v2: Vec<Vec3>,
}

impl TriangleSoup {
    /// Number of triangles.
    #[inline]
    pub fn len(&self) -> usize {
        self.v0.len()
    }

    /// True when there are no triangles.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.v0.is_empty()
    }

    /// The three corners of triangle `i`.
    #[inline(always)]
    pub fn get(&self, i: usize) -> [Vec3; 3] {
        [self.v0[i], self.v1[i], self.v2[i]]
    }

    /// The bounding box of triangle `i`.
    #[inline]
    pub fn bounds(&self, i: usize) -> Aabb {
        let [a, b, c] = self.get(i);
        Aabb::new(a.min(b).min(c), a.max(b).max(c))
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        3 * self.v0.capacity() * std::mem::size_of::<Vec3>()
    }
}

/// A scene: meshes plus their baked world-space soup, with a version that every change bumps.
///
/// Changes go through [`Scene::set_transform`] (a rigid motion of one mesh) and
/// [`Scene::replace_positions`] (a deformation keeping the triangles), each of which re-bakes only
/// that mesh's range of the soup and records, per mesh, the version at which it last moved or
/// deformed, so a tracer can ask [`Scene::changes_since`] what changed since its last prepare
/// (and update instead of rebuilding). A scene value has an identity of its own ([`Stamp`]): a
/// clone is a different scene, so a tracer prepared for one refuses the other.
#[derive(Debug)]
pub struct Scene {
    /// Display name (file name or generator spec).
    pub name: String,
    meshes: Vec<Mesh>,
    /// `first_prim[m]` is the primitive id of mesh `m`'s first triangle; one extra entry at the end.
    first_prim: Vec<u32>,
    soup: TriangleSoup,
    bounds: Aabb,
    /// World bounds and degenerate count of each mesh (the scene's are their union and sum).
    mesh_bounds: Vec<Aabb>,
    mesh_degenerate: Vec<usize>,
    degenerate: usize,
    id: u64,
    version: u64,
    /// Version at which each mesh last moved rigidly / deformed (0: never since creation).
    moved_at: Vec<u64>,
    deformed_at: Vec<u64>,
    /// Material runs over primitive ids: run `r` covers `mat_start[r]..mat_start[r + 1]` (the
    /// last up to the end) with `mat[r]` (`None`: no material). 4 + 32 B per run, not per
    /// triangle; a lookup is a binary search over the runs.
    mat_start: Vec<u32>,
    mat: Vec<Option<Material>>,
}

static NEXT_SCENE_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

fn next_scene_id() -> u64 {
    NEXT_SCENE_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl Clone for Scene {
    /// A copy with an identity of its own (tracers prepared for `self` must prepare again).
    fn clone(&self) -> Self {
        Self {
            name: self.name.clone(),
            meshes: self.meshes.clone(),
            first_prim: self.first_prim.clone(),
            soup: self.soup.clone(),
            bounds: self.bounds,
            mesh_bounds: self.mesh_bounds.clone(),
            mesh_degenerate: self.mesh_degenerate.clone(),
            degenerate: self.degenerate,
            id: next_scene_id(),
            version: 0,
            moved_at: vec![0; self.meshes.len()],
            deformed_at: vec![0; self.meshes.len()],
            mat_start: self.mat_start.clone(),
            mat: self.mat.clone(),
        }
    }
}

/// Which scene, at which version, a tracer was prepared for. `Stamp::default()` is "never
/// prepared": it matches no scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stamp {
    scene: u64,
    version: u64,
}

impl Stamp {
    /// Ok when `scene` is the scene this stamp was taken of, unchanged since; otherwise the error
    /// a trace returns (the tracer `tracer` must be prepared again).
    pub fn check(&self, scene: &Scene, tracer: &str) -> Result<()> {
        if *self == scene.stamp() {
            return Ok(());
        }
        Err(Error::Invalid(if self.scene == 0 {
            format!("tracer {tracer}: not prepared; call prepare(scene) before tracing")
        } else if self.scene != scene.id {
            format!(
                "tracer {tracer}: prepared for another scene than {:?}; call prepare(scene) first",
                scene.name
            )
        } else {
            format!(
                "tracer {tracer}: scene {:?} changed since prepare (version {} -> {}); call prepare(scene) first",
                scene.name, self.version, scene.version
            )
        }))
    }
}

/// What changed in a scene since a [`Stamp`], as [`Scene::changes_since`] reports it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Change {
    /// Nothing: the stamp is current.
    None,
    /// Another scene, or never prepared: everything is new.
    All,
    /// Some meshes changed; the triangle count and ids are unchanged.
    Meshes {
        /// Meshes whose transform changed (rigid motion), and nothing else.
        moved: Vec<usize>,
        /// Meshes whose positions changed (deformation, same triangles); may also have moved.
        deformed: Vec<usize>,
    },
}

impl Scene {
    /// Builds a scene, checking that every index is in range and every position finite.
    /// A scene may have zero triangles (tracers then report misses); the CLI rejects that for
    /// files, where it is almost always a mistake.
    pub fn from_meshes(name: impl Into<String>, meshes: Vec<Mesh>) -> Result<Self> {
        let name = name.into();
        let mut first_prim = Vec::with_capacity(meshes.len() + 1);
        let mut total: u64 = 0;
        for (m, mesh) in meshes.iter().enumerate() {
            first_prim.push(total as u32);
            check_positions(&name, m, mesh, &mesh.positions)?;
            let nv = mesh.positions.len() as u64;
            if let Some(f) = mesh
                .indices
                .iter()
                .position(|t| t.iter().any(|&i| i as u64 >= nv))
            {
                return Err(Error::parse(
                    &name,
                    format!("mesh {m} ({}), triangle {f}", mesh.name),
                    format!(
                        "vertex index out of range {:?} (the mesh has {nv} vertices)",
                        mesh.indices[f]
                    ),
                ));
            }
            check_transform(&name, m, mesh, &mesh.transform)?;
            check_materials(&name, m, mesh)?;
            check_colors(&name, m, mesh)?;
            total += mesh.indices.len() as u64;
        }
        if total >= u32::MAX as u64 {
            return Err(Error::Invalid(format!(
                "{name}: {total} triangles; at most {} are supported",
                u32::MAX - 1
            )));
        }
        first_prim.push(total as u32);
        let nm = meshes.len();
        let n = total as usize;
        let (mut mat_start, mut mat) = (Vec::new(), Vec::new());
        for (m, mesh) in meshes.iter().enumerate() {
            if mesh.indices.is_empty() {
                continue;
            }
            let first = first_prim[m];
            let lead = mesh
                .materials
                .first()
                .is_none_or(|r| r.0 > 0)
                .then_some((0, None));
            for (k, material) in lead
                .into_iter()
                .chain(mesh.materials.iter().map(|&(k, m)| (k, Some(m))))
            {
                // Adjacent equal runs (across meshes too) are merged.
                if mat.last() != Some(&material) {
                    mat_start.push(first + k);
                    mat.push(material);
                }
            }
        }
        let mut scene = Self {
            name,
            meshes,
            first_prim,
            soup: TriangleSoup {
                v0: vec![Vec3::ZERO; n],
                v1: vec![Vec3::ZERO; n],
                v2: vec![Vec3::ZERO; n],
            },
            bounds: Aabb::EMPTY,
            mesh_bounds: vec![Aabb::EMPTY; nm],
            mesh_degenerate: vec![0; nm],
            degenerate: 0,
            id: next_scene_id(),
            version: 0,
            moved_at: vec![0; nm],
            deformed_at: vec![0; nm],
            mat_start,
            mat,
        };
        for m in 0..nm {
            scene.bake_mesh(m);
        }
        scene.sum_meshes();
        Ok(scene)
    }

    /// Bakes mesh `m` into its range of the soup (world positions; degenerate triangles
    /// collapsed to their first corner) and records its bounds and degenerate count.
    fn bake_mesh(&mut self, m: usize) {
        use rayon::prelude::*;
        let mesh = &self.meshes[m];
        let range = self.first_prim[m] as usize..self.first_prim[m + 1] as usize;
        let xf = mesh.transform;
        let world: Vec<Vec3> = if mesh.positions.len() > 1 << 14 {
            mesh.positions
                .par_iter()
                .map(|&p| xf.transform_point3(p))
                .collect()
        } else {
            mesh.positions
                .iter()
                .map(|&p| xf.transform_point3(p))
                .collect()
        };
        const CH: usize = 1 << 14;
        let soup = &mut self.soup;
        let (bounds, degenerate) = soup.v0[range.clone()]
            .par_chunks_mut(CH)
            .zip(soup.v1[range.clone()].par_chunks_mut(CH))
            .zip(soup.v2[range].par_chunks_mut(CH))
            .zip(mesh.indices.par_chunks(CH))
            .map(|(((v0, v1), v2), idx)| {
                let (mut b, mut d) = (Aabb::EMPTY, 0usize);
                for (k, t) in idx.iter().enumerate() {
                    let (a, bb, c) = (
                        world[t[0] as usize],
                        world[t[1] as usize],
                        world[t[2] as usize],
                    );
                    b = b.grow(a).grow(bb).grow(c);
                    if is_degenerate(a, bb, c) {
                        d += 1;
                        (v0[k], v1[k], v2[k]) = (a, a, a);
                    } else {
                        (v0[k], v1[k], v2[k]) = (a, bb, c);
                    }
                }
                (b, d)
            })
            .reduce(|| (Aabb::EMPTY, 0), |x, y| (x.0.union(y.0), x.1 + y.1));
        self.mesh_bounds[m] = bounds;
        self.mesh_degenerate[m] = degenerate;
    }

    fn sum_meshes(&mut self) {
        self.bounds = self
            .mesh_bounds
            .iter()
            .fold(Aabb::EMPTY, |a, b| a.union(*b));
        self.degenerate = self.mesh_degenerate.iter().sum();
    }

    /// Sets mesh `m`'s local-to-world transform (a rigid or affine motion: triangles and local
    /// positions unchanged), re-bakes that mesh's triangles and bumps the version.
    pub fn set_transform(&mut self, m: usize, transform: Affine3A) -> Result<()> {
        let mesh = self.mesh_checked(m)?;
        check_transform(&self.name, m, mesh, &transform)?;
        self.meshes[m].transform = transform;
        self.version += 1;
        self.moved_at[m] = self.version;
        self.bake_mesh(m);
        self.sum_meshes();
        Ok(())
    }

    /// Replaces mesh `m`'s local positions (a deformation: same vertex count, same triangles),
    /// re-bakes that mesh's triangles, bumps the version, and returns the old positions (so an
    /// animation can reuse the buffer: nothing is copied).
    pub fn replace_positions(&mut self, m: usize, positions: Vec<Vec3>) -> Result<Vec<Vec3>> {
        let mesh = self.mesh_checked(m)?;
        if positions.len() != mesh.positions.len() {
            return Err(Error::Invalid(format!(
                "{}: mesh {m} ({}): {} positions given, the mesh has {} vertices (a deformation keeps them)",
                self.name,
                mesh.name,
                positions.len(),
                mesh.positions.len()
            )));
        }
        check_positions(&self.name, m, mesh, &positions)?;
        let old = std::mem::replace(&mut self.meshes[m].positions, positions);
        self.version += 1;
        self.deformed_at[m] = self.version;
        self.bake_mesh(m);
        self.sum_meshes();
        Ok(old)
    }

    /// Records a new frame of the same geometry: every mesh counts as deformed, so tracers
    /// rebuild or update as after a real change (benchmarks use it to measure a prepare).
    pub fn touch(&mut self) {
        self.version += 1;
        self.deformed_at.iter_mut().for_each(|v| *v = self.version);
    }

    fn mesh_checked(&self, m: usize) -> Result<&Mesh> {
        self.meshes.get(m).ok_or_else(|| {
            Error::Invalid(format!(
                "{}: mesh {m} out of range (the scene has {} meshes)",
                self.name,
                self.meshes.len()
            ))
        })
    }

    /// This scene as it is now (compare with [`Stamp::check`]).
    pub fn stamp(&self) -> Stamp {
        Stamp {
            scene: self.id,
            version: self.version,
        }
    }

    /// The version: 0 when made, bumped by every change.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// What changed since `stamp` was taken (of this scene or another).
    pub fn changes_since(&self, stamp: Stamp) -> Change {
        if stamp.scene != self.id {
            return Change::All;
        }
        if stamp.version == self.version {
            return Change::None;
        }
        let v = stamp.version;
        let deformed: Vec<usize> = (0..self.meshes.len())
            .filter(|&m| self.deformed_at[m] > v)
            .collect();
        let moved = (0..self.meshes.len())
            .filter(|&m| self.moved_at[m] > v && self.deformed_at[m] <= v)
            .collect();
        Change::Meshes { moved, deformed }
    }

    /// The world-space triangles.
    #[inline]
    pub fn triangles(&self) -> &TriangleSoup {
        &self.soup
    }

    /// Number of triangles.
    #[inline]
    pub fn len(&self) -> usize {
        self.soup.len()
    }

    /// True when the scene has no triangles.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.soup.is_empty()
    }

    /// The meshes.
    pub fn meshes(&self) -> &[Mesh] {
        &self.meshes
    }

    /// Primitive-id range of mesh `m`.
    pub fn mesh_prims(&self, m: usize) -> std::ops::Range<usize> {
        self.first_prim[m] as usize..self.first_prim[m + 1] as usize
    }

    /// The mesh (geometry id) holding primitive `prim`; `MISS` for `MISS` or an id out of range.
    pub fn geometry_of(&self, prim: u32) -> u32 {
        if prim as usize >= self.len() {
            return crate::rays::MISS;
        }
        // Meshes are few; the last mesh whose first primitive is <= prim (empty meshes skipped).
        (self.first_prim.partition_point(|&f| f <= prim) - 1) as u32
    }

    /// Total number of source vertices.
    pub fn vertex_count(&self) -> usize {
        self.meshes.iter().map(|m| m.positions.len()).sum()
    }

    /// World-space bounds of all triangles (degenerate ones included).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// World-space bounds of mesh `m`.
    pub fn mesh_bounds(&self, m: usize) -> Aabb {
        self.mesh_bounds[m]
    }

    /// Number of degenerate (never-hit) triangles.
    pub fn degenerate_count(&self) -> usize {
        self.degenerate
    }

    /// Bytes held: source meshes plus the world soup.
    pub fn bytes(&self) -> usize {
        let src: usize = self
            .meshes
            .iter()
            .map(|m| {
                m.positions.capacity() * 12
                    + m.indices.capacity() * 12
                    + m.colors.capacity() * 12
                    + std::mem::size_of::<Mesh>()
            })
            .sum();
        src + self.soup.bytes()
            + self.first_prim.capacity() * 4
            + self.mat_start.capacity() * 4
            + self.mat.capacity() * std::mem::size_of::<Option<Material>>()
    }

    /// The material of primitive `prim` (`None`: its mesh has none, or `prim` is out of range).
    #[inline]
    pub fn material(&self, prim: u32) -> Option<&Material> {
        if prim as usize >= self.len() {
            return None;
        }
        let r = self
            .mat_start
            .partition_point(|&f| f <= prim)
            .checked_sub(1)?;
        self.mat[r].as_ref()
    }

    /// The diffuse colour at barycentrics (`u`, `v`) of primitive `prim` (a hit's `u`, `v`):
    /// its material's diffuse colour (`default`'s when it has none), or, where its mesh has
    /// vertex colours, their interpolation times the material's colour (alone when it has none).
    #[inline]
    pub fn albedo(&self, prim: u32, u: f32, v: f32, default: &Material) -> Vec3 {
        let m = self.material(prim);
        let g = self.geometry_of(prim);
        let colored = self
            .meshes
            .get(g as usize)
            .filter(|mesh| !mesh.colors.is_empty());
        match colored {
            None => m.unwrap_or(default).diffuse,
            Some(mesh) => {
                let [a, b, c] = mesh.indices[prim as usize - self.first_prim[g as usize] as usize]
                    .map(|i| mesh.colors[i as usize]);
                let col = a * (1.0 - u - v) + b * u + c * v;
                col.clamp(Vec3::ZERO, Vec3::ONE) * m.map_or(Vec3::ONE, |m| m.diffuse)
            }
        }
    }

    /// The material runs: `(first primitive, material)` in increasing order, each up to the next
    /// (the last to the end of the scene); `None` for primitives without a material.
    pub fn material_runs(
        &self,
    ) -> impl Iterator<Item = (std::ops::Range<usize>, Option<&Material>)> {
        let n = self.len();
        (0..self.mat.len()).map(move |r| {
            let end = self.mat_start.get(r + 1).map_or(n, |&e| e as usize);
            (self.mat_start[r] as usize..end, self.mat[r].as_ref())
        })
    }

    /// True when some primitive's material emits light (the scene has area lights).
    pub fn has_emission(&self) -> bool {
        self.mat.iter().flatten().any(Material::is_emissive)
    }

    /// Geometric unit normal of triangle `prim` in world space (zero for degenerate ones).
    pub fn normal(&self, prim: usize) -> Vec3 {
        let [a, b, c] = self.soup.get(prim);
        crate::geom::triangle::normal(a, b, c).normalize_or_zero()
    }
}

/// The embedded default scene: the Stanford Bunny at Stanford's decimation level 2 (16,301
/// triangles; see `assets/README.md` for the credit), used by `raysift render` without a scene.
pub fn default_scene() -> Result<Scene> {
    const BYTES: &[u8] = include_bytes!("../../../../assets/bunny.ply.gz");
    let name = "default (Stanford bunny, 16K triangles)";
    let mut ply = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(BYTES), &mut ply)
        .map_err(|e| Error::parse(name, "gzip stream", e.to_string()))?;
    Scene::from_meshes(name, io::ply::parse(&ply, name)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Mesh {
        Mesh::new(
            "q",
            vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            vec![[0, 1, 2], [0, 2, 3], [0, 0, 1]],
        )
    }

    #[test]
    fn bake_keeps_ids_and_collapses_degenerates() {
        let s = Scene::from_meshes("t", vec![quad(), quad()]).unwrap();
        assert_eq!(s.len(), 6);
        assert_eq!(s.degenerate_count(), 2);
        assert_eq!(s.triangles().get(2), [Vec3::ZERO; 3]);
        assert_eq!(s.mesh_prims(1), 3..6);
        assert_eq!(s.bounds(), Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)));
    }

    #[test]
    fn transforms_move_the_soup() {
        let mut s = Scene::from_meshes("t", vec![quad()]).unwrap();
        s.set_transform(0, Affine3A::from_translation(Vec3::new(0.0, 0.0, 5.0)))
            .unwrap();
        assert_eq!(s.triangles().v0[0], Vec3::new(0.0, 0.0, 5.0));
        assert_eq!(s.bounds().min.z, 5.0);
        let bad = Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0));
        let e = s.set_transform(0, bad).unwrap_err().to_string();
        assert!(e.contains("non-finite transform"), "{e}");
        assert!(s.set_transform(3, Affine3A::IDENTITY).is_err());
    }

    #[test]
    fn partial_rebake_equals_a_fresh_bake() {
        let mut s = Scene::from_meshes("t", vec![quad(), quad(), quad()]).unwrap();
        let xf = Affine3A::from_rotation_z(0.3) * Affine3A::from_translation(Vec3::ONE);
        s.set_transform(1, xf).unwrap();
        let mut moved = quad();
        moved.positions[2] = Vec3::new(3.0, 1.0, -2.0);
        s.replace_positions(2, moved.positions.clone()).unwrap();
        let mut m1 = quad();
        m1.transform = xf;
        let fresh = Scene::from_meshes("f", vec![quad(), m1, moved]).unwrap();
        for i in 0..s.len() {
            assert_eq!(
                s.triangles().get(i),
                fresh.triangles().get(i),
                "triangle {i}"
            );
        }
        assert_eq!(s.bounds(), fresh.bounds());
        assert_eq!(s.degenerate_count(), fresh.degenerate_count());
        let e = s.replace_positions(0, vec![Vec3::ZERO]).unwrap_err();
        assert!(e.to_string().contains("1 positions given"), "{e}");
    }

    #[test]
    fn changes_since_names_what_moved() {
        let mut s = Scene::from_meshes("t", vec![quad(), quad(), quad()]).unwrap();
        let fresh = Stamp::default();
        assert_eq!(s.changes_since(fresh), Change::All);
        let v0 = s.stamp();
        assert_eq!(s.changes_since(v0), Change::None);
        assert!(v0.check(&s, "x").is_ok());
        s.set_transform(2, Affine3A::from_translation(Vec3::X))
            .unwrap();
        let v1 = s.stamp();
        s.replace_positions(0, quad().positions).unwrap();
        assert_eq!(
            s.changes_since(v0),
            Change::Meshes {
                moved: vec![2],
                deformed: vec![0]
            }
        );
        assert_eq!(
            s.changes_since(v1),
            Change::Meshes {
                moved: vec![],
                deformed: vec![0]
            }
        );
        let e = v0.check(&s, "bvh").unwrap_err().to_string();
        assert!(e.contains("bvh") && e.contains("changed"), "{e}");
        // A clone is another scene.
        let c = s.clone();
        assert_eq!(c.changes_since(s.stamp()), Change::All);
        assert!(s.stamp().check(&c, "bvh").is_err());
        assert!(Stamp::default()
            .check(&s, "bvh")
            .unwrap_err()
            .to_string()
            .contains("not prepared"));
    }

    #[test]
    fn geometry_of_finds_the_mesh() {
        let empty = Mesh::new("e", vec![], vec![]);
        let s = Scene::from_meshes("t", vec![quad(), empty, quad()]).unwrap();
        assert_eq!(s.geometry_of(0), 0);
        assert_eq!(s.geometry_of(2), 0);
        assert_eq!(s.geometry_of(3), 2);
        assert_eq!(s.geometry_of(5), 2);
        assert_eq!(s.geometry_of(6), crate::rays::MISS);
        assert_eq!(s.geometry_of(crate::rays::MISS), crate::rays::MISS);
    }

    #[test]
    fn rejects_bad_indices_and_nan() {
        let mut m = quad();
        m.indices.push([0, 1, 4]);
        let e = Scene::from_meshes("bad.obj", vec![m])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.obj") && e.contains("triangle 3") && e.contains("out of range"),
            "{e}"
        );
        let mut m = quad();
        m.positions[1].y = f32::NAN;
        let e = Scene::from_meshes("nan.ply", vec![m])
            .unwrap_err()
            .to_string();
        assert!(e.contains("nan.ply") && e.contains("vertex 1"), "{e}");
    }

    #[test]
    fn materials_by_triangle_range() {
        let red = Material {
            diffuse: Vec3::new(0.9, 0.1, 0.1),
            ..Default::default()
        };
        let lamp = Material {
            emission: Vec3::splat(5.0),
            ..Default::default()
        };
        let mut a = quad();
        a.materials = vec![(1, red), (2, lamp)];
        let s = Scene::from_meshes("t", vec![quad(), a, quad().with_material(red)]).unwrap();
        let got: Vec<Option<Material>> = (0..10).map(|p| s.material(p).copied()).collect();
        let want = [
            None,
            None,
            None,
            None,
            Some(red),
            Some(lamp),
            Some(red),
            Some(red),
            Some(red),
            None,
        ];
        assert_eq!(got, want);
        assert!(s.has_emission());
        assert!(!Scene::from_meshes("t", vec![quad().with_material(red)])
            .unwrap()
            .has_emission());
        let runs: Vec<_> = s.material_runs().map(|(r, m)| (r, m.copied())).collect();
        assert_eq!(runs[0], (0..4, None));
        assert_eq!(runs[2], (5..6, Some(lamp)));
        assert_eq!(runs[3], (6..9, Some(red)));
        let mut bad = quad();
        bad.materials = vec![(
            0,
            Material {
                diffuse: Vec3::splat(1.5),
                ..Default::default()
            },
        )];
        let e = Scene::from_meshes("b.obj", vec![bad])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("b.obj") && e.contains("material 0") && e.contains("diffuse"),
            "{e}"
        );
        let mut bad = quad();
        bad.materials = vec![(3, red)];
        assert!(Scene::from_meshes("b", vec![bad]).is_err());
    }

    #[test]
    fn empty_scene_is_allowed() {
        let s = Scene::from_meshes("e", vec![]).unwrap();
        assert!(s.is_empty());
        assert!(s.bounds().is_empty());
    }
}
