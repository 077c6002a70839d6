//! Critical gain and delay scales, and the conservatism of Theorem 1 (Theorem 1+ behind a
//! leader).
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
//! solved by regula falsi (Illinois) in `c` to `1e-15` relative. Two tracked roots that land on
//! one point are one root only when both were real (a real pair meeting and turning complex);
//! two complex ones mean the corrector jumped to a neighbour of a cluster (rings with uniform
//! gains and mixed delays have such clusters near the crossing), and the step is retried
//! shorter. The answer is then **certified once**, at `c*`, by two argument-principle counts
//! ([`super::argument_principle`]): right of `Re s = −δ` (`δ` a quarter of the distance to the
//! next tracked root, moved 8× closer to the axis up to twice when the strip holds more roots
//! than expected) exactly consensus plus the crossing root(s) with their multiplicity, right
//! of `Re s = +ε` (`ε = 10⁻⁹(1 + max_i d_i^+)`, just right of the axis) nothing else. On long
//! rings the rightmost roots at `c = 1` are slow modes that cross late or never, while a fast
//! mode crosses first: then the certificate counts roots right of the axis at the tracked
//! crossing, or the tracked roots recede (the continuation gives up after three steps in which
//! every one of them moved left). The first scale with a root right of the axis is then
//! bracketed by argument-principle counts alone (no solve) until only a few roots have crossed
//! at its top, one shift-invert solve there gives them, and they are followed back down to
//! `c*`. If that fails too, the search falls back to bisection with full solves down to
//! `1e-10` relative (the method of the first version, about 15 full solves), whose answer gets
//! the same certificate. A critical scale whose counts do not confirm it is reported with
//! `certified: false`, and the command line prints UNCERTIFIED.
//!
//! Behind a leader (an undelayed vertex no arc enters, as [`super::analysis`] appends it) the
//! reference is Theorem `thm.1+`, `α_j (d_j^+ + 2 b_j) < 1/2`, cycles or not; otherwise
//! Theorem `thm.1` ([`ReferenceTheorem`]).
//!
//! Scaling the delays by `r` instead crosses at the same `r* = c*`, but at the frequency
//! `ω/c*` (the substitution `s = s'/r` above): the report gives both frequencies.
//!
//! This module holds the reports and the search that calls the two methods:
//! `continuation` (the fast path) and `bisection` (the fallback and test reference).

use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;

use super::argument_principle::{count_with_laplacian, RootCount};
use super::collocation::DENSE_SOLVE_LIMIT;
use super::collocation::{
    laplacian, rightmost_roots, rightmost_roots_shift_invert_unchecked, validate_network,
    CollocationError, CollocationOptions, RootsReport,
};

mod bisection;
mod continuation;

pub(crate) use bisection::bisection_search;
use continuation::{axis_line, certify_at, certify_crossing, continuation, counted_crossing};

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
    /// The sufficient condition the exact scale is compared with: Theorem `thm.1` without a
    /// leader, Theorem `thm.1+` behind one (cycles or not).
    pub reference: ReferenceTheorem,
    /// The reference's scale: `1/(2 max_j α_j d_j^+)` (Theorem 1, eq. `degree1`) or
    /// `1/(2 max_j α_j (d_j^+ + 2 b_j))` (Theorem 1+, eq. `degree1+`), the value `check`
    /// prints as `max_gain_scale`.
    pub reference_gain_scale: f64,
    /// `c* / c_ref`.
    pub conservatism_ratio: f64,
    /// Exact critical scale of all delays (equals `c*`, see module docs).
    pub critical_delay_scale: f64,
    /// The reference's delay scale (equals `c_ref`).
    pub reference_delay_scale: f64,
    /// `r* / r_ref`.
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
    /// Argument-principle certificate at `c*` (both searches; `None` when a count failed).
    pub certificate: Option<CrossingCertificate>,
    /// The certificate exists and holds: exactly the crossing root(s) on the axis at `c*`,
    /// nothing right of it. Otherwise the scale is UNCERTIFIED.
    pub certified: bool,
}

/// The paper's sufficient condition a critical scale is measured against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ReferenceTheorem {
    /// Theorem `thm.1`: `α_j d_j^+ < 1/2` (no leader).
    Theorem1,
    /// Theorem `thm.1+`: `α_j (d_j^+ + 2 b_j) < 1/2`, the leader's pinning gains `b_j` counted
    /// twice (a network behind a leader).
    Theorem1Plus,
}

