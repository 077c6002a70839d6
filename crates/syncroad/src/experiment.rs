//! One run of a scenario from Rust code, with the program's own law: the same path as
//! `syncroad run` (backend → outcome → record → files), built step by step.
//!
//! ```no_run
//! # fn main() -> anyhow::Result<()> {
//! use syncroad::{Backend, Run};
//! let sc = syncroad_control::Scenario::load("scenarios/sugiyama-ring.json".as_ref())?;
//! // "follow" is a law this program registered (syncroad_control::registry::register).
//! let run = Run::new(&sc)
//!     .law("follow", serde_json::json!({"gain": 0.2}))?
//!     .backend(Backend::Sumo)
//!     .run()?;
//! println!("{:?}", run.outcome.sync.verdict);
//! run.write("out/follow".as_ref(), None)?;
//! # Ok(()) }
//! ```
//!
//! A SUMO run steps the law in a worker process that is this program started again: the
//! program registers its laws, then serves as a worker when asked
//! (`syncroad_sumo::is_worker_invocation()` → `syncroad_sumo::worker_main()`), before anything
//! else in `main`. `examples/own_law.rs` is a whole program.

use std::path::PathBuf;

use anyhow::Context;
use syncroad_control::scenario::Backend;
use syncroad_control::user_law::UserLaw;
use syncroad_control::NamedLaw;
use syncroad_control::{EvalOptions, NativeOptions, Scenario};
use syncroad_sumo::{load_road, RunOptions, WorkerCommand};

use crate::pipeline::{self, Finished};

/// A run being set up: the scenario, the law that drives it, the backend.
#[derive(Debug, Clone)]
pub struct Run {
    scenario: Scenario,
    backend: Backend,
    work_dir: Option<PathBuf>,
    worker: Option<WorkerCommand>,
    record_every: usize,
}

impl Run {
    /// A run of `scenario` as it is (its law, its backend).
    pub fn new(scenario: &Scenario) -> Self {
        Self {
            scenario: scenario.clone(),
            backend: scenario.backend(),
            work_dir: None,
            worker: None,
            record_every: 1,
        }
    }

    /// Drives the vehicles the scenario's law would drive with the law of the registry named
    /// `name` (one this program registered, or a built-in one), built with `params` (a JSON
    /// object).
    pub fn law(mut self, name: &str, params: serde_json::Value) -> anyhow::Result<Self> {
        if !params.is_object() {
            anyhow::bail!("Run::law({name}): params = {params}: must be a JSON object");
        }
        let law = NamedLaw {
            name: name.to_string(),
            params,
        };
        law.check(&format!("Run::law({name})"))?;
        law.require_road(
            self.scenario.is_ring(),
            &format!("scenario {}", self.scenario.name()),
        )?;
        self.scenario = self.scenario.with_controller(UserLaw::Rust(law));
        Ok(self)
    }

    /// The backend (default: the scenario's).
    pub fn backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// Where SUMO's own files of the run go (default: a temporary folder).
    pub fn work_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.work_dir = Some(dir.into());
        self
    }

    /// The worker program of SUMO runs (default: this program, started again).
    pub fn worker(mut self, worker: WorkerCommand) -> Self {
        self.worker = Some(worker);
        self
    }

    /// Records every `k`-th step (default 1).
    pub fn record_every(mut self, k: usize) -> Self {
        self.record_every = k.max(1);
        self
    }

    /// The scenario as it runs (with the law in place).
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// Runs it and evaluates it: the output, the outcome and the `metrics.json` record, which
    /// [`Finished::write`] writes. Errors are the checks made before the run starts; a run
    /// that fails part-way is returned with its rows and a failed stop.
    pub fn run(self) -> anyhow::Result<Finished> {
        let sc = &self.scenario;
        let eval = EvalOptions::of(sc);
        let output = match self.backend {
            Backend::Native => {
                if let Some(why) = sc.native_refusal() {
                    anyhow::bail!(why);
                }
                let opts = NativeOptions {
                    record_every: self.record_every,
                    ..NativeOptions::default()
                };
                pipeline::native_with(sc, opts).context("nothing was run")?
            }
            Backend::Sumo => {
                let tmp;
                let work = match &self.work_dir {
                    Some(d) => d.clone(),
                    None => {
                        tmp = tempfile::tempdir().context("a work folder for SUMO")?;
                        tmp.path().to_path_buf()
                    }
                };
                let worker = match self.worker {
                    Some(w) => w,
                    None => WorkerCommand::current_exe().context("this program as SUMO worker")?,
                };
                let mut opts = RunOptions::new(work, worker);
                opts.record_every = self.record_every;
                let road = load_road(sc)?;
                pipeline::sumo(sc, &road, &opts)?.output
            }
        };
        Ok(Finished::new(sc, syncroad_control::PROTOCOL, output, eval))
    }
}
