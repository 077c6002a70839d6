//! Combined, serializable results for a command-line front end: JSON through `serde`, a plain
//! text table through `Display`.

use super::argument_principle::{count_roots_right_of, ArgumentPrincipleError, RootCount};
use super::cacc_modes::{cacc_modes, CaccError, CaccModes, CaccParams};
use super::collocation::{
    rightmost_roots, rightmost_roots_shift_invert, CollocationError, CollocationOptions,
    RootsReport,
};
use super::critical::{critical_scale_from, CriticalError, CriticalMethod, CriticalReport};
use super::ring_modes::RingModes;
use super::string_stability::{
    string_stability, StringStabilityError, StringStabilityOptions, StringStabilityReport,
};
use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;
use std::fmt;

/// Failure of a combined analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReportError {
    /// Root computation failed or the network is invalid.
    #[error("characteristic roots: {0}")]
    Roots(#[from] CollocationError),
    /// Critical-scale search failed for a reason other than "no delay".
    #[error("critical scale: {0}")]
    Critical(#[from] CriticalError),
    /// The argument-principle certificate failed.
    #[error("root-count certificate: {0}")]
    Certificate(#[from] ArgumentPrincipleError),
    /// Invalid platoon.
    #[error("CACC platoon: {0}")]
    Cacc(#[from] CaccError),
    /// String-stability analysis failed.
    #[error("string stability: {0}")]
    StringStability(#[from] StringStabilityError),
}

/// Exact stability of a delayed-driver network (eq. `chandler+`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NetworkStabilityReport {
    /// Rightmost roots, abscissa and residuals at the given gains and delays.
    pub roots: RootsReport,
    /// Critical gain/delay scales and Theorem-1 conservatism; `None` when no driver is
    /// delayed (stable for every gain).
    pub critical: Option<CriticalReport>,
    /// Argument-principle certificate of the rightmost roots, if requested.
    pub certificate: Option<RootsCertificate>,
}

/// Argument-principle counts on both sides of the computed abscissa `a`: right of `a + δ`
/// nothing (but consensus, if `a + δ < 0`), right of `a − δ` exactly the reported roots with
/// real part above `a − δ`, with their multiplicities and conjugates. `δ` is a quarter of the
/// gap to the next reported root (at most `0.05(1 + |a|)`, and at most `|a|/2`, so that
/// neither line meets the consensus root).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RootsCertificate {
    /// `δ` [1/s].
    pub margin: f64,
    /// Count right of `a − δ`.
    pub left: RootCount,
    /// Count right of `a + δ`.
    pub right: RootCount,
    /// Expected `left.count` from the reported roots.
    pub expected_left: usize,
    /// Expected `right.count` (1 when the consensus root lies right of `a + δ`).
    pub expected_right: usize,
    /// Both counts as expected: no root was missed and the multiplicities are right.
    pub certified: bool,
}

impl RootsCertificate {
    /// The verdict the two counts prove on their own, whatever roots the solve missed:
    /// `Some(true)` when the count right of `a + δ < 0` finds the consensus root alone (every
    /// other root lies left of it), `Some(false)` when the count right of `a − δ > 0` finds a
    /// root, `None` when neither decides.
    pub fn verdict_by_counts(&self) -> Option<bool> {
        if self.right.sigma < 0.0 && self.right.count == 1 {
            Some(true)
        } else if self.left.sigma > 0.0 && self.left.count > 0 {
            Some(false)
        } else {
            None
        }
    }
}

impl NetworkStabilityReport {
    /// `Some(true)` synchronizes, `Some(false)` does not, `None` when the certificate was
    /// requested and failed (roots may have been missed) and its counts do not decide the
    /// verdict on their own ([`RootsCertificate::verdict_by_counts`]).
    pub fn certified_stability(&self) -> Option<bool> {
        match &self.certificate {
            Some(c) if !c.certified => c.verdict_by_counts(),
            _ => Some(self.roots.is_stable()),
        }
    }
}

/// Counts roots on both sides of the computed abscissa (see [`RootsCertificate`]).
///
/// # Errors
/// [`ArgumentPrincipleError`] if a count fails.
pub fn certify_roots(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    roots: &RootsReport,
) -> Result<RootsCertificate, ArgumentPrincipleError> {
    let a = roots.abscissa;
    let scale = 1.0 + a.abs();
    let gap = roots
        .roots
        .iter()
        .map(|r| a - r.root.re)
        .filter(|g| *g > 1e-9 * scale)
        .fold(f64::INFINITY, f64::min);
    let mut margin = if gap.is_finite() {
        (0.25 * gap).min(0.05 * scale)
    } else {
        1e-3 * scale
    };
    if a != 0.0 {
        margin = margin.min(0.5 * a.abs());
    }
    let (lo, hi) = (a - margin, a + margin);
    let left = count_roots_right_of(adjacency, delays_s, lo)?;
    let right = count_roots_right_of(adjacency, delays_s, hi)?;
    let in_strip: usize = roots
        .roots
        .iter()
        .filter(|r| r.root.re > lo)
        .map(|r| {
            let s = Complex64::from(r.root);
            let real = s.im.abs() <= 1e-12 * (1.0 + s.norm());
            r.multiplicity * if real { 1 } else { 2 }
        })
        .sum();
    let expected_left = in_strip + usize::from(lo < 0.0);
    let expected_right = usize::from(hi < 0.0);
    Ok(RootsCertificate {
        margin,
        left,
        right,
        expected_left,
        expected_right,
        certified: left.count == expected_left && right.count == expected_right,
    })
}

/// CACC platoon: eigenvalue verdicts and, if the platoon is stable, string stability.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaccReport {
    /// Eigenvalues with the exact and the Theorem `thm.cacc` verdicts.
    pub modes: CaccModes,
    /// The critical scale of the coupling gains `η_i`, `ν_i`, beside the theorem's.
    pub critical: super::CaccCritical,
    /// String-stability numbers (`None` for an unstable platoon).
    pub string_stability: Option<StringStabilityReport>,
}

/// Roots and critical scales of a delayed-driver network; with `certify`, also the
/// argument-principle count of roots beyond the computed abscissa.
///
/// # Errors
/// [`ReportError`] from the root, critical-scale or certificate computation.
pub fn analyse_network(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
    certify: bool,
) -> Result<NetworkStabilityReport, ReportError> {
    if certify {
        return analyse_network_reporting(adjacency, delays_s, options, &|_| {});
    }
    let roots = rightmost_roots(adjacency, delays_s, options)?;
    critical_after(adjacency, delays_s, options, roots, None)
}

/// [`analyse_network`] with the certificate, naming each step to `on_step` as it starts.
///
/// # Errors
/// As [`analyse_network`].
pub fn analyse_network_reporting(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
    on_step: &(dyn Fn(&'static str) + Sync),
) -> Result<NetworkStabilityReport, ReportError> {
    on_step("rightmost roots and their root count");
    let (roots, certificate) = certified_roots(adjacency, delays_s, options)?;
    on_step("critical gain scale");
    critical_after(adjacency, delays_s, options, roots, certificate)
}

/// The critical scale from the roots at the given gains, and the whole report.
fn critical_after(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
    roots: RootsReport,
    certificate: Option<RootsCertificate>,
) -> Result<NetworkStabilityReport, ReportError> {
    let critical = match critical_scale_from(adjacency, delays_s, &roots, options) {
        Ok(c) => Some(c),
        Err(CriticalError::NoDelay) => None,
        Err(e) => return Err(e.into()),
    };
    Ok(NetworkStabilityReport {
        roots,
        critical,
        certificate,
    })
}

pub use super::collocation::DENSE_SOLVE_LIMIT;

/// The rightmost roots with their certificate: shift-invert Arnoldi first
/// ([`rightmost_roots_shift_invert`]), and the dense collocation when that fails or its roots
/// are not certified (networks up to [`DENSE_SOLVE_LIMIT`]).
fn certified_roots(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
) -> Result<(RootsReport, Option<RootsCertificate>), ReportError> {
    let large = adjacency.nrows() > DENSE_SOLVE_LIMIT;
    let fast = match rightmost_roots_shift_invert(adjacency, delays_s, options) {
        // A count line through a root the solve missed fails the count: not certified.
        Ok(r) => match certify_roots(adjacency, delays_s, &r) {
            Ok(c) if c.certified || large => return Ok((r, Some(c))),
            Ok(c) => Some((r, c)),
            Err(e) if large => return Err(e.into()),
            Err(_) => None,
        },
        Err(e) if large => return Err(e.into()),
        Err(_) => None,
    };
    let dense = rightmost_roots(adjacency, delays_s, options)?;
    let c = certify_roots(adjacency, delays_s, &dense)?;
    match fast {
        // Keep the dense answer unless it is no better certified.
        Some((r, fc)) if !c.certified && fc.certified => Ok((r, Some(fc))),
        _ => Ok((dense, Some(c))),
    }
}

/// Eigenvalues, both verdicts and string stability of a CACC platoon.
///
/// # Errors
/// [`ReportError`] for invalid parameters or options.
pub fn analyse_cacc(
    params: &CaccParams,
    options: &StringStabilityOptions,
) -> Result<CaccReport, ReportError> {
    let modes = cacc_modes(params)?;
    let string_stability = if modes.exactly_stable {
        Some(string_stability(params, options)?)
    } else {
        None
    };
    Ok(CaccReport {
        modes,
        critical: super::cacc_critical(params)?,
        string_stability,
    })
}

impl fmt::Display for NetworkStabilityReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.roots;
        writeln!(
            f,
            "vehicles {}  collocation M = {} (order {})",
            r.vehicles, r.nodes_per_delay, r.collocation_order
        )?;
        writeln!(
            f,
            "{:>4} {:>14} {:>14} {:>10} {:>5}",
            "#", "Re s [1/s]", "Im s [rad/s]", "residual", "mult"
        )?;
        for (k, root) in r.roots.iter().enumerate() {
            writeln!(
                f,
                "{:>4} {:>14.6e} {:>14.6e} {:>10.1e} {:>5}",
                k + 1,
                root.root.re,
                root.root.im,
                root.residual,
                root.multiplicity
            )?;
        }
        writeln!(
            f,
            "spectral abscissa {:.6e} 1/s -> {}",
            r.abscissa,
            if r.is_stable() {
                "synchronizes"
            } else {
                "does not synchronize"
            }
        )?;
        if let Some(c) = &self.certificate {
            writeln!(
                f,
                "argument principle: {} root(s) right of {:.6e} (expected {}), {} right of {:.6e} (expected {}), with multiplicity -> {}",
                c.left.count,
                c.left.sigma,
                c.expected_left,
                c.right.count,
                c.right.sigma,
                c.expected_right,
                match (c.certified, c.verdict_by_counts()) {
                    (true, _) => "certified",
                    (false, None) => "NOT CERTIFIED: roots may have been missed",
                    (false, Some(true)) => "the roots listed do not match the counts (roots missed, or a multiplicity wrong), but nothing other than consensus lies right of the second line: synchronizes, certified by that count",
                    (false, Some(false)) => "the roots listed do not match the counts (roots missed, or a multiplicity wrong), but the count right of the first line finds a root in the right half-plane: does not synchronize, certified by that count",
                }
            )?;
        }
        match &self.critical {
            Some(c) => {
                writeln!(
                    f,
                    "critical gain scale {:.10}  {} {:.10}  ratio {:.6}  (crossing {:.6} rad/s)",
                    c.critical_gain_scale,
                    c.reference.label(),
                    c.reference_gain_scale,
                    c.conservatism_ratio,
                    c.crossing_frequency_rad_s
                )?;
                writeln!(
                    f,
                    "critical delay scale {:.10}  {} {:.10}  ratio {:.6}  (max delay {:.6} s, crossing {:.6} rad/s)",
                    c.critical_delay_scale,
                    c.reference.label(),
                    c.reference_delay_scale,
                    c.delay_conservatism_ratio,
                    c.critical_max_delay_s,
                    c.delay_crossing_frequency_rad_s
                )?;
                critical_certificate_line(f, c)
            }
            None => writeln!(f, "no delays: stable for every gain scale"),
        }
    }
}

/// The line under the critical scales: their root-count certificate, or UNCERTIFIED.
fn critical_certificate_line(f: &mut fmt::Formatter<'_>, c: &CriticalReport) -> fmt::Result {
    let method = match c.method {
        CriticalMethod::Continuation => "continuation",
        CriticalMethod::CountedBracket => "counted bracket",
        CriticalMethod::Bisection => "bisection",
    };
    match &c.certificate {
        Some(x) => writeln!(
            f,
            "critical scale ({method}, {} full solve(s)): at c* {} root(s) right of {:.3e} (expected {}), {} other than consensus right of {:.3e} (expected 0) -> {}",
            c.full_solves,
            x.left.count,
            x.left.sigma,
            x.expected_left,
            x.right.non_consensus(),
            x.right.sigma,
            if x.certified {
                "certified"
            } else {
                "UNCERTIFIED: another root may cross first"
            }
        ),
        None => writeln!(
            f,
            "critical scale ({method}, {} full solve(s)): UNCERTIFIED (the root count at c* failed)",
            c.full_solves
        ),
    }
}

impl fmt::Display for RingModes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.ring;
        writeln!(
            f,
            "uniform ring: N = {}, k_f = {} 1/s, k_b = {} 1/s, α = {} s",
            r.vehicles, r.gain_front, r.gain_back, r.delay_s
        )?;
        let dominant = &self.modes[self.dominant_mode];
        writeln!(
            f,
            "spectral abscissa {:.6e} 1/s (mode k = {}, root {:.6e} + {:.6e}i) -> {}",
            self.abscissa,
            self.dominant_mode,
            dominant.root.re,
            dominant.root.im,
            if self.abscissa < 0.0 {
                "synchronizes"
            } else {
                "does not synchronize"
            }
        )?;
        writeln!(
            f,
            "critical gain scale {:.10} (closed form, Lambert W per mode)  Theorem-1 {:.10}  ratio {:.6}",
            self.critical_gain_scale, self.theorem1_gain_scale, self.conservatism_ratio
        )
    }
}

