//! Independent certificate for the rightmost roots: counting characteristic roots to the right
//! of a vertical line by the argument principle.
//!
//! Every root `s` of `det M(s) = det(sI + diag(e^{−sα_i})L) = 0` (eq. `chandler+`) is an
//! eigenvalue of `−diag(e^{−sα_i})L`, so by Gershgorin a root with `Re s ≥ σ` satisfies
//! `|s| ≤ B(σ) = max_i 2 d_i^+ e^{−σα_i}`. The number of roots in `{Re s > σ}`, counted with
//! multiplicity, is therefore the winding number around the rectangle
//! `[σ, R] × [−R, R]` of
//!
//! `f(s) = det M(s) / (s + ρ)^N`,  `ρ = max(0, −σ) + 1` (the pole `−ρ` lies left of `σ`),
//!
//! with `R = 2(B + ρ) + |σ| + 1`. `M(s)` has real coefficients, so `f(s̄) = conj f(s)`: the
//! lower half of the rectangle turns `f` by as much as the upper half, and only the upper
//! half is walked, from `R` on the real axis up, across and down to `σ` (the winding is the
//! phase change over `π`; both ends are real, so it is a whole number of half turns). On the
//! top and right sides
//! `f = det(I + X)` with `‖X‖ = ‖(diag(e^{−sα})L − ρI)/(s + ρ)‖ ≤ 1/2`, so `f` turns little
//! there and the walk is cheap; near the line `Re s = σ` it follows `arg f` closely.
//!
//! **The consensus root.** Every `det M` vanishes at `s = 0` (`L1 = 0`), and `f` is multiplied
//! by `(s + ρ)/s` (with either denominator), which divides that root out exactly; the count
//! adds it back when `σ < 0`. The certificate's line passes `10⁻⁹` right of the axis, and the
//! walk down it would otherwise shrink its steps to that distance near the real axis (about a
//! tenth of the certificate's determinants on wide graphs). The pole sits on the root itself,
//! not beside it, so nothing is left there for the step tests to resolve.
//!
//! **Step control.** Each step from `a` to `b = a + h·e` is accepted only if
//! 1. the wrapped phase change `Δ = arg(f(b)/f(a))` satisfies `|Δ| ≤ 1.5` (well inside `π`);
//! 2. `Δ` agrees within `0.1` with the trapezoid prediction `Im((g(a) + g(b))/2 · h e)`, where
//!    `g = f'/f = tr(M⁻¹M') − N/(s + ρ)` is the exact logarithmic derivative
//!    (`tr(M⁻¹M') = Σ_k u_kk'/u_kk` from an LU that carries the derivative,
//!    [`super::banded`]): one root passed close by turns `f` by nearly `π` while the ends see
//!    little of it, and a full turn hidden inside the step would make them differ by about `2π`;
//! 3. `h·|g(b) − g(a)| ≤ 0.5`: two roots on one side passed close by turn `f` by a full turn
//!    that the wrapped phase and the trapezoid both miss, but each changes `g` across the step
//!    by about `4/h`, while roots further away than the step change it by `h/d²`. The change
//!    is measured, not `|g|` itself: on hundreds of drivers `g` carries a large, smooth part
//!    from the many roots beside the line, which tests 1 and 2 handle;
//! 4. `h · max(|g(a)|, |g(b)|) ≤ 4`: no root within a quarter step of either end, where it
//!    could cancel the change of test 3 (`|g| ≳ 1/d` at distance `d`);
//!
//! otherwise the step is halved. The accumulated phase over `π` must be within `10⁻⁶` of a
//! whole number. This is a floating-point computation, not interval arithmetic, but no root can
//! hide without violating one of the tests at every scale the step halving visits. A test walks
//! the same control along segments beside 2 000 known root sets (clouds, close
//! pairs, multiple roots, lattices in step with the halving, roots at the ends) and compares
//! with the exact phase; with test 3 left out it miscounts some of them. (The first version's
//! steps were bounded by `h·|g| ≤ 1` and `|Δ| ≤ 0.5`: twice the steps for the same counts.)
//! The count uses neither the collocation nor Newton's method, so it certifies them.
//!
//! **Wide graphs.** With `(s + ρ)^N` below, every root near the line turns `f` by about `π`
//! as the walk passes it, so on hundreds of drivers the walk takes thousands of steps. Where a
//! determinant is expensive (the sparse LU of a wide graph, [`CountReference::pays`]) `f`
//! divides by a function whose roots are known in closed form and lie roughly where the
//! network's do instead (the same Laplacian with one delay for everyone,
//! [`super::count_reference`]); its roots are kept at least `gap` off the line, the steps along
//! the line at most `gap` long, and those right of the line are added to the winding. The count
//! is the same (tested against the power denominator and Lambert W's closed form) in about
//! 60 % of the steps at the given gains (a ring and three random arcs per driver, N = 200), in
//! half of them on eight random arcs per driver at N = 400.

