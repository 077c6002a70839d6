//! The one law object every backend drives.
//!
//! A [`SpeedController`] sees the state at step n of every vehicle on the road (speeds and
//! unwrapped rear-bumper positions, the leader first when the road has one) and returns the
//! speeds wanted at step n+1. The native simulator and the SUMO loop both call
//! [`controller_for`] and step the result, so a scenario runs the same law code on either
//! backend; with SUMO's ballistic position update the two agree run against run.
//!
//! * Delayed drivers (eq. `chandler+`, pinning `b_i (v_0 − v_i)` of eq. `proto-lin+` when the
//!   scenario has a leader): [`DelayedDriverLaw`], second order on the step grid.
//! * CACC (eqs. `veh-proto1`, `veh-proto2`): [`CaccLaw`] gives `a_des` from the measured state,
//!   held over the step; [`PowertrainLag`] integrates `τ_i a' + a = a_des` exactly over it.

use serde::{Deserialize, Serialize};

use crate::cacc::{CaccLaw, PlatoonView, PowertrainLag};
use crate::delayed_driver::{DelayedDriverLaw, LawError};
use crate::drive::{Drive, SumoDriver};
use crate::noisy_idm::{HumanController, HumanSetup};
use crate::registry::NamedLaw;
use crate::road::RingView;
use crate::safety::{FilterParams, SafetyFilter, SafetyMode, REACTION_S};
use crate::scenario::{LeaderProfile, Model, Scenario};
use crate::sensed::Neighbors;
use crate::speed_controller::LawContext;
use crate::user_law::{PythonLaw, UserLaw};

pub use crate::speed_controller::SpeedController;

/// Errors building a controller.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControllerError {
    /// The delayed-driver law rejected its inputs.
    #[error("delayed-driver law: {0}")]
    Law(#[from] LawError),
    /// A CACC platoon needs its leader on the road.
    #[error("the CACC model needs a leader vehicle: run it on a straight road (road.type = \"straight\")")]
    CaccNeedsLeader,
    /// Stochastic humans follow a predecessor around a ring.
    #[error("the stochastic human drivers (noisy IDM) drive on a ring (each vehicle follows its predecessor); this road is straight")]
    HumansNeedRing,
    /// A law of the registry the run names (a wave damper) could not be built.
    #[error("{law}: {reason}")]
    Named {
        /// The law's name.
        law: String,
        /// What went wrong.
        reason: String,
    },
    /// A Python controller where nothing embeds Python to build it.
    #[error("controller.python = {python}: this caller cannot run Python controllers; run the scenario with the syncroad CLI, its Python package or a SUMO worker")]
    NoPythonHost {
        /// As written.
        python: String,
    },
    /// The program's Rust law could not be built (not registered in this process, or it
    /// refused its parameters).
    #[error("controller.rust = {name}: {reason}")]
    Rust {
        /// Its name.
        name: String,
        /// What went wrong.
        reason: String,
    },
    /// The user's Python controller could not be built (missing file, class or method; its
    /// `__init__` raised).
    #[error("controller.python = {python}: {reason}")]
    Python {
        /// As written.
        python: String,
        /// What went wrong, with the Python traceback.
        reason: String,
    },
}

/// Everything a backend needs to build the law of a scenario, resolved: what a SUMO worker
/// receives instead of the scenario file, so nothing is validated twice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LawSpec {
    /// The validated model.
    pub model: Model,
    /// Step Δt \[s\].
    pub step_s: f64,
    /// Initial speeds of the controlled vehicles \[m/s\] (the delay buffers' pre-history).
    pub initial_speed_mps: Vec<f64>,
    /// The vehicles on the road and the road itself as the backend resolved them: what a law
    /// of the registry or the user's controller is built for.
    pub context: LawContext,
    /// A law of the registry ([`crate::registry`]: a wave damper) that drives the law's
    /// vehicles instead of the model's law; `None`: the model's law, or the user's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damper: Option<NamedLaw>,
    /// Stochastic humans computed by the bridge on some vehicles of a ring
    /// ([`crate::noisy_idm`]); `None`: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub humans: Option<HumanSetup>,
    /// The user's own law in place of the model's ([`crate::user_law`]); a damper, when
    /// named, drives instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub user: Option<UserLaw>,
    /// syncroad's safety filter under the law ([`crate::safety`], `"safety": "filter"`);
    /// `None`: no filter (no layer, or SUMO's checks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safety: Option<FilterParams>,
}

