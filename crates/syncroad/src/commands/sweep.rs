//! `syncroad sweep`: run a sweep spec (or a shard of it) into a resumable folder, write the
//! results table and its plots; `syncroad sweep collect` merges shard folders;
//! `--emit-slurm` writes the job array that runs the shards on a cluster.
//!
//! Exit codes: 0 every point of the shard has a row and none failed (whatever the runs found),
//! 1 a point matched `--fail-on`, 2 bad input (nothing ran), 3 some point failed or (collect)
//! is missing or duplicated, 130 interrupted (the rows of finished points are kept; run the
//! same command again to resume).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use serde_json::{Map, Value};
use syncroad_sumo::interrupt_flag;

use crate::cli::{SweepAction, SweepArgs};
use crate::config;
use crate::error::{InputError, Status};
use crate::gate::{FailOn, Judged};
use crate::output::write_text;
use crate::stdout::outln;
use crate::sweep::exec;
use crate::sweep::rows::read_rows;
use crate::sweep::slurm::{self, SlurmOptions};
use crate::sweep::{plots, ExecOptions, Shard, Sweep};
use syncroad_control::scenario::SafetyMode;

/// Dispatches `sweep` and `sweep collect`.
pub fn run(a: &SweepArgs) -> anyhow::Result<Status> {
    if let Some(SweepAction::Collect {
        spec,
        out,
        shards,
        no_plots,
        fail_on,
        safety,
    }) = &a.action
    {
        return collect(spec, out, shards, !no_plots, fail_on, *safety);
    }
    let (Some(spec), Some(out)) = (&a.spec, &a.out) else {
        return Err(InputError::new("sweep needs a SPEC file and --out DIR").into());
    };
    let sweep = Sweep::load_with(spec, a.safety)?;
    check_gate(&sweep, &a.fail_on)?;
    if let Some(dir) = &a.emit_slurm {
        return emit(&sweep, spec, out, dir, a);
    }
    let shard = match &a.shard {
        Some(s) => Shard::parse(s)?,
        None => Shard::all(),
    };
    let opts = ExecOptions {
        jobs: config::jobs(a.jobs)?,
        shard,
        keep_runs: a.keep_runs,
        run_plots: a.run_plots,
        retry_failed: a.retry_failed,
        fcd: a.fcd,
        fcd_every: config::fcd_every(a.fcd_every)?,
    };
    let _lock = exec::open_out(&sweep, out, shard)?;
    let interrupt = interrupt_flag()?;
    let started = Instant::now();
    let summary = exec::run(&sweep, out, &opts, interrupt)?;
    let wall = started.elapsed().as_secs_f64();
    let rows = read_rows(&sweep, out, shard)?;
    let finished = rows.len();
    // Failed before this call too (a resumed sweep skips them unless --retry-failed).
    let failed = rows
        .values()
        .filter(|r| r.get("status").and_then(Value::as_str) == Some("failed"))
        .count();
    let unsafe_line = unsafe_line(&rows);
    let gated = gate(&rows, &a.fail_on);
    write_tables(&sweep, out, rows, !a.no_plots)?;
    let shard_text = if shard.count > 1 {
        format!(" (shard {}/{})", shard.index, shard.count)
    } else {
        String::new()
    };
    outln!(
        "sweep {}: {} points{shard_text}; ran {} ({} failed), {} finished before, {} not run (interrupted)",
        sweep.name, summary.points, summary.ran, summary.failed, summary.skipped, summary.interrupted
    );
    outln!("{unsafe_line}");
    // Throughput of the runs that ran to their end (a sweep that simulated nothing prints none).
    let simulated = summary.ran.saturating_sub(summary.failed);
    if simulated > 0 {
        // syncroad's own vehicles; a road of inflows only has none to count (its vehicles
        // come and go), so it says runs per second alone.
        let n = sweep.base.vehicles();
        let vehicle_seconds = if n > 0 {
            let veh_s = n as f64 * sweep.base.horizon_s() * simulated as f64;
            format!(", {:.0} simulated vehicle-seconds per second", veh_s / wall)
        } else {
            String::new()
        };
        outln!(
            "  {:.2} runs/s{vehicle_seconds} ({} jobs{})",
            summary.ran as f64 / wall,
            opts.jobs,
            if summary.workers > 0 {
                format!(", {} SUMO worker processes", summary.workers)
            } else {
                String::new()
            }
        );
        if summary.sumo_step_s > 0.0 {
            // The points' time inside SUMO's step, spread over the jobs that could step at
            // once (no more than the points and the cores), is the least wall time these runs
            // could take: the rest is syncroad's loop, starts and evaluation.
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            let lanes = opts.jobs.min(summary.ran).min(cores).max(1);
            let bound = summary.sumo_step_s / lanes as f64;
            outln!(
                "  inside SUMO's step: {:.1} s over the points; stepped {} at a time at least {:.1} s, this sweep {:.1} s ({:.2}x its stepping bound)",
                summary.sumo_step_s,
                lanes,
                bound,
                wall,
                wall / bound
            );
        }
    }
    outln!(
        "wrote {} rows to {}/results.parquet and results.csv",
        finished,
        out.display()
    );
    if summary.interrupted > 0 {
        crate::stdout::errln!(
            "error: interrupted; {} points not run. Run the same command again to finish them.",
            summary.interrupted
        );
        return Ok(Status::Interrupted);
    }
    if failed > 0 {
        crate::stdout::errln!(
            "error: some points failed; their rows hold the error (status = \"failed\"); --retry-failed runs them again"
        );
        return Ok(Status::RunFailed);
    }
    Ok(gated)
}

