//! What watches the loop: the observers of the SUMO loop under the one trait both loops use,
//! [`StepObserver`] (syncroad-control's; the native simulator's recorder and spread watch are
//! the others) — the safety counters, the recorder that streams rows, SUMO-side measurements.
//! (The law's graph from SUMO is read before a step, not after it: `super::topology`.) The
//! runner calls each in turn after every full step; the
//! benchmark's probe times each by its [`StepObserver::name`].

use std::io::Write;
use std::time::{Duration, Instant};

use pyo3::prelude::*;
use pyo3::types::PyTuple;
use syncroad_control::metrics::speed_range;
use syncroad_control::observer::StepObserver;

use super::meter::Meter;
use super::step::CoSim;
use super::CosimError;
use crate::protocol::{write_msg, Event, RangeChunk, RowChunk, Totals, WorkerMsg};

/// Longest time rows wait in the worker before they are sent.
const FLUSH_INTERVAL: Duration = Duration::from_millis(200);
/// Records between two looks at the clock for [`FLUSH_INTERVAL`].
const CLOCK_EVERY: usize = 16;
/// Override events sent to the parent per run (all are counted).
const MAX_OVERRIDE_EVENTS: usize = 20;

pub(super) fn pipe(e: std::io::Error) -> CosimError {
    CosimError::Pipe(e.to_string())
}

/// The loop as an observer sees it: the state after `steps_done` steps and the channel to the
/// parent.
pub(super) struct Observed<'o, 'a, 'py> {
    /// Steps done: the state is at time `steps_done Δt`.
    pub steps_done: usize,
    /// The co-simulation after those steps.
    pub sim: &'o CoSim<'a, 'py>,
    /// Messages and rows to the parent.
    pub out: &'o mut dyn Write,
}

impl Observed<'_, '_, '_> {
    /// Time of the state \[s\].
    pub fn time_s(&self) -> f64 {
        self.steps_done as f64 * self.sim.req.step_s
    }

    /// True after the horizon's last step.
    pub fn last(&self) -> bool {
        self.steps_done == self.sim.req.steps
    }
}

/// An observer of the SUMO loop: [`StepObserver`] over the loop's state, for any borrow of it.
/// `'d` is how long the observer itself lives.
pub(super) type SumoObserver<'d, 'a, 'py> =
    dyn for<'o> StepObserver<Observed<'o, 'a, 'py>, Error = CosimError> + 'd;

/// Counts collisions, teleports and overridden commands after each step, sending the first
/// events to the parent.
pub(super) struct SafetyWatch {
    pub totals: Totals,
    override_events: usize,
}

impl SafetyWatch {
    pub fn new(totals: Totals) -> Self {
        Self {
            totals,
            override_events: 0,
        }
    }

    fn check_overrides(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        let sim = at.sim;
        let req = sim.req;
        // The law's flags, not the layout's vehicles: this runs every step, and a flag per
        // vehicle is all it needs until a command was overridden.
        let cases = sim.law_driven().iter().zip(&sim.v).zip(&sim.cmd);
        for (i, ((&law, v), c)) in cases.enumerate() {
            if !law {
                continue;
            }
            let d = (v - c).abs();
            if d > req.override_tolerance_mps {
                let dep = &req.layout.vehicles[i];
                self.totals.overrides += 1;
                self.totals.max_override_mps = self.totals.max_override_mps.max(d);
                if self.override_events < MAX_OVERRIDE_EVENTS {
                    self.override_events += 1;
                    let e = Event::Override {
                        step: at.steps_done,
                        vehicle: dep.id.clone(),
                        commanded_mps: sim.cmd[i],
                        realised_mps: sim.v[i],
                    };
                    write_msg(&mut at.out, &WorkerMsg::Event(e)).map_err(pipe)?;
                }
            }
        }
        Ok(())
    }
}

impl<'o, 'a, 'py> StepObserver<Observed<'o, 'a, 'py>> for SafetyWatch {
    type Error = CosimError;

    fn name(&self) -> &'static str {
        "safety counters"
    }

    fn after_step(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        let step = at.steps_done;
        let (colliding, teleports) = at.sim.safety_counts()?;
        if colliding > 0 {
            self.totals.collision_steps += 1;
            self.totals.colliding_vehicles += colliding;
            let e = Event::Collision {
                step,
                vehicles: colliding,
            };
            write_msg(&mut at.out, &WorkerMsg::Event(e)).map_err(pipe)?;
        }
        if teleports > 0 {
            self.totals.teleports += teleports;
            let e = Event::Teleport {
                step,
                count: teleports,
            };
            write_msg(&mut at.out, &WorkerMsg::Event(e)).map_err(pipe)?;
        }
        if at.sim.controlled() {
            self.check_overrides(at)?;
        }
        Ok(())
    }
}

