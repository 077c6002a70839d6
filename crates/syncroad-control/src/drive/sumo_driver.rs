//! SUMO's own drivers as baselines: which car-following model a vehicle that the law does not
//! command uses, the vehicle-type attributes that select it, and the named presets.
//!
//! The point of a baseline is the traffic it makes. Measured on the Sugiyama ring with SUMO
//! 1.28.0 (`docs/src/human-preset.md`): Krauss forms no stop-and-go jam there, neither with its
//! default σ = 0.5 nor with σ = 0.9 (the flow crawls, nobody stops); SUMO's IDM with the
//! `human` preset's values does, from a perturbed start, and the stochastic humans computed by
//! the bridge (`human-noisy`, `flow-idm-noise`) do from a uniform start. ACC and CACC are
//! SUMO's built-in adaptive-cruise models, the natural baselines for a platoon.
//!
//! Every named driver is one entry of [`PRESETS`]: parsing, the name a run is given, a preset
//! with some of its values changed (`human:tau=1.2`) and the unknown-driver message all read
//! that table.

use std::fmt;

use serde::{Deserialize, Serialize};

use super::car_following::{CarFollowing, CfModel};
use crate::noisy_idm::NoisyIdm;

/// A SUMO car-following model driving a vehicle, or a stochastic human computed by the bridge.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "driver", rename_all = "snake_case")]
pub enum SumoDriver {
    /// Krauss with driver imperfection σ ∈ \[0, 1\], written `krauss-SIGMA` (`krauss` is
    /// SUMO's default σ = 0.5).
    Krauss {
        /// σ.
        sigma: f64,
    },
    /// The `human` preset's IDM with SUMO's driver-state device (Ornstein–Uhlenbeck errors in
    /// the perceived gap and speed difference, scaled by 1 − awareness), written
    /// `driverstate-A` with the driver's constant awareness A ∈ (0, 1] (1: no error).
    DriverState {
        /// Initial (and minimum) awareness.
        awareness: f64,
    },
    /// A stochastic human computed by the bridge, not by SUMO: IDM with Gaussian noise
    /// ([`crate::noisy_idm`]), sent as a speed command every step. The presets `human-noisy`
    /// and `flow-idm-noise`, any of their values changed (`human-noisy:noise=0.5`), or
    /// `noisy-idm:accel=..:...:noise=..:form=flow|step`.
    Noisy(NoisyIdm),
    /// Any of SUMO's car-following models with values of its parameters: a preset (`idm`,
    /// `acc`, `cacc`, `human`, `flow-idm`), `MODEL:name=value:name=value`
    /// (e.g. `idm:accel=1.3:tau=0.8`), or a preset with some of its values changed
    /// (`human:tau=1.2`).
    Model(CarFollowing),
}

/// The human driver of mixed traffic wherever none is named (a scenario's `mixed.human`,
/// `compare --mixed-driver`, a sweep's `mixed_driver`): the `human` preset, SUMO's IDM
/// calibrated so that the Sugiyama ring jams as the experiment did.
pub const DEFAULT_HUMAN: &str = "human";

/// A named driver: one entry of [`PRESETS`].
#[derive(Debug, Clone, Copy)]
pub struct Preset {
    /// The name `compare --baselines`, a sweep's `runs` and `mixed.human` take.
    pub name: &'static str,
    /// What it is, for the unknown-driver message.
    pub about: &'static str,
    /// A family of drivers written beside it in that message (`krauss-SIGMA ...`), or "".
    pub family: &'static str,
    driver: fn() -> SumoDriver,
}

impl Preset {
    /// The driver this name stands for.
    pub fn driver(&self) -> SumoDriver {
        (self.driver)()
    }
}

/// The IDM of the `human` and `flow-idm` presets: Flow's values with acceleration `accel` and
/// time headway `tau`, SUMO's attribute names.
fn idm_preset(accel: f64, tau: f64) -> SumoDriver {
    SumoDriver::Model(CarFollowing::with(
        CfModel::Idm,
        &[
            ("accel", accel),
            ("decel", 1.5),
            ("tau", tau),
            ("minGap", 2.0),
            ("delta", 4.0),
            ("maxSpeed", 30.0),
            ("length", 5.0),
        ],
    ))
}

