//! Independent certificate for the rightmost roots: counting characteristic roots to the right
//! of a vertical line by the argument principle.
//!
//! Every root `s` of `det(sI + diag(e^{−sα_i})L) = 0` (eq. `chandler+`) is an eigenvalue of
//! `−diag(e^{−sα_i})L`, so by Gershgorin a root with `Re s ≥ σ` satisfies
//! `|s| ≤ B(σ) = max_i 2 d_i^+ e^{−σα_i}`. The number of roots in `{Re s > σ}` is therefore the
//! winding number of `det M(s)` (an entire function) around the rectangle
//! `[σ, B + 1] × [−(B + 1), B + 1]`, which is computed by following `arg det M(s)` along the
//! boundary with an adaptive step (the phase may change by at most 0.5 rad between samples).
//! This uses neither the collocation nor Newton's method, so it can certify them: no root
//! lies right of the computed abscissa, and the reported rightmost roots are all there are.

use super::collocation::{laplacian, validate_network, CollocationError};
use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;

/// Failure of the root count.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArgumentPrincipleError {
    /// Invalid network description.
    #[error(transparent)]
    Network(#[from] CollocationError),
    /// `σ` is not finite.
    #[error("abscissa line σ = {sigma} must be finite")]
    NonFiniteLine {
        /// The offending value.
        sigma: f64,
    },
    /// The contour passes (numerically) through a root; move `σ` slightly.
    #[error("a characteristic root lies on the contour near s = {re} + {im}i; shift σ slightly")]
    RootOnContour {
        /// Real part of the contour point.
        re: f64,
        /// Imaginary part of the contour point.
        im: f64,
    },
}

/// Number of characteristic roots with `Re s > σ`, counted with multiplicity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RootCount {
    /// The vertical line `σ` [1/s].
    pub sigma: f64,
    /// Roots strictly right of `σ`, including the consensus root `0` when `σ < 0`.
    pub count: usize,
    /// Whether the count includes the consensus root (`σ < 0`).
    pub includes_consensus: bool,
    /// Half-width `B + 1` of the enclosing rectangle [1/s].
    pub radius: f64,
    /// Determinant evaluations used.
    pub evaluations: usize,
}

impl RootCount {
    /// Roots right of `σ` other than consensus.
    pub fn non_consensus(&self) -> usize {
        self.count
            .saturating_sub(usize::from(self.includes_consensus))
    }
}

