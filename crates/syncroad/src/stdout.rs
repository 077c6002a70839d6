//! Standard output that survives a closed or full reader: `syncroad run … | head -1` or
//! stdout sent to `/dev/full`. The first failed write (EPIPE, ENOSPC, …) turns stdout off
//! for the rest of the process; the command goes on, writes its files and exits with its own
//! status, as `head`-friendly command-line tools do. Files and stderr are unaffected.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};

static CLOSED: AtomicBool = AtomicBool::new(false);

/// Writes to stdout unless an earlier write failed; a failure closes stdout quietly.
pub fn write(args: std::fmt::Arguments<'_>) {
    if CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if out.write_fmt(args).and_then(|()| out.flush()).is_err() {
        CLOSED.store(true, Ordering::Relaxed);
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
