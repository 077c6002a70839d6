//! Weighted directed interaction graphs `G[A]` (paper, Section 2.1).
//!
//! Row `i` of the adjacency matrix `A = (a_ij)` lists the vehicles whose speed driver `i`
//! reacts to: `a_ij > 0` means "`i` sees `j`" (an arc `j → i`). The graph is stored sparsely
//! (compressed rows) so that rings of 20 000 vehicles cost kilobytes, not gigabytes.

use nalgebra::DMatrix;

mod stationary;
use serde::Serialize;
use stationary::stationary_distribution;

/// Errors raised while building a [`Graph`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraphError {
    /// The graph has no vertices.
    #[error("the graph must have at least one vehicle, got 0")]
    Empty,
    /// An arc points to a vehicle index outside `0..n`.
    #[error("arc {from} -> {to}: vehicle index out of range (valid indices are 0..{n})")]
    UnknownVehicle {
        /// Tail of the arc.
        from: usize,
        /// Head of the arc.
        to: usize,
        /// Number of vehicles.
        n: usize,
    },
    /// `a_ii ≠ 0`: the paper's graphs have no self-loops.
    #[error(
        "arc {vehicle} -> {vehicle} is a self-loop; the interaction graph has none (a_ii = 0)"
    )]
    SelfLoop {
        /// The vehicle.
        vehicle: usize,
    },
    /// A weight that is negative, zero or not finite.
    #[error("arc {from} -> {to} has weight {weight}; weights must be finite and > 0")]
    BadWeight {
        /// Tail of the arc.
        from: usize,
        /// Head of the arc.
        to: usize,
        /// The offending weight.
        weight: f64,
    },
    /// A dense computation was requested on a graph too large for it.
    #[error("graph has {n} vehicles; this dense computation is limited to {limit}")]
    TooLargeForDense {
        /// Number of vehicles.
        n: usize,
        /// The limit.
        limit: usize,
    },
}

/// One arc of the interaction graph: driver `to` reacts to the speed of vehicle `from` with
/// gain `weight = a_{to,from}`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Arc {
    /// The observed vehicle `j`.
    pub from: usize,
    /// The reacting driver `i`.
    pub to: usize,
    /// The gain `a_ij` [1/s].
    pub weight: f64,
}

/// A weighted directed graph without self-loops, stored as compressed rows of `A`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Graph {
    n: usize,
    /// `row_start[i]..row_start[i+1]` indexes the in-neighbours of `i` in `cols`/`weights`.
    row_start: Vec<usize>,
    cols: Vec<usize>,
    weights: Vec<f64>,
}

impl Graph {
    /// The graph of no vehicles: the model of a scenario without vehicles of its own (only an
    /// inflow's, which come and go), which no analysis takes.
    pub(crate) fn empty() -> Self {
        Self {
            n: 0,
            row_start: vec![0],
            cols: Vec::new(),
            weights: Vec::new(),
        }
    }

    /// Builds a graph on `n` vertices from arcs. Parallel arcs are summed.
    pub fn from_arcs(n: usize, arcs: &[Arc]) -> Result<Self, GraphError> {
        if n == 0 {
            return Err(GraphError::Empty);
        }
        for a in arcs {
            if a.from >= n || a.to >= n {
                return Err(GraphError::UnknownVehicle {
                    from: a.from,
                    to: a.to,
                    n,
                });
            }
            if a.from == a.to {
                return Err(GraphError::SelfLoop { vehicle: a.from });
            }
            if !(a.weight.is_finite() && a.weight > 0.0) {
                return Err(GraphError::BadWeight {
                    from: a.from,
                    to: a.to,
                    weight: a.weight,
                });
            }
        }
        let mut sorted: Vec<Arc> = arcs.to_vec();
        sorted.sort_by_key(|a| (a.to, a.from));
        let mut row_start = vec![0usize; n + 1];
        let mut cols = Vec::with_capacity(sorted.len());
        let mut weights: Vec<f64> = Vec::with_capacity(sorted.len());
        let mut last: Option<(usize, usize)> = None;
        for a in &sorted {
            if last == Some((a.to, a.from)) {
                *weights.last_mut().expect("a previous arc exists") += a.weight;
                continue;
            }
            last = Some((a.to, a.from));
            cols.push(a.from);
            weights.push(a.weight);
            row_start[a.to + 1] += 1;
        }
        for i in 0..n {
            row_start[i + 1] += row_start[i];
        }
        Ok(Self {
            n,
            row_start,
            cols,
            weights,
        })
    }

