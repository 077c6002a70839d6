//! Step 2 of the method: the characteristic matrix `M(s)`, Newton refinement of a root on
//! `[M(s)x = 0, cᴴx = 1]` with its residual certificate, and the multiplicity of each root.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use super::super::banded::{NetworkLu, NetworkMatrix, RecentPivots};
use super::network::laplacian;
use super::{CollocationOptions, RefinedRoot};

/// Characteristic matrix `M(s) = sI + diag(e^{−sα_i}) L` of eq. `chandler+`.
pub fn characteristic_matrix(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    s: Complex64,
) -> DMatrix<Complex64> {
    char_matrix_from_laplacian(&laplacian(adjacency), delays_s, s)
}

fn char_matrix_from_laplacian(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    s: Complex64,
) -> DMatrix<Complex64> {
    let n = l.nrows();
    let mut m = DMatrix::from_fn(n, n, |i, j| {
        Complex64::new(l[(i, j)], 0.0) * (-s * delays_s[i]).exp()
    });
    for i in 0..n {
        m[(i, i)] += s;
    }
    m
}

/// Derivative `M'(s) = I − diag(α_i e^{−sα_i}) L`.
fn char_matrix_derivative(l: &DMatrix<f64>, delays_s: &[f64], s: Complex64) -> DMatrix<Complex64> {
    let n = l.nrows();
    let mut m = DMatrix::from_fn(n, n, |i, j| {
        -Complex64::new(l[(i, j)], 0.0) * delays_s[i] * (-s * delays_s[i]).exp()
    });
    for i in 0..n {
        m[(i, i)] += 1.0;
    }
    m
}

/// Newton refinement of a root of `det M(s) = 0` on `[M(s)x = 0, cᴴx = 1]`.
pub(crate) fn newton_refine(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    s0: Complex64,
    options: &CollocationOptions,
) -> RefinedRoot {
    let n = l.nrows();
    let mut s = s0;
    // Two steps of inverse iteration give the approximate null vector.
    let mut x = DVector::from_fn(n, |i, _| Complex64::new(1.0, 0.1 * i as f64));
    for _ in 0..2 {
        let m = char_matrix_from_laplacian(l, delays_s, s);
        if let Some(y) = m.lu().solve(&x) {
            let norm = y.norm();
            if norm.is_finite() && norm > 0.0 {
                x = y / Complex64::new(norm, 0.0);
            }
        }
    }
    let c = x.clone();
    let mut steps = 0;
    let mut converged = false;
    while steps < options.max_newton_steps {
        steps += 1;
        let m = char_matrix_from_laplacian(l, delays_s, s);
        let dm = char_matrix_derivative(l, delays_s, s);
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
        let Some(delta) = j.lu().solve(&(-f)) else {
            break;
        };
        x += delta.rows(0, n);
        s += delta[n];
        if delta[n].norm() <= options.newton_tolerance * (1.0 + s.norm()) {
            converged = true;
            break;
        }
    }
    let m = char_matrix_from_laplacian(l, delays_s, s);
    let null_vector_residual = (&m * &x).norm() / (m.norm() * x.norm()).max(f64::MIN_POSITIVE);
    RefinedRoot {
        root: s.into(),
        residual: relative_residual(l, delays_s, s),
        null_vector_residual,
        newton_steps: steps,
        converged,
        multiplicity: 1,
    }
}

/// `σ_min(M(s)) / σ_max(M(s))`.
fn relative_residual(l: &DMatrix<f64>, delays_s: &[f64], s: Complex64) -> f64 {
    let sv = char_matrix_from_laplacian(l, delays_s, s).singular_values();
    let max = sv.max();
    if max > 0.0 {
        sv.min() / max
    } else {
        0.0
    }
}

/// Number of zeros of `det M(s)` (gains scaled by `c`) inside the circle `|z − s| = r`, by the
/// trapezoid rule on 8 points for `(1/2πi)∮ g(z) dz = mean_k (z_k − s) g(z_k)`; `None` if a
/// point hits a root or the mean is not close to a whole number. `recent`: the pivots of the
/// Newton iteration the circle belongs to.
pub(crate) fn zeros_in_circle(
    band: &NetworkMatrix,
    c: f64,
    s: Complex64,
    r: f64,
    recent: &mut RecentPivots,
) -> Option<usize> {
    const K: usize = 8;
    let mut sum = Complex64::new(0.0, 0.0);
    for k in 0..K {
        let dz = Complex64::from_polar(r, (k as f64 + 0.5) * std::f64::consts::TAU / K as f64);
        sum += dz
            * band
                .factor_near(c, s + dz, Some(recent))
                .log_det_derivative()?;
    }
    let mean = sum / K as f64;
    let count = mean.re.round();
    ((mean - count).norm() < 0.05 && count >= 0.0).then_some(count as usize)
}

