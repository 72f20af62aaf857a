//! OFF loader (placeholder until the loaders land).

use crate::error::{Error, Result};
use crate::scene::Mesh;

/// Parses a OFF file's bytes into meshes.
pub fn parse(_bytes: &[u8], file: &str) -> Result<Vec<Mesh>> {
    Err(Error::Invalid(format!(
        "{file}: the OFF loader is not built yet"
    )))
}
