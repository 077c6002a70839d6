//! SUMO's own drivers as baselines: which car-following model a vehicle that the law does not
//! command uses, and the vehicle-type attributes that select it.
//!
//! The point of a baseline is the traffic it makes. Measured on the Sugiyama ring with SUMO
//! 1.28.0 (`docs/src/human-preset.md`): Krauss forms no stop-and-go jam there, neither with its
//! default σ = 0.5 nor with σ = 0.9 (the flow crawls, nobody stops); SUMO's IDM with the
//! `human` preset's values does, from a perturbed start, and the stochastic humans computed by
//! the bridge (`human-noisy`, `flow-idm-noise`) do from a uniform start. ACC and CACC are
//! SUMO's built-in adaptive-cruise models, the natural baselines for a platoon.

use std::fmt;

use serde::{Deserialize, Serialize};

use syncroad_control::noisy_idm::{NoisyIdm, NOISY_PRESETS};

use crate::car_following::{CarFollowing, CfModel};

/// Speed mode of law-commanded vehicles when SUMO drivers share the road: bit 0 only, SUMO's
/// safe speed towards the leader is kept (accelerations are not limited). With every check off
/// a commanded vehicle would drive into a SUMO driver that brakes.
pub const MIXED_SPEED_MODE: i32 = 1;

/// Emission class set on every vehicle type, so fuel and CO2 come from one stated model
/// (HBEFA 4, petrol passenger car, Euro 6ab; built into SUMO 1.28).
pub const EMISSION_CLASS: &str = "HBEFA4/PC_petrol_Euro-6ab";

/// A SUMO car-following model driving a vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "driver", rename_all = "snake_case")]
pub enum SumoDriver {
    /// Krauss with driver imperfection σ ∈ \[0, 1\].
    Krauss {
        /// σ.
        sigma: f64,
    },
    /// The Intelligent Driver Model with SUMO's defaults.
    Idm,
    /// SUMO's ACC model (Milanés & Shladover).
    Acc,
    /// SUMO's CACC model (Milanés & Shladover); without a CACC-equipped leader it falls back
    /// to ACC.
    Cacc,
    /// The `human` preset: IDM calibrated on the Sugiyama ring ([`CarFollowing::preset`]).
    Human,
    /// The `flow-idm` preset: Flow's `IDMController` defaults ([`CarFollowing::preset`]).
    FlowIdm,
    /// The `human` preset's IDM with SUMO's driver-state device (Ornstein–Uhlenbeck errors in
    /// the perceived gap and speed difference, scaled by 1 − awareness), written
    /// `driverstate-A` with the driver's constant awareness A ∈ (0, 1] (1: no error).
    DriverState {
        /// Initial (and minimum) awareness.
        awareness: f64,
    },
    /// A stochastic human computed by the bridge, not by SUMO: IDM with Gaussian noise
    /// ([`syncroad_control::noisy_idm`]), sent as a speed command every step. The presets
    /// `human-noisy` and `flow-idm-noise`, any of their values changed
    /// (`human-noisy:noise=0.5`), or `noisy-idm:accel=..:...:noise=..:form=flow|step`.
    Noisy(NoisyIdm),
    /// Any of SUMO's car-following models with its parameters, written
    /// `MODEL:name=value:name=value` (e.g. `idm:accel=1.3:tau=0.8`), or a preset with some of
    /// its values changed (`human:tau=1.2`).
    Custom(CarFollowing),
}

/// Errors naming a driver.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriverError {
    /// Unknown name.
    #[error("{flag} = {value}: unknown driver; use krauss (σ 0.5), krauss-SIGMA with SIGMA in [0, 1] (e.g. krauss-0.9), idm, acc, cacc, a preset: human (IDM calibrated on the Sugiyama ring), flow-idm, the human preset with SUMO's driver-state device: driverstate-AWARENESS (e.g. driverstate-0.5), a stochastic human computed by syncroad: human-noisy, flow-idm-noise, noisy-idm:noise=..:form=flow|step, or any SUMO model with its parameters as MODEL:name=value:... (e.g. idm:accel=1.3:tau=0.8, eidm:..., w99:..., human:tau=1.2)")]
    Unknown {
        /// Flag or field.
        flag: String,
        /// The value.
        value: String,
    },
    /// A parameter of a `MODEL:name=value` driver is malformed, unknown or out of range.
    #[error("{flag} = {value}: {reason}")]
    Parameter {
        /// Flag or field.
        flag: String,
        /// The value.
        value: String,
        /// What is wrong and what would be valid.
        reason: String,
    },
    /// σ out of range.
    #[error("{flag} = {value}: Krauss σ = {sigma} must lie in [0, 1]")]
    Sigma {
        /// Flag or field.
        flag: String,
        /// The value.
        value: String,
        /// σ.
        sigma: f64,
    },
}

