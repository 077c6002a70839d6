//! The table: SUMO's car-following models and the `<vType>` attributes its parser hands to
//! each (see the parent module for where the table comes from).

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
