//! The subcommands.

use std::path::Path;

use anyhow::Context;
use syncroad_control::metrics::{sync_metrics, VerdictThresholds};
use syncroad_control::scenario::Model;
use syncroad_control::{simulate, theory, NativeOptions, Scenario, StopReason, Verdict};

use crate::cli::{Cli, Command, OutputArgs};
use crate::exit_codes;
use crate::report;

/// Marks errors caused by the user's input (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InputError(pub String);

/// Loads and validates a scenario, mapping failures to [`InputError`].
pub fn load_scenario(path: &Path) -> anyhow::Result<Scenario> {
    Scenario::load(path).map_err(|e| {
        anyhow::Error::new(InputError(format!(
            "{e}\n  (scenario {}; fix the field named above — `syncroad --help` and README.md describe the format)",
            path.display()
        )))
    })
}

/// Runs a parsed command line and returns the exit code.
pub fn run(cli: Cli) -> anyhow::Result<u8> {
    match cli.command {
        Command::Check { scenario, json } => check(&scenario, json),
        Command::Simulate { scenario, out } => simulate_cmd(&scenario, &out),
        Command::Bench { horizon_s, sizes } => crate::bench::run(horizon_s, &sizes),
    }
}

fn check(path: &Path, json: bool) -> anyhow::Result<u8> {
    let sc = load_scenario(path)?;
    let rep = theory::report(&sc);
    if json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print!("{}", report::theory_table(&rep));
    }
    Ok(if rep.certified {
        exit_codes::SUCCESS
    } else {
        exit_codes::NOT_SYNCHRONIZED
    })
}

/// Verdict thresholds: the scenario's, overridden by the command line.
pub fn thresholds(sc: &Scenario, out: &OutputArgs) -> anyhow::Result<VerdictThresholds> {
    let t = VerdictThresholds {
        tolerance_mps: out.tolerance_mps.unwrap_or(sc.file.verdict.tolerance_mps),
        window_s: out.window_s.unwrap_or(sc.file.verdict.window_s),
    };
    if !(t.tolerance_mps.is_finite() && t.tolerance_mps > 0.0) {
        return Err(InputError(format!(
            "--tolerance-mps = {}: must be a finite number > 0",
            t.tolerance_mps
        ))
        .into());
    }
    if !(t.window_s.is_finite() && t.window_s > 0.0 && t.window_s <= sc.horizon_s()) {
        return Err(InputError(format!(
            "--window-s = {}: must be > 0 and ≤ the horizon ({} s)",
            t.window_s,
            sc.horizon_s()
        ))
        .into());
    }
    Ok(t)
}

fn simulate_cmd(path: &Path, out: &OutputArgs) -> anyhow::Result<u8> {
    let sc = load_scenario(path)?;
    let th = thresholds(&sc, out)?;
    std::fs::create_dir_all(&out.out)
        .with_context(|| format!("cannot create output folder {}", out.out.display()))?;
    let every = out.record_every.unwrap_or_else(|| (sc.steps / 2000).max(1));
    if every == 0 {
        return Err(InputError("--record-every = 0: must be ≥ 1".into()).into());
    }
    let run = simulate(
        &sc,
        NativeOptions {
            record_every: every,
        },
    );
    let incomplete = !matches!(run.stop, StopReason::Horizon);
    let desired = match &sc.model {
        Model::Cacc(c) => Some(c.desired_gap_m.as_slice()),
        Model::DelayedDriver(_) => None,
    };
    let metrics = sync_metrics(&run.trajectory, th, desired, incomplete);
    let theory = theory::report(&sc);
    report::write_run(
        &out.out,
        &sc,
        "native",
        &run.trajectory,
        &metrics,
        &run.stop,
        &theory,
        None,
    )?;
    print!(
        "{}",
        report::metrics_table(&sc, "native", &metrics, &run.stop, &theory)
    );
    println!(
        "wrote {}/trajectories.csv and {}/metrics.json",
        out.out.display(),
        out.out.display()
    );
    if !out.no_plots {
        let plots = crate::plots::RunPlots {
            traj: &run.trajectory,
            ring_length_m: sc.ring_length_m(),
            title: format!("{} (native)", sc.name),
        };
        let files = plots.write_all(&out.out)?;
        println!(
            "wrote {} plots: time_space, speeds, spread (PNG and SVG)",
            files.len()
        );
    }
    Ok(match metrics.verdict {
        Verdict::Synchronized => exit_codes::SUCCESS,
        _ => exit_codes::NOT_SYNCHRONIZED,
    })
}
