//! The IFP index of a SISO agent with a pole at zero (Lemma `lem.linear-pass`):
//! `W(λ) = η(λ) / (λ ρ(λ))` is IFP(α) with `α = −inf_ω Re W(iω)` when ρ is Hurwitz and
//! `η_0 ρ_0 ≥ 0`.
//!
//! `Re W(iω)` is a rational function of `x = ω²`: with `η(iω) = E_r + i E_i` and
//! `ρ(iω) = R_r + i R_i`, `Re W(iω) = (E_i R_r − E_r R_i) / (ω |ρ(iω)|²) = A(x) / B(x)`. The infimum
//! over `x ≥ 0` is attained at `x = 0`, at a real root of `A'B − AB'` in `(0, ∞)`, or approached
//! as `x → ∞`; all candidates are evaluated exactly, so no frequency grid is involved.

use serde::Serialize;

use crate::poly::Poly;

/// Errors of the IFP computation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IfpError {
    /// ρ is not Hurwitz: Lemma `lem.linear-pass` does not apply.
    #[error("ρ(λ) = {0:?} (ascending coefficients) is not Hurwitz; Lemma lem.linear-pass needs all roots of ρ in Re λ < 0")]
    RhoNotHurwitz(Vec<f64>),
    /// `η_0 ρ_0 < 0`: the residue at the pole λ = 0 is negative.
    #[error("η_0·ρ_0 = {0} < 0: the residue of W at λ = 0 is negative, so W is not IFP for any α (Lemma lem.prl, condition 2)")]
    NegativeResidue(f64),
    /// `W` is not proper (`deg η > deg ρ + 1`) or η is zero.
    #[error("deg η = {eta} exceeds deg ρ + 1 = {rho_plus_one}: W must be proper")]
    NotProper {
        /// deg η.
        eta: usize,
        /// deg ρ + 1.
        rho_plus_one: usize,
    },
    /// A coefficient is not finite.
    #[error("coefficient {which}[{index}] = {value} is not finite")]
    NonFinite {
        /// `eta` or `rho`.
        which: &'static str,
        /// Position.
        index: usize,
        /// Value.
        value: f64,
    },
}

/// The IFP index and where it is attained.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IfpIndex {
    /// α = −inf_ω Re W(iω).
    pub alpha: f64,
    /// A frequency ω ≥ 0 [rad/s] attaining the infimum (`None` when only approached as ω → ∞).
    pub omega_at_inf: Option<f64>,
}

/// `p(iω)` split into its real and imaginary parts, each a polynomial in ω.
pub(crate) fn split_at_imag_axis(p: &Poly) -> (Poly, Poly) {
    // p(iω) = Σ c_k i^k ω^k: real part takes k ≡ 0 (+), 2 (−); imaginary k ≡ 1 (+), 3 (−).
    let n = p.coeffs.len();
    let mut re = vec![0.0; n];
    let mut im = vec![0.0; n];
    for (k, &c) in p.coeffs.iter().enumerate() {
        match k % 4 {
            0 => re[k] = c,
            1 => im[k] = c,
            2 => re[k] = -c,
            _ => im[k] = -c,
        }
    }
    (Poly::new(&re), Poly::new(&im))
}

/// The stationary points `x > 0` of `a(x)/b(x)`: the positive real roots of `a'b − ab'`,
/// each polished by Newton steps. With the values at `x = 0` and as `x → ∞` they are every
/// candidate for the extremes of the rational function on `[0, ∞)`.
pub(crate) fn stationary_points(a: &Poly, b: &Poly) -> Vec<f64> {
    let crit = a.derivative().mul(b).sub(&a.mul(&b.derivative()));
    let scale = crit.coeffs.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    if scale == 0.0 || crit.degree() == 0 {
        return Vec::new();
    }
    let dcrit = crit.derivative();
    let mut out = Vec::new();
    for z in crit.roots() {
        if z.im.abs() > 1e-6 * (1.0 + z.re.abs()) || z.re <= 0.0 {
            continue;
        }
        let mut x = z.re;
        for _ in 0..8 {
            let d = dcrit.eval(x);
            if d == 0.0 {
                break;
            }
            let step = crit.eval(x) / d;
            x -= step;
            if step.abs() <= 1e-15 * x.abs() {
                break;
            }
        }
        if x > 0.0 {
            out.push(x);
        }
    }
    out
}

/// Even polynomial in ω → polynomial in x = ω².
fn even_to_x(p: &Poly) -> Poly {
    Poly::new(&p.coeffs.iter().step_by(2).copied().collect::<Vec<_>>())
}

/// `Re W(iω)` for `W = η/(λρ)`.
pub fn re_w(eta: &Poly, rho: &Poly, omega: f64) -> f64 {
    use num_complex::Complex64;
    let s = Complex64::new(0.0, omega);
    (eta.eval_c(s) / (s * rho.eval_c(s))).re
}

