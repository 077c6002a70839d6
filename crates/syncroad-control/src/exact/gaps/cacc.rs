//! Gap certificate of the CACC platoon (eqs. `veh1`, `veh-proto1`, `veh-proto2`): spacing
//! errors under initial speed perturbations, a leader speed step and the scenario's own leader
//! profile, from the linear closed loop.
//!
//! With `e_i = g_i − s_i` (bumper gap minus desired gap), speeds and accelerations as
//! deviations from the leader's initial speed, the platoon is `x' = Ax + b d(t)`,
//! `x = (e, v, a)`, `d` the leader's speed deviation: `e_i' = v_{i−1} − v_i` (`v_{−1} = d`),
//! `v_i' = a_i`, `τ_i a_i' = μ_i (d − v_i) + η_i e_i − ν_i e_{i+1} − a_i`. It is integrated
//! exactly on a grid of `h = 0.01 s` by the exponential of the augmented matrix (the leader's
//! speed piecewise linear between grid points, as the profiles are with breakpoints on the
//! grid). At rest every `a_des,i = 0`, so `η_N e_N = 0`, then `η_i e_i = ν_i e_{i+1} = 0` up the
//! platoon: the gaps settle at the desired gaps.
//!
//! * `M_i = sup_t Σ_j |E_ij(t)|`, `E_ij` the spacing error of follower `i` after a unit initial
//!   speed change of follower `j`: perturbations of at most `ε` shrink gap `i` by `≤ M_i ε`;
//! * the leader step: `sup_t max_i |r_i(t)|` per m/s of a leader speed step;
//! * the scenario's own run (its initial gaps and speeds, its leader profile): `min_t min_i g_i`.

use nalgebra::DMatrix;

use super::{GapCertificate, GapError, SafeBinding, GAP_HORIZON_LIMIT_S, GAP_RING_LIMIT};
use crate::scenario::CaccModel;
use crate::scenario::Scenario;

/// Grid step of the exact discretisation [s].
const STEP_S: f64 = 0.01;

/// Largest platoon certified (the step costs `O(N³)`).
pub const CACC_GAP_LIMIT: usize = 20;

/// The closed-loop matrix `A` and the input column `b` (module documentation).
fn closed_loop(m: &CaccModel) -> (DMatrix<f64>, Vec<f64>) {
    let n = m.mu.len();
    let (e, v, a) = (0, n, 2 * n);
    let mut am = DMatrix::zeros(3 * n, 3 * n);
    let mut b = vec![0.0; 3 * n];
    for i in 0..n {
        if i > 0 {
            am[(e + i, v + i - 1)] = 1.0;
        } else {
            b[e] = 1.0;
        }
        am[(e + i, v + i)] = -1.0;
        am[(v + i, a + i)] = 1.0;
        let tau = m.tau_s[i];
        am[(a + i, v + i)] = -m.mu[i] / tau;
        am[(a + i, e + i)] = m.eta[i] / tau;
        if i + 1 < n {
            am[(a + i, e + i + 1)] = -m.nu[i] / tau;
        }
        am[(a + i, a + i)] = -1.0 / tau;
        b[a + i] = m.mu[i] / tau;
    }
    (am, b)
}

/// One grid step of `x' = Ax + b d`, `d` linear over the step: `(Φ, φ_d, φ_slope)` from the
/// exponential of the augmented matrix `[[A, b, 0], [0, 0, 1], [0, 0, 0]]·h`.
fn step_maps(am: &DMatrix<f64>, b: &[f64], h: f64) -> (DMatrix<f64>, Vec<f64>, Vec<f64>) {
    let k = am.nrows();
    let mut big = DMatrix::zeros(k + 2, k + 2);
    big.view_mut((0, 0), (k, k)).copy_from(am);
    for i in 0..k {
        big[(i, k)] = b[i];
    }
    big[(k, k + 1)] = 1.0;
    let ex = (big * h).exp();
    let phi = ex.view((0, 0), (k, k)).into_owned();
    let pd = (0..k).map(|i| ex[(i, k)]).collect();
    let ps = (0..k).map(|i| ex[(i, k + 1)]).collect();
    (phi, pd, ps)
}

/// The smallest gap of the scenario's own run as the runs apply the law: every step, held
/// until the next (the native run of the same law, which SUMO's equals); `None` when that run
/// did not reach its horizon.
fn sampled_own_min_gap(sc: &Scenario) -> Option<f64> {
    let run = crate::native::simulate(sc, crate::native::NativeOptions::default());
    let t = &run.trajectory;
    let low = (0..t.len())
        .flat_map(|k| t.gaps(k).to_vec())
        .fold(f64::INFINITY, f64::min);
    (run.stop.is_complete() && low.is_finite()).then_some(low)
}

