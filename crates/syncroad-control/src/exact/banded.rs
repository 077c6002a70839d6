//! The characteristic matrix `M(s) = sI + c·diag(e^{−sα_i}) L` of eq. `chandler+` as a band
//! matrix, factored without forming an inverse.
//!
//! Rings and platoons couple each driver to a few neighbours, so after a reverse
//! Cuthill–McKee ordering `L` is a band matrix of small bandwidth (2 for any ring, one-way or
//! both ways). A band LU with partial pivoting then costs `O(N·k_l(k_l + k_u))` instead of
//! `O(N³)`. Graphs without a small bandwidth (random digraphs, long arcs, chords) are factored
//! by the sparse LU of [`super::sparse_lu`] in Markowitz's order, whichever of
//! the two costs fewer operations on a trial factorization; rows of drivers that observe every
//! other vehicle with one gain are taken out as a rank-one correction (`SparseForm`).
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

pub(crate) use super::dual::Dual;
use super::sparse_lu::{markowitz_order, ColumnPattern, SparseLu, Symbolic};

/// The Laplacian of a network with its delays, ordered for cheap factorizations of
/// `M(s) = sI + c·diag(e^{−sα_i})L`: a band (reverse Cuthill–McKee order) when the graph has
/// a small bandwidth, else a sparse LU in Markowitz's order
/// ([`super::sparse_lu`]), whichever costs fewer operations.
#[derive(Debug, Clone)]
pub(crate) struct NetworkMatrix {
    /// `perm[p]` is the vehicle at position `p`.
    perm: Vec<usize>,
    /// Per position: `(position of the column, L entry)`, the diagonal always included.
    rows: Vec<Vec<(usize, f64)>>,
    /// Delay of the driver at each position \[s\].
    delays: Vec<f64>,
    kl: usize,
    ku: usize,
    /// The sparse form, when the sparse LU is the cheaper factorization.
    sparse: Option<SparseForm>,
}

/// The Laplacian as `L = L_s − c·1ᵀ`: `L_s` by columns for the sparse LU, and `c_p` for the
/// drivers that observe every other vehicle with one gain (all-to-all rows), whose rows would
/// otherwise fill the factors. `det(A − u1ᵀ) = det A · (1 − 1ᵀA⁻¹u)` (the matrix determinant
/// lemma) and Sherman–Morrison's formula then cost one more sparse solve.
#[derive(Debug, Clone)]
struct SparseForm {
    /// The pattern of `L_s` (diagonal included) by columns.
    pattern: ColumnPattern,
    /// Each stored entry's `(row position, L_s entry)`.
    entries: Vec<(usize, f64)>,
    /// `c_p` per position; empty when no row observes everyone.
    dense_rows: Vec<f64>,
    /// The pivots and patterns of a factorization at `s = 1 + i`, reused while they pass the
    /// pivoting threshold (fixed once made, so every factorization is the same whatever the
    /// order the threads ask for them).
    symbolic: Option<Symbolic>,
}

impl SparseForm {
    /// `values[k] = entry(row position, column position, L_s entry)` in the pattern's order.
    fn values(&self, entry: impl Fn(usize, usize, f64) -> Dual) -> Vec<Dual> {
        (0..self.pattern.len())
            .flat_map(|q| (self.pattern.starts[q]..self.pattern.starts[q + 1]).map(move |k| (q, k)))
            .map(|(q, k)| entry(self.entries[k].0, q, self.entries[k].1))
            .collect()
    }

