//! Uniform ring roads: Fourier modes and Lambert W roots (fast path and test oracle).
//!
//! On a circular road with `N` identical drivers (eq. `chandler+` with equal delays α), each
//! driver weighs its predecessor with `k_f` and its follower with `k_b`. The Laplacian
//! `L = D − A` is circulant, so the characteristic equation `det(sI + e^{−sα}L) = 0` splits
//! into `N` scalar equations
//!
//! `s + λ_k e^{−sα} = 0`,  `λ_k = k_f (1 − e^{−iθ_k}) + k_b (1 − e^{iθ_k})`,  `θ_k = 2πk/N`,
//!
//! with roots `s = W_j(−λ_k α)/α` on the branches `j` of Lambert W; branch 0 is the rightmost.
//! Mode `k = 0` (`λ_0 = 0`) is the consensus root `s = 0`.
//!
//! The critical gain of a mode has a closed form. For `λ = |λ| e^{iφ}` with `|φ| < π/2`, a root
//! `s = iω` of `s + cλ e^{−sα} = 0` requires `ω = c|λ|` and `ωα = φ + π/2 (mod 2π)`; the
//! smallest such gain is `c_k = (φ_k + π/2)/(α|λ_k|)`. For the unidirectional ring
//! (`k_b = 0`) this gives `αK_crit = (π/N) / (2 sin(π/N)) → 1/2` as `N → ∞`: the
//! Theorem-1 bound (eq. `degree1`) is asymptotically tight for long unidirectional rings,
//! whereas a single follower on a straight road is stable up to `αK = π/2`.

use super::lambert_w::{lambert_w, LambertWError};
use super::Root;
use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;
use std::f64::consts::{FRAC_PI_2, PI};

/// Invalid ring description or a failed mode evaluation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RingError {
    /// A ring needs at least two vehicles.
    #[error("a ring road needs at least 2 vehicles, got {vehicles}")]
    TooFewVehicles {
        /// Requested number of vehicles.
        vehicles: usize,
    },
    /// A gain is negative or not finite.
    #[error("ring gain {name} = {value} must be finite and ≥ 0")]
    InvalidGain {
        /// Which gain (`gain_front` or `gain_back`).
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// Both gains are zero: nobody reacts, the graph has no arcs.
    #[error(
        "ring gains gain_front and gain_back are both zero; the interaction graph has no arcs"
    )]
    NoCoupling,
    /// The delay is negative or not finite.
    #[error("ring delay_s = {delay_s} must be finite and ≥ 0")]
    InvalidDelay {
        /// The offending delay \[s\].
        delay_s: f64,
    },
    /// Lambert W failed for one mode.
    #[error("mode {mode}: {source}")]
    LambertW {
        /// Fourier index `k` of the mode.
        mode: usize,
        /// Underlying failure.
        source: LambertWError,
    },
}

/// A uniform ring road (circular road of eq. `chandler`, generalized to bidirectional
/// weights as allowed by eq. `chandler+`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct UniformRing {
    /// Number of vehicles `N` (≥ 2).
    pub vehicles: usize,
    /// Weight `k_f = a_{i,i−1}` [1/s] on the predecessor's relative speed.
    pub gain_front: f64,
    /// Weight `k_b = a_{i,i+1}` [1/s] on the follower's relative speed.
    pub gain_back: f64,
    /// Common driver reaction delay α \[s\].
    pub delay_s: f64,
}

/// One Fourier mode of a uniform ring and its rightmost root.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RingMode {
    /// Fourier index `k` (`0 ≤ k < N`); `k = 0` is consensus.
    pub index: usize,
    /// Wave number `θ_k = 2πk/N` \[rad\].
    pub theta_rad: f64,
    /// Laplacian eigenvalue `λ_k` [1/s].
    pub laplacian_eigenvalue: Root,
    /// Rightmost root `W_0(−λ_k α)/α` [1/s].
    pub root: Root,
    /// Gain scale `c_k` at which this mode reaches the imaginary axis (∞ for consensus).
    pub critical_gain_scale: f64,
}

/// All modes of a uniform ring with the summary numbers.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RingModes {
    /// The ring analysed.
    pub ring: UniformRing,
    /// Every mode, by Fourier index.
    pub modes: Vec<RingMode>,
    /// Spectral abscissa over all roots except the consensus root [1/s].
    pub abscissa: f64,
    /// Fourier index of the mode attaining the abscissa.
    pub dominant_mode: usize,
    /// Exact critical scale `c*` of all gains (`min_k c_k`).
    pub critical_gain_scale: f64,
    /// Theorem-1 scale `1/(2 α d^+)` with `d^+ = k_f + k_b` (eq. `degree1`).
    pub theorem1_gain_scale: f64,
    /// `c* / c_Theorem1` (≥ 1 whenever Theorem 1 is correct).
    pub conservatism_ratio: f64,
}

