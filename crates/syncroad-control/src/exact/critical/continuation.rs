//! Continuation of the rightmost roots in the gain scale `c` until one crosses the imaginary
//! axis, regula falsi on the crossing, and the argument-principle certificate at `c*` (the
//! method of the parent module's documentation).

use nalgebra::DMatrix;
use num_complex::Complex64;
use rayon::prelude::*;

use super::super::argument_principle::{count_with_laplacian, log_det_derivative};
use super::super::banded::{NetworkMatrix, RecentPivots};
use super::CrossingCertificate;

/// A root crossing the imaginary axis at gain scale `scale`.
pub(super) struct Crossing {
    pub(super) scale: f64,
    pub(super) root: Complex64,
    pub(super) multiplicity: usize,
    pub(super) bracket: [f64; 2],
    pub(super) bracket_re: [f64; 2],
    /// The other tracked roots at `scale`.
    others: Vec<Complex64>,
}

/// Newton's step `s − m/(log det M)'(s)` for gains scaled by `c`, from `s0`, factoring with
/// the pivots `recent` of the root's track. Newton stops when [`CRAWL`] steps in a row each
/// shrank by less than a tenth (and has converged only if they are below `10⁻¹¹` relative, at a
/// multiple root's noise floor): inside a dense cloud of roots `1/(log det M)'` is the cloud's
/// mean field, and the iterates crawl through it in even steps of about 10⁻³ (40 factorizations
/// each, 480 of the 680 Newton spent on eight random arcs per driver at N = 400), while near a
/// root the steps shrink quadratically, and near `k` nearly equal roots by `(k − 1)/k`.
pub(crate) fn newton_track(
    band: &NetworkMatrix,
    c: f64,
    s0: Complex64,
    m: usize,
    recent: &mut RecentPivots,
) -> Option<Complex64> {
    newton_iterations(band, c, s0, m, recent, CRAWL).0
}

/// [`newton_track`] stopping after `crawl` steps that shrink by less than a tenth, with the
/// factorizations it made.
fn newton_iterations(
    band: &NetworkMatrix,
    c: f64,
    s0: Complex64,
    m: usize,
    recent: &mut RecentPivots,
    crawl: usize,
) -> (Option<Complex64>, usize) {
    let mut s = s0;
    let mut last = f64::INFINITY;
    let mut crawling = 0;
    for k in 1..=40 {
        let Some(g) = log_det_derivative(band, c, s, recent) else {
            return (None, k);
        };
        let step = m as f64 / g;
        if !(step.re.is_finite() && step.im.is_finite()) {
            return (None, k);
        }
        s -= step;
        if s.im < 0.0 {
            s = s.conj();
        }
        crawling = if step.norm() > 0.9 * last {
            crawling + 1
        } else {
            0
        };
        last = step.norm();
        if last <= 1e-15 * (1.0 + s.norm()) {
            return (Some(s), k);
        }
        // Crawling at the noise floor of a multiple root is convergence as well.
        if crawling >= crawl {
            let converged = last <= 1e-11 * (1.0 + s.norm());
            return (converged.then_some(s), k);
        }
    }
    ((last <= 1e-11 * (1.0 + s.norm())).then_some(s), 40)
}

/// Newton steps in a row that shrink by less than a tenth before Newton gives up
/// ([`newton_track`]).
const CRAWL: usize = 5;

/// The root of multiplicity `m` through `from = (c0, s0)` followed to gain scale `c1` by Newton,
/// halving the step in `log c` (at most `depth` times) where Newton does not converge.
fn follow(
    band: &NetworkMatrix,
    from: (f64, Complex64),
    c1: f64,
    m: usize,
    depth: usize,
    recent: &mut RecentPivots,
) -> Option<Complex64> {
    let (c0, s0) = from;
    if let Some(s) = newton_track(band, c1, s0, m, recent) {
        if (s - s0).norm() <= 0.05 * (1.0 + s0.norm()) {
            return Some(s);
        }
    }
    if depth == 0 {
        return None;
    }
    let mid = (c0 * c1).sqrt();
    let s_mid = follow(band, from, mid, m, depth - 1, recent)?;
    follow(band, (mid, s_mid), c1, m, depth - 1, recent)
}