    /// The LU of `A = (the matrix of values) − u·1ᵀ` with `u_p = weight(p)·c_p`, with the
    /// pivots of `recent` when it holds some, else this form's own; when they are refused, a
    /// fresh factorization, whose pivots `recent` then keeps.
    fn factor(
        &self,
        values: &[Dual],
        weight: impl Fn(usize) -> Dual,
        recent: Option<&mut RecentPivots>,
    ) -> NetworkLu {
        let reused = recent
            .as_ref()
            .and_then(|r| r.pivots.as_ref())
            .or(self.symbolic.as_ref())
            .and_then(|sym| sym.refactor(&self.pattern, values));
        let lu = reused.unwrap_or_else(|| {
            let lu = SparseLu::new(&self.pattern, values);
            if let Some(r) = recent {
                r.pivots = Symbolic::of(&lu);
                r.fresh += 1;
            }
            lu
        });
        if self.dense_rows.is_empty() || !lu.is_regular() {
            return NetworkLu::Sparse { lu, rank_one: None };
        }
        let mut w: Vec<Dual> = self
            .dense_rows
            .iter()
            .enumerate()
            .map(|(p, &c)| weight(p).scale(c))
            .collect();
        lu.solve_dual(&mut w);
        let f = w.iter().fold(Dual::ONE, |f, x| f.sub(*x));
        NetworkLu::Sparse {
            lu,
            rank_one: Some((w, f)),
        }
    }
}

/// The pivots of the last fresh sparse factorization in one sequence of nearby points (one
/// stretch of a root count's contour, one root's Newton iterates along its track), tried
/// before the network's own. Those were chosen at `s = 1 + i`; near a root, where `M(s)` is
/// nearly singular, the pivoting threshold refuses them at almost every point, and each such
/// point used to be factored afresh (a fifth of all factorizations of a stability report on
/// the random digraphs of 200, at one and a half times the cost of a refactorization). The
/// points of one sequence differ little, so the pivots of its last fresh factorization mostly
/// pass. Each sequence owns its own, so every factorization is still the same whatever the
/// order the threads ask for them.
#[derive(Debug, Clone, Default)]
pub(crate) struct RecentPivots {
    pivots: Option<Symbolic>,
    /// Fresh factorizations in the sequence so far.
    fresh: usize,
}

impl RecentPivots {
    /// Fresh factorizations in the sequence so far (those whose pivots it kept).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn fresh(&self) -> usize {
        self.fresh
    }
}

/// `c_i` for every row of `l` that observes all other vehicles with one gain (`l_ij = −c_i`
/// for every `j ≠ i`), else 0; `None` when no row does.
fn all_to_all_rows(l: &DMatrix<f64>) -> Option<Vec<f64>> {
    let n = l.nrows();
    let c: Vec<f64> = (0..n)
        .map(|i| {
            let first = l[(i, (i + 1) % n)];
            let uniform = (0..n).all(|j| j == i || l[(i, j)] == first);
            if uniform && first != 0.0 && n > 2 {
                -first
            } else {
                0.0
            }
        })
        .collect();
    c.iter().any(|&x| x != 0.0).then_some(c)
}

/// Below this sum of half-bandwidths the band LU is used without trying the sparse one.
const NARROW_BAND: usize = 8;

/// A sparse LU does this many times more bookkeeping per operation than a band LU (searches,
/// indirect addressing); measured on rings with chords and random digraphs.
const SPARSE_OVERHEAD: usize = 3;

impl NetworkMatrix {
    /// Factorization form of the Laplacian `l` (any square matrix with the pattern of a
    /// graph).
    pub(crate) fn new(l: &DMatrix<f64>, delays_s: &[f64]) -> Self {
        if let Some(c) = all_to_all_rows(l) {
            let n = l.nrows();
            let l_s = DMatrix::from_fn(n, n, |i, j| l[(i, j)] + c[i]);
            return Self::sparse(&l_s, delays_s, c);
        }
        let band = Self::in_order(l, delays_s, reverse_cuthill_mckee(l));
        if band.kl + band.ku <= NARROW_BAND {
            return band;
        }
        let sparse = Self::sparse(l, delays_s, Vec::new());
        // The cost of the sparse form's pivots, found by its factorization at s = 1 + i.
        let trial = sparse
            .sparse
            .as_ref()
            .and_then(|f| f.symbolic.as_ref())
            .map_or(usize::MAX, Symbolic::operations);
        let band_operations = band.len() * band.kl * (band.kl + band.ku);
        if trial.saturating_mul(SPARSE_OVERHEAD) < band_operations {
            sparse
        } else {
            band
        }
    }

