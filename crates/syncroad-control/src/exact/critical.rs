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
//! Method: **continuation** from the roots at the given gains (`c = 1`, one full solve by
//! [`rightmost_roots`]). Every reported rightmost root `s_j` (with its multiplicity `m_j`) is
//! followed in `c` by a predictor and the Newton step `s − m_j / (log det M)'(s)`, which
//! converges quadratically even at the multiple roots of symmetric graphs; the scale is
//! stepped geometrically towards the axis until a root changes side, and the crossing is
//! solved by regula falsi (Illinois) in `c` to `1e-15` relative. The answer is then
//! **certified once**, at `c*`, by two argument-principle counts ([`super::argument_principle`])
//! on the lines `Re s = ∓δ` (`δ` a quarter of the distance to the next tracked root): left
//! of the axis exactly consensus plus the crossing root(s) with their multiplicity, right of
//! it nothing. If the continuation fails or the certificate disagrees, the search falls back to
//! bisection with full solves down to `1e-10` relative (the method of the first version,
//! about 15 full solves).
//!
//! Scaling the delays by `r` instead crosses at the same `r* = c*`, but at the frequency
//! `ω/c*` (the substitution `s = s'/r` above): the report gives both frequencies.

use super::argument_principle::{count_with_laplacian, log_det_derivative, RootCount};
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
    /// Crossing frequency `ω` [rad/s] of the root reaching the axis when the *gains* are
    /// scaled by `c*` (0 if real).
    pub crossing_frequency_rad_s: f64,
    /// Crossing frequency [rad/s] when the *delays* are scaled by `r* = c*` instead: `ω/c*`.
    pub delay_crossing_frequency_rad_s: f64,
    /// Multiplicity of the crossing root (each of `±iω`).
    pub crossing_multiplicity: usize,
    /// Bracket `[c_lo, c_hi]` ∋ `c*` of the final solve.
    pub bracket: [f64; 2],
    /// Real part of the crossing root (continuation) or spectral abscissa (bisection) at
    /// `c_lo` and `c_hi` [1/s].
    pub bracket_abscissae: [f64; 2],
    /// Number of full root computations used (the one at `c = 1` included).
    pub full_solves: usize,
    /// How `c*` was found.
    pub method: CriticalMethod,
    /// Argument-principle certificate at `c*` (continuation only).
    pub certificate: Option<CrossingCertificate>,
}

/// How the critical scale was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CriticalMethod {
    /// Newton continuation of the rightmost roots in `c`, certified at `c*`.
    Continuation,
    /// Bisection with full solves (fallback).
    Bisection,
}

/// Root counts at the critical scale on both sides of the imaginary axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CrossingCertificate {
    /// Distance `δ` of the counting lines from the axis [1/s].
    pub margin: f64,
    /// Count right of `−δ` (consensus and the crossing roots expected).
    pub left: RootCount,
    /// Count right of `+δ` (nothing expected).
    pub right: RootCount,
    /// Expected `left.count`: consensus plus the crossing roots with multiplicity.
    pub expected_left: usize,
    /// Both counts as expected.
    pub certified: bool,
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
/// conservatism ratio of Theorem `thm.1`, to about `1e-10` relative or better.
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
    validate_network(adjacency, delays_s)?;
    if no_delay(adjacency, delays_s) {
        return Err(CriticalError::NoDelay);
    }
    let roots = rightmost_roots(adjacency, delays_s, options)?;
    critical_scale_from(adjacency, delays_s, &roots, options)
}

fn no_delay(adjacency: &DMatrix<f64>, delays_s: &[f64]) -> bool {
    (0..adjacency.nrows()).all(|i| delays_s[i] * adjacency.row(i).sum() == 0.0)
}

