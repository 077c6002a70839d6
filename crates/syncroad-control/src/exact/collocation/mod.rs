//! Rightmost characteristic roots of the delayed-driver network for any weighted graph and
//! heterogeneous delays.
//!
//! The network of eq. `chandler+`, `v_i'(t) = u_i(t − α_i)`, `u_i = Σ_j a_ij (v_j − v_i)`,
//! has the characteristic matrix `M(s) = sI + diag(e^{−sα_i}) L` with `L = D − A`. The root
//! `s = 0` (eigenvector `1`) is consensus and is simple when the graph has a directed spanning
//! tree; synchronization is exponentially stable iff every other root has `Re s < 0`.
//!
//! Method:
//! 1. **Collocation of the infinitesimal generator.** The state is `v(t)` together with each
//!    delayed driver's input history `φ_i(θ) = u_i(t + θ)`, `θ ∈ [−α_i, 0]`. The generator is
//!    `λ v_i = φ_i(−α_i)`, `λ φ_i = dφ_i/dθ` with the boundary condition `φ_i(0) = −(Lv)_i`.
//!    Each `φ_i` is collocated on `M + 1` Chebyshev points of its own interval, the boundary
//!    node is eliminated, giving a matrix of order `N + M·#{i : α_i > 0}` whose eigenvalues
//!    approximate the roots spectrally well (drivers without delay need no history). The
//!    consensus root is reproduced exactly (`v = 1`, `φ = 0`), so exactly one eigenvalue
//!    near 0 is discarded.
//! 2. **Newton refinement** of the rightmost candidates on `[M(s)x = 0, cᴴx = 1]`, the accuracy
//!    being certified by `σ_min(M(s))/σ_max(M(s))`.
//!
//! The method's steps live in their own files: `network` (checking the input, the Laplacian),
//! `generator` (the collocation matrix and its eigenvalues), `arnoldi` (its rightmost
//! eigenvalues without the dense Schur form, for large networks), `refine` (the
//! characteristic matrix, Newton refinement and multiplicities); this file holds the reports,
//! [`rightmost_roots`] (dense) and [`rightmost_roots_shift_invert`], which run the steps.
//!
//! # Reference
//! D. Breda, S. Maset, R. Vermiglio, "Pseudospectral differencing methods for characteristic
//! roots of delay differential equations", SIAM J. Sci. Comput. 27 (2005) 482–495.
//! L. N. Trefethen, *Spectral Methods in MATLAB*, SIAM 2000, ch. 6 (Chebyshev differentiation).

use nalgebra::DMatrix;
use num_complex::Complex64;
use rayon::prelude::*;
use serde::Serialize;

use super::banded::NetworkMatrix;
use super::Root;

mod arnoldi;
mod generator;
mod network;
mod refine;

pub(crate) use generator::eigenvalues;
use generator::{default_nodes, generator_matrix};
pub(crate) use network::{laplacian, validate_network};
pub use refine::characteristic_matrix;
pub(crate) use refine::newton_refine;
use refine::{assign_multiplicities, newton_on_band, root_residuals};

