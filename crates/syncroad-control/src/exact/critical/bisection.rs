//! The first version's search for the critical scale: bracket the abscissa's sign change and
//! bisect with full solves, a secant on the tracked root inside the bracket. The fallback of
//! the continuation and its reference in tests; its answer carries the same root-count
//! certificate.

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::super::banded::{NetworkMatrix, RecentPivots};
use super::super::collocation::DENSE_SOLVE_LIMIT;
use super::super::collocation::{
    laplacian, rightmost_roots, rightmost_roots_shift_invert, validate_network, CollocationError,
    CollocationOptions, RootsReport,
};
use super::continuation::newton_track;
use super::{certify_at, CriticalError, CriticalMethod, CriticalReport, Crossing};

/// Rightmost roots with all gains scaled by `c`: the dense collocation up to
/// [`DENSE_SOLVE_LIMIT`] vehicles, shift-invert Arnoldi beyond (the dense eigenvalue step
/// costs `O((N·M)³)`, minutes at `N = 400`); the certificate checks the outcome either way.
fn abscissa_at(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    c: f64,
    options: &CollocationOptions,
) -> Result<RootsReport, CollocationError> {
    let scaled = adjacency * c;
    if adjacency.nrows() <= DENSE_SOLVE_LIMIT {
        rightmost_roots(&scaled, delays_s, options)
    } else {
        rightmost_roots_shift_invert(&scaled, delays_s, options)
    }
}

/// A stable scale `lo` and an unstable scale `hi` with the full solves at both.
struct Bracket {
    lo: f64,
    lo_report: RootsReport,
    hi: f64,
    hi_report: RootsReport,
}

impl Bracket {
    /// From Theorem 1's scale: halve until stable, then double until unstable.
    fn find(
        theorem1: f64,
        eval: &mut impl FnMut(f64) -> Result<RootsReport, CollocationError>,
    ) -> Result<Self, CriticalError> {
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
        Ok(Self {
            lo,
            lo_report,
            hi,
            hi_report,
        })
    }

    /// Keeps `r`, the full solve at `c`, on its side of the bracket.
    fn keep(&mut self, c: f64, r: RootsReport) {
        if r.is_stable() {
            self.lo = c;
            self.lo_report = r;
        } else {
            self.hi = c;
            self.hi_report = r;
        }
    }

    /// Bisects with full solves to a bracket of `relative` width.
    fn bisect_to(
        &mut self,
        relative: f64,
        eval: &mut impl FnMut(f64) -> Result<RootsReport, CollocationError>,
    ) -> Result<(), CriticalError> {
        while (self.hi - self.lo) > relative * self.hi {
            let mid = 0.5 * (self.lo + self.hi);
            let r = eval(mid)?;
            self.keep(mid, r);
        }
        Ok(())
    }
}

/// Secant on the real part of the dominant root, tracked by Newton inside the bracket: the
/// crossing `(c*, s*)` when it converges there.
fn secant(l: &DMatrix<f64>, delays_s: &[f64], b: &Bracket) -> Option<(f64, Complex64)> {
    // The root near `s0` with gains scaled by `c`: Newton on `det M(s)` from its LU.
    let network = NetworkMatrix::new(l, delays_s);
    let mut recent = RecentPivots::default();
    let mut track_root = |c: f64, s0: Complex64| newton_track(&network, c, s0, 1, &mut recent);
    let s_hi: Complex64 = b.hi_report.roots[0].root.into();
    let s_lo = track_root(b.lo, s_hi)?;
    let (mut c0, mut g0) = (b.lo, s_lo.re);
    let (mut c1, mut g1, mut z1) = (b.hi, s_hi.re, s_hi);
    for _ in 0..60 {
        if g1 == g0 {
            return None;
        }
        let c2 = c1 - g1 * (c1 - c0) / (g1 - g0);
        if !(b.lo..=b.hi).contains(&c2) {
            return None;
        }
        let z2 = track_root(c2, z1)?;
        (c0, g0) = (c1, g1);
        (c1, g1, z1) = (c2, z2.re, z2);
        if (c1 - c0).abs() <= 1e-14 * c1 || g1.abs() <= 1e-15 * z1.norm() {
            return Some((c1, z1));
        }
    }
    None
}

/// Certifies a secant's `c*` with full computations on both sides (a root that crossed
/// earlier inside the bracket shows up as instability below c*); true when c* is the
/// crossing. The bracket narrows to the solves made either way.
fn certify_secant(
    c_star: f64,
    b: &mut Bracket,
    eval: &mut impl FnMut(f64) -> Result<RootsReport, CollocationError>,
) -> Result<bool, CriticalError> {
    let below = c_star * (1.0 - 1e-7);
    let r_below = eval(below)?;
    let stable_below = r_below.is_stable();
    b.keep(below, r_below);
    if !stable_below {
        return Ok(false);
    }
    let above = c_star * (1.0 + 1e-7);
    let r_above = eval(above)?;
    let unstable_above = !r_above.is_stable();
    b.keep(above, r_above);
    // Stable above too: the tracked root did not cross here.
    Ok(unstable_above)
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
    let mut b = Bracket::find(theorem1, &mut eval)?;
    b.bisect_to(1e-3, &mut eval)?;
    let mut crossing = None;
    if let Some((c, s)) = use_secant.then(|| secant(&l, delays_s, &b)).flatten() {
        if certify_secant(c, &mut b, &mut eval)? {
            crossing = Some((c, s));
        }
    }
    let (c_star, s_star) = match crossing {
        Some(x) => x,
        None => {
            // Fall back to bisection with full solves down to 1e-10 relative.
            b.bisect_to(1e-10, &mut eval)?;
            (0.5 * (b.lo + b.hi), b.hi_report.roots[0].root.into())
        }
    };
    // The same root counts as the continuation's certificate, the other roots of the last
    // solve above c* setting the margin.
    let multiplicity = b.hi_report.roots[0].multiplicity;
    let others: Vec<Complex64> = b.hi_report.roots[1..]
        .iter()
        .map(|r| Complex64::from(r.root))
        .collect();
    let certificate = certify_at(&l, delays_s, c_star, (s_star, multiplicity), &others);
    Ok(CriticalReport::of_crossing(
        adjacency,
        delays_s,
        &l,
        Crossing {
            scale: c_star,
            root: s_star,
            multiplicity,
            bracket: [b.lo, b.hi],
            bracket_abscissae: [b.lo_report.abscissa, b.hi_report.abscissa],
            full_solves,
            method: CriticalMethod::Bisection,
            certificate,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::super::super::ring_modes::UniformRing;
    use super::*;
    use approx::assert_relative_eq;

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
}
