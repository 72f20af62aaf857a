//! The tracers, one module (file or folder) per technique, and the registry ([`REGISTRY`]) that
//! names them: the CLI (`raysift tracers`, `--tracer`), the renderers, the benchmark harness and
//! the conformance suite all read this one table, so a technique joins everything by adding its
//! entry here.
//!
//! | name | technique | module |
//! |---|---|---|
//! | `naive` | brute force, the ground truth | [`naive`] |
//! | `bvh` | binned-SAH BVH (Wald 2007), pbrt-style traversal: the static baseline | [`bvh`] |
//! | `dacrt` | divide-and-conquer ray tracing (Mora 2011) | [`dacrt`] |
//! | `dacrt5d` | divide-and-conquer over 5D ray hierarchies (Hoedt; Arvo & Kirk 1987) | [`dacrt5d`] |
//! | `kdtree` | SAH kd-tree (Wald & Havran 2006), single-ray stack walk | [`kdtree`] |
//! | `rtrps` | bounding spheres and ray-planes (Suzuki 2010) | [`rtrps`] |

pub mod bvh;
pub mod cone;
pub mod dacrt;
pub mod dacrt5d;
pub mod kdtree;
pub mod naive;
pub mod rtrps;
pub mod rtt;

use crate::error::{Error, Result};
use crate::tracer::{CounterDocs, Tracer};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// One option of a tracer's `Config`: its key and a one-line meaning (the default comes from
/// the `Config`'s `Default`, see [`Entry::options`]).
#[derive(Clone, Copy, Debug)]
pub struct OptionDoc {
    /// The `--opt` key.
    pub key: &'static str,
    /// What it does (the `Config` field's doc has the details and measurements' links).
    pub doc: &'static str,
}

/// A named set of options the conformance suite checks against `naive` (every case, closest
/// hit and occlusion), so a tracer's modes are proven without test code of their own.
#[derive(Clone, Copy, Debug)]
pub struct Preset {
    /// Short name, printed on failure.
    pub name: &'static str,
    /// `key=value` options.
    pub opts: &'static [(&'static str, &'static str)],
}

/// Builds a tracer from `key=value` options.
type Constructor = fn(&[(String, String)]) -> Result<Box<dyn Tracer>>;

/// A registered tracer.
pub struct Entry {
    /// The registry name (`--tracer`).
    pub name: &'static str,
    /// The paper it implements (or "ground truth" / "baseline").
    pub paper: &'static str,
    /// One line: what it does.
    pub summary: &'static str,
    /// Builds it with `key=value` options (unknown keys are an error).
    create: Constructor,
    /// The defaults of its options as JSON (`Config::default()` serialised; empty for none).
    defaults: fn() -> serde_json::Map<String, serde_json::Value>,
    /// The meaning of each option, one per key of `defaults`.
    option_docs: &'static [OptionDoc],
    /// Configurations the conformance suite checks (the defaults are always checked too).
    pub presets: &'static [Preset],
    /// Counters a prepare reports in `Stats::built`: `(name, meaning)`.
    pub built_counters: CounterDocs,
    /// Counters a trace reports in `Stats::work`: `(name, meaning)`.
    pub work_counters: CounterDocs,
}

/// An option with its default and meaning, as `raysift tracers --verbose` lists them.
#[derive(Clone, Debug, Serialize)]
pub struct OptionInfo {
    /// The key.
    pub key: &'static str,
    /// The default, as JSON.
    pub default: serde_json::Value,
    /// What it does.
    pub doc: &'static str,
}

impl Entry {
    /// Builds this tracer with `key=value` options.
    pub fn create(&self, opts: &[(String, String)]) -> Result<Box<dyn Tracer>> {
        (self.create)(opts)
    }

    /// Every option with its default and meaning, in the `Config`'s field order.
    pub fn options(&self) -> Vec<OptionInfo> {
        let defaults = (self.defaults)();
        defaults
            .into_iter()
            .map(|(k, default)| {
                let doc = self.option_docs.iter().find(|d| d.key == k);
                OptionInfo {
                    key: doc.map_or("?", |d| d.key),
                    default,
                    doc: doc.map_or("(undocumented)", |d| d.doc),
                }
            })
            .collect()
    }

