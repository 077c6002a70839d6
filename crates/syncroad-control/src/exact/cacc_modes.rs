//! Closed-loop eigenvalues of the bidirectional CACC platoon next to Theorem `thm.cacc`.
//!
//! Followers `i = 1..N` obey eq. `veh1`, `τ_i q_i''' + q_i'' = a_des,i`, with the controller of
//! eqs. `veh-proto1`/`veh-proto2`:
//! `a_des,i = μ_i(v_0 − v_i) + η_i(q_{i−1} − q_i − s_i) + ν_i(q_{i+1} − q_i + s_{i+1})`,
//! where vehicle `N` has no `ν` term and the leader `q_0` drives at constant `v_0`.
//! In the error coordinates `e_i = q_{i−1} − q_i − s_i` (gap error \[m\]), `ε_i = v_i − v_0`
//! [m/s] and `a_i = q_i''` [m/s²] the platoon is the linear system `x' = A x` with, per
//! follower,
//!
//! `e_i' = ε_{i−1} − ε_i` (`ε_0 = 0`), `ε_i' = a_i`,
//! `τ_i a_i' = −a_i − μ_i ε_i + η_i e_i − ν_i e_{i+1}`,
//!
//! state order `(e_1, ε_1, a_1, e_2, …)`. The goal eq. `cacc-goal` holds for every initial
//! state iff `A` is Hurwitz. Theorem `thm.cacc` is sufficient: `μ_i τ_i < 1/2`, `η_i, ν_i > 0`
//! and eq. `constants-vehi`, `μ_i²/2 > η_i + ν_i` (`1 < i < N`), `> 2η_1 + ν_1` (`i = 1`),
//! `> η_N` (`i = N`). For a single follower (`N = 1`) the same computation of its proof
//! (eq. `degree1+` with `d_1^+ = 0`, `b_1 = η_1`, IFP index `1/μ_1²`) gives `μ_1²/2 > 2η_1`.

use super::schur_eigenvalues::schur_eigenvalues;
use super::Root;
use nalgebra::DMatrix;
use serde::Serialize;

/// Invalid platoon parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CaccError {
    /// No followers.
    #[error("a platoon needs at least 1 follower")]
    NoFollowers,
    /// A parameter vector has the wrong length.
    #[error("{name} has {got} entries, expected {expected} for {followers} followers")]
    LengthMismatch {
        /// Parameter name.
        name: &'static str,
        /// Entries given.
        got: usize,
        /// Entries expected.
        expected: usize,
        /// Number of followers.
        followers: usize,
    },
    /// A parameter is not finite, or out of its range.
    #[error("{name}[{vehicle}] = {value} must be finite and {requirement}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Follower index (1-based, as in the paper).
        vehicle: usize,
        /// The offending value.
        value: f64,
        /// What is required.
        requirement: &'static str,
    },
    /// The eigenvalue iteration did not converge.
    #[error("eigenvalues of the {order}×{order} platoon matrix did not converge")]
    EigenvaluesFailed {
        /// Matrix order.
        order: usize,
    },
}

/// Parameters of followers `1..N` (index 0 is follower 1).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaccParams {
    /// Powertrain time constants `τ_i` \[s\] (eq. `veh1`), > 0.
    pub tau_s: Vec<f64>,
    /// Speed gains `μ_i` [1/s] on `v_0 − v_i`, > 0.
    pub mu: Vec<f64>,
    /// Front gap gains `η_i` [1/s²], ≥ 0.
    pub eta: Vec<f64>,
    /// Rear gap gains `ν_i` [1/s²] for followers `1..N−1` (`N − 1` entries), ≥ 0.
    pub nu: Vec<f64>,
}

impl CaccParams {
    /// A homogeneous platoon of `followers` vehicles.
    pub fn homogeneous(followers: usize, tau_s: f64, mu: f64, eta: f64, nu: f64) -> Self {
        CaccParams {
            tau_s: vec![tau_s; followers],
            mu: vec![mu; followers],
            eta: vec![eta; followers],
            nu: vec![nu; followers.saturating_sub(1)],
        }
    }

