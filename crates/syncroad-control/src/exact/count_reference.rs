//! A denominator for the root count that follows the roots ([`super::argument_principle`]).
//!
//! The count walks `arg f` for `f = det M(s) / q(s)`. With `q = (s + ρ)^N` every root near the
//! line `Re s = σ` turns `f` by about `π` as the walk passes it while the `N`-fold pole turns
//! it back far away, so on a network of hundreds of drivers the phase along the line runs
//! through hundreds of radians and every determinant buys at most half a radian of it.
//!
//! Here `q` is the characteristic function of a network whose roots are known in closed form
//! and lie where the true ones roughly do: the same Laplacian, every driver with the mean
//! delay `ᾱ`, so that `q(s) = Π_k (s + λ_k e^{−sᾱ})` over the eigenvalues `λ_k` of `L` (each
//! factor's roots are `W_b(−λ_k ᾱ)/ᾱ`, Lambert W). Then most of the phase of `det M` is
//! divided out and the walk takes a fraction of the steps.
//!
//! `q`'s roots are poles of `f`, and a pole next to a root of `det M` on the other side of the
//! line would turn `f` by a whole turn within a short stretch of the line while leaving it
//! smooth elsewhere, which no step test can see from afar. So every factor is moved left,
//! `(s + κ_k) + λ_k e^{−(s + κ_k)ᾱ}` with `κ_k ≥ 0`, until its rightmost root (branches
//! `|b| ≤ 3` of Lambert W; the principal one is the rightmost) is at least `gap` left of the
//! line, and the walk's steps on the line are at most `gap` long: a pole and a root that
//! straddle the line are then at least `gap` apart, and a step that passes them turns by more
//! than the step test allows. No pole lies inside the contour, so the winding of `f` is the
//! count of roots itself; `q` need not equal anything (its `λ_k` need not even be exact
//! eigenvalues), it only has to be analytic, `q(s̄) = conj q(s)`, free of roots right of
//! `σ − gap`, and `≈ s^N` far out, as `det M` is.
//!
//! The eigenvalues cost a dense Schur form, `O(N³)` once per count; it pays where each
//! determinant is expensive (wide graphs in the sparse LU), not on rings, whose band LU costs
//! less than the Schur form saves.

use std::sync::{Arc, Mutex};

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::lambert_w::lambert_w;

/// The denominator `q` of the module documentation.
pub(crate) struct CountReference {
    /// `(λ_k, κ_k)`: the eigenvalues of `L`, in conjugate pairs, and each factor's shift.
    modes: Vec<(Complex64, f64)>,
    /// The common delay `ᾱ`.
    delay: f64,
    /// The reference's roots right of the line, all inside the contour.
    poles_inside: usize,
}

/// Use the reference when one factorization costs more than this many multiply–adds per
/// `N³`: it saves about two thirds of some thousand determinants (each about 12 times its
/// multiply–adds in flops, complex and with the derivative) against a Schur form of about
/// `10 N³` flops.
const PAYS_FROM_OPERATIONS_PER_N3: f64 = 1.0 / 800.0;

/// Schur iterations allowed per vehicle before the reference is given up (the plain
/// denominator is used then).
const SCHUR_ITERATIONS_PER_VEHICLE: usize = 30;

/// Lambert W branches `|b| ≤` this are placed; those beyond must lie far left of the line.
const BRANCHES: i64 = 3;

impl CountReference {
    /// Whether a network of `n` drivers whose factorization takes `operations` multiply–adds
    /// is worth a reference. Below 100 drivers the roots' phase is short enough that the
    /// steps the gap imposes on the line cost more than they save.
    pub(crate) fn pays(n: usize, operations: usize) -> bool {
        n >= 100 && operations as f64 >= PAYS_FROM_OPERATIONS_PER_N3 * (n as f64).powi(3)
    }

    /// The reference for the count right of `σ` inside the rectangle `[σ, right] × [−r, r]`
    /// on the network with Laplacian `c·l`, every pole at least `gap > 0` from the line;
    /// `None` when the eigenvalues or a Lambert W value cannot be computed or a factor's roots
    /// cannot be kept clear of the contour (the count then divides by `(s + ρ)^N`).
    pub(crate) fn new(
        l: &DMatrix<f64>,
        c: f64,
        delays_s: &[f64],
        sigma: f64,
        gap: f64,
        rectangle: (f64, f64),
    ) -> Option<Self> {
        let n = l.nrows();
        let observing: Vec<f64> = (0..n)
            .filter(|&i| l[(i, i)] != 0.0)
            .map(|i| delays_s[i])
            .collect();
        let delay = if observing.is_empty() {
            0.0
        } else {
            observing.iter().sum::<f64>() / observing.len() as f64
        };
        let eigenvalues: Vec<Complex64> = eigenvalues_of(l)?.iter().map(|z| z * c).collect();
        // Conjugate pairs from the upper half (the Schur form gives them as exact pairs), so
        // that `q(s̄) = conj q(s)` holds exactly.
        let real = eigenvalues.iter().filter(|z| z.im == 0.0).count();
        let upper: Vec<Complex64> = eigenvalues.iter().copied().filter(|z| z.im > 0.0).collect();
        if real + 2 * upper.len() != n {
            return None;
        }
        let mut reference = CountReference {
            modes: Vec::with_capacity(n),
            delay,
            poles_inside: 0,
        };
        let place = |lambda| Placement::of(lambda, delay, sigma, gap, rectangle);
        for &lambda in eigenvalues.iter().filter(|z| z.im == 0.0) {
            let p = place(lambda)?;
            reference.modes.push((lambda, p.shift));
            reference.poles_inside += p.inside;
        }
        for &lambda in &upper {
            let p = place(lambda)?;
            reference.modes.push((lambda, p.shift));
            reference.modes.push((lambda.conj(), p.shift));
            reference.poles_inside += 2 * p.inside;
        }
        Some(reference)
    }

