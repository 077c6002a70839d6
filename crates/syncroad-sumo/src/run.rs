//! One SUMO run of a validated scenario, seen from the parent: every check that can be made
//! before SUMO starts (network file, road shape, ring capacity, road length for the horizon),
//! the routes file, the supervised worker, and the results as a [`Trajectory`] comparable with
//! the native simulator's.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use syncroad_control::native::initial_positions;
use syncroad_control::scenario::{Model, RoadSpec, Scenario};
use syncroad_control::Trajectory;

use crate::drivers::{SumoDriver, MIXED_SPEED_MODE};
use crate::layout::{ring_layout, straight_layout, Layout, LayoutError, VehicleType};
use crate::net::{read_ring, read_straight, NetError, Road};
use crate::protocol::{Control, Event, Finish, Measure, ReadMode, Request, StopReason};
use crate::supervisor::{run_worker, Supervision, SupervisorError, WorkerCommand, WorkerRun};

/// Tolerance between commanded and realised speed before a command counts as overridden [m/s].
pub const OVERRIDE_TOLERANCE_MPS: f64 = 1e-6;

/// Steps between two reads of SUMO's odometer with [`ReadMode::Getters`].
pub const ODOMETER_EVERY: usize = 10;

/// Errors found before SUMO starts.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrepareError {
    /// The scenario names no network.
    #[error("sumo.net is not set; the sumo backend needs a network file, e.g. \"sumo\": {{\"net\": \"{example}\"}} (relative to the scenario file)")]
    NoNet {
        /// A shipped network that fits the road type.
        example: String,
    },
    /// The network file does not exist.
    #[error("sumo.net = {path}: file not found (checked before starting SUMO)")]
    NetNotFound {
        /// The resolved path.
        path: PathBuf,
    },
    /// The network file is unusable.
    #[error(transparent)]
    Net(#[from] NetError),
    /// The vehicles do not fit.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// A number SUMO cannot represent.
    #[error("{field} = {value}: {expected}")]
    Unrepresentable {
        /// Scenario field.
        field: &'static str,
        /// Its value.
        value: String,
        /// What SUMO accepts.
        expected: &'static str,
    },
    /// The per-vehicle drivers do not match the scenario.
    #[error("drivers: {got} given for {expected} vehicles; give one per scenario vehicle (leader excluded)")]
    Drivers {
        /// Scenario vehicles.
        expected: usize,
        /// Drivers given.
        got: usize,
    },
    /// A measurement option is out of range.
    #[error("{field} = {value}: {expected}")]
    Measure {
        /// Option.
        field: &'static str,
        /// Its value.
        value: String,
        /// What is valid.
        expected: &'static str,
    },
    /// The work folder cannot be written.
    #[error("cannot write {path}: {reason}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        reason: String,
    },
}

/// Options of a SUMO run.
#[derive(Clone)]
pub struct RunOptions {
    /// Folder for the routes file and SUMO's log.
    pub work_dir: PathBuf,
    /// How to start the worker.
    pub worker: WorkerCommand,
    /// Record every k-th step.
    pub record_every: usize,
    /// Ballistic position update (trapezoidal, as the native simulator); see
    /// [`crate::controller`].
    pub ballistic: bool,
    /// Drive with SUMO's own car-following model (Krauss, this σ) instead of the scenario's law.
    pub sumo_model_sigma: Option<f64>,
    /// Wall-clock limit; `None` takes `sumo.timeout_s` of the scenario.
    pub timeout: Option<Duration>,
    /// Ctrl-C flag.
    pub interrupt: Option<Arc<AtomicBool>>,
    /// How the loop reads states.
    pub read: ReadMode,
    /// Called when SUMO runs in the worker.
    pub on_start: Option<crate::supervisor::StartHook>,
    /// Per scenario vehicle (the leader excluded): `Some` lets that SUMO model drive it instead
    /// of the law. Empty: the law drives every vehicle. The leader always follows its profile.
    pub drivers: Vec<Option<SumoDriver>>,
    /// SUMO-side measurements (flow, time loss, fuel, CO2, hard braking).
    pub measure: Option<MeasureOptions>,
}