/// The worst signs `−sign(h_ij)` of the unit responses in row `i` of `x` (0 where the response
/// is 0): the speed perturbation pattern that shrinks gap `i` most at that time.
fn worst_signs(x: &DMatrix<f64>, i: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|j| -x[(i, j)].signum() * f64::from(u8::from(x[(i, j)] != 0.0)))
        .collect()
}

/// The responses at t = 0, one column each: the `n` unit speed perturbations, the leader
/// step (column `n`, driven by the input), the scenario's own run (its gap errors and speeds,
/// its leader profile) and the initial gap errors alone (speeds at the leader's, a constant
/// leader).
fn initial_columns(sc: &Scenario, m: &CaccModel) -> DMatrix<f64> {
    let n = m.mu.len();
    let mut x = DMatrix::zeros(3 * n, n + 3);
    for j in 0..n {
        x[(n + j, j)] = 1.0;
    }
    let v_lead0 = m.leader.initial_speed();
    let g0 = sc.initial_gap_m();
    for i in 0..n {
        x[(i, n + 1)] = g0[i] - m.desired_gap_m[i];
        x[(n + i, n + 1)] = sc.initial_speed_mps()[i] - v_lead0;
        x[(i, n + 2)] = g0[i] - m.desired_gap_m[i];
    }
    x
}

/// What the certificate keeps of the responses over time, each with the gap and time where it
/// occurs: the shrinkage sups `M_i` and their worst, the safe perturbation (what a gap has
/// left, `d_i + E_i(t)`, over what a unit perturbation of the worst signs takes from it), the
/// leader step's largest spacing error and the own run's smallest gap.
struct Extremes {
    shrinkage: Vec<f64>,
    worst: (f64, usize, f64),
    worst_pattern: Vec<f64>,
    safe: (f64, usize, f64),
    safe_pattern: Vec<f64>,
    step_peak: f64,
    own_min: (f64, usize, f64),
}

impl Extremes {
    fn new(n: usize) -> Self {
        Self {
            shrinkage: vec![0.0; n],
            worst: (0.0, 0, 0.0),
            worst_pattern: vec![0.0; n],
            safe: (f64::INFINITY, 0, 0.0),
            safe_pattern: vec![0.0; n],
            step_peak: 0.0,
            own_min: (f64::INFINITY, 0, 0.0),
        }
    }

    /// Takes in the responses `x` (columns of [`initial_columns`]) at time `t`.
    fn observe(&mut self, x: &DMatrix<f64>, m: &CaccModel, t: f64) {
        let n = self.shrinkage.len();
        for i in 0..n {
            let row: f64 = (0..n).map(|j| x[(i, j)].abs()).sum();
            self.shrinkage[i] = self.shrinkage[i].max(row);
            if row > self.worst.0 {
                self.worst = (row, i, t);
                self.worst_pattern = worst_signs(x, i, n);
            }
            let left = m.desired_gap_m[i] + x[(i, n + 2)];
            if row > 1e-12 && left / row < self.safe.0 {
                self.safe = (left / row, i, t);
                self.safe_pattern = worst_signs(x, i, n);
            }
            self.step_peak = self.step_peak.max(x[(i, n)].abs());
            let gap = m.desired_gap_m[i] + x[(i, n + 1)];
            if gap < self.own_min.0 {
                self.own_min = (gap, i, t);
            }
        }
    }
}

