//! Documented exit codes of `syncroad`, chosen in one place from a command's [`Status`] or
//! error.

use crate::error::{InputError, Status};

/// The run finished and the verdict is "synchronized" (for `check`: certified).
pub const SUCCESS: u8 = 0;
/// The run finished but the speeds did not synchronize, or the verdict is inconclusive
/// (for `check`: the sufficient conditions do not certify synchronization).
pub const NOT_SYNCHRONIZED: u8 = 1;
/// Bad input: unreadable or invalid scenario, bad command-line value.
pub const BAD_INPUT: u8 = 2;
/// A run failed while executing (I/O error, SUMO crash, timeout). Partial results are written.
pub const RUN_FAILED: u8 = 3;
/// Interrupted by Ctrl-C (SIGINT). Partial results are written. SIGTERM and SIGHUP are handled
/// alike and exit with `128 + signal` (143 and 129), as a shell reports a process they killed.
pub const INTERRUPTED: u8 = 130;

/// The exit code of an interrupted command: `128 + signal`, or [`INTERRUPTED`] when the
/// signal is unknown.
fn interrupted() -> u8 {
    syncroad_sumo::interrupt_signal()
        .and_then(|s| u8::try_from(128 + s).ok())
        .unwrap_or(INTERRUPTED)
}

/// The exit code of a command's result. A signal that arrived after the runs, while the files
/// were written or plotted, still ends the command as interrupted (its files are whole: each
/// is written atomically); a bad input stays a bad input.
pub fn of(result: &anyhow::Result<Status>) -> u8 {
    let bad_input = matches!(result, Err(e) if e.chain().any(|c| c.is::<InputError>()));
    if syncroad_sumo::interrupt_signal().is_some() && !bad_input {
        if !matches!(result, Ok(Status::Interrupted)) {
            crate::stdout::errln!(
                "error: interrupted ({}) after the runs; the files written are complete, the command did not finish",
                syncroad_sumo::interrupt_signal_name()
            );
        }
        return interrupted();
    }
    match result {
        Ok(Status::Success) => SUCCESS,
        Ok(Status::NotSynchronized) => NOT_SYNCHRONIZED,
        Ok(Status::RunFailed) => RUN_FAILED,
        Ok(Status::Interrupted) => interrupted(),
        Err(e) if e.chain().any(|c| c.is::<InputError>()) => BAD_INPUT,
        Err(_) => RUN_FAILED,
    }
}