/// Records every `every`-th step and streams the rows in chunks, so a crash or Ctrl-C loses at
/// most one chunk or [`FLUSH_INTERVAL`] (looked at every [`CLOCK_EVERY`] records) of the run.
/// The speed range of the judged vehicles is kept at every step and sent with the rows.
pub(super) struct Recorder {
    rows: RowChunk,
    /// Each vehicle's gap to whoever is ahead on the road's lanes (NaN without other traffic).
    gaps: Vec<f64>,
    ranges: RangeChunk,
    /// The leader vehicle's index offset (1 with a leader vehicle: it is not judged).
    k0: usize,
    every: usize,
    chunk: usize,
    last_flush: Instant,
}

/// Whether the run steps the user's Python code in this worker: code that can end the process
/// at any step (`os._exit`, a crash in an extension, memory the kernel takes back with
/// SIGKILL), so that every record is sent, and the pipe flushed, before the next step calls it.
fn runs_user_code(req: &crate::protocol::Request) -> bool {
    matches!(
        &req.control,
        crate::protocol::Control::Law { law }
            if matches!(law.user, Some(syncroad_control::user_law::UserLaw::Python(_)))
    )
}

impl Recorder {
    pub fn new(sim: &CoSim<'_, '_>) -> Self {
        let req = sim.req;
        // One record a chunk under user code: a worker that dies at any step leaves every
        // whole sample before it with the parent.
        let chunk = if runs_user_code(req) {
            1
        } else {
            req.chunk_records.max(1)
        };
        Self {
            rows: RowChunk::new(sim.v.len(), chunk),
            gaps: vec![f64::NAN; sim.v.len()],
            ranges: RangeChunk::default(),
            k0: usize::from(req.layout.leader_vehicle),
            every: req.record_every.max(1),
            chunk,
            last_flush: Instant::now(),
        }
    }

    fn record(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        let sim = at.sim;
        let (lo, hi) = speed_range(&sim.v[self.k0.min(sim.v.len())..]);
        let t = at.time_s();
        self.ranges.push(t, lo, hi);
        if at.steps_done.is_multiple_of(self.every) || at.last() {
            // With other traffic on the road, each vehicle's gap to whoever is ahead of it;
            // without, NaN: the gaps between syncroad's vehicles follow from the positions.
            if let Some(topology) = &sim.topology {
                topology
                    .borrow_mut()
                    .gaps_ahead(sim.py, sim.ls, &mut self.gaps)
                    .map_err(CosimError::from)?;
            }
            self.rows.push(t, &sim.v, &sim.q, &sim.cmd, &self.gaps);
            // The clock is read every CLOCK_EVERY records only: a small ring records a step
            // in a few µs, where a clock read every step is a visible share of its cost.
            let n = self.rows.len();
            if n >= self.chunk
                || (n.is_multiple_of(CLOCK_EVERY) && self.last_flush.elapsed() >= FLUSH_INTERVAL)
            {
                self.flush(&mut at.out)?;
            }
        }
        Ok(())
    }

    /// Sends what is held, through to the pipe.
    pub fn flush(&mut self, out: &mut impl Write) -> Result<(), CosimError> {
        self.ranges.write(out).map_err(pipe)?;
        self.rows.write(out).map_err(pipe)?;
        out.flush().map_err(pipe)?;
        self.last_flush = Instant::now();
        Ok(())
    }
}

impl<'o, 'a, 'py> StepObserver<Observed<'o, 'a, 'py>> for Recorder {
    type Error = CosimError;

    fn name(&self) -> &'static str {
        "rows"
    }

    fn start(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        self.record(at)
    }

    fn after_step(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        self.record(at)
    }
}

/// SUMO-side measurements ([`Meter`]) as an observer: the per-vehicle argument tuples it calls
/// libsumo with, and the vehicles' braking limit.
pub(super) struct Measurements<'x, 'py> {
    pub meter: Meter<'py>,
    pub id_args: &'x [Bound<'py, PyTuple>],
}

impl<'o, 'a, 'py> StepObserver<Observed<'o, 'a, 'py>> for Measurements<'_, '_> {
    type Error = CosimError;

    fn name(&self) -> &'static str {
        "measurements"
    }

    fn start(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        if self.meter.warm_at_start() {
            let req = at.sim.req;
            let decel = req.layout.vtype.decel_mps2;
            let py = self.meter.py();
            let direct = at.sim.direct();
            self.meter
                .after_step(py, 0, req.step_s, self.id_args, direct, &[], &[], decel)?;
        }
        Ok(())
    }

    fn after_step(&mut self, at: &mut Observed<'_, '_, '_>) -> Result<(), CosimError> {
        let sim = at.sim;
        let req = sim.req;
        let decel = req.layout.vtype.decel_mps2;
        self.meter.after_step(
            self.meter.py(),
            at.steps_done,
            req.step_s,
            self.id_args,
            sim.direct(),
            &sim.v_prev,
            &sim.v,
            decel,
        )?;
        Ok(())
    }
}
