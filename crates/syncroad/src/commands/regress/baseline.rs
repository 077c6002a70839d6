//! The baseline file: what to re-run (a native run, one SUMO run or a comparison), the
//! tolerances per metric, and the reference metrics with their stamps; read and written
//! atomically.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::InputError;
use crate::output::write_json;

/// Absolute and relative tolerance of one metric.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerance {
    /// Absolute tolerance.
    #[serde(default)]
    pub abs: f64,
    /// Relative tolerance (fraction of the baseline value).
    #[serde(default)]
    pub rel: f64,
}

/// Tolerances: a default and per-key overrides (exact keys or prefixes ending in `.`/`*`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerances {
    /// Used for keys without an override.
    pub default: Tolerance,
    /// Overrides; a key ending in `*` applies to every key with that prefix.
    #[serde(default)]
    pub keys: BTreeMap<String, Tolerance>,
}

impl Tolerances {
    pub(super) fn for_key(&self, key: &str) -> Tolerance {
        if let Some(t) = self.keys.get(key) {
            return *t;
        }
        self.keys
            .iter()
            .filter_map(|(k, t)| {
                k.strip_suffix('*')
                    .filter(|p| key.starts_with(p))
                    .map(|p| (p.len(), *t))
            })
            .max_by_key(|(len, _)| *len)
            .map_or(self.default, |(_, t)| t)
    }
}

/// What a baseline re-runs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// The native simulator (`syncroad simulate`); the default, so older baselines stay valid.
    #[default]
    Native,
    /// One SUMO run of the scenario's law: `syncroad compare --baselines protocol`.
    Sumo,
    /// `syncroad compare` with the baseline's `runs` and `mixed`.
    Compare,
}

fn is_native(k: &Kind) -> bool {
    *k == Kind::Native
}

/// The baseline file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Baseline {
    /// What this baseline guards.
    #[serde(default)]
    pub about: Option<String>,
    /// What to re-run.
    #[serde(default, skip_serializing_if = "is_native")]
    pub kind: Kind,
    /// For `compare`: the runs, as `--baselines` takes them (default: the command's default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub runs: Option<String>,
    /// For `compare`: mixed-traffic counts, as `--mixed` takes them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mixed: Option<String>,
    /// For `compare`: the human driver of the mixed runs, as `--mixed-driver` takes it
    /// (default: the command's default, `human`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mixed_driver: Option<String>,
    /// Scenario file, relative to the baseline's folder.
    pub scenario: String,
    /// Tolerances.
    pub tolerances: Tolerances,
    /// Versions and platform of the reference run.
    #[serde(default)]
    pub stamp: BTreeMap<String, Value>,
    /// The reference metrics.
    pub metrics: Value,
}

/// Reads a baseline file.
pub fn load(path: &Path) -> anyhow::Result<Baseline> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::caused(format!("cannot read baseline {}", path.display()), e))?;
    let b: Baseline = serde_json::from_str(&text)
        .map_err(|e| InputError::caused(format!("baseline {}", path.display()), e))?;
    for (k, t) in std::iter::once(("default".to_string(), b.tolerances.default))
        .chain(b.tolerances.keys.clone())
    {
        if !(t.abs.is_finite() && t.abs >= 0.0 && t.rel.is_finite() && t.rel >= 0.0) {
            return Err(InputError::new(format!(
                "baseline {}: tolerances.{k} = {{abs: {}, rel: {}}}: both must be finite and ≥ 0",
                path.display(),
                t.abs,
                t.rel
            ))
            .into());
        }
    }
    Ok(b)
}

/// Writes a baseline file (pretty JSON, trailing newline), atomically: an interrupted or
/// failed write leaves the old baseline whole.
pub fn save(path: &Path, b: &Baseline) -> anyhow::Result<()> {
    write_json(path, &serde_json::to_value(b)?)
}
