//! The scene's input: meshes (positions, indices, transform, materials, vertex colours) and
//! the material model the renderers use.

use glam::{Affine3A, Vec3};

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
    /// Materials by triangle range: `(first, material)` applies from the mesh's triangle `first`
    /// up to the next entry's `first` (entries in increasing order). Empty: the mesh has no
    /// material, and renderers use their default grey ([`Scene::material`](super::Scene::material) gives `None`).
    pub materials: Vec<(u32, Material)>,
    /// Per-vertex diffuse colours (PLY `red green blue`), each in [0, 1], one per position, or
    /// empty. Where present they are the surface's diffuse colour, times its material's when it
    /// has one ([`Scene::albedo`](super::Scene::albedo)).
    pub colors: Vec<Vec3>,
}

impl Mesh {
    /// A mesh with identity transform and no material.
    pub fn new(name: impl Into<String>, positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Self {
        Self {
            name: name.into(),
            positions,
            indices,
            transform: Affine3A::IDENTITY,
            materials: Vec::new(),
            colors: Vec::new(),
        }
    }

    /// The mesh with per-vertex colours (one per position; checked by [`Scene::from_meshes`](super::Scene::from_meshes)).
    pub fn with_colors(mut self, colors: Vec<Vec3>) -> Self {
        self.colors = colors;
        self
    }

    /// The mesh with one material on all its triangles.
    pub fn with_material(mut self, m: Material) -> Self {
        self.materials = vec![(0, m)];
        self
    }
}

/// A surface's material, as the renderers use it: Lambertian diffuse reflectance, emitted
/// radiance (non-zero makes the surface an area light, emitting from both sides), or a perfect
/// mirror (reflects everything; its diffuse colour is then the mirror's tint).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Material {
    /// Diffuse reflectance (albedo) per RGB channel, each in [0, 1].
    pub diffuse: Vec3,
    /// Emitted radiance per RGB channel (W·sr⁻¹·m⁻² in scene units), each >= 0.
    pub emission: Vec3,
    /// A perfect mirror.
    pub mirror: bool,
}

impl Default for Material {
    /// Grey 0.7, not emissive, not a mirror (the path tracer's albedo for material-less meshes).
    fn default() -> Self {
        Self {
            diffuse: Vec3::splat(0.7),
            emission: Vec3::ZERO,
            mirror: false,
        }
    }
}

impl Material {
    /// True when the surface emits light.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// Checks that the colours are finite, the albedo in [0, 1] and the emission non-negative;
    /// the error names the field.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if !self.diffuse.is_finite()
            || self.diffuse.min_element() < 0.0
            || self.diffuse.max_element() > 1.0
        {
            return Err(format!(
                "diffuse colour {:?} outside [0, 1]",
                self.diffuse.to_array()
            ));
        }
        if !self.emission.is_finite() || self.emission.min_element() < 0.0 {
            return Err(format!(
                "emission {:?} must be finite and non-negative",
                self.emission.to_array()
            ));
        }
        Ok(())
    }
}
