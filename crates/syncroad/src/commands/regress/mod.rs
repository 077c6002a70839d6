//! `syncroad regress`: compare a fresh run's metrics with a committed baseline.
//!
//! A baseline file names its scenario (relative to the baseline's folder), carries per-metric
//! tolerances and the metrics of a reference run:
//!
//! ```json
//! {
//!   "scenario": "../../scenarios/ring-theorem1.json",
//!   "tolerances": {"default": {"abs": 1e-9, "rel": 1e-6},
//!                  "keys": {"sync.spread_l2": {"abs": 0, "rel": 1e-3}}},
//!   "stamp": {"syncroad_version": "0.1.0", "platform": "x86_64-linux"},
//!   "metrics": { ...metrics.json of the reference run... }
//! }
//! ```
//!
//! Metrics are flattened to dotted keys (`sync.final_spread_mps`, `runs[1].congestion.…`).
//! A number passes when `|fresh − base| ≤ abs + rel·|base|`; strings, booleans and nulls must
//! be equal; a key missing on either side fails, and so does NaN (written as `null` in JSON)
//! where the baseline has a number. Stamps (versions, platform) are compared and a mismatch is
//! reported, but does not fail the check by itself.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use syncroad_control::record::STAMPS;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::config::load_scenario;
use crate::error::{InputError, Status};
use crate::output::{write_json, write_text};
use crate::pipeline::{self, Finished};
use crate::stdout::{out, outln};
use syncroad_control::EvalOptions;

mod reports;
pub use reports::{junit, markdown, Reports};

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
    fn for_key(&self, key: &str) -> Tolerance {
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
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
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

/// Splits a metrics document into (stamps, results).
pub fn split_stamps(mut doc: Value) -> (BTreeMap<String, Value>, Value) {
    let mut stamps = BTreeMap::new();
    if let Value::Object(map) = &mut doc {
        for k in STAMPS {
            if let Some(v) = map.remove(k) {
                stamps.insert(k.to_string(), v);
            }
        }
    }
    (stamps, doc)
}

/// Flattens a JSON value into dotted keys.
pub fn flatten(v: &Value) -> BTreeMap<String, Value> {
    fn go(prefix: &str, v: &Value, out: &mut BTreeMap<String, Value>) {
        match v {
            Value::Object(m) => {
                for (k, x) in m {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    go(&key, x, out);
                }
            }
            Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    go(&format!("{prefix}[{i}]"), x, out);
                }
            }
            leaf => {
                out.insert(prefix.to_string(), leaf.clone());
            }
        }
    }
    let mut out = BTreeMap::new();
    go("", v, &mut out);
    out
}

/// One failed comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    /// Dotted key.
    pub key: String,
    /// Baseline value (or "missing").
    pub base: String,
    /// Fresh value (or "missing").
    pub fresh: String,
    /// Why it failed.
    pub why: String,
}

/// Outcome of a comparison.
#[derive(Debug, Clone, Default)]
pub struct Comparison {
    /// Keys compared.
    pub compared: usize,
    /// Every key compared, in order (baseline keys, then extra fresh keys).
    pub keys: Vec<String>,
    /// Failures.
    pub failures: Vec<Failure>,
    /// Stamp mismatches (reported, not failing).
    pub stamp_notes: Vec<String>,
}

