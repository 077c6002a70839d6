//! The worker side: one process, SUMO runs one after another (one request line each).
//!
//! [`worker_main`] is the whole program of a worker. Any binary can become a worker by calling
//! it when started with [`WORKER_ARG`] as its first argument; the `syncroad` CLI re-executes
//! itself that way, and this crate ships `syncroad-sumo-worker` for tests and benchmarks.
//!
//! SUMO and Python print to the C-level stdout, which would corrupt the frames, so the worker
//! first moves the protocol to a duplicate of stdout and points descriptor 1 at stderr.

use std::fs::File;
use std::io::{BufRead, BufWriter, Write};
use std::os::fd::{FromRawFd, OwnedFd};
use std::process::ExitCode;

use crate::protocol::{write_msg, Job, WorkerMsg};
use crate::python::SumoPackages;

/// First argument that turns a binary into a worker.
pub const WORKER_ARG: &str = "__sumo-worker";

/// Exit code of a worker that reported a clean failure ([`WorkerMsg::Failed`]).
pub const EXIT_FAILED: u8 = 3;

/// True when this process was started as a worker (`<exe> __sumo-worker`): binaries that
/// embed the worker call [`worker_main`] first thing when this holds.
pub fn is_worker_invocation() -> bool {
    std::env::args_os().nth(1).is_some_and(|a| a == WORKER_ARG)
}

/// The protocol writer's buffer \[bytes\]: below a chunk of rows (`prepare::chunk_records`), so
/// that a chunk is not copied into it first.
const OUT_BUFFER_BYTES: usize = 64 * 1024;

/// Room asked for in the protocol pipe \[bytes\] (the default fs.pipe-max-size).
#[cfg(target_os = "linux")]
const PROTOCOL_PIPE_BYTES: libc::c_int = 1 << 20;

/// Redirects descriptor 1 to stderr and returns the original stdout for the protocol.
fn take_protocol_channel() -> std::io::Result<File> {
    // SAFETY: dup/dup2 on the process's own standard descriptors; the duplicate is owned by
    // the returned File and nothing else holds it.
    unsafe {
        let fd = libc::dup(1);
        if fd < 0 {
            return Err(std::io::Error::last_os_error());
        }
        if libc::dup2(2, 1) < 0 {
            return Err(std::io::Error::last_os_error());
        }
        libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
        // A pipe of the default 64 KiB blocks the loop on every 256 KiB chunk of rows until the
        // parent has read it; with room for a few chunks the loop runs on while the parent
        // decodes. Linux only, and capped by fs.pipe-max-size: a refusal keeps the default.
        #[cfg(target_os = "linux")]
        libc::fcntl(fd, libc::F_SETPIPE_SZ, PROTOCOL_PIPE_BYTES);
        Ok(File::from(OwnedFd::from_raw_fd(fd)))
    }
}

/// The worker program of a Rust binary: libsumo from the project's virtualenv
/// ([`worker_main_with`]`(`[`SumoPackages::ProjectVenv`]`)`).
pub fn worker_main() -> ExitCode {
    ExitCode::from(worker_main_with(SumoPackages::ProjectVenv))
}

/// The worker program: reads one [`Job`] line from stdin, runs it, streams the results;
/// returns the exit code (0, or [`EXIT_FAILED`] after a reported failure).
/// `packages` says where libsumo is imported from. Initializes the embedded interpreter when
/// the process has none yet (a Rust binary); inside a Python process it uses the running one.
pub fn worker_main_with(packages: SumoPackages) -> u8 {
    crate::python::use_packages(packages);
    pyo3::Python::initialize();
    let proto = match take_protocol_channel() {
        Ok(f) => f,
        Err(e) => {
            eprintln!("syncroad-sumo worker: cannot set up the protocol channel: {e}");
            return EXIT_FAILED;
        }
    };
    // Small messages are gathered into one write; a frame at least this long (a full chunk of
    // rows, about 256 KiB) skips the buffer and goes to the pipe from its own bytes.
    // Descendants orphaned by their parent (a helper's helper) are handed to this worker
    // rather than to init, so that `end_descendants` finds them all.
    #[cfg(target_os = "linux")]
    // SAFETY: prctl with an integer argument on this process.
    unsafe {
        libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0);
    }
    let mut out = BufWriter::with_capacity(OUT_BUFFER_BYTES, proto);
    let mut input = std::io::stdin().lock();
    // A controller for the native simulator of the parent, in a process of its own.
    if std::env::var_os(crate::serve::SERVE_ENV).is_some() {
        return crate::serve::serve(&mut input, &mut out);
    }
    let mut line = String::new();
    let mut code = 0;
    // One request per line until the parent closes stdin; SUMO starts and closes per run.
    loop {
        line.clear();
        match input.read_line(&mut line) {
            Ok(0) => return code,
            Ok(_) => {}
            Err(e) => {
                let _ = write_msg(
                    &mut out,
                    &WorkerMsg::Failed {
                        message: format!("cannot read the request from stdin: {e}"),
                    },
                );
                let _ = out.flush();
                return EXIT_FAILED;
            }
        }
        let result = match serde_json::from_str::<Job>(&line) {
            Ok(job) => pyo3::Python::attach(|py| crate::cosim::run(py, &job, &mut out))
                .map_err(crate::cosim::failure_msg),
            Err(e) => Err(WorkerMsg::Failed {
                message: format!("malformed request: {e}"),
            }),
        };
        // Whatever the run's controller started (a helper process, a fork) ends with the run:
        // the next run on this worker starts clean, and nothing the user's code left holds
        // the worker's pipes.
        end_descendants();
        code = match result {
            Ok(()) => 0,
            Err(message) => {
                if write_msg(&mut out, &message).is_err() {
                    return EXIT_FAILED;
                }
                EXIT_FAILED
            }
        };
        if out.flush().is_err() {
            // The parent is gone.
            return EXIT_FAILED;
        }
    }
}

/// The children of this process, from `/proc/self/task/*/children` (every thread's).
#[cfg(target_os = "linux")]
fn children() -> Vec<libc::pid_t> {
    let mut pids = Vec::new();
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return pids;
    };
    for task in tasks.flatten() {
        if let Ok(text) = std::fs::read_to_string(task.path().join("children")) {
            pids.extend(
                text.split_whitespace()
                    .filter_map(|p| p.parse::<libc::pid_t>().ok()),
            );
        }
    }
    pids
}

/// Kills and reaps every process this worker started during a run, and those they started
/// (handed to this worker when orphaned: it is their subreaper). libsumo starts none, so
/// anything found is the user's controller's.
fn end_descendants() {
    #[cfg(target_os = "linux")]
    for _ in 0..64 {
        let pids = children();
        if pids.is_empty() {
            return;
        }
        for pid in pids {
            // SAFETY: signals and reaps a child of this process; it is ours until reaped, so
            // the pid cannot name another process.
            unsafe {
                libc::kill(pid, libc::SIGKILL);
                libc::waitpid(pid, std::ptr::null_mut(), 0);
            }
        }
    }
}
