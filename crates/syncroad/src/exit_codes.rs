//! Documented exit codes of `syncroad`.

use std::process::ExitCode;

/// The run finished and the verdict is "synchronized" (for `check`: certified).
pub const SUCCESS: u8 = 0;
/// The run finished but the speeds did not synchronize, or the verdict is inconclusive
/// (for `check`: the sufficient conditions do not certify synchronization).
pub const NOT_SYNCHRONIZED: u8 = 1;
/// Bad input: unreadable or invalid scenario, bad command-line value.
pub const BAD_INPUT: u8 = 2;
/// A run failed while executing (I/O error, SUMO crash, timeout). Partial results are written.
pub const RUN_FAILED: u8 = 3;
/// Interrupted by Ctrl-C. Partial results are written.
#[allow(dead_code)] // used by the SUMO commands
pub const INTERRUPTED: u8 = 130;

/// Converts a code to [`ExitCode`].
pub fn code(c: u8) -> ExitCode {
    ExitCode::from(c)
}
