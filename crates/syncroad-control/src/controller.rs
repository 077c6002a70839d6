//! The one law object every backend drives.
//!
//! A [`SpeedController`] sees the state at step n of every vehicle on the road (speeds and
//! unwrapped rear-bumper positions, the leader first when the road has one) and returns the
//! speeds wanted at step n+1. The native simulator and the SUMO loop both call
//! [`controller_for`] and step the result, so a scenario runs the same law code on either
//! backend; with SUMO's ballistic position update the two agree run against run.
//!
//! The law is an entry of the registry ([`crate::registry`]): a damper or another law a run
//! names, the user's own, or — when nothing else is named — `protocol`, the scenario's model
//! law ([`crate::protocol_law`]). Stochastic humans take over their vehicles' commands, and
//! the safety filter sits under all of them.

use serde::{Deserialize, Serialize};

use crate::drive::sumo_driver::DriverError;
use crate::drive::{Drive, SumoDriver};
use crate::model::ProtocolInput;
use crate::noisy_idm::{HumanController, HumanSetup};
use crate::registry::NamedLaw;
use crate::road::RingView;
use crate::safety::{FilterParams, SafetyFilter, SafetyMode, REACTION_S};
use crate::scenario::Scenario;
use crate::speed_controller::LawContext;
use crate::user_law::{PythonLaw, UserLaw};

pub use crate::speed_controller::SpeedController;

/// Errors building a controller.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControllerError {
    /// Stochastic humans follow a predecessor around a ring.
    #[error("the stochastic human drivers (noisy IDM) drive on a ring (each vehicle follows its predecessor); this road is straight")]
    HumansNeedRing,
    /// A law of the registry (the scenario's own `protocol`, or a wave damper the run names)
    /// could not be built.
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
    /// The user's Python controller was still being built when the run's time limit passed
    /// (its `__init__` blocked): the run failed, the input may be fine.
    #[error("controller.python = {python}: {reason}")]
    TimedOut {
        /// As written.
        python: String,
        /// What happened.
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
    /// Step Δt \[s\].
    pub step_s: f64,
    /// The vehicles on the road and the road itself as the backend resolved them, and the
    /// scenario's model: what a law of the registry (the scenario's own `protocol` among
    /// them) or the user's controller is built for.
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
        Self::among(scenario, false)
    }

    /// [`LawSpec::of`], its law's vehicles among syncroad's stochastic humans when `humans`
    /// (which sets the default safety layer: [`Scenario::safety_for`]).
    fn among(scenario: &Scenario, humans: bool) -> Self {
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
            step_s: scenario.step_s(),
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
                seed: scenario.seed(),
                protocol: Some(Box::new(ProtocolInput {
                    model: scenario.model().clone(),
                    initial_speed_mps: scenario.initial_speed_mps().to_vec(),
                    leader_vehicle: leader,
                })),
            },
            damper: None,
            humans: None,
            user: scenario.controller().cloned(),
            safety: filter_params(
                scenario.safety_for(false, humans),
                vt.min_gap_m,
                vt.decel_mps2,
                None,
            ),
        }
    }

    /// The law of the run `drive` on the native simulator: the scenario's law with the
    /// drivers [`drivers_for`] resolves, on a ring of the scenario's length; `None` when one of
    /// SUMO's own drivers takes part (only SUMO runs it), or a damper or stochastic human is
    /// asked for on a straight road.
    pub fn of_drive(sc: &Scenario, drive: &Drive) -> Option<Self> {
        let (drivers, damper) = drivers_for(sc, &drive.drivers, drive.damper.as_ref()).ok()?;
        let sumo = drivers.iter().flatten().any(|d| !d.commanded_by_bridge());
        let ring_needed = damper.is_some() || drivers.iter().any(Option::is_some);
        if sumo || (ring_needed && sc.ring_length_m().is_none()) {
            return None;
        }
        // Automated cars among humans: some vehicles of the law, some not.
        let humans = drivers.iter().any(Option::is_some) && drivers.iter().any(Option::is_none);
        Self::among(sc, humans)
            .driven_by(&drivers, damper, sc.seed())
            .ok()
    }

    /// This law, built for the run's road and vehicles, with who drives each scenario vehicle
    /// (`drivers`, one per vehicle, `None` for the law; empty: the law everywhere) and a
    /// damper in place of the law: a vehicle of SUMO's own drivers takes no command, a
    /// stochastic human's is computed by its driver here (its noise drawn from `seed`). The
    /// one resolution both backends make; stochastic humans need a ring.
    pub fn driven_by(
        mut self,
        drivers: &[Option<SumoDriver>],
        damper: Option<NamedLaw>,
        seed: u64,
    ) -> Result<Self, ControllerError> {
        self.damper = damper;
        if drivers.is_empty() {
            return Ok(self);
        }
        let k0 = usize::from(self.leader_vehicle());
        let mut humans = vec![None; k0];
        humans.extend(drivers.iter().map(|d| match d {
            Some(SumoDriver::Noisy(h)) => Some(*h),
            _ => None,
        }));
        let c = &mut self.context;
        for (flag, d) in c.controlled[k0..].iter_mut().zip(drivers) {
            *flag = d.is_none();
        }
        if humans.iter().any(Option::is_some) {
            let Some(ring_length_m) = c.ring_length_m.filter(|_| k0 == 0) else {
                return Err(ControllerError::HumansNeedRing);
            };
            self.humans = Some(HumanSetup {
                drivers: humans,
                ring_length_m,
                length_m: c.length_m.clone(),
                seed,
                speed_limit_mps: c.speed_limit_mps,
            });
        }
        Ok(self)
    }
}

