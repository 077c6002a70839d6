//! `syncroad run` (scenarios with `"backend": "sumo"`) and `syncroad sumo-bench`: the scenario's law on SUMO traffic, through
//! libsumo in a supervised worker process (crate `syncroad-sumo`).
//!
//! `main` first checks `syncroad_sumo::is_worker_invocation()`: the CLI re-executes itself as
//! the worker process of each SUMO run.
//!
//! Exit codes: 0 synchronized, 1 not synchronized, 2 bad input (everything checked before SUMO
//! starts: scenario, network file, ring capacity, road length), 3 the run failed (worker crash,
//! timeout, non-finite command, vehicle lost; partial results written and marked incomplete),
//! 130 Ctrl-C (partial results written).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use serde_json::json;
use syncroad_control::congestion::congestion_metrics;
use syncroad_control::metrics::sync_metrics;
use syncroad_control::scenario::Model;
use syncroad_control::{theory, Verdict};
use syncroad_sumo::bench::{format_table, run_case, standard_cases};
use syncroad_sumo::protocol::ReadMode;
use syncroad_sumo::{interrupt_flag, run_scenario, RunOptions, WorkerCommand};

use crate::cli::OutputArgs;
use crate::commands::{default_record_every, load_scenario, thresholds, InputError};
use crate::exit_codes;
use crate::report;

/// Options of the SUMO backend.
#[derive(Debug, Clone, clap::Args)]
pub struct SumoArgs {
    /// Wall-clock limit of the SUMO run [s] (default: the scenario's sumo.timeout_s).
    #[arg(long)]
    pub timeout_s: Option<f64>,
    /// Baseline: let SUMO's own car-following model (Krauss with this σ, e.g. 0.5) drive
    /// instead of the scenario's law.
    #[arg(long)]
    pub krauss_sigma: Option<f64>,
    /// Use SUMO's default Euler position update (x += Δt v^{n+1}) instead of the ballistic
    /// (trapezoidal) one the native simulator shares.
    #[arg(long)]
    pub euler: bool,
    /// Read states through libsumo subscriptions instead of per-vehicle getters.
    #[arg(long)]
    pub subscriptions: bool,
}