    /// The sparse form of `L = l_s − c·1ᵀ` (`c` by vehicle, empty for none), in Markowitz's
    /// order.
    fn sparse(l_s: &DMatrix<f64>, delays_s: &[f64], c: Vec<f64>) -> Self {
        let mut form = Self::in_order(l_s, delays_s, markowitz_order(&rows_of(l_s)));
        let pattern = ColumnPattern::of_rows(&form.rows);
        let mut entries = vec![(0, 0.0); pattern.rows.len()];
        let mut next = pattern.starts.clone();
        for (r, row) in form.rows.iter().enumerate() {
            for &(q, lv) in row {
                entries[next[q]] = (r, lv);
                next[q] += 1;
            }
        }
        let dense_rows = if c.is_empty() {
            c
        } else {
            form.perm.iter().map(|&v| c[v]).collect()
        };
        form.sparse = Some(SparseForm {
            pattern,
            entries,
            dense_rows,
            symbolic: None,
        });
        let symbolic = match form.factor(1.0, Complex64::new(1.0, 1.0)) {
            NetworkLu::Sparse { lu, .. } => Symbolic::of(&lu),
            NetworkLu::Band(_) => None,
        };
        if let Some(f) = form.sparse.as_mut() {
            f.symbolic = symbolic;
        }
        form
    }

    /// The rows of `l` with vehicle `perm[p]` at position `p`, band widths measured.
    fn in_order(l: &DMatrix<f64>, delays_s: &[f64], perm: Vec<usize>) -> Self {
        let n = l.nrows();
        let mut pos = vec![0; n];
        for (p, &v) in perm.iter().enumerate() {
            pos[v] = p;
        }
        let by_vehicle = rows_of(l);
        let (mut kl, mut ku) = (0, 0);
        let rows: Vec<Vec<(usize, f64)>> = perm
            .iter()
            .enumerate()
            .map(|(p, &i)| {
                let mut row: Vec<(usize, f64)> =
                    by_vehicle[i].iter().map(|&(j, lv)| (pos[j], lv)).collect();
                row.sort_by_key(|e| e.0);
                for &(q, _) in &row {
                    kl = kl.max(p.saturating_sub(q));
                    ku = ku.max(q.saturating_sub(p));
                }
                row
            })
            .collect();
        let delays = perm.iter().map(|&i| delays_s[i]).collect();
        NetworkMatrix {
            perm,
            rows,
            delays,
            kl,
            ku,
            sparse: None,
        }
    }

    /// Number of vehicles.
    pub(crate) fn len(&self) -> usize {
        self.perm.len()
    }

    /// Multiply–adds of one factorization in the form this network chose (the sparse form's
    /// as its factorization at `s = 1 + i` found them).
    pub(crate) fn operations(&self) -> usize {
        match &self.sparse {
            Some(f) => f.symbolic.as_ref().map_or(usize::MAX, Symbolic::operations),
            None => self.len() * self.kl * (self.kl + self.ku),
        }
    }

    /// Vehicle at each position.
    pub(crate) fn permutation(&self) -> &[usize] {
        &self.perm
    }

    /// LU of `M(s) = sI + c·diag(e^{−sα_i})L` with the derivative `M'(s)` carried along.
    pub(crate) fn factor(&self, c: f64, s: Complex64) -> NetworkLu {
        self.factor_near(c, s, None)
    }

    /// [`Self::factor`], reusing the pivots of the sequence of nearby points `recent` belongs
    /// to (and keeping those of a fresh factorization there).
    pub(crate) fn factor_near(
        &self,
        c: f64,
        s: Complex64,
        recent: Option<&mut RecentPivots>,
    ) -> NetworkLu {
        let entry = |p: usize, q: usize, lv: f64, e: Complex64, alpha: f64| {
            let mut x = Dual {
                v: e * lv,
                d: -e * lv * alpha,
            };
            if q == p {
                x.v += s;
                x.d += 1.0;
            }
            x
        };
        let scale: Vec<Complex64> = self.delays.iter().map(|&a| (-s * a).exp() * c).collect();
        if let Some(form) = &self.sparse {
            let values = form.values(|p, q, lv| entry(p, q, lv, scale[p], self.delays[p]));
            return form.factor(
                &values,
                |p| Dual {
                    v: scale[p],
                    d: -scale[p] * self.delays[p],
                },
                recent,
            );
        }
        let scale = &scale;
        let entries = self.rows.iter().enumerate().flat_map(|(p, row)| {
            row.iter()
                .map(move |&(q, lv)| (p, q, entry(p, q, lv, scale[p], self.delays[p])))
        });
        NetworkLu::Band(BandLu::new(self.len(), self.kl, self.ku, entries))
    }

