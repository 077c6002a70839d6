//! SUMO's car-following models with all their parameters, checked before SUMO starts.
//!
//! SUMO reads a model's parameters from the `<vType>` element, but only those the model
//! knows: any other attribute is dropped **without a warning** (SUMO 1.28 ignores `sigma` on
//! an IDM vehicle, for instance, and its `getImperfection` returns −1). A typo or a parameter
//! of another model therefore changes nothing and says nothing. [`CarFollowing::validate`]
//! rejects such a parameter and names the valid ones, and checks that every value is finite
//! and in range, so that a scenario states exactly the drivers SUMO runs.
//!
//! # The table and where it comes from
//! [`CfModel::model_params`] lists, per model, the attributes SUMO's parser hands to it:
//! * `SUMOVehicleParserHelper::getAllowedCFModelAttrs` in eclipse-sumo/sumo
//!   (`src/utils/vehicle/SUMOVehicleParserHelper.cpp`), one set per model; the XML names are
//!   those of `src/utils/xml/SUMOXMLDefinitions.cpp` (e.g. `SUMO_ATTR_CF_EIDM_T_LOOK_AHEAD` is
//!   `tpreview`);
//! * checked against SUMO 1.28.0 itself by `python-host/check_car_following.py`: which models
//!   load, for which `sigma` and `accel` reach the vehicle, and the attribute names of
//!   `<vType>` in SUMO's own schema (`data/xsd/types/route.xsd`). In 1.28 `accel`, `decel`,
//!   `emergencyDecel`, `apparentDecel` and `tau` reach every model (W99 has no `accel`), so
//!   they are listed for every model; `sigmaStep` reaches the Krauss family (SUMO rounds it
//!   to a multiple of the step and warns).
//!
//! Attributes of the vehicle rather than of the model ([`VEHICLE_PARAMS`]: `length`, `minGap`,
//! `maxSpeed`, `speedFactor`, `speedDev`, `actionStepLength`, `startupDelay`) are valid for
//! every model. Not covered: `Rail` (its `trainType` is a name, not a number), `CC` (needs a
//! platooning setup), the newest ACC/CACC attributes whose model scope could not be confirmed
//! (`speedControlMinGap`, `collisionAvoidanceOverride`), distributions in `speedFactor`.
//!
//! # Reference
//! SUMO documentation, "Definition of Vehicles, Vehicle Types, and Routes", section
//! Car-Following Models, and "Car-Following-Models" (eclipse-sumo/sumo, `docs/web/docs`).

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

/// A SUMO car-following model (the value of `carFollowModel`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum CfModel {
    /// SUMO's default: Krauß with modifications (σ driver imperfection).
    Krauss,
    /// The original Krauß model.
    KraussOrig1,
    /// Krauss with road slope.
    KraussPS,
    /// Krauss with five experimental parameters `tmp1..tmp5`.
    KraussX,
    /// Variant of Krauss (`tmp1..tmp5`).
    SmartSK,
    /// Model by D. Krajzewicz (`tmp1..tmp5`).
    Daniel1,
    /// P. Wagner's model with Todosiev's action points.
    PWagner2009,
    /// B. Kerner's model.
    BKerner,
    /// Intelligent Driver Model (Treiber et al.).
    #[serde(rename = "IDM")]
    Idm,
    /// IDM with memory (adaptation to the past level of service).
    #[serde(rename = "IDMM")]
    Idmm,
    /// Extended IDM (Salles et al.): reaction time, estimation errors, jerk limits.
    #[serde(rename = "EIDM")]
    Eidm,
    /// Wiedemann's psycho-physical model (2 parameters).
    Wiedemann,
    /// Wiedemann 99 (10 parameters `cc0..cc9`; SUMO names them `cc1..cc9`).
    W99,
    /// ACC of Milanés & Shladover.
    #[serde(rename = "ACC")]
    Acc,
    /// CACC of Milanés & Shladover.
    #[serde(rename = "CACC")]
    Cacc,
}

/// Vehicle attributes valid for every model.
pub const VEHICLE_PARAMS: &[&str] = &[
    "length",
    "minGap",
    "maxSpeed",
    "speedFactor",
    "speedDev",
    "actionStepLength",
    "startupDelay",
];

