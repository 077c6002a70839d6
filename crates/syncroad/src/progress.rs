//! Progress of long work on stderr: a bar with an ETA on a terminal, a line per tenth of the
//! work otherwise (logs of batch jobs stay short).

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};

use indicatif::{ProgressBar, ProgressStyle};

/// A progress report for `total` items.
pub struct Progress {
    label: &'static str,
    total: u64,
    done: AtomicU64,
    bar: Option<ProgressBar>,
}

impl Progress {
    /// Starts reporting.
    pub fn new(label: &'static str, total: u64) -> Self {
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = ProgressBar::new(total);
            b.set_style(
                ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} ({elapsed}, ETA {eta})")
                    .expect("a valid template")
                    .progress_chars("=> "),
            );
            b.set_message(label);
            b
        });
        Self {
            label,
            total,
            done: AtomicU64::new(0),
            bar,
        }
    }

    /// One item finished; `error` names why it failed.
    pub fn finished(&self, item: &str, error: Option<&str>) {
        let d = self.done.fetch_add(1, Ordering::SeqCst) + 1;
        match &self.bar {
            Some(b) => {
                b.inc(1);
                if let Some(e) = error {
                    b.println(format!("{}: {item} FAILED: {e}", self.label));
                }
            }
            None => {
                if let Some(e) = error {
                    eprintln!("{}: {item} FAILED: {e}", self.label);
                }
                let t = self.total.max(1);
                if d == t || d * 10 / t != (d - 1) * 10 / t {
                    eprintln!("{}: {d}/{t} done ({item} finished)", self.label);
                }
            }
        }
    }

    /// All items finished.
    pub fn done(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
