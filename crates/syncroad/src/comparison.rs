//! A comparison: one scenario, several drivers, planned and run as one batch. The same
//! network, vehicles, initial state and seed run with the scenario's law and with SUMO's own
//! car-following models (Krauss with σ 0.5 and, for stop-and-go waves at ring density, σ 0.9;
//! IDM; for platoons ACC and CACC), and on mixed rings where only some vehicles run the law.
//!
//! A [`Request`] (from `syncroad compare`'s flags or a regress baseline) becomes a [`Plan`]
//! (every run a [`RunPlan`], all checked before any starts), run by the one batch runner.
//! Every run is its own SUMO worker process; each writes its own folder (trajectories.csv,
//! metrics.json, plots); a failed run is marked and the others still report. The combined
//! `compare.json` holds the stamps once (syncroad and SUMO versions, platform, seed, scenario
//! hash) and each run's metrics without them, so it is the document `syncroad regress`
//! compares for baselines of kind `compare`.

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::Context;
use serde_json::{json, Value};
use syncroad_control::drive::{mixed_controllers, mixed_series, Drive, DEFAULT_MIXED_CONTROLLER};
use syncroad_control::record::SHARED_KEYS;
use syncroad_control::scenario::Model;
use syncroad_control::{EvalOptions, RunRecord, Scenario, SumoDriver};
use syncroad_sumo::{
    check_sumo_numbers, load_road, Road, WorkerCommand, WorkerPool, EMISSION_CLASS,
};

use crate::batch::JobEnd;
use crate::config;
use crate::error::InputError;
use crate::output::{self, write_json};
use crate::pipeline::{self, Finished};
use crate::plan::{folder_name, Measurements, RunPlan};
use crate::plots::{spread_plot, Spread, SpreadLabels};

/// A validated comparison.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The runs in column order, each planned whole (drivers, recording, measurements,
    /// evaluation, time limit).
    pub runs: Vec<RunPlan>,
    /// Parallel workers.
    pub jobs: usize,
    /// Warm-up of every run [s].
    pub warmup_s: f64,
    /// Draw plots.
    pub plots: bool,
    /// Mixed runs: name and count of automated vehicles.
    pub mixed_runs: Vec<(String, usize)>,
    /// The scenario's road, read once for every run.
    pub road: Road,
    /// How finished runs are reported (`None`: a bar on a terminal, a line each elsewhere).
    pub progress: Option<crate::progress::ProgressMode>,
}

/// What a comparison runs and how, whoever asks: `syncroad compare`'s flags, or a regress
/// baseline's `runs` and `mixed`. [`plan`] checks it against the scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    /// Run names, comma-separated (`None`: the default set for the road).
    pub baselines: Option<String>,
    /// Automated-vehicle counts of the mixed runs, comma-separated.
    pub mixed: Option<String>,
    /// The mixed runs' human driver.
    pub mixed_driver: String,
    /// The mixed runs' automated controllers, comma-separated.
    pub mixed_controller: String,
    /// Measure SUMO's surrogate safety measures.
    pub ssm: bool,
    /// Parallel runs (`None`: every core).
    pub jobs: Option<usize>,
    /// Warm-up excluded from the congestion metrics [s].
    pub warmup_s: Option<f64>,
    /// Read fuel and CO2 every this many steps.
    pub emission_every: usize,
    /// Record every this many steps.
    pub record_every: Option<usize>,
    /// Per-run wall-clock limit [s].
    pub timeout_s: Option<f64>,
    /// Draw the plots.
    pub plots: bool,
    /// Every run also writes SUMO's floating-car data for `syncroad replay`.
    pub fcd: bool,
    /// That floating-car data every this many steps (`None`: every step).
    pub fcd_every: Option<usize>,
    /// How finished runs are reported (`None`: a bar on a terminal, a line each elsewhere).
    pub progress: Option<crate::progress::ProgressMode>,
}

