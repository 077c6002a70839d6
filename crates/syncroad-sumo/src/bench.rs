//! The SUMO benchmark: in one command, for a ring of N vehicles,
//! * **SUMO alone** — a worker that only calls `simulation.step`: the same vehicles in speed
//!   mode 32, each commanded once to hold its speed, so SUMO's own work per step is the same
//!   as under the law, and no per-step calls;
//! * **SUMO + controller** — the real co-simulation loop: every vehicle's speed read
//!   (`getSpeed`, odometer every 10 steps), the delayed-driver law (eq. `chandler+`) in Rust,
//!   one `setSpeed` per vehicle, rows recorded and streamed every step, the per-vehicle calls
//!   going straight to libsumo's C++ functions ([`crate::direct`]); and the same loop with
//!   every per-vehicle call through the Python module;
//! * **TraCI reference** — `python-host/traci_reference.py`, run twice: reading every vehicle
//!   through one subscription result per step (as Flow does: the fair anchor) and with one
//!   getter call per value (a naive loop); both ratios are printed. It is the traci socket
//!   client driving a `sumo` subprocess with the same reads and writes.
//!
//! Each measurement is its own process (one SUMO per process); alone and controlled are
//! alternated `repeats` times and the fastest of each is kept. The overhead is
//! `controlled / alone − 1`. Because runs in separate processes see different load from other
//! work on the machine, the controlled runs also time `simulation.step` itself: the in-run
//! overhead (time outside SUMO's step over time inside it, same process, same seconds) is the
//! steadier figure.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Serialize;
use syncroad_control::Scenario;

use crate::prepare::{load_road, prepare, PrepareError, RunOptions};
use crate::probe::{Probe, ProbeMode, ProbeTimes};
use crate::protocol::{Finish, JobRef, ReadMode, Request};
use crate::supervisor::{run_worker_job, Supervision, SupervisorError, WorkerCommand};
use crate::venv::{find_venv, VenvError};

