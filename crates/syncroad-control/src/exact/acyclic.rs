//! Exact roots of acyclic networks (predecessor following behind a leader, eq. `chandler`).
//!
//! When the interaction graph has no directed cycle, ordering the drivers topologically makes
//! the Laplacian triangular, so `det(sI + diag(e^{−sα_i}) L) = Π_i (s + d_i^+ e^{−sα_i})`: every
//! driver contributes the roots of its own scalar equation, `s = W_k(−d_i α_i)/α_i` (Lambert W,
//! principal branch rightmost), or `s = −d_i` without delay. Identical drivers give roots of
//! high multiplicity, which no eigenvalue solver resolves accurately; here they are exact.
//! Drivers with `d_i = 0` (the leader) contribute the consensus root 0.
//!
//! The critical scale of all gains follows in closed form: driver i crosses the imaginary axis
//! at `c α_i d_i = π/2` (root `i·π/(2α_i)`), so `c* = min_i π/(2 α_i d_i)`.

use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;

use super::lambert_w::lambert_w;

/// Errors of the acyclic analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AcyclicError {
    /// The graph has a directed cycle: the determinant does not factor.
    #[error("the interaction graph has a directed cycle (through driver {0}); use the full solve")]
    Cyclic(usize),
    /// Shapes disagree.
    #[error("adjacency is {rows}×{cols} but {delays} delays were given")]
    Shape {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
        /// Delays.
        delays: usize,
    },
    /// No driver reacts to anybody: every root is consensus.
    #[error("no driver has a positive total gain d_i^+: nothing to analyse")]
    NoCoupling,
}

/// Rightmost root of one driver's factor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DriverRoot {
    /// Driver index.
    pub driver: usize,
    /// Its total gain d_i^+ [1/s] (pinning included).
    pub gain: f64,
    /// Its delay α_i [s].
    pub delay_s: f64,
    /// Rightmost root of `s + d_i e^{−sα_i} = 0` [1/s] (upper half plane).
    pub re: f64,
    /// Imaginary part [rad/s].
    pub im: f64,
}

/// Exact spectrum summary of an acyclic network.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AcyclicReport {
    /// Per-driver rightmost roots (drivers with d_i > 0).
    pub drivers: Vec<DriverRoot>,
    /// Spectral abscissa over the non-consensus roots [1/s].
    pub abscissa: f64,
    /// The driver attaining it.
    pub dominant_driver: usize,
    /// Exact critical scale of all gains, `min_i π/(2 α_i d_i)` (∞ without delays).
    pub critical_gain_scale: f64,
}

/// Returns a topological order, or the index of a driver on a cycle.
fn topological_order(a: &DMatrix<f64>) -> Result<Vec<usize>, usize> {
    let n = a.nrows();
    // Arc j → i when a_ij > 0; count in-arcs of each i.
    let mut indeg: Vec<usize> = (0..n)
        .map(|i| (0..n).filter(|&j| j != i && a[(i, j)] > 0.0).count())
        .collect();
    let mut ready: Vec<usize> = (0..n).filter(|&i| indeg[i] == 0).collect();
    let mut order = Vec::with_capacity(n);
    while let Some(j) = ready.pop() {
        order.push(j);
        for i in 0..n {
            if i != j && a[(i, j)] > 0.0 {
                indeg[i] -= 1;
                if indeg[i] == 0 {
                    ready.push(i);
                }
            }
        }
    }
    if order.len() == n {
        Ok(order)
    } else {
        Err((0..n).find(|&i| indeg[i] > 0).unwrap_or(0))
    }
}