impl Request {
    /// `baselines` and `mixed` with every other choice at `syncroad compare`'s defaults, and
    /// no plots (a regression check).
    pub fn runs(baselines: Option<String>, mixed: Option<String>) -> Self {
        Self {
            baselines,
            mixed,
            mixed_driver: syncroad_control::drive::DEFAULT_HUMAN.into(),
            mixed_controller: DEFAULT_MIXED_CONTROLLER.into(),
            ssm: false,
            jobs: None,
            warmup_s: None,
            emission_every: 1,
            record_every: None,
            timeout_s: None,
            plots: false,
            fcd: false,
            fcd_every: None,
            progress: None,
        }
    }
}

/// The `--baselines` runs: the law, dampers (on a ring) and SUMO drivers, each once.
fn baseline_runs(sc: &Scenario, a: &Request) -> anyhow::Result<Vec<Drive>> {
    let bad = |m: String| anyhow::Error::new(InputError::new(m));
    let n = sc.vehicles();
    let default = if sc.is_ring() {
        "protocol,krauss,krauss-0.9,idm"
    } else {
        "protocol,krauss,idm,acc,cacc"
    };
    let list = a
        .baselines
        .as_deref()
        .unwrap_or(if a.mixed.is_some() { "" } else { default });
    let mut runs: Vec<Drive> = Vec::new();
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let mut spec = Drive::parse("--baselines", name, n)
            .map_err(|e| InputError::about("--baselines", e))?;
        // The scenario's own law is the user's controller when it names one: the run says so.
        if let (true, Some(c)) = (spec.name == "protocol", sc.controller()) {
            spec.name = c.label();
        }
        if let Some(d) = &spec.damper {
            d.require_road(sc.is_ring(), &format!("scenario {}", sc.name()))
                .map_err(|e| InputError::caused("--baselines", e))?;
        }
        if runs.iter().any(|r| r.name == spec.name) {
            return Err(bad(format!("--baselines: {} is listed twice", spec.name)));
        }
        runs.push(spec);
    }
    Ok(runs)
}

/// The `--mixed` runs (K automated vehicles of each `--mixed-controller` among
/// `--mixed-driver` humans; the all-human ring once) with their names and counts.
fn mixed_runs(sc: &Scenario, a: &Request) -> anyhow::Result<MixedRuns> {
    let bad = |m: String| anyhow::Error::new(InputError::new(m));
    let n = sc.vehicles();
    let mut runs: Vec<Drive> = Vec::new();
    let mut mixed = Vec::new();
    let mut mixed_runs = Vec::new();
    if let Some(m) = &a.mixed {
        let names: Vec<&str> = a.mixed_controller.split(',').collect();
        let controllers = mixed_controllers("--mixed-controller", &names)
            .map_err(|e| InputError::about("--mixed-controller", e))?;
        let law = controllers.iter().any(|c| c.is_law());
        if law && (!sc.is_ring() || !matches!(sc.model(), Model::DelayedDriver(_))) {
            return Err(bad(format!(
                "--mixed = {m}: mixed traffic needs a ring of delayed drivers (scenario {} is not one)",
                sc.name()
            )));
        }
        for d in controllers.iter().filter_map(|c| c.damper.as_ref()) {
            d.require_road(sc.is_ring(), &format!("scenario {}", sc.name()))
                .map_err(|e| InputError::caused(format!("--mixed = {m}"), e))?;
        }
        let human = SumoDriver::parse("--mixed-driver", &a.mixed_driver)
            .map_err(|e| InputError::about("--mixed-driver", e))?;
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
            for run in mixed_series(n, k, &k.to_string(), &controllers, &human) {
                mixed_runs.push((run.name.clone(), k));
                runs.push(run);
            }
        }
    }
    Ok((runs, mixed_runs))
}

/// Mixed runs and, for each, its name and count of automated vehicles.
type MixedRuns = (Vec<Drive>, Vec<(String, usize)>);

