//! libsumo as the loop calls it: handles to the SWIG entry points, how vehicle states are read
//! each step ([`Reader`]), SUMO's command line, and the command checks.

use std::path::Path;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyInt, PyString, PyTuple};

use crate::direct::{Direct, DirectError};
use crate::protocol::{ReadMode, Request};
use crate::python::{py_error, PythonError};

/// libsumo variable ids (traci constants) read through subscriptions.
const VAR_SPEED: i32 = 0x40;
const VAR_DISTANCE: i32 = 0x84;

pub(crate) fn tail(path: &Path, lines: usize) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let all: Vec<&str> = text.lines().collect();
    all[all.len().saturating_sub(lines)..].join("\n")
}

/// Handles to the libsumo functions the loop calls (the SWIG entry points of `_libsumo`, which
/// skip one Python wrapper layer per call).
pub(crate) struct Libsumo<'py> {
    pub(crate) py: Python<'py>,
    /// libsumo's compiled module (`libsumo._libsumo`).
    pub(crate) native: Bound<'py, PyModule>,
    pub(crate) step: Bound<'py, PyAny>,
    pub(crate) set_speed: Bound<'py, PyAny>,
    pub(crate) all_subscriptions: Bound<'py, PyAny>,
    pub(crate) colliding: Bound<'py, PyAny>,
    pub(crate) teleports: Bound<'py, PyAny>,
}

impl<'py> Libsumo<'py> {
    pub(crate) fn new(py: Python<'py>, native: Bound<'py, PyModule>) -> Result<Self, PythonError> {
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
            native,
        })
    }

    pub(crate) fn call(
        &self,
        name: &str,
        args: impl pyo3::call::PyCallArgs<'py>,
    ) -> Result<Bound<'py, PyAny>, PythonError> {
        self.native
            .call_method1(name, args)
            .map_err(|e| py_error(self.py, format!("_libsumo.{name}"), e))
    }

    pub(crate) fn simulation_step(&self) -> Result<(), PythonError> {
        self.step
            .call1((0.0,))
            .map(|_| ())
            .map_err(|e| py_error(self.py, "simulation.step", e))
    }

    pub(crate) fn count(&self, f: &Bound<'py, PyAny>, what: &str) -> Result<usize, PythonError> {
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
pub(crate) fn set_item_f64(tuple: &Bound<'_, PyTuple>, i: isize, x: f64) -> PyResult<()> {
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
/// (nothing is sent), else negatives are set to 0 and their number returned. Only the vehicles
/// the law drives (`law_driven[i]`) count: the law's output for a vehicle SUMO drives is never
/// sent, so it can neither stop the run nor count as clamped.
pub fn sanitize_commands(next: &mut [f64], law_driven: &[bool]) -> Result<usize, usize> {
    debug_assert_eq!(next.len(), law_driven.len());
    if let Some(i) = (0..next.len()).find(|&i| law_driven[i] && !next[i].is_finite()) {
        return Err(i);
    }
    let mut clamped = 0;
    for (x, _) in next
        .iter_mut()
        .zip(law_driven)
        .filter(|(x, &law)| law && **x < 0.0)
    {
        *x = 0.0;
        clamped += 1;
    }
    Ok(clamped)
}

/// How vehicle states are read each step.
pub(crate) struct Reader<'a, 'py> {
    py: Python<'py>,
    ls: &'a Libsumo<'py>,
    ids: &'a [Bound<'py, PyString>],
    /// Subscriptions (speed and odometer every step) instead of direct getters.
    pub(crate) subscribed: bool,
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
    pub(crate) direct: Option<Direct>,
}

impl<'a, 'py> Reader<'a, 'py> {
    pub(crate) fn new(
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
        Ok(self.ids.iter().position(|id| {
            !present
                .iter()
                .any(|p| id.to_cow().is_ok_and(|s| s == p.as_str()))
        }))
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
    pub(crate) fn speeds(&self, v: &mut [f64]) -> Result<Option<usize>, PythonError> {
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
    pub(crate) fn odometers(&self, d: &mut [f64]) -> Result<Option<usize>, PythonError> {
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
        std::iter::once(&req.routes_file)
            .chain(&req.extra_routes)
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(","),
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
    let detector = req.measure.as_ref().and_then(|m| m.detector_file.as_ref());
    let additional: Vec<String> = req
        .extra_additional
        .iter()
        .chain(detector)
        .map(|p| p.display().to_string())
        .collect();
    if !additional.is_empty() {
        a.push("--additional-files".into());
        a.push(additional.join(","));
    }
    if let Some(f) = &req.fcd_file {
        a.push("--fcd-output".into());
        a.push(f.display().to_string());
        if req.fcd_every > 1 {
            a.push("--device.fcd.period".into());
            a.push(format!("{}", req.step_s * req.fcd_every as f64));
        }
    }
    if let Some(f) = &req.summary_file {
        a.extend(crate::summary::summary_args(
            f,
            req.step_s,
            req.record_every,
        ));
    }
    if let Some(m) = &req.measure {
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
        if let Some(f) = &m.ssm_file {
            a.extend(crate::ssm::ssm_args(f));
        }
    }
    a
}
