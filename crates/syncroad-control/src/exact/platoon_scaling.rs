//! How the least-stable closed-loop eigenvalue of a bidirectional platoon shrinks with its
//! size `N`, and the fitted exponent `p` of `|Re λ_max| ≈ C·N^p`.
//!
//! Two laws:
//! * [`PlatoonLaw::Cacc`] — the paper's CACC law (eqs. `veh1`, `veh-proto1`, `veh-proto2`),
//!   homogeneous, with the leader's speed broadcast to every follower (the `μ_i(v_0 − v_i)`
//!   term). Per Laplacian mode `λ` of the gap coupling (the grounded path with gains `η`
//!   forward and `ν` backward) the characteristic polynomial is `τs³ + s² + μs + λ`, so for
//!   small `λ` the least-stable root is about `−λ_min/μ`. With symmetric gains `η = ν`,
//!   `λ_min ≈ η(π/(2N + 1))²`: exponent −2. With front/back mistuning `η > ν` the
//!   similarity `diag(√(η/ν)^i)` makes the path symmetric with off-diagonal `√(ην)`, and
//!   `λ_min → (√η − √ν)²`: the eigenvalue stays bounded away from zero (exponent → 0); with
//!   `η < ν` a mode localized at the tail makes it exponentially small. So for this law the
//!   `O(1/N)` of mistuning does not appear; the fit says so rather than assuming it. (The
//!   same similarity, with entries `(η/ν)^{i/2}`, makes a mistuned platoon's matrix strongly
//!   non-normal: its computed eigenvalues lose accuracy like `ε·(η/ν)^{N/2}`.)
//! * [`PlatoonLaw::RelativeVelocity`] — the double-integrator law of Barooah, Mehta &
//!   Hespanha, `ẍ_i = −k_f(x_i − x_{i−1} + Δ) − k_b(x_i − x_{i+1} − Δ) − b_f(ẋ_i − ẋ_{i−1})
//!   − b_b(ẋ_i − ẋ_{i+1})` (no leader broadcast; the last vehicle has no follower term). With
//!   symmetric gains the least-stable eigenvalue is `O(1/N²)`; mistuning the velocity gains
//!   (`b_f = b_0(1 + ε)`, `b_b = b_0(1 − ε)`) improves it to `O(1/N)`.
//!
//! # Reference
//! P. Barooah, P. G. Mehta, J. P. Hespanha, "Mistuning-based control design to improve
//! closed-loop stability margin of vehicular platoons", IEEE Trans. Automatic Control 54(9)
//! (2009) 2100–2113.
//! I. Herman, D. Martinec, Z. Hurák, M. Šebek, "Nonzero bound on Fiedler eigenvalue causes
//! exponential growth of H-infinity norm of vehicular platoon", IEEE Trans. Automatic
//! Control 60(8) (2015) 2248–2253.

use super::cacc_modes::{cacc_modes, CaccError, CaccParams};
use super::collocation::{eigenvalues, CollocationError};
use nalgebra::DMatrix;
use serde::Serialize;

/// Failure of the scaling study.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlatoonScalingError {
    /// Fewer than two distinct sizes: no exponent can be fitted.
    #[error("platoon scaling needs at least 2 distinct platoon sizes ≥ 2, got {sizes:?}")]
    TooFewSizes {
        /// The sizes given.
        sizes: Vec<usize>,
    },
    /// A gain is not finite or out of range.
    #[error("platoon law gain {name} = {value} must be finite and > 0")]
    InvalidGain {
        /// Which gain.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// The CACC platoon could not be analysed.
    #[error("CACC platoon of {vehicles} followers: {source}")]
    Cacc {
        /// Platoon size.
        vehicles: usize,
        /// Cause.
        source: CaccError,
    },
    /// Eigenvalues of the relative-velocity platoon failed.
    #[error("platoon of {vehicles} vehicles: {source}")]
    Eigenvalues {
        /// Platoon size.
        vehicles: usize,
        /// Cause.
        source: CollocationError,
    },
    /// The platoon is not asymptotically stable at some size; the exponent is meaningless.
    #[error("the platoon of {vehicles} vehicles is not asymptotically stable (spectral abscissa {abscissa} ≥ 0)")]
    Unstable {
        /// Platoon size.
        vehicles: usize,
        /// Spectral abscissa [1/s].
        abscissa: f64,
    },
}

