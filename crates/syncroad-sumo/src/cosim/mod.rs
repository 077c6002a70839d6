//! The co-simulation loop that runs inside a worker: libsumo and the Rust law in one process,
//! no inter-process traffic per step, trajectory rows streamed to the parent in chunks.
//!
//! Per step n: the law turns the measured `v^n` into `v^{n+1}` (see `syncroad_control::controller`;
//! the loop adds no latency), non-finite commands stop the run before they reach SUMO, the
//! commands go out with `vehicle.setSpeed`, SUMO steps, and the new speeds are read back.
//! Collisions, teleports and overridden commands are counted.
//!
//! # Reading states
//! [`ReadMode::Direct`] (default) reads `getSpeed` of every vehicle every step and sends the
//! commands with `setSpeed`, each as one batch straight into the C++ functions of the libsumo
//! Python loaded ([`crate::direct`]), and advances positions by SUMO's own update rule
//! (trapezoidal with the ballistic update, else `Δt v^{n+1}`); SUMO's odometer `getDistance`
//! is read every `odometer_every` steps and at the end, replaces the integrated value, and the
//! largest deviation is reported (0 up to rounding: the integration is SUMO's own).
//! [`ReadMode::Getters`] makes the same calls through the Python module, one interpreter round
//! trip per vehicle. [`ReadMode::Subscriptions`] subscribes to speed and odometer; measured with
//! libsumo 1.28.0 at N = 2000, keeping the subscriptions up to date costs SUMO about 30 % of a
//! bare step, more than the getters' calls (`syncroad sumo-bench` measures the first two).

//!
//! The folder: [`libsumo`](self::libsumo) (handles and reading states), `step` (one step, apart
//! from the loop), `runner` (the loop: horizon, observers, stop reason), `meter`
//! (SUMO-side measurements) and `topology` (the law's graph read from SUMO before each step
//! when other traffic shares the road).

use std::io::Write;

use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};
use syncroad_control::{controller_for_in, SpeedController};

use crate::probe::Probe;
use crate::protocol::{write_msg, Control, Finish, Job, Request, StartInfo, WorkerMsg};
use crate::python::{load_libsumo, py_error, PythonError};

mod adopt;
mod guests;
pub(crate) mod libsumo;
mod meter;
mod observer;
mod runner;
mod step;
mod timing;
mod topology;

pub use libsumo::sumo_args;
use libsumo::{tail, Libsumo};

