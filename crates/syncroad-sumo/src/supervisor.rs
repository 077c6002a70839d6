//! The parent side: starts a worker process, feeds it a [`Request`], collects the streamed rows
//! and turns every way a worker can end (finished, failed, crashed on a signal, timed out,
//! interrupted by Ctrl-C) into a result that still holds every row received.

use std::collections::VecDeque;
use std::ffi::OsString;
use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use syncroad_control::Trajectory;

use crate::frozen::FrozenWatch;
use crate::protocol::{read_frame, Event, Finish, Frame, JobRef, Request, StartInfo, WorkerMsg};
use crate::worker::WORKER_ARG;

/// Lines of worker stderr kept for error messages.
const STDERR_LINES: usize = 30;

/// Exit code for a run interrupted by Ctrl-C (128 + SIGINT).
pub const EXIT_INTERRUPTED: u8 = 130;

/// How to start a worker.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkerCommand {
    /// The executable.
    pub program: PathBuf,
    /// Its arguments.
    pub args: Vec<OsString>,
    /// The worker embeds the libpython this crate was built against (a Rust binary): it is
    /// given that interpreter's libdir and home (see build.rs). False for a worker that is a
    /// Python interpreter itself (`python -m syncroad._worker`), which brings its own.
    pub embeds_build_python: bool,
}

/// The worker command of this process when it is not the running executable (set once by a
/// host such as the Python package, whose executable is the Python interpreter).
static PROCESS_WORKER: std::sync::OnceLock<WorkerCommand> = std::sync::OnceLock::new();

impl WorkerCommand {
    /// The running executable re-executed as a worker (`<exe> __sumo-worker`); the binary must
    /// call [`crate::worker_main`] when it sees [`WORKER_ARG`].
    pub fn current_exe() -> std::io::Result<Self> {
        Ok(Self {
            program: std::env::current_exe()?,
            args: vec![WORKER_ARG.into()],
            embeds_build_python: true,
        })
    }

    /// A given worker binary (e.g. `syncroad-sumo-worker`).
    pub fn binary(program: impl Into<PathBuf>) -> Self {
        Self {
            program: program.into(),
            args: Vec::new(),
            embeds_build_python: true,
        }
    }

    /// A Python interpreter running a module whose entry calls
    /// [`crate::worker_main_with`]`(`[`SumoPackages::Interpreter`](crate::SumoPackages)`)`:
    /// `python -m syncroad._worker`.
    pub fn python_module(python: impl Into<PathBuf>, module: &str) -> Self {
        Self {
            program: python.into(),
            args: vec!["-m".into(), module.into()],
            embeds_build_python: false,
        }
    }

    /// The worker of this process: the one set by [`WorkerCommand::set_for_process`], else
    /// the running executable ([`WorkerCommand::current_exe`]).
    pub fn for_process() -> std::io::Result<Self> {
        match PROCESS_WORKER.get() {
            Some(cmd) => Ok(cmd.clone()),
            None => Self::current_exe(),
        }
    }

    /// The process to start, with its arguments and environment (the libpython it was built
    /// against, one OpenBLAS thread), its standard streams left to the caller.
    pub(crate) fn command(&self) -> Command {
        let mut command = Command::new(&self.program);
        if self.embeds_build_python {
            pin_build_python(&mut command);
        }
        // numpy (which a user's Python controller or the full libsumo package imports) starts an
        // OpenBLAS thread per core that the worker never uses; in a sweep those threads took
        // cycles from the other workers' SUMO steps.
        if std::env::var_os("OPENBLAS_NUM_THREADS").is_none() {
            command.env("OPENBLAS_NUM_THREADS", "1");
        }
        command.args(&self.args);
        command
    }

    /// Sets the worker of every run this process starts through [`WorkerCommand::for_process`]
    /// (once; a second call returns `false` and changes nothing).
    pub fn set_for_process(cmd: WorkerCommand) -> bool {
        PROCESS_WORKER.set(cmd).is_ok()
    }
}

