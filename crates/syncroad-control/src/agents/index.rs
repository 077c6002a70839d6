//! The IFP index `α_i = −inf_ω Re W_i(iω)` of one agent, the number Theorems 1 and 1+ weigh
//! against the graph (eqs. `degree1`, `degree1+`).
//!
//! * **Rational** (`τ = 0`): exact, by Lemma `lem.linear-pass` ([`crate::ifp::ifp_index`]: the
//!   infimum over the real roots of a polynomial in `ω²`, no frequency grid).
//! * **Delayed integrator** `k e^{−sτ}/s`: exact, `α = kτ` (Lemma `lem.delay-pass` for `k = 1`;
//!   `Re W(iω) = −k sin(ωτ)/ω` has its infimum `−kτ` as `ω → 0`).
//! * **Delayed rational**: the paper has no lemma. Writing `W = k e^{−sτ}/s + G(s) e^{−sτ}` with
//!   `k = η_0/ρ_0` and `G = (η − kρ)/(sρ)` (no pole at zero, stable when ρ is Hurwitz),
//!   `Re W(iω) ≥ −k sin(ωτ)/ω − |G(iω)| ≥ −kτ − ‖G‖_∞`, so `α ≤ kτ + ‖G‖_∞` rigorously, with
//!   `‖G‖_∞` found exactly as the largest value of a rational function of `ω²`. That upper
//!   bound is what the certificate uses (an agent that is IFP(α) is IFP(α') for every α' ≥ α);
//!   beside it, `−min Re W(iω)` over a frequency sweep refined by golden sections is a lower
//!   bound, so the user sees how tight it is. The dissipation inequality the theorems need
//!   then follows from the frequency-domain inequality by Parseval's theorem, as in the proof
//!   of Lemma `lem.delay-pass`.

use num_complex::Complex64;
use serde::Serialize;

use super::Transfer;
use crate::ifp::{ifp_index, split_at_imag_axis, stationary_points, IfpError};
use crate::poly::Poly;

/// How an index was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IndexMethod {
    /// Rational agent: exact infimum (Lemma `lem.linear-pass`).
    Rational,
    /// Delayed integrator: `α = kτ` (Lemma `lem.delay-pass`).
    DelayedIntegrator,
    /// Delayed rational agent: `kτ + ‖G‖_∞`, a rigorous upper bound.
    DelayedRationalBound,
}

impl IndexMethod {
    /// What the index rests on, in words.
    pub fn rests_on(self) -> &'static str {
        match self {
            IndexMethod::Rational => "Lemma lem.linear-pass: ρ Hurwitz, η_0 ρ_0 ≥ 0; α = −inf Re W(iω), exact",
            IndexMethod::DelayedIntegrator => "Lemma lem.delay-pass: W = k e^{−sτ}/s has α = kτ, exact",
            IndexMethod::DelayedRationalBound => "the frequency-domain inequality Re W(iω) ≥ −α (via Parseval, as Lemma lem.delay-pass; the paper proves it only for the delayed integrator); α ≤ kτ + sup|G(iω)| with W = (k/s + G) e^{−sτ}, a rigorous upper bound",
        }
    }
}

/// One agent's IFP index.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AgentIndex {
    /// The index the certificate uses: exact, or a rigorous upper bound (`exact: false`).
    pub ifp_index: f64,
    /// The index is exact (not only a bound).
    pub exact: bool,
    /// A lower bound of the true index (equal to `ifp_index` when exact).
    pub lower_bound: f64,
    /// A frequency [rad/s] attaining the infimum, when one is known.
    pub omega_at_inf: Option<f64>,
    /// How it was found.
    pub method: IndexMethod,
}

