//! The inflows' controlled vehicles (`sumo.inflows[k].controlled`): vehicles that enter the
//! network during the run and leave it at the end of their route, each driven by a law of the
//! registry from its first step to its last.
//!
//! Unlike the scenario's fixed set (numbered once, stepped together on the scenario's graph),
//! these come and go: the worker recognises them by their vehicle type when SUMO reports them
//! departed, builds the inflow's law for each one alone (a one-vehicle open road) and drops it
//! when SUMO reports the vehicle arrived. Each step, before SUMO's, every one of them is read
//! (its speed, whoever SUMO reports ahead of it on its lanes with the gap and that vehicle's
//! speed, the lane's speed limit), stepped by its law, and commanded with `setSpeed`; a command
//! above the speed limit is sent as the limit. With nobody within [`LOOKAHEAD_M`] ahead, the
//! law sees the free road: a leader that far ahead at the lane's speed limit (every law gets
//! finite inputs; the dampers then cruise at their desired speed, the delayed driver closes on
//! the limit). The law's graph is thus "each vehicle follows
//! whoever is ahead of it now", over the vehicles present.
//!
//! They drive under SUMO's checks (safe speed, right of way, red lights: speed mode 25)
//! unless the scenario turns the safety layer `off`; syncroad's own filter is the fixed set's.
//!
//! # Reference
//! SUMO documentation, TraCI "Vehicle Value Retrieval": `getLeader` measures "from the front +
//! minGap to the back of the leader", and "Simulation Value Retrieval":
//! `getDepartedIDList`, `getArrivedIDList`.

use std::collections::HashMap;

use pyo3::prelude::*;
use pyo3::types::PyString;
use syncroad_control::scenario::SafetyMode;
use syncroad_control::sensed::{Neighbors, Sensed};
use syncroad_control::sumo_facts::Guests as Report;
use syncroad_control::{LawHost as _, SpeedController, StopReason, UserLaw};

use crate::user_law::PythonHost;

use super::libsumo::Libsumo;
use super::CosimError;
use crate::direct::{CppIds, Direct, DirectError};
use crate::protocol::{GuestLaw, Request};
use crate::python::{py_error, PythonError};

/// How far ahead a vehicle looks for the one it follows \[m\] (SUMO looks further when its
/// braking distance is longer); with nobody that close, a leader this far ahead at the lane's
/// speed limit stands for the free road.
const LOOKAHEAD_M: f64 = 250.0;

/// One controlled vehicle on the road.
struct Guest<'py> {
    id: Bound<'py, PyString>,
    name: String,
    /// Its inflow's entry in [`Guests::laws`].
    law: usize,
    controller: Box<dyn SpeedController>,
    /// SUMO's time when it entered \[s\].
    entered_s: f64,
    /// The command sent before the last step (NaN before its first).
    last_command: f64,
}

/// The controlled vehicles of the inflows between two steps.
pub(super) struct Guests<'a, 'py> {
    laws: &'a [GuestLaw],
    /// Their vehicle types, for the departures.
    types: HashMap<String, usize>,
    on_road: Vec<Guest<'py>>,
    speed_mode: i32,
    drive: Drive,
    travel_time_sum_s: f64,
    /// The ids of [`Guests::on_road`] as C++ strings for the direct calls, made again after a
    /// step that changed who is on the road.
    cpp_ids: Option<CppIds>,
    /// Per vehicle on the road: speed, the leader's speed and gap (NaN: nobody ahead), the
    /// speed limit, the command (reused from step to step).
    speeds: Vec<f64>,
    leader_speeds: Vec<f64>,
    leader_gaps: Vec<f64>,
    limits: Vec<f64>,
    commands: Vec<f64>,
}