    /// Number of followers `N`.
    pub fn followers(&self) -> usize {
        self.tau_s.len()
    }

    /// Checks lengths and ranges.
    ///
    /// # Errors
    /// [`CaccError`] naming the parameter, the follower and the value.
    pub fn validate(&self) -> Result<usize, CaccError> {
        let n = self.followers();
        if n == 0 {
            return Err(CaccError::NoFollowers);
        }
        for (name, v, expected) in [
            ("mu", &self.mu, n),
            ("eta", &self.eta, n),
            ("nu", &self.nu, n - 1),
        ] {
            if v.len() != expected {
                return Err(CaccError::LengthMismatch {
                    name,
                    got: v.len(),
                    expected,
                    followers: n,
                });
            }
        }
        let checks: [(&'static str, &Vec<f64>, bool, &'static str); 4] = [
            ("tau_s", &self.tau_s, true, "> 0"),
            ("mu", &self.mu, true, "> 0"),
            ("eta", &self.eta, false, "≥ 0"),
            ("nu", &self.nu, false, "≥ 0"),
        ];
        for (name, values, strict, requirement) in checks {
            for (i, &value) in values.iter().enumerate() {
                let ok = value.is_finite() && if strict { value > 0.0 } else { value >= 0.0 };
                if !ok {
                    return Err(CaccError::InvalidParameter {
                        name,
                        vehicle: i + 1,
                        value,
                        requirement,
                    });
                }
            }
        }
        Ok(n)
    }

    /// Closed-loop matrix `A` (order `3N`) in the coordinates of the module documentation.
    ///
    /// # Errors
    /// As [`CaccParams::validate`].
    pub fn closed_loop_matrix(&self) -> Result<DMatrix<f64>, CaccError> {
        let n = self.validate()?;
        let mut a = DMatrix::zeros(3 * n, 3 * n);
        for i in 0..n {
            let (e, v, acc) = (3 * i, 3 * i + 1, 3 * i + 2);
            if i > 0 {
                a[(e, 3 * (i - 1) + 1)] = 1.0;
            }
            a[(e, v)] = -1.0;
            a[(v, acc)] = 1.0;
            let tau = self.tau_s[i];
            a[(acc, acc)] = -1.0 / tau;
            a[(acc, v)] = -self.mu[i] / tau;
            a[(acc, e)] = self.eta[i] / tau;
            if i + 1 < n {
                a[(acc, 3 * (i + 1))] = -self.nu[i] / tau;
            }
        }
        Ok(a)
    }
}

/// Theorem `thm.cacc` conditions of one follower.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CaccCondition {
    /// Follower index (1-based).
    pub vehicle: usize,
    /// `μ_i τ_i` (must be `< 1/2`).
    pub mu_tau: f64,
    /// `μ_i²/2 − rhs_i` of eq. `constants-vehi` (must be `> 0`).
    pub degree_margin: f64,
    /// Gains `η_i` (and `ν_i` for `i < N`) strictly positive, as the theorem assumes.
    pub gains_positive: bool,
    /// All conditions of this follower hold.
    pub holds: bool,
}

/// Exact eigenvalue verdict next to Theorem `thm.cacc`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaccModes {
    /// Number of followers `N`.
    pub followers: usize,
    /// All `3N` eigenvalues of the closed loop, by decreasing real part.
    pub eigenvalues: Vec<Root>,
    /// Spectral abscissa [1/s].
    pub abscissa: f64,
    /// Exact verdict: every eigenvalue has `Re < 0`.
    pub exactly_stable: bool,
    /// Per-follower conditions of Theorem `thm.cacc`.
    pub theorem_conditions: Vec<CaccCondition>,
    /// Theorem `thm.cacc` applies (so it claims stability).
    pub theorem_holds: bool,
}

