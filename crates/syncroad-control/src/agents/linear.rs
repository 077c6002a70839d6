//! A linear agent the user writes: a transfer function `W = η/(sρ) · e^{−sτ}` or a SISO state
//! space `x' = A x + b u(t − τ)`, `y = c x` whose `A` has a pole at zero, driving its vehicle's
//! speed `y`.
//!
//! The state space is turned into its transfer function by the Faddeev–LeVerrier recursion
//! (`det(sI − A)` and `c adj(sI − A) b`, no eigenvalues), so the two forms are one agent: the
//! pole at zero is the constant term of `det(sI − A)`, which must vanish. No factor is
//! cancelled, so a hidden mode of the user's `A` stays in `ρ` and in every analysis.
//!
//! To run, the transfer function is realised in controllable canonical form and discretised
//! exactly for an input linear over each step (`e^{AΔt}` and the responses to a held and a
//! ramping input, one matrix exponential of the augmented matrix); the delay is a buffer of
//! whole steps.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::Transfer;
use crate::poly::Poly;

/// How a scenario file gives one linear agent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum LinearAgentSpec {
    /// A transfer function `W = η(s)/(s ρ(s)) · e^{−s delay_s}`.
    Transfer {
        /// η, coefficients lowest degree first (as `syncroad ifp`).
        eta: Vec<f64>,
        /// ρ, coefficients lowest degree first.
        rho: Vec<f64>,
        /// Input delay \[s\], a whole number of steps.
        #[serde(default)]
        delay_s: f64,
    },
    /// A SISO state space `x' = A x + b u(t − delay_s)`, `y = c x`; `A` must have an eigenvalue
    /// at zero (the agent integrates its input into a speed).
    StateSpace {
        /// `A`, n rows of n.
        a: Vec<Vec<f64>>,
        /// `b`, n entries.
        b: Vec<f64>,
        /// `c`, n entries.
        c: Vec<f64>,
        /// Input delay \[s\], a whole number of steps.
        #[serde(default)]
        delay_s: f64,
    },
}

/// What is wrong with a linear agent: the field (below `model.agents[i]`), its value and what
/// would be valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field} = {value}: {expected}")]
pub struct LinearAgentError {
    /// The field, e.g. `eta[2]`.
    pub field: String,
    /// The value as written.
    pub value: String,
    /// What would be valid.
    pub expected: String,
}

fn bad(
    field: impl Into<String>,
    value: impl ToString,
    expected: impl Into<String>,
) -> LinearAgentError {
    LinearAgentError {
        field: field.into(),
        value: value.to_string(),
        expected: expected.into(),
    }
}

/// The largest order an agent may have: the canonical realisation, its exponential and the
/// root searches stay well conditioned below it.
pub const MAX_ORDER: usize = 12;

/// A validated linear agent: its transfer function and a realisation to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinearAgent {
    /// `W = η/(sρ) · e^{−sτ}`.
    pub transfer: Transfer,
    /// The agent was given as a state space (its transfer function found from it).
    pub from_state_space: bool,
}

impl LinearAgentSpec {
    /// Validates the agent.
    ///
    /// # Errors
    /// A field that is empty or not finite, a negative delay, a state space that is not SISO
    /// or has no pole at zero, an improper transfer function, `η(0) = 0` (the agent holds no
    /// constant speed), `ρ(0) = 0` (a double pole at zero), an order above [`MAX_ORDER`].
    pub fn validate(&self) -> Result<LinearAgent, LinearAgentError> {
        let (eta, rho, delay_s, ss) = match self {
            LinearAgentSpec::Transfer { eta, rho, delay_s } => {
                finite("eta", eta)?;
                finite("rho", rho)?;
                (eta.clone(), rho.clone(), *delay_s, false)
            }
            LinearAgentSpec::StateSpace { a, b, c, delay_s } => {
                let (eta, rho) = state_space_transfer(a, b, c)?;
                (eta, rho, *delay_s, true)
            }
        };
        if !(delay_s.is_finite() && delay_s >= 0.0) {
            return Err(bad("delay_s", delay_s, "must be a finite number ≥ 0 [s]"));
        }
        let (e, r) = (Poly::new(&eta), Poly::new(&rho));
        if r.coeffs.iter().all(|&x| x == 0.0) {
            return Err(bad(
                "rho",
                format!("{rho:?}"),
                "must not be zero: W = η/(sρ)",
            ));
        }
        if e.coeffs.iter().all(|&x| x == 0.0) {
            return Err(bad(
                "eta",
                format!("{eta:?}"),
                "must not be zero: the agent would ignore its input",
            ));
        }
        if e.degree() > r.degree() + 1 {
            return Err(bad(
                "eta",
                format!("{eta:?}"),
                format!(
                    "has degree {} but W = η/(sρ) must be proper: deg η ≤ deg ρ + 1 = {}",
                    e.degree(),
                    r.degree() + 1
                ),
            ));
        }
        if r.degree() + 1 > MAX_ORDER {
            return Err(bad(
                "rho",
                format!("{rho:?}"),
                format!(
                    "gives an agent of order {} (deg ρ + 1); at most {MAX_ORDER}",
                    r.degree() + 1
                ),
            ));
        }
        if r.coeffs[0] == 0.0 {
            return Err(bad(
                "rho",
                format!("{rho:?}"),
                "must have ρ(0) ≠ 0 (ρ_0 = 0 is a second pole at zero: the agent would integrate its speed twice)",
            ));
        }
        if e.coeffs[0] == 0.0 {
            return Err(bad(
                "eta",
                format!("{eta:?}"),
                "must have η(0) ≠ 0: with η_0 = 0 the pole at zero cancels, and the agent cannot hold a constant speed",
            ));
        }
        Ok(LinearAgent {
            transfer: Transfer {
                eta: e.coeffs,
                rho: r.coeffs,
                delay_s,
            },
            from_state_space: ss,
        })
    }
}