    /// `M'(s)·x = x − c·diag(α_i e^{−sα_i})·L·x` (positions in this form's order).
    pub(crate) fn derivative_times(&self, c: f64, s: Complex64, x: &[Complex64]) -> Vec<Complex64> {
        // The all-to-all rows are stored as `L_s` with `L = L_s − c_p·1ᵀ`.
        let dense = self.sparse.as_ref().map_or(&[][..], |f| &f.dense_rows[..]);
        let total: Complex64 = x.iter().sum();
        self.rows
            .iter()
            .enumerate()
            .map(|(p, row)| {
                let mut lx: Complex64 = row.iter().map(|&(q, lv)| x[q] * lv).sum();
                if let Some(&cp) = dense.get(p) {
                    lx -= total * cp;
                }
                let alpha = self.delays[p];
                x[p] - (-s * alpha).exp() * (c * alpha) * lx
            })
            .collect()
    }

    /// LU of `diag(r_i)·L − σI` (positions in this form's order), without derivative.
    pub(crate) fn factor_scaled(&self, row_scale: &[Complex64], sigma: Complex64) -> NetworkLu {
        let entry = |p: usize, q: usize, lv: f64| {
            let mut v = row_scale[p] * lv;
            if q == p {
                v -= sigma;
            }
            Dual {
                v,
                d: Complex64::new(0.0, 0.0),
            }
        };
        if let Some(form) = &self.sparse {
            let values = form.values(entry);
            return form.factor(
                &values,
                |p| Dual {
                    v: row_scale[p],
                    d: Complex64::new(0.0, 0.0),
                },
                None,
            );
        }
        let entries = self
            .rows
            .iter()
            .enumerate()
            .flat_map(|(p, row)| row.iter().map(move |&(q, lv)| (p, q, entry(p, q, lv))));
        NetworkLu::Band(BandLu::new(self.len(), self.kl, self.ku, entries))
    }
}

/// An LU of `M(s)` (or of the shift-invert matrix) in the form its network chose.
#[derive(Debug, Clone)]
pub(crate) enum NetworkLu {
    /// Band LU (narrow graphs).
    Band(BandLu),
    /// Sparse LU (graphs without a small bandwidth), with the rank-one correction of the
    /// all-to-all rows: `w = A⁻¹u` and `f = 1 − 1ᵀw` in dual numbers ([`SparseForm`]).
    Sparse {
        /// The LU of the sparse part.
        lu: SparseLu,
        /// `(w, f)` when some rows observe everyone.
        rank_one: Option<(Vec<Dual>, Dual)>,
    },
}

impl NetworkLu {
    /// `false` when a pivot vanished (`s` is numerically a root).
    pub(crate) fn is_regular(&self) -> bool {
        match self {
            NetworkLu::Band(lu) => !lu.singular,
            NetworkLu::Sparse { lu, rank_one } => {
                lu.is_regular() && rank_one.as_ref().is_none_or(|(_, f)| f.v.norm() > 0.0)
            }
        }
    }