/// Runs a scenario in SUMO; writes trajectories.csv and metrics.json (and SUMO's routes file
/// and log under `<out>/sumo/`), even when the run fails part-way.
pub fn run(path: &Path, out: &OutputArgs, args: &SumoArgs) -> anyhow::Result<u8> {
    let sc = load_scenario(path)?;
    let th = thresholds(&sc, out)?;
    if out.record_every == Some(0) {
        return Err(InputError("--record-every = 0: must be ≥ 1".into()).into());
    }
    let timeout =
        match args.timeout_s {
            Some(t) => Some(Duration::try_from_secs_f64(t).map_err(|_| {
                InputError(format!("--timeout-s = {t}: must be a finite number ≥ 0"))
            })?),
            None => None,
        };
    std::fs::create_dir_all(&out.out)
        .with_context(|| format!("cannot create output folder {}", out.out.display()))?;
    let worker = WorkerCommand::current_exe().context("cannot locate the syncroad executable")?;
    let mut opts = RunOptions::new(out.out.join("sumo"), worker);
    opts.record_every = out
        .record_every
        .unwrap_or_else(|| default_record_every(sc.steps, sc.n));
    opts.ballistic = !args.euler;
    opts.sumo_model_sigma = args.krauss_sigma;
    opts.timeout = timeout;
    opts.interrupt = Some(interrupt_flag()?);
    if args.subscriptions {
        opts.read = ReadMode::Subscriptions;
    }
    let run = run_scenario(&sc, &opts).map_err(|e| InputError(e.to_string()))?;
    let outcome = run.outcome();
    let traj = run.trajectory(&sc);
    let desired = match &sc.model {
        Model::Cacc(c) => Some(c.desired_gap_m.as_slice()),
        Model::DelayedDriver(_) => None,
    };
    let sync = sync_metrics(&traj, th, desired, outcome.is_err());
    let ring = sc.is_ring().then(|| run.road_length_m());
    let warmup = out.warmup_s.unwrap_or(0.25 * sc.horizon_s());
    let congestion = congestion_metrics(&traj, warmup, ring);
    let theory = theory::report(&sc);
    let start = run.worker.start.as_ref();
    let finish = run.worker.result.as_ref().ok();
    let extra = json!({
        "complete": outcome.is_ok(),
        "error": outcome.as_ref().err().map(|e| e.to_string()),
        "sumo_version": start.map(|s| s.python.sumo_version.clone()),
        "libsumo": start.map(|s| s.python.libsumo_file.clone()),
        "road_length_m": run.road_length_m(),
        "gap_scale": run.request.layout.gap_scale,
        "controller": if args.krauss_sigma.is_some() { "sumo_krauss" } else { "law" },
        "krauss_sigma": args.krauss_sigma,
        "step_method": if args.euler { "euler" } else { "ballistic" },
        "totals": finish.map(|f| &f.totals),
        "events": &run.worker.events,
    });
    let stop = match (&run.worker.result, &outcome) {
        (Ok(f), _) => serde_json::to_value(&f.stop)?,
        (Err(_), Err(e)) => json!({"reason": "failed", "error": e.to_string()}),
        (Err(_), Ok(_)) => unreachable!("an Ok outcome has a finish"),
    };
    let record = report::RunRecord {
        scenario: &sc,
        backend: "sumo",
        trajectory: &traj,
        sync: &sync,
        congestion: congestion.as_ref().ok(),
        stop,
        theory: &theory,
        extra: Some(extra),
    };
    record.write(&out.out)?;
    let (csv, metrics) = (
        out.out.join("trajectories.csv"),
        out.out.join("metrics.json"),
    );
    print!(
        "{}",
        report::metrics_table(
            &sc,
            "sumo",
            &sync,
            outcome.as_ref().err().map(|e| e.to_string()).as_deref(),
            &theory
        )
    );
    if let Some(s) = start {
        println!(
            "  SUMO: {} (libsumo {}), ring/road length {:.4} m",
            s.python.sumo_version, s.python.libsumo_file, s.road_length_m
        );
    }
    if let Some(f) = finish {
        let t = &f.totals;
        println!(
            "  SUMO safety: {} collision steps, {} teleports, {} overridden commands (max {:.3} m/s), {} negative commands sent as 0",
            t.collision_steps, t.teleports, t.overrides, t.max_override_mps, t.negative_commands_clamped
        );
    }
    println!(
        "wrote {} and {}{}",
        csv.display(),
        metrics.display(),
        if outcome.is_ok() {
            ""
        } else {
            " (incomplete run)"
        }
    );
    if outcome.is_ok() && !out.no_plots {
        let plots = crate::plots::RunPlots {
            traj: &traj,
            ring_length_m: ring,
            title: format!("{} (SUMO)", sc.name),
        };
        let files = plots.write_all(&out.out)?;
        println!(
            "wrote {} plots: time_space, speeds, spread (PNG and SVG)",
            files.len()
        );
    }
    match outcome {
        Err(e) => {
            eprintln!("error: {e}");
            Ok(e.exit_code().unwrap_or(exit_codes::RUN_FAILED))
        }
        Ok(_) => Ok(match sync.verdict {
            Verdict::Synchronized => exit_codes::SUCCESS,
            _ => exit_codes::NOT_SYNCHRONIZED,
        }),
    }
}

/// The SUMO benchmark: SUMO alone vs SUMO + controller vs the TraCI reference at N = 22 and
/// N = 2000; prints a table, optionally writes JSON.
pub fn bench(quick: bool, json_out: Option<&PathBuf>) -> anyhow::Result<u8> {
    let repo = syncroad_sumo::repo_dir();
    let worker = WorkerCommand::current_exe().context("cannot locate the syncroad executable")?;
    let work = std::env::temp_dir().join(format!("syncroad-sumo-bench-{}", std::process::id()));
    let mut results = Vec::new();
    for case in standard_cases(&repo.join("sumo-nets"), quick) {
        let mut progress = |l: &str| eprintln!("{l}");
        results.push(run_case(
            &case,
            &worker,
            &work,
            &repo.join("python-host"),
            &mut progress,
        )?);
    }
    let _ = std::fs::remove_dir_all(&work);
    print!("{}", format_table(&results));
    if let Some(p) = json_out {
        std::fs::write(p, serde_json::to_string_pretty(&results)? + "\n")
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(exit_codes::SUCCESS)
}
