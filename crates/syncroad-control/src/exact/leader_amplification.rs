//! Worst amplification along a platoon behind a leader: the peak gain of the transfer from
//! the leader's speed to each follower's, for any graph (heterogeneous chains, bidirectional
//! platoons with pinning).
//!
//! With the leader as the undelayed vertex `0̂` whose speed `v_0` is the input, the followers
//! of eq. `chandler+` obey `(sI + diag(e^{−sα_i}) L_f) v = diag(e^{−sα_i}) b v_0`, where `L_f`
//! is the followers' block of the Laplacian (pinning gains `b_i` on its diagonal). So
//! `T(s) = (sI + E(s)L_f)⁻¹ E(s) b` and `T(0) = 1` (`L_f 1 = b`): a slow change of the
//! leader's speed reaches everyone unchanged. The report gives `sup_ω |T_i(iω)|` per follower
//! and the worst of them; it is 1 when no follower ever overshoots the leader's speed, and
//! grows along a string-unstable platoon (`peak^i` for Chandler's road, `2αK > 1`).
//!
//! Method: `|T(iω)|` on a frequency grid (log-spaced from `10⁻³ ω_c` to `ω_c`, linear to
//! `4ω_c`, `ω_c = max_i (d_i^+ + b_i)`, plus the frequencies of the given roots, where narrow
//! resonances sit), one band LU of `M(iω)` per point ([`super::banded`]), then a
//! golden-section refinement of each follower's peak. The network must be stable.

use nalgebra::DMatrix;
use num_complex::Complex64;
use serde::Serialize;

use super::banded::NetworkMatrix;
use super::collocation::laplacian;

/// Peak gains from the leader's speed to the followers'.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LeaderAmplification {
    /// Per follower (in the scenario's vehicle order): `sup_ω |T_i(iω)|`.
    pub peaks: Vec<f64>,
    /// Per follower: the frequency of the peak [rad/s] (0 when the supremum is the limit
    /// `ω → 0`).
    pub peak_frequencies_rad_s: Vec<f64>,
    /// `max_i sup_ω |T_i(iω)|`: the worst amplification along the platoon.
    pub worst_peak: f64,
    /// The follower attaining it.
    pub worst_vehicle: usize,
    /// Its frequency [rad/s].
    pub worst_frequency_rad_s: f64,
    /// No follower's speed overshoots the leader's at any frequency (`worst_peak ≤ 1 + 10⁻⁹`).
    pub no_amplification: bool,
}

/// `sup_ω |T_i(iω)|` for every follower of `adjacency` (the leader is vertex `leader`, which
/// observes nobody), with `root_frequencies` added to the grid (see the module documentation).
/// `None` when the leader does not exist, observes someone, or the transfer cannot be
/// evaluated (a root on the imaginary axis).
pub fn leader_amplification(
    adjacency: &DMatrix<f64>,
    delays_s: &[f64],
    leader: usize,
    root_frequencies: &[f64],
) -> Option<LeaderAmplification> {
    let n_all = adjacency.nrows();
    if leader >= n_all || adjacency.row(leader).iter().any(|&x| x != 0.0) || n_all < 2 {
        return None;
    }
    let followers: Vec<usize> = (0..n_all).filter(|&i| i != leader).collect();
    let l_all = laplacian(adjacency);
    let nf = followers.len();
    let l_f = DMatrix::from_fn(nf, nf, |r, c| l_all[(followers[r], followers[c])]);
    let b: Vec<f64> = followers.iter().map(|&i| adjacency[(i, leader)]).collect();
    let delays: Vec<f64> = followers.iter().map(|&i| delays_s[i]).collect();
    let band = NetworkMatrix::new(&l_f, &delays);
    let perm = band.permutation().to_vec();
    let gains = |omega: f64| -> Option<Vec<f64>> {
        let s = Complex64::new(0.0, omega);
        let lu = band.factor(1.0, s);
        let mut x: Vec<Complex64> = perm
            .iter()
            .map(|&v| (-s * delays[v]).exp() * b[v])
            .collect();
        if !lu.solve(&mut x) {
            return None;
        }
        let mut g = vec![0.0; nf];
        for (p, &v) in perm.iter().enumerate() {
            g[v] = x[p].norm();
        }
        g.iter().all(|y| y.is_finite()).then_some(g)
    };
    let wc = (0..nf).map(|r| l_f[(r, r)]).fold(0.0, f64::max).max(1e-9);
    let mut grid: Vec<f64> = (0..=300)
        .map(|k| wc * 10f64.powf(-3.0 + 3.0 * k as f64 / 300.0))
        .collect();
    grid.extend((1..=600).map(|k| wc * (1.0 + 3.0 * k as f64 / 600.0)));
    grid.extend(root_frequencies.iter().filter(|w| **w > 0.0).copied());
    grid.sort_by(f64::total_cmp);
    // Start from the ω → 0 limit |T_i| = 1.
    let mut best: Vec<(f64, f64)> = vec![(1.0, 0.0); nf];
    let mut at: Vec<usize> = vec![usize::MAX; nf];
    let mut values = Vec::with_capacity(grid.len());
    for &w in &grid {
        values.push(gains(w)?);
    }
    for (k, g) in values.iter().enumerate() {
        for i in 0..nf {
            if g[i] > best[i].0 {
                best[i] = (g[i], grid[k]);
                at[i] = k;
            }
        }
    }
    for i in 0..nf {
        let k = at[i];
        if k == usize::MAX {
            continue;
        }
        let lo = if k > 0 { grid[k - 1] } else { 0.5 * grid[k] };
        let hi = grid.get(k + 1).copied().unwrap_or(2.0 * grid[k]);
        if let Some((w, v)) = golden_max(|w| gains(w).map(|g| g[i]), lo, hi) {
            if v > best[i].0 {
                best[i] = (v, w);
            }
        }
    }
    // Back to the scenario's vehicle order (the leader removed).
    let peaks: Vec<f64> = best.iter().map(|b| b.0).collect();
    let (worst, &(worst_peak, worst_frequency_rad_s)) = best
        .iter()
        .enumerate()
        .max_by(|x, y| x.1 .0.total_cmp(&y.1 .0))?;
    Some(LeaderAmplification {
        no_amplification: worst_peak <= 1.0 + 1e-9,
        peak_frequencies_rad_s: best.iter().map(|b| b.1).collect(),
        peaks,
        worst_peak,
        worst_vehicle: followers[worst],
        worst_frequency_rad_s,
    })
}