/// Errors of the benchmark.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BenchError {
    /// The generated scenario did not validate (a bug in the case definition).
    #[error("benchmark scenario for {name}: {reason}")]
    Scenario {
        /// Case name.
        name: String,
        /// Validation error.
        reason: String,
    },
    /// Pre-start checks failed.
    #[error(transparent)]
    Prepare(#[from] PrepareError),
    /// A worker failed.
    #[error(transparent)]
    Worker(#[from] SupervisorError),
    /// The run stopped early.
    #[error("benchmark run {name} stopped early: {reason}")]
    Stopped {
        /// Case name.
        name: String,
        /// Why.
        reason: String,
    },
    /// The venv is missing.
    #[error(transparent)]
    Venv(#[from] VenvError),
    /// The TraCI reference failed.
    #[error("TraCI reference failed: {0}")]
    Traci(String),
    /// The benchmark's temporary folder could not be made.
    #[error("a temporary folder for the benchmark's runs: {0}")]
    TempDir(String),
    /// `--case` names no standard case.
    #[error("--case {case:?}: no benchmark case starts with it; the cases are {valid}")]
    UnknownCase {
        /// What was asked for.
        case: String,
        /// The case names.
        valid: String,
    },
}

/// One benchmark case.
#[derive(Debug, Clone)]
pub struct BenchCase {
    /// Name in the report.
    pub name: String,
    /// Ring network.
    pub net: PathBuf,
    /// Vehicles.
    pub vehicles: usize,
    /// Nominal ring length used for the initial gaps \[m\].
    pub nominal_length_m: f64,
    /// Timed steps.
    pub steps: usize,
    /// Untimed warm-up steps before them.
    pub warmup: usize,
    /// Alternations of alone / controlled.
    pub repeats: usize,
    /// Also run the TraCI reference.
    pub traci: bool,
    /// Also run the TraCI reference with per-call reads (slow: three round trips per vehicle
    /// and step).
    pub traci_per_call: bool,
    /// Also run the TraCI reference with your own Python controller (as Flow runs one).
    pub traci_python: bool,
    /// Timed steps of the TraCI references (after the same warm-up). A TraCI loop makes the
    /// same round trips every step, so its per-step time settles within a few hundred steps;
    /// the quick form times 250 of them at N = 22 (a sixteenth of its 4 000 steps).
    pub traci_steps: usize,
}

/// Timings of one case [ms per step].
#[derive(Debug, Clone, Serialize)]
pub struct BenchResult {
    /// Case name.
    pub name: String,
    /// Vehicles.
    pub vehicles: usize,
    /// Timed steps per run.
    pub steps: usize,
    /// Best SUMO-alone time.
    pub alone_ms: f64,
    /// Best SUMO + controller time.
    pub controlled_ms: f64,
    /// All alone samples.
    pub alone_samples_ms: Vec<f64>,
    /// All controlled samples.
    pub controlled_samples_ms: Vec<f64>,
    /// `controlled / alone − 1` [%], best run against best run.
    pub overhead_pct: f64,
    /// Median over the controlled runs of (loop time outside `simulation.step`) / (time in
    /// it) [%]: both from the same run, so other load on the machine cancels out.
    pub in_run_overhead_pct: f64,
    /// Best SUMO + controller time with the per-vehicle calls through Python.
    pub python_getters_ms: f64,
    /// All samples of that.
    pub python_getters_samples_ms: Vec<f64>,
    /// Its overhead over SUMO alone [%].
    pub python_getters_overhead_pct: f64,
    /// Same-process overhead: one run alternating blocks of SUMO alone and the full loop
    /// (median over the repeats) [%]. Free of the process-to-process variance of SUMO itself.
    pub interleaved_overhead_pct: f64,
    /// The per-repeat values of that.
    pub interleaved_samples_pct: Vec<f64>,
    /// Median over the interleaved runs of the full steps' time outside `simulation.step` over
    /// the time inside it [%], with no phase or observer timers: the clocks of an ordinary run
    /// only (the profiled runs read seven more clocks per step, a visible share on small rings).
    pub in_run_untimed_pct: f64,
    /// Median over runs of the full loop with an ordinary run's clocks only (no interleaving,
    /// no clock per step beyond the two around SUMO's step) of the time outside
    /// `simulation.step` over the time inside it [%]: the loop's cost as a user's run pays it.
    #[serde(default)]
    pub in_run_plain_pct: f64,
    /// The floor: libsumo's own read and command calls (the profile's law + `setSpeed` and
    /// reads) over `simulation.step` [%], median over the repeats' profiled runs.
    pub floor_pct: f64,
    /// That floor in each repeat [%].
    #[serde(default)]
    pub floor_samples_pct: Vec<f64>,
    /// The loop's cost in the plain run over the floor of the same repeat's profiled run,
    /// median over the repeats (runs next to each other in time share this machine's speed
    /// of the moment).
    #[serde(default)]
    pub plain_over_floor: f64,
    /// The same with the interleaved runs' cost.
    #[serde(default)]
    pub interleaved_over_floor: f64,
    /// TraCI reference time, every read through one subscription result per step (as Flow
    /// reads its vehicles).
    pub traci_ms: Option<f64>,
    /// `traci / controlled`.
    pub speedup_vs_traci: Option<f64>,
    /// TraCI reference time with one getter call per value (three per vehicle and step).
    pub traci_per_call_ms: Option<f64>,
    /// `traci_per_call / controlled`.
    pub speedup_vs_traci_per_call: Option<f64>,
    /// Where a step of the fastest controlled run went, by phase and observer of the loop
    /// [ms/step]: `simulation.step`, the law with its commands, the reads, each observer, and
    /// the rest of the loop (the timer's own reads of the clock among it).
    pub profile_ms: Vec<(String, f64)>,
    /// Best SUMO + the same law as a Python controller in the worker
    /// (`python-host/bench_controller.py`, numpy, one call per step) [ms/step].
    pub python_controller_ms: f64,
    /// All samples of that.
    pub python_controller_samples_ms: Vec<f64>,
    /// Its overhead over SUMO alone [%], best run against best run.
    pub python_controller_overhead_pct: f64,
    /// Where a step of the fastest Python-controller run went [ms/step] (the law's phase is
    /// the call into Python with its packing and checks, and `setSpeed`).
    pub python_profile_ms: Vec<(String, f64)>,
    /// The TraCI reference loop calling the same Python controller each step, reading through
    /// subscriptions as Flow does [ms/step].
    pub traci_python_ms: Option<f64>,
    /// `traci_python / python_controller`.
    pub python_speedup_vs_traci: Option<f64>,
}

/// All vehicles start evenly spaced at 10 m/s, so the law's commands stay at 10 m/s and the
/// baseline's held speeds and the controlled run drive exactly the same traffic.
///
/// The two standard cases: the Sugiyama ring (N = 22) and the 20 km ring (N = 2000).
///
/// The quick form is a smoke test of the benchmark (the guide's test runs it): every kind of
/// run once, a fifth of the steps, 250 TraCI steps at N = 22 and 5 at N = 2000, and at N = 2000
/// one TraCI loop (subscriptions): no per-call loop (about a minute even for 15 steps) and no
/// Python-controller loop (the one at N = 22 runs the same code; at N = 2000 its start alone,
/// 2000 vehicles set up call by call, took a fifth of the quick form). Its figures are not the
/// benchmark's: quote the full form.
pub fn standard_cases(nets: &Path, quick: bool) -> Vec<BenchCase> {
    let s = if quick { 5 } else { 1 };
    vec![
        BenchCase {
            name: "sugiyama-ring N=22".into(),
            net: nets.join("sugiyama-ring.net.xml"),
            vehicles: 22,
            nominal_length_m: 230.0,
            steps: 20_000 / s,
            warmup: 500 / s,
            repeats: if quick { 1 } else { 5 },
            traci: true,
            traci_per_call: true,
            traci_python: true,
            traci_steps: if quick { 250 } else { 20_000 },
        },
        BenchCase {
            name: "ring-20km N=2000".into(),
            net: nets.join("ring-20km.net.xml"),
            vehicles: 2000,
            nominal_length_m: 20_000.0,
            steps: 300 / s,
            warmup: 30 / s,
            repeats: if quick { 1 } else { 3 },
            traci: true,
            // About a minute even in the quick form: the quick form skips it here.
            traci_per_call: !quick,
            // Its start alone (2000 vehicles set up call by call) takes seconds; the quick
            // form runs it at N = 22.
            traci_python: !quick,
            traci_steps: if quick { 5 } else { 300 },
        },
    ]
}

fn scenario(case: &BenchCase) -> Result<Scenario, BenchError> {
    let json = format!(
        r#"{{"name": "bench", "backend": "sumo", "seed": 1, "step_s": 0.1,
        "horizon_s": {}, "vehicles": {},
        "road": {{"type": "ring", "length_m": {}}},
        "model": {{"type": "delayed_driver",
                   "graph": {{"type": "unidirectional_ring", "gain": 0.5}}, "delay_s": 0.5}},
        "initial": {{"speed_mps": 10.0}},
        "sumo": {{"net": "{}"}}}}"#,
        (case.steps + case.warmup) as f64 * 0.1,
        case.vehicles,
        case.nominal_length_m,
        case.net.display()
    );
    Scenario::from_json(&json).map_err(|e| BenchError::Scenario {
        name: case.name.clone(),
        reason: e.to_string(),
    })
}