impl<'a, 'py> Guests<'a, 'py> {
    /// For the request's laws; `None` when no inflow has controlled vehicles.
    pub fn new(req: &'a Request) -> Option<Self> {
        if req.guests.is_empty() {
            return None;
        }
        Some(Self {
            laws: &req.guests,
            types: req
                .guests
                .iter()
                .enumerate()
                .map(|(i, g)| (crate::inflows::guest_type(g.inflow), i))
                .collect(),
            on_road: Vec::new(),
            speed_mode: match req.safety {
                SafetyMode::Off => SafetyMode::Off.speed_mode(),
                _ => SafetyMode::Sumo.speed_mode(),
            },
            drive: Drive {
                tolerance_mps: req.override_tolerance_mps,
                neighbors: Neighbors {
                    ring: false,
                    ahead: vec![Sensed::Nobody],
                    behind: vec![Sensed::Nobody],
                },
                report: Report {
                    laws: req
                        .guests
                        .iter()
                        .map(|g| format!("inflow{}: {}", g.inflow, described(&g.law)))
                        .collect(),
                    ..Report::default()
                },
                speed_sum: 0.0,
                speed_samples: 0,
            },
            travel_time_sum_s: 0.0,
            cpp_ids: None,
            speeds: Vec::new(),
            leader_speeds: Vec::new(),
            leader_gaps: Vec::new(),
            limits: Vec::new(),
            commands: Vec::new(),
        })
    }

    /// Before SUMO's step `step` at time `t_s`: reads every controlled vehicle, steps its law
    /// and sends its command. A non-finite command stops the run before it reaches SUMO, as
    /// the fixed set's do (`Ok(Some(stop))`; the rows so far are kept).
    ///
    /// With `direct` (libsumo's C++ functions, as the fixed set reads them) each kind of read
    /// and the commands go as one batch for all of them; else one Python call per vehicle and
    /// value. The same calls either way (reads have no effect on SUMO's state before its
    /// step), so the same run.
    pub fn command(
        &mut self,
        ls: &Libsumo<'py>,
        direct: Option<&Direct>,
        step: usize,
        t_s: f64,
    ) -> Result<Option<StopReason>, CosimError> {
        match direct {
            Some(d) => self.command_direct(d, step, t_s),
            None => self.command_python(ls, step, t_s),
        }
    }

    /// [`Guests::command`] through libsumo's C++ functions.
    fn command_direct(
        &mut self,
        d: &Direct,
        step: usize,
        t_s: f64,
    ) -> Result<Option<StopReason>, CosimError> {
        let n = self.on_road.len();
        if self.cpp_ids.is_none() {
            let names: Vec<&str> = self.on_road.iter().map(|g| g.name.as_str()).collect();
            self.cpp_ids = Some(CppIds::new(&names).ok_or_else(|| PythonError::Call {
                call: "the inflows' vehicle ids as C++ strings".into(),
                traceback: "allocation failed".into(),
            })?);
        }
        let ids = self.cpp_ids.as_ref().expect("made above");
        for b in [
            &mut self.speeds,
            &mut self.leader_speeds,
            &mut self.leader_gaps,
            &mut self.limits,
            &mut self.commands,
        ] {
            b.resize(n, 0.0);
        }
        let on_road = &self.on_road;
        d.speeds_of(ids, &mut self.speeds)
            .map_err(|e| failed(on_road, "getSpeed", e))?;
        d.leaders_of(
            ids,
            LOOKAHEAD_M,
            &mut self.leader_speeds,
            &mut self.leader_gaps,
        )
        .map_err(|e| failed(on_road, "getLeader", e))?;
        d.allowed_speeds_of(ids, &mut self.limits)
            .map_err(|e| failed(on_road, "getAllowedSpeed", e))?;
        for (i, g) in self.on_road.iter_mut().enumerate() {
            let gap = self.leader_gaps[i];
            let leader = (!gap.is_nan()).then_some((self.leader_speeds[i], gap));
            let min_gap_m = self.laws[g.law].min_gap_m;
            match self.drive.step(
                g,
                min_gap_m,
                self.speeds[i],
                leader,
                self.limits[i],
                step,
                t_s,
            ) {
                Ok(cmd) => self.commands[i] = cmd,
                Err(stop) => return Ok(Some(stop)),
            }
        }
        d.set_speeds_of(ids, &self.commands)
            .map_err(|e| failed(&self.on_road, "setSpeed", e))?;
        Ok(None)
    }

