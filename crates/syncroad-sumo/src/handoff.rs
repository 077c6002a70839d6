//! A run stepped by a caller in this very process (`syncroad.Simulation`, the Gymnasium
//! environment): the run's loop and the caller meet in a [`Handoff`], one observation and one
//! set of commands per step, without a second process, a socket or the interpreter in between.
//!
//! The loop runs on a thread of its own, the caller on its thread; each waits for the other's
//! turn spinning for a short while ([`SPIN`]: a SUMO step of a small ring and a policy's
//! arithmetic take tens of microseconds, less than waking a blocked thread) and then blocks.
//! Neither holds the interpreter while it waits, so the other takes it without waiting.
//!
//! libsumo runs one simulation per process: [`claim_libsumo`] hands this process's libsumo to
//! one run at a time; while it is taken, runs go to worker processes as before. A run started
//! [`here`] runs its SUMO on a thread of this process instead of a worker (see
//! `supervisor::run_here`).

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use syncroad_control::LawContext;

/// How long a side looks for the other's turn before it blocks.
pub const SPIN: Duration = Duration::from_micros(200);

/// A look that found nothing (the other side is slower: a policy that computes for long, or
/// more busy threads than cores, as with several environments side by side) makes that side's
/// next 2, then 4, … up to this many waits block without looking first; a look that finds the
/// other's turn starts over. Timing only: the exchanges, and so the run, are the same.
const SPIN_BACKOFF_MAX: u32 = 1024;

/// How long a blocked side sleeps before it looks again (the wake-up normally comes first).
const SIGNAL_POLL: Duration = Duration::from_millis(20);

/// Blocked waits after which a caller looks for a pending signal (Ctrl-C): every 100 ms.
const SIGNAL_POLLS: u32 = 5;

/// Nobody's turn: the run has not published its first observation yet.
const START: u32 = 0;
/// An observation waits for the caller.
const OBS: u32 = 1;
/// Commands wait for the run.
const CMD: u32 = 2;
/// The caller closed the run; it stops at its next step.
const CLOSED: u32 = 3;
/// The run ended: no observation follows.
const ENDED: u32 = 4;

#[derive(Debug, Default)]
struct Data {
    /// The run's context, which the caller is told once, with the first observation.
    first: Option<LawContext>,
    /// (time, step) and the rows of one observation, as the caller unpacks them.
    obs: Vec<f64>,
    /// One command per vehicle.
    cmd: Vec<f64>,
    /// Why the caller closed the run.
    closed: String,
}

/// Why the run's side of an exchange ends the run.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// The caller closed the run (its reason).
    Closed(String),
    /// The caller's commands do not fit the run.
    Failed(String),
}

/// The meeting point of one run and its caller.
#[derive(Debug, Default)]
pub struct Shared {
    state: AtomicU32,
    /// The run's looks for the caller's commands, and the caller's for the run's observation.
    run_looks: Looks,
    caller_looks: Looks,
    data: Mutex<Data>,
    waiters: AtomicUsize,
    lock: Mutex<()>,
    wake: Condvar,
}

/// One side's record of whether looking before blocking pays (see [`SPIN_BACKOFF_MAX`]);
/// only that side's thread touches it.
#[derive(Debug, Default)]
struct Looks {
    misses: AtomicU32,
    skip: AtomicU32,
}

impl Looks {
    /// Whether to look this time (a skipped look counts down).
    fn look(&self) -> bool {
        let skip = self.skip.load(Ordering::Relaxed);
        if skip > 0 {
            self.skip.store(skip - 1, Ordering::Relaxed);
            return false;
        }
        true
    }

    fn found(&self, found: bool) {
        if found {
            self.misses.store(0, Ordering::Relaxed);
        } else {
            let m = (self.misses.load(Ordering::Relaxed) + 1).min(10);
            self.misses.store(m, Ordering::Relaxed);
            self.skip
                .store((1u32 << m).min(SPIN_BACKOFF_MAX), Ordering::Relaxed);
        }
    }
}

impl Shared {
    fn set(&self, state: u32) {
        self.state.store(state, Ordering::SeqCst);
        self.notify();
    }

    fn notify(&self) {
        if self.waiters.load(Ordering::SeqCst) > 0 {
            let _g = self.lock.lock().unwrap_or_else(|p| p.into_inner());
            self.wake.notify_all();
        }
    }