    /// Option keys that have a default but no doc, or a doc but no such option (the registry
    /// test demands none).
    pub fn undocumented_options(&self) -> Vec<String> {
        let defaults = (self.defaults)();
        let mut bad: Vec<String> = defaults
            .keys()
            .filter(|k| !self.option_docs.iter().any(|d| d.key == k.as_str()))
            .map(|k| format!("{}: option {k} has no doc", self.name))
            .collect();
        bad.extend(
            self.option_docs
                .iter()
                .filter(|d| !defaults.contains_key(d.key))
                .map(|d| format!("{}: doc for unknown option {}", self.name, d.key)),
        );
        bad
    }
}

fn defaults_of<C: Default + Serialize>() -> serde_json::Map<String, serde_json::Value> {
    match serde_json::to_value(C::default()) {
        Ok(serde_json::Value::Object(m)) => m,
        _ => serde_json::Map::new(),
    }
}

/// Every registered tracer, in the order the CLI lists them.
pub static REGISTRY: &[Entry] = &[
    Entry {
        name: "naive",
        paper: "ground truth",
        summary: "every ray against every triangle (threaded); the answer every tracer must equal",
        create: |opts| {
            no_options("naive", opts)?;
            Ok(Box::new(naive::Naive::new()))
        },
        defaults: serde_json::Map::new,
        option_docs: &[],
        presets: &[],
        built_counters: &[],
        work_counters: naive::COUNTERS,
    },
    Entry {
        name: "bvh",
        paper: "baseline: binned SAH BVH (Wald 2007), pbrt-v4 traversal",
        summary: "static binned-SAH bounding volume hierarchy, rebuilt (or refitted) each frame",
        create: |opts| Ok(Box::new(bvh::BvhTracer::new(config_from_opts("bvh", opts)?)?)),
        defaults: defaults_of::<bvh::Config>,
        option_docs: bvh::OPTION_DOCS,
        presets: bvh::PRESETS,
        built_counters: bvh::COUNTERS.0,
        work_counters: bvh::COUNTERS.1,
    },
    Entry {
        name: "dacrt",
        paper: "Mora 2011, Naive ray-tracing: a divide-and-conquer approach",
        summary: "divide-and-conquer ray tracing: no stored tree, rays and triangles filtered in place each call",
        create: |opts| Ok(Box::new(dacrt::Dacrt::new(config_from_opts("dacrt", opts)?))),
        defaults: defaults_of::<dacrt::Config>,
        option_docs: dacrt::OPTION_DOCS,
        presets: dacrt::PRESETS,
        built_counters: dacrt::COUNTERS.0,
        work_counters: dacrt::COUNTERS.1,
    },
    Entry {
        name: "dacrt5d",
        paper: "Hoedt, DACRT over 5D ray hierarchies (after Arvo & Kirk 1987, ray classification)",
        summary: "divide-and-conquer over ray space: 5D ray bundles split in place, triangles culled by each bundle's frustum or cone",
        create: |opts| Ok(Box::new(dacrt5d::Dacrt5d::new(config_from_opts("dacrt5d", opts)?))),
        defaults: defaults_of::<dacrt5d::Config>,
        option_docs: dacrt5d::OPTION_DOCS,
        presets: dacrt5d::PRESETS,
        built_counters: dacrt5d::COUNTERS.0,
        work_counters: dacrt5d::COUNTERS.1,
    },
    Entry {
        name: "kdtree",
        paper: "Wald & Havran 2006, On building fast kd-trees for ray tracing (the shafts paper's baseline)",
        summary: "event-sorted SAH kd-tree with empty-space cutting, rebuilt each frame; single-ray stack walk",
        create: |opts| Ok(Box::new(kdtree::KdTracer::new(config_from_opts("kdtree", opts)?)?)),
        defaults: defaults_of::<kdtree::Config>,
        option_docs: kdtree::OPTION_DOCS,
        presets: kdtree::PRESETS,
        built_counters: kdtree::COUNTERS.0,
        work_counters: kdtree::COUNTERS.1,
    },
    Entry {
        name: "rtrps",
        paper: "Suzuki et al. 2010, A fast ray-tracing using bounding spheres and frustum rays for dynamic scene rendering (RTRPS)",
        summary: "bounding-sphere hierarchy updated per part, N×N ray groups tested as row and column ray-planes; other rays alone",
        create: |opts| Ok(Box::new(rtrps::Rtrps::new(config_from_opts("rtrps", opts)?)?)),
        defaults: defaults_of::<rtrps::Config>,
        option_docs: rtrps::OPTION_DOCS,
        presets: rtrps::PRESETS,
        built_counters: rtrps::COUNTERS.0,
        work_counters: rtrps::COUNTERS.1,
    },
    Entry {
        name: "rtt",
        paper: "relevant-triangle tracing with shafts (4×4 tiles over an SAH kd-tree; ../shared/papers/relevant-triangles-tracing-shafts.md)",
        summary: "SAH kd-tree; each 4×4 tile's corner rays cap a shaft whose relevant-triangle list answers the other rays, proven ray by ray",
        create: |opts| Ok(Box::new(rtt::Rtt::new(config_from_opts("rtt", opts)?)?)),
        defaults: defaults_of::<rtt::Config>,
        option_docs: rtt::OPTION_DOCS,
        presets: rtt::PRESETS,
        built_counters: rtt::COUNTERS.0,
        work_counters: rtt::COUNTERS.1,
    },
];

