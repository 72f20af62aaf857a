//! Links the peer against the Embree 4 shared library that ships inside the `embreex` wheel
//! (`site-packages/embreex.libs/libembree4-<hash>.so.4`, next to its TBB), so a fresh machine
//! needs only `pip install -r bench/requirements.txt`.
//!
//! Lookup order: `$EMBREE_LIB` (full path of a libembree4 shared object), `$EMBREE_LIB_DIR`
//! (a folder holding one), then `python3` (or `$PYTHON`) asked where `embreex` is installed.
//! The folder is added as an rpath, so the binary runs without LD_LIBRARY_PATH.

use std::path::{Path, PathBuf};
use std::process::Command;

fn find_in(dir: &Path) -> Option<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("libembree4") && n.contains(".so"))
        })
        .collect();
    found.sort();
    found.pop()
}

fn from_python() -> Result<PathBuf, String> {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    // embreex.libs/ (auditwheel) sits beside the embreex package; also look inside it.
    let script = "import embreex, os; d = os.path.dirname(os.path.abspath(embreex.__file__)); \
                  print(os.path.join(os.path.dirname(d), 'embreex.libs')); print(d)";
    let out = Command::new(&python)
        .args(["-c", script])
        .output()
        .map_err(|e| format!("could not run {python}: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "{python} could not import embreex ({}); run: pip install -r bench/requirements.txt",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        if let Some(p) = find_in(Path::new(line.trim())) {
            return Ok(p);
        }
    }
    Err(format!(
        "embreex is installed but no libembree4*.so* was found beside it ({})",
        String::from_utf8_lossy(&out.stdout).trim()
    ))
}

fn main() {
    println!("cargo:rerun-if-env-changed=EMBREE_LIB");
    println!("cargo:rerun-if-env-changed=EMBREE_LIB_DIR");
    println!("cargo:rerun-if-env-changed=PYTHON");
    println!("cargo:rerun-if-changed=build.rs");
    let lib = if let Ok(p) = std::env::var("EMBREE_LIB") {
        PathBuf::from(p)
    } else if let Ok(d) = std::env::var("EMBREE_LIB_DIR") {
        find_in(Path::new(&d))
            .unwrap_or_else(|| panic!("EMBREE_LIB_DIR={d} holds no libembree4*.so*"))
    } else {
        from_python().unwrap_or_else(|e| panic!("embree-peer: {e}"))
    };
    let lib = lib.canonicalize().unwrap_or(lib);
    let dir = lib.parent().expect("library path has a folder");
    // Linking the file by path records its SONAME as DT_NEEDED; the rpath finds it at run time
    // (and libembree4's own $ORIGIN rpath finds the bundled TBB).
    println!("cargo:rustc-link-arg={}", lib.display());
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", dir.display());
    println!("cargo:rustc-env=EMBREE_LIB_PATH={}", lib.display());
}