impl ReferenceTheorem {
    /// The name and inequality, as the tables print them.
    pub fn label(self) -> &'static str {
        match self {
            ReferenceTheorem::Theorem1 => "Theorem 1 (α_j d_j^+ < 1/2)",
            ReferenceTheorem::Theorem1Plus => "Theorem 1+ (α_j(d_j^+ + 2b_j) < 1/2)",
        }
    }
}

/// The reference condition of a network and its gain scale. A leader is the one undelayed
/// vertex no arc enters (its speed never changes; `analysis::network_matrices` appends it so):
/// then Theorem 1+ with `b_j = a_{j,leader}` and `d_j^+` the follower arcs, so
/// `α_j (d_j^+ + 2 b_j) = α_j (l_jj + b_j)`. Otherwise Theorem 1 on `l_jj = d_j^+` (also for
/// a delayed driver no arc enters, such as the head of a chain without a leader: Theorem 1's
/// form, although its graph is not strongly connected).
pub(crate) fn reference_scale(l: &DMatrix<f64>, delays_s: &[f64]) -> (ReferenceTheorem, f64) {
    let n = l.nrows();
    let sources: Vec<usize> = (0..n)
        .filter(|&i| l[(i, i)] == 0.0 && delays_s[i] == 0.0)
        .collect();
    let leader = match sources.as_slice() {
        [k] if n > 1 => Some(*k),
        _ => None,
    };
    let worst = (0..n)
        .map(|i| {
            let pinning = leader.map_or(0.0, |k| -l[(i, k)]);
            delays_s[i] * (l[(i, i)] + pinning)
        })
        .fold(0.0, f64::max);
    let reference = if leader.is_some() {
        ReferenceTheorem::Theorem1Plus
    } else {
        ReferenceTheorem::Theorem1
    };
    (reference, 1.0 / (2.0 * worst))
}

/// How the critical scale was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CriticalMethod {
    /// Newton continuation of the rightmost roots in `c`, certified at `c*`.
    Continuation,
    /// The first crossing bracketed by root counts (narrowed to `1e-6` only when the crossing
    /// found in the bracket as counted is not certified), the roots that crossed followed down
    /// by Newton and the crossing solved by regula falsi (when the continuation gives up
    /// inside the counted bracket).
    CountedBracket,
    /// Bisection with full solves (fallback).
    Bisection,
}

/// Root counts at the critical scale on both sides of the imaginary axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CrossingCertificate {
    /// Distance `δ` of the left counting line from the axis [1/s].
    pub margin: f64,
    /// Count right of `−δ` (consensus and the crossing roots expected).
    pub left: RootCount,
    /// Count right of `+ε`, just right of the axis (`ε = 10⁻⁹(1 + max_i d_i^+)` at `c*`;
    /// nothing but consensus expected).
    pub right: RootCount,
    /// Expected `left.count`: consensus plus the crossing roots with multiplicity.
    pub expected_left: usize,
    /// Both counts as expected.
    pub certified: bool,
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
    validate_network(adjacency, delays_s)?;
    if no_delay(adjacency, delays_s) {
        return Err(CriticalError::NoDelay);
    }
    let l = laplacian(adjacency);
    // Follow the rightmost roots from c = 1. On long rings the first root to cross need not
    // be among the rightmost at c = 1: then either the tracked roots cross later (the count
    // right of the axis at their crossing is positive) or they never do (the continuation
    // gives up). Either way the scale at which some root first reaches the right half-plane
    // is bracketed by root counts, which cost no solve, until a few roots have crossed at its
    // top; one solve there gives them, and they are followed back down to c*.
    let mut start = 1.0f64;
    let mut start_roots = roots.clone();
    let mut full_solves = 1;
    let mut found = None;
    let mut bracketed = false;
    // The bracket of the first crossing from root counts, with the roots at its top.
    let mut bracket: Option<(f64, f64)> = None;
    let mut bracket_roots: Option<RootsReport> = None;
    for _ in 0..4 {
        let tracked = tracked_roots(&start_roots);
        let increasing = tracked.iter().all(|t| t.0.re < 0.0);
        let ls = &l * start;
        let x = continuation(&ls, delays_s, &tracked).map(|mut x| {
            let certificate = certify_crossing(&ls, delays_s, &x);
            x.scale *= start;
            x.bracket = x.bracket.map(|b| b * start);
            (x, certificate)
        });
        let restart = match x {
            Some((x, Some(c))) if c.certified => {
                found = Some((x, c));
                break;
            }
            Some((x, Some(c))) if c.right.non_consensus() > 0 && !increasing => x.scale,
            Some((x, Some(c))) if c.right.non_consensus() > 0 && !bracketed => {
                bracketed = true;
                let known = (x.scale, c.right.non_consensus());
                bracket = first_unstable_scale(&l, delays_s, start, Some(known));
                match bracket {
                    Some((_, hi)) => hi,
                    None => break,
                }
            }
            None if increasing && !bracketed => {
                bracketed = true;
                bracket = first_unstable_scale(&l, delays_s, start, None);
                match bracket {
                    Some((_, hi)) => hi,
                    None => break,
                }
            }
            _ => break,
        };
        start = restart;
        full_solves += 1;
        start_roots = roots_at(adjacency, delays_s, start, options)?;
        if bracket.is_some_and(|b| b.1 == start) {
            bracket_roots = Some(start_roots.clone());
        }
    }
    // The continuation gave up inside the bracket: narrow it by root counts and follow the
    // roots that crossed (no further solve).
    if found.is_none() {
        if let (Some(b), Some(r)) = (bracket, &bracket_roots) {
            if let Some(report) = counted_bracket(adjacency, delays_s, &l, b, r, full_solves) {
                return Ok(report);
            }
        }
    }
    let Some((x, certificate)) = found else {
        let mut r = fallback(adjacency, delays_s, options)?;
        r.full_solves += full_solves - 1;
        return Ok(r);
    };
    let crossing = found_crossing(x, full_solves, CriticalMethod::Continuation, certificate);
    Ok(CriticalReport::of_crossing(
        adjacency, delays_s, &l, crossing,
    ))
}

