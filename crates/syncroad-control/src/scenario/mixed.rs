//! Mixed traffic on a ring: a fraction p of the vehicles (the penetration rate) runs the law or
//! a wave damper, the others are SUMO human drivers. Which vehicles are automated is drawn from
//! the scenario's seed, so a run is reproducible and a sweep over seeds samples placements.
//!
//! ```json
//! "mixed": {"penetration": 0.5, "controller": "law", "human": "human"}
//! ```
//! * `penetration` p ∈ \[0, 1\]: `round(p N)` vehicles are automated (halves round up);
//! * `controller`: `law` (the scenario's model, default), `follower-stopper-U` (desired speed
//!   U in m/s) or `pi-saturation` — the wave dampers of Stern et al. (2018);
//! * `human`: the SUMO driver of the other vehicles (default `human`, the calibrated preset;
//!   any name `compare --baselines` takes). The SUMO backend checks it before SUMO starts.

use serde::{Deserialize, Serialize};

use super::{invalid, ScenarioError};
use crate::damper::{DamperError, DamperSpec};
use crate::rng::SplitMix64;

/// Mixed traffic as written in the scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixedSpec {
    /// Fraction p of automated vehicles, in \[0, 1\].
    pub penetration: f64,
    /// What drives the automated vehicles: `law`, `follower-stopper-U` or `pi-saturation`.
    #[serde(default = "default_controller")]
    pub controller: String,
    /// SUMO driver of the other vehicles.
    #[serde(default = "default_human")]
    pub human: String,
}

fn default_controller() -> String {
    "law".into()
}

fn default_human() -> String {
    "human".into()
}

/// Salt of the placement stream, so that it is independent of the initial perturbation drawn
/// from the same seed.
const PLACEMENT_SALT: u64 = 0x6d69_7865_645f_7031; // "mixed_p1"

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
    pub fn damper(&self) -> Result<Option<DamperSpec>, ScenarioError> {
        let field = "mixed.controller";
        DamperSpec::parse(field, &self.controller).map_err(|e| {
            let why = match e {
                DamperError::FollowerStopper { source, .. } => source.to_string(),
                DamperError::PiSaturation { source, .. } => source.to_string(),
                _ => "unknown controller; use law, follower-stopper-U (desired speed U in m/s, \
                      e.g. follower-stopper-4.3) or pi-saturation"
                    .into(),
            };
            invalid(field, &self.controller, why)
        })
    }

    /// The automated vehicles among `n`, ascending (see [`automated_vehicles`]).
    pub fn automated(&self, n: usize, seed: u64) -> Vec<usize> {
        automated_vehicles(n, self.penetration, seed)
    }
}

/// `round(p n)` vehicles out of `n`, drawn without replacement from `seed` (a partial
/// Fisher–Yates shuffle of SplitMix64 draws), ascending. The same seed gives the same choice on
/// every platform.
pub fn automated_vehicles(n: usize, penetration: f64, seed: u64) -> Vec<usize> {
    let k = ((penetration * n as f64).round() as usize).min(n);
    let mut rng = SplitMix64::new(seed ^ PLACEMENT_SALT);
    let mut idx: Vec<usize> = (0..n).collect();
    for j in 0..k {
        let r = j + (rng.next_u64() % (n - j) as u64) as usize;
        idx.swap(j, r);
    }
    let mut chosen = idx[..k].to_vec();
    chosen.sort_unstable();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_count_is_round_p_n_and_the_choice_depends_on_the_seed_only() {
        assert_eq!(automated_vehicles(22, 0.5, 42).len(), 11);
        assert_eq!(automated_vehicles(22, 0.0, 42), Vec::<usize>::new());
        assert_eq!(automated_vehicles(22, 1.0, 42), (0..22).collect::<Vec<_>>());
        assert_eq!(automated_vehicles(21, 0.5, 1).len(), 11); // 10.5 rounds up
        assert_eq!(automated_vehicles(22, 0.05, 1).len(), 1); // 1.1
        let a = automated_vehicles(22, 0.5, 42);
        assert_eq!(a, automated_vehicles(22, 0.5, 42));
        assert_ne!(a, automated_vehicles(22, 0.5, 43));
        assert!(a.windows(2).all(|w| w[0] < w[1]) && a.iter().all(|&i| i < 22));
    }

    #[test]
    fn every_vehicle_is_chosen_about_equally_often() {
        // Over 2000 seeds each of 22 vehicles is chosen with probability 1/2: the count is
        // Binomial(2000, 1/2), mean 1000, sd 22.4; ±150 is more than 6 sd.
        let mut hits = [0usize; 22];
        for seed in 0..2000 {
            for i in automated_vehicles(22, 0.5, seed) {
                hits[i] += 1;
            }
        }
        assert!(hits.iter().all(|&h| (850..=1150).contains(&h)), "{hits:?}");
    }

    #[test]
    fn bad_values_are_named() {
        let m = |p: f64, c: &str| MixedSpec {
            penetration: p,
            controller: c.into(),
            human: "human".into(),
        };
        assert_eq!(
            m(1.5, "law").validate(true).unwrap_err().to_string(),
            "mixed.penetration = 1.5: must lie in [0, 1] (the fraction of automated vehicles)"
        );
        assert!(m(0.5, "law").validate(false).is_err());
        let e = m(0.5, "bang-bang").validate(true).unwrap_err().to_string();
        assert!(
            e.starts_with("mixed.controller = bang-bang: unknown controller; use law, "),
            "{e}"
        );
        assert!(m(0.5, "pi-saturation").validate(true).is_ok());
    }
}
