//! One run as a command plans it, before any run starts: who drives ([`Drive`]), how often
//! it is recorded, what SUMO measures, how it is evaluated and how long it may take. `run`,
//! `compare` and `sweep` each build a [`RunPlan`] per run (a sweep's checks and its runs build
//! the same plan for a point), and a run's SUMO options come from [`RunPlan::sumo_options`]
//! only.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use syncroad_control::sumo_facts::Emissions;
use syncroad_control::EvalOptions;
use syncroad_sumo::{MeasureOptions, ReadMode, RunOptions, WorkerCommand};

use syncroad_control::drive::Drive;

/// The longest run folder name [`folder_name`] gives (bytes).
pub const FOLDER_MAX: usize = 96;

/// A run's folder name: its name with every character but letters, digits and `._=+-`
/// replaced by `_` (`human:tau=1.2` → `human_tau=1.2`), because SUMO reads `a:b` in an
/// output path as host:port and a shell or a list option splits on others. A name longer
/// than [`FOLDER_MAX`] keeps its first characters and ends in 16 hex digits of its SHA-256,
/// so the folder fits a file name (255 bytes on common file systems) and stays distinct.
pub fn folder_name(name: &str) -> String {
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._=+-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if safe.len() <= FOLDER_MAX {
        return safe;
    }
    use sha2::{Digest, Sha256};
    let digest = Sha256::digest(name.as_bytes());
    let hex: String = digest[..8].iter().map(|b| format!("{b:02x}")).collect();
    // `safe` is ASCII: any byte index is a character boundary.
    format!("{}-{hex}", &safe[..FOLDER_MAX - 17])
}

/// SUMO's measurements of a run beyond its trajectory (the warm-up is the evaluation's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Measurements {
    /// Read fuel and CO2 every this many steps (≥ 1).
    pub emission_every: usize,
    /// Write SUMO's trip info with its emission totals.
    pub tripinfo: bool,
    /// Log SUMO's surrogate safety measures.
    pub ssm: bool,
    /// The emission sums to read ([`Emissions::ALL`]: the whole record's).
    pub emissions: Emissions,
}

/// One planned run.
#[derive(Debug, Clone)]
pub struct RunPlan {
    /// Who drives: the run's name, SUMO drivers, a damper.
    pub drive: Drive,
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
    /// Also write SUMO's floating-car data for `syncroad replay` (`--fcd`).
    pub fcd: bool,
    /// The floating-car data every this many steps (`--fcd-every`; 1: every step).
    pub fcd_every: usize,
}

impl RunPlan {
    /// `spec` recorded every `record_every` steps and judged by `eval`, with no time limit
    /// beyond the scenario's, no measurements, the ballistic update and direct reads.
    pub fn new(drive: Drive, record_every: usize, eval: EvalOptions) -> Self {
        Self {
            drive,
            record_every,
            timeout: None,
            eval,
            measure: None,
            ballistic: true,
            read: ReadMode::Direct,
            fcd: false,
            fcd_every: 1,
        }
    }

    /// The run's name.
    pub fn name(&self) -> &str {
        &self.drive.name
    }

    /// The run's folder under a command's output folder ([`folder_name`] of its name).
    pub fn folder(&self) -> String {
        folder_name(&self.drive.name)
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
        o.drivers = self.drive.drivers.clone();
        o.damper = self.drive.damper.clone();
        o.fcd = self.fcd;
        o.fcd_every = self.fcd_every;
        o.warmup_s = self.eval.warmup_s;
        o.measure = self.measure.map(|m| MeasureOptions {
            emission_every: m.emission_every,
            tripinfo: m.tripinfo,
            ssm: m.ssm,
            emissions: m.emissions,
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
        let spec = Drive::parse("--baselines", "idm", sc.vehicles()).unwrap();
        let mut eval = EvalOptions::of(&sc);
        eval.warmup_s = 40.0;
        let mut plan = RunPlan::new(spec.clone(), 5, eval);
        plan.timeout = Some(Duration::from_secs(9));
        plan.ballistic = false;
        plan.fcd = true;
        plan.fcd_every = 10;
        plan.measure = Some(Measurements {
            emission_every: 3,
            tripinfo: true,
            ssm: false,
            emissions: Emissions::ALL,
        });
        let o = plan.sumo_options("w".into(), WorkerCommand::binary("syncroad"), None);
        assert_eq!(
            (o.record_every, o.ballistic, o.fcd, o.fcd_every),
            (5, false, true, 10)
        );
        // SUMO measures, and every vehicle's metrics (SUMO's summary) skip, the warm-up the
        // evaluation skips.
        assert_eq!(o.warmup_s, 40.0);
        assert_eq!(o.timeout, Some(Duration::from_secs(9)));
        assert_eq!(o.drivers, spec.drivers);
        let m = o.measure.unwrap();
        assert_eq!((m.emission_every, m.tripinfo), (3, true));
        assert_eq!(plan.name(), "idm");
        assert!(RunPlan::new(spec, 1, eval)
            .sumo_options("w".into(), WorkerCommand::binary("syncroad"), None)
            .measure
            .is_none());
    }

    #[test]
    fn folders_are_safe_bounded_and_distinct() {
        assert_eq!(folder_name("human:tau=1.2"), "human_tau=1.2");
        // A 300-character driver value once gave a folder name past the 255-byte limit.
        let long = format!("human:tau=1.{}", "0".repeat(300));
        let other = format!("human:tau=1.{}1", "0".repeat(299));
        let (a, b) = (folder_name(&long), folder_name(&other));
        assert_eq!(a.len(), FOLDER_MAX);
        assert!(a.starts_with("human_tau=1.000"), "{a}");
        assert_ne!(a, b);
        assert!(a
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "._=+-".contains(c)));
    }
}