/// Conditions of Theorem `thm.cacc`, follower by follower.
pub fn theorem_conditions(p: &CaccParams) -> Vec<CaccCondition> {
    let n = p.followers();
    (0..n)
        .map(|i| {
            let nu = if i + 1 < n { p.nu[i] } else { 0.0 };
            let rhs = if n == 1 {
                2.0 * p.eta[0]
            } else if i == 0 {
                2.0 * p.eta[0] + nu
            } else if i + 1 == n {
                p.eta[i]
            } else {
                p.eta[i] + nu
            };
            let mu_tau = p.mu[i] * p.tau_s[i];
            let degree_margin = p.mu[i] * p.mu[i] / 2.0 - rhs;
            let gains_positive = p.eta[i] > 0.0 && (i + 1 == n || nu > 0.0);
            CaccCondition {
                vehicle: i + 1,
                mu_tau,
                degree_margin,
                gains_positive,
                holds: mu_tau < 0.5 && degree_margin > 0.0 && gains_positive,
            }
        })
        .collect()
}

/// Eigenvalues of the CACC closed loop with both verdicts.
///
/// # Errors
/// [`CaccError`] for invalid parameters or a failed eigenvalue iteration.
pub fn cacc_modes(params: &CaccParams) -> Result<CaccModes, CaccError> {
    let a = params.closed_loop_matrix()?;
    let order = a.nrows();
    let mut eigenvalues: Vec<Root> = schur_eigenvalues(a, f64::EPSILON, 10_000 * order)
        .ok_or(CaccError::EigenvaluesFailed { order })?
        .into_iter()
        .map(Root::from)
        .collect();
    eigenvalues.sort_by(|a, b| b.re.total_cmp(&a.re));
    let abscissa = eigenvalues[0].re;
    let conditions = theorem_conditions(params);
    let theorem_holds = conditions.iter().all(|c| c.holds);
    Ok(CaccModes {
        followers: params.followers(),
        eigenvalues,
        abscissa,
        exactly_stable: abscissa < 0.0,
        theorem_conditions: conditions,
        theorem_holds,
    })
}

/// The platoon's critical gain scale: every coupling gain `η_i`, `ν_i` times `c` (the speed
/// gains `μ_i` and the lags belong to each vehicle's own agent, `1/(s(τ_i s² + s + μ_i))`, and
/// stay).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaccCritical {
    /// The scale at which the closed loop stops being Hurwitz, searched from the scenario's
    /// own scale (`None`: no crossing up to [`CaccCritical::searched_up_to`], or the platoon is
    /// unstable at every scale down to its lower end).
    pub critical_gain_scale: Option<f64>,
    /// `|Im s|` of the root pair on the imaginary axis there \[rad/s\].
    pub crossing_frequency_rad_s: Option<f64>,
    /// The largest scale at which Theorem `thm.cacc` still holds: `min_i (μ_i²/2)/rhs_i` when
    /// every `μ_i τ_i < 1/2` and every gain is positive (its margins are linear in `c`), else
    /// `None`.
    pub theorem_gain_scale: Option<f64>,
    /// `critical_gain_scale / theorem_gain_scale`: how far the theorem is from exact.
    pub conservatism_ratio: Option<f64>,
    /// The search's range of scales.
    pub searched_from: f64,
    /// See [`CaccCritical::searched_from`].
    pub searched_up_to: f64,
}

/// The largest coupling scale at which Theorem `thm.cacc` holds (see
/// [`CaccCritical::theorem_gain_scale`]).
fn theorem_gain_scale(p: &CaccParams) -> Option<f64> {
    let conditions = theorem_conditions(p);
    if !conditions
        .iter()
        .all(|c| c.mu_tau < 0.5 && c.gains_positive)
    {
        return None;
    }
    conditions
        .iter()
        .zip(&p.mu)
        .map(|(c, mu)| {
            let half = 0.5 * mu * mu;
            // rhs_i = μ_i²/2 − margin_i scales with c: the margin vanishes at half / rhs.
            half / (half - c.degree_margin)
        })
        .min_by(f64::total_cmp)
}