/// One continuation step of root `j` from `c` to `c_next`: a secant predictor in `log c`
/// from the step before (`prev`), Newton's corrector, and a restart off the real axis where two
/// real roots met. None when the corrector fails or lands far from its predictor (it may have
/// jumped to another root). `recent`: the pivots of root `j`'s track.
fn correct_root(
    band: &NetworkMatrix,
    (c, c_next): (f64, f64),
    cur: Complex64,
    prev: Option<(f64, Complex64)>,
    m: usize,
    dlog: f64,
    recent: &mut RecentPivots,
) -> Option<Complex64> {
    let pred = match prev {
        Some((cp, sp)) => cur + (cur - sp) * ((c_next / c).ln() / (c / cp).ln()),
        None => cur,
    };
    let close = |s: Complex64| (s - pred).norm() <= 0.05 * (1.0 + cur.norm());
    if let Some(s) = newton_track(band, c_next, pred, m, recent) {
        if close(s) {
            return Some(s);
        }
    }
    // Two real roots that meet leave the axis as a conjugate pair: restart off the axis.
    if cur.im.abs() <= 1e-9 * (1.0 + cur.norm()) {
        let kick = Complex64::new(pred.re, 0.1 * dlog * (1.0 + cur.norm()));
        let s = newton_track(band, c_next, kick, m, recent)?;
        return close(s).then_some(s);
    }
    None
}

/// Roots that met (a real pair turned complex) are one root from now on: the duplicates are
/// dropped from `next`, `cur`, `mult` and `pivots` alike. Two complex roots landing on one
/// point are not a meeting but a corrector that jumped from one root of a cluster to its
/// neighbour: then nothing is dropped and the answer is false (retry the step shorter).
fn merge_met_roots(
    next: &mut Vec<Complex64>,
    cur: &mut Vec<Complex64>,
    mult: &mut Vec<usize>,
    pivots: &mut Vec<RecentPivots>,
) -> bool {
    let mut keep = vec![true; next.len()];
    let real = |s: Complex64| s.im.abs() <= 1e-9 * (1.0 + s.norm());
    for i in 0..next.len() {
        for j in i + 1..next.len() {
            if keep[j] && (next[i] - next[j]).norm() < 1e-6 * (1.0 + next[i].norm()) {
                if !(real(cur[i]) && real(cur[j])) {
                    return false;
                }
                keep[j] = false;
            }
        }
    }
    retain_kept(next, &keep);
    retain_kept(cur, &keep);
    retain_kept(mult, &keep);
    retain_kept(pivots, &keep);
    true
}

/// Keeps the entries of `v` whose `keep` flag is set.
fn retain_kept<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut k = keep.iter().copied();
    v.retain(|_| k.next().unwrap_or(true));
}