/// The index of `t`.
///
/// # Errors
/// Lemma `lem.linear-pass`'s hypotheses, the failing one named: ρ not Hurwitz, `η_0 ρ_0 < 0`,
/// `W` not proper, a coefficient not finite; a negative or non-finite delay.
pub fn index(t: &Transfer) -> Result<AgentIndex, IfpError> {
    let exact = ifp_index(&t.eta, &t.rho)?;
    if t.delay_s == 0.0 {
        return Ok(AgentIndex {
            ifp_index: exact.alpha,
            exact: true,
            lower_bound: exact.alpha,
            omega_at_inf: exact.omega_at_inf,
            method: IndexMethod::Rational,
        });
    }
    let (eta, rho) = (Poly::new(&t.eta), Poly::new(&t.rho));
    let k = eta.coeffs[0] / rho.coeffs[0];
    if eta.degree() == 0 && rho.degree() == 0 {
        let alpha = k * t.delay_s;
        return Ok(AgentIndex {
            ifp_index: alpha,
            exact: true,
            lower_bound: alpha,
            omega_at_inf: Some(0.0),
            method: IndexMethod::DelayedIntegrator,
        });
    }
    // G = q/ρ with q = (η − kρ)/s: the constant term of η − kρ is zero by the choice of k.
    let diff = eta.sub(&rho.mul(&Poly::new(&[k])));
    let q = Poly::new(if diff.coeffs.len() > 1 {
        &diff.coeffs[1..]
    } else {
        &[0.0]
    });
    let g_sup = sup_abs_on_axis(&q, &rho);
    let upper = k * t.delay_s + g_sup;
    let (lower, omega) = sampled_infimum(t, q.coeffs[0] / rho.coeffs[0] - k * t.delay_s);
    // Where a value of Re W(iω) meets the bound (the lag's infimum as ω → 0, say), the bound
    // is the index.
    let exact = upper - lower <= 1e-12 * upper.abs().max(1.0);
    Ok(AgentIndex {
        ifp_index: upper,
        exact,
        lower_bound: if exact { upper } else { lower.min(upper) },
        omega_at_inf: omega,
        method: IndexMethod::DelayedRationalBound,
    })
}

/// `|p(iω)|²` as a polynomial in `x = ω²`.
pub(crate) fn abs2_in_x(p: &Poly) -> Poly {
    let (r, i) = split_at_imag_axis(p);
    let even = r.mul(&r).add(&i.mul(&i));
    Poly::new(&even.coeffs.iter().step_by(2).copied().collect::<Vec<_>>())
}

/// `sup_ω |q(iω)/ρ(iω)|` for Hurwitz ρ: the largest of `Q(x)/R(x)` over `x = ω² ≥ 0` at
/// `x = 0`, at the positive real roots of `Q'R − QR'`, and as `x → ∞`.
pub(crate) fn sup_abs_on_axis(q: &Poly, rho: &Poly) -> f64 {
    let (a, b) = (abs2_in_x(q), abs2_in_x(rho));
    let f = |x: f64| a.eval(x) / b.eval(x);
    let best = stationary_points(&a, &b)
        .into_iter()
        .map(f)
        .fold(f(0.0), f64::max);
    let limit = match a.degree().cmp(&b.degree()) {
        std::cmp::Ordering::Less => 0.0,
        std::cmp::Ordering::Equal => a.coeffs[a.degree()] / b.coeffs[b.degree()],
        std::cmp::Ordering::Greater => f64::INFINITY,
    };
    best.max(limit).max(0.0).sqrt()
}

