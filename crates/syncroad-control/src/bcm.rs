//! The bilateral control model (BCM) of Horn (2013): each vehicle looks ahead and behind and
//! accelerates to stand midway between its leader and its follower, at the speed between
//! theirs, with a pull towards a desired speed:
//!
//! `a_i = k_d (s_i − s_f) + k_v ((v_l − v_i) − (v_i − v_f)) + k_c (v_des − v_i)`,
//!
//! with `s_i` the gap to the vehicle ahead (speed `v_l`) and `s_f` the gap of the vehicle
//! behind (speed `v_f`) to this one. The acceleration is tracked over the step within the
//! vehicle's bounds ([`AccelLimits`]): `v_{n+1} = v_n + a Δt`, clamped to `[−b Δt, a_max Δt]`
//! and at least 0. On a ring every vehicle has both neighbours (the law's entry needs a ring).
//!
//! Defaults are Flow's `BCMController` (flow-project/flow,
//! `flow/controllers/car_following_models.py`): `k_d = k_v = k_c = 1`, `v_des = 8 m/s`.
//!
//! # Reference
//! B. K. P. Horn, "Suppressing traffic flow instabilities", Proc. 16th International IEEE
//! Conference on Intelligent Transportation Systems (ITSC 2013), 13–20: the bilateral
//! control law (its k_d and k_v terms); the k_c term is Flow's.

use serde::Deserialize;

use crate::actuation::AccelLimits;
use crate::road::RingView;
use crate::speed_controller::{law_params, LawContext, LawEntry, Road, SpeedController};

/// The law's entry in [`crate::registry`]: `bcm`, parameters `k_d`, `k_v`, `k_c`,
/// `desired_speed_mps`.
pub const ENTRY: LawEntry = LawEntry {
    name: "bcm",
    summary:
        "bilateral control model of Horn (2013): midway between leader and follower (Flow's gains)",
    road: Road::Ring,
    looks_behind: true,
    shorthand: None,
    check: |p| law_params::<BcmParams>(p)?.check(),
    build: |c, p| {
        let params: BcmParams = law_params(p)?;
        params.check()?;
        Ok(Box::new(Bcm::new(params, c)))
    },
};

/// The BCM's gains.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BcmParams {
    /// Gain on the difference of the gaps ahead and behind \[1/s²\].
    pub k_d: f64,
    /// Gain on the difference of the relative speeds ahead and behind \[1/s\].
    pub k_v: f64,
    /// Gain on the distance to the desired speed \[1/s\].
    pub k_c: f64,
    /// Desired speed \[m/s\].
    pub desired_speed_mps: f64,
}

impl Default for BcmParams {
    /// Flow's defaults.
    fn default() -> Self {
        Self {
            k_d: 1.0,
            k_v: 1.0,
            k_c: 1.0,
            desired_speed_mps: 8.0,
        }
    }
}

impl BcmParams {
    fn check(&self) -> Result<(), String> {
        for (name, x) in [
            ("k_d", self.k_d),
            ("k_v", self.k_v),
            ("k_c", self.k_c),
            ("desired_speed_mps", self.desired_speed_mps),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(format!("BCM {name} = {x}: valid is a finite number ≥ 0"));
            }
        }
        Ok(())
    }

    /// The BCM's acceleration \[m/s²\].
    pub fn accel(&self, v: f64, gap: f64, v_lead: f64, gap_behind: f64, v_behind: f64) -> f64 {
        self.k_d * (gap - gap_behind)
            + self.k_v * ((v_lead - v) - (v - v_behind))
            + self.k_c * (self.desired_speed_mps - v)
    }
}

/// The BCM on every vehicle of a ring.
struct Bcm {
    params: BcmParams,
    view: RingView,
    limits: AccelLimits,
    dt_s: f64,
}

impl Bcm {
    fn new(params: BcmParams, c: &LawContext) -> Self {
        Self {
            params,
            view: RingView::on(c.ring_length_m, &c.length_m),
            limits: c.limits(),
            dt_s: c.step_s,
        }
    }
}

impl SpeedController for Bcm {
    fn step(&mut self, _t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        self.view.observe(speeds, positions);
        let n = speeds.len();
        for i in 0..n {
            // Vehicle i follows i − 1, so the vehicle behind i is i + 1, and vehicle 0 is
            // behind vehicle N − 1 (one lap on).
            let f = (i + 1) % n;
            let a = self.params.accel(
                speeds[i],
                self.view.gaps_m[i],
                self.view.leader_speeds_mps[i],
                self.view.gaps_m[f],
                speeds[f],
            );
            out[i] = self
                .limits
                .next_speed_mps(speeds[i], speeds[i] + a * self.dt_s, self.dt_s);
        }
    }

    fn sense(&mut self, neighbors: &crate::sensed::Neighbors) {
        self.view.sense(neighbors);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn the_acceleration_is_horns_formula_by_hand() {
        let p = BcmParams::default();
        // v = 6, ahead 12 m at 7 m/s, behind 8 m at 5 m/s:
        // 1·(12 − 8) + 1·((7 − 6) − (6 − 5)) + 1·(8 − 6) = 4 + 0 + 2 = 6.
        assert_relative_eq!(p.accel(6.0, 12.0, 7.0, 8.0, 5.0), 6.0, epsilon = 1e-15);
        // Midway at the common desired speed: no acceleration.
        assert_eq!(p.accel(8.0, 10.0, 8.0, 10.0, 8.0), 0.0);
    }

    #[test]
    fn on_a_ring_each_vehicle_reads_the_one_ahead_and_the_one_behind() {
        // Three 5 m cars on a 100 m ring, rear bumpers at 60, 40, 10: gaps 45 (vehicle 0,
        // behind vehicle 2 one lap on), 15, 25; vehicle 1's follower is vehicle 2 (gap 25).
        let c = LawContext {
            step_s: 0.1,
            ids: vec!["a".into(), "b".into(), "c".into()],
            length_m: vec![5.0; 3],
            ring_length_m: Some(100.0),
            controlled: vec![true; 3],
            accel_mps2: f64::INFINITY,
            decel_mps2: f64::INFINITY,
            speed_limit_mps: None,
            signals: false,
            seed: 0,
            protocol: None,
        };
        let p = BcmParams::default();
        let mut law = Bcm::new(p, &c);
        let v = [8.0, 7.0, 6.0];
        let mut out = [0.0; 3];
        law.step(0.0, &v, &[60.0, 40.0, 10.0], &mut out);
        // Vehicle 1: gap 15 to vehicle 0 (8 m/s), its follower vehicle 2 at 25 m, 6 m/s.
        let a1 = p.accel(7.0, 15.0, 8.0, 25.0, 6.0);
        assert_relative_eq!(out[1], 7.0 + a1 * 0.1, epsilon = 1e-12);
        // Vehicle 0 follows vehicle 2 (gap 45, 6 m/s), vehicle 1 is behind it (gap 15).
        let a0 = p.accel(8.0, 45.0, 6.0, 15.0, 7.0);
        assert_relative_eq!(out[0], 8.0 + a0 * 0.1, epsilon = 1e-12);
    }
}