/// The start of inverse iteration: a fixed vector with no special direction.
fn inverse_iteration_start(n: usize) -> Vec<Complex64> {
    (0..n)
        .map(|i| Complex64::new(1.0, 0.1 * i as f64))
        .collect()
}

/// `steps` inverse iterations `x ← M⁻¹x/|M⁻¹x|` with the factors `lu` (positions in the
/// network's order): `x` tends to the null vector of the root nearest the factored point.
/// `false`, with `x` as the last iteration left it, when a solve fails or is not finite.
fn inverse_iterations(lu: &NetworkLu, x: &mut [Complex64], steps: usize) -> bool {
    for _ in 0..steps {
        if !lu.solve(x) {
            return false;
        }
        let norm = x.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 0.0) {
            return false;
        }
        x.iter_mut().for_each(|z| *z /= norm);
    }
    true
}

/// A point in the basin of Newton on `det M` of the root nearest `s0`, or `None`. That Newton
/// step is `1/Σ_r 1/(s − r)` over every root `r`: where hundreds of roots lie near the axis
/// (random digraphs with several arcs per driver), the roots other than the nearest pull it
/// off course from more than about 10⁻³ away, less than a collocation eigenvalue's error there
/// (on a random digraph of 400 with eight arcs per driver, a third of the candidates wandered
/// 65 steps to a root 0.13 away). Three inverse iterations at `s0` pick out the null vector `x`
/// of the nearest root; one Newton step on `M(s)x = 0, xᴴx = 1` along it (Ruhe's nonlinear
/// inverse iteration), `s0 − 1/(xᴴ M(s0)⁻¹ M'(s0) x)`, involves that root alone. A step longer
/// than 5 % of `1 + |s0|` is not taken.
fn nearest_root_estimate(
    band: &NetworkMatrix,
    s0: Complex64,
    recent: &mut RecentPivots,
) -> Option<Complex64> {
    let lu = band.factor_near(1.0, s0, Some(recent));
    let mut x = inverse_iteration_start(band.len());
    if !inverse_iterations(&lu, &mut x, 3) {
        return None;
    }
    let mut u = band.derivative_times(1.0, s0, &x);
    if !lu.solve(&mut u) {
        return None;
    }
    let xu: Complex64 = x.iter().zip(&u).map(|(a, b)| a.conj() * b).sum();
    let s = s0 - 1.0 / xu;
    (s.re.is_finite() && s.im.is_finite() && (s - s0).norm() <= 0.05 * (1.0 + s0.norm()))
        .then_some(s)
}

/// Newton on `det M(s) = 0` with the band LU: `s − m/g(s)`, the multiplicity `m` estimated on a
/// circle around the iterate (after three steps, and every ten while it has not converged).
/// Returns the root, its multiplicity, the steps, and whether the tolerance was met.
pub(super) fn newton_on_band(
    band: &NetworkMatrix,
    s0: Complex64,
    options: &CollocationOptions,
) -> Option<(Complex64, usize, usize, bool)> {
    let mut m = 1usize;
    let mut step_norm = f64::INFINITY;
    let max_steps = options.max_newton_steps.max(20) * 2;
    // The iterates and the circles around them factor with the pivots of the last fresh
    // factorization among them.
    let mut recent = RecentPivots::default();
    // The step along the null vector counts as one of Newton's.
    let (mut s, mut steps) = match nearest_root_estimate(band, s0, &mut recent) {
        Some(s) => (s, 1),
        None => (s0, 0),
    };
    while steps < max_steps {
        steps += 1;
        let Some(g) = band
            .factor_near(1.0, s, Some(&mut recent))
            .log_det_derivative()
        else {
            step_norm = 0.0; // s is a root to working precision
            break;
        };
        let step = m as f64 / g;
        if !(step.re.is_finite() && step.im.is_finite()) {
            return None;
        }
        s -= step;
        step_norm = step.norm();
        if step_norm <= options.newton_tolerance * (1.0 + s.norm()) {
            break;
        }
        if steps == 3 || steps % 10 == 0 {
            let r = (20.0 * step_norm).max(1e-9 * (1.0 + s.norm()));
            if let Some(k) = zeros_in_circle(band, 1.0, s, r, &mut recent) {
                m = k.max(1);
            }
        }
    }
    let converged = step_norm <= options.newton_tolerance * (1.0 + s.norm());
    if step_norm > 1e-10 * (1.0 + s.norm()) {
        return None;
    }
    let multiplicity = zeros_in_circle(band, 1.0, s, 1e-6 * (1.0 + s.norm()), &mut recent)
        .unwrap_or(m)
        .max(1);
    Some((s, multiplicity, steps, converged))
}