use super::banded::{NetworkMatrix, RecentPivots};
use super::collocation::{laplacian, validate_network, CollocationError};
use super::count_reference::CountReference;
use nalgebra::DMatrix;
use num_complex::Complex64;
use rayon::prelude::*;
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
    /// The accumulated phase is not a whole number of turns.
    #[error("the phase of det M(s) around the contour right of σ = {sigma} adds up to {winding} turns, not a whole number")]
    NonIntegerWinding {
        /// The line.
        sigma: f64,
        /// The accumulated winding number.
        winding: f64,
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
    /// Half-width `R` of the enclosing rectangle [1/s].
    pub radius: f64,
    /// Determinant evaluations used.
    pub evaluations: usize,
    /// Steps rejected by the step control (halved and retried).
    pub rejected_steps: usize,
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
/// [`ArgumentPrincipleError`] for invalid input, a root on the contour or a phase that does
/// not close.
pub fn count_roots_right_of(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    sigma: f64,
) -> Result<RootCount, ArgumentPrincipleError> {
    validate_network(adjacency, delays_s)?;
    count_with_laplacian(&laplacian(adjacency), 1.0, delays_s, sigma)
}

/// The denominator `q` of the count's `f = det M / q` (module documentation).
enum Divisor {
    /// `(s + ρ)^N`.
    Power(f64),
    /// A function whose roots follow the network's ([`CountReference`]).
    Reference(CountReference),
}

impl Divisor {
    /// `q(s)/|q(s)|` and `q'(s)/q(s)` for `n` drivers.
    fn phase_and_log_derivative(&self, s: Complex64, n: usize) -> (Complex64, Complex64) {
        match self {
            Divisor::Power(rho) => {
                let v = s + rho;
                ((v / v.norm()).powi(n as i32), n as f64 / v)
            }
            Divisor::Reference(q) => q.phase_and_log_derivative(s),
        }
    }

    /// Roots of `q` inside the contour: poles of `f`, each a turn off the winding.
    fn poles_inside(&self) -> usize {
        match self {
            Divisor::Power(_) => 0,
            Divisor::Reference(q) => q.poles_inside(),
        }
    }
}

/// `f(s)/|f(s)|` and the logarithmic derivative `g(s) = f'(s)/f(s)` for `f = det M / q`
/// (module documentation), from one LU of `M(s)` carrying its derivative ([`super::banded`]),
/// with the pivots of the stretch of contour `recent` follows.
fn phase_and_log_derivative(
    band: &NetworkMatrix,
    q: &Divisor,
    rho: f64,
    s: Complex64,
    recent: &mut RecentPivots,
) -> Option<(Complex64, Complex64)> {
    let lu = band.factor_near(1.0, s, Some(recent));
    let (q_phase, q_g) = q.phase_and_log_derivative(s, band.len());
    // The consensus root, divided out exactly: `f` is multiplied by `(s + ρ)/s`.
    let consensus_phase = (s / s.norm()) * ((s + rho) / (s + rho).norm()).conj();
    let consensus_g = 1.0 / s - 1.0 / (s + rho);
    let phase = lu.phase()? * (q_phase * consensus_phase).conj();
    let g = lu.log_det_derivative()? - q_g - consensus_g;
    (g.re.is_finite() && g.im.is_finite() && phase.re.is_finite() && phase.im.is_finite())
        .then_some((phase, g))
}

/// `d/ds log det M(s) = tr(M(s)⁻¹M'(s))` for `M(s) = sI + c·diag(e^{−sα_i})L`, or `None` at a
/// root. Newton's step `s − m/g(s)` converges quadratically to a root of multiplicity `m`.
/// `recent`: the pivots of the sequence of nearby points `s` belongs to (Newton's iterates).
pub(crate) fn log_det_derivative(
    band: &NetworkMatrix,
    c: f64,
    s: Complex64,
    recent: &mut RecentPivots,
) -> Option<Complex64> {
    band.factor_near(c, s, Some(recent)).log_det_derivative()
}

/// [`count_roots_right_of`] for a validated Laplacian `l` with every gain scaled by `c` (the
/// searches for the critical scale count at many `c` on one `l`, whose eigenvalues the
/// denominator then computes once).
pub(crate) fn count_with_laplacian(
    l: &DMatrix<f64>,
    c: f64,
    delays_s: &[f64],
    sigma: f64,
) -> Result<RootCount, ArgumentPrincipleError> {
    count_dividing_by(l, c, delays_s, sigma, Denominator::WherePays)
}

/// The denominator `q` of the count's `f = det M / q`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Denominator {
    /// `(s + ρ)^N`.
    #[cfg_attr(not(test), allow(dead_code))]
    Power,
    /// The [`CountReference`] (falling back to `(s + ρ)^N` when it cannot be made).
    #[cfg_attr(not(test), allow(dead_code))]
    FollowingRoots,
    /// The [`CountReference`] where it pays ([`CountReference::pays`]), else `(s + ρ)^N`.
    WherePays,
}

