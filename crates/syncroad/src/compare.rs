//! `syncroad compare`: one scenario, several drivers. The same network, vehicles, initial state
//! and seed run with the scenario's law and with SUMO's own car-following models (Krauss with
//! σ 0.5 and, for stop-and-go waves at ring density, σ 0.9; IDM; for platoons ACC and CACC),
//! and, with `--mixed`, on rings where only some vehicles run the law.
//!
//! Every run is its own SUMO worker process; up to `--jobs` run at once. Each writes its own
//! folder (trajectories.csv, metrics.json, plots); a failed run is marked and the others still
//! report. The combined `compare.json` holds the stamps once (syncroad and SUMO versions,
//! platform, seed, scenario hash) and each run's metrics without them, so it is the document
//! `syncroad regress` compares for baselines of kind `compare`.
//!
//! Exit codes: 0 every run completed, 2 bad input (nothing ran), 3 some run failed (the others'
//! results are written), 130 interrupted.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use serde_json::{json, Value};
use syncroad_control::congestion::congestion_metrics;
use syncroad_control::metrics::{sync_metrics, VerdictThresholds};
use syncroad_control::scenario::Model;
use syncroad_control::Scenario;
use syncroad_sumo::run::{check_sumo_numbers, layout_for, loop_position, MeasureOptions};
use syncroad_sumo::{interrupt_flag, run_scenario, RunOptions, SumoDriver, WorkerCommand};

use crate::commands::{default_record_every, load_scenario, InputError};
use crate::exit_codes;

/// Options of `syncroad compare`.
#[derive(Debug, Clone, clap::Args)]
pub struct CompareArgs {
    /// Scenario file (JSON) with a SUMO network (`sumo.net`).
    pub scenario: PathBuf,
    /// Output folder: one subfolder per run, compare.json (created if missing).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Runs, comma-separated: protocol (the scenario's law), krauss (SUMO's default, σ 0.5),
    /// krauss-SIGMA (e.g. krauss-0.9), idm, acc, cacc. Default: protocol,krauss,krauss-0.9,idm
    /// on rings; protocol,krauss,idm,acc,cacc on straight roads.
    #[arg(long)]
    pub baselines: Option<String>,
    /// Mixed traffic on a ring: for each count K, a run where K evenly spaced vehicles run the
    /// law and the others are --mixed-driver (e.g. 0,1,2,4; 0 is the all-human ring).
    #[arg(long)]
    pub mixed: Option<String>,
    /// The human drivers of --mixed runs.
    #[arg(long, default_value = "krauss-0.9")]
    pub mixed_driver: String,
    /// Runs at once, each its own SUMO process (default: the number of cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Warm-up excluded from every congestion and SUMO metric [s] (default: a quarter of the
    /// horizon).
    #[arg(long)]
    pub warmup_s: Option<f64>,
    /// Read fuel and CO2 every k steps (1 = every step, exact at SUMO's step).
    #[arg(long, default_value_t = 1)]
    pub emission_every: usize,
    /// Record every k-th step in trajectories.csv (default: about 2000 samples).
    #[arg(long)]
    pub record_every: Option<usize>,
    /// Wall-clock limit of each SUMO run [s] (default: the scenario's sumo.timeout_s).
    #[arg(long)]
    pub timeout_s: Option<f64>,
    /// Do not draw plots.
    #[arg(long)]
    pub no_plots: bool,
}

/// One run of a comparison: a name and who drives each scenario vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    /// Folder and column name (`protocol`, `krauss-0.9`, `mixed-2`, ...).
    pub name: String,
    /// Per scenario vehicle: `None` = the law, `Some` = that SUMO model.
    pub drivers: Vec<Option<SumoDriver>>,
}

/// A validated comparison.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The runs in column order.
    pub runs: Vec<RunSpec>,
    /// Parallel workers.
    pub jobs: usize,
    /// Warm-up [s].
    pub warmup_s: f64,
    /// Emission sampling stride.
    pub emission_every: usize,
    /// Recording stride.
    pub record_every: usize,
    /// Per-run wall-clock limit.
    pub timeout: Option<Duration>,
    /// Draw plots.
    pub plots: bool,
    /// Mixed-run counts, when asked.
    pub mixed: Vec<usize>,
}

