//! One step of the co-simulation, apart from the loop that runs it: (the graph from SUMO, when
//! other traffic shares the road) → law → command → `simulationStep` → read back. [`CoSim`]
//! holds the state between steps; the runner (`super::runner`) owns the horizon, the
//! observers and the stop reason.
//!
//! # Timing (measured with libsumo 1.28.0, see `tests/sumo.rs::actuation_timing`)
//! A speed set with `setSpeed` (speed mode 32) before `simulationStep` is the speed `getSpeed`
//! reports right after that step, exactly. So the loop adds no latency of its own: the law's
//! `v^{n+1}` computed from `v^n` is realised at step n+1, and the driver delay α_i = m_i Δt of
//! eq. `chandler+` lives only in the law's delay buffer, as in the native simulator. With
//! `--step-method.ballistic` SUMO advances positions by `x^{n+1} = x^n + Δt (v^n + v^{n+1}) / 2`,
//! the native simulator's trapezoidal rule; SUMO's default (Euler) update would use
//! `x^{n+1} = x^n + Δt v^{n+1}`. Speed mode 32 turns every check off: SUMO realises any
//! non-negative command and lets vehicles collide (counted by the runner).

use std::time::Instant;

use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};
use syncroad_control::{SpeedController, StopReason};

use super::guests::Guests;
use super::libsumo::{sanitize_commands, set_item_f64, tail, Libsumo, Reader};
use super::topology::Topology;
use super::CosimError;
use crate::protocol::Request;
use crate::python::{py_error, PythonError};

/// Wall time of one step's parts \[s\].
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StepTimes {
    /// Law and commands.
    pub command_s: f64,
    /// `simulationStep`.
    pub step_s: f64,
    /// Reading the speeds (and odometers) back.
    pub read_s: f64,
}

/// The co-simulation between two steps.
pub(super) struct CoSim<'a, 'py> {
    pub py: Python<'py>,
    pub ls: &'a Libsumo<'py>,
    pub req: &'a Request,
    controller: Option<Box<dyn SpeedController>>,
    reader: Reader<'a, 'py>,
    ids: &'a [Bound<'py, PyString>],
    /// `(id, speed)` per vehicle, built once and refilled each step (see `set_item_f64`).
    speed_args: Vec<Bound<'py, PyTuple>>,
    /// The law drives every vehicle (the batch `setSpeed` applies).
    all_law: bool,
    /// Per vehicle: the law drives it (SUMO drives the others).
    law_driven: Vec<bool>,
    q0: Vec<f64>,
    dist: Vec<f64>,
    next: Vec<f64>,
    /// Speeds at the current step \[m/s\].
    pub v: Vec<f64>,
    /// Speeds at the previous step \[m/s\].
    pub v_prev: Vec<f64>,
    /// Unwrapped rear-bumper positions \[m\].
    pub q: Vec<f64>,
    /// The commands that produced `v` (NaN where SUMO drives).
    pub cmd: Vec<f64>,
    /// Negative commands sent as 0.
    pub negative_commands_clamped: usize,
    /// Largest odometer deviation from the integrated positions \[m\].
    pub odometer_deviation_max_m: f64,
    /// The law's graph as SUMO sees it, read before each step when other traffic shares the
    /// road.
    /// In a cell: the recorder also reads the road's order, at each recorded state.
    pub topology: Option<std::cell::RefCell<Topology<'py>>>,
    /// Time the law and the reads of each step too (the benchmark's profile); SUMO's own step
    /// is always timed.
    pub phase_times: bool,
    /// The inflows' vehicles a law drives from their entry to their exit, when some inflow
    /// has them.
    pub guests: Option<Guests<'a, 'py>>,
}

