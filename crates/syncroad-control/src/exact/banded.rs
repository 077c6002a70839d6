//! The characteristic matrix `M(s) = sI + c·diag(e^{−sα_i}) L` of eq. `chandler+` as a band
//! matrix, factored without forming an inverse.
//!
//! Rings and platoons couple each driver to a few neighbours, so after a reverse
//! Cuthill–McKee ordering `L` is a band matrix of small bandwidth (2 for any ring, one-way or
//! both ways). A band LU with partial pivoting then costs `O(N·k_l(k_l + k_u))` instead of
//! `O(N³)`; a dense graph simply has full bandwidth, and the same code is a dense LU.
//!
//! The factorization carries the derivative in `s` along (dual numbers `a + a'ε`), so that
//! `d/ds log det M(s) = Σ_k u_kk'/u_kk` comes out of the diagonal of `U`: the argument
//! principle and the Newton steps `s − m/(log det M)'` need no inverse. The same LU solves
//! linear systems (the shift-invert step of [`super::collocation`]'s Arnoldi iteration).
//!
//! # Reference
//! E. Cuthill, J. McKee, "Reducing the bandwidth of sparse symmetric matrices", Proc. 24th
//! ACM National Conference (1969) 157–172; G. H. Golub, C. F. Van Loan, *Matrix
//! Computations*, 4th ed., §4.3.5 (band Gaussian elimination with partial pivoting).

use nalgebra::DMatrix;
use num_complex::Complex64;

/// A complex number with its derivative in `s`: `v + d·ε`, `ε² = 0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Dual {
    /// Value.
    pub(crate) v: Complex64,
    /// Derivative.
    pub(crate) d: Complex64,
}

impl Dual {
    fn mul(self, o: Dual) -> Dual {
        Dual {
            v: self.v * o.v,
            d: self.v * o.d + self.d * o.v,
        }
    }
    fn div(self, o: Dual) -> Dual {
        let v = self.v / o.v;
        Dual {
            v,
            d: (self.d - v * o.d) / o.v,
        }
    }
    fn sub(self, o: Dual) -> Dual {
        Dual {
            v: self.v - o.v,
            d: self.d - o.d,
        }
    }
}

/// The Laplacian of a network in band form (reverse Cuthill–McKee order) with its delays.
#[derive(Debug, Clone)]
pub(crate) struct BandedNetwork {
    /// `perm[p]` is the vehicle at position `p`.
    perm: Vec<usize>,
    /// Per position: `(position of the column, L entry)`, the diagonal always included.
    rows: Vec<Vec<(usize, f64)>>,
    /// Delay of the driver at each position \[s\].
    delays: Vec<f64>,
    kl: usize,
    ku: usize,
}

impl BandedNetwork {
    /// Band form of the Laplacian `l` (any square matrix with the pattern of a graph).
    pub(crate) fn new(l: &DMatrix<f64>, delays_s: &[f64]) -> Self {
        let n = l.nrows();
        let perm = reverse_cuthill_mckee(l);
        let mut pos = vec![0; n];
        for (p, &v) in perm.iter().enumerate() {
            pos[v] = p;
        }
        let (mut kl, mut ku) = (0, 0);
        let rows: Vec<Vec<(usize, f64)>> = perm
            .iter()
            .enumerate()
            .map(|(p, &i)| {
                // The diagonal is kept even when zero (a leader observes nobody): `s` sits there.
                let mut row: Vec<(usize, f64)> = (0..n)
                    .filter(|&j| j == i || l[(i, j)] != 0.0)
                    .map(|j| (pos[j], l[(i, j)]))
                    .collect();
                row.sort_by_key(|e| e.0);
                for &(q, _) in &row {
                    kl = kl.max(p.saturating_sub(q));
                    ku = ku.max(q.saturating_sub(p));
                }
                row
            })
            .collect();
        let delays = perm.iter().map(|&i| delays_s[i]).collect();
        BandedNetwork {
            perm,
            rows,
            delays,
            kl,
            ku,
        }
    }

    /// Number of vehicles.
    pub(crate) fn len(&self) -> usize {
        self.perm.len()
    }

    /// Vehicle at each position.
    pub(crate) fn permutation(&self) -> &[usize] {
        &self.perm
    }

    /// LU of `M(s) = sI + c·diag(e^{−sα_i})L` with the derivative `M'(s)` carried along.
    pub(crate) fn factor(&self, c: f64, s: Complex64) -> BandLu {
        let entries = self.rows.iter().enumerate().flat_map(|(p, row)| {
            let alpha = self.delays[p];
            let e = (-s * alpha).exp() * c;
            row.iter().map(move |&(q, lv)| {
                let mut x = Dual {
                    v: e * lv,
                    d: -e * lv * alpha,
                };
                if q == p {
                    x.v += s;
                    x.d += 1.0;
                }
                (p, q, x)
            })
        });
        BandLu::new(self.len(), self.kl, self.ku, entries)
    }

