//! The user's Python controller in a process of its own, for the native simulator: the
//! simulator and every row it computes stay in the caller's process (the CLI, a notebook), and
//! only the controller's `step` runs in a supervised child, as it runs inside a SUMO worker. Its
//! `os._exit`, a crash, the signal handlers it installs, the memory it takes and the processes
//! it starts end with the child; a `step` that blocks is stopped by the run's time limit or by
//! Ctrl-C. The run then stops at that step with the reason, every row before it kept.
//!
//! The child is this crate's worker program started with [`SERVE_ENV`] set ([`crate::serve`]): it reads the law
//! and its context as one JSON line, builds the controller with [`PythonHost`] and answers one
//! request per step. The exchange after the JSON line, little-endian:
//! * child → parent once: `B` (built) or `R`, a `u32` length and the reason (refused);
//! * parent → child each step: `S`, the time `f64`, `n: u32`, `n` speeds and `n` positions;
//! * child → parent each step: `C`, `n: u32` and `n` commands, or `F`, a `u32` length and the
//!   reason (the controller failed: it raised, or returned what is not a speed).

use std::collections::VecDeque;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::process::{Child, ChildStdin, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use syncroad_control::controller::ControllerError;
use syncroad_control::user_law::{LawContext, PythonLaw};
use syncroad_control::{ControllerEnd, LawHost, SpeedController};

use crate::serve::{Setup, SERVE_ENV};
use crate::supervisor::WorkerCommand;
use crate::user_law::PythonHost;

/// Lines of the child's output (the controller's prints, Python's last words) kept for
/// messages.
const TAIL_LINES: usize = 20;

/// Builds the user's Python controllers in a supervised child process each ([`ContainedController`]).
#[derive(Debug, Clone)]
pub struct ContainedHost {
    worker: Result<WorkerCommand, String>,
    /// When the run must have ended (its time limit), if it has one.
    deadline: Option<Instant>,
    /// The process's stop flag (Ctrl-C, SIGTERM, SIGHUP, once the caller installed the
    /// handlers with [`crate::interrupt_flag`]): a step waiting for the child gives up when it
    /// is set, and the run's loop stops on it.
    cancel: Option<Arc<AtomicBool>>,
}

impl ContainedHost {
    /// A host whose children are `worker` (the process's own: [`WorkerCommand::for_process`]),
    /// held to `timeout` from now and stopped by the process's stop flag.
    pub fn new(worker: std::io::Result<WorkerCommand>, timeout: Option<Duration>) -> Self {
        Self {
            worker: worker.map_err(|e| format!("cannot locate the worker program: {e}")),
            deadline: timeout.map(|t| Instant::now() + t),
            // Read, never installed here: a library caller keeps its own signal handling.
            cancel: Some(crate::signals::stop_flag()),
        }
    }
}

impl LawHost for ContainedHost {
    fn python(
        &self,
        law: &PythonLaw,
        context: &LawContext,
    ) -> Result<Box<dyn SpeedController>, ControllerError> {
        let fail = |reason: String| ControllerError::Python {
            python: law.python.clone(),
            reason,
        };
        if is_simulation_stand_in(law) {
            return PythonHost.python(law, context);
        }
        let worker = self.worker.as_ref().map_err(|e| fail(e.clone()))?;
        ContainedController::start(worker, law, context, self.deadline, self.cancel.clone())
            .map(|c| Box::new(c) as Box<dyn SpeedController>)
            .map_err(|e| match e {
                Start::Refused(why) => fail(why),
                // A time limit or Ctrl-C while `__init__` ran: the run failed, not its input.
                Start::Stopped(why) => ControllerError::TimedOut {
                    python: law.python.clone(),
                    reason: why,
                },
            })
    }
}

/// Whether `law` is the stand-in a `syncroad.Simulation` puts into its run
/// (`SimulationController` of the package's `_remote.py`): the caller's own stepping loop, met
/// in memory in the caller's process, so it is built there, not in a process of its own.
fn is_simulation_stand_in(law: &PythonLaw) -> bool {
    law.class == "SimulationController"
        && matches!(
            &law.source,
            syncroad_control::user_law::PythonSource::File { path }
                if path.ends_with("syncroad/_remote.py")
        )
}

/// Why a controller's process did not start serving.
enum Start {
    /// It could not build the controller (bad input), or could not be started at all.
    Refused(String),
    /// The run's time limit passed, or Ctrl-C came, while it built the controller.
    Stopped(String),
}

/// What the child said.
enum Reply {
    Built,
    Refused(String),
    Commands(Vec<f64>),
    Failed(String),
    /// Its output ended: it exited or was killed.
    Gone,
}

/// Reads one reply from the child's protocol stream.
fn read_reply(r: &mut impl Read) -> std::io::Result<Reply> {
    let mut tag = [0u8; 1];
    if r.read(&mut tag)? == 0 {
        return Ok(Reply::Gone);
    }
    let mut word = [0u8; 4];
    let text = |r: &mut dyn Read, word: &mut [u8; 4]| -> std::io::Result<String> {
        r.read_exact(word)?;
        let mut bytes = vec![0u8; u32::from_le_bytes(*word) as usize];
        r.read_exact(&mut bytes)?;
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    };
    Ok(match tag[0] {
        b'B' => Reply::Built,
        b'R' => Reply::Refused(text(r, &mut word)?),
        b'F' => Reply::Failed(text(r, &mut word)?),
        b'C' => {
            r.read_exact(&mut word)?;
            let n = u32::from_le_bytes(word) as usize;
            let mut bytes = vec![0u8; 8 * n];
            r.read_exact(&mut bytes)?;
            Reply::Commands(
                bytes
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                    .collect(),
            )
        }
        other => {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("unknown reply {other:#04x}"),
            ))
        }
    })
}

