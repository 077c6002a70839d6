//! `syncroad sumo-bench`: SUMO alone vs SUMO + controller vs a TraCI-socket loop.

use std::path::Path;

use anyhow::Context;
use syncroad_sumo::bench::{format_profile, format_table, run_case, standard_cases};
use syncroad_sumo::WorkerCommand;

use crate::error::Status;
use crate::output::write_json;
use crate::stdout::out;

/// The SUMO benchmark: SUMO alone vs SUMO + controller vs the TraCI reference at N = 22 and
/// N = 2000; prints a table, optionally writes JSON.
pub fn run(quick: bool, json_out: Option<&Path>) -> anyhow::Result<Status> {
    let repo = syncroad_sumo::repo_dir();
    let worker = WorkerCommand::for_process().context("cannot locate the syncroad executable")?;
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
    out!("{}", format_table(&results));
    out!("\nwhere a step goes:\n{}", format_profile(&results));
    if let Some(p) = json_out {
        write_json(p, &serde_json::to_value(&results)?)?;
    }
    Ok(Status::Success)
}
