//! Complex Lambert W function on every branch.
//!
//! A uniform ring of delayed drivers (eq. `chandler+` with equal delays α) splits into
//! scalar modes `s + λ e^{−sα} = 0`, whose roots are `s = W_k(−λα)/α`. This file provides
//! `W_k(z)` for any integer branch `k` by Halley iteration on `f(w) = w e^w − z`, started
//! from the branch-point series near `z = −1/e`, from `w ≈ z` near the origin (principal
//! branch) and from the logarithmic asymptotic series elsewhere.
//!
//! # Reference
//! R. M. Corless, G. H. Gonnet, D. E. G. Hare, D. J. Jeffrey, D. E. Knuth, "On the Lambert W
//! function", Adv. Comput. Math. 5 (1996) 329–359 (branch cuts, series, Halley's method).

use num_complex::Complex64;
use std::f64::consts::{E, PI};

/// Failure of the Lambert W evaluation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LambertWError {
    /// The argument has a NaN or infinite component.
    #[error("Lambert W argument z = {re} + {im}i is not finite")]
    NonFiniteArgument {
        /// Real part of the argument.
        re: f64,
        /// Imaginary part of the argument.
        im: f64,
    },
    /// `W_k(0)` is `−∞` for every branch `k ≠ 0`.
    #[error("Lambert W branch {branch} is singular at z = 0 (only branch 0 is finite there)")]
    SingularAtZero {
        /// Requested branch index.
        branch: i64,
    },
    /// Halley's iteration did not reach the tolerance.
    #[error("Lambert W branch {branch} did not converge at z = {re} + {im}i after {iterations} Halley steps")]
    NoConvergence {
        /// Requested branch index.
        branch: i64,
        /// Real part of the argument.
        re: f64,
        /// Imaginary part of the argument.
        im: f64,
        /// Number of Halley steps taken.
        iterations: usize,
    },
}

const MAX_HALLEY_STEPS: usize = 100;

/// Branch `k` of the Lambert W function: the solution `w` of `w e^w = z` that lies on
/// branch `k` of the standard (Corless et al.) branch structure.
///
/// The principal branch `k = 0` is real on `[−1/e, ∞)`; branches `k = −1` and `k = 1`
/// meet it at the branch point `−1/e`. On the negative real axis (the branch cuts) the value
/// is the limit from above, `Im z ↓ 0`, as in Corless et al.
///
/// # Errors
/// [`LambertWError::NonFiniteArgument`], [`LambertWError::SingularAtZero`] for `k ≠ 0, z = 0`,
/// and [`LambertWError::NoConvergence`] if Halley's iteration stalls.
pub fn lambert_w(branch: i64, z: Complex64) -> Result<Complex64, LambertWError> {
    if !z.re.is_finite() || !z.im.is_finite() {
        return Err(LambertWError::NonFiniteArgument { re: z.re, im: z.im });
    }
    if z == Complex64::new(0.0, 0.0) {
        return if branch == 0 {
            Ok(Complex64::new(0.0, 0.0))
        } else {
            Err(LambertWError::SingularAtZero { branch })
        };
    }
    // Negative real axis with a signed zero imaginary part: use +0 so that the closed side
    // of each cut is reproduced consistently.
    let z = if z.im == 0.0 {
        Complex64::new(z.re, 0.0)
    } else {
        z
    };
    // On the principal branch cut (−∞, −1/e) the two limits are conjugate; the iteration may
    // land on either, so the closed side (from above, Im W_0 ∈ (0, π)) is restored afterwards.
    let on_principal_cut = branch == 0 && z.im == 0.0 && z.re < -1.0 / E;
    let close_cut = |w: Complex64| {
        if on_principal_cut && w.im < 0.0 {
            w.conj()
        } else {
            w
        }
    };
    let mut w = initial_guess(branch, z);
    let scale = z.norm().max(f64::MIN_POSITIVE);
    for iteration in 0..MAX_HALLEY_STEPS {
        let ew = w.exp();
        let f = w * ew - z;
        let wp1 = w + 1.0;
        let denom = ew * wp1 - (w + 2.0) * f / (2.0 * wp1);
        if denom.norm() == 0.0 || !denom.re.is_finite() {
            break;
        }
        let step = f / denom;
        w -= step;
        if step.norm() <= 4.0 * f64::EPSILON * (1.0 + w.norm()) {
            return Ok(close_cut(w));
        }
        // Halley converges cubically; a tiny residual relative to |z| is also accepted.
        if iteration > 3 && (w * w.exp() - z).norm() <= 8.0 * f64::EPSILON * scale {
            return Ok(close_cut(w));
        }
    }
    // Accept a result whose residual is at rounding level (happens at the branch point,
    // where the iteration converges only linearly because w + 1 → 0).
    if (w * w.exp() - z).norm() <= 1e-12 * scale.max(1.0) && w.re.is_finite() {
        return Ok(close_cut(w));
    }
    Err(LambertWError::NoConvergence {
        branch,
        re: z.re,
        im: z.im,
        iterations: MAX_HALLEY_STEPS,
    })
}