impl LawSpec {
    /// The law of a validated scenario, on the native simulator.
    pub fn of(scenario: &Scenario) -> Self {
        let leader = crate::start::leader_start(scenario).is_some();
        let mut ids: Vec<String> = leader.then(|| "leader".to_string()).into_iter().collect();
        ids.extend((0..scenario.vehicles()).map(|i| format!("v{i}")));
        // The leader vehicle is placed as if it were as long as vehicle 0.
        let mut length_m: Vec<f64> = Vec::new();
        if leader {
            length_m.push(scenario.length_m()[0]);
        }
        length_m.extend_from_slice(scenario.length_m());
        let vt = scenario.sumo().vehicle_type();
        Self {
            model: scenario.model().clone(),
            step_s: scenario.step_s(),
            initial_speed_mps: scenario.initial_speed_mps().to_vec(),
            context: LawContext {
                step_s: scenario.step_s(),
                controlled: vec![true; ids.len()],
                ids,
                length_m,
                ring_length_m: scenario.ring_length_m(),
                accel_mps2: vt.accel_mps2,
                decel_mps2: vt.decel_mps2,
                speed_limit_mps: None,
                signals: false,
            },
            damper: None,
            humans: None,
            user: scenario.controller().cloned(),
            safety: filter_params(
                scenario.safety_for(false),
                vt.min_gap_m,
                vt.decel_mps2,
                None,
            ),
        }
    }

    /// The law of the run `drive` on the native simulator: the scenario's law with the damper and the
    /// stochastic humans on a ring of the scenario's length; `None` when a SUMO driver takes
    /// part (only SUMO runs it: a run that leaves the drivers to a scenario with a `mixed`
    /// block included) or a damper or human is asked for on a straight road.
    pub fn of_drive(sc: &Scenario, drive: &Drive) -> Option<Self> {
        if drive.drivers.is_empty() && sc.mixed().is_some() {
            return None;
        }
        let mut law = Self::of(sc);
        if drive.damper.is_none() && drive.drivers.iter().all(Option::is_none) {
            return Some(law);
        }
        let ring = sc.ring_length_m()?;
        let mut humans = Vec::with_capacity(drive.drivers.len());
        for d in &drive.drivers {
            humans.push(match d {
                None => None,
                Some(SumoDriver::Noisy(h)) => Some(*h),
                Some(_) => return None,
            });
        }
        law.damper = drive.damper.clone();
        for (c, h) in law.context.controlled.iter_mut().zip(&humans) {
            *c = h.is_none();
        }
        if humans.iter().any(Option::is_some) {
            law.humans = Some(HumanSetup {
                drivers: humans,
                ring_length_m: ring,
                length_m: sc.length_m().to_vec(),
                seed: sc.seed(),
                speed_limit_mps: None,
            });
        }
        Some(law)
    }
}

/// The filter's parameters for the safety layer `mode` (`None` unless it is the filter), from
/// the vehicle type's `minGap` and `decel` and the road's speed limit, when it has one.
pub fn filter_params(
    mode: SafetyMode,
    min_gap_m: f64,
    decel_mps2: f64,
    speed_limit_mps: Option<f64>,
) -> Option<FilterParams> {
    (mode == SafetyMode::Filter).then_some(FilterParams {
        min_gap_m,
        decel_mps2,
        reaction_s: REACTION_S,
        speed_limit_mps,
    })
}

/// What builds the laws this crate holds as data only: the user's Python controllers.
pub trait LawHost {
    /// Builds the controller of `law` for `context` (imports its class and calls it with its
    /// parameters).
    fn python(
        &self,
        law: &PythonLaw,
        context: &LawContext,
    ) -> Result<Box<dyn SpeedController>, ControllerError>;
}

/// Delayed drivers. With a leader vehicle, index 0 is the leader driven at `v_0`.
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

    fn sense(&mut self, neighbors: &Neighbors) {
        self.law.sense(neighbors, usize::from(self.leader_vehicle));
    }
}

