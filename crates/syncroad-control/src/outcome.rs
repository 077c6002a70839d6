//! One run, whatever ran it: the backend's [`RunOutput`] and the [`Outcome`] derived from it.
//!
//! ```text
//! backend (native simulator | SUMO worker) ─► RunOutput ─► evaluate ─► Outcome ─► RunRecord
//! ```
//! Every command that runs a scenario (`run`, each `compare` run, each `map` point) goes through
//! [`evaluate`], so the same trajectory always gives the same metrics and verdict.

use crate::collisions::Collisions;
use crate::congestion::{congestion_metrics, CongestionError, CongestionMetrics, STOP_SPEED_MPS};
use crate::metrics::{
    sync_metrics, sync_metrics_of, SpreadSeries, SyncMetrics, Verdict, VerdictThresholds,
};
use crate::scenario::{Model, Scenario};
use crate::stop::StopReason;
use crate::sumo_facts::SumoFacts;
use crate::theory::{self, TheoryReport};
use crate::trajectory::Trajectory;

/// What a backend returns: the samples of the controlled vehicles, why the run stopped, and
/// the facts only that backend knows.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// Samples of the controlled vehicles (gaps, leader speed), every row received.
    pub trajectory: Trajectory,
    /// Why the run stopped.
    pub stop: StopReason,
    /// The ring's circumference the backend drove on \[m\] (SUMO's measured length, or the
    /// scenario's), `None` on a straight road.
    pub ring_length_m: Option<f64>,
    /// Backend facts: `None` for the native simulator.
    pub sumo: Option<SumoFacts>,
    /// The spread at every step, whatever the recording stride (the metrics are computed from
    /// it); `None`: from the recorded samples.
    pub spread: Option<SpreadSeries>,
    /// Overlapping and reversing vehicles seen by the native simulator at every step; `None`
    /// for SUMO, whose own counters ([`SumoFacts`]) say it.
    pub collisions: Option<Collisions>,
    /// Who drove each vehicle on the native simulator, when not the scenario's law (SUMO runs
    /// report it in their facts); `None`: the law.
    pub drivers: Option<Vec<String>>,
    /// The safety layer under the law ([`crate::safety`]); `None` when no law drove.
    pub safety_layer: Option<crate::safety::SafetyLayer>,
}

impl RunOutput {
    /// The output of a native run of `scenario`: its samples, stop, spread at every step and
    /// collisions, `drivers` when not the scenario's law drove, and the safety layer its
    /// filter (if any) makes (no layer otherwise: the native simulator has no checks of its
    /// own).
    pub fn native(
        scenario: &Scenario,
        run: crate::native::NativeRun,
        drivers: Option<Vec<String>>,
    ) -> Self {
        Self {
            trajectory: run.trajectory,
            stop: run.stop,
            ring_length_m: scenario.ring_length_m(),
            sumo: None,
            spread: Some(run.spread),
            collisions: Some(run.collisions),
            drivers,
            safety_layer: Some(crate::safety::SafetyLayer::of(
                run.filter,
                crate::safety::SafetyMode::Off,
            )),
        }
    }
}

/// How to judge a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalOptions {
    /// Verdict thresholds.
    pub thresholds: VerdictThresholds,
    /// Warm-up excluded from the congestion metrics \[s\].
    pub warmup_s: f64,
    /// Compute the gap certificate of the scenario's linear model for the record
    /// (`exact::gaps`; a tenth of a second to seconds per scenario, so a sweep asks for it only
    /// when one of its columns is the certificate's).
    pub gap_certificate: bool,
}

impl EvalOptions {
    /// The scenario's verdict thresholds, a warm-up of a quarter of the horizon, and the gap
    /// certificate.
    pub fn of(scenario: &Scenario) -> Self {
        Self {
            thresholds: scenario.verdict_thresholds(),
            warmup_s: 0.25 * scenario.horizon_s(),
            gap_certificate: true,
        }
    }
}

/// Everything derived from one run.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Synchronization metrics and the verdict.
    pub sync: SyncMetrics,
    /// Congestion metrics, or why they were skipped.
    pub congestion: Result<CongestionMetrics, CongestionError>,
    /// The paper's conditions for the scenario.
    pub theory: TheoryReport,
    /// The warm-up used \[s\].
    pub warmup_s: f64,
    /// Whether the record is to carry the gap certificate ([`EvalOptions::gap_certificate`]).
    pub gap_certificate: bool,
}