    /// The pivots of the LU (of its sparse part, for the rank-one form).
    fn pivots(&self) -> Box<dyn Iterator<Item = Dual> + '_> {
        match self {
            NetworkLu::Band(lu) => Box::new(lu.pivots()),
            NetworkLu::Sparse { lu, .. } => Box::new(lu.pivots()),
        }
    }

    /// `det M` normalized to modulus 1 (its phase), or `None` if singular or not finite.
    pub(crate) fn phase(&self) -> Option<Complex64> {
        if !self.is_regular() {
            return None;
        }
        let (odd, mut phase) = match self {
            NetworkLu::Band(lu) => (lu.odd_permutation(), Complex64::new(1.0, 0.0)),
            // det(A − u1ᵀ) = det A · f.
            NetworkLu::Sparse { lu, rank_one } => (
                lu.odd_permutation(),
                rank_one
                    .as_ref()
                    .map_or(Complex64::new(1.0, 0.0), |(_, f)| f.v / f.v.norm()),
            ),
        };
        for u in self.pivots() {
            let norm = u.v.norm();
            if !(norm.is_finite() && norm > 0.0) {
                return None;
            }
            phase *= u.v / norm;
        }
        Some(if odd { -phase } else { phase })
    }

    /// `d/ds log det M(s) = Σ_k u_kk'/u_kk` (and `f'/f` for the rank-one form), or `None` if
    /// singular or not finite.
    pub(crate) fn log_det_derivative(&self) -> Option<Complex64> {
        if !self.is_regular() {
            return None;
        }
        let correction = match self {
            NetworkLu::Sparse {
                rank_one: Some((_, f)),
                ..
            } => f.d / f.v,
            _ => Complex64::new(0.0, 0.0),
        };
        let g = self.pivots().map(|u| u.d / u.v).sum::<Complex64>() + correction;
        (g.re.is_finite() && g.im.is_finite()).then_some(g)
    }

    /// Solves `A x = b` in place (positions in the network's order); `false` if singular.
    pub(crate) fn solve(&self, b: &mut [Complex64]) -> bool {
        match self {
            NetworkLu::Band(lu) => lu.solve(b),
            NetworkLu::Sparse { lu, rank_one } => {
                if !lu.solve(b) {
                    return false;
                }
                // Sherman–Morrison: x = A⁻¹b + w·(1ᵀA⁻¹b)/f.
                if let Some((w, f)) = rank_one {
                    let t = b.iter().sum::<Complex64>() / f.v;
                    for (x, wp) in b.iter_mut().zip(w) {
                        *x += wp.v * t;
                    }
                }
                true
            }
        }
    }
}