const KRAUSS: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "sigma",
    "sigmaStep",
];
const KRAUSS_X: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "sigma",
    "sigmaStep",
    "tmp1",
    "tmp2",
    "tmp3",
    "tmp4",
    "tmp5",
];
const SMART_SK: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "sigma",
    "collisionMinGapFactor",
    "tmp1",
    "tmp2",
    "tmp3",
    "tmp4",
    "tmp5",
];
const PWAGNER: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "sigma",
    "collisionMinGapFactor",
    "tauLast",
    "apProb",
];
const BKERNER: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "k",
    "phi",
];
const IDM: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "delta",
    "stepping",
];
const IDMM: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "adaptFactor",
    "adaptTime",
    "stepping",
];
const EIDM: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "delta",
    "stepping",
    "tpreview",
    "tPersDrive",
    "treaction",
    "tPersEstimate",
    "ccoolness",
    "sigmaleader",
    "sigmagap",
    "sigmaerror",
    "jerkmax",
    "epsilonacc",
    "taccmax",
    "Mflatness",
    "Mbegin",
    "vehdynamics",
    "maxvehpreview",
];
const WIEDEMANN: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "security",
    "estimation",
];
const W99: &[&str] = &[
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "cc1",
    "cc2",
    "cc3",
    "cc4",
    "cc5",
    "cc6",
    "cc7",
    "cc8",
    "cc9",
];
const ACC: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "speedControlGain",
    "gapClosingControlGainSpeed",
    "gapClosingControlGainSpace",
    "gapControlGainSpeed",
    "gapControlGainSpace",
    "collisionAvoidanceGainSpeed",
    "collisionAvoidanceGainSpace",
    "applyDriverState",
];
const CACC: &[&str] = &[
    "accel",
    "decel",
    "emergencyDecel",
    "apparentDecel",
    "tau",
    "collisionMinGapFactor",
    "speedControlGainCACC",
    "gapClosingControlGainGap",
    "gapClosingControlGainGapDot",
    "gapControlGainGap",
    "gapControlGainGapDot",
    "collisionAvoidanceGainGap",
    "collisionAvoidanceGainGapDot",
    "gapClosingControlGainSpeed",
    "gapClosingControlGainSpace",
    "gapControlGainSpeed",
    "gapControlGainSpace",
    "collisionAvoidanceGainSpeed",
    "collisionAvoidanceGainSpace",
    "tauCACCToACC",
    "applyDriverState",
];

impl CfModel {
    /// Every model of the table.
    pub const ALL: [CfModel; 15] = [
        CfModel::Krauss,
        CfModel::KraussOrig1,
        CfModel::KraussPS,
        CfModel::KraussX,
        CfModel::SmartSK,
        CfModel::Daniel1,
        CfModel::PWagner2009,
        CfModel::BKerner,
        CfModel::Idm,
        CfModel::Idmm,
        CfModel::Eidm,
        CfModel::Wiedemann,
        CfModel::W99,
        CfModel::Acc,
        CfModel::Cacc,
    ];