/// [`critical_scale`] starting from the rightmost roots at the given gains (a full solve the
/// caller already has), by continuation (module documentation).
///
/// # Errors
/// As [`critical_scale`].
pub fn critical_scale_from(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    roots: &RootsReport,
    options: &CollocationOptions,
) -> Result<CriticalReport, CriticalError> {
    let n = validate_network(adjacency, delays_s)?;
    if no_delay(adjacency, delays_s) {
        return Err(CriticalError::NoDelay);
    }
    let l = laplacian(adjacency);
    // Follow the rightmost roots from c = 1. On long rings the first root to cross need not
    // be among the rightmost at c = 1; then the count right of the axis at the tracked
    // crossing is positive, and one full solve there gives the roots that crossed earlier,
    // which are followed back down (at most three restarts before bisection).
    let mut start = 1.0f64;
    let mut start_roots = roots.clone();
    let mut full_solves = 1;
    let mut found = None;
    for _ in 0..3 {
        let tracked: Vec<(Complex64, usize)> = start_roots
            .roots
            .iter()
            .map(|r| (Complex64::from(r.root), r.multiplicity))
            .collect();
        let ls = &l * start;
        let Some(mut x) = continuation(&ls, delays_s, &tracked) else {
            break;
        };
        let certificate = certify_crossing(&ls, delays_s, &x);
        x.scale *= start;
        x.bracket = x.bracket.map(|b| b * start);
        match certificate {
            Some(c) if c.certified => {
                found = Some((x, c));
                break;
            }
            Some(c) if c.right.non_consensus() > 0 => {
                start = x.scale;
                full_solves += 1;
                start_roots = rightmost_roots(&(adjacency * start), delays_s, options)?;
            }
            _ => break,
        }
    }
    let Some((x, certificate)) = found else {
        let mut r = fallback(adjacency, delays_s, options)?;
        r.full_solves += full_solves - 1;
        return Ok(r);
    };
    let certificate = Some(certificate);
    let worst = (0..n).map(|i| delays_s[i] * l[(i, i)]).fold(0.0, f64::max);
    let theorem1 = 1.0 / (2.0 * worst);
    let c_star = x.scale;
    let omega = x.root.im.abs();
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
        crossing_frequency_rad_s: omega,
        delay_crossing_frequency_rad_s: omega / c_star,
        crossing_multiplicity: x.multiplicity,
        bracket: x.bracket,
        bracket_abscissae: x.bracket_re,
        full_solves,
        method: CriticalMethod::Continuation,
        certificate,
    })
}

fn fallback(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
) -> Result<CriticalReport, CriticalError> {
    let mut r = bisection_search(adjacency, delays_s, options, true)?;
    r.full_solves += 1; // the solve at c = 1 the continuation started from
    Ok(r)
}

/// A root crossing the imaginary axis at gain scale `scale`.
struct Crossing {
    scale: f64,
    root: Complex64,
    multiplicity: usize,
    bracket: [f64; 2],
    bracket_re: [f64; 2],
    /// The other tracked roots at `scale`.
    others: Vec<Complex64>,
}

/// Newton's step `s − m/(log det M)'(s)` for gains scaled by `c`, from `s0`.
fn newton_track(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    c: f64,
    s0: Complex64,
    m: usize,
) -> Option<Complex64> {
    let lc = l * c;
    let mut s = s0;
    let mut last = f64::INFINITY;
    for _ in 0..40 {
        let g = log_det_derivative(&lc, delays_s, s)?;
        let step = m as f64 / g;
        if !(step.re.is_finite() && step.im.is_finite()) {
            return None;
        }
        s -= step;
        if s.im < 0.0 {
            s = s.conj();
        }
        last = step.norm();
        if last <= 1e-15 * (1.0 + s.norm()) {
            return Some(s);
        }
    }
    (last <= 1e-11 * (1.0 + s.norm())).then_some(s)
}

