//! The loop around [`CoSim::step`]: it owns the horizon, the observers (safety counters,
//! SUMO-side measurements, the recorder that streams rows, benchmark timing) and the typed
//! stop reason, and reports the end of the run.

use std::io::Write;
use std::time::{Duration, Instant};

use pyo3::prelude::*;
use pyo3::types::PyTuple;
use syncroad_control::metrics::speed_range;
use syncroad_control::{StopReason, Trajectory};

use super::meter::Meter;
use super::step::{CoSim, StepTimes};
use super::CosimError;
use crate::protocol::{
    write_msg, write_ranges, write_rows, Event, Finish, PhaseTimes, Totals, WorkerMsg,
};

/// Longest time rows wait in the worker before they are sent.
const FLUSH_INTERVAL: Duration = Duration::from_millis(200);
/// Override events sent to the parent per run (all are counted).
const MAX_OVERRIDE_EVENTS: usize = 20;

fn pipe(e: std::io::Error) -> CosimError {
    CosimError::Pipe(e.to_string())
}

/// Counts collisions, teleports and overridden commands after each step, sending the first
/// events to the parent.
struct SafetyWatch {
    totals: Totals,
    override_events: usize,
}

impl SafetyWatch {
    fn after_step(
        &mut self,
        sim: &CoSim<'_, '_>,
        step: usize,
        out: &mut impl Write,
    ) -> Result<(), CosimError> {
        let ls = sim.ls;
        let colliding = ls.count(&ls.colliding, "simulation.getCollidingVehiclesNumber")?;
        if colliding > 0 {
            self.totals.collision_steps += 1;
            self.totals.colliding_vehicles += colliding;
            let e = Event::Collision {
                step,
                vehicles: colliding,
            };
            write_msg(out, &WorkerMsg::Event(e)).map_err(pipe)?;
        }
        let teleports = ls.count(&ls.teleports, "simulation.getStartingTeleportNumber")?;
        if teleports > 0 {
            self.totals.teleports += teleports;
            let e = Event::Teleport {
                step,
                count: teleports,
            };
            write_msg(out, &WorkerMsg::Event(e)).map_err(pipe)?;
        }
        Ok(())
    }

    fn check_overrides(
        &mut self,
        sim: &CoSim<'_, '_>,
        step: usize,
        out: &mut impl Write,
    ) -> Result<(), CosimError> {
        let req = sim.req;
        for (i, dep) in req.layout.vehicles.iter().enumerate() {
            if dep.driver.is_some() {
                continue;
            }
            let d = (sim.v[i] - sim.cmd[i]).abs();
            if d > req.override_tolerance_mps {
                self.totals.overrides += 1;
                self.totals.max_override_mps = self.totals.max_override_mps.max(d);
                if self.override_events < MAX_OVERRIDE_EVENTS {
                    self.override_events += 1;
                    let e = Event::Override {
                        step,
                        vehicle: dep.id.clone(),
                        commanded_mps: sim.cmd[i],
                        realised_mps: sim.v[i],
                    };
                    write_msg(out, &WorkerMsg::Event(e)).map_err(pipe)?;
                }
            }
        }
        Ok(())
    }
}

/// Records every `record_every`-th step and streams the rows in chunks, so a crash or Ctrl-C
/// loses at most one chunk or [`FLUSH_INTERVAL`] of the run.
/// The speed range of the judged vehicles is kept at every step and sent with the rows.
struct Recorder {
    rows: Trajectory,
    ranges: Vec<[f64; 3]>,
    /// The leader vehicle's index offset (1 with a leader vehicle: it is not judged).
    k0: usize,
    every: usize,
    chunk: usize,
    last_flush: Instant,
}

impl Recorder {
    /// Keeps the speed range of step time `t` (every step).
    fn observe(&mut self, t: f64, sim: &CoSim<'_, '_>) {
        let (lo, hi) = speed_range(&sim.v[self.k0.min(sim.v.len())..]);
        self.ranges.push([t, lo, hi]);
    }

    fn record(
        &mut self,
        t: f64,
        sim: &CoSim<'_, '_>,
        out: &mut impl Write,
    ) -> Result<(), CosimError> {
        self.rows.push_commanded(t, &sim.v, &sim.q, &sim.cmd);
        if self.rows.len() >= self.chunk || self.last_flush.elapsed() >= FLUSH_INTERVAL {
            self.flush(out)?;
        }
        Ok(())
    }

    fn flush(&mut self, out: &mut impl Write) -> Result<(), CosimError> {
        write_ranges(out, &mut self.ranges).map_err(pipe)?;
        write_rows(out, &mut self.rows).map_err(pipe)?;
        self.last_flush = Instant::now();
        Ok(())
    }
}

/// The benchmark's view: the first `untimed` steps are not timed; with `block > 0`, blocks of
/// `block` bare steps (only `simulationStep`) alternate with controlled ones and each kind's
/// wall time is attributed at the next step's start.
struct Timing {
    untimed: usize,
    block: usize,
    phases: PhaseTimes,
    last_kind: Option<(bool, Instant)>,
    loop_start: Instant,
}