/// The rows of `l` by vehicle, as `(column vehicle, entry)`; the diagonal is kept even when
/// zero (a leader observes nobody): `s` sits there.
fn rows_of(l: &DMatrix<f64>) -> Vec<Vec<(usize, f64)>> {
    let n = l.nrows();
    (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| j == i || l[(i, j)] != 0.0)
                .map(|j| (j, l[(i, j)]))
                .collect()
        })
        .collect()
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

    /// The diagonal of `U`.
    fn pivots(&self) -> impl Iterator<Item = Dual> + '_ {
        (0..self.n).map(move |k| self.a[self.idx(k, k)])
    }

    /// `true` when the row interchanges are odd in number.
    fn odd_permutation(&self) -> bool {
        (0..self.n).filter(|&k| self.piv[k] != k).count() % 2 == 1
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

    /// `form`'s determinant phase, log-derivative and solve against the dense reference.
    fn assert_matches_dense(form: &NetworkMatrix, l: &DMatrix<f64>, d: &[f64], case: &str) {
        let n = l.nrows();
        for &s in &[Complex64::new(-0.3, 1.7), Complex64::new(0.2, 0.05)] {
            let lu = form.factor(1.3, s);
            let (g, det) = dense(l, d, 1.3, s);
            let got = lu.log_det_derivative().unwrap();
            assert!(
                (got - g).norm() <= 1e-11 * (1.0 + g.norm()),
                "{case}: {got} against {g}"
            );
            let phase = lu.phase().unwrap();
            assert!((phase - det / det.norm()).norm() < 1e-11, "{case}");
            // A solve against the dense matrix-vector product (in the form's order).
            let x = DVector::from_fn(n, |i, _| Complex64::new(i as f64, 1.0));
            let m = DMatrix::from_fn(n, n, |i, j| {
                1.3 * l[(i, j)] * (-s * d[i]).exp() + if i == j { s } else { 0.0.into() }
            });
            let b = &m * &x;
            let p = form.permutation();
            let mut y: Vec<Complex64> = p.iter().map(|&v| b[v]).collect();
            assert!(lu.solve(&mut y));
            for (k, &v) in p.iter().enumerate() {
                assert!((y[k] - x[v]).norm() < 1e-9 * (1.0 + x[v].norm()), "{case}");
            }
            // `M'(s)·x` against the dense derivative's product.
            let dm = DMatrix::from_fn(n, n, |i, j| {
                -1.3 * l[(i, j)] * d[i] * (-s * d[i]).exp()
                    + if i == j {
                        Complex64::new(1.0, 0.0)
                    } else {
                        Complex64::new(0.0, 0.0)
                    }
            });
            let want = &dm * &x;
            let x_pos: Vec<Complex64> = p.iter().map(|&v| x[v]).collect();
            let got = form.derivative_times(1.3, s, &x_pos);
            for (k, &v) in p.iter().enumerate() {
                assert!(
                    (got[k] - want[v]).norm() < 1e-12 * (1.0 + want[v].norm()),
                    "{case}: M'x {} against {}",
                    got[k],
                    want[v]
                );
            }
        }
    }

    #[test]
    fn band_lu_matches_the_dense_determinant_and_log_derivative() {
        let mut rng = Lcg(11);
        for trial in 0..6 {
            let n = 4 + 3 * trial;
            let (a, d) = random_network(n, &mut rng);
            let l = laplacian(&a);
            let band = NetworkMatrix::in_order(&l, &d, reverse_cuthill_mckee(&l));
            assert_matches_dense(&band, &l, &d, &format!("band, trial {trial}"));
        }
    }

    #[test]
    fn sparse_lu_matches_the_dense_determinant_and_log_derivative() {
        let mut rng = Lcg(17);
        for trial in 0..4 {
            let n = 10 + 25 * trial;
            let (a, d) = random_network(n, &mut rng);
            let l = laplacian(&a);
            let sparse = NetworkMatrix::sparse(&l, &d, Vec::new());
            assert_matches_dense(&sparse, &l, &d, &format!("sparse, trial {trial}"));
        }
        // A random digraph of 150 drivers has no small bandwidth: the sparse form is chosen.
        let (a, d) = random_network(150, &mut rng);
        let l = laplacian(&a);
        let chosen = NetworkMatrix::new(&l, &d);
        assert!(
            chosen.sparse.is_some(),
            "bandwidth {} + {}",
            chosen.kl,
            chosen.ku
        );
        assert_matches_dense(&chosen, &l, &d, "chosen for N = 150");
    }

    #[test]
    fn all_to_all_rows_are_a_rank_one_correction() {
        // Drivers 0..n/2 observe everyone with their own gain, the others a random sparse set.
        let mut rng = Lcg(23);
        for n in [6usize, 40] {
            let (sparse_part, d) = random_network(n, &mut rng);
            let a = DMatrix::from_fn(n, n, |i, j| match (i < n / 2, i == j) {
                (_, true) => 0.0,
                (true, false) => 0.1 + 0.01 * i as f64,
                (false, false) => sparse_part[(i, j)],
            });
            let l = laplacian(&a);
            let form = NetworkMatrix::new(&l, &d);
            let rows = form.sparse.as_ref().map(|f| f.dense_rows.clone());
            assert_eq!(
                rows.map(|r| r.iter().filter(|&&c| c != 0.0).count()),
                Some(n / 2),
                "N = {n}: the all-to-all rows are found"
            );
            assert_matches_dense(&form, &l, &d, &format!("all-to-all rows, N = {n}"));
        }
    }

    #[test]
    fn a_leader_row_of_zeros_still_carries_s() {
        // Vertex 2 observes nobody (a leader): its row of M(s) is s alone, so
        // det M = s · det(sI + e^{−sα}L_f) and (log det M)' has the term 1/s.
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 0.5, 1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let l = laplacian(&a);
        let d = [0.7, 0.4, 0.0];
        let band = NetworkMatrix::new(&l, &d);
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
            let band = NetworkMatrix::new(&laplacian(&a), &vec![0.5; n]);
            assert!(
                band.kl <= 2 && band.ku <= 2,
                "N={n}: {} {}",
                band.kl,
                band.ku
            );
        }
    }
}
