//! `syncroad-sumo-worker`: without arguments, runs one SUMO co-simulation request read from
//! stdin (see `syncroad_sumo::worker_main`; started by the supervisor, never by hand).
//!
//! `syncroad-sumo-worker --bench [--quick] [--json FILE]` runs the SUMO benchmark (SUMO alone vs
//! SUMO + controller vs the TraCI reference at N = 22 and N = 2000), starting itself as the
//! worker of every measurement.

use std::path::PathBuf;
use std::process::ExitCode;

use syncroad_sumo::bench::{format_profile, format_table, run_standard};
use syncroad_sumo::WorkerCommand;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) != Some("--bench") {
        return syncroad_sumo::worker_main();
    }
    let quick = args.iter().any(|a| a == "--quick");
    let json = args
        .iter()
        .position(|a| a == "--json")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from);
    let worker = match std::env::current_exe() {
        Ok(p) => WorkerCommand::binary(p),
        Err(e) => {
            eprintln!("error: cannot locate this executable: {e}");
            return ExitCode::FAILURE;
        }
    };
    let results = match run_standard(&worker, quick, &mut |l: &str| eprintln!("{l}")) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    print!("{}", format_table(&results));
    print!("\nwhere a step goes:\n{}", format_profile(&results));
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&results).expect("results serialise");
        let text = text + "\n";
        if let Err(e) = syncroad_sumo::write_result(&path, |w| w.write_all(text.as_bytes())) {
            let cause = std::error::Error::source(&e).map_or(String::new(), |c| format!(": {c}"));
            eprintln!("error: {e}{cause}");
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
