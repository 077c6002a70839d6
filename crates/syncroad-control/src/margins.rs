//! Safety margins of a run: what a driver trades for its speed. Time headway and the smallest
//! gap come from the trajectory; surrogate safety measures (time to collision, deceleration
//! rate to avoid a crash) from SUMO's SSM device; and a label says whether the law's vehicles
//! ignored SUMO's safe speed.
//!
//! Definitions (vehicle-samples after the warm-up):
//! * **time headway** `h = Δx / v` (bumper-to-bumper gap over the follower's speed) for samples
//!   with `v ≥ 1 m/s`; below 1 m/s a vehicle stands in the jam (the threshold of the jam in
//!   Sugiyama's sense) and `Δx / v` says nothing about how closely it follows. Minimum and mean;
//!   `null` when no sample moves that fast;
//! * **minimum gap** over every sample;
//! * **TTC, DRAC** as SUMO's SSM device logs them (see `SsmSummary`): conflicts whose TTC fell
//!   below, or DRAC rose above, the device's thresholds after the warm-up;
//! * **ignores safe speed**: some vehicle took law commands with bit 0 of SUMO's speed mode
//!   off, so SUMO did not cap its command at the safe speed towards its leader.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use crate::sumo_facts::SsmSummary;
use crate::sumo_facts::SumoFacts;
use crate::trajectory::Trajectory;

/// Speed below which a sample has no meaningful time headway \[m/s\].
pub const HEADWAY_MIN_SPEED_MPS: f64 = 1.0;

/// Safety margins of one run (present in the record when the run measured them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SafetyMargins {
    /// Smallest time headway Δx/v over samples with v ≥ 1 m/s \[s\].
    #[schemars(title = "time headway min")]
    pub time_headway_min_s: Option<f64>,
    /// Mean time headway over the same samples \[s\].
    #[schemars(title = "time headway mean")]
    pub time_headway_mean_s: Option<f64>,
    /// Smallest bumper-to-bumper gap \[m\].
    #[schemars(title = "min gap")]
    pub min_gap_m: Option<f64>,
    /// Some law-commanded vehicle drove with SUMO's safe-speed check off (speed mode bit 0).
    #[schemars(title = "ignores SUMO's safe speed")]
    pub ignores_safe_speed: bool,
    /// SUMO's speed mode of the law-commanded vehicles (`null` when SUMO drives every vehicle).
    pub law_speed_mode: Option<i32>,
    /// SUMO's surrogate safety measures.
    pub ssm: SsmSummary,
}

impl SafetyMargins {
    /// The margins of a trajectory after `warmup_s`, with SUMO's SSM summary; `None` unless the
    /// run measured SSM.
    pub fn of(traj: &Trajectory, warmup_s: f64, facts: &SumoFacts) -> Option<Self> {
        let ssm = facts.ssm.clone()?;
        let first = traj.time_s.partition_point(|&t| t < warmup_s - 1e-9);
        let n = traj.n;
        let (mut h_min, mut h_sum, mut h_count) = (f64::INFINITY, 0.0, 0usize);
        let mut gap_min = f64::INFINITY;
        for k in first..traj.len() {
            for i in 0..n {
                let gap = traj.gaps_m.get(k * n + i).copied().unwrap_or(f64::NAN);
                if !gap.is_finite() {
                    continue;
                }
                gap_min = gap_min.min(gap);
                let v = traj.speeds_mps[k * n + i];
                if v >= HEADWAY_MIN_SPEED_MPS {
                    let h = gap / v;
                    h_min = h_min.min(h);
                    h_sum += h;
                    h_count += 1;
                }
            }
        }
        let law_driven = facts.drivers.iter().any(|d| !is_sumo_driver(d));
        let law_speed_mode = facts.law_speed_mode.filter(|_| law_driven);
        Some(Self {
            time_headway_min_s: (h_count > 0).then_some(h_min),
            time_headway_mean_s: (h_count > 0).then(|| h_sum / h_count as f64),
            min_gap_m: gap_min.is_finite().then_some(gap_min),
            ignores_safe_speed: law_speed_mode.is_some_and(|m| m & 1 == 0),
            law_speed_mode,
            ssm,
        })
    }
}