    /// LU of `diag(r_i)·L − σI` (positions in band order), without derivative.
    pub(crate) fn factor_scaled(&self, row_scale: &[Complex64], sigma: Complex64) -> BandLu {
        let entries = self.rows.iter().enumerate().flat_map(|(p, row)| {
            let r = row_scale[p];
            row.iter().map(move |&(q, lv)| {
                let mut v = r * lv;
                if q == p {
                    v -= sigma;
                }
                (
                    p,
                    q,
                    Dual {
                        v,
                        d: Complex64::new(0.0, 0.0),
                    },
                )
            })
        });
        BandLu::new(self.len(), self.kl, self.ku, entries)
    }
}

/// Band LU with partial pivoting, `PA = LU`, in dual numbers (LAPACK `gbtrf` layout: the
/// multipliers stay where they were computed, `U` has bandwidth `k_l + k_u`).
#[derive(Debug, Clone)]
pub(crate) struct BandLu {
    n: usize,
    kl: usize,
    ku: usize,
    w: usize,
    a: Vec<Dual>,
    piv: Vec<usize>,
    singular: bool,
}

impl BandLu {
    fn new(
        n: usize,
        kl: usize,
        ku: usize,
        entries: impl Iterator<Item = (usize, usize, Dual)>,
    ) -> Self {
        let w = 2 * kl + ku + 1;
        let mut lu = BandLu {
            n,
            kl,
            ku,
            w,
            a: vec![Dual::default(); n * w],
            piv: (0..n).collect(),
            singular: false,
        };
        for (r, c, x) in entries {
            let k = lu.idx(r, c);
            lu.a[k].v += x.v;
            lu.a[k].d += x.d;
        }
        lu.decompose();
        lu
    }

    fn idx(&self, r: usize, c: usize) -> usize {
        r * self.w + (c + self.kl - r)
    }

    fn decompose(&mut self) {
        let n = self.n;
        for k in 0..n {
            let last = (k + self.kl).min(n - 1);
            let right = (k + self.kl + self.ku).min(n - 1);
            let mut p = k;
            let mut best = self.a[self.idx(k, k)].v.norm();
            for r in k + 1..=last {
                let x = self.a[self.idx(r, k)].v.norm();
                if x > best {
                    best = x;
                    p = r;
                }
            }
            if !(best > 0.0 && best.is_finite()) {
                self.singular = true;
                return;
            }
            self.piv[k] = p;
            if p != k {
                for c in k..=right {
                    let (i, j) = (self.idx(k, c), self.idx(p, c));
                    self.a.swap(i, j);
                }
            }
            let pivot = self.a[self.idx(k, k)];
            for r in k + 1..=last {
                let i = self.idx(r, k);
                if self.a[i] == Dual::default() {
                    continue;
                }
                let m = self.a[i].div(pivot);
                self.a[i] = m;
                for c in k + 1..=right {
                    let (t, u) = (self.idx(r, c), self.idx(k, c));
                    self.a[t] = self.a[t].sub(m.mul(self.a[u]));
                }
            }
        }
    }

    /// `false` when a pivot vanished (`s` is numerically a root).
    pub(crate) fn is_regular(&self) -> bool {
        !self.singular
    }

    /// `det M / Π_k shift` normalized to modulus 1 (the phase of `det M(s)/shift^N`), or
    /// `None` if singular or not finite.
    pub(crate) fn phase_over(&self, shift: Complex64) -> Option<Complex64> {
        if self.singular {
            return None;
        }
        let mut phase = Complex64::new(1.0, 0.0);
        let mut swaps = 0;
        for k in 0..self.n {
            let z = self.a[self.idx(k, k)].v / shift;
            let norm = z.norm();
            if !(norm.is_finite() && norm > 0.0) {
                return None;
            }
            phase *= z / norm;
            swaps += usize::from(self.piv[k] != k);
        }
        Some(if swaps % 2 == 1 { -phase } else { phase })
    }

    /// `d/ds log det M(s) = Σ_k u_kk'/u_kk`, or `None` if singular or not finite.
    pub(crate) fn log_det_derivative(&self) -> Option<Complex64> {
        if self.singular {
            return None;
        }
        let mut g = Complex64::new(0.0, 0.0);
        for k in 0..self.n {
            let u = self.a[self.idx(k, k)];
            g += u.d / u.v;
        }
        (g.re.is_finite() && g.im.is_finite()).then_some(g)
    }

    /// Solves `A x = b` in place (positions in band order); `false` if singular.
    pub(crate) fn solve(&self, b: &mut [Complex64]) -> bool {
        if self.singular {
            return false;
        }
        let n = self.n;
        for k in 0..n {
            let p = self.piv[k];
            if p != k {
                b.swap(k, p);
            }
            let bk = b[k];
            for r in k + 1..=(k + self.kl).min(n - 1) {
                b[r] -= self.a[self.idx(r, k)].v * bk;
            }
        }
        for k in (0..n).rev() {
            let mut sum = b[k];
            for c in k + 1..=(k + self.kl + self.ku).min(n - 1) {
                sum -= self.a[self.idx(k, c)].v * b[c];
            }
            b[k] = sum / self.a[self.idx(k, k)].v;
        }
        true
    }
}