impl UniformRing {
    /// Checks and builds a ring description.
    ///
    /// # Errors
    /// [`RingError`] naming the offending field.
    pub fn new(
        vehicles: usize,
        gain_front: f64,
        gain_back: f64,
        delay_s: f64,
    ) -> Result<Self, RingError> {
        if vehicles < 2 {
            return Err(RingError::TooFewVehicles { vehicles });
        }
        for (name, value) in [("gain_front", gain_front), ("gain_back", gain_back)] {
            if !value.is_finite() || value < 0.0 {
                return Err(RingError::InvalidGain { name, value });
            }
        }
        if gain_front == 0.0 && gain_back == 0.0 {
            return Err(RingError::NoCoupling);
        }
        if !delay_s.is_finite() || delay_s < 0.0 {
            return Err(RingError::InvalidDelay { delay_s });
        }
        Ok(UniformRing {
            vehicles,
            gain_front,
            gain_back,
            delay_s,
        })
    }

    /// Adjacency matrix `A` of eq. `chandler+`: `a_{i,i−1} = k_f`, `a_{i,i+1} = k_b`
    /// (indices mod N; for `N = 2` both weights land on the one neighbour).
    pub fn adjacency(&self) -> DMatrix<f64> {
        let n = self.vehicles;
        let mut a = DMatrix::zeros(n, n);
        for i in 0..n {
            a[(i, (i + n - 1) % n)] += self.gain_front;
            a[(i, (i + 1) % n)] += self.gain_back;
        }
        a
    }

    /// Delays of all drivers, `α_i = α` \[s\].
    pub fn delays(&self) -> Vec<f64> {
        vec![self.delay_s; self.vehicles]
    }

    /// Laplacian eigenvalue `λ_k = k_f (1 − e^{−iθ_k}) + k_b (1 − e^{iθ_k})` of mode `k`,
    /// with eigenvector `(e^{iθ_k j})_j`.
    pub fn laplacian_eigenvalue(&self, k: usize) -> Complex64 {
        let (cos, sin) = unit_root(k, self.vehicles);
        let (kf, kb) = (self.gain_front, self.gain_back);
        Complex64::new((kf + kb) * (1.0 - cos), (kf - kb) * sin)
    }

    /// Root of mode `k` on Lambert W branch `branch`: `s = W_branch(−λ_k α)/α`
    /// (`s = −λ_k` without delay; only branch 0 exists then).
    ///
    /// # Errors
    /// [`RingError::LambertW`] if the branch is singular (consensus mode, `branch ≠ 0`).
    pub fn mode_root(&self, k: usize, branch: i64) -> Result<Complex64, RingError> {
        let lambda = self.laplacian_eigenvalue(k);
        if self.delay_s == 0.0 {
            return Ok(-lambda);
        }
        let w = lambert_w(branch, -lambda * self.delay_s)
            .map_err(|source| RingError::LambertW { mode: k, source })?;
        Ok(w / self.delay_s)
    }

    /// Closed-form critical gain scale of mode `k`: `(arg λ_k + π/2)/(α|λ_k|)`; infinite for
    /// the consensus mode and without delay (a delay-free ring is stable for every gain).
    pub fn mode_critical_gain_scale(&self, k: usize) -> f64 {
        let lambda = self.laplacian_eigenvalue(k);
        if k.is_multiple_of(self.vehicles) || self.delay_s == 0.0 || lambda.norm() == 0.0 {
            return f64::INFINITY;
        }
        (lambda.arg() + FRAC_PI_2) / (self.delay_s * lambda.norm())
    }

    /// Theorem-1 gain scale `1/(2 α (k_f + k_b))` (eq. `degree1`; ∞ without delay).
    pub fn theorem1_gain_scale(&self) -> f64 {
        1.0 / (2.0 * self.delay_s * (self.gain_front + self.gain_back))
    }

