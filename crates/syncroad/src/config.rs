//! Options validated once, before any work starts: every command turns its clap arguments into
//! one of these, so a bad value is refused with the flag's name before a run begins.

use std::path::{Path, PathBuf};
use std::time::Duration;

use syncroad_control::metrics::VerdictThresholds;
use syncroad_control::scenario::SafetyMode;
use syncroad_control::{EvalOptions, Scenario, Trajectory};

use crate::cli::OutputArgs;
use crate::error::InputError;

/// Loads and validates a scenario; a failure is an [`InputError`] that leads with the
/// library's message (it names the field, the value and what is valid).
/// A loop or route through a network is checked and measured on `sumo.net`; the cycle found
/// for `road.through` is printed to stderr.
pub fn load_scenario(path: &Path) -> anyhow::Result<Scenario> {
    load_scenario_with(path, None)
}

/// [`load_scenario`] with the safety layer `--safety` chose in place of the file's `safety`
/// (`None`: the file's): validated as the file's own value, and part of the scenario's hash.
pub fn load_scenario_with(path: &Path, safety: Option<SafetyMode>) -> anyhow::Result<Scenario> {
    let edit = |f: &mut syncroad_control::scenario::ScenarioFile| {
        if safety.is_some() {
            f.safety = safety;
        }
    };
    let sc = Scenario::load_edited(path, Some(&syncroad_sumo::NetReader), edit).map_err(|e| {
        anyhow::Error::from(InputError::new(format!(
            "{e}\n  (scenario {}; fix the field named above — `syncroad --help` and the guide's docs/src/scenarios.md describe the format)",
            path.display()
        )))
    })?;
    note_measured_road(&sc);
    note_config(&sc);
    note_older_shapes(&sc);
    Ok(sc)
}

/// One line naming the one shape a law takes, when the scenario names one in an older shape
/// (which keeps working).
pub fn note_older_shapes(sc: &Scenario) {
    let Some(m) = sc.mixed() else { return };
    let syncroad_control::scenario::LawChoice::Name(name) = &m.controller else {
        return;
    };
    let shape = match m.damper() {
        Ok(Some(law)) if law.params.as_object().is_some_and(|o| !o.is_empty()) => {
            format!("{{\"law\": \"{}\", \"params\": {}}}", law.name, law.params)
        }
        Ok(Some(law)) => format!("{{\"law\": \"{}\"}}", law.name),
        // The scenario's own law, or a name validation refuses anyway.
        _ => return,
    };
    crate::stdout::errln!(
        "note: mixed.controller = \"{name}\" is the older shape of a law; the one shape is {shape}"
    );
}

/// Tells which options of `sumo.config` syncroad did not give SUMO.
pub fn note_config(sc: &Scenario) {
    let s = sc.sumo();
    if let (Some(c), false) = (s.config(), s.config_ignored().is_empty()) {
        crate::stdout::errln!(
            "note: sumo.config {}: syncroad takes its net-file, route-files and additional-files; not given to SUMO (the scenario sets time, step and seed, and outputs go to the run folder): {}",
            c.display(),
            s.config_ignored().join(", ")
        );
    }
}

/// Tells, when the scenario brings other traffic (`sumo.routes`, `sumo.additional`), that the
/// conditions and the exact analysis printed are for the scenario's fixed graph only.
pub fn note_fixed_graph(sc: &Scenario) {
    let Some((field, _)) = sc.sumo().other_traffic_source() else {
        return;
    };
    crate::stdout::errln!(
        "note: {field} adds other traffic; in SUMO the law takes its graph from the road each step (who is ahead of and behind each vehicle on its lane), so where that traffic changes lanes into or out of the controlled lane or merges into it the graph changes (a run counts it as safety.topology_changes and leaves `certified` empty), and the results above hold for the scenario's fixed graph only"
    );
}

/// Says that the scenario's runs are driven by the user's own controller, which the analysis
/// of its model does not cover; `true` when it did.
pub fn note_own_controller(sc: &Scenario) -> bool {
    let Some(c) = sc.controller() else {
        return false;
    };
    let (field, value) = c.named_by();
    crate::stdout::errln!(
        "note: {field} = {value}: the scenario's runs are driven by {}; the analysis above is of its model's law (model), not of that controller",
        c.label()
    );
    true
}

