//! The eigenvalues of a real matrix from its real Schur form, without the Schur vectors.
//!
//! Every eigenvalue step of this crate (the collocated generator's dense spectrum, the
//! reference count's Laplacian, the CACC closed loop) needs the eigenvalues alone, yet
//! `nalgebra::linalg::Schur::try_new` also forms the Hessenberg reduction's orthogonal factor
//! and updates it, and the whole of `T`, with every reflection. Its eigenvalue-only entry
//! (`complex_eigenvalues` on a matrix) has no iteration cap, and on the exactly repeated roots
//! of symmetric graphs it does not return. [`schur_eigenvalues`] is the same implicit
//! double-shift (Francis) iteration as `Schur::try_new`, with the same deflation test and the
//! same cap, applied with nalgebra's own reflections and rotations, but only to the rows and
//! columns of the active block (LAPACK's `dlahqr` without `wantt`/`wantz`): a reflection's
//! effect on the active block never depends on the entries outside it, so the eigenvalues are
//! the same bits as those of `Schur::try_new(..).complex_eigenvalues()`, and the iteration
//! gives up at the same sweep. The tests compare both, bit for bit, on random, structured and
//! repeated-root matrices.
//!
//! Restricted to the active block, a sweep costs `O(m²)` for a block of order `m` instead of
//! `O(N·m)` for `T` and `O(N·m)` more for the vectors; the Householder reduction to
//! Hessenberg form is the same.

use nalgebra::linalg::givens::GivensRotation;
use nalgebra::linalg::{householder, Hessenberg};
use nalgebra::{Const, DMatrix, DVector, Dyn, Matrix2, Reflection, Unit, Vector2, Vector3};
use num_complex::Complex64;

/// The eigenvalues of `a` (square), in the order of its real Schur form's diagonal, complex
/// pairs as `(re + i·im, re − i·im)`; `None` when the iteration has not converged after
/// `max_sweeps` double-shift sweeps (each deflated 2 × 2 block counts as one), exactly when
/// `Schur::try_new(a, eps, max_sweeps)` returns `None`.
///
/// `eps` is the deflation threshold, relative to the two neighbouring diagonal entries (an
/// absolute floor of `eps²` below that). `max_sweeps` must be positive (nalgebra reads 0 as
/// "no cap"; so does this function, which is why no caller passes it).
pub(crate) fn schur_eigenvalues(
    mut t: DMatrix<f64>,
    eps: f64,
    max_sweeps: usize,
) -> Option<Vec<Complex64>> {
    assert!(t.is_square(), "eigenvalues of a non-square matrix");
    debug_assert!(max_sweeps > 0, "a cap of 0 sweeps means none");
    let dim = t.nrows();
    match dim {
        0 => return Some(Vec::new()),
        1 => return Some(vec![Complex64::new(t[(0, 0)], 0.0)]),
        // nalgebra decouples a 2 × 2 matrix as it is (no scaling, no iteration).
        2 => {
            split_real_pair(&mut t, 0);
            return Some(block_eigenvalues(&t, 1.0));
        }
        _ => {}
    }
    let amax = t.camax();
    if amax != 0.0 {
        t.unscale_mut(amax);
    }
    let mut t = Hessenberg::new(t).unpack_h();
    let mut work = DVector::<f64>::zeros(dim);

    let mut sweeps = 0;
    let (mut start, mut end) = delimit(&mut t, eps, dim - 1);
    while end != start {
        if end - start + 1 > 2 {
            sweep(&mut t, &mut work, start, end);
        } else {
            split_real_pair(&mut t, start);
            if end > 2 {
                end -= 2;
            } else {
                break;
            }
        }
        (start, end) = delimit(&mut t, eps, end);
        sweeps += 1;
        if sweeps == max_sweeps {
            return None;
        }
    }
    Some(block_eigenvalues(&t, amax))
}

