//! The co-simulation loop that runs inside a worker: libsumo and the Rust law in one process,
//! no inter-process traffic per step, trajectory rows streamed to the parent in chunks.
//!
//! Per step n: the law turns the measured `v^n` into `v^{n+1}` (see [`crate::controller`] for
//! why no latency is added), non-finite commands stop the run before they reach SUMO, the
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

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyString, PyTuple};

use crate::controller::{controller_for, SpeedController};
use crate::direct::{Direct, DirectError};
use crate::protocol::{
    write_msg, write_rows, Control, Event, Finish, Measure, Measured, PhaseTimes, ReadMode,
    Request, RowChunk, StartInfo, StopReason, Totals, WorkerMsg,
};
use crate::python::{load_libsumo, py_error, PythonError};

/// libsumo variable ids (traci constants) read through subscriptions.
const VAR_SPEED: i32 = 0x40;
const VAR_DISTANCE: i32 = 0x84;
/// Speed mode with every safety check off: SUMO realises the command as given.
const SPEED_MODE_RAW: i32 = 32;
/// Longest time rows wait in the worker before they are sent.
const FLUSH_INTERVAL: std::time::Duration = std::time::Duration::from_millis(200);
/// Override events sent to the parent per run (all are counted).
const MAX_OVERRIDE_EVENTS: usize = 20;

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
    /// The scenario sent by the parent does not validate in the worker.
    #[error("scenario rejected in the worker: {0}")]
    Scenario(String),
    /// The law could not be built.
    #[error(transparent)]
    Controller(#[from] crate::controller::ControllerError),
    /// The pipe to the parent broke (the parent is gone).
    #[error("writing to the parent failed: {0}")]
    Pipe(String),
}

fn tail(path: &Path, lines: usize) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let all: Vec<&str> = text.lines().collect();
    all[all.len().saturating_sub(lines)..].join("\n")
}

/// Handles to the libsumo functions the loop calls (the SWIG entry points of `_libsumo`, which
/// skip one Python wrapper layer per call).
struct Libsumo<'py> {
    py: Python<'py>,
    module: Bound<'py, PyModule>,
    native: Bound<'py, PyModule>,
    step: Bound<'py, PyAny>,
    set_speed: Bound<'py, PyAny>,
    all_subscriptions: Bound<'py, PyAny>,
    colliding: Bound<'py, PyAny>,
    teleports: Bound<'py, PyAny>,
}

impl<'py> Libsumo<'py> {
    fn new(py: Python<'py>, module: Bound<'py, PyModule>) -> Result<Self, PythonError> {
        let native = module
            .getattr("_libsumo")
            .and_then(|m| m.cast_into::<PyModule>().map_err(PyErr::from))
            .map_err(|e| py_error(py, "libsumo._libsumo", e))?;
        let f = |name: &str| {
            native
                .getattr(name)
                .map_err(|e| py_error(py, format!("_libsumo.{name}"), e))
        };
        Ok(Self {
            step: f("simulation_step")?,
            set_speed: f("vehicle_setSpeed")?,
            all_subscriptions: f("vehicle_getAllSubscriptionResults")?,
            colliding: f("simulation_getCollidingVehiclesNumber")?,
            teleports: f("simulation_getStartingTeleportNumber")?,
            py,
            module,
            native,
        })
    }

    fn call(
        &self,
        name: &str,
        args: impl pyo3::call::PyCallArgs<'py>,
    ) -> Result<Bound<'py, PyAny>, PythonError> {
        self.native
            .call_method1(name, args)
            .map_err(|e| py_error(self.py, format!("_libsumo.{name}"), e))
    }

    fn simulation_step(&self) -> Result<(), PythonError> {
        self.step
            .call1((0.0,))
            .map(|_| ())
            .map_err(|e| py_error(self.py, "simulation.step", e))
    }

    fn count(&self, f: &Bound<'py, PyAny>, what: &str) -> Result<usize, PythonError> {
        f.call0()
            .and_then(|x| x.extract::<usize>())
            .map_err(|e| py_error(self.py, what.to_string(), e))
    }
}

