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
    quiet: bool,
    start: Instant,
}

impl Progress {
    /// Starts reporting: a bar on a terminal, a line per finished item elsewhere (a batch
    /// job's log).
    pub fn new(label: &'static str, total: u64) -> Self {
        Self::shown(label, total, None)
    }

    /// Starts reporting as `how` says (`None`: as [`Progress::new`]): `auto` a bar on a
    /// terminal and nothing elsewhere, `lines` a line per finished item wherever stderr goes,
    /// `never` nothing.
    pub fn shown(label: &'static str, total: u64, how: Option<ProgressMode>) -> Self {
        let terminal = std::io::stderr().is_terminal();
        let (bar, quiet) = match how {
            None => (terminal, false),
            Some(ProgressMode::Auto) => (terminal, !terminal),
            Some(ProgressMode::Lines) => (false, false),
            Some(ProgressMode::Never) => (false, true),
        };
        let bar = bar.then(|| {
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
            quiet,
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
            None if self.quiet => {}
            None => crate::stdout::errln!(
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

/// A computation that cannot count its items (the exact stability analysis): once it has
/// lasted `after`, a line on stderr with the step under way and the time spent, again at
/// every new step and every 5 s; nothing for a quick one. Stops when dropped.
pub struct Ticker {
    shared: std::sync::Arc<(std::sync::Mutex<TickerState>, std::sync::Condvar)>,
    thread: Option<std::thread::JoinHandle<()>>,
}

struct TickerState {
    step: &'static str,
    changed: bool,
    done: bool,
}

impl Ticker {
    /// Starts the clock; `label` begins every line.
    pub fn start(label: &'static str, after: std::time::Duration) -> Self {
        let shared = std::sync::Arc::new((
            std::sync::Mutex::new(TickerState {
                step: "starting",
                changed: false,
                done: false,
            }),
            std::sync::Condvar::new(),
        ));
        let inner = shared.clone();
        let start = Instant::now();
        let thread = std::thread::spawn(move || {
            let (lock, wake) = &*inner;
            let mut state = lock.lock().unwrap_or_else(|e| e.into_inner());
            let mut next = start + after;
            loop {
                let now = Instant::now();
                if state.done {
                    return;
                }
                if now >= next || (state.changed && now >= start + after) {
                    crate::stdout::errln!(
                        "{label}: {} ({:.1} s so far)",
                        state.step,
                        start.elapsed().as_secs_f64()
                    );
                    state.changed = false;
                    next = now.max(start + after) + std::time::Duration::from_secs(5);
                }
                let wait = next.saturating_duration_since(Instant::now());
                state = wake
                    .wait_timeout(state, wait)
                    .unwrap_or_else(|e| e.into_inner())
                    .0;
            }
        });
        Ticker {
            shared,
            thread: Some(thread),
        }
    }

    /// A new step has started.
    pub fn step(&self, step: &'static str) {
        let (lock, wake) = &*self.shared;
        let mut state = lock.lock().unwrap_or_else(|e| e.into_inner());
        state.step = step;
        state.changed = true;
        wake.notify_one();
    }
}

impl Drop for Ticker {
    fn drop(&mut self) {
        let (lock, wake) = &*self.shared;
        lock.lock().unwrap_or_else(|e| e.into_inner()).done = true;
        wake.notify_one();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// When one run shows its progress on stderr (`--progress` of `run` and `simulate`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ProgressMode {
    /// A line redrawn in place once the run has lasted 2 s when stderr is a terminal; nothing
    /// when it is not (a log, a pipe, a notebook).
    #[default]
    Auto,
    /// Plain lines, whatever stderr is: one as soon as the first samples are recorded, then
    /// one every 5 s (for the logs of batch jobs, and for scripts that act once a run is under
    /// way).
    Lines,
    /// Nothing.
    Never,
}

enum Shown {
    Bar(Option<ProgressBar>),
    Lines(Option<Instant>),
    Off,
}

/// Progress of one run: simulated time against the horizon, the samples recorded so far
/// (each of them kept in the files whatever stops the run after the report), the speed and
/// the time left. Fed by the native loop or by the SUMO supervisor as rows arrive.
pub struct RunProgress {
    label: &'static str,
    horizon_s: f64,
    step_s: f64,
    start: Instant,
    shown: std::sync::Mutex<Shown>,
}

impl RunProgress {
    /// Wall seconds before a terminal's bar appears (short runs show none).
    pub const BAR_AFTER_S: f64 = 2.0; // `ProgressMode::Auto`'s help says 2 s
    /// Wall seconds between two plain lines.
    pub const LINE_EVERY_S: f64 = 5.0; // `ProgressMode::Lines`'s help says 5 s

    /// Reports the run `label` (`run`, `simulate`) of `horizon_s` simulated seconds in steps
    /// of `step_s`.
    pub fn new(mode: ProgressMode, label: &'static str, horizon_s: f64, step_s: f64) -> Self {
        let shown = match mode {
            ProgressMode::Auto if std::io::stderr().is_terminal() => Shown::Bar(None),
            ProgressMode::Lines => Shown::Lines(None),
            ProgressMode::Auto | ProgressMode::Never => Shown::Off,
        };
        Self {
            label,
            horizon_s,
            step_s,
            start: Instant::now(),
            shown: std::sync::Mutex::new(shown),
        }
    }

    /// The run has reached `time_s` with `samples` recorded.
    pub fn update(&self, time_s: f64, samples: usize) {
        let Ok(mut shown) = self.shown.lock() else {
            return;
        };
        let elapsed = self.start.elapsed().as_secs_f64();
        match &mut *shown {
            Shown::Off => {}
            Shown::Lines(last) => {
                if last.is_some_and(|l| l.elapsed().as_secs_f64() < Self::LINE_EVERY_S) {
                    return;
                }
                *last = Some(Instant::now());
                crate::stdout::errln!("{}: {}", self.label, self.status(time_s, samples, elapsed));
            }
            Shown::Bar(bar) => {
                if bar.is_none() && elapsed >= Self::BAR_AFTER_S {
                    let b = ProgressBar::new(1000);
                    b.set_style(
                        ProgressStyle::with_template("{prefix} [{bar:30}] {msg}")
                            .expect("a valid template")
                            .progress_chars("=> "),
                    );
                    b.set_prefix(self.label);
                    *bar = Some(b);
                }
                if let Some(b) = bar {
                    b.set_position((1000.0 * self.fraction(time_s)) as u64);
                    b.set_message(self.status(time_s, samples, elapsed));
                }
            }
        }
    }

    /// The run ended: the bar is cleared (the summary follows).
    pub fn finish(&self) {
        if let Ok(mut shown) = self.shown.lock() {
            if let Shown::Bar(Some(b)) = &mut *shown {
                b.finish_and_clear();
            }
        }
    }

    fn fraction(&self, time_s: f64) -> f64 {
        if self.horizon_s > 0.0 {
            (time_s / self.horizon_s).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    fn status(&self, time_s: f64, samples: usize, elapsed: f64) -> String {
        let f = self.fraction(time_s);
        let left = if f > 0.0 {
            format!("about {:.0} s left", elapsed * (1.0 - f) / f)
        } else {
            "time left not known yet".to_string()
        };
        let rate = time_s / elapsed.max(1e-9);
        format!(
            "t = {time_s:.1} of {:.1} s ({:.0}%), {samples} samples recorded; {elapsed:.1} s elapsed, {:.0} steps/s, {rate:.0}x real time, {left}",
            self.horizon_s,
            100.0 * f,
            rate / self.step_s.max(1e-12),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_status_line_says_where_the_run_stands_and_what_is_left() {
        let p = RunProgress::new(ProgressMode::Never, "run", 300.0, 0.1);
        // A quarter of the horizon in 10 s: three times as long again.
        let s = p.status(75.0, 751, 10.0);
        assert_eq!(
            s,
            "t = 75.0 of 300.0 s (25%), 751 samples recorded; 10.0 s elapsed, 75 steps/s, 8x real time, about 30 s left"
        );
        assert!(p.status(0.0, 1, 1.0).ends_with("time left not known yet"));
        // Past the horizon (the last step's time rounds up): never over 100 %.
        assert!(p.status(300.1, 3002, 40.0).contains("(100%)"));
    }
}