/// Law-controlled vehicles of a mixed ring with `k` of `n`: `⌊j n / k⌋`, j = 0..k.
pub fn mixed_controlled(n: usize, k: usize) -> Vec<usize> {
    (0..k).map(|j| j * n / k).collect()
}

/// Parses and checks every option before anything runs.
pub fn plan(sc: &Scenario, a: &CompareArgs) -> anyhow::Result<Plan> {
    let bad = |m: String| anyhow::Error::new(InputError(m));
    let n = sc.n;
    let default = if sc.is_ring() {
        "protocol,krauss,krauss-0.9,idm"
    } else {
        "protocol,krauss,idm,acc,cacc"
    };
    let list = a
        .baselines
        .as_deref()
        .unwrap_or(if a.mixed.is_some() { "" } else { default });
    let mut runs: Vec<RunSpec> = Vec::new();
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let drivers = if name.eq_ignore_ascii_case("protocol") {
            vec![None; n]
        } else {
            let d = SumoDriver::parse("--baselines", name).map_err(|e| bad(e.to_string()))?;
            vec![Some(d); n]
        };
        let name = if name.eq_ignore_ascii_case("protocol") {
            "protocol".to_string()
        } else {
            SumoDriver::parse("--baselines", name)
                .map_err(|e| bad(e.to_string()))?
                .to_string()
        };
        if runs.iter().any(|r| r.name == name) {
            return Err(bad(format!("--baselines: {name} is listed twice")));
        }
        runs.push(RunSpec { name, drivers });
    }
    let mut mixed = Vec::new();
    if let Some(m) = &a.mixed {
        if !sc.is_ring() || !matches!(sc.model, Model::DelayedDriver(_)) {
            return Err(bad(format!(
                "--mixed = {m}: mixed traffic needs a ring of delayed drivers (scenario {} is not one)",
                sc.name
            )));
        }
        let human =
            SumoDriver::parse("--mixed-driver", &a.mixed_driver).map_err(|e| bad(e.to_string()))?;
        for x in m.split(',').map(str::trim) {
            let k: usize = x.parse().map_err(|_| {
                bad(format!(
                    "--mixed = {m}: {x:?} is not a vehicle count; give counts 0..={n} separated by commas, e.g. 0,1,2,4"
                ))
            })?;
            if k > n {
                return Err(bad(format!(
                    "--mixed = {m}: {k} controlled vehicles but the scenario has {n}"
                )));
            }
            if mixed.contains(&k) {
                return Err(bad(format!("--mixed = {m}: {k} is listed twice")));
            }
            mixed.push(k);
            let mut drivers = vec![Some(human); n];
            for i in mixed_controlled(n, k) {
                drivers[i] = None;
            }
            runs.push(RunSpec {
                name: format!("mixed-{k}"),
                drivers,
            });
        }
    }
    if runs.is_empty() {
        return Err(bad(
            "--baselines is empty: name at least one run (e.g. protocol,krauss) or give --mixed"
                .into(),
        ));
    }
    let jobs = match a.jobs {
        Some(0) => return Err(bad("--jobs = 0: must be ≥ 1".into())),
        Some(j) => j,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let warmup_s = a.warmup_s.unwrap_or(0.25 * sc.horizon_s());
    if !(warmup_s.is_finite() && warmup_s >= 0.0 && warmup_s < sc.horizon_s()) {
        return Err(bad(format!(
            "--warmup-s = {warmup_s}: must be ≥ 0 and shorter than the horizon ({} s)",
            sc.horizon_s()
        )));
    }
    if a.emission_every == 0 {
        return Err(bad(
            "--emission-every = 0: must be ≥ 1 (1 = read fuel and CO2 every step)".into(),
        ));
    }
    if a.record_every == Some(0) {
        return Err(bad("--record-every = 0: must be ≥ 1".into()));
    }
    let timeout = match a.timeout_s {
        Some(t) => Some(
            Duration::try_from_secs_f64(t)
                .map_err(|_| bad(format!("--timeout-s = {t}: must be a finite number ≥ 0")))?,
        ),
        None => None,
    };
    // Everything SUMO would reject, before any worker starts.
    check_sumo_numbers(sc).map_err(|e| bad(e.to_string()))?;
    layout_for(sc, 0.0).map_err(|e| bad(e.to_string()))?;
    Ok(Plan {
        runs,
        jobs,
        warmup_s,
        emission_every: a.emission_every,
        record_every: a
            .record_every
            .unwrap_or_else(|| default_record_every(sc.steps, sc.n)),
        timeout,
        plots: !a.no_plots,
        mixed,
    })
}

