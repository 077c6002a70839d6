//! The range each parameter's value must lie in, by SUMO attribute name.

/// The range a parameter must lie in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Range {
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
    pub(super) fn of(name: &str) -> Range {
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

    pub(super) fn contains(self, x: f64) -> bool {
        match self {
            Range::Positive => x > 0.0,
            Range::NonNegative => x >= 0.0,
            Range::UnitInterval => (0.0..=1.0).contains(&x),
            Range::Flag => x == 0.0 || x == 1.0,
            Range::PositiveInteger => x >= 1.0 && x.fract() == 0.0,
            Range::Finite => true,
        }
    }

    pub(super) fn describe(self) -> &'static str {
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
