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
//! traffic: which vehicles are automated), `validate` (every
//! check, with field paths), `graph_spec` (building the interaction graph) and this file, the
//! sealed [`Scenario`] every backend runs.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::graph::{Graph, GraphError};

pub mod file;
mod graph_spec;
pub mod leader;
pub mod mixed;
pub mod per_vehicle;
mod validate;

pub use file::*;
pub use leader::LeaderProfile;
pub use mixed::{automated_vehicles, MixedSpec};
pub use per_vehicle::PerVehicle;

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
}

pub(crate) fn invalid(
    field: impl Into<String>,
    value: impl std::fmt::Display,
    expected: impl Into<String>,
) -> ScenarioError {
    ScenarioError::Invalid {
        field: field.into(),
        value: value.to_string(),
        expected: expected.into(),
    }
}

/// The validated delayed-driver model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DelayedDriverModel {
    /// Interaction graph `A`.
    pub graph: Graph,
    /// Delays α_i [s].
    pub delay_s: Vec<f64>,
    /// Delays in steps m_i = α_i / Δt.
    pub delay_steps: Vec<usize>,
    /// Leader speed v_0 and pinning gains b_i, if any.
    pub leader: Option<(f64, Vec<f64>)>,
    /// Pre-history convention.
    pub history: HistorySpec,
}

/// The validated CACC model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaccModel {
    /// μ_i [1/s].
    pub mu: Vec<f64>,
    /// η_i [1/s²].
    pub eta: Vec<f64>,
    /// ν_i [1/s²] (ν_N is forced to 0: the last vehicle has no follower).
    pub nu: Vec<f64>,
    /// Desired gaps s_i [m].
    pub desired_gap_m: Vec<f64>,
    /// Lags τ_i [s].
    pub tau_s: Vec<f64>,
    /// Lengths [m].
    pub length_m: Vec<f64>,
    /// Leader speed profile.
    pub leader: LeaderProfile,
}

/// The validated model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Model {
    /// Delayed drivers (eq. `chandler+`).
    DelayedDriver(DelayedDriverModel),
    /// Bidirectional CACC platoon.
    Cacc(CaccModel),
}

/// A validated scenario: every per-vehicle value resolved, every number checked.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// The file as written (for hashing and reports).
    pub file: ScenarioFile,
    /// Name used in reports.
    pub name: String,
    /// Number of (controlled) vehicles N.
    pub n: usize,
    /// Step Δt [s].
    pub step_s: f64,
    /// Number of steps.
    pub steps: usize,
    /// The model.
    pub model: Model,
    /// Initial speeds v_i(0) [m/s], perturbation included.
    pub initial_speed_mps: Vec<f64>,
    /// Initial bumper-to-bumper gaps to the predecessor [m], perturbation included. On a ring
    /// `gap[0]` is the gap from vehicle 0 to vehicle N−1.
    pub initial_gap_m: Vec<f64>,
    /// Vehicle lengths [m].
    pub length_m: Vec<f64>,
    /// Folder of the scenario file (for relative paths).
    pub base_dir: PathBuf,
}

impl Scenario {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let file = ScenarioFile::from_json(&text, &path.display().to_string())?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        file.validate(&base)
    }

    /// Parses and validates scenario JSON text (relative paths resolve against the current folder).
    pub fn from_json(text: &str) -> Result<Self, ScenarioError> {
        ScenarioFile::from_json(text, "<string>")?.validate(Path::new("."))
    }

    /// Stable hash of the scenario as written (FNV-1a over its canonical JSON), for stamping results.
    pub fn hash_hex(&self) -> String {
        let json = serde_json::to_string(&self.file).expect("a scenario always serializes");
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for b in json.bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
        format!("{h:016x}")
    }

    /// Simulated time [s].
    pub fn horizon_s(&self) -> f64 {
        self.steps as f64 * self.step_s
    }

    /// The leader's speed at `t`, if the model has a leader.
    pub fn leader_speed_at(&self, t: f64) -> Option<f64> {
        match &self.model {
            Model::DelayedDriver(m) => m.leader.as_ref().map(|(v0, _)| *v0),
            Model::Cacc(c) => Some(c.leader.speed_at(t)),
        }
    }

    /// True when the road is a ring.
    pub fn is_ring(&self) -> bool {
        matches!(self.file.road, RoadSpec::Ring { .. })
    }

    /// The ring's nominal circumference [m], `None` on a straight road.
    pub fn ring_length_m(&self) -> Option<f64> {
        match self.file.road {
            RoadSpec::Ring { length_m } => Some(length_m),
            RoadSpec::Straight { .. } => None,
        }
    }
}
