//! The safety layer between every law and the command: the scenario's `safety` key.
//!
//! * `off` — the law's command goes out as it is (SUMO's speed mode 32: every check off). The
//!   record says so, and a run whose vehicles collide is marked unsafe ([`crate::record::safe`]).
//! * `sumo` — SUMO's own checks through the speed mode: its safe
//!   speed towards the vehicle ahead, right of way at junctions, braking for red lights
//!   ([`SafetyMode::speed_mode`]); the commands it did not realise are counted
//!   (`safety.overridden_commands`).
//! * `filter` — syncroad's own filter, the same code on both backends: every command of a
//!   law-driven vehicle is capped by the safe speed of Gipps (1981) towards the vehicle ahead,
//!   `v_safe = −b τ + √(b² τ² + v_l² + 2 b (s − s₀))`: the largest speed from which the
//!   follower, reacting after τ and braking at b, stops behind a leader that brakes at b from
//!   v_l, keeping the standstill gap s₀ ([`safe_speed_mps`]). s is the bumper-to-bumper gap,
//!   s₀ the vehicle type's `minGap`, b its `decel`, τ = [`REACTION_S`] (SUMO's default `tau`,
//!   so the filter keeps the margin SUMO's own drivers keep). In SUMO the vehicles also brake
//!   for red lights (speed mode bit 4).
//!
//! The default is `sumo` when other traffic shares the road (SUMO's drivers among the law's
//! vehicles, the user's routes, additional files or configuration) or the network has traffic
//! lights: that traffic and those signals go by SUMO's rules, and a law that ignored them
//! would drive into the traffic or through red lights. It is
//! `off` when the law drives every vehicle alone (the paper's rings and platoons, the
//! stochastic humans), so those runs stay the law's exact dynamics, checkable against the
//! native simulator and the exact analysis; their collisions mark them unsafe.
//!
//! # Reference
//! P. G. Gipps, "A behavioural car-following model for computer simulation", Transportation
//! Research Part B 15(2) (1981) 105–111: the safe speed with equal deceleration estimates.

use serde::{Deserialize, Serialize};

use crate::road::RingView;
pub use crate::scenario::SafetyMode;
use crate::sensed::Neighbors;
pub use crate::speed_controller::FilterReport;
use crate::speed_controller::{ControllerEnd, SpeedController};

/// The reaction time τ of the filter's safe speed \[s\]: SUMO's default `tau`.
pub const REACTION_S: f64 = 1.0;

/// Cuts smaller than this are rounding, not overrides \[m/s\].
const CUT_EPS_MPS: f64 = 1e-9;

/// The filter's parameters: the vehicle type's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilterParams {
    /// Standstill gap s₀ (SUMO's `minGap`) \[m\].
    pub min_gap_m: f64,
    /// Deceleration b assumed of the follower and the leader \[m/s²\].
    pub decel_mps2: f64,
    /// Reaction time τ \[s\].
    pub reaction_s: f64,
    /// The road's speed limit \[m/s\] (in SUMO its lowest lane limit along the road, times
    /// the vehicles' speed factor of 1), which no command exceeds; `None`: no limit (the
    /// native simulator's road has none).
    #[serde(default)]
    pub speed_limit_mps: Option<f64>,
}

/// The safety layer a run drove under, as the record reports it: what actually ran.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct SafetyLayer {
    /// `off`, `sumo` or `filter`.
    pub mode: SafetyMode,
    /// What the filter did (`filter` only).
    pub filter: Option<FilterReport>,
}

impl SafetyLayer {
    /// The layer of a run whose controller reported `filter` (the filter ran) or not (the
    /// run's other layer, `otherwise`: SUMO's checks, or none).
    pub fn of(filter: Option<FilterReport>, otherwise: SafetyMode) -> Self {
        Self {
            mode: if filter.is_some() {
                SafetyMode::Filter
            } else {
                otherwise
            },
            filter,
        }
    }
}

/// Gipps' safe speed \[m/s\] behind a leader at `leader_mps`, `gap_m` bumper to bumper,
/// keeping `p.min_gap_m` at a standstill; 0 when even a stop now is too late.
pub fn safe_speed_mps(gap_m: f64, leader_mps: f64, p: &FilterParams) -> f64 {
    let b = p.decel_mps2;
    let bt = b * p.reaction_s;
    let room = gap_m - p.min_gap_m;
    let disc = bt * bt + leader_mps.max(0.0).powi(2) + 2.0 * b * room;
    if disc <= 0.0 {
        return 0.0;
    }
    (disc.sqrt() - bt).max(0.0)
}

/// A law with the filter under it: its commands to the vehicles in `controlled` are capped by
/// the safe speed towards whoever is ahead (the layout's predecessor, or the vehicle SUMO
/// senses there when other traffic shares the road).
pub struct SafetyFilter {
    inner: Box<dyn SpeedController>,
    view: RingView,
    controlled: Vec<bool>,
    params: FilterParams,
    report: FilterReport,
}

