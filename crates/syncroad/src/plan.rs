//! One run as a command plans it, before any run starts: who drives ([`RunSpec`]), how often
//! it is recorded, what SUMO measures, how it is evaluated and how long it may take. `run`,
//! `compare` and `sweep` each build a [`RunPlan`] per run (a sweep's checks and its runs build
//! the same plan for a point), and a run's SUMO options come from [`RunPlan::sumo_options`]
//! only.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use syncroad_control::EvalOptions;
use syncroad_sumo::{MeasureOptions, ReadMode, RunOptions, WorkerCommand};

use crate::runs::RunSpec;

/// SUMO's measurements of a run beyond its trajectory (the warm-up is the evaluation's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Measurements {
    /// Read fuel and CO2 every this many steps (≥ 1).
    pub emission_every: usize,
    /// Write SUMO's trip info with its emission totals.
    pub tripinfo: bool,
    /// Log SUMO's surrogate safety measures.
    pub ssm: bool,
}

/// One planned run.
#[derive(Debug, Clone)]
pub struct RunPlan {
    /// Who drives: the run's name, SUMO drivers, a damper.
    pub spec: RunSpec,
    /// Record every this many steps.
    pub record_every: usize,
    /// Wall-clock limit; `None` takes the scenario's `sumo.timeout_s`.
    pub timeout: Option<Duration>,
    /// How the record judges the run; its warm-up is also where SUMO starts measuring.
    pub eval: EvalOptions,
    /// SUMO-side measurements; `None`: the trajectory only.
    pub measure: Option<Measurements>,
    /// SUMO's ballistic position update (the native simulator's); `false`: Euler.
    pub ballistic: bool,
    /// How the SUMO loop reads the vehicles.
    pub read: ReadMode,
}

impl RunPlan {
    /// `spec` recorded every `record_every` steps and judged by `eval`, with no time limit
    /// beyond the scenario's, no measurements, the ballistic update and direct reads.
    pub fn new(spec: RunSpec, record_every: usize, eval: EvalOptions) -> Self {
        Self {
            spec,
            record_every,
            timeout: None,
            eval,
            measure: None,
            ballistic: true,
            read: ReadMode::Direct,
        }
    }

    /// The run's name.
    pub fn name(&self) -> &str {
        &self.spec.name
    }

    /// The options of this run in SUMO: its work folder, the worker to start and the interrupt
    /// flag it watches.
    pub fn sumo_options(
        &self,
        work_dir: PathBuf,
        worker: WorkerCommand,
        interrupt: Option<Arc<AtomicBool>>,
    ) -> RunOptions {
        let mut o = RunOptions::new(work_dir, worker);
        o.record_every = self.record_every;
        o.ballistic = self.ballistic;
        o.timeout = self.timeout;
        o.interrupt = interrupt;
        o.read = self.read;
        o.drivers = self.spec.drivers.clone();
        o.damper = self.spec.damper;
        o.measure = self.measure.map(|m| MeasureOptions {
            warmup_s: self.eval.warmup_s,
            emission_every: m.emission_every,
            tripinfo: m.tripinfo,
            ssm: m.ssm,
        });
        o
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sumo_options_carry_every_choice_of_the_plan() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenarios/ring-theorem1.json"
        );
        let sc = syncroad_control::Scenario::load(std::path::Path::new(path)).unwrap();
        let spec = RunSpec::parse("--baselines", "idm", sc.vehicles()).unwrap();
        let mut eval = EvalOptions::of(&sc);
        eval.warmup_s = 40.0;
        let mut plan = RunPlan::new(spec.clone(), 5, eval);
        plan.timeout = Some(Duration::from_secs(9));
        plan.ballistic = false;
        plan.measure = Some(Measurements {
            emission_every: 3,
            tripinfo: true,
            ssm: false,
        });
        let o = plan.sumo_options("w".into(), WorkerCommand::binary("syncroad"), None);
        assert_eq!((o.record_every, o.ballistic), (5, false));
        assert_eq!(o.timeout, Some(Duration::from_secs(9)));
        assert_eq!(o.drivers, spec.drivers);
        let m = o.measure.unwrap();
        // SUMO measures from the warm-up the evaluation skips.
        assert_eq!((m.warmup_s, m.emission_every, m.tripinfo), (40.0, 3, true));
        assert_eq!(plan.name(), "idm");
        assert!(RunPlan::new(spec, 1, eval)
            .sumo_options("w".into(), WorkerCommand::binary("syncroad"), None)
            .measure
            .is_none());
    }
}
