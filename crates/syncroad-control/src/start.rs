//! Where a scenario's vehicles start on their road: the initial positions from the gaps and the
//! leader's start, shared by the native simulator and the SUMO layout (positions as in
//! [`crate::road`]: unwrapped rear bumpers, vehicle 0 in front).

use crate::scenario::{Model, Scenario};

/// Initial unwrapped positions (rear bumpers) from the gaps: vehicle 0 at 0 (or one gap behind
/// the leader's rear bumper at `leader_position_m`), each next vehicle one length plus one gap
/// further back.
pub fn initial_positions(scenario: &Scenario, leader_position_m: Option<f64>) -> Vec<f64> {
    let n = scenario.vehicles();
    let mut q = vec![0.0; n];
    if n == 0 {
        return q;
    }
    let (l, g) = (scenario.length_m(), scenario.initial_gap_m());
    q[0] = match leader_position_m {
        Some(q0) => q0 - l[0] - g[0],
        None => 0.0,
    };
    for i in 1..n {
        q[i] = q[i - 1] - l[i] - g[i];
    }
    q
}

/// Where the leader vehicle starts and how fast, when the road has one: a delayed-driver
/// leader one gap ahead of vehicle 0 at `v_0`, a CACC leader at 0 on its profile.
pub fn leader_start(scenario: &Scenario) -> Option<(f64, f64)> {
    match scenario.model() {
        Model::DelayedDriver(_) | Model::Linear(_) => scenario
            .model()
            .pinning()
            .map(|(v0, _)| (scenario.length_m()[0] + scenario.initial_gap_m()[0], *v0)),
        Model::Cacc(m) => Some((0.0, m.leader.initial_speed())),
    }
}
