//! The field's wave dampers as ring controllers: a [`SpeedController`] that runs the
//! FollowerStopper or the PI controller with saturation of Stern et al. (2018) on every vehicle
//! of a ring, so that a SUMO run (or a mixed ring, where only some vehicles take its commands)
//! drives them through the same bridge as the synchronization law.
//!
//! Each vehicle i follows vehicle i−1 (vehicle 0 follows vehicle N−1, one lap ahead). From the
//! unwrapped rear-bumper positions `q` the controller forms the bumper-to-bumper gap
//! `Δx_i = q_{i−1} − q_i − ℓ_i` (`+ C` for vehicle 0, C the ring's circumference as the backend
//! measures it) and the leader's speed `v_{i−1}`, and steps the fleet law, which tracks each
//! command velocity within the vehicle's acceleration bounds ([`AccelLimits`]).
//!
//! # Reference
//! R. E. Stern et al., "Dissipation of stop-and-go waves via control of autonomous vehicles:
//! Field experiments", Transp. Res. C 89 (2018) 205–221.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::actuation::AccelLimits;
use crate::flow_dampers::{FlowFollowerStopper, FlowPiSaturation};
use crate::follower_stopper::{FollowerStopper, FollowerStopperError, FollowerStopperParams};
use crate::pi_saturation::{PiSaturation, PiSaturationError, PiSaturationParams};
use crate::road::RingView;
use crate::speed_controller::SpeedController;

/// Which damper, with the parameters a user chooses (the rest are the field experiment's).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum DamperSpec {
    /// FollowerStopper with desired speed U and the field experiment's bands
    /// ([`FollowerStopperParams::stern2018`]).
    FollowerStopper {
        /// Desired speed U \[m/s\].
        desired_speed_mps: f64,
    },
    /// PI with saturation with the field experiment's parameters
    /// ([`PiSaturationParams::default`]).
    PiSaturation,
    /// Flow's master FollowerStopper ([`crate::flow_dampers`]) with desired speed U.
    FlowFollowerStopper {
        /// Desired speed U \[m/s\].
        desired_speed_mps: f64,
    },
    /// Flow's master PISaturation ([`crate::flow_dampers`]).
    FlowPiSaturation,
}

/// Errors naming a damper.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DamperError {
    /// Not a damper name.
    #[error("{field} = {value}: unknown controller; use law, follower-stopper-U with the desired speed U in m/s (e.g. follower-stopper-4.3), pi-saturation, or Flow's versions flow-follower-stopper-U, flow-pi-saturation")]
    Unknown {
        /// Flag or field.
        field: String,
        /// The value.
        value: String,
    },
    /// FollowerStopper parameters.
    #[error("{field}: {source}")]
    FollowerStopper {
        /// Flag or field.
        field: String,
        /// The cause.
        source: FollowerStopperError,
    },
    /// PI parameters.
    #[error("{field}: {source}")]
    PiSaturation {
        /// Flag or field.
        field: String,
        /// The cause.
        source: PiSaturationError,
    },
    /// The dampers follow a predecessor around a ring.
    #[error("{damper}: the wave dampers drive on a ring (each vehicle follows its predecessor); {road} is a straight road")]
    NotARing {
        /// The damper.
        damper: String,
        /// The road: `scenario NAME`, or `this road`.
        road: String,
    },
}

impl DamperSpec {
    /// The one check that a damper has a ring to drive on: every command and the SUMO run ask
    /// it, so the refusal reads the same everywhere. `road` names the road in the message
    /// (`scenario NAME`).
    pub fn require_ring(&self, ring: bool, road: &str) -> Result<(), DamperError> {
        if ring {
            Ok(())
        } else {
            Err(DamperError::NotARing {
                damper: self.to_string(),
                road: road.to_string(),
            })
        }
    }

    /// Parses `follower-stopper-U` (U in m/s) or `pi-saturation`; `Ok(None)` for `law`.
    /// `field` names the flag or field in errors.
    pub fn parse(field: &str, s: &str) -> Result<Option<Self>, DamperError> {
        let low = s.trim().to_ascii_lowercase();
        let d = match low.as_str() {
            "law" => return Ok(None),
            "pi-saturation" | "pi_saturation" => DamperSpec::PiSaturation,
            "flow-pi-saturation" => DamperSpec::FlowPiSaturation,
            _ => match (
                low.strip_prefix("follower-stopper-")
                    .and_then(|u| u.parse::<f64>().ok()),
                low.strip_prefix("flow-follower-stopper-")
                    .and_then(|u| u.parse::<f64>().ok()),
            ) {
                (Some(u), _) => DamperSpec::FollowerStopper {
                    desired_speed_mps: u,
                },
                (_, Some(u)) => DamperSpec::FlowFollowerStopper {
                    desired_speed_mps: u,
                },
                (None, None) => {
                    return Err(DamperError::Unknown {
                        field: field.into(),
                        value: s.into(),
                    })
                }
            },
        };
        d.validate(field)?;
        Ok(Some(d))
    }

