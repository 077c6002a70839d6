//! `syncroad`: argument definitions plus glue. The work happens in `syncroad-control`
//! (laws, theory, native simulator, the run outcome and record) and `syncroad-sumo` (SUMO
//! co-simulation).
//!
//! * [`cli`] — clap definitions, the help text;
//! * [`config`] — options validated once, before any work starts;
//! * [`commands`] — one module per command;
//! * [`pipeline`] — one run, whatever runs it: backend → outcome → record → files;
//! * [`output`], [`plots`], [`report`], [`stability`] — files, figures and text tables;
//! * [`error`], [`exit_codes`] — the one error funnel; only [`main`] picks the exit code.

mod batch;
mod cli;
mod commands;
mod config;
mod error;
mod exit_codes;
mod gaps;
mod lock;
mod output;
mod pipeline;
mod plots;
mod progress;
mod report;
mod runs;
mod stability;
mod stdout;
mod sweep;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    // Each SUMO run re-executes this binary as its worker process.
    if syncroad_sumo::is_worker_invocation() {
        return syncroad_sumo::worker_main();
    }
    let cli = cli::Cli::parse();
    let result = commands::run(cli);
    if let Err(err) = &result {
        eprintln!("error: {}", error::describe(err));
    }
    exit_codes::of(&result)
}