/// Every root that changed side between `c` (`cur`) and `c_next` (`next`) crosses inside; the
/// first in `c` wins, with the other roots followed to its scale (each with the pivots of its
/// own track, `pivots`).
fn first_crossing(
    band: &NetworkMatrix,
    (c, c_next): (f64, f64),
    cur: &[Complex64],
    next: &[Complex64],
    mult: &[usize],
    pivots: &mut [RecentPivots],
) -> Option<Crossing> {
    let mut best: Option<Crossing> = None;
    for j in 0..next.len() {
        if (cur[j].re < 0.0) == (next[j].re < 0.0) {
            continue;
        }
        let m = mult[j];
        // A root whose crossing cannot be solved is left out: were it the first to cross, it
        // would be right of the axis at the crossing reported, and the certificate's count
        // there would refuse it.
        let Some((c_star, s_star, bracket, bracket_re)) =
            solve_crossing(band, m, (c, cur[j]), (c_next, next[j]), &mut pivots[j])
        else {
            continue;
        };
        if best.as_ref().is_none_or(|b| c_star < b.scale) {
            // The other roots at c*, followed from the bracket end nearer in log c; one that
            // cannot be followed there only loosens the margin (the certificate still counts).
            let others = (0..next.len())
                .filter(|&i| i != j)
                .filter_map(|i| {
                    let (from_c, from) = if (c_star / c).ln().abs() < (c_star / c_next).ln().abs() {
                        (c, cur[i])
                    } else {
                        (c_next, next[i])
                    };
                    follow(band, (from_c, from), c_star, mult[i], 6, &mut pivots[i])
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
    best
}

/// Continuation steps (accepted or halved) before the search gives up.
const CONTINUATION_STEPS: usize = 100;

/// Accepted steps in a row in which every tracked root moved away from the axis before a
/// search towards instability gives up: such roots are slow modes that cross late or never
/// (on long rings and random digraphs a fast mode crosses first), and the root counts of the
/// caller's fallback find the crossing for less than following them further.
const RECEDING_STEPS: usize = 3;

/// Follows the tracked roots in `c` from 1 until one crosses the axis (module documentation).
pub(super) fn continuation(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    tracked: &[(Complex64, usize)],
) -> Option<Crossing> {
    if tracked.is_empty() {
        return None;
    }
    let band = NetworkMatrix::new(l, delays_s);
    let increasing = tracked.iter().all(|(s, _)| s.re < 0.0);
    let sign = if increasing { 1.0 } else { -1.0 };
    let mut c = 1.0f64;
    let mut mult: Vec<usize> = tracked.iter().map(|t| t.1).collect();
    let mut cur: Vec<Complex64> = tracked.iter().map(|t| t.0).collect();
    let mut prev: Option<(f64, Vec<Complex64>)> = None;
    let mut dlog = 0.05f64;
    let mut receding = 0;
    // Each root's Newton steps factor with the pivots of its own track.
    let mut pivots = vec![RecentPivots::default(); cur.len()];
    // A budget of steps: tracked roots that wander without crossing (on long random digraphs
    // the first root to cross need not be among them) cost more to follow than the root
    // counts that bracket the crossing instead (the caller's fallback).
    for _ in 0..CONTINUATION_STEPS {
        if !(1e-18..=1e12).contains(&c) {
            return None;
        }
        let c_next = c * (sign * dlog).exp();
        let step = |(j, recent): (usize, &mut RecentPivots)| {
            let before = match &prev {
                Some((cp, sp)) if sp.len() == cur.len() => Some((*cp, sp[j])),
                _ => None,
            };
            correct_root(&band, (c, c_next), cur[j], before, mult[j], dlog, recent)
        };
        // The roots are corrected in parallel, each on its own (the order of the results is
        // kept, so the outcome does not depend on the threads).
        let corrected: Option<Vec<_>> = pivots.par_iter_mut().enumerate().map(step).collect();
        let Some(mut next) = corrected else {
            dlog /= 2.0;
            if dlog < 1e-9 {
                return None;
            }
            continue;
        };
        if !merge_met_roots(&mut next, &mut cur, &mut mult, &mut pivots) {
            dlog /= 2.0;
            if dlog < 1e-9 {
                return None;
            }
            continue;
        }
        let event = if increasing {
            next.iter().any(|s| s.re >= 0.0)
        } else {
            next.iter().all(|s| s.re < 0.0)
        };
        if event {
            return first_crossing(&band, (c, c_next), &cur, &next, &mult, &mut pivots);
        }
        if increasing && next.iter().zip(&cur).all(|(n, c)| n.re < c.re) {
            receding += 1;
            if receding >= RECEDING_STEPS {
                return None;
            }
        } else {
            receding = 0;
        }
        prev = Some((c, std::mem::replace(&mut cur, next)));
        c = c_next;
        dlog = (dlog * 1.5).min(0.3);
    }
    None
}

/// The first crossing inside a counted bracket `(lo, hi)` (`lo` stable, a root right of the
/// axis at `hi`), from the roots `roots_hi` at `hi`: the bracket is narrowed to a relative
/// width `width` by the counts `unstable(c)` (not at all for `∞`), every root right of the
/// axis at its top is followed down to its bottom, and the first to change side is solved by regula falsi.
pub(super) fn counted_crossing(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    bracket: (f64, f64),
    roots_hi: &[(Complex64, usize)],
    unstable: impl Fn(f64) -> Option<bool>,
    width: f64,
) -> Option<Crossing> {
    let band = NetworkMatrix::new(l, delays_s);
    let (mut lo, hi0) = bracket;
    let mut hi = hi0;
    while hi / lo > 1.0 + width {
        let mid = (lo * hi).sqrt();
        if unstable(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    // Each root with the pivots of its own track.
    let mut at_hi: Vec<(Complex64, usize, RecentPivots)> = roots_hi
        .iter()
        .filter_map(|&(s, m)| {
            let mut recent = RecentPivots::default();
            follow(&band, (hi0, s), hi, m, 8, &mut recent).map(|s| (s, m, recent))
        })
        .collect();
    let mut best: Option<Crossing> = None;
    for j in 0..at_hi.len() {
        let (s_hi, m) = (at_hi[j].0, at_hi[j].1);
        if s_hi.re < 0.0 {
            continue;
        }
        let recent = &mut at_hi[j].2;
        let Some(s_lo) = follow(&band, (hi, s_hi), lo, m, 8, recent) else {
            continue;
        };
        if s_lo.re >= 0.0 {
            continue;
        }
        let Some((c_star, root, br, br_re)) =
            solve_crossing(&band, m, (lo, s_lo), (hi, s_hi), recent)
        else {
            continue;
        };
        if best.as_ref().is_none_or(|b| c_star < b.scale) {
            let others = at_hi
                .iter_mut()
                .enumerate()
                .filter(|(i, _)| *i != j)
                .filter_map(|(_, (s, mi, recent))| follow(&band, (hi, *s), c_star, *mi, 8, recent))
                .collect();
            best = Some(Crossing {
                scale: c_star,
                root,
                multiplicity: m,
                bracket: br,
                bracket_re: br_re,
                others,
            });
        }
    }
    best
}

/// Regula falsi (Illinois) in `c` on `Re s(c) = 0` between two tracked points of opposite sign.
#[allow(clippy::type_complexity)]
fn solve_crossing(
    band: &NetworkMatrix,
    m: usize,
    a: (f64, Complex64),
    b: (f64, Complex64),
    recent: &mut RecentPivots,
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
        // Newton from the root interpolated along the chord between the two ends: among the
        // hundreds of roots a dense graph has near the axis, Newton converges only from much
        // closer than the root at the nearer end (within about the inverse of the other
        // roots' pull, `1/|Σ 1/(s − r)|`, which was 2·10⁻³ on a random digraph of 400 whose
        // nearer end lay 10⁻² away); the nearer end is the fallback.
        let chord = sa + (sb - sa) * ((c - ca) / (cb - ca));
        let nearer = if (c - ca).abs() < (c - cb).abs() {
            sa
        } else {
            sb
        };
        let s = newton_track(band, c, chord, m, recent)
            .or_else(|| newton_track(band, c, nearer, m, recent))?;
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

/// Argument-principle counts at `c*` either side of the axis ([`certify_at`]).
pub(super) fn certify_crossing(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    x: &Crossing,
) -> Option<CrossingCertificate> {
    certify_at(l, delays_s, x.scale, (x.root, x.multiplicity), &x.others)
}

/// The line just right of the imaginary axis that the counts look right of, for the gains of
/// `l` scaled by `c`: `ε = 10⁻⁹ (1 + c·max_i d_i^+)`, far above the error of a root solved onto
/// the axis (`10⁻¹⁵` relative) and far below any distance the walks cannot resolve.
pub(super) fn axis_line(l: &DMatrix<f64>, c: f64) -> f64 {
    // `c·max d_i` is `max c·d_i` exactly for `c > 0` (rounding is monotone), without forming
    // `c·L`, which the count forms itself.
    1e-9 * (1.0 + c * l.diagonal().max())
}

/// Root counts at gain scale `c_star`: right of the line `Re s = +ε` ([`axis_line`]) nothing
/// but consensus — no root has crossed yet — and right of `Re s = −δ` consensus and the
/// crossing root `(s, m)` with its conjugate. `δ` is a quarter of the distance from the axis
/// to the nearest other known root `others`; when the strip holds more roots than expected,
/// the left line moves 8× closer to the axis (up to four times, to 1/4096 of where it started)
/// before the certificate is refused: a crossing found from a counted bracket knows only the
/// roots it followed, and a slow mode it never followed can sit a few 10⁻⁴ left of the axis
/// (a leader with cycles of 400, draw 2 of the stability families: certified at the fourth
/// line, where three lines refused it and sent the search to a bisection of 17 full solves).
/// (The right line once sat at `+δ` as well, which let a pair that had crossed by less than
/// `δ` pass for the one on the axis.)
pub(super) fn certify_at(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    c_star: f64,
    crossing: (Complex64, usize),
    others: &[Complex64],
) -> Option<CrossingCertificate> {
    let (root, multiplicity) = crossing;
    let scale = 1.0 + root.norm();
    let separation = others.iter().map(|s| -s.re).fold(f64::INFINITY, f64::min);
    let mut margin = if separation > 1e-9 * scale {
        (0.25 * separation).min(0.05 * scale)
    } else {
        1e-3 * scale
    };
    let real = root.im.abs() <= 1e-12 * scale;
    let expected_left = 1 + multiplicity * if real { 1 } else { 2 };
    let right = count_with_laplacian(l, c_star, delays_s, axis_line(l, c_star)).ok()?;
    let mut last = None;
    for _ in 0..5 {
        if let Ok(left) = count_with_laplacian(l, c_star, delays_s, -margin) {
            let certificate = CrossingCertificate {
                margin,
                left,
                right,
                expected_left,
                certified: left.count == expected_left && right.non_consensus() == 0,
            };
            if certificate.certified || right.non_consensus() > 0 || left.count < expected_left {
                return Some(certificate);
            }
            last = Some(certificate);
        }
        margin /= 8.0;
    }
    last
}

#[cfg(test)]
mod tests {
    use super::super::super::collocation::laplacian;
    use super::super::super::collocation::tests::{
        denser_random_digraph, family_random_digraph, random_network, Lcg,
    };
    use super::super::super::collocation::CollocationOptions;
    use super::super::super::ring_modes::UniformRing;
    use super::super::{bisection_search, critical_scale, CriticalMethod};
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::DMatrix;
    use std::f64::consts::PI;

    /// The network matrix of `(a, delays)` and its eight rightmost roots (shift-invert).
    fn band_and_eight_rightmost(
        a: &DMatrix<f64>,
        delays: &[f64],
    ) -> (NetworkMatrix, super::super::super::collocation::RootsReport) {
        let eight = CollocationOptions {
            roots: 8,
            ..CollocationOptions::default()
        };
        let roots =
            super::super::super::collocation::rightmost_roots_shift_invert(a, delays, &eight)
                .unwrap();
        (NetworkMatrix::new(&laplacian(a), delays), roots)
    }

    #[test]
    fn newton_near_a_root_factors_afresh_once_not_at_every_iterate() {
        // A random digraph of the stability families (a ring and three random arcs per
        // driver, delays 0.2–0.8 s), factored by the sparse LU. Near a root M(s) is nearly
        // singular, and near some roots (the fourth from the right here) the pivots the network
        // chose at s = 1 + i are refused: each such point used to be factored afresh. Newton's
        // iterates now reuse the pivots of the last fresh factorization among them, and reach
        // the same root.
        let (a, delays) = family_random_digraph(120, &mut Lcg(2000), (0.3, 0.4));
        let (band, roots) = band_and_eight_rightmost(&a, &delays);
        // The points Newton visits near a root, each factored on its own as before.
        let near = |root: Complex64| -> Vec<Complex64> {
            (3..=9)
                .map(|k| {
                    let d = 10f64.powi(-k);
                    root + Complex64::new(d, d)
                })
                .collect()
        };
        let alone = |near: &[Complex64]| -> Vec<(Complex64, RecentPivots)> {
            near.iter()
                .map(|&s| {
                    let mut r = RecentPivots::default();
                    (log_det_derivative(&band, 1.0, s, &mut r).unwrap(), r)
                })
                .collect()
        };
        // A root near which the network's own pivots are refused every time (the rightmost
        // such root).
        let root: Complex64 = roots
            .roots
            .iter()
            .map(|r| Complex64::from(r.root))
            .find(|&root| alone(&near(root)).iter().all(|(_, r)| r.fresh() == 1))
            .expect("a root near which the network's pivots are refused");
        let mut recent = RecentPivots::default();
        let found = newton_track(
            &band,
            1.0,
            root + Complex64::new(1e-3, 1e-3),
            1,
            &mut recent,
        )
        .expect("Newton converges from nearby");
        assert!(
            (found - root).norm() <= 1e-10 * (1.0 + root.norm()),
            "{found} against {root}"
        );
        assert!(
            recent.fresh() <= 2,
            "{} fresh factorizations",
            recent.fresh()
        );
        let near = near(root);
        let alone = alone(&near);
        // One sequence over the same points: two fresh factorizations, the same derivatives
        // (to the rounding of a matrix this close to singular: 1e-9 from the root, pivots in
        // another order differ in the eighth digit).
        let mut along = RecentPivots::default();
        for (&s, &(reference, _)) in near.iter().zip(&alone) {
            let g = log_det_derivative(&band, 1.0, s, &mut along).unwrap();
            assert!(
                (g - reference).norm() <= 1e-6 * reference.norm(),
                "{g} against {reference}"
            );
        }
        assert!(
            along.fresh() <= 2,
            "{} of {} afresh",
            along.fresh(),
            near.len()
        );
    }

    #[test]
    fn continuation_equals_the_bisection_answer() {
        // The fast search must not change results beyond 1e-10: compare with the first
        // version's bisection (full solves only), on heterogeneous graphs, a symmetric ring
        // (double roots) and an all-to-all graph (roots of multiplicity N − 1).
        let opts = CollocationOptions::default();
        let mut rng = Lcg(31);
        let mut cases = Vec::new();
        for n in [4usize, 6, 9] {
            cases.push(random_network(n, &mut rng));
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

    /// Every root of the uniform one-way ring (modes 1 … n−1, Lambert-W branches |b| ≤ 3) in
    /// decreasing real part: the closed form.
    fn ring_roots(ring: &UniformRing, n: usize) -> Vec<Complex64> {
        let mut roots: Vec<Complex64> = (1..n)
            .flat_map(|k| (-3i64..=3).map(move |b| (k, b)))
            .map(|(k, b)| ring.mode_root(k, b).unwrap())
            .collect();
        roots.sort_by(|a, b| b.re.total_cmp(&a.re));
        roots
    }

    #[test]
    fn a_slow_mode_near_the_axis_that_was_never_followed_does_not_refuse_the_crossing() {
        // Oracle: a leader (row of zeros, the consensus root), a driver following it with gain
        // ε and one following that driver with gain 1, every delay α = 1: L is triangular, so
        // det M(s) = s (s + cε e^{−s}) (s + c e^{−s}). The last factor crosses at c* = π/2 with
        // s = iπ/2 (Lambert W); the middle one leaves a slow real root at about −c*ε, here
        // 10⁻⁴, that a crossing found from a counted bracket has not followed (`others` is
        // empty). The strip right of −δ holds it until δ is below 10⁻⁴: the fifth line,
        // 1/4096 of where the first one starts (0.05·(1 + π/2)).
        let c_star = std::f64::consts::FRAC_PI_2;
        let eps = 1e-4 / c_star;
        let l = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 0.0, -eps, eps, 0.0, 0.0, -1.0, 1.0]);
        let delays = [1.0; 3];
        let root = Complex64::new(0.0, c_star);
        let c = certify_at(&l, &delays, c_star, (root, 1), &[]).unwrap();
        assert!(c.certified, "{c:?}");
        assert_eq!((c.left.count, c.right.count), (3, 0));
        let first = 0.05 * (1.0 + root.norm());
        assert!(
            c.margin < 1e-4 && c.margin > first / 8f64.powi(5),
            "δ = {}",
            c.margin
        );
    }

    #[test]
    fn newton_stops_crawling_through_a_dense_cloud_of_roots_and_finds_the_same_roots() {
        // The random digraph of 150 with eight arcs per driver (below): near 2 rad/s hundreds
        // of roots lie within 0.2 of the axis, and Newton on det M started among them crawls
        // in even steps of about 10⁻³ for all its 40 iterations. Starts on a grid there and
        // 10⁻⁴ from each of the eight rightmost roots, Newton with and without the stop: both
        // reach the same roots from the latter (to 10⁻¹⁰), and the stopped one spends well under
        // half the factorizations.
        let (a, delays) = denser_random_digraph(150, 8, &mut Lcg(8), (0.3, 0.5));
        let (band, roots) = band_and_eight_rightmost(&a, &delays);
        let grid = (0..24)
            .map(|k| Complex64::new(-0.02 - 0.02 * (k % 4) as f64, 1.7 + 0.1 * (k / 4) as f64));
        let near = roots
            .roots
            .iter()
            .map(|r| Complex64::from(r.root) + Complex64::new(1e-4, 1e-4));
        let (mut stopped, mut crawled, mut longest, mut found) = (0, 0, 0, 0);
        for s0 in grid.chain(near) {
            let (fast, n_fast) =
                newton_iterations(&band, 1.0, s0, 1, &mut RecentPivots::default(), CRAWL);
            let (slow, n_slow) =
                newton_iterations(&band, 1.0, s0, 1, &mut RecentPivots::default(), usize::MAX);
            if let Some(root) = fast {
                let other = slow.expect("a root the stopped Newton found");
                assert!(
                    (root - other).norm() <= 1e-10 * root.norm(),
                    "{root} vs {other}"
                );
                found += 1;
            }
            stopped += n_fast;
            crawled += n_slow;
            longest = longest.max(n_slow);
        }
        assert!(found >= 8, "{found} roots found");
        assert!(
            longest >= 30,
            "no start crawled ({longest} factorizations at most)"
        );
        assert!(
            2 * stopped < crawled,
            "{stopped} against {crawled} factorizations"
        );
    }

    #[test]
    fn regula_falsi_starts_newton_on_the_chord_where_the_roots_are_dense() {
        // A random digraph of 150 drivers with eight random arcs each: near its crossing the
        // roots lie so close together that Newton on det M converges only from within about
        // 10⁻³ of one. Regula falsi across a bracket 5 % below and 2 % above the crossing
        // started Newton at its first point from the root at the nearer end, and Newton did not
        // converge there; from the root interpolated along the chord it does.
        let (a, delays) = denser_random_digraph(150, 8, &mut Lcg(8), (0.3, 0.5));
        let l = laplacian(&a);
        let band = NetworkMatrix::new(&l, &delays);
        let options = CollocationOptions::default();
        let roots =
            super::super::super::collocation::rightmost_roots_shift_invert(&a, &delays, &options)
                .unwrap();
        let report = super::super::critical_scale_from(&a, &delays, &roots, &options).unwrap();
        let c_star = report.critical_gain_scale;
        // The oracle: argument-principle counts just below and just above c*.
        let crossed = |c: f64| {
            count_with_laplacian(&l, c, &delays, axis_line(&l, c))
                .unwrap()
                .non_consensus()
        };
        assert_eq!(crossed(c_star * (1.0 - 1e-6)), 0);
        assert!(crossed(c_star * (1.0 + 1e-6)) >= 2);
        let on_axis = Complex64::new(0.0, report.crossing_frequency_rad_s);
        let mut recent = RecentPivots::default();
        let (lo, hi) = (0.95 * c_star, 1.02 * c_star);
        let s_lo = follow(&band, (c_star, on_axis), lo, 1, 8, &mut recent).unwrap();
        let s_hi = follow(&band, (c_star, on_axis), hi, 1, 8, &mut recent).unwrap();
        assert!(
            s_lo.re < 0.0 && s_hi.re > 0.0,
            "{s_lo} at {lo}, {s_hi} at {hi}"
        );
        let first = (lo * s_hi.re - hi * s_lo.re) / (s_hi.re - s_lo.re);
        let nearer = if first - lo < hi - first { s_lo } else { s_hi };
        assert!(
            newton_track(&band, first, nearer, 1, &mut RecentPivots::default()).is_none(),
            "Newton now converges from the nearer end: this network no longer shows the chord's use"
        );
        let (c, root, _, _) = solve_crossing(
            &band,
            1,
            (lo, s_lo),
            (hi, s_hi),
            &mut RecentPivots::default(),
        )
        .expect("the crossing is solved");
        assert_relative_eq!(c, c_star, max_relative = 1e-9);
        assert!(root.re.abs() <= 1e-12, "{root}");
    }

    #[test]
    fn a_pair_that_crossed_by_less_than_the_margin_is_not_certified() {
        // Oracle: the one-way ring's closed form. Just above c* the crossing pair lies right of
        // the axis by far less than the margin δ (a quarter of the way to the next root); a
        // count right of +δ took it for the pair on the axis and certified the wrong scale.
        let (n, alpha) = (6, 0.5);
        let ring = UniformRing::new(n, 1.0, 0.0, alpha).unwrap();
        let exact = ring.modes().unwrap().critical_gain_scale;
        let l = laplacian(&ring.adjacency());
        let at = |c: f64| {
            let roots = ring_roots(&UniformRing::new(n, c, 0.0, alpha).unwrap(), n);
            let top = roots.iter().copied().find(|s| s.im > 0.0).unwrap();
            let others: Vec<Complex64> = roots
                .into_iter()
                .filter(|s| (s - top).norm() > 1e-9 && (s - top.conj()).norm() > 1e-9)
                .collect();
            (top, others)
        };
        let above = exact * (1.0 + 1e-4);
        let (top, others) = at(above);
        assert!(
            top.re > 0.0 && top.re < 1e-3 && -others[0].re > 0.1,
            "{top} {}",
            others[0]
        );
        let c = certify_at(&l, &ring.delays(), above, (top, 1), &others).unwrap();
        assert_eq!(c.right.non_consensus(), 2);
        assert!(!c.certified);
        // At c* itself the same counts certify it.
        let (top, others) = at(exact);
        assert!(top.re.abs() < 1e-12);
        let c = certify_at(&l, &ring.delays(), exact, (top, 1), &others).unwrap();
        assert!(c.certified, "{c:?}");
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
}
