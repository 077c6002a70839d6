//! Scenario files: the JSON a user writes ([`ScenarioFile`]) and the validated, resolved form
//! every backend runs ([`Scenario`]).
//!
//! Uniform values may be given once (`"delay_s": 0.5`) and per-vehicle values as lists
//! (`"delay_s": [0.4, 0.6, ...]`). Unknown fields are rejected. [`ScenarioFile::validate`]
//! checks everything that can be checked before a simulation starts, and every error names the
//! field path, the value and what would be valid.
//!
//! The folder holds one concept per file: [`file`] (the schema a user writes), [`per_vehicle`]
//! (values given once or per vehicle), [`leader`] (leader speed profiles), [`mixed`] (mixed
//! traffic: which vehicles are automated), `validate` (every check, with field paths), `sumo`
//! (the `sumo` section as typed [`SumoSettings`]), `graph_spec` (building the interaction
//! graph) and this file, the sealed [`Scenario`] every backend runs: private fields read
//! through accessors, made only by validation, so no code reads the raw file after it.

use std::path::{Path, PathBuf};

use crate::graph::GraphError;
use crate::metrics::VerdictThresholds;

pub mod file;
mod graph_spec;
pub mod leader;
pub mod mixed;
mod network_road;
pub mod per_vehicle;
mod scale;
mod select;
mod sumo;
mod validate;

pub use crate::model::{
    CaccModel, DelayedDriverModel, GraphShape, LeaderProfile, LinearModel, Model,
};
pub use file::*;
pub use mixed::{LawChoice, MixedSpec};
pub use network_road::{ConfigInputs, MeasuredRoad, RoadReader};
pub use per_vehicle::PerVehicle;
pub use scale::Scaled;
pub use select::{SelectorMatch, VehicleSelector};
pub use sumo::{SumoSettings, SumoVehicleType, VehicleClass, MAX_TIMEOUT_S, VEHICLE_CLASSES};

/// The most steps a run may take (`horizon_s / step_s`): 10⁷ steps of N vehicles already take
/// minutes natively and hours in SUMO, and each step keeps one value of the spread.
pub const MAX_STEPS: usize = 10_000_000;

/// The most values the delayed-driver law may buffer (`(max_i α_i/Δt + 2) · N`, 8 bytes each:
/// 128 MiB).
pub const MAX_DELAY_BUFFER: usize = 1 << 24;

/// The largest speed a scenario may name [m/s] (initial speeds, leader speeds): 3600 km/h,
/// far above any road vehicle, and low enough that positions over the longest run keep
/// millimetre resolution in f64.
pub const MAX_SPEED_MPS: f64 = 1000.0;

/// Errors raised while reading or validating a scenario.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario file {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The JSON is malformed or has unknown/missing fields.
    #[error("scenario {path}: {source}")]
    Json {
        /// The path (or `<string>`).
        path: String,
        /// serde_json's message, with line and column.
        source: serde_json::Error,
    },
    /// A field holds a value outside its valid range.
    #[error("{field} = {value}: {expected}")]
    Invalid {
        /// Field path, e.g. `model.delay_s[3]`.
        field: String,
        /// The offending value as written.
        value: String,
        /// What would be valid.
        expected: String,
    },
    /// The run would take more than [`MAX_STEPS`] steps.
    #[error("horizon_s = {h} s with step_s = {dt} s is {n} steps; at most {max} steps are allowed, so give horizon_s ≤ {hmax} s at this step (or a larger step_s)", max = MAX_STEPS, h = readable(*.horizon_s), dt = readable(*.step_s), n = readable(*.steps), hmax = readable(*.max_horizon_s))]
    TooManySteps {
        /// The horizon \[s\].
        horizon_s: f64,
        /// The step \[s\].
        step_s: f64,
        /// `horizon_s / step_s`.
        steps: f64,
        /// The longest horizon allowed at this step \[s\].
        max_horizon_s: f64,
    },
    /// The delay buffers would pass [`MAX_DELAY_BUFFER`] values.
    #[error("model.delay_s[{vehicle}] = {delay_s} s with step_s = {step_s} s needs a delay buffer of {values:.3e} values; at most {max} are allowed, so give step_s ≥ {min_step_s:.3e} s (or shorter delays)", max = MAX_DELAY_BUFFER)]
    DelayBufferTooLarge {
        /// The vehicle with the longest delay.
        vehicle: usize,
        /// Its delay \[s\].
        delay_s: f64,
        /// The step \[s\].
        step_s: f64,
        /// Values the buffers would hold.
        values: f64,
        /// The smallest step that fits \[s\].
        min_step_s: f64,
    },
    /// A per-vehicle list has the wrong length.
    #[error("{field} has {len} entries but the scenario has {vehicles} vehicles; give one value per vehicle or a single number")]
    LengthMismatch {
        /// Field path.
        field: String,
        /// Entries given.
        len: usize,
        /// Number of vehicles.
        vehicles: usize,
    },
    /// A reaction delay that does not lie on the step grid.
    #[error("model.delay_s[{vehicle}] = {delay_s} s is not a whole multiple of step_s = {step_s} s; use a delay of k·{step_s} s (e.g. {nearest} s) or a step that divides it")]
    DelayNotMultipleOfStep {
        /// Vehicle index.
        vehicle: usize,
        /// The delay α_i [s].
        delay_s: f64,
        /// The step Δt [s].
        step_s: f64,
        /// The nearest on-grid delay [s].
        nearest: f64,
    },
    /// The interaction graph is malformed.
    #[error("model.graph: {0}")]
    Graph(#[from] GraphError),
    /// The network does not hold the road of a loop or route, or a SUMO configuration cannot be
    /// read (the network reader's message, which names the `road.…` or `sumo.config` field).
    #[error("{0}")]
    Road(String),
}