/// Time headway below which a moving vehicle follows unsafely closely \[s\]: the IDM's safe time
/// headway T of Flow's ring benchmark (`IDMController`, T = 1 s).
pub const SAFE_HEADWAY_S: f64 = 1.0;

/// Gap safety of every run, from the trajectory alone (no SUMO device needed), so an all-damper
/// ring, which runs with SUMO's checks off, has its closest approach and collisions counted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GapSafety {
    #[schemars(title = "min gap")]
    /// Smallest bumper-to-bumper gap after the warm-up \[m\]; ≤ 0 means vehicles touched.
    pub min_gap_m: f64,
    /// Vehicle-time after the warm-up with v ≥ 1 m/s and Δx/v < [`SAFE_HEADWAY_S`] \[s\],
    /// summed over vehicles (each sample stands for the time to the next one); null with fewer
    /// than two samples after the warm-up, where no time is measured.
    #[schemars(title = "time below a 1 s headway")]
    pub time_below_safe_headway_s: Option<f64>,
    /// Vehicle-samples with a gap ≤ 0 after the warm-up (overlaps: collisions).
    #[schemars(title = "overlapping vehicle-samples")]
    pub overlap_samples: usize,
    /// Smallest time headway Δx/v after the warm-up over the samples with v ≥ 1 m/s \[s\];
    /// null when no vehicle drove that fast.
    #[serde(default)]
    #[schemars(title = "min time headway")]
    pub min_time_headway_s: Option<f64>,
}

impl GapSafety {
    /// The gap safety of a trajectory after `warmup_s`; `None` without gaps (a road without
    /// leaders) or samples.
    pub fn of(traj: &Trajectory, warmup_s: f64) -> Option<Self> {
        let first = traj.time_s.partition_point(|&t| t < warmup_s - 1e-9);
        let n = traj.n;
        let (mut min_gap, mut below, mut overlaps) = (f64::INFINITY, 0.0, 0usize);
        let mut min_headway = f64::INFINITY;
        for k in first..traj.len() {
            let dt = if k + 1 < traj.len() {
                traj.time_s[k + 1] - traj.time_s[k]
            } else {
                0.0
            };
            for i in 0..n {
                let gap = traj.gaps_m.get(k * n + i).copied().unwrap_or(f64::NAN);
                if !gap.is_finite() {
                    continue;
                }
                min_gap = min_gap.min(gap);
                overlaps += usize::from(gap <= 0.0);
                let v = traj.speeds_mps[k * n + i];
                if v >= HEADWAY_MIN_SPEED_MPS {
                    min_headway = min_headway.min(gap / v);
                    if gap / v < SAFE_HEADWAY_S {
                        below += dt;
                    }
                }
            }
        }
        min_gap.is_finite().then_some(Self {
            min_gap_m: min_gap,
            time_below_safe_headway_s: (traj.len() >= first + 2).then_some(below),
            overlap_samples: overlaps,
            min_time_headway_s: min_headway.is_finite().then_some(min_headway),
        })
    }
}

