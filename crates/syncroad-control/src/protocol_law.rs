//! The scenario's own law as an entry of the registry, `protocol`: the delayed drivers of
//! eq. `chandler+` (pinned by `b_i (v_0 − v_i)` of eq. `proto-lin+` when the scenario has a
//! leader), second order on the step grid, or the bidirectional
//! CACC of eqs. `veh-proto1/2` ([`CaccController`]: `a_des` from the measured state, held over
//! the step, through the powertrain lag `τ_i a' + a = a_des` integrated exactly over it), or
//! the user's linear agents on a graph (both as one network controller). It
//! takes no parameters of its own: the run's context carries the scenario's model
//! ([`ProtocolInput`]).

use crate::agents::stepper::LinearNetworkLaw;
use crate::cacc::{CaccLaw, PlatoonView, PowertrainLag};
use crate::delayed_driver::DelayedDriverLaw;
use crate::model::{LeaderProfile, Model, ProtocolInput};
use crate::sensed::Neighbors;
use crate::speed_controller::{LawContext, LawEntry, Road, SpeedController};

/// The name of the scenario's own law (its `model`: the delayed drivers or the bidirectional
/// CACC) wherever a driver is named: runs, tables, folders, plots and the drivers of a record.
/// `law` is read as its older spelling.
pub const PROTOCOL: &str = "protocol";

/// The registry's entry of the scenario's own law.
pub const ENTRY: LawEntry = LawEntry {
    name: PROTOCOL,
    summary: "the scenario's own law, from its model block: the delayed drivers of eq. chandler+ on its graph, the bidirectional CACC of eqs. veh-proto1/2 behind its leader, or the user's linear agents on a graph",
    road: Road::Any,
    looks_behind: true,
    shorthand: None,
    check: no_params,
    build,
};

fn no_params(params: &serde_json::Value) -> Result<(), String> {
    match params.as_object() {
        Some(o) if o.is_empty() => Ok(()),
        None if params.is_null() => Ok(()),
        _ => Err(format!(
            "params {params}: the protocol takes its parameters from the scenario's model block; give none"
        )),
    }
}

fn build(ctx: &LawContext, params: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
    no_params(params)?;
    let Some(p) = ctx.protocol.as_deref() else {
        return Err(
            "these vehicles are not a scenario's: the protocol is the law of a scenario's model, which this run has none of"
                .into(),
        );
    };
    controller(p, ctx.step_s)
}

/// The law of `p` at step `step_s`.
fn controller(p: &ProtocolInput, step_s: f64) -> Result<Box<dyn SpeedController>, String> {
    let n = p.initial_speed_mps.len();
    match &p.model {
        Model::DelayedDriver(m) => {
            let v0 = m.leader.as_ref().map(|(v0, _)| *v0);
            Ok(Box::new(NetworkController {
                law: m
                    .law(step_s, &p.initial_speed_mps)
                    .map_err(|e| format!("delayed-driver law: {e}"))?,
                v0,
                leader_vehicle: p.leader_vehicle,
                next: vec![0.0; n],
            }))
        }
        Model::Linear(m) => Ok(Box::new(NetworkController {
            law: LinearNetworkLaw::new(m, step_s, &p.initial_speed_mps),
            v0: m.leader.as_ref().map(|(v0, _)| *v0),
            leader_vehicle: p.leader_vehicle,
            next: vec![0.0; n],
        })),
        Model::Cacc(m) => {
            if !p.leader_vehicle {
                return Err(CACC_NEEDS_LEADER.into());
            }
            Ok(Box::new(CaccController {
                law: CaccLaw::new(m),
                lag: PowertrainLag::new(&m.tau_s, step_s),
                profile: m.leader.clone(),
                dt_s: step_s,
                a_des: vec![0.0; n],
                next: vec![0.0; n],
                sensed: None,
            }))
        }
    }
}

/// Why a CACC platoon without its leader on the road is refused.
pub const CACC_NEEDS_LEADER: &str =
    "the CACC model needs a leader vehicle: run it on a straight road (road.type = \"straight\")";

/// Drivers on a graph stepped from the measured speeds: the delayed drivers of eq.
/// `chandler+` or the user's linear agents.
trait DriverNetwork: Send {
    /// From the drivers' speeds (and the leader's `v_0`) the next speeds into `next`.
    fn step(&mut self, speeds_mps: &[f64], leader_speed_mps: f64, next_mps: &mut [f64]);
    /// The graph as the simulator sees it this step (`k0`: the leader vehicle's offset).
    fn sense(&mut self, _neighbors: &Neighbors, _k0: usize) {}
}

impl DriverNetwork for DelayedDriverLaw {
    fn step(&mut self, speeds_mps: &[f64], leader_speed_mps: f64, next_mps: &mut [f64]) {
        DelayedDriverLaw::step(self, speeds_mps, leader_speed_mps, next_mps);
    }

    fn sense(&mut self, neighbors: &Neighbors, k0: usize) {
        DelayedDriverLaw::sense(self, neighbors, k0);
    }
}

impl DriverNetwork for LinearNetworkLaw {
    fn step(&mut self, speeds_mps: &[f64], leader_speed_mps: f64, next_mps: &mut [f64]) {
        LinearNetworkLaw::step(self, speeds_mps, leader_speed_mps, next_mps);
    }
}

/// A network of drivers. With a leader vehicle, index 0 is the leader driven at `v_0`.
struct NetworkController<L> {
    law: L,
    v0: Option<f64>,
    leader_vehicle: bool,
    next: Vec<f64>,
}

impl<L: DriverNetwork> SpeedController for NetworkController<L> {
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
