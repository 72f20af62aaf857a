//! Resource limits shared by every reader (scene files, gzip, `.npy`), so hostile input fails
//! with a clear error before allocating, never with an out-of-memory abort.
//!
//! The rules (the reasons are in `docs/fuzzing.md`, "Limits"):
//!
//! - **Counts against bytes.** A header that declares more elements than the rest of the file can
//!   hold (PLY element counts, OFF counts, glTF accessors against their buffer views, a `.npy`
//!   shape against the data after its header) is an error at the header, before any element is
//!   read or any space reserved. Each loader does this check with its format's smallest possible
//!   element size.
//! - **gzip.** A `.gz` file is inflated as a stream and refused once it has produced more than
//!   [`gzip_cap`] bytes: [`GZ_MAX_RATIO`] times its compressed size plus [`GZ_SLACK`]. Real meshes
//!   inflate 3–6× (the shared dragon 4.1×, Sponza 5.7×); a decompression bomb inflates up to
//!   about 1032× (deflate's limit), so it is stopped after at most 64× its size.
//! - **Memory.** A file whose decoded content cannot fit in the memory the system has available
//!   (`MemAvailable` in `/proc/meminfo`) is refused up front with the amount it needs: a plain
//!   scene file larger than that, a rays, hits or occlusion file whose arrays would not fit, a
//!   gzip stream whose inflated size would not fit. Where `/proc/meminfo` cannot be read (other
//!   systems) this check is skipped and the other limits still apply.

use crate::error::{Error, Result};

/// A `.gz` input may inflate to at most this many times its compressed size (plus
/// [`GZ_SLACK`]).
pub const GZ_MAX_RATIO: u64 = 64;

/// Bytes a `.gz` input may always inflate to, whatever its size (tiny files have a poor ratio).
pub const GZ_SLACK: u64 = 64 << 10;

/// The most bytes a gzip stream of `compressed` bytes may inflate to:
/// `GZ_MAX_RATIO * compressed + GZ_SLACK`.
pub fn gzip_cap(compressed: u64) -> u64 {
    compressed
        .saturating_mul(GZ_MAX_RATIO)
        .saturating_add(GZ_SLACK)
}

/// The system's available memory in bytes (`MemAvailable` in `/proc/meminfo`), or `None` where
/// it cannot be read.
pub fn mem_available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_meminfo(&text)
}

/// `MemAvailable` from the text of `/proc/meminfo`, in bytes.
fn parse_meminfo(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_ascii_whitespace().skip(1);
    let n: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => n.checked_mul(1024),
        None => Some(n),
        Some(_) => None,
    }
}

/// Fails unless `bytes` of decoded `what` fit in the available memory (see the module doc).
pub fn check_memory(file: &str, place: &str, what: &str, bytes: u64) -> Result<()> {
    check_memory_with(mem_available(), file, place, what, bytes)
}

/// [`check_memory`] against `available` bytes, read once by a caller that checks often.
pub fn check_memory_with(
    available: Option<u64>,
    file: &str,
    place: &str,
    what: &str,
    bytes: u64,
) -> Result<()> {
    match available {
        Some(avail) if bytes > avail => Err(Error::parse(
            file,
            place,
            format!(
                "{what} need {} but only {} of memory is available (MemAvailable); refused rather than run out of memory",
                human(bytes),
                human(avail)
            ),
        )),
        _ => Ok(()),
    }
}

/// `bytes` as a short human-readable size, with the exact count.
pub fn human(bytes: u64) -> String {
    const G: f64 = (1u64 << 30) as f64;
    const M: f64 = (1u64 << 20) as f64;
    let b = bytes as f64;
    if b >= G {
        format!("{:.1} GiB ({bytes} bytes)", b / G)
    } else if b >= M {
        format!("{:.1} MiB ({bytes} bytes)", b / M)
    } else {
        format!("{bytes} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_and_caps() {
        let t = "MemTotal:       24683584 kB\nMemFree:        21165068 kB\nMemAvailable:   24214512 kB\n";
        assert_eq!(parse_meminfo(t), Some(24214512 * 1024));
        assert_eq!(parse_meminfo("MemTotal: 1 kB\n"), None);
        assert_eq!(gzip_cap(1000), 64_000 + 65_536);
        assert_eq!(gzip_cap(u64::MAX), u64::MAX);
        if cfg!(target_os = "linux") {
            assert!(mem_available().is_some_and(|m| m > 0));
        }
        assert!(check_memory("f", "p", "rays", u64::MAX)
            .map_err(|e| e.to_string())
            .map_or_else(
                |e| e.contains("MemAvailable"),
                |_| mem_available().is_none()
            ));
    }
}
