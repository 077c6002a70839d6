//! Step 1 of the method: collocation of the infinitesimal generator on Chebyshev points (see
//! the parent module) and the eigenvalues of the resulting real matrix.

use nalgebra::{DMatrix, Schur};
use num_complex::Complex64;

use super::CollocationError;

/// Chebyshev points `x_k = cos(kπ/M)` and differentiation matrix (Trefethen, `cheb`).
pub(super) fn chebyshev(m: usize) -> (Vec<f64>, DMatrix<f64>) {
    let x: Vec<f64> = (0..=m)
        .map(|k| (std::f64::consts::PI * k as f64 / m as f64).cos())
        .collect();
    let c = |k: usize| {
        let w = if k == 0 || k == m { 2.0 } else { 1.0 };
        if k.is_multiple_of(2) {
            w
        } else {
            -w
        }
    };
    let mut d = DMatrix::zeros(m + 1, m + 1);
    for i in 0..=m {
        for j in 0..=m {
            if i != j {
                d[(i, j)] = c(i) / c(j) / (x[i] - x[j]);
            }
        }
    }
    for i in 0..=m {
        let row_sum: f64 = (0..=m).filter(|&j| j != i).map(|j| d[(i, j)]).sum();
        d[(i, i)] = -row_sum;
    }
    (x, d)
}

/// Default number of Chebyshev intervals from the dimensionless loop gain `max 2 d_i α_i`.
pub(super) fn default_nodes(l: &DMatrix<f64>, delays_s: &[f64]) -> usize {
    let rho = (0..l.nrows())
        .map(|i| 2.0 * l[(i, i)] * delays_s[i])
        .fold(0.0, f64::max);
    (8 + (2.0 * rho).ceil() as usize).clamp(8, 40)
}

/// Collocation matrix of the infinitesimal generator (see the module documentation).
pub(super) fn generator_matrix(l: &DMatrix<f64>, delays_s: &[f64], m: usize) -> DMatrix<f64> {
    let n = l.nrows();
    let delayed: Vec<usize> = (0..n).filter(|&i| delays_s[i] > 0.0).collect();
    let order = n + m * delayed.len();
    let (_, d) = chebyshev(m);
    let mut a = DMatrix::zeros(order, order);
    for i in 0..n {
        if delays_s[i] == 0.0 {
            for j in 0..n {
                a[(i, j)] = -l[(i, j)];
            }
        }
    }
    for (slot, &i) in delayed.iter().enumerate() {
        let base = n + slot * m; // φ_{i,k} for k = 1..=m sits at base + k − 1
        let scale = 2.0 / delays_s[i];
        a[(i, base + m - 1)] = 1.0; // λ v_i = φ_i(−α_i) = φ_{i,M}
        for k in 1..=m {
            let row = base + k - 1;
            for l_idx in 1..=m {
                a[(row, base + l_idx - 1)] = scale * d[(k, l_idx)];
            }
            // Boundary node φ_{i,0} = −(Lv)_i.
            for j in 0..n {
                a[(row, j)] = -scale * d[(k, 0)] * l[(i, j)];
            }
        }
    }
    a
}

/// Eigenvalues of a real matrix by the real Schur form.
///
/// nalgebra's Francis iteration has no exceptional shifts, and it can stagnate on clusters of
/// (exactly) repeated eigenvalues, which symmetric graphs produce: an all-to-all graph with
/// equal delays has every collocated non-consensus root `N − 1` times. When it stalls, the
/// deflation threshold is relaxed step by step (`10⁻¹⁴ … 10⁻¹¹` relative to the neighbouring
/// diagonal entries), which lets a converged cluster split off; the eigenvalues then carry an
/// error of that order, well inside Newton's basin, and Newton refines them on `M(s)`.
pub(crate) fn eigenvalues(a: DMatrix<f64>) -> Result<Vec<Complex64>, CollocationError> {
    let order = a.nrows();
    // LAPACK's iteration budget (dlahqr: 30 sweeps per eigenvalue).
    let max_iter = 30 * order.max(10);
    for eps in [f64::EPSILON, 1e-14, 1e-13, 1e-12, 1e-11] {
        if let Some(schur) = Schur::try_new(a.clone(), eps, max_iter) {
            return Ok(schur.complex_eigenvalues().iter().copied().collect());
        }
    }
    Err(CollocationError::EigenvaluesFailed { order })
}
