//! glTF loader (placeholder until the loaders land).

use crate::error::{Error, Result};
use crate::scene::Mesh;
use std::path::Path;

/// Parses glTF (`.gltf` JSON or `.glb`) bytes into meshes; `base` resolves external buffers.
pub fn parse(_bytes: &[u8], file: &str, _base: Option<&Path>) -> Result<Vec<Mesh>> {
    Err(Error::Invalid(format!(
        "{file}: the glTF loader is not built yet"
    )))
}