/// The certificate fields of a root found on the band path: `σ_min/σ_max` of `M(s)` and the
/// residual of the null vector from two steps of inverse iteration.
pub(super) fn root_residuals(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    band: &NetworkMatrix,
    s: Complex64,
) -> (f64, f64) {
    let n = l.nrows();
    let m = char_matrix_from_laplacian(l, delays_s, s);
    let lu = band.factor(1.0, s);
    let perm = band.permutation();
    let mut x = inverse_iteration_start(n);
    let mut null_vector_residual = 0.0;
    inverse_iterations(&lu, &mut x, 2);
    let mut xv = DVector::zeros(n);
    for (p, &v) in perm.iter().enumerate() {
        xv[v] = x[p];
    }
    if xv.norm() > 0.0 {
        null_vector_residual = (&m * &xv).norm() / (m.norm() * xv.norm()).max(f64::MIN_POSITIVE);
    }
    (relative_residual(l, delays_s, s), null_vector_residual)
}

/// Multiplicity of each refined root as a zero of `det M(s)`: the larger of the number of
/// collocation eigenvalues in a small cluster around it (algebraic multiplicity, which the
/// collocation reproduces) and the dimension of the numerical null space of `M(s)`
/// (geometric multiplicity). The cluster radius stays below half the distance to any other
/// refined root.
pub(super) fn assign_multiplicities(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    eigenvalues: &[Complex64],
    roots: &mut [RefinedRoot],
) {
    let centres: Vec<Complex64> = roots.iter().map(|r| Complex64::from(r.root)).collect();
    for (k, r) in roots.iter_mut().enumerate() {
        let s = centres[k];
        let mut radius = 1e-4 * (1.0 + s.norm());
        for (j, &z) in centres.iter().enumerate() {
            if j != k {
                radius = radius
                    .min(0.5 * (z - s).norm())
                    .min(0.5 * (z.conj() - s).norm());
            }
        }
        if s.im != 0.0 {
            radius = radius.min(s.im.abs());
        }
        let cluster = eigenvalues
            .iter()
            .filter(|&&z| (z - s).norm() < radius)
            .count();
        let sv = char_matrix_from_laplacian(l, delays_s, s).singular_values();
        let max = sv.max();
        let null = sv.iter().filter(|&&x| x <= 1e-8 * max).count();
        r.multiplicity = cluster.max(null).max(1);
    }
}

#[cfg(test)]
mod repeated_roots {
    use super::super::super::lambert_w::lambert_w;
    use super::super::{rightmost_roots, CollocationOptions};
    use approx::assert_relative_eq;
    use nalgebra::DMatrix;
    use num_complex::Complex64;

    /// All-to-all coupling with gain `k`: `L = kN I − k 11ᵀ`, eigenvalues 0 and `Nk`
    /// (multiplicity `N − 1`).
    fn all_to_all(n: usize, k: f64) -> DMatrix<f64> {
        DMatrix::from_fn(n, n, |i, j| if i == j { 0.0 } else { k })
    }

    #[test]
    fn all_to_all_uniform_delay_roots_are_the_lambert_w_roots_with_multiplicity() {
        // det(sI + e^{−sα}L) = s · (s + Nk e^{−sα})^{N−1}: the non-consensus roots are
        // W_b(−Nkα)/α, each of multiplicity N − 1.
        for &n in &[3usize, 4, 5, 10] {
            for &k in &[0.1, 0.3] {
                let alpha = 0.5;
                let a = all_to_all(n, k);
                let r = rightmost_roots(&a, &vec![alpha; n], &CollocationOptions::default())
                    .unwrap_or_else(|e| panic!("N={n} k={k}: {e}"));
                let w0 =
                    lambert_w(0, Complex64::new(-(n as f64) * k * alpha, 0.0)).unwrap() / alpha;
                assert_relative_eq!(r.abscissa, w0.re, epsilon = 1e-10);
                assert_relative_eq!(r.roots[0].root.im, w0.im.abs(), epsilon = 1e-10);
                assert_eq!(r.roots[0].multiplicity, n - 1, "N={n} k={k}");
            }
        }
    }