    /// Moves from one of `from` to `to`; returns the state found when it is none of `from`.
    fn advance(&self, from: &[u32], to: u32) -> Result<(), u32> {
        let mut s = self.state.load(Ordering::SeqCst);
        loop {
            if !from.contains(&s) {
                return Err(s);
            }
            match self
                .state
                .compare_exchange(s, to, Ordering::SeqCst, Ordering::SeqCst)
            {
                Ok(_) => {
                    self.notify();
                    return Ok(());
                }
                Err(now) => s = now,
            }
        }
    }

    /// The caller's close: the run stops at its next step (unless it has ended already).
    fn close(&self, reason: String) {
        self.data().closed = reason;
        let _ = self.advance(&[START, OBS, CMD], CLOSED);
    }

    /// Waits until `done(state)` holds, or `give_up()` says to stop waiting (checked between
    /// blocked waits); returns the state seen.
    fn wait(
        &self,
        looks: &Looks,
        done: impl Fn(u32) -> bool,
        mut give_up: impl FnMut() -> bool,
    ) -> u32 {
        if looks.look() {
            let start = Instant::now();
            for k in 1u32.. {
                let s = self.state.load(Ordering::SeqCst);
                if done(s) {
                    looks.found(true);
                    return s;
                }
                // The clock now and then only: reading it costs more than a look.
                if k.is_multiple_of(64) && start.elapsed() >= SPIN {
                    break;
                }
                std::hint::spin_loop();
            }
            looks.found(false);
        }
        self.waiters.fetch_add(1, Ordering::SeqCst);
        let mut guard = self.lock.lock().unwrap_or_else(|p| p.into_inner());
        let s = loop {
            let s = self.state.load(Ordering::SeqCst);
            if done(s) || give_up() {
                break s;
            }
            guard = self
                .wake
                .wait_timeout(guard, SIGNAL_POLL)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        };
        drop(guard);
        self.waiters.fetch_sub(1, Ordering::SeqCst);
        s
    }

    fn data(&self) -> std::sync::MutexGuard<'_, Data> {
        self.data.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The run's side: publishes the observation `fill` writes (and `first` before the first
    /// one), waits for the caller's commands and copies them into `out`.
    pub fn exchange(
        &self,
        first: Option<LawContext>,
        fill: impl FnOnce(&mut Vec<f64>),
        out: &mut [f64],
    ) -> Result<(), Stop> {
        {
            let mut d = self.data();
            if first.is_some() {
                d.first = first;
            }
            fill(&mut d.obs);
        }
        if self.advance(&[START, CMD], OBS).is_err() {
            return Err(Stop::Closed(self.data().closed.clone()));
        }
        match self.wait(&self.run_looks, |s| s == CMD || s == CLOSED, || false) {
            CMD => {
                let d = self.data();
                if d.cmd.len() != out.len() {
                    return Err(Stop::Failed(format!(
                        "the caller sent {} commands for {} vehicles",
                        d.cmd.len(),
                        out.len()
                    )));
                }
                out.copy_from_slice(&d.cmd);
                Ok(())
            }
            _ => Err(Stop::Closed(self.data().closed.clone())),
        }
    }

    /// The run's side: no observation follows (the run ended, whatever the reason).
    pub fn end(&self) {
        self.set(ENDED);
    }
}

/// The caller's end of a [`Shared`] meeting point, as a Python object
/// (`syncroad._syncroad.Handoff`); the run's controller finds it on the object it is built
/// from (its `syncroad_handoff` attribute).
#[pyclass(module = "syncroad._syncroad", frozen)]
#[derive(Debug)]
pub struct Handoff {
    shared: Arc<Shared>,
}

impl Handoff {
    /// The run's end of this meeting point.
    pub fn shared(&self) -> Arc<Shared> {
        self.shared.clone()
    }

    /// [`Handoff::wait`], after handing over the commands already in place when `send`.
    fn wait_for(&self, py: Python<'_>, timeout_s: Option<f64>, mut send: bool) -> PyResult<u8> {
        let shared = self.shared.clone();
        let deadline = timeout_s.map(|t| Instant::now() + Duration::from_secs_f64(t.max(0.0)));
        loop {
            let (sent, s) = py.detach(|| {
                let sent = !send || shared.advance(&[OBS], CMD).is_ok();
                // Back to the interpreter every few blocked waits, for its signals.
                let mut polls = 0u32;
                let s = shared.wait(
                    &shared.caller_looks,
                    |s| s == OBS || s == ENDED,
                    || {
                        polls += 1;
                        polls >= SIGNAL_POLLS || deadline.is_some_and(|d| Instant::now() >= d)
                    },
                );
                (sent, s)
            });
            if !sent {
                return Err(PyValueError::new_err("the run is not waiting for commands"));
            }
            send = false;
            match s {
                OBS => return Ok(1),
                ENDED => return Ok(2),
                _ => {}
            }
            py.check_signals()?;
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Ok(0);
            }
        }
    }
}