/// The bidirectional CACC law with the powertrain lag `τ_i q''' + q'' = a_des` integrated
/// exactly over the step for the held `a_des`. Index 0 is the leader, driven along its profile.
pub struct CaccController {
    law: CaccLaw,
    lag: PowertrainLag,
    profile: LeaderProfile,
    dt_s: f64,
    a_des: Vec<f64>,
    next: Vec<f64>,
    /// The graph from the simulator this step (the leader is vehicle 0); `None`: fixed.
    sensed: Option<Neighbors>,
}

impl SpeedController for CaccController {
    fn step(&mut self, t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        let view = PlatoonView {
            leader_position_m: positions[0],
            leader_speed_mps: self.profile.speed_at(t),
            positions_m: &positions[1..],
            speeds_mps: &speeds[1..],
        };
        match &self.sensed {
            None => self.law.desired_accelerations(&view, &mut self.a_des),
            Some(nb) => self
                .law
                .desired_accelerations_sensed(&view, nb, &mut self.a_des),
        }
        self.lag.step(&self.a_des, &speeds[1..], &mut self.next);
        out[1..].copy_from_slice(&self.next);
        out[0] = self.profile.speed_at(t + self.dt_s);
    }

    fn sense(&mut self, neighbors: &Neighbors) {
        neighbors.keep_in(&mut self.sensed);
    }
}

/// Builds the controller of a law; `leader_vehicle` says whether the leader is the first
/// vehicle on the road. Stochastic humans, when the law has them, take over their vehicles'
/// commands from the law or damper.
pub fn controller_for(
    law: &LawSpec,
    leader_vehicle: bool,
) -> Result<Box<dyn SpeedController>, ControllerError> {
    controller_for_in(law, leader_vehicle, None)
}

/// [`controller_for`] with a host that builds the user's Python controller, when the law has
/// one (without a host such a law is refused with [`ControllerError::NoPythonHost`]).
pub fn controller_for_in(
    law: &LawSpec,
    leader_vehicle: bool,
    host: Option<&dyn LawHost>,
) -> Result<Box<dyn SpeedController>, ControllerError> {
    let inner = law_controller(law, leader_vehicle, host)?;
    let driven: Box<dyn SpeedController> = match &law.humans {
        None => inner,
        Some(_) if leader_vehicle => return Err(ControllerError::HumansNeedRing),
        Some(h) => Box::new(HumanController::new(inner, h, law.step_s)),
    };
    let c = &law.context;
    Ok(match law.safety {
        None => driven,
        Some(p) => Box::new(SafetyFilter::new(
            driven,
            RingView::on(c.ring_length_m, &c.length_m),
            c.controlled.clone(),
            p,
        )),
    })
}

fn law_controller(
    law: &LawSpec,
    leader_vehicle: bool,
    host: Option<&dyn LawHost>,
) -> Result<Box<dyn SpeedController>, ControllerError> {
    let n = law.initial_speed_mps.len();
    if let Some(d) = &law.damper {
        return d
            .build(&law.context)
            .map_err(|reason| ControllerError::Named {
                law: d.to_string(),
                reason,
            });
    }
    if let Some(u) = &law.user {
        return match (u, host) {
            (UserLaw::Python(p), Some(h)) => h.python(p, &law.context),
            (UserLaw::Python(p), None) => Err(ControllerError::NoPythonHost {
                python: p.python.clone(),
            }),
            (UserLaw::Rust(r), _) => {
                r.build(&law.context)
                    .map_err(|reason| ControllerError::Rust {
                        name: r.name.clone(),
                        reason,
                    })
            }
        };
    }
    match &law.model {
        Model::DelayedDriver(m) => {
            let v0 = m.leader.as_ref().map(|(v0, _)| *v0);
            Ok(Box::new(DelayedDriverController {
                law: m.law(law.step_s, &law.initial_speed_mps)?,
                v0,
                leader_vehicle,
                next: vec![0.0; n],
            }))
        }
        Model::Cacc(m) => {
            if !leader_vehicle {
                return Err(ControllerError::CaccNeedsLeader);
            }
            Ok(Box::new(CaccController {
                law: CaccLaw::new(m),
                lag: PowertrainLag::new(&m.tau_s, law.step_s),
                profile: m.leader.clone(),
                dt_s: law.step_s,
                a_des: vec![0.0; n],
                next: vec![0.0; n],
                sensed: None,
            }))
        }
    }
}
