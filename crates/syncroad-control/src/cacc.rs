//! The bidirectional CACC law of eqs. `veh-proto1`/`veh-proto2` and the powertrain lag of
//! eq. `veh1`, `τ_i q_i''' + q_i'' = a_des,i`.
//!
//! Vehicle 0 is the leader, followers are 1..=N (stored at indices 0..N). Gaps are
//! bumper-to-bumper: `g_i = q_{i−1} − q_i − ℓ_i` with `q` the rear bumper and `ℓ_i` the length
//! of vehicle i. The paper's `q_{i−1} − q_i − s_i` with rear-bumper spacing `s_i` is the same law
//! with `s_i = s_i^gap + ℓ_i`, so
//!
//! `a_des,i = μ_i (v_0 − v_i) + η_i (g_i − s_i) + ν_i (s_{i+1} − g_{i+1})`, the ν-term absent for
//! the last vehicle.

use crate::model::CaccModel;
use crate::sensed::{Neighbors, Sensed};

/// Measured state of the platoon at one instant.
#[derive(Debug, Clone, Copy)]
pub struct PlatoonView<'a> {
    /// Leader rear-bumper position q_0 [m].
    pub leader_position_m: f64,
    /// Leader speed v_0 [m/s] (broadcast to every follower).
    pub leader_speed_mps: f64,
    /// Follower rear-bumper positions q_1..q_N [m].
    pub positions_m: &'a [f64],
    /// Follower speeds v_1..v_N [m/s].
    pub speeds_mps: &'a [f64],
}

/// The CACC law: gains, desired gaps and vehicle lengths.
#[derive(Debug, Clone)]
pub struct CaccLaw {
    mu: Vec<f64>,
    eta: Vec<f64>,
    nu: Vec<f64>,
    gap: Vec<f64>,
    length: Vec<f64>,
}

impl CaccLaw {
    /// The law of a validated CACC model.
    pub fn new(model: &CaccModel) -> Self {
        Self {
            mu: model.mu.clone(),
            eta: model.eta.clone(),
            nu: model.nu.clone(),
            gap: model.desired_gap_m.clone(),
            length: model.length_m.clone(),
        }
    }

    /// Number of followers N.
    pub fn len(&self) -> usize {
        self.mu.len()
    }

    /// Always false: a platoon has at least one follower.
    pub fn is_empty(&self) -> bool {
        self.mu.is_empty()
    }

    /// Bumper-to-bumper gap of follower `i` (0-based) to its predecessor [m].
    pub fn gap_m(&self, view: &PlatoonView<'_>, i: usize) -> f64 {
        let front = if i == 0 {
            view.leader_position_m
        } else {
            view.positions_m[i - 1]
        };
        front - view.positions_m[i] - self.length[i]
    }

    /// Desired accelerations a_des,i (eqs. `veh-proto1`, `veh-proto2`) into `out`.
    pub fn desired_accelerations(&self, view: &PlatoonView<'_>, out: &mut [f64]) {
        self.accelerations(view, None, out);
    }

    /// The same with the graph taken from the simulator: follower i is vehicle i + 1 of
    /// `neighbors` (the leader is vehicle 0); the η-term takes the gap to whoever is ahead of
    /// it now and the ν-term the gap of whoever is behind it, with the desired gaps of the
    /// platoon's places ([`crate::sensed`]); a term with nobody there drops.
    pub fn desired_accelerations_sensed(
        &self,
        view: &PlatoonView<'_>,
        neighbors: &Neighbors,
        out: &mut [f64],
    ) {
        self.accelerations(view, Some(neighbors), out);
    }

    fn accelerations(&self, view: &PlatoonView<'_>, sensed: Option<&Neighbors>, out: &mut [f64]) {
        let n = self.len();
        assert_eq!(view.positions_m.len(), n);
        assert_eq!(view.speeds_mps.len(), n);
        assert_eq!(out.len(), n);
        // The gap on one side of follower i as sensed, else its layout gap `layout(i)`.
        let side = |s: Option<Sensed>, layout: usize| match s {
            Some(Sensed::Other { gap_m, .. }) => Some(gap_m),
            Some(Sensed::Nobody) => None,
            Some(Sensed::Layout) | None => Some(self.gap_m(view, layout)),
        };
        for i in 0..n {
            let mut a = self.mu[i] * (view.leader_speed_mps - view.speeds_mps[i]);
            if let Some(g) = side(sensed.map(|nb| nb.ahead[i + 1]), i) {
                a += self.eta[i] * (g - self.gap[i]);
            }
            if i + 1 < n {
                if let Some(g) = side(sensed.map(|nb| nb.behind[i + 1]), i + 1) {
                    a += self.nu[i] * (self.gap[i + 1] - g);
                }
            }
            out[i] = a;
        }
    }
}

/// First-order powertrain lag `τ a' + a = a_des` (eq. `veh1` with `a = q''`), discretised
/// exactly for a desired acceleration held over the step (zero-order hold), with the speed
/// integrated by the trapezoidal rule of the resulting acceleration.
#[derive(Debug, Clone)]
pub struct PowertrainLag {
    /// e^{−Δt/τ_i}.
    decay: Vec<f64>,
    /// Current accelerations a_i [m/s²].
    accel: Vec<f64>,
    dt_s: f64,
}