/// What to measure in SUMO during a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasureOptions {
    /// Warm-up before measuring \[s\] (rounded down to whole steps).
    pub warmup_s: f64,
    /// Read fuel and CO2 every this many steps (≥ 1).
    pub emission_every: usize,
    /// Also write SUMO's trip info with emission totals (`tripinfo.xml` in the work folder).
    pub tripinfo: bool,
}

/// Where the induction loop `loop0` sits on a ring: lane, position on it \[m\] and the ring
/// coordinate of that point \[m\] (10 m into the first normal lane, or its middle).
pub fn loop_position(road: &Road) -> Option<(String, f64, f64)> {
    if !road.ring {
        return None;
    }
    let mut offset = 0.0;
    for seg in &road.segments {
        if !seg.internal {
            let pos = (seg.length_m / 2.0).min(10.0);
            return Some((seg.lane.clone(), pos, offset + pos));
        }
        offset += seg.length_m;
    }
    None
}

impl RunOptions {
    /// Defaults: every step recorded, ballistic update, the scenario's law, its timeout.
    pub fn new(work_dir: impl Into<PathBuf>, worker: WorkerCommand) -> Self {
        Self {
            work_dir: work_dir.into(),
            worker,
            record_every: 1,
            ballistic: true,
            sumo_model_sigma: None,
            timeout: None,
            interrupt: None,
            read: ReadMode::Direct,
            on_start: None,
            drivers: Vec::new(),
            measure: None,
        }
    }
}

/// The network file of a scenario, resolved and checked to exist.
pub fn net_path(scenario: &Scenario) -> Result<PathBuf, PrepareError> {
    let Some(net) = &scenario.file.sumo.net else {
        return Err(PrepareError::NoNet {
            example: if scenario.is_ring() {
                "../sumo-nets/sugiyama-ring.net.xml".into()
            } else {
                "../sumo-nets/straight-20km.net.xml".into()
            },
        });
    };
    let p = if net.is_absolute() {
        net.clone()
    } else {
        scenario.base_dir.join(net)
    };
    if !p.is_file() {
        return Err(PrepareError::NetNotFound { path: p });
    }
    Ok(p)
}

/// Numbers SUMO itself restricts: its clock counts whole milliseconds and `--seed` is a
/// 32-bit signed integer.
pub fn check_sumo_numbers(scenario: &Scenario) -> Result<(), PrepareError> {
    let ms = scenario.step_s * 1000.0;
    if (ms - ms.round()).abs() > 1e-9 * ms.max(1.0) || ms.round() < 1.0 {
        return Err(PrepareError::Unrepresentable {
            field: "step_s",
            value: scenario.step_s.to_string(),
            expected: "SUMO's clock counts whole milliseconds: use a multiple of 0.001 s",
        });
    }
    if scenario.file.seed > i32::MAX as u64 {
        return Err(PrepareError::Unrepresentable {
            field: "seed",
            value: scenario.file.seed.to_string(),
            expected: "SUMO's --seed takes 0 ..= 2147483647",
        });
    }
    Ok(())
}

