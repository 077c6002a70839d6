//! Critical gain and delay scales, and the conservatism of Theorem 1.
//!
//! Scaling every gain `a_ij → c·a_ij` of eq. `chandler+` moves the non-consensus roots; the
//! *critical gain scale* `c*` is the smallest `c` at which the spectral abscissa reaches 0
//! (a root crosses the imaginary axis at `iω`). Theorem `thm.1` (via `thm.delay-agent` and
//! eq. `degree1`) guarantees stability for `c < c_T1 = 1/(2 max_j α_j d_j^+)` on strongly
//! connected graphs; the *conservatism ratio* is `c*/c_T1 ≥ 1`.
//!
//! Scaling all delays by `r` is equivalent: with `s = s'/r`,
//! `det(sI + diag(e^{−s rα_i})L) = r^{−N} det(s'I + r·diag(e^{−s'α_i})L)`, so the critical
//! delay scale equals `c*` and the Theorem-1 delay scale equals `c_T1`. The tests check this
//! identity by computing with scaled delays directly.
//!
//! For the straight road of eq. `chandler` (one follower per mode, `s + cK e^{−sα} = 0`) the
//! exact bound is `αK < π/2`, whereas Section `sec.cacc` quotes `2αK < 1` as necessary and
//! sufficient; `1/2` is rather the string-stability bound of that road
//! ([`super::string_stability::chandler_string_peak`]) and the long-ring limit
//! ([`super::ring_modes`]).
//!
//! Method: bracket `c*` with full root computations ([`rightmost_roots`]), bisect the bracket to
//! a relative width of `1e-3`, then solve `Re s(c) = 0` by the secant method on the dominant root
//! tracked by Newton's method (quadratic convergence of the root, superlinear in `c`). Two more
//! full computations at `c*(1 ∓ 1e-7)` certify the answer (stable below, unstable above); if
//! another root crossed first, or the secant stalls, bisection with full computations continues
//! down to `1e-10` relative.

use super::collocation::{
    laplacian, rightmost_roots, validate_network, CollocationError, CollocationOptions, RootsReport,
};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use serde::Serialize;

/// Failure of the critical-scale search.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CriticalError {
    /// Invalid network or failed root computation.
    #[error(transparent)]
    Roots(#[from] CollocationError),
    /// No driver has a delay: the delay-free network is stable for every gain scale.
    #[error(
        "all delays are zero; the network synchronizes for every gain scale (no critical gain)"
    )]
    NoDelay,
    /// Still stable at the largest scale tried.
    #[error("still stable at gain scale {scale}; no crossing found")]
    NoCrossing {
        /// Largest scale tried.
        scale: f64,
    },
    /// Unstable even at the smallest scale tried.
    #[error("unstable even at gain scale {scale}; cannot bracket the critical gain")]
    UnstableAtSmallGain {
        /// Smallest scale tried.
        scale: f64,
    },
}

/// Exact critical scales next to Theorem 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CriticalReport {
    /// Number of vehicles `N`.
    pub vehicles: usize,
    /// Whether the graph is strongly connected (a hypothesis of Theorem `thm.1`).
    pub strongly_connected: bool,
    /// Exact critical scale `c*` of the whole gain matrix.
    pub critical_gain_scale: f64,
    /// Theorem-1 scale `c_T1 = 1/(2 max_j α_j d_j^+)` (eq. `degree1`).
    pub theorem1_gain_scale: f64,
    /// `c* / c_T1`.
    pub conservatism_ratio: f64,
    /// Exact critical scale of all delays (equals `c*`, see module docs).
    pub critical_delay_scale: f64,
    /// Theorem-1 delay scale (equals `c_T1`).
    pub theorem1_delay_scale: f64,
    /// `r* / r_T1`.
    pub delay_conservatism_ratio: f64,
    /// Largest delay at the critical delay scale, `r* max_i α_i` \[s\].
    pub critical_max_delay_s: f64,
    /// Crossing frequency `ω` [rad/s] of the root reaching the axis at `c*` (0 if real).
    pub crossing_frequency_rad_s: f64,
    /// Certified bracket `[c_lo, c_hi]` ∋ `c*` from full root computations.
    pub bracket: [f64; 2],
    /// Spectral abscissa at `c_lo` (negative) and `c_hi` (non-negative) [1/s].
    pub bracket_abscissae: [f64; 2],
    /// Number of full root computations used.
    pub full_solves: usize,
    /// Whether the secant on the tracked root converged and was certified by full computations
    /// at `c*(1 ∓ 1e-7)` (otherwise the answer is the midpoint of a bracket bisected to 1e-10
    /// relative).
    pub secant_converged: bool,
}

