//! `syncroad`: argument definitions plus glue. The work happens in `syncroad-control`
//! (laws, theory, native simulator) and `syncroad-sumo` (SUMO co-simulation).

mod bench;
mod cli;
mod commands;
mod exit_codes;
mod plots;
mod regress;
mod report;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
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
