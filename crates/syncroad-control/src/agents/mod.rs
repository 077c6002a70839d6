//! The model's agents as the theory sees them: each driver `i` is a SISO agent with a pole at
//! zero and an input delay,
//!
//! `W_i(s) = η_i(s) / (s ρ_i(s)) · e^{−s τ_i}` (eq. `SISO-pole0` with the delay of eq.
//! `agent-delay0`),
//!
//! from its input `u_i = Σ_j a_ij (y_j − y_i) − b_i (y_i − y_0)` to its speed `y_i`. Every kind
//! of agent gives its [`Transfer`]: the delayed driver of eq. `chandler+` is `e^{−sα}/s`, the
//! CACC vehicle of eq. `veh1` is `1/(s(τs² + s + μ))`, and a [`linear`] agent is whatever the
//! user writes. The IFP index, the certificate of Theorem 1/1+ and exact stability read the
//! transfers only, so a kind of agent costs its own file and nothing else.
//!
//! [`index`] computes the index: exactly for rational agents (Lemma `lem.linear-pass`), exactly
//! for a delayed integrator (Lemma `lem.delay-pass`: `α = τ·η_0/ρ_0`), and for a delayed
//! rational agent as a rigorous upper bound with a sampled lower bound beside it.

pub mod index;
pub mod linear;
pub mod stepper;

use num_complex::Complex64;
use serde::{Deserialize, Serialize};

use crate::poly::Poly;

pub use index::{index, AgentIndex, IndexMethod};
pub use linear::{LinearAgent, LinearAgentError, LinearAgentSpec};

/// One agent's transfer function `W(s) = η(s)/(s ρ(s)) · e^{−s τ}` from its input to its speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Transfer {
    /// η, coefficients lowest degree first.
    pub eta: Vec<f64>,
    /// ρ, coefficients lowest degree first.
    pub rho: Vec<f64>,
    /// Input delay τ \[s\].
    pub delay_s: f64,
}

impl Transfer {
    /// The delayed driver of eq. `chandler+`: `v' = u(t − α)`, `W = e^{−sα}/s`.
    pub fn delayed_integrator(delay_s: f64) -> Self {
        Self {
            eta: vec![1.0],
            rho: vec![1.0],
            delay_s,
        }
    }

    /// The CACC vehicle of the proof of Theorem `thm.cacc`: `τ y''' + y'' + μ y' = u`,
    /// `W = 1/(s(τs² + s + μ))`.
    pub fn cacc_vehicle(mu: f64, tau_s: f64) -> Self {
        Self {
            eta: vec![1.0],
            rho: vec![mu, 1.0, tau_s],
            delay_s: 0.0,
        }
    }

    /// `W(s)`.
    pub fn eval(&self, s: Complex64) -> Complex64 {
        let (num, den) = self.eval_parts(s);
        num / den
    }

    /// `η(s) e^{−sτ}` and `s ρ(s)`: `W`'s numerator and denominator at `s`.
    pub fn eval_parts(&self, s: Complex64) -> (Complex64, Complex64) {
        let horner = |c: &[f64]| {
            c.iter()
                .rev()
                .fold(Complex64::new(0.0, 0.0), |acc, &x| acc * s + x)
        };
        (
            horner(&self.eta) * (-s * self.delay_s).exp(),
            s * horner(&self.rho),
        )
    }

    /// Whether the agent is a delayed integrator `k e^{−sτ}/s` (constant η and ρ).
    pub fn is_integrator(&self) -> bool {
        Poly::new(&self.eta).degree() == 0 && Poly::new(&self.rho).degree() == 0
    }

    /// The order of the agent, `deg ρ + 1` (its pole at zero counted).
    pub fn order(&self) -> usize {
        Poly::new(&self.rho).degree() + 1
    }
}