impl<'a, 'py> CoSim<'a, 'py> {
    /// Takes control of the law's vehicles and reads the state after insertion.
    pub fn new(
        py: Python<'py>,
        ls: &'a Libsumo<'py>,
        req: &'a Request,
        ids: &'a [Bound<'py, PyString>],
        controller: Option<Box<dyn SpeedController>>,
    ) -> Result<Self, CosimError> {
        let n = ids.len();
        // A SUMO driver on a road of several lanes keeps its lane too: a lane change would take
        // it out of the order along the road that positions, gaps and the law's graph assume.
        if req.layout.road.multi_lane {
            for (id, dep) in ids.iter().zip(&req.layout.vehicles) {
                if dep.driver.is_some() {
                    ls.call("vehicle_setLaneChangeMode", (id.clone(), 0))?;
                }
            }
        }
        if controller.is_some() {
            for (id, dep) in ids.iter().zip(&req.layout.vehicles) {
                if dep.driver.is_some() {
                    continue;
                }
                ls.call("vehicle_setSpeedMode", (id.clone(), req.speed_mode))?;
                ls.call("vehicle_setLaneChangeMode", (id.clone(), 0))?;
            }
        }
        let speed_args = ids
            .iter()
            .map(|id| {
                PyTuple::new(
                    py,
                    [id.as_any().clone(), 0.0f64.into_pyobject(py)?.into_any()],
                )
            })
            .collect::<PyResult<_>>()
            .map_err(|e| py_error(py, "argument tuples", e))?;
        let q0: Vec<f64> = req.layout.vehicles.iter().map(|v| v.q0_m).collect();
        let mut sim = Self {
            py,
            ls,
            req,
            reader: Reader::new(py, ls, req.read, ids)?,
            controller,
            ids,
            speed_args,
            all_law: req.layout.vehicles.iter().all(|v| v.driver.is_none()),
            law_driven: req
                .layout
                .vehicles
                .iter()
                .map(|v| v.driver.is_none())
                .collect(),
            q: q0.clone(),
            q0,
            dist: vec![0.0; n],
            next: vec![0.0; n],
            v: vec![0.0; n],
            v_prev: vec![0.0; n],
            cmd: vec![f64::NAN; n],
            negative_commands_clamped: 0,
            odometer_deviation_max_m: 0.0,
            topology: match req.sense_graph {
                true => Some(std::cell::RefCell::new(Topology::new(ls, req)?)),
                false => None,
            },
            phase_times: false,
            guests: Guests::new(req),
        };
        // Those inserted in the first step, which inserted the fixed set.
        if let Some(g) = sim.guests.as_mut() {
            g.after_step(ls)?;
        }
        if let Some(i) = sim.reader.speeds(&mut sim.v)? {
            return Err(sim.lost(i));
        }
        if let Some(i) = sim.reader.odometers(&mut sim.dist)? {
            return Err(sim.lost(i));
        }
        for i in 0..n {
            sim.q[i] = sim.q0[i] + sim.dist[i];
        }
        Ok(sim)
    }

    /// The batch calls into libsumo's C++ functions are in use.
    pub fn direct_calls(&self) -> bool {
        self.reader.direct.is_some()
    }

    /// The batch calls into libsumo's C++ functions, when the run reads through them.
    pub(super) fn direct(&self) -> Option<&crate::direct::Direct> {
        self.reader.direct.as_ref()
    }

    /// SUMO's counts after the last step: vehicles in a collision, teleports that started. One
    /// C++ call for both with the batch calls in use, else one Python call each.
    pub fn safety_counts(&self) -> Result<(usize, usize), CosimError> {
        let ls = self.ls;
        let Some(d) = &self.reader.direct else {
            return Ok((
                ls.count(&ls.colliding, "simulation.getCollidingVehiclesNumber")?,
                ls.count(&ls.teleports, "simulation.getStartingTeleportNumber")?,
            ));
        };
        d.safety_counts().map_err(|(k, m)| {
            let call = ["getCollidingVehiclesNumber", "getStartingTeleportNumber"][k];
            PythonError::Call {
                call: format!("libsumo::Simulation::{call}() (direct)"),
                traceback: format!("C++ exception: {m}"),
            }
            .into()
        })
    }

    /// Per vehicle: the law drives it (SUMO drives the others).
    pub fn law_driven(&self) -> &[bool] {
        &self.law_driven
    }

    /// What the safety filter under the law did, when it ran.
    pub fn filter_report(&self) -> Option<syncroad_control::speed_controller::FilterReport> {
        self.controller.as_ref().and_then(|c| c.filter_report())
    }

    /// A law drives some vehicles.
    pub fn controlled(&self) -> bool {
        self.controller.is_some()
    }

    fn lost(&self, i: usize) -> CosimError {
        CosimError::NotInserted {
            pending: 1,
            expected: self.ids.len(),
            ids: self.req.layout.vehicles[i].id.clone(),
            log: self.req.log_file.display().to_string(),
            log_tail: tail(&self.req.log_file, 20),
        }
    }

    /// Only `simulationStep` (the benchmark's bare steps: vehicles keep their last command).
    pub fn step_bare(&mut self) -> Result<(), CosimError> {
        Ok(self.ls.simulation_step()?)
    }

    /// Step n → n+1: the law turns `v^n` into `v^{n+1}` (non-finite commands stop the run
    /// before they reach SUMO), the commands go out, SUMO steps, the speeds are read back and
    /// the positions advance by SUMO's own update rule (the odometer replaces them every
    /// `odometer_every` steps). `Ok(Some(stop))` ends the run.
    pub fn step(
        &mut self,
        step: usize,
        times: &mut StepTimes,
    ) -> Result<Option<StopReason>, CosimError> {
        let req = self.req;
        let t_law = self.phase_times.then(Instant::now);
        if let Some(t) = self.topology.as_mut().map(std::cell::RefCell::get_mut) {
            t.sense(self.py, self.ls)?;
            if let Some(c) = self.controller.as_deref_mut() {
                c.sense(&t.neighbors);
            }
        }
        if let Some(c) = self.controller.as_deref_mut() {
            c.step(step as f64 * req.step_s, &self.v, &self.q, &mut self.next);
            if let Some(end) = c.ended() {
                return Ok(Some(end.at(step, step as f64 * req.step_s)));
            }
            match sanitize_commands(&mut self.next, &self.law_driven) {
                Ok(clamped) => self.negative_commands_clamped += clamped,
                Err(i) => {
                    return Ok(Some(StopReason::NonFiniteCommand {
                        vehicle: req.layout.vehicles[i].id.clone(),
                        step,
                        value: format!("{}", self.next[i]),
                    }))
                }
            }
            self.send_commands()?;
        }
        if let Some(g) = self.guests.as_mut() {
            let direct = self.reader.direct.as_ref();
            if let Some(stop) = g.command(self.ls, direct, step, step as f64 * req.step_s)? {
                return Ok(Some(stop));
            }
        }
        let t_step = Instant::now();
        self.ls.simulation_step()?;
        let t_stepped = Instant::now();
        if let Some(g) = self.guests.as_mut() {
            g.after_step(self.ls)?;
        }
        if let Some(t_law) = t_law {
            times.command_s = (t_step - t_law).as_secs_f64();
        }
        times.step_s = (t_stepped - t_step).as_secs_f64();
        self.v_prev.copy_from_slice(&self.v);
        if let Some(i) = self.reader.speeds(&mut self.v)? {
            return Ok(Some(self.vehicle_lost(i, step + 1)));
        }
        let dt = req.step_s;
        for i in 0..self.v.len() {
            self.q[i] += if req.ballistic {
                0.5 * dt * (self.v_prev[i] + self.v[i])
            } else {
                dt * self.v[i]
            };
        }
        let last = step + 1 == req.steps;
        if self.reader.subscribed || (step + 1).is_multiple_of(req.odometer_every.max(1)) || last {
            if let Some(i) = self.reader.odometers(&mut self.dist)? {
                return Ok(Some(self.vehicle_lost(i, step + 1)));
            }
            for i in 0..self.v.len() {
                let sumo_q = self.q0[i] + self.dist[i];
                self.odometer_deviation_max_m = self
                    .odometer_deviation_max_m
                    .max((sumo_q - self.q[i]).abs());
                self.q[i] = sumo_q;
            }
        }
        if self.phase_times {
            times.read_s = t_stepped.elapsed().as_secs_f64();
        }
        Ok(None)
    }

    fn vehicle_lost(&self, i: usize, step: usize) -> StopReason {
        StopReason::VehicleLost {
            vehicle: self.req.layout.vehicles[i].id.clone(),
            step,
            ring: self.req.layout.road.ring,
        }
    }

    /// Sends `next` to SUMO: one batch into the C++ functions when the law drives every
    /// vehicle, else one `setSpeed` per law-driven vehicle.
    fn send_commands(&mut self) -> Result<(), CosimError> {
        let vehicles = &self.req.layout.vehicles;
        match self.reader.direct.as_ref().filter(|_| self.all_law) {
            Some(d) => {
                if let Err(e) = d.set_speeds(&self.next) {
                    return Err(PythonError::Call {
                        call: format!(
                            "libsumo::Vehicle::setSpeed({}, {}) (direct)",
                            self.ids[e.vehicle], self.next[e.vehicle]
                        ),
                        traceback: format!("C++ exception: {}", e.message),
                    }
                    .into());
                }
            }
            None => {
                for (((id, args), x), _) in self
                    .ids
                    .iter()
                    .zip(&self.speed_args)
                    .zip(&self.next)
                    .zip(vehicles)
                    .filter(|(_, dep)| dep.driver.is_none())
                {
                    set_item_f64(args, 1, *x)
                        .and_then(|()| self.ls.set_speed.call1(args))
                        .map_err(|e| {
                            py_error(self.py, format!("vehicle.setSpeed({id}, {x})"), e)
                        })?;
                }
            }
        }
        if self.all_law {
            self.cmd.copy_from_slice(&self.next);
        } else {
            for ((c, x), dep) in self.cmd.iter_mut().zip(&self.next).zip(vehicles) {
                *c = if dep.driver.is_none() { *x } else { f64::NAN };
            }
        }
        Ok(())
    }
}
