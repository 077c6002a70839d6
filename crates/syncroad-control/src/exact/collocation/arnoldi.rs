//! Step 1 for large networks: the rightmost eigenvalues of the collocation matrix `A` without
//! its dense Schur form, by Arnoldi's method on `(A − σI)⁻¹` at a few shifts `σ` along the
//! imaginary axis; then Newton on `det M(s)` with the band LU of [`super::super::banded`].
//!
//! The dense eigenvalue step costs `O((N·M)³)`: 0.4 s at `N = 50`, half a minute at `N = 200`.
//! The shift-invert step is cheap because `A − σI` reduces to an `N×N` band system. With the
//! state `(v, φ)` of the parent module, `(A − σI)(v, φ) = (f, h)` reads, per delayed driver,
//! `P_i φ_i = h_i + (2/α_i) d_0 (Lv)_i` with `P_i = (2/α_i)D̃ − σI` (the Chebyshev block,
//! `M×M`), so `φ_i = t_i + (Lv)_i w_i` with `t_i = P_i⁻¹h_i`, `w_i = P_i⁻¹(2/α_i)d_0`; and the
//! rows of `v` become `(diag(ρ)L − σI)v = g` with `ρ_i = (w_i)_M ≈ −e^{−σα_i}` (`−1` for an
//! undelayed driver) and `g_i = f_i − (t_i)_M`: the collocated characteristic matrix, band
//! after the reverse Cuthill–McKee order.
//!
//! Each shift yields the eigenvalues nearest to it; shifts are spaced along `Re s = x_0 > 0`
//! up to the Gershgorin bound `max_i 2d_i^+` of the roots' modulus right of the axis. Nothing
//! guarantees that every rightmost root is found: the argument-principle certificate decides
//! ([`super::super::report::certify_roots`]), and the caller falls back to the dense solve.
//!
//! Multiplicities come from the roots themselves: `m = (1/K) Σ_k (z_k − s) g(z_k)` on `K`
//! points `z_k` of a small circle around `s` (the trapezoid rule for the residue of
//! `g = (log det M)'`, exact up to `(r/d)^K` for the next root at distance `d`).
//!
//! # Reference
//! Y. Saad, *Numerical Methods for Large Eigenvalue Problems*, 2nd ed., SIAM 2011, §6.2
//! (Arnoldi) and §8.1 (shift-and-invert); W. Michiels, N. Guglielmi, "An iterative method for
//! computing the pseudospectral abscissa for a class of nonlinear eigenvalue problems", SIAM
//! J. Sci. Comput. 34 (2012) (the Schur complement of the collocated generator).

use nalgebra::{DMatrix, DVector, Schur};
use num_complex::Complex64;
use rayon::prelude::*;

use super::super::banded::{NetworkLu, NetworkMatrix};
use super::generator::chebyshev;

/// The shift-and-invert operator `(A − σI)⁻¹` of the collocation matrix.
struct ShiftInvert<'a> {
    n: usize,
    m: usize,
    /// Slot of each vehicle's history in the state vector (`None`: undelayed).
    slot: Vec<Option<usize>>,
    /// Sparse rows of `L` (vehicle order).
    rows: &'a [Vec<(usize, f64)>],
    band: &'a NetworkMatrix,
    /// Per slot: the LU of `P_i` and `w_i`.
    blocks: Vec<(
        nalgebra::LU<Complex64, nalgebra::Dyn, nalgebra::Dyn>,
        DVector<Complex64>,
    )>,
    lu: NetworkLu,
}

