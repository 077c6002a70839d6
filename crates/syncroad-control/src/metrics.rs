//! Synchronization metrics and the verdict.
//!
//! * `spread(t) = max_ij |v_i(t) − v_j(t)|` without a leader (eq. `sync`), and
//!   `max_i |v_i(t) − v_0(t)|` with one (eq. `sync1`);
//! * its L2 norm `(∫ spread² dt)^{1/2}` (eq. `sync+`, trapezoidal rule over the samples);
//! * the final spread, the time after which the spread stays within the tolerance, and the
//!   exponential decay rate fitted to `ln spread` over the second half of the run.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::trajectory::Trajectory;

/// Outcome of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The spread stayed within the tolerance over the final window.
    Synchronized,
    /// The spread did not decay (or the run diverged).
    NotSynchronized,
    /// The spread decays but had not reached the tolerance by the horizon.
    Inconclusive,
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Verdict::Synchronized => "synchronized",
            Verdict::NotSynchronized => "not synchronized",
            Verdict::Inconclusive => "inconclusive",
        })
    }
}

/// Thresholds of the verdict.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct VerdictThresholds {
    /// Spread tolerance [m/s].
    pub tolerance_mps: f64,
    /// Final window [s].
    pub window_s: f64,
}

/// Synchronization metrics of one run. The spread figures are `null` for a run that produced
/// no sample (it never started, or died before its first step): nothing was measured, so
/// nothing is reported, and its verdict is "not synchronized" with that reason.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SyncMetrics {
    /// Whether the spread is taken against the leader speed v_0.
    pub against_leader: bool,
    /// Spread at t = 0 [m/s].
    #[schemars(title = "initial spread")]
    pub initial_spread_mps: Option<f64>,
    /// Spread at the last sample [m/s].
    #[schemars(title = "final spread")]
    pub final_spread_mps: Option<f64>,
    /// Largest spread over the final window [m/s].
    #[schemars(title = "max spread over the final window")]
    pub window_max_spread_mps: Option<f64>,
    /// Largest spread over the run [m/s].
    #[schemars(title = "max spread")]
    pub max_spread_mps: Option<f64>,
    /// `(∫ spread² dt)^{1/2}` [m/s·√s].
    #[schemars(title = "L2 norm of the spread")]
    pub spread_l2: Option<f64>,
    /// First time after which the spread stays ≤ tolerance [s], if it does.
    #[schemars(title = "time to tolerance")]
    pub time_to_tolerance_s: Option<f64>,
    /// Fitted exponential rate of `spread ~ e^{rate·t}` over the second half [1/s]
    /// (negative = decaying), if enough samples lie above round-off.
    #[schemars(title = "fitted decay rate")]
    pub decay_rate_per_s: Option<f64>,
    /// Largest |gap − desired gap| at the last sample [m], for platoons.
    pub final_gap_error_m: Option<f64>,
    /// The verdict.
    #[schemars(title = "verdict")]
    pub verdict: Verdict,
    /// Why the verdict is not what the spread alone says: SUMO overrode the law (collisions,
    /// teleports, overridden commands); `null` when the spread decides.
    pub verdict_reason: Option<String>,
    /// Thresholds used.
    pub thresholds: VerdictThresholds,
    /// True when the run stopped before its horizon.
    pub incomplete: bool,
}

/// The smallest and largest of `speeds` (NaN ignored; `(∞, −∞)` when there is none).
pub fn speed_range(speeds: &[f64]) -> (f64, f64) {
    speeds
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
}

/// The spread of speeds lying in `[lo, hi]`: `hi − lo` without a leader (eq. `sync`), and
/// `max_i |v_i − v_0| = max(hi − v_0, v_0 − lo)` against the leader speed `v_0` (eq. `sync1`).
pub fn spread_of_range(lo: f64, hi: f64, leader: Option<f64>) -> f64 {
    match leader {
        Some(v0) => (hi - v0).max(v0 - lo).max(0.0),
        None => hi - lo,
    }
}

/// Spread of sample `k`.
pub fn spread_at(traj: &Trajectory, k: usize) -> f64 {
    let (lo, hi) = speed_range(traj.speeds(k));
    spread_of_range(lo, hi, traj.leader(k))
}

/// Spread over all samples.
pub fn spread_series(traj: &Trajectory) -> Vec<f64> {
    (0..traj.len()).map(|k| spread_at(traj, k)).collect()
}

/// The spread at every step of a run, whatever stride the trajectory was recorded at: the
/// metrics are computed from it, so `--record-every` changes the files, never the numbers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpreadSeries {
    /// Step times \[s\].
    pub time_s: Vec<f64>,
    /// Spread at each time \[m/s\].
    pub spread_mps: Vec<f64>,
}

impl SpreadSeries {
    /// The spread of every sample of a trajectory.
    pub fn of_trajectory(traj: &Trajectory) -> Self {
        Self {
            time_s: traj.time_s.clone(),
            spread_mps: spread_series(traj),
        }
    }