/// One implicit double-shift sweep over the active block `start..=end` (order above 2), its
/// shifts the eigenvalues of the trailing 2 × 2 block: the bulge is brought in at `start` by a
/// 3-reflection and chased down to `end`, each reflection applied to the block's rows from the
/// left and to its columns from the right.
fn sweep(t: &mut DMatrix<f64>, work: &mut DVector<f64>, start: usize, end: usize) {
    let (m, n) = (end - 1, end);
    let (h11, h12) = (t[(start, start)], t[(start, start + 1)]);
    let (h21, h22) = (t[(start + 1, start)], t[(start + 1, start + 1)]);
    let h32 = t[(start + 2, start + 1)];
    let (hnn, hmm, hnm, hmn) = (t[(n, n)], t[(m, m)], t[(n, m)], t[(m, n)]);
    let trace = hnn + hmm;
    let det = hnn * hmm - hnm * hmn;
    let mut axis = Vector3::new(
        h11 * h11 + h12 * h21 - trace * h11 + det,
        h21 * (h11 + h22 - trace),
        h21 * h32,
    );
    for k in start..n - 1 {
        let (norm, not_zero) = householder::reflection_axis_mut(&mut axis);
        if not_zero {
            if k > start {
                t[(k, k - 1)] = norm;
                t[(k + 1, k - 1)] = 0.0;
                t[(k + 2, k - 1)] = 0.0;
            }
            let reflection = Reflection::new(Unit::new_unchecked(axis), 0.0);
            // Rows k..k+2 over the block's columns from k; columns k..k+2 over its rows down
            // to the bulge's (k + 3) or the block's end.
            reflection.reflect(&mut t.generic_view_mut((k, k), (Const::<3>, Dyn(end + 1 - k))));
            let rows = (k + 4).min(end + 1) - start;
            reflection.reflect_rows(
                &mut t.generic_view_mut((start, k), (Dyn(rows), Const::<3>)),
                &mut work.rows_mut(0, rows),
            );
        }
        axis.x = t[(k + 1, k)];
        axis.y = t[(k + 2, k)];
        if k < n - 2 {
            axis.z = t[(k + 3, k)];
        }
    }
    let mut axis = Vector2::new(axis.x, axis.y);
    let (norm, not_zero) = householder::reflection_axis_mut(&mut axis);
    if not_zero {
        let reflection = Reflection::new(Unit::new_unchecked(axis), 0.0);
        t[(m, m - 1)] = norm;
        t[(n, m - 1)] = 0.0;
        reflection.reflect(&mut t.generic_view_mut((m, m), (Const::<2>, Dyn(end + 1 - m))));
        let rows = end + 1 - start;
        reflection.reflect_rows(
            &mut t.generic_view_mut((start, m), (Dyn(rows), Const::<2>)),
            &mut work.rows_mut(0, rows),
        );
    }
}

/// Triangularizes the 2 × 2 block at `at` when its eigenvalues are real (a rotation from both
/// sides, the block alone), as nalgebra's `compute_2x2_basis` does; a complex pair stays.
fn split_real_pair(t: &mut DMatrix<f64>, at: usize) {
    let h10 = t[(at + 1, at)];
    if h10 == 0.0 {
        return;
    }
    let (h00, h01, h11) = (t[(at, at)], t[(at, at + 1)], t[(at + 1, at + 1)]);
    // The discriminant as (a − d)²/4 + bc, non-negative for symmetric blocks.
    let half_difference = (h00 - h11) * 0.5;
    let discriminant = h10 * h01 + half_difference * half_difference;
    if discriminant < 0.0 || discriminant.is_nan() {
        return;
    }
    let root = discriminant.sqrt();
    let half_trace = (h00 + h11) * 0.5;
    let x1 = (half_trace + root) - h11;
    let x2 = (half_trace - root) - h11;
    // The larger first component, for a well-conditioned rotation.
    let x = if x1.abs() > x2.abs() { x1 } else { x2 };
    let rotation = GivensRotation::new(x, h10).0;
    let mut block: Matrix2<f64> = t.fixed_view::<2, 2>(at, at).into_owned();
    rotation.inverse().rotate(&mut block);
    rotation.rotate_rows(&mut block);
    block[(1, 0)] = 0.0;
    t.fixed_view_mut::<2, 2>(at, at).copy_from(&block);
}