/// Reverse Cuthill–McKee order of the symmetrized pattern of `l` (off-diagonal entries):
/// breadth-first from a vertex of least degree, neighbours by increasing degree, reversed.
fn reverse_cuthill_mckee(l: &DMatrix<f64>) -> Vec<usize> {
    let n = l.nrows();
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); n];
    for i in 0..n {
        for j in 0..n {
            if i != j && (l[(i, j)] != 0.0 || l[(j, i)] != 0.0) {
                adj[i].push(j);
            }
        }
    }
    let degree: Vec<usize> = adj.iter().map(Vec::len).collect();
    for a in adj.iter_mut() {
        a.sort_by_key(|&j| (degree[j], j));
    }
    let mut order = Vec::with_capacity(n);
    let mut seen = vec![false; n];
    while order.len() < n {
        let start = (0..n)
            .filter(|&v| !seen[v])
            .min_by_key(|&v| (degree[v], v))
            .expect("an unvisited vertex is left");
        seen[start] = true;
        let mut head = order.len();
        order.push(start);
        while head < order.len() {
            let v = order[head];
            head += 1;
            for &w in &adj[v] {
                if !seen[w] {
                    seen[w] = true;
                    order.push(w);
                }
            }
        }
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::super::collocation::laplacian;
    use super::super::collocation::tests::{random_network, Lcg};
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::DVector;

    /// Dense reference: `det M(s)` by nalgebra's LU, `tr(M⁻¹M')` by the inverse.
    fn dense(l: &DMatrix<f64>, d: &[f64], c: f64, s: Complex64) -> (Complex64, Complex64) {
        let n = l.nrows();
        let m = DMatrix::from_fn(n, n, |i, j| {
            c * l[(i, j)] * (-s * d[i]).exp() + if i == j { s } else { 0.0.into() }
        });
        let dm = DMatrix::from_fn(n, n, |i, j| {
            -c * l[(i, j)] * d[i] * (-s * d[i]).exp()
                + if i == j {
                    1.0.into()
                } else {
                    Complex64::new(0.0, 0.0)
                }
        });
        let inv = m.clone().try_inverse().unwrap();
        ((&inv * dm).trace(), m.determinant())
    }

    #[test]
    fn band_lu_matches_the_dense_determinant_and_log_derivative() {
        let mut rng = Lcg(11);
        for trial in 0..6 {
            let n = 4 + 3 * trial;
            let (a, d) = random_network(n, &mut rng);
            let l = laplacian(&a);
            let band = BandedNetwork::new(&l, &d);
            for &s in &[Complex64::new(-0.3, 1.7), Complex64::new(0.2, 0.05)] {
                let lu = band.factor(1.3, s);
                let (g, det) = dense(&l, &d, 1.3, s);
                assert_relative_eq!(lu.log_det_derivative().unwrap().re, g.re, epsilon = 1e-11);
                assert_relative_eq!(lu.log_det_derivative().unwrap().im, g.im, epsilon = 1e-11);
                let phase = lu.phase_over(Complex64::new(1.0, 0.0)).unwrap();
                assert!((phase - det / det.norm()).norm() < 1e-11, "trial {trial}");
                // A solve against the dense matrix-vector product (in band order).
                let x = DVector::from_fn(n, |i, _| Complex64::new(i as f64, 1.0));
                let m = DMatrix::from_fn(n, n, |i, j| {
                    1.3 * l[(i, j)] * (-s * d[i]).exp() + if i == j { s } else { 0.0.into() }
                });
                let b = &m * &x;
                let p = band.permutation();
                let mut y: Vec<Complex64> = p.iter().map(|&v| b[v]).collect();
                assert!(lu.solve(&mut y));
                for (k, &v) in p.iter().enumerate() {
                    assert!((y[k] - x[v]).norm() < 1e-10, "trial {trial}");
                }
            }
        }
    }

    #[test]
    fn a_leader_row_of_zeros_still_carries_s() {
        // Vertex 2 observes nobody (a leader): its row of M(s) is s alone, so
        // det M = s · det(sI + e^{−sα}L_f) and (log det M)' has the term 1/s.
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 0.5, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let l = laplacian(&a);
        let d = [0.7, 0.4, 0.0];
        let band = BandedNetwork::new(&l, &d);
        let s = Complex64::new(-0.2, 0.9);
        let (g, _) = dense(&l, &d, 1.0, s);
        let lu = band.factor(1.0, s);
        assert!(lu.is_regular());
        assert!((lu.log_det_derivative().unwrap() - g).norm() < 1e-12);
    }

    #[test]
    fn rings_have_bandwidth_two() {
        for n in [5usize, 50, 201] {
            let a = DMatrix::from_fn(n, n, |i, j| {
                if j == (i + n - 1) % n || j == (i + 1) % n {
                    1.0
                } else {
                    0.0
                }
            });
            let band = BandedNetwork::new(&laplacian(&a), &vec![0.5; n]);
            assert!(
                band.kl <= 2 && band.ku <= 2,
                "N={n}: {} {}",
                band.kl,
                band.ku
            );
        }
    }
}