/// Runs a benchmark job in a worker; it must reach its last step.
fn run_to_end(
    worker: &WorkerCommand,
    req: &Request,
    probe: Probe,
    work: &Path,
) -> Result<(Finish, ProbeTimes), BenchError> {
    let job = JobRef::Bench {
        request: req,
        probe,
    };
    let mut fin = run_worker_job(worker, job, &Supervision::default()).result?;
    if fin.steps_done != req.steps {
        return Err(BenchError::Stopped {
            name: work.display().to_string(),
            reason: format!("{:?}", fin.stop),
        });
    }
    let times = fin.probe.take().unwrap_or_default();
    Ok((fin, times))
}

/// One run of the case: SUMO alone (`read` = None) or the full loop reading by `read`.
fn timed(
    worker: &WorkerCommand,
    sc: &Scenario,
    work: &Path,
    read: Option<ReadMode>,
    warmup: usize,
) -> Result<Timing, BenchError> {
    let mut opts = RunOptions::new(work, worker.clone());
    if let Some(r) = read {
        opts.read = r;
    }
    let req = prepare(sc, &load_road(sc)?, &opts)?;
    let probe = Probe {
        mode: match read {
            Some(_) => ProbeMode::Loop,
            None => ProbeMode::Alone,
        },
        untimed_steps: warmup,
    };
    let (_, t) = run_to_end(worker, &req, probe, work)?;
    let per = |x: f64| 1e3 * x / t.timed_steps as f64;
    let p = &t.phases;
    let outside_sumo = t.loop_wall_s - p.step_s;
    let mut profile = vec![
        ("simulation.step".to_string(), per(p.step_s)),
        ("law + setSpeed".to_string(), per(p.command_s)),
        ("read speeds + odometers".to_string(), per(p.read_speeds_s)),
    ];
    profile.extend(p.observers.iter().map(|(n, s)| (n.clone(), per(*s))));
    let accounted = p.command_s + p.read_speeds_s + p.observers_s();
    profile.push((
        "rest of the loop".to_string(),
        per(outside_sumo - accounted),
    ));
    Ok(Timing {
        ms_per_step: per(t.loop_wall_s),
        in_run_overhead_pct: 100.0 * outside_sumo / p.step_s,
        profile,
    })
}

/// Steps per block of the interleaved run.
const INTERLEAVE_BLOCK: usize = 25;