/// The layout of a scenario on its network (all pre-start checks).
pub fn layout_for(scenario: &Scenario, sigma: f64) -> Result<Layout, PrepareError> {
    let net = net_path(scenario)?;
    let s = &scenario.file.sumo;
    let vtype = VehicleType {
        min_gap_m: s.min_gap_m,
        accel_mps2: s.accel_mps2,
        decel_mps2: s.decel_mps2,
        emergency_decel_mps2: s.emergency_decel_mps2,
        max_speed_mps: s.max_speed_mps,
        sigma,
    };
    let horizon = scenario.horizon_s();
    let layout = match scenario.file.road {
        RoadSpec::Ring { .. } => {
            let road = read_ring(&net)?;
            ring_layout(
                &road,
                vtype,
                &scenario.length_m,
                &scenario.initial_gap_m,
                &scenario.initial_speed_mps,
                horizon,
            )?
        }
        RoadSpec::Straight { .. } => {
            let road = read_straight(&net)?;
            let dt = scenario.step_s;
            let travel = |f: &dyn Fn(f64) -> f64| -> f64 {
                (0..scenario.steps)
                    .map(|k| 0.5 * dt * (f(k as f64 * dt) + f((k + 1) as f64 * dt)))
                    .sum()
            };
            let (leader, v0) = match &scenario.model {
                Model::Cacc(m) => (
                    Some((0.0, scenario.length_m[0], travel(&|t| m.leader.speed_at(t)))),
                    m.leader.initial_speed(),
                ),
                Model::DelayedDriver(m) => match &m.leader {
                    Some((v0, _)) => {
                        let q0 = scenario.length_m[0] + scenario.initial_gap_m[0];
                        (Some((q0, scenario.length_m[0], travel(&|_| *v0))), *v0)
                    }
                    None => (None, 0.0),
                },
            };
            let q = initial_positions(scenario, leader.map(|l| l.0));
            straight_layout(
                &road,
                vtype,
                &scenario.length_m,
                &q,
                &scenario.initial_speed_mps,
                leader,
                v0,
                horizon,
            )?
        }
    };
    Ok(layout)
}

/// Builds the worker request of a scenario (writes the routes file into `opts.work_dir`).
pub fn prepare(scenario: &Scenario, opts: &RunOptions) -> Result<Request, PrepareError> {
    check_sumo_numbers(scenario)?;
    let layout = layout_for(scenario, opts.sumo_model_sigma.unwrap_or(0.0))?;
    let io = |path: &Path, e: std::io::Error| PrepareError::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let mut layout = layout;
    if !opts.drivers.is_empty() {
        let k0 = usize::from(layout.leader_vehicle);
        if opts.drivers.len() != layout.vehicles.len() - k0 {
            return Err(PrepareError::Drivers {
                expected: layout.vehicles.len() - k0,
                got: opts.drivers.len(),
            });
        }
        for (dep, d) in layout.vehicles[k0..].iter_mut().zip(&opts.drivers) {
            dep.driver = *d;
        }
    }
    let sumo_driven = layout
        .vehicles
        .iter()
        .filter(|v| v.driver.is_some())
        .count();
    let law_driven = layout.vehicles.len() - sumo_driven - usize::from(layout.leader_vehicle);
    let speed_mode = if sumo_driven > 0 && law_driven > 0 {
        MIXED_SPEED_MODE
    } else {
        32
    };
    let measure = match &opts.measure {
        None => None,
        Some(m) => {
            if !(m.warmup_s.is_finite() && m.warmup_s >= 0.0 && m.warmup_s < scenario.horizon_s()) {
                return Err(PrepareError::Measure {
                    field: "--warmup-s",
                    value: m.warmup_s.to_string(),
                    expected: "must be ≥ 0 and shorter than the horizon",
                });
            }
            if m.emission_every == 0 {
                return Err(PrepareError::Measure {
                    field: "--emission-every",
                    value: "0".into(),
                    expected: "must be ≥ 1 (1 = read fuel and CO2 every step)",
                });
            }
            std::fs::create_dir_all(&opts.work_dir).map_err(|e| io(&opts.work_dir, e))?;
            let detector_file = match loop_position(&layout.road) {
                Some((lane, pos, _)) => {
                    let f = opts.work_dir.join("detectors.add.xml");
                    // SUMO resolves `file` relative to the additional file itself.
                    let text = format!(
                        "<additional>\n    <inductionLoop id=\"loop0\" lane=\"{lane}\" pos=\"{pos}\" period=\"86400\" file=\"e1.xml\"/>\n</additional>\n"
                    );
                    std::fs::write(&f, text).map_err(|e| io(&f, e))?;
                    Some(f)
                }
                None => None,
            };
            Some(Measure {
                warmup_steps: (m.warmup_s / scenario.step_s + 1e-9).floor() as usize,
                emission_every: m.emission_every,
                detector_file,
                tripinfo_file: m.tripinfo.then(|| opts.work_dir.join("tripinfo.xml")),
            })
        }
    };
    let routes_file = layout
        .write_routes(&opts.work_dir)
        .map_err(|e| io(&opts.work_dir, e))?;
    let control = match opts.sumo_model_sigma {
        Some(_) => Control::SumoModel,
        None => Control::Law {
            scenario: serde_json::to_value(&scenario.file).expect("a scenario serialises"),
            base_dir: scenario.base_dir.clone(),
        },
    };
    Ok(Request {
        layout,
        routes_file,
        log_file: opts.work_dir.join("sumo.log"),
        step_s: scenario.step_s,
        steps: scenario.steps,
        seed: scenario.file.seed,
        ballistic: opts.ballistic,
        control,
        observe: true,
        speed_mode,
        measure,
        record_every: opts.record_every.max(1),
        chunk_records: chunk_records(scenario.n),
        override_tolerance_mps: OVERRIDE_TOLERANCE_MPS,
        untimed_steps: 0,
        read: opts.read,
        odometer_every: ODOMETER_EVERY,
        interleave_block: 0,
    })
}