impl Timing {
    /// Called at the start of each step; true when this step is a bare one.
    fn start_step(&mut self, step: usize) -> bool {
        if step == self.untimed {
            self.loop_start = Instant::now();
        }
        if self.block == 0 {
            return false;
        }
        let bare = (step / self.block).is_multiple_of(2);
        let now = Instant::now();
        if let Some((was_bare, t0)) = self.last_kind.take() {
            self.phases
                .add_interleaved(was_bare, (now - t0).as_secs_f64());
        }
        if step >= self.untimed {
            self.last_kind = Some((bare, now));
        }
        bare
    }

    fn stepped(&mut self, step: usize, t: &StepTimes) {
        if step >= self.untimed {
            t.add_to(&mut self.phases);
        }
    }

    fn finish(mut self) -> (f64, PhaseTimes) {
        if let Some((was_bare, t0)) = self.last_kind.take() {
            self.phases
                .add_interleaved(was_bare, t0.elapsed().as_secs_f64());
        }
        (self.loop_start.elapsed().as_secs_f64(), self.phases)
    }
}

/// Runs the steps of the request to its horizon or to a stop, then reports the end.
pub(super) fn run_steps(
    mut sim: CoSim<'_, '_>,
    id_args: &[Bound<'_, PyTuple>],
    out: &mut impl Write,
) -> Result<(), CosimError> {
    let req = sim.req;
    let py = sim.py;
    let dt = req.step_s;
    let decel = req.layout.vtype.decel_mps2;
    let mut meter = match &req.measure {
        Some(m) if req.observe => {
            let mut meter = Meter::new(sim.ls, m)?;
            if m.warmup_steps == 0 {
                meter.after_step(py, 0, dt, id_args, &[], &[], decel)?;
            }
            Some(meter)
        }
        _ => None,
    };
    let mut safety = SafetyWatch {
        totals: Totals {
            direct_calls: sim.direct_calls(),
            ..Totals::default()
        },
        override_events: 0,
    };
    let mut recorder = Recorder {
        rows: Trajectory::new(sim.v.len()),
        ranges: Vec::new(),
        k0: usize::from(req.layout.leader_vehicle),
        every: req.record_every.max(1),
        chunk: req.chunk_records.max(1),
        last_flush: Instant::now(),
    };
    let mut timing = Timing {
        untimed: req.untimed_steps,
        block: req.interleave_block,
        phases: PhaseTimes::default(),
        last_kind: None,
        loop_start: Instant::now(),
    };
    if req.observe {
        recorder.observe(0.0, &sim);
        recorder.record(0.0, &sim, out)?;
    }
    let mut watch = req
        .watch_leaders
        .then(|| super::leaders::LeaderWatch::new(req));
    let mut stop = StopReason::Horizon;
    let mut steps_done = 0usize;
    for step in 0..req.steps {
        if timing.start_step(step) {
            sim.step_bare()?;
            steps_done = step + 1;
            continue;
        }
        let mut times = StepTimes::default();
        let stopped = sim.step(step, &mut times)?;
        if let Some(s) = stopped {
            if !matches!(s, StopReason::NonFiniteCommand { .. }) {
                steps_done = step + 1;
            }
            stop = s;
            break;
        }
        steps_done = step + 1;
        if let Some(w) = watch.as_mut() {
            if (step + 1).is_multiple_of(super::leaders::LEADER_CHECK_EVERY) {
                w.check(py, sim.ls)?;
            }
        }
        safety.after_step(&sim, step + 1, out)?;
        timing.stepped(step, &times);
        if !req.observe {
            continue;
        }
        if let Some(m) = meter.as_mut() {
            m.after_step(py, step + 1, dt, id_args, &sim.v_prev, &sim.v, decel)?;
        }
        if sim.controlled() {
            safety.check_overrides(&sim, step + 1, out)?;
        }
        let last = step + 1 == req.steps;
        recorder.observe((step + 1) as f64 * dt, &sim);
        if (step + 1) % recorder.every == 0 || last {
            recorder.record((step + 1) as f64 * dt, &sim, out)?;
        }
    }
    let (loop_wall_s, phases) = timing.finish();
    // Measurements cover whole runs; a run that lost a vehicle could not even ask SUMO for
    // the lost vehicle's time loss, so an early stop keeps its stop reason and no measurement.
    let measured = match meter {
        Some(m) if matches!(stop, StopReason::Horizon) => Some(m.finish(py, id_args)?),
        _ => None,
    };
    recorder.flush(out)?;
    let mut totals = safety.totals;
    totals.negative_commands_clamped = sim.negative_commands_clamped;
    totals.odometer_deviation_max_m = sim.odometer_deviation_max_m;
    totals.topology_changes = watch.map(|w| w.changes);
    let finish = Finish {
        stop,
        steps_done,
        totals,
        loop_wall_s,
        timed_steps: steps_done.saturating_sub(req.untimed_steps),
        phases,
        measured,
    };
    write_msg(out, &WorkerMsg::Finished(finish)).map_err(pipe)?;
    Ok(())
}