/// The eigenvalues of a quasi-triangular `t` scaled back by `scale`: its diagonal, and each
/// 2 × 2 block with a non-zero subdiagonal entry as a conjugate pair.
fn block_eigenvalues(t: &DMatrix<f64>, scale: f64) -> Vec<Complex64> {
    let dim = t.nrows();
    let mut out = Vec::with_capacity(dim);
    let mut m = 0;
    while m + 1 < dim {
        let n = m + 1;
        if t[(n, m)] * scale == 0.0 {
            out.push(Complex64::new(t[(m, m)] * scale, 0.0));
            m += 1;
        } else {
            let (hmm, hnm, hmn, hnn) = (
                t[(m, m)] * scale,
                t[(n, m)] * scale,
                t[(m, n)] * scale,
                t[(n, n)] * scale,
            );
            let half_difference = (hmm - hnn) * 0.5;
            let discriminant = hnm * hmn + half_difference * half_difference;
            let imaginary = Complex64::new(0.0, (-discriminant).sqrt());
            let half_trace = Complex64::new((hnn + hmm) * 0.5, 0.0);
            out.push(half_trace + imaginary);
            out.push(half_trace - imaginary);
            m += 2;
        }
    }
    if m + 1 == dim {
        out.push(Complex64::new(t[(m, m)] * scale, 0.0));
    }
    out
}

/// The active block ending at or above `end`: the trailing subdiagonal entries that are
/// negligible are set to zero (deflation), then the block reaches up to the next negligible
/// one. `(0, 0)` when everything above `end` has deflated.
fn delimit(t: &mut DMatrix<f64>, eps: f64, end: usize) -> (usize, usize) {
    let negligible = |t: &DMatrix<f64>, row: usize| {
        let off = t[(row, row - 1)].abs();
        off <= eps * eps || off <= eps * (t[(row, row)].abs() + t[(row - 1, row - 1)].abs())
    };
    let mut n = end;
    while n > 0 {
        if !negligible(t, n) {
            break;
        }
        t[(n, n - 1)] = 0.0;
        n -= 1;
    }
    if n == 0 {
        return (0, 0);
    }
    let mut start = n - 1;
    while start > 0 {
        if t[(start, start - 1)] == 0.0 || negligible(t, start) {
            t[(start, start - 1)] = 0.0;
            break;
        }
        start -= 1;
    }
    (start, n)
}

#[cfg(test)]
mod tests {
    use super::super::collocation::tests::Lcg;
    use super::*;
    use nalgebra::linalg::Schur;

    /// nalgebra's eigenvalues through the full Schur form (vectors and all of `T`).
    fn reference(a: &DMatrix<f64>, eps: f64, cap: usize) -> Option<Vec<Complex64>> {
        Schur::try_new(a.clone(), eps, cap)
            .map(|s| s.complex_eigenvalues().iter().copied().collect())
    }

    fn bits(values: &Option<Vec<Complex64>>) -> Option<Vec<(u64, u64)>> {
        values
            .as_ref()
            .map(|v| v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect())
    }

    fn assert_same_bits(a: &DMatrix<f64>, eps: f64, cap: usize, what: &str) {
        let ours = schur_eigenvalues(a.clone(), eps, cap);
        let theirs = reference(a, eps, cap);
        assert_eq!(
            bits(&ours),
            bits(&theirs),
            "{what}: ours {ours:?}, nalgebra's {theirs:?}"
        );
    }

    fn random(n: usize, rng: &mut Lcg) -> DMatrix<f64> {
        DMatrix::from_fn(n, n, |_, _| rng.next() * 2.0 - 1.0)
    }

    #[test]
    fn random_matrices_give_nalgebras_eigenvalues_bit_for_bit() {
        let mut rng = Lcg(7);
        for n in (1..=12).chain([17, 25, 40, 63]) {
            for _ in 0..4 {
                let a = random(n, &mut rng);
                assert_same_bits(&a, f64::EPSILON, 30 * n.max(10), &format!("random {n}×{n}"));
            }
        }
    }