impl SumoDriver {
    /// SUMO's default driver: Krauss with σ = 0.5.
    pub const DEFAULT_KRAUSS: SumoDriver = SumoDriver::Krauss { sigma: 0.5 };

    /// Parses `krauss`, `krauss-0.9`, `idm`, `acc`, `cacc`, and the presets `human` and
    /// `flow-idm` (case-insensitive); `flag` names
    /// the flag or field in the error.
    pub fn parse(flag: &str, s: &str) -> Result<Self, DriverError> {
        let (head, params) = s.trim().split_once(':').unwrap_or((s.trim(), ""));
        let head_low = head.trim().to_ascii_lowercase();
        if NOISY_PRESETS.contains(&head_low.as_str()) || head_low == "noisy-idm" {
            return Self::noisy(flag, s, &head_low, params);
        }
        if let Some((model, params)) = s.trim().split_once(':') {
            return Self::custom(flag, s, model, params);
        }
        let low = s.trim().to_ascii_lowercase();
        match low.as_str() {
            "krauss" => return Ok(Self::DEFAULT_KRAUSS),
            "idm" => return Ok(Self::Idm),
            "acc" => return Ok(Self::Acc),
            "cacc" => return Ok(Self::Cacc),
            "human" => return Ok(Self::Human),
            "flow-idm" => return Ok(Self::FlowIdm),
            _ => {}
        }
        if let Some(a) = low
            .strip_prefix("driverstate-")
            .and_then(|x| x.parse::<f64>().ok())
        {
            return if a > 0.0 && a <= 1.0 {
                Ok(Self::DriverState { awareness: a })
            } else {
                Err(DriverError::Parameter {
                    flag: flag.into(),
                    value: s.into(),
                    reason: format!("awareness = {a}: valid is (0, 1] (1 = no perception error)"),
                })
            };
        }
        if let Some(sigma) = low
            .strip_prefix("krauss-")
            .and_then(|x| x.parse::<f64>().ok())
        {
            return Self::krauss(flag, s, sigma);
        }
        Err(DriverError::Unknown {
            flag: flag.into(),
            value: s.into(),
        })
    }

    /// A stochastic human: a preset or `noisy-idm` (Flow's IDM defaults without noise) with
    /// `name=value` changes, checked.
    fn noisy(flag: &str, s: &str, head: &str, params: &str) -> Result<Self, DriverError> {
        let bad = |reason: String| DriverError::Parameter {
            flag: flag.into(),
            value: s.into(),
            reason,
        };
        let mut d = NoisyIdm::preset(head).unwrap_or(NoisyIdm {
            idm: syncroad_control::IdmParams::FLOW,
            noise: 0.0,
            form: syncroad_control::NoiseForm::StepConsistent,
        });
        for (name, value) in name_values(params, "noise=0.3").map_err(bad)? {
            d.set(name, value).map_err(bad)?;
        }
        d.validate(flag)
            .map_err(|e| bad(format!("{} = {}: valid is {}", e.name, e.value, e.valid)))?;
        Ok(Self::Noisy(d))
    }

    /// `MODEL:name=value:...`: a SUMO model (by its SUMO or short name) or a preset, with
    /// parameters checked by [`CarFollowing::check_values`] (the names the model knows, finite
    /// values in range).
    fn custom(flag: &str, s: &str, model: &str, params: &str) -> Result<Self, DriverError> {
        let bad = |reason: String| DriverError::Parameter {
            flag: flag.into(),
            value: s.into(),
            reason,
        };
        let low = model.trim().to_ascii_lowercase();
        let mut cf = if crate::car_following::PRESETS.contains(&low.as_str()) {
            CarFollowing::preset(flag, &low).map_err(|e| bad(e.to_string()))?
        } else {
            let m = match low.as_str() {
                "krauss" => CfModel::Krauss,
                "idm" => CfModel::Idm,
                "acc" => CfModel::Acc,
                "cacc" => CfModel::Cacc,
                _ => {
                    CarFollowing::parse_model(flag, model.trim()).map_err(|e| bad(e.to_string()))?
                }
            };
            CarFollowing::new(m)
        };
        for (name, value) in name_values(params, "accel=1.3").map_err(bad)? {
            let v: f64 = value
                .parse()
                .map_err(|_| bad(format!("{name}: {value:?} is not a number")))?;
            cf.params.insert(name.to_string(), v);
        }
        cf.check_values(flag).map_err(|e| bad(e.to_string()))?;
        Ok(Self::Custom(cf))
    }