/// Parses and checks every option before anything runs.
pub fn plan(sc: &Scenario, a: &Request) -> anyhow::Result<Plan> {
    let bad = |m: String| anyhow::Error::new(InputError::new(m));
    if sc.vehicles() == 0 {
        // Every run would drive the same traffic: the drivers are SUMO's and the inflows' laws.
        return Err(bad(format!(
            "scenario {}: no vehicles of its own (\"vehicles\": 0), so every driver a comparison swaps in would drive nobody; compare the inflows' drivers in a sweep over sumo.inflows[k].controlled instead (the guide's \"Open roads\")",
            sc.name()
        )));
    }
    let mut runs = baseline_runs(sc, a)?;
    // Two spellings of one driver among the named runs are one run twice. (The mixed series
    // may repeat a named run on purpose: mixed-0, all humans, is its reference.)
    for (i, r) in runs.iter().enumerate() {
        if let Some(o) = runs[..i].iter().find(|o| o.same_run(r)) {
            return Err(bad(format!(
                "--baselines: {} and {} are the same run (the same drivers, however spelt); a comparison runs each once — drop one",
                o.name, r.name
            )));
        }
    }
    let (mixed, mixed_runs) = mixed_runs(sc, a)?;
    runs.extend(mixed);
    if runs.is_empty() {
        return Err(bad(
            "--baselines is empty: name at least one run (e.g. protocol,krauss) or give --mixed"
                .into(),
        ));
    }
    let jobs = config::jobs(a.jobs)?;
    let warmup_s = config::warmup_s(a.warmup_s, sc)?;
    if a.emission_every == 0 {
        return Err(bad(
            "--emission-every = 0: must be ≥ 1 (1 = read fuel and CO2 every step)".into(),
        ));
    }
    // Everything SUMO would reject, before any worker starts; the road is read once.
    let before = |e| InputError::caused("before starting SUMO", e);
    check_sumo_numbers(sc).map_err(before)?;
    let road = load_road(sc).map_err(before)?;
    syncroad_sumo::layout_for(sc, &road).map_err(before)?;
    for (i, r) in runs.iter().enumerate() {
        if let Some(o) = runs[..i]
            .iter()
            .find(|o| folder_name(&o.name) == folder_name(&r.name))
        {
            return Err(bad(format!(
                "--baselines: runs {} and {} would write the same folder {}; name one of them otherwise",
                o.name,
                r.name,
                folder_name(&r.name)
            )));
        }
    }
    let record_every = config::record_every(a.record_every, sc)?;
    let fcd_every = config::fcd_every(a.fcd_every)?;
    let timeout = config::timeout(a.timeout_s)?;
    let mut eval = EvalOptions::of(sc);
    eval.warmup_s = warmup_s;
    let measure = Measurements {
        emission_every: a.emission_every,
        tripinfo: true,
        ssm: a.ssm,
        emissions: syncroad_control::sumo_facts::Emissions::ALL,
    };
    let runs: Vec<RunPlan> = runs
        .into_iter()
        .map(|spec| {
            let mut run = RunPlan::new(spec, record_every, eval);
            run.timeout = timeout;
            run.measure = Some(measure);
            run.fcd = a.fcd;
            run.fcd_every = fcd_every;
            run
        })
        .collect();
    // Every run as SUMO will be given it (drivers, their step-dependent values, measurements),
    // before any run starts: a driver SUMO cannot take is bad input, not a run that failed
    // after the others ran.
    let worker = WorkerCommand::binary("syncroad");
    for run in &runs {
        let opts = run.sumo_options(std::env::temp_dir(), worker.clone(), None);
        syncroad_sumo::check_run(sc, &road, &opts).map_err(|e| {
            InputError::caused(format!("run {}: before starting SUMO", run.name()), e)
        })?;
    }
    Ok(Plan {
        runs,
        jobs,
        warmup_s,
        plots: a.plots,
        mixed_runs,
        road,
        progress: a.progress,
    })
}