/// Every named driver. Adding a preset is one entry here.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "krauss",
        about: "σ 0.5",
        family: "krauss-SIGMA with SIGMA in [0, 1] (e.g. krauss-0.9)",
        driver: || SumoDriver::Krauss { sigma: 0.5 },
    },
    Preset {
        name: "idm",
        about: "SUMO's IDM with its defaults",
        family: "",
        driver: || SumoDriver::Model(CarFollowing::new(CfModel::Idm)),
    },
    Preset {
        name: "acc",
        about: "SUMO's ACC",
        family: "",
        driver: || SumoDriver::Model(CarFollowing::new(CfModel::Acc)),
    },
    Preset {
        name: "cacc",
        about: "SUMO's CACC, ACC without a CACC-equipped leader",
        family: "",
        driver: || SumoDriver::Model(CarFollowing::new(CfModel::Cacc)),
    },
    // SUMO's IDM calibrated on the Sugiyama ring (22 vehicles, 230 m; every value's source is
    // in docs/src/human-preset.md): from a near-uniform start a stop-and-go jam forms by
    // itself (first vehicle below 1 m/s at 254–358 s over 10 seeds), vehicles stop in it, and
    // it travels backward at 17.6 km/h (Sugiyama et al. 2008: about 20 km/h). Flow's IDM ring
    // values (a = 1 m/s², b = 1.5 m/s², T = 1 s, s0 = 2 m, δ = 4, v0 = 30 m/s) with
    // a = 1.3 m/s² and T = 0.8 s, which move the wave from 15.3 km/h (the low edge of the
    // target) to 17.6 km/h; length 5 m.
    Preset {
        name: "human",
        about: "IDM calibrated on the Sugiyama ring: Flow's with a = 1.3 m/s², T = 0.8 s",
        family: "the human preset with SUMO's driver-state device: driverstate-AWARENESS \
                 (e.g. driverstate-0.5)",
        driver: || idm_preset(1.3, 0.8),
    },
    // Flow's IDMController defaults unchanged, run by SUMO's IDM (without Flow's acceleration
    // noise, which SUMO's IDM does not have): wave 15.3 km/h.
    Preset {
        name: "flow-idm",
        about: "Flow's IDMController defaults",
        family: "",
        driver: || idm_preset(1.0, 1.0),
    },
    Preset {
        name: "human-noisy",
        about: "a stochastic human computed by syncroad: the human preset's IDM with \
                step-consistent noise, jams from a uniform start",
        family: "",
        driver: || SumoDriver::Noisy(NoisyIdm::HUMAN_NOISY),
    },
    Preset {
        name: "flow-idm-noise",
        about: "Flow's IDM with Flow's ring-example noise 0.2",
        family: "noisy-idm:noise=..:form=flow|step",
        driver: || SumoDriver::Noisy(NoisyIdm::FLOW_IDM_NOISE),
    },
];

/// The named preset `name` (exact, lower case).
pub fn preset(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name == name)
}

/// What the unknown-driver message lists: every preset with what it is, then the general form.
fn known_drivers() -> String {
    let mut out = String::new();
    for p in PRESETS {
        out.push_str(&format!("{} ({}), ", p.name, p.about));
        if !p.family.is_empty() {
            out.push_str(p.family);
            out.push_str(", ");
        }
    }
    out.push_str(
        "or any SUMO model with its parameters as MODEL:name=value:... (e.g. \
         idm:accel=1.3:tau=0.8, eidm:..., w99:..., human:tau=1.2)",
    );
    out
}

