//! Writing output files atomically: data goes to a temporary file beside the target, which is
//! renamed over it only when everything was written, so an error never leaves a half-written file.

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` through `f`, atomically.
pub fn write_atomic(
    path: &Path,
    f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let name = path.display().to_string();
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".raysift-")
        .tempfile_in(dir)
        .map_err(|e| Error::io(&name, e))?;
    {
        let mut w = BufWriter::new(tmp.as_file());
        f(&mut w).map_err(|e| Error::io(&name, e))?;
        w.flush().map_err(|e| Error::io(&name, e))?;
    }
    // Temporary files are created private (0600); outputs should be readable like any new file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(|e| Error::io(&name, e))?;
    }
    tmp.persist(path).map_err(|e| Error::io(&name, e.error))?;
    Ok(())
}