/// Spectral abscissa with all gains scaled by `c`.
fn abscissa_at(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    c: f64,
    options: &CollocationOptions,
) -> Result<RootsReport, CollocationError> {
    rightmost_roots(&(adjacency * c), delays_s, options)
}

/// Whether every vehicle reaches every other along arcs `j → i` (`a_ij > 0`).
pub(crate) fn strongly_connected(adjacency: &DMatrix<f64>) -> bool {
    let n = adjacency.nrows();
    let reach = |forward: bool| {
        let mut seen = vec![false; n];
        seen[0] = true;
        let mut stack = vec![0];
        while let Some(v) = stack.pop() {
            for w in 0..n {
                let arc = if forward {
                    adjacency[(w, v)]
                } else {
                    adjacency[(v, w)]
                };
                if !seen[w] && arc > 0.0 {
                    seen[w] = true;
                    stack.push(w);
                }
            }
        }
        seen.iter().all(|&s| s)
    };
    n > 0 && reach(true) && reach(false)
}

/// Newton on `[M(s)x = 0, cᴴx = 1]` for gains scaled by `scale`, from `(s, x)`.
fn track_root(l: &DMatrix<f64>, delays_s: &[f64], scale: f64, s0: Complex64) -> Option<Complex64> {
    let n = l.nrows();
    let build = |s: Complex64| {
        let mut m = DMatrix::from_fn(n, n, |i, j| {
            Complex64::new(scale * l[(i, j)], 0.0) * (-s * delays_s[i]).exp()
        });
        let mut dm = DMatrix::from_fn(n, n, |i, j| {
            -Complex64::new(scale * l[(i, j)], 0.0) * delays_s[i] * (-s * delays_s[i]).exp()
        });
        for i in 0..n {
            m[(i, i)] += s;
            dm[(i, i)] += 1.0;
        }
        (m, dm)
    };
    let mut s = s0;
    let mut x = DVector::from_fn(n, |i, _| Complex64::new(1.0, 0.1 * i as f64));
    for _ in 0..2 {
        let y = build(s).0.lu().solve(&x)?;
        x = &y / Complex64::new(y.norm(), 0.0);
    }
    let c = x.clone();
    for _ in 0..50 {
        let (m, dm) = build(s);
        let mut j = DMatrix::zeros(n + 1, n + 1);
        j.view_mut((0, 0), (n, n)).copy_from(&m);
        let dmx = &dm * &x;
        for i in 0..n {
            j[(i, n)] = dmx[i];
            j[(n, i)] = c[i].conj();
        }
        let mut f = DVector::zeros(n + 1);
        f.rows_mut(0, n).copy_from(&(&m * &x));
        f[n] = c.dotc(&x) - 1.0;
        let delta = j.lu().solve(&(-f))?;
        x += delta.rows(0, n);
        s += delta[n];
        if delta[n].norm() <= 1e-15 * (1.0 + s.norm()) {
            return Some(s);
        }
    }
    None
}

/// Critical gain and delay scales of the delayed-driver network (eq. `chandler+`) and the
/// conservatism ratio of Theorem `thm.1`, to about `1e-10` relative.
///
/// # Errors
/// [`CriticalError::Roots`] for invalid input, [`CriticalError::NoDelay`] when no driver is
/// delayed, [`CriticalError::NoCrossing`] / [`CriticalError::UnstableAtSmallGain`] when the
/// abscissa cannot be bracketed.
pub fn critical_scale(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
) -> Result<CriticalReport, CriticalError> {
    search(adjacency, delays_s, options, true)
}