/// Records per chunk: about 256 KiB of rows, at least one record.
pub fn chunk_records(n: usize) -> usize {
    ((256 * 1024) / (8 * (1 + 3 * (n + 1)))).max(1)
}

/// The result of a SUMO run: every row received, and how the run ended.
#[derive(Debug, Clone)]
pub struct SumoRun {
    /// The request that was run.
    pub request: Request,
    /// What the worker produced.
    pub worker: WorkerRun,
}

/// The end of a run in one error type: supervision failures and stops of the loop.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RunError {
    /// The worker failed, crashed, timed out or was interrupted.
    #[error(transparent)]
    Supervisor(#[from] SupervisorError),
    /// The law produced a non-finite speed.
    #[error("the law commanded a non-finite speed ({value} m/s) to vehicle {vehicle} at step {step}; the run stopped before sending it to SUMO")]
    NonFiniteCommand {
        /// SUMO vehicle id.
        vehicle: String,
        /// Step.
        step: usize,
        /// The value.
        value: String,
    },
    /// A vehicle left the road.
    #[error("vehicle {vehicle} left the road at step {step} (end of the straight road?)")]
    VehicleLost {
        /// SUMO vehicle id.
        vehicle: String,
        /// Step.
        step: usize,
    },
}

impl RunError {
    /// Process exit code the CLI should use, when it is a special one (130 for Ctrl-C).
    pub fn exit_code(&self) -> Option<u8> {
        match self {
            RunError::Supervisor(s) => s.exit_code(),
            _ => None,
        }
    }
}

/// Runs a scenario in SUMO: pre-start checks (errors here mean SUMO never started), then one
/// supervised worker. Rows are in the result whatever the end of the run.
pub fn run_scenario(scenario: &Scenario, opts: &RunOptions) -> Result<SumoRun, PrepareError> {
    let request = prepare(scenario, opts)?;
    let timeout = opts
        .timeout
        .or_else(|| Duration::try_from_secs_f64(scenario.file.sumo.timeout_s).ok());
    let worker = run_worker(
        &opts.worker,
        &request,
        &Supervision {
            timeout,
            interrupt: opts.interrupt.clone(),
            on_start: opts.on_start.clone(),
        },
    );
    Ok(SumoRun { request, worker })
}

/// Summary written next to the trajectory.
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary<'a> {
    /// False when the run did not reach its end (crash, timeout, Ctrl-C, stop of the loop).
    pub complete: bool,
    /// The error, if any.
    pub error: Option<String>,
    /// The worker's end-of-run report.
    pub finish: Option<&'a Finish>,
    /// Samples written.
    pub samples: usize,
    /// SUMO's road length \[m\] (`lane.getLength`, normal plus internal lanes).
    pub road_length_m: Option<f64>,
    /// Gap scale applied on a ring.
    pub gap_scale: f64,
    /// Python / libsumo / SUMO versions.
    pub python: Option<&'a crate::python::PythonInfo>,
    /// Events.
    pub events: &'a [Event],
}