    /// The value of `carFollowModel`.
    pub fn sumo_name(self) -> &'static str {
        match self {
            CfModel::Krauss => "Krauss",
            CfModel::KraussOrig1 => "KraussOrig1",
            CfModel::KraussPS => "KraussPS",
            CfModel::KraussX => "KraussX",
            CfModel::SmartSK => "SmartSK",
            CfModel::Daniel1 => "Daniel1",
            CfModel::PWagner2009 => "PWagner2009",
            CfModel::BKerner => "BKerner",
            CfModel::Idm => "IDM",
            CfModel::Idmm => "IDMM",
            CfModel::Eidm => "EIDM",
            CfModel::Wiedemann => "Wiedemann",
            CfModel::W99 => "W99",
            CfModel::Acc => "ACC",
            CfModel::Cacc => "CACC",
        }
    }

    /// The model named `name` (SUMO's spelling, any case).
    pub fn from_sumo_name(name: &str) -> Option<CfModel> {
        let name = name.trim();
        Self::ALL
            .into_iter()
            .find(|m| m.sumo_name().eq_ignore_ascii_case(name))
    }

    /// The model's own parameters (SUMO attribute names), without [`VEHICLE_PARAMS`].
    pub fn model_params(self) -> &'static [&'static str] {
        match self {
            CfModel::Krauss | CfModel::KraussOrig1 | CfModel::KraussPS => KRAUSS,
            CfModel::KraussX => KRAUSS_X,
            CfModel::SmartSK | CfModel::Daniel1 => SMART_SK,
            CfModel::PWagner2009 => PWAGNER,
            CfModel::BKerner => BKERNER,
            CfModel::Idm => IDM,
            CfModel::Idmm => IDMM,
            CfModel::Eidm => EIDM,
            CfModel::Wiedemann => WIEDEMANN,
            CfModel::W99 => W99,
            CfModel::Acc => ACC,
            CfModel::Cacc => CACC,
        }
    }

    /// Whether a vehicle of this model takes the attribute `name`.
    pub fn accepts(self, name: &str) -> bool {
        VEHICLE_PARAMS.contains(&name) || self.model_params().contains(&name)
    }

    /// Every valid attribute name, the vehicle's then the model's.
    pub fn valid_names(self) -> Vec<&'static str> {
        VEHICLE_PARAMS
            .iter()
            .chain(self.model_params())
            .copied()
            .collect()
    }
}

impl fmt::Display for CfModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.sumo_name())
    }
}

/// The range a parameter must lie in.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Range {
    /// Finite, > 0.
    Positive,
    /// Finite, ≥ 0.
    NonNegative,
    /// In \[0, 1\].
    UnitInterval,
    /// 0 or 1.
    Flag,
    /// A whole number ≥ 1.
    PositiveInteger,
    /// Any finite number (gains, W99's cc's, experimental parameters).
    Finite,
}

impl Range {
    fn of(name: &str) -> Range {
        match name {
            "accel" | "decel" | "emergencyDecel" | "apparentDecel" | "tau" | "length"
            | "maxSpeed" | "speedFactor" | "actionStepLength" | "sigmaStep" | "stepping"
            | "delta" | "tpreview" | "tPersDrive" | "tPersEstimate" | "jerkmax" | "Mflatness"
            | "Mbegin" => Range::Positive,
            "minGap"
            | "speedDev"
            | "startupDelay"
            | "collisionMinGapFactor"
            | "treaction"
            | "sigmaleader"
            | "sigmagap"
            | "sigmaerror"
            | "epsilonacc"
            | "taccmax"
            | "adaptFactor"
            | "adaptTime"
            | "tauCACCToACC" => Range::NonNegative,
            "sigma" | "ccoolness" | "apProb" => Range::UnitInterval,
            "vehdynamics" => Range::Flag,
            "maxvehpreview" => Range::PositiveInteger,
            _ => Range::Finite,
        }
    }

    fn contains(self, x: f64) -> bool {
        match self {
            Range::Positive => x > 0.0,
            Range::NonNegative => x >= 0.0,
            Range::UnitInterval => (0.0..=1.0).contains(&x),
            Range::Flag => x == 0.0 || x == 1.0,
            Range::PositiveInteger => x >= 1.0 && x.fract() == 0.0,
            Range::Finite => true,
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Range::Positive => "a finite number > 0",
            Range::NonNegative => "a finite number ≥ 0",
            Range::UnitInterval => "a number in [0, 1]",
            Range::Flag => "0 or 1",
            Range::PositiveInteger => "a whole number ≥ 1",
            Range::Finite => "a finite number",
        }
    }
}