/// Compares fresh results against the baseline.
pub fn compare(
    base: &Baseline,
    fresh_stamps: &BTreeMap<String, Value>,
    fresh: &Value,
) -> Comparison {
    let b = flatten(&base.metrics);
    let f = flatten(fresh);
    let mut c = Comparison::default();
    for (k, bv) in &b {
        c.compared += 1;
        c.keys.push(k.clone());
        let Some(fv) = f.get(k) else {
            c.failures.push(Failure {
                key: k.clone(),
                base: bv.to_string(),
                fresh: "missing".into(),
                why: "key missing from the fresh metrics".into(),
            });
            continue;
        };
        let fail = |why: String| Failure {
            key: k.clone(),
            base: bv.to_string(),
            fresh: fv.to_string(),
            why,
        };
        match (bv.as_f64(), fv.as_f64()) {
            (Some(x), Some(y)) => {
                let t = base.tolerances.for_key(k);
                let allowed = t.abs + t.rel * x.abs();
                let d = (y - x).abs();
                if d.is_nan() || d > allowed {
                    let rel = if x != 0.0 {
                        format!(" ({:+.3e} relative)", (y - x) / x.abs())
                    } else {
                        String::new()
                    };
                    c.failures.push(fail(format!(
                        "differs by {:.3e}{rel}; allowed {:.3e}",
                        y - x,
                        allowed
                    )));
                }
            }
            (Some(_), None) if fv.is_null() => c
                .failures
                .push(fail("fresh value is null (NaN or missing number)".into())),
            _ => {
                if bv != fv {
                    c.failures.push(fail("values differ".into()));
                }
            }
        }
    }
    for k in f.keys().filter(|k| !b.contains_key(*k)) {
        c.compared += 1;
        c.keys.push(k.clone());
        c.failures.push(Failure {
            key: k.clone(),
            base: "missing".into(),
            fresh: f[k].to_string(),
            why: "extra key not in the baseline (run with --update to accept it)".into(),
        });
    }
    for (k, v) in &base.stamp {
        match fresh_stamps.get(k) {
            Some(w) if w == v => {}
            Some(w) => c
                .stamp_notes
                .push(format!("{k}: baseline {v}, this run {w}")),
            None => c
                .stamp_notes
                .push(format!("{k}: baseline {v}, this run has none")),
        }
    }
    // A baseline without a stamp says nothing about where it was recorded: --strict fails it.
    for (k, w) in fresh_stamps {
        if !base.stamp.contains_key(k) && !w.is_null() {
            c.stamp_notes
                .push(format!("{k}: the baseline has none, this run {w}"));
        }
    }
    c
}