/// Counts the characteristic roots of eq. `chandler+` with `Re s > σ` by the argument principle.
///
/// # Errors
/// [`ArgumentPrincipleError`] for invalid input or a root on the contour.
pub fn count_roots_right_of(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    sigma: f64,
) -> Result<RootCount, ArgumentPrincipleError> {
    let n = validate_network(adjacency, delays_s)?;
    if !sigma.is_finite() {
        return Err(ArgumentPrincipleError::NonFiniteLine { sigma });
    }
    let l = laplacian(adjacency);
    let bound = (0..n)
        .map(|i| 2.0 * l[(i, i)] * (-sigma * delays_s[i]).exp())
        .fold(0.0, f64::max);
    let r = bound + 1.0;
    let right = r.max(sigma + 1.0);
    // Counter-clockwise rectangle.
    let corners = [
        Complex64::new(sigma, -r),
        Complex64::new(right, -r),
        Complex64::new(right, r),
        Complex64::new(sigma, r),
    ];
    let phase = |s: Complex64| -> Option<Complex64> {
        let mut m = DMatrix::from_fn(n, n, |i, j| {
            Complex64::new(l[(i, j)], 0.0) * (-s * delays_s[i]).exp()
        });
        for i in 0..n {
            m[(i, i)] += s;
        }
        let d = m.lu().determinant();
        let norm = d.norm();
        (norm.is_finite() && norm > 0.0).then(|| d / norm)
    };
    let scale = r + sigma.abs();
    let mut evaluations = 0;
    let mut total_angle = 0.0;
    for side in 0..4 {
        let (a, b) = (corners[side], corners[(side + 1) % 4]);
        let length = (b - a).norm();
        let dir = (b - a) / length;
        let mut t = 0.0;
        let mut h = length / 200.0;
        let on_contour =
            |s: Complex64| ArgumentPrincipleError::RootOnContour { re: s.re, im: s.im };
        let mut p = phase(a).ok_or_else(|| on_contour(a))?;
        evaluations += 1;
        while t < length {
            let step = h.min(length - t);
            let s_next = a + dir * (t + step);
            evaluations += 1;
            let q = phase(s_next).ok_or_else(|| on_contour(s_next))?;
            let delta = (q / p).arg();
            if delta.abs() > 0.5 {
                h = step / 2.0;
                if h < 1e-13 * scale {
                    return Err(on_contour(s_next));
                }
                continue;
            }
            total_angle += delta;
            p = q;
            t += step;
            if delta.abs() < 0.1 {
                h = (2.0 * step).min(length / 20.0);
            }
        }
    }
    let winding = total_angle / (2.0 * std::f64::consts::PI);
    let count = winding.round();
    if (winding - count).abs() > 1e-6 || count < 0.0 {
        return Err(ArgumentPrincipleError::RootOnContour { re: sigma, im: 0.0 });
    }
    Ok(RootCount {
        sigma,
        count: count as usize,
        includes_consensus: sigma < 0.0,
        radius: r,
        evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::super::collocation::tests::{random_network, Lcg};
    use super::super::collocation::{rightmost_roots, CollocationOptions};
    use super::super::ring_modes::UniformRing;
    use super::*;

    #[test]
    fn ring_counts_match_lambert_w_roots_on_all_branches() {
        // Oracle: enumerate the roots W_b(−λ_k α)/α of every mode on branches |b| ≤ 8 (those
        // further out have Re s ≪ σ here) and count the ones right of σ.
        for &(n, kf, kb, alpha) in &[
            (6usize, 1.0, 0.0, 0.5),
            (9, 0.8, 0.4, 1.0),
            (12, 1.5, 0.5, 0.7),
        ] {
            let ring = UniformRing::new(n, kf, kb, alpha).unwrap();
            for &sigma in &[-2.5, -1.0, -0.3, 0.05] {
                let mut expected = 0;
                for k in 0..n {
                    for b in -8i64..=8 {
                        if k == 0 && b != 0 {
                            continue; // λ_0 = 0: only the consensus root
                        }
                        if ring.mode_root(k, b).unwrap().re > sigma {
                            expected += 1;
                        }
                    }
                }
                let c = count_roots_right_of(&ring.adjacency(), &ring.delays(), sigma).unwrap();
                assert_eq!(c.count, expected, "N={n} σ={sigma}");
            }
        }
    }

    #[test]
    fn collocation_misses_no_root_right_of_its_abscissa() {
        let mut rng = Lcg(99);
        for trial in 0..8 {
            let n = 3 + trial % 6;
            let (mut a, delays) = random_network(n, &mut rng);
            let worst = (0..n)
                .map(|i| delays[i] * a.row(i).sum())
                .fold(0.0, f64::max);
            a *= (0.3 + 1.2 * rng.next()) / worst;
            let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
            let margin = 1e-6 * (1.0 + r.abscissa.abs());
            let right = count_roots_right_of(&a, &delays, r.abscissa + margin).unwrap();
            assert_eq!(
                right.non_consensus(),
                0,
                "trial {trial}: roots beyond the abscissa"
            );
            // Just left of the abscissa the dominant root (pair) appears.
            let left = count_roots_right_of(&a, &delays, r.abscissa - margin).unwrap();
            let expected = if r.roots[0].root.im > 0.0 { 2 } else { 1 };
            assert_eq!(left.non_consensus(), expected, "trial {trial}");
        }
    }

    #[test]
    fn mixed_undelayed_and_delayed_drivers_are_certified_too() {
        // Drivers with α_i = 0 carry no input history in the collocation; check that the
        // reduced generator still finds the rightmost roots.
        let mut rng = Lcg(5);
        for trial in 0..6 {
            let n = 4 + trial;
            let (mut a, mut delays) = random_network(n, &mut rng);
            for (i, d) in delays.iter_mut().enumerate() {
                if i % 2 == trial % 2 {
                    *d = 0.0;
                }
            }
            let worst = (0..n)
                .map(|i| delays[i] * a.row(i).sum())
                .fold(0.0, f64::max);
            a *= 1.2 / worst;
            let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
            let margin = 1e-6 * (1.0 + r.abscissa.abs());
            let right = count_roots_right_of(&a, &delays, r.abscissa + margin).unwrap();
            assert_eq!(right.non_consensus(), 0, "trial {trial}");
            let left = count_roots_right_of(&a, &delays, r.abscissa - margin).unwrap();
            let expected = if r.roots[0].root.im > 0.0 { 2 } else { 1 };
            assert_eq!(left.non_consensus(), expected, "trial {trial}");
        }
    }

    #[test]
    fn errors_are_specific() {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 1.0, 0.0]);
        assert_eq!(
            count_roots_right_of(&a, &[0.5, 0.5], f64::NAN)
                .unwrap_err()
                .to_string(),
            "abscissa line σ = NaN must be finite"
        );
        // The consensus root s = 0 sits on the line σ = 0.
        let e = count_roots_right_of(&a, &[0.5, 0.5], 0.0).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("a characteristic root lies on the contour"),
            "{e}"
        );
    }
}