/// The user's Python controller stepped in a child process ([`ContainedHost`]).
pub struct ContainedController {
    child: Child,
    stdin: Option<BufWriter<ChildStdin>>,
    replies: mpsc::Receiver<std::io::Result<Reply>>,
    tail: Arc<Mutex<VecDeque<String>>>,
    threads: Vec<std::thread::JoinHandle<()>>,
    deadline: Option<Instant>,
    cancel: Option<Arc<AtomicBool>>,
    ended: Option<ControllerEnd>,
    frame: Vec<u8>,
}

impl ContainedController {
    fn start(
        worker: &WorkerCommand,
        law: &PythonLaw,
        context: &LawContext,
        deadline: Option<Instant>,
        cancel: Option<Arc<AtomicBool>>,
    ) -> Result<Self, Start> {
        let mut child = worker
            .command()
            .env(SERVE_ENV, "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()
            .map_err(|e| {
                Start::Refused(format!(
                    "cannot start the controller's process {}: {e}",
                    worker.program.display()
                ))
            })?;
        let tail = Arc::new(Mutex::new(VecDeque::new()));
        let mut threads = Vec::new();
        if let Some(err) = child.stderr.take() {
            let tail = tail.clone();
            threads.push(std::thread::spawn(move || {
                for line in BufReader::new(err).lines().map_while(Result::ok) {
                    let mut t = tail.lock().unwrap_or_else(|e| e.into_inner());
                    if t.len() == TAIL_LINES {
                        t.pop_front();
                    }
                    t.push_back(syncroad_control::user_text::kept(line));
                }
            }));
        }
        let (tx, replies) = mpsc::channel();
        let out = child.stdout.take().expect("piped stdout");
        threads.push(std::thread::spawn(move || {
            let mut r = BufReader::new(out);
            loop {
                let reply = read_reply(&mut r);
                let end = !matches!(reply, Ok(Reply::Built | Reply::Commands(_)));
                if tx.send(reply).is_err() || end {
                    break;
                }
            }
        }));
        let mut c = Self {
            stdin: child.stdin.take().map(BufWriter::new),
            child,
            replies,
            tail,
            threads,
            deadline,
            cancel,
            ended: None,
            frame: Vec::new(),
        };
        let setup = serde_json::to_string(&Setup {
            law: law.clone(),
            context: context.clone(),
        })
        .map_err(|e| Start::Refused(e.to_string()))?;
        let sent = c.send(|w| writeln!(w, "{setup}"));
        match c.wait_reply("while the controller was built (its __init__ ran)") {
            Ok(Reply::Built) if sent.is_ok() => Ok(c),
            Ok(Reply::Refused(why)) => Err(Start::Refused(why)),
            Ok(Reply::Built) => Err(Start::Refused(
                "the controller's process stopped reading".into(),
            )),
            Ok(Reply::Failed(why)) => Err(Start::Refused(why)),
            Ok(Reply::Commands(_)) => Err(Start::Refused(
                "the controller's process answered out of turn".into(),
            )),
            Ok(Reply::Gone) => Err(Start::Refused(c.gone("while its controller was built"))),
            Err(why) => Err(Start::Stopped(why)),
        }
    }

    fn send(
        &mut self,
        f: impl FnOnce(&mut BufWriter<ChildStdin>) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        let w = self
            .stdin
            .as_mut()
            .ok_or_else(|| std::io::Error::from(std::io::ErrorKind::BrokenPipe))?;
        f(w).and_then(|()| w.flush())
    }

    /// The next reply, waiting no longer than the run's time limit and giving up on Ctrl-C
    /// (`Err` says which).
    fn wait_reply(&mut self, during: &str) -> Result<Reply, String> {
        loop {
            let tick = Duration::from_millis(50);
            match self.replies.recv_timeout(tick) {
                Ok(Ok(r)) => return Ok(r),
                Ok(Err(e)) => {
                    return Err(format!(
                        "the controller's process sent what it may not: {e}"
                    ))
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(Reply::Gone),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if self.deadline.is_some_and(|d| Instant::now() >= d) {
                self.kill();
                return Err(format!(
                    "the run exceeded its time limit {during} (it blocked, or is slower than the limit allows); the controller's process was stopped (raise --timeout-s)"
                ));
            }
            if self.cancelled() {
                self.kill();
                return Err(format!("interrupted {during}"));
            }
        }
    }

    fn cancelled(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::SeqCst))
    }

    /// Why the child is gone: its exit code or signal, and its last output.
    fn gone(&mut self, when: &str) -> String {
        let how = match self.child.wait() {
            Ok(st) => match st.signal() {
                Some(sig) => format!("was killed by signal {sig}"),
                None => format!("exited with code {}", st.code().unwrap_or(-1)),
            },
            Err(e) => format!("could not be waited for ({e})"),
        };
        // The reader of its output ends with the process group.
        self.kill();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let tail: Vec<String> = self
            .tail
            .lock()
            .map(|t| t.iter().cloned().collect())
            .unwrap_or_default();
        format!(
            "the controller's process (pid {}) {how} {when}; its last output:\n{}",
            self.child.id(),
            tail.join("\n")
        )
    }

    /// Kills the child's process group (its helpers too); the child is reaped on drop.
    fn kill(&mut self) {
        self.stdin = None;
        // SAFETY: the group this controller's child leads; the child is not reaped before
        // drop, so its id cannot name another group.
        unsafe { libc::killpg(self.child.id() as libc::pid_t, libc::SIGKILL) };
    }
}

impl SpeedController for ContainedController {
    fn step(&mut self, time_s: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        out.copy_from_slice(speeds);
        if self.ended.is_some() {
            return;
        }
        let n = speeds.len();
        let mut frame = std::mem::take(&mut self.frame);
        frame.clear();
        frame.push(b'S');
        frame.extend(time_s.to_le_bytes());
        frame.extend((n as u32).to_le_bytes());
        for x in speeds.iter().chain(positions) {
            frame.extend(x.to_le_bytes());
        }
        let sent = self.send(|w| w.write_all(&frame));
        self.frame = frame;
        let reply = match sent {
            Ok(()) => self.wait_reply("while the controller's step ran"),
            Err(_) => Ok(Reply::Gone),
        };
        self.ended = match reply {
            Ok(Reply::Commands(c)) if c.len() == n => {
                out.copy_from_slice(&c);
                None
            }
            Ok(Reply::Failed(why)) => Some(ControllerEnd::Failed(why)),
            Ok(Reply::Gone) => Some(ControllerEnd::Failed(self.gone("during its step"))),
            Ok(_) => Some(ControllerEnd::Failed(
                "the controller's process answered out of turn".into(),
            )),
            // Ctrl-C: the run's loop stops on its flag, this step's commands unused.
            Err(_) if self.cancelled() => None,
            Err(why) => Some(ControllerEnd::Failed(why)),
        };
    }

    fn ended(&mut self) -> Option<ControllerEnd> {
        self.ended.clone()
    }
}

impl Drop for ContainedController {
    fn drop(&mut self) {
        self.kill();
        let _ = self.child.wait();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