/// Errors naming the field, the value and what is valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CarFollowingError {
    /// Not a model of the table.
    #[error("{field}.model = {value:?}: unknown car-following model; valid: {valid}")]
    UnknownModel {
        /// Field path.
        field: String,
        /// The value.
        value: String,
        /// The valid names.
        valid: String,
    },
    /// A parameter the model does not take (SUMO would drop it silently).
    #[error("{field}.params.{name}: {model} has no parameter {name:?}; valid: {valid}")]
    UnknownParameter {
        /// Field path.
        field: String,
        /// The model.
        model: CfModel,
        /// The parameter.
        name: String,
        /// The valid names.
        valid: String,
    },
    /// A value outside its range (or NaN / infinite).
    #[error("{field}.params.{name} = {value}: valid is {valid}")]
    OutOfRange {
        /// Field path.
        field: String,
        /// The parameter.
        name: String,
        /// The value.
        value: f64,
        /// The valid range, in words.
        valid: String,
    },
    /// Not a named preset.
    #[error("{field} = {value:?}: unknown driver preset; valid: {valid}")]
    UnknownPreset {
        /// Field path.
        field: String,
        /// The value.
        value: String,
        /// The valid names.
        valid: String,
    },
}

/// A driver: a car-following model and the values of any of its parameters (the others keep
/// SUMO's defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CarFollowing {
    /// The model.
    pub model: CfModel,
    /// Parameter values by SUMO attribute name.
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
}

/// Named presets, see [`CarFollowing::preset`].
pub const PRESETS: &[&str] = &["human", "flow-idm"];

impl CarFollowing {
    /// A model with no parameters set.
    pub fn new(model: CfModel) -> Self {
        Self {
            model,
            params: BTreeMap::new(),
        }
    }

    /// A model with parameters (unchecked; call [`validate`](Self::validate)).
    pub fn with(model: CfModel, params: &[(&str, f64)]) -> Self {
        Self {
            model,
            params: params.iter().map(|&(k, v)| (k.to_string(), v)).collect(),
        }
    }

    /// Parses a model name for the field `field`.
    pub fn parse_model(field: &str, name: &str) -> Result<CfModel, CarFollowingError> {
        CfModel::from_sumo_name(name).ok_or_else(|| CarFollowingError::UnknownModel {
            field: field.into(),
            value: name.into(),
            valid: CfModel::ALL.map(CfModel::sumo_name).join(", "),
        })
    }

    /// A named preset. Every value's source is documented in `docs/human-preset.md`:
    /// * `human` — SUMO's IDM calibrated on the Sugiyama ring (22 vehicles, 230 m): from a
    ///   near-uniform start a stop-and-go jam forms by itself (first vehicle below 1 m/s at
    ///   254–358 s over 10 seeds), vehicles stop in it, and it travels backward at 17.6 km/h
    ///   (Sugiyama et al. 2008: about 20 km/h). Flow's IDM ring values (a = 1 m/s²,
    ///   b = 1.5 m/s², T = 1 s, s0 = 2 m, δ = 4, v0 = 30 m/s) with a = 1.3 m/s² and T = 0.8 s,
    ///   which move the wave from 15.3 km/h (the low edge of the target) to 17.6 km/h;
    ///   length 5 m.
    /// * `flow-idm` — Flow's `IDMController` defaults unchanged, run by SUMO's IDM (without
    ///   Flow's acceleration noise, which SUMO's IDM does not have): wave 15.3 km/h.
    pub fn preset(field: &str, name: &str) -> Result<CarFollowing, CarFollowingError> {
        let idm = |accel: f64, tau: f64| {
            CarFollowing::with(
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
            )
        };
        match name.trim().to_ascii_lowercase().as_str() {
            "human" => Ok(idm(1.3, 0.8)),
            "flow-idm" => Ok(idm(1.0, 1.0)),
            _ => Err(CarFollowingError::UnknownPreset {
                field: field.into(),
                value: name.into(),
                valid: PRESETS.join(", "),
            }),
        }
    }

