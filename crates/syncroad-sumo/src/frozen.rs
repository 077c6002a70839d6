//! A worker that is stopped (SIGSTOP, SIGTSTP, a debugger) sends nothing and never ends: left
//! alone it holds its run, and every run queued behind it, until the run's time limit (600 s
//! by default). The supervisor reads the worker's state from `/proc/PID/stat` about twice a
//! second and gives up on a worker that stays stopped for [`FROZEN_LIMIT`].
//!
//! A Ctrl-Z of the whole job stops the supervisor too, so it cannot count that time; after
//! `fg` both run again.

use std::time::{Duration, Instant};

/// How long a worker may stay stopped before its run fails.
pub const FROZEN_LIMIT: Duration = Duration::from_secs(10);

/// How often the state is read.
const PROBE_EVERY: Duration = Duration::from_millis(500);

/// Watches one worker process.
#[derive(Debug)]
pub(crate) struct FrozenWatch {
    pid: u32,
    since: Option<Instant>,
    last_probe: Option<Instant>,
}

/// The state letter of `/proc/PID/stat` (`R`, `S`, `T` stopped, `t` traced, ...).
fn state_of(pid: u32) -> Option<char> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // `pid (comm) S ...`: the command may hold spaces and parentheses; the state follows the
    // last ')'.
    stat.rsplit_once(')')?.1.trim_start().chars().next()
}

impl FrozenWatch {
    /// Watches `pid`.
    pub(crate) fn new(pid: u32) -> Self {
        Self {
            pid,
            since: None,
            last_probe: None,
        }
    }

    /// The watched pid.
    pub(crate) fn pid(&self) -> u32 {
        self.pid
    }

    /// How long the worker has been stopped, once that passes [`FROZEN_LIMIT`].
    pub(crate) fn frozen(&mut self) -> Option<Duration> {
        let now = Instant::now();
        if self.last_probe.is_some_and(|t| now - t < PROBE_EVERY) {
            return None;
        }
        self.last_probe = Some(now);
        if matches!(state_of(self.pid), Some('T' | 't')) {
            let since = *self.since.get_or_insert(now);
            Some(now - since).filter(|d| *d >= FROZEN_LIMIT)
        } else {
            self.since = None;
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Polls `pid`'s state until `want` holds (a signal takes effect when the process next
    /// runs, which on a loaded machine can be long after `kill` returned); the state last read.
    fn state_once(pid: u32, want: impl Fn(Option<char>) -> bool) -> Option<char> {
        let give_up = Instant::now() + Duration::from_secs(120);
        loop {
            let s = state_of(pid);
            if want(s) || Instant::now() >= give_up {
                return s;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    #[test]
    fn a_stopped_process_reads_as_stopped_and_a_running_one_does_not() {
        let mut child = std::process::Command::new("sleep")
            .arg("300")
            .spawn()
            .unwrap();
        let pid = child.id();
        let running = |s: Option<char>| matches!(s, Some('S' | 'R'));
        let s = state_once(pid, running);
        assert!(running(s), "{s:?}");
        // SAFETY: signalling our own child.
        unsafe { libc::kill(pid as i32, libc::SIGSTOP) };
        assert_eq!(state_once(pid, |s| s == Some('T')), Some('T'));
        let mut w = FrozenWatch::new(pid);
        // Seen stopped, but not yet for the limit.
        assert_eq!(w.frozen(), None);
        assert!(w.since.is_some());
        unsafe { libc::kill(pid as i32, libc::SIGCONT) };
        let s = state_once(pid, running);
        assert!(running(s), "{s:?}");
        // The next probe (due after PROBE_EVERY) reads it running.
        std::thread::sleep(PROBE_EVERY + Duration::from_millis(100));
        assert_eq!(w.frozen(), None);
        assert!(w.since.is_none(), "running again resets the clock");
        let _ = child.kill();
        let _ = child.wait();
    }
}