impl SafetyFilter {
    /// `inner` under the filter, on the road of `view`.
    pub fn new(
        inner: Box<dyn SpeedController>,
        view: RingView,
        controlled: Vec<bool>,
        params: FilterParams,
    ) -> Self {
        Self {
            inner,
            view,
            controlled,
            params,
            report: FilterReport::default(),
        }
    }
}

impl SpeedController for SafetyFilter {
    fn step(&mut self, t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        self.inner.step(t, speeds, positions, out);
        self.view.observe(speeds, positions);
        for (i, o) in out.iter_mut().enumerate() {
            let gap = self.view.gaps_m[i];
            if !self.controlled.get(i).copied().unwrap_or(false) {
                continue;
            }
            let limit = self.params.speed_limit_mps.unwrap_or(f64::INFINITY);
            let safe = if gap.is_finite() {
                safe_speed_mps(gap, self.view.leader_speeds_mps[i], &self.params)
            } else {
                f64::INFINITY
            }
            .min(limit);
            let cut = *o - safe;
            if cut > CUT_EPS_MPS {
                *o = safe;
                self.report.overrides += 1;
                self.report.largest_cut_mps = self.report.largest_cut_mps.max(cut);
            }
        }
    }

    fn sense(&mut self, neighbors: &Neighbors) {
        self.inner.sense(neighbors);
        self.view.sense(neighbors);
    }

    fn ended(&mut self) -> Option<ControllerEnd> {
        self.inner.ended()
    }

    fn filter_report(&self) -> Option<FilterReport> {
        Some(self.report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const P: FilterParams = FilterParams {
        min_gap_m: 2.5,
        decel_mps2: 4.5,
        reaction_s: 1.0,
        speed_limit_mps: None,
    };

    /// The safe speed is the largest v whose stopping distance v τ + v²/(2b) fits in the
    /// room left by the leader's, s − s₀ + v_l²/(2b): equality there, and a stop in time.
    #[test]
    fn the_safe_speed_stops_exactly_behind_a_braking_leader() {
        for (gap, vl) in [(5.45, 7.8), (10.0, 0.0), (30.0, 20.0), (2.5, 3.0)] {
            let v = safe_speed_mps(gap, vl, &P);
            let follower = v * P.reaction_s + v * v / (2.0 * P.decel_mps2);
            let room = gap - P.min_gap_m + vl * vl / (2.0 * P.decel_mps2);
            assert_relative_eq!(follower, room, epsilon = 1e-12);
        }
        // The Sugiyama ring: 22 cars of 5 m on 230 m, gap 5.45 m, all at 7.8 m/s: the safe
        // speed is −4.5 + √(4.5² + 7.8² + 2·4.5·2.95) = 5.869… m/s, below the law's 7.8.
        assert_relative_eq!(
            safe_speed_mps(5.45, 7.8, &P),
            -4.5 + (20.25f64 + 60.84 + 26.55).sqrt(),
            epsilon = 1e-12
        );
        // Closer than the standstill gap behind a stopped car: stop.
        assert_eq!(safe_speed_mps(1.0, 0.0, &P), 0.0);
    }

    struct Constant(f64);
    impl SpeedController for Constant {
        fn step(&mut self, _t: f64, _v: &[f64], _q: &[f64], out: &mut [f64]) {
            out.fill(self.0);
        }
    }

    #[test]
    fn the_filter_caps_the_law_where_it_is_unsafe_and_counts_it() {
        // Three 5 m cars on a 100 m ring, rear bumpers at 60, 40, 10: gaps 45, 15, 25 m; the
        // law wants 12 m/s everywhere, every car drives 8 m/s.
        let view = RingView::new(100.0, &[5.0; 3]);
        let mut f = SafetyFilter::new(Box::new(Constant(12.0)), view, vec![true, true, false], P);
        let mut out = [0.0; 3];
        f.step(0.0, &[8.0; 3], &[60.0, 40.0, 10.0], &mut out);
        let v1 = safe_speed_mps(15.0, 8.0, &P);
        assert!(v1 < 12.0);
        // Vehicle 0 (45 m) is safe at 12; vehicle 1 (15 m) is capped; vehicle 2 is not the
        // law's (a human), untouched.
        assert!(safe_speed_mps(45.0, 8.0, &P) > 12.0);
        assert_eq!(out, [12.0, v1, 12.0]);
        assert_eq!(
            f.filter_report(),
            Some(FilterReport {
                overrides: 1,
                largest_cut_mps: 12.0 - v1
            })
        );
    }

    #[test]
    fn the_filter_keeps_the_speed_limit_even_with_nobody_ahead() {
        // An open road: vehicle 0 has nobody ahead, vehicle 1 is 200 m behind it; the law
        // wants 40 m/s on a 15 m/s road.
        let view = RingView::on(None, &[5.0; 2]);
        let p = FilterParams {
            speed_limit_mps: Some(15.0),
            ..P
        };
        let mut f = SafetyFilter::new(Box::new(Constant(40.0)), view, vec![true; 2], p);
        let mut out = [0.0; 2];
        f.step(0.0, &[14.0, 14.0], &[205.0, 0.0], &mut out);
        assert_eq!(out, [15.0, 15.0]);
        assert_eq!(f.filter_report().unwrap().overrides, 2);
    }
}