    /// [`Guests::command`] through Python, one call per vehicle and value.
    fn command_python(
        &mut self,
        ls: &Libsumo<'py>,
        step: usize,
        t_s: f64,
    ) -> Result<Option<StopReason>, CosimError> {
        let py = ls.py;
        for g in &mut self.on_road {
            let v: f64 = float(ls.call("vehicle_getSpeed", (g.id.clone(),))?, "getSpeed")?;
            let leader = ls.call("vehicle_getLeader", (g.id.clone(), LOOKAHEAD_M))?;
            let ahead: Option<(String, f64)> = if leader.is_none() {
                None
            } else {
                leader
                    .extract()
                    .map_err(|e| py_error(py, format!("vehicle.getLeader({})", g.id), e))?
            };
            let limit: f64 = float(
                ls.call("vehicle_getAllowedSpeed", (g.id.clone(),))?,
                "getAllowedSpeed",
            )?;
            let leader = match ahead {
                Some((id, d)) if !id.is_empty() && d >= 0.0 => {
                    Some((float(ls.call("vehicle_getSpeed", (id,))?, "getSpeed")?, d))
                }
                _ => None,
            };
            let min_gap_m = self.laws[g.law].min_gap_m;
            let cmd = match self.drive.step(g, min_gap_m, v, leader, limit, step, t_s) {
                Ok(cmd) => cmd,
                Err(stop) => return Ok(Some(stop)),
            };
            ls.call("vehicle_setSpeed", (g.id.clone(), cmd))?;
        }
        Ok(None)
    }

    /// After a SUMO step: takes over the controlled vehicles SUMO inserted in it and lets go
    /// of those that left at the end of their route.
    pub fn after_step(&mut self, ls: &Libsumo<'py>) -> Result<(), CosimError> {
        let py = ls.py;
        let arrived: Vec<String> = ls
            .call("simulation_getArrivedIDList", ())?
            .extract()
            .map_err(|e| py_error(py, "simulation.getArrivedIDList", e))?;
        let departed: Vec<String> = ls
            .call("simulation_getDepartedIDList", ())?
            .extract()
            .map_err(|e| py_error(py, "simulation.getDepartedIDList", e))?;
        if arrived.is_empty() && departed.is_empty() {
            return Ok(());
        }
        let now: f64 = float(ls.call("simulation_getTime", ())?, "getTime")?;
        if !arrived.is_empty() {
            let gone: std::collections::HashSet<&str> =
                arrived.iter().map(String::as_str).collect();
            let report = &mut self.drive.report;
            let sum = &mut self.travel_time_sum_s;
            let before = self.on_road.len();
            self.on_road.retain(|g| {
                let left = gone.contains(g.name.as_str());
                if left {
                    report.left += 1;
                    *sum += now - g.entered_s;
                }
                !left
            });
            if self.on_road.len() != before {
                self.cpp_ids = None;
            }
        }
        for id in departed {
            let vtype: String = ls
                .call("vehicle_getTypeID", (id.as_str(),))?
                .extract()
                .map_err(|e| py_error(py, format!("vehicle.getTypeID({id})"), e))?;
            let Some(&law) = self.types.get(&vtype) else {
                continue;
            };
            let spec = &self.laws[law];
            // Built for this vehicle: a law that draws random numbers draws its own stream.
            let mut context = spec.context.clone();
            context.ids = vec![id.clone()];
            let controller = match &spec.law {
                UserLaw::Rust(named) => named.build_alone(&context),
                UserLaw::Python(p) => PythonHost.python(p, &context).map_err(|e| e.to_string()),
            }
            .map_err(|e| PythonError::Call {
                call: format!("building the law {} for vehicle {id}", described(&spec.law)),
                traceback: e,
            })?;
            let name = id;
            let id = PyString::new(py, &name);
            ls.call("vehicle_setSpeedMode", (id.clone(), self.speed_mode))?;
            self.on_road.push(Guest {
                id,
                name,
                law,
                controller,
                entered_s: now,
                last_command: f64::NAN,
            });
            self.cpp_ids = None;
            self.drive.report.entered += 1;
        }
        self.drive.report.present_max = self.drive.report.present_max.max(self.on_road.len());
        Ok(())
    }

