//! A linear adaptive cruise control (LACC): a constant-time-gap spacing policy, its gap and
//! speed errors fed back through a first-order actuator lag,
//!
//! `u = k_1 (s − s₀ − h v) + k_2 (v_l − v)`,  `τ a' + a = u`,
//!
//! with `s` the bumper-to-bumper gap to the vehicle ahead (speed `v_l`), `h` the time gap and
//! `s₀` the standstill distance. Each step integrates the lag by Euler, `a ← a + Δt (u − a)/τ`,
//! and the speed by `v_{n+1} = v_n + a Δt` within the vehicle's bounds ([`AccelLimits`]).
//!
//! Defaults are Flow's `LACController` (flow-project/flow,
//! `flow/controllers/car_following_models.py`; the linear ACC of Wu et al.'s Flow benchmarks):
//! `k_1 = 0.3`, `k_2 = 0.4`, `h = 1 s`, `τ = 0.1 s`. Flow subtracts the vehicle length from its
//! bumper-to-bumper headway, which is a standstill distance of one length: `s₀ = 5 m` here.
//!
//! # Reference
//! The constant-time-gap ACC of e.g. V. Milanés and S. E. Shladover, "Modeling cooperative and
//! autonomous adaptive cruise control dynamic responses using experimental data",
//! Transportation Research Part C 48 (2014) 285–300 (its ACC: `a = k_1 e + k_2 ė`); Flow's
//! gains and lag.

use serde::Deserialize;

use crate::actuation::AccelLimits;
use crate::damper::{FleetLaw, RingFleet};
use crate::speed_controller::{law_params, LawContext, LawEntry, Road};

/// The law's entry in [`crate::registry`]: `lacc`, parameters `k_1`, `k_2`, `time_gap_s`,
/// `lag_s`, `standstill_m`.
pub const ENTRY: LawEntry = LawEntry {
    name: "lacc",
    summary: "linear adaptive cruise control: constant time gap, first-order lag (Flow's gains)",
    road: Road::Any,
    looks_behind: false,
    shorthand: None,
    check: |p| law_params::<LaccParams>(p)?.check(),
    build: |c, p| {
        let params: LaccParams = law_params(p)?;
        params.check()?;
        Ok(Box::new(Lacc::new(params, c)))
    },
};

/// The LACC's gains, time gap, lag and standstill distance.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LaccParams {
    /// Gain on the spacing error \[1/s²\].
    pub k_1: f64,
    /// Gain on the speed error \[1/s\].
    pub k_2: f64,
    /// Time gap h \[s\].
    pub time_gap_s: f64,
    /// Actuator lag τ \[s\].
    pub lag_s: f64,
    /// Standstill distance s₀ \[m\].
    pub standstill_m: f64,
}

impl Default for LaccParams {
    /// Flow's defaults (s₀ its vehicle length).
    fn default() -> Self {
        Self {
            k_1: 0.3,
            k_2: 0.4,
            time_gap_s: 1.0,
            lag_s: 0.1,
            standstill_m: 5.0,
        }
    }
}

impl LaccParams {
    fn check(&self) -> Result<(), String> {
        for (name, x) in [
            ("k_1", self.k_1),
            ("k_2", self.k_2),
            ("time_gap_s", self.time_gap_s),
            ("standstill_m", self.standstill_m),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(format!("LACC {name} = {x}: valid is a finite number ≥ 0"));
            }
        }
        if !(self.lag_s.is_finite() && self.lag_s > 0.0) {
            return Err(format!(
                "LACC lag_s = {}: valid is a finite number > 0 s",
                self.lag_s
            ));
        }
        Ok(())
    }

    /// The commanded acceleration u \[m/s²\].
    pub fn command(&self, v: f64, gap: f64, v_lead: f64) -> f64 {
        self.k_1 * (gap - self.standstill_m - self.time_gap_s * v) + self.k_2 * (v_lead - v)
    }
}

/// The LACC on every vehicle (a fleet law over the road's gaps, [`RingFleet`]); one with
/// nobody ahead holds its speed.
struct Lacc {
    params: LaccParams,
    limits: AccelLimits,
    dt_s: f64,
    accel: Vec<f64>,
}

impl Lacc {
    fn new(params: LaccParams, c: &LawContext) -> RingFleet<Self> {
        RingFleet::new(
            c,
            Self {
                params,
                limits: c.limits(),
                dt_s: c.step_s,
                accel: vec![0.0; c.length_m.len()],
            },
        )
    }
}

impl FleetLaw for Lacc {
    fn step_fleet(&mut self, v: &[f64], gaps: &[f64], lead: &[f64], out: &mut [f64]) -> bool {
        let dt = self.dt_s;
        for i in 0..v.len() {
            let u = if gaps[i].is_finite() {
                self.params.command(v[i], gaps[i], lead[i])
            } else {
                0.0
            };
            let a = &mut self.accel[i];
            *a += dt * (u - *a) / self.params.lag_s;
            out[i] = self.limits.next_speed_mps(v[i], v[i] + *a * dt, dt);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::speed_controller::SpeedController;
    use approx::assert_relative_eq;

    #[test]
    fn the_command_and_the_lag_are_the_formulas_by_hand() {
        let p = LaccParams::default();
        // v = 8, gap 20 m, leader 9 m/s: 0.3 (20 − 5 − 8) + 0.4 (1) = 2.1 + 0.4 = 2.5.
        assert_relative_eq!(p.command(8.0, 20.0, 9.0), 2.5, epsilon = 1e-15);
        // At the equilibrium gap s₀ + h v with equal speeds: no command.
        assert_eq!(p.command(8.0, 13.0, 8.0), 0.0);
        // Two cars on an open road, the second 20 m behind the first: step 1 gives
        // a = 0.1·2.5/0.1 = 2.5 (Δt = τ), v = 8 + 0.25; the first, with nobody ahead, holds.
        let c = LawContext {
            step_s: 0.1,
            ids: vec!["a".into(), "b".into()],
            length_m: vec![5.0; 2],
            ring_length_m: None,
            controlled: vec![true; 2],
            accel_mps2: f64::INFINITY,
            decel_mps2: f64::INFINITY,
            speed_limit_mps: None,
            signals: false,
            seed: 0,
            protocol: None,
        };
        let mut law = Lacc::new(p, &c);
        let mut out = [0.0; 2];
        law.step(0.0, &[9.0, 8.0], &[25.0, 0.0], &mut out);
        assert_relative_eq!(out[1], 8.25, epsilon = 1e-12);
        assert_eq!(out[0], 9.0);
    }
}