/// Gives a worker that embeds Python the libpython and standard library of the interpreter
/// pyo3 was built against, not those of the first `python3` on PATH (see build.rs).
fn pin_build_python(command: &mut Command) {
    if let Some(libdir) = option_env!("SYNCROAD_PYTHON_LIBDIR") {
        let mut paths = vec![PathBuf::from(libdir)];
        if let Some(old) = std::env::var_os("LD_LIBRARY_PATH") {
            paths.extend(std::env::split_paths(&old));
        }
        if let Ok(joined) = std::env::join_paths(paths) {
            command.env("LD_LIBRARY_PATH", joined);
        }
    }
    if let (None, Some(home)) = (
        std::env::var_os("PYTHONHOME"),
        option_env!("SYNCROAD_PYTHON_HOME"),
    ) {
        command.env("PYTHONHOME", home);
    }
}

/// Called once SUMO runs in the worker (e.g. to show progress).
pub type StartHook = Arc<dyn Fn(&StartInfo) + Send + Sync>;

/// Where a run stands each time a chunk of rows arrives from the worker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowsProgress {
    /// The worker's process id.
    pub pid: u32,
    /// Samples (recorded steps) received so far; each is whole, and each is kept whatever
    /// happens to the run after this call.
    pub records: usize,
    /// Simulated time of the last sample received \[s\].
    pub time_s: f64,
}

/// Called after each chunk of rows the worker sends (at most every 200 ms of the worker's
/// wall time, and at the end): progress reports, and tests that must act once a run has
/// recorded something rather than after a guessed delay.
pub type RowsHook = Arc<dyn Fn(&RowsProgress) + Send + Sync>;

/// Limits of one supervised run.
#[derive(Clone, Default)]
pub struct Supervision {
    /// Wall-clock limit (none when `None`).
    pub timeout: Option<Duration>,
    /// Set by a Ctrl-C handler ([`interrupt_flag`]); the worker is stopped when it turns true.
    pub interrupt: Option<Arc<AtomicBool>>,
    /// Called when the worker reports that SUMO started.
    pub on_start: Option<StartHook>,
    /// Called after each chunk of rows received.
    pub on_rows: Option<RowsHook>,
}

impl std::fmt::Debug for Supervision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Supervision")
            .field("timeout", &self.timeout)
            .field("interrupt", &self.interrupt)
            .field("on_start", &self.on_start.as_ref().map(|_| "hook"))
            .field("on_rows", &self.on_rows.as_ref().map(|_| "hook"))
            .finish()
    }
}

/// The process-wide stop flag, set by Ctrl-C, SIGTERM or SIGHUP (see `signals`). Workers run
/// in their own process group, so a terminal Ctrl-C reaches only the parent, which stops the
/// worker itself and keeps what it received.
pub fn interrupt_flag() -> Result<Arc<AtomicBool>, SupervisorError> {
    crate::signals::interrupt_flag().map_err(SupervisorError::CtrlC)
}