impl<'a> ShiftInvert<'a> {
    fn new(
        rows: &'a [Vec<(usize, f64)>],
        band: &'a NetworkMatrix,
        delays_s: &[f64],
        m: usize,
        sigma: Complex64,
    ) -> Option<Self> {
        let n = delays_s.len();
        let (_, d) = chebyshev(m);
        let d_tilde = d.view((1, 1), (m, m)).map(|x| Complex64::new(x, 0.0));
        let d0 = d.view((1, 0), (m, 1)).map(|x| Complex64::new(x, 0.0));
        let mut slot = vec![None; n];
        let mut blocks = Vec::new();
        let mut rho = vec![Complex64::new(-1.0, 0.0); n];
        for i in 0..n {
            if delays_s[i] > 0.0 {
                let scale = 2.0 / delays_s[i];
                let mut p = &d_tilde * Complex64::new(scale, 0.0);
                for k in 0..m {
                    p[(k, k)] -= sigma;
                }
                let lu = p.lu();
                let w = lu.solve(&(&d0 * Complex64::new(scale, 0.0)))?;
                let w = w.column(0).into_owned();
                rho[i] = w[m - 1];
                slot[i] = Some(blocks.len());
                blocks.push((lu, w));
            }
        }
        let row_scale: Vec<Complex64> = band.permutation().iter().map(|&v| rho[v]).collect();
        let lu = band.factor_scaled(&row_scale, sigma);
        lu.is_regular().then_some(ShiftInvert {
            n,
            m,
            slot,
            rows,
            band,
            blocks,
            lu,
        })
    }

    fn order(&self) -> usize {
        self.n + self.m * self.blocks.len()
    }

    fn apply(&self, y: &DVector<Complex64>) -> Option<DVector<Complex64>> {
        let (n, m) = (self.n, self.m);
        let mut t: Vec<DVector<Complex64>> = Vec::with_capacity(self.blocks.len());
        for (k, (lu, _)) in self.blocks.iter().enumerate() {
            let h = y.rows(n + k * m, m).into_owned();
            t.push(lu.solve(&h)?);
        }
        let perm = self.band.permutation();
        let mut g: Vec<Complex64> = perm
            .iter()
            .map(|&v| match self.slot[v] {
                Some(k) => y[v] - t[k][m - 1],
                None => y[v],
            })
            .collect();
        if !self.lu.solve(&mut g) {
            return None;
        }
        let mut x = DVector::zeros(self.order());
        for (p, &v) in perm.iter().enumerate() {
            x[v] = g[p];
        }
        for i in 0..n {
            if let Some(k) = self.slot[i] {
                let lv: Complex64 = self.rows[i].iter().map(|&(j, w)| x[j] * w).sum();
                let phi = &t[k] + &self.blocks[k].1 * lv;
                x.rows_mut(n + k * m, m).copy_from(&phi);
            }
        }
        Some(x)
    }
}

/// Eigenvalues of the collocation matrix near the imaginary axis, up to `|Im| ≤ reach`: the
/// `keep` nearest to each of the shifts (see the module documentation), each with the error
/// bound of its Ritz pair ([`arnoldi_ritz`]).
pub(super) fn eigenvalues_near_axis(
    l: &DMatrix<f64>,
    delays_s: &[f64],
    m: usize,
    band: &NetworkMatrix,
    reach: f64,
) -> Vec<(Complex64, f64)> {
    let n = l.nrows();
    let rows: Vec<Vec<(usize, f64)>> = (0..n)
        .map(|i| {
            (0..n)
                .filter(|&j| l[(i, j)] != 0.0)
                .map(|j| (j, l[(i, j)]))
                .collect()
        })
        .collect();
    // Long networks crowd their roots near the axis: one shift per 16 vehicles keeps the
    // rightmost within the nearest `keep` of some shift (N = 400: 25 shifts).
    let shifts = 7.max(n / 16);
    let spacing = reach.max(1e-3) / (shifts - 1) as f64;
    let x0 = 0.25 * spacing;
    // The shifts are independent: searched in parallel, their eigenvalues kept in shift order
    // (the result does not depend on the threads).
    let per_shift: Vec<Vec<(Complex64, f64)>> = (0..shifts)
        .into_par_iter()
        .map(|k| {
            let sigma = Complex64::new(x0, spacing * k as f64);
            let Some(op) = ShiftInvert::new(&rows, band, delays_s, m, sigma) else {
                return Vec::new();
            };
            let kdim = op.order().min(48);
            let keep = (kdim / 2).max(1);
            let mut near = arnoldi_ritz(&op, kdim);
            near.sort_by(|a, b| a.0.norm().total_cmp(&b.0.norm()));
            near.iter()
                .take(keep)
                .map(|&(d, error)| (sigma + d, error))
                .collect()
        })
        .collect();
    per_shift.into_iter().flatten().collect()
}

