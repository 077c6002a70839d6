//! The left null vector of a graph Laplacian as the stationary distribution of a Markov chain,
//! by Grassmann–Taksar–Heyman elimination on the sparse rows (see
//! [`Graph::left_null_vector`]).

use super::Graph;

/// A censored state of the GTH elimination: its index, its in-rates from the states left at
/// that time, and the sum of its out-rates to them.
type Censored = (usize, Vec<(usize, f64)>, f64);

/// GTH elimination for [`Graph::left_null_vector`] on a strongly connected graph.
pub(super) fn stationary_distribution(g: &Graph) -> Vec<f64> {
    use std::cmp::Reverse;
    use std::collections::{BTreeMap, BinaryHeap};
    let n = g.n;
    if n == 1 {
        return vec![1.0];
    }
    // out_[i][j] = rate i → j = a_ij; in_[j][i] mirrors it.
    let mut out_: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); n];
    let mut in_: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); n];
    for i in 0..n {
        for (j, w) in g.row(i) {
            *out_[i].entry(j).or_insert(0.0) += w;
            *in_[j].entry(i).or_insert(0.0) += w;
        }
    }
    let degree = |k: usize, out_: &[BTreeMap<usize, f64>], in_: &[BTreeMap<usize, f64>]| {
        out_[k].len() * in_[k].len()
    };
    let mut heap: BinaryHeap<Reverse<(usize, usize)>> = (0..n)
        .map(|k| Reverse((degree(k, &out_, &in_), k)))
        .collect();
    let mut eliminated = vec![false; n];
    let mut order: Vec<Censored> = Vec::with_capacity(n - 1);
    while order.len() < n - 1 {
        let Some(Reverse((d, k))) = heap.pop() else {
            break;
        };
        if eliminated[k] || d != degree(k, &out_, &in_) {
            continue; // stale entry
        }
        eliminated[k] = true;
        let outs: Vec<(usize, f64)> = std::mem::take(&mut out_[k]).into_iter().collect();
        let ins: Vec<(usize, f64)> = std::mem::take(&mut in_[k]).into_iter().collect();
        for &(j, _) in &outs {
            in_[j].remove(&k);
        }
        for &(i, _) in &ins {
            out_[i].remove(&k);
        }
        let s: f64 = outs.iter().map(|x| x.1).sum();
        // Censoring k: the detour i → k → j becomes a direct rate q_ik q_kj / s.
        for &(i, q_ik) in &ins {
            for &(j, q_kj) in &outs {
                if i != j {
                    let r = q_ik * q_kj / s;
                    *out_[i].entry(j).or_insert(0.0) += r;
                    *in_[j].entry(i).or_insert(0.0) += r;
                }
            }
        }
        let touched: Vec<usize> = ins.iter().chain(&outs).map(|x| x.0).collect();
        for v in touched {
            heap.push(Reverse((degree(v, &out_, &in_), v)));
        }
        order.push((k, ins, s));
    }
    let last = (0..n)
        .find(|&k| !eliminated[k])
        .expect("one state is left after censoring n − 1");
    let mut p = vec![0.0; n];
    p[last] = 1.0;
    for (k, ins, s) in order.iter().rev() {
        p[*k] = ins.iter().map(|&(i, q)| p[i] * q).sum::<f64>() / s;
    }
    let total: f64 = p.iter().sum();
    p.iter_mut().for_each(|x| *x /= total);
    p
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use approx::assert_relative_eq;

    #[test]
    fn left_null_vector_of_large_graphs_matches_closed_forms() {
        // One-way ring, N = 5000: p_i ∝ 1/k_i (p_j k_j = p_{j+1} k_{j+1} along the ring).
        let n = 5000;
        let k: Vec<f64> = (0..n)
            .map(|i| 0.3 + 0.7 * ((i * 37) % 101) as f64 / 100.0)
            .collect();
        let g = Graph::unidirectional_ring(n, &k).unwrap();
        let p = g.left_null_vector().unwrap().unwrap();
        let z: f64 = k.iter().map(|x| 1.0 / x).sum();
        for i in 0..n {
            assert_relative_eq!(p[i], 1.0 / k[i] / z, max_relative = 1e-12);
        }
        // Two-way path (a tree, strongly connected): detailed balance p_i a_{i,i+1} =
        // p_{i+1} a_{i+1,i}, so p_{i+1}/p_i = a_{i,i+1}/a_{i+1,i}.
        let n = 3000;
        let mut arcs = Vec::new();
        for i in 0..n - 1 {
            let back = 0.5 + 0.5 * ((i * 13) % 17) as f64 / 16.0; // a_{i,i+1}: i sees i+1
            let fwd = 0.5 + 0.5 * ((i * 7) % 11) as f64 / 10.0; // a_{i+1,i}
            arcs.push(Arc {
                from: i + 1,
                to: i,
                weight: back,
            });
            arcs.push(Arc {
                from: i,
                to: i + 1,
                weight: fwd,
            });
        }
        let g = Graph::from_arcs(n, &arcs).unwrap();
        let p = g.left_null_vector().unwrap().unwrap();
        let mut q = vec![1.0f64; n];
        for i in 0..n - 1 {
            q[i + 1] = q[i] * g_weight(&g, i, i + 1) / g_weight(&g, i + 1, i);
        }
        let z: f64 = q.iter().sum();
        for i in 0..n {
            assert_relative_eq!(p[i], q[i] / z, max_relative = 1e-12);
        }
    }

    /// `a_ij` of a graph.
    fn g_weight(g: &Graph, i: usize, j: usize) -> f64 {
        g.row(i).find(|&(c, _)| c == j).map_or(0.0, |(_, w)| w)
    }

    #[test]
    fn left_null_vector_of_a_large_irregular_graph_has_a_tiny_residual() {
        // Bidirectional ring of 2000 with heterogeneous gains and random chords: no closed
        // form, so check pᵀL = 0 (relative to Σ_j p_j d_j) and Σp = 1, p > 0 directly.
        let n = 2000;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut arcs = Vec::new();
        for i in 0..n {
            arcs.push(Arc {
                from: (i + n - 1) % n,
                to: i,
                weight: 0.3 + next(),
            });
            arcs.push(Arc {
                from: (i + 1) % n,
                to: i,
                weight: 0.1 + 0.3 * next(),
            });
            if next() < 0.05 {
                let j = (next() * n as f64) as usize % n;
                if j != i {
                    arcs.push(Arc {
                        from: j,
                        to: i,
                        weight: next(),
                    });
                }
            }
        }
        let g = Graph::from_arcs(n, &arcs).unwrap();
        let p = g.left_null_vector().unwrap().unwrap();
        assert!(p.iter().all(|&x| x > 0.0));
        assert_relative_eq!(p.iter().sum::<f64>(), 1.0, epsilon = 1e-13);
        // (pᵀL)_j = p_j d_j − Σ_i p_i a_ij, from the sparse rows.
        let d = g.in_degrees();
        let mut r: Vec<f64> = (0..n).map(|j| p[j] * d[j]).collect();
        for i in 0..n {
            for (j, w) in g.row(i) {
                r[j] -= p[i] * w;
            }
        }
        let scale: f64 = (0..n).map(|j| p[j] * d[j]).sum();
        let residual = r.iter().map(|x| x.abs()).sum::<f64>() / scale;
        assert!(residual < 1e-12, "‖pᵀL‖₁ / Σ p_j d_j = {residual:e}");
    }
}
