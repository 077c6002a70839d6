//! The user's Python controller as a [`SpeedController`]: built once from its class and
//! parameters, stepped every step with numpy arrays, inside the SUMO worker's interpreter or,
//! for the native simulator, in a controller process of its own ([`crate::contained`]); the
//! [`PythonHost`] builds it in the interpreter of the process it runs in.
//!
//! Each step the adapter writes five rows of float64 (speeds, accelerations over the last step,
//! odometers, gaps and the speeds of the vehicles ahead) straight into the numpy block the
//! Python side (`user_law.py`) owns and shows as the observation's arrays, calls `step(obs)`
//! once, and reads the commands from the numpy array the Python side copied them into. One
//! call into Python per step and no allocation, whatever the number of vehicles.
//!
//! The commands are checked before they reach a vehicle: an exception, a result of the wrong
//! type or length, or a speed that is not finite or is negative stops the run with the step, the
//! vehicle and the controller's own traceback ([`SpeedController::ended`]); the rows before
//! it are kept.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use syncroad_control::controller::ControllerError;
use syncroad_control::road::RingView;
use syncroad_control::sensed::Neighbors;
use syncroad_control::user_law::{LawContext, PythonLaw, PythonSource};
use syncroad_control::{ControllerEnd, LawHost, SpeedController};

use std::sync::Arc;

use crate::handoff::{Handoff, Shared, Stop};
use crate::python::{add_packages, py_error};

/// The Python half of the adapter.
const HELPER: &std::ffi::CStr = pyo3::ffi::c_str!(include_str!("user_law.py"));

/// Builds the user's Python controllers in this process's interpreter (initialized on first
/// use, with the SUMO environment's packages on its path, where numpy is).
#[derive(Debug, Clone, Copy, Default)]
pub struct PythonHost;

impl LawHost for PythonHost {
    fn python(
        &self,
        law: &PythonLaw,
        context: &LawContext,
    ) -> Result<Box<dyn SpeedController>, ControllerError> {
        Python::initialize();
        Python::attach(|py| PythonController::new(py, law, context)).map(|c| Box::new(c) as _)
    }
}

/// Whether the controller returns target speeds or accelerations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Command {
    Speed,
    Acceleration,
}

/// A user's Python controller, stepped by either backend.
pub struct PythonController {
    stepper: Py<PyAny>,
    /// Addresses of the Python side's arrays (kept alive by it): `rows` of 5 × n and `out` of
    /// n float64.
    rows: usize,
    out: usize,
    command: Command,
    ids: Vec<String>,
    dt_s: f64,
    /// The gap to the vehicle ahead and its speed (SUMO's lane neighbour when sensed).
    view: RingView,
    controlled: Vec<bool>,
    steps: usize,
    start_m: Vec<f64>,
    last_mps: Vec<f64>,
    /// Why the run ends, once it does.
    ended: Option<ControllerEnd>,
    /// The caller in this process the controller stands for (`syncroad.Simulation`): the
    /// observation and the commands go through this meeting point instead of `step(obs)`.
    handoff: Option<Caller>,
}

/// The observation's rows the adapter computes: speeds, accelerations over the last step,
/// odometers, gaps and the speeds ahead (the caller's observation adds the lights' two).
const ROWS: usize = 5;

/// A caller in this process, met through a [`Handoff`].
struct Caller {
    shared: Arc<Shared>,
    /// The run's context, which the caller is told with the first observation.
    context: LawContext,
    /// The Stepper's reading of the traffic lights ahead and its two arrays (n float64 each),
    /// on a network with traffic lights.
    signals: Option<(Py<PyAny>, usize, usize)>,
    /// The observation handed over (time, step, then the rows), swapped with the meeting
    /// point's each step: no allocation per step.
    obs: Vec<f64>,
}

impl Drop for PythonController {
    fn drop(&mut self) {
        if let Some(c) = &self.handoff {
            c.shared.end();
        }
    }
}

