//! Progress on stderr (indicatif draws nothing when stderr is not a terminal, so scripts and
//! `--json` consumers see clean output).

use indicatif::{ProgressBar, ProgressStyle};
use std::time::Duration;

/// A spinner with a message and the elapsed time, for one long step.
pub fn spinner(msg: impl Into<String>) -> ProgressBar {
    let pb = ProgressBar::new_spinner().with_message(msg.into());
    pb.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").expect("valid template"),
    );
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

/// A bar over `frames` frames, with the time left.
pub fn frames(frames: u32) -> ProgressBar {
    let pb = ProgressBar::new(frames as u64);
    pb.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames [{elapsed}<{eta}]")
            .expect("valid template"),
    );
    pb
}