/// What one run left behind.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// The run's name.
    pub name: String,
    /// Reached the horizon.
    pub complete: bool,
    /// Why not.
    pub error: Option<String>,
    /// Its metrics document (stamps included), `None` when SUMO never produced a row.
    pub metrics: Option<Value>,
    /// SUMO version reported by the worker.
    pub sumo_version: Option<String>,
    /// The speed spread over time `(t, spread)` for the combined plot.
    pub spread: Vec<(f64, f64)>,
}

/// Keys of a run's metrics that are stamps, lifted to the top of compare.json.
const RUN_STAMPS: [&str; 6] = [
    "syncroad_version",
    "platform",
    "sumo_version",
    "scenario_hash",
    "seed",
    "emission_class",
];

/// Occurrences of SUMO's emergency-braking warning in its log.
fn emergency_braking_warnings(log: &Path) -> usize {
    std::fs::read_to_string(log)
        .map(|t| t.matches("performs emergency braking").count())
        .unwrap_or(0)
}

fn run_one(
    sc: &Scenario,
    spec: &RunSpec,
    plan: &Plan,
    dir: &Path,
    worker: &WorkerCommand,
    interrupt: &Arc<AtomicBool>,
) -> anyhow::Result<RunResult> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut opts = RunOptions::new(dir.join("sumo"), worker.clone());
    opts.record_every = plan.record_every;
    opts.timeout = plan.timeout;
    opts.interrupt = Some(interrupt.clone());
    opts.drivers = spec.drivers.clone();
    opts.measure = Some(MeasureOptions {
        warmup_s: plan.warmup_s,
        emission_every: plan.emission_every,
        tripinfo: true,
    });
    let run = run_scenario(sc, &opts).map_err(|e| InputError(e.to_string()))?;
    let outcome = run.outcome();
    let traj = run.trajectory(sc);
    let th = VerdictThresholds {
        tolerance_mps: sc.file.verdict.tolerance_mps,
        window_s: sc.file.verdict.window_s,
    };
    let desired = match &sc.model {
        Model::Cacc(c) => Some(c.desired_gap_m.as_slice()),
        Model::DelayedDriver(_) => None,
    };
    let sync = sync_metrics(&traj, th, desired, outcome.is_err());
    let ring = sc.is_ring().then(|| run.road_length_m());
    let congestion = congestion_metrics(&traj, plan.warmup_s, ring).ok();
    let finish = run.worker.result.as_ref().ok();
    let start = run.worker.start.as_ref();
    let sumo_version = start.map(|s| s.python.sumo_version.clone());
    let measured = finish.and_then(|f| f.measured.as_ref());
    // Distance driven after the warm-up, from the recorded positions.
    let first = traj.time_s.partition_point(|&t| t < plan.warmup_s - 1e-9);
    let distance_m: f64 = if traj.len() > first + 1 {
        let n = traj.n;
        let q = |k: usize| &traj.positions_m[k * n..(k + 1) * n];
        q(traj.len() - 1)
            .iter()
            .zip(q(first))
            .map(|(b, a)| b - a)
            .sum()
    } else {
        0.0
    };
    let measured_s = measured.map_or(0.0, |m| m.steps as f64 * sc.step_s);
    let sumo = measured.map(|m| {
        let per_km = |mg: f64| {
            if distance_m > 0.0 {
                mg / 1000.0 / (distance_m / 1000.0)
            } else {
                f64::NAN
            }
        };
        json!({
            "measured_s": measured_s,
            "flow_veh_per_h": m.loop_passages.map(|p| p as f64 / measured_s * 3600.0),
            "loop_passages": m.loop_passages,
            "loop_ring_m": loop_position(&run.request.layout.road).map(|l| l.2),
            "road_length_m": run.road_length_m(),
            "flow_from_speed_veh_per_h": match (ring, &congestion) {
                (Some(l), Some(c)) => Some(sc.n as f64 * c.mean_speed_mps / l * 3600.0),
                _ => None,
            },
            "time_loss_s": m.time_loss_s,
            "time_loss_per_vehicle_s": m.time_loss_s / sc.n as f64,
            "fuel_mg": m.fuel_mg,
            "fuel_total_mg": m.fuel_total_mg,
            "co2_mg": m.co2_mg,
            "distance_m": distance_m,
            "fuel_g_per_km": per_km(m.fuel_mg),
            "co2_g_per_km": per_km(m.co2_mg),
            "hard_braking_steps": m.hard_braking_steps,
        })
    });
    let totals = finish.map(|f| &f.totals);
    let controlled = spec.drivers.iter().filter(|d| d.is_none()).count();
    let doc = json!({
        "syncroad_version": env!("CARGO_PKG_VERSION"),
        "platform": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        "sumo_version": sumo_version,
        "scenario_hash": sc.hash_hex(),
        "seed": sc.file.seed,
        "emission_class": syncroad_sumo::drivers::EMISSION_CLASS,
        "run": spec.name,
        "scenario": sc.name,
        "law_controlled_vehicles": controlled,
        "drivers": spec.drivers.iter().map(|d| d.map_or("law".to_string(), |d| d.to_string())).collect::<Vec<_>>(),
        "complete": outcome.is_ok(),
        "error": outcome.as_ref().err().map(|e| e.to_string()),
        "stop": finish.map(|f| serde_json::to_value(&f.stop).unwrap_or(Value::Null)),
        "warmup_s": plan.warmup_s,
        "emission_every": plan.emission_every,
        "sync": sync,
        "congestion": congestion,
        "sumo": sumo,
        "safety": totals.map(|t| json!({
            "collision_steps": t.collision_steps,
            "colliding_vehicles": t.colliding_vehicles,
            "teleports": t.teleports,
            "emergency_braking_warnings": emergency_braking_warnings(&dir.join("sumo").join("sumo.log")),
            "overridden_commands": t.overrides,
            "negative_commands_clamped": t.negative_commands_clamped,
        })),
    });
    crate::report::write_run_files(dir, &traj, &doc)?;
    if plan.plots && traj.len() >= 2 {
        crate::plots::RunPlots {
            traj: &traj,
            ring_length_m: ring,
            title: format!("{}: {}", sc.name, spec.name),
        }
        .write_all(dir)?;
    }
    Ok(RunResult {
        name: spec.name.clone(),
        complete: outcome.is_ok(),
        error: outcome.err().map(|e| e.to_string()),
        metrics: Some(doc),
        sumo_version,
        spread: traj
            .time_s
            .iter()
            .copied()
            .zip(syncroad_control::metrics::spread_series(&traj))
            .collect(),
    })
}