    /// Rightmost roots of all `N` modes via Lambert W (the fast path).
    ///
    /// # Errors
    /// [`RingError::LambertW`] if an evaluation fails to converge.
    pub fn modes(&self) -> Result<RingModes, RingError> {
        let n = self.vehicles;
        let mut modes = Vec::with_capacity(n);
        let mut abscissa = f64::NEG_INFINITY;
        let mut dominant_mode = 1;
        let mut critical = f64::INFINITY;
        for k in 0..n {
            let root = self.mode_root(k, 0)?;
            let c_k = self.mode_critical_gain_scale(k);
            if k > 0 {
                if root.re > abscissa {
                    abscissa = root.re;
                    dominant_mode = k;
                }
                critical = critical.min(c_k);
            }
            modes.push(RingMode {
                index: k,
                theta_rad: 2.0 * PI * k as f64 / n as f64,
                laplacian_eigenvalue: self.laplacian_eigenvalue(k).into(),
                root: root.into(),
                critical_gain_scale: c_k,
            });
        }
        let theorem1 = self.theorem1_gain_scale();
        Ok(RingModes {
            ring: *self,
            modes,
            abscissa,
            dominant_mode,
            critical_gain_scale: critical,
            theorem1_gain_scale: theorem1,
            conservatism_ratio: critical / theorem1,
        })
    }
}