impl Drop for Handoff {
    /// A caller that goes away closes the run, which would otherwise wait for it forever.
    fn drop(&mut self) {
        self.shared
            .close("the caller went away before the run's horizon".into());
    }
}

#[pymethods]
impl Handoff {
    #[new]
    fn new() -> Self {
        Self {
            shared: Arc::new(Shared::default()),
        }
    }

    /// Waits up to `timeout_s` (None: without limit) for the run's next observation, with
    /// the interpreter released: 1 when it is there ([`Handoff::take`]), 2 when the run ended
    /// instead, 0 when the time ran out. A pending signal (Ctrl-C) raises its exception.
    #[pyo3(signature = (timeout_s=None))]
    fn wait(&self, py: Python<'_>, timeout_s: Option<f64>) -> PyResult<u8> {
        self.wait_for(py, timeout_s, false)
    }

    /// Hands the run one command per vehicle (float64 bytes, native order) for its next step,
    /// then waits for its next observation as [`Handoff::wait`] does without a time limit.
    /// The commands go out once the interpreter is released, so the run takes it back at once.
    fn step(&self, py: Python<'_>, commands: &[u8]) -> PyResult<u8> {
        if self.shared.state.load(Ordering::SeqCst) != OBS {
            return Err(PyValueError::new_err(
                "the run is not waiting for commands (no observation was taken)",
            ));
        }
        if !commands.len().is_multiple_of(8) {
            return Err(PyValueError::new_err(format!(
                "commands: {} bytes, not a whole number of float64",
                commands.len()
            )));
        }
        {
            let mut d = self.shared.data();
            d.cmd.clear();
            d.cmd.extend(
                commands
                    .chunks_exact(8)
                    .map(|c| f64::from_ne_bytes(c.try_into().expect("8 bytes"))),
            );
        }
        self.wait_for(py, None, true)
    }

    /// The fields sent once (`dt_s`, `ids`, `controlled`, `length_m`, `ring_length_m`,
    /// `speed_limit_mps`) as a dict of lists and numbers; None before the first observation.
    fn first<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(f) = self.shared.data().first.clone() else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("dt_s", f.step_s)?;
        d.set_item("ids", f.ids)?;
        d.set_item("controlled", f.controlled)?;
        d.set_item("length_m", f.length_m)?;
        d.set_item("ring_length_m", f.ring_length_m)?;
        d.set_item(
            "speed_limit_mps",
            f.speed_limit_mps.unwrap_or(f64::INFINITY),
        )?;
        Ok(Some(d))
    }

    /// The observation waiting for the caller as float64 bytes: time, step, then the rows.
    fn take<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        if self.shared.state.load(Ordering::SeqCst) != OBS {
            return Err(PyValueError::new_err("no observation is waiting"));
        }
        let d = self.shared.data();
        // SAFETY: a slice of f64 viewed as its bytes (any bit pattern is a valid u8).
        let bytes =
            unsafe { std::slice::from_raw_parts(d.obs.as_ptr().cast::<u8>(), 8 * d.obs.len()) };
        Ok(PyBytes::new(py, bytes))
    }

    /// Closes the run: it stops at its next step, saying `reason`.
    fn close(&self, reason: String) {
        self.shared.close(reason);
    }
}

/// Whether a run of this process holds its libsumo.
static LIBSUMO_TAKEN: AtomicBool = AtomicBool::new(false);

/// Takes this process's libsumo for one run; false while another run holds it.
pub fn claim_libsumo() -> bool {
    LIBSUMO_TAKEN
        .compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst)
        .is_ok()
}

/// Gives this process's libsumo back.
pub fn release_libsumo() {
    LIBSUMO_TAKEN.store(false, Ordering::SeqCst);
}