/// Replaces item `i` of an argument tuple that only this loop holds by the float `x`.
///
/// `PyTuple_SetItem` refuses (SystemError) unless the caller holds the only reference, which
/// is the case between calls: the libsumo wrappers do not keep their argument tuple. Reusing
/// the tuple saves an allocation per `setSpeed`, a measurable part of the loop's overhead on
/// small rings.
fn set_item_f64(tuple: &Bound<'_, PyTuple>, i: isize, x: f64) -> PyResult<()> {
    let py = tuple.py();
    // SAFETY: `tuple` is a live tuple; PyFloat_FromDouble returns a new reference or NULL with
    // an exception set; PyTuple_SetItem steals that reference (also on failure) and checks the
    // index and that the tuple is not shared.
    unsafe {
        let f = pyo3::ffi::PyFloat_FromDouble(x);
        if f.is_null() {
            return Err(PyErr::fetch(py));
        }
        if pyo3::ffi::PyTuple_SetItem(tuple.as_ptr(), i, f) != 0 {
            return Err(PyErr::fetch(py));
        }
    }
    Ok(())
}

/// Checks the law's commands before they reach SUMO, which accepts NaN and ∞ silently and
/// reads a negative speed as "release control": `Err(i)` for the first non-finite command
/// (nothing is sent), else negatives are set to 0 and their number returned.
pub fn sanitize_commands(next: &mut [f64]) -> Result<usize, usize> {
    if let Some(i) = next.iter().position(|x| !x.is_finite()) {
        return Err(i);
    }
    let mut clamped = 0;
    for x in next.iter_mut().filter(|x| **x < 0.0) {
        *x = 0.0;
        clamped += 1;
    }
    Ok(clamped)
}

/// How vehicle states are read each step.
struct Reader<'a, 'py> {
    py: Python<'py>,
    ls: &'a Libsumo<'py>,
    ids: &'a [Bound<'py, PyString>],
    /// Subscriptions (speed and odometer every step) instead of direct getters.
    subscribed: bool,
    get_speed: Bound<'py, PyAny>,
    get_distance: Bound<'py, PyAny>,
    /// `(id,)` per vehicle, built once: a getter call then allocates nothing but its result.
    id_args: Vec<Bound<'py, PyTuple>>,
    id_count: Bound<'py, PyAny>,
    key_speed: Bound<'py, PyInt>,
    key_distance: Bound<'py, PyInt>,
    /// The subscription results of the current step (read once for speeds and odometers).
    cache: std::cell::RefCell<Option<Bound<'py, PyDict>>>,
    /// Batch calls into libsumo's C++ functions ([`ReadMode::Direct`]).
    direct: Option<Direct>,
}

