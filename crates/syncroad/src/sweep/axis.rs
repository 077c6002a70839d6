//! Sweep axes: what a user writes (`values`, `linspace`, `logspace` over a field path or a
//! gain/delay scale) and the validated axis, and setting a field path in scenario JSON.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::InputError;

fn bad(m: impl Into<String>) -> InputError {
    InputError::new(m)
}

/// One axis as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisFile {
    /// Scenario field path, or `scale.gain` / `scale.delay`.
    pub field: String,
    /// Explicit values.
    #[serde(default)]
    pub values: Option<Vec<Value>>,
    /// `[first, last, count]`, evenly spaced.
    #[serde(default)]
    pub linspace: Option<(f64, f64, usize)>,
    /// `[first, last, count]`, geometrically spaced.
    #[serde(default)]
    pub logspace: Option<(f64, f64, usize)>,
}

/// What an axis sets.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// A scenario field path.
    Field(Vec<String>),
    /// Every gain times the value.
    GainScale,
    /// Every delay times the value.
    DelayScale,
}

/// A validated axis.
#[derive(Debug, Clone)]
pub struct Axis {
    /// The path as written (the table column).
    pub field: String,
    /// What it sets.
    pub target: Target,
    /// Its values.
    pub values: Vec<Value>,
}

impl Axis {
    /// Numeric values, when every value is a number.
    pub fn numbers(&self) -> Option<Vec<f64>> {
        self.values.iter().map(Value::as_f64).collect()
    }
}

pub(super) fn spaced(
    field: &str,
    kind: &str,
    (a, b, n): (f64, f64, usize),
    geometric: bool,
) -> Result<Vec<Value>, InputError> {
    let here = format!("axes[{field}].{kind} = [{a}, {b}, {n}]");
    if !(a.is_finite() && b.is_finite()) {
        return Err(bad(format!(
            "{here}: first and last must be finite numbers"
        )));
    }
    if !(1..=100_000).contains(&n) {
        return Err(bad(format!("{here}: count must be between 1 and 100000")));
    }
    if geometric && !(a > 0.0 && b > 0.0) {
        return Err(bad(format!(
            "{here}: a logspace needs first > 0 and last > 0"
        )));
    }
    Ok((0..n)
        .map(|k| {
            let t = if n == 1 {
                0.0
            } else {
                k as f64 / (n - 1) as f64
            };
            let x = if geometric {
                if k + 1 == n {
                    b
                } else {
                    a * (b / a).powf(t)
                }
            } else if k + 1 == n {
                b
            } else {
                a + (b - a) * t
            };
            serde_json::json!(x)
        })
        .collect())
}

impl AxisFile {
    pub(super) fn validate(&self) -> Result<Axis, InputError> {
        let f = &self.field;
        let given = [
            self.values.is_some(),
            self.linspace.is_some(),
            self.logspace.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(bad(format!(
                "axes[{f}]: give exactly one of \"values\", \"linspace\" or \"logspace\""
            )));
        }
        let values = if let Some(v) = &self.values {
            if v.is_empty() {
                return Err(bad(format!(
                    "axes[{f}].values is empty: give at least one value"
                )));
            }
            v.clone()
        } else if let Some(l) = self.linspace {
            spaced(f, "linspace", l, false)?
        } else {
            spaced(f, "logspace", self.logspace.expect("one is given"), true)?
        };
        let target = match f.as_str() {
            "scale.gain" => Target::GainScale,
            "scale.delay" => Target::DelayScale,
            _ => {
                let parts: Vec<String> = f.split('.').map(str::to_string).collect();
                if parts.iter().any(String::is_empty) {
                    return Err(bad(format!(
                        "axes[{f}]: not a field path; write it as in the scenario file, e.g. model.graph.gain_pred"
                    )));
                }
                if matches!(parts[0].as_str(), "seed" | "backend") {
                    return Err(bad(format!(
                        "axes[{f}]: set {} with the spec's \"{}\" instead of an axis",
                        parts[0],
                        if parts[0] == "seed" {
                            "seeds"
                        } else {
                            "backend"
                        }
                    )));
                }
                Target::Field(parts)
            }
        };
        if !matches!(target, Target::Field(_)) {
            for v in &values {
                if v.as_f64().is_none_or(|x| !(x.is_finite() && x > 0.0)) {
                    return Err(bad(format!(
                        "axes[{f}]: value {v} is not a number > 0 (scales multiply every gain or delay)"
                    )));
                }
            }
        }
        Ok(Axis {
            field: f.clone(),
            target,
            values,
        })
    }
}

/// Sets `path` in `doc` to `value`, creating objects along the way.
pub(super) fn set_path(
    doc: &mut Value,
    path: &[String],
    value: Value,
    field: &str,
) -> Result<(), InputError> {
    let mut cur = doc;
    for (k, key) in path.iter().enumerate() {
        let last = k + 1 == path.len();
        cur = match cur {
            Value::Object(map) => {
                if last {
                    map.insert(key.clone(), value);
                    return Ok(());
                }
                map.entry(key.clone())
                    .or_insert_with(|| Value::Object(Default::default()))
            }
            Value::Array(items) => {
                let i: usize = key.parse().map_err(|_| {
                    bad(format!(
                        "axes[{field}]: {key:?} indexes a list; use a vehicle number"
                    ))
                })?;
                let len = items.len();
                let slot = items.get_mut(i).ok_or_else(|| {
                    bad(format!(
                        "axes[{field}]: index {i} is past the end of a list of {len}"
                    ))
                })?;
                if last {
                    *slot = value;
                    return Ok(());
                }
                slot
            }
            other => {
                return Err(bad(format!(
                    "axes[{field}]: {} holds {other}, which has no field {key:?}",
                    path[..k].join(".")
                )))
            }
        };
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logspace_is_geometric_with_exact_ends() {
        let v = spaced("x", "logspace", (0.1, 10.0, 3), true).unwrap();
        assert_eq!(v[0].as_f64(), Some(0.1));
        assert!((v[1].as_f64().unwrap() - 1.0).abs() < 1e-15);
        assert_eq!(v[2].as_f64(), Some(10.0));
    }
}
