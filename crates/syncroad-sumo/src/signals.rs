//! SIGINT, SIGTERM and SIGHUP, all handled alike: a process-wide flag that supervised runs
//! check, so the parent stops its workers and keeps every row received. SIGTERM and SIGHUP
//! are what `timeout`, CI cancellation and `docker stop` send; left at their default they
//! would kill the parent and lose the run.
//!
//! The handler only stores two atomics (async-signal-safe); the signal's number is kept for
//! the exit code (`128 + signal`, as a shell reports a process killed by it).

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};

/// The signals treated as "stop and keep what was computed".
pub const HANDLED: [i32; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
static RECEIVED: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    RECEIVED.store(sig, Ordering::SeqCst);
    if let Some(f) = FLAG.get() {
        f.store(true, Ordering::SeqCst);
    }
}

/// The process-wide stop flag; installs the handlers for [`HANDLED`] on first use.
pub fn interrupt_flag() -> Result<Arc<AtomicBool>, String> {
    static INSTALLED: OnceLock<Result<(), String>> = OnceLock::new();
    let flag = FLAG
        .get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone();
    INSTALLED
        .get_or_init(|| {
            for sig in HANDLED {
                // SAFETY: a zeroed sigaction with a handler that only stores atomics.
                let ok = unsafe {
                    let mut sa: libc::sigaction = std::mem::zeroed();
                    sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
                    sa.sa_flags = libc::SA_RESTART;
                    libc::sigemptyset(&mut sa.sa_mask);
                    libc::sigaction(sig, &sa, std::ptr::null_mut()) == 0
                };
                if !ok {
                    return Err(format!(
                        "cannot handle signal {sig}: {}",
                        std::io::Error::last_os_error()
                    ));
                }
            }
            Ok(())
        })
        .clone()
        .map(|()| flag)
}

/// The last handled signal received, if any.
pub fn received() -> Option<i32> {
    Some(RECEIVED.load(Ordering::SeqCst)).filter(|&s| s != 0)
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