impl<'a, 'py> Reader<'a, 'py> {
    fn new(
        py: Python<'py>,
        ls: &'a Libsumo<'py>,
        mode: ReadMode,
        ids: &'a [Bound<'py, PyString>],
    ) -> Result<Self, PythonError> {
        let subscribed = mode == ReadMode::Subscriptions;
        if subscribed {
            for id in ids {
                ls.call(
                    "vehicle_subscribe",
                    (id.clone(), vec![VAR_SPEED, VAR_DISTANCE]),
                )?;
            }
        }
        let f = |name: &str| {
            ls.native
                .getattr(name)
                .map_err(|e| py_error(py, format!("_libsumo.{name}"), e))
        };
        let direct = if mode == ReadMode::Direct {
            let file: String = ls
                .native
                .getattr("__file__")
                .and_then(|f| f.extract())
                .map_err(|e| py_error(py, "libsumo._libsumo.__file__", e))?;
            let names: Vec<String> = ids.iter().map(|id| id.to_string()).collect();
            Direct::load(&file, &names)
        } else {
            None
        };
        Ok(Self {
            direct,
            py,
            ls,
            ids,
            subscribed,
            get_speed: f("vehicle_getSpeed")?,
            id_args: ids
                .iter()
                .map(|id| PyTuple::new(py, [id]))
                .collect::<PyResult<_>>()
                .map_err(|e| py_error(py, "argument tuples", e))?,
            get_distance: f("vehicle_getDistance")?,
            id_count: f("vehicle_getIDCount")?,
            key_speed: PyInt::new(py, VAR_SPEED),
            key_distance: PyInt::new(py, VAR_DISTANCE),
            cache: std::cell::RefCell::new(None),
        })
    }

    /// Index of the first vehicle no longer in the simulation, if the count dropped.
    fn missing(&self) -> Result<Option<usize>, PythonError> {
        let count = self.ls.count(&self.id_count, "vehicle.getIDCount")?;
        if count == self.ids.len() {
            return Ok(None);
        }
        let present: Vec<String> = self
            .ls
            .call("vehicle_getIDList", ())?
            .extract()
            .map_err(|e| py_error(self.py, "vehicle.getIDList", e))?;
        Ok(self
            .ids
            .iter()
            .position(|id| !present.iter().any(|p| id.to_str().is_ok_and(|s| s == p))))
    }

    /// A failed direct call: `Some(i)` if vehicle i left the simulation, else the error.
    fn direct_failure(&self, call: &str, e: DirectError) -> Result<Option<usize>, PythonError> {
        match self.missing()? {
            Some(i) => Ok(Some(i)),
            None => Err(PythonError::Call {
                call: format!("libsumo::Vehicle::{call}({}) (direct)", self.ids[e.vehicle]),
                traceback: format!("C++ exception: {}", e.message),
            }),
        }
    }

    /// Measured speeds into `v`; `Some(i)` when vehicle i left the simulation.
    fn speeds(&self, v: &mut [f64]) -> Result<Option<usize>, PythonError> {
        if let Some(d) = &self.direct {
            return match d.speeds(v) {
                Ok(()) => Ok(None),
                Err(e) => self.direct_failure("getSpeed", e),
            };
        }
        if self.subscribed {
            let all = self
                .ls
                .all_subscriptions
                .call0()
                .and_then(|x| x.cast_into::<PyDict>().map_err(PyErr::from))
                .map_err(|e| py_error(self.py, "vehicle.getAllSubscriptionResults", e))?;
            *self.cache.borrow_mut() = Some(all);
            return self.cached(&self.key_speed, v);
        }
        for ((id, args), x) in self.ids.iter().zip(&self.id_args).zip(v.iter_mut()) {
            match self.get_speed.call1(args).and_then(|r| r.extract::<f64>()) {
                Ok(speed) => *x = speed,
                // An unknown vehicle raises: find out whether one left the simulation.
                Err(e) => match self.missing()? {
                    Some(i) => return Ok(Some(i)),
                    None => {
                        return Err(py_error(self.py, format!("vehicle.getSpeed({id})"), e));
                    }
                },
            }
        }
        Ok(None)
    }

    /// SUMO odometers (`vehicle.getDistance`) into `d`.
    fn odometers(&self, d: &mut [f64]) -> Result<Option<usize>, PythonError> {
        if let Some(direct) = &self.direct {
            return match direct.odometers(d) {
                Ok(()) => Ok(None),
                Err(e) => self.direct_failure("getDistance", e),
            };
        }
        if self.subscribed {
            return self.cached(&self.key_distance, d);
        }
        for ((id, args), x) in self.ids.iter().zip(&self.id_args).zip(d.iter_mut()) {
            *x = self
                .get_distance
                .call1(args)
                .and_then(|r| r.extract::<f64>())
                .map_err(|e| py_error(self.py, format!("vehicle.getDistance({id})"), e))?;
        }
        Ok(None)
    }

    fn cached(
        &self,
        key: &Bound<'py, PyInt>,
        out: &mut [f64],
    ) -> Result<Option<usize>, PythonError> {
        let cache = self.cache.borrow();
        let all = cache.as_ref().expect("speeds() fills the cache first");
        for (i, id) in self.ids.iter().enumerate() {
            let Some(entry) = all
                .get_item(id)
                .map_err(|e| py_error(self.py, "subscription lookup", e))?
            else {
                return Ok(Some(i));
            };
            out[i] = entry
                .get_item(key)
                .and_then(|x| x.extract::<f64>())
                .map_err(|e| py_error(self.py, format!("subscription value of {id}"), e))?;
        }
        Ok(None)
    }
}

