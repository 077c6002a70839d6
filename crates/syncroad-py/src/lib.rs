//! `syncroad._syncroad`: the pyo3 extension behind the `syncroad` Python package. It holds no
//! logic of its own: the console script runs the CLI's [`syncroad::host::main`], the API runs
//! the CLI's commands through [`syncroad::host::execute`] and reads the files they write, and
//! SUMO runs go to supervised worker processes (`python -m syncroad._worker`, which runs the
//! Rust worker loop with libsumo from the package's environment).
//!
//! Long commands run with the GIL released on a thread of their own, while the calling thread
//! polls Python's signal handlers: a `KeyboardInterrupt` (Ctrl-C in a notebook) stops the
//! command as Ctrl-C stops the CLI (rows kept, files written), then is raised.
#![warn(missing_docs)]

use std::path::PathBuf;
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// The module that runs a SUMO worker (`python -m syncroad._worker`).
const WORKER_MODULE: &str = "syncroad._worker";

/// How often the calling thread looks for a pending signal while a command runs.
const POLL: Duration = Duration::from_millis(50);

/// SUMO runs of this process start `sys.executable -m syncroad._worker`; job scripts
/// (`sweep --emit-slurm`) run the `syncroad` console script of this environment.
fn set_worker(py: Python<'_>) -> PyResult<()> {
    // A user's Python controller on the native simulator runs in this interpreter, with the
    // packages of its environment.
    syncroad_sumo::use_packages(syncroad_sumo::SumoPackages::Interpreter);
    let exe: PathBuf = py.import("sys")?.getattr("executable")?.extract()?;
    syncroad_sumo::WorkerCommand::set_for_process(syncroad_sumo::WorkerCommand::python_module(
        exe,
        WORKER_MODULE,
    ));
    let scripts: PathBuf = py
        .import("sysconfig")?
        .call_method1("get_path", ("scripts",))?
        .extract()?;
    syncroad::host::set_program(scripts.join("syncroad"));
    Ok(())
}

/// The `syncroad` console script: the CLI's main with the same commands and exit codes. The
/// CLI's own signal handlers are installed (the caller resets SIGINT to its default first).
#[pyfunction]
fn main(py: Python<'_>, argv: Vec<String>) -> PyResult<u8> {
    set_worker(py)?;
    Ok(py.detach(|| syncroad::host::main(argv)))
}

/// Runs the SUMO worker loop in this process (stdin: requests, stdout: frames) with libsumo
/// imported from this interpreter's environment; returns the worker's exit code.
#[pyfunction]
fn worker_main(py: Python<'_>) -> u8 {
    // The loop attaches to the interpreter for each run itself.
    py.detach(|| syncroad_sumo::worker_main_with(syncroad_sumo::SumoPackages::Interpreter))
}

/// Runs one CLI command line (`argv[0]` is the program name) for the API and returns
/// `(exit_code, error_or_None, captured_stdout)`. Ctrl-C stops the command as in the CLI and
/// raises `KeyboardInterrupt` once it has stopped. With `here`, its SUMO run steps on a thread
/// of this process with this process's libsumo, which the caller has claimed
/// ([`claim_libsumo`]), instead of in a worker process.
#[pyfunction]
#[pyo3(signature = (argv, capture=true, here=false))]
fn execute(
    py: Python<'_>,
    argv: Vec<String>,
    capture: bool,
    here: bool,
) -> PyResult<(u8, Option<String>, String)> {
    set_worker(py)?;
    syncroad_sumo::host_delivers_interrupts();
    syncroad_sumo::clear_interrupt();
    let (ended, pending) = py.detach(|| {
        std::thread::scope(|s| {
            let work = s.spawn(|| {
                if here {
                    syncroad_sumo::here(|| syncroad::host::execute(argv, capture))
                } else {
                    syncroad::host::execute(argv, capture)
                }
            });
            let mut pending: Option<PyErr> = None;
            while !work.is_finished() {
                std::thread::sleep(POLL);
                if pending.is_none() {
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        syncroad_sumo::interrupt(libc::SIGINT);
                        pending = Some(e);
                    }
                }
            }
            (work.join(), pending)
        })
    });
    syncroad_sumo::clear_interrupt();
    if let Some(e) = pending {
        return Err(e);
    }
    let ended = ended.map_err(|_| PyRuntimeError::new_err("the syncroad command panicked"))?;
    Ok((ended.code, ended.error, ended.stdout))
}

/// Takes this process's libsumo for one run stepped here (`execute(..., here=True)`); False
/// while another run of this process holds it, or when this process's own code has started a
/// libsumo simulation.
#[pyfunction]
fn claim_libsumo(py: Python<'_>) -> PyResult<bool> {
    if !syncroad_sumo::claim_libsumo() {
        return Ok(false);
    }
    // The caller's own libsumo simulation (libsumo runs one per process).
    match syncroad_sumo::libsumo_is_loaded(py) {
        Ok(false) => Ok(true),
        // A libsumo that cannot be imported here is the worker's to report.
        Ok(true) | Err(_) => {
            syncroad_sumo::release_libsumo();
            Ok(false)
        }
    }
}

/// Gives back what [`claim_libsumo`] took.
#[pyfunction]
fn release_libsumo() {
    syncroad_sumo::release_libsumo();
}

/// Loads and validates a scenario file; returns the CLI's error message, or `None` when valid.
#[pyfunction]
fn validate_scenario(path: PathBuf) -> Option<String> {
    syncroad::host::validate_scenario(&path).err()
}

/// The Python module `syncroad._syncroad`.
#[pymodule]
fn _syncroad(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(main, m)?)?;
    m.add_function(wrap_pyfunction!(worker_main, m)?)?;
    m.add_function(wrap_pyfunction!(execute, m)?)?;
    m.add_function(wrap_pyfunction!(validate_scenario, m)?)?;
    m.add_function(wrap_pyfunction!(claim_libsumo, m)?)?;
    m.add_function(wrap_pyfunction!(release_libsumo, m)?)?;
    m.add_class::<syncroad_sumo::Handoff>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