/// The platoon with every `η_i` and `ν_i` times `c`.
pub fn scaled_coupling(p: &CaccParams, c: f64) -> CaccParams {
    CaccParams {
        tau_s: p.tau_s.clone(),
        mu: p.mu.clone(),
        eta: p.eta.iter().map(|x| x * c).collect(),
        nu: p.nu.iter().map(|x| x * c).collect(),
    }
}

/// The rightmost eigenvalue of the platoon with its coupling scaled by `c`.
fn rightmost(p: &CaccParams, c: f64) -> Result<Root, CaccError> {
    let a = scaled_coupling(p, c).closed_loop_matrix()?;
    let order = a.nrows();
    schur_eigenvalues(a, f64::EPSILON, 10_000 * order)
        .ok_or(CaccError::EigenvaluesFailed { order })?
        .into_iter()
        .map(Root::from)
        .max_by(|a, b| a.re.total_cmp(&b.re))
        .ok_or(CaccError::EigenvaluesFailed { order })
}

/// [`CaccCritical`] by bisection on the closed loop's spectral abscissa: from the scenario's
/// scale (1) up by doublings to the first unstable scale (or down by halvings to the first
/// stable one), then 200 halvings of the bracket, to the last bit. For one follower it is
/// the closed form `μ/(τη)` at `ω = √(μ/τ)` (Routh–Hurwitz of `τs³ + s² + μs + cη`, tested).
///
/// # Errors
/// [`CaccError`] for invalid parameters or an eigenvalue iteration that fails.
pub fn cacc_critical(p: &CaccParams) -> Result<CaccCritical, CaccError> {
    const RANGE: f64 = 1.0e9;
    let unstable = |c: f64| -> Result<bool, CaccError> { Ok(rightmost(p, c)?.re >= 0.0) };
    let theorem = theorem_gain_scale(p);
    let none = |from: f64, to: f64| CaccCritical {
        critical_gain_scale: None,
        crossing_frequency_rad_s: None,
        theorem_gain_scale: theorem,
        conservatism_ratio: None,
        searched_from: from,
        searched_up_to: to,
    };
    let (mut lo, mut hi) = (1.0, 1.0);
    if unstable(1.0)? {
        while unstable(lo)? {
            lo /= 2.0;
            if lo < 1.0 / RANGE {
                return Ok(none(lo, 1.0));
            }
        }
    } else {
        while !unstable(hi)? {
            hi *= 2.0;
            if hi > RANGE {
                return Ok(none(1.0, hi));
            }
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if unstable(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let crossing = rightmost(p, hi)?;
    let critical = 0.5 * (lo + hi);
    Ok(CaccCritical {
        critical_gain_scale: Some(critical),
        crossing_frequency_rad_s: Some(crossing.im.abs()),
        theorem_gain_scale: theorem,
        conservatism_ratio: theorem.map(|t| critical / t),
        searched_from: lo.min(1.0),
        searched_up_to: hi.max(1.0),
    })
}

#[cfg(test)]
mod tests {
    use super::super::collocation::tests::Lcg;
    use super::*;
    use approx::assert_relative_eq;
    use num_complex::Complex64;

    /// Roots of `τs³ + s² + μs + η` by Durand–Kerner (independent of any matrix code).
    fn cubic_roots(tau: f64, mu: f64, eta: f64) -> [Complex64; 3] {
        let (a, b, c) = (1.0 / tau, mu / tau, eta / tau);
        let p = |z: Complex64| ((z + a) * z + b) * z + c;
        let mut r = [
            Complex64::new(0.4, 0.9),
            Complex64::new(0.4, 0.9).powu(2),
            Complex64::new(0.4, 0.9).powu(3),
        ];
        for _ in 0..500 {
            for k in 0..3 {
                let mut d = Complex64::new(1.0, 0.0);
                for j in 0..3 {
                    if j != k {
                        d *= r[k] - r[j];
                    }
                }
                r[k] -= p(r[k]) / d;
            }
        }
        r
    }

    /// One follower: `τs³ + s² + μs + cη` is Hurwitz iff `c < μ/(τη)`, and at that scale its
    /// roots on the axis are `±i√(μ/τ)` (Routh–Hurwitz; the real and imaginary parts of the
    /// polynomial at `iω` vanish together there).
    #[test]
    fn the_critical_scale_of_one_follower_is_routh_hurwitz_closed_form() {
        let mut rng = Lcg(11);
        for _ in 0..40 {
            let tau = 0.1 + rng.next();
            let mu = 0.2 + 2.0 * rng.next();
            let eta = 0.05 + 3.0 * rng.next();
            let p = CaccParams::homogeneous(1, tau, mu, eta, 0.0);
            let c = cacc_critical(&p).unwrap();
            let want = mu / (tau * eta);
            assert_relative_eq!(c.critical_gain_scale.unwrap(), want, max_relative = 1e-9);
            assert_relative_eq!(
                c.crossing_frequency_rad_s.unwrap(),
                (mu / tau).sqrt(),
                max_relative = 1e-6
            );
            // The theorem for one follower, μ²/2 > 2cη with μτ < 1/2: c < μ²/(4η).
            match c.theorem_gain_scale {
                Some(t) => {
                    assert!(mu * tau < 0.5);
                    assert_relative_eq!(t, mu * mu / (4.0 * eta), max_relative = 1e-12);
                    // A sufficient condition: never beyond the exact scale.
                    assert!(t <= want * (1.0 + 1e-12), "{t} > {want}");
                }
                None => assert!(mu * tau >= 0.5),
            }
        }
    }

    /// A longer platoon: at the critical scale `det(iω* I − A(c*))` vanishes (a complex LU,
    /// independent of the eigenvalue iteration), and just below it the platoon is stable,
    /// just above it not.
    #[test]
    fn at_the_critical_scale_of_a_platoon_a_root_pair_sits_on_the_axis() {
        let p = CaccParams::homogeneous(6, 0.4, 0.9, 0.35, 0.1);
        let c = cacc_critical(&p).unwrap();
        let (cs, w) = (
            c.critical_gain_scale.unwrap(),
            c.crossing_frequency_rad_s.unwrap(),
        );
        assert!(
            cacc_modes(&scaled_coupling(&p, cs * (1.0 - 1e-6)))
                .unwrap()
                .exactly_stable
        );
        assert!(
            !cacc_modes(&scaled_coupling(&p, cs * (1.0 + 1e-6)))
                .unwrap()
                .exactly_stable
        );
        let a = scaled_coupling(&p, cs).closed_loop_matrix().unwrap();
        let n = a.nrows();
        let m = nalgebra::DMatrix::<Complex64>::from_fn(n, n, |i, j| {
            let d = if i == j {
                Complex64::new(0.0, w)
            } else {
                Complex64::new(0.0, 0.0)
            };
            d - Complex64::new(a[(i, j)], 0.0)
        });
        // Relative to the determinant's size a step off the crossing.
        let at = m.clone().lu().determinant().norm();
        let off = nalgebra::DMatrix::<Complex64>::from_fn(n, n, |i, j| {
            let d = if i == j {
                Complex64::new(0.0, 1.1 * w)
            } else {
                Complex64::new(0.0, 0.0)
            };
            d - Complex64::new(a[(i, j)], 0.0)
        })
        .lu()
        .determinant()
        .norm();
        assert!(
            at < 1e-7 * off,
            "det at the crossing {at:e}, beside it {off:e}"
        );
    }

    #[test]
    fn single_follower_matches_routh_hurwitz() {
        // N = 1: τs³ + s² + μs + η is Hurwitz iff μ > τη (all coefficients positive).
        let mut rng = Lcg(3);
        let mut seen = [0usize; 2];
        for _ in 0..400 {
            let tau = 0.05 + rng.next();
            let mu = 0.05 + 2.0 * rng.next();
            let eta = 0.05 + 3.0 * rng.next();
            let margin = mu - tau * eta;
            if margin.abs() < 1e-3 {
                continue;
            }
            let m = cacc_modes(&CaccParams::homogeneous(1, tau, mu, eta, 0.0)).unwrap();
            assert_eq!(m.exactly_stable, margin > 0.0, "τ={tau} μ={mu} η={eta}");
            seen[usize::from(margin > 0.0)] += 1;
        }
        assert!(
            seen[0] > 20 && seen[1] > 20,
            "both verdicts exercised: {seen:?}"
        );
    }

    #[test]
    fn unidirectional_platoon_eigenvalues_are_the_vehicle_cubics() {
        // ν = 0 makes A block lower triangular: the spectrum is the union of the roots of
        // τ_i s³ + s² + μ_i s + η_i.
        let p = CaccParams {
            tau_s: vec![0.3, 0.5, 0.2, 0.4],
            mu: vec![1.0, 0.8, 1.5, 0.6],
            eta: vec![0.5, 0.3, 0.9, 0.2],
            nu: vec![0.0; 3],
        };
        let m = cacc_modes(&p).unwrap();
        for i in 0..4 {
            for z in cubic_roots(p.tau_s[i], p.mu[i], p.eta[i]) {
                let best = m
                    .eigenvalues
                    .iter()
                    .map(|e| (Complex64::new(e.re, e.im) - z).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!(best < 1e-10, "vehicle {i}: root {z} missing");
            }
        }
    }

    #[test]
    fn theorem_cacc_is_never_contradicted() {
        let mut rng = Lcg(11);
        let mut applied = 0;
        for trial in 0..300 {
            let n = 1 + trial % 12;
            let mut p = CaccParams::homogeneous(n, 0.0, 0.0, 0.0, 0.0);
            for i in 0..n {
                p.mu[i] = 0.3 + 2.0 * rng.next();
                p.tau_s[i] = 0.5 / p.mu[i] * rng.next();
                // Draw the gap gains inside the theorem's region (fractions of μ²/2).
                let budget = p.mu[i] * p.mu[i] / 2.0;
                p.eta[i] = 0.3 * budget * (0.01 + rng.next());
                if i + 1 < n {
                    p.nu[i] = 0.3 * budget * (0.01 + rng.next());
                }
            }
            let m = cacc_modes(&p).unwrap();
            if m.theorem_holds {
                applied += 1;
                assert!(
                    m.exactly_stable,
                    "trial {trial}: {:?}",
                    m.theorem_conditions
                );
            }
        }
        assert!(applied > 200, "theorem applied in {applied} trials");
    }

    #[test]
    fn exact_analysis_shows_theorem_conservatism() {
        // Stable although μτ > 1/2 violates the theorem: N = 1, τ = 1, μ = 1, η = 0.1
        // (Routh: μ = 1 > τη = 0.1).
        let m = cacc_modes(&CaccParams::homogeneous(1, 1.0, 1.0, 0.1, 0.0)).unwrap();
        assert!(m.exactly_stable && !m.theorem_holds);
        assert_relative_eq!(m.theorem_conditions[0].mu_tau, 1.0);
    }

    #[test]
    fn errors_name_parameter_vehicle_and_value() {
        let mut p = CaccParams::homogeneous(3, 0.5, 1.0, 0.2, 0.1);
        p.tau_s[1] = 0.0;
        assert_eq!(
            cacc_modes(&p).unwrap_err().to_string(),
            "tau_s[2] = 0 must be finite and > 0"
        );
        let mut p = CaccParams::homogeneous(3, 0.5, 1.0, 0.2, 0.1);
        p.nu.push(0.1);
        assert_eq!(
            cacc_modes(&p).unwrap_err().to_string(),
            "nu has 3 entries, expected 2 for 3 followers"
        );
        let p = CaccParams::homogeneous(0, 0.5, 1.0, 0.2, 0.1);
        assert_eq!(
            cacc_modes(&p).unwrap_err().to_string(),
            "a platoon needs at least 1 follower"
        );
    }
}