/// SUMO's command line for a request.
pub fn sumo_args(req: &Request) -> Vec<String> {
    let mut a: Vec<String> = vec![
        "sumo".into(),
        "--net-file".into(),
        req.layout.road.path.display().to_string(),
        "--route-files".into(),
        req.routes_file.display().to_string(),
        "--step-length".into(),
        format!("{}", req.step_s),
        "--seed".into(),
        req.seed.to_string(),
        "--collision.action".into(),
        "warn".into(),
        "--collision.mingap-factor".into(),
        "0".into(),
        "--collision.check-junctions".into(),
        "true".into(),
        "--time-to-teleport".into(),
        "-1".into(),
        "--no-step-log".into(),
        "true".into(),
        "--duration-log.disable".into(),
        "true".into(),
        "--xml-validation".into(),
        "never".into(),
        "--log".into(),
        req.log_file.display().to_string(),
    ];
    if req.ballistic {
        a.push("--step-method.ballistic".into());
        a.push("true".into());
    }
    if let Some(m) = &req.measure {
        if let Some(f) = &m.detector_file {
            a.push("--additional-files".into());
            a.push(f.display().to_string());
        }
        if let Some(f) = &m.tripinfo_file {
            for x in [
                "--device.emissions.probability",
                "1",
                "--tripinfo-output.write-unfinished",
                "true",
                "--tripinfo-output",
            ] {
                a.push(x.into());
            }
            a.push(f.display().to_string());
        }
    }
    a
}

/// The loop's SUMO-side measurements (see [`Measured`]).
struct Meter<'py> {
    req: Measure,
    fuel: Bound<'py, PyAny>,
    co2: Bound<'py, PyAny>,
    time_loss: Bound<'py, PyAny>,
    loop_ids: Option<Bound<'py, PyAny>>,
    last_on_loop: Vec<String>,
    time_loss_at_warmup: f64,
    out: Measured,
}

impl<'py> Meter<'py> {
    fn new(ls: &Libsumo<'py>, req: &Measure) -> Result<Self, PythonError> {
        let f = |name: &str| {
            ls.native
                .getattr(name)
                .map_err(|e| py_error(ls.py, format!("_libsumo.{name}"), e))
        };
        Ok(Self {
            req: req.clone(),
            fuel: f("vehicle_getFuelConsumption")?,
            co2: f("vehicle_getCO2Emission")?,
            time_loss: f("vehicle_getTimeLoss")?,
            loop_ids: match req.detector_file {
                Some(_) => Some(f("inductionloop_getLastStepVehicleIDs")?),
                None => None,
            },
            last_on_loop: Vec::new(),
            time_loss_at_warmup: 0.0,
            out: Measured {
                loop_passages: req.detector_file.as_ref().map(|_| 0),
                ..Measured::default()
            },
        })
    }