/// How a supervised run failed. Rows received before the failure stay in [`WorkerRun`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SupervisorError {
    /// The worker could not be started.
    #[error("cannot start the SUMO worker {program}: {reason}")]
    Spawn {
        /// The executable.
        program: String,
        /// The OS error.
        reason: String,
    },
    /// The signal handlers could not be installed.
    #[error("cannot install the Ctrl-C/SIGTERM/SIGHUP handlers: {0}")]
    CtrlC(String),
    /// The worker died on a signal (e.g. SIGSEGV inside libsumo on a malformed net).
    #[error("the SUMO worker (pid {pid}) crashed with signal {signal} ({name}) after {records} recorded samples; its last output:\n{stderr_tail}")]
    Crashed {
        /// Worker pid.
        pid: u32,
        /// Signal number.
        signal: i32,
        /// Signal name.
        name: &'static str,
        /// Samples received before the crash.
        records: usize,
        /// Last lines of the worker's stderr (SUMO's console output).
        stderr_tail: String,
    },
    /// The worker exited without reporting a result.
    #[error("the SUMO worker (pid {pid}) exited with code {code} without a result; its last output:\n{stderr_tail}")]
    Exited {
        /// Worker pid.
        pid: u32,
        /// Exit code.
        code: i32,
        /// Last stderr lines.
        stderr_tail: String,
    },
    /// The wall-clock limit was reached.
    #[error("the SUMO run exceeded its time limit of {seconds} s and was stopped after {records} recorded samples (raise sumo.timeout_s)")]
    Timeout {
        /// The limit \[s\].
        seconds: f64,
        /// Samples received.
        records: usize,
    },
    /// The worker stayed stopped (SIGSTOP, SIGTSTP) for [`crate::FROZEN_LIMIT`]; it was killed.
    #[error("the SUMO worker (pid {pid}) was stopped (SIGSTOP or SIGTSTP) for {seconds:.0} s and was killed after {records} recorded samples; the run failed (a sweep's --retry-failed runs it again)")]
    Frozen {
        /// Worker pid.
        pid: u32,
        /// How long it was stopped \[s\].
        seconds: f64,
        /// Samples received.
        records: usize,
    },
    /// Ctrl-C, SIGTERM or SIGHUP.
    #[error(
        "interrupted ({}) after {records} recorded samples",
        crate::signals::received_name()
    )]
    Interrupted {
        /// Samples received.
        records: usize,
    },
    /// The worker reported a clean failure.
    #[error("{0}")]
    Worker(String),
    /// The worker refused the run before SUMO started: its law could not be built (the
    /// user's controller: its file, class or parameters). Bad input, not a failed run.
    #[error("{0}")]
    Refused(String),
    /// The stream from the worker was corrupted.
    #[error("protocol error talking to the SUMO worker: {0}")]
    Protocol(#[from] crate::protocol::ProtocolError),
    /// Waiting for the worker failed.
    #[error("waiting for the SUMO worker failed: {0}")]
    Wait(String),
}

impl SupervisorError {
    /// Process exit code the CLI should use: 130 for Ctrl-C, else `None` (the CLI's default).
    pub fn exit_code(&self) -> Option<u8> {
        matches!(self, SupervisorError::Interrupted { .. }).then_some(EXIT_INTERRUPTED)
    }
}

/// Everything a worker produced.
#[derive(Debug, Clone)]
pub struct WorkerRun {
    /// Start information (absent if SUMO never started).
    pub start: Option<StartInfo>,
    /// Every row received.
    pub rows: Trajectory,
    /// `(t, min v_i, max v_i)` of every step received (leader vehicle excluded): the spread at
    /// every step, whatever the recording stride.
    pub ranges: Vec<[f64; 3]>,
    /// Every event received.
    pub events: Vec<Event>,
    /// The end of the run, or why there is none.
    pub result: Result<Finish, SupervisorError>,
    /// Worker pid.
    pub pid: u32,
    /// The rows and steps a whole run sends (room is made for them at its first rows).
    expected: (usize, usize),
}