/// Derives the metrics and the verdict of a run. A run that stopped early is never
/// "synchronized", and neither is a SUMO run whose speeds were not the law's (see
/// [`sumo_overruled`]), a native run whose vehicles overlapped or reversed
/// ([`Collisions::overruled`]) or a ring that came to a standstill ([`standstill`]).
pub fn evaluate(scenario: &Scenario, run: &RunOutput, opts: EvalOptions) -> Outcome {
    let incomplete = !run.stop.is_complete();
    let sync = if scenario.vehicles() == 0 {
        no_fixed_set(opts.thresholds, incomplete)
    } else {
        judged(scenario, run, opts.thresholds, incomplete)
    };
    Outcome {
        sync,
        congestion: congestion_metrics(&run.trajectory, opts.warmup_s, run.ring_length_m),
        theory: theory::report(scenario),
        warmup_s: opts.warmup_s,
        gap_certificate: opts.gap_certificate,
    }
}

/// The synchronization metrics of the scenario's vehicles, with the verdict overruled where
/// SUMO or the native checks say the run was not the law's.
fn judged(
    scenario: &Scenario,
    run: &RunOutput,
    thresholds: VerdictThresholds,
    incomplete: bool,
) -> SyncMetrics {
    let desired = match scenario.model() {
        Model::Cacc(c) => Some(c.desired_gap_m.as_slice()),
        Model::DelayedDriver(_) | Model::Linear(_) => None,
    };
    let mut sync = match &run.spread {
        Some(spread) => sync_metrics_of(spread, &run.trajectory, thresholds, desired, incomplete),
        None => sync_metrics(&run.trajectory, thresholds, desired, incomplete),
    };
    if let Some(facts) = &run.sumo {
        for (at_best, reason) in sumo_overruled(facts, thresholds.tolerance_mps) {
            sync.overrule(at_best, reason);
        }
    }
    if let Some(c) = &run.collisions {
        for (at_best, reason) in c.overruled() {
            sync.overrule(at_best, reason);
        }
    }
    if let Some(reason) = standstill(&run.trajectory, &sync) {
        sync.overrule(Verdict::NotSynchronized, reason);
    }
    if let Some(reason) = stopped_early(&run.stop) {
        sync.overrule(reason.0, reason.1);
    }
    sync
}

/// What a run that stopped before its horizon may still be called, and why: a stop that is a
/// finding ([`StopReason::is_finding`]) makes it "not synchronized"; a run cut off by anything
/// else is at best "inconclusive", whatever its spread did before the cut.
fn stopped_early(stop: &StopReason) -> Option<(Verdict, String)> {
    let finding = stop.is_finding()?;
    let what = match stop {
        StopReason::Diverged { time_s, .. } => format!("its speeds diverged at t = {time_s} s"),
        StopReason::NonFiniteCommand { step, .. } => {
            format!("the law commanded a non-finite speed at step {step}")
        }
        StopReason::VehicleLost { vehicle, step, .. } => {
            format!("vehicle {vehicle} left the road at step {step}")
        }
        StopReason::Interrupted { time_s, .. } => {
            format!("the run was interrupted at t = {time_s:.3} s, before its horizon")
        }
        StopReason::ControllerFailed { time_s, .. } => format!(
            "the controller failed at t = {time_s:.3} s: the run was cut off before its horizon"
        ),
        StopReason::StoppedByController { time_s, .. } => {
            format!("the controller ended the run at t = {time_s:.3} s, before its horizon")
        }
        StopReason::Failed { .. } => "the run failed before its horizon".to_string(),
        StopReason::Horizon => return None,
    };
    Some(if finding {
        (Verdict::NotSynchronized, what)
    } else {
        (
            Verdict::Inconclusive,
            format!("{what}; what its spread would have done is not known"),
        )
    })
}

/// The verdict of a run without a fixed set of vehicles (`"vehicles": 0`: only an inflow's
/// vehicles, which come and go): no spread to measure, so no verdict but "inconclusive",
/// saying why.
fn no_fixed_set(thresholds: VerdictThresholds, incomplete: bool) -> SyncMetrics {
    SyncMetrics {
        against_leader: false,
        initial_spread_mps: None,
        final_spread_mps: None,
        window_max_spread_mps: None,
        max_spread_mps: None,
        spread_l2: None,
        time_to_tolerance_s: None,
        decay_rate_per_s: None,
        final_gap_error_m: None,
        verdict: Verdict::Inconclusive,
        verdict_reason: Some(NO_FIXED_SET.to_string()),
        thresholds,
        incomplete,
    }
}