pub(crate) fn invalid(
    field: impl Into<String>,
    value: impl std::fmt::Display,
    expected: impl Into<String>,
) -> ScenarioError {
    ScenarioError::Invalid {
        field: field.into(),
        value: readable_number(value.to_string()),
        expected: expected.into(),
    }
}

/// A number as an error shows it: Rust writes a float in full positional notation, so
/// `1e300` would fill the screen with 300 zeros; past 20 characters a number is written
/// `1e300` (the shortest form that reads back to it).
pub(crate) fn readable(x: f64) -> String {
    readable_number(x.to_string())
}

/// [`readable`] for a value already written: a number past 20 characters is rewritten, anything
/// else is left as it is.
fn readable_number(text: String) -> String {
    match text.parse::<f64>() {
        Ok(x) if text.len() > 20 && x.is_finite() => format!("{x:e}"),
        _ => text,
    }
}

/// A validated scenario: every per-vehicle value resolved, every number checked. Only
/// [`ScenarioFile::validate`] (or [`Scenario::load`], [`Scenario::from_json`]) makes one; its
/// values are read through accessors.
#[derive(Debug, Clone)]
pub struct Scenario {
    name: String,
    hash_hex: String,
    seed: u64,
    backend: Backend,
    n: usize,
    step_s: f64,
    steps: usize,
    model: Model,
    road: RoadSpec,
    measured: Option<MeasuredRoad>,
    ring_measured_m: Option<f64>,
    initial_speed_mps: Vec<f64>,
    initial_gap_m: Vec<f64>,
    length_m: Vec<f64>,
    verdict: VerdictThresholds,
    sumo: SumoSettings,
    mixed: Option<MixedSpec>,
    controller: Option<crate::user_law::UserLaw>,
    safety: Option<SafetyMode>,
}

impl Scenario {
    /// Why the native simulator cannot run this scenario as written, when it cannot: the
    /// user's own SUMO traffic (`sumo.routes`, `sumo.additional`) or vehicles
    /// (`sumo.controlled`) exist only in SUMO, and running syncroad's vehicles without them
    /// would report on another experiment.
    pub fn native_refusal(&self) -> Option<String> {
        let s = self.sumo();
        let how = "run it on SUMO (\"backend\": \"sumo\", `syncroad run`)";
        if let Some(sel) = s.controlled() {
            return Some(format!(
                "scenario {}: sumo.controlled = {}: the law drives the user's own SUMO vehicles, which exist only in SUMO; {how}",
                self.name(),
                serde_json::to_string(sel).unwrap_or_default()
            ));
        }
        if self.safety == Some(SafetyMode::Sumo) {
            return Some(format!(
                "scenario {}: safety = sumo: SUMO's own checks need SUMO; on the native simulator use \"safety\": \"filter\" (syncroad's safe-speed filter, the same on both backends) or \"off\", or {how}",
                self.name()
            ));
        }
        if let Some((field, value)) = s.other_traffic_source() {
            return Some(format!(
                "scenario {}: {field} = {value}: the user's own traffic, which only SUMO drives, shares the road; the native simulator would run syncroad's vehicles without it and report on another road; {how}",
                self.name(),
            ));
        }
        None
    }

