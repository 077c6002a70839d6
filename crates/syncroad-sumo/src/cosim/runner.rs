//! The loop around [`CoSim::step`]: it owns the horizon, the observers (see
//! [`super::observer`]) and the typed stop reason, and reports the end of the run. With the
//! benchmark's probe it also runs the probe's timer.

use std::io::Write;
use std::time::Instant;

use pyo3::prelude::*;
use pyo3::types::PyTuple;
use syncroad_control::StopReason;

use super::meter::Meter;
use super::observer::{Measurements, Observed, Recorder, SafetyWatch, SumoObserver};
use super::step::{CoSim, StepTimes};
use super::timing::ProbeTimer;
use super::CosimError;
use crate::probe::Probe;
use crate::protocol::{Finish, Totals};

/// Runs the steps of the request to its horizon or to a stop; returns the end of the run,
/// which the caller reports once SUMO is closed (its log is then complete on disk, and the
/// parent counts SUMO's warnings in it).
pub(super) fn run_steps(
    mut sim: CoSim<'_, '_>,
    id_args: &[Bound<'_, PyTuple>],
    probe: Option<Probe>,
    mut out: &mut impl Write,
) -> Result<Finish, CosimError> {
    let req = sim.req;
    let py = sim.py;
    let mut safety = SafetyWatch::new(Totals {
        direct_calls: sim.direct_calls(),
        ..Totals::default()
    });
    let mut meter = match &req.measure {
        Some(m) => Some(Measurements {
            meter: Meter::new(sim.ls, m)?,
            id_args,
        }),
        None => None,
    };
    let mut recorder = Recorder::new(&sim);
    let mut timer = probe.map(ProbeTimer::new);
    // The profile times the law and the reads too; the other benchmark runs keep an ordinary
    // run's clocks (around SUMO's step) so that the timers add nothing to what they measure.
    sim.phase_times = timer.as_ref().is_some_and(ProbeTimer::profiles_observers);
    let (stop, steps_done, step_s) = {
        let mut observers: Vec<&mut SumoObserver<'_, '_, '_>> = Vec::with_capacity(3);
        observers.push(&mut safety);
        if let Some(m) = meter.as_mut() {
            observers.push(m);
        }
        observers.push(&mut recorder);
        step_loop(&mut sim, &mut observers, timer.as_mut(), &mut out)?
    };
    // Measurements cover whole runs; a run that lost a vehicle could not even ask SUMO for
    // the lost vehicle's time loss, so an early stop keeps its stop reason and no measurement.
    let measured = match meter {
        Some(m) if matches!(stop, StopReason::Horizon) => Some(m.meter.finish(py, id_args)?),
        _ => None,
    };
    recorder.flush(out)?;
    let mut totals = safety.totals;
    totals.negative_commands_clamped = sim.negative_commands_clamped;
    totals.odometer_deviation_max_m = sim.odometer_deviation_max_m;
    totals.topology_changes = sim.topology.as_ref().map(|t| t.borrow().changes);
    totals.filter = sim.filter_report();
    totals.guests = sim.guests.as_ref().map(|g| Box::new(g.report()));
    totals.chosen_later = sim
        .req
        .adopt
        .as_ref()
        .and(sim.topology.as_ref())
        .map(|t| t.borrow().chosen_later);
    let finish = Finish {
        stop,
        steps_done,
        totals,
        probe: timer.map(|t| t.finish(steps_done)),
        measured,
        step_s,
    };
    Ok(finish)
}

/// The steps: each full step is followed by every observer in turn; the probe's bare steps
/// only step SUMO. Returns the stop reason, the steps done and the time inside SUMO's full
/// steps.
fn step_loop<'a, 'py>(
    sim: &mut CoSim<'a, 'py>,
    observers: &mut [&mut SumoObserver<'_, 'a, 'py>],
    mut timer: Option<&mut ProbeTimer>,
    out: &mut dyn Write,
) -> Result<(StopReason, usize, f64), CosimError> {
    let steps = sim.req.steps;
    let mut step_s = 0.0;
    let mut at = Observed {
        steps_done: 0,
        sim: &*sim,
        out: &mut *out,
    };
    for o in observers.iter_mut() {
        o.start(&mut at)?;
    }
    let profile = timer.as_ref().is_some_and(|t| t.profiles_observers());
    for step in 0..steps {
        if let Some(t) = timer.as_deref_mut() {
            if !t.start_step(step) {
                sim.step_bare()?;
                continue;
            }
        }
        let mut times = StepTimes::default();
        let stopped = sim.step(step, &mut times)?;
        step_s += times.step_s;
        if let Some(s) = stopped {
            // A command that never reached SUMO leaves the step undone.
            let done = match s {
                StopReason::NonFiniteCommand { .. }
                | StopReason::ControllerFailed { .. }
                | StopReason::StoppedByController { .. } => step,
                _ => step + 1,
            };
            return Ok((s, done, step_s));
        }
        let mut at = Observed {
            steps_done: step + 1,
            sim: &*sim,
            out: &mut *out,
        };
        for o in observers.iter_mut() {
            let t0 = profile.then(Instant::now);
            o.after_step(&mut at)?;
            if let (Some(t), Some(t0)) = (timer.as_deref_mut(), t0) {
                t.observed(step, o.name(), t0);
            }
        }
        if let Some(t) = timer.as_deref_mut() {
            t.stepped(step, &times);
        }
    }
    Ok((StopReason::Horizon, steps, step_s))
}
