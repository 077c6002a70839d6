//! The checks of a leader's speed profile (CACC platoons; the profile itself is
//! [`crate::model::LeaderProfile`]).

use super::{invalid, ScenarioError};

pub use crate::model::LeaderProfile;

impl LeaderProfile {
    pub(crate) fn validate(&self) -> Result<(), ScenarioError> {
        let f = "model.leader";
        let nonneg = |name: &str, x: f64| -> Result<(), ScenarioError> {
            if !x.is_finite() || x < 0.0 {
                return Err(invalid(
                    format!("{f}.{name}"),
                    x,
                    "must be a finite number ≥ 0",
                ));
            }
            Ok(())
        };
        // A speed: ≥ 0 and at most MAX_SPEED_MPS.
        let speed = |name: &str, x: f64| -> Result<(), ScenarioError> {
            nonneg(name, x)?;
            if x > super::MAX_SPEED_MPS {
                return Err(invalid(
                    format!("{f}.{name}"),
                    x,
                    format!("must be at most {} m/s", super::MAX_SPEED_MPS),
                ));
            }
            Ok(())
        };
        match self {
            LeaderProfile::Constant { speed_mps } => speed("speed_mps", *speed_mps),
            LeaderProfile::BrakeAndRecover {
                speed_mps,
                start_s,
                low_mps,
                decel_mps2,
                hold_s,
                accel_mps2,
            } => {
                speed("speed_mps", *speed_mps)?;
                nonneg("start_s", *start_s)?;
                speed("low_mps", *low_mps)?;
                nonneg("hold_s", *hold_s)?;
                for (name, x) in [("decel_mps2", *decel_mps2), ("accel_mps2", *accel_mps2)] {
                    if !x.is_finite() || x <= 0.0 {
                        return Err(invalid(
                            format!("{f}.{name}"),
                            x,
                            "must be a finite number > 0",
                        ));
                    }
                }
                if low_mps > speed_mps {
                    return Err(invalid(
                        format!("{f}.low_mps"),
                        low_mps,
                        format!("must not exceed speed_mps = {speed_mps}"),
                    ));
                }
                Ok(())
            }
            LeaderProfile::Points { points } => {
                if points.is_empty() {
                    return Err(invalid(
                        format!("{f}.points"),
                        "[]",
                        "needs at least one [t_s, v_mps] pair",
                    ));
                }
                for (k, p) in points.iter().enumerate() {
                    nonneg(&format!("points[{k}][0]"), p[0])?;
                    speed(&format!("points[{k}][1]"), p[1])?;
                    if k > 0 && p[0] <= points[k - 1][0] {
                        return Err(invalid(
                            format!("{f}.points[{k}][0]"),
                            p[0],
                            format!("times must increase (previous is {})", points[k - 1][0]),
                        ));
                    }
                }
                Ok(())
            }
        }
    }
}