/// Invalid network data or a failed root computation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CollocationError {
    /// The adjacency matrix is not square.
    #[error("adjacency matrix must be square, got {rows}×{cols}")]
    AdjacencyNotSquare {
        /// Number of rows.
        rows: usize,
        /// Number of columns.
        cols: usize,
    },
    /// Fewer than two vehicles: there is nothing to synchronize.
    #[error("the network needs at least 2 vehicles, got {vehicles}")]
    TooFewVehicles {
        /// Number of vehicles.
        vehicles: usize,
    },
    /// The delay vector does not have one entry per vehicle.
    #[error("{delays} delays given for {vehicles} vehicles")]
    DelayCountMismatch {
        /// Number of delays.
        delays: usize,
        /// Number of vehicles.
        vehicles: usize,
    },
    /// A coupling gain is negative or not finite.
    #[error("coupling gain a[{row}][{col}] = {value} must be finite and ≥ 0")]
    InvalidGain {
        /// Row (the reacting driver `i`).
        row: usize,
        /// Column (the observed vehicle `j`).
        col: usize,
        /// The offending value.
        value: f64,
    },
    /// A driver is coupled to itself.
    #[error("adjacency diagonal a[{vehicle}][{vehicle}] = {value} must be 0")]
    NonZeroDiagonal {
        /// The vehicle.
        vehicle: usize,
        /// The offending value.
        value: f64,
    },
    /// A delay is negative or not finite.
    #[error("delay α[{vehicle}] = {delay_s} s must be finite and ≥ 0")]
    InvalidDelay {
        /// The vehicle.
        vehicle: usize,
        /// The offending delay \[s\].
        delay_s: f64,
    },
    /// Without a directed spanning tree the consensus root is multiple and the velocities
    /// do not synchronize for any gains.
    #[error("the interaction graph has no directed spanning tree (vehicle {unreached} is not reached from any single vehicle); velocities cannot synchronize")]
    NoSpanningTree {
        /// A vehicle not reachable from the best candidate root.
        unreached: usize,
    },
    /// The eigenvalue iteration of the collocation matrix did not converge.
    #[error("eigenvalues of the {order}×{order} collocation matrix did not converge")]
    EigenvaluesFailed {
        /// Order of the collocation matrix.
        order: usize,
    },
    /// The root search produced no non-consensus root.
    #[error("no characteristic root other than consensus was found")]
    NoRoots,
}

/// Largest network for the dense collocation ([`rightmost_roots`]) when the shift-invert
/// roots are not certified: its eigenvalue step costs `O((N·M)³)`, about 0.4 s at `N = 50`.
pub const DENSE_SOLVE_LIMIT: usize = 150;

/// Options of [`rightmost_roots`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CollocationOptions {
    /// Chebyshev intervals `M` per delayed driver; `None` picks
    /// `clamp(8 + ⌈2ρ⌉, 8, 40)` with `ρ = max_i 2 d_i^+ α_i`. The collocation only has to
    /// place the rightmost roots in Newton's basin and rank them, so a modest `M` suffices
    /// (the cost of the dense eigenvalue step grows like `(N·M)³`).
    pub nodes_per_delay: Option<usize>,
    /// Number of distinct roots (upper half plane, by decreasing real part) to report.
    pub roots: usize,
    /// Newton stops when the relative step is below this.
    pub newton_tolerance: f64,
    /// Newton iteration cap.
    pub max_newton_steps: usize,
}

impl Default for CollocationOptions {
    fn default() -> Self {
        CollocationOptions {
            nodes_per_delay: None,
            roots: 4,
            newton_tolerance: 1e-14,
            max_newton_steps: 40,
        }
    }
}

/// A refined characteristic root with its certificate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RefinedRoot {
    /// The root `s` [1/s].
    pub root: Root,
    /// `σ_min(M(s)) / σ_max(M(s))`: zero at an exact root.
    pub residual: f64,
    /// `‖M(s)x‖ / (‖M(s)‖_F ‖x‖)` for the Newton null vector `x`.
    pub null_vector_residual: f64,
    /// Newton steps used.
    pub newton_steps: usize,
    /// Whether Newton met its tolerance.
    pub converged: bool,
    /// Multiplicity of the root as a zero of `det M(s)`.
    pub multiplicity: usize,
}

/// Rightmost roots of `det(sI + diag(e^{−sα_i})L) = 0` other than consensus.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RootsReport {
    /// Number of vehicles `N`.
    pub vehicles: usize,
    /// Chebyshev intervals per delayed driver used.
    pub nodes_per_delay: usize,
    /// Order of the collocation matrix.
    pub collocation_order: usize,
    /// Rightmost roots (upper half plane, decreasing real part).
    pub roots: Vec<RefinedRoot>,
    /// Spectral abscissa over the non-consensus roots [1/s]; `< 0` means the velocities
    /// synchronize exponentially.
    pub abscissa: f64,
    /// Largest residual `σ_min/σ_max` among the reported roots.
    pub max_residual: f64,
}