/// Names of all registered tracers, in the order the CLI lists them.
pub fn names() -> Vec<&'static str> {
    REGISTRY.iter().map(|e| e.name).collect()
}

/// The registry entry `name`.
pub fn entry(name: &str) -> Result<&'static Entry> {
    REGISTRY.iter().find(|e| e.name == name).ok_or_else(|| {
        Error::Invalid(format!(
            "unknown tracer {name:?}; available: {}",
            names().join(", ")
        ))
    })
}

/// Builds the tracer `name` with options `key=value` (each tracer documents its keys in its
/// `Config`; unknown keys are an error).
pub fn create(name: &str, opts: &[(String, String)]) -> Result<Box<dyn Tracer>> {
    entry(name)?.create(opts)
}

fn no_options(name: &str, opts: &[(String, String)]) -> Result<()> {
    match opts.first() {
        Some((k, _)) => Err(Error::Invalid(format!(
            "tracer {name} takes no options (got {k:?})"
        ))),
        None => Ok(()),
    }
}

/// Parses `key=value` options into a tracer's `Config` (a serde struct with
/// `#[serde(default, deny_unknown_fields)]`): values that parse as JSON (numbers, booleans) are
/// taken as such, others as strings. An unknown key's error lists the valid ones.
pub fn config_from_opts<C: DeserializeOwned + Default + Serialize>(
    tracer: &str,
    opts: &[(String, String)],
) -> Result<C> {
    let mut obj = serde_json::Map::new();
    for (k, v) in opts {
        let val = serde_json::from_str(v).unwrap_or_else(|_| serde_json::Value::String(v.clone()));
        obj.insert(k.clone(), val);
    }
    serde_json::from_value(serde_json::Value::Object(obj)).map_err(|e| {
        let keys: Vec<String> = defaults_of::<C>().keys().cloned().collect();
        Error::Invalid(format!(
            "tracer {tracer}: bad option: {e} (options: {}; `raysift tracers --verbose` lists their defaults and meanings)",
            keys.join(", ")
        ))
    })
}

/// Splits `key=value` strings.
pub fn parse_opts(raw: &[String]) -> Result<Vec<(String, String)>> {
    raw.iter()
        .map(|s| {
            s.split_once('=')
                .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
                .ok_or_else(|| Error::Invalid(format!("tracer option {s:?}: expected key=value")))
        })
        .collect()
}

/// `key=value` pairs of a preset, owned (for [`create`]).
pub fn preset_opts(p: &Preset) -> Vec<(String, String)> {
    p.opts
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_option_is_documented_and_every_preset_builds() {
        for e in REGISTRY {
            assert!(
                e.undocumented_options().is_empty(),
                "{:?}",
                e.undocumented_options()
            );
            assert!(!e.paper.is_empty() && !e.summary.is_empty());
            e.create(&[]).unwrap();
            for p in e.presets {
                e.create(&preset_opts(p))
                    .unwrap_or_else(|err| panic!("{} preset {}: {err}", e.name, p.name));
            }
            assert!(!e.work_counters.is_empty(), "{} names no counters", e.name);
            assert_eq!(create(e.name, &[]).unwrap().name(), e.name);
        }
        assert_eq!(names()[0], "naive");
    }

    #[test]
    fn unknown_names_and_options_say_what_is_allowed() {
        let e = create("nope", &[]).err().unwrap().to_string();
        assert!(e.contains("nope") && e.contains("dacrt"), "{e}");
        let e = create("bvh", &[("bins_".into(), "3".into())])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("bins_") && e.contains("max_leaf"), "{e}");
    }
}
