//! `raysift`: the command line over the raysift library: scene info, ray generation, batch tracing
//! with any tracer, rendering, animation, export, and the list of tracers.
//!
//! One module per command (`info`, `rays`, `trace`, `render`, `animate`, `export`, `tracers`,
//! `soak`),
//! plus what they share: arguments (`args`), thread pools and pinning (`pool`), progress display
//! (`progress`) and the typed `--json` reports (`report`).
//!
//! Every error is one line on stderr naming the file and place (or clap's whole usage message for
//! a usage error), with exit code 2; output files are written atomically, so a failed command
//! leaves none behind.

mod animate;
mod args;
mod cones;
mod export;
mod image_out;
mod info;
mod pool;
mod progress;
mod rays;
mod record;
mod render;
mod report;
mod scenefile;
mod soak;
mod trace;
mod tracers;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "raysift", version, about = "Batch ray/triangle intersection for dynamic scenes", long_about = None)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Print triangles, vertices, bounds, meshes and bytes of a scene.
    Info(info::InfoArgs),
    /// Generate rays and write them as rays.npy (float32, N×8).
    #[command(subcommand)]
    Rays(rays::RaysCmd),
    /// Trace a rays file with one tracer and write hits.npy (or occlusion flags).
    Trace(trace::TraceArgs),
    /// Render an image (the embedded bunny when no scene is given).
    Render(render::RenderArgs),
    /// Render a sequence whose geometry changes every frame, re-preparing the tracer each frame.
    Animate(animate::AnimateArgs),
    /// Write the world-space triangles as a float32 (T, 9) .npy file [v0 v1 v2], in primitive-id order.
    Export(export::ExportArgs),
    /// List the available tracers (--verbose: options, presets and counters; --json: all of it).
    Tracers(tracers::TracersArgs),
    /// Adversarial scenes and rays, every tracer and preset against naive; reproductions of any
    /// disagreement are written to files.
    Soak(soak::SoakArgs),
    /// Cone tracing: the n nearest triangles per cone (one per pixel, or from cones.npy).
    Cones(cones::ConesArgs),
}

fn main() {
    let argv: Vec<String> = std::env::args().collect();
    if let Some(tracer) = tracers::opt_help_requested(&argv) {
        if let Err(e) = tracers::print_opt_help(&tracer) {
            eprintln!("raysift: error: {e:#}");
            std::process::exit(2);
        }
        return;
    }
    // Usage errors are clap's whole message (what is missing or wrong, the allowed values, the
    // usage line), exit code 2; no arguments at all print the help, also with code 2.
    let matches = <Cli as clap::CommandFactory>::command().get_matches();
    let cli =
        <Cli as clap::FromArgMatches>::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // Which `render` arguments were typed (a scene file's settings yield to them).
    let given = matches
        .subcommand_matches("render")
        .map(render::given_ids)
        .unwrap_or_default();
    if let Err(e) = run(cli, &given) {
        eprintln!("raysift: error: {e:#}");
        std::process::exit(2);
    }
}

fn run(cli: Cli, given: &[String]) -> Result<()> {
    match cli.cmd {
        Cmd::Info(a) => info::run(&a),
        Cmd::Rays(r) => rays::run(r),
        Cmd::Trace(t) => pool::with_threads(&t.tracer, || trace::run(&t)),
        Cmd::Render(r) => pool::with_threads(&r.tracer, || render::run(&r, given)),
        Cmd::Animate(a) => pool::with_threads(&a.tracer, || animate::run(&a)),
        Cmd::Export(a) => export::run(&a),
        Cmd::Tracers(a) => tracers::run(&a),
        Cmd::Soak(a) => soak::run(&a),
        Cmd::Cones(a) => cones::run(&a),
    }
}
