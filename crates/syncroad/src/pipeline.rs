//! One run, whatever runs it:
//!
//! ```text
//! validated Scenario ─► backend: native simulator | SUMO worker ─► RunOutput
//!                   ─► evaluate ─► Outcome ─► RunRecord ─► metrics.json + CSV + plots
//! ```
//! `run`, `simulate`, every `compare` run, every `sweep` and `map` point and `regress` go through
//! [`native`] or [`sumo`] and then [`Finished::new`]; nothing else computes metrics.

use std::path::Path;

use syncroad_control::controller::ControllerError;
use syncroad_control::{
    evaluate, simulate_with, EvalOptions, LawSpec, NativeOptions, Outcome, RunOutput, RunRecord,
    Scenario,
};
use syncroad_sumo::{
    ContainedHost, PrepareError, Prepared, Road, RunOptions, SumoRun, SupervisorError,
    WorkerCommand, WorkerPool,
};

use crate::output;
use crate::plots::RunPlots;

/// Runs a scenario on the native simulator, recording every `record_every`-th step. An error
/// is a law that could not be built (the user's controller): nothing ran.
pub fn native(sc: &Scenario, record_every: usize) -> Result<RunOutput, ControllerError> {
    native_with(
        sc,
        NativeOptions {
            record_every,
            ..NativeOptions::default()
        },
    )
}

/// [`native`] with every option: a stop flag (signals) and a progress callback.
pub fn native_with(sc: &Scenario, opts: NativeOptions<'_>) -> Result<RunOutput, ControllerError> {
    native_run(sc, &LawSpec::of(sc), None, opts)
}

/// [`native_with`] for a resolved law (a damper or stochastic humans on the ring), with the
/// vehicles' driver labels in the record.
pub fn native_law(
    sc: &Scenario,
    law: &LawSpec,
    drivers: Vec<String>,
    opts: NativeOptions<'_>,
) -> Result<RunOutput, ControllerError> {
    native_run(sc, law, Some(drivers), opts)
}

fn native_run(
    sc: &Scenario,
    law: &LawSpec,
    drivers: Option<Vec<String>>,
    opts: NativeOptions<'_>,
) -> Result<RunOutput, ControllerError> {
    // The user's Python controller steps in a supervised process of its own, never in this
    // one (a caller that gives its own host keeps it).
    let contained = ContainedHost::new(WorkerCommand::for_process(), opts.timeout);
    let mut opts = opts;
    opts.host = opts.host.or(Some(&contained));
    Ok(RunOutput::native(
        sc,
        simulate_with(sc, law, opts)?,
        drivers,
    ))
}

/// A SUMO run's output, and whether the user interrupted it.
pub struct SumoOutput {
    /// The output.
    pub output: RunOutput,
    /// Ctrl-C (or a signal) stopped it.
    pub interrupted: bool,
    /// Seconds inside SUMO's step, when the worker reported its end (a timing: not recorded).
    pub step_s: Option<f64>,
    /// Why the worker refused the run before SUMO started, if it did: its law could not be
    /// built (the user's controller). Bad input, not a failed run.
    pub refused: Option<String>,
}

/// Runs a scenario in one supervised SUMO worker on a road read once. Errors are the checks
/// made before SUMO starts; a run that fails part-way returns its rows with a failed stop.
pub fn sumo(sc: &Scenario, road: &Road, opts: &RunOptions) -> Result<SumoOutput, PrepareError> {
    Ok(sumo_output(sc, Prepared::new(sc, road, opts)?.run()))
}

/// [`sumo`] on a long-lived worker of `pool` (a sweep's many runs share a few processes).
pub fn sumo_pooled(
    sc: &Scenario,
    road: &Road,
    opts: &RunOptions,
    pool: &WorkerPool,
) -> Result<SumoOutput, PrepareError> {
    Ok(sumo_output(sc, Prepared::new(sc, road, opts)?.run_in(pool)))
}

fn sumo_output(sc: &Scenario, run: SumoRun) -> SumoOutput {
    SumoOutput {
        output: run.output(sc),
        interrupted: matches!(run.failure(), Some(SupervisorError::Interrupted { .. })),
        step_s: run.step_s(),
        refused: match run.failure() {
            Some(SupervisorError::Refused(why)) => Some(why.clone()),
            _ => None,
        },
    }
}

/// A run with everything derived from it.
pub struct Finished {
    /// What the backend returned.
    pub output: RunOutput,
    /// Metrics, congestion, theory.
    pub outcome: Outcome,
    /// The `metrics.json` record.
    pub record: RunRecord,
}

impl Finished {
    /// Evaluates the run named `name`.
    pub fn new(sc: &Scenario, name: &str, output: RunOutput, eval: EvalOptions) -> Self {
        let outcome = evaluate(sc, &output, eval);
        let record = RunRecord::new(sc, name, &output, &outcome);
        Self {
            output,
            outcome,
            record,
        }
    }

    /// Writes `trajectories.csv`, the plots under `title` when given and the run has at least
    /// two samples, and `metrics.json` last, into `dir`. Returns the plot files. When a file
    /// cannot be written the record is not lost: it is kept in a new file
    /// ([`output::rescue_record`]) that the error names.
    pub fn write(&self, dir: &Path, plots: Option<String>) -> anyhow::Result<usize> {
        self.write_files(dir, plots).map_err(|e| {
            let kept = output::rescue_record(dir, &self.record);
            e.context(format!(
                "the run's files could not all be written to {} (the run's record is kept {kept})",
                dir.display()
            ))
        })
    }

    fn write_files(&self, dir: &Path, plots: Option<String>) -> anyhow::Result<usize> {
        output::write_run_rows(dir, &self.output.trajectory)?;
        // The user's whole text behind the stop, where the record and the messages show part.
        if let Some(full) = self.output.stop.full_text() {
            output::write_text(
                &dir.join(syncroad_control::user_text::FULL_TEXT_FILE),
                &(syncroad_control::user_text::escaped(full) + "\n"),
            )?;
        }
        if self.output.sumo.is_none() {
            // Where a native run's road lies, for its animation (a SUMO run's is in sumo/).
            let road = crate::animate::NativeRoad {
                ring_length_m: self.output.ring_length_m,
            };
            output::write_json(
                &dir.join(crate::animate::NATIVE_ROAD_FILE),
                &serde_json::to_value(road)?,
            )?;
        }
        let n = match plots {
            // A run of an inflow's vehicles alone has no fixed set, so no samples of its own,
            // but every vehicle's speed field.
            Some(title) if self.output.trajectory.len() >= 2 || self.output.trajectory.n == 0 => {
                let mut files = RunPlots {
                    traj: &self.output.trajectory,
                    ring_length_m: self.output.ring_length_m,
                    title: title.clone(),
                }
                .write_all(dir)?;
                // With other traffic and SUMO's floating-car data: every vehicle on the road.
                let all = self
                    .output
                    .sumo
                    .as_ref()
                    .and_then(|s| s.all_vehicles.as_ref());
                if all.is_some() {
                    files.extend(crate::plots::field_time_space(
                        dir,
                        &dir.join(output::SUMO_WORK_DIR),
                        &title,
                    )?);
                }
                files.len()
            }
            _ => 0,
        };
        output::write_run_record(dir, &self.record)?;
        Ok(n)
    }
}
