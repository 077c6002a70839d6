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
//! Attributes of the vehicle rather than of the model
//! ([`VEHICLE_PARAMS`](models::VEHICLE_PARAMS): `length`, `minGap`, `maxSpeed`, `speedFactor`,
//! `speedDev`, `actionStepLength`, `startupDelay`) are valid for every model. Not covered:
//! `Rail` (its `trainType` is a name, not a number), `CC` (needs a platooning setup), the
//! newest ACC/CACC attributes whose model scope could not be confirmed
//! (`speedControlMinGap`, `collisionAvoidanceOverride`), distributions in `speedFactor`.
//!
//! The folder: `models` (the table of models and their parameters), `range` (the range each
//! parameter's value must lie in) and this file, a driver ([`CarFollowing`]) and its checks.
//!
//! # Reference
//! SUMO documentation, "Definition of Vehicles, Vehicle Types, and Routes", section
//! Car-Following Models, and "Car-Following-Models" (eclipse-sumo/sumo, `docs/web/docs`).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

mod models;
mod range;

pub use models::CfModel;
use range::Range;

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

    /// Checks every parameter for a simulation with step `step_s`: known to the model
    /// (else the error lists the valid names), finite, in range; `emergencyDecel ≥ decel`
    /// when both are set; `actionStepLength` a whole multiple of the step (SUMO would round it).
    /// `field` is the path of this driver in the user's input, used in every message.
    pub fn validate(&self, field: &str, step_s: f64) -> Result<(), CarFollowingError> {
        self.check_values(field)?;
        if let Some(&asl) = self.params.get("actionStepLength") {
            let steps = asl / step_s;
            if steps < 1.0 - 1e-9 || (steps - steps.round()).abs() > 1e-9 {
                return Err(CarFollowingError::OutOfRange {
                    field: field.into(),
                    name: "actionStepLength".into(),
                    value: asl,
                    valid: format!("a whole multiple ≥ 1 of the step {step_s} s"),
                });
            }
        }
        Ok(())
    }

    /// The checks of [`validate`](Self::validate) that need no step: names the model knows,
    /// finite values in range, `emergencyDecel ≥ decel`.
    pub fn check_values(&self, field: &str) -> Result<(), CarFollowingError> {
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
    fn serde_round_trip_and_unknown_fields_are_refused() {
        let d = CarFollowing::with(CfModel::Idm, &[("accel", 1.3), ("tau", 0.8)]);
        let json = serde_json::to_string(&d).unwrap();
        assert_eq!(serde_json::from_str::<CarFollowing>(&json).unwrap(), d);
        assert!(serde_json::from_str::<CarFollowing>(r#"{"model":"IDM","parms":{}}"#).is_err());
        assert!(serde_json::from_str::<CarFollowing>(r#"{"model":"Foo"}"#).is_err());
    }
}