    /// Builds a graph from a dense adjacency matrix (zero entries are "no arc").
    pub fn from_dense(a: &DMatrix<f64>) -> Result<Self, GraphError> {
        let n = a.nrows();
        let mut arcs = Vec::new();
        for i in 0..n {
            for j in 0..a.ncols() {
                let w = a[(i, j)];
                if w != 0.0 {
                    arcs.push(Arc {
                        from: j,
                        to: i,
                        weight: w,
                    });
                }
            }
        }
        Self::from_arcs(n, &arcs)
    }

    /// Unidirectional ring: driver `i` follows its predecessor `i−1` (vehicle 0 follows
    /// `n−1`) with gain `k` — the circular road of eq. `chandler`.
    pub fn unidirectional_ring(n: usize, k: &[f64]) -> Result<Self, GraphError> {
        let arcs: Vec<Arc> = (0..n)
            .filter(|_| n > 1)
            .map(|i| Arc {
                from: (i + n - 1) % n,
                to: i,
                weight: k[i],
            })
            .collect();
        Self::from_arcs(n, &arcs)
    }

    /// Bidirectional ring: driver `i` reacts to its predecessor with gain `k_pred[i]` and to
    /// its follower with gain `k_follow[i]`.
    pub fn bidirectional_ring(
        n: usize,
        k_pred: &[f64],
        k_follow: &[f64],
    ) -> Result<Self, GraphError> {
        let mut arcs = Vec::with_capacity(2 * n);
        if n > 1 {
            for i in 0..n {
                arcs.push(Arc {
                    from: (i + n - 1) % n,
                    to: i,
                    weight: k_pred[i],
                });
                arcs.push(Arc {
                    from: (i + 1) % n,
                    to: i,
                    weight: k_follow[i],
                });
            }
        }
        Self::from_arcs(n, &arcs)
    }

    /// Chain: driver `i ≥ 1` follows `i−1` with gain `k[i]`; vehicle 0 is the head and sees nobody.
    pub fn chain(n: usize, k: &[f64]) -> Result<Self, GraphError> {
        let arcs: Vec<Arc> = (1..n)
            .map(|i| Arc {
                from: i - 1,
                to: i,
                weight: k[i],
            })
            .collect();
        Self::from_arcs(n, &arcs)
    }

    /// All-to-all coupling with gain `k[i]` on every other vehicle.
    pub fn all_to_all(n: usize, k: &[f64]) -> Result<Self, GraphError> {
        let mut arcs = Vec::with_capacity(n * n.saturating_sub(1));
        for i in 0..n {
            for j in 0..n {
                if i != j {
                    arcs.push(Arc {
                        from: j,
                        to: i,
                        weight: k[i],
                    });
                }
            }
        }
        Self::from_arcs(n, &arcs)
    }

    /// Number of vehicles `N`.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false: a graph has at least one vertex.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Number of arcs.
    pub fn arc_count(&self) -> usize {
        self.cols.len()
    }