thread_local! {
    static HERE: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f` with the SUMO runs it starts on this thread stepped in this process (a thread of
/// its own, with this process's libsumo, which the caller has claimed) instead of a worker.
pub fn here<T>(f: impl FnOnce() -> T) -> T {
    struct Reset(bool);
    impl Drop for Reset {
        fn drop(&mut self) {
            HERE.with(|h| h.set(self.0));
        }
    }
    let _reset = Reset(HERE.with(|h| h.replace(true)));
    f()
}

/// True inside [`here`].
pub(crate) fn is_here() -> bool {
    HERE.with(Cell::get)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The caller's side of one step, as `Simulation` makes it: the observation's values,
    /// then commands `f(observation)`; None once the run ended.
    fn caller_step(s: &Shared, f: impl Fn(&[f64]) -> Vec<f64>) -> Option<Vec<f64>> {
        if s.wait(&s.caller_looks, |x| x == OBS || x == ENDED, || false) == ENDED {
            return None;
        }
        let obs = s.data().obs.clone();
        s.data().cmd = f(&obs);
        s.advance(&[OBS], CMD).expect("the run waits for commands");
        Some(obs)
    }

    #[test]
    fn every_observation_meets_its_commands_in_order_and_the_end_is_seen() {
        let s = Arc::new(Shared::default());
        let run = {
            let s = s.clone();
            std::thread::spawn(move || {
                // The run's side: observation k is [k, 10k]; the command must be k + 1.
                let mut got = Vec::new();
                for k in 0..500 {
                    let mut out = [0.0];
                    let first = (k == 0).then(|| LawContext {
                        step_s: 0.1,
                        ids: vec!["a".into()],
                        length_m: vec![5.0],
                        ring_length_m: None,
                        controlled: vec![true],
                        accel_mps2: 2.6,
                        decel_mps2: 4.5,
                        speed_limit_mps: None,
                        signals: false,
                        seed: 0,
                        protocol: None,
                    });
                    let obs = [k as f64, 10.0 * k as f64];
                    s.exchange(first, |o| *o = obs.to_vec(), &mut out)
                        .expect("the caller answers");
                    got.push(out[0]);
                }
                s.end();
                got
            })
        };
        let mut seen = 0;
        while let Some(obs) = caller_step(&s, |o| vec![o[0] + 1.0]) {
            assert_eq!(obs, vec![seen as f64, 10.0 * seen as f64]);
            seen += 1;
        }
        assert_eq!(seen, 500);
        let got = run.join().unwrap();
        assert_eq!(got, (1..=500).map(f64::from).collect::<Vec<_>>());
        assert_eq!(s.data().first.as_ref().unwrap().ids, vec!["a".to_string()]);
    }

    #[test]
    fn a_close_reaches_the_run_whether_it_waits_or_is_about_to_publish() {
        // Closed while the run waits for commands.
        let s = Arc::new(Shared::default());
        let run = {
            let s = s.clone();
            std::thread::spawn(move || {
                let mut out = [0.0];
                let r = s.exchange(None, |o| *o = vec![0.0], &mut out);
                s.end();
                r
            })
        };
        assert_eq!(s.wait(&s.caller_looks, |x| x == OBS, || false), OBS);
        s.close("closed by the caller".into());
        assert_eq!(
            run.join().unwrap(),
            Err(Stop::Closed("closed by the caller".into()))
        );
        assert_eq!(s.state.load(Ordering::SeqCst), ENDED);
        // Closed before the run publishes: the observation is never offered.
        let s = Shared::default();
        s.close("gone".into());
        let mut out = [0.0];
        assert_eq!(
            s.exchange(None, |o| *o = vec![1.0], &mut out),
            Err(Stop::Closed("gone".into()))
        );
        // A close after the end changes nothing.
        s.end();
        s.close("late".into());
        assert_eq!(s.state.load(Ordering::SeqCst), ENDED);
    }

    #[test]
    fn commands_of_the_wrong_count_fail_the_run() {
        let s = Arc::new(Shared::default());
        let run = {
            let s = s.clone();
            std::thread::spawn(move || {
                let mut out = [0.0, 0.0];
                s.exchange(None, |o| *o = vec![0.0], &mut out)
            })
        };
        caller_step(&s, |_| vec![1.0]);
        assert_eq!(
            run.join().unwrap(),
            Err(Stop::Failed(
                "the caller sent 1 commands for 2 vehicles".into()
            ))
        );
    }
}