/// Errors naming a driver.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriverError {
    /// Unknown name.
    #[error("{flag} = {value}: unknown driver; use {}", known_drivers())]
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

    /// Parses a preset of [`PRESETS`] (case-insensitive), a preset with changes
    /// (`PRESET:name=value:...`), `krauss-SIGMA`, `driverstate-AWARENESS`,
    /// `noisy-idm:name=value:...` or `MODEL:name=value:...`; `flag` names the flag or field
    /// in the error.
    pub fn parse(flag: &str, s: &str) -> Result<Self, DriverError> {
        let bad = |reason: String| DriverError::Parameter {
            flag: flag.into(),
            value: s.into(),
            reason,
        };
        let (head, changes) = match s.trim().split_once(':') {
            Some((h, c)) => (h.trim(), Some(c)),
            None => (s.trim(), None),
        };
        let low = head.to_ascii_lowercase();
        let base = if let Some(p) = preset(&low) {
            p.driver()
        } else if low == "noisy-idm" {
            // Flow's IDM without noise: the start of a stochastic human written out in full.
            SumoDriver::Noisy(NoisyIdm::BARE)
        } else if changes.is_some() {
            let model = CarFollowing::parse_model(flag, head).map_err(|e| bad(e.to_string()))?;
            SumoDriver::Model(CarFollowing::new(model))
        } else {
            return Self::family(flag, s, &low);
        };
        match changes {
            None if !matches!(base, SumoDriver::Noisy(_)) => Ok(base),
            // A stochastic human is checked even unchanged (`noisy-idm` alone).
            _ => base.changed(flag, changes.unwrap_or(""), bad),
        }
    }

    /// `krauss-SIGMA` and `driverstate-AWARENESS`, the two written families.
    fn family(flag: &str, s: &str, low: &str) -> Result<Self, DriverError> {
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

    /// This driver with the `name=value` changes of `params`, checked: a stochastic human's by
    /// [`NoisyIdm::set`] and its validation, a SUMO model's by
    /// [`CarFollowing::check_values`] (the names the model knows, finite values in range).
    fn changed(
        self,
        flag: &str,
        params: &str,
        bad: impl Fn(String) -> DriverError,
    ) -> Result<Self, DriverError> {
        if let SumoDriver::Noisy(mut d) = self {
            for (name, value) in name_values(params, "noise=0.3").map_err(&bad)? {
                d.set(name, value).map_err(&bad)?;
            }
            d.validate(flag)
                .map_err(|e| bad(format!("{} = {}: valid is {}", e.name, e.value, e.valid)))?;
            return Ok(SumoDriver::Noisy(d));
        }
        if !self.vtype_params().is_empty() {
            return Err(bad(format!("{self} takes no changed values")));
        }
        let mut cf = self.car_following();
        for (name, value) in name_values(params, "accel=1.3").map_err(&bad)? {
            let v: f64 = value
                .parse()
                .map_err(|_| bad(format!("{name}: {value:?} is not a number")))?;
            cf.params.insert(name.to_string(), v);
        }
        cf.check_values(flag).map_err(|e| bad(e.to_string()))?;
        Ok(SumoDriver::Model(cf))
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

    /// True for the stochastic humans, which the bridge commands like the law; SUMO's model
    /// drives every other driver.
    pub fn commanded_by_bridge(&self) -> bool {
        matches!(self, SumoDriver::Noisy(_))
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

    /// The `carFollowModel` attribute and the model's parameters of a `vType`.
    pub fn vtype_attributes(&self) -> String {
        self.car_following().vtype_attributes()
    }

    /// The same driver as a fully parameterized [`CarFollowing`].
    pub fn car_following(&self) -> CarFollowing {
        match self {
            SumoDriver::Model(cf) => cf.clone(),
            SumoDriver::Krauss { sigma } => {
                CarFollowing::with(CfModel::Krauss, &[("sigma", *sigma)])
            }
            SumoDriver::DriverState { .. } => preset("human")
                .expect("the human preset exists")
                .driver()
                .car_following(),
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
    /// The preset's name when the driver is one, else the written form, which parses back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(p) = PRESETS.iter().find(|p| p.driver() == *self) {
            return write!(f, "{}", p.name);
        }
        match self {
            SumoDriver::Krauss { sigma } => write!(f, "krauss-{sigma}"),
            SumoDriver::DriverState { awareness } => write!(f, "driverstate-{awareness}"),
            SumoDriver::Noisy(d) => write!(f, "{d}"),
            SumoDriver::Model(cf) => {
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
    fn every_preset_parses_to_its_driver_and_keeps_its_name() {
        let unknown = SumoDriver::parse("x", "wiedemann").unwrap_err().to_string();
        for p in PRESETS {
            let d = SumoDriver::parse("--baselines", p.name).unwrap();
            assert_eq!(d, p.driver(), "{}", p.name);
            assert_eq!(d.to_string(), p.name);
            assert_eq!(
                SumoDriver::parse("x", &p.name.to_ascii_uppercase()).unwrap(),
                d
            );
            // The unknown-driver message lists it.
            assert!(unknown.contains(&format!("{} (", p.name)), "{unknown}");
        }
        let names: Vec<_> = PRESETS.iter().map(|p| p.name).collect();
        let mut unique = names.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), names.len(), "{names:?}");
    }

    #[test]
    fn names_round_trip_and_errors_name_the_flag() {
        for name in ["krauss-0.9", "driverstate-0.5"] {
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
            .starts_with(
                "--baselines = wiedemann: unknown driver; use krauss (σ 0.5), krauss-SIGMA"
            ));
        assert!(SumoDriver::parse("x", "driverstate-0")
            .unwrap_err()
            .to_string()
            .contains("awareness = 0: valid is (0, 1]"));
    }

    #[test]
    fn the_human_presets_have_their_documented_values() {
        // docs/src/human-preset.md: Flow's IDM with a = 1.3 m/s², T = 0.8 s.
        let human = preset("human").unwrap().driver().car_following();
        human.validate("driver", 0.1).unwrap();
        assert_eq!(
            human.vtype_attributes(),
            r#"carFollowModel="IDM" accel="1.3" decel="1.5" delta="4" length="5" maxSpeed="30" minGap="2" tau="0.8""#
        );
        let flow = preset("flow-idm").unwrap().driver().car_following();
        assert_eq!((flow.params["accel"], flow.params["tau"]), (1.0, 1.0));
        // driverstate-A is the human preset with the device.
        let ds = SumoDriver::parse("x", "driverstate-0.5").unwrap();
        assert_eq!(ds.car_following(), human);
        assert!(!ds.same_driver(&preset("human").unwrap().driver()));
        let SumoDriver::Noisy(noisy) = preset("human-noisy").unwrap().driver() else {
            panic!("human-noisy is a stochastic human")
        };
        assert_eq!(
            (noisy.idm.accel_mps2, noisy.idm.time_headway_s),
            (human.params["accel"], human.params["tau"])
        );
    }

    #[test]
    fn stochastic_humans_parse_round_trip_and_name_bad_values() {
        let d = SumoDriver::parse("--baselines", "human-noisy:noise=0.5").unwrap();
        let SumoDriver::Noisy(n) = &d else {
            panic!("{d:?}")
        };
        assert!(d.commanded_by_bridge());
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
        assert!(!d.commanded_by_bridge());
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
        let mut want = preset("human").unwrap().driver().car_following();
        want.params.insert("tau".into(), 1.2);
        assert_eq!(h, want);
        // The same driver however it is spelt.
        let k = SumoDriver::parse("x", "krauss:sigma=0.9").unwrap();
        assert!(k.same_driver(&SumoDriver::parse("x", "krauss-0.9").unwrap()));
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
            "driverstate-0.5:tau=1",
        ] {
            let e = SumoDriver::parse("--baselines", bad)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(&format!("--baselines = {bad}: ")), "{e}");
        }
    }

    #[test]
    fn the_krauss_and_model_names_render_the_attributes_of_their_model() {
        for (name, want) in [
            ("krauss", r#"carFollowModel="Krauss" sigma="0.5""#),
            ("krauss-0.9", r#"carFollowModel="Krauss" sigma="0.9""#),
            ("idm", r#"carFollowModel="IDM""#),
            ("acc", r#"carFollowModel="ACC""#),
            ("cacc", r#"carFollowModel="CACC""#),
        ] {
            let d = SumoDriver::parse("--baselines", name).unwrap();
            d.car_following().validate("--baselines", 0.1).unwrap();
            assert_eq!(d.vtype_attributes(), want, "{name}");
        }
    }
}
