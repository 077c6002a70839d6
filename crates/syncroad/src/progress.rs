//! Progress of long work on stderr: a bar with an ETA on a terminal, otherwise one line per
//! finished item with the elapsed time (what a batch job's log should show).

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

/// A progress report for `total` items.
pub struct Progress {
    label: &'static str,
    total: u64,
    done: AtomicU64,
    bar: Option<ProgressBar>,
    start: Instant,
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
            start: Instant::now(),
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
            None => eprintln!(
                "{}: [{d:>2}/{} done, {:6.1} s] {item} {}",
                self.label,
                self.total,
                self.start.elapsed().as_secs_f64(),
                error.map_or("finished".to_string(), |e| format!("FAILED: {e}"))
            ),
        }
    }

    /// All items finished.
    pub fn done(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