    /// In-neighbours of driver `i` with their gains: the `(j, a_ij)` with `a_ij > 0`.
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let r = self.row_start[i]..self.row_start[i + 1];
        self.cols[r.clone()]
            .iter()
            .copied()
            .zip(self.weights[r].iter().copied())
    }

    /// Raw compressed-row arrays `(row_start, cols, weights)` for tight loops.
    pub fn csr(&self) -> (&[usize], &[usize], &[f64]) {
        (&self.row_start, &self.cols, &self.weights)
    }

    /// All arcs.
    pub fn arcs(&self) -> Vec<Arc> {
        (0..self.n)
            .flat_map(|i| {
                self.row(i).map(move |(j, w)| Arc {
                    from: j,
                    to: i,
                    weight: w,
                })
            })
            .collect()
    }

    /// Weighted in-degree `d_i^+ = Σ_j a_ij` (paper, Section 2.1): the total gain of driver `i`.
    pub fn in_degree(&self, i: usize) -> f64 {
        self.row(i).map(|(_, w)| w).sum()
    }

    /// All weighted in-degrees `d^+`.
    pub fn in_degrees(&self) -> Vec<f64> {
        (0..self.n).map(|i| self.in_degree(i)).collect()
    }

    /// Weighted out-degrees `d_j^- = Σ_k a_kj`.
    pub fn out_degrees(&self) -> Vec<f64> {
        let mut d = vec![0.0; self.n];
        for i in 0..self.n {
            for (j, w) in self.row(i) {
                d[j] += w;
            }
        }
        d
    }

    /// The same graph with every gain multiplied by `c`.
    pub fn scaled(&self, c: f64) -> Self {
        let mut g = self.clone();
        g.weights.iter_mut().for_each(|w| *w *= c);
        g
    }

    /// Vertices reachable from `start` along arcs (information flow `j → i`).
    fn reachable(&self, start: usize, forward: bool) -> Vec<bool> {
        // Out-adjacency (who sees j) is needed for forward reachability.
        let mut out: Vec<Vec<usize>> = vec![Vec::new(); self.n];
        let mut inn: Vec<Vec<usize>> = vec![Vec::new(); self.n];
        for i in 0..self.n {
            for (j, _) in self.row(i) {
                out[j].push(i);
                inn[i].push(j);
            }
        }
        let adj = if forward { &out } else { &inn };
        let mut seen = vec![false; self.n];
        let mut stack = vec![start];
        seen[start] = true;
        while let Some(v) = stack.pop() {
            for &w in &adj[v] {
                if !seen[w] {
                    seen[w] = true;
                    stack.push(w);
                }
            }
        }
        seen
    }

    /// Strong connectivity: a walk exists between any two vertices (Theorem `thm.1` needs it).
    pub fn is_strongly_connected(&self) -> bool {
        self.reachable(0, true).iter().all(|&b| b) && self.reachable(0, false).iter().all(|&b| b)
    }

    /// A root of a directed spanning tree, if the graph is quasi-strongly connected: a vertex
    /// from which every other vertex is reached along arcs.
    pub fn spanning_tree_root(&self) -> Option<usize> {
        let candidate = self.source_candidate();
        self.reachable(candidate, true)
            .iter()
            .all(|&b| b)
            .then_some(candidate)
    }

    /// `None` when the graph has a directed spanning tree; otherwise a vertex that no single
    /// vertex reaches (for error messages).
    pub fn spanning_tree_gap(&self) -> Option<usize> {
        self.reachable(self.source_candidate(), true)
            .iter()
            .position(|&b| !b)
    }

    /// The number of source strongly connected components: groups of vertices that reach
    /// each other and that no vertex outside reaches ("reaches" in the consensus
    /// literature). It is the multiplicity of the Laplacian's zero eigenvalue, algebraic and
    /// geometric alike, so the consensus root `s = 0` is simple exactly when it is 1: when the
    /// graph has a directed spanning tree.
    ///
    /// # Reference
    /// J. S. Caughman, J. J. P. Veerman, "Kernels of directed graph Laplacians", Electron. J.
    /// Combin. 13 (2006) R39.
    pub fn source_components(&self) -> usize {
        let mut assigned = vec![false; self.n];
        let mut count = 0;
        for v in 0..self.n {
            if assigned[v] {
                continue;
            }
            let from = self.reachable(v, true);
            let to = self.reachable(v, false);
            // v's component is a source when everything that reaches v is reached from v.
            if (0..self.n).all(|u| !to[u] || from[u]) {
                count += 1;
                for u in 0..self.n {
                    if from[u] && to[u] {
                        assigned[u] = true;
                    }
                }
            }
        }
        count
    }

    /// A vertex of a source strongly connected component.
    fn source_candidate(&self) -> usize {
        // Any root lies in the unique source strongly connected component; trying each vertex
        // is O(N·E), so first look for a candidate by a single sweep: the last vertex to finish
        // a DFS over the whole graph is in a source component.
        let mut visited = vec![false; self.n];
        let mut candidate = 0;
        let mut out: Vec<Vec<usize>> = vec![Vec::new(); self.n];
        for i in 0..self.n {
            for (j, _) in self.row(i) {
                out[j].push(i);
            }
        }
        for s in 0..self.n {
            if visited[s] {
                continue;
            }
            candidate = s;
            let mut stack = vec![s];
            visited[s] = true;
            while let Some(v) = stack.pop() {
                for &w in &out[v] {
                    if !visited[w] {
                        visited[w] = true;
                        stack.push(w);
                    }
                }
            }
        }
        candidate
    }

    /// Dense adjacency matrix `A` (for small graphs).
    pub fn adjacency_dense(&self) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(self.n, self.n);
        for i in 0..self.n {
            for (j, w) in self.row(i) {
                a[(i, j)] += w;
            }
        }
        a
    }

    /// Weighted Laplacian `L = D − A` with `D = diag(d^+)`, so that `u = −L v` (eq. `proto-lin`).
    pub fn laplacian_dense(&self) -> DMatrix<f64> {
        let mut l = -self.adjacency_dense();
        for i in 0..self.n {
            l[(i, i)] = self.in_degree(i);
        }
        l
    }

    /// The positive left null vector `p` of the Laplacian, `pᵀL = 0`, normalised to `Σ p_i = 1`
    /// (footnote of Lemma `lem.tech1`). Returns `None` when the graph is not strongly connected
    /// (then `p` is not positive).
    ///
    /// `p_i` is the weight of driver `i` in the storage function of Theorem `thm.1`'s proof; for
    /// delay-free integrators it is the share of driver `i`'s initial speed in the consensus speed.
    ///
    /// `pᵀL = 0` reads `p_j d_j^+ = Σ_i p_i a_ij`: `p` is the stationary distribution of the
    /// continuous-time Markov chain with rates `a_ij` from `i` to `j`. It is computed by the
    /// Grassmann–Taksar–Heyman elimination on the sparse rows: states are censored one by one
    /// (fewest neighbours first, so a ring stays a ring and costs O(N)), and every operation
    /// adds or divides positive numbers, so each `p_i` is accurate to a few ulps relative to
    /// itself. The error type is kept for callers; the sparse solve has no size limit.
    ///
    /// # Reference
    /// W. K. Grassmann, M. I. Taksar, D. P. Heyman, "Regenerative analysis and steady state
    /// distributions for Markov chains", Oper. Res. 33 (1985) 1107–1116.
    pub fn left_null_vector(&self) -> Result<Option<Vec<f64>>, GraphError> {
        if !self.is_strongly_connected() {
            return Ok(None);
        }
        Ok(Some(stationary_distribution(self)))
    }
}