/// What one run left behind.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// The run's name.
    pub name: String,
    /// Its record (stamps included), or why it never produced one.
    pub record: Result<RunRecord, String>,
    /// The speed spread over time, for the combined plot.
    pub spread: Spread,
}

impl RunResult {
    /// Reached the horizon.
    pub fn complete(&self) -> bool {
        self.record.as_ref().is_ok_and(|r| r.complete)
    }

    /// Why not.
    pub fn error(&self) -> Option<&str> {
        match &self.record {
            Ok(r) => r.error.as_deref(),
            Err(e) => Some(e),
        }
    }
}

/// One run through the pipeline on a worker of `pool`, written into `dir`.
fn run_one(
    sc: &Scenario,
    run: &RunPlan,
    plan: &Plan,
    dir: &Path,
    pool: &WorkerPool,
    interrupt: &Arc<AtomicBool>,
) -> anyhow::Result<RunResult> {
    let opts = run.sumo_options(
        dir.join(output::SUMO_WORK_DIR),
        pool.command().clone(),
        Some(interrupt.clone()),
    );
    // A run of the user's own controller (`--baselines python:…`) is the scenario with it.
    let own;
    let sc = match &run.drive.user {
        Some(u) => {
            own = sc.with_controller(u.clone());
            &own
        }
        None => sc,
    };
    let out = pipeline::sumo_pooled(sc, &plan.road, &opts, pool)
        .map_err(|e| InputError::caused("before starting SUMO", e))?;
    let f = Finished::new(sc, run.name(), out.output, run.eval);
    let title = plan.plots.then(|| format!("{}: {}", sc.name(), run.name()));
    f.write(dir, title)?;
    Ok(RunResult {
        name: run.name().to_string(),
        spread: Spread::of(run.name(), &f.output.trajectory),
        record: Ok(f.record),
    })
}

/// Runs every run of the plan, `plan.jobs` at a time, with a progress bar on stderr. A run
/// that fails keeps its place (marked) and never stops the others. The runs share `plan.jobs`
/// long-lived worker processes, as a sweep's points do: each run starts its own SUMO in one,
/// and a worker that crashed or was stopped is replaced (starting Python and loading libsumo
/// took more CPU than a short run's SUMO).
pub fn run_all(
    sc: &Scenario,
    plan: &Plan,
    out: &Path,
    interrupt: Arc<AtomicBool>,
) -> anyhow::Result<Vec<RunResult>> {
    let pool = WorkerPool::new(
        WorkerCommand::for_process().context("cannot locate the syncroad executable")?,
    );
    let ends = crate::batch::run(
        ("compare", plan.progress),
        plan.jobs,
        &interrupt,
        &plan.runs,
        |run| run.name().to_string(),
        |run| {
            let dir = out.join(run.folder());
            let r = run_one(sc, run, plan, &dir, &pool, &interrupt).unwrap_or_else(|e| RunResult {
                name: run.name().to_string(),
                record: Err(crate::error::describe(&e)),
                spread: Spread::default(),
            });
            let error = r.error().map(str::to_string);
            JobEnd::Done(r, error)
        },
    )?;
    // A run the interrupt kept from starting keeps its place, marked.
    Ok(plan
        .runs
        .iter()
        .zip(ends)
        .map(|(run, end)| {
            end.unwrap_or_else(|| RunResult {
                name: run.name().to_string(),
                record: Err("not started: interrupted".into()),
                spread: Spread::default(),
            })
        })
        .collect())
}

