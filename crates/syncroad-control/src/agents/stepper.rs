//! The linear agents of a [`LinearModel`] stepped on the run's grid: each step every agent
//! reads the measured speeds, forms `u_i = Σ_j a_ij (v_j − v_i) + b_i (v_0 − v_i)` (eqs.
//! `proto-lin`, `proto-lin+`), takes its own input of `m_i` steps ago from a buffer (zero
//! before t = 0: the agents were at rest in their equilibria), and advances its state exactly
//! for an input linear over the step ([`super::linear::Discrete`]): from `u^{n−m}` to
//! `u^{n−m+1}` when the agent is delayed (both known), and for an undelayed agent to the
//! extrapolation `2u^n − u^{n−1}` (held at the first step, whose input jumps at t = 0). The
//! step is then second order in Δt, so a run's decay rate meets the exact roots'. Its output
//! is the speed it commands for the next step.
//!
//! Each agent starts in the equilibrium of its initial speed. When the simulator moved a
//! vehicle at another speed than its agent's output (a safety layer, a jam), the agent's
//! integrator is shifted so that its output is the measured speed again, as the delayed driver
//! integrates from the measured speed; with nothing overriding, the shift is zero.

use nalgebra::DVector;

use super::linear::Discrete;
use crate::model::LinearModel;

/// The stepper of a linear network (the drivers only; a leader vehicle is the caller's).
pub struct LinearNetworkLaw {
    agents: Vec<Discrete>,
    states: Vec<DVector<f64>>,
    /// One state's room per agent for the next state (no allocation in the step).
    scratch: Vec<DVector<f64>>,
    /// Output each agent last commanded.
    last: Vec<f64>,
    /// Input histories, `slots_i = m_i + 2` entries each, the newest at `heads[i]`.
    inputs: Vec<Vec<f64>>,
    heads: Vec<usize>,
    rows: Vec<Vec<(usize, f64)>>,
    pinning: Option<(f64, Vec<f64>)>,
    steps: usize,
}

impl LinearNetworkLaw {
    /// The agents of `m` at step `dt_s`, each in the equilibrium of its initial speed.
    pub fn new(m: &LinearModel, dt_s: f64, initial_speeds_mps: &[f64]) -> Self {
        let agents: Vec<Discrete> = m.agents.iter().map(|a| a.discretize(dt_s)).collect();
        let scratch = agents.iter().map(|d| DVector::zeros(d.c.len())).collect();
        let states = agents
            .iter()
            .zip(initial_speeds_mps)
            .map(|(d, &v)| &d.unit_equilibrium * v)
            .collect();
        Self {
            states,
            scratch,
            last: initial_speeds_mps.to_vec(),
            inputs: m.delay_steps.iter().map(|&k| vec![0.0; k + 2]).collect(),
            steps: 0,
            heads: vec![0; agents.len()],
            rows: (0..m.graph.len())
                .map(|i| m.graph.row(i).collect())
                .collect(),
            pinning: m.leader.clone(),
            agents,
        }
    }