/// [`count_with_laplacian`] with the denominator chosen.
pub(crate) fn count_dividing_by(
    unscaled: &DMatrix<f64>,
    c: f64,
    delays_s: &[f64],
    sigma: f64,
    denominator: Denominator,
) -> Result<RootCount, ArgumentPrincipleError> {
    if !sigma.is_finite() {
        return Err(ArgumentPrincipleError::NonFiniteLine { sigma });
    }
    let scaled;
    let l = if c == 1.0 {
        unscaled
    } else {
        scaled = unscaled * c;
        &scaled
    };
    let n = l.nrows();
    let bound = (0..n)
        .map(|i| 2.0 * l[(i, i)] * (-sigma * delays_s[i]).exp())
        .fold(0.0, f64::max);
    let rho = (-sigma).max(0.0) + 1.0;
    let r = 2.0 * (bound + rho) + sigma.abs() + 1.0;
    let right = r.max(sigma + 1.0);
    // The upper half of the counter-clockwise rectangle, from its right side's crossing of
    // the real axis to the line's: `f(s̄) = conj f(s)`, so the lower half turns by as much.
    let corners = [
        Complex64::new(right, 0.0),
        Complex64::new(right, r),
        Complex64::new(sigma, r),
        Complex64::new(sigma, 0.0),
    ];
    let scale = r + sigma.abs();
    let on_contour = |s: Complex64| ArgumentPrincipleError::RootOnContour { re: s.re, im: s.im };
    let band = NetworkMatrix::new(l, delays_s);
    // On wide graphs the denominator follows the roots (`count_reference`), its poles at
    // least `gap` left of the line and the steps along the line at most `gap` long.
    let gap = (bound + rho) / 64.0;
    let wanted = match denominator {
        Denominator::Power => false,
        Denominator::FollowingRoots => true,
        Denominator::WherePays => CountReference::pays(n, band.operations()),
    };
    let divisor = wanted
        .then(|| CountReference::new(unscaled, c, delays_s, sigma, gap, (right, r)))
        .flatten()
        .map_or(Divisor::Power(rho), Divisor::Reference);
    let line_cap = match divisor {
        Divisor::Power(_) => r / 8.0,
        Divisor::Reference(_) => (r / 8.0).min(gap),
    };
    // The line, where the roots crowd the walk, in sixteen pieces: the pieces are walked in
    // parallel and their turns added in order, so the count does not depend on the threads.
    let pieces = 16;
    let mut segments = vec![
        (corners[0], corners[1], r / 8.0),
        (corners[1], corners[2], (right - sigma) / 8.0),
    ];
    segments.extend((0..pieces).map(|k| {
        let at = |k: usize| corners[2] + (corners[3] - corners[2]) * (k as f64 / pieces as f64);
        (at(k), at(k + 1), line_cap)
    }));
    // Each piece factors with the pivots of its own last fresh factorization.
    let walks: Vec<Result<Walk, ArgumentPrincipleError>> = segments
        .par_iter()
        .map(|&(a, b, cap)| {
            let mut recent = RecentPivots::default();
            let eval = |s: Complex64| {
                phase_and_log_derivative(&band, &divisor, rho, s, &mut recent).ok_or(on_contour(s))
            };
            walk(eval, a, b, cap, scale, &STEP_CONTROL)
        })
        .collect();
    let (mut total_angle, mut evaluations, mut rejected_steps) = (0.0, 0, 0);
    for w in walks {
        let w = w?;
        total_angle += w.angle;
        evaluations += w.evaluations;
        rejected_steps += w.rejected_steps;
    }
    // Both ends are real, so the half turns by a whole number of half turns.
    let winding = total_angle / std::f64::consts::PI;
    // The denominator's poles inside, and the consensus root divided out when it is inside.
    let poles_inside = divisor.poles_inside() + usize::from(sigma < 0.0);
    let winding = winding + poles_inside as f64;
    let count = winding.round();
    if (winding - count).abs() > 1e-6 || count < 0.0 {
        return Err(ArgumentPrincipleError::NonIntegerWinding { sigma, winding });
    }
    Ok(RootCount {
        sigma,
        count: count as usize,
        includes_consensus: sigma < 0.0,
        radius: r,
        evaluations,
        rejected_steps,
    })
}

