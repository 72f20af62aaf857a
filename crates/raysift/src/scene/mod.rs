//! Scenes: triangle meshes, each with a rigid transform, baked into one world-space triangle soup
//! that every tracer reads.
//!
//! Storage (bytes per triangle, documented in ARCHITECTURE.md):
//! - the **source meshes**, indexed: local positions (12 B per vertex) and `[u32; 3]` indices
//!   (12 B per triangle), plus one `Affine3A` per mesh;
//! - the **world soup**, structure-of-arrays by corner: `v0`, `v1`, `v2` arrays of `Vec3`
//!   (36 B per triangle), rebuilt by [`Scene::rebake`] after a transform or a vertex changes.
//!
//! Primitive ids are the triangle's index in load order (meshes in order, each mesh's faces in
//! file order, polygons fanned in order), so another program loading the same file agrees.
//! Degenerate triangles keep their id but are collapsed to their first vertex in the soup, so
//! the shared triangle test never hits them (see `geom::triangle`).

pub mod animate;
pub mod io;
pub mod procedural;

use crate::error::{Error, Result};
use crate::geom::{triangle::is_degenerate, Aabb};
use glam::{Affine3A, Vec3};

pub use io::load;

/// One mesh: local-space vertices, triangles as index triples, and a rigid (affine) transform.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// Name from the file (object, group, node) or generator.
    pub name: String,
    /// Local-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`.
    pub indices: Vec<[u32; 3]>,
    /// Local-to-world transform.
    pub transform: Affine3A,
}

impl Mesh {
    /// A mesh with identity transform.
    pub fn new(name: impl Into<String>, positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Self {
        Self {
            name: name.into(),
            positions,
            indices,
            transform: Affine3A::IDENTITY,
        }
    }
}

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

/// A scene: meshes plus their baked world-space soup.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Display name (file name or generator spec).
    pub name: String,
    meshes: Vec<Mesh>,
    /// `first_prim[m]` is the primitive id of mesh `m`'s first triangle; one extra entry at the end.
    first_prim: Vec<u32>,
    soup: TriangleSoup,
    bounds: Aabb,
    degenerate: usize,
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
            if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
                return Err(Error::parse(
                    &name,
                    format!("mesh {m} ({}), vertex {i}", mesh.name),
                    format!("non-finite coordinate {:?}", mesh.positions[i]),
                ));
            }
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
            if !transform_is_finite(&mesh.transform) {
                return Err(Error::parse(
                    &name,
                    format!("mesh {m} ({})", mesh.name),
                    "non-finite transform",
                ));
            }
            total += mesh.indices.len() as u64;
        }
        if total >= u32::MAX as u64 {
            return Err(Error::Invalid(format!(
                "{name}: {total} triangles; at most {} are supported",
                u32::MAX - 1
            )));
        }
        first_prim.push(total as u32);
        let mut scene = Self {
            name,
            meshes,
            first_prim,
            soup: TriangleSoup::default(),
            bounds: Aabb::EMPTY,
            degenerate: 0,
        };
        scene.rebake();
        Ok(scene)
    }

    /// Recomputes the world soup, bounds and degenerate count from the meshes (call after
    /// changing transforms or positions).
    pub fn rebake(&mut self) {
        let n = *self.first_prim.last().unwrap_or(&0) as usize;
        let soup = &mut self.soup;
        for v in [&mut soup.v0, &mut soup.v1, &mut soup.v2] {
            v.clear();
            v.reserve_exact(n);
        }
        let mut bounds = Aabb::EMPTY;
        let mut degenerate = 0;
        for mesh in &self.meshes {
            let world: Vec<Vec3> = mesh
                .positions
                .iter()
                .map(|&p| mesh.transform.transform_point3(p))
                .collect();
            for t in &mesh.indices {
                let (a, b, c) = (
                    world[t[0] as usize],
                    world[t[1] as usize],
                    world[t[2] as usize],
                );
                bounds = bounds.grow(a).grow(b).grow(c);
                if is_degenerate(a, b, c) {
                    degenerate += 1;
                    soup.v0.push(a);
                    soup.v1.push(a);
                    soup.v2.push(a);
                } else {
                    soup.v0.push(a);
                    soup.v1.push(b);
                    soup.v2.push(c);
                }
            }
        }
        self.bounds = bounds;
        self.degenerate = degenerate;
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

    /// Mutable access to one mesh (positions or transform); call [`Scene::rebake`] afterwards.
    /// Changing the number of triangles is not allowed (ids must stay stable): it panics at rebake
    /// time through the debug assertion below, so use [`Scene::from_meshes`] for that.
    pub fn mesh_mut(&mut self, m: usize) -> &mut Mesh {
        &mut self.meshes[m]
    }

    /// Sets mesh `m`'s transform and rebakes.
    pub fn set_transform(&mut self, m: usize, transform: Affine3A) {
        self.meshes[m].transform = transform;
        self.rebake();
    }

    /// Primitive-id range of mesh `m`.
    pub fn mesh_prims(&self, m: usize) -> std::ops::Range<usize> {
        self.first_prim[m] as usize..self.first_prim[m + 1] as usize
    }

    /// Total number of source vertices.
    pub fn vertex_count(&self) -> usize {
        self.meshes.iter().map(|m| m.positions.len()).sum()
    }

    /// World-space bounds of all triangles (degenerate ones included).
    pub fn bounds(&self) -> Aabb {
        self.bounds
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
                    + std::mem::size_of::<Mesh>()
            })
            .sum();
        src + self.soup.bytes() + self.first_prim.capacity() * 4
    }

    /// Geometric unit normal of triangle `prim` in world space (zero for degenerate ones).
    pub fn normal(&self, prim: usize) -> Vec3 {
        let [a, b, c] = self.soup.get(prim);
        crate::geom::triangle::normal(a, b, c).normalize_or_zero()
    }
}

fn transform_is_finite(t: &Affine3A) -> bool {
    t.matrix3.x_axis.is_finite()
        && t.matrix3.y_axis.is_finite()
        && t.matrix3.z_axis.is_finite()
        && t.translation.is_finite()
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
        s.set_transform(0, Affine3A::from_translation(Vec3::new(0.0, 0.0, 5.0)));
        assert_eq!(s.triangles().v0[0], Vec3::new(0.0, 0.0, 5.0));
        assert_eq!(s.bounds().min.z, 5.0);
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
    fn empty_scene_is_allowed() {
        let s = Scene::from_meshes("e", vec![]).unwrap();
        assert!(s.is_empty());
        assert!(s.bounds().is_empty());
    }
}