impl RootsReport {
    /// `true` iff every non-consensus root has negative real part.
    pub fn is_stable(&self) -> bool {
        self.abscissa < 0.0
    }
}

/// Rightmost characteristic roots of the delayed-driver network (eq. `chandler+`) other than
/// the consensus root, and the spectral abscissa.
///
/// `adjacency` holds `a_ij ≥ 0` (driver `i` reacting to vehicle `j`) with zero diagonal;
/// `delays_s[i]` is driver `i`'s reaction delay `α_i` \[s\] (zero allowed).
///
/// # Errors
/// [`CollocationError`] for malformed input, a graph without a directed spanning tree, or a
/// failed eigenvalue iteration.
pub fn rightmost_roots(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
) -> Result<RootsReport, CollocationError> {
    let n = validate_network(adjacency, delays_s)?;
    let l = laplacian(adjacency);
    let m = options
        .nodes_per_delay
        .unwrap_or_else(|| default_nodes(&l, delays_s))
        .max(2);
    let a = generator_matrix(&l, delays_s, m);
    let order = a.nrows();
    let all = eigenvalues(a)?;
    let mut eig = all.clone();
    // Discard the consensus eigenvalue (the one closest to 0).
    if let Some(pos) = eig
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.norm().total_cmp(&b.1.norm()))
        .map(|(p, _)| p)
    {
        eig.swap_remove(pos);
    }
    eig.retain(|z| z.im >= -1e-9 * (1.0 + z.norm()));
    eig.sort_by(|a, b| b.re.total_cmp(&a.re));
    let scale = l.diagonal().max().max(1e-300);
    let mut refined: Vec<RefinedRoot> = Vec::new();
    let candidates = (2 * options.roots + 4).min(eig.len());
    for &z in eig.iter().take(candidates) {
        let mut r = newton_refine(&l, delays_s, z, options);
        let s: Complex64 = r.root.into();
        if s.norm() < 1e-9 * scale {
            continue; // Newton fell into the consensus root
        }
        if s.im < 0.0 {
            r.root = s.conj().into();
        }
        let s: Complex64 = r.root.into();
        if s.im.abs() < 1e-12 * (1.0 + s.norm()) {
            r.root.im = 0.0;
        }
        if refined
            .iter()
            .any(|q| (Complex64::from(q.root) - s).norm() < 1e-8 * (1.0 + s.norm()))
        {
            continue;
        }
        refined.push(r);
    }
    if refined.is_empty() {
        return Err(CollocationError::NoRoots);
    }
    refined.sort_by(|a, b| b.root.re.total_cmp(&a.root.re));
    refined.truncate(options.roots.max(1));
    assign_multiplicities(&l, delays_s, &all, &mut refined);
    let abscissa = refined[0].root.re;
    let max_residual = refined.iter().map(|r| r.residual).fold(0.0, f64::max);
    Ok(RootsReport {
        vehicles: n,
        nodes_per_delay: m,
        collocation_order: order,
        roots: refined,
        abscissa,
        max_residual,
    })
}

/// [`rightmost_roots`] for large networks: the candidates from shift-invert Arnoldi on the
/// same collocation matrix instead of its dense Schur form (`arnoldi`), refined by Newton on
/// `det M(s)` with a band LU, multiplicities from small contour integrals.
///
/// The dense solve finds every collocation eigenvalue; this one only those near its shifts,
/// so its answer must be certified ([`super::report::certify_roots`]); where the certificate
/// fails, [`super::report::analyse_network`] falls back to [`rightmost_roots`]. Roots far from
/// the axis (beyond `1.2 max_i 2d_i^+` in frequency) may be left out, so fewer than
/// `options.roots` can be reported.
///
/// # Errors
/// As [`rightmost_roots`]; [`CollocationError::NoRoots`] when no candidate converged.
pub fn rightmost_roots_shift_invert(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
) -> Result<RootsReport, CollocationError> {
    shift_invert(adjacency, delays_s, options, true)
}

