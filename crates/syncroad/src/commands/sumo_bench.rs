//! `syncroad sumo-bench`: SUMO alone vs SUMO + controller vs a TraCI-socket loop.

use std::path::Path;

use anyhow::Context;
use syncroad_sumo::bench::{
    format_profile, format_python, format_table, run_standard, BenchError, Selection,
};
use syncroad_sumo::WorkerCommand;

use crate::error::Status;
use crate::output::write_json;
use crate::stdout::{out, outln};

/// The SUMO benchmark: SUMO alone vs SUMO + controller vs the TraCI reference at N = 22 and
/// N = 2000 (or the cases `sel` keeps); prints a table, optionally writes JSON.
pub fn run(sel: &Selection, json_out: Option<&Path>) -> anyhow::Result<Status> {
    let worker = WorkerCommand::for_process().context("cannot locate the syncroad executable")?;
    let results = match run_standard(&worker, sel, &mut |l: &str| crate::stdout::errln!("{l}")) {
        // Refused before any measurement: bad input (exit 2), not a failed run.
        Err(e @ BenchError::UnknownCase { .. }) => {
            return Err(crate::error::InputError::new(format!("sumo-bench {e}")).into())
        }
        r => r?,
    };
    out!("{}", format_table(&results));
    out!("\nwhere a step goes:\n{}", format_profile(&results));
    out!(
        "\nyour own Python controller (python-host/bench_controller.py, the same law):\n{}",
        format_python(&results)
    );
    if let Some(p) = json_out {
        write_json(p, &serde_json::to_value(&results)?)?;
    }
    Ok(Status::Success)
}

/// `sumo-bench --step-time`: each scenario's run through one worker; prints the seconds spent
/// inside SUMO's step in each and their sum (the stepping bound of a sweep over these points
/// is the sum divided by the cores).
pub fn step_time(paths: &[std::path::PathBuf]) -> anyhow::Result<Status> {
    let scenarios = paths
        .iter()
        .map(|p| crate::config::load_scenario(p))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if let Some((p, _)) = paths
        .iter()
        .zip(&scenarios)
        .find(|(_, sc)| sc.backend() != syncroad_control::scenario::Backend::Sumo)
    {
        return Err(crate::error::InputError::new(format!(
            "sumo-bench --step-time {}: backend is not \"sumo\"; SUMO's step is timed on SUMO scenarios only",
            p.display()
        ))
        .into());
    }
    let worker = WorkerCommand::for_process().context("cannot locate the syncroad executable")?;
    // A folder of our own for the runs' SUMO files, removed when dropped.
    let tmp = tempfile::Builder::new()
        .prefix("syncroad-sumo-step-time-")
        .tempdir()
        .context("a temporary folder for the runs")?;
    let work = tmp.path().join("runs");
    let mut progress = |k: usize, t: f64| {
        crate::stdout::errln!("{}: inside simulation.step {t:.4} s", paths[k].display())
    };
    let times = syncroad_sumo::bench::step_seconds(&worker, &scenarios, &work, &mut progress);
    drop(tmp);
    let times = times?;
    for (p, t) in paths.iter().zip(&times) {
        outln!("{}\t{t:.6}", p.display());
    }
    outln!("total\t{:.6}", times.iter().sum::<f64>());
    Ok(Status::Success)
}