/// The crossing inside the counted bracket `b` (roots `r` at its top), followed down from
/// the bracket as it is and, when that crossing is not certified, from the bracket narrowed
/// by root counts ([`NARROWING`]); `None` when none can be certified.
fn counted_bracket(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    l: &DMatrix<f64>,
    b: (f64, f64),
    r: &RootsReport,
    full_solves: usize,
) -> Option<CriticalReport> {
    let roots = tracked_roots(r);
    // Each narrower attempt bisects from the same bracket through the same scales: their
    // counts are made once.
    let counted = std::cell::RefCell::new(Vec::<(f64, Option<bool>)>::new());
    let unstable = |c: f64| {
        if let Some(&(_, k)) = counted
            .borrow()
            .iter()
            .find(|(x, _)| x.to_bits() == c.to_bits())
        {
            return k;
        }
        let k = unstable_at(l, delays_s, c).map(|k| k > 0);
        counted.borrow_mut().push((c, k));
        k
    };
    let certified = |width: f64| {
        let x = counted_crossing(l, delays_s, b, &roots, unstable, width)?;
        let c = certify_crossing(l, delays_s, &x).filter(|c| c.certified)?;
        Some((x, c))
    };
    let (x, c) = NARROWING.iter().find_map(|&width| certified(width))?;
    let crossing = found_crossing(x, full_solves, CriticalMethod::CountedBracket, c);
    Some(CriticalReport::of_crossing(
        adjacency, delays_s, l, crossing,
    ))
}

/// The roots of a solve as the searches follow them: value and multiplicity.
fn tracked_roots(r: &RootsReport) -> Vec<(Complex64, usize)> {
    r.roots
        .iter()
        .map(|r| (Complex64::from(r.root), r.multiplicity))
        .collect()
}

/// A crossing a search found, with its certificate, as the report's [`Crossing`].
fn found_crossing(
    x: continuation::Crossing,
    full_solves: usize,
    method: CriticalMethod,
    certificate: CrossingCertificate,
) -> Crossing {
    Crossing {
        scale: x.scale,
        root: x.root,
        multiplicity: x.multiplicity,
        bracket: x.bracket,
        bracket_abscissae: x.bracket_re,
        full_solves,
        method,
        certificate: Some(certificate),
    }
}

/// The first crossing as a search found it: everything else in a [`CriticalReport`] follows.
pub(crate) struct Crossing {
    /// The critical gain scale c*.
    pub scale: f64,
    /// The root on the imaginary axis at c*.
    pub root: Complex64,
    /// Its multiplicity.
    pub multiplicity: usize,
    /// Gain scales bracketing c*.
    pub bracket: [f64; 2],
    /// The abscissae at the bracket's ends.
    pub bracket_abscissae: [f64; 2],
    /// Full collocation solves spent.
    pub full_solves: usize,
    /// How c* was found.
    pub method: CriticalMethod,
    /// The root-count certificate of the crossing, when one was made.
    pub certificate: Option<CrossingCertificate>,
}

