//! Values given once for every vehicle or once per vehicle.

use serde::{Deserialize, Serialize};

use super::{invalid, ScenarioError};

/// A value given once for all vehicles or once per vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerVehicle {
    /// The same value for every vehicle.
    Uniform(f64),
    /// One value per vehicle.
    List(Vec<f64>),
}

impl PerVehicle {
    /// The common value when every vehicle has the same one (ignoring the first `skip`
    /// entries of a list, e.g. the unused gain of a chain's head).
    pub fn uniform_value(&self, skip: usize) -> Option<f64> {
        match self {
            PerVehicle::Uniform(x) => Some(*x),
            PerVehicle::List(v) => {
                let rest = v.get(skip..)?;
                let first = *rest.first()?;
                rest.iter().all(|x| *x == first).then_some(first)
            }
        }
    }

    pub(crate) fn resolve(&self, field: &str, n: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = match self {
            PerVehicle::Uniform(x) => vec![*x; n],
            PerVehicle::List(xs) => {
                if xs.len() != n {
                    return Err(ScenarioError::LengthMismatch {
                        field: field.to_string(),
                        len: xs.len(),
                        vehicles: n,
                    });
                }
                xs.clone()
            }
        };
        for (i, x) in v.iter().enumerate() {
            if !x.is_finite() {
                return Err(invalid(
                    format!("{field}[{i}]"),
                    x,
                    "must be a finite number",
                ));
            }
        }
        Ok(v)
    }

    pub(crate) fn resolve_nonneg(&self, field: &str, n: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = self.resolve(field, n)?;
        for (i, x) in v.iter().enumerate() {
            if *x < 0.0 {
                return Err(invalid(format!("{field}[{i}]"), x, "must be ≥ 0"));
            }
        }
        Ok(v)
    }

    pub(crate) fn resolve_pos(&self, field: &str, n: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = self.resolve(field, n)?;
        for (i, x) in v.iter().enumerate() {
            if *x <= 0.0 {
                return Err(invalid(format!("{field}[{i}]"), x, "must be > 0"));
            }
        }
        Ok(v)
    }
}