    /// Checks the parameters; `field` names where they were given.
    pub fn validate(&self, field: &str) -> Result<(), DamperError> {
        match self {
            DamperSpec::FollowerStopper { desired_speed_mps }
            | DamperSpec::FlowFollowerStopper { desired_speed_mps } => {
                FollowerStopperParams::stern2018(*desired_speed_mps)
                    .validate()
                    .map_err(|source| DamperError::FollowerStopper {
                        field: field.into(),
                        source,
                    })
            }
            DamperSpec::PiSaturation | DamperSpec::FlowPiSaturation => {
                PiSaturationParams::default().validate().map_err(|source| {
                    DamperError::PiSaturation {
                        field: field.into(),
                        source,
                    }
                })
            }
        }
    }
}

impl fmt::Display for DamperSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DamperSpec::FollowerStopper { desired_speed_mps } => {
                write!(f, "follower-stopper-{desired_speed_mps}")
            }
            DamperSpec::PiSaturation => write!(f, "pi-saturation"),
            DamperSpec::FlowFollowerStopper { desired_speed_mps } => {
                write!(f, "flow-follower-stopper-{desired_speed_mps}")
            }
            DamperSpec::FlowPiSaturation => write!(f, "flow-pi-saturation"),
        }
    }
}

/// A damper on a ring, resolved by the backend: what the controller needs besides the states.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DamperSetup {
    /// The damper.
    pub spec: DamperSpec,
    /// Circumference C of the ring as the backend measures it \[m\].
    pub ring_length_m: f64,
    /// Vehicle lengths ℓ_i \[m\].
    pub length_m: Vec<f64>,
    /// Largest acceleration of the tracking \[m/s²\].
    pub accel_mps2: f64,
    /// Largest deceleration of the tracking \[m/s²\].
    pub decel_mps2: f64,
}

enum Fleet {
    FollowerStopper(FollowerStopper),
    PiSaturation(PiSaturation),
    FlowFollowerStopper(FlowFollowerStopper),
    FlowPiSaturation(FlowPiSaturation),
}

/// A damper driving every vehicle of a ring (a mixed ring sends only some of its commands).
pub struct DamperController {
    fleet: Fleet,
    view: RingView,
}

impl DamperController {
    /// A checked controller with step `dt_s`.
    pub fn new(setup: &DamperSetup, dt_s: f64) -> Result<Self, DamperError> {
        let n = setup.length_m.len();
        let limits = AccelLimits {
            accel_mps2: setup.accel_mps2,
            decel_mps2: setup.decel_mps2,
        };
        let field = "damper";
        let fleet = match setup.spec {
            DamperSpec::FollowerStopper { desired_speed_mps } => Fleet::FollowerStopper(
                FollowerStopper::new(
                    FollowerStopperParams::stern2018(desired_speed_mps),
                    n,
                    dt_s,
                    limits,
                )
                .map_err(|source| DamperError::FollowerStopper {
                    field: field.into(),
                    source,
                })?,
            ),
            DamperSpec::PiSaturation => Fleet::PiSaturation(
                PiSaturation::new(PiSaturationParams::default(), n, dt_s, limits).map_err(
                    |source| DamperError::PiSaturation {
                        field: field.into(),
                        source,
                    },
                )?,
            ),
            DamperSpec::FlowFollowerStopper { desired_speed_mps } => Fleet::FlowFollowerStopper(
                FlowFollowerStopper::new(FollowerStopperParams::stern2018(desired_speed_mps), dt_s),
            ),
            DamperSpec::FlowPiSaturation => Fleet::FlowPiSaturation(FlowPiSaturation::new(
                PiSaturationParams::default(),
                n,
                dt_s,
                setup.accel_mps2,
            )),
        };
        setup.spec.validate(field)?;
        Ok(Self {
            fleet,
            view: RingView::new(setup.ring_length_m, &setup.length_m),
        })
    }
}

