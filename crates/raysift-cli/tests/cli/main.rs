//! End-to-end tests of the `raysift` command: the README's commands work, every tracer agrees
//! through the files, and bad input gives a one-line error naming the file, exit code 2, no panic
//! and no output file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary under test: this build's, or `$RAYSIFT_BIN` (to hold another build, such as an
/// installed or an older `raysift`, to these tests).
fn raysift(args: &[&str]) -> Output {
    let bin = std::env::var("RAYSIFT_BIN").unwrap_or(env!("CARGO_BIN_EXE_raysift").into());
    Command::new(bin).args(args).output().expect("raysift runs")
}

fn ok(args: &[&str]) -> Output {
    let o = raysift(args);
    assert!(
        o.status.success(),
        "raysift {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Runs a command that must fail cleanly: exit code 2, one line on stderr mentioning `needle`, no panic.
fn fails(args: &[&str], needle: &str) -> String {
    let o = raysift(args);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(
        o.status.code(),
        Some(2),
        "raysift {args:?}: expected exit 2, got {:?}; stderr: {err}",
        o.status.code()
    );
    assert!(
        !err.contains("panicked"),
        "raysift {args:?} panicked: {err}"
    );
    assert!(
        err.contains(needle),
        "raysift {args:?}: error should mention {needle:?}: {err}"
    );
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one-line error expected: {err}"
    );
    err
}

/// Runs a command with a usage error: exit code 2 and clap's whole message (what is wrong,
/// mentioning `needle`, and the usage line), no panic.
fn usage_fails(args: &[&str], needle: &str) -> String {
    let o = raysift(args);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(2), "raysift {args:?}: {err}");
    assert!(
        !err.contains("panicked"),
        "raysift {args:?} panicked: {err}"
    );
    assert!(
        err.contains(needle),
        "raysift {args:?}: error should mention {needle:?}: {err}"
    );
    assert!(
        err.contains("Usage:") || err.contains("--help"),
        "raysift {args:?}: the usage should follow: {err}"
    );
    err
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn p(dir: &Path, name: &str) -> String {
    dir.join(name).display().to_string()
}

fn json(o: &Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}): {}",
            String::from_utf8_lossy(&o.stdout)
        )
    })
}

fn tracer_names() -> Vec<String> {
    json(&ok(&["tracers", "--json"]))
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["name"].as_str().unwrap().to_string())
        .collect()
}

mod commands;
mod cones;
mod errors;
mod record;
mod scenefile;
