//! The loop's SUMO-side measurements after the warm-up: induction-loop passages, time loss,
//! fuel and CO2, hard braking (an observer of the step loop).

use pyo3::prelude::*;
use pyo3::types::PyTuple;
use syncroad_control::record::Measured;

use super::libsumo::Libsumo;
use crate::direct::Direct;
use crate::protocol::Measure;
use crate::python::{py_error, PythonError};

/// The loop's SUMO-side measurements (see [`Measured`]).
pub(super) struct Meter<'py> {
    req: Measure,
    fuel: Bound<'py, PyAny>,
    co2: Bound<'py, PyAny>,
    time_loss: Bound<'py, PyAny>,
    loop_ids: Option<Bound<'py, PyAny>>,
    last_on_loop: Vec<String>,
    time_loss_at_warmup: f64,
    out: Measured,
    /// One value per vehicle, for the batch reads.
    values: Vec<f64>,
}

/// Which emission a batch read asks for.
#[derive(Clone, Copy)]
enum Emission {
    Fuel,
    Co2,
}

impl<'py> Meter<'py> {
    pub(super) fn new(ls: &Libsumo<'py>, req: &Measure) -> Result<Self, PythonError> {
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
            values: Vec::new(),
            out: Measured {
                loop_passages: req.detector_file.as_ref().map(|_| 0),
                fuel_mg: req.emissions.fuel.then_some(0.0),
                fuel_total_mg: req.emissions.fuel_total.then_some(0.0),
                co2_mg: req.emissions.co2.then_some(0.0),
                ..Measured::default()
            },
        })
    }

    /// Measuring starts with the state after insertion (no warm-up).
    pub(super) fn warm_at_start(&self) -> bool {
        self.req.warmup_steps == 0
    }

    /// The interpreter the meter calls into.
    pub(super) fn py(&self) -> Python<'py> {
        self.fuel.py()
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

    /// The emission summed over the vehicles (in their order, from 0, as [`Meter::sum`] adds
    /// Python's answers: the same total bit for bit): one batch call into libsumo's C++
    /// functions where `direct` has them (the emission model runs every step, and a Python
    /// call per vehicle and value cost as much again), else a Python call per vehicle.
    fn emission(
        &mut self,
        py: Python<'py>,
        which: Emission,
        direct: Option<&Direct>,
        args: &[Bound<'py, PyTuple>],
    ) -> Result<f64, PythonError> {
        let (f, name) = match which {
            Emission::Fuel => (&self.fuel, "getFuelConsumption"),
            Emission::Co2 => (&self.co2, "getCO2Emission"),
        };
        if let Some(d) = direct {
            self.values.resize(args.len(), 0.0);
            let read = match which {
                Emission::Fuel => d.fuel(&mut self.values),
                Emission::Co2 => d.co2(&mut self.values),
            };
            if let Some(read) = read {
                read.map_err(|e| PythonError::Call {
                    call: format!(
                        "libsumo::Vehicle::{name}({}) (direct)",
                        args[e.vehicle]
                            .get_item(0)
                            .map(|id| id.to_string())
                            .unwrap_or_default()
                    ),
                    traceback: format!("C++ exception: {}", e.message),
                })?;
                return Ok(self.values.iter().fold(0.0, |t, x| t + x));
            }
        }
        self.sum(py, f, &format!("vehicle.{name}"), args)
    }

    /// After SUMO step `s` (1-based: the state at t = s Δt); `v_prev`, `v` are the measured
    /// speeds before and after it; `direct` reads the emissions in one batch where present.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn after_step(
        &mut self,
        py: Python<'py>,
        s: usize,
        dt: f64,
        args: &[Bound<'py, PyTuple>],
        direct: Option<&Direct>,
        v_prev: &[f64],
        v: &[f64],
        decel_mps2: f64,
    ) -> Result<(), PythonError> {
        let warm = self.req.warmup_steps;
        let k = self.req.emission_every.max(1);
        let measuring = s > warm;
        // Only the sums asked for run the emission model (see `Emissions`).
        if s > 0 && s.is_multiple_of(k) {
            let held = dt * k as f64;
            let fuel_after = self.out.fuel_mg.is_some() && measuring;
            if self.out.fuel_total_mg.is_some() || fuel_after {
                let fuel = self.emission(py, Emission::Fuel, direct, args)?;
                if let Some(total) = &mut self.out.fuel_total_mg {
                    *total += fuel * held;
                }
                if let Some(after) = self.out.fuel_mg.as_mut().filter(|_| measuring) {
                    *after += fuel * held;
                }
            }
            if self.out.co2_mg.is_some() && measuring {
                let co2 = self.emission(py, Emission::Co2, direct, args)?;
                if let Some(c) = &mut self.out.co2_mg {
                    *c += co2 * held;
                }
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

    pub(super) fn finish(
        mut self,
        py: Python<'py>,
        args: &[Bound<'py, PyTuple>],
    ) -> Result<Measured, PythonError> {
        let end = self.sum(py, &self.time_loss, "vehicle.getTimeLoss", args)?;
        self.out.time_loss_s = end - self.time_loss_at_warmup;
        Ok(self.out)
    }
}
