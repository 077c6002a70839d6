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

use std::path::Path;

use anyhow::Context;
use serde_json::Value;
use syncroad_control::EvalOptions;

use crate::config::load_scenario;
use crate::error::{InputError, Status};
use crate::output::write_text;
use crate::pipeline::{self, Finished};
use crate::stdout::{out, outln};

pub(crate) mod baseline;
mod diff;
mod reports;
pub use baseline::{load, save, Baseline, Kind};
pub use diff::{compare, incomplete_runs, render, split_stamps, Comparison, Failure};
pub use reports::{junit, markdown, Reports};

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
            syncroad_control::PROTOCOL,
            pipeline::native(&sc, every).context("nothing was run")?,
            EvalOptions::of(&sc),
        );
        return Ok(f.record.to_json());
    }
    let runs = match base.kind {
        Kind::Sumo => Some(syncroad_control::PROTOCOL.to_string()),
        _ => base.runs.clone(),
    };
    // A folder of our own (made here, removed when dropped, whatever the run's end): the
    // comparison writes into a new subfolder of it.
    let tmp = tempfile::Builder::new()
        .prefix("syncroad-regress-")
        .tempdir()
        .context("a temporary folder for the baseline's comparison")?;
    let out = tmp.path().join(sc.name());
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
    drop(tmp);
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
    diff::check_tolerance_keys(baseline_path, &base)?;
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
        crate::stdout::errln!(
            "regress {}: interrupted; the baseline was neither compared nor updated",
            baseline_path.display()
        );
        return Ok(Status::Interrupted);
    }
    if update {
        record(&mut base, fresh, baseline_path, "updating")?;
        outln!("updated {}", baseline_path.display());
        return Ok(Status::Success);
    }
    let (stamps, results) = split_stamps(fresh);
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
        crate::stdout::errln!(
            "regress {}: the baseline was recorded on another version or platform, and --strict is given",
            baseline_path.display()
        );
    }
    Ok(Status::verdict(c.failures.is_empty() && stamps_ok))
}

/// Records `fresh` as the baseline's metrics and stamps and writes it (atomically); refused
/// when a run did not complete, since a baseline is a reference.
fn record(
    base: &mut Baseline,
    fresh: Value,
    baseline_path: &Path,
    doing: &str,
) -> anyhow::Result<()> {
    let (stamps, results) = split_stamps(fresh);
    let incomplete = incomplete_runs(&results);
    if !incomplete.is_empty() {
        anyhow::bail!(
            "not {doing} {}: a baseline is recorded only from complete runs, and {} did not complete",
            baseline_path.display(),
            incomplete.join("; ")
        );
    }
    base.metrics = results;
    base.stamp = stamps;
    save(baseline_path, base)
}

/// `syncroad regress BASELINE --init SCENARIO`: a new baseline for the user's own scenario,
/// recorded from a fresh run as `--update` records one: `kind` as asked (default: a native
/// run for a native scenario, one SUMO run of its law for a SUMO scenario), the scenario named
/// relative to the baseline's folder (so the two travel together), the tolerances of the
/// committed baselines (last-bit differences only; widen them per metric under
/// `tolerances.keys`). An existing file at BASELINE is never replaced.
pub fn init(baseline_path: &Path, scenario: &Path, kind: Option<Kind>) -> anyhow::Result<Status> {
    if std::fs::symlink_metadata(baseline_path).is_ok() {
        return Err(InputError::new(format!(
            "--init: {} exists; --init writes a new baseline and never replaces a file (`syncroad regress {} --update` re-records a baseline)",
            baseline_path.display(),
            baseline_path.display()
        ))
        .into());
    }
    crate::output::check_file_target("BASELINE", baseline_path)?;
    let sc = load_scenario(scenario)?;
    let kind = kind.unwrap_or(match sc.backend() {
        syncroad_control::scenario::Backend::Native => Kind::Native,
        syncroad_control::scenario::Backend::Sumo => Kind::Sumo,
    });
    let folder = baseline_path.parent().filter(|p| !p.as_os_str().is_empty());
    let relative = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let from = relative(folder.unwrap_or(Path::new(".")));
    let named =
        pathdiff::diff_paths(relative(scenario), &from).unwrap_or_else(|| relative(scenario));
    let mut base = Baseline {
        about: Some(format!(
            "{} of {}, made by `syncroad regress --init`: same scenario and seed give the same metrics, so the tolerances only absorb last-bit differences between builds; widen a metric's under tolerances.keys",
            match kind {
                Kind::Native => "A native run",
                Kind::Sumo => "One SUMO run of the scenario's law",
                Kind::Compare => "syncroad compare",
            },
            scenario.display()
        )),
        kind,
        runs: None,
        mixed: None,
        mixed_driver: None,
        scenario: named.display().to_string(),
        tolerances: baseline::Tolerances {
            default: baseline::Tolerance {
                abs: 1e-9,
                rel: 1e-6,
            },
            keys: Default::default(),
        },
        stamp: Default::default(),
        metrics: Value::Null,
    };
    let fresh = fresh_metrics(&base, baseline_path)?;
    if syncroad_sumo::interrupt_signal().is_some() {
        return Ok(Status::Interrupted);
    }
    record(&mut base, fresh, baseline_path, "writing")?;
    outln!(
        "wrote {} ({:?} baseline of {}); `syncroad regress {}` checks a fresh run against it",
        baseline_path.display(),
        kind,
        base.scenario,
        baseline_path.display()
    );
    Ok(Status::Success)
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

#[cfg(test)]
mod tests {
    use super::baseline::{Tolerance, Tolerances};
    use super::diff::flatten;
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