    /// The same driver as `other` however it was spelt (`krauss-0.9` and `krauss:sigma=0.9`,
    /// `human` and `IDM:accel=1.3:…` with the preset's values): the same model with the same
    /// values set, the same device parameters and, for the bridge's stochastic humans, the
    /// same noise. (A value set to SUMO's own default still counts as a difference.)
    pub fn same_driver(&self, other: &Self) -> bool {
        match (self, other) {
            (SumoDriver::Noisy(a), SumoDriver::Noisy(b)) => a == b,
            (SumoDriver::Noisy(_), _) | (_, SumoDriver::Noisy(_)) => false,
            _ => {
                self.car_following() == other.car_following()
                    && self.vtype_params() == other.vtype_params()
            }
        }
    }

    /// Krauss with driver imperfection `sigma`, checked to lie in \[0, 1\]; `flag` and
    /// `value` name where it was given in the error.
    pub fn krauss(flag: &str, value: &str, sigma: f64) -> Result<Self, DriverError> {
        if (0.0..=1.0).contains(&sigma) {
            Ok(Self::Krauss { sigma })
        } else {
            Err(DriverError::Sigma {
                flag: flag.into(),
                value: value.into(),
                sigma,
            })
        }
    }

    /// The `carFollowModel` (and σ) attributes of a `vType`.
    pub fn vtype_attributes(&self) -> String {
        match self {
            SumoDriver::Krauss { sigma } => format!(r#"carFollowModel="Krauss" sigma="{sigma}""#),
            SumoDriver::Idm => r#"carFollowModel="IDM""#.into(),
            SumoDriver::Acc => r#"carFollowModel="ACC""#.into(),
            SumoDriver::Cacc => r#"carFollowModel="CACC""#.into(),
            SumoDriver::Human
            | SumoDriver::FlowIdm
            | SumoDriver::Custom(_)
            | SumoDriver::Noisy(_)
            | SumoDriver::DriverState { .. } => self.car_following().vtype_attributes(),
        }
    }
}

impl SumoDriver {
    /// The same driver as a fully parameterized [`CarFollowing`]; it renders the same
    /// `vType` attributes as [`vtype_attributes`](Self::vtype_attributes).
    pub fn car_following(&self) -> CarFollowing {
        match self {
            SumoDriver::Custom(cf) => cf.clone(),
            SumoDriver::Krauss { sigma } => {
                CarFollowing::with(CfModel::Krauss, &[("sigma", *sigma)])
            }
            SumoDriver::Idm => CarFollowing::new(CfModel::Idm),
            SumoDriver::Acc => CarFollowing::new(CfModel::Acc),
            SumoDriver::Cacc => CarFollowing::new(CfModel::Cacc),
            SumoDriver::Human | SumoDriver::DriverState { .. } => {
                CarFollowing::preset("driver", "human").expect("the human preset exists")
            }
            SumoDriver::FlowIdm => {
                CarFollowing::preset("driver", "flow-idm").expect("the flow-idm preset exists")
            }
            // SUMO's IDM with the same values: what the vehicle type says; the bridge
            // commands the vehicle, so SUMO's model never drives it.
            SumoDriver::Noisy(d) => {
                let p = &d.idm;
                CarFollowing::with(
                    CfModel::Idm,
                    &[
                        ("accel", p.accel_mps2),
                        ("decel", p.decel_mps2),
                        ("tau", p.time_headway_s),
                        ("minGap", p.min_gap_m),
                        ("delta", p.delta),
                        ("maxSpeed", p.desired_speed_mps),
                        ("length", 5.0),
                    ],
                )
            }
        }
    }
}

impl SumoDriver {
    /// `<param>` children of the driver's `vType` (SUMO's device parameters), empty for most.
    pub fn vtype_params(&self) -> Vec<(&'static str, String)> {
        match self {
            SumoDriver::DriverState { awareness } => vec![
                ("has.driverstate.device", "true".into()),
                ("device.driverstate.initialAwareness", awareness.to_string()),
                ("device.driverstate.minAwareness", awareness.to_string()),
            ],
            _ => Vec::new(),
        }
    }
}

/// The `name=value` pairs of a driver's `:`-separated parameters, each name given once (a
/// repeated name was a silent choice of the last value); `example` shows the form in errors.
fn name_values<'a>(params: &'a str, example: &str) -> Result<Vec<(&'a str, &'a str)>, String> {
    let mut pairs: Vec<(&str, &str)> = Vec::new();
    for kv in params.split(':').map(str::trim).filter(|x| !x.is_empty()) {
        let (name, value) = kv
            .split_once('=')
            .ok_or_else(|| format!("{kv:?} is not name=value (e.g. {example})"))?;
        let (name, value) = (name.trim(), value.trim());
        if let Some((_, first)) = pairs.iter().find(|(n, _)| *n == name) {
            return Err(format!(
                "{name} is given twice ({first} and {value}); give each parameter once"
            ));
        }
        pairs.push((name, value));
    }
    Ok(pairs)
}