/// Exact roots of an acyclic delayed-driver network.
pub fn acyclic_roots(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
) -> Result<AcyclicReport, AcyclicError> {
    let n = adjacency.nrows();
    if adjacency.ncols() != n || delays_s.len() != n {
        return Err(AcyclicError::Shape {
            rows: n,
            cols: adjacency.ncols(),
            delays: delays_s.len(),
        });
    }
    topological_order(adjacency).map_err(AcyclicError::Cyclic)?;
    let mut drivers = Vec::new();
    for i in 0..n {
        let d: f64 = (0..n).filter(|&j| j != i).map(|j| adjacency[(i, j)]).sum();
        if d <= 0.0 {
            continue;
        }
        let a = delays_s[i];
        let root = if a == 0.0 {
            Complex64::new(-d, 0.0)
        } else {
            let w = lambert_w(0, Complex64::new(-d * a, 0.0))
                .expect("the principal branch exists for every real argument");
            w / a
        };
        drivers.push(DriverRoot {
            driver: i,
            gain: d,
            delay_s: a,
            re: root.re,
            im: root.im.abs(),
        });
    }
    let dominant = drivers
        .iter()
        .max_by(|x, y| x.re.total_cmp(&y.re))
        .copied()
        .ok_or(AcyclicError::NoCoupling)?;
    let critical = drivers
        .iter()
        .filter(|r| r.delay_s > 0.0)
        .map(|r| std::f64::consts::FRAC_PI_2 / (r.delay_s * r.gain))
        .fold(f64::INFINITY, f64::min);
    Ok(AcyclicReport {
        abscissa: dominant.re,
        dominant_driver: dominant.driver,
        drivers,
        critical_gain_scale: critical,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact::collocation::{characteristic_matrix, rightmost_roots, CollocationOptions};
    use approx::assert_relative_eq;

    fn chain(gains: &[f64]) -> DMatrix<f64> {
        // Vertex 0 is the leader; driver i follows i − 1 with gain gains[i − 1].
        let n = gains.len() + 1;
        let mut a = DMatrix::zeros(n, n);
        for i in 1..n {
            a[(i, i - 1)] = gains[i - 1];
        }
        a
    }

    #[test]
    fn distinct_drivers_agree_with_the_full_solve() {
        let a = chain(&[0.6, 0.9, 0.4, 1.2]);
        let d = [0.0, 0.8, 0.5, 1.1, 0.3];
        let ex = acyclic_roots(&a, &d).unwrap();
        let full = rightmost_roots(&a, &d, &CollocationOptions::default()).unwrap();
        assert_relative_eq!(ex.abscissa, full.abscissa, epsilon = 1e-10);
        // Each root makes the characteristic matrix singular.
        for r in &ex.drivers {
            let m = characteristic_matrix(&a, &d, Complex64::new(r.re, r.im));
            let sv = m.singular_values();
            let smin = sv.iter().copied().fold(f64::INFINITY, f64::min);
            assert!(
                smin < 1e-12 * sv.max(),
                "driver {}: σ_min = {smin}",
                r.driver
            );
        }
    }

    #[test]
    fn chandler_boundary_is_alpha_k_pi_over_two_for_identical_drivers() {
        // Twelve identical drivers: a root of multiplicity 12, exact here.
        let a = chain(&[0.6; 12]);
        let mut d = vec![0.8; 13];
        d[0] = 0.0;
        let ex = acyclic_roots(&a, &d).unwrap();
        assert_relative_eq!(
            ex.critical_gain_scale * 0.8 * 0.6,
            std::f64::consts::FRAC_PI_2,
            epsilon = 1e-15
        );
        // At the critical scale the root sits on the axis at ω = π/(2α).
        let at = acyclic_roots(&(a * ex.critical_gain_scale), &d).unwrap();
        assert!(at.abscissa.abs() < 1e-12, "{}", at.abscissa);
        assert_relative_eq!(
            at.drivers[0].im,
            std::f64::consts::PI / 1.6,
            epsilon = 1e-12
        );
    }

    #[test]
    fn cycles_are_rejected() {
        let mut a = chain(&[1.0, 1.0]);
        a[(0, 2)] = 1.0;
        assert_eq!(
            acyclic_roots(&a, &[0.1; 3]).unwrap_err(),
            AcyclicError::Cyclic(0)
        );
    }
}