/// One run alternating blocks of SUMO alone and the full controller loop in the same process:
/// `controlled / bare − 1` [%] of the mean wall time per step, and the full steps' time outside
/// `simulation.step` over the time inside it [%].
fn interleaved(
    worker: &WorkerCommand,
    sc: &Scenario,
    work: &Path,
    warmup: usize,
) -> Result<(f64, f64), BenchError> {
    let opts = RunOptions::new(work, worker.clone());
    let req = prepare(sc, &load_road(sc)?, &opts)?;
    let probe = Probe {
        mode: ProbeMode::Interleaved {
            block: INTERLEAVE_BLOCK,
        },
        untimed_steps: warmup,
    };
    let (_, t) = run_to_end(worker, &req, probe, work)?;
    let p = &t.phases;
    let bare = p.bare_wall_s / p.bare_steps.max(1) as f64;
    let controlled = p.controlled_wall_s / p.controlled_steps.max(1) as f64;
    let in_run = 100.0 * (p.controlled_wall_s - p.step_s) / p.step_s;
    Ok((100.0 * (controlled / bare - 1.0), in_run))
}

/// One run of the full loop with an ordinary run's clocks only ([`ProbeMode::Plain`]): its
/// time outside `simulation.step` over the time inside it [%].
fn plain(
    worker: &WorkerCommand,
    sc: &Scenario,
    work: &Path,
    warmup: usize,
) -> Result<f64, BenchError> {
    let opts = RunOptions::new(work, worker.clone());
    let req = prepare(sc, &load_road(sc)?, &opts)?;
    let probe = Probe {
        mode: ProbeMode::Plain,
        untimed_steps: warmup,
    };
    let (_, t) = run_to_end(worker, &req, probe, work)?;
    let p = &t.phases;
    Ok(100.0 * (t.loop_wall_s - p.step_s) / p.step_s)
}

/// One timed worker run.
struct Timing {
    ms_per_step: f64,
    /// Time outside `simulation.step` over time inside it, in the same run [%].
    in_run_overhead_pct: f64,
    /// Where a step's time went [ms/step], by phase and observer (full-loop runs).
    profile: Vec<(String, f64)>,
}

/// Median over the repeats of `cost[r] / floor[r]`.
fn median_ratio(cost: &[f64], floor: &[f64]) -> f64 {
    let r: Vec<f64> = cost.iter().zip(floor).map(|(c, f)| c / f).collect();
    median(&r)
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let m = s.len() / 2;
    if s.len() % 2 == 1 {
        s[m]
    } else {
        0.5 * (s[m - 1] + s[m])
    }
}

/// How the TraCI reference reads the vehicles (`READS` of `traci_reference.py`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TraciReads {
    /// One subscription read per step for every vehicle, as Flow reads them.
    Subscriptions,
    /// Three getter calls per vehicle and step, one socket round trip each.
    PerCall,
}

impl TraciReads {
    fn arg(self) -> &'static str {
        match self {
            TraciReads::Subscriptions => "subscriptions",
            TraciReads::PerCall => "per-call",
        }
    }
}

fn traci_reference(
    case: &BenchCase,
    routes: &Path,
    python_host: &Path,
    reads: TraciReads,
    controller: Option<&str>,
) -> Result<f64, BenchError> {
    let venv = find_venv()?;
    let py = venv.join("bin").join("python");
    let sumo_home = Command::new(&py)
        .args(["-c", "import sumo; print(sumo.SUMO_HOME)"])
        .output()
        .map_err(|e| BenchError::Traci(format!("{}: {e}", py.display())))?;
    let sumo = PathBuf::from(String::from_utf8_lossy(&sumo_home.stdout).trim())
        .join("bin")
        .join("sumo");
    let out = Command::new(&py)
        .arg(python_host.join("traci_reference.py"))
        .arg(&sumo)
        .arg(&case.net)
        .arg(routes)
        .args([
            "0.1".to_string(),
            "1".to_string(),
            (case.traci_steps + case.warmup).to_string(),
            case.warmup.to_string(),
            reads.arg().to_string(),
        ])
        .args(controller)
        .output()
        .map_err(|e| BenchError::Traci(e.to_string()))?;
    if !out.status.success() {
        return Err(BenchError::Traci(format!(
            "{}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        )));
    }
    ms_per_step(&String::from_utf8_lossy(&out.stdout))
}

/// The figure of the reference's output: `ms_per_step` of the last JSON line that has one
/// (SUMO and traci print their own lines before it).
fn ms_per_step(text: &str) -> Result<f64, BenchError> {
    text.lines()
        .rev()
        .find_map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).ok()?;
            v.get("ms_per_step")?.as_f64()
        })
        .ok_or_else(|| BenchError::Traci(format!("no JSON line with ms_per_step in: {text}")))
}