/// The combined document: stamps once, each run's metrics without them, and for `--mixed`
/// the reductions of every mixed run (name, automated vehicles) against the all-human ring.
pub fn combined(sc: &Scenario, results: &[RunResult], mixed: &[(String, usize)]) -> Value {
    let mut runs = serde_json::Map::new();
    for r in results {
        let mut m = match &r.record {
            Ok(rec) => rec.to_json(),
            Err(e) => json!({"run": r.name, "complete": false, "error": e}),
        };
        if let Value::Object(o) = &mut m {
            for k in SHARED_KEYS {
                o.remove(k);
            }
        }
        runs.insert(r.name.clone(), m);
    }
    let mut doc = json!({
        "syncroad_version": env!("CARGO_PKG_VERSION"),
        "platform": format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
        "sumo_version": results
            .iter()
            .find_map(|r| r.record.as_ref().ok()?.sumo_version.clone()),
        "scenario": sc.name(),
        "scenario_hash": sc.hash_hex(),
        "seed": sc.seed(),
        "emission_class": EMISSION_CLASS,
        "runs": Value::Object(runs.clone()),
    });
    if mixed.iter().any(|m| m.1 == 0) && mixed.iter().any(|m| m.1 > 0) {
        let get = |name: &str, path: &[&str]| -> Option<f64> {
            let mut v = runs.get(name)?;
            for p in path {
                v = v.get(p)?;
            }
            v.as_f64()
        };
        let std_path = ["congestion", "speed_std_mps"];
        let fuel_path = ["sumo", "fuel_g_per_km"];
        let mut red = serde_json::Map::new();
        for (name, _) in mixed.iter().filter(|m| m.1 > 0) {
            let rel = |p: &[&str]| match (get("mixed-0", p), get(name, p)) {
                (Some(h), Some(x)) if h != 0.0 => Some(1.0 - x / h),
                _ => None,
            };
            red.insert(
                name.clone(),
                json!({"speed_std_reduction": rel(&std_path), "fuel_per_km_reduction": rel(&fuel_path)}),
            );
        }
        doc["mixed_reduction_vs_all_human"] = Value::Object(red);
    }
    doc
}

/// Runs a comparison into `out` and returns the combined document (the CLI and `regress`).
/// No file it writes may be one of `inputs`.
pub fn compare_into(
    sc: &Scenario,
    plan: &Plan,
    out: &Path,
    inputs: &output::Inputs,
    interrupt: Arc<AtomicBool>,
) -> anyhow::Result<(Value, Vec<RunResult>)> {
    // Every folder (distinct: `plan` refuses two names that give one) is checked, and an
    // earlier comparison's files cleared, before any run.
    // The locks are held until the last file is written.
    let mut locks = vec![output::prepare_dir(
        "--out",
        out,
        &["compare.json"],
        inputs,
    )?];
    let mut files = vec![
        output::METRICS_FILE,
        output::TRAJECTORY_FILE,
        syncroad_control::user_text::FULL_TEXT_FILE,
    ];
    files.extend(crate::plots::RUN_PLOT_FILES);
    for run in &plan.runs {
        locks.push(output::prepare_dir(
            "--out",
            &out.join(run.folder()),
            &files,
            inputs,
        )?);
    }
    let results = run_all(sc, plan, out, interrupt)?;
    if plan.plots {
        let spreads: Vec<Spread> = results.iter().map(|r| r.spread.clone()).collect();
        let title = format!("{}: speed spread by driver", sc.name());
        let labels = SpreadLabels {
            stem: "compare_spread",
            title: &title,
            y_desc: "speed spread [m/s]",
        };
        spread_plot(out, &labels, &spreads)?;
    }
    let mut doc = combined(sc, &results, &plan.mixed_runs);
    doc["order"] = json!(plan.runs.iter().map(RunPlan::name).collect::<Vec<_>>());
    // Each run's folder under --out (its name made safe for paths).
    doc["folders"] = json!(plan
        .runs
        .iter()
        .map(|r| (r.name().to_string(), json!(r.folder())))
        .collect::<serde_json::Map<_, _>>());
    write_json(&out.join("compare.json"), &doc)?;
    drop(locks);
    Ok((doc, results))
}
