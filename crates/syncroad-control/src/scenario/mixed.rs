//! Mixed traffic on a ring: a fraction p of the vehicles (the penetration rate) runs the scenario's
//! law (the protocol) or a wave damper, the others are SUMO human drivers. Which vehicles are automated is drawn from
//! the scenario's seed, so a run is reproducible and a sweep over seeds samples placements.
//!
//! ```json
//! "mixed": {"penetration": 0.5, "controller": "protocol", "human": "human", "placement": "seeded"}
//! ```
//! * `penetration` p ∈ \[0, 1\]: `round(p N)` vehicles are automated (halves round up);
//! * `placement`: `seeded` (default: drawn from the scenario's seed) or `even` (spread evenly,
//!   as `compare --mixed` places them), see [`Placement`];
//! * `controller`: `protocol` (the scenario's model, default; `law` is its older spelling), `follower-stopper-U` (desired speed
//!   U in m/s) or `pi-saturation` — the wave dampers of Stern et al. (2018);
//! * `human`: the SUMO driver of the other vehicles (default `human`, the calibrated preset;
//!   any name `compare --baselines` takes). The SUMO backend checks it before SUMO starts.

use serde::{Deserialize, Serialize};

use super::{invalid, ScenarioError};
use crate::drive::placement::{automated_count, Placement};
use crate::drive::sumo_driver::DEFAULT_HUMAN;
use crate::registry::NamedLaw;

/// What drives the automated vehicles of a mixed ring (`mixed.controller`), in the one shape
/// a scenario names a law wherever it goes: `{"law": NAME, "params": {...}}` (a law of the
/// registry, `protocol` the scenario's own) or `{"python": "FILE.py:Class", "params": {...}}`
/// (the user's class). The older shape, a registry name with its shorthand parameter
/// (`"follower-stopper-4.3"`), keeps working.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "serde_json::Value", into = "serde_json::Value")]
pub enum LawChoice {
    /// A registry name with its shorthand (`"protocol"`, `"follower-stopper-4.3"`).
    Name(String),
    /// `{"law": NAME, "params": {...}}`.
    Law {
        /// The registry's name.
        law: String,
        /// Its parameters (a JSON object), added to those the name carries.
        params: Option<serde_json::Value>,
    },
    /// `{"python": "FILE.py:Class", "params": {...}}`.
    Python {
        /// `FILE.py:Class` (relative to the scenario's folder) or `package.module:Class`.
        python: String,
        /// Keyword arguments of the class.
        params: Option<serde_json::Value>,
    },
}

impl TryFrom<serde_json::Value> for LawChoice {
    type Error = String;
    fn try_from(v: serde_json::Value) -> Result<Self, String> {
        let usage = "name the law as {\"law\": NAME, \"params\": {...}} (a law of `syncroad laws`, protocol the scenario's own) or {\"python\": \"FILE.py:Class\", \"params\": {...}}";
        let object = match v {
            serde_json::Value::String(s) => return Ok(LawChoice::Name(s)),
            serde_json::Value::Object(o) => o,
            other => return Err(format!("mixed.controller = {other}: {usage}")),
        };
        if let Some(k) = object
            .keys()
            .find(|k| !matches!(k.as_str(), "law" | "python" | "params"))
        {
            return Err(format!("mixed.controller.{k}: unknown field; {usage}"));
        }
        let text = |k: &str| match object.get(k) {
            None => Ok(None),
            Some(serde_json::Value::String(s)) => Ok(Some(s.clone())),
            Some(other) => Err(format!("mixed.controller.{k} = {other}: must be a string")),
        };
        let params = object.get("params").cloned();
        match (text("law")?, text("python")?) {
            (Some(law), None) => Ok(LawChoice::Law { law, params }),
            (None, Some(python)) => Ok(LawChoice::Python { python, params }),
            _ => Err(format!(
                "mixed.controller = {}: {usage}, one of the two",
                serde_json::Value::Object(object)
            )),
        }
    }
}

impl From<LawChoice> for serde_json::Value {
    fn from(c: LawChoice) -> Self {
        let with = |key: &str, name: String, params: Option<serde_json::Value>| {
            let mut o = serde_json::Map::new();
            o.insert(key.into(), name.into());
            if let Some(p) = params {
                o.insert("params".into(), p);
            }
            serde_json::Value::Object(o)
        };
        match c {
            LawChoice::Name(s) => s.into(),
            LawChoice::Law { law, params } => with("law", law, params),
            LawChoice::Python { python, params } => with("python", python, params),
        }
    }
}

impl std::fmt::Display for LawChoice {
    /// As tables and messages name it: the registry name, or `python:Class`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LawChoice::Name(s) | LawChoice::Law { law: s, .. } => f.write_str(s),
            LawChoice::Python { python, .. } => {
                let class = python.rsplit_once(':').map_or(python.as_str(), |(_, c)| c);
                write!(f, "python:{class}")
            }
        }
    }
}

