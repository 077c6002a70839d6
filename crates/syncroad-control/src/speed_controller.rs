//! The seam every law drives through: one step of commanded speeds ([`SpeedController`]), what
//! a law is built for ([`LawContext`]), and the one shape of a law's entry in the registry
//! ([`LawEntry`]: its name, the road it needs, its parameters and how it is built). The
//! built-in laws and the user's own are entries of the same table ([`crate::registry`]); both
//! backends build and step them the same way.

use serde::{Deserialize, Serialize};

use crate::model::ProtocolInput;
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

    /// What the safety filter under the law did ([`crate::safety::SafetyFilter`]); `None`
    /// for a law without it.
    fn filter_report(&self) -> Option<FilterReport> {
        None
    }
}

/// What the safety filter did over a run ([`crate::safety`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct FilterReport {
    /// Vehicle-steps whose command the filter lowered to the safe speed.
    pub overrides: usize,
    /// The largest cut of a command \[m/s\].
    pub largest_cut_mps: f64,
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
    /// The vehicles' largest acceleration \[m/s²\] (their type's `accel`): the bound a law
    /// that commands a velocity tracks it within.
    pub accel_mps2: f64,
    /// The vehicles' largest deceleration \[m/s²\] (their type's `decel`).
    pub decel_mps2: f64,
    /// The road's speed limit \[m/s\] (in SUMO the lowest lane limit along the road);
    /// `None`: the road has none (the native simulator's).
    #[serde(default)]
    pub speed_limit_mps: Option<f64>,
    /// The network has traffic lights (a SUMO run): a controller that reads the signal ahead
    /// of each vehicle asks SUMO for it each step.
    #[serde(default)]
    pub signals: bool,
    /// The run's seed: a law that draws random numbers (the stochastic humans) draws them
    /// from it, a stream per vehicle.
    #[serde(default)]
    pub seed: u64,
    /// The scenario's own law (its model), which the registry's `protocol` entry builds;
    /// `None` where the vehicles are not a scenario's (an inflow's vehicles, a test's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub protocol: Option<Box<ProtocolInput>>,
}

/// The road a law needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Road {
    /// Any road.
    Any,
    /// A ring: each vehicle follows its predecessor, vehicle 0 the last one a lap ahead.
    Ring,
}

/// Builds a law for a run from its parameters; an `Err` says what is wrong with them.
pub type BuildLaw = fn(&LawContext, &serde_json::Value) -> Result<Box<dyn SpeedController>, String>;

/// Checks a law's parameters before anything runs; an `Err` says what is wrong with them.
pub type CheckParams = fn(&serde_json::Value) -> Result<(), String>;

/// One law of the registry: everything a scenario, a command and both backends need of it.
#[derive(Debug, Clone, Copy)]
pub struct LawEntry {
    /// Its name in scenarios, tables and folders: letters, digits, `-` and `_`.
    pub name: &'static str,
    /// One line on what it is and where it comes from (`syncroad laws` lists it).
    pub summary: &'static str,
    /// The road it drives on (checked before a run starts).
    pub road: Road,
    /// It reads the vehicle behind each vehicle too (the bilateral laws): it cannot drive a
    /// vehicle that enters and leaves on its own, behind whoever is ahead of it (an inflow's
    /// `controlled` vehicles), which senses only the vehicle ahead.
    pub looks_behind: bool,
    /// A parameter that may be written after the name (`follower-stopper-4.3` for
    /// `{"desired_speed_mps": 4.3}`); the law's name in tables then carries it.
    pub shorthand: Option<&'static str>,
    /// Checks its parameters (called when a scenario or command names it).
    pub check: CheckParams,
    /// Builds it for a run.
    pub build: BuildLaw,
}

impl LawEntry {
    /// An entry that drives any road, checks its parameters when it is built, and has no
    /// shorthand: what a user's own law needs (`LawEntry::new("mine", build)`).
    pub const fn new(name: &'static str, build: BuildLaw) -> Self {
        Self {
            name,
            summary: "",
            road: Road::Any,
            looks_behind: false,
            shorthand: None,
            check: accept_any,
            build,
        }
    }
}

fn accept_any(_: &serde_json::Value) -> Result<(), String> {
    Ok(())
}

/// A law's parameters as its own type (a struct with `#[serde(deny_unknown_fields)]`), with
/// an error naming what is wrong.
pub fn law_params<T: serde::de::DeserializeOwned>(params: &serde_json::Value) -> Result<T, String> {
    T::deserialize(params).map_err(|e| format!("params {params}: {e}"))
}
