//! PLY loader (placeholder until the loaders land).

use crate::error::{Error, Result};
use crate::scene::Mesh;

/// Parses a PLY file's bytes into meshes.
pub fn parse(_bytes: &[u8], file: &str) -> Result<Vec<Mesh>> {
    Err(Error::Invalid(format!(
        "{file}: the PLY loader is not built yet"
    )))
}