/// [`rightmost_roots_shift_invert`] without the residuals (`NaN`): for the solves inside the
/// critical search, which only follows their roots and certifies its crossing by root counts
/// (a dense SVD of `M(s)` per root, about a quarter of such a solve on 400 drivers).
pub(crate) fn rightmost_roots_shift_invert_unchecked(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
) -> Result<RootsReport, CollocationError> {
    shift_invert(adjacency, delays_s, options, false)
}

/// A Ritz value whose error bound is below this (relative to `1 + |λ|`) is converged: Newton
/// refines it to the root it stands for.
const RITZ_CONVERGED: f64 = 1e-4;

fn shift_invert(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    options: &CollocationOptions,
    residuals: bool,
) -> Result<RootsReport, CollocationError> {
    let n = validate_network(adjacency, delays_s)?;
    let l = laplacian(adjacency);
    let m = options
        .nodes_per_delay
        .unwrap_or_else(|| default_nodes(&l, delays_s))
        .max(2);
    let delayed = delays_s.iter().filter(|&&a| a > 0.0).count();
    let order = n + m * delayed;
    let band = NetworkMatrix::new(&l, delays_s);
    let reach = 1.2 * l.diagonal().iter().fold(0.0f64, |a, &d| a.max(2.0 * d));
    let mut eig = arnoldi::eigenvalues_near_axis(&l, delays_s, m, &band, reach);
    eig.retain(|(z, _)| z.im >= -1e-9 * (1.0 + z.norm()));
    // The converged Ritz values first, each class from the right: the unconverged ones crowd
    // around the rightmost root on dense graphs and would take every candidate's place.
    let converged = |&(z, error): &(Complex64, f64)| error <= RITZ_CONVERGED * (1.0 + z.norm());
    eig.sort_by(|a, b| {
        converged(b)
            .cmp(&converged(a))
            .then(b.0.re.total_cmp(&a.0.re))
    });
    // Neighbouring shifts find the same eigenvalues.
    let mut candidates: Vec<Complex64> = Vec::new();
    for (z, _) in eig {
        if candidates
            .iter()
            .all(|q| (q - z).norm() > 1e-7 * (1.0 + z.norm()))
        {
            candidates.push(z);
        }
    }
    let scale = l.diagonal().max().max(1e-300);
    let mut refined: Vec<RefinedRoot> = Vec::new();
    // Each candidate's Newton iteration is independent: run in parallel, their roots taken in
    // the candidates' order (the result does not depend on the threads).
    let polished: Vec<_> = candidates
        .par_iter()
        .take(2 * options.roots + 5)
        .map(|&z| newton_on_band(&band, z, options))
        .collect();
    for (mut s, multiplicity, newton_steps, converged) in polished.into_iter().flatten() {
        if s.norm() < 1e-9 * scale {
            continue; // the consensus root
        }
        if s.im < 0.0 {
            s = s.conj();
        }
        if s.im.abs() < 1e-12 * (1.0 + s.norm()) {
            s.im = 0.0;
        }
        if refined
            .iter()
            .any(|q| (Complex64::from(q.root) - s).norm() < 1e-8 * (1.0 + s.norm()))
        {
            continue;
        }
        refined.push(RefinedRoot {
            root: s.into(),
            residual: 0.0,
            null_vector_residual: 0.0,
            newton_steps,
            converged,
            multiplicity,
        });
    }
    if refined.is_empty() {
        return Err(CollocationError::NoRoots);
    }
    refined.sort_by(|a, b| b.root.re.total_cmp(&a.root.re));
    refined.truncate(options.roots.max(1));
    // Each residual is a dense SVD of M(s): the roots' in parallel.
    refined.par_iter_mut().for_each(|r| {
        (r.residual, r.null_vector_residual) = if residuals {
            root_residuals(&l, delays_s, &band, r.root.into())
        } else {
            (f64::NAN, f64::NAN)
        };
    });
    let abscissa = refined[0].root.re;
    let max_residual = if residuals {
        refined.iter().map(|r| r.residual).fold(0.0, f64::max)
    } else {
        f64::NAN
    };
    Ok(RootsReport {
        vehicles: n,
        nodes_per_delay: m,
        collocation_order: order,
        roots: refined,
        abscissa,
        max_residual,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::ring_modes::UniformRing;
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::DVector;
    use std::f64::consts::PI;

    /// Deterministic pseudo-random numbers in [0, 1) (xorshift), to keep tests reproducible.
    pub(crate) struct Lcg(pub(crate) u64);
    impl Lcg {
        pub(crate) fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Random strongly connected graph: a ring backbone plus random extra arcs.
    pub(crate) fn random_network(n: usize, rng: &mut Lcg) -> (DMatrix<f64>, Vec<f64>) {
        let mut a = DMatrix::zeros(n, n);
        for i in 0..n {
            a[(i, (i + n - 1) % n)] = 0.2 + rng.next();
            for j in 0..n {
                if j != i && rng.next() < 0.15 {
                    a[(i, j)] += rng.next();
                }
            }
        }
        let delays = (0..n).map(|_| 0.2 + 1.5 * rng.next()).collect();
        (a, delays)
    }

    /// A random digraph of the stability families (`scripts/stability-families.py`): a ring
    /// and three random arcs per driver, gains `gain.0 + gain.1·U(0, 1)`, delays 0.2–0.8 s.
    pub(crate) fn family_random_digraph(
        n: usize,
        rng: &mut Lcg,
        gain: (f64, f64),
    ) -> (DMatrix<f64>, Vec<f64>) {
        denser_random_digraph(n, 3, rng, gain)
    }

    /// [`family_random_digraph`] with `arcs` random arcs per driver.
    pub(crate) fn denser_random_digraph(
        n: usize,
        arcs: usize,
        rng: &mut Lcg,
        gain: (f64, f64),
    ) -> (DMatrix<f64>, Vec<f64>) {
        let mut a = DMatrix::zeros(n, n);
        for i in 0..n {
            a[(i, (i + n - 1) % n)] = gain.0 + gain.1 * rng.next();
            for _ in 0..arcs {
                let j = (rng.next() * n as f64) as usize % n;
                if j != i && a[(i, j)] == 0.0 {
                    a[(i, j)] = gain.0 + gain.1 * rng.next();
                }
            }
        }
        let delays = (0..n).map(|_| 0.2 + 0.6 * rng.next()).collect();
        (a, delays)
    }

    #[test]
    fn scalar_chandler_follower_crosses_at_alpha_k_pi_over_two() {
        // Leader-follower straight road reduced to one mode: two vehicles where only vehicle 1
        // reacts (a_10 = K) is s(s + K e^{−sα}) = 0; the non-consensus root is that of
        // s + K e^{−sα} = 0, stable iff αK < π/2, with roots ±iK exactly at αK = π/2.
        let alpha = 0.8;
        for &(ak, stable) in &[(1.0, true), (1.5, true), (1.6, false), (3.0, false)] {
            let a = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, ak / alpha, 0.0]);
            let r = rightmost_roots(&a, &[alpha, alpha], &CollocationOptions::default()).unwrap();
            assert_eq!(r.is_stable(), stable, "αK = {ak}");
            assert!(r.max_residual < 1e-13);
        }
        let k = PI / 2.0 / alpha;
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 0.0, k, 0.0]);
        let r = rightmost_roots(&a, &[alpha, alpha], &CollocationOptions::default()).unwrap();
        assert!(r.abscissa.abs() < 1e-12);
        assert_relative_eq!(r.roots[0].root.im, k, max_relative = 1e-12);
    }

    #[test]
    fn full_solve_matches_fourier_path_on_uniform_rings() {
        for &(n, kf, kb, alpha) in &[
            (10usize, 1.0, 0.0, 0.3),
            (12, 0.6, 0.4, 0.9),
            (20, 1.2, 0.3, 0.5),
            (30, 0.5, 0.5, 1.0),
        ] {
            let ring = UniformRing::new(n, kf, kb, alpha).unwrap();
            let fast = ring.modes().unwrap();
            let full = rightmost_roots(
                &ring.adjacency(),
                &ring.delays(),
                &CollocationOptions::default(),
            )
            .unwrap();
            assert_relative_eq!(full.abscissa, fast.abscissa, epsilon = 1e-11);
            // Every reported root is one of the mode roots on some branch.
            for r in &full.roots {
                let s: Complex64 = r.root.into();
                let hit = (0..n).any(|k| {
                    (-2i64..=2).any(|b| {
                        ring.mode_root(k, b)
                            .map(|z| (z - s).norm() < 1e-9 || (z.conj() - s).norm() < 1e-9)
                            .unwrap_or(false)
                    })
                });
                assert!(hit, "N={n}: root {s} is not a mode root");
            }
        }
    }

    #[test]
    fn theorem_one_holds_on_random_heterogeneous_networks() {
        // Theorem thm.delay-agent: strongly connected and α_j d_j^+ < 1/2 ⇒ synchronization.
        let mut rng = Lcg(0x9e37_79b9_7f4a_7c15);
        for trial in 0..25 {
            let n = 3 + trial % 8;
            let (mut a, delays) = random_network(n, &mut rng);
            let worst = (0..n)
                .map(|i| delays[i] * a.row(i).sum())
                .fold(0.0, f64::max);
            // Scale gains so that the worst driver has α_j d_j^+ = 0.499 < 1/2.
            a *= 0.499 / worst;
            let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
            assert!(r.abscissa < 0.0, "trial {trial}: abscissa {}", r.abscissa);
            assert!(
                r.max_residual < 1e-12,
                "trial {trial}: residual {}",
                r.max_residual
            );
            assert!(r
                .roots
                .iter()
                .all(|q| q.converged && q.null_vector_residual < 1e-13));
        }
    }

    #[test]
    fn abscissa_is_insensitive_to_the_number_of_collocation_nodes() {
        let mut rng = Lcg(42);
        let (a, delays) = random_network(7, &mut rng);
        let coarse = CollocationOptions {
            nodes_per_delay: Some(12),
            ..Default::default()
        };
        let fine = CollocationOptions {
            nodes_per_delay: Some(30),
            ..Default::default()
        };
        let r1 = rightmost_roots(&a, &delays, &coarse).unwrap();
        let r2 = rightmost_roots(&a, &delays, &fine).unwrap();
        assert_relative_eq!(r1.abscissa, r2.abscissa, epsilon = 1e-11);
    }

    #[test]
    fn default_node_count_agrees_with_a_fine_discretization_beyond_theorem_one() {
        // Gains beyond Theorem 1 (worst α_j d_j^+ from 0.5 to 2) push roots far from the origin,
        // the hardest case for a coarse collocation.
        let mut rng = Lcg(2024);
        let fine = CollocationOptions {
            nodes_per_delay: Some(32),
            ..Default::default()
        };
        for trial in 0..10 {
            let n = 3 + trial % 7;
            let (mut a, delays) = random_network(n, &mut rng);
            let worst = (0..n)
                .map(|i| delays[i] * a.row(i).sum())
                .fold(0.0, f64::max);
            a *= (0.5 + 1.5 * rng.next()) / worst;
            let coarse = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
            let reference = rightmost_roots(&a, &delays, &fine).unwrap();
            assert_relative_eq!(coarse.abscissa, reference.abscissa, epsilon = 1e-11);
        }
    }

    #[test]
    fn undelayed_drivers_reduce_to_laplacian_eigenvalues() {
        // No delays: roots are −eig(L). A directed 3-cycle with unit weights has
        // eig(L) = 1 − e^{2πik/3}, i.e. roots −3/2 ± i√3/2.
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        let r = rightmost_roots(&a, &[0.0; 3], &CollocationOptions::default()).unwrap();
        assert_relative_eq!(r.abscissa, -1.5, epsilon = 1e-13);
        assert_relative_eq!(r.roots[0].root.im, 3f64.sqrt() / 2.0, epsilon = 1e-13);
    }

    /// Fixed-step trapezoid simulation of eq. `chandler+` with every delay a multiple of the
    /// step; returns the decay rate of the disagreement `(I − 11ᵀ/N)v`, measured between two
    /// windowed maxima.
    fn simulated_decay_rate(
        a: &DMatrix<f64>,
        delays: &[f64],
        h: f64,
        t_end: f64,
        window_s: f64,
    ) -> f64 {
        let n = a.nrows();
        let l = laplacian(a);
        let lags: Vec<usize> = delays.iter().map(|&d| (d / h).round() as usize).collect();
        let steps = (t_end / h).round() as usize;
        let max_lag = *lags.iter().max().unwrap();
        // History: a non-synchronized constant profile for t ≤ 0.
        let mut v: Vec<DVector<f64>> = Vec::with_capacity(steps + max_lag + 1);
        for _ in 0..=max_lag {
            v.push(DVector::from_fn(n, |i, _| (i as f64 * 1.3).sin()));
        }
        let rhs = |v: &Vec<DVector<f64>>, k: usize| -> DVector<f64> {
            DVector::from_fn(n, |i, _| {
                let past = &v[k - lags[i]];
                -(l.row(i) * past)[0]
            })
        };
        let spread = |x: &DVector<f64>| {
            let mean = x.mean();
            x.iter().map(|y| (y - mean).abs()).fold(0.0, f64::max)
        };
        let mut env = Vec::with_capacity(steps);
        for step in 0..steps {
            let k = max_lag + step;
            let f_now = rhs(&v, k);
            // All lags ≥ 1 step, so f at k + 1 only needs stored values: explicit trapezoid.
            let f_next = rhs(&v, k + 1);
            let next = &v[k] + (f_now + f_next) * (h / 2.0);
            env.push(spread(&next));
            v.push(next);
        }
        let window = (window_s / h) as usize;
        let max_on = |end: usize| env[end - window..end].iter().cloned().fold(0.0, f64::max);
        let (t1, t2) = (steps / 2, steps);
        (max_on(t2) / max_on(t1)).ln() / ((t2 - t1) as f64 * h)
    }

    #[test]
    fn simulated_decay_matches_the_predicted_abscissa() {
        // Heterogeneous 4-vehicle network, delays on a 1/400 s grid.
        let a = DMatrix::from_row_slice(
            4,
            4,
            &[
                0.0, 0.0, 0.3, 0.9, //
                1.1, 0.0, 0.0, 0.0, //
                0.2, 0.8, 0.0, 0.0, //
                0.0, 0.0, 1.0, 0.0,
            ],
        );
        let delays = [0.5, 0.75, 0.4, 0.6];
        let r = rightmost_roots(&a, &delays, &CollocationOptions::default()).unwrap();
        let gap = r.roots[0].root.re - r.roots[1].root.re;
        assert!(gap > 0.1, "dominant root not separated: {:?}", r.roots);
        let t_end = 30.0 / r.abscissa.abs();
        // Maxima over one oscillation period plus the longest delay.
        let window = 2.0 * PI / r.roots[0].root.im.max(0.1) + 0.75;
        let rate = simulated_decay_rate(&a, &delays, 1.0 / 400.0, t_end, window);
        assert_relative_eq!(rate, r.abscissa, max_relative = 0.01);
    }
}