/// A homogeneous bidirectional platoon law.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "law", rename_all = "snake_case")]
pub enum PlatoonLaw {
    /// The paper's CACC law with leader-speed broadcast.
    Cacc {
        /// Powertrain lag τ \[s\].
        tau_s: f64,
        /// Speed gain μ [1/s].
        mu: f64,
        /// Front gap gain η [1/s²].
        eta: f64,
        /// Rear gap gain ν [1/s²].
        nu: f64,
    },
    /// Barooah–Mehta–Hespanha's double integrators with relative position and velocity.
    RelativeVelocity {
        /// Front position gain `k_f` [1/s²].
        k_front: f64,
        /// Rear position gain `k_b` [1/s²].
        k_back: f64,
        /// Front velocity gain `b_f` [1/s].
        b_front: f64,
        /// Rear velocity gain `b_b` [1/s].
        b_back: f64,
    },
}

/// Least-stable eigenvalue at one size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ScalingPoint {
    /// Number of followers `N`.
    pub vehicles: usize,
    /// Real part of the least-stable eigenvalue [1/s] (negative).
    pub least_stable_re: f64,
}

/// The study: one point per size and the fitted power law.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlatoonScaling {
    /// The law.
    pub law: PlatoonLaw,
    /// Points by increasing size.
    pub points: Vec<ScalingPoint>,
    /// Least-squares slope `p` of `ln|Re λ|` against `ln N`.
    pub exponent: f64,
    /// `C` of `|Re λ| ≈ C N^p` [1/s].
    pub prefactor: f64,
}

/// Sizes of the default study, N = 10 … 200 roughly evenly in log N.
pub const DEFAULT_SIZES: [usize; 9] = [10, 15, 20, 30, 45, 65, 100, 140, 200];

impl PlatoonLaw {
    fn validate(&self) -> Result<(), PlatoonScalingError> {
        let gains: Vec<(&'static str, f64)> = match *self {
            PlatoonLaw::Cacc { tau_s, mu, eta, nu } => {
                vec![("tau_s", tau_s), ("mu", mu), ("eta", eta), ("nu", nu)]
            }
            PlatoonLaw::RelativeVelocity {
                k_front,
                k_back,
                b_front,
                b_back,
            } => vec![
                ("k_front", k_front),
                ("k_back", k_back),
                ("b_front", b_front),
                ("b_back", b_back),
            ],
        };
        for (name, value) in gains {
            if !(value.is_finite() && value > 0.0) {
                return Err(PlatoonScalingError::InvalidGain { name, value });
            }
        }
        Ok(())
    }

    /// Spectral abscissa of the closed loop with `n` followers [1/s].
    ///
    /// # Errors
    /// [`PlatoonScalingError`] for invalid gains or a failed eigenvalue computation.
    pub fn abscissa(&self, n: usize) -> Result<f64, PlatoonScalingError> {
        self.validate()?;
        match *self {
            PlatoonLaw::Cacc { tau_s, mu, eta, nu } => {
                cacc_modes(&CaccParams::homogeneous(n, tau_s, mu, eta, nu))
                    .map(|m| m.abscissa)
                    .map_err(|source| PlatoonScalingError::Cacc {
                        vehicles: n,
                        source,
                    })
            }
            PlatoonLaw::RelativeVelocity {
                k_front,
                k_back,
                b_front,
                b_back,
            } => {
                // State (x_1 … x_N, v_1 … v_N) relative to the leader's trajectory.
                let mut a = DMatrix::zeros(2 * n, 2 * n);
                for i in 0..n {
                    a[(i, n + i)] = 1.0;
                    let (kb, bb) = if i + 1 < n {
                        (k_back, b_back)
                    } else {
                        (0.0, 0.0)
                    };
                    a[(n + i, i)] = -(k_front + kb);
                    a[(n + i, n + i)] = -(b_front + bb);
                    if i > 0 {
                        a[(n + i, i - 1)] = k_front;
                        a[(n + i, n + i - 1)] = b_front;
                    }
                    if i + 1 < n {
                        a[(n + i, i + 1)] = kb;
                        a[(n + i, n + i + 1)] = bb;
                    }
                }
                let eig = eigenvalues(a).map_err(|source| PlatoonScalingError::Eigenvalues {
                    vehicles: n,
                    source,
                })?;
                Ok(eig.iter().map(|z| z.re).fold(f64::NEG_INFINITY, f64::max))
            }
        }
    }
}

