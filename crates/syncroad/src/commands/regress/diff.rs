//! A fresh metrics document against the baseline's: flattened to dotted keys, each number
//! within its tolerance, stamps compared apart, the result rendered for the terminal.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use serde_json::Value;
use syncroad_control::record::STAMPS;

use super::baseline::Baseline;
use crate::error::InputError;

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

/// Every tolerance override names a metric of the baseline (an exact key, or a prefix ending
/// in `*` that some key starts with): a typo would silently leave the metric at the default.
pub fn check_tolerance_keys(path: &Path, b: &Baseline) -> anyhow::Result<()> {
    let keys = flatten(&b.metrics);
    for k in b.tolerances.keys.keys() {
        let known = match k.strip_suffix('*') {
            Some(prefix) => keys.keys().any(|m| m.starts_with(prefix)),
            None => keys.contains_key(k),
        };
        if known {
            continue;
        }
        // A prefix is matched against the metrics' own prefixes (`sync.`, `congestion.`, …).
        let candidates: std::collections::BTreeSet<String> = match k.strip_suffix('*') {
            Some(_) => keys
                .keys()
                .flat_map(|m| m.match_indices('.').map(|(i, _)| format!("{}*", &m[..=i])))
                .collect(),
            None => keys.keys().cloned().collect(),
        };
        let nearest = candidates
            .iter()
            .min_by_key(|m| strsim::levenshtein(k, m))
            .map_or(String::new(), |m| format!("; the nearest is {m}"));
        return Err(InputError::new(format!(
            "baseline {}: tolerances.keys.{k}: no metric of the baseline is {}{nearest} (keys are dotted paths of its metrics, or prefixes ending in *)",
            path.display(),
            if k.ends_with('*') { "under that prefix" } else { "called that" },
        ))
        .into());
    }
    Ok(())
}