/// The gap certificate of a CACC scenario.
///
/// # Errors
/// [`GapError::TooLarge`] beyond [`CACC_GAP_LIMIT`] followers, [`GapError::Grows`] for
/// an unstable platoon.
pub(super) fn cacc_gap_certificate(
    sc: &Scenario,
    m: &CaccModel,
) -> Result<GapCertificate, GapError> {
    let n = m.mu.len();
    if n > CACC_GAP_LIMIT {
        return Err(GapError::TooLarge {
            vehicles: n,
            limit: CACC_GAP_LIMIT,
            ring_limit: GAP_RING_LIMIT,
        });
    }
    let (am, b) = closed_loop(m);
    let (phi, pd, ps) = step_maps(&am, &b, STEP_S);
    let k = 3 * n;
    let mut x = initial_columns(sc, m);
    let v_lead0 = m.leader.initial_speed();
    let g0 = sc.initial_gap_m().to_vec();
    // The gap errors' column is measured against its own size (at least 1 m).
    let x_scale = (0..n)
        .map(|i| (g0[i] - m.desired_gap_m[i]).abs())
        .fold(0.0, f64::max)
        .max(1.0);
    let d_own = |t: f64| m.leader.speed_at(t) - v_lead0;
    let mut ext = Extremes::new(n);
    let mut quiet = 0.0;
    let mut t = 0.0;
    let window_s = 10.0;
    let (settled, horizon_s) = loop {
        ext.observe(&x, m, t);
        // The step's column settles at v = 1 (every follower at the new speed); the gap
        // errors' column at 0.
        let step_size = (0..k)
            .map(|r| (x[(r, n)] - if (n..2 * n).contains(&r) { 1.0 } else { 0.0 }).abs())
            .fold(0.0, f64::max);
        let own_errors = x.column(n + 2).amax() / x_scale;
        let size = x.columns(0, n).amax().max(step_size).max(own_errors);
        if !size.is_finite() || size > 1e9 {
            return Err(GapError::Grows {
                growth: 1e9,
                time_s: t,
                shrinkage_at_least_m_per_mps: ext.worst.0,
                safe_at_most_mps: m.desired_gap_m[ext.worst.1] / ext.worst.0,
            });
        }
        // Unit responses and the step settled, and the own run past its horizon.
        quiet = if size <= 1e-5 * ext.worst.0.max(1.0) {
            quiet + STEP_S
        } else {
            0.0
        };
        if quiet >= window_s && t >= sc.horizon_s() {
            break (true, t);
        }
        if t >= GAP_HORIZON_LIMIT_S {
            break (false, t);
        }
        let (d0, d1) = (d_own(t), d_own(t + STEP_S));
        let mut next = &phi * &x;
        for i in 0..k {
            // The leader step: d = 1 from t = 0+ on; the own run: the profile.
            next[(i, n)] += pd[i];
            next[(i, n + 1)] += pd[i] * d0 + ps[i] * (d1 - d0) / STEP_S;
        }
        x = next;
        t += STEP_S;
    };
    let sampled = sampled_own_min_gap(sc);
    let own_perturbation = sc
        .initial_speed_mps()
        .iter()
        .map(|v| (v - v_lead0).abs())
        .fold(0.0, f64::max);
    let Extremes {
        shrinkage,
        worst,
        worst_pattern,
        safe,
        safe_pattern,
        step_peak,
        own_min,
    } = ext;
    Ok(GapCertificate {
        final_gap_m: m.desired_gap_m.clone(),
        final_speed_mps: m.leader.speed_at(horizon_s),
        worst_shrinkage_m_per_mps: worst.0,
        shrinkage_m_per_mps: shrinkage,
        worst_gap: worst.1,
        worst_time_s: worst.2,
        worst_pattern,
        safe_perturbation_mps: safe.0,
        safe_binding: Some(SafeBinding {
            gap: safe.1,
            time_s: safe.2,
            pattern: safe_pattern,
        }),
        own_perturbation_mps: own_perturbation,
        own_min_gap_m: own_min.0,
        own_min_gap_vehicle: own_min.1,
        own_min_gap_time_s: own_min.2,
        own_contact: own_min.0 <= 0.0 || sampled.is_some_and(|g| g <= 0.0),
        initial_gap_m: g0,
        horizon_s,
        settled,
        step_s: STEP_S,
        integration_error_m_per_mps: 0.0,
        leader_step_m_per_mps: Some(step_peak),
        sampled_own_min_gap_m: sampled,
    })
}

#[cfg(test)]
mod tests {
    use super::super::gap_certificate;
    use crate::native::{simulate, NativeOptions};
    use crate::scenario::Scenario;
    use approx::assert_relative_eq;