    /// The safety layer the scenario names (`safety`); `None`: the default, which depends on
    /// who shares the road ([`Scenario::safety_for`]).
    pub fn safety(&self) -> Option<SafetyMode> {
        self.safety
    }

    /// The safety layer of a run: the scenario's, or by default `sumo` when other traffic
    /// shares the road or signals stand on it (`other_traffic`: SUMO's drivers among the law's
    /// vehicles or the network's traffic lights, as the backend knows them; or the user's
    /// routes, additional files or configuration), `filter` among syncroad's own stochastic
    /// humans (`humans`), and `off` when the law drives alone.
    ///
    /// Among humans the law's vehicles are automated cars, which the field holds to a safe
    /// speed (Flow's automated vehicles keep SUMO's safe speed by default): the filter gives
    /// them Gipps' safe speed with SUMO's τ on both backends alike, where `off` would let a
    /// law drive into a human who brakes on a whim. The law alone on its fixed graph, as the
    /// paper has it, stays unfiltered.
    pub fn safety_for(&self, other_traffic: bool, humans: bool) -> SafetyMode {
        self.safety
            .unwrap_or(if other_traffic || self.sumo().other_traffic() {
                SafetyMode::Sumo
            } else if humans {
                SafetyMode::Filter
            } else {
                SafetyMode::Off
            })
    }

    /// The user's own controller in place of the model's law, when the scenario names one.
    pub fn controller(&self) -> Option<&crate::user_law::UserLaw> {
        self.controller.as_ref()
    }