/// Runs one case; `progress` receives a line per measurement.
pub fn run_case(
    case: &BenchCase,
    worker: &WorkerCommand,
    work_dir: &Path,
    python_host: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<BenchResult, BenchError> {
    let sc = scenario(case)?;
    let controller = bench_controller(python_host);
    let py = python_scenario(&sc, python_host, case)?;
    let m = repeats(case, &sc, &py, worker, work_dir, progress)?;
    let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let (a, c, sub) = (best(&m.alone), best(&m.controlled), best(&m.python_getters));
    let routes = work_dir.join("controlled").join("routes.rou.xml");
    let mut traci = |reads: TraciReads| -> Result<Option<f64>, BenchError> {
        if !case.traci || (reads == TraciReads::PerCall && !case.traci_per_call) {
            return Ok(None);
        }
        let t = traci_reference(case, &routes, python_host, reads, None)?;
        progress(&format!(
            "{}: TraCI reference, {:<13}    {t:9.4} ms/step",
            case.name,
            reads.arg()
        ));
        Ok(Some(t))
    };
    let traci_ms = traci(TraciReads::Subscriptions)?;
    let traci_per_call_ms = traci(TraciReads::PerCall)?;
    let traci_python_ms = if case.traci && case.traci_python {
        let t = traci_reference(
            case,
            &routes,
            python_host,
            TraciReads::Subscriptions,
            Some(&controller),
        )?;
        progress(&format!(
            "{}: TraCI reference, Python controller {t:9.4} ms/step",
            case.name
        ));
        Some(t)
    } else {
        None
    };
    let pc = best(&m.python_controller);
    Ok(BenchResult {
        name: case.name.clone(),
        vehicles: case.vehicles,
        steps: case.steps,
        alone_ms: a,
        controlled_ms: c,
        overhead_pct: 100.0 * (c / a - 1.0),
        in_run_overhead_pct: median(&m.in_run),
        python_getters_ms: sub,
        python_getters_overhead_pct: 100.0 * (sub / a - 1.0),
        interleaved_overhead_pct: median(&m.interleaved_pct),
        alone_samples_ms: m.alone,
        controlled_samples_ms: m.controlled,
        python_getters_samples_ms: m.python_getters,
        interleaved_samples_pct: m.interleaved_pct,
        in_run_untimed_pct: median(&m.in_run_untimed),
        in_run_plain_pct: median(&m.in_run_plain),
        floor_pct: median(&m.floors),
        plain_over_floor: median_ratio(&m.in_run_plain, &m.floors),
        interleaved_over_floor: median_ratio(&m.in_run_untimed, &m.floors),
        floor_samples_pct: m.floors,
        traci_ms,
        speedup_vs_traci: traci_ms.map(|t| t / c),
        traci_per_call_ms,
        speedup_vs_traci_per_call: traci_per_call_ms.map(|t| t / c),
        profile_ms: m.profile,
        python_controller_ms: pc,
        python_controller_overhead_pct: 100.0 * (pc / a - 1.0),
        python_controller_samples_ms: m.python_controller,
        python_profile_ms: m.python_profile,
        traci_python_ms,
        python_speedup_vs_traci: traci_python_ms.map(|t| t / pc),
    })
}

/// The benchmark's Python controller, `FILE.py:Class`.
fn bench_controller(python_host: &Path) -> String {
    format!(
        "{}:Follow",
        python_host.join("bench_controller.py").display()
    )
}

/// The case's scenario driven by the benchmark's Python controller.
fn python_scenario(
    sc: &Scenario,
    python_host: &Path,
    case: &BenchCase,
) -> Result<Scenario, BenchError> {
    let spec = syncroad_control::user_law::ControllerSpec {
        python: Some(bench_controller(python_host)),
        ..Default::default()
    };
    let law = spec
        .resolve(python_host)
        .map_err(|e| BenchError::Scenario {
            name: case.name.clone(),
            reason: e.to_string(),
        })?;
    Ok(sc.with_controller(law))
}

/// The samples of a case's repeats, one of each kind per repeat.
struct Samples {
    alone: Vec<f64>,
    controlled: Vec<f64>,
    python_getters: Vec<f64>,
    interleaved_pct: Vec<f64>,
    in_run_untimed: Vec<f64>,
    in_run_plain: Vec<f64>,
    /// The floor of each repeat's profiled run [%].
    floors: Vec<f64>,
    in_run: Vec<f64>,
    /// The profile of the fastest controlled run.
    profile: Vec<(String, f64)>,
    python_controller: Vec<f64>,
    python_profile: Vec<(String, f64)>,
}

/// Alternates SUMO alone, the controlled loop (direct calls), the loop through Python
/// getters and the same-process interleaved run, `case.repeats` times.
fn repeats(
    case: &BenchCase,
    sc: &Scenario,
    py: &Scenario,
    worker: &WorkerCommand,
    work_dir: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<Samples, BenchError> {
    let mut m = Samples {
        alone: Vec::new(),
        controlled: Vec::new(),
        python_getters: Vec::new(),
        interleaved_pct: Vec::new(),
        in_run_untimed: Vec::new(),
        in_run_plain: Vec::new(),
        floors: Vec::new(),
        in_run: Vec::new(),
        profile: Vec::new(),
        python_controller: Vec::new(),
        python_profile: Vec::new(),
    };
    for r in 0..case.repeats {
        let a = timed(worker, sc, &work_dir.join("alone"), None, case.warmup)?.ms_per_step;
        progress(&format!(
            "{}: SUMO alone                        {a:9.4} ms/step (run {})",
            case.name,
            r + 1
        ));
        m.alone.push(a);
        let c = timed(
            worker,
            sc,
            &work_dir.join("controlled"),
            Some(ReadMode::Direct),
            case.warmup,
        )?;
        m.in_run.push(c.in_run_overhead_pct);
        m.floors.push(floor_pct(&c.profile));
        if m.controlled.iter().all(|&x| x > c.ms_per_step) {
            m.profile = c.profile;
        }
        let c = c.ms_per_step;
        progress(&format!(
            "{}: SUMO + controller (direct)        {c:9.4} ms/step (run {})",
            case.name,
            r + 1
        ));
        m.controlled.push(c);
        let s = timed(
            worker,
            sc,
            &work_dir.join("python-getters"),
            Some(ReadMode::Getters),
            case.warmup,
        )?
        .ms_per_step;
        progress(&format!(
            "{}: SUMO + controller (Python getters){s:9.4} ms/step (run {})",
            case.name,
            r + 1
        ));
        m.python_getters.push(s);
        let p = timed(
            worker,
            py,
            &work_dir.join("python-controller"),
            Some(ReadMode::Direct),
            case.warmup,
        )?;
        if m.python_controller.iter().all(|&x| x > p.ms_per_step) {
            m.python_profile = p.profile;
        }
        let p = p.ms_per_step;
        progress(&format!(
            "{}: SUMO + Python controller (worker) {p:9.4} ms/step (run {})",
            case.name,
            r + 1
        ));
        m.python_controller.push(p);
        let (i, untimed) = interleaved(worker, sc, &work_dir.join("interleaved"), case.warmup)?;
        progress(&format!(
            "{}: same-process overhead (interleaved) {i:7.1} % (run {})",
            case.name,
            r + 1
        ));
        m.interleaved_pct.push(i);
        m.in_run_untimed.push(untimed);
        let p = plain(worker, sc, &work_dir.join("plain"), case.warmup)?;
        progress(&format!(
            "{}: loop over SUMO's step (plain run)   {p:7.1} % (run {})",
            case.name,
            r + 1
        ));
        m.in_run_plain.push(p);
    }
    Ok(m)
}

/// SUMO's own stepping time of each scenario's run: the run as `syncroad run` makes it, through
/// one long-lived worker, and the wall time spent inside `simulation.step` \[s\] as every run
/// reports it ([`Finish::step_s`], the figure a sweep sums), without the profile's timers (the same traffic as the real run; holding speeds instead would let
/// a perturbed ring's vehicles drive into each other and time SUMO's collision handling).
/// Summed over a sweep's points and divided by the cores, it is the sweep's stepping bound:
/// what SUMO needs to step every point.
pub fn step_seconds(
    worker: &WorkerCommand,
    scenarios: &[Scenario],
    work: &Path,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Vec<f64>, BenchError> {
    let mut w = crate::supervisor::Worker::spawn(worker)?;
    let mut out = Vec::with_capacity(scenarios.len());
    for (k, sc) in scenarios.iter().enumerate() {
        let opts = RunOptions::new(work.join(k.to_string()), worker.clone());
        let req = prepare(sc, &load_road(sc)?, &opts)?;
        let fin = w
            .run_job(JobRef::Run(&req), &Supervision::default())
            .result?;
        if fin.steps_done != req.steps {
            return Err(BenchError::Stopped {
                name: sc.name().to_string(),
                reason: format!("{:?}", fin.stop),
            });
        }
        progress(k, fin.step_s);
        out.push(fin.step_s);
    }
    Ok(out)
}

/// Which of the standard cases run, and how.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Selection {
    /// Shorter runs (a smoke test of the benchmark).
    pub quick: bool,
    /// Only the case whose name starts with this (`sugiyama-ring`, `ring-20km`).
    pub case: Option<String>,
    /// Leave out the TraCI reference (the loop's own figures only, in a fraction of the time).
    pub no_traci: bool,
}

/// The standard cases that `sel` selects; an unknown case name is refused with the names.
pub fn select_cases(nets: &Path, sel: &Selection) -> Result<Vec<BenchCase>, BenchError> {
    let mut cases = standard_cases(nets, sel.quick);
    if let Some(want) = &sel.case {
        let names: Vec<String> = cases
            .iter()
            .map(|c| c.name.split(' ').next().unwrap_or_default().to_string())
            .collect();
        cases.retain(|c| !want.is_empty() && c.name.starts_with(want.as_str()));
        if cases.is_empty() {
            return Err(BenchError::UnknownCase {
                case: want.clone(),
                valid: names.join(", "),
            });
        }
    }
    if sel.no_traci {
        for c in &mut cases {
            c.traci = false;
            c.traci_per_call = false;
        }
    }
    Ok(cases)
}

/// The standard cases ([`standard_cases`]) that `sel` selects, with the repository's networks
/// and TraCI reference, `worker` starting every measurement; the work folder is removed
/// afterwards. A case name that selects nothing is refused ([`BenchError::UnknownCase`])
/// before any measurement.
pub fn run_standard(
    worker: &WorkerCommand,
    sel: &Selection,
    progress: &mut dyn FnMut(&str),
) -> Result<Vec<BenchResult>, BenchError> {
    let repo = crate::venv::repo_dir();
    let cases = select_cases(&repo.join("sumo-nets"), sel)?;
    // A folder of our own for the runs' SUMO files, removed when dropped.
    let tmp = tempfile::Builder::new()
        .prefix("syncroad-sumo-bench-")
        .tempdir()
        .map_err(|e| BenchError::TempDir(e.to_string()))?;
    let work = tmp.path().join("runs");
    cases
        .iter()
        .map(|case| run_case(case, worker, &work, &repo.join("python-host"), progress))
        .collect()
}

/// libsumo's own calls (law + `setSpeed`, reads) over `simulation.step` in `profile` [%].
fn floor_pct(profile: &[(String, f64)]) -> f64 {
    let of = |name: &str| {
        profile
            .iter()
            .find(|(n, _)| n == name)
            .map_or(0.0, |(_, t)| *t)
    };
    100.0 * (of("law + setSpeed") + of("read speeds + odometers")) / of("simulation.step")
}

/// The profile of each case: one line per phase, its time per step and its share of the step.
pub fn format_profile(results: &[BenchResult]) -> String {
    let mut s = String::new();
    for r in results {
        let total: f64 = r.profile_ms.iter().map(|(_, t)| t).sum();
        s.push_str(&format!(
            "{} (N = {}): {total:.4} ms/step in the fastest controlled run, SUMO alone {:.4}\n",
            r.name, r.vehicles, r.alone_ms
        ));
        for (name, t) in &r.profile_ms {
            s.push_str(&format!(
                "  {name:<26} {t:>9.4} ms/step {:>6.1} %\n",
                100.0 * t / total
            ));
        }
        s.push_str(&format!(
            "  floor (libsumo's calls): {:.1} % of SUMO's step; the loop costs {:.1} % of it in a plain run, {:.2}x the floor ({:.1} %, {:.2}x, in the interleaved runs; medians over the repeats, each run over its own repeat's floor)\n",
            r.floor_pct,
            r.in_run_plain_pct,
            r.plain_over_floor,
            r.in_run_untimed_pct,
            r.interleaved_over_floor
        ));
    }
    s
}

/// The user's Python controller beside the Rust law and Flow's way of driving it: SUMO alone,
/// the Rust law, the Python controller in the worker, the same controller from the TraCI
/// loop, and where a step of the Python run goes.
pub fn format_python(results: &[BenchResult]) -> String {
    let mut s = String::from(
        "case                   alone ms/step  Rust law ms/step  Python in worker ms/step  overhead  TraCI + Python ms/step  worker vs TraCI\n",
    );
    for r in results {
        s.push_str(&format!(
            "{:<22} {:>13.4} {:>17.4} {:>25.4} {:>8.1}%  {:>22} {:>16}\n",
            r.name,
            r.alone_ms,
            r.controlled_ms,
            r.python_controller_ms,
            r.python_controller_overhead_pct,
            r.traci_python_ms
                .map(|t| format!("{t:.4}"))
                .unwrap_or_default(),
            r.python_speedup_vs_traci
                .map(|x| format!("{x:.1}×"))
                .unwrap_or_default(),
        ));
    }
    for r in results {
        let total: f64 = r.python_profile_ms.iter().map(|(_, t)| t).sum();
        s.push_str(&format!(
            "{} (N = {}), the fastest Python-controller run: {total:.4} ms/step\n",
            r.name, r.vehicles
        ));
        for (name, t) in &r.python_profile_ms {
            let name = if name == "law + setSpeed" {
                "Python step(obs) + setSpeed"
            } else {
                name.as_str()
            };
            s.push_str(&format!(
                "  {name:<28} {t:>9.4} ms/step {:>6.1} %\n",
                100.0 * t / total
            ));
        }
    }
    s
}

/// A plain-text table of results.
pub fn format_table(results: &[BenchResult]) -> String {
    let mut s = String::from(
        "case                   alone ms/step  +controller ms/step  overhead  in-run overhead  same-process  (Python getters: ms/step  overhead)  TraCI subscr. ms/step  vs TraCI  TraCI per-call ms/step  vs per-call\n",
    );
    for r in results {
        s.push_str(&format!(
            "{:<22} {:>13.4} {:>20.4} {:>8.1}% {:>15.1}% {:>12.1}%  {:>24.4} {:>9.1}%  {:>21} {:>9}  {:>22} {:>11}\n",
            r.name,
            r.alone_ms,
            r.controlled_ms,
            r.overhead_pct,
            r.in_run_overhead_pct,
            r.interleaved_overhead_pct,
            r.python_getters_ms,
            r.python_getters_overhead_pct,
            r.traci_ms.map(|t| format!("{t:.4}")).unwrap_or_default(),
            r.speedup_vs_traci
                .map(|x| format!("{x:.1}×"))
                .unwrap_or_default(),
            r.traci_per_call_ms
                .map(|t| format!("{t:.4}"))
                .unwrap_or_default(),
            r.speedup_vs_traci_per_call
                .map(|x| format!("{x:.1}×"))
                .unwrap_or_default(),
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_selection_keeps_the_named_case_and_can_leave_traci_out() {
        let nets = Path::new("nets");
        let all = select_cases(nets, &Selection::default()).unwrap();
        assert_eq!(all.len(), 2);
        assert!(all.iter().all(|c| c.traci));
        let sel = Selection {
            case: Some("sugiyama".into()),
            no_traci: true,
            ..Selection::default()
        };
        let one = select_cases(nets, &sel).unwrap();
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].vehicles, 22);
        assert!(!one[0].traci && !one[0].traci_per_call);
        for bad in ["ring-2km", ""] {
            let sel = Selection {
                case: Some(bad.into()),
                ..Selection::default()
            };
            let e = select_cases(nets, &sel).unwrap_err().to_string();
            assert!(e.contains(&format!("{bad:?}")), "{e}");
            assert!(e.contains("sugiyama-ring, ring-20km"), "{e}");
        }
    }

    #[test]
    fn the_floor_is_libsumos_calls_over_sumos_step() {
        let profile = [
            ("simulation.step", 0.040),
            ("law + setSpeed", 0.0025),
            ("read speeds + odometers", 0.0015),
            ("rows", 0.0005),
            ("rest of the loop", 0.0002),
        ]
        .map(|(n, t)| (n.to_string(), t));
        // (2.5 + 1.5) µs of libsumo calls on a 40 µs step; the rows are syncroad's own.
        assert!((floor_pct(&profile) - 10.0).abs() < 1e-9);
    }

    #[test]
    fn each_repeat_is_set_against_its_own_floor() {
        // The machine changes speed between repeats (SUMO's step half as long in the second,
        // so both shares move): each pair keeps its ratio (1.2, 1.2, 1.5), median 1.2. The
        // cost over one run's floor would give anything from 0.6 to 3.0 here.
        let cost = [12.0, 6.0, 15.0];
        let floor = [10.0, 5.0, 10.0];
        assert!((median_ratio(&cost, &floor) - 1.2).abs() < 1e-12);
        assert!((median_ratio(&[11.0, 13.0], &[10.0, 10.0]) - 1.2).abs() < 1e-12);
    }

    #[test]
    fn the_reference_figure_is_the_last_json_line_that_has_one() {
        let text = "Loading net-file from 'ring.net.xml' ... done (3ms).\n\
                    {\"warmup\": 5}\n\
                    {\"ms_per_step\": 2.5, \"steps\": 100}\n\
                    Simulation ended at time: 10.00\n";
        assert_eq!(ms_per_step(text).unwrap(), 2.5);
        let e = ms_per_step("Step #10.00\n{\"steps\": 100}\n").unwrap_err();
        assert!(
            e.to_string().contains("no JSON line with ms_per_step"),
            "{e}"
        );
    }
}
