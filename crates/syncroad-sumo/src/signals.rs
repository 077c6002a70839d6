//! SIGINT, SIGTERM and SIGHUP, all handled alike: a process-wide flag that supervised runs
//! check, so the parent stops its workers and keeps every row received. SIGTERM and SIGHUP
//! are what `timeout`, CI cancellation and `docker stop` send; left at their default they
//! would kill the parent and lose the run.
//!
//! The handlers are `signal-hook`'s: each signal stores its number (for the exit code,
//! `128 + signal`, as a shell reports a process killed by it) and sets the flag; both are
//! atomics, so the handlers are async-signal-safe.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

/// The signals treated as "stop and keep what was computed".
pub const HANDLED: [i32; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
static RECEIVED: OnceLock<Arc<AtomicUsize>> = OnceLock::new();

fn received_cell() -> &'static Arc<AtomicUsize> {
    RECEIVED.get_or_init(|| Arc::new(AtomicUsize::new(0)))
}

/// True once a host delivers the interrupts itself ([`host_delivers_interrupts`]).
static HOST_DELIVERS: AtomicBool = AtomicBool::new(false);

fn flag_cell() -> Arc<AtomicBool> {
    FLAG.get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone()
}

/// A host that owns the process's signals (a Python interpreter: its own SIGINT handler
/// raises `KeyboardInterrupt`) delivers them through [`interrupt`]; [`interrupt_flag`] then
/// installs no handler. Call before the first [`interrupt_flag`].
pub fn host_delivers_interrupts() {
    HOST_DELIVERS.store(true, Ordering::SeqCst);
}

/// Sets the stop flag as the handler of `signal` would (for a host that delivers interrupts).
pub fn interrupt(signal: i32) {
    received_cell().store(signal as usize, Ordering::SeqCst);
    flag_cell().store(true, Ordering::SeqCst);
}

/// Clears the stop flag and the received signal, so a host's next command starts afresh
/// (a notebook goes on after a `KeyboardInterrupt`).
pub fn clear_interrupt() {
    flag_cell().store(false, Ordering::SeqCst);
    received_cell().store(0, Ordering::SeqCst);
}

/// The process-wide stop flag as it is, without installing any handler: set once a handler
/// installed by [`interrupt_flag`] ran, or a host delivered an interrupt; never set otherwise.
/// For code that must notice a stop without taking the process's signals (a library call).
pub(crate) fn stop_flag() -> Arc<AtomicBool> {
    flag_cell()
}

/// The process-wide stop flag; installs the handlers for [`HANDLED`] on first use (unless a
/// host delivers the interrupts: [`host_delivers_interrupts`]).
pub fn interrupt_flag() -> Result<Arc<AtomicBool>, String> {
    static INSTALLED: OnceLock<Result<(), String>> = OnceLock::new();
    let flag = flag_cell();
    if HOST_DELIVERS.load(Ordering::SeqCst) {
        return Ok(flag);
    }
    INSTALLED
        .get_or_init(|| {
            for sig in HANDLED {
                let cannot = |e: std::io::Error| format!("cannot handle signal {sig}: {e}");
                // The number first, then the flag: whoever sees the flag finds the number.
                signal_hook::flag::register_usize(sig, received_cell().clone(), sig as usize)
                    .map_err(cannot)?;
                signal_hook::flag::register(sig, flag.clone()).map_err(cannot)?;
            }
            Ok(())
        })
        .clone()
        .map(|()| flag)
}

/// Makes a file-size limit (`ulimit -f`, a quota that sends SIGXFSZ) a failed write instead
/// of a silent death: SIGXFSZ's default action ends the process at once, with no record and
/// a temporary file left behind. With a handler installed (it only notes the signal, which is
/// async-signal-safe) the write that passed the limit fails with `EFBIG`, and the run's files
/// take the path of a full disk: a message naming the file, the record kept under an unsaved
/// name, no temporary file left. Call once at the start of a process that writes run files
/// (the CLI and its workers; CPython ignores SIGXFSZ itself).
pub fn survive_file_size_limit() -> Result<(), String> {
    static INSTALLED: OnceLock<Result<(), String>> = OnceLock::new();
    INSTALLED
        .get_or_init(|| {
            signal_hook::flag::register(libc::SIGXFSZ, Arc::new(AtomicBool::new(false)))
                .map(|_| ())
                .map_err(|e| format!("cannot handle signal SIGXFSZ: {e}"))
        })
        .clone()
}

/// The last handled signal received, if any.
pub fn received() -> Option<i32> {
    let s = received_cell().load(Ordering::SeqCst);
    (s != 0).then_some(s as i32)
}

/// The received signal's name for messages (`Ctrl-C` for SIGINT).
pub fn received_name() -> &'static str {
    name_of(received())
}

fn name_of(sig: Option<i32>) -> &'static str {
    match sig {
        Some(libc::SIGTERM) => "SIGTERM",
        Some(libc::SIGHUP) => "SIGHUP",
        _ => "Ctrl-C",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_termination_signal_sets_the_flag_and_is_remembered() {
        let flag = interrupt_flag().unwrap();
        assert!(!flag.load(Ordering::SeqCst));
        // SAFETY: raising a handled signal in this process runs `on_signal`. (SIGINT, so
        // the other tests of this process still read "Ctrl-C".)
        unsafe { libc::raise(libc::SIGINT) };
        assert!(flag.load(Ordering::SeqCst));
        assert_eq!(received(), Some(libc::SIGINT));
        assert_eq!(received_name(), "Ctrl-C");
    }

    #[test]
    fn signals_are_named() {
        assert_eq!(name_of(Some(libc::SIGTERM)), "SIGTERM");
        assert_eq!(name_of(Some(libc::SIGHUP)), "SIGHUP");
        assert_eq!(name_of(None), "Ctrl-C");
    }
}