    /// The same scenario driven by `law` in place of its own (a Rust program's law, say):
    /// another scenario, whose hash covers the law's name, parameters and source.
    pub fn with_controller(&self, law: crate::user_law::UserLaw) -> Scenario {
        let text = serde_json::to_string(&law).expect("a law always serializes");
        let hash_hex = crate::fingerprint::fnv1a_hex(format!(
            "{}{text}{}",
            self.hash_hex,
            law.source_hash().unwrap_or("")
        ));
        Scenario {
            controller: Some(law),
            hash_hex,
            ..self.clone()
        }
    }

    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        Self::load_from(path, None)
    }

    /// [`Scenario::load`] for scenarios whose road may run through a network (`loop`,
    /// `route`): `reader` checks and measures it on `sumo.net`.
    pub fn load_with(path: &Path, reader: &dyn RoadReader) -> Result<Self, ScenarioError> {
        Self::load_from(path, Some(reader))
    }

    fn load_from(path: &Path, reader: Option<&dyn RoadReader>) -> Result<Self, ScenarioError> {
        Self::load_edited(path, reader, |_| {})
    }

    /// Reads a scenario file, lets `edit` change it as written (a command-line option that
    /// overrides one of its keys, such as `--safety`), and validates the result: the edit is
    /// checked as the file's own value would be, and the scenario's hash covers it.
    pub fn load_edited(
        path: &Path,
        reader: Option<&dyn RoadReader>,
        edit: impl FnOnce(&mut ScenarioFile),
    ) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut file = ScenarioFile::from_json(&text, &path.display().to_string())?;
        edit(&mut file);
        // Relative paths inside the scenario resolve against its folder; a scenario read from
        // a pipe or a device (`/dev/stdin`) has no folder of its own: the current one is used.
        let regular = std::fs::metadata(path).is_ok_and(|m| m.is_file());
        let base = if regular {
            path.parent().map(Path::to_path_buf).unwrap_or_default()
        } else {
            PathBuf::from(".")
        };
        file.validate_with(&base, reader)
    }

    /// Parses and validates scenario JSON text (relative paths resolve against the current folder).
    pub fn from_json(text: &str) -> Result<Self, ScenarioError> {
        ScenarioFile::from_json(text, "<string>")?.validate(Path::new("."))
    }

    /// Mixed traffic: which vehicles are automated and who drives the others (`None`: every
    /// vehicle runs the model).
    pub fn mixed(&self) -> Option<&MixedSpec> {
        self.mixed.as_ref()
    }

    /// Name used in reports and output file names (`"scenario"` when the file gives none).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Stable hash of the scenario as written (FNV-1a over its canonical JSON), for stamping results.
    pub fn hash_hex(&self) -> &str {
        &self.hash_hex
    }

    /// Seed of every random choice in the run.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Backend `syncroad run` uses.
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// Number of (controlled) vehicles N; a platoon's leader is not counted.
    pub fn vehicles(&self) -> usize {
        self.n
    }

    /// Step Δt [s].
    pub fn step_s(&self) -> f64 {
        self.step_s
    }

    /// Number of steps.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Simulated time [s].
    pub fn horizon_s(&self) -> f64 {
        self.steps as f64 * self.step_s
    }

    /// The validated model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Initial speeds v_i(0) [m/s], perturbation included.
    pub fn initial_speed_mps(&self) -> &[f64] {
        &self.initial_speed_mps
    }

    /// Initial bumper-to-bumper gaps to the predecessor [m], perturbation included. On a ring
    /// `gap[0]` is the gap from vehicle 0 to vehicle N−1.
    pub fn initial_gap_m(&self) -> &[f64] {
        &self.initial_gap_m
    }

    /// Vehicle lengths [m].
    pub fn length_m(&self) -> &[f64] {
        &self.length_m
    }

    /// Thresholds of the synchronization verdict.
    pub fn verdict_thresholds(&self) -> VerdictThresholds {
        self.verdict
    }

    /// The validated `sumo` section (network, vehicle type, time limit).
    pub fn sumo(&self) -> &SumoSettings {
        &self.sumo
    }

    /// The leader's speed at `t`, if the model has a leader.
    pub fn leader_speed_at(&self, t: f64) -> Option<f64> {
        match &self.model {
            Model::DelayedDriver(_) | Model::Linear(_) => self.model.pinning().map(|(v0, _)| *v0),
            Model::Cacc(c) => Some(c.leader.speed_at(t)),
        }
    }

    /// True when the road is closed: a ring, or a loop through a network.
    pub fn is_ring(&self) -> bool {
        self.road.is_closed()
    }

    /// The closed road's length [m]: a ring's circumference (as its network measures it when
    /// the scenario names one, `sumo.net`; else `road.length_m`), a loop's length measured on
    /// its network; `None` on an open road.
    pub fn ring_length_m(&self) -> Option<f64> {
        match self.road {
            RoadSpec::Ring { length_m } => Some(self.ring_measured_m.unwrap_or(length_m)),
            RoadSpec::Loop { .. } => self.measured.as_ref().map(|m| m.length_m),
            RoadSpec::Straight { .. } | RoadSpec::Route { .. } => None,
        }
    }

    /// The road as the scenario gives it.
    pub fn road(&self) -> &RoadSpec {
        &self.road
    }

    /// A loop or route as measured on its network (`None` for a ring or a straight road).
    pub fn measured_road(&self) -> Option<&MeasuredRoad> {
        self.measured.as_ref()
    }
}

#[cfg(test)]
mod readable_tests {
    use super::readable_number;

    #[test]
    fn huge_and_tiny_numbers_are_written_short_and_read_back_exactly() {
        for x in [1e300, -2.5e200, 1e-300, 3.0e-25, 1.7976931348623157e308] {
            let long = x.to_string();
            assert!(long.len() > 20, "{long}");
            let short = readable_number(long);
            assert!(short.len() <= 24, "{short}");
            assert_eq!(short.parse::<f64>().unwrap(), x, "{short}");
        }
        // Through the scenario's own check.
        let mut sc: serde_json::Value =
            serde_json::from_str(include_str!("../../../../scenarios/ring-theorem1.json")).unwrap();
        sc["horizon_s"] = serde_json::json!(1e300);
        let err = super::Scenario::from_json(&sc.to_string())
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("horizon_s = 1e300 s "), "{err}");
        assert!(err.len() < 200, "{err}");
        sc["horizon_s"] = serde_json::json!(60);
        sc["initial"] = serde_json::json!({"speed_mps": 1e300});
        let err = super::Scenario::from_json(&sc.to_string())
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("initial.speed_mps"), "{err}");
        assert!(err.contains(" = 1e300: "), "{err}");
        // What people write stays as written.
        for s in [
            "0.1",
            "2.1000000000000005",
            "-3",
            "1000",
            "inf",
            "NaN",
            "abc",
            "v0",
        ] {
            assert_eq!(readable_number(s.to_string()), s);
        }
    }
}