/// Who drives each vehicle of a run of `sc` and which damper commands the law's vehicles:
/// the run's own `drivers` and `damper` when it names drivers, else the scenario's `mixed`
/// block (the automated vehicles placed as it says, drawn from the seed; the others its
/// `human`), else the law on every vehicle (no drivers). Both backends ask here.
pub fn drivers_for(
    sc: &Scenario,
    drivers: &[Option<SumoDriver>],
    damper: Option<&NamedLaw>,
) -> Result<(Vec<Option<SumoDriver>>, Option<NamedLaw>), DriverError> {
    let Some(m) = sc.mixed().filter(|_| drivers.is_empty()) else {
        return Ok((drivers.to_vec(), damper.cloned()));
    };
    let human = SumoDriver::parse("mixed.human", &m.human)?;
    let mut out = vec![Some(human); sc.vehicles()];
    for i in m.automated(sc.vehicles(), sc.seed()) {
        out[i] = None;
    }
    // Validated with the scenario: the name parses.
    Ok((out, damper.cloned().or(m.damper().ok().flatten())))
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

/// Builds the controller of a law. Stochastic humans, when the law has them, take over their
/// vehicles' commands from the law or damper.
pub fn controller_for(law: &LawSpec) -> Result<Box<dyn SpeedController>, ControllerError> {
    controller_for_in(law, None)
}

/// [`controller_for`] with a host that builds the user's Python controller, when the law has
/// one (without a host such a law is refused with [`ControllerError::NoPythonHost`]).
pub fn controller_for_in(
    law: &LawSpec,
    host: Option<&dyn LawHost>,
) -> Result<Box<dyn SpeedController>, ControllerError> {
    let inner = law_controller(law, host)?;
    let driven: Box<dyn SpeedController> = match &law.humans {
        None => inner,
        Some(_) if law.leader_vehicle() => return Err(ControllerError::HumansNeedRing),
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

impl LawSpec {
    /// The leader vehicle is the first on the road (a platoon behind its leader).
    pub fn leader_vehicle(&self) -> bool {
        self.context
            .protocol
            .as_ref()
            .is_some_and(|p| p.leader_vehicle)
    }
}

/// The law that commands the law's vehicles: the damper the run names, else the user's own,
/// else the scenario's `protocol` — each an entry of the registry.
fn law_controller(
    law: &LawSpec,
    host: Option<&dyn LawHost>,
) -> Result<Box<dyn SpeedController>, ControllerError> {
    if let Some(u) = law.user.as_ref().filter(|_| law.damper.is_none()) {
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
    let named = law.damper.clone().unwrap_or_else(NamedLaw::protocol);
    named
        .build(&law.context)
        .map_err(|reason| ControllerError::Named {
            law: named.to_string(),
            reason,
        })
}
