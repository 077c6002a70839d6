//! The seam between the laws of `syncroad-control` and the SUMO loop.
//!
//! A [`SpeedController`] sees what SUMO measured at step n for every SUMO vehicle (speeds and
//! unwrapped rear-bumper positions) and returns the speeds wanted at step n+1. The adapters
//! here wrap the very law objects the native simulator drives, so a scenario run natively and
//! in SUMO uses the same law code.
//!
//! # Timing (measured with libsumo 1.28.0, see `tests/sumo.rs::actuation_timing`)
//! A speed set with `setSpeed` (speed mode 32) before `simulationStep` is the speed `getSpeed`
//! reports right after that step, exactly. So the SUMO loop adds no latency of its own: the
//! law's `v^{n+1}` computed from `v^n` is realised at step n+1, and the driver delay
//! α_i = m_i Δt of eq. `chandler+` lives only in the law's delay buffer, exactly as in the native
//! simulator. With `--step-method.ballistic` SUMO advances positions by
//! `x^{n+1} = x^n + Δt (v^n + v^{n+1}) / 2`, the trapezoidal rule the native simulator uses;
//! SUMO's default (Euler) update would use `x^{n+1} = x^n + Δt v^{n+1}`.
//!
//! Speed mode 32 turns every check off: SUMO realises any non-negative command, even above
//! the vehicle type's maxSpeed and the lane's limit, and lets vehicles collide (counted by the
//! loop). The override counter is a safety net for commands SUMO does not realise.

use syncroad_control::cacc::{CaccLaw, PlatoonView, PowertrainLag};
use syncroad_control::scenario::{LeaderProfile, Model, Scenario};
use syncroad_control::DelayedDriverLaw;

/// A law that commands speeds one step ahead.
pub trait SpeedController {
    /// From the measured state at time `time_s` = t_n (speeds [m/s] and unwrapped rear-bumper
    /// positions \[m\] of all SUMO vehicles, the leader first when it is a SUMO vehicle) writes
    /// the speeds wanted at t_{n+1} into `next_speeds_mps`.
    fn step(
        &mut self,
        time_s: f64,
        speeds_mps: &[f64],
        positions_m: &[f64],
        next_speeds_mps: &mut [f64],
    );
}

/// Errors building a controller.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControllerError {
    /// The delayed-driver law rejected its inputs.
    #[error("delayed-driver law: {0}")]
    Law(#[from] syncroad_control::delayed_driver::LawError),
    /// A CACC platoon needs its leader as a SUMO vehicle.
    #[error("the CACC model needs a leader vehicle: run it on a straight road (road.type = \"straight\")")]
    CaccNeedsLeader,
}

/// Delayed drivers (eq. `chandler+`, with pinning `b_i (v_0 − v_i)` of eq. `proto-lin+` when the
/// scenario has a leader). With a leader vehicle, index 0 is the leader driven at `v_0`.
pub struct DelayedDriverController {
    law: DelayedDriverLaw,
    v0: Option<f64>,
    leader_vehicle: bool,
    next: Vec<f64>,
}

impl SpeedController for DelayedDriverController {
    fn step(&mut self, _t: f64, speeds: &[f64], _positions: &[f64], out: &mut [f64]) {
        let k = usize::from(self.leader_vehicle);
        self.law
            .step(&speeds[k..], self.v0.unwrap_or(0.0), &mut self.next);
        out[k..].copy_from_slice(&self.next);
        if self.leader_vehicle {
            out[0] = self.v0.unwrap_or(speeds[0]);
        }
    }
}

/// The bidirectional CACC law (eqs. `veh-proto1`, `veh-proto2`) with the powertrain lag
/// `τ_i q''' + q'' = a_des` integrated exactly over the step for the held a_des. Index 0 is the
/// leader, driven along its speed profile.
pub struct CaccController {
    law: CaccLaw,
    lag: PowertrainLag,
    profile: LeaderProfile,
    dt_s: f64,
    a_des: Vec<f64>,
    next: Vec<f64>,
}

impl SpeedController for CaccController {
    fn step(&mut self, t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        let view = PlatoonView {
            leader_position_m: positions[0],
            leader_speed_mps: self.profile.speed_at(t),
            positions_m: &positions[1..],
            speeds_mps: &speeds[1..],
        };
        self.law.desired_accelerations(&view, &mut self.a_des);
        self.lag.step(&self.a_des, &speeds[1..], &mut self.next);
        out[1..].copy_from_slice(&self.next);
        out[0] = self.profile.speed_at(t + self.dt_s);
    }
}

/// Builds the controller of a validated scenario; `leader_vehicle` says whether the layout put
/// a leader vehicle first.
pub fn controller_for(
    scenario: &Scenario,
    leader_vehicle: bool,
) -> Result<Box<dyn SpeedController>, ControllerError> {
    match &scenario.model {
        Model::DelayedDriver(m) => {
            let v0 = m.leader.as_ref().map(|(v0, _)| *v0);
            let law = DelayedDriverLaw::for_model(m, scenario.step_s, &scenario.initial_speed_mps)?;
            Ok(Box::new(DelayedDriverController {
                law,
                v0,
                leader_vehicle,
                next: vec![0.0; scenario.n],
            }))
        }
        Model::Cacc(m) => {
            if !leader_vehicle {
                return Err(ControllerError::CaccNeedsLeader);
            }
            Ok(Box::new(CaccController {
                law: CaccLaw::new(m),
                lag: PowertrainLag::new(&m.tau_s, scenario.step_s),
                profile: m.leader.clone(),
                dt_s: scenario.step_s,
                a_des: vec![0.0; scenario.n],
                next: vec![0.0; scenario.n],
            }))
        }
    }
}
