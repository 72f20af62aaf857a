//! Progress on stderr (indicatif draws nothing when stderr is not a terminal, so scripts and
//! `--json` consumers see clean output).

use indicatif::{ProgressBar, ProgressStyle};
use std::time::Duration;

/// A spinner with a message and the elapsed time, for one long step.
pub fn spinner(msg: impl Into<String>) -> ProgressBar {
    if quiet() {
        return ProgressBar::hidden();
    }
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
    if quiet() {
        pb.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    pb.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames [{elapsed}<{eta}]")
            .expect("valid template"),
    );
    pb
}

/// `--quiet`: no spinner or bar at all, even on a terminal.
static QUIET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Silences every spinner and bar of this process (`render --quiet`, `animate --quiet`).
pub fn set_quiet(q: bool) {
    QUIET.store(q, std::sync::atomic::Ordering::Relaxed);
}

/// Whether `--quiet` was given.
pub fn quiet() -> bool {
    QUIET.load(std::sync::atomic::Ordering::Relaxed)
}

/// What a render will trace, for the bar's length (rays expected) and its phase names.
#[derive(Clone, Copy, Debug)]
pub enum Plan {
    /// Ray casting: camera rays, then shadow rays.
    Raycast { pixels: u64 },
    /// Path tracing: `spp` samples of up to `bounces + 1` depths; the first sample's rays give
    /// the estimate for the others.
    Path { spp: u32, bounces: u32, pixels: u64 },
    /// Distribution: camera rays, then about `per_hit` rays for each camera hit.
    Distribution { per_hit: u64 },
    /// Instant radiosity: photons, then per sample camera rays and `subset` shadow rays per
    /// camera hit.
    Radiosity { subset: u64, spp: u32 },
}

#[derive(Default)]
struct State {
    rays: u64,
    sample: u32,
    depth: u32,
    seen_shadow: bool,
    seen_camera: bool,
    total: u64,
    phase: String,
}

/// A progress bar over one render, fed by [`raysift::render::progress::Watched`]'s calls: rays
/// done against rays expected, rays/s, the sample and bounce or the phase, and the time left.
/// It appears once the render has run a second, on a terminal and without `--quiet`.
pub struct RenderBar {
    pb: ProgressBar,
    plan: Plan,
    start: std::time::Instant,
    state: std::sync::Mutex<State>,
}

impl RenderBar {
    /// A hidden bar for `plan`.
    pub fn new(plan: Plan) -> Self {
        let pb = ProgressBar::with_draw_target(Some(1), indicatif::ProgressDrawTarget::hidden());
        pb.set_style(
            ProgressStyle::with_template("{bar:30} {percent:>3}% {msg} [{elapsed}<{eta}]")
                .expect("valid template"),
        );
        let total = match plan {
            Plan::Raycast { pixels } => 2 * pixels,
            Plan::Path {
                spp,
                bounces,
                pixels,
            } => 2 * spp as u64 * (bounces as u64 + 1) * pixels,
            Plan::Distribution { .. } | Plan::Radiosity { .. } => 1,
        };
        Self {
            pb,
            plan,
            start: std::time::Instant::now(),
            state: std::sync::Mutex::new(State {
                total,
                ..Default::default()
            }),
        }
    }

    /// Records one trace call.
    pub fn on(&self, c: raysift::render::progress::Call) {
        use raysift::render::progress::CallKind;
        let mut s = self.state.lock().expect("progress state");
        s.rays += c.rays;
        let intersect = c.kind == CallKind::Intersect;
        match self.plan {
            Plan::Raycast { .. } => {
                s.phase = if intersect { "camera" } else { "shadow" }.into();
            }
            Plan::Path { spp, .. } => {
                if c.camera && intersect {
                    if s.sample == 1 {
                        // The first sample's rays, times the samples.
                        s.total = (s.rays - c.rays) * spp as u64;
                    }
                    s.sample += 1;
                    s.depth = 0;
                } else if intersect {
                    s.depth += 1;
                }
                s.phase = format!("sample {}/{spp}, bounce {}", s.sample, s.depth);
            }
            Plan::Distribution { per_hit } => {
                if c.camera && intersect && !s.seen_camera {
                    s.seen_camera = true;
                    s.total = c.rays + c.hits * per_hit;
                    s.phase = "primary".into();
                } else if intersect {
                    s.phase = if s.seen_shadow {
                        "bounce"
                    } else {
                        "reflection"
                    }
                    .into();
                } else {
                    s.phase = if s.phase == "bounce" || s.phase == "bounce shadow" {
                        "bounce shadow"
                    } else {
                        s.seen_shadow = true;
                        "shadow"
                    }
                    .into();
                }
            }
            Plan::Radiosity { subset, spp } => {
                if c.camera && intersect {
                    if !s.seen_camera {
                        // The photons so far, and every sample like the first.
                        s.seen_camera = true;
                        s.total = s.rays - c.rays + spp as u64 * (c.rays + c.hits * subset);
                    }
                    s.sample += 1;
                    s.phase = format!("sample {}/{spp}, camera", s.sample);
                } else if intersect {
                    s.phase = "photons".into();
                } else {
                    s.phase = format!("sample {}/{spp}, shadow", s.sample);
                }
            }
        }
        let secs = self.start.elapsed().as_secs_f64();
        if self.pb.is_hidden() && !quiet() && secs > 1.0 {
            self.pb
                .set_draw_target(indicatif::ProgressDrawTarget::stderr());
            self.pb.enable_steady_tick(Duration::from_millis(200));
        }
        self.pb.set_length(s.total.max(s.rays));
        self.pb.set_position(s.rays);
        self.pb.set_message(format!(
            "{} · {:.2} Mrays/s",
            s.phase,
            s.rays as f64 / secs.max(1e-9) / 1e6
        ));
    }

    /// Clears the bar.
    pub fn finish(&self) {
        self.pb.finish_and_clear();
    }
}