    /// Appends the spread at time `t`.
    pub fn push(&mut self, t: f64, spread_mps: f64) {
        self.time_s.push(t);
        self.spread_mps.push(spread_mps);
    }

    /// Number of steps.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// True when nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }
}

/// Least-squares slope of `ln y` against `t` over the samples with `y > floor`.
pub fn fit_decay_rate(t: &[f64], y: &[f64], floor: f64) -> Option<f64> {
    let pts: Vec<(f64, f64)> = t
        .iter()
        .zip(y)
        .filter(|(_, &y)| y > floor && y.is_finite())
        .map(|(&t, &y)| (t, y.ln()))
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let m = pts.len() as f64;
    let (st, sy) = pts.iter().fold((0.0, 0.0), |(a, b), (t, y)| (a + t, b + y));
    let (mt, my) = (st / m, sy / m);
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (t, y) in &pts {
        sxx += (t - mt) * (t - mt);
        sxy += (t - mt) * (y - my);
    }
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Computes the metrics and verdict; `desired_gaps` enables the platoon gap error;
/// `incomplete` marks runs that stopped early (they are never "synchronized").
pub fn sync_metrics(
    traj: &Trajectory,
    thresholds: VerdictThresholds,
    desired_gaps: Option<&[f64]>,
    incomplete: bool,
) -> SyncMetrics {
    sync_metrics_of(
        &SpreadSeries::of_trajectory(traj),
        traj,
        thresholds,
        desired_gaps,
        incomplete,
    )
}

/// [`sync_metrics`] with the spread taken from `spread` (every step of the run) rather than
/// from the recorded samples; `traj` gives the final gaps.
pub fn sync_metrics_of(
    spread: &SpreadSeries,
    traj: &Trajectory,
    thresholds: VerdictThresholds,
    desired_gaps: Option<&[f64]>,
    incomplete: bool,
) -> SyncMetrics {
    let s = &spread.spread_mps;
    let t = &spread.time_s;
    let last = s.len().saturating_sub(1);
    let t_end = t.last().copied().unwrap_or(0.0);
    let mut l2 = 0.0;
    for k in 1..s.len() {
        l2 += 0.5 * (t[k] - t[k - 1]) * (s[k] * s[k] + s[k - 1] * s[k - 1]);
    }
    let window_start = t_end - thresholds.window_s;
    let window_max = t
        .iter()
        .zip(s)
        .filter(|(&tk, _)| tk >= window_start - 1e-9)
        .map(|(_, &x)| x)
        .fold(0.0, f64::max);
    let max_spread = s.iter().copied().fold(0.0, f64::max);
    let time_to_tol = match s
        .iter()
        .rposition(|&x| x.is_nan() || x > thresholds.tolerance_mps)
    {
        None => Some(0.0),
        Some(k) if k < last => Some(t[k + 1]),
        Some(_) => None,
    };
    let half = s.len() / 2;
    // Fit only above a floor well clear of round-off relative to the initial spread.
    let floor = 1e-10 * s.first().copied().unwrap_or(1.0).max(1e-300);
    let rate = fit_decay_rate(&t[half..], &s[half..], floor);
    let final_gap_error = desired_gaps.filter(|_| !traj.is_empty()).map(|d| {
        traj.gaps(traj.len() - 1)
            .iter()
            .zip(d)
            .map(|(g, d)| (g - d).abs())
            .fold(0.0, f64::max)
    });
    let diverged = s.iter().any(|x| !x.is_finite());
    // A run cut off before its horizon has no verdict of its own but a diverged spread: what
    // it would have done is not known (the caller says why it stopped, and a stop that is a
    // finding, such as a divergence or a lost vehicle, makes it "not synchronized").
    let verdict = if diverged {
        Verdict::NotSynchronized
    } else if incomplete {
        Verdict::Inconclusive
    } else if window_max <= thresholds.tolerance_mps {
        Verdict::Synchronized
    } else if rate.is_none_or(|r| r >= -1e-3) {
        Verdict::NotSynchronized
    } else {
        Verdict::Inconclusive
    };
    let measured = !s.is_empty();
    let some = |x: f64| measured.then_some(x);
    SyncMetrics {
        against_leader: !traj.leader_speed_mps.is_empty(),
        initial_spread_mps: s.first().copied(),
        final_spread_mps: s.get(last).copied(),
        window_max_spread_mps: some(window_max),
        max_spread_mps: some(max_spread),
        spread_l2: some(l2.sqrt()),
        time_to_tolerance_s: time_to_tol.filter(|_| measured),
        decay_rate_per_s: rate,
        final_gap_error_m: final_gap_error,
        verdict: if measured {
            verdict
        } else {
            Verdict::Inconclusive
        },
        verdict_reason: (!measured).then(|| "the run produced no sample".to_string()),
        thresholds,
        incomplete,
    }
}

impl Verdict {
    /// How bad a verdict is: synchronized < inconclusive < not synchronized.
    fn rank(self) -> u8 {
        match self {
            Verdict::Synchronized => 0,
            Verdict::Inconclusive => 1,
            Verdict::NotSynchronized => 2,
        }
    }
}

impl SyncMetrics {
    /// Caps the verdict at `at_best` because of `reason`: a verdict already worse stays, and
    /// the reason is recorded either way.
    pub fn overrule(&mut self, at_best: Verdict, reason: String) {
        if at_best.rank() > self.verdict.rank() {
            self.verdict = at_best;
        }
        self.verdict_reason = Some(match self.verdict_reason.take() {
            Some(r) => format!("{r}; {reason}"),
            None => reason,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn traj_from(f: impl Fn(f64) -> f64, t_end: f64, dt: f64) -> Trajectory {
        let mut tr = Trajectory::new(2);
        let steps = (t_end / dt).round() as usize;
        for k in 0..=steps {
            let t = k as f64 * dt;
            let d = f(t);
            tr.push(
                t,
                &[10.0 + d / 2.0, 10.0 - d / 2.0],
                &[0.0, 0.0],
                &[0.0, 0.0],
                None,
            );
        }
        tr
    }

    const TH: VerdictThresholds = VerdictThresholds {
        tolerance_mps: 0.05,
        window_s: 5.0,
    };

    #[test]
    fn a_run_without_samples_reports_nothing_measured() {
        // A worker that died before its first step: no spread, no zero made up for it.
        let m = sync_metrics(&Trajectory::new(3), TH, None, true);
        assert_eq!(m.initial_spread_mps, None);
        assert_eq!(m.final_spread_mps, None);
        assert_eq!(m.max_spread_mps, None);
        assert_eq!(m.window_max_spread_mps, None);
        assert_eq!(m.spread_l2, None);
        assert_eq!(m.time_to_tolerance_s, None);
        // Nothing measured, nothing judged.
        assert_eq!(m.verdict, Verdict::Inconclusive);
        assert_eq!(
            m.verdict_reason.as_deref(),
            Some("the run produced no sample")
        );
        // Even one that claims to be complete.
        let m = sync_metrics(&Trajectory::new(3), TH, None, false);
        assert_eq!(m.verdict, Verdict::Inconclusive);
    }

    #[test]
    fn exponential_decay_is_fitted_and_integrated_exactly() {
        // spread = 2 e^{−0.3 t}: rate −0.3, L2² = 4/(0.6) (1 − e^{−0.6·40}), time to 0.05 = ln(40)/0.3.
        let tr = traj_from(|t| 2.0 * (-0.3 * t).exp(), 40.0, 0.01);
        let m = sync_metrics(&tr, TH, None, false);
        assert_relative_eq!(m.decay_rate_per_s.unwrap(), -0.3, epsilon = 1e-9);
        assert_relative_eq!(
            m.spread_l2.unwrap(),
            (4.0 / 0.6 * (1.0 - (-24.0f64).exp())).sqrt(),
            max_relative = 1e-4
        );
        assert_relative_eq!(
            m.time_to_tolerance_s.unwrap(),
            40f64.ln() / 0.3,
            epsilon = 0.011
        );
        assert_eq!(m.verdict, Verdict::Synchronized);
    }

    #[test]
    fn growing_oscillation_is_not_synchronized() {
        let tr = traj_from(
            |t| 0.1 * (0.05 * t).exp() * (1.0 + 0.5 * (2.0 * t).sin()),
            60.0,
            0.05,
        );
        let m = sync_metrics(&tr, TH, None, false);
        assert_eq!(m.verdict, Verdict::NotSynchronized);
        assert!(m.decay_rate_per_s.unwrap() > 0.0);
        assert_eq!(m.time_to_tolerance_s, None);
    }

    #[test]
    fn slow_decay_is_inconclusive() {
        let tr = traj_from(|t| 5.0 * (-0.05 * t).exp(), 20.0, 0.05);
        let m = sync_metrics(&tr, TH, None, false);
        assert_eq!(m.verdict, Verdict::Inconclusive);
    }

    #[test]
    fn incomplete_runs_are_never_synchronized_and_inconclusive_unless_diverged() {
        let tr = traj_from(|_| 0.0, 10.0, 0.1);
        assert_eq!(
            sync_metrics(&tr, TH, None, false).verdict,
            Verdict::Synchronized
        );
        assert_eq!(
            sync_metrics(&tr, TH, None, true).verdict,
            Verdict::Inconclusive
        );
        // Cut off with a spread that had already blown up: that much is known.
        let blown = traj_from(|t| if t > 5.0 { f64::INFINITY } else { 1.0 }, 10.0, 0.1);
        assert_eq!(
            sync_metrics(&blown, TH, None, true).verdict,
            Verdict::NotSynchronized
        );
        // A run that produced no sample has no verdict either.
        let none = sync_metrics(&Trajectory::default(), TH, None, true);
        assert_eq!(none.verdict, Verdict::Inconclusive);
        assert_eq!(
            none.verdict_reason.as_deref(),
            Some("the run produced no sample")
        );
    }
}
