//! One run, whatever ran it: the backend's [`RunOutput`] and the [`Outcome`] derived from it.
//!
//! ```text
//! backend (native simulator | SUMO worker) ─► RunOutput ─► evaluate ─► Outcome ─► RunRecord
//! ```
//! Every command that runs a scenario (`run`, each `compare` run, each `map` point) goes through
//! [`evaluate`], so the same trajectory always gives the same metrics and verdict.

use crate::congestion::{congestion_metrics, CongestionError, CongestionMetrics};
use crate::facts::SumoFacts;
use crate::metrics::{sync_metrics, SyncMetrics, VerdictThresholds};
use crate::scenario::{Model, Scenario};
use crate::stop::StopReason;
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
}

/// How to judge a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalOptions {
    /// Verdict thresholds.
    pub thresholds: VerdictThresholds,
    /// Warm-up excluded from the congestion metrics \[s\].
    pub warmup_s: f64,
}

impl EvalOptions {
    /// The scenario's verdict thresholds and a warm-up of a quarter of the horizon.
    pub fn of(scenario: &Scenario) -> Self {
        Self {
            thresholds: scenario.verdict_thresholds(),
            warmup_s: 0.25 * scenario.horizon_s(),
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
}

/// Derives the metrics and the verdict of a run. A run that stopped early is never
/// "synchronized".
pub fn evaluate(scenario: &Scenario, run: &RunOutput, opts: EvalOptions) -> Outcome {
    let desired = match scenario.model() {
        Model::Cacc(c) => Some(c.desired_gap_m.as_slice()),
        Model::DelayedDriver(_) => None,
    };
    let sync = sync_metrics(
        &run.trajectory,
        opts.thresholds,
        desired,
        !run.stop.is_complete(),
    );
    Outcome {
        sync,
        congestion: congestion_metrics(&run.trajectory, opts.warmup_s, run.ring_length_m),
        theory: theory::report(scenario),
        warmup_s: opts.warmup_s,
    }
}
