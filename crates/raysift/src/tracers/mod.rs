//! The tracers, one module (file or folder) per technique, and the registry that builds them by
//! name for the CLI, the renderers and the tests.
//!
//! | name | technique | module |
//! |---|---|---|
//! | `naive` | brute force, the ground truth | [`naive`] |
//! | `bvh` | binned-SAH BVH (Wald 2007), pbrt-style traversal: the static baseline | [`bvh`] |
//! | `dacrt` | divide-and-conquer ray tracing (Mora 2011) | [`dacrt`] |

pub mod bvh;
pub mod dacrt;
pub mod naive;

use crate::error::{Error, Result};
use crate::tracer::Tracer;
use serde::de::DeserializeOwned;

/// Names of all registered tracers, in the order the CLI lists them.
pub const NAMES: &[&str] = &["naive", "bvh", "dacrt"];

/// Builds the tracer `name` with options `key=value` (each tracer documents its keys in its
/// `Config`; unknown keys are an error).
pub fn create(name: &str, opts: &[(String, String)]) -> Result<Box<dyn Tracer>> {
    match name {
        "naive" => {
            no_options(name, opts)?;
            Ok(Box::new(naive::Naive::new()))
        }
        "bvh" => Ok(Box::new(bvh::BvhTracer::new(config_from_opts(
            name, opts,
        )?)?)),
        "dacrt" => Ok(Box::new(dacrt::Dacrt::new(config_from_opts(name, opts)?))),
        _ => Err(Error::Invalid(format!(
            "unknown tracer {name:?}; available: {}",
            NAMES.join(", ")
        ))),
    }
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
/// taken as such, others as strings.
pub fn config_from_opts<C: DeserializeOwned>(tracer: &str, opts: &[(String, String)]) -> Result<C> {
    let mut obj = serde_json::Map::new();
    for (k, v) in opts {
        let val = serde_json::from_str(v).unwrap_or_else(|_| serde_json::Value::String(v.clone()));
        obj.insert(k.clone(), val);
    }
    serde_json::from_value(serde_json::Value::Object(obj))
        .map_err(|e| Error::Invalid(format!("tracer {tracer}: bad option: {e}")))
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