impl SpeedController for DamperController {
    fn step(&mut self, _t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        self.view.observe(speeds, positions);
        // The slices have the fleet's length by construction; a mismatch is a bug in the
        // caller, reported as NaN commands, which the loop stops on before they reach SUMO.
        let ok = match &mut self.fleet {
            Fleet::FollowerStopper(f) => f
                .step(speeds, &self.view.gaps_m, &self.view.leader_speeds_mps, out)
                .is_ok(),
            Fleet::PiSaturation(p) => p
                .step(speeds, &self.view.gaps_m, &self.view.leader_speeds_mps, out)
                .is_ok(),
            Fleet::FlowFollowerStopper(f) => {
                f.step(speeds, &self.view.gaps_m, &self.view.leader_speeds_mps, out);
                true
            }
            Fleet::FlowPiSaturation(p) => {
                p.step(speeds, &self.view.gaps_m, &self.view.leader_speeds_mps, out);
                true
            }
        };
        if !ok {
            out.fill(f64::NAN);
        }
    }

    fn sense(&mut self, neighbors: &crate::sensed::Neighbors) {
        self.view.sense(neighbors);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn setup(spec: DamperSpec) -> DamperSetup {
        DamperSetup {
            spec,
            ring_length_m: 100.0,
            length_m: vec![5.0; 3],
            accel_mps2: f64::INFINITY,
            decel_mps2: f64::INFINITY,
        }
    }

    #[test]
    fn names_parse_and_round_trip() {
        assert_eq!(DamperSpec::parse("--x", "law").unwrap(), None);
        let fs = DamperSpec::parse("--x", "follower-stopper-4.3")
            .unwrap()
            .unwrap();
        assert_eq!(
            fs,
            DamperSpec::FollowerStopper {
                desired_speed_mps: 4.3
            }
        );
        assert_eq!(fs.to_string(), "follower-stopper-4.3");
        for flow in ["flow-follower-stopper-4.3", "flow-pi-saturation"] {
            let d = DamperSpec::parse("--x", flow).unwrap().unwrap();
            assert_eq!(d.to_string(), flow);
        }
        assert_eq!(
            DamperSpec::parse("--x", "PI-saturation").unwrap(),
            Some(DamperSpec::PiSaturation)
        );
        let e = DamperSpec::parse("--x", "follower-stopper").unwrap_err();
        assert!(
            e.to_string().starts_with(
                "--x = follower-stopper: unknown controller; use law, follower-stopper-U"
            ),
            "{e}"
        );
        let e = DamperSpec::parse("--x", "follower-stopper--1").unwrap_err();
        assert_eq!(
            e.to_string(),
            "--x: FollowerStopper desired_speed_mps = -1: valid is a finite number ≥ 0 m/s"
        );
    }

    #[test]
    fn ring_gaps_wrap_and_commands_follow_the_bands() {
        // Three 5 m cars on a 100 m ring, rear bumpers at 60, 40, 10: gaps
        // vehicle 1: 60 − 40 − 5 = 15, vehicle 2: 40 − 10 − 5 = 25,
        // vehicle 0 (follows 2 one lap ahead): 10 + 100 − 60 − 5 = 45.
        let mut c = DamperController::new(
            &setup(DamperSpec::FollowerStopper {
                desired_speed_mps: 8.0,
            }),
            0.1,
        )
        .unwrap();
        let q = [60.0, 40.0, 10.0];
        let v = [5.0, 5.0, 5.0];
        let mut out = [0.0; 3];
        c.step(0.0, &v, &q, &mut out);
        assert_eq!(c.view.gaps_m, [45.0, 15.0, 25.0]);
        assert_eq!(c.view.leader_speeds_mps, [5.0, 5.0, 5.0]);
        // Every gap is beyond Δx_3 = 6 m with Δv = 0: command U = 8, reached in one step.
        assert_eq!(out, [8.0, 8.0, 8.0]);
        // Vehicle 1 closer: gap 5.625 m (q = 60 − 5 − 5.625 = 49.375) lies in the third band
        // (5.25, 6]: v = min(v_lead, U) = 5, command 5 + (8 − 5)·(5.625 − 5.25)/0.75 = 6.5.
        let q = [60.0, 49.375, 10.0];
        c.step(0.1, &v, &q, &mut out);
        assert_relative_eq!(out[1], 6.5, epsilon = 1e-12);
    }

    #[test]
    fn pi_saturation_on_the_ring_saturates_to_the_leader_at_a_small_gap() {
        // Gap below the safe gap Δx_s = max(2 Δv, 4) = 4 m: α = 0, β = 1, command = v_lead.
        let mut c = DamperController::new(&setup(DamperSpec::PiSaturation), 0.1).unwrap();
        // Vehicle 1 is 3 m behind vehicle 0 (q = 60 − 5 − 3 = 52); vehicle 0 drives 4 m/s.
        let q = [60.0, 52.0, 10.0];
        let v = [4.0, 6.0, 6.0];
        let mut out = [0.0; 3];
        c.step(0.0, &v, &q, &mut out);
        assert_relative_eq!(out[1], 4.0, epsilon = 1e-12);
    }
}