    /// Checks every parameter for a simulation with step `step_s`: known to the model
    /// (else the error lists the valid names), finite, in range; `emergencyDecel ≥ decel`
    /// when both are set; `actionStepLength` a whole multiple of the step (SUMO would round it).
    /// `field` is the path of this driver in the user's input, used in every message.
    pub fn validate(&self, field: &str, step_s: f64) -> Result<(), CarFollowingError> {
        let out_of_range = |name: &str, value: f64, valid: String| CarFollowingError::OutOfRange {
            field: field.into(),
            name: name.into(),
            value,
            valid,
        };
        for (name, &value) in &self.params {
            if !self.model.accepts(name) {
                return Err(CarFollowingError::UnknownParameter {
                    field: field.into(),
                    model: self.model,
                    name: name.clone(),
                    valid: self.model.valid_names().join(", "),
                });
            }
            let range = Range::of(name);
            if !value.is_finite() || !range.contains(value) {
                return Err(out_of_range(name, value, range.describe().into()));
            }
        }
        if let (Some(&decel), Some(&emergency)) =
            (self.params.get("decel"), self.params.get("emergencyDecel"))
        {
            if emergency < decel {
                return Err(out_of_range(
                    "emergencyDecel",
                    emergency,
                    format!("≥ decel = {decel} m/s²"),
                ));
            }
        }
        if let Some(&asl) = self.params.get("actionStepLength") {
            let steps = asl / step_s;
            if steps < 1.0 - 1e-9 || (steps - steps.round()).abs() > 1e-9 {
                return Err(out_of_range(
                    "actionStepLength",
                    asl,
                    format!("a whole multiple ≥ 1 of the step {step_s} s"),
                ));
            }
        }
        Ok(())
    }