/// Tells which cycle a `road.through` loop takes and how long it measured.
pub fn note_measured_road(sc: &Scenario) {
    if let (
        Some(m),
        syncroad_control::scenario::RoadSpec::Loop {
            through: Some(t), ..
        },
    ) = (sc.measured_road(), sc.road())
    {
        crate::stdout::errln!(
            "road: the shortest cycle through `{t}` on lane {}: {} ({} edges, {:.3} m)",
            m.lanes.first().copied().unwrap_or(0),
            m.edges.join(" "),
            m.edges.len(),
            m.length_m
        );
    }
}

/// Default sampling stride: about 2000 samples over the horizon, fewer for large fleets so a
/// trajectory stays within about 4 million vehicle-samples (≈ 100 MB).
pub fn default_record_every(steps: usize, n: usize) -> usize {
    let samples = (4_000_000 / n.max(1)).clamp(2, 2000);
    (steps / samples).max(1)
}

/// `--jobs`: at least 1; default all cores.
pub fn jobs(flag: Option<usize>) -> anyhow::Result<usize> {
    match flag {
        Some(0) => Err(InputError::new("--jobs = 0: must be ≥ 1").into()),
        Some(j) => Ok(j),
        None => Ok(std::thread::available_parallelism().map_or(1, |n| n.get())),
    }
}

pub use syncroad_control::scenario::MAX_TIMEOUT_S;

/// `--timeout-s`: a number of seconds in [0, [`MAX_TIMEOUT_S`]].
pub fn timeout(flag: Option<f64>) -> anyhow::Result<Option<Duration>> {
    flag.map(|t| timeout_as("--timeout-s", t)).transpose()
}

/// A wall-clock limit given as `field`: a number of seconds in (0, [`MAX_TIMEOUT_S`]] (a
/// limit of 0 would stop every run before its first step: bad input, not a failed run).
pub fn timeout_as(field: &str, t: f64) -> anyhow::Result<Duration> {
    if !(t > 0.0 && t <= MAX_TIMEOUT_S) {
        return Err(InputError::new(format!(
            "{field} = {t}: must be a number of seconds > 0 and at most {MAX_TIMEOUT_S:e}"
        ))
        .into());
    }
    Ok(Duration::from_secs_f64(t))
}

/// `--warmup-s`: ≥ 0 and shorter than the horizon; default a quarter of it.
pub fn warmup_s(flag: Option<f64>, sc: &Scenario) -> anyhow::Result<f64> {
    warmup_s_as("--warmup-s", flag, sc)
}

/// [`warmup_s`] given as `field` (a flag, or a sweep spec's `warmup_s`).
pub fn warmup_s_as(field: &str, flag: Option<f64>, sc: &Scenario) -> anyhow::Result<f64> {
    let w = flag.unwrap_or(0.25 * sc.horizon_s());
    if !(w.is_finite() && w >= 0.0 && w < sc.horizon_s()) {
        return Err(InputError::new(format!(
            "{field} = {w}: must be ≥ 0 and shorter than the horizon ({} s)",
            sc.horizon_s()
        ))
        .into());
    }
    Ok(w)
}

/// The most vehicle-samples a recorded trajectory may hold (speed, position, gap and command
/// each: about 1.6 GB in memory, several GB of CSV).
pub const MAX_RECORDED_VALUES: usize = 50_000_000;

/// `--fcd-every`: at least 1; every step when not given.
pub fn fcd_every(flag: Option<usize>) -> anyhow::Result<usize> {
    match flag {
        Some(0) => Err(InputError::new(
            "--fcd-every = 0: must be ≥ 1 (SUMO writes its floating-car data every k-th step; 1 is every step)",
        )
        .into()),
        k => Ok(k.unwrap_or(1)),
    }
}

/// `--record-every`: at least 1, and few enough samples to stay within
/// [`MAX_RECORDED_VALUES`]; default about 2000 samples. (The metrics use every step whatever
/// the stride.)
pub fn record_every(flag: Option<usize>, sc: &Scenario) -> anyhow::Result<usize> {
    record_every_as("--record-every", flag, sc)
}