/// Starting point for Halley's iteration on branch `k`.
fn initial_guess(k: i64, z: Complex64) -> Complex64 {
    let branch_point_distance = (z + 1.0 / E).norm();
    // Branch-point series W = −1 + p − p²/3 + 11p³/72 with p = ±sqrt(2(ez + 1)).
    // Branch 0 takes +p; branch −1 takes −p on the upper half plane (closed side of its cut
    // on the real axis) and branch 1 takes −p on the lower half plane.
    let near_branch_point = branch_point_distance < 0.3;
    // On the principal cut near the branch point a real start would keep Halley real.
    let near_principal_cut = z.im == 0.0 && z.re < -1.0 / E && z.re > -3.0;
    let use_series = match k {
        0 => near_branch_point || near_principal_cut,
        -1 => near_branch_point && z.im >= 0.0,
        1 => near_branch_point && z.im < 0.0,
        _ => false,
    };
    if use_series {
        let mut p = (2.0 * (E * z + 1.0)).sqrt();
        if k != 0 {
            p = -p;
        }
        return -1.0 + p - p * p / 3.0 + 11.0 / 72.0 * p * p * p;
    }
    if k == 0 && z.norm() < 1.0 {
        // Taylor start near the origin: W(z) ≈ z − z² + 1.5 z³.
        return z * (1.0 - z + 1.5 * z * z);
    }
    if k == 0 && z.norm() < 3.0 {
        // Between origin and asymptotic regime: log(1 + z) is a good start for branch 0.
        return (1.0 + z).ln();
    }
    // Asymptotic series W_k(z) ≈ L1 − L2 + L2/L1 with L1 = ln z + 2πik, L2 = ln L1.
    let l1 = z.ln() + Complex64::new(0.0, 2.0 * PI * k as f64);
    let l2 = l1.ln();
    l1 - l2 + l2 / l1
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn residual(w: Complex64, z: Complex64) -> f64 {
        (w * w.exp() - z).norm() / z.norm().max(1.0)
    }

    #[test]
    fn real_principal_values_match_known_constants() {
        // Omega constant: W(1) = 0.567143290409783872999...
        let w = lambert_w(0, Complex64::new(1.0, 0.0)).unwrap();
        assert_relative_eq!(w.re, 0.567_143_290_409_784, epsilon = 1e-15);
        assert!(w.im.abs() < 1e-15);
        // W(e) = 1, W(−1/e) = −1, W(−ln2/2) = −ln 2 (since −ln2 e^{−ln2} = −ln2/2).
        let w = lambert_w(0, Complex64::new(E, 0.0)).unwrap();
        assert_relative_eq!(w.re, 1.0, epsilon = 1e-15);
        let w = lambert_w(0, Complex64::new(-1.0 / E, 0.0)).unwrap();
        assert_relative_eq!(w.re, -1.0, epsilon = 1e-7);
        let w = lambert_w(0, Complex64::new(-(2f64.ln()) / 2.0, 0.0)).unwrap();
        assert_relative_eq!(w.re, -(2f64.ln()), epsilon = 1e-14);
        // Branch −1 on (−1/e, 0): W_{−1}(−ln2/2) = −2 ln 2 (−2ln2 · e^{−2ln2} = −ln2/2).
        let w = lambert_w(-1, Complex64::new(-(2f64.ln()) / 2.0, 0.0)).unwrap();
        assert_relative_eq!(w.re, -2.0 * 2f64.ln(), epsilon = 1e-14);
        assert!(w.im.abs() < 1e-14);
        // On the cut, from above: W_0(−π/2) = iπ/2 (iπ/2 · e^{iπ/2} = −π/2).
        let w = lambert_w(0, Complex64::new(-PI / 2.0, 0.0)).unwrap();
        assert!(w.re.abs() < 1e-15);
        assert_relative_eq!(w.im, PI / 2.0, epsilon = 1e-15);
        // Tabulated complex values (Corless et al., conjugate pair on branches ±1):
        // W_{±1}(1) = −1.533913319793574... ± 4.375185153061898...i
        let w = lambert_w(1, Complex64::new(1.0, 0.0)).unwrap();
        assert_relative_eq!(w.re, -1.533_913_319_793_574, epsilon = 1e-13);
        assert_relative_eq!(w.im, 4.375_185_153_061_898, epsilon = 1e-13);
        let w = lambert_w(-1, Complex64::new(1.0, 0.0)).unwrap();
        assert_relative_eq!(w.im, -4.375_185_153_061_898, epsilon = 1e-13);
    }

    #[test]
    fn defining_identity_and_branch_logarithm_hold_on_all_branches() {
        // W_k(z) e^{W_k(z)} = z, and off the real axis the branch index is pinned by
        // ln W_k(z) + W_k(z) = ln z + 2πik with principal logarithms (Corless et al., §4):
        // a value from a neighbouring branch would be off by 2πi.
        let mut checked = 0;
        for k in -6i64..=6 {
            for &r in &[1e-6, 0.01, 0.2, 0.367, 0.5, 1.0, 3.0, 10.0, 1e3, 1e8] {
                for j in 0..24 {
                    let theta = -PI + (j as f64 + 0.5) * 2.0 * PI / 24.0;
                    let z = Complex64::from_polar(r, theta);
                    let w = lambert_w(k, z).unwrap();
                    assert!(residual(w, z) < 1e-13, "k={k} z={z} w={w}");
                    let lhs = w.ln() + w;
                    let rhs = z.ln() + Complex64::new(0.0, 2.0 * PI * k as f64);
                    assert!(
                        (lhs - rhs).norm() < 1e-10 * (1.0 + rhs.norm()),
                        "branch identity failed k={k} z={z} w={w}"
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 13 * 10 * 24);
    }

    #[test]
    fn values_on_the_negative_real_axis_are_limits_from_above() {
        for k in -3i64..=3 {
            for &x in &[-0.2, -0.3, -0.5, -1.0, -2.0, -10.0, -1e4] {
                let on_axis = lambert_w(k, Complex64::new(x, 0.0)).unwrap();
                let above = lambert_w(k, Complex64::new(x, 1e-12)).unwrap();
                assert!(
                    (on_axis - above).norm() < 1e-9,
                    "k={k} x={x}: {on_axis} vs {above}"
                );
            }
        }
    }

    #[test]
    fn branch_point_neighbourhood_converges() {
        for &eps in &[1e-14, 1e-10, 1e-6, 1e-3, 0.1] {
            for j in 0..8 {
                let theta = -PI + (j as f64 + 0.5) * PI / 4.0;
                let z = Complex64::new(-1.0 / E, 0.0) + Complex64::from_polar(eps, theta);
                for k in -1..=1 {
                    let w = lambert_w(k, z).unwrap();
                    assert!(residual(w, z) < 1e-12, "k={k} z={z} w={w}");
                }
            }
        }
    }

    #[test]
    fn principal_branch_has_the_largest_real_part() {
        // Needed by the ring fast path: the rightmost root of s + λe^{−sα} = 0 is W_0(−λα)/α.
        for &r in &[0.05, 0.3, 1.0, 1.5, 3.0, 20.0] {
            for j in 0..36 {
                let z = Complex64::from_polar(r, -PI + (j as f64 + 0.5) * PI / 18.0);
                let w0 = lambert_w(0, z).unwrap().re;
                for k in [-3i64, -2, -1, 1, 2, 3] {
                    assert!(lambert_w(k, z).unwrap().re < w0, "k={k} z={z}");
                }
            }
        }
    }

    #[test]
    fn errors_name_the_problem() {
        let e = lambert_w(0, Complex64::new(f64::NAN, 0.0)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "Lambert W argument z = NaN + 0i is not finite"
        );
        let e = lambert_w(-1, Complex64::new(0.0, 0.0)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "Lambert W branch -1 is singular at z = 0 (only branch 0 is finite there)"
        );
    }
}