impl WorkerRun {
    /// Keeps what one frame of the worker brings (rows, ranges, events; the end in `end`) and
    /// calls the hooks of `limits` for it.
    fn take(
        &mut self,
        f: Frame,
        limits: &Supervision,
        end: &mut Option<Result<Finish, SupervisorError>>,
    ) {
        match f {
            Frame::Rows(mut c) => {
                let time_s = c.time_s.last().copied();
                if self.rows.is_empty() {
                    let (rows, steps) = self.expected;
                    self.rows.reserve_commanded(rows);
                    self.ranges.reserve(steps);
                }
                self.rows.append(&mut c);
                if let (Some(hook), Some(time_s)) = (&limits.on_rows, time_s) {
                    hook(&RowsProgress {
                        pid: self.pid,
                        records: self.rows.len(),
                        time_s,
                    });
                }
            }
            Frame::Ranges(mut r) => self.ranges.append(&mut r),
            Frame::Msg(WorkerMsg::Started(s)) => {
                if let Some(hook) = &limits.on_start {
                    hook(&s);
                }
                self.start = Some(s);
            }
            Frame::Msg(WorkerMsg::Event(e)) => self.events.push(e),
            Frame::Msg(WorkerMsg::Finished(f)) => *end = Some(Ok(*f)),
            Frame::Msg(WorkerMsg::Failed { message }) => {
                *end = Some(Err(SupervisorError::Worker(message)))
            }
            Frame::Msg(WorkerMsg::Refused { message }) => {
                *end = Some(Err(SupervisorError::Refused(message)))
            }
        }
    }

    /// A run with nothing received yet.
    fn empty(request: &Request, result: Result<Finish, SupervisorError>, pid: u32) -> Self {
        Self {
            start: None,
            rows: Trajectory::new(request.layout.vehicles.len()),
            ranges: Vec::new(),
            events: Vec::new(),
            result,
            pid,
            // At most 2^24 values a vector made room for at once (beyond, the vectors grow as the
            // rows come: a run whose horizon would not fit must fail when it gets there, not
            // at its start).
            expected: {
                const AT_ONCE: usize = 1 << 24;
                let n = request.layout.vehicles.len().max(1);
                let rows = Trajectory::samples_recorded(request.steps, request.record_every);
                (rows.min(AT_ONCE / n), (request.steps + 1).min(AT_ONCE / 3))
            },
        }
    }

    /// True when the worker finished the run and reported its end.
    pub fn complete(&self) -> bool {
        self.result.is_ok()
    }
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        libc::SIGPIPE => "SIGPIPE",
        _ => "signal",
    }
}

/// A worker process that runs requests one after another: SUMO is started and closed for each
/// run inside the same process, so only the first run pays for Python and the libsumo import.
/// A worker that crashed, timed out or was interrupted is gone ([`Worker::alive`] is false);
/// start a new one for the next run.
pub struct Worker {
    child: Child,
    stdin: Option<ChildStdin>,
    frames: mpsc::Receiver<Result<Option<Frame>, crate::protocol::ProtocolError>>,
    reader: Option<std::thread::JoinHandle<()>>,
    stderr_thread: Option<std::thread::JoinHandle<()>>,
    stderr_tail: Arc<Mutex<VecDeque<String>>>,
    stderr_lines: Arc<std::sync::atomic::AtomicUsize>,
    alive: bool,
    runs: usize,
}

impl std::fmt::Debug for Worker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker")
            .field("pid", &self.child.id())
            .field("alive", &self.alive)
            .field("runs", &self.runs)
            .finish()
    }
}