    #[test]
    fn structured_matrices_give_nalgebras_eigenvalues_bit_for_bit() {
        let mut rng = Lcg(11);
        // Block triangular (zero subdiagonals from the start), a Laplacian of a directed ring
        // with repeated circulant structure, a symmetric one, a companion matrix, zero and
        // identity.
        let mut blocks = random(20, &mut rng);
        for (i, j) in [(5, 4), (6, 5), (12, 11), (19, 18)] {
            blocks[(i, j)] = 0.0;
            for r in i..20 {
                for c in 0..i {
                    blocks[(r, c)] = 0.0;
                }
            }
        }
        let ring = DMatrix::from_fn(16, 16, |i, j| {
            if i == j {
                1.0
            } else if j == (i + 1) % 16 {
                -1.0
            } else {
                0.0
            }
        });
        let all_to_all = DMatrix::from_fn(12, 12, |i, j| if i == j { 11.0 } else { -1.0 });
        let companion = DMatrix::from_fn(9, 9, |i, j| match (i, j) {
            (0, _) => -((j + 1) as f64),
            (i, j) if i == j + 1 => 1.0,
            _ => 0.0,
        });
        let big = DMatrix::from_fn(30, 30, |i, j| {
            1e150 * ((i * 31 + j * 7) % 13) as f64 - 6e150
        });
        let cases = [
            ("block triangular", blocks),
            ("directed ring", ring),
            ("all to all", all_to_all),
            ("companion", companion),
            ("zero", DMatrix::zeros(7, 7)),
            ("identity", DMatrix::identity(7, 7)),
            ("large entries", big),
        ];
        for (what, a) in &cases {
            for eps in [f64::EPSILON, 1e-14, 1e-12] {
                assert_same_bits(a, eps, 30 * a.nrows().max(10), what);
            }
        }
    }

    #[test]
    fn the_cap_stops_it_at_the_same_sweep_as_nalgebras() {
        // Low caps on random and repeated-root matrices: both give up, or neither, and
        // agree when they do not.
        let mut rng = Lcg(3);
        let a = random(24, &mut rng);
        let all_to_all = DMatrix::from_fn(10, 10, |i, j| if i == j { 9.0 } else { -1.0 });
        let mut gave_up = 0;
        for cap in 1..60 {
            for m in [&a, &all_to_all] {
                assert_same_bits(m, f64::EPSILON, cap, &format!("cap {cap}"));
                gave_up += usize::from(schur_eigenvalues(m.clone(), f64::EPSILON, cap).is_none());
            }
        }
        assert!(
            gave_up > 10,
            "the low caps stopped the iteration only {gave_up} times"
        );
    }

    #[test]
    fn the_eigenvalues_are_the_spectrum() {
        // Independent of nalgebra: a triangular matrix's diagonal, and the trace and the sum
        // of squares (trace of A²) of a random one.
        let triangular =
            DMatrix::from_fn(8, 8, |i, j| if i <= j { (i + 2 * j) as f64 } else { 0.0 });
        let mut values: Vec<f64> = schur_eigenvalues(triangular, f64::EPSILON, 300)
            .unwrap()
            .iter()
            .map(|z| {
                assert_eq!(z.im, 0.0);
                z.re
            })
            .collect();
        values.sort_by(f64::total_cmp);
        assert_eq!(values, (0..8).map(|i| (3 * i) as f64).collect::<Vec<_>>());

        let mut rng = Lcg(5);
        let a = random(30, &mut rng);
        let z = schur_eigenvalues(a.clone(), f64::EPSILON, 300).unwrap();
        let trace: Complex64 = z.iter().sum();
        let trace_sq: Complex64 = z.iter().map(|z| z * z).sum();
        assert!((trace.re - a.trace()).abs() < 1e-12 && trace.im.abs() < 1e-12);
        assert!((trace_sq.re - (&a * &a).trace()).abs() < 1e-11 && trace_sq.im.abs() < 1e-11);
    }
}
