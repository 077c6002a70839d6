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

/// Mixed traffic as written in the scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixedSpec {
    /// Fraction p of automated vehicles, in \[0, 1\].
    pub penetration: f64,
    /// What drives the automated vehicles: `protocol`, `follower-stopper-U` or `pi-saturation`.
    #[serde(default = "default_controller")]
    pub controller: String,
    /// SUMO driver of the other vehicles.
    #[serde(default = "default_human")]
    pub human: String,
    /// Where the automated vehicles sit.
    #[serde(default)]
    pub placement: Placement,
}

fn default_controller() -> String {
    crate::registry::PROTOCOL.into()
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

    /// The damper of the automated vehicles, `None` for the scenario's law.
    pub fn damper(&self) -> Result<Option<NamedLaw>, ScenarioError> {
        let field = "mixed.controller";
        NamedLaw::parse(field, &self.controller)
            .map_err(|e| invalid(field, &self.controller, e.why()))
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
            controller: "protocol".into(),
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
            controller: c.into(),
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