/// Ritz values of `op` mapped back to `λ − σ = 1/θ`, from `kdim` Arnoldi steps (modified
/// Gram–Schmidt, twice), each with the error bound `|β yₖ|/|θ|²` of its Ritz pair (`β` the
/// last subdiagonal entry, `y` the unit eigenvector of the Hessenberg matrix; Saad §6.2):
/// without restarts only the few nearest pairs converge, and on dense graphs the others
/// crowd around the nearest root, 10⁻³ to 10⁻¹ from any root.
fn arnoldi_ritz(op: &ShiftInvert, kdim: usize) -> Vec<(Complex64, f64)> {
    let order = op.order();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut v0 = DVector::from_fn(order, |_, _| Complex64::new(next(), next()));
    v0 /= Complex64::new(v0.norm(), 0.0);
    let mut basis = vec![v0];
    let mut h = DMatrix::<Complex64>::zeros(kdim + 1, kdim);
    let mut steps = 0;
    for j in 0..kdim {
        let Some(mut w) = op.apply(&basis[j]) else {
            break;
        };
        let scale = w.norm();
        for _ in 0..2 {
            for (i, v) in basis.iter().enumerate() {
                let c = v.dotc(&w);
                h[(i, j)] += c;
                w -= v * c;
            }
        }
        steps = j + 1;
        let beta = w.norm();
        h[(j + 1, j)] = Complex64::new(beta, 0.0);
        if beta.is_nan() || beta <= 1e-10 * scale {
            break; // invariant subspace: its Ritz values are exact (to 1e-10, Newton does the rest)
        }
        basis.push(w / Complex64::new(beta, 0.0));
    }
    if steps == 0 {
        return Vec::new();
    }
    // As for the dense collocation matrix, the QR iteration can stall on clusters (symmetric
    // graphs): relax the deflation threshold step by step.
    let hk = h.view((0, 0), (steps, steps)).into_owned();
    let Some(schur) = [f64::EPSILON, 1e-14, 1e-13, 1e-12, 1e-11]
        .iter()
        .find_map(|&eps| Schur::try_new(hk.clone(), eps, 30 * steps.max(10)))
    else {
        return Vec::new();
    };
    let beta = h[(steps, steps - 1)].norm();
    let (q, t) = schur.unpack();
    (0..steps)
        .filter(|&k| t[(k, k)].norm() > 0.0)
        .map(|k| {
            let theta = t[(k, k)];
            let last = last_eigenvector_entry(&q, &t, k);
            (
                Complex64::new(1.0, 0.0) / theta,
                beta * last / theta.norm_sqr(),
            )
        })
        .collect()
}

