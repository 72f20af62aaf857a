//! Thread pools: `--threads N` runs a command inside an N-worker rayon pool, `--pin` pins worker k
//! to core k.

use crate::args::TracerArgs;
use anyhow::{bail, Context, Result};

/// Runs `f` in a rayon pool of `--threads` workers (all cores when not given), optionally
/// pinning worker k to the k-th core this process may run on (`--pin`).
pub fn with_threads<T: Send>(a: &TracerArgs, f: impl FnOnce() -> Result<T> + Send) -> Result<T> {
    if a.threads == Some(0) {
        bail!("--threads must be at least 1");
    }
    if a.threads.is_none() && !a.pin {
        return f();
    }
    let mut b = rayon::ThreadPoolBuilder::new().num_threads(a.threads.unwrap_or(0));
    if a.pin {
        let cores = core_affinity::get_core_ids().unwrap_or_default();
        if cores.is_empty() {
            bail!("--pin: cannot read this process's CPU affinity");
        }
        b = b.start_handler(move |k| {
            core_affinity::set_for_current(cores[k % cores.len()]);
        });
    }
    b.build().context("starting the thread pool")?.install(f)
}
