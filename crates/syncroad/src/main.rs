//! `syncroad`: argument definitions plus glue. The work happens in `syncroad-control`
//! (laws, theory, native simulator) and `syncroad-sumo` (SUMO co-simulation).

mod bench;
mod cli;
mod commands;
mod compare;
mod exit_codes;
mod map;
mod plots;
mod regress;
mod report;
mod stability;
mod sumo_cmd;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    // Each SUMO run re-executes this binary as its worker process.
    if syncroad_sumo::is_worker_invocation() {
        return syncroad_sumo::worker_main();
    }
    let cli = cli::Cli::parse();
    match commands::run(cli) {
        Ok(code) => exit_codes::code(code),
        Err(err) => {
            eprintln!("error: {err:#}");
            let code = if err.downcast_ref::<commands::InputError>().is_some() {
                exit_codes::BAD_INPUT
            } else {
                exit_codes::RUN_FAILED
            };
            exit_codes::code(code)
        }
    }
}