/// The search of [`critical_scale`]; `use_secant = false` forces the bisection fallback.
fn search(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
    use_secant: bool,
) -> Result<CriticalReport, CriticalError> {
    let n = validate_network(adjacency, delays_s)?;
    let l = laplacian(adjacency);
    let worst = (0..n).map(|i| delays_s[i] * l[(i, i)]).fold(0.0, f64::max);
    if worst == 0.0 {
        return Err(CriticalError::NoDelay);
    }
    let theorem1 = 1.0 / (2.0 * worst);
    let mut full_solves = 0;
    let mut eval = |c: f64| {
        full_solves += 1;
        abscissa_at(adjacency, delays_s, c, options)
    };
    // Bracket.
    let mut lo = theorem1;
    let mut lo_report = eval(lo)?;
    let mut halvings = 0;
    while !lo_report.is_stable() {
        halvings += 1;
        if halvings > 60 {
            return Err(CriticalError::UnstableAtSmallGain { scale: lo });
        }
        lo /= 2.0;
        lo_report = eval(lo)?;
    }
    let mut hi = 2.0 * lo;
    let mut hi_report = eval(hi)?;
    let mut doublings = 0;
    while hi_report.is_stable() {
        doublings += 1;
        if doublings > 40 {
            return Err(CriticalError::NoCrossing { scale: hi });
        }
        lo = hi;
        lo_report = hi_report;
        hi *= 2.0;
        hi_report = eval(hi)?;
    }
    // Bisect with full solves to a 1e-3 relative bracket.
    while (hi - lo) > 1e-3 * hi {
        let mid = 0.5 * (lo + hi);
        let r = eval(mid)?;
        if r.is_stable() {
            lo = mid;
            lo_report = r;
        } else {
            hi = mid;
            hi_report = r;
        }
    }
    // Secant on the real part of the dominant root, tracked by Newton inside the bracket.
    let s_hi: Complex64 = hi_report.roots[0].root.into();
    let mut c_star = 0.5 * (lo + hi);
    let mut s_star = s_hi;
    let mut secant_converged = false;
    let tracked_lo = if use_secant {
        track_root(&l, delays_s, lo, s_hi)
    } else {
        None
    };
    if let Some(s_lo) = tracked_lo {
        let (mut c0, mut g0) = (lo, s_lo.re);
        let (mut c1, mut g1, mut z1) = (hi, s_hi.re, s_hi);
        for _ in 0..60 {
            if g1 == g0 {
                break;
            }
            let c2 = c1 - g1 * (c1 - c0) / (g1 - g0);
            if !(lo..=hi).contains(&c2) {
                break;
            }
            let Some(z2) = track_root(&l, delays_s, c2, z1) else {
                break;
            };
            (c0, g0) = (c1, g1);
            (c1, g1, z1) = (c2, z2.re, z2);
            if (c1 - c0).abs() <= 1e-14 * c1 || g1.abs() <= 1e-15 * z1.norm() {
                c_star = c1;
                s_star = z1;
                secant_converged = true;
                break;
            }
        }
    }
    if secant_converged {
        // Certify with full computations on both sides; a root that crossed earlier inside the
        // bracket shows up as instability below c*.
        let below = c_star * (1.0 - 1e-7);
        let above = c_star * (1.0 + 1e-7);
        let r_below = eval(below)?;
        if r_below.is_stable() {
            lo = below;
            lo_report = r_below;
            let r_above = eval(above)?;
            if r_above.is_stable() {
                secant_converged = false; // tracked root did not cross here
                lo = above;
                lo_report = r_above;
            } else {
                hi = above;
                hi_report = r_above;
            }
        } else {
            secant_converged = false;
            hi = below;
            hi_report = r_below;
        }
    }
    if !secant_converged {
        // Fall back to bisection with full solves down to 1e-10 relative.
        while (hi - lo) > 1e-10 * hi {
            let mid = 0.5 * (lo + hi);
            let r = eval(mid)?;
            if r.is_stable() {
                lo = mid;
                lo_report = r;
            } else {
                hi = mid;
                hi_report = r;
            }
        }
        c_star = 0.5 * (lo + hi);
        s_star = hi_report.roots[0].root.into();
    }
    Ok(CriticalReport {
        vehicles: n,
        strongly_connected: strongly_connected(adjacency),
        critical_gain_scale: c_star,
        theorem1_gain_scale: theorem1,
        conservatism_ratio: c_star / theorem1,
        critical_delay_scale: c_star,
        theorem1_delay_scale: theorem1,
        delay_conservatism_ratio: c_star / theorem1,
        critical_max_delay_s: c_star * delays_s.iter().cloned().fold(0.0, f64::max),
        crossing_frequency_rad_s: s_star.im.abs(),
        bracket: [lo, hi],
        bracket_abscissae: [lo_report.abscissa, hi_report.abscissa],
        full_solves,
        secant_converged,
    })
}

#[cfg(test)]
mod tests {
    use super::super::ring_modes::UniformRing;
    use super::*;
    use approx::assert_relative_eq;
    use std::f64::consts::PI;