/// IFP index of `W(λ) = η(λ)/(λ ρ(λ))`, coefficients ascending (Lemma `lem.linear-pass`).
pub fn ifp_index(eta: &[f64], rho: &[f64]) -> Result<IfpIndex, IfpError> {
    for (which, c) in [("eta", eta), ("rho", rho)] {
        if let Some((index, &value)) = c.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(IfpError::NonFinite {
                which,
                index,
                value,
            });
        }
    }
    let (eta_p, rho_p) = (Poly::new(eta), Poly::new(rho));
    if !rho_p.is_hurwitz() {
        return Err(IfpError::RhoNotHurwitz(rho.to_vec()));
    }
    if eta_p.degree() > rho_p.degree() + 1 {
        return Err(IfpError::NotProper {
            eta: eta_p.degree(),
            rho_plus_one: rho_p.degree() + 1,
        });
    }
    let r0e0 = eta_p.coeffs[0] * rho_p.coeffs[0];
    if r0e0 < 0.0 {
        return Err(IfpError::NegativeResidue(r0e0));
    }
    let (er, ei) = split_at_imag_axis(&eta_p);
    let (rr, ri) = split_at_imag_axis(&rho_p);
    // Numerator (E_i R_r − E_r R_i) is odd in ω; divide by ω.
    let num_odd = ei.mul(&rr).sub(&er.mul(&ri));
    let num_even = Poly::new(if num_odd.coeffs.len() > 1 {
        &num_odd.coeffs[1..]
    } else {
        &[0.0]
    });
    let a = even_to_x(&num_even);
    let b = even_to_x(&rr.mul(&rr).add(&ri.mul(&ri)));
    let f = |x: f64| a.eval(x) / b.eval(x);
    // Candidates: x = 0, stationary points in (0, ∞), and the limit x → ∞.
    let mut best = (f(0.0), Some(0.0));
    for x in stationary_points(&a, &b) {
        if f(x) < best.0 {
            best = (f(x), Some(x.sqrt()));
        }
    }
    let limit = if a.degree() == b.degree() {
        a.coeffs[a.degree()] / b.coeffs[b.degree()]
    } else if a.degree() < b.degree() {
        0.0
    } else {
        f64::NEG_INFINITY
    };
    if limit < best.0 {
        best = (limit, None);
    }
    Ok(IfpIndex {
        alpha: -best.0,
        omega_at_inf: best.1,
    })
}

/// IFP index of the CACC agent `τ y''' + y'' + μ y' = u` (proof of Theorem `thm.cacc`):
/// `W = 1/(λ(τλ² + λ + μ))`.
pub fn cacc_agent_index(mu: f64, tau: f64) -> Result<IfpIndex, IfpError> {
    ifp_index(&[1.0], &[mu, 1.0, tau])
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn cacc_agent_index_is_one_over_mu_squared_when_mu_tau_below_half() {
        // Proof of Theorem thm.cacc: Re W(iω) = −1/(μ² + (1 − 2τμ)ω² + τ²ω⁴), inf at ω = 0.
        for (mu, tau) in [(1.0, 0.3), (2.0, 0.2), (0.5, 0.99)] {
            let r = cacc_agent_index(mu, tau).unwrap();
            assert_relative_eq!(r.alpha, 1.0 / (mu * mu), max_relative = 1e-12);
            assert_eq!(r.omega_at_inf, Some(0.0));
        }
    }

    #[test]
    fn cacc_agent_index_beyond_the_theorem_has_interior_minimum() {
        // μτ > 1/2: the denominator is smallest at ω² = (2τμ − 1)/(2τ²), so
        // α = 1/(μ² − (2τμ − 1)²/(4τ²)).
        let (mu, tau) = (2.0, 0.5);
        let r = cacc_agent_index(mu, tau).unwrap();
        let x = (2.0 * tau * mu - 1.0) / (2.0 * tau * tau);
        assert_relative_eq!(
            r.alpha,
            1.0 / (mu * mu - (2.0 * tau * mu - 1.0f64).powi(2) / (4.0 * tau * tau)),
            max_relative = 1e-12
        );
        assert_relative_eq!(r.omega_at_inf.unwrap(), x.sqrt(), max_relative = 1e-9);
    }

    #[test]
    fn remark_weak_agent_index_closed_form() {
        // y''' + p y'' + q y' = u: Re W(iω) = −p/(p²ω² + (q − ω²)²).
        for (p, q) in [(1.0, 1.0), (0.5, 2.0), (3.0, 1.0)] {
            let r = ifp_index(&[1.0], &[q, p, 1.0]).unwrap();
            let xm: f64 = q - p * p / 2.0;
            let dmin = if xm > 0.0 {
                p * p * xm + (q - xm).powi(2)
            } else {
                q * q
            };
            assert_relative_eq!(r.alpha, p / dmin, max_relative = 1e-12);
            // Independent check against a dense frequency sweep (never lower than the sweep).
            let sweep = (0..200_000)
                .map(|k| {
                    re_w(
                        &Poly::new(&[1.0]),
                        &Poly::new(&[q, p, 1.0]),
                        k as f64 * 1e-4,
                    )
                })
                .fold(f64::INFINITY, f64::min);
            assert!(r.alpha >= -sweep - 1e-12 && r.alpha <= -sweep + 1e-6);
        }
    }

    #[test]
    fn pure_integrator_is_passive() {
        // W = 1/λ: Re W(iω) = 0, α = 0.
        let r = ifp_index(&[1.0], &[1.0]).unwrap();
        assert_relative_eq!(r.alpha, 0.0);
    }

    #[test]
    fn preconditions_are_checked() {
        assert!(matches!(
            ifp_index(&[1.0], &[1.0, -1.0, 1.0]),
            Err(IfpError::RhoNotHurwitz(_))
        ));
        let e = ifp_index(&[-1.0], &[1.0, 1.0]).unwrap_err();
        assert!(e.to_string().contains("residue"), "{e}");
        assert!(matches!(
            ifp_index(&[1.0, f64::NAN], &[1.0]),
            Err(IfpError::NonFinite {
                which: "eta",
                index: 1,
                ..
            })
        ));
        assert!(matches!(
            ifp_index(&[0.0, 0.0, 0.0, 1.0], &[1.0]),
            Err(IfpError::NotProper { .. })
        ));
    }
}