    /// The `carFollowModel` and parameter attributes of a `<vType>` element, parameters in
    /// name order, numbers in their shortest exact decimal form.
    pub fn vtype_attributes(&self) -> String {
        let mut s = format!(r#"carFollowModel="{}""#, self.model.sumo_name());
        for (name, value) in &self.params {
            s.push_str(&format!(r#" {name}="{value}""#));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drivers::SumoDriver;

    /// Output of `python-host/check_car_following.py` against SUMO 1.28.0 (the eclipse-sumo
    /// and libsumo wheels): `<vType>` attributes of SUMO's schema.
    const SUMO_1_28_VTYPE_ATTRIBUTES: &str = "Mbegin Mflatness accel actionStepLength adaptFactor \
        adaptTime apProb apparentDecel applyDriverState boardingDuration boardingFactor c1 \
        carFollowModel cc1 cc2 cc3 cc4 cc5 cc6 cc7 cc8 cc9 ccAccel ccDecel ccoolness \
        collisionAvoidanceGainGap collisionAvoidanceGainGapDot collisionAvoidanceGainSpace \
        collisionAvoidanceGainSpeed collisionAvoidanceOverride collisionMinGapFactor color \
        constSpacing containerCapacity curveIntegration curveResistance decel delta \
        desAccelProfile desiredMaxSpeed emergencyDecel emissionClass epsilonacc estimation \
        flatbedD flatbedH flatbedKa flatbedKp flatbedKv gapClosingControlGainGap \
        gapClosingControlGainGapDot gapClosingControlGainSpace gapClosingControlGainSpeed \
        gapControlGainGap gapControlGainGapDot gapControlGainSpace gapControlGainSpeed guiShape \
        hasDriverState height imgFile impatience jerkmax k kp lambda laneChangeModel lanesCount \
        latAlignment length loadingDuration maneuverAngleTimes mass massFactor maxAccelProfile \
        maxPower maxSpeed maxSpeedLat maxTraction maxvehpreview minGap minGapLat omegaN osgFile \
        parkingBadges personCapacity phi ploegH ploegKd ploegKp probability refId \
        resCoef_constant resCoef_linear resCoef_quadratic resistanceTable scale security sigma \
        sigmaStep sigmaerror sigmagap sigmaleader speedControlGain speedControlGainCACC \
        speedControlMinGap speedDev speedFactor speedFactorPremature speedTable startupDelay \
        stepping tPersDrive tPersEstimate taccmax tau tauCACCToACC tauEngine tauLast \
        timeToTeleport timeToTeleportBidi tmp1 tmp2 tmp3 tmp4 tmp5 tpreview tractionTable \
        trainType treaction vClass vehdynamics width xi";
    /// Same script: models whose `sigma` reaches the vehicle in SUMO 1.28.0.
    const SUMO_1_28_SIGMA_APPLIED: &[&str] = &[
        "Krauss",
        "KraussOrig1",
        "KraussPS",
        "KraussX",
        "SmartSK",
        "Daniel1",
        "PWagner2009",
    ];
    /// Same script: models whose `accel` reaches the vehicle in SUMO 1.28.0 (all but W99).
    const SUMO_1_28_ACCEL_IGNORED: &[&str] = &["W99"];

    #[test]
    fn every_name_in_the_table_is_a_vtype_attribute_of_sumo_1_28() {
        let known: Vec<&str> = SUMO_1_28_VTYPE_ATTRIBUTES.split_whitespace().collect();
        for m in CfModel::ALL {
            for name in m.valid_names() {
                assert!(
                    known.contains(&name),
                    "{m}: {name} is not a SUMO 1.28 vType attribute"
                );
            }
        }
    }

    #[test]
    fn sigma_and_accel_belong_to_the_models_sumo_applies_them_to() {
        for m in CfModel::ALL {
            assert_eq!(
                m.accepts("sigma"),
                SUMO_1_28_SIGMA_APPLIED.contains(&m.sumo_name()),
                "sigma for {m}"
            );
            assert_eq!(
                m.accepts("accel"),
                !SUMO_1_28_ACCEL_IGNORED.contains(&m.sumo_name()),
                "accel for {m}"
            );
        }
    }

    #[test]
    fn model_specific_parameters_follow_sumos_parser() {
        // SUMOVehicleParserHelper::getAllowedCFModelAttrs: IDM takes delta and stepping,
        // EIDM 16 more, W99 cc1..cc9, ACC/CACC their gains; nobody else takes them.
        let owners = |name: &str| -> Vec<&str> {
            CfModel::ALL
                .into_iter()
                .filter(|m| m.model_params().contains(&name))
                .map(CfModel::sumo_name)
                .collect()
        };
        assert_eq!(owners("delta"), ["IDM", "EIDM"]);
        assert_eq!(owners("stepping"), ["IDM", "IDMM", "EIDM"]);
        assert_eq!(owners("treaction"), ["EIDM"]);
        assert_eq!(owners("cc9"), ["W99"]);
        assert_eq!(owners("speedControlGain"), ["ACC"]);
        assert_eq!(owners("gapControlGainSpeed"), ["ACC", "CACC"]);
        assert_eq!(owners("tauCACCToACC"), ["CACC"]);
        assert_eq!(owners("tmp1"), ["KraussX", "SmartSK", "Daniel1"]);
        assert_eq!(owners("k"), ["BKerner"]);
        assert_eq!(owners("security"), ["Wiedemann"]);
        assert_eq!(owners("adaptTime"), ["IDMM"]);
        assert_eq!(owners("tauLast"), ["PWagner2009"]);
        assert_eq!(EIDM.len(), 23);
    }

    #[test]
    fn an_unknown_parameter_is_rejected_with_the_valid_names() {
        let d = CarFollowing::with(CfModel::Idm, &[("sigma", 0.5)]);
        let msg = d.validate("drivers.human", 0.1).unwrap_err().to_string();
        assert_eq!(
            msg,
            "drivers.human.params.sigma: IDM has no parameter \"sigma\"; valid: length, minGap, \
             maxSpeed, speedFactor, speedDev, actionStepLength, startupDelay, accel, decel, \
             emergencyDecel, apparentDecel, tau, collisionMinGapFactor, delta, stepping"
        );
        let typo = CarFollowing::with(CfModel::Krauss, &[("sigam", 0.5)]);
        assert!(matches!(
            typo.validate("x", 0.1),
            Err(CarFollowingError::UnknownParameter { ref name, .. }) if name == "sigam"
        ));
    }

    #[test]
    fn values_must_be_finite_and_in_range() {
        let check = |model, name: &str, value: f64| {
            CarFollowing::with(model, &[(name, value)])
                .validate("d", 0.1)
                .map_err(|e| e.to_string())
        };
        assert_eq!(
            check(CfModel::Krauss, "sigma", 1.5),
            Err("d.params.sigma = 1.5: valid is a number in [0, 1]".into())
        );
        assert_eq!(
            check(CfModel::Idm, "decel", 0.0),
            Err("d.params.decel = 0: valid is a finite number > 0".into())
        );
        assert_eq!(
            check(CfModel::Idm, "tau", f64::NAN),
            Err("d.params.tau = NaN: valid is a finite number > 0".into())
        );
        assert_eq!(
            check(CfModel::Acc, "speedControlGain", f64::INFINITY),
            Err("d.params.speedControlGain = inf: valid is a finite number".into())
        );
        assert!(check(CfModel::Acc, "speedControlGain", -0.4).is_ok());
        assert!(check(CfModel::Eidm, "maxvehpreview", 2.5).is_err());
        assert!(check(CfModel::Eidm, "vehdynamics", 1.0).is_ok());
        assert_eq!(
            check(CfModel::Idm, "actionStepLength", 0.05),
            Err(
                "d.params.actionStepLength = 0.05: valid is a whole multiple ≥ 1 of the step 0.1 s"
                    .into()
            )
        );
        assert_eq!(
            check(CfModel::Idm, "actionStepLength", 0.25),
            Err(
                "d.params.actionStepLength = 0.25: valid is a whole multiple ≥ 1 of the step 0.1 s"
                    .into()
            )
        );
        assert!(check(CfModel::Idm, "actionStepLength", 0.3).is_ok());
        let d = CarFollowing::with(CfModel::Krauss, &[("decel", 4.5), ("emergencyDecel", 3.0)]);
        assert_eq!(
            d.validate("d", 0.1).unwrap_err().to_string(),
            "d.params.emergencyDecel = 3: valid is ≥ decel = 4.5 m/s²"
        );
    }

    #[test]
    fn model_names_parse_in_any_case_and_unknown_ones_list_the_valid() {
        assert_eq!(CarFollowing::parse_model("m", "eidm"), Ok(CfModel::Eidm));
        assert_eq!(CarFollowing::parse_model("m", "W99"), Ok(CfModel::W99));
        let err = CarFollowing::parse_model("drivers.h", "Rail").unwrap_err();
        assert_eq!(
            err.to_string(),
            "drivers.h.model = \"Rail\": unknown car-following model; valid: Krauss, KraussOrig1, \
             KraussPS, KraussX, SmartSK, Daniel1, PWagner2009, BKerner, IDM, IDMM, EIDM, \
             Wiedemann, W99, ACC, CACC"
        );
        for m in CfModel::ALL {
            assert_eq!(CfModel::from_sumo_name(m.sumo_name()), Some(m));
            // serde uses SUMO's spelling too.
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{}\"", m.sumo_name()));
        }
    }

    #[test]
    fn presets_are_valid_and_render_their_attributes() {
        let human = CarFollowing::preset("driver", "human").unwrap();
        human.validate("driver", 0.1).unwrap();
        assert_eq!(
            human.vtype_attributes(),
            r#"carFollowModel="IDM" accel="1.3" decel="1.5" delta="4" length="5" maxSpeed="30" minGap="2" tau="0.8""#
        );
        let flow = CarFollowing::preset("driver", "flow-idm").unwrap();
        assert_eq!(flow.params["accel"], 1.0);
        assert_eq!(flow.params["tau"], 1.0);
        assert_eq!(
            CarFollowing::preset("driver", "sugiyama")
                .unwrap_err()
                .to_string(),
            "driver = \"sugiyama\": unknown driver preset; valid: human, flow-idm"
        );
    }

    #[test]
    fn todays_driver_names_render_the_same_attributes() {
        for name in ["krauss", "krauss-0.9", "idm", "acc", "cacc"] {
            let d = SumoDriver::parse("--baselines", name).unwrap();
            let cf = d.car_following();
            cf.validate("--baselines", 0.1).unwrap();
            assert_eq!(cf.vtype_attributes(), d.vtype_attributes(), "{name}");
        }
    }

    #[test]
    fn serde_round_trip_and_unknown_fields_are_refused() {
        let d = CarFollowing::preset("d", "human").unwrap();
        let json = serde_json::to_string(&d).unwrap();
        assert_eq!(serde_json::from_str::<CarFollowing>(&json).unwrap(), d);
        assert!(serde_json::from_str::<CarFollowing>(r#"{"model":"IDM","parms":{}}"#).is_err());
        assert!(serde_json::from_str::<CarFollowing>(r#"{"model":"Foo"}"#).is_err());
    }
}
