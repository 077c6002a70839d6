//! The network as plain data: checks of the adjacency matrix and delays (a directed spanning
//! tree included) and the weighted Laplacian.

use nalgebra::DMatrix;

use super::CollocationError;
use crate::graph::Graph;

/// Checks the plain-data network description and returns `N`.
pub(crate) fn validate_network(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
) -> Result<usize, CollocationError> {
    let (rows, cols) = adjacency.shape();
    if rows != cols {
        return Err(CollocationError::AdjacencyNotSquare { rows, cols });
    }
    let n = rows;
    if n < 2 {
        return Err(CollocationError::TooFewVehicles { vehicles: n });
    }
    if delays_s.len() != n {
        return Err(CollocationError::DelayCountMismatch {
            delays: delays_s.len(),
            vehicles: n,
        });
    }
    for i in 0..n {
        for j in 0..n {
            let value = adjacency[(i, j)];
            if i == j {
                if value != 0.0 {
                    return Err(CollocationError::NonZeroDiagonal { vehicle: i, value });
                }
            } else if !value.is_finite() || value < 0.0 {
                return Err(CollocationError::InvalidGain {
                    row: i,
                    col: j,
                    value,
                });
            }
        }
    }
    for (vehicle, &delay_s) in delays_s.iter().enumerate() {
        if !delay_s.is_finite() || delay_s < 0.0 {
            return Err(CollocationError::InvalidDelay { vehicle, delay_s });
        }
    }
    // Every off-diagonal weight was checked finite and ≥ 0 and the diagonal zero: the graph
    // module's checks cannot refuse it.
    let graph = Graph::from_dense(adjacency).expect("a validated adjacency matrix");
    if let Some(unreached) = graph.spanning_tree_gap() {
        return Err(CollocationError::NoSpanningTree { unreached });
    }
    Ok(n)
}

/// Weighted Laplacian `L = D − A` with `D = diag(d_i^+)`, `d_i^+ = Σ_j a_ij`.
pub(crate) fn laplacian(adjacency: &DMatrix<f64>) -> DMatrix<f64> {
    let n = adjacency.nrows();
    let mut l = -adjacency.clone();
    for i in 0..n {
        l[(i, i)] = adjacency.row(i).iter().sum::<f64>();
    }
    l
}

#[cfg(test)]
mod tests {
    use super::super::{rightmost_roots, CollocationError, CollocationOptions, RootsReport};
    use nalgebra::DMatrix;

    #[test]
    fn errors_name_field_and_value() {
        let opts = CollocationOptions::default();
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 1.0, 0.0]);
        let msg = |r: Result<RootsReport, CollocationError>| r.unwrap_err().to_string();
        assert_eq!(
            msg(rightmost_roots(&DMatrix::zeros(2, 3), &[0.1, 0.1], &opts)),
            "adjacency matrix must be square, got 2×3"
        );
        assert_eq!(
            msg(rightmost_roots(&a, &[0.1], &opts)),
            "1 delays given for 2 vehicles"
        );
        assert_eq!(
            msg(rightmost_roots(&a, &[0.1, -0.2], &opts)),
            "delay α[1] = -0.2 s must be finite and ≥ 0"
        );
        let mut bad = a.clone();
        bad[(0, 1)] = -1.0;
        assert_eq!(
            msg(rightmost_roots(&bad, &[0.1, 0.1], &opts)),
            "coupling gain a[0][1] = -1 must be finite and ≥ 0"
        );
        let mut bad = a.clone();
        bad[(1, 1)] = 2.0;
        assert_eq!(
            msg(rightmost_roots(&bad, &[0.1, 0.1], &opts)),
            "adjacency diagonal a[1][1] = 2 must be 0"
        );
        // Two vehicles both following a third one that follows nobody is fine (tree rooted
        // at 2); two separate pairs are not.
        let tree = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        assert!(rightmost_roots(&tree, &[0.1; 3], &opts).is_ok());
        let mut split = DMatrix::zeros(4, 4);
        split[(0, 1)] = 1.0;
        split[(1, 0)] = 1.0;
        split[(2, 3)] = 1.0;
        split[(3, 2)] = 1.0;
        let m = msg(rightmost_roots(&split, &[0.1; 4], &opts));
        assert!(
            m.starts_with("the interaction graph has no directed spanning tree (vehicle"),
            "{m}"
        );
    }
}