impl fmt::Display for CaccReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = &self.modes;
        writeln!(
            f,
            "followers {}  abscissa {:.6e} 1/s  exact: {}  Theorem thm.cacc: {}",
            m.followers,
            m.abscissa,
            if m.exactly_stable {
                "stable"
            } else {
                "unstable"
            },
            if m.theorem_holds {
                "applies (stable)"
            } else {
                "does not apply"
            }
        )?;
        let c = &self.critical;
        match (c.critical_gain_scale, c.crossing_frequency_rad_s) {
            (Some(cs), Some(w)) => write!(
                f,
                "critical gain scale {cs:.10} (η, ν × c; bisection on the eigenvalues)  crossing {w:.6} rad/s"
            )?,
            _ => write!(
                f,
                "critical gain scale: none found for c in [{:.3e}, {:.3e}]",
                c.searched_from, c.searched_up_to
            )?,
        }
        match (c.theorem_gain_scale, c.conservatism_ratio) {
            (Some(t), Some(r)) => writeln!(f, "  Theorem thm.cacc {t:.10}  ratio {r:.6}")?,
            (Some(t), None) => writeln!(f, "  Theorem thm.cacc {t:.10}")?,
            _ => writeln!(f, "  Theorem thm.cacc: at no scale")?,
        }
        writeln!(f, "{:>4} {:>8} {:>14}", "i", "μτ", "μ²/2 − rhs")?;
        for c in &m.theorem_conditions {
            writeln!(
                f,
                "{:>4} {:>8.4} {:>14.6}",
                c.vehicle, c.mu_tau, c.degree_margin
            )?;
        }
        if let Some(s) = &self.string_stability {
            writeln!(
                f,
                "max_i sup_ω |G(i+1)/G(i)| = {:.6} (follower {}, ω = {:.4} rad/s) -> {}",
                s.max_successive_ratio,
                s.worst_follower,
                s.worst_frequency_rad_s,
                if s.string_stable {
                    "string stable"
                } else {
                    "string unstable"
                }
            )?;
            writeln!(
                f,
                "braking pulse: peak gap error first {:.4} m, last {:.4} m, amplification {:.4}",
                s.simulated_peak_gap_error_m[0],
                s.simulated_peak_gap_error_m[s.followers - 1],
                s.simulated_peak_amplification
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::ring_modes::UniformRing;
    use super::*;

    #[test]
    fn network_report_serializes_the_documented_fields() {
        let ring = UniformRing::new(6, 1.0, 0.5, 0.4).unwrap();
        let r = analyse_network(
            &ring.adjacency(),
            &ring.delays(),
            &CollocationOptions::default(),
            true,
        )
        .unwrap();
        assert!(r.certificate.unwrap().certified);
        let json = serde_json::to_value(&r).unwrap();
        for key in ["abscissa", "roots", "max_residual"] {
            assert!(json["roots"].get(key).is_some(), "missing roots.{key}");
        }
        for key in [
            "critical_gain_scale",
            "reference",
            "reference_gain_scale",
            "conservatism_ratio",
            "critical_delay_scale",
            "reference_delay_scale",
        ] {
            assert!(
                json["critical"].get(key).is_some(),
                "missing critical.{key}"
            );
        }
        let text = r.to_string();
        assert!(text.contains("critical gain scale") && text.contains("synchronizes"));
        assert!(text.contains("certified"));
        // Without delays there is no critical scale, and the report says so.
        let r = analyse_network(
            &ring.adjacency(),
            &[0.0; 6],
            &CollocationOptions::default(),
            false,
        )
        .unwrap();
        assert!(r.critical.is_none());
        assert!(r.to_string().contains("stable for every gain scale"));
    }

    #[test]
    fn ring_table_names_the_dominant_mode() {
        let ring = UniformRing::new(8, 1.0, 0.0, 0.5).unwrap();
        let text = ring.modes().unwrap().to_string();
        // Real gains: the dominant modes are the conjugate pair k = 1 and k = N − 1.
        assert!(
            text.contains("mode k = 1,") || text.contains("mode k = 7,"),
            "{text}"
        );
        assert!(text.contains("synchronizes"));
    }

    #[test]
    fn cacc_report_skips_string_stability_when_unstable() {
        let unstable = CaccParams::homogeneous(3, 1.0, 0.1, 2.0, 0.5);
        let r = analyse_cacc(&unstable, &StringStabilityOptions::default()).unwrap();
        assert!(!r.modes.exactly_stable && r.string_stability.is_none());
        let stable = CaccParams::homogeneous(3, 0.4, 1.0, 0.15, 0.1);
        let r = analyse_cacc(&stable, &StringStabilityOptions::default()).unwrap();
        let json = serde_json::to_value(&r).unwrap();
        assert!(json["string_stability"]["max_successive_ratio"].is_number());
        assert!(r.to_string().contains("Theorem thm.cacc: applies"));
    }

    #[test]
    fn delay_line_prints_the_delay_scaled_crossing_frequency() {
        // Bidirectional ring N = 22, K = 1, α = 0.2: with the delays scaled the crossing is
        // at ω = λ_max = 4 rad/s (with the gains scaled at c*·4 = 5π/2).
        let ring = UniformRing::new(22, 1.0, 1.0, 0.2).unwrap();
        let r = analyse_network(
            &ring.adjacency(),
            &ring.delays(),
            &CollocationOptions::default(),
            false,
        )
        .unwrap();
        let text = r.to_string();
        let line = text
            .lines()
            .find(|l| l.starts_with("critical delay scale"))
            .unwrap();
        assert!(line.contains("crossing 4.000000 rad/s"), "{line}");
    }

    #[test]
    fn counts_that_decide_on_their_own_certify_the_verdict_despite_a_missed_root() {
        // A solve that misses a root near the abscissa (a random digraph of 400 did: four
        // roots right of a − δ where three were reported) leaves the list of roots incomplete,
        // but the count right of a + δ < 0 alone proves that nothing other than consensus lies
        // right of it, and the count right of a − δ > 0 alone proves an unstable root. The
        // oracle: the rings' Lambert W roots, every mode on branches |b| ≤ 8.
        for &(kf, kb, alpha, stable) in &[(1.0, 0.3, 0.5, true), (1.0, 0.0, 2.5, false)] {
            let ring = UniformRing::new(7, kf, kb, alpha).unwrap();
            let (a, d) = (ring.adjacency(), ring.delays());
            let abscissa = (1..7)
                .flat_map(|k| (-8i64..=8).map(move |b| (k, b)))
                .map(|(k, b)| ring.mode_root(k, b).unwrap().re)
                .fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(abscissa < 0.0, stable, "the closed form's verdict");
            let margin = 0.25 * abscissa.abs();
            let left = count_roots_right_of(&a, &d, abscissa - margin).unwrap();
            let right = count_roots_right_of(&a, &d, abscissa + margin).unwrap();
            let certificate = RootsCertificate {
                margin,
                left,
                right,
                // As if the solve had reported one pair fewer than there are.
                expected_left: left.count - 2,
                expected_right: usize::from(stable),
                certified: false,
            };
            assert_eq!(
                certificate.verdict_by_counts(),
                Some(stable),
                "{kf} {kb} {alpha}"
            );
            let mut roots = rightmost_roots(&a, &d, &CollocationOptions::default()).unwrap();
            roots.roots.remove(0);
            let report = NetworkStabilityReport {
                roots,
                critical: None,
                certificate: Some(certificate),
            };
            assert_eq!(report.certified_stability(), Some(stable));
            assert!(report.to_string().contains("do not match the counts"));
        }
    }

    #[test]
    fn a_missing_root_fails_the_certificate_and_withholds_the_verdict() {
        // Drop the dominant root from a correct report: the count right of a − δ then finds
        // more roots than reported, and the verdict is withheld.
        let ring = UniformRing::new(7, 1.0, 0.3, 0.5).unwrap();
        let (a, d) = (ring.adjacency(), ring.delays());
        let mut roots = rightmost_roots(&a, &d, &CollocationOptions::default()).unwrap();
        assert!(certify_roots(&a, &d, &roots).unwrap().certified);
        roots.roots.remove(0);
        roots.abscissa = roots.roots[0].root.re;
        let c = certify_roots(&a, &d, &roots).unwrap();
        assert!(!c.certified);
        let report = NetworkStabilityReport {
            roots,
            critical: None,
            certificate: Some(c),
        };
        assert_eq!(report.certified_stability(), None);
        assert!(report.to_string().contains("NOT CERTIFIED"));
    }
}
