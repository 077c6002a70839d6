//! `syncroad`: argument definitions plus glue. The work happens in `syncroad-control` (laws,
//! theory, native simulator, the run outcome and record) and `syncroad-sumo` (SUMO
//! co-simulation). The CLI is a library so that the binary (`src/main.rs`) and the Python
//! package (`crates/syncroad-py`) run the same commands through [`host`].
//!
//! * [`cli`] — clap definitions, the help text;
//! * [`config`] — options validated once, before any work starts;
//! * [`commands`] — one module per command;
//! * [`comparison`] — one scenario under several drivers, planned and run as one batch (the
//!   `compare` command and `regress` baselines of kind compare);
//! * [`plan`] — one run as a command plans it (who drives, recording, measurements,
//!   evaluation, time limit), built before any run starts;
//! * [`pipeline`] — one run, whatever runs it: backend → outcome → record → files;
//!   [`experiment`] — the same path for Rust programs with their own law ([`Run`]);
//! * [`output`], [`plots`], [`tables`], [`stability`] — files, figures and text tables;
//!   [`animate`] — animations of finished runs on their road's geometry;
//! * [`error`], [`exit_codes`] — the one error funnel; only [`host::execute`] picks the exit
//!   code; [`gate`] — `--fail-on`, what makes a comparison or a sweep exit 1;
//! * [`host`] — a command line in, an exit code out: the whole CLI as a function.

mod animate;
mod batch;
mod cli;
mod commands;
mod comparison;
mod config;
mod error;
mod exit_codes;
pub mod experiment;
mod gaps;
mod gate;
pub mod host;
mod lock;
mod output;
mod pipeline;
mod plan;
mod plots;
mod progress;
mod stability;
mod stdout;
mod sweep;
mod tables;

pub use experiment::Run;
pub use pipeline::Finished;
pub use syncroad_control::scenario::Backend;