    /// The poles of `f` inside the contour (the reference's roots right of the line): the
    /// count is the winding plus these.
    pub(crate) fn poles_inside(&self) -> usize {
        self.poles_inside
    }

    /// `q(s)/|q(s)|` and `q'(s)/q(s)`.
    pub(crate) fn phase_and_log_derivative(&self, s: Complex64) -> (Complex64, Complex64) {
        let one = Complex64::new(1.0, 0.0);
        let mut phase = one;
        let mut g = Complex64::new(0.0, 0.0);
        for &(lambda, kappa) in &self.modes {
            let t = s + kappa;
            let e = (-t * self.delay).exp();
            let v = t + lambda * e;
            phase *= v / v.norm();
            g += (one - lambda * self.delay * e) / v;
        }
        (phase / phase.norm(), g)
    }
}

/// The eigenvalues of the Laplacians whose Schur forms were computed last, most recent first,
/// by a hash of their entries: the search for the critical scale counts at many gain scales of
/// one Laplacian, each count needs them, and each Schur form is an `O(N³)` step that no thread
/// shares (a tenth of a second at N = 400). A hash, not the matrix, so that nothing of size
/// `N²` stays behind; were two Laplacians to share one, a count would still be right, since
/// `q` need not equal anything (module documentation).
static SPECTRA: Mutex<Vec<(u64, Arc<[Complex64]>)>> = Mutex::new(Vec::new());

/// Spectra [`SPECTRA`] keeps.
const SPECTRA_KEPT: usize = 4;

/// The eigenvalues of `l` from its real Schur form (conjugate pairs exact), or `None` when the
/// iteration does not converge; the same values whether they were kept or computed.
fn eigenvalues_of(l: &DMatrix<f64>) -> Option<Arc<[Complex64]>> {
    use std::hash::{Hash, Hasher};
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    l.shape().hash(&mut hasher);
    l.iter().for_each(|v| v.to_bits().hash(&mut hasher));
    let key = hasher.finish();
    let kept = SPECTRA
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .iter()
        .find(|(k, _)| *k == key)
        .map(|(_, e)| Arc::clone(e));
    if kept.is_some() {
        return kept;
    }
    let n = l.nrows();
    let eigenvalues: Arc<[Complex64]> = super::schur_eigenvalues::schur_eigenvalues(
        l.clone(),
        f64::EPSILON,
        SCHUR_ITERATIONS_PER_VEHICLE * n.max(1),
    )?
    .into();
    let mut spectra = SPECTRA.lock().unwrap_or_else(|p| p.into_inner());
    spectra.insert(0, (key, Arc::clone(&eigenvalues)));
    spectra.truncate(SPECTRA_KEPT);
    Some(eigenvalues)
}

/// Where one factor `(s + κ) + λe^{−(s + κ)ᾱ}` puts its roots.
struct Placement {
    /// `κ`.
    shift: f64,
    /// Its roots right of the line.
    inside: usize,
}

impl Placement {
    /// The smallest shift `κ` (either way) that leaves no root of the factor of `λ` within
    /// `gap` of the line `σ`, and every root right of it at least `gap` inside the
    /// rectangle's other sides.
    fn of(
        lambda: Complex64,
        delay: f64,
        sigma: f64,
        gap: f64,
        (right, r): (f64, f64),
    ) -> Option<Self> {
        let roots: Vec<Complex64> = if delay == 0.0 || lambda == Complex64::new(0.0, 0.0) {
            vec![-lambda]
        } else {
            let z = -lambda * delay;
            (-BRANCHES..=BRANCHES)
                .map(|b| lambert_w(b, z).ok().map(|w| w / delay))
                .collect::<Option<_>>()?
        };
        // The branches beyond the placed ones lie left of the outermost placed ones
        // (`Re W_b` falls as `|b|` grows).
        let tail = if roots.len() > 1 {
            roots[0].re.max(roots[roots.len() - 1].re)
        } else {
            f64::NEG_INFINITY
        };
        let clear = |kappa: f64| {
            tail - kappa < sigma - gap
                && roots.iter().all(|z| {
                    let re = z.re - kappa;
                    re <= sigma - gap
                        || (re >= sigma + gap && re <= right - gap && z.im.abs() <= r - gap)
                })
        };
        let shift = std::iter::once(0.0)
            .chain(
                roots
                    .iter()
                    .flat_map(|z| [z.re - (sigma - gap), z.re - (sigma + gap)]),
            )
            .filter(|&k| k.is_finite() && clear(k))
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))?;
        let inside = roots.iter().filter(|z| z.re - shift > sigma).count();
        Some(Placement { shift, inside })
    }
}