/// The phase change of `f` along one straight segment of the contour.
struct Walk {
    angle: f64,
    evaluations: usize,
    rejected_steps: usize,
}

/// The bounds of the walk's step control (module documentation) on one step: its turn `|Δ|`,
/// its departure from the trapezoid prediction, the change `h·|g(b) − g(a)|` and `h·|g|` at
/// its ends. The step doubles when all but the trapezoid's are below 0.4 of their bounds.
#[derive(Debug, Clone, Copy)]
struct StepControl {
    turn: f64,
    trapezoid: f64,
    variation: f64,
    stiffness: f64,
}

/// The step control every count walks with.
const STEP_CONTROL: StepControl = StepControl {
    turn: 1.5,
    trapezoid: 0.1,
    variation: 0.5,
    stiffness: 4.0,
};

/// Walks from `a` to `b` under the step control of the module documentation, steps at most
/// `cap` long.
fn walk(
    mut eval: impl FnMut(Complex64) -> Result<(Complex64, Complex64), ArgumentPrincipleError>,
    a: Complex64,
    b: Complex64,
    cap: f64,
    scale: f64,
    control: &StepControl,
) -> Result<Walk, ArgumentPrincipleError> {
    let length = (b - a).norm();
    let dir = (b - a) / length;
    let mut w = Walk {
        angle: 0.0,
        evaluations: 1,
        rejected_steps: 0,
    };
    let mut t = 0.0;
    let (mut p, mut g) = eval(a)?;
    let mut h = (1.0 / g.norm().max(1e-300)).min(cap);
    while t < length {
        let step = h.min(length - t);
        let s_next = a + dir * (t + step);
        w.evaluations += 1;
        let (q, g_next) = eval(s_next)?;
        let delta = (q / p).arg();
        let predicted = ((g + g_next) * 0.5 * dir * step).im;
        let variation = step * (g_next - g).norm();
        let stiffness = step * g.norm().max(g_next.norm());
        let within = |bound: f64| {
            delta.abs() <= control.turn * bound
                && (delta - predicted).abs() <= control.trapezoid
                && variation <= control.variation * bound
                && stiffness <= control.stiffness * bound
        };
        if !within(1.0) {
            w.rejected_steps += 1;
            h = step / 2.0;
            if h < 1e-13 * scale {
                return Err(ArgumentPrincipleError::RootOnContour {
                    re: s_next.re,
                    im: s_next.im,
                });
            }
            continue;
        }
        w.angle += delta;
        p = q;
        g = g_next;
        t += step;
        if within(0.4) {
            h = (2.0 * step).min(cap);
        }
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::super::collocation::tests::{family_random_digraph, random_network, Lcg};
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

    /// Walks segments of length 0.5–2 beside `trials` known sets of roots under `control` and
    /// returns how many walks ended with a phase other than the exact one (oracle: each root
    /// turns `Π (s − r)` along a straight segment by `arg((b − r)/(a − r))`, which no
    /// wrapping confuses). Eight families: clouds on both sides,
    /// clouds on one side, clusters of nearly equal roots, lattices, close pairs, multiple
    /// roots, roots at the ends, lattices in step with the halving from the cap, each beside a
    /// far cloud of up to 100 roots (a large, smooth part of `g`, as on wide graphs).
    fn walks_against_known_roots(control: &StepControl, trials: usize) -> usize {
        let mut rng = Lcg(12345);
        let log_uniform = |lo: f64, hi: f64, r: f64| (lo.ln() + (hi / lo).ln() * r).exp();
        let mut wrong = 0;
        for trial in 0..trials {
            let len = 0.5 + 1.5 * rng.next();
            let (a, b) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, len));
            let k = log_uniform(1.0, 300.0, rng.next()) as usize + 1;
            let w = log_uniform(1e-3, 0.3, rng.next()) * len;
            let side = if rng.next() < 0.5 { 1.0 } else { -1.0 };
            let mut roots: Vec<Complex64> = Vec::new();
            // Along the segment and a tenth beyond either end.
            let along = |rng: &mut Lcg| len * (1.2 * rng.next() - 0.1);
            match trial % 8 {
                0 => {
                    for _ in 0..k {
                        let y = along(&mut rng);
                        roots.push(Complex64::new(w * (2.0 * rng.next() - 1.0), y));
                    }
                }
                1 => {
                    let d = log_uniform(1e-4, 0.3, rng.next()) * len;
                    for _ in 0..k {
                        let y = along(&mut rng);
                        roots.push(Complex64::new(side * (d + w * rng.next()), y));
                    }
                }
                2 => {
                    for _ in 0..1 + k / 10 {
                        let y = along(&mut rng);
                        let centre = Complex64::new(w * (2.0 * rng.next() - 1.0), y);
                        let eps = log_uniform(1e-7, 1e-2, rng.next()) * len;
                        for _ in 0..1 + (4.0 * rng.next()) as usize {
                            let t = std::f64::consts::TAU * rng.next();
                            roots.push(centre + Complex64::from_polar(eps * rng.next(), t));
                        }
                    }
                }
                3 | 7 => {
                    let d = log_uniform(1e-4, 0.3, rng.next()) * len;
                    let (spacing, first) = if trial % 8 == 3 {
                        let spacing = log_uniform(1e-3, 0.3, rng.next()) * len;
                        (spacing, -0.1 * len + spacing * rng.next())
                    } else {
                        // In step with the halving from the cap (the segment's length).
                        let spacing = len / 2f64.powi(1 + (8.0 * rng.next()) as i32);
                        (spacing, spacing * (0.5 - 4.0))
                    };
                    let mut y = first;
                    while y < 1.1 * len {
                        roots.push(Complex64::new(side * d, y));
                        y += spacing;
                    }
                }
                4 => {
                    for _ in 0..1 + k / 10 {
                        let y = len * rng.next();
                        let sep = log_uniform(1e-5, 0.1, rng.next()) * len;
                        let d = log_uniform(1e-5, 0.1, rng.next()) * len;
                        let other = if rng.next() < 0.5 { 1.0 } else { -1.0 };
                        roots.push(Complex64::new(d, y));
                        roots.push(Complex64::new(other * d * (0.5 + rng.next()), y + sep));
                    }
                }
                5 => {
                    for _ in 0..1 + k / 20 {
                        let centre =
                            Complex64::new(0.1 * w * (2.0 * rng.next() - 1.0), len * rng.next());
                        let m = 2 + (3.0 * rng.next()) as usize;
                        roots.extend(std::iter::repeat_n(centre, m));
                    }
                }
                _ => {
                    for _ in 0..1 + k / 10 {
                        let end = if rng.next() < 0.5 { 0.0 } else { len };
                        let y = end + 0.02 * len * (2.0 * rng.next() - 1.0);
                        roots.push(Complex64::new(0.1 * w * (2.0 * rng.next() - 1.0), y));
                    }
                }
            }
            let far_side = if rng.next() < 0.5 { 1.0 } else { -1.0 };
            for _ in 0..(100.0 * rng.next()) as usize {
                let x = far_side * (0.5 + 3.0 * rng.next()) * len;
                roots.push(Complex64::new(x, len * (3.0 * rng.next() - 1.0)));
            }
            let exact: f64 = roots.iter().map(|r| ((b - r) / (a - r)).arg()).sum();
            let eval = |s: Complex64| {
                let (mut phase, mut g) = (Complex64::new(1.0, 0.0), Complex64::new(0.0, 0.0));
                for r in &roots {
                    phase *= (s - r) / (s - r).norm();
                    g += 1.0 / (s - r);
                }
                Ok((phase, g))
            };
            let cap = if rng.next() < 0.5 { len } else { len / 16.0 };
            // A walk that refuses (a root on the contour) is not wrong.
            if let Ok(walked) = walk(eval, a, b, cap, len, control) {
                wrong += usize::from((walked.angle - exact).abs() > 1e-6);
            }
        }
        wrong
    }

    #[test]
    fn the_walk_turns_as_far_as_known_roots_turn_it_and_needs_its_variation_test() {
        let trials = 2000;
        let wrong = walks_against_known_roots(&STEP_CONTROL, trials);
        assert_eq!(wrong, 0, "miscounted walks of {trials}");
        // Without the change of g across the step, close pairs on one side hide a full turn.
        let without_variation = StepControl {
            variation: f64::INFINITY,
            ..STEP_CONTROL
        };
        let wrong = walks_against_known_roots(&without_variation, trials);
        assert!(
            wrong > 0,
            "the walk without its variation test miscounts none"
        );
    }

    #[test]
    fn a_line_a_billionth_right_of_the_consensus_root_costs_no_more_than_one_further_off() {
        // The certificate's line passes 10⁻⁹ right of the axis, next to the consensus root.
        // Divided out exactly, the root no longer shrinks the walk's steps as the line nears
        // the real axis: the count there costs about what it costs 10⁻³ away (8 and 10
        // determinants more; 70 more on the ring of 12 without the division), and both agree with
        // Lambert W's closed form, as does a line just left of the root.
        for (n, kf, kb, alpha) in [(12usize, 1.0, 0.5, 0.4), (40, 0.8, 0.3, 0.5)] {
            let ring = UniformRing::new(n, kf, kb, alpha).unwrap();
            let (a, d) = (ring.adjacency(), ring.delays());
            let near = count_roots_right_of(&a, &d, 1e-9).unwrap();
            let off = count_roots_right_of(&a, &d, 1e-3).unwrap();
            assert_eq!(near.count, lambert_count(&ring, 1e-9), "N={n}");
            assert_eq!(off.count, lambert_count(&ring, 1e-3), "N={n}");
            assert!(
                near.evaluations <= off.evaluations + 20,
                "N={n}: {} determinants at 1e-9, {} at 1e-3",
                near.evaluations,
                off.evaluations
            );
            let left = count_roots_right_of(&a, &d, -1e-9).unwrap();
            assert_eq!(left.count, lambert_count(&ring, -1e-9), "N={n}");
            assert_eq!(left.count, near.count + 1, "N={n}");
        }
    }

    /// Roots of a uniform ring right of `σ` with multiplicity, from Lambert W on branches
    /// `|b| ≤ 8` of every Fourier mode (the oracle).
    fn lambert_count(ring: &UniformRing, sigma: f64) -> usize {
        let mut count = 0;
        for k in 0..ring.vehicles {
            for b in -8i64..=8 {
                if k == 0 && b != 0 {
                    continue;
                }
                if ring.mode_root(k, b).unwrap().re > sigma {
                    count += 1;
                }
            }
        }
        count
    }

    #[test]
    fn lines_next_to_double_and_nearly_real_roots_count_them_all() {
        // Symmetric rings have λ_k = λ_{N−k} real: every root is double. With α·λ_max just
        // above 1/e the dominant pair W_{0,−1}(−αλ)/α is nearly real (Im ≈ 0.05).
        let e_inv = (-1.0f64).exp();
        for &(n, k, alpha) in &[
            (8usize, 0.5, 0.9),
            (12, 1.0, 0.4),
            (10, e_inv / 4.0 * 1.0005, 1.0),
            (9, 0.3, 1.1),
        ] {
            let ring = UniformRing::new(n, k, k, alpha).unwrap();
            let modes = ring.modes().unwrap();
            let a = modes.abscissa;
            for &offset in &[1e-6, -1e-6, 1e-3, -1e-3] {
                let sigma = a + offset * (1.0 + a.abs());
                let c = count_roots_right_of(&ring.adjacency(), &ring.delays(), sigma).unwrap();
                assert_eq!(
                    c.count,
                    lambert_count(&ring, sigma),
                    "N={n} k={k} α={alpha} σ = abscissa {offset:+e}"
                );
            }
        }
    }

    #[test]
    fn all_to_all_counts_the_root_of_multiplicity_n_minus_one() {
        // L = nkI − k11ᵀ: det M = s (s + nk e^{−sα})^{n−1}. N = 3 is small enough for any
        // factorization; N = 200 goes through the rank-one correction of the all-to-all rows,
        // with a root of multiplicity 199 next to the line.
        for (n, k, alpha) in [(3usize, 0.4, 0.7), (200, 1.2 / 200.0, 0.7)] {
            let a = DMatrix::from_fn(n, n, |i, j| if i == j { 0.0 } else { k });
            let w = |b: i64| {
                let z = Complex64::new(-(n as f64) * k * alpha, 0.0);
                super::super::lambert_w::lambert_w(b, z).unwrap() / alpha
            };
            let abscissa = w(0).re;
            for &offset in &[1e-6, -1e-6, 0.2] {
                let sigma = abscissa + offset;
                let expected = 1 + (n - 1) * (-8i64..=8).filter(|&b| w(b).re > sigma).count();
                let c = count_roots_right_of(&a, &vec![alpha; n], sigma).unwrap();
                assert_eq!(c.count, expected, "N = {n}, σ = abscissa {offset:+e}");
            }
        }
    }

    #[test]
    fn the_denominator_following_the_roots_counts_what_lambert_w_counts_even_beside_a_root() {
        // With one delay for every driver the reference's roots are the network's own roots
        // (up to the rounding of the Schur form's eigenvalues): the count is then mostly the
        // reference's poles inside the contour, placed and counted by Lambert W, while the
        // walk itself sees almost nothing. The oracle is the ring's closed form; the lines pass
        // 1e-7 on either side of the rightmost roots and far from them.
        for &(n, kf, kb, alpha) in &[
            (12usize, 1.0, 0.3, 0.7),
            (17, 0.9, 0.0, 1.1),
            (24, 1.2, 0.5, 0.6),
        ] {
            let ring = UniformRing::new(n, kf, kb, alpha).unwrap();
            let (a, delays) = (ring.adjacency(), ring.delays());
            let l = laplacian(&a);
            let mut roots: Vec<Complex64> = (1..n)
                .flat_map(|k| (-1i64..=1).map(move |b| (k, b)))
                .map(|(k, b)| ring.mode_root(k, b).unwrap())
                .collect();
            roots.sort_by(|x, y| y.re.total_cmp(&x.re));
            let mut lines = vec![-2.0, -0.5, 0.05];
            for r in &roots[..6] {
                lines.extend([r.re + 1e-7, r.re - 1e-7]);
            }
            for sigma in lines {
                let expected = lambert_count(&ring, sigma);
                let c = count_dividing_by(&l, 1.0, &delays, sigma, Denominator::FollowingRoots)
                    .unwrap();
                assert_eq!(c.count, expected, "N={n} σ={sigma}");
            }
        }
    }

    #[test]
    fn a_root_and_a_reference_root_on_either_side_of_the_line_are_both_counted() {
        // A ring whose delays differ from their mean by under 0.1 %: each root lies within
        // about 1e-4 of the reference's root (the mean-delay ring, Lambert W), and a line
        // between the two would leave a pole of f a hair from a zero across the line, a full
        // turn within a stretch no step from afar sees (this lost a pair on a ring of 400
        // when the poles stayed where they were). The lines pass between the collocation's
        // rightmost roots and the reference's nearest ones; the power denominator, which has
        // no pole near the line, is the second method.
        let (n, kf, kb, alpha) = (24usize, 1.0, 0.3, 0.7);
        let ring = UniformRing::new(n, kf, kb, alpha).unwrap();
        let a = ring.adjacency();
        let delays: Vec<f64> = (0..n)
            .map(|i| alpha * (1.0 + 8e-4 * (i as f64 * 1.7).sin()))
            .collect();
        let mean = delays.iter().sum::<f64>() / n as f64;
        let reference = UniformRing::new(n, kf, kb, mean).unwrap();
        let reference_roots: Vec<Complex64> = (1..n)
            .flat_map(|k| (-1i64..=1).map(move |b| (k, b)))
            .map(|(k, b)| reference.mode_root(k, b).unwrap())
            .collect();
        let l = laplacian(&a);
        let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
        let mut between = 0;
        for root in r.roots.iter().take(6) {
            let s = Complex64::from(root.root);
            let nearest = reference_roots
                .iter()
                .min_by(|x, y| (**x - s).norm().total_cmp(&(**y - s).norm()))
                .unwrap();
            if (nearest - s).norm() > 1e-3 || (nearest.re - s.re).abs() < 1e-9 {
                continue;
            }
            between += 1;
            let sigma = 0.5 * (nearest.re + s.re);
            let power = count_dividing_by(&l, 1.0, &delays, sigma, Denominator::Power).unwrap();
            let following =
                count_dividing_by(&l, 1.0, &delays, sigma, Denominator::FollowingRoots).unwrap();
            assert_eq!(
                following.count, power.count,
                "σ={sigma} between {s} and {nearest}"
            );
        }
        assert!(
            between >= 2,
            "only {between} lines between a root and its reference"
        );
    }

    #[test]
    fn both_denominators_count_alike_on_random_networks_with_mixed_delays() {
        // A second method for the same count: the power denominator walks every root's phase,
        // the reference divides most of it out. Lines right beside the collocation's rightmost
        // roots, where the two walks differ most.
        let mut rng = Lcg(2024);
        for trial in 0..6 {
            let n = 20 + 8 * trial;
            let (mut a, delays) = random_network(n, &mut rng);
            let worst = (0..n)
                .map(|i| delays[i] * a.row(i).sum())
                .fold(0.0, f64::max);
            a *= (0.4 + 0.3 * rng.next()) / worst;
            let l = laplacian(&a);
            let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
            let mut lines = vec![1e-9, -0.3];
            for root in r.roots.iter().take(3) {
                let m = 1e-6 * (1.0 + root.root.re.abs());
                lines.extend([root.root.re + m, root.root.re - m]);
            }
            for sigma in lines {
                let power = count_dividing_by(&l, 1.0, &delays, sigma, Denominator::Power).unwrap();
                let following =
                    count_dividing_by(&l, 1.0, &delays, sigma, Denominator::FollowingRoots)
                        .unwrap();
                assert_eq!(
                    following.count, power.count,
                    "trial {trial} N={n} σ={sigma}"
                );
            }
        }
    }

    #[test]
    fn on_a_wide_random_digraph_the_denominator_following_the_roots_saves_most_steps() {
        // The family the reference is for (`scripts/stability-families.py`'s random digraphs:
        // a ring and three random arcs per driver, delays 0.2–0.8 s), N = 200: the same counts
        // as the power denominator at the given gains and past the first crossing, in under
        // two thirds of the determinants at the given gains (314 and 266 against 523 and 469;
        // under half before the walk measured the change of g rather than g itself, which
        // spared the power denominator more steps than the reference).
        let n = 200;
        let (a, delays) = family_random_digraph(n, &mut Lcg(77), (0.2, 0.3));
        let l = laplacian(&a);
        assert!(CountReference::pays(
            n,
            NetworkMatrix::new(&l, &delays).operations()
        ));
        // Past the crossing the reference's roots right of the line stay there as counted
        // poles and only those within the gap of the line move: fewer steps, if fewer saved.
        for (scale, sigma, saving) in [(1.0, 1e-9, 1.5), (1.0, -0.05, 1.5), (2.5, 1e-9, 1.3)] {
            let ls = &l * scale;
            let power = count_dividing_by(&ls, 1.0, &delays, sigma, Denominator::Power).unwrap();
            // The reference as the searches make it: the unscaled Laplacian's eigenvalues,
            // computed once, times the scale.
            let following =
                count_dividing_by(&l, scale, &delays, sigma, Denominator::FollowingRoots).unwrap();
            assert_eq!(following.count, power.count, "scale {scale} σ={sigma}");
            assert!(
                saving * following.evaluations as f64 <= power.evaluations as f64,
                "scale {scale} σ={sigma}: {} evaluations against {}",
                following.evaluations,
                power.evaluations
            );
        }
    }
}
