//! # syncroad-sumo
//!
//! Runs syncroad's velocity-synchronization laws (eq. `chandler+`, eqs. `veh-proto1/2` of
//! Proskurnikov & Mazo) on SUMO traffic through libsumo, embedded with pyo3. This is the only
//! crate of the workspace that links Python.
//!
//! libsumo allows one simulation per process and crashes the process on malformed input, so
//! every run lives in its own **worker process**; the control loop runs inside the worker (law
//! and libsumo in one process, no per-step IPC) and streams trajectory rows to the parent.
//!
//! Layers, bottom up (modules are private; the types below are the crate's face):
//! * `venv`, `python` — the project's virtualenv, the embedded interpreter, Python errors with
//!   their tracebacks;
//! * `net`, `layout` — network files read once and checked before SUMO starts, vehicle
//!   departures, ring capacity, the routes file;
//! * `controlled` — the user's own vehicles the law drives (`sumo.controlled`), checked in
//!   their files before SUMO starts;
//! * `ssm` — SUMO's surrogate-safety device: its options and a summary of its log;
//! * `replay` — SUMO's floating-car data of a run, the files that replay it in sumo-gui, and
//!   where the run's road lies on the network;
//! * `summary` — SUMO's summary output: the metrics of every vehicle in the network;
//! * `protocol`, `cosim`, `worker` — the worker process: one step of the co-simulation apart
//!   from the loop that runs it;
//! * `handoff` — a run stepped by a caller in this very process (the Python package's
//!   `Simulation`), and this process's libsumo lent to one such run at a time;
//! * `supervisor`, `prepare`, `output` — the parent: [`Prepared::new`] checks everything it can before SUMO
//!   starts, [`Prepared::run`] supervises the worker, [`SumoRun::output`] is the
//!   [`RunOutput`](syncroad_control::RunOutput) every backend returns;
//! * `result_file` — the one writer of every result file: atomic replacement of regular
//!   files, written through to FIFOs and devices, never renamed over anything else;
//! * [`bench`](mod@bench) — SUMO alone vs SUMO + controller vs a TraCI-socket reference.
#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod bench;
mod contained;
mod controlled;
mod cosim;
mod direct;
mod frozen;
mod handoff;
mod inflows;
mod input_file;
mod layout;
mod net;
mod output;
mod outputs;
mod prepare;
mod prepare_error;
mod probe;
mod protocol;
mod python;
mod replay;
mod result_file;
mod serve;
mod signals;
mod ssm;
mod summary;
mod supervisor;
mod user_files;
mod user_law;
mod venv;
mod worker;

pub use contained::{ContainedController, ContainedHost};
pub use frozen::FROZEN_LIMIT;
pub use handoff::{claim_libsumo, here, release_libsumo, Handoff};
pub use layout::EMISSION_CLASS;
pub use net::{read_config, read_network_road, ConfigError, NetReader, Road};
pub use prepare::{
    check_run, check_sumo_numbers, layout_for, load_road, loop_position, net_path, run_scenario,
    MeasureOptions, PrepareError, Prepared, RunOptions, SumoRun, WORK_FILES,
};
pub use probe::{PhaseTimes, Probe, ProbeMode, ProbeTimes};
pub use protocol::{Event, Finish, Job, ReadMode, Request, StartInfo, Totals};
pub use python::{libsumo_is_loaded, use_packages, SumoPackages};
pub use replay::{
    ReplayError, RoadTrace, TraceLane, FCD_FILE, REPLAY_CONFIG, REPLAY_TYPES, ROAD_FILE,
};
pub use result_file::{write_result, write_result_via_path, ResultFileError};
pub use signals::{
    clear_interrupt, host_delivers_interrupts, interrupt, received as interrupt_signal,
    received_name as interrupt_signal_name, survive_file_size_limit,
};
pub use supervisor::{
    interrupt_flag, RowsHook, RowsProgress, StartHook, SupervisorError, WorkerCommand, WorkerPool,
};
pub use user_law::{PythonController, PythonHost};
pub use venv::{repo_dir, sumo_program, VenvError};
pub use worker::{is_worker_invocation, worker_main, worker_main_with};