/// Runs every run of the plan, `plan.jobs` at a time, with a progress line per start and end
/// on stderr. A run that fails keeps its place (marked) and never stops the others.
pub fn run_all(
    sc: &Scenario,
    plan: &Plan,
    out: &Path,
    interrupt: Arc<AtomicBool>,
) -> anyhow::Result<Vec<RunResult>> {
    let worker = WorkerCommand::current_exe().context("cannot locate the syncroad executable")?;
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let total = plan.runs.len();
    let results: Mutex<Vec<Option<RunResult>>> = Mutex::new(vec![None; total]);
    let t0 = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..plan.jobs.min(total) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                if i >= total {
                    break;
                }
                let spec = &plan.runs[i];
                eprintln!(
                    "[{:>2}/{total} done, {:6.1} s] {} started",
                    done.load(Ordering::SeqCst),
                    t0.elapsed().as_secs_f64(),
                    spec.name
                );
                let r = if interrupt.load(Ordering::SeqCst) {
                    Err(anyhow::anyhow!("not started: interrupted"))
                } else {
                    run_one(sc, spec, plan, &out.join(&spec.name), &worker, &interrupt)
                };
                let r = r.unwrap_or_else(|e| RunResult {
                    name: spec.name.clone(),
                    complete: false,
                    error: Some(format!("{e:#}")),
                    metrics: None,
                    sumo_version: None,
                    spread: Vec::new(),
                });
                let k = done.fetch_add(1, Ordering::SeqCst) + 1;
                eprintln!(
                    "[{k:>2}/{total} done, {:6.1} s] {} {}",
                    t0.elapsed().as_secs_f64(),
                    spec.name,
                    match &r.error {
                        None => "finished".to_string(),
                        Some(e) => format!("FAILED: {e}"),
                    }
                );
                results.lock().expect("no panic holds the lock")[i] = Some(r);
            });
        }
    });
    Ok(results
        .into_inner()
        .expect("no panic holds the lock")
        .into_iter()
        .map(|r| r.expect("every run reports"))
        .collect())
}