/// Follows the tracked roots in `c` from 1 until one crosses the axis (module documentation).
fn continuation(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    tracked: &[(Complex64, usize)],
) -> Option<Crossing> {
    if tracked.is_empty() {
        return None;
    }
    let increasing = tracked.iter().all(|(s, _)| s.re < 0.0);
    let sign = if increasing { 1.0 } else { -1.0 };
    let mut c = 1.0f64;
    let mut mult: Vec<usize> = tracked.iter().map(|t| t.1).collect();
    let mut cur: Vec<Complex64> = tracked.iter().map(|t| t.0).collect();
    let mut prev: Option<(f64, Vec<Complex64>)> = None;
    let mut dlog = 0.05f64;
    for _ in 0..2000 {
        if !(1e-18..=1e12).contains(&c) {
            return None;
        }
        let c_next = c * (sign * dlog).exp();
        let correct = |j: usize| -> Option<Complex64> {
            let pred = match &prev {
                Some((cp, sp)) if sp.len() == cur.len() => {
                    cur[j] + (cur[j] - sp[j]) * ((c_next / c).ln() / (c / cp).ln())
                }
                _ => cur[j],
            };
            let close = |s: Complex64| (s - pred).norm() <= 0.05 * (1.0 + cur[j].norm());
            if let Some(s) = newton_track(l, delays_s, c_next, pred, mult[j]) {
                // A corrector far from its predictor may have jumped to another root.
                if close(s) {
                    return Some(s);
                }
            }
            // Two real roots that meet leave the axis as a conjugate pair: restart off the axis.
            if cur[j].im.abs() <= 1e-9 * (1.0 + cur[j].norm()) {
                let kick = Complex64::new(pred.re, 0.1 * dlog * (1.0 + cur[j].norm()));
                let s = newton_track(l, delays_s, c_next, kick, mult[j])?;
                return close(s).then_some(s);
            }
            None
        };
        let Some(mut next) = (0..cur.len()).map(correct).collect::<Option<Vec<_>>>() else {
            dlog /= 2.0;
            if dlog < 1e-9 {
                return None;
            }
            continue;
        };
        // Roots that met (a real pair turned complex) are one root from now on.
        let mut keep = vec![true; next.len()];
        for i in 0..next.len() {
            for j in i + 1..next.len() {
                if keep[j] && (next[i] - next[j]).norm() < 1e-6 * (1.0 + next[i].norm()) {
                    keep[j] = false;
                }
            }
        }
        if keep.iter().any(|k| !k) {
            let mut idx = 0;
            next.retain(|_| {
                idx += 1;
                keep[idx - 1]
            });
            let mut idx = 0;
            cur.retain(|_| {
                idx += 1;
                keep[idx - 1]
            });
            let mut idx = 0;
            mult.retain(|_| {
                idx += 1;
                keep[idx - 1]
            });
        }
        let event = if increasing {
            next.iter().any(|s| s.re >= 0.0)
        } else {
            next.iter().all(|s| s.re < 0.0)
        };
        if event {
            // Every root that changed side crosses inside (c, c_next); the first in c wins.
            let mut best: Option<Crossing> = None;
            for j in 0..next.len() {
                if (cur[j].re < 0.0) == (next[j].re < 0.0) {
                    continue;
                }
                let m = mult[j];
                let (c_star, s_star, bracket, bracket_re) =
                    solve_crossing(l, delays_s, m, (c, cur[j]), (c_next, next[j]))?;
                if best.as_ref().is_none_or(|b| c_star < b.scale) {
                    // The other roots at c*, from the bracket end nearer in log c; one that
                    // cannot be followed there only loosens the margin (the certificate still
                    // counts).
                    let others = (0..next.len())
                        .filter(|&i| i != j)
                        .filter_map(|i| {
                            let from = if (c_star / c).ln().abs() < (c_star / c_next).ln().abs() {
                                cur[i]
                            } else {
                                next[i]
                            };
                            newton_track(l, delays_s, c_star, from, mult[i])
                        })
                        .collect();
                    best = Some(Crossing {
                        scale: c_star,
                        root: s_star,
                        multiplicity: m,
                        bracket,
                        bracket_re,
                        others,
                    });
                }
            }
            return best;
        }
        prev = Some((c, std::mem::replace(&mut cur, next)));
        c = c_next;
        dlog = (dlog * 1.5).min(0.3);
    }
    None
}

