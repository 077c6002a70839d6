//! String amplification measured on a run behind a leader: how the peak speed deviation grows
//! or shrinks from one vehicle to the next, beside the exact figure `stability` computes from
//! the transfer functions.
//!
//! With `v_ref` the leader's speed at t = 0 (the cruise speed the platoon starts from) and
//! `p_i = max_t |v_i(t) − v_ref|` the peak deviation of each vehicle (the leader first), the
//! step ratios `p_i / p_{i−1}` say where a disturbance grows: all ≤ 1 for a string-stable
//! platoon whose impulse responses are non-negative (then the L∞ gain equals |H(0)| = 1), and
//! some well above 1 for a string-unstable one. Vehicles whose predecessor never deviated
//! (`p_{i−1} = 0`) give no ratio.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::trajectory::Trajectory;

/// The measured string amplification of a platoon run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StringAmplification {
    /// The first non-zero peak deviation along the platoon (the leader's, or the first
    /// follower's when the leader keeps its speed) \[m/s\].
    pub first_peak_deviation_mps: f64,
    /// The largest `p_i / p_{i−1}` (`null` when no vehicle's predecessor deviated).
    #[schemars(title = "string: worst step ratio")]
    pub worst_step_ratio: Option<f64>,
    /// The follower (0-based, leader not counted) where it occurs.
    #[schemars(title = "string: at follower")]
    pub worst_step_vehicle: Option<usize>,
    /// The last vehicle's peak over the first non-zero peak.
    #[schemars(title = "string: last / first peak")]
    pub end_to_end_ratio: Option<f64>,
}

/// Peaks below this are no deviation at all (rounding of a constant speed).
const NO_DEVIATION_MPS: f64 = 1e-9;

/// The measured amplification of a run with a leader (`None` without one or without samples).
pub fn measured(traj: &Trajectory) -> Option<StringAmplification> {
    if traj.leader_speed_mps.is_empty() || traj.is_empty() {
        return None;
    }
    let v_ref = traj.leader_speed_mps[0];
    let mut peaks = vec![0.0f64; traj.n + 1];
    for k in 0..traj.len() {
        peaks[0] = peaks[0].max((traj.leader_speed_mps[k] - v_ref).abs());
        for (i, v) in traj.speeds(k).iter().enumerate() {
            peaks[i + 1] = peaks[i + 1].max((v - v_ref).abs());
        }
    }
    let first = peaks.iter().copied().find(|p| *p > NO_DEVIATION_MPS)?;
    let mut worst: Option<(f64, usize)> = None;
    for i in 1..peaks.len() {
        if peaks[i - 1] > NO_DEVIATION_MPS {
            let r = peaks[i] / peaks[i - 1];
            if worst.is_none_or(|(w, _)| r > w) {
                worst = Some((r, i - 1));
            }
        }
    }
    Some(StringAmplification {
        first_peak_deviation_mps: first,
        worst_step_ratio: worst.map(|w| w.0),
        worst_step_vehicle: worst.map(|w| w.1),
        end_to_end_ratio: Some(peaks[traj.n] / first),
    })
}