/// Errors inside the worker loop.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CosimError {
    /// A Python / libsumo call failed.
    #[error(transparent)]
    Python(#[from] PythonError),
    /// SUMO refused to start (the reason is in its log).
    #[error("SUMO did not start: {reason}\nSUMO log {log}:\n{log_tail}")]
    StartFailed {
        /// The exception text.
        reason: String,
        /// The log file.
        log: String,
        /// Its last lines.
        log_tail: String,
    },
    /// Vehicles were not inserted at t = 0.
    #[error("{pending} of {expected} vehicles could not be inserted (still pending: {ids}); SUMO log {log}:\n{log_tail}")]
    NotInserted {
        /// How many are missing.
        pending: usize,
        /// How many were expected.
        expected: usize,
        /// Some of their ids.
        ids: String,
        /// The log file.
        log: String,
        /// Its last lines.
        log_tail: String,
    },
    /// libsumo's lane lengths disagree with the network file's.
    #[error("road length of {net}: libsumo reports {sumo_m} m, the file says {file_m} m; rebuild the net with `bash sumo-nets/build.sh`")]
    LengthMismatch {
        /// The network.
        net: String,
        /// Σ lane.getLength.
        sumo_m: f64,
        /// Σ of the file's lane lengths.
        file_m: f64,
    },
    /// The law could not be built.
    #[error(transparent)]
    Controller(#[from] syncroad_control::controller::ControllerError),
    /// The user's vehicles `sumo.controlled` chooses are not the run's.
    #[error("sumo.controlled = {selector}: {reason}")]
    Controlled {
        /// The selection, as JSON.
        selector: String,
        /// What is wrong and what would be valid.
        reason: String,
    },
    /// The pipe to the parent broke (the parent is gone).
    #[error("writing to the parent failed: {0}")]
    Pipe(String),
}

/// The message a worker sends for a run that ended in `e`: a law that could not be built
/// refused the run before SUMO started ([`WorkerMsg::Refused`]: bad input); anything else
/// failed it ([`WorkerMsg::Failed`]).
pub fn failure_msg(e: CosimError) -> WorkerMsg {
    match e {
        CosimError::Controller(c) => WorkerMsg::Refused {
            message: c.to_string(),
        },
        other => WorkerMsg::Failed {
            message: other.to_string(),
        },
    }
}

/// Runs the job; every message goes to `out`. The returned error is also what the worker
/// reports as [`WorkerMsg::Failed`].
pub fn run(py: Python<'_>, job: &Job, out: &mut impl Write) -> Result<(), CosimError> {
    let req = job.request();
    let probe = match job {
        Job::Run(_) => None,
        Job::Bench { probe, .. } => Some(*probe),
    };
    // Build the law first: a law problem must not cost a SUMO start.
    let controller: Option<Box<dyn SpeedController>> = match &req.control {
        Control::Law { law } => Some(controller_for_in(law, Some(&crate::user_law::PythonHost))?),
        Control::SumoModel => None,
    };
    let (module, python) = load_libsumo(py)?;
    // A worker's stderr is its parent's log; a run in the caller's process says nothing there.
    if !crate::handoff::is_here() {
        eprintln!(
            "syncroad-sumo worker: python {} (sys.prefix {}), libsumo {} ({})",
            python
                .python_version
                .split_whitespace()
                .next()
                .unwrap_or("?"),
            python.sys_prefix,
            python.libsumo_file,
            python.sumo_version
        );
    }
    let ls = Libsumo::new(py, module)?;
    let args = sumo_args(req);
    if let Err(e) = ls.native.call_method1("simulation_start", (args.clone(),)) {
        // SUMO's own words (libsumo's exception and its log), not the Python traceback of
        // the binding, which says nothing about the user's files.
        return Err(CosimError::StartFailed {
            reason: format!("libsumo.start refused the run: {}", e.value(py)),
            log: req.log_file.display().to_string(),
            log_tail: tail(&req.log_file, 20),
        });
    }
    let result = run_started(py, &ls, req, controller, probe, python, out);
    // Close SUMO whatever happened, and before the end is reported: closing flushes SUMO's
    // log, whose emergency-braking warnings the parent counts when the end arrives (a pooled
    // worker goes on to its next run, so nothing else would make the log complete in time).
    let _ = ls.native.call_method0("simulation_close");
    let finish = result?;
    write_msg(out, &WorkerMsg::Finished(Box::new(finish)))
        .map_err(|e| CosimError::Pipe(e.to_string()))?;
    out.flush().map_err(|e| CosimError::Pipe(e.to_string()))
}

/// After `libsumo.start`: checks that every vehicle is on the road and that SUMO's road length
/// is the one the layout used, reports the start, then runs the steps.
fn run_started(
    py: Python<'_>,
    ls: &Libsumo<'_>,
    req: &Request,
    controller: Option<Box<dyn SpeedController>>,
    probe: Option<Probe>,
    python: crate::python::PythonInfo,
    out: &mut impl Write,
) -> Result<Finish, CosimError> {
    let n = req.layout.vehicles.len();
    // Insertion happens in the first step; states after it are the initial conditions.
    ls.simulation_step()?;
    // The user's own vehicles the law drives, bound now that SUMO has inserted them.
    let bound;
    let (req, controlled) = match &req.adopt {
        Some(sel) => {
            bound = adopt::bind(ls, req, sel)?;
            let ids = bound.layout.vehicles.iter().map(|v| v.id.clone()).collect();
            (&bound, ids)
        }
        None => (req, Vec::new()),
    };
    let pending: Vec<String> = ls
        .call("simulation_getPendingVehicles", ())?
        .extract()
        .map_err(|e| py_error(py, "simulation.getPendingVehicles", e))?;
    let on_road = if req.extra_routes.is_empty() {
        ls.count(
            &ls.native
                .getattr("vehicle_getIDCount")
                .map_err(|e| py_error(py, "vehicle_getIDCount", e))?,
            "vehicle.getIDCount",
        )?
    } else {
        // The user's own traffic shares the road: count syncroad's vehicles only.
        let all: Vec<String> = ls
            .call("vehicle_getIDList", ())?
            .extract()
            .map_err(|e| py_error(py, "vehicle.getIDList", e))?;
        let all: std::collections::HashSet<String> = all.into_iter().collect();
        req.layout
            .vehicles
            .iter()
            .filter(|v| all.contains(&v.id))
            .count()
    };
    let ours: std::collections::HashSet<&str> =
        req.layout.vehicles.iter().map(|v| v.id.as_str()).collect();
    let pending: Vec<String> = pending
        .into_iter()
        .filter(|p| ours.contains(p.as_str()))
        .collect();
    if !pending.is_empty() || on_road != n {
        return Err(CosimError::NotInserted {
            pending: n - on_road.min(n),
            expected: n,
            ids: pending
                .iter()
                .take(10)
                .cloned()
                .collect::<Vec<_>>()
                .join(", "),
            log: req.log_file.display().to_string(),
            log_tail: tail(&req.log_file, 20),
        });
    }
    let mut road_length = 0.0;
    for seg in &req.layout.road.segments {
        let l: f64 = ls
            .call("lane_getLength", (seg.lane.as_str(),))?
            .extract()
            .map_err(|e| py_error(py, format!("lane.getLength({})", seg.lane), e))?;
        road_length += l;
    }
    // The layout placed the vehicles with the lengths read from the file before SUMO started;
    // SUMO must agree, or the ring coordinate (and every gap) would be off.
    let parsed = req.layout.road.length_m();
    if (road_length - parsed).abs() > 1e-6 * parsed.max(1.0) {
        return Err(CosimError::LengthMismatch {
            net: req.layout.road.path.display().to_string(),
            sumo_m: road_length,
            file_m: parsed,
        });
    }
    let started = StartInfo {
        python,
        road_length_m: road_length,
        vehicles: on_road,
        pid: std::process::id(),
        controlled,
    };
    write_msg(out, &WorkerMsg::Started(started)).map_err(|e| CosimError::Pipe(e.to_string()))?;
    let ids: Vec<Bound<'_, PyString>> = req
        .layout
        .vehicles
        .iter()
        .map(|v| PyString::intern(py, &v.id))
        .collect();
    let id_args: Vec<Bound<'_, PyTuple>> = ids
        .iter()
        .map(|id| PyTuple::new(py, [id]))
        .collect::<PyResult<_>>()
        .map_err(|e| py_error(py, "argument tuples", e))?;
    let sim = step::CoSim::new(py, ls, req, &ids, controller)?;
    runner::run_steps(sim, &id_args, probe, out)
}

#[cfg(test)]
mod tests {
    use super::libsumo::{sanitize_commands, set_item_f64};
    use super::*;
    use pyo3::types::PyTuple;

    #[test]
    fn argument_tuples_are_refilled_only_when_unshared() {
        Python::initialize();
        Python::attach(|py| {
            let t = PyTuple::new(py, [1.0f64, 2.0]).unwrap();
            set_item_f64(&t, 1, 7.5).unwrap();
            assert_eq!(t.get_item(1).unwrap().extract::<f64>().unwrap(), 7.5);
            let shared = t.clone();
            let err = set_item_f64(&t, 0, 1.0).unwrap_err();
            assert!(err.is_instance_of::<pyo3::exceptions::PySystemError>(py));
            drop(shared);
        });
    }

    #[test]
    fn insertion_failure_names_the_vehicles_and_the_log() {
        let e = CosimError::NotInserted {
            pending: 2,
            expected: 22,
            ids: "v3, v4".into(),
            log: "/w/sumo.log".into(),
            log_tail: "Warning: ...".into(),
        };
        assert_eq!(
            e.to_string(),
            "2 of 22 vehicles could not be inserted (still pending: v3, v4); SUMO log /w/sumo.log:\nWarning: ..."
        );
        let e = CosimError::from(syncroad_control::controller::ControllerError::Named {
            law: "protocol".into(),
            reason: syncroad_control::protocol_law::CACC_NEEDS_LEADER.into(),
        });
        assert_eq!(
            e.to_string(),
            "protocol: the CACC model needs a leader vehicle: run it on a straight road (road.type = \"straight\")"
        );
    }

    #[test]
    fn non_finite_commands_never_reach_sumo() {
        let mut c = [1.0, -0.5, f64::NAN, 2.0];
        assert_eq!(sanitize_commands(&mut c, &[true; 4]), Err(2));
        // Nothing was changed: the run stops with the command as the law produced it.
        assert_eq!(c[1], -0.5);
        let mut c = [1.0, f64::INFINITY];
        assert_eq!(sanitize_commands(&mut c, &[true; 2]), Err(1));
    }

    #[test]
    fn commands_for_vehicles_sumo_drives_are_ignored() {
        // Mixed traffic: the law's output for SUMO-driven vehicles 1 and 2 is never sent.
        let mut c = [1.0, f64::NAN, -4.0, -0.5];
        assert_eq!(
            sanitize_commands(&mut c, &[true, false, false, true]),
            Ok(1)
        );
        assert_eq!(c[3], 0.0);
        assert_eq!(c[2], -4.0);
    }

    #[test]
    fn negative_commands_become_zero() {
        let mut c = [1.0, -0.5, -0.0, 2.0, -3.0];
        assert_eq!(sanitize_commands(&mut c, &[true; 5]), Ok(2));
        assert_eq!(c, [1.0, 0.0, -0.0, 2.0, 0.0]);
    }
}
