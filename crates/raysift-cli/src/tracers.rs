//! `raysift tracers`: the registered tracers (`tracers::REGISTRY`): name, paper and summary;
//! `--verbose` adds every option with its default and meaning, the conformance presets and the
//! counters with their meanings; `--json` prints all of it. `--opt help` on a tracing command
//! prints one tracer's options.

use crate::report::{print_json, CounterDoc, CountersDoc, PresetReport, TracerReport};
use anyhow::Result;
use clap::Args;
use raysift::tracers::{self, Entry};

#[derive(Args)]
pub struct TracersArgs {
    /// Also list every option (default, meaning), preset and counter (meaning).
    #[arg(long, short)]
    verbose: bool,
    /// Print the registry as a JSON list of objects (name, paper, summary, options, presets,
    /// counters).
    #[arg(long)]
    json: bool,
}

pub fn run(a: &TracersArgs) -> Result<()> {
    if a.json {
        let all: Vec<TracerReport> = tracers::REGISTRY.iter().map(report).collect();
        return print_json(&all);
    }
    let w = name_width();
    for (k, e) in tracers::REGISTRY.iter().enumerate() {
        if a.verbose && k > 0 {
            println!();
        }
        println!("{:<w$}  {} — {}", e.name, e.paper, e.summary);
        if a.verbose {
            print_options(e);
            print_presets(e);
            print_counters("built counters (after prepare)", e.built_counters);
            print_counters("work counters (per trace)", e.work_counters);
        }
    }
    Ok(())
}

/// `--opt help`: when a tracing command's arguments ask for it (`--opt help` or `--opt=help`),
/// the tracer they name (`--tracer`, default `bvh`), so its options can be printed before any
/// other argument is checked (a user asking for help has not yet written a full command).
pub fn opt_help_requested(args: &[String]) -> Option<String> {
    if !matches!(
        args.get(1).map(String::as_str),
        Some("trace" | "render" | "animate")
    ) {
        return None;
    }
    let value_of = |flag: &str| {
        let eq = format!("{flag}=");
        args.iter()
            .enumerate()
            .filter_map(|(i, s)| {
                if s == flag {
                    args.get(i + 1).cloned()
                } else {
                    s.strip_prefix(&eq).map(str::to_string)
                }
            })
            .collect::<Vec<_>>()
    };
    if !value_of("--opt").iter().any(|v| v == "help") {
        return None;
    }
    Some(value_of("--tracer").pop().unwrap_or_else(|| "bvh".into()))
}

/// Prints the options of the tracer `name` (for `--opt help`).
pub fn print_opt_help(name: &str) -> Result<()> {
    let e = tracers::entry(name)?;
    println!("{} — {}", e.name, e.summary);
    print_options(e);
    Ok(())
}

fn name_width() -> usize {
    tracers::REGISTRY
        .iter()
        .map(|e| e.name.len())
        .max()
        .unwrap_or(0)
}

/// A default as `--opt` takes it: strings bare, everything else as JSON.
fn bare(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::String(s) => s.clone(),
        v => v.to_string(),
    }
}

fn print_options(e: &Entry) {
    let opts = e.options();
    if opts.is_empty() {
        println!("  options: none");
        return;
    }
    println!("  options (--opt key=value; default, meaning):");
    let kw = opts.iter().map(|o| o.key.len()).max().unwrap_or(0);
    let defaults: Vec<String> = opts.iter().map(|o| bare(&o.default)).collect();
    let dw = defaults.iter().map(String::len).max().unwrap_or(0);
    for (o, d) in opts.iter().zip(&defaults) {
        println!("    {:<kw$}  {d:<dw$}  {}", o.key, o.doc);
    }
}

fn print_presets(e: &Entry) {
    if e.presets.is_empty() {
        return;
    }
    println!("  presets (each checked against naive by the conformance suite):");
    for p in e.presets {
        let opts: Vec<String> = p.opts.iter().map(|(k, v)| format!("{k}={v}")).collect();
        println!("    {}: {}", p.name, opts.join(" "));
    }
}

fn print_counters(title: &str, docs: &[(&str, &str)]) {
    if docs.is_empty() {
        return;
    }
    println!("  {title}:");
    let w = docs.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    for (n, d) in docs {
        println!("    {n:<w$}  {d}");
    }
}

fn report(e: &Entry) -> TracerReport {
    let counters = |docs: &[(&'static str, &'static str)]| {
        docs.iter()
            .map(|&(name, doc)| CounterDoc { name, doc })
            .collect()
    };
    TracerReport {
        name: e.name,
        paper: e.paper,
        summary: e.summary,
        options: e.options(),
        presets: e
            .presets
            .iter()
            .map(|p| PresetReport {
                name: p.name,
                opts: p.opts.iter().copied().collect(),
            })
            .collect(),
        counters: CountersDoc {
            built: counters(e.built_counters),
            work: counters(e.work_counters),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn argv(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_string).collect()
    }

    #[test]
    fn opt_help_is_found_in_any_tracing_command() {
        let f = |s: &str| opt_help_requested(&argv(s));
        assert_eq!(
            f("raysift trace x --tracer dacrt --opt help"),
            Some("dacrt".into())
        );
        assert_eq!(
            f("raysift render --opt=help --tracer=naive"),
            Some("naive".into())
        );
        assert_eq!(f("raysift animate --opt help"), Some("bvh".into()));
        assert_eq!(f("raysift trace x --opt lanes=8"), None);
        assert_eq!(f("raysift info help --opt help"), None);
    }
}