/// `--fail-on` a finding the sweep's table has no column for is refused before any point runs.
fn check_gate(sweep: &Sweep, fail_on: &[FailOn]) -> Result<(), InputError> {
    let verdicts = fail_on
        .iter()
        .find(|f| matches!(f, FailOn::NotSynchronized | FailOn::Inconclusive));
    match verdicts {
        Some(f) if !sweep.metrics.iter().any(|m| m == "sync.verdict") => {
            Err(InputError::new(format!(
                "--fail-on {}: the sweep's metrics leave out sync.verdict, so no row says whether its run synchronized; add \"sync.verdict\" to the spec's \"metrics\" or gate on unsafe only",
                clap::ValueEnum::to_possible_value(f).map_or_else(String::new, |v| v.get_name().to_string())
            )))
        }
        _ => Ok(()),
    }
}

/// What `--fail-on` makes of the rows (a point is named by its number and run).
fn gate(rows: &BTreeMap<usize, Map<String, Value>>, fail_on: &[FailOn]) -> Status {
    crate::gate::judge(
        fail_on,
        rows.iter().map(|(id, r)| Judged {
            name: format!(
                "{id} ({})",
                r.get("run").and_then(Value::as_str).unwrap_or("?")
            ),
            verdict: r.get("sync.verdict").and_then(Value::as_str),
            safe: r.get("safe").and_then(Value::as_bool),
        }),
    )
}

fn write_tables(
    sweep: &Sweep,
    out: &Path,
    rows: BTreeMap<usize, Map<String, Value>>,
    plots: bool,
) -> anyhow::Result<()> {
    let table = exec::table(sweep, rows);
    table.write_parquet(&out.join("results.parquet"))?;
    table.write_csv(&out.join("results.csv"))?;
    if plots && !table.rows.is_empty() {
        let files = plots::draw(sweep, &table, &out.join("plots"))?;
        if !files.is_empty() {
            outln!("wrote {} plots to {}/plots", files.len() / 2, out.display());
        }
    }
    Ok(())
}

/// The options of `a` that each array task of an emitted Slurm job passes on to its own
/// `syncroad sweep` of one shard.
fn task_flags(a: &SweepArgs) -> anyhow::Result<Vec<String>> {
    let mut f: Vec<String> = [
        (a.keep_runs, "--keep-runs"),
        (a.run_plots, "--run-plots"),
        (a.fcd, "--fcd"),
        (a.retry_failed, "--retry-failed"),
    ]
    .into_iter()
    .filter(|(on, _)| *on)
    .map(|(_, flag)| flag.to_string())
    .collect();
    if a.fcd_every.is_some() {
        f.push("--fcd-every".into());
        f.push(config::fcd_every(a.fcd_every)?.to_string());
    }
    f.extend(safety_flag(a.safety));
    Ok(f)
}

/// `--safety LAYER` as given, for the commands an emitted job runs (its hash depends on it).
fn safety_flag(safety: Option<SafetyMode>) -> Vec<String> {
    safety
        .map(|m| vec!["--safety".to_string(), m.name().to_string()])
        .unwrap_or_default()
}