    #[test]
    fn one_slower_driver_in_an_all_to_all_five_keeps_a_triple_root() {
        // Delays (0.5, 0.5, 0.5, 0.5, 0.6), gain 0.1: on {x : x_5 = 0, Σx = 0} (dimension 3)
        // L acts as 5k, so s + 5k e^{−0.5 s} = 0 gives a root of multiplicity 3. On the
        // symmetric vectors (a, a, a, a, b) the 2×2 reduction L_red = k[[1, −1], [−4, 4]]
        // gives s = −k(e^{−0.5 s} + 4 e^{−0.6 s}) (besides consensus).
        let k = 0.1;
        let a = all_to_all(5, k);
        let delays = [0.5, 0.5, 0.5, 0.5, 0.6];
        let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
        let triple = lambert_w(0, Complex64::new(-5.0 * k * 0.5, 0.0)).unwrap() / 0.5;
        // Scalar Newton on the reduced equation from the real axis.
        let f = |s: f64| s + k * ((-0.5 * s).exp() + 4.0 * (-0.6 * s).exp());
        let df = |s: f64| 1.0 - k * (0.5 * (-0.5 * s).exp() + 2.4 * (-0.6 * s).exp());
        let mut s = -0.5;
        for _ in 0..50 {
            s -= f(s) / df(s);
        }
        let found = |z: Complex64| {
            r.roots
                .iter()
                .find(|q| (Complex64::from(q.root) - z).norm() < 1e-9)
                .map(|q| q.multiplicity)
        };
        assert_eq!(found(triple), Some(3), "{:?}", r.roots);
        assert_eq!(found(Complex64::new(s, 0.0)), Some(1), "{:?}", r.roots);
        assert_relative_eq!(r.abscissa, triple.re.max(s), epsilon = 1e-10);
    }
}

#[cfg(test)]
mod nearest_root {
    use super::super::tests::{denser_random_digraph, Lcg};
    use super::super::{laplacian, rightmost_roots_shift_invert, CollocationOptions};
    use super::*;

    /// Newton on `det M` alone from `s` (40 steps), as the refinement started before.
    fn det_newton(band: &NetworkMatrix, mut s: Complex64) -> Option<Complex64> {
        let mut recent = RecentPivots::default();
        for _ in 0..40 {
            let g = band
                .factor_near(1.0, s, Some(&mut recent))
                .log_det_derivative()?;
            let step = 1.0 / g;
            s -= step;
            if step.norm() <= 1e-14 * (1.0 + s.norm()) {
                return Some(s);
            }
        }
        None
    }

    #[test]
    fn candidates_a_hundredth_from_a_root_among_dense_roots_reach_it() {
        // A random digraph of 150 drivers with eight random arcs each: its roots lie so close
        // together that Newton on det M alone reaches a root from 10⁻² away only from some
        // directions (three to six of eight for each of the four rightmost roots). The
        // refinement, which first steps along the root's null vector, reaches it from all.
        let (a, delays) = denser_random_digraph(150, 8, &mut Lcg(8), (0.3, 0.5));
        let options = CollocationOptions::default();
        let roots = rightmost_roots_shift_invert(&a, &delays, &options).unwrap();
        let l = laplacian(&a);
        let band = NetworkMatrix::new(&l, &delays);
        let mut missed_alone = 0;
        for r in roots.roots.iter().take(4) {
            let root: Complex64 = r.root.into();
            // A root by a dense SVD of M(s), which shares nothing with the sparse LU.
            assert!(relative_residual(&l, &delays, root) <= 1e-12, "{root}");
            for k in 0..8 {
                let s0 = root + Complex64::from_polar(1e-2, k as f64 * std::f64::consts::TAU / 8.0);
                let (s, multiplicity, _, converged) =
                    newton_on_band(&band, s0, &options).expect("the refinement converges");
                assert!(converged && multiplicity == 1);
                assert!((s - root).norm() <= 1e-10, "from {s0}: {s} against {root}");
                if det_newton(&band, s0).is_none_or(|s| (s - root).norm() > 1e-9) {
                    missed_alone += 1;
                }
            }
        }
        assert!(
            missed_alone >= 8,
            "Newton on det M alone missed only {missed_alone} of 32"
        );
    }
}
