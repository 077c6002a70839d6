//! The seam every law drives through: one step of commanded speeds. The laws ([`crate::controller`])
//! and the wave dampers ([`crate::damper`]) implement it; both backends step it.

use serde::{Deserialize, Serialize};

use crate::sensed::Neighbors;
use crate::stop::StopReason;

/// A law that commands speeds one step ahead.
pub trait SpeedController: Send {
    /// From the state at time `time_s` = t_n (speeds \[m/s\] and unwrapped rear-bumper positions
    /// \[m\] of every vehicle on the road, the leader first when there is one) writes the
    /// speeds wanted at t_{n+1} into `next_speeds_mps`.
    fn step(
        &mut self,
        time_s: f64,
        speeds_mps: &[f64],
        positions_m: &[f64],
        next_speeds_mps: &mut [f64],
    );

    /// Who is directly ahead of and behind each vehicle on its lane at this step, as the
    /// simulator sees it, given before [`SpeedController::step`] when other traffic shares the
    /// road: the edges to a vehicle's layout neighbours point at whoever is there now
    /// ([`crate::sensed`]). A controller that is never given one runs its fixed graph; one that
    /// has no neighbours to retarget keeps the default, which ignores it.
    fn sense(&mut self, _neighbors: &Neighbors) {}

    /// Whether and why this controller ends the run, asked after every step: both loops then
    /// stop with [`ControllerEnd::at`] and keep every row before it. The built-in laws never
    /// end a run.
    fn ended(&mut self) -> Option<ControllerEnd> {
        None
    }
}

/// Why a controller ends a run before its horizon.
#[derive(Debug, Clone, PartialEq)]
pub enum ControllerEnd {
    /// It cannot go on: the user's controller raised, or returned commands that are not speeds
    /// (the traceback, or what is wrong with them).
    Failed(String),
    /// It ends the run on purpose (the caller closed a stepping loop), for this reason.
    Stopped(String),
}

impl ControllerEnd {
    /// The run's stop at step `step`, time `time_s`.
    pub fn at(self, step: usize, time_s: f64) -> StopReason {
        match self {
            ControllerEnd::Failed(error) => StopReason::ControllerFailed {
                step,
                time_s,
                error,
            },
            ControllerEnd::Stopped(why) => StopReason::StoppedByController { step, time_s, why },
        }
    }
}

/// What a law is built for: the run's step and vehicles, as the backend resolved them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LawContext {
    /// Step Δt \[s\].
    pub step_s: f64,
    /// The vehicles' ids, as the stepped speeds are ordered (the leader vehicle first when
    /// there is one).
    pub ids: Vec<String>,
    /// Their lengths ℓ_i \[m\].
    pub length_m: Vec<f64>,
    /// The ring's circumference as the backend measures it \[m\]; `None` on an open road
    /// (vehicle 0 then has nobody ahead).
    pub ring_length_m: Option<f64>,
    /// Which vehicles take the controller's commands (SUMO's drivers and the stochastic humans
    /// drive the others).
    pub controlled: Vec<bool>,
}