/// Why a run without a fixed set of vehicles has no verdict.
pub const NO_FIXED_SET: &str = "the scenario has no vehicles of its own (\"vehicles\": 0): the vehicles of its inflows enter and leave, so there is no fixed set whose speeds could synchronize; its results are every vehicle's (all_vehicles: throughput, travel time, the speed field) and those of the inflows' vehicles a law drove (guests)";

/// Why a "synchronized" run without a leader is a jam: every vehicle stands (|v| below
/// [`STOP_SPEED_MPS`], the congestion metrics' stop speed, whatever the verdict's tolerance)
/// at the last sample. Equal speeds of 0 m/s are a standstill, not the
/// synchronized motion the verdict reports (a FollowerStopper with U = 0 stops every vehicle).
/// Behind a leader that stops, standing still is what following means, and stays.
pub fn standstill(traj: &Trajectory, sync: &SyncMetrics) -> Option<String> {
    if sync.verdict != Verdict::Synchronized || sync.against_leader || traj.is_empty() {
        return None;
    }
    let fastest = traj
        .speeds(traj.len() - 1)
        .iter()
        .fold(0.0, |m: f64, v| m.max(v.abs()));
    (fastest < STOP_SPEED_MPS).then(|| {
        format!(
            "every vehicle stands still at the end (fastest {fastest:.3} m/s, below the stop speed {STOP_SPEED_MPS} m/s): equal speeds of 0 m/s are a jam, not synchronized motion"
        )
    })
}