/// Least-stable eigenvalue at every size and the fitted exponent.
///
/// # Errors
/// [`PlatoonScalingError`] for fewer than two sizes, invalid gains, a failed eigenvalue
/// computation, or a platoon that is unstable at some size.
pub fn platoon_scaling(
    law: PlatoonLaw,
    sizes: &[usize],
) -> Result<PlatoonScaling, PlatoonScalingError> {
    let mut sizes: Vec<usize> = sizes.iter().copied().filter(|&n| n >= 2).collect();
    sizes.sort_unstable();
    sizes.dedup();
    if sizes.len() < 2 {
        return Err(PlatoonScalingError::TooFewSizes { sizes });
    }
    let mut points = Vec::with_capacity(sizes.len());
    for &n in &sizes {
        let abscissa = law.abscissa(n)?;
        if abscissa >= 0.0 {
            return Err(PlatoonScalingError::Unstable {
                vehicles: n,
                abscissa,
            });
        }
        points.push(ScalingPoint {
            vehicles: n,
            least_stable_re: abscissa,
        });
    }
    let xs: Vec<f64> = points.iter().map(|p| (p.vehicles as f64).ln()).collect();
    let ys: Vec<f64> = points.iter().map(|p| (-p.least_stable_re).ln()).collect();
    let k = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / k, ys.iter().sum::<f64>() / k);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    let exponent = sxy / sxx;
    Ok(PlatoonScaling {
        law,
        points,
        exponent,
        prefactor: (my - exponent * mx).exp(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::PI;

    const CACC_SYM: PlatoonLaw = PlatoonLaw::Cacc {
        tau_s: 0.3,
        mu: 1.2,
        eta: 0.3,
        nu: 0.3,
    };

    #[test]
    fn symmetric_cacc_gains_scale_as_one_over_n_squared() {
        let r = platoon_scaling(CACC_SYM, &DEFAULT_SIZES).unwrap();
        assert!((r.exponent + 2.0).abs() < 0.1, "exponent {}", r.exponent);
        // Closed form at N = 200: the grounded path with a free end has
        // λ_min = 4η sin²(π/(2(2N + 1))); the least-stable root is that of
        // τs³ + s² + μs + λ_min, ≈ −λ_min/μ to first order in λ_min.
        let lambda = 4.0 * 0.3 * (PI / (2.0 * 401.0)).sin().powi(2);
        let last = r.points.last().unwrap();
        assert_relative_eq!(last.least_stable_re, -lambda / 1.2, max_relative = 1e-3);
    }

    #[test]
    fn relative_velocity_law_reproduces_barooah_mehta_hespanha() {
        let sym = PlatoonLaw::RelativeVelocity {
            k_front: 1.0,
            k_back: 1.0,
            b_front: 0.5,
            b_back: 0.5,
        };
        let r = platoon_scaling(sym, &DEFAULT_SIZES).unwrap();
        assert!(
            (r.exponent + 2.0).abs() < 0.1,
            "symmetric exponent {}",
            r.exponent
        );
        let mistuned = PlatoonLaw::RelativeVelocity {
            k_front: 1.0,
            k_back: 1.0,
            b_front: 0.5 * 1.5,
            b_back: 0.5 * 0.5,
        };
        let r = platoon_scaling(mistuned, &DEFAULT_SIZES).unwrap();
        assert!(
            (r.exponent + 1.0).abs() < 0.1,
            "mistuned exponent {}",
            r.exponent
        );
    }

    #[test]
    fn mistuned_cacc_gap_gains_keep_a_uniform_margin() {
        // η > ν: λ_min → (√η − √ν)², and the least-stable root tends to the rightmost root of
        // τs³ + s² + μs + (√η − √ν)².
        let law = PlatoonLaw::Cacc {
            tau_s: 0.3,
            mu: 1.2,
            eta: 0.36,
            nu: 0.24,
        };
        let lambda = (0.6f64 - 0.24f64.sqrt()).powi(2);
        // Rightmost (real) root of the cubic by Newton from 0.
        let (p, dp) = (
            |s: f64| ((0.3 * s + 1.0) * s + 1.2) * s + lambda,
            |s: f64| (0.9 * s + 2.0) * s + 1.2,
        );
        let mut s = 0.0;
        for _ in 0..50 {
            s -= p(s) / dp(s);
        }
        let r = law.abscissa(100).unwrap();
        // The finite-N correction is O(1/N²) (2 % at N = 100).
        assert_relative_eq!(r, s, max_relative = 0.05);
        // Up to N = 100, where the non-normal eigenvalues are still accurate (module docs).
        let fit = platoon_scaling(law, &DEFAULT_SIZES[..7]).unwrap();
        assert!(fit.exponent > -0.5, "exponent {}", fit.exponent);
    }

    #[test]
    fn errors_are_specific() {
        assert_eq!(
            platoon_scaling(CACC_SYM, &[10]).unwrap_err().to_string(),
            "platoon scaling needs at least 2 distinct platoon sizes ≥ 2, got [10]"
        );
        let bad = PlatoonLaw::Cacc {
            tau_s: 0.3,
            mu: -1.0,
            eta: 0.3,
            nu: 0.3,
        };
        assert_eq!(
            platoon_scaling(bad, &[10, 20]).unwrap_err().to_string(),
            "platoon law gain mu = -1 must be finite and > 0"
        );
    }
}