impl SumoRun {
    /// How the run ended: `Ok` only when the horizon was reached.
    pub fn outcome(&self) -> Result<&Finish, RunError> {
        match &self.worker.result {
            Err(e) => Err(RunError::Supervisor(e.clone())),
            Ok(f) => match &f.stop {
                StopReason::Horizon => Ok(f),
                StopReason::NonFiniteCommand {
                    vehicle,
                    step,
                    value,
                } => Err(RunError::NonFiniteCommand {
                    vehicle: vehicle.clone(),
                    step: *step,
                    value: value.clone(),
                }),
                StopReason::VehicleLost { vehicle, step } => Err(RunError::VehicleLost {
                    vehicle: vehicle.clone(),
                    step: *step,
                }),
            },
        }
    }

    /// SUMO's road length, or the parsed one if SUMO never started.
    pub fn road_length_m(&self) -> f64 {
        self.worker
            .start
            .as_ref()
            .map(|s| s.road_length_m)
            .unwrap_or_else(|| self.request.layout.road.length_m())
    }

    /// The controlled vehicles' samples (the leader vehicle, if any, becomes the reference
    /// speed), with bumper-to-bumper gaps as the native simulator computes them.
    pub fn trajectory(&self, scenario: &Scenario) -> Trajectory {
        let rows = &self.worker.rows;
        let all = rows.n;
        let k0 = usize::from(self.request.layout.leader_vehicle);
        let n = all - k0;
        let lengths: Vec<f64> = self
            .request
            .layout
            .vehicles
            .iter()
            .map(|v| v.length_m)
            .collect();
        let ring = self.request.layout.road.ring.then(|| self.road_length_m());
        let mut t = Trajectory::new(n);
        let mut gaps = vec![0.0; n];
        for k in 0..rows.len() {
            let q = &rows.positions_m[k * all..(k + 1) * all];
            let v = &rows.speeds_mps[k * all..(k + 1) * all];
            for i in 0..n {
                let j = k0 + i;
                gaps[i] = if i > 0 || k0 == 1 {
                    q[j - 1] - q[j] - lengths[j]
                } else if let Some(c) = ring {
                    q[all - 1] + c - q[j] - lengths[j]
                } else {
                    f64::NAN
                };
            }
            let time = rows.time_s[k];
            t.push(
                time,
                &v[k0..],
                &q[k0..],
                &gaps,
                scenario.leader_speed_at(time),
            );
        }
        t
    }

    /// Writes `trajectory.csv` (all rows received) and `sumo-run.json` (complete flag, error,
    /// counters, events) into `dir`.
    pub fn write_outputs(&self, scenario: &Scenario, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        let traj = self.trajectory(scenario);
        let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join("trajectory.csv"))?);
        traj.write_csv(&mut f)?;
        let outcome = self.outcome();
        let summary = RunSummary {
            complete: outcome.is_ok(),
            error: outcome.as_ref().err().map(|e| e.to_string()),
            finish: self.worker.result.as_ref().ok(),
            samples: traj.len(),
            road_length_m: self.worker.start.as_ref().map(|s| s.road_length_m),
            gap_scale: self.request.layout.gap_scale,
            python: self.worker.start.as_ref().map(|s| &s.python),
            events: &self.worker.events,
        };
        let text = serde_json::to_string_pretty(&summary).map_err(std::io::Error::other)?;
        std::fs::write(dir.join("sumo-run.json"), text + "\n")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stop_errors_name_vehicle_and_step() {
        let e = RunError::NonFiniteCommand {
            vehicle: "v3".into(),
            step: 41,
            value: "NaN".into(),
        };
        assert_eq!(
            e.to_string(),
            "the law commanded a non-finite speed (NaN m/s) to vehicle v3 at step 41; the run stopped before sending it to SUMO"
        );
        assert_eq!(e.exit_code(), None);
        let e = PrepareError::NoNet {
            example: "../sumo-nets/sugiyama-ring.net.xml".into(),
        };
        assert!(e
            .to_string()
            .starts_with("sumo.net is not set; the sumo backend needs a network file"));
    }
}