/// The combined document: stamps once, each run's metrics without them, and for `--mixed`
/// the reductions against the all-human ring.
pub fn combined(sc: &Scenario, results: &[RunResult], mixed: &[usize]) -> Value {
    let mut runs = serde_json::Map::new();
    let mut stamps = serde_json::Map::new();
    for r in results {
        let mut m = r
            .metrics
            .clone()
            .unwrap_or_else(|| json!({"run": r.name, "complete": false, "error": r.error}));
        if let Value::Object(o) = &mut m {
            for k in RUN_STAMPS {
                if let Some(v) = o.remove(k) {
                    stamps.entry(k.to_string()).or_insert(v);
                }
            }
        }
        runs.insert(r.name.clone(), m);
    }
    let mut doc = json!({
        "syncroad_version": env!("CARGO_PKG_VERSION"),
        "platform": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        "sumo_version": results.iter().find_map(|r| r.sumo_version.clone()),
        "scenario": sc.name,
        "scenario_hash": sc.hash_hex(),
        "seed": sc.file.seed,
        "emission_class": syncroad_sumo::drivers::EMISSION_CLASS,
        "runs": Value::Object(runs.clone()),
    });
    if mixed.contains(&0) && mixed.len() > 1 {
        let get = |k: usize, path: &[&str]| -> Option<f64> {
            let mut v = runs.get(&format!("mixed-{k}"))?;
            for p in path {
                v = v.get(p)?;
            }
            v.as_f64()
        };
        let std_path = ["congestion", "speed_std_mps"];
        let fuel_path = ["sumo", "fuel_g_per_km"];
        let mut red = serde_json::Map::new();
        for &k in mixed.iter().filter(|&&k| k > 0) {
            let rel = |p: &[&str]| match (get(0, p), get(k, p)) {
                (Some(h), Some(x)) if h != 0.0 => Some(1.0 - x / h),
                _ => None,
            };
            red.insert(
                format!("mixed-{k}"),
                json!({"speed_std_reduction": rel(&std_path), "fuel_per_km_reduction": rel(&fuel_path)}),
            );
        }
        doc["mixed_reduction_vs_all_human"] = Value::Object(red);
    }
    doc
}

