//! Writing output files atomically: data goes to a temporary file beside the target, which is
//! renamed over it only when everything was written, so an error never leaves a half-written file.
//!
//! Errors name the target the caller asked for, never the temporary file (whose random name,
//! `.raysift-xSKV0y`, means nothing to a user).

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` through `f`, atomically.
pub fn write_atomic(
    path: &Path,
    f: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let name = path.display().to_string();
    if path.is_dir() {
        return Err(Error::Invalid(format!(
            "{name}: is a folder; give a file name"
        )));
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::Builder::new()
        .prefix(".raysift-")
        .tempfile_in(dir)
        .map_err(|e| folder_error(&name, dir, &e))?;
    {
        // Writes go to the `File` itself, whose errors carry no path.
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
    // A failed rename's error (a plain OS error) is about the target.
    tmp.persist(path).map_err(|e| Error::io(&name, e.error))?;
    Ok(())
}

/// Why the temporary file could not be made in `dir`, in terms of the user's path `name`
/// (tempfile's own error names the temporary file).
fn folder_error(name: &str, dir: &Path, e: &std::io::Error) -> Error {
    let why = match std::fs::metadata(dir) {
        Err(m) => m.to_string(),
        Ok(m) if !m.is_dir() => "not a folder".to_string(),
        // Permission denied, read-only file system, ...: the kind says it without the path.
        Ok(_) => std::io::Error::from(e.kind()).to_string(),
    };
    Error::Invalid(format!(
        "{name}: cannot create the file in {}: {why}",
        dir.display()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_target_not_the_temporary_file() {
        let d = tempfile::tempdir().unwrap();
        let missing = d.path().join("no-such-folder").join("x.png");
        let e = write_atomic(&missing, |w| w.write_all(b"x"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.png") && e.contains("no-such-folder"), "{e}");
        assert!(!e.contains(".raysift-"), "{e}");
        let e = write_atomic(d.path(), |w| w.write_all(b"x"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a folder"), "{e}");
        let e = write_atomic(&d.path().join("y.npy"), |_| {
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("y.npy") && e.contains("disk full"), "{e}");
        assert_eq!(
            std::fs::read_dir(d.path()).unwrap().count(),
            0,
            "nothing left"
        );
    }
}