impl PythonController {
    /// Imports the class of `law` and makes the instance, for the run of `setup`.
    pub fn new(
        py: Python<'_>,
        law: &PythonLaw,
        setup: &LawContext,
    ) -> Result<Self, ControllerError> {
        let fail = |reason: String| ControllerError::Python {
            python: law.python.clone(),
            reason,
        };
        add_packages(py).map_err(|e| fail(e.to_string()))?;
        let helper = pyo3::types::PyModule::from_code(
            py,
            HELPER,
            c"syncroad_user_law.py",
            c"syncroad_user_law",
        )
        .map_err(|e| fail(py_error(py, "loading syncroad's controller adapter", e).to_string()))?;
        let (kind, place) = match &law.source {
            PythonSource::File { path } => ("file", path.display().to_string()),
            PythonSource::Module { module } => ("module", module.clone()),
        };
        let params = pythonize(py, &law.params).map_err(|e| fail(e.to_string()))?;
        let state = law.state.as_ref().map(|p| p.display().to_string());
        let built = helper
            .call_method1("build", (kind, &place, &law.class, params, state))
            .map_err(|e| {
                let what = if law.state.is_some() {
                    format!("restoring {} from its pickled state", law.class)
                } else {
                    format!("{}(**params)", law.class)
                };
                fail(py_error(py, what, e).to_string())
            })?;
        let (obj, command): (Bound<'_, PyAny>, String) = built
            .extract()
            .map_err(|e| fail(py_error(py, "build", e).to_string()))?;
        let stepper = helper
            .getattr("Stepper")
            .and_then(|s| {
                s.call1((
                    obj,
                    setup.ids.clone(),
                    setup.step_s,
                    setup.length_m.clone(),
                    setup.ring_length_m,
                    setup.controlled.clone(),
                    setup.speed_limit_mps,
                    setup.signals,
                ))
            })
            .map_err(|e| fail(py_error(py, "Stepper", e).to_string()))?;
        let address = |name: &str| {
            stepper
                .getattr(name)
                .and_then(|a| a.extract::<usize>())
                .map_err(|e| fail(py_error(py, name.to_string(), e).to_string()))
        };
        let (rows, out) = (address("rows_address")?, address("out_address")?);
        let handoff = match obj_handoff(&stepper) {
            Some(shared) => Some(Caller {
                shared,
                context: setup.clone(),
                signals: if setup.signals {
                    let read = stepper
                        .getattr("read_signals")
                        .map_err(|e| fail(py_error(py, "Stepper.read_signals", e).to_string()))?;
                    Some((
                        read.unbind(),
                        address("signal_distance_address")?,
                        address("signal_stop_address")?,
                    ))
                } else {
                    None
                },
                obs: Vec::new(),
            }),
            None => None,
        };
        let stepper = stepper
            .getattr("step")
            .map_err(|e| fail(py_error(py, "Stepper.step", e).to_string()))?;
        Ok(Self {
            rows,
            out,
            stepper: stepper.unbind(),
            command: if command == "acceleration" {
                Command::Acceleration
            } else {
                Command::Speed
            },
            ids: setup.ids.clone(),
            dt_s: setup.step_s,
            view: RingView::on(setup.ring_length_m, &setup.length_m),
            controlled: setup.controlled.clone(),
            steps: 0,
            start_m: Vec::new(),
            last_mps: Vec::new(),
            ended: None,
            handoff,
        })
    }

    /// This step's [`ROWS`] rows of n values into `rows`: speeds, accelerations over the last
    /// step, odometers, gaps and the speeds of the vehicles ahead.
    fn observe(&mut self, speeds: &[f64], positions: &[f64], rows: &mut [f64]) {
        let n = speeds.len();
        if self.steps == 0 {
            self.start_m = positions.to_vec();
            self.last_mps = speeds.to_vec();
        }
        self.view.observe(speeds, positions);
        let (v, rest) = rows.split_at_mut(n);
        let (a, rest) = rest.split_at_mut(n);
        let (odo, rest) = rest.split_at_mut(n);
        let (gap, lead) = rest.split_at_mut(n);
        v.copy_from_slice(speeds);
        for i in 0..n {
            a[i] = (speeds[i] - self.last_mps[i]) / self.dt_s;
            odo[i] = positions[i] - self.start_m[i];
        }
        gap.copy_from_slice(&self.view.gaps_m);
        lead.copy_from_slice(&self.view.leader_speeds_mps);
        self.last_mps.copy_from_slice(speeds);
    }

    /// [`Self::call`] for a caller in this process: the same observation (and the lights'
    /// rows, which the Stepper reads from libsumo on a network with lights) handed over with
    /// the interpreter released while the caller decides.
    fn call_here(
        &mut self,
        time_s: f64,
        speeds: &[f64],
        positions: &[f64],
        out: &mut [f64],
    ) -> Result<(), ControllerEnd> {
        let n = speeds.len();
        let mut obs = std::mem::take(&mut self.handoff.as_mut().expect("a caller here").obs);
        obs.resize(2 + (ROWS + 2) * n, 0.0);
        obs[0] = time_s;
        obs[1] = self.steps as f64;
        let (rows, lights) = obs[2..].split_at_mut(ROWS * n);
        self.observe(speeds, positions, rows);
        let caller = self.handoff.as_mut().expect("a caller here");
        let (distance, stop) = lights.split_at_mut(n);
        match &caller.signals {
            Some((read, d, s)) => {
                Python::attach(|py| {
                    read.bind(py).call0().map(|_| ()).map_err(|e| {
                        ControllerEnd::Failed(
                            py_error(py, "reading the traffic lights ahead", e).to_string(),
                        )
                    })
                })?;
                // SAFETY: the Stepper's two float64 arrays of n values (kept as its
                // attributes while this controller holds it), written by `read_signals` just
                // now; nothing else writes them while the loop steps.
                unsafe {
                    distance.copy_from_slice(std::slice::from_raw_parts(*d as *const f64, n));
                    stop.copy_from_slice(std::slice::from_raw_parts(*s as *const f64, n));
                }
            }
            None => {
                distance.fill(f64::INFINITY);
                stop.fill(0.0);
            }
        }
        let first = (self.steps == 0).then(|| caller.context.clone());
        let shared = &caller.shared;
        let result = Python::attach(|py| {
            py.detach(|| shared.exchange(first, |o| std::mem::swap(o, &mut obs), out))
        });
        caller.obs = obs;
        result.map_err(|s| match s {
            Stop::Closed(why) => ControllerEnd::Stopped(why),
            Stop::Failed(why) => ControllerEnd::Failed(why),
        })
    }

    /// Writes this step's observation into the Python side's rows (speeds, accelerations,
    /// odometers, gaps, speeds ahead), calls `step(obs)` and reads its commands into `out`.
    fn call(
        &mut self,
        py: Python<'_>,
        time_s: f64,
        speeds: &[f64],
        positions: &[f64],
        out: &mut [f64],
    ) -> Result<(), ControllerEnd> {
        let n = speeds.len();
        // SAFETY: `rows` and `out` are the data of the C-contiguous float64 arrays of 5 × n and
        // n values the Stepper made for these n vehicles (`step` checks the count) and keeps as
        // attributes while this controller holds it (`stepper` is its bound method); the GIL
        // is held, so no Python code runs while they are written or read.
        let rows = unsafe { std::slice::from_raw_parts_mut(self.rows as *mut f64, ROWS * n) };
        self.observe(speeds, positions, rows);
        self.stepper
            .bind(py)
            .call1((time_s, self.steps))
            .map_err(|e| {
                // An exception that says it ends the run on purpose (`syncroad_stop = True`,
                // as syncroad.Simulation's close) is a stop with its message, not a failure.
                let value = e.value(py);
                let deliberate = value
                    .getattr("syncroad_stop")
                    .and_then(|x| x.is_truthy())
                    .unwrap_or(false);
                match value.str() {
                    Ok(text) if deliberate => ControllerEnd::Stopped(text.to_string()),
                    _ => ControllerEnd::Failed(
                        py_error(py, "the controller's step(obs)", e).to_string(),
                    ),
                }
            })?;
        // SAFETY: as above; `step` returned, having copied n commands into `out`.
        unsafe {
            std::ptr::copy_nonoverlapping(self.out as *const f64, out.as_mut_ptr(), n);
        }
        Ok(())
    }

    /// Checks the commands of the controlled vehicles and turns accelerations into speeds.
    fn check(&self, time_s: f64, speeds: &[f64], out: &mut [f64]) -> Result<(), String> {
        for i in 0..out.len() {
            if !self.controlled[i] {
                out[i] = speeds[i];
                continue;
            }
            let x = out[i];
            let bad = !x.is_finite() || (self.command == Command::Speed && x < 0.0);
            if bad {
                let (what, valid) = match self.command {
                    Command::Speed => ("target speed", "target speeds must be finite and ≥ 0 m/s"),
                    Command::Acceleration => ("acceleration", "accelerations must be finite"),
                };
                return Err(format!(
                    "at step {} (t = {time_s:.3} s) the controller's {what} for vehicle {} (obs.ids[{i}]) is {x}; {valid}",
                    self.steps,
                    self.ids[i],
                ));
            }
            if self.command == Command::Acceleration {
                out[i] = (speeds[i] + x * self.dt_s).max(0.0);
            }
        }
        Ok(())
    }
}

impl SpeedController for PythonController {
    fn step(&mut self, time_s: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        if self.ended.is_none() && (speeds.len() != self.ids.len() || out.len() != speeds.len()) {
            // The arrays on the Python side hold exactly the vehicles the controller was built for.
            self.ended = Some(ControllerEnd::Failed(format!(
                "the controller was built for {} vehicles and is stepped with {}",
                self.ids.len(),
                speeds.len()
            )));
        }
        if self.ended.is_none() {
            let called = if self.handoff.is_some() {
                self.call_here(time_s, speeds, positions, out)
            } else {
                Python::attach(|py| self.call(py, time_s, speeds, positions, out))
            };
            let result = called.and_then(|()| {
                self.check(time_s, speeds, out)
                    .map_err(ControllerEnd::Failed)
            });
            self.ended = result.err();
            self.steps += 1;
        }
        if self.ended.is_some() {
            // Nothing of a failed step is sent: the loop stops on `ended` first.
            out.copy_from_slice(speeds);
        }
    }

    fn sense(&mut self, neighbors: &Neighbors) {
        self.view.sense(neighbors);
    }

    fn ended(&mut self) -> Option<ControllerEnd> {
        self.ended.clone()
    }
}

/// The meeting point of the caller the Stepper's controller stands for, when it is one
/// (its `syncroad_handoff` attribute is a [`Handoff`] of this process).
fn obj_handoff(stepper: &Bound<'_, PyAny>) -> Option<Arc<Shared>> {
    let obj = stepper.getattr("controller").ok()?;
    let h = obj.getattr("syncroad_handoff").ok()?;
    let h = h.cast::<Handoff>().ok()?;
    Some(h.get().shared())
}

/// A JSON value as the Python object `json.loads` makes of it.
fn pythonize<'py>(
    py: Python<'py>,
    value: &serde_json::Value,
) -> Result<Bound<'py, PyDict>, crate::python::PythonError> {
    let text = value.to_string();
    py.import("json")
        .and_then(|j| j.call_method1("loads", (text,)))
        .and_then(|d| d.cast_into::<PyDict>().map_err(Into::into))
        .map_err(|e| py_error(py, "json.loads(controller.params)", e))
}
