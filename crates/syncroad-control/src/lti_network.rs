//! Networks of general linear SISO agents `x_j' = P_j x_j + Q_j u_j`, `y_j = R_j x_j` coupled by
//! the protocol of eq. `proto-lin`, `u_j = Σ_k a_jk (y_k − y_j)`.
//!
//! This is the setting of Section 3 of the paper beyond vehicles: it lets the examples of
//! Remark `rem.weak` (third-order agents) and the remark on harmonic oscillators be simulated
//! and checked against their closed forms. Integration is the classical fourth-order
//! Runge–Kutta method.

use nalgebra::{DMatrix, DVector};

use crate::graph::Graph;

/// One agent in state-space form.
#[derive(Debug, Clone)]
pub struct LtiAgent {
    /// State matrix P.
    pub p: DMatrix<f64>,
    /// Input vector Q.
    pub q: DVector<f64>,
    /// Output row R.
    pub r: DVector<f64>,
}

impl LtiAgent {
    /// The agent `s ρ(s) ζ = u`, `y = η(s) ζ` of eq. `SISO-pole0` (ascending coefficients,
    /// `deg η ≤ deg ρ`), in controllable canonical form of order `deg ρ + 1`.
    pub fn from_pole_at_zero(eta: &[f64], rho: &[f64]) -> Self {
        // Denominator λ ρ(λ), ascending: [0, ρ_0, ρ_1, ...].
        let mut den = vec![0.0];
        den.extend_from_slice(rho);
        let n = den.len() - 1;
        let lead = den[n];
        let mut p = DMatrix::zeros(n, n);
        for k in 0..n - 1 {
            p[(k, k + 1)] = 1.0;
        }
        for k in 0..n {
            p[(n - 1, k)] = -den[k] / lead;
        }
        let mut q = DVector::zeros(n);
        q[n - 1] = 1.0 / lead;
        let mut r = DVector::zeros(n);
        for (k, &e) in eta.iter().enumerate() {
            r[k] = e;
        }
        Self { p, q, r }
    }

    /// State dimension.
    pub fn order(&self) -> usize {
        self.q.len()
    }
}

/// A network of LTI agents over a graph.
#[derive(Debug, Clone)]
pub struct LtiNetwork {
    agents: Vec<LtiAgent>,
    graph: Graph,
    offsets: Vec<usize>,
}

impl LtiNetwork {
    /// A network; `agents.len()` must equal the graph's size.
    ///
    /// # Panics
    /// If the sizes differ.
    pub fn new(agents: Vec<LtiAgent>, graph: Graph) -> Self {
        assert_eq!(agents.len(), graph.len(), "one agent per graph vertex");
        let mut offsets = vec![0];
        for a in &agents {
            offsets.push(offsets.last().copied().unwrap_or(0) + a.order());
        }
        Self {
            agents,
            graph,
            offsets,
        }
    }

    /// Total state dimension.
    pub fn dim(&self) -> usize {
        *self.offsets.last().unwrap_or(&0)
    }

    /// Outputs `y_j = R_j x_j` of a stacked state.
    pub fn outputs(&self, x: &[f64]) -> Vec<f64> {
        self.agents
            .iter()
            .enumerate()
            .map(|(j, a)| {
                let xs = &x[self.offsets[j]..self.offsets[j + 1]];
                a.r.iter().zip(xs).map(|(r, x)| r * x).sum()
            })
            .collect()
    }

    fn deriv(&self, x: &[f64], dx: &mut [f64]) {
        let y = self.outputs(x);
        for (j, a) in self.agents.iter().enumerate() {
            let u: f64 = self.graph.row(j).map(|(k, w)| w * (y[k] - y[j])).sum();
            let (o, n) = (self.offsets[j], a.order());
            for r in 0..n {
                let mut acc = a.q[r] * u;
                for c in 0..n {
                    acc += a.p[(r, c)] * x[o + c];
                }
                dx[o + r] = acc;
            }
        }
    }

    /// Integrates from `x0` for `steps` steps of `dt` and returns the outputs at every step
    /// (row k = time k·dt), including the initial one.
    pub fn simulate(&self, x0: &[f64], dt: f64, steps: usize) -> Vec<Vec<f64>> {
        let d = self.dim();
        assert_eq!(x0.len(), d, "initial state has the stacked dimension");
        let mut x = x0.to_vec();
        let mut out = vec![self.outputs(&x)];
        let (mut k1, mut k2, mut k3, mut k4, mut t) = (
            vec![0.0; d],
            vec![0.0; d],
            vec![0.0; d],
            vec![0.0; d],
            vec![0.0; d],
        );
        for _ in 0..steps {
            self.deriv(&x, &mut k1);
            (0..d).for_each(|i| t[i] = x[i] + 0.5 * dt * k1[i]);
            self.deriv(&t, &mut k2);
            (0..d).for_each(|i| t[i] = x[i] + 0.5 * dt * k2[i]);
            self.deriv(&t, &mut k3);
            (0..d).for_each(|i| t[i] = x[i] + dt * k3[i]);
            self.deriv(&t, &mut k4);
            (0..d).for_each(|i| x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
            out.push(self.outputs(&x));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use num_complex::Complex64;

    #[test]
    fn canonical_form_realises_the_transfer_function() {
        // R (λI − P)^{-1} Q = η(λ)/(λρ(λ)) at a test point.
        let (eta, rho) = ([2.0, 0.5], [3.0, 1.0, 0.25]);
        let a = LtiAgent::from_pole_at_zero(&eta, &rho);
        let lam = Complex64::new(0.3, 1.7);
        let n = a.order();
        let m = DMatrix::<Complex64>::from_fn(n, n, |r, c| {
            let d = if r == c {
                lam
            } else {
                Complex64::new(0.0, 0.0)
            };
            d - Complex64::new(a.p[(r, c)], 0.0)
        });
        let qc =
            DVector::<Complex64>::from_iterator(n, a.q.iter().map(|&x| Complex64::new(x, 0.0)));
        let sol = m.lu().solve(&qc).unwrap();
        let w: Complex64 = a.r.iter().zip(sol.iter()).map(|(r, s)| s * *r).sum();
        let expect = (eta[0] + eta[1] * lam) / (lam * (rho[0] + rho[1] * lam + rho[2] * lam * lam));
        assert_relative_eq!(w.re, expect.re, epsilon = 1e-12);
        assert_relative_eq!(w.im, expect.im, epsilon = 1e-12);
    }
}