    /// `scenarios/platoon-cacc.json` at a 0.01 s step, with `initial` replaced when given.
    fn platoon(initial: Option<serde_json::Value>, constant_leader: bool) -> Scenario {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenarios/platoon-cacc.json"
        );
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        v["step_s"] = serde_json::json!(0.01);
        if let Some(i) = initial {
            v["initial"] = i;
        }
        if constant_leader {
            v["model"]["leader"] = serde_json::json!({"type": "constant", "speed_mps": 20.0});
        }
        Scenario::from_json(&v.to_string()).unwrap()
    }

    #[test]
    fn the_platoon_own_run_and_worst_pattern_agree_with_the_native_simulator() {
        // The scenario's own run (perturbed speeds and gaps, the leader braking and recovering):
        // the smallest gap, predicted exactly from the linear loop, against the native law.
        let sc = platoon(None, false);
        let c = gap_certificate(&sc).unwrap().unwrap();
        assert!(c.settled && !c.own_contact);
        let run = simulate(&sc, NativeOptions::default());
        let t = &run.trajectory;
        let low = (0..t.len())
            .flat_map(|k| t.gaps(k).to_vec())
            .fold(f64::INFINITY, f64::min);
        assert!(
            (low - c.own_min_gap_m).abs() < 0.01,
            "{low} vs {}",
            c.own_min_gap_m
        );
        // The worst sign pattern at the desired gaps and a constant leader shrinks the worst
        // gap by M·ε at t*.
        let eps = 0.5;
        let speeds: Vec<f64> = c.worst_pattern.iter().map(|s| 20.0 + eps * s).collect();
        let sc = platoon(Some(serde_json::json!({"speed_mps": speeds})), true);
        let run = simulate(&sc, NativeOptions::default());
        let t = &run.trajectory;
        let k = (c.worst_time_s / 0.01).round() as usize;
        let shrink = 10.0 - t.gaps(k)[c.worst_gap];
        assert_relative_eq!(
            shrink,
            c.worst_shrinkage_m_per_mps * eps,
            max_relative = 1e-2
        );
        // A leader step: no spacing error beyond the step bound.
        let r = c.leader_step_m_per_mps.unwrap();
        assert!(r > 0.0);
        let sc = platoon(Some(serde_json::json!({"speed_mps": 20.0})), false);
        let run = simulate(&sc, NativeOptions::default());
        let t = &run.trajectory;
        // The profile is a superposition of steps of total variation 16 m/s (down 8, up 8):
        // |e_i| ≤ 16·r; and the braking alone, 8 m/s, must reach at least a step's peak.
        let mut worst = 0.0f64;
        for k in 0..t.len() {
            for g in t.gaps(k) {
                assert!((g - 10.0).abs() <= 16.0 * r * (1.0 + 1e-2), "{g}");
                worst = worst.max((g - 10.0).abs());
            }
        }
        assert!(worst > 0.0 && worst <= 16.0 * r);
    }

    /// CACC regulates gaps: a large initial gap closes while a perturbation acts, so the safe
    /// perturbation is not `g(0)/M`. With uniform initial gaps of 20 m (desired 10 m) and a
    /// constant leader, the native simulator run from the binding sign pattern keeps every gap
    /// open at 0.98 of the certified perturbation and makes contact at 1.02 of it; `g(0)/M`
    /// would certify more than the law allows.
    #[test]
    fn the_safe_perturbation_of_a_platoon_with_large_initial_gaps_is_exact() {
        let base = platoon(
            Some(serde_json::json!({"speed_mps": 20.0, "gap_m": 20.0})),
            true,
        );
        let c = gap_certificate(&base).unwrap().unwrap();
        let b = c.safe_binding.clone().unwrap();
        let x = c.safe_perturbation_mps;
        let naive = (0..c.initial_gap_m.len())
            .map(|i| c.initial_gap_m[i] / c.shrinkage_m_per_mps[i])
            .fold(f64::INFINITY, f64::min);
        assert!(x < naive, "{x} vs g(0)/M = {naive}");
        let min_gap = |scale: f64| {
            let speeds: Vec<f64> = b.pattern.iter().map(|s| 20.0 + scale * x * s).collect();
            let sc = platoon(
                Some(serde_json::json!({"speed_mps": speeds, "gap_m": 20.0})),
                true,
            );
            let run = simulate(&sc, NativeOptions::default());
            let t = &run.trajectory;
            (0..t.len())
                .flat_map(|k| t.gaps(k).to_vec())
                .fold(f64::INFINITY, f64::min)
        };
        let (inside, outside) = (min_gap(0.98), min_gap(1.02));
        assert!(inside > 0.0, "contact at 0.98·X: {inside} m");
        assert!(outside < 0.0, "no contact at 1.02·X: {outside} m");
    }

    /// Both backends apply the CACC law every step and hold it (sampled data); the
    /// certificate's model is the continuous-time law (exact exponential). The smallest gap of
    /// the scenario's own run converges to the continuous one at first order in the step:
    /// halving the step halves the difference (ratios 1.8–2.2), and the certificate reports the
    /// sampled value at the scenario's own step.
    #[test]
    fn the_sampled_law_converges_to_the_certificates_continuous_law_at_first_order() {
        let at = |step: f64| {
            let path = concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../scenarios/platoon-cacc.json"
            );
            let mut v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
            v["step_s"] = serde_json::json!(step);
            let sc = Scenario::from_json(&v.to_string()).unwrap();
            gap_certificate(&sc).unwrap().unwrap()
        };
        let certs: Vec<_> = [0.04, 0.02, 0.01].iter().map(|h| at(*h)).collect();
        let continuous = certs[0].own_min_gap_m;
        let errors: Vec<f64> = certs
            .iter()
            .map(|c| {
                assert!((c.own_min_gap_m - continuous).abs() < 1e-6);
                continuous - c.sampled_own_min_gap_m.unwrap()
            })
            .collect();
        assert!(errors[2] > 0.0 && errors[0] < 0.05, "{errors:?}");
        for w in errors.windows(2) {
            let ratio = w[0] / w[1];
            assert!((1.8..=2.2).contains(&ratio), "{errors:?}: ratio {ratio}");
        }
    }
}