/// Golden-section search for the maximum of `f` on `[a, b]`.
fn golden_max(f: impl Fn(f64) -> Option<f64>, a: f64, b: f64) -> Option<(f64, f64)> {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (a, b);
    let mut x1 = b - r * (b - a);
    let mut x2 = a + r * (b - a);
    let (mut f1, mut f2) = (f(x1)?, f(x2)?);
    for _ in 0..80 {
        if (b - a).abs() <= 1e-12 * b.abs().max(1e-300) {
            break;
        }
        if f1 < f2 {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + r * (b - a);
            f2 = f(x2)?;
        } else {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - r * (b - a);
            f1 = f(x1)?;
        }
    }
    Some(if f1 > f2 { (x1, f1) } else { (x2, f2) })
}

#[cfg(test)]
mod tests {
    use super::super::string_stability::chandler_string_peak;
    use super::*;
    use approx::assert_relative_eq;

    /// Chandler's road: `n` followers, each seeing its predecessor with gain `k`, the first
    /// the leader (vertex `n`) with pinning `k`; delay `alpha` for everyone.
    fn chain(n: usize, k: f64, alpha: f64) -> (DMatrix<f64>, Vec<f64>) {
        let mut a = DMatrix::zeros(n + 1, n + 1);
        a[(0, n)] = k;
        for i in 1..n {
            a[(i, i - 1)] = k;
        }
        let mut d = vec![alpha; n];
        d.push(0.0);
        (a, d)
    }

    #[test]
    fn homogeneous_chain_amplifies_as_the_single_link_peak_to_the_power_i() {
        // T_i = H^i with H = K e^{−sα}/(s + K e^{−sα}); |H|^i peaks where |H| does, so
        // sup_ω|T_i| = (sup_ω|H|)^i (closed form of |H|² in chandler_string_peak).
        for &(k, alpha) in &[(0.6, 1.0), (1.0, 0.9)] {
            let n = 12;
            let (a, d) = chain(n, k, alpha);
            let r = leader_amplification(&a, &d, n, &[]).unwrap();
            let peak = chandler_string_peak(alpha * k);
            assert!(peak > 1.0);
            for i in 0..n {
                assert_relative_eq!(r.peaks[i], peak.powi(i as i32 + 1), max_relative = 1e-8);
            }
            assert_eq!(r.worst_vehicle, n - 1);
            assert!(!r.no_amplification);
        }
        // 2αK ≤ 1: |H| ≤ 1 everywhere, no follower overshoots.
        let (a, d) = chain(8, 0.5, 0.9);
        let r = leader_amplification(&a, &d, 8, &[]).unwrap();
        assert!(r.no_amplification, "{r:?}");
        assert_relative_eq!(r.worst_peak, 1.0, epsilon = 1e-9);
    }

    #[test]
    fn symmetric_pair_behind_a_leader_reduces_to_one_follower() {
        // Two followers watching each other (gain a) and the leader (gain b): by symmetry
        // v_1 = v_2, and T = b e^{−sα}/(s + b e^{−sα}), Chandler's single link with K = b,
        // whatever a (the graph has a cycle, so the acyclic path does not apply).
        let (a_gain, b, alpha) = (0.7, 0.8, 1.0);
        let a = DMatrix::from_row_slice(3, 3, &[0.0, a_gain, b, a_gain, 0.0, b, 0.0, 0.0, 0.0]);
        let r = leader_amplification(&a, &[alpha, alpha, 0.0], 2, &[]).unwrap();
        let peak = chandler_string_peak(alpha * b);
        assert_relative_eq!(r.peaks[0], peak, max_relative = 1e-9);
        assert_relative_eq!(r.peaks[1], peak, max_relative = 1e-9);
    }
}