/// Renders the comparison as a readable diff.
pub fn render(c: &Comparison, baseline: &Path) -> String {
    let mut s = String::new();
    for n in &c.stamp_notes {
        let _ = writeln!(
            s,
            "note: stamp differs — {n} (results may legitimately differ across versions/platforms)"
        );
    }
    if c.failures.is_empty() {
        let _ = writeln!(
            s,
            "regress {}: PASS ({} metrics within tolerance)",
            baseline.display(),
            c.compared
        );
    } else {
        let _ = writeln!(
            s,
            "regress {}: FAIL ({} of {} metrics)",
            baseline.display(),
            c.failures.len(),
            c.compared
        );
        let w = c.failures.iter().map(|f| f.key.len()).max().unwrap_or(0);
        for f in &c.failures {
            let _ = writeln!(
                s,
                "  {:<w$}  baseline {:>14}  fresh {:>14}  {}",
                f.key, f.base, f.fresh, f.why
            );
        }
    }
    s
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

/// Re-runs what the baseline names and returns the fresh metrics document: the native run's
/// metrics.json, or compare.json of a SUMO comparison (run in a temporary folder, without
/// plots, removed afterwards).
pub fn fresh_metrics(base: &Baseline, baseline_path: &Path) -> anyhow::Result<Value> {
    let dir = baseline_path.parent().unwrap_or(Path::new("."));
    let scenario = dir.join(&base.scenario);
    let sc = load_scenario(&scenario)?;
    if base.kind == Kind::Native {
        if base.runs.is_some() || base.mixed.is_some() || base.mixed_driver.is_some() {
            return Err(InputError::new(format!(
                "baseline {}: runs/mixed/mixed_driver apply only to \"kind\": \"compare\" (this one is native)",
                baseline_path.display()
            ))
            .into());
        }
        let every = crate::config::default_record_every(sc.steps(), sc.vehicles());
        let f = Finished::new(
            &sc,
            "law",
            pipeline::native(&sc, every),
            EvalOptions::of(&sc),
        );
        return Ok(f.record.to_json());
    }
    let runs = match base.kind {
        Kind::Sumo => Some("protocol".to_string()),
        _ => base.runs.clone(),
    };
    let out = std::env::temp_dir().join(format!(
        "syncroad-regress-{}-{}",
        std::process::id(),
        sc.name()
    ));
    let mut request = crate::comparison::Request::runs(runs, base.mixed.clone());
    if let Some(human) = &base.mixed_driver {
        request.mixed_driver = human.clone();
    }
    let plan = crate::comparison::plan(&sc, &request).map_err(|e| {
        e.context(InputError::new(format!(
            "baseline {}",
            baseline_path.display()
        )))
    })?;
    let flag = syncroad_sumo::interrupt_flag()?;
    let result =
        crate::comparison::compare_into(&sc, &plan, &out, &crate::output::Inputs::none(), flag);
    let _ = std::fs::remove_dir_all(&out);
    Ok(result?.0)
}

/// `syncroad regress`: compare with the baseline, or `--update` it.
pub fn run(
    baseline_path: &Path,
    update: bool,
    metrics: Option<&Path>,
    reports: &Reports,
) -> anyhow::Result<Status> {
    let mut base = load(baseline_path)?;
    check_report_paths(&base, baseline_path, metrics, reports)?;
    let fresh = match metrics {
        Some(m) => {
            let text = std::fs::read_to_string(m).map_err(|e| {
                InputError::caused(format!("cannot read metrics {}", m.display()), e)
            })?;
            serde_json::from_str(&text)
                .map_err(|e| InputError::caused(format!("metrics {}", m.display()), e))?
        }
        None => fresh_metrics(&base, baseline_path)?,
    };
    if syncroad_sumo::interrupt_signal().is_some() {
        eprintln!(
            "regress {}: interrupted; the baseline was neither compared nor updated",
            baseline_path.display()
        );
        return Ok(Status::Interrupted);
    }
    let (stamps, results) = split_stamps(fresh);
    if update {
        let incomplete = incomplete_runs(&results);
        if !incomplete.is_empty() {
            anyhow::bail!(
                "not updating {}: a baseline is recorded only from complete runs, and {} did not complete",
                baseline_path.display(),
                incomplete.join("; ")
            );
        }
        base.metrics = results;
        base.stamp = stamps;
        save(baseline_path, &base)?;
        outln!("updated {}", baseline_path.display());
        return Ok(Status::Success);
    }
    let c = compare(&base, &stamps, &results);
    out!("{}", render(&c, baseline_path));
    if let Some(p) = &reports.junit {
        let text = junit(&c, baseline_path, reports.strict)?;
        write_text(p, &text)?;
    }
    if let Some(p) = &reports.markdown {
        let text = markdown(&c, baseline_path, reports.strict);
        write_text(p, &text)?;
    }
    let stamps_ok = c.stamp_notes.is_empty() || !reports.strict;
    if !stamps_ok {
        eprintln!(
            "regress {}: the baseline was recorded on another version or platform, and --strict is given",
            baseline_path.display()
        );
    }
    Ok(Status::verdict(c.failures.is_empty() && stamps_ok))
}

/// Refuses, before anything runs, a `--junit`/`--markdown` path that would destroy an input
/// (the baseline, its scenario, `--metrics`) or the other report, that is a folder, or whose
/// folder does not exist: a report written after minutes of simulation must not fail then.
fn check_report_paths(
    base: &Baseline,
    baseline_path: &Path,
    metrics: Option<&Path>,
    reports: &Reports,
) -> anyhow::Result<()> {
    let scenario = baseline_path
        .parent()
        .unwrap_or(Path::new("."))
        .join(&base.scenario);
    let mut inputs = crate::output::Inputs::none()
        .with("the baseline", baseline_path)
        .with("the baseline's scenario", &scenario);
    if let Some(m) = metrics {
        inputs = inputs.with("--metrics", m);
    }
    let named = [
        ("--junit", &reports.junit),
        ("--markdown", &reports.markdown),
    ];
    for (flag, path) in named {
        let Some(p) = path else { continue };
        crate::output::refuse_input(flag, p, &inputs)?;
        crate::output::check_file_target(flag, p)?;
    }
    if let (Some(j), Some(m)) = (&reports.junit, &reports.markdown) {
        if j == m || crate::output::same_file(j, m) {
            return Err(InputError::new(format!(
                "--junit and --markdown are the same file ({}); give each report its own path",
                j.display()
            ))
            .into());
        }
    }
    Ok(())
}

/// The runs of a metrics document (one record, or compare's `runs`) that did not reach their
/// horizon, each with its error.
pub fn incomplete_runs(doc: &Value) -> Vec<String> {
    let one = |name: &str, r: &Value| {
        (r.get("complete") != Some(&Value::Bool(true))).then(|| {
            let why = r
                .get("error")
                .and_then(Value::as_str)
                .unwrap_or("no record");
            format!("{name} ({why})")
        })
    };
    match doc.get("runs").and_then(Value::as_object) {
        Some(runs) => runs.iter().filter_map(|(k, r)| one(k, r)).collect(),
        None => one("the run", doc).into_iter().collect(),
    }
}

/// Writes a baseline file (pretty JSON, trailing newline), atomically: an interrupted or
/// failed write leaves the old baseline whole.
pub fn save(path: &Path, b: &Baseline) -> anyhow::Result<()> {
    write_json(path, &serde_json::to_value(b)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn base(metrics: Value) -> Baseline {
        Baseline {
            about: None,
            kind: Kind::Native,
            runs: None,
            mixed: None,
            mixed_driver: None,
            scenario: "x.json".into(),
            tolerances: Tolerances {
                default: Tolerance {
                    abs: 0.0,
                    rel: 1e-3,
                },
                keys: [
                    ("sync.l2".to_string(), Tolerance { abs: 0.5, rel: 0.0 }),
                    ("cong.*".to_string(), Tolerance { abs: 1.0, rel: 0.0 }),
                ]
                .into_iter()
                .collect(),
            },
            stamp: [("platform".to_string(), json!("x86_64-linux"))]
                .into_iter()
                .collect(),
            metrics,
        }
    }

    #[test]
    fn within_tolerance_passes_beyond_fails() {
        let b = base(
            json!({"sync": {"l2": 3.0, "final": 1.0, "verdict": "synchronized"}, "cong": {"mean": 8.0}}),
        );
        let stamps = [("platform".to_string(), json!("x86_64-linux"))]
            .into_iter()
            .collect();
        let ok = compare(
            &b,
            &stamps,
            &json!({"sync": {"l2": 3.4, "final": 1.0009, "verdict": "synchronized"}, "cong": {"mean": 8.9}}),
        );
        assert!(ok.failures.is_empty(), "{:?}", ok.failures);
        assert_eq!(ok.compared, 4);
        let bad = compare(
            &b,
            &stamps,
            &json!({"sync": {"l2": 3.6, "final": 1.0011, "verdict": "not_synchronized"}, "cong": {"mean": 9.1}}),
        );
        let keys: Vec<&str> = bad.failures.iter().map(|f| f.key.as_str()).collect();
        assert_eq!(keys, ["cong.mean", "sync.final", "sync.l2", "sync.verdict"]);
    }

    #[test]
    fn a_baseline_without_a_stamp_is_a_stamp_note_so_strict_fails_it() {
        let mut b = base(json!({"a": 1.0}));
        b.stamp.clear();
        let stamps = [
            ("platform".to_string(), json!("x86_64-linux")),
            ("sumo_version".to_string(), Value::Null),
        ]
        .into_iter()
        .collect();
        let c = compare(&b, &stamps, &json!({"a": 1.0}));
        assert!(c.failures.is_empty());
        assert_eq!(
            c.stamp_notes,
            ["platform: the baseline has none, this run \"x86_64-linux\""]
        );
    }

    #[test]
    fn nan_missing_and_extra_keys_fail_and_stamps_are_reported() {
        let b = base(json!({"a": 1.0, "b": 2.0}));
        let stamps = [("platform".to_string(), json!("aarch64-linux"))]
            .into_iter()
            .collect();
        let c = compare(&b, &stamps, &json!({"a": null, "c": 3.0}));
        let whys: Vec<(&str, &str)> = c
            .failures
            .iter()
            .map(|f| (f.key.as_str(), f.why.as_str()))
            .collect();
        assert_eq!(
            whys,
            [
                ("a", "fresh value is null (NaN or missing number)"),
                ("b", "key missing from the fresh metrics"),
                (
                    "c",
                    "extra key not in the baseline (run with --update to accept it)"
                )
            ]
        );
        assert_eq!(
            c.stamp_notes,
            ["platform: baseline \"x86_64-linux\", this run \"aarch64-linux\""]
        );
        let text = render(&c, Path::new("b.json"));
        assert!(text.contains("FAIL (3 of 3 metrics)"), "{text}");
    }

    #[test]
    fn incomplete_runs_are_named_with_their_error() {
        let doc = json!({"runs": {"a": {"complete": true}, "b": {"complete": false, "error": "interrupted"}}});
        assert_eq!(incomplete_runs(&doc), ["b (interrupted)"]);
        assert!(incomplete_runs(&json!({"complete": true})).is_empty());
        assert_eq!(
            incomplete_runs(&json!({"complete": false})),
            ["the run (no record)"]
        );
    }

    #[test]
    fn flatten_names_nested_and_array_keys() {
        let f = flatten(&json!({"runs": [{"x": 1}, {"x": 2}], "s": {"t": true}}));
        assert_eq!(
            f.keys().collect::<Vec<_>>(),
            ["runs[0].x", "runs[1].x", "s.t"]
        );
    }
}