/// Regula falsi (Illinois) in `c` on `Re s(c) = 0` between two tracked points of opposite sign.
#[allow(clippy::type_complexity)]
fn solve_crossing(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    m: usize,
    a: (f64, Complex64),
    b: (f64, Complex64),
) -> Option<(f64, Complex64, [f64; 2], [f64; 2])> {
    let (mut ca, mut sa) = a;
    let (mut cb, mut sb) = b;
    let (mut fa, mut fb) = (sa.re, sb.re);
    let mut side = 0i8;
    for _ in 0..200 {
        if (cb - ca).abs() <= 1e-15 * ca.abs().max(cb.abs()) {
            break;
        }
        let c = (ca * fb - cb * fa) / (fb - fa);
        let c = if c.is_finite() && c > ca.min(cb) && c < ca.max(cb) {
            c
        } else {
            0.5 * (ca + cb)
        };
        let start = if (c - ca).abs() < (c - cb).abs() {
            sa
        } else {
            sb
        };
        let s = newton_track(l, delays_s, c, start, m)?;
        if s.re == 0.0 {
            return Some((c, s, [c, c], [0.0, 0.0]));
        }
        if (s.re < 0.0) == (fa < 0.0) {
            (ca, sa, fa) = (c, s, s.re);
            if side == -1 {
                fb /= 2.0;
            }
            side = -1;
        } else {
            (cb, sb, fb) = (c, s, s.re);
            if side == 1 {
                fa /= 2.0;
            }
            side = 1;
        }
        if s.re.abs() <= 1e-15 * (1.0 + s.norm()) {
            break;
        }
    }
    let (lo, hi) = if ca < cb {
        ((ca, sa), (cb, sb))
    } else {
        ((cb, sb), (ca, sa))
    };
    // Report the end point nearer the axis.
    let (c_star, s_star) = if lo.1.re.abs() <= hi.1.re.abs() {
        lo
    } else {
        hi
    };
    Some((c_star, s_star, [lo.0, hi.0], [lo.1.re, hi.1.re]))
}

/// Argument-principle counts at `c*` on the lines `Re s = ∓δ`.
fn certify_crossing(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    x: &Crossing,
) -> Option<CrossingCertificate> {
    let scale = 1.0 + x.root.norm();
    let separation = x.others.iter().map(|s| -s.re).fold(f64::INFINITY, f64::min);
    let margin = if separation > 1e-9 * scale {
        (0.25 * separation).min(0.05 * scale)
    } else {
        1e-3 * scale
    };
    let lc = l * x.scale;
    let left = count_with_laplacian(&lc, delays_s, -margin).ok()?;
    let right = count_with_laplacian(&lc, delays_s, margin).ok()?;
    let real = x.root.im.abs() <= 1e-12 * scale;
    let expected_left = 1 + x.multiplicity * if real { 1 } else { 2 };
    Some(CrossingCertificate {
        margin,
        left,
        right,
        expected_left,
        certified: left.count == expected_left && right.non_consensus() == 0,
    })
}