/// Summary of a graph for reports.
#[derive(Debug, Clone, Serialize)]
pub struct GraphSummary {
    /// Number of vehicles `N`.
    pub vehicles: usize,
    /// Number of arcs.
    pub arcs: usize,
    /// Strongly connected.
    pub strongly_connected: bool,
    /// Root of a directed spanning tree, if any.
    pub spanning_tree_root: Option<usize>,
}

impl From<&Graph> for GraphSummary {
    fn from(g: &Graph) -> Self {
        Self {
            vehicles: g.len(),
            arcs: g.arc_count(),
            strongly_connected: g.is_strongly_connected(),
            spanning_tree_root: g.spanning_tree_root(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn ring_degrees_and_connectivity() {
        let g = Graph::unidirectional_ring(5, &[0.3; 5]).unwrap();
        assert_eq!(g.arc_count(), 5);
        assert!(g.is_strongly_connected());
        for d in g.in_degrees() {
            assert_relative_eq!(d, 0.3);
        }
        for d in g.out_degrees() {
            assert_relative_eq!(d, 0.3);
        }
        // Laplacian rows sum to zero: L·1 = 0.
        let l = g.laplacian_dense();
        for i in 0..5 {
            assert_relative_eq!(l.row(i).sum(), 0.0, epsilon = 1e-15);
        }
    }

    #[test]
    fn chain_has_spanning_tree_rooted_at_head_but_is_not_strong() {
        let g = Graph::chain(4, &[0.0, 1.0, 1.0, 1.0]).unwrap();
        assert!(!g.is_strongly_connected());
        assert_eq!(g.spanning_tree_root(), Some(0));
        assert_eq!(g.left_null_vector().unwrap(), None);
    }

    #[test]
    fn source_components_are_the_laplacians_zero_eigenvalues() {
        use nalgebra::DMatrix;
        // Independent oracle: the number of zero singular values of L = D − A.
        let zeros = |a: &DMatrix<f64>| {
            let mut l = -a.clone();
            for i in 0..a.nrows() {
                l[(i, i)] = a.row(i).iter().sum::<f64>();
            }
            l.singular_values()
                .iter()
                .filter(|s| s.abs() < 1e-9)
                .count()
        };
        let mut cases = Vec::new();
        // A ring of 22 drivers of which only 1 and 3 see anybody (0 → 1, 2 → 3).
        let mut two_edges = DMatrix::zeros(22, 22);
        two_edges[(1, 0)] = 0.5;
        two_edges[(3, 2)] = 0.5;
        cases.push((two_edges, 20));
        // Two 2-cycles that do not see each other, and one that sees both.
        let mut cycles = DMatrix::zeros(5, 5);
        for (i, j) in [(0, 1), (1, 0), (2, 3), (3, 2), (4, 0), (4, 2)] {
            cycles[(i, j)] = 0.7;
        }
        cases.push((cycles, 2));
        // A bidirectional ring: one component.
        let mut ring = DMatrix::zeros(6, 6);
        for i in 0..6 {
            ring[(i, (i + 5) % 6)] = 0.4;
            ring[(i, (i + 1) % 6)] = 0.1;
        }
        cases.push((ring, 1));
        // A chain behind its head, and nobody seeing anybody.
        let mut chain = DMatrix::zeros(4, 4);
        for i in 1..4 {
            chain[(i, i - 1)] = 1.0;
        }
        cases.push((chain, 1));
        cases.push((DMatrix::zeros(3, 3), 3));
        for (a, want) in cases {
            let g = Graph::from_dense(&a).unwrap();
            assert_eq!(g.source_components(), want, "{a}");
            assert_eq!(zeros(&a), want, "{a}");
            assert_eq!(g.spanning_tree_gap().is_none(), want == 1, "{a}");
        }
    }

    #[test]
    fn two_disconnected_parts_have_no_spanning_tree() {
        let g = Graph::from_arcs(
            4,
            &[
                Arc {
                    from: 0,
                    to: 1,
                    weight: 1.0,
                },
                Arc {
                    from: 2,
                    to: 3,
                    weight: 1.0,
                },
            ],
        )
        .unwrap();
        assert_eq!(g.spanning_tree_root(), None);
    }

    #[test]
    fn left_null_vector_of_a_heterogeneous_ring_is_inverse_gain() {
        // For a unidirectional ring with gains k_i, pᵀL = 0 gives p_i k_i = p_{i+1} k_{i+1}... so
        // p_i ∝ 1/k_i (closed form).
        let k = [0.5, 1.0, 2.0, 4.0];
        let g = Graph::unidirectional_ring(4, &k).unwrap();
        let p = g.left_null_vector().unwrap().unwrap();
        let z: f64 = k.iter().map(|x| 1.0 / x).sum();
        for i in 0..4 {
            assert_relative_eq!(p[i], 1.0 / k[i] / z, epsilon = 1e-12);
        }
        // pᵀ L = 0 as a direct check.
        let l = g.laplacian_dense();
        let pt = nalgebra::RowDVector::from_row_slice(&p);
        assert!((pt * l).norm() < 1e-12);
    }

    #[test]
    fn bad_arcs_are_rejected_with_clear_messages() {
        let e = Graph::from_arcs(
            3,
            &[Arc {
                from: 1,
                to: 1,
                weight: 1.0,
            }],
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "arc 1 -> 1 is a self-loop; the interaction graph has none (a_ii = 0)"
        );
        let e = Graph::from_arcs(
            3,
            &[Arc {
                from: 0,
                to: 7,
                weight: 1.0,
            }],
        )
        .unwrap_err();
        assert!(e.to_string().contains("valid indices are 0..3"), "{e}");
        let e = Graph::from_arcs(
            3,
            &[Arc {
                from: 0,
                to: 1,
                weight: -1.0,
            }],
        )
        .unwrap_err();
        assert!(e.to_string().contains("weight -1"), "{e}");
        assert_eq!(Graph::from_arcs(0, &[]).unwrap_err(), GraphError::Empty);
    }

    #[test]
    fn parallel_arcs_are_summed() {
        let g = Graph::from_arcs(
            2,
            &[
                Arc {
                    from: 0,
                    to: 1,
                    weight: 1.0,
                },
                Arc {
                    from: 0,
                    to: 1,
                    weight: 0.5,
                },
                Arc {
                    from: 1,
                    to: 0,
                    weight: 1.0,
                },
            ],
        )
        .unwrap();
        assert_eq!(g.arc_count(), 2);
        assert_relative_eq!(g.in_degree(1), 1.5);
    }
}