fn finite(field: &str, v: &[f64]) -> Result<(), LinearAgentError> {
    if v.is_empty() {
        return Err(bad(
            field,
            "[]",
            "must have at least one coefficient (lowest degree first)",
        ));
    }
    if let Some((k, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(bad(format!("{field}[{k}]"), x, "must be a finite number"));
    }
    Ok(())
}

/// `c (sI − A)^{−1} b = η(s)/(s ρ(s))` by Faddeev–LeVerrier.
fn state_space_transfer(
    a: &[Vec<f64>],
    b: &[f64],
    c: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), LinearAgentError> {
    let n = a.len();
    if n == 0 {
        return Err(bad("a", "[]", "must be an n×n matrix with n ≥ 1"));
    }
    if n > MAX_ORDER {
        return Err(bad(
            "a",
            format!("{n} rows"),
            format!("at most {MAX_ORDER} states"),
        ));
    }
    for (i, row) in a.iter().enumerate() {
        if row.len() != n {
            return Err(bad(
                format!("a[{i}]"),
                format!("{} entries", row.len()),
                format!("must have {n} entries: A is square (one row per state)"),
            ));
        }
        finite(&format!("a[{i}]"), row)?;
    }
    for (name, v) in [("b", b), ("c", c)] {
        if v.len() != n {
            return Err(bad(
                name,
                format!("{} entries", v.len()),
                format!("must have {n} entries, one per state: the agent is SISO (one input, one output)"),
            ));
        }
        finite(name, v)?;
    }
    let am = DMatrix::from_fn(n, n, |i, j| a[i][j]);
    let (bv, cv) = (DVector::from_column_slice(b), DVector::from_column_slice(c));
    // det(sI − A) = s^n + p_{n−1} s^{n−1} + … + p_0; adj(sI − A) = Σ_{k=1}^{n} M_k s^{n−k}.
    let mut p = vec![0.0; n + 1];
    p[n] = 1.0;
    let mut num = vec![0.0; n];
    let mut m = DMatrix::<f64>::zeros(n, n);
    for k in 1..=n {
        m = &am * &m + DMatrix::identity(n, n) * p[n - k + 1];
        num[n - k] = (cv.transpose() * &m * &bv)[(0, 0)];
        p[n - k] = -(&am * &m).trace() / k as f64;
    }
    let scale = p.iter().fold(0.0f64, |s, x| s.max(x.abs())) * am.norm().max(1.0);
    if p[0].abs() > 1e-12 * scale.max(1.0) {
        return Err(bad(
            "a",
            format!("det(A) = {:e}", (-1f64).powi(n as i32) * p[0]),
            "must have an eigenvalue at zero (det A = 0): the agent integrates its input into a speed, W = η/(sρ)",
        ));
    }
    // ρ = det(sI − A)/s, η = c adj(sI − A) b.
    Ok((num, p[1..].to_vec()))
}

/// The agent realised in controllable canonical form and discretised for a held input.
#[derive(Debug, Clone)]
pub struct Discrete {
    /// `e^{AΔt}`.
    pub phi: DMatrix<f64>,
    /// `∫_0^Δt e^{A(Δt−σ)} b dσ`: the response to an input held over the step.
    pub gamma: DVector<f64>,
    /// `∫_0^Δt e^{A(Δt−σ)} b σ/Δt dσ`: the response to an input ramping by 1 over the step.
    pub gamma_ramp: DVector<f64>,
    /// Output row `c`.
    pub c: DVector<f64>,
    /// Feedthrough `d` (`deg η = deg ρ + 1`).
    pub d: f64,
    /// The state of constant output 1: `A x = 0`, `c x = 1`.
    pub unit_equilibrium: DVector<f64>,
}

impl LinearAgent {
    /// The continuous realisation `(A, b, c, d)` of `W` without its delay, of order `deg ρ + 1`.
    pub fn realization(&self) -> (DMatrix<f64>, DVector<f64>, DVector<f64>, f64) {
        let rho = &self.transfer.rho;
        // d(s) = s ρ(s), ascending.
        let mut den = vec![0.0];
        den.extend_from_slice(rho);
        let n = den.len() - 1;
        let lead = den[n];
        let mut eta = self.transfer.eta.clone();
        eta.resize(n + 1, 0.0);
        let d = eta[n] / lead;
        let mut a = DMatrix::zeros(n, n);
        for k in 0..n - 1 {
            a[(k, k + 1)] = 1.0;
        }
        for k in 0..n {
            a[(n - 1, k)] = -den[k] / lead;
        }
        let mut b = DVector::zeros(n);
        b[n - 1] = 1.0;
        let c = DVector::from_fn(n, |k, _| (eta[k] - d * den[k]) / lead);
        (a, b, c, d)
    }

    /// The realisation discretised at step `dt_s` for an input linear over the step: one
    /// exponential of `[[AΔt, bΔt, 0], [0, 0, 1], [0, 0, 0]]`, whose last two columns are the
    /// responses to a held and to a ramping input.
    pub fn discretize(&self, dt_s: f64) -> Discrete {
        let (a, b, c, d) = self.realization();
        let n = a.nrows();
        let mut aug = DMatrix::zeros(n + 2, n + 2);
        aug.view_mut((0, 0), (n, n)).copy_from(&(&a * dt_s));
        aug.view_mut((0, n), (n, 1)).copy_from(&(&b * dt_s));
        aug[(n, n + 1)] = 1.0;
        let e = aug.exp();
        let mut unit_equilibrium = DVector::zeros(n);
        unit_equilibrium[0] = 1.0 / c[0];
        Discrete {
            phi: e.view((0, 0), (n, n)).into_owned(),
            gamma: e.view((0, n), (n, 1)).column(0).into_owned(),
            gamma_ramp: e.view((0, n + 1), (n, 1)).column(0).into_owned(),
            c,
            d,
            unit_equilibrium,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use num_complex::Complex64;

    fn w_of_realization(ag: &LinearAgent, s: Complex64) -> Complex64 {
        let (a, b, c, d) = ag.realization();
        let n = a.nrows();
        let m = DMatrix::<Complex64>::from_fn(n, n, |i, j| {
            let id = if i == j { s } else { Complex64::new(0.0, 0.0) };
            id - Complex64::new(a[(i, j)], 0.0)
        });
        let bc = DVector::<Complex64>::from_fn(n, |i, _| Complex64::new(b[i], 0.0));
        let x = m.lu().solve(&bc).unwrap();
        (0..n).map(|i| x[i] * c[i]).sum::<Complex64>() + d
    }

    #[test]
    fn the_canonical_realization_and_the_state_space_form_give_the_same_transfer() {
        // A mass with a lag and a zero: W = (2 + 0.5 s)/(s(3 + s + 0.25 s²)).
        let spec = LinearAgentSpec::Transfer {
            eta: vec![2.0, 0.5],
            rho: vec![3.0, 1.0, 0.25],
            delay_s: 0.0,
        };
        let ag = spec.validate().unwrap();
        let s = Complex64::new(0.3, 1.7);
        let w = ag.transfer.eval(s);
        assert_relative_eq!(w_of_realization(&ag, s).re, w.re, max_relative = 1e-12);
        assert_relative_eq!(w_of_realization(&ag, s).im, w.im, max_relative = 1e-12);
        // The same agent as a state space (its canonical realisation, written out) gives back
        // η and ρ up to the scale of ρ's leading coefficient.
        let (a, b, c, _) = ag.realization();
        let ss = LinearAgentSpec::StateSpace {
            a: (0..3)
                .map(|i| (0..3).map(|j| a[(i, j)]).collect())
                .collect(),
            b: b.iter().copied().collect(),
            c: c.iter().copied().collect(),
            delay_s: 0.0,
        }
        .validate()
        .unwrap();
        assert!(ss.from_state_space);
        let w2 = ss.transfer.eval(s);
        assert_relative_eq!(w2.re, w.re, max_relative = 1e-12);
        assert_relative_eq!(w2.im, w.im, max_relative = 1e-12);
    }

    #[test]
    fn a_biproper_agent_has_its_feedthrough() {
        // W = (1 + s + 2 s²)/(s (1 + s)): deg η = deg ρ + 1.
        let ag = LinearAgentSpec::Transfer {
            eta: vec![1.0, 1.0, 2.0],
            rho: vec![1.0, 1.0],
            delay_s: 0.0,
        }
        .validate()
        .unwrap();
        let s = Complex64::new(-0.2, 0.9);
        let (w, wr) = (ag.transfer.eval(s), w_of_realization(&ag, s));
        assert_relative_eq!(wr.re, w.re, max_relative = 1e-12);
        assert_relative_eq!(wr.im, w.im, max_relative = 1e-12);
    }

    #[test]
    fn the_discretization_integrates_a_held_input_exactly() {
        // W = 1/(s(1 + T s)) under a unit step from rest: y(t) = t − T(1 − e^{−t/T}).
        let t_lag = 0.7;
        let ag = LinearAgentSpec::Transfer {
            eta: vec![1.0],
            rho: vec![1.0, t_lag],
            delay_s: 0.0,
        }
        .validate()
        .unwrap();
        let dt = 0.1;
        let dz = ag.discretize(dt);
        let mut x = DVector::zeros(2);
        for k in 1..=30 {
            x = &dz.phi * &x + &dz.gamma;
            let t = k as f64 * dt;
            let y = dz.c.dot(&x);
            assert_relative_eq!(y, t - t_lag * (1.0 - (-t / t_lag).exp()), epsilon = 1e-12);
        }
        assert_relative_eq!(dz.c.dot(&dz.unit_equilibrium), 1.0);
        // A unit ramp u = t from rest: y(t) = t²/2 − T t + T²(1 − e^{−t/T}).
        let mut x = DVector::zeros(2);
        for k in 0..30 {
            x = &dz.phi * &x + &dz.gamma * (k as f64 * dt) + &dz.gamma_ramp * dt;
            let t = (k + 1) as f64 * dt;
            let want = t * t / 2.0 - t_lag * t + t_lag * t_lag * (1.0 - (-t / t_lag).exp());
            assert_relative_eq!(dz.c.dot(&x), want, epsilon = 1e-12);
        }
    }

    #[test]
    fn bad_agents_name_the_field_and_what_is_valid() {
        let tf = |eta: Vec<f64>, rho: Vec<f64>, delay_s: f64| {
            LinearAgentSpec::Transfer { eta, rho, delay_s }
                .validate()
                .unwrap_err()
                .to_string()
        };
        assert!(tf(vec![1.0, f64::NAN], vec![1.0], 0.0).starts_with("eta[1] = NaN"));
        assert!(tf(vec![], vec![1.0], 0.0).starts_with("eta = []"));
        assert!(tf(vec![1.0], vec![1.0], -0.1).starts_with("delay_s = -0.1"));
        assert!(tf(vec![1.0, 0.0, 0.0, 1.0], vec![1.0], 0.0).contains("proper"));
        assert!(tf(vec![0.0, 1.0], vec![1.0, 1.0], 0.0).contains("η(0) ≠ 0"));
        assert!(tf(vec![1.0], vec![0.0, 1.0], 0.0).contains("second pole at zero"));
        let ss = |a: Vec<Vec<f64>>, b: Vec<f64>, c: Vec<f64>| {
            LinearAgentSpec::StateSpace {
                a,
                b,
                c,
                delay_s: 0.0,
            }
            .validate()
            .unwrap_err()
            .to_string()
        };
        let e = ss(vec![vec![-1.0]], vec![1.0], vec![1.0]);
        assert!(e.contains("eigenvalue at zero"), "{e}");
        let e = ss(
            vec![vec![0.0, 1.0], vec![0.0, -1.0]],
            vec![0.0, 1.0],
            vec![1.0],
        );
        assert!(e.starts_with("c = 1 entries") && e.contains("SISO"), "{e}");
        let e = ss(
            vec![vec![0.0, 1.0], vec![0.0]],
            vec![0.0, 1.0],
            vec![1.0, 0.0],
        );
        assert!(e.starts_with("a[1] = 1 entries"), "{e}");
    }
}
