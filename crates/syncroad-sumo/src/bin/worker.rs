//! `syncroad-sumo-worker`: without arguments, runs one SUMO co-simulation request read from
//! stdin (see `syncroad_sumo::worker_main`; started by the supervisor, never by hand).
//!
//! `syncroad-sumo-worker --bench [--quick] [--case NAME] [--no-traci] [--json FILE]` runs the
//! SUMO benchmark (SUMO alone vs SUMO + controller vs the TraCI reference at N = 22 and
//! N = 2000, or the one case named), starting itself as the worker of every measurement.
//! Arguments are read by `lexopt` (the SUMO crate stays free of clap); a stray or misspelt one
//! is refused with exit 2.

use std::path::PathBuf;
use std::process::ExitCode;

use syncroad_sumo::bench::{format_profile, format_table, run_standard, BenchError, Selection};
use syncroad_sumo::WorkerCommand;

/// What the command line asks for.
#[derive(Debug, PartialEq)]
enum Mode {
    /// No arguments: one co-simulation request from stdin.
    Worker,
    /// `--bench [--quick] [--case NAME] [--no-traci] [--json FILE]`.
    Bench {
        sel: Selection,
        json: Option<PathBuf>,
    },
}

const USAGE: &str =
    "usage: syncroad-sumo-worker [--bench [--quick] [--case NAME] [--no-traci] [--json FILE]]";

/// Reads the arguments; anything else (an unknown flag, a benchmark option without `--bench`,
/// `--json` without a file) is refused with the argument named rather than ignored.
fn parse(args: impl IntoIterator<Item = std::ffi::OsString>) -> Result<Mode, lexopt::Error> {
    use lexopt::prelude::*;
    let mut parser = lexopt::Parser::from_args(args);
    let (mut bench, mut sel, mut json) = (false, Selection::default(), None);
    while let Some(arg) = parser.next()? {
        match arg {
            Long("bench") => bench = true,
            Long("quick") => sel.quick = true,
            Long("no-traci") => sel.no_traci = true,
            Long("case") => sel.case = Some(parser.value()?.string()?),
            Long("json") => json = Some(PathBuf::from(parser.value()?)),
            other => return Err(other.unexpected()),
        }
    }
    if !bench && (sel != Selection::default() || json.is_some()) {
        return Err("--quick, --case, --no-traci and --json apply only with --bench".into());
    }
    Ok(if bench {
        Mode::Bench { sel, json }
    } else {
        Mode::Worker
    })
}

fn main() -> ExitCode {
    let (sel, json) = match parse(std::env::args_os().skip(1)) {
        Ok(Mode::Worker) => return syncroad_sumo::worker_main(),
        Ok(Mode::Bench { sel, json }) => (sel, json),
        Err(e) => {
            eprintln!("error: {e}\n{USAGE}");
            return ExitCode::from(2);
        }
    };
    let worker = match std::env::current_exe() {
        Ok(p) => WorkerCommand::binary(p),
        Err(e) => {
            eprintln!("error: cannot locate this executable: {e}");
            return ExitCode::FAILURE;
        }
    };
    let results = match run_standard(&worker, &sel, &mut |l: &str| eprintln!("{l}")) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e:#}");
            // An unknown case is bad input, refused before any measurement, like a stray flag.
            return match e {
                BenchError::UnknownCase { .. } => ExitCode::from(2),
                _ => ExitCode::FAILURE,
            };
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_strs(args: &[&str]) -> Result<Mode, String> {
        parse(args.iter().map(std::ffi::OsString::from)).map_err(|e| e.to_string())
    }

    #[test]
    fn arguments_are_read_and_strays_refused_by_name() {
        assert_eq!(parse_strs(&[]), Ok(Mode::Worker));
        assert_eq!(
            parse_strs(&["--bench", "--json", "b.json", "--quick"]),
            Ok(Mode::Bench {
                sel: Selection {
                    quick: true,
                    ..Selection::default()
                },
                json: Some("b.json".into())
            })
        );
        assert_eq!(
            parse_strs(&["--bench", "--case", "sugiyama-ring", "--no-traci"]),
            Ok(Mode::Bench {
                sel: Selection {
                    quick: false,
                    case: Some("sugiyama-ring".into()),
                    no_traci: true,
                },
                json: None
            })
        );
        assert_eq!(
            parse_strs(&["--bench"]),
            Ok(Mode::Bench {
                sel: Selection::default(),
                json: None
            })
        );
        let e = parse_strs(&["--bench", "--jsn", "b.json"]).unwrap_err();
        assert!(e.contains("--jsn"), "{e}");
        let e = parse_strs(&["--bench", "--json"]).unwrap_err();
        assert!(e.contains("--json"), "{e}");
        for alone in [&["--quick"][..], &["--no-traci"], &["--case", "ring-20km"]] {
            let e = parse_strs(alone).unwrap_err();
            assert!(e.contains("only with --bench"), "{e}");
        }
        let e = parse_strs(&["--bench", "--case"]).unwrap_err();
        assert!(e.contains("--case"), "{e}");
        assert!(parse_strs(&["stray"]).unwrap_err().contains("stray"));
    }
}