/// Mixed traffic as written in the scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixedSpec {
    /// Fraction p of automated vehicles, in \[0, 1\].
    pub penetration: f64,
    /// What drives the automated vehicles ([`LawChoice`]): the scenario's law (default), a
    /// wave damper or another law of the registry, or the user's Python class.
    #[serde(default = "default_controller")]
    pub controller: LawChoice,
    /// SUMO driver of the other vehicles.
    #[serde(default = "default_human")]
    pub human: String,
    /// Where the automated vehicles sit.
    #[serde(default)]
    pub placement: Placement,
}

fn default_controller() -> LawChoice {
    LawChoice::Name(crate::registry::PROTOCOL.into())
}

fn default_human() -> String {
    DEFAULT_HUMAN.into()
}

impl MixedSpec {
    /// Checks the penetration rate and the controller name on a road with `n` vehicles.
    pub(crate) fn validate(&self, ring: bool) -> Result<(), ScenarioError> {
        if !ring {
            return Err(invalid(
                "mixed",
                "given",
                "mixed traffic needs a ring road (road.type = \"ring\")",
            ));
        }
        let p = self.penetration;
        if !(p.is_finite() && (0.0..=1.0).contains(&p)) {
            return Err(invalid(
                "mixed.penetration",
                p,
                "must lie in [0, 1] (the fraction of automated vehicles)",
            ));
        }
        self.damper()?;
        Ok(())
    }

    /// The damper of the automated vehicles, `None` for the scenario's law or the user's
    /// Python class ([`MixedSpec::python`]).
    pub fn damper(&self) -> Result<Option<NamedLaw>, ScenarioError> {
        let field = "mixed.controller";
        let (name, params) = match &self.controller {
            LawChoice::Name(s) => (s, None),
            LawChoice::Law { law, params } => (law, params.as_ref()),
            LawChoice::Python { .. } => return Ok(None),
        };
        let to_err = |e: crate::registry::LawNameError| invalid(field, name, e.why());
        let extra = match params {
            None => None,
            Some(p) => Some(p.as_object().ok_or_else(|| {
                invalid(
                    "mixed.controller.params",
                    p,
                    "must be a JSON object of the law's parameters",
                )
            })?),
        };
        let law = NamedLaw::named(field, name, extra).map_err(to_err)?;
        if let (None, Some(p)) = (&law, extra.filter(|o| !o.is_empty())) {
            return Err(invalid(
                "mixed.controller.params",
                serde_json::Value::Object(p.clone()),
                "the scenario's own law takes its parameters from the model; give none",
            ));
        }
        Ok(law)
    }

    /// The user's Python class that drives the automated vehicles, as the scenario's
    /// `controller` block would name it; `None` for a law of the registry.
    pub fn python(&self) -> Option<crate::user_law::ControllerSpec> {
        match &self.controller {
            LawChoice::Python { python, params } => Some(crate::user_law::ControllerSpec {
                python: Some(python.clone()),
                params: params.clone(),
                ..Default::default()
            }),
            _ => None,
        }
    }

    /// The automated vehicles among `n`, ascending: `round(p n)` of them, placed by
    /// [`Placement::automated`] (a seeded placement draws from `seed`).
    pub fn automated(&self, n: usize, seed: u64) -> Vec<usize> {
        self.placement
            .automated(n, automated_count(n, self.penetration), seed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_places_round_p_n_vehicles_its_way() {
        let m = |placement| MixedSpec {
            penetration: 0.2,
            controller: LawChoice::Name("protocol".into()),
            human: DEFAULT_HUMAN.into(),
            placement,
        };
        // round(0.2 · 22) = 4; even: ⌊j 22 / 4⌋.
        assert_eq!(m(Placement::Even).automated(22, 42), [0, 5, 11, 16]);
        let seeded = m(Placement::Seeded).automated(22, 42);
        assert_eq!(seeded.len(), 4);
        assert_ne!(seeded, m(Placement::Seeded).automated(22, 43));
        let json: MixedSpec = serde_json::from_str(r#"{"penetration": 0.5}"#).unwrap();
        assert_eq!(
            (json.placement, json.human.as_str()),
            (Placement::Seeded, "human")
        );
        let bad =
            serde_json::from_str::<MixedSpec>(r#"{"penetration": 0.5, "placement": "random"}"#)
                .unwrap_err()
                .to_string();
        assert!(bad.contains("even") && bad.contains("seeded"), "{bad}");
    }

    #[test]
    fn bad_values_are_named() {
        let m = |p: f64, c: &str| MixedSpec {
            penetration: p,
            controller: LawChoice::Name(c.into()),
            human: "human".into(),
            placement: Placement::Seeded,
        };
        assert_eq!(
            m(1.5, "law").validate(true).unwrap_err().to_string(),
            "mixed.penetration = 1.5: must lie in [0, 1] (the fraction of automated vehicles)"
        );
        assert!(m(0.5, "law").validate(false).is_err());
        let e = m(0.5, "bang-bang").validate(true).unwrap_err().to_string();
        assert!(
            e.starts_with("mixed.controller = bang-bang: unknown controller; use protocol, "),
            "{e}"
        );
        assert!(m(0.5, "pi-saturation").validate(true).is_ok());
    }
}