impl PowertrainLag {
    /// Lags τ_i [s], step Δt [s], vehicles starting at zero acceleration.
    pub fn new(tau_s: &[f64], dt_s: f64) -> Self {
        Self {
            decay: tau_s.iter().map(|t| (-dt_s / t).exp()).collect(),
            accel: vec![0.0; tau_s.len()],
            dt_s,
        }
    }

    /// Current accelerations [m/s²].
    pub fn accelerations(&self) -> &[f64] {
        &self.accel
    }

    /// Advances the accelerations under `a_des` for one step and returns, in `next_speeds`,
    /// the speeds at the end of the step starting from `speeds`.
    pub fn step(&mut self, a_des: &[f64], speeds: &[f64], next_speeds: &mut [f64]) {
        for i in 0..self.accel.len() {
            let a0 = self.accel[i];
            let a1 = a_des[i] + (a0 - a_des[i]) * self.decay[i];
            next_speeds[i] = speeds[i] + 0.5 * self.dt_s * (a0 + a1);
            self.accel[i] = a1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::LeaderProfile;
    use approx::assert_relative_eq;

    fn model(n: usize) -> CaccModel {
        CaccModel {
            mu: vec![1.0; n],
            eta: vec![0.1; n],
            nu: {
                let mut v = vec![0.05; n];
                v[n - 1] = 0.0;
                v
            },
            desired_gap_m: vec![10.0; n],
            tau_s: vec![0.3; n],
            length_m: vec![5.0; n],
            leader: LeaderProfile::Constant { speed_mps: 20.0 },
        }
    }

    #[test]
    fn equilibrium_gives_zero_command() {
        let law = CaccLaw::new(&model(3));
        // Leader rear bumper at 100; follower i at 100 − (i+1)·(10 + 5).
        let q = [85.0, 70.0, 55.0];
        let v = [20.0; 3];
        let view = PlatoonView {
            leader_position_m: 100.0,
            leader_speed_mps: 20.0,
            positions_m: &q,
            speeds_mps: &v,
        };
        let mut a = [1.0; 3];
        law.desired_accelerations(&view, &mut a);
        assert_eq!(a, [0.0; 3]);
    }

    #[test]
    fn gap_terms_have_the_signs_of_the_paper() {
        // Vehicle 2 (index 1) is 1 m too close to vehicle 1: vehicle 1 speeds up by ν, vehicle 2
        // slows down by η.
        let law = CaccLaw::new(&model(3));
        let q = [85.0, 71.0, 56.0];
        let v = [20.0; 3];
        let view = PlatoonView {
            leader_position_m: 100.0,
            leader_speed_mps: 20.0,
            positions_m: &q,
            speeds_mps: &v,
        };
        let mut a = [0.0; 3];
        law.desired_accelerations(&view, &mut a);
        assert_relative_eq!(a[0], 0.05 * 1.0);
        assert_relative_eq!(a[1], -0.1 * 1.0);
        assert_relative_eq!(a[2], 0.0);
    }

    /// A car cuts in 6 m ahead of follower 2 (index 1), 9 m behind follower 1: follower 2's
    /// η-term takes the 6 m gap, follower 1's ν-term the 9 m gap, each against its own place's
    /// desired gap; everyone where the layout put them is the fixed graph's law exactly.
    #[test]
    fn a_cut_in_retargets_the_gap_terms_of_both_sides() {
        let law = CaccLaw::new(&model(3));
        let q = [85.0, 71.0, 56.0];
        let v = [20.0, 19.0, 21.0];
        let view = PlatoonView {
            leader_position_m: 100.0,
            leader_speed_mps: 20.0,
            positions_m: &q,
            speeds_mps: &v,
        };
        let (mut fixed, mut sensed) = ([0.0; 3], [0.0; 3]);
        law.desired_accelerations(&view, &mut fixed);
        let mut nb = Neighbors::layout(4, false);
        law.desired_accelerations_sensed(&view, &nb, &mut sensed);
        assert_eq!(fixed, sensed);
        let cut = |gap_m| Sensed::Other {
            speed_mps: 15.0,
            gap_m,
        };
        nb.ahead[2] = cut(6.0);
        nb.behind[1] = cut(9.0);
        law.desired_accelerations_sensed(&view, &nb, &mut sensed);
        // Follower 1: μ (20 − 20) + η (gap 10 − 10) + ν (10 − 9).
        assert_relative_eq!(sensed[0], 0.05 * (10.0 - 9.0), epsilon = 1e-15);
        // Follower 2: μ (20 − 19) + η (6 − 10) + ν (10 − its follower's layout gap 10).
        assert_relative_eq!(sensed[1], 1.0 + 0.1 * (6.0 - 10.0), epsilon = 1e-15);
        assert_eq!(sensed[2], fixed[2]);
    }

    #[test]
    fn lag_step_response_matches_closed_form() {
        // a(t) = a_des (1 − e^{−t/τ}), v(t) = a_des (t − τ (1 − e^{−t/τ})).
        let tau = 0.4;
        let dt = 0.001;
        let mut lag = PowertrainLag::new(&[tau], dt);
        let mut v = [0.0];
        let mut next = [0.0];
        for _ in 0..2000 {
            lag.step(&[1.5], &v, &mut next);
            v = next;
        }
        let t: f64 = 2.0;
        assert_relative_eq!(
            lag.accelerations()[0],
            1.5 * (1.0 - (-t / tau).exp()),
            epsilon = 1e-12
        );
        assert_relative_eq!(
            v[0],
            1.5 * (t - tau * (1.0 - (-t / tau).exp())),
            epsilon = 1e-6
        );
    }
}