impl CriticalReport {
    /// The report of a crossing of the network with Laplacian `l`: the reference theorem's
    /// scale ([`reference_scale`]), the ratios, and the delay-scale view (the same c*, the
    /// crossing at ω/c*) are derived here once for every search.
    pub(crate) fn of_crossing(
        adjacency: &DMatrix<f64>,
        delays_s: &[f64],
        l: &DMatrix<f64>,
        x: Crossing,
    ) -> Self {
        let n = l.nrows();
        let (reference, theorem1) = reference_scale(l, delays_s);
        let c_star = x.scale;
        let omega = x.root.im.abs();
        CriticalReport {
            vehicles: n,
            strongly_connected: strongly_connected(adjacency),
            critical_gain_scale: c_star,
            reference,
            reference_gain_scale: theorem1,
            conservatism_ratio: c_star / theorem1,
            critical_delay_scale: c_star,
            reference_delay_scale: theorem1,
            delay_conservatism_ratio: c_star / theorem1,
            critical_max_delay_s: c_star * delays_s.iter().cloned().fold(0.0, f64::max),
            crossing_frequency_rad_s: omega,
            delay_crossing_frequency_rad_s: omega / c_star,
            crossing_multiplicity: x.multiplicity,
            bracket: x.bracket,
            bracket_abscissae: x.bracket_abscissae,
            full_solves: x.full_solves,
            method: x.method,
            certified: x.certificate.is_some_and(|c| c.certified),
            certificate: x.certificate,
        }
    }
}

/// Rightmost roots with all gains scaled by `c` (at least 8, the roots that crossed at the
/// top of a counted bracket among them when there are few): shift-invert first, the dense
/// collocation if that fails, up to [`DENSE_SOLVE_LIMIT`] vehicles (the crossing certificate
/// checks the outcome either way). The shift-invert roots come without their residuals: the
/// search only follows them.
fn roots_at(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    c: f64,
    options: &CollocationOptions,
) -> Result<RootsReport, CollocationError> {
    let scaled = adjacency * c;
    let wide = CollocationOptions {
        roots: options.roots.max(8),
        ..*options
    };
    match rightmost_roots_shift_invert_unchecked(&scaled, delays_s, &wide) {
        Ok(r) => Ok(r),
        Err(e) if adjacency.nrows() > DENSE_SOLVE_LIMIT => Err(e),
        Err(_) => rightmost_roots(&scaled, delays_s, options),
    }
}

/// The roots other than consensus right of the imaginary axis at gain scale `c`: the
/// argument-principle count right of the line `Re s = δ`, `δ = 10⁻⁹(1 + max_i d_i^+)`, close
/// enough to the axis for a bracket of the crossing (the continuation refines it).
fn unstable_at(l: &DMatrix<f64>, delays_s: &[f64], c: f64) -> Option<usize> {
    count_with_laplacian(l, c, delays_s, axis_line(l, c))
        .ok()
        .map(|r| r.count)
}

/// The counts grow the scale by this factor from a stable one until a root has crossed.
const BRACKET_GROWTH: f64 = 1.5;

/// A bracket from root counts is narrowed until at most this many roots have crossed at its
/// top: following a root down from there costs a fraction of a count, so a few are followed
/// rather than counted away (tens of roots cross within 25 % of the scale on random digraphs).
const FEW_CROSSED: usize = 6;

/// The counts stop narrowing a bracket at this ratio of its ends, however many crossed.
const NARROWEST: f64 = 1.02;

/// When the crossing followed down from a counted bracket is not certified (a root that
/// crossed was lost on the way, or crossed back), the bracket is narrowed by root counts to
/// this relative width and the roots followed again. The certificate, not the narrowing,
/// decides: narrowing first cost a dozen counts, most of a report on wide graphs.
const NARROWED: f64 = 1e-6;

/// The relative widths of the counted bracket the roots are followed down from, one after
/// another until a crossing is certified: as counted, then narrowed by root counts to 10⁻²,
/// 10⁻³ and [`NARROWED`] (from a bracket of a few per cent, about three counts, three more and
/// ten more). On draw 2 of the stability families' random digraphs of 400 the roots could not
/// be followed through the bracket as counted (5 %) but could through 10⁻²: three counts
/// instead of the sixteen that narrowing straight to 10⁻⁶ cost (21 s to 12 s).
const NARROWING: [f64; 4] = [f64::INFINITY, 1e-2, 1e-3, NARROWED];

