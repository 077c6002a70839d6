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

thread_local! {
    /// What this thread prints while a [`capture`] runs on it (`None`: print to stdout).
    /// Per thread, so that commands a host runs side by side (two stepping loops of the
    /// Python package at once) each collect their own report instead of waiting for each
    /// other: a command prints from the thread it runs on.
    static CAPTURED: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}

/// Runs `f` with what it prints on this thread collected instead of written to stdout, and
/// returns both.
pub fn capture<R>(f: impl FnOnce() -> R) -> (R, String) {
    let before = CAPTURED.with(|c| c.replace(Some(String::new())));
    let r = f();
    let text = CAPTURED.with(|c| c.replace(before)).unwrap_or_default();
    (r, text)
}

/// Writes to stdout unless an earlier write failed; a failure closes stdout quietly.
pub fn write(args: std::fmt::Arguments<'_>) {
    let captured = CAPTURED.with(|c| {
        c.borrow_mut()
            .as_mut()
            .map(|buf| std::fmt::Write::write_fmt(buf, args))
            .is_some()
    });
    if captured {
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

/// `eprintln!` that never panics: with stderr closed (`syncroad … 2>&1 | head -1`) the
/// message is dropped and the command goes on to its own exit code. `eprintln!` panics on a
/// failed write, which would end the command with Rust's 101.
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}

pub(crate) use {errln, out, outln};