/// The first version's search: bracket and bisect with full solves, a secant on the tracked
/// root when `use_secant`; the fallback of [`critical_scale_from`] and its reference in tests.
pub(crate) fn bisection_search(
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
        delay_crossing_frequency_rad_s: s_star.im.abs() / c_star,
        crossing_multiplicity: hi_report.roots[0].multiplicity,
        bracket: [lo, hi],
        bracket_abscissae: [lo_report.abscissa, hi_report.abscissa],
        full_solves,
        method: CriticalMethod::Bisection,
        certificate: None,
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
            assert_eq!(r.method, CriticalMethod::Continuation);
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
            assert_eq!(r.method, CriticalMethod::Continuation, "trial {trial}");
            assert!(r.certificate.unwrap().certified);
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
        let r = bisection_search(
            &ring.adjacency(),
            &ring.delays(),
            &CollocationOptions::default(),
            false,
        )
        .unwrap();
        assert_eq!(r.method, CriticalMethod::Bisection);
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

    #[test]
    fn continuation_equals_the_bisection_answer() {
        // The fast search must not change results beyond 1e-10: compare with the first
        // version's bisection (full solves only), on heterogeneous graphs, a symmetric ring
        // (double roots) and an all-to-all graph (roots of multiplicity N − 1).
        let opts = CollocationOptions::default();
        let mut rng = super::super::collocation::tests::Lcg(31);
        let mut cases = Vec::new();
        for n in [4usize, 6, 9] {
            cases.push(super::super::collocation::tests::random_network(
                n, &mut rng,
            ));
        }
        let ring = UniformRing::new(8, 0.7, 0.7, 0.6).unwrap();
        cases.push((ring.adjacency(), ring.delays()));
        cases.push((
            DMatrix::from_fn(5, 5, |i, j| if i == j { 0.0 } else { 0.1 }),
            vec![0.5; 5],
        ));
        for (k, (a, d)) in cases.iter().enumerate() {
            let fast = critical_scale(a, d, &opts).unwrap();
            let slow = bisection_search(a, d, &opts, false).unwrap();
            assert_eq!(fast.method, CriticalMethod::Continuation, "case {k}");
            assert_eq!(fast.full_solves, 1, "case {k}");
            assert_relative_eq!(
                fast.critical_gain_scale,
                slow.critical_gain_scale,
                max_relative = 1e-10
            );
            assert_relative_eq!(
                fast.crossing_frequency_rad_s,
                slow.crossing_frequency_rad_s,
                max_relative = 1e-6
            );
        }
    }

    #[test]
    fn multiple_roots_cross_together_on_symmetric_graphs() {
        // All-to-all, k = 0.1, α = 0.5, N = 5: the mode s + 5ck e^{−sα} = 0 (multiplicity 4)
        // crosses at 5c k α = π/2, at ω = π/(2α).
        let a = DMatrix::from_fn(5, 5, |i, j| if i == j { 0.0 } else { 0.1 });
        let r = critical_scale(&a, &[0.5; 5], &CollocationOptions::default()).unwrap();
        assert_relative_eq!(r.critical_gain_scale, PI / 2.0 / 0.25, max_relative = 1e-12);
        assert_relative_eq!(r.crossing_frequency_rad_s, PI, max_relative = 1e-12);
        assert_eq!(r.crossing_multiplicity, 4);
        let cert = r.certificate.unwrap();
        assert_eq!(cert.expected_left, 1 + 2 * 4);
        assert!(cert.certified);
    }

    #[test]
    fn delay_scaling_crosses_at_the_unscaled_frequency() {
        // Scaling delays by r: s + λ e^{−s rα} = 0 crosses at ω = |λ| (gain scaling: c|λ|).
        // Bidirectional ring N = 22, K = 1: λ_max = 4. One-way ring N = 3, K = 0.5:
        // |λ_1| = 2K sin(π/3) = √3/2.
        for (ring, omega) in [
            (UniformRing::new(22, 1.0, 1.0, 0.2).unwrap(), 4.0),
            (
                UniformRing::new(3, 0.5, 0.0, 0.7).unwrap(),
                3f64.sqrt() / 2.0,
            ),
        ] {
            let r = critical_scale(
                &ring.adjacency(),
                &ring.delays(),
                &CollocationOptions::default(),
            )
            .unwrap();
            assert_relative_eq!(
                r.delay_crossing_frequency_rad_s,
                omega,
                max_relative = 1e-10
            );
            // Directly, with the delays scaled by r*: the rightmost root sits at iω.
            let scaled: Vec<f64> = ring
                .delays()
                .iter()
                .map(|d| d * r.critical_delay_scale)
                .collect();
            let at = rightmost_roots(&ring.adjacency(), &scaled, &CollocationOptions::default())
                .unwrap();
            assert!(at.abscissa.abs() < 1e-9);
            assert_relative_eq!(at.roots[0].root.im, omega, max_relative = 1e-9);
        }
    }
}