impl Worker {
    /// Starts a worker process (in its own process group, so a terminal Ctrl-C reaches only
    /// the parent).
    pub fn spawn(cmd: &WorkerCommand) -> Result<Self, SupervisorError> {
        let mut child = cmd
            .command()
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()
            .map_err(|e| SupervisorError::Spawn {
                program: cmd.program.display().to_string(),
                reason: e.to_string(),
            })?;
        let verbose = std::env::var_os("SYNCROAD_SUMO_VERBOSE").is_some();
        let stderr_tail = Arc::new(Mutex::new(VecDeque::<String>::new()));
        let stderr_lines = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let stderr_thread = child.stderr.take().map(|err| {
            let tail = stderr_tail.clone();
            let count = stderr_lines.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(err).lines().map_while(Result::ok) {
                    if verbose {
                        let _ = writeln!(std::io::stderr().lock(), "[sumo worker] {line}");
                    }
                    let mut t = tail.lock().expect("stderr tail lock");
                    if t.len() == STDERR_LINES {
                        t.pop_front();
                    }
                    t.push_back(tail_line(line));
                    count.fetch_add(1, Ordering::SeqCst);
                }
            })
        });
        let (tx, frames) = mpsc::channel();
        let stdout = child.stdout.take().expect("piped stdout");
        let reader = std::thread::spawn(move || {
            let mut r = BufReader::with_capacity(1 << 20, stdout);
            loop {
                let f = read_frame(&mut r);
                let end = !matches!(f, Ok(Some(_)));
                if tx.send(f).is_err() || end {
                    break;
                }
            }
        });
        Ok(Self {
            stdin: child.stdin.take(),
            child,
            frames,
            reader: Some(reader),
            stderr_thread,
            stderr_tail,
            stderr_lines,
            alive: true,
            runs: 0,
        })
    }

    /// The worker's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// False once the worker crashed, exited, or was stopped for a timeout or Ctrl-C.
    pub fn alive(&self) -> bool {
        self.alive
    }

    /// A worker's failure message with SUMO's own `Error:` lines of this run appended: libsumo
    /// reports only "Process Error" for a network it cannot load, and says why on stderr.
    fn with_sumo_errors(&self, message: String, lines_before: usize) -> String {
        // SUMO wrote its lines before the worker reported; give the reader a moment.
        std::thread::sleep(Duration::from_millis(100));
        let new = self
            .stderr_lines
            .load(Ordering::SeqCst)
            .saturating_sub(lines_before);
        let errors: Vec<String> = self
            .stderr_tail
            .lock()
            .map(|t| {
                let skip = t.len().saturating_sub(new);
                t.iter()
                    .skip(skip)
                    .filter(|l| l.trim_start().starts_with("Error"))
                    .cloned()
                    .collect()
            })
            .unwrap_or_default();
        if errors.is_empty() {
            message
        } else {
            format!("{message}\nSUMO said:\n{}", errors.join("\n"))
        }
    }

    fn tail_text(&self) -> String {
        self.stderr_tail
            .lock()
            .map(|t| {
                // The worker's output holds the user's prints: each line set off, escaped.
                t.iter()
                    .map(|l| format!("  | {}", syncroad_control::user_text::escaped(l)))
                    .collect::<Vec<_>>()
                    .join("\n")
            })
            .unwrap_or_default()
    }

    /// Runs `request` under `limits` and returns what the worker produced. The run ends with
    /// the worker's `Finished` or `Failed` message; a worker that dies instead is reaped and
    /// the way it ended (signal, exit code) becomes the error.
    pub fn run(&mut self, request: &Request, limits: &Supervision) -> WorkerRun {
        self.run_job(JobRef::Run(request), limits)
    }

    /// Runs `job` (a run, or a run under the benchmark's probe) under `limits`.
    pub(crate) fn run_job(&mut self, job: JobRef<'_>, limits: &Supervision) -> WorkerRun {
        let request = job.request();
        let mut run = WorkerRun::empty(
            request,
            Err(SupervisorError::Wait("not started".into())),
            self.pid(),
        );
        if !self.alive {
            run.result = Err(SupervisorError::Wait(
                "the worker is no longer running".into(),
            ));
            return run;
        }
        self.runs += 1;
        let lines_before = self.stderr_lines.load(Ordering::SeqCst);
        let line = serde_json::to_string(&job).expect("a job serialises");
        let sent = match self.stdin.as_mut() {
            Some(stdin) => writeln!(stdin, "{line}").and_then(|()| stdin.flush()),
            None => Err(std::io::Error::from(std::io::ErrorKind::BrokenPipe)),
        };
        let started = Instant::now();
        let mut watch = FrozenWatch::new(run.pid);
        let mut end: Option<Result<Finish, SupervisorError>> = None;
        let mut protocol: Option<crate::protocol::ProtocolError> = None;
        let mut stopped: Option<SupervisorError> = None;
        let mut eof = sent.is_err();
        let handle =
            |f: Frame, run: &mut WorkerRun, end: &mut Option<Result<Finish, SupervisorError>>| {
                run.take(f, limits, end)
            };
        while !eof {
            match self.frames.recv_timeout(Duration::from_millis(50)) {
                Ok(Ok(Some(frame))) => {
                    handle(frame, &mut run, &mut end);
                    if end.is_some() {
                        break;
                    }
                }
                Ok(Ok(None)) | Err(mpsc::RecvTimeoutError::Disconnected) => eof = true,
                Ok(Err(e)) => {
                    protocol = Some(e);
                    eof = true;
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
            if stopped.is_none() {
                stopped = stop_reason(limits, started, &mut watch);
                if stopped.is_some() {
                    let _ = self.child.kill();
                }
            }
        }
        // A run that ended with a message leaves the worker ready for the next one, unless it
        // was stopped; anything else means the process is gone or unusable.
        let ended_cleanly = stopped.is_none() && end.is_some();
        let status = if ended_cleanly {
            None
        } else {
            self.alive = false;
            let _ = self.child.kill();
            let status = self.reap();
            // The reader has ended: take every frame it got before the pipe closed.
            while let Ok(Ok(Some(frame))) = self.frames.try_recv() {
                handle(frame, &mut run, &mut end);
            }
            Some(status)
        };
        let records = run.rows.len();
        run.result = if let Some(s) = stopped {
            Err(match s {
                SupervisorError::Interrupted { .. } => SupervisorError::Interrupted { records },
                SupervisorError::Timeout { seconds, .. } => {
                    SupervisorError::Timeout { seconds, records }
                }
                SupervisorError::Frozen { pid, seconds, .. } => SupervisorError::Frozen {
                    pid,
                    seconds,
                    records,
                },
                other => other,
            })
        } else if let Some(e) = end {
            e.map_err(|e| match e {
                SupervisorError::Worker(m) => {
                    SupervisorError::Worker(self.with_sumo_errors(m, lines_before))
                }
                other => other,
            })
        } else {
            match status.expect("reaped above") {
                Ok(st) => match st.signal() {
                    Some(sig) => Err(SupervisorError::Crashed {
                        pid: run.pid,
                        signal: sig,
                        name: signal_name(sig),
                        records,
                        stderr_tail: self.tail_text(),
                    }),
                    None => match protocol {
                        Some(p) => Err(SupervisorError::Protocol(p)),
                        None => Err(SupervisorError::Exited {
                            pid: run.pid,
                            code: st.code().unwrap_or(-1),
                            stderr_tail: self.tail_text(),
                        }),
                    },
                },
                Err(e) => Err(SupervisorError::Wait(e.to_string())),
            }
        };
        run
    }

    /// Waits for the process, ends whatever it left running in its process group (a user's
    /// controller may start helpers or fork: they hold the worker's pipes open, and the reader
    /// threads would wait for them forever), and joins the reader threads.
    fn reap(&mut self) -> std::io::Result<std::process::ExitStatus> {
        self.stdin = None;
        end_group_after_exit(self.child.id());
        let status = self.child.wait();
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
        if let Some(t) = self.stderr_thread.take() {
            let _ = t.join();
        }
        status
    }
}

impl Drop for Worker {
    /// Closing stdin ends the worker's request loop; it exits by itself.
    fn drop(&mut self) {
        if self.alive {
            self.alive = false;
            let _ = self.reap();
        }
    }
}

/// Longest line of a worker's output kept in its tail \[bytes\]: the tail is quoted in errors.
const TAIL_LINE_BYTES: usize = 2000;

/// `line` cut to [`TAIL_LINE_BYTES`] (at a character boundary), saying how much was left out.
fn tail_line(mut line: String) -> String {
    if line.len() <= TAIL_LINE_BYTES {
        return line;
    }
    let total = line.len();
    let mut end = TAIL_LINE_BYTES;
    while !line.is_char_boundary(end) {
        end -= 1;
    }
    line.truncate(end);
    line.push_str(&format!(" [… {} more bytes]", total - end));
    line
}

/// Waits until the worker `pid` (a process-group leader: [`Worker::spawn`]) has exited, without
/// reaping it, then kills every process left in its group. Its exit status stays to be
/// collected by `wait`; until then the pid, and so the group id, cannot be taken by another
/// process, so the kill reaches only what the worker left behind.
fn end_group_after_exit(pid: u32) {
    let id: libc::id_t = pid;
    // SAFETY: waitid on our own child with WNOWAIT leaves it to be reaped by `Child::wait`;
    // killpg signals the group this supervisor created for it.
    unsafe {
        let mut info: libc::siginfo_t = std::mem::zeroed();
        loop {
            let r = libc::waitid(libc::P_PID, id, &mut info, libc::WEXITED | libc::WNOWAIT);
            if r == 0 {
                break;
            }
            if std::io::Error::last_os_error().kind() != std::io::ErrorKind::Interrupted {
                // Already reaped (ECHILD): its group id may be free again, so nothing is sent.
                return;
            }
        }
        libc::killpg(pid as libc::pid_t, libc::SIGKILL);
    }
}

/// Why a run in flight must stop now, if it must: Ctrl-C (or SIGTERM, SIGHUP), its time
/// limit, or a worker that stays stopped ([`FrozenWatch`]).
fn stop_reason(
    limits: &Supervision,
    started: Instant,
    watch: &mut FrozenWatch,
) -> Option<SupervisorError> {
    if limits
        .interrupt
        .as_ref()
        .is_some_and(|f| f.load(Ordering::SeqCst))
    {
        return Some(SupervisorError::Interrupted { records: 0 });
    }
    if let Some(t) = limits.timeout.filter(|t| started.elapsed() > *t) {
        return Some(SupervisorError::Timeout {
            seconds: t.as_secs_f64(),
            records: 0,
        });
    }
    watch.frozen().map(|d| SupervisorError::Frozen {
        pid: watch.pid(),
        seconds: d.as_secs_f64(),
        records: 0,
    })
}

/// Runs `request` in a new worker process started by `cmd`, under `limits`.
pub fn run_worker(cmd: &WorkerCommand, request: &Request, limits: &Supervision) -> WorkerRun {
    run_worker_job(cmd, JobRef::Run(request), limits)
}

/// Runs `job` in a new worker process started by `cmd`, under `limits`.
pub(crate) fn run_worker_job(
    cmd: &WorkerCommand,
    job: JobRef<'_>,
    limits: &Supervision,
) -> WorkerRun {
    if crate::handoff::is_here() {
        return run_here(job, limits);
    }
    match Worker::spawn(cmd) {
        Ok(mut w) => w.run_job(job, limits),
        Err(e) => WorkerRun::empty(job.request(), Err(e), 0),
    }
}

/// Runs `job` on a thread of this process, with this process's libsumo (the caller claimed it:
/// [`crate::handoff::here`]): the same loop and the same frames as a worker's, read as they
/// come. Nothing can stop a thread from outside, so the run's time limit and the frozen-worker
/// watch do not apply; the caller that steps the run ends it.
fn run_here(job: JobRef<'_>, limits: &Supervision) -> WorkerRun {
    let request = job.request();
    let mut run = WorkerRun::empty(
        request,
        Err(SupervisorError::Wait("not started".into())),
        std::process::id(),
    );
    let owned = job.to_job();
    let (reader, writer) = match std::io::pipe() {
        Ok(p) => p,
        Err(e) => {
            run.result = Err(SupervisorError::Spawn {
                program: "a pipe to a run in this process".into(),
                reason: e.to_string(),
            });
            return run;
        }
    };
    let mut end: Option<Result<Finish, SupervisorError>> = None;
    let mut protocol = None;
    let stepped = std::thread::scope(|s| {
        let stepper = s.spawn(move || {
            let mut out = std::io::BufWriter::with_capacity(64 * 1024, writer);
            let result = crate::handoff::here(|| {
                pyo3::Python::attach(|py| crate::cosim::run(py, &owned, &mut out))
            });
            if let Err(e) = result {
                let _ = crate::protocol::write_msg(&mut out, &crate::cosim::failure_msg(e));
            }
            let _ = out.flush();
        });
        let mut r = BufReader::with_capacity(1 << 20, reader);
        loop {
            match read_frame(&mut r) {
                Ok(Some(f)) => run.take(f, limits, &mut end),
                Ok(None) => break,
                Err(e) => {
                    protocol = Some(e);
                    // Read on to the end, or the loop would wait on a full pipe forever.
                    let _ = std::io::copy(&mut r, &mut std::io::sink());
                    break;
                }
            }
        }
        stepper.join()
    });
    run.result = match (end, protocol, stepped) {
        (Some(Ok(f)), _, _) => Ok(f),
        (Some(Err(e)), _, _) => Err(e),
        (None, Some(p), _) => Err(SupervisorError::Protocol(p)),
        (None, None, Err(_)) => Err(SupervisorError::Worker(
            "the run in this process panicked".into(),
        )),
        (None, None, Ok(())) => Err(SupervisorError::Worker(
            "the run in this process ended without its end".into(),
        )),
    };
    run
}

/// Long-lived workers shared by the threads of a sweep or a comparison: a run takes an idle
/// worker (or starts one), and a worker that is still usable afterwards goes back for the next
/// run. At most as many workers exist as runs in flight.
#[derive(Debug)]
pub struct WorkerPool {
    cmd: WorkerCommand,
    idle: Mutex<Vec<Worker>>,
    started: std::sync::atomic::AtomicUsize,
}

impl WorkerPool {
    /// An empty pool that starts workers with `cmd`.
    pub fn new(cmd: WorkerCommand) -> Self {
        Self {
            cmd,
            idle: Mutex::new(Vec::new()),
            started: std::sync::atomic::AtomicUsize::new(0),
        }
    }

    /// The command that starts this pool's workers.
    pub fn command(&self) -> &WorkerCommand {
        &self.cmd
    }

    /// Runs `request` on a pooled worker.
    pub fn run(&self, request: &Request, limits: &Supervision) -> WorkerRun {
        let idle = self.idle.lock().map(|mut v| v.pop()).ok().flatten();
        let mut worker = match idle {
            Some(w) => w,
            None => match Worker::spawn(&self.cmd) {
                Ok(w) => {
                    self.started.fetch_add(1, Ordering::SeqCst);
                    w
                }
                Err(e) => return WorkerRun::empty(request, Err(e), 0),
            },
        };
        let run = worker.run(request, limits);
        if worker.alive() {
            if let Ok(mut v) = self.idle.lock() {
                v.push(worker);
            }
        }
        run
    }

    /// Worker processes started so far (crashed ones are replaced, so this can exceed the
    /// number of threads).
    pub fn workers_started(&self) -> usize {
        self.started.load(Ordering::SeqCst)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interrupted_maps_to_exit_code_130() {
        let e = SupervisorError::Interrupted { records: 12 };
        assert_eq!(e.exit_code(), Some(130));
        assert_eq!(
            e.to_string(),
            "interrupted (Ctrl-C) after 12 recorded samples"
        );
        assert_eq!(SupervisorError::Worker("x".into()).exit_code(), None);
    }

    #[test]
    fn crash_message_names_signal_and_samples() {
        let e = SupervisorError::Crashed {
            pid: 42,
            signal: 11,
            name: signal_name(11),
            records: 3,
            stderr_tail: "Loading net-file".into(),
        };
        assert_eq!(
            e.to_string(),
            "the SUMO worker (pid 42) crashed with signal 11 (SIGSEGV) after 3 recorded samples; its last output:\nLoading net-file"
        );
    }
}