    #[test]
    fn single_follower_critical_gain_is_pi_over_two() {
        // Chandler's straight road, one mode: s + cK e^{−sα} = 0 is stable iff αcK < π/2;
        // Theorem 1 (its graph is not strongly connected) would give αcK < 1/2.
        let (alpha, k) = (0.6, 1.3);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, k, 0.0]);
        let r = critical_scale(&a, &[alpha, alpha], &CollocationOptions::default()).unwrap();
        assert_relative_eq!(
            r.critical_gain_scale * alpha * k,
            PI / 2.0,
            max_relative = 1e-10
        );
        assert_relative_eq!(
            r.crossing_frequency_rad_s,
            PI / 2.0 / alpha,
            max_relative = 1e-8
        );
        assert!(!r.strongly_connected);
        assert_relative_eq!(r.conservatism_ratio, PI, max_relative = 1e-10);
    }

    #[test]
    fn two_drivers_following_each_other() {
        // a_12 = a_21 = k: L has eigenvalue 2k, crossing at 2αck = π/2, i.e. αck = π/4,
        // against Theorem 1's αck < 1/2 · 1/1 → c_T1 = 1/(2αk): ratio π/2.
        let (alpha, k) = (0.9, 0.7);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, k, k, 0.0]);
        let r = critical_scale(&a, &[alpha, alpha], &CollocationOptions::default()).unwrap();
        assert_relative_eq!(
            r.critical_gain_scale * alpha * k,
            PI / 4.0,
            max_relative = 1e-10
        );
        assert_relative_eq!(r.conservatism_ratio, PI / 2.0, max_relative = 1e-10);
        assert!(r.strongly_connected);
    }

    #[test]
    fn full_search_matches_closed_form_on_uniform_rings() {
        for &(n, kf, kb, alpha) in &[
            (3usize, 1.0, 0.0, 0.5),
            (8, 1.0, 0.0, 1.0),
            (7, 0.8, 0.3, 0.7),
            (10, 0.5, 0.5, 1.2),
        ] {
            let ring = UniformRing::new(n, kf, kb, alpha).unwrap();
            let exact = ring.modes().unwrap();
            let r = critical_scale(
                &ring.adjacency(),
                &ring.delays(),
                &CollocationOptions::default(),
            )
            .unwrap();
            assert_relative_eq!(
                r.critical_gain_scale,
                exact.critical_gain_scale,
                max_relative = 1e-9
            );
            assert_relative_eq!(
                r.theorem1_gain_scale,
                exact.theorem1_gain_scale,
                max_relative = 1e-14
            );
            assert!(r.bracket[0] <= r.critical_gain_scale && r.critical_gain_scale <= r.bracket[1]);
            assert!(r.secant_converged);
        }
    }

    #[test]
    fn heterogeneous_critical_scales_respect_theorem_one_and_delay_equivalence() {
        let mut rng = super::super::collocation::tests::Lcg(7);
        let opts = CollocationOptions::default();
        for trial in 0..5 {
            let n = 3 + trial;
            let (a, delays) = super::super::collocation::tests::random_network(n, &mut rng);
            let r = critical_scale(&a, &delays, &opts).unwrap();
            assert!(r.strongly_connected);
            // Certified bracket of relative width 2e-7 around c*.
            assert!(r.secant_converged, "trial {trial}");
            assert!(r.bracket[1] - r.bracket[0] <= 2.1e-7 * r.critical_gain_scale);
            assert!(
                r.conservatism_ratio >= 1.0,
                "trial {trial}: {}",
                r.conservatism_ratio
            );
            // Delay scaling computed directly (not through the gain identity).
            let scaled = |f: f64| -> Vec<f64> { delays.iter().map(|d| d * f).collect() };
            let below =
                rightmost_roots(&a, &scaled(r.critical_delay_scale * (1.0 - 1e-6)), &opts).unwrap();
            let above =
                rightmost_roots(&a, &scaled(r.critical_delay_scale * (1.0 + 1e-6)), &opts).unwrap();
            assert!(
                below.abscissa < 0.0 && above.abscissa > 0.0,
                "trial {trial}"
            );
            // At c* the dominant root sits on the imaginary axis.
            let at = rightmost_roots(&(&a * r.critical_gain_scale), &delays, &opts).unwrap();
            assert!(at.abscissa.abs() < 1e-9, "trial {trial}: {}", at.abscissa);
        }
    }

    #[test]
    fn bisection_fallback_reaches_the_closed_form_too() {
        let ring = UniformRing::new(5, 1.0, 0.25, 0.8).unwrap();
        let exact = ring.modes().unwrap().critical_gain_scale;
        let r = search(
            &ring.adjacency(),
            &ring.delays(),
            &CollocationOptions::default(),
            false,
        )
        .unwrap();
        assert!(!r.secant_converged);
        assert_relative_eq!(r.critical_gain_scale, exact, max_relative = 1e-9);
        assert!(r.bracket[1] - r.bracket[0] <= 1e-10 * r.bracket[1]);
    }

    #[test]
    fn errors_are_specific() {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 1.0, 0.0]);
        assert_eq!(
            critical_scale(&a, &[0.0, 0.0], &CollocationOptions::default())
                .unwrap_err()
                .to_string(),
            "all delays are zero; the network synchronizes for every gain scale (no critical gain)"
        );
        assert_eq!(
            critical_scale(&a, &[0.1], &CollocationOptions::default())
                .unwrap_err()
                .to_string(),
            "1 delays given for 2 vehicles"
        );
    }
}