impl fmt::Display for SumoDriver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SumoDriver::Krauss { sigma } if *sigma == 0.5 => write!(f, "krauss"),
            SumoDriver::Krauss { sigma } => write!(f, "krauss-{sigma}"),
            SumoDriver::Idm => write!(f, "idm"),
            SumoDriver::Acc => write!(f, "acc"),
            SumoDriver::Cacc => write!(f, "cacc"),
            SumoDriver::Human => write!(f, "human"),
            SumoDriver::FlowIdm => write!(f, "flow-idm"),
            SumoDriver::DriverState { awareness } => write!(f, "driverstate-{awareness}"),
            SumoDriver::Noisy(d) => match d.preset_name() {
                Some(p) => write!(f, "{p}"),
                None => write!(f, "{d}"),
            },
            SumoDriver::Custom(cf) => {
                write!(f, "{}", cf.model.sumo_name().to_ascii_lowercase())?;
                for (name, value) in &cf.params {
                    write!(f, ":{name}={value}")?;
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_errors_name_the_flag() {
        for name in [
            "krauss",
            "krauss-0.9",
            "idm",
            "acc",
            "cacc",
            "human",
            "flow-idm",
            "human-noisy",
            "flow-idm-noise",
            "driverstate-0.5",
        ] {
            assert_eq!(
                SumoDriver::parse("--baselines", name).unwrap().to_string(),
                name
            );
        }
        assert_eq!(
            SumoDriver::parse("--baselines", "krauss-1.5")
                .unwrap_err()
                .to_string(),
            "--baselines = krauss-1.5: Krauss σ = 1.5 must lie in [0, 1]"
        );
        assert!(SumoDriver::parse("--baselines", "wiedemann")
            .unwrap_err()
            .to_string()
            .starts_with("--baselines = wiedemann: unknown driver; use krauss"));
    }

    #[test]
    fn stochastic_humans_parse_round_trip_and_name_bad_values() {
        let d = SumoDriver::parse("--baselines", "human-noisy:noise=0.5").unwrap();
        let SumoDriver::Noisy(n) = &d else {
            panic!("{d:?}")
        };
        assert_eq!(n.noise, 0.5);
        assert_eq!(n.idm.accel_mps2, 1.3);
        assert_eq!(SumoDriver::parse("x", &d.to_string()).unwrap(), d);
        assert!(d.to_string().starts_with("noisy-idm:accel=1.3:"), "{d}");
        let f = SumoDriver::parse("x", "noisy-idm:noise=0.2:form=flow").unwrap();
        assert_eq!(f, SumoDriver::parse("x", "flow-idm-noise").unwrap());
        assert_eq!(f.to_string(), "flow-idm-noise");
        for (bad, why) in [
            (
                "human-noisy:noise=-1",
                "noise = -1: valid is a finite number ≥ 0",
            ),
            (
                "human-noisy:form=euler",
                "form = \"euler\": valid are flow, step",
            ),
            ("human-noisy:sigma=1", "no parameter \"sigma\""),
            ("human-noisy:noise", "is not name=value"),
        ] {
            let e = SumoDriver::parse("--baselines", bad)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(&format!("--baselines = {bad}: ")), "{e}");
            assert!(e.contains(why), "{e}");
        }
    }

    #[test]
    fn any_model_with_its_parameters_and_presets_with_changes() {
        let d = SumoDriver::parse("--baselines", "IDM:tau=0.8:accel=1.3").unwrap();
        assert_eq!(d.to_string(), "idm:accel=1.3:tau=0.8");
        assert_eq!(SumoDriver::parse("x", &d.to_string()).unwrap(), d);
        assert_eq!(
            d.vtype_attributes(),
            r#"carFollowModel="IDM" accel="1.3" tau="0.8""#
        );
        // A preset with one value changed keeps the others.
        let h = SumoDriver::parse("x", "human:tau=1.2")
            .unwrap()
            .car_following();
        let mut want = SumoDriver::Human.car_following();
        want.params.insert("tau".into(), 1.2);
        assert_eq!(h, want);
        // Models beyond the short names, by SUMO's spelling.
        let w = SumoDriver::parse("x", "w99:cc1=1.5")
            .unwrap()
            .car_following();
        assert_eq!(w.model, CfModel::W99);
        // A parameter the model does not know: the error lists the valid ones.
        let e = SumoDriver::parse("--baselines", "idm:sigmaa=0.5")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--baselines = idm:sigmaa=0.5: "), "{e}");
        assert!(
            e.contains("sigmaa") && e.contains("accel") && e.contains("delta"),
            "{e}"
        );
        for bad in [
            "idm:accel=-1",
            "idm:accel=nan",
            "idm:accel",
            "idm:accel=fast",
            "nosuch:tau=1",
        ] {
            let e = SumoDriver::parse("--baselines", bad)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(&format!("--baselines = {bad}: ")), "{e}");
        }
    }
}