    /// From the measured speeds `v^n` of the drivers (and the leader's `v_0`, read only with
    /// pinning) the speeds the agents command for step n+1.
    pub fn step(&mut self, speeds_mps: &[f64], leader_speed_mps: f64, next_mps: &mut [f64]) {
        for i in 0..self.agents.len() {
            let v = speeds_mps[i];
            let mut u: f64 = self.rows[i]
                .iter()
                .map(|&(j, a)| a * (speeds_mps[j] - v))
                .sum();
            if let Some((_, b)) = &self.pinning {
                u += b[i] * (leader_speed_mps - v);
            }
            let ag = &self.agents[i];
            let x = &mut self.states[i];
            // Where the vehicle went at another speed than commanded, move the integrator.
            let drift = v - self.last[i];
            if drift != 0.0 {
                x.axpy(drift, &ag.unit_equilibrium, 1.0);
            }
            let buf = &mut self.inputs[i];
            let slots = buf.len();
            let head = (self.heads[i] + 1) % slots;
            self.heads[i] = head;
            // The buffer holds u^n … u^{n−m−1} (m = slots − 2): u^{n−m−1} is the one after
            // u^n, u^{n−m} the one after that.
            buf[head] = u;
            let (start, end) = if slots == 2 {
                let before = buf[(head + 1) % slots];
                (u, if self.steps == 0 { u } else { 2.0 * u - before })
            } else if self.steps + 2 < slots {
                // u^{n−m+1} is still before t = 0: zero up to the jump at t = 0.
                (buf[(head + 2) % slots], buf[(head + 2) % slots])
            } else {
                (buf[(head + 2) % slots], buf[(head + 3) % slots])
            };
            let delayed = start;
            let next = &mut self.scratch[i];
            next.gemv(1.0, &ag.phi, x, 0.0);
            next.axpy(start, &ag.gamma, 1.0);
            next.axpy(end - start, &ag.gamma_ramp, 1.0);
            std::mem::swap(x, next);
            let y = ag.c.dot(x) + ag.d * delayed;
            self.last[i] = y;
            next_mps[i] = y;
        }
        self.steps += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agents::LinearAgentSpec;
    use crate::graph::Graph;
    use crate::model::GraphShape;
    use approx::assert_relative_eq;

    fn model(n: usize, spec: LinearAgentSpec, delay_steps: usize, k: f64) -> LinearModel {
        let a = spec.validate().unwrap();
        LinearModel {
            graph: Graph::unidirectional_ring(n, &vec![k; n]).unwrap(),
            agents: vec![a; n],
            delay_steps: vec![delay_steps; n],
            leader: None,
            shape: GraphShape::UnidirectionalRing { gain: Some(k) },
        }
    }

    #[test]
    fn equal_speeds_stay_equal_and_the_mean_of_a_balanced_ring_is_kept() {
        let m = model(
            4,
            LinearAgentSpec::Transfer {
                eta: vec![1.0],
                rho: vec![1.0, 0.5],
                delay_s: 0.2,
            },
            2,
            0.8,
        );
        let mut law = LinearNetworkLaw::new(&m, 0.1, &[10.0; 4]);
        let mut v = vec![10.0; 4];
        let mut next = vec![0.0; 4];
        for _ in 0..50 {
            law.step(&v, 0.0, &mut next);
            v.copy_from_slice(&next);
        }
        for x in &v {
            assert_relative_eq!(*x, 10.0, epsilon = 1e-12);
        }
        // A balanced graph keeps Σ y_i' = Σ u_i = 0 for integrator-led agents: the mean speed
        // is invariant and the speeds converge to it.
        let mut law = LinearNetworkLaw::new(&m, 0.1, &[8.0, 12.0, 9.0, 11.0]);
        let mut v = vec![8.0, 12.0, 9.0, 11.0];
        let spread = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max((x - 10.0).abs()));
        let mut spreads = Vec::new();
        for k in 0..3000 {
            law.step(&v, 0.0, &mut next);
            v.copy_from_slice(&next);
            assert_relative_eq!(v.iter().sum::<f64>(), 40.0, epsilon = 1e-9);
            if k % 1000 == 999 {
                spreads.push(spread(&v));
            }
        }
        assert!(
            spreads[2] < 1e-4 && spreads[2] < 0.1 * spreads[0],
            "{spreads:?}"
        );
    }

    #[test]
    fn an_undelayed_integrator_pair_takes_second_order_steps() {
        // Two integrators a_12 = a_21 = k: the difference e obeys e' = −2k e. The first step
        // holds its input (e_1 = (1 − 2kΔt) e_0), the next extrapolate it linearly (the
        // two-step Adams–Bashforth rule e_{n+1} = e_n − 2kΔt(3e_n − e_{n−1})/2), and the run
        // stays within O(Δt²) of e^{−2kt}.
        let m = LinearModel {
            graph: Graph::all_to_all(2, &[0.5, 0.5]).unwrap(),
            agents: vec![
                LinearAgentSpec::Transfer {
                    eta: vec![1.0],
                    rho: vec![1.0],
                    delay_s: 0.0
                }
                .validate()
                .unwrap();
                2
            ],
            delay_steps: vec![0, 0],
            leader: None,
            shape: GraphShape::Other,
        };
        let (dt, k) = (0.01, 0.5);
        let mut law = LinearNetworkLaw::new(&m, dt, &[9.0, 11.0]);
        let mut v = vec![9.0, 11.0];
        let mut next = vec![0.0; 2];
        let (mut e_prev, mut e) = (2.0, 2.0);
        for n in 0..400 {
            law.step(&v, 0.0, &mut next);
            v.copy_from_slice(&next);
            let e_next = if n == 0 {
                (1.0 - 2.0 * k * dt) * e
            } else {
                e - 2.0 * k * dt * (1.5 * e - 0.5 * e_prev)
            };
            (e_prev, e) = (e, e_next);
            assert_relative_eq!(v[1] - v[0], e, max_relative = 1e-10);
            let t = (n + 1) as f64 * dt;
            assert_relative_eq!(e, 2.0 * (-2.0 * k * t).exp(), max_relative = 1e-3);
        }
    }
}
