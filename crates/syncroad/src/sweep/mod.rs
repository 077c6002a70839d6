//! Parameter sweeps: a spec names a base scenario, axes over its fields, runs and seeds;
//! every point goes through the one run pipeline ([`crate::pipeline`]), SUMO points on
//! long-lived workers; rows are kept per point so a sweep resumes and shards; the table is
//! written as Parquet and CSV and plotted.
//!
//! [`spec`] (the file), [`points`] (their count, seeds and shards), [`checks`] (every point
//! validated before anything runs), [`exec`]
//! (running, resuming, sharding), [`rows`] (a folder's rows, each checked to be the sweep's),
//! [`table`]
//! (typed columns, Parquet and CSV), [`stats`] (mean and interval over seeds), [`plots`]
//! and [`slurm`] (a job array that runs the shards).

pub mod axis;
pub mod checks;
pub mod exec;
pub mod plots;
pub mod points;
pub mod rows;
pub mod slurm;
pub mod spec;
pub mod stats;
pub mod table;

pub use exec::ExecOptions;
pub use points::Shard;
pub use spec::Sweep;