fn emit(
    sweep: &Sweep,
    spec: &Path,
    out: &Path,
    dir: &Path,
    a: &SweepArgs,
) -> anyhow::Result<Status> {
    // What the array sets itself is refused, not dropped.
    if let Some(s) = &a.shard {
        return Err(InputError::new(format!(
            "--shard {s}: with --emit-slurm each array task runs one shard of --shards (here {}); drop --shard",
            a.shards
        ))
        .into());
    }
    if let Some(j) = a.jobs {
        return Err(InputError::new(format!(
            "--jobs {j}: with --emit-slurm each array task runs --cpus-per-task points at once (here {}); drop --jobs, or set --cpus-per-task {j}",
            a.cpus_per_task
        ))
        .into());
    }
    let opts = SlurmOptions {
        shards: a.shards,
        max_running: a.max_running,
        cpus_per_task: a.cpus_per_task,
        partition: a.partition.clone(),
        account: a.account.clone(),
        time: a.time.clone(),
        extra: a.sbatch_option.clone(),
        task_flags: task_flags(a)?,
        collect_flags: safety_flag(a.safety),
    };
    let e = slurm::emit(&sweep.name, spec, out, dir, &opts)?;
    outln!(
        "sweep {}: {} points in {} shards; wrote {}, {} and {}",
        sweep.name,
        sweep.len(),
        opts.shards,
        e.array.display(),
        e.collect.display(),
        e.submit.display()
    );
    outln!("submit with: bash {}", slurm::shell_word(&e.submit));
    outln!(
        "the merged table will be {}/merged/results.parquet; submitting again resumes unfinished shards",
        out.display()
    );
    Ok(Status::Success)
}

/// How many of the rows are of unsafe runs (`safe` = false): the line every sweep summary
/// prints beside its failed points.
/// How many runs were unsafe, of those that could be judged (a run that never started has no
/// `safe`, and is not counted as safe).
fn unsafe_line(rows: &BTreeMap<usize, Map<String, Value>>) -> String {
    let judged: Vec<bool> = rows
        .values()
        .filter_map(|r| r.get("safe").and_then(Value::as_bool))
        .collect();
    let n = judged.iter().filter(|s| !**s).count();
    let unjudged = rows.len() - judged.len();
    format!(
        "  unsafe: {n} of {} runs (collisions, overlaps, teleports or emergency braking: column safe = false){}",
        judged.len(),
        if unjudged > 0 {
            format!("; {unjudged} not judged (no run to judge: column safe empty)")
        } else {
            String::new()
        }
    )
}

fn collect(
    spec: &Path,
    out: &Path,
    shards: &[std::path::PathBuf],
    plots: bool,
    fail_on: &[FailOn],
    safety: Option<SafetyMode>,
) -> anyhow::Result<Status> {
    let sweep = Sweep::load_with(spec, safety)?;
    check_gate(&sweep, fail_on)?;
    let mut merged: BTreeMap<usize, Map<String, Value>> = BTreeMap::new();
    let mut from: BTreeMap<usize, &Path> = BTreeMap::new();
    let mut duplicated = Vec::new();
    for dir in shards {
        let meta = dir.join("sweep.json");
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&meta).map_err(|e| {
            InputError::new(format!("{}: not a sweep folder ({e})", dir.display()))
        })?)
        .with_context(|| format!("{} is not valid JSON", meta.display()))?;
        if doc["spec_hash"].as_str() != Some(sweep.hash.as_str()) {
            return Err(InputError::new(format!(
                "{}: ran another spec or base scenario (hash {}, {} has {})",
                dir.display(),
                doc["spec_hash"].as_str().unwrap_or("?"),
                spec.display(),
                sweep.hash
            ))
            .into());
        }
        for (id, row) in read_rows(&sweep, dir, Shard::all())? {
            if let Some(first) = from.get(&id) {
                duplicated.push(format!(
                    "{id} (in {} and {})",
                    first.display(),
                    dir.display()
                ));
                continue;
            }
            from.insert(id, dir);
            merged.insert(id, row);
        }
    }
    let missing: Vec<usize> = (0..sweep.len())
        .filter(|id| !merged.contains_key(id))
        .collect();
    let _lock = exec::open_out(&sweep, out, Shard::all())?;
    // The merged folder holds the rows too, so it resumes like any sweep folder.
    for (id, row) in &merged {
        let text = serde_json::to_string(row)? + "\n";
        let path = out.join("rows").join(format!("{id:07}.json"));
        write_text(&path, &text)?;
    }
    let rows = merged.len();
    let unsafe_line = unsafe_line(&merged);
    let gated = gate(&merged, fail_on);
    write_tables(&sweep, out, merged, plots)?;
    outln!(
        "collected {rows} of {} points from {} shard folders into {}/results.parquet and results.csv",
        sweep.len(),
        shards.len(),
        out.display()
    );
    outln!("{unsafe_line}");
    let mut ok = true;
    if !missing.is_empty() {
        ok = false;
        let shown: Vec<String> = missing.iter().take(20).map(usize::to_string).collect();
        crate::stdout::errln!(
            "error: {} points missing: {}{} (run their shards again; finished points are skipped)",
            missing.len(),
            shown.join(", "),
            if missing.len() > 20 { ", ..." } else { "" }
        );
    }
    if !duplicated.is_empty() {
        ok = false;
        crate::stdout::errln!(
            "error: {} points duplicated: {} (the first copy is kept)",
            duplicated.len(),
            duplicated
                .iter()
                .take(20)
                .cloned()
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(if ok { gated } else { Status::RunFailed })
}