/// A bracket of the first gain scale at which a root reaches the right half-plane, from a
/// stable `lo`, with at most [`FEW_CROSSED`] roots right of the axis at its top (or
/// `hi/lo ≤` [`NARROWEST`]): by counting roots ([`unstable_at`]) while growing the scale by
/// [`BRACKET_GROWTH`] (unless `hi` is given, with the roots right of the axis there), then
/// bisecting in `log c`.
fn first_unstable_scale(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    lo: f64,
    hi: Option<(f64, usize)>,
) -> Option<(f64, f64)> {
    let mut lo = lo;
    let (mut hi, mut crossed) = match hi {
        Some(h) => h,
        None => {
            let mut c = lo;
            loop {
                c *= BRACKET_GROWTH;
                if c > lo * 1e12 {
                    return None;
                }
                match unstable_at(l, delays_s, c)? {
                    0 => lo = c,
                    k => break (c, k),
                }
            }
        }
    };
    while crossed > FEW_CROSSED && hi / lo > NARROWEST {
        let mid = (lo * hi).sqrt();
        match unstable_at(l, delays_s, mid)? {
            0 => lo = mid,
            k => (hi, crossed) = (mid, k),
        }
    }
    Some((lo, hi))
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

#[cfg(test)]
mod tests {
    use super::super::collocation::tests::{random_network, Lcg};
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
                r.reference_gain_scale,
                exact.theorem1_gain_scale,
                max_relative = 1e-14
            );
            assert!(r.bracket[0] <= r.critical_gain_scale && r.critical_gain_scale <= r.bracket[1]);
            assert_eq!(r.method, CriticalMethod::Continuation);
        }
    }

    #[test]
    fn heterogeneous_critical_scales_respect_theorem_one_and_delay_equivalence() {
        let mut rng = Lcg(7);
        let opts = CollocationOptions::default();
        for trial in 0..5 {
            let n = 3 + trial;
            let (a, delays) = random_network(n, &mut rng);
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

    /// A ring of `n` drivers with gains and delays drawn from `rng`: predecessor gains in
    /// [0.4, 0.8], follower gains in [0.1, 0.4] when `bidirectional`, delays in [0.3, 0.7] s.
    fn heterogeneous_ring(
        n: usize,
        bidirectional: bool,
        rng: &mut Lcg,
    ) -> (DMatrix<f64>, Vec<f64>) {
        let mut a = DMatrix::zeros(n, n);
        for i in 0..n {
            a[(i, (i + n - 1) % n)] = 0.4 + 0.4 * rng.next();
            if bidirectional {
                a[(i, (i + 1) % n)] = 0.1 + 0.3 * rng.next();
            }
        }
        let delays = (0..n).map(|_| 0.3 + 0.4 * rng.next()).collect();
        (a, delays)
    }

    #[test]
    fn fast_report_equals_the_bisection_on_long_heterogeneous_rings() {
        // The whole fast path (shift-invert roots, continuation, root counts bracketing a
        // crossing that the rightmost roots at c = 1 do not make) against the first version's
        // search with dense full solves only: the critical scale to 1e-10, the crossing
        // frequency to 1e-8 and the abscissa at the given gains to 1e-12.
        let opts = CollocationOptions::default();
        let mut rng = Lcg(2025);
        for &(n, bidirectional) in &[(24usize, true), (30, false), (40, true)] {
            let (a, d) = heterogeneous_ring(n, bidirectional, &mut rng);
            let fast = super::super::report::analyse_network(&a, &d, &opts, true).unwrap();
            assert!(fast.certificate.unwrap().certified, "N={n}");
            let dense = rightmost_roots(&a, &d, &opts).unwrap();
            assert_relative_eq!(fast.roots.abscissa, dense.abscissa, epsilon = 1e-12);
            let fast = fast.critical.unwrap();
            let slow = bisection_search(&a, &d, &opts, false).unwrap();
            assert_eq!(fast.method, CriticalMethod::Continuation, "N={n}");
            assert!(fast.certificate.unwrap().certified, "N={n}");
            assert_relative_eq!(
                fast.critical_gain_scale,
                slow.critical_gain_scale,
                max_relative = 1e-10
            );
            assert_relative_eq!(
                fast.crossing_frequency_rad_s,
                slow.crossing_frequency_rad_s,
                max_relative = 1e-8
            );
        }
    }

    #[test]
    fn clustered_crossings_are_followed_without_the_bisection() {
        // 50 drivers on a bidirectional ring, gains 0.8/0.3, delays 0.3 + 0.05 k_i s. On these
        // two the corrector used to jump from one root of the cluster near iω ≈ 3.3 to its
        // neighbour; the two were merged as "roots that met", the certificate then counted the
        // lost one, and the search fell back to bisection (16 full solves, 16 s). Now: the
        // continuation, certified, and c* bracketed by two dense solves (another method).
        let opts = CollocationOptions::default();
        for digits in [
            "04402424404022400424422400404240400402022442422442",
            "02123002022022213402413212341240203122240313100001",
        ] {
            let d: Vec<f64> = digits
                .bytes()
                .map(|b| 0.3 + 0.05 * f64::from(b - b'0'))
                .collect();
            let n = d.len();
            let mut a = DMatrix::zeros(n, n);
            for i in 0..n {
                a[(i, (i + n - 1) % n)] = 0.8;
                a[(i, (i + 1) % n)] = 0.3;
            }
            let r = super::super::report::analyse_network(&a, &d, &opts, true)
                .unwrap()
                .critical
                .unwrap();
            assert_eq!(r.method, CriticalMethod::Continuation, "{digits}");
            assert!(r.certified && r.full_solves <= 2, "{digits}: {r:?}");
            let abscissa = |c: f64| rightmost_roots(&(&a * c), &d, &opts).unwrap().abscissa;
            assert!(
                abscissa(r.critical_gain_scale * (1.0 - 1e-7)) < 0.0,
                "{digits}"
            );
            assert!(
                abscissa(r.critical_gain_scale * (1.0 + 1e-7)) > 0.0,
                "{digits}"
            );
        }
    }

    #[test]
    fn the_counted_bracket_reaches_the_closed_form_crossing() {
        // The path taken when the continuation gives up inside the counted bracket (a
        // 200-vehicle bidirectional ring of the spread benchmark): bracket by counts, follow
        // the roots that crossed, regula falsi. Against the uniform ring's closed form.
        let ring = UniformRing::new(12, 0.8, 0.3, 0.5).unwrap();
        let exact = ring.modes().unwrap().critical_gain_scale;
        let (a, d) = (ring.adjacency(), ring.delays());
        let l = laplacian(&a);
        let (lo, hi) = first_unstable_scale(&l, &d, 1.0, None).unwrap();
        assert!(lo < exact && exact <= hi && hi / lo <= BRACKET_GROWTH + 1e-12);
        let crossed = unstable_at(&l, &d, hi).unwrap();
        assert!(crossed > 0 && (crossed <= FEW_CROSSED || hi / lo <= NARROWEST));
        let roots = roots_at(&a, &d, hi, &CollocationOptions::default()).unwrap();
        let tracked: Vec<(Complex64, usize)> = roots
            .roots
            .iter()
            .map(|r| (Complex64::from(r.root), r.multiplicity))
            .collect();
        let unstable = |c| unstable_at(&l, &d, c).map(|k| k > 0);
        // Followed down from the bracket as counted, and from the bracket narrowed to 1e-6.
        for width in [f64::INFINITY, NARROWED] {
            let x = counted_crossing(&l, &d, (lo, hi), &tracked, unstable, width).unwrap();
            assert_relative_eq!(x.scale, exact, max_relative = 1e-10);
            assert!(certify_crossing(&l, &d, &x).unwrap().certified);
        }
    }

    #[test]
    fn the_bisection_is_certified_by_the_same_counts() {
        let ring = UniformRing::new(6, 1.0, 0.3, 0.5).unwrap();
        let r = bisection_search(
            &ring.adjacency(),
            &ring.delays(),
            &CollocationOptions::default(),
            true,
        )
        .unwrap();
        let c = r.certificate.unwrap();
        assert!(r.certified && c.certified);
        assert_eq!(c.expected_left, 3);
        // A wrong c* (10 % above) is refused: roots lie right of the axis there.
        let l = laplacian(&ring.adjacency());
        let root = Complex64::new(0.0, r.crossing_frequency_rad_s);
        let wrong = certify_at(
            &l,
            &ring.delays(),
            1.1 * r.critical_gain_scale,
            (root, 1),
            &[],
        );
        assert!(!wrong.unwrap().certified);
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
