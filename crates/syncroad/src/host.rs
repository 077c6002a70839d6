//! The CLI as a function: a command line in, an exit code (and the error, and optionally what
//! was printed) out. The `syncroad` binary is [`main`]; the Python package calls [`main`] for
//! its console script and [`execute`] for its API, so both run the very commands of the CLI.

use std::ffi::OsString;

use clap::Parser;

use crate::{cli, commands, config, error, exit_codes, stdout};

pub use crate::config::{program, set_program};

/// How a command ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ended {
    /// The documented exit code (see the README's exit codes).
    pub code: u8,
    /// The error, with its cause chain (`{:#}`), when the command failed or the command line
    /// was refused (then clap's message, usage included).
    pub error: Option<String>,
    /// What the command printed to stdout, when it was captured (else empty).
    pub stdout: String,
}

/// Runs a command line (`args[0]` is the program name) and returns how it ended; with
/// `capture`, what it prints is returned instead of written to stdout. Nothing is printed of
/// the error: the caller chooses ([`main`] prints it as `error: …`).
pub fn execute<I, T>(args: I, capture: bool) -> Ended
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let parsed = match cli::Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let code = u8::try_from(e.exit_code()).unwrap_or(exit_codes::BAD_INPUT);
            let text = e.render().to_string();
            // --help and --version "fail" with exit code 0: their text is the output.
            return if code == exit_codes::SUCCESS {
                Ended {
                    code,
                    error: None,
                    stdout: text,
                }
            } else {
                Ended {
                    code,
                    error: Some(text),
                    stdout: String::new(),
                }
            };
        }
    };
    run_parsed(parsed, capture)
}

/// Runs a parsed command line (see [`execute`]).
fn run_parsed(parsed: cli::Cli, capture: bool) -> Ended {
    // Per command: the Python API runs many in one process.
    crate::plots::set_pdf(parsed.pdf);
    let run = || {
        let result = commands::run(parsed);
        let code = exit_codes::of(&result);
        let error = result.err().map(|e| error::describe(&e));
        match (stdout::failure(), error) {
            // The output the command printed was lost: never a success.
            (Some(why), None) => (
                if code == exit_codes::SUCCESS {
                    exit_codes::RUN_FAILED
                } else {
                    code
                },
                Some(format!(
                    "cannot write to standard output: {why}; what the command printed is incomplete (files it wrote are whole)"
                )),
            ),
            (_, error) => (code, error),
        }
    };
    let ((code, error), stdout) = if capture {
        stdout::capture(run)
    } else {
        (run(), String::new())
    };
    Ended {
        code,
        error,
        stdout,
    }
}

/// The `syncroad` program: runs the command line, prints an error as `error: …` on stderr
/// (clap's refusals and `--help` as clap prints them) and returns the exit code.
pub fn main<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let parsed = match cli::Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            // Usage errors on stderr, --help and --version on stdout, as clap's `parse` does.
            let _ = e.print();
            return u8::try_from(e.exit_code()).unwrap_or(exit_codes::BAD_INPUT);
        }
    };
    let ended = run_parsed(parsed, false);
    if let Some(err) = &ended.error {
        crate::stdout::errln!("error: {err}");
    }
    ended.code
}

/// Loads and validates a scenario file as every command does; the error is the CLI's
/// message, which names the field, the value and what is valid.
pub fn validate_scenario(path: &std::path::Path) -> Result<(), String> {
    config::load_scenario(path)
        .map(|_| ())
        .map_err(|e| error::describe(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refused_command_line_is_bad_input_with_claps_message() {
        let e = execute(["syncroad", "frobnicate"], true);
        assert_eq!(e.code, exit_codes::BAD_INPUT);
        let err = e.error.expect("an error");
        assert!(
            err.contains("unrecognized subcommand 'frobnicate'"),
            "{err}"
        );
        assert!(e.stdout.is_empty());
    }

    #[test]
    fn help_is_output_with_exit_code_zero() {
        let e = execute(["syncroad", "--help"], true);
        assert_eq!((e.code, e.error), (exit_codes::SUCCESS, None));
        assert!(e.stdout.contains("Usage: syncroad"), "{}", e.stdout);
    }

    #[test]
    fn a_command_prints_into_the_capture_and_a_bad_file_is_named() {
        let e = execute(["syncroad", "schema"], true);
        assert_eq!((e.code, e.error), (exit_codes::SUCCESS, None));
        let schema: serde_json::Value = serde_json::from_str(&e.stdout).expect("JSON");
        assert_eq!(
            e.stdout.trim_end(),
            syncroad_control::record::schema::metrics_schema_text().trim_end()
        );
        assert!(schema.is_object());
        let e = execute(["syncroad", "check", "/nonexistent/s.json"], true);
        assert_eq!(e.code, exit_codes::BAD_INPUT);
        assert!(e.error.expect("an error").contains("/nonexistent/s.json"));
        let v = validate_scenario(std::path::Path::new("/nonexistent/s.json")).unwrap_err();
        assert!(v.contains("/nonexistent/s.json"), "{v}");
    }
}