    /// What the run's controlled vehicles did, for the record.
    pub fn report(&self) -> Report {
        let mut r = self.drive.report.clone();
        r.present_at_end = self.on_road.len();
        r.mean_travel_time_s = (r.left > 0).then(|| self.travel_time_sum_s / r.left as f64);
        r.mean_speed_mps = (self.drive.speed_samples > 0)
            .then(|| self.drive.speed_sum / self.drive.speed_samples as f64);
        r
    }
}

/// What drives each controlled vehicle a step, whichever way it is read, and what it counts.
struct Drive {
    tolerance_mps: f64,
    /// What the vehicle being stepped senses (one vehicle: its leader).
    neighbors: Neighbors,
    report: Report,
    speed_sum: f64,
    speed_samples: usize,
}

impl Drive {
    /// One vehicle's step: its law given its speed `v`, the vehicle SUMO reports ahead of it
    /// (`Some((speed, gap))`, the gap as `getLeader` measures it: from its front plus its
    /// minGap) or nobody within [`LOOKAHEAD_M`], and the lane's speed limit `limit`. The
    /// command to send (at most the limit, at least 0), or the stop a non-finite command
    /// makes.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        g: &mut Guest<'_>,
        min_gap_m: f64,
        v: f64,
        leader: Option<(f64, f64)>,
        limit: f64,
        step: usize,
        t_s: f64,
    ) -> Result<f64, StopReason> {
        if g.last_command.is_finite() {
            let off = (v - g.last_command).abs();
            if off > self.tolerance_mps {
                self.report.overridden_commands += 1;
                self.report.max_override_mps = self.report.max_override_mps.max(off);
            }
        }
        self.speed_sum += v;
        self.speed_samples += 1;
        self.neighbors.ahead[0] = match leader {
            Some((speed_mps, gap_m)) => Sensed::Other {
                speed_mps,
                gap_m: gap_m + min_gap_m,
            },
            // The free road: a leader at the end of sight, at the lane's speed limit.
            None => Sensed::Other {
                speed_mps: limit,
                gap_m: LOOKAHEAD_M,
            },
        };
        g.controller.sense(&self.neighbors);
        let mut next = [0.0];
        g.controller.step(t_s, &[v], &[0.0], &mut next);
        // A Python controller that raised or returned what is not a speed ends the run, its
        // rows kept, as the fixed set's does.
        if let Some(end) = g.controller.ended() {
            return Err(end.at(step, t_s));
        }
        let mut cmd = next[0];
        if !cmd.is_finite() {
            return Err(StopReason::NonFiniteCommand {
                vehicle: g.name.clone(),
                step,
                value: format!("{cmd}"),
            });
        }
        if cmd > limit {
            cmd = limit;
            self.report.speed_limited_commands += 1;
        }
        let cmd = cmd.max(0.0);
        g.last_command = cmd;
        self.report.commands += 1;
        Ok(cmd)
    }
}

/// A direct call that threw for one of the vehicles on the road.
fn failed(on_road: &[Guest<'_>], call: &str, e: DirectError) -> CosimError {
    PythonError::Call {
        call: format!(
            "libsumo::Vehicle::{call}({}) (direct)",
            on_road[e.vehicle].name
        ),
        traceback: format!("C++ exception: {}", e.message),
    }
    .into()
}

fn float(x: Bound<'_, PyAny>, what: &str) -> Result<f64, CosimError> {
    x.extract()
        .map_err(|e| py_error(x.py(), format!("vehicle.{what}"), e).into())
}

/// The law of an inflow's vehicles as the record's report names it: a registry law with its
/// parameters, or `python:Class`.
fn described(law: &UserLaw) -> String {
    match law {
        UserLaw::Rust(named) => named.described(),
        UserLaw::Python(p) => p.label(),
    }
}