/// `|yₙ|` of the unit eigenvector `y = Qz` of `QTQᴴ` for the eigenvalue `T_kk` (`z` by back
/// substitution in the triangular `T`, `z_k = 1`).
fn last_eigenvector_entry(q: &DMatrix<Complex64>, t: &DMatrix<Complex64>, k: usize) -> f64 {
    let theta = t[(k, k)];
    let mut z = vec![Complex64::new(0.0, 0.0); k + 1];
    z[k] = Complex64::new(1.0, 0.0);
    for i in (0..k).rev() {
        let sum: Complex64 = (i + 1..=k).map(|j| t[(i, j)] * z[j]).sum();
        let mut gap = t[(i, i)] - theta;
        // Equal eigenvalues: perturb the gap as LAPACK's trevc does.
        if gap.norm() < f64::EPSILON * theta.norm() {
            gap = Complex64::new(f64::EPSILON * theta.norm(), 0.0);
        }
        z[i] = -sum / gap;
    }
    let y = q.columns(0, k + 1) * DVector::from_vec(z);
    let norm = y.norm();
    if norm > 0.0 {
        y[y.len() - 1].norm() / norm
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::argument_principle::count_with_laplacian;
    use super::super::super::ring_modes::UniformRing;
    use super::super::tests::{family_random_digraph, random_network, Lcg};
    use super::super::{
        laplacian, rightmost_roots, rightmost_roots_shift_invert, CollocationOptions,
    };
    use approx::assert_relative_eq;
    use nalgebra::DMatrix;
    use num_complex::Complex64;

    /// Both solves must report the same roots with the same multiplicities; with `all`, as
    /// many roots (otherwise the shift-invert solve may leave out roots far from the axis, but
    /// finds at least three).
    fn assert_same_roots(a: &DMatrix<f64>, d: &[f64], case: &str, all: bool) {
        let opts = CollocationOptions::default();
        let dense = rightmost_roots(a, d, &opts).unwrap();
        let fast = rightmost_roots_shift_invert(a, d, &opts).unwrap();
        assert_relative_eq!(fast.abscissa, dense.abscissa, epsilon = 1e-10);
        if all {
            assert_eq!(fast.roots.len(), dense.roots.len(), "{case}");
        } else {
            assert!(fast.roots.len() >= 3, "{case}");
        }
        for (f, s) in fast.roots.iter().zip(&dense.roots) {
            let (f, s, m) = (
                Complex64::from(f.root),
                Complex64::from(s.root),
                s.multiplicity,
            );
            assert!(
                (f - s).norm() < 1e-10 * (1.0 + s.norm()),
                "{case}: {f} vs {s}"
            );
            let fm = fast
                .roots
                .iter()
                .find(|r| (Complex64::from(r.root) - s).norm() < 1e-9)
                .unwrap()
                .multiplicity;
            assert_eq!(fm, m, "{case}: multiplicity of {s}");
        }
        assert!(fast.max_residual < 1e-12, "{case}");
    }

    #[test]
    fn shift_invert_finds_the_dense_solves_roots() {
        let mut rng = Lcg(77);
        for trial in 0..6 {
            let n = 4 + 2 * trial;
            let (mut a, delays) = random_network(n, &mut rng);
            let worst = (0..n)
                .map(|i| delays[i] * a.row(i).sum())
                .fold(0.0, f64::max);
            a *= (0.3 + 1.2 * rng.next()) / worst;
            assert_same_roots(&a, &delays, &format!("random trial {trial}"), true);
        }
    }

    #[test]
    fn the_rightmost_roots_of_a_random_digraph_are_the_rightmost() {
        // A random digraph of 120 (a ring and three random arcs per driver). Unconverged Ritz
        // values crowd around its rightmost root and once took most of the Newton candidates'
        // places: the solve reported its sixth root as the fourth. The converged ones now come
        // first. Oracle: argument-principle counts just left of each reported root's real part,
        // 2k roots for the k-th pair.
        let (a, delays) = family_random_digraph(120, &mut Lcg(2000), (0.3, 0.4));
        let r = rightmost_roots_shift_invert(&a, &delays, &CollocationOptions::default()).unwrap();
        assert_eq!(r.roots.len(), 4);
        let l = laplacian(&a);
        for (k, root) in r.roots.iter().enumerate() {
            let root = Complex64::from(root.root);
            assert!(root.re > 0.0 && root.im > 0.0, "{root}");
            let right = count_with_laplacian(&l, 1.0, &delays, root.re - 1e-6)
                .unwrap()
                .count;
            assert_eq!(right, 2 * (k + 1), "right of the root {root}");
        }
    }

    #[test]
    fn shift_invert_counts_repeated_roots() {
        // Symmetric ring: every non-consensus root is double (λ_k = λ_{N−k}); all-to-all with
        // equal delays: the root W_0(−Nkα)/α has multiplicity N − 1 = 4.
        let ring = UniformRing::new(9, 0.6, 0.6, 0.8).unwrap();
        assert_same_roots(&ring.adjacency(), &ring.delays(), "symmetric ring", true);
        let a = DMatrix::from_fn(5, 5, |i, j| if i == j { 0.0 } else { 0.1 });
        assert_same_roots(&a, &[0.5; 5], "all-to-all", false);
        let fast =
            rightmost_roots_shift_invert(&a, &[0.5; 5], &CollocationOptions::default()).unwrap();
        assert_eq!(fast.roots[0].multiplicity, 4);
    }
}