    fn sum(
        &self,
        py: Python<'py>,
        f: &Bound<'py, PyAny>,
        what: &str,
        args: &[Bound<'py, PyTuple>],
    ) -> Result<f64, PythonError> {
        let mut total = 0.0;
        for a in args {
            total += f
                .call1(a)
                .and_then(|r| r.extract::<f64>())
                .map_err(|e| py_error(py, what.to_string(), e))?;
        }
        Ok(total)
    }

    /// After SUMO step `s` (1-based: the state at t = s Δt); `v_prev`, `v` are the measured
    /// speeds before and after it.
    #[allow(clippy::too_many_arguments)]
    fn after_step(
        &mut self,
        py: Python<'py>,
        s: usize,
        dt: f64,
        args: &[Bound<'py, PyTuple>],
        v_prev: &[f64],
        v: &[f64],
        decel_mps2: f64,
    ) -> Result<(), PythonError> {
        let warm = self.req.warmup_steps;
        let k = self.req.emission_every.max(1);
        let measuring = s > warm;
        if s > 0 && s % k == 0 {
            let fuel = self.sum(py, &self.fuel, "vehicle.getFuelConsumption", args)?;
            self.out.fuel_total_mg += fuel * dt * k as f64;
            if measuring {
                self.out.fuel_mg += fuel * dt * k as f64;
                let co2 = self.sum(py, &self.co2, "vehicle.getCO2Emission", args)?;
                self.out.co2_mg += co2 * dt * k as f64;
            }
        }
        if s == warm {
            self.time_loss_at_warmup =
                self.sum(py, &self.time_loss, "vehicle.getTimeLoss", args)?;
        }
        if let Some(f) = &self.loop_ids {
            if s >= warm {
                let ids: Vec<String> = f
                    .call1(("loop0",))
                    .and_then(|r| r.extract())
                    .map_err(|e| py_error(py, "inductionloop.getLastStepVehicleIDs(loop0)", e))?;
                if measuring {
                    let new = ids
                        .iter()
                        .filter(|i| !self.last_on_loop.contains(i))
                        .count();
                    *self.out.loop_passages.get_or_insert(0) += new;
                }
                self.last_on_loop = ids;
            }
        }
        if measuring {
            self.out.steps += 1;
            // 1e-9 m/s² above decel: rounding of a braking exactly at decel does not count.
            self.out.hard_braking_steps += v_prev
                .iter()
                .zip(v)
                .filter(|(a, b)| (*a - *b) / dt > decel_mps2 + 1e-9)
                .count();
        }
        Ok(())
    }

    fn finish(
        mut self,
        py: Python<'py>,
        args: &[Bound<'py, PyTuple>],
    ) -> Result<Measured, PythonError> {
        let end = self.sum(py, &self.time_loss, "vehicle.getTimeLoss", args)?;
        self.out.time_loss_s = end - self.time_loss_at_warmup;
        Ok(self.out)
    }
}

/// Runs the request; every message goes to `out`. The returned error is also what the worker
/// reports as [`WorkerMsg::Failed`].
pub fn run(py: Python<'_>, req: &Request, out: &mut impl Write) -> Result<(), CosimError> {
    let pipe = |e: std::io::Error| CosimError::Pipe(e.to_string());
    // Build the law first: a scenario problem must not cost a SUMO start.
    let controller: Option<Box<dyn SpeedController>> = match &req.control {
        Control::Law { scenario, base_dir } => {
            let file: syncroad_control::ScenarioFile = serde_json::from_value(scenario.clone())
                .map_err(|e| CosimError::Scenario(e.to_string()))?;
            let sc = file
                .validate(base_dir)
                .map_err(|e| CosimError::Scenario(e.to_string()))?;
            Some(controller_for(&sc, req.layout.leader_vehicle)?)
        }
        Control::SumoModel | Control::Hold => None,
    };
    let (module, python) = load_libsumo(py)?;
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
    let ls = Libsumo::new(py, module)?;
    let args = sumo_args(req);
    if let Err(e) = ls.module.call_method1("start", (args.clone(),)) {
        return Err(CosimError::StartFailed {
            reason: crate::python::py_error(py, "libsumo.start", e).to_string(),
            log: req.log_file.display().to_string(),
            log_tail: tail(&req.log_file, 20),
        });
    }
    let result = run_started(py, &ls, req, controller, python, out);
    // Close SUMO whatever happened (the worker exits right after).
    let _ = ls.module.call_method0("close");
    result?;
    out.flush().map_err(pipe)
}

fn run_started(
    py: Python<'_>,
    ls: &Libsumo<'_>,
    req: &Request,
    mut controller: Option<Box<dyn SpeedController>>,
    python: crate::python::PythonInfo,
    out: &mut impl Write,
) -> Result<(), CosimError> {
    let pipe = |e: std::io::Error| CosimError::Pipe(e.to_string());
    let n = req.layout.vehicles.len();
    let dt = req.step_s;
    // Insertion happens in the first step; states after it are the initial conditions.
    ls.simulation_step()?;
    let pending: Vec<String> = ls
        .call("simulation_getPendingVehicles", ())?
        .extract()
        .map_err(|e| py_error(py, "simulation.getPendingVehicles", e))?;
    let on_road = ls.count(
        &ls.native
            .getattr("vehicle_getIDCount")
            .map_err(|e| py_error(py, "vehicle_getIDCount", e))?,
        "vehicle.getIDCount",
    )?;
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
    write_msg(
        out,
        &WorkerMsg::Started(StartInfo {
            python,
            road_length_m: road_length,
            vehicles: on_road,
            pid: std::process::id(),
        }),
    )
    .map_err(pipe)?;

    let ids: Vec<Bound<'_, PyString>> = req
        .layout
        .vehicles
        .iter()
        .map(|v| PyString::intern(py, &v.id))
        .collect();
    let controlled = controller.is_some();
    let all_law = req.layout.vehicles.iter().all(|v| v.driver.is_none());
    let hold = matches!(req.control, Control::Hold);
    if controlled || hold {
        for (id, dep) in ids.iter().zip(&req.layout.vehicles) {
            if dep.driver.is_some() {
                continue;
            }
            let mode = if hold { SPEED_MODE_RAW } else { req.speed_mode };
            ls.call("vehicle_setSpeedMode", (id.clone(), mode))?;
            ls.call("vehicle_setLaneChangeMode", (id.clone(), 0))?;
            if hold {
                ls.call("vehicle_setSpeed", (id.clone(), dep.speed_mps))?;
            }
        }
    }
    let reader = Reader::new(py, ls, req.read, &ids)?;
    // `(id, speed)` per vehicle, built once and refilled each step (see `set_item_f64`).
    let speed_args: Vec<Bound<'_, PyTuple>> = ids
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
    let mut v = vec![0.0; n];
    let mut dist = vec![0.0; n];
    let mut q = q0.clone();
    let mut cmd = vec![f64::NAN; n];
    let mut totals = Totals {
        direct_calls: reader.direct.is_some(),
        ..Totals::default()
    };
    let mut rows = RowChunk::new(n);
    let mut override_events = 0usize;
    let odometer_every = req.odometer_every.max(1);
    let lost = |i: usize| -> CosimError {
        CosimError::NotInserted {
            pending: 1,
            expected: n,
            ids: req.layout.vehicles[i].id.clone(),
            log: req.log_file.display().to_string(),
            log_tail: tail(&req.log_file, 20),
        }
    };

    let id_args: Vec<Bound<'_, PyTuple>> = ids
        .iter()
        .map(|id| PyTuple::new(py, [id]))
        .collect::<PyResult<_>>()
        .map_err(|e| py_error(py, "argument tuples", e))?;
    let decel = req.layout.vtype.decel_mps2;
    let mut meter = match &req.measure {
        Some(m) if req.observe => {
            let mut meter = Meter::new(ls, m)?;
            if m.warmup_steps == 0 {
                meter.after_step(py, 0, dt, &id_args, &[], &[], decel)?;
            }
            Some(meter)
        }
        _ => None,
    };
    let mut stop = StopReason::Horizon;
    if req.observe {
        if let Some(i) = reader.speeds(&mut v)? {
            return Err(lost(i));
        }
        if let Some(i) = reader.odometers(&mut dist)? {
            return Err(lost(i));
        }
        for i in 0..n {
            q[i] = q0[i] + dist[i];
        }
        rows.push(0.0, &v, &q, &cmd);
    }
    let mut next = vec![0.0; n];
    let mut v_prev = vec![0.0; n];
    let mut steps_done = 0usize;
    let mut phases = PhaseTimes::default();
    let mut last_flush = Instant::now();
    let mut timer = Instant::now();
    // Interleaved benchmark: wall time per kind of step, attributed at the next step's start.
    let mut last_kind: Option<(bool, Instant)> = None;
    'steps: for step in 0..req.steps {
        if step == req.untimed_steps {
            timer = Instant::now();
        }
        let bare = req.interleave_block > 0 && (step / req.interleave_block) % 2 == 0;
        if req.interleave_block > 0 {
            let now = Instant::now();
            if let Some((was_bare, t0)) = last_kind.take() {
                phases.add_interleaved(was_bare, (now - t0).as_secs_f64());
            }
            if step >= req.untimed_steps {
                last_kind = Some((bare, now));
            }
        }
        let t = step as f64 * dt;
        let t_law = Instant::now();
        if bare {
            ls.simulation_step()?;
            steps_done = step + 1;
            continue;
        }
        if let Some(c) = controller.as_deref_mut() {
            c.step(t, &v, &q, &mut next);
            match sanitize_commands(&mut next) {
                Ok(clamped) => totals.negative_commands_clamped += clamped,
                Err(i) => {
                    stop = StopReason::NonFiniteCommand {
                        vehicle: req.layout.vehicles[i].id.clone(),
                        step,
                        value: format!("{}", next[i]),
                    };
                    break 'steps;
                }
            }
            // The batch call sets every vehicle; with SUMO drivers on the road only the law's
            // vehicles are commanded, one call each.
            let direct = reader.direct.as_ref().filter(|_| all_law);
            if let Some(d) = direct {
                if let Err(e) = d.set_speeds(&next) {
                    return Err(PythonError::Call {
                        call: format!(
                            "libsumo::Vehicle::setSpeed({}, {}) (direct)",
                            ids[e.vehicle], next[e.vehicle]
                        ),
                        traceback: format!("C++ exception: {}", e.message),
                    }
                    .into());
                }
            } else {
                for (((id, args), x), _) in ids
                    .iter()
                    .zip(&speed_args)
                    .zip(&next)
                    .zip(&req.layout.vehicles)
                    .filter(|(_, dep)| dep.driver.is_none())
                {
                    set_item_f64(args, 1, *x)
                        .and_then(|()| ls.set_speed.call1(args))
                        .map_err(|e| py_error(py, format!("vehicle.setSpeed({id}, {x})"), e))?;
                }
            }
            if all_law {
                cmd.copy_from_slice(&next);
            } else {
                for ((c, x), dep) in cmd.iter_mut().zip(&next).zip(&req.layout.vehicles) {
                    // Rows carry NaN where SUMO's own model drives.
                    *c = if dep.driver.is_none() { *x } else { f64::NAN };
                }
            }
        }
        let t_step = Instant::now();
        ls.simulation_step()?;
        let t_stepped = Instant::now();
        steps_done = step + 1;
        let colliding = ls.count(&ls.colliding, "simulation.getCollidingVehiclesNumber")?;
        if colliding > 0 {
            totals.collision_steps += 1;
            totals.colliding_vehicles += colliding;
            write_msg(
                out,
                &WorkerMsg::Event(Event::Collision {
                    step: step + 1,
                    vehicles: colliding,
                }),
            )
            .map_err(pipe)?;
        }
        let teleports = ls.count(&ls.teleports, "simulation.getStartingTeleportNumber")?;
        if teleports > 0 {
            totals.teleports += teleports;
            write_msg(
                out,
                &WorkerMsg::Event(Event::Teleport {
                    step: step + 1,
                    count: teleports,
                }),
            )
            .map_err(pipe)?;
        }
        if step >= req.untimed_steps {
            phases.command_s += (t_step - t_law).as_secs_f64();
            phases.step_s += (t_stepped - t_step).as_secs_f64();
        }
        if !req.observe {
            continue;
        }
        v_prev.copy_from_slice(&v);
        let t_read = Instant::now();
        if let Some(i) = reader.speeds(&mut v)? {
            stop = StopReason::VehicleLost {
                vehicle: req.layout.vehicles[i].id.clone(),
                step: step + 1,
            };
            break;
        }
        if step >= req.untimed_steps {
            phases.read_speeds_s += t_read.elapsed().as_secs_f64();
        }
        // Positions advance by SUMO's own update rule; the odometer is read every
        // `odometer_every` steps (and at the end) and replaces the integrated value.
        for i in 0..n {
            q[i] += if req.ballistic {
                0.5 * dt * (v_prev[i] + v[i])
            } else {
                dt * v[i]
            };
        }
        let last = step + 1 == req.steps;
        if reader.subscribed || (step + 1) % odometer_every == 0 || last {
            if let Some(i) = reader.odometers(&mut dist)? {
                stop = StopReason::VehicleLost {
                    vehicle: req.layout.vehicles[i].id.clone(),
                    step: step + 1,
                };
                break;
            }
            for i in 0..n {
                let sumo_q = q0[i] + dist[i];
                let dev = (sumo_q - q[i]).abs();
                if dev > totals.odometer_deviation_max_m {
                    totals.odometer_deviation_max_m = dev;
                }
                q[i] = sumo_q;
            }
        }
        if let Some(m) = meter.as_mut() {
            m.after_step(py, step + 1, dt, &id_args, &v_prev, &v, decel)?;
        }
        if controlled {
            for i in (0..n).filter(|&i| req.layout.vehicles[i].driver.is_none()) {
                let d = (v[i] - cmd[i]).abs();
                if d > req.override_tolerance_mps {
                    totals.overrides += 1;
                    totals.max_override_mps = totals.max_override_mps.max(d);
                    if override_events < MAX_OVERRIDE_EVENTS {
                        override_events += 1;
                        write_msg(
                            out,
                            &WorkerMsg::Event(Event::Override {
                                step: step + 1,
                                vehicle: req.layout.vehicles[i].id.clone(),
                                commanded_mps: cmd[i],
                                realised_mps: v[i],
                            }),
                        )
                        .map_err(pipe)?;
                    }
                }
            }
        }
        if (step + 1) % req.record_every.max(1) == 0 || last {
            rows.push((step + 1) as f64 * dt, &v, &q, &cmd);
            // A chunk leaves when full or after FLUSH_INTERVAL, so a crash or Ctrl-C loses
            // at most that much of the run.
            if rows.len() >= req.chunk_records.max(1) || last_flush.elapsed() >= FLUSH_INTERVAL {
                write_rows(out, &mut rows).map_err(pipe)?;
                last_flush = Instant::now();
            }
        }
    }
    if let Some((was_bare, t0)) = last_kind {
        phases.add_interleaved(was_bare, t0.elapsed().as_secs_f64());
    }
    let loop_wall_s = timer.elapsed().as_secs_f64();
    let measured = match meter {
        Some(m) => Some(m.finish(py, &id_args)?),
        None => None,
    };
    write_rows(out, &mut rows).map_err(pipe)?;
    write_msg(
        out,
        &WorkerMsg::Finished(Finish {
            stop,
            steps_done,
            totals,
            loop_wall_s,
            timed_steps: steps_done.saturating_sub(req.untimed_steps),
            phases,
            measured,
        }),
    )
    .map_err(pipe)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn argument_tuples_are_refilled_only_when_unshared() {
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
        let e = CosimError::from(crate::controller::ControllerError::CaccNeedsLeader);
        assert_eq!(
            e.to_string(),
            "the CACC model needs a leader vehicle: run it on a straight road (road.type = \"straight\")"
        );
    }

    #[test]
    fn non_finite_commands_never_reach_sumo() {
        let mut c = [1.0, -0.5, f64::NAN, 2.0];
        assert_eq!(sanitize_commands(&mut c), Err(2));
        // Nothing was changed: the run stops with the command as the law produced it.
        assert_eq!(c[1], -0.5);
        let mut c = [1.0, f64::INFINITY];
        assert_eq!(sanitize_commands(&mut c), Err(1));
    }

    #[test]
    fn negative_commands_become_zero() {
        let mut c = [1.0, -0.5, -0.0, 2.0, -3.0];
        assert_eq!(sanitize_commands(&mut c), Ok(2));
        assert_eq!(c, [1.0, 0.0, -0.0, 2.0, 0.0]);
    }
}