/// One table row: label, dotted path into a run's metrics, decimals.
const ROWS: [(&str, &str, usize); 20] = [
    ("verdict", "sync.verdict", 0),
    ("final spread [m/s]", "sync.final_spread_mps", 4),
    ("mean speed [m/s]", "congestion.mean_speed_mps", 3),
    ("speed std [m/s]", "congestion.speed_std_mps", 3),
    (
        "std across vehicles [m/s]",
        "congestion.speed_std_across_vehicles_mps",
        3,
    ),
    ("min speed [m/s]", "congestion.min_speed_mps", 3),
    ("stop events", "congestion.stop_events", 0),
    ("stopped fraction", "congestion.stopped_fraction", 4),
    ("wave amplitude [m/s]", "congestion.wave_amplitude_mps", 3),
    ("wave speed [m/s]", "congestion.wave_speed_mps", 2),
    ("flow, loop [veh/h]", "sumo.flow_veh_per_h", 0),
    ("flow, N·v̄/L [veh/h]", "sumo.flow_from_speed_veh_per_h", 0),
    ("time loss / veh [s]", "sumo.time_loss_per_vehicle_s", 1),
    ("fuel [g/km]", "sumo.fuel_g_per_km", 2),
    ("CO2 [g/km]", "sumo.co2_g_per_km", 1),
    ("hard braking [veh-steps]", "sumo.hard_braking_steps", 0),
    (
        "emergency braking warn.",
        "safety.emergency_braking_warnings",
        0,
    ),
    ("collision steps", "safety.collision_steps", 0),
    ("teleports", "safety.teleports", 0),
    ("overridden commands", "safety.overridden_commands", 0),
];

fn cell(m: Option<&Value>, path: &str, decimals: usize) -> String {
    let mut v = match m {
        Some(v) => v,
        None => return "—".into(),
    };
    for p in path.split('.') {
        match v.get(p) {
            Some(x) => v = x,
            None => return "—".into(),
        }
    }
    match v {
        Value::Number(x) => format!("{:.*}", decimals, x.as_f64().unwrap_or(f64::NAN)),
        Value::String(s) => s
            .replace("_synchronized", "_sync")
            .replace("not_sync", "not sync"),
        Value::Null => "—".into(),
        other => other.to_string(),
    }
}

/// The side-by-side table (one column per run; Markdown, so it pastes into the README).
pub fn table(doc: &Value) -> String {
    let runs = doc["runs"].as_object().cloned().unwrap_or_default();
    let names: Vec<&String> = runs.keys().collect();
    let mut order: Vec<(String, Option<&Value>)> = Vec::new();
    for n in names {
        order.push((n.clone(), runs.get(n)));
    }
    // Keep the run order of the plan (JSON maps are sorted; the plan order is in "order").
    if let Some(o) = doc.get("order").and_then(|o| o.as_array()) {
        order.sort_by_key(|(n, _)| o.iter().position(|x| x.as_str() == Some(n)));
    }
    let mut s = String::new();
    s.push_str("| metric |");
    for (n, m) in &order {
        let ok = m.and_then(|m| m.get("complete")).and_then(Value::as_bool) == Some(true);
        s.push_str(&format!(" {n}{} |", if ok { "" } else { " (FAILED)" }));
    }
    s.push_str("\n|---|");
    s.push_str(&"---:|".repeat(order.len()));
    s.push('\n');
    for (label, path, d) in ROWS {
        s.push_str(&format!("| {label} |"));
        for (_, m) in &order {
            s.push_str(&format!(" {} |", cell(*m, path, d)));
        }
        s.push('\n');
    }
    s
}

/// Runs a comparison into `out` and returns the combined document (the CLI and `regress`).
pub fn compare_into(
    sc: &Scenario,
    plan: &Plan,
    out: &Path,
    interrupt: Arc<AtomicBool>,
) -> anyhow::Result<(Value, Vec<RunResult>)> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create output folder {}", out.display()))?;
    let results = run_all(sc, plan, out, interrupt)?;
    if plan.plots {
        spread_plot(
            out,
            &format!("{}: speed spread by driver", sc.name),
            &results,
        )?;
    }
    let mut doc = combined(sc, &results, &plan.mixed);
    doc["order"] = json!(plan.runs.iter().map(|r| r.name.clone()).collect::<Vec<_>>());
    std::fs::write(
        out.join("compare.json"),
        serde_json::to_string_pretty(&doc)? + "\n",
    )
    .with_context(|| format!("cannot write {}/compare.json", out.display()))?;
    Ok((doc, results))
}