/// [`record_every`] given as `field` (a flag, or a sweep spec's `record_every`).
pub fn record_every_as(field: &str, flag: Option<usize>, sc: &Scenario) -> anyhow::Result<usize> {
    let k = match flag {
        Some(0) => return Err(InputError::new(format!("{field} = 0: must be ≥ 1")).into()),
        Some(k) => k,
        None => default_record_every(sc.steps(), sc.vehicles()),
    };
    let values = Trajectory::samples_recorded(sc.steps(), k).saturating_mul(sc.vehicles());
    // Even the first and the last sample alone: no stride helps.
    if sc.vehicles().saturating_mul(3) > MAX_RECORDED_VALUES {
        return Err(InputError::new(format!(
            "vehicles = {}: a trajectory of so many vehicles cannot be kept in memory (at most {} vehicles, {MAX_RECORDED_VALUES} vehicle-samples)",
            sc.vehicles(),
            MAX_RECORDED_VALUES / 3
        ))
        .into());
    }
    if values > MAX_RECORDED_VALUES {
        let min_k = sc
            .steps()
            .div_ceil(MAX_RECORDED_VALUES / sc.vehicles().max(1) - 2);
        return Err(InputError::new(format!(
            "{field} = {k}: {} steps (horizon_s = {} s / step_s = {} s) of {} vehicles would record {values} vehicle-samples, more than the {MAX_RECORDED_VALUES} kept in memory; give {field} ≥ {min_k}",
            sc.steps(),
            sc.horizon_s(),
            sc.step_s(),
            sc.vehicles()
        ))
        .into());
    }
    Ok(k)
}

/// The validated output options of a command that runs one scenario.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Output folder.
    pub out: PathBuf,
    /// Verdict thresholds and warm-up.
    pub eval: EvalOptions,
    /// Recording stride.
    pub record_every: usize,
    /// Draw plots.
    pub plots: bool,
}

impl RunConfig {
    /// Validates `--tolerance-mps`, `--window-s`, `--record-every` and `--warmup-s` against the
    /// scenario (the same rules `compare` applies).
    pub fn new(sc: &Scenario, a: &OutputArgs) -> anyhow::Result<Self> {
        let mut eval = EvalOptions::of(sc);
        let t = VerdictThresholds {
            tolerance_mps: a.tolerance_mps.unwrap_or(eval.thresholds.tolerance_mps),
            window_s: a.window_s.unwrap_or(eval.thresholds.window_s),
        };
        if !(t.tolerance_mps.is_finite() && t.tolerance_mps > 0.0) {
            return Err(InputError::new(format!(
                "--tolerance-mps = {}: must be a finite number > 0",
                t.tolerance_mps
            ))
            .into());
        }
        if !(t.window_s.is_finite() && t.window_s > 0.0 && t.window_s <= sc.horizon_s()) {
            return Err(InputError::new(format!(
                "--window-s = {}: must be > 0 and ≤ the horizon ({} s)",
                t.window_s,
                sc.horizon_s()
            ))
            .into());
        }
        eval.thresholds = t;
        eval.warmup_s = warmup_s(a.warmup_s, sc)?;
        Ok(Self {
            out: a.out.clone(),
            eval,
            record_every: record_every(a.record_every, sc)?,
            plots: !a.no_plots,
        })
    }
}

/// The program that runs this CLI when it is not the running executable (see [`program`]).
static PROGRAM: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();

/// Sets the program that later runs of this CLI start (the job scripts of
/// `sweep --emit-slurm`): a host whose executable is not `syncroad` (the Python package: its
/// console script). Once; a second call changes nothing.
pub fn set_program(path: std::path::PathBuf) {
    let _ = PROGRAM.set(path);
}

/// The program that runs this CLI: the one [`set_program`] gave, else the running executable.
pub fn program() -> std::io::Result<std::path::PathBuf> {
    match PROGRAM.get() {
        Some(p) => Ok(p.clone()),
        None => std::env::current_exe(),
    }
}