/// What SUMO did instead of the law, with the best verdict it leaves. A small spread means
/// nothing when SUMO, not the law, set the speeds:
/// * collisions and teleports: vehicles stopped or jumped → at best "not synchronized";
/// * commands SUMO did not realise by more than the verdict's tolerance (`tolerance_mps`), or
///   negative commands sent as 0 → at best "inconclusive";
/// * a run whose counters never arrived → at best "inconclusive".
pub fn sumo_overruled(facts: &SumoFacts, tolerance_mps: f64) -> Vec<(Verdict, String)> {
    let Some(s) = &facts.safety else {
        return vec![(
            Verdict::Inconclusive,
            "SUMO's safety counters are missing (the worker never reported its end)".into(),
        )];
    };
    let mut out = Vec::new();
    if s.collision_steps > 0 || s.teleports > 0 {
        out.push((
            Verdict::NotSynchronized,
            format!(
                "SUMO reported {} collision steps and {} teleports: the speeds are SUMO's, not the law's",
                s.collision_steps, s.teleports
            ),
        ));
    }
    if s.overridden_commands > 0 && facts.max_override_mps > tolerance_mps {
        out.push((
            Verdict::Inconclusive,
            format!(
                "SUMO overrode {} law commands, by up to {:.3e} m/s (more than the {tolerance_mps} m/s tolerance)",
                s.overridden_commands, facts.max_override_mps
            ),
        ));
    }
    if s.graph_changed() {
        let c = s.topology_changes.unwrap_or_default();
        // The law followed SUMO's graph, so the speeds are the law's and the verdict stands;
        // what no longer applies is the theory of the scenario's graph.
        out.push((
            Verdict::Synchronized,
            format!(
                "the vehicle ahead of a controlled vehicle changed {c} time{} in SUMO (other traffic changed lanes into or out of the controlled lane, or merged into it) and the law took its graph from SUMO each step; the Theorem-1 certificate and the exact analysis hold for the scenario's fixed graph only",
                if c == 1 { "" } else { "s" }
            ),
        ));
    }
    if s.negative_commands_clamped > 0 {
        out.push((
            Verdict::Inconclusive,
            format!(
                "{} negative law commands were sent to SUMO as 0 m/s",
                s.negative_commands_clamped
            ),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::VerdictThresholds;
    use crate::sumo_facts::Safety;
    use crate::trajectory::Trajectory;

    fn flat() -> SyncMetrics {
        let mut tr = Trajectory::new(2);
        for k in 0..=100 {
            tr.push(k as f64 * 0.1, &[5.0, 5.0], &[0.0, 0.0], &[0.0, 0.0], None);
        }
        let th = VerdictThresholds {
            tolerance_mps: 0.05,
            window_s: 1.0,
        };
        sync_metrics(&tr, th, None, false)
    }

    fn facts(safety: Safety, max_override_mps: f64) -> SumoFacts {
        SumoFacts {
            safety: Some(safety),
            max_override_mps,
            ..SumoFacts::default()
        }
    }

    fn judged(f: &SumoFacts) -> SyncMetrics {
        let mut m = flat();
        for (v, r) in sumo_overruled(f, 0.05) {
            m.overrule(v, r);
        }
        m
    }

    fn at_speed(v: f64, leader: Option<f64>) -> (Trajectory, SyncMetrics) {
        at_speed_within(v, leader, 0.05)
    }

    fn at_speed_within(
        v: f64,
        leader: Option<f64>,
        tolerance_mps: f64,
    ) -> (Trajectory, SyncMetrics) {
        let mut tr = Trajectory::new(2);
        for k in 0..=100 {
            tr.push(k as f64 * 0.1, &[v, v], &[0.0, 0.0], &[5.0, 5.0], leader);
        }
        let th = VerdictThresholds {
            tolerance_mps,
            window_s: 1.0,
        };
        let m = sync_metrics(&tr, th, None, false);
        (tr, m)
    }

    #[test]
    fn a_ring_at_standstill_is_a_jam_but_a_stop_behind_a_stopped_leader_is_not() {
        let (tr, m) = at_speed(0.0, None);
        assert_eq!(m.verdict, Verdict::Synchronized);
        let why = standstill(&tr, &m).unwrap();
        assert!(
            why.starts_with("every vehicle stands still at the end"),
            "{why}"
        );
        // Standing is below the congestion metrics' stop speed (0.1 m/s), whatever the
        // verdict's tolerance: a ring cruising at 7.77 m/s with a tolerance of 10 m/s moves.
        let stands = |v: f64, tol: f64| {
            let (tr, m) = at_speed_within(v, None, tol);
            standstill(&tr, &m).is_some()
        };
        assert!(stands(0.09, 0.05));
        assert!(!stands(0.11, 0.05));
        assert!(!stands(7.77, 10.0));
        assert!(stands(0.09, 10.0));
        let (tr, m) = at_speed(0.0, Some(0.0));
        assert!(m.against_leader);
        assert!(standstill(&tr, &m).is_none());
    }

    #[test]
    fn a_clean_sumo_run_keeps_the_spread_verdict() {
        let m = judged(&facts(Safety::default(), 0.0));
        assert_eq!(m.verdict, Verdict::Synchronized);
        assert_eq!(m.verdict_reason, None);
        // Overrides within the tolerance do not matter.
        let small = Safety {
            overridden_commands: 3,
            ..Safety::default()
        };
        assert_eq!(judged(&facts(small, 0.01)).verdict, Verdict::Synchronized);
    }

    #[test]
    fn collisions_and_teleports_are_never_synchronized() {
        let crash = Safety {
            collision_steps: 22,
            overridden_commands: 106,
            ..Safety::default()
        };
        let m = judged(&facts(crash, 6.9e7));
        assert_eq!(m.verdict, Verdict::NotSynchronized);
        let why = m.verdict_reason.unwrap();
        assert!(why.contains("22 collision steps and 0 teleports"), "{why}");
        assert!(why.contains("overrode 106 law commands"), "{why}");
        let tele = Safety {
            teleports: 1,
            ..Safety::default()
        };
        assert_eq!(judged(&facts(tele, 0.0)).verdict, Verdict::NotSynchronized);
    }

    #[test]
    fn overrides_beyond_the_tolerance_and_missing_counters_are_inconclusive() {
        let over = Safety {
            overridden_commands: 1,
            ..Safety::default()
        };
        assert_eq!(judged(&facts(over, 0.2)).verdict, Verdict::Inconclusive);
        let neg = Safety {
            negative_commands_clamped: 4,
            ..Safety::default()
        };
        assert_eq!(judged(&facts(neg, 0.0)).verdict, Verdict::Inconclusive);
        let none = SumoFacts::default();
        assert_eq!(judged(&none).verdict, Verdict::Inconclusive);
    }

    #[test]
    fn a_graph_that_changed_in_sumo_keeps_the_verdict_and_says_the_theory_is_for_a_fixed_graph() {
        let watched = |c| Safety {
            topology_changes: Some(c),
            ..Safety::default()
        };
        assert_eq!(
            judged(&facts(watched(0), 0.0)).verdict,
            Verdict::Synchronized
        );
        let m = judged(&facts(watched(7), 0.0));
        assert_eq!(m.verdict, Verdict::Synchronized);
        let why = m.verdict_reason.unwrap();
        assert!(why.contains("changed 7 times in SUMO"), "{why}");
        assert!(why.contains("took its graph from SUMO"), "{why}");
        assert!(
            why.contains("hold for the scenario's fixed graph only"),
            "{why}"
        );
        // A verdict already lowered stays lowered.
        let mut both = watched(7);
        both.negative_commands_clamped = 1;
        assert_eq!(judged(&facts(both, 0.0)).verdict, Verdict::Inconclusive);
    }
}
