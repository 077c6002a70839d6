//! Step 1 of the method: collocation of the infinitesimal generator on Chebyshev points (see
//! the parent module) and the eigenvalues of the resulting real matrix.

use nalgebra::DMatrix;
use num_complex::Complex64;

use super::CollocationError;
use crate::exact::schur_eigenvalues::schur_eigenvalues;

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
        if let Some(eigenvalues) = schur_eigenvalues(a.clone(), eps, max_iter) {
            return Ok(eigenvalues);
        }
    }
    Err(CollocationError::EigenvaluesFailed { order })
}

#[cfg(test)]
mod tests {
    use super::super::network::laplacian;
    use super::super::tests::{random_network, Lcg};
    use super::*;
    use nalgebra::linalg::Schur;

    /// [`eigenvalues`] by nalgebra's full Schur form, through the same ladder of tolerances.
    fn by_full_schur(a: &DMatrix<f64>) -> Option<Vec<Complex64>> {
        let max_iter = 30 * a.nrows().max(10);
        [f64::EPSILON, 1e-14, 1e-13, 1e-12, 1e-11]
            .iter()
            .find_map(|&eps| {
                Schur::try_new(a.clone(), eps, max_iter)
                    .map(|s| s.complex_eigenvalues().iter().copied().collect())
            })
    }

    #[test]
    fn collocated_generators_have_the_full_schur_forms_eigenvalues_bit_for_bit() {
        // Random networks with mixed delays, and all-to-all graphs with equal delays, whose
        // N − 1 repeated roots can stall the iteration at the tightest tolerance (the ladder
        // of looser ones is then taken, and has to be taken alike).
        let mut rng = Lcg(0x5eed);
        let mut cases: Vec<(DMatrix<f64>, Vec<f64>)> = [4, 7, 12]
            .iter()
            .map(|&n| random_network(n, &mut rng))
            .collect();
        for n in [3, 4, 5, 10] {
            for k in [0.1, 0.3] {
                let a = DMatrix::from_fn(n, n, |i, j| if i == j { 0.0 } else { k });
                cases.push((a, vec![0.5; n]));
            }
        }
        let bits = |v: &Option<Vec<Complex64>>| {
            v.as_ref().map(|v| {
                v.iter()
                    .map(|z| (z.re.to_bits(), z.im.to_bits()))
                    .collect::<Vec<_>>()
            })
        };
        let mut loosened = 0;
        for (a, delays) in &cases {
            let l = laplacian(a);
            let g = generator_matrix(&l, delays, default_nodes(&l, delays));
            let ours = eigenvalues(g.clone()).ok();
            assert!(ours.is_some(), "order {}: no eigenvalues", g.nrows());
            assert_eq!(bits(&ours), bits(&by_full_schur(&g)), "order {}", g.nrows());
            let tightest = Schur::try_new(g.clone(), f64::EPSILON, 30 * g.nrows().max(10));
            loosened += usize::from(tightest.is_none());
        }
        assert!(loosened > 0, "no case needed a looser tolerance");
    }
}