/// True for a driver label of a SUMO car-following model (the law, the dampers and the
/// stochastic humans of [`crate::noisy_idm`] are commanded by the bridge).
fn is_sumo_driver(label: &str) -> bool {
    // Labels are drivers' names as they print ([`SumoDriver`]'s `Display`); the law's and the
    // dampers' names are no driver's.
    crate::drive::SumoDriver::parse("driver", label).is_ok_and(|d| !d.commanded_by_bridge())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn facts(drivers: &[&str], mode: i32) -> SumoFacts {
        SumoFacts {
            drivers: drivers.iter().map(|s| s.to_string()).collect(),
            law_speed_mode: Some(mode),
            ssm: Some(SsmSummary::default()),
            ..SumoFacts::default()
        }
    }

    #[test]
    fn gap_safety_counts_close_following_time_and_overlaps() {
        let mut t = Trajectory::new(2);
        // Before the warm-up: ignored.
        t.push(0.0, &[5.0, 5.0], &[0.0, 0.0], &[0.1, 0.1], None);
        // 1 s to the next sample: vehicle 0 at 4 m/s with 2 m (0.5 s headway) counts 1 s;
        // vehicle 1 at 2 m/s with 3 m (1.5 s) does not.
        t.push(1.0, &[4.0, 2.0], &[0.0, 0.0], &[2.0, 3.0], None);
        // 0.5 s to the next: vehicle 0 standing (no headway), vehicle 1 overlaps.
        t.push(2.0, &[0.5, 5.0], &[0.0, 0.0], &[2.5, -0.2], None);
        t.push(2.5, &[0.5, 5.0], &[0.0, 0.0], &[2.5, 8.0], None);
        let g = GapSafety::of(&t, 1.0).unwrap();
        assert_relative_eq!(g.min_gap_m, -0.2);
        // Vehicle 1 at 5 m/s with −0.2 m is below 1 s too: 1 s + 0.5 s.
        assert_relative_eq!(g.time_below_safe_headway_s.unwrap(), 1.5);
        assert_eq!(g.overlap_samples, 1);
        // Headways of the samples at ≥ 1 m/s: 2/4, 3/2, −0.2/5, 8/5: the least is −0.04 s.
        assert_relative_eq!(g.min_time_headway_s.unwrap(), -0.04);
        // One sample after the warm-up measures no time: null, not 0 (the gap still counts);
        // its only vehicles at ≥ 1 m/s have 8/5 = 1.6 s.
        let g = GapSafety::of(&t, 2.5).unwrap();
        assert_eq!(g.time_below_safe_headway_s, None);
        assert_relative_eq!(g.min_gap_m, 2.5);
        assert_relative_eq!(g.min_time_headway_s.unwrap(), 1.6);
    }

    #[test]
    fn headway_and_gap_follow_their_definitions() {
        let mut t = Trajectory::new(2);
        // Before the warm-up (ignored): a tiny gap.
        t.push(0.0, &[5.0, 5.0], &[0.0, 0.0], &[0.1, 0.1], None);
        // v = 4 with gap 8 → 2 s; v = 2 with gap 3 → 1.5 s.
        t.push(1.0, &[4.0, 2.0], &[0.0, 0.0], &[8.0, 3.0], None);
        // v = 0.5 (in the jam): gap 2.5 counts for the minimum gap, not for the headway.
        t.push(2.0, &[0.5, 5.0], &[0.0, 0.0], &[2.5, 10.0], None);
        let m = SafetyMargins::of(&t, 1.0, &facts(&["protocol", "human"], 32)).unwrap();
        assert_relative_eq!(m.time_headway_min_s.unwrap(), 1.5);
        assert_relative_eq!(m.time_headway_mean_s.unwrap(), (2.0 + 1.5 + 2.0) / 3.0);
        assert_relative_eq!(m.min_gap_m.unwrap(), 2.5);
        assert!(m.ignores_safe_speed);
        // Speed mode 1 keeps the safe speed; with only SUMO drivers no mode applies.
        assert!(
            !SafetyMargins::of(&t, 1.0, &facts(&["protocol", "human"], 1))
                .unwrap()
                .ignores_safe_speed
        );
        let humans = SafetyMargins::of(&t, 1.0, &facts(&["human", "idm"], 32)).unwrap();
        assert!(!humans.ignores_safe_speed);
        assert_eq!(humans.law_speed_mode, None);
        // Without SSM the run did not measure margins.
        let mut f = facts(&["protocol"], 32);
        f.ssm = None;
        assert_eq!(SafetyMargins::of(&t, 1.0, &f), None);
    }
}
