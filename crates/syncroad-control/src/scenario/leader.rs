//! The leader's speed profile over time (CACC platoons).

use serde::{Deserialize, Serialize};

use super::{invalid, ScenarioError};

/// The leader's speed over time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum LeaderProfile {
    /// Constant speed v_0.
    Constant {
        /// v_0 [m/s].
        speed_mps: f64,
    },
    /// Cruise at v_0, brake at `decel_mps2` from `start_s` down to `low_mps`, hold for `hold_s`,
    /// then accelerate back at `accel_mps2`.
    BrakeAndRecover {
        /// Cruise speed [m/s].
        speed_mps: f64,
        /// Start of braking [s].
        start_s: f64,
        /// Lowest speed [m/s].
        low_mps: f64,
        /// Braking deceleration (positive) [m/s²].
        decel_mps2: f64,
        /// Time at the low speed [s].
        hold_s: f64,
        /// Acceleration back to cruise [m/s²].
        accel_mps2: f64,
    },
    /// Piecewise-linear speed through `(t, v)` points, constant outside.
    Points {
        /// `[t_s, v_mps]` pairs with increasing times.
        points: Vec<[f64; 2]>,
    },
}

impl LeaderProfile {
    /// Leader speed at time `t` [m/s].
    pub fn speed_at(&self, t: f64) -> f64 {
        match self {
            LeaderProfile::Constant { speed_mps } => *speed_mps,
            LeaderProfile::BrakeAndRecover {
                speed_mps,
                start_s,
                low_mps,
                decel_mps2,
                hold_s,
                accel_mps2,
            } => {
                let t_brake = (speed_mps - low_mps) / decel_mps2;
                let t_acc = (speed_mps - low_mps) / accel_mps2;
                let t1 = start_s + t_brake;
                let t2 = t1 + hold_s;
                if t < *start_s {
                    *speed_mps
                } else if t < t1 {
                    speed_mps - decel_mps2 * (t - start_s)
                } else if t < t2 {
                    *low_mps
                } else if t < t2 + t_acc {
                    low_mps + accel_mps2 * (t - t2)
                } else {
                    *speed_mps
                }
            }
            LeaderProfile::Points { points } => {
                let first = points[0];
                let last = points[points.len() - 1];
                if t <= first[0] {
                    return first[1];
                }
                if t >= last[0] {
                    return last[1];
                }
                let k = points.partition_point(|p| p[0] <= t);
                let (a, b) = (points[k - 1], points[k]);
                a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0])
            }
        }
    }

    /// Initial (t = 0) leader speed [m/s].
    pub fn initial_speed(&self) -> f64 {
        self.speed_at(0.0)
    }

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