/// `(cos θ, sin θ)` of `θ = 2πk/n`, exact at the quarter turns so that real modes (e.g.
/// `θ = π`) stay exactly real and their roots keep the conjugate-symmetric convention.
fn unit_root(k: usize, n: usize) -> (f64, f64) {
    let k = k % n;
    match (4 * k).cmp(&n) {
        std::cmp::Ordering::Equal => return (0.0, 1.0),
        _ if k == 0 => return (1.0, 0.0),
        _ if 2 * k == n => return (-1.0, 0.0),
        _ if 4 * k == 3 * n => return (0.0, -1.0),
        _ => {}
    }
    let theta = 2.0 * PI * k as f64 / n as f64;
    (theta.cos(), theta.sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Characteristic matrix `sI + e^{−sα}L` applied to the Fourier vector of mode `k`,
    /// built from the adjacency matrix (independent of the circulant formula).
    fn fourier_residual(ring: &UniformRing, k: usize, s: Complex64) -> f64 {
        let a = ring.adjacency();
        let n = ring.vehicles;
        let theta = 2.0 * PI * k as f64 / n as f64;
        let x: Vec<Complex64> = (0..n)
            .map(|j| Complex64::from_polar(1.0 / (n as f64).sqrt(), theta * j as f64))
            .collect();
        let e = (-s * ring.delay_s).exp();
        let mut worst: f64 = 0.0;
        for i in 0..n {
            let d: f64 = a.row(i).iter().sum();
            let mut lx = x[i] * d;
            for j in 0..n {
                lx -= x[j] * a[(i, j)];
            }
            worst = worst.max((s * x[i] + e * lx).norm());
        }
        worst
    }

    #[test]
    fn unidirectional_ring_at_its_closed_form_critical_gain_has_root_on_axis() {
        // k_b = 0: the critical mode is k = N−1 and αK* = (π/N)/(2 sin(π/N)); there the
        // mode root is exactly i|λ| with |λ| = 2K sin(π/N) (derived in the module docs).
        for &n in &[2usize, 3, 5, 10, 100, 1000] {
            let alpha = 0.7;
            let k_star = (PI / n as f64) / (2.0 * (PI / n as f64).sin()) / alpha;
            let ring = UniformRing::new(n, k_star, 0.0, alpha).unwrap();
            let modes = ring.modes().unwrap();
            assert_relative_eq!(modes.critical_gain_scale, 1.0, epsilon = 1e-12);
            let s = ring.mode_root(n - 1, 0).unwrap();
            let omega = 2.0 * k_star * (PI / n as f64).sin();
            assert!(s.re.abs() < 1e-12, "N={n}: Re s = {}", s.re);
            assert_relative_eq!(s.im, omega, max_relative = 1e-12);
            assert!(modes.abscissa.abs() < 1e-12);
            // Real gains: modes k and N−k are conjugate, either may be reported.
            assert!(modes.dominant_mode == n - 1 || modes.dominant_mode == 1);
        }
    }

    #[test]
    fn ring_roots_solve_the_full_characteristic_equation_for_n_up_to_1000() {
        for &n in &[2usize, 7, 30, 250, 1000] {
            let ring = UniformRing::new(n, 0.9, 0.35, 0.4).unwrap();
            let modes = ring.modes().unwrap();
            // The residual is O(N²) per mode; sample every 7th mode on the largest rings.
            let stride = if n > 300 { 7 } else { 1 };
            for mode in modes.modes.iter().step_by(stride) {
                let s: Complex64 = mode.root.into();
                let scale = 1.0 + s.norm();
                assert!(
                    fourier_residual(&ring, mode.index, s) < 1e-12 * scale,
                    "N={n} k={}",
                    mode.index
                );
            }
            assert_eq!(modes.modes[0].root, Root { re: 0.0, im: 0.0 });
        }
    }

    #[test]
    fn principal_branch_is_rightmost_for_every_ring_mode() {
        let ring = UniformRing::new(40, 1.1, 0.6, 0.5).unwrap();
        for k in 1..40 {
            let s0 = ring.mode_root(k, 0).unwrap();
            for branch in [-4i64, -3, -2, -1, 1, 2, 3, 4] {
                let s = ring.mode_root(k, branch).unwrap();
                if s.re >= s0.re {
                    // Only a real mode (θ = π here) has its conjugate root on branch ∓1.
                    assert_eq!(k, 20);
                    assert!(branch.abs() == 1 && (s - s0.conj()).norm() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn unidirectional_critical_gain_tends_to_one_half_from_above() {
        let mut previous = f64::INFINITY;
        for &n in &[2usize, 3, 4, 8, 16, 64, 1000, 100_000] {
            let ring = UniformRing::new(n, 1.0, 0.0, 1.0).unwrap();
            // αK* with α = K = 1 is the critical scale itself.
            let c = (1..n)
                .map(|k| ring.mode_critical_gain_scale(k))
                .fold(f64::INFINITY, f64::min);
            assert!(c > 0.5 && c < previous, "N={n}: αK* = {c}");
            previous = c;
        }
        assert_relative_eq!(previous, 0.5, epsilon = 1e-9);
        // N = 2 unidirectional: λ = 2K, so αK* = π/4.
        let ring = UniformRing::new(2, 1.0, 0.0, 1.0).unwrap();
        assert_relative_eq!(
            ring.modes().unwrap().critical_gain_scale,
            PI / 4.0,
            epsilon = 1e-15
        );
    }

    #[test]
    fn symmetric_rings_have_real_modes_and_pi_over_two_crossings() {
        // k_f = k_b = k: λ_k = 2k(1 − cos θ_k) real, crossing at αλ = π/2. For even N the
        // largest λ is 4k, so αk* = π/8 against the Theorem-1 αk < 1/4: ratio π/2.
        let ring = UniformRing::new(10, 1.0, 1.0, 1.0).unwrap();
        let modes = ring.modes().unwrap();
        assert_relative_eq!(modes.critical_gain_scale, PI / 8.0, epsilon = 1e-15);
        assert_relative_eq!(modes.theorem1_gain_scale, 0.25, epsilon = 1e-15);
        assert_relative_eq!(modes.conservatism_ratio, PI / 2.0, epsilon = 1e-14);
        // Two drivers following each other: a_12 = a_21 = 2k, λ = 4k, same numbers.
        let pair = UniformRing::new(2, 0.5, 0.5, 1.0).unwrap();
        let m = pair.modes().unwrap();
        assert_relative_eq!(m.critical_gain_scale, PI / 4.0, epsilon = 1e-15);
        assert_relative_eq!(m.conservatism_ratio, PI / 2.0, epsilon = 1e-14);
    }

    #[test]
    fn theorem_one_is_never_contradicted_on_rings() {
        for n in 2..60 {
            for &(kf, kb) in &[(1.0, 0.0), (0.0, 1.0), (0.7, 0.3), (0.2, 1.3)] {
                let ring = UniformRing::new(n, kf, kb, 0.8).unwrap();
                let m = ring.modes().unwrap();
                assert!(m.conservatism_ratio >= 1.0, "N={n} kf={kf} kb={kb}");
                // Just below the Theorem-1 scale every non-consensus root is stable.
                let scaled = UniformRing::new(
                    n,
                    kf * 0.999 * m.theorem1_gain_scale,
                    kb * 0.999 * m.theorem1_gain_scale,
                    0.8,
                )
                .unwrap();
                assert!(scaled.modes().unwrap().abscissa < 0.0);
            }
        }
    }

    #[test]
    fn errors_name_field_and_value() {
        assert_eq!(
            UniformRing::new(1, 1.0, 0.0, 1.0).unwrap_err().to_string(),
            "a ring road needs at least 2 vehicles, got 1"
        );
        assert_eq!(
            UniformRing::new(4, -1.0, 0.0, 1.0).unwrap_err().to_string(),
            "ring gain gain_front = -1 must be finite and ≥ 0"
        );
        assert_eq!(
            UniformRing::new(4, 0.0, 0.0, 1.0).unwrap_err().to_string(),
            "ring gains gain_front and gain_back are both zero; the interaction graph has no arcs"
        );
        assert_eq!(
            UniformRing::new(4, 1.0, 0.0, f64::NAN)
                .unwrap_err()
                .to_string(),
            "ring delay_s = NaN must be finite and ≥ 0"
        );
    }
}