fn draw_spread<DB: plotters::prelude::DrawingBackend>(
    root: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    results: &[RunResult],
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("plotting failed: {e:?}");
    root.fill(&WHITE).map_err(err)?;
    let pos = || {
        results
            .iter()
            .flat_map(|r| r.spread.iter())
            .filter(|(_, y)| y.is_finite() && *y > 0.0)
    };
    let t_end = pos().map(|p| p.0).fold(1.0, f64::max);
    let lo = pos().map(|p| p.1).fold(f64::INFINITY, f64::min).max(1e-12);
    let hi = pos().map(|p| p.1).fold(0.0, f64::max).max(lo * 10.0);
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_end, (lo * 0.5..hi * 2.0).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("time [s]")
        .y_desc("speed spread [m/s]")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()
        .map_err(err)?;
    for (k, r) in results.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(
                r.spread
                    .iter()
                    .copied()
                    .filter(|(_, y)| y.is_finite() && *y > 0.0),
                colour.stroke_width(2),
            ))
            .map_err(err)?
            .label(r.name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// `compare_spread.png` and `.svg`: every run's speed spread on one log scale.
fn spread_plot(out: &Path, title: &str, results: &[RunResult]) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::plots::ensure_font();
    let png = out.join("compare_spread.png");
    draw_spread(
        &BitMapBackend::new(&png, (900, 500)).into_drawing_area(),
        title,
        results,
    )
    .with_context(|| format!("cannot write {}", png.display()))?;
    let svg = out.join("compare_spread.svg");
    draw_spread(
        &SVGBackend::new(&svg, (900, 500)).into_drawing_area(),
        title,
        results,
    )
    .with_context(|| format!("cannot write {}", svg.display()))?;
    Ok(())
}

/// `syncroad compare`.
pub fn run(a: &CompareArgs) -> anyhow::Result<u8> {
    let sc = load_scenario(&a.scenario)?;
    let plan = plan(&sc, a)?;
    let interrupt = interrupt_flag()?;
    let (doc, results) = compare_into(&sc, &plan, &a.out, interrupt.clone())?;
    println!(
        "{}: {} vehicles, seed {}, warm-up {} s, {}, emission class {}",
        sc.name,
        sc.n,
        sc.file.seed,
        plan.warmup_s,
        doc["sumo_version"].as_str().unwrap_or("?"),
        syncroad_sumo::drivers::EMISSION_CLASS
    );
    if let Some((_, _, x)) = sc
        .is_ring()
        .then(|| layout_for(&sc, 0.0).ok())
        .flatten()
        .and_then(|l| loop_position(&l.road))
    {
        println!("induction loop loop0 at ring coordinate {x:.2} m");
    }
    print!("{}", table(&doc));
    if let Some(red) = doc
        .get("mixed_reduction_vs_all_human")
        .and_then(|r| r.as_object())
    {
        for (k, v) in red {
            let pct = |x: &Value| {
                x.as_f64()
                    .map_or("—".into(), |x| format!("{:+.1} %", -100.0 * x))
            };
            println!(
                "{k} vs mixed-0 (all human): speed std {}, fuel per km {}",
                pct(&v["speed_std_reduction"]),
                pct(&v["fuel_per_km_reduction"])
            );
        }
    }
    println!(
        "wrote {}/compare.json and one folder per run ({})",
        a.out.display(),
        plan.runs
            .iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    if interrupt.load(Ordering::SeqCst) {
        return Ok(exit_codes::INTERRUPTED);
    }
    let failed: Vec<&RunResult> = results.iter().filter(|r| !r.complete).collect();
    for r in &failed {
        eprintln!(
            "error: run {} failed: {}",
            r.name,
            r.error.as_deref().unwrap_or("?")
        );
    }
    Ok(if failed.is_empty() {
        exit_codes::SUCCESS
    } else {
        exit_codes::RUN_FAILED
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixed_vehicles_are_evenly_spaced() {
        assert_eq!(mixed_controlled(22, 0), Vec::<usize>::new());
        assert_eq!(mixed_controlled(22, 1), [0]);
        assert_eq!(mixed_controlled(22, 2), [0, 11]);
        assert_eq!(mixed_controlled(22, 4), [0, 5, 11, 16]);
    }
}