/// `−min Re W(iω)` over a logarithmic sweep refined by golden sections, with `limit0` the
/// value as `ω → 0`: a lower bound of the index (every sample is a value of `Re W`).
fn sampled_infimum(t: &Transfer, limit0: f64) -> (f64, Option<f64>) {
    let re = |w: f64| t.eval(Complex64::new(0.0, w)).re;
    let tau = t.delay_s.max(1e-9);
    let scale = Poly::new(&t.rho)
        .roots()
        .iter()
        .map(|z| z.norm())
        .fold(1.0 / tau, f64::max);
    let (lo, hi) = ((1e-4 * scale.min(1.0 / tau)).ln(), (1e3 * scale).ln());
    const POINTS: usize = 600;
    let mut best = (limit0, Some(0.0));
    let mut best_k = None;
    let omega = |k: usize| (lo + (hi - lo) * k as f64 / (POINTS - 1) as f64).exp();
    for k in 0..POINTS {
        let v = re(omega(k));
        if v < best.0 {
            best = (v, Some(omega(k)));
            best_k = Some(k);
        }
    }
    if let Some(k) = best_k {
        // Golden-section search between the neighbours of the best sample.
        let (mut a, mut b) = (omega(k.saturating_sub(1)), omega((k + 1).min(POINTS - 1)));
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..60 {
            let (c, d) = (b - g * (b - a), a + g * (b - a));
            if re(c) < re(d) {
                b = d;
            } else {
                a = c;
            }
        }
        let w = 0.5 * (a + b);
        if re(w) < best.0 {
            best = (re(w), Some(w));
        }
    }
    (-best.0, best.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn a_delayed_integrator_has_its_delay_times_its_gain() {
        let r = index(&Transfer {
            eta: vec![2.0],
            rho: vec![4.0],
            delay_s: 0.6,
        })
        .unwrap();
        assert!(r.exact);
        assert_relative_eq!(r.ifp_index, 0.3, max_relative = 1e-15);
        assert_eq!(r.method, IndexMethod::DelayedIntegrator);
    }

    #[test]
    fn a_delayed_first_order_lag_has_its_bound_attained_at_zero_frequency() {
        // W = e^{−sτ}/(s(1 + Ts)): k = 1, G = −T/(1 + Ts), ‖G‖_∞ = T, so α ≤ τ + T; a dense
        // sweep of Re W(iω) (computed here independently) lies inside the bracket.
        let (tau, t_lag) = (0.3, 0.5);
        let tr = Transfer {
            eta: vec![1.0],
            rho: vec![1.0, t_lag],
            delay_s: tau,
        };
        let r = index(&tr).unwrap();
        assert_relative_eq!(r.ifp_index, tau + t_lag, max_relative = 1e-12);
        // Re W(iω) → −(τ + T) as ω → 0: the bound is attained, so it is the index.
        assert!(r.exact);
        let sweep = (1..400_000)
            .map(|k| {
                let w = k as f64 * 1e-4;
                let s = Complex64::new(0.0, w);
                ((-s * tau).exp() / (s * (1.0 + t_lag * s))).re
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            r.lower_bound >= -sweep - 1e-9,
            "{} vs {}",
            r.lower_bound,
            -sweep
        );
        assert!(r.lower_bound <= r.ifp_index);
        // With no lag the bound is exact: the delayed integrator.
        let r0 = index(&Transfer {
            eta: vec![1.0],
            rho: vec![1.0, 0.0],
            delay_s: tau,
        })
        .unwrap();
        assert_relative_eq!(r0.ifp_index, tau);
    }

    #[test]
    fn the_rational_index_is_lemma_linear_pass() {
        // y''' + p y'' + q y' = u (Remark rem.weak): α = p / min_x (p² x + (q − x)²).
        let (p, q) = (1.0, 2.0);
        let r = index(&Transfer {
            eta: vec![1.0],
            rho: vec![q, p, 1.0],
            delay_s: 0.0,
        })
        .unwrap();
        let xm: f64 = q - p * p / 2.0;
        assert_relative_eq!(
            r.ifp_index,
            p / (p * p * xm + (q - xm).powi(2)),
            max_relative = 1e-12
        );
        assert!(r.exact);
    }

    #[test]
    fn the_sup_of_a_lag_is_its_dc_gain_and_a_resonance_its_peak() {
        // |1/(1 + s)| peaks at ω = 0; |1/(s² + 0.2 s + 1)| at its resonance, 1/(2ζ√(1−ζ²)).
        assert_relative_eq!(
            sup_abs_on_axis(&Poly::new(&[1.0]), &Poly::new(&[1.0, 1.0])),
            1.0
        );
        let zeta: f64 = 0.1;
        assert_relative_eq!(
            sup_abs_on_axis(&Poly::new(&[1.0]), &Poly::new(&[1.0, 2.0 * zeta, 1.0])),
            1.0 / (2.0 * zeta * (1.0 - zeta * zeta).sqrt()),
            max_relative = 1e-12
        );
    }
}
