//! Standard output that survives a closed or full reader: `syncroad run … | head -1` or
//! stdout sent to `/dev/full`. The first failed write (EPIPE, ENOSPC, …) turns stdout off
//! for the rest of the process; the command goes on and writes its files. A closed reader
//! (EPIPE) is what `head` does and leaves the exit status alone; any other failure (a full
//! disk, an I/O error) lost output the user asked for, so [`failure`] reports it and the
//! command does not exit 0. Files and stderr are unaffected.
//!
//! A host that runs a command as a function ([`crate::host::execute`]) can [`capture`] what
//! it prints instead (the Python package returns the report as a string).

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

static CLOSED: AtomicBool = AtomicBool::new(false);

/// The first failed write that was not a closed reader.
static FAILED: Mutex<Option<String>> = Mutex::new(None);

/// Why stdout stopped, unless it stopped because its reader closed (EPIPE): the text of the
/// first write error (`No space left on device`, …).
pub fn failure() -> Option<String> {
    FAILED.lock().unwrap_or_else(|e| e.into_inner()).clone()
}

/// What is printed while a [`capture`] runs (`None`: print to stdout).
static CAPTURED: Mutex<Option<String>> = Mutex::new(None);

/// One [`capture`] at a time.
static CAPTURING: Mutex<()> = Mutex::new(());

/// Runs `f` with what it prints collected instead of written to stdout, and returns both.
pub fn capture<R>(f: impl FnOnce() -> R) -> (R, String) {
    let _one = CAPTURING.lock().unwrap_or_else(|e| e.into_inner());
    *CAPTURED.lock().unwrap_or_else(|e| e.into_inner()) = Some(String::new());
    let r = f();
    let text = CAPTURED
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take()
        .unwrap_or_default();
    (r, text)
}

/// Writes to stdout unless an earlier write failed; a failure closes stdout quietly.
pub fn write(args: std::fmt::Arguments<'_>) {
    if let Some(buf) = CAPTURED.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
        let _ = std::fmt::Write::write_fmt(buf, args);
        return;
    }
    if CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        CLOSED.store(true, Ordering::Relaxed);
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            FAILED
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .get_or_insert(e.to_string());
        }
    }
}

/// `print!` that stops quietly when stdout is closed (see [`write`]).
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::stdout::write(format_args!($($arg)*))
    };
}

/// `println!` that stops quietly when stdout is closed (see [`write`]).
macro_rules! outln {
    () => {
        $crate::stdout::write(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::stdout::write(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub(crate) use {out, outln};
