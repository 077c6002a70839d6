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
//! Layers, bottom up:
//! * [`venv`], [`python`] — the project's virtualenv, the embedded interpreter, Python errors
//!   with their tracebacks;
//! * [`net`], [`layout`] — network files read and checked before SUMO starts, vehicle
//!   departures, ring capacity, the routes file;
//! * [`car_following`], [`drivers`] — SUMO's car-following models with all their parameters,
//!   validated before SUMO starts, named presets, and the short baseline names;
//! * [`controller`] — the seam to the laws of `syncroad-control` and SUMO's actuation timing;
//! * [`protocol`], [`cosim`], [`worker`] — the worker process and its loop;
//! * [`supervisor`], [`run`] — the parent: spawning, supervising, results;
//! * [`bench`](mod@bench) — SUMO alone vs SUMO + controller vs a TraCI-socket reference.
#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod bench;
pub mod car_following;
pub mod controller;
pub mod cosim;
pub mod direct;
pub mod drivers;
pub mod layout;
pub mod net;
pub mod protocol;
pub mod python;
pub mod run;
pub mod supervisor;
pub mod venv;
pub mod worker;

pub use car_following::{CarFollowing, CarFollowingError, CfModel};
pub use controller::{controller_for, SpeedController};
pub use drivers::SumoDriver;
pub use run::{run_scenario, RunError, RunOptions, SumoRun};
pub use supervisor::{interrupt_flag, run_worker, Supervision, SupervisorError, WorkerCommand};
pub use venv::repo_dir;
pub use worker::{is_worker_invocation, worker_main, WORKER_ARG};
