//! Scenario files: the JSON a user writes ([`ScenarioFile`]) and the validated, resolved form
//! every backend runs ([`Scenario`]).
//!
//! Uniform values may be given once (`"delay_s": 0.5`) and per-vehicle values as lists
//! (`"delay_s": [0.4, 0.6, ...]`). Unknown fields are rejected. [`ScenarioFile::validate`]
//! checks everything that can be checked before a simulation starts, and every error names the
//! field path, the value and what would be valid.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::graph::{Arc, Graph, GraphError};
use crate::rng::SplitMix64;

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

fn invalid(
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

/// A value given once for all vehicles or once per vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerVehicle {
    /// The same value for every vehicle.
    Uniform(f64),
    /// One value per vehicle.
    List(Vec<f64>),
}

impl PerVehicle {
    /// The common value when every vehicle has the same one (ignoring the first `skip`
    /// entries of a list, e.g. the unused gain of a chain's head).
    pub fn uniform_value(&self, skip: usize) -> Option<f64> {
        match self {
            PerVehicle::Uniform(x) => Some(*x),
            PerVehicle::List(v) => {
                let rest = v.get(skip..)?;
                let first = *rest.first()?;
                rest.iter().all(|x| *x == first).then_some(first)
            }
        }
    }

    fn resolve(&self, field: &str, n: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = match self {
            PerVehicle::Uniform(x) => vec![*x; n],
            PerVehicle::List(xs) => {
                if xs.len() != n {
                    return Err(ScenarioError::LengthMismatch {
                        field: field.to_string(),
                        len: xs.len(),
                        vehicles: n,
                    });
                }
                xs.clone()
            }
        };
        for (i, x) in v.iter().enumerate() {
            if !x.is_finite() {
                return Err(invalid(
                    format!("{field}[{i}]"),
                    x,
                    "must be a finite number",
                ));
            }
        }
        Ok(v)
    }

    fn resolve_nonneg(&self, field: &str, n: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = self.resolve(field, n)?;
        for (i, x) in v.iter().enumerate() {
            if *x < 0.0 {
                return Err(invalid(format!("{field}[{i}]"), x, "must be ≥ 0"));
            }
        }
        Ok(v)
    }

    fn resolve_pos(&self, field: &str, n: usize) -> Result<Vec<f64>, ScenarioError> {
        let v = self.resolve(field, n)?;
        for (i, x) in v.iter().enumerate() {
            if *x <= 0.0 {
                return Err(invalid(format!("{field}[{i}]"), x, "must be > 0"));
            }
        }
        Ok(v)
    }
}

/// Where a run executes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// The fixed-step Rust simulator.
    Native,
    /// SUMO through libsumo in a worker process.
    #[default]
    Sumo,
}

/// The scenario file as written by the user.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Short name used in reports and output file names.
    #[serde(default)]
    pub name: Option<String>,
    /// Free text.
    #[serde(default)]
    pub description: Option<String>,
    /// Backend for `syncroad run` (default `sumo`).
    #[serde(default)]
    pub backend: Backend,
    /// Seed of every random choice in the run.
    pub seed: u64,
    /// Step Δt [s].
    pub step_s: f64,
    /// Simulated time [s].
    pub horizon_s: f64,
    /// The vehicles: a count, or one entry per vehicle carrying its own values (a platoon's
    /// leader is not counted).
    pub vehicles: VehiclesSpec,
    /// The road.
    pub road: RoadSpec,
    /// The controller and its parameters.
    pub model: ModelSpec,
    /// Initial speeds and gaps.
    #[serde(default)]
    pub initial: InitialSpec,
    /// Thresholds of the synchronization verdict.
    #[serde(default)]
    pub verdict: VerdictSpec,
    /// SUMO-specific settings (used by the `sumo` backend).
    #[serde(default)]
    pub sumo: SumoSpec,
}

/// The vehicle set: a count, or one entry per vehicle.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum VehiclesSpec {
    /// N identical slots; per-vehicle values come from the model and `initial` fields.
    Count(usize),
    /// One entry per vehicle.
    List(Vec<VehicleEntry>),
}

impl VehiclesSpec {
    /// Number of vehicles N.
    pub fn count(&self) -> usize {
        match self {
            VehiclesSpec::Count(n) => *n,
            VehiclesSpec::List(v) => v.len(),
        }
    }

    fn entries(&self) -> &[VehicleEntry] {
        match self {
            VehiclesSpec::Count(_) => &[],
            VehiclesSpec::List(v) => v,
        }
    }
}

impl<'de> Deserialize<'de> for VehiclesSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match serde_json::Value::deserialize(d)? {
            serde_json::Value::Number(x) => x
                .as_u64()
                .map(|n| VehiclesSpec::Count(n as usize))
                .ok_or_else(|| D::Error::custom(format!("vehicles = {x}: must be a whole number ≥ 1 or a list of per-vehicle entries"))),
            serde_json::Value::Array(items) => items
                .into_iter()
                .enumerate()
                .map(|(i, e)| serde_json::from_value(e).map_err(|err| D::Error::custom(format!("vehicles[{i}]: {err}"))))
                .collect::<Result<Vec<_>, _>>()
                .map(VehiclesSpec::List),
            other => Err(D::Error::custom(format!(
                "vehicles = {other}: must be a count (e.g. 22) or a list of per-vehicle entries (e.g. [{{\"delay_s\": 0.5}}, ...])"
            ))),
        }
    }
}

/// Values of one vehicle. Each overrides nothing: a value may be given here or in the
/// corresponding scenario-wide field, not both.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleEntry {
    /// Reaction delay α_i [s] (delayed-driver model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay_s: Option<f64>,
    /// Initial speed [m/s].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_mps: Option<f64>,
    /// Initial bumper-to-bumper gap to the predecessor [m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap_m: Option<f64>,
}

/// Merges a scenario-wide field with the per-vehicle entries into one [`PerVehicle`].
fn merge(
    field: &str,
    entry_field: &str,
    wide: Option<&PerVehicle>,
    entries: &[VehicleEntry],
    get: impl Fn(&VehicleEntry) -> Option<f64>,
) -> Result<Option<PerVehicle>, ScenarioError> {
    let given: Vec<Option<f64>> = entries.iter().map(&get).collect();
    if given.iter().all(Option::is_none) {
        return Ok(wide.cloned());
    }
    if let Some(i) = given
        .iter()
        .position(Option::is_some)
        .filter(|_| wide.is_some())
    {
        return Err(invalid(
            format!("vehicles[{i}].{entry_field}"),
            given[i].unwrap_or_default(),
            format!("{field} is set too; give each value once (either in {field} or in every vehicle entry)"),
        ));
    }
    if let Some(i) = given.iter().position(Option::is_none) {
        return Err(invalid(
            format!("vehicles[{i}].{entry_field}"),
            "missing",
            format!("other vehicle entries give {entry_field}; give it for every vehicle, or use {field} for all"),
        ));
    }
    Ok(Some(PerVehicle::List(
        given.into_iter().map(|x| x.unwrap_or_default()).collect(),
    )))
}

/// The road the vehicles drive on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum RoadSpec {
    /// A single-lane ring road of the given length (circular road of eq. `chandler`).
    Ring {
        /// Nominal circumference [m]; the SUMO backend uses the length SUMO reports for its net.
        length_m: f64,
    },
    /// A straight single-lane road (platoons, predecessor following behind a leader).
    Straight {
        /// Usable length [m].
        #[serde(default = "default_straight_length")]
        length_m: f64,
    },
}

fn default_straight_length() -> f64 {
    20_000.0
}

/// The controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ModelSpec {
    /// Delayed drivers, eq. `chandler+`: `v_i'(t) = u_i(t − α_i)`, `u_i = Σ_j a_ij (v_j − v_i)`
    /// (plus `b_i (v_0 − v_i)` with a leader, eq. `proto-lin+`).
    DelayedDriver {
        /// Interaction graph with its gains `a_ij` [1/s].
        graph: GraphSpec,
        /// Reaction delays α_i [s], whole multiples of `step_s` (or per vehicle in `vehicles`).
        #[serde(default)]
        delay_s: Option<PerVehicle>,
        /// Optional reference: a leader at speed `v_0` seen by pinned drivers (`b_i > 0`).
        #[serde(default)]
        leader: Option<DriverLeaderSpec>,
        /// What drivers had seen before t = 0.
        #[serde(default)]
        history: HistorySpec,
    },
    /// Bidirectional CACC of eqs. `veh-proto1`/`veh-proto2` behind a leader.
    Cacc(CaccSpec),
}

/// Reference for the delayed-driver model (Theorem `thm.1+`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriverLeaderSpec {
    /// Leader speed v_0 [m/s].
    pub speed_mps: f64,
    /// Pinning gains b_i ≥ 0 [1/s]; at least one positive.
    pub pinning: PerVehicle,
}

/// Delay-buffer history before t = 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HistorySpec {
    /// Speeds were constant at their initial values for t ≤ 0 (the usual DDE initial function):
    /// drivers react to the initial speed differences from t = 0 on.
    #[default]
    ConstantSpeeds,
    /// No reaction was pending: `u_i(t) = 0` for t < 0, so driver i first reacts at t = α_i.
    NoReaction,
}

/// Interaction graph of the delayed-driver model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum GraphSpec {
    /// Each driver follows its predecessor (vehicle 0 follows vehicle N−1): eq. `chandler` on a ring.
    UnidirectionalRing {
        /// Gain K_i on the predecessor [1/s].
        gain: PerVehicle,
    },
    /// Each driver reacts to predecessor and follower.
    BidirectionalRing {
        /// Gain on the predecessor [1/s].
        gain_pred: PerVehicle,
        /// Gain on the follower [1/s].
        gain_follow: PerVehicle,
    },
    /// Driver i ≥ 1 follows i−1; vehicle 0 follows the leader (pinning) if one is given.
    Chain {
        /// Gain on the predecessor [1/s] (entry 0 unused).
        gain: PerVehicle,
    },
    /// Each driver reacts to every other vehicle with gain `gain[i]`.
    AllToAll {
        /// Gain per observed vehicle [1/s].
        gain: PerVehicle,
    },
    /// Explicit arcs.
    Edges {
        /// The arcs `from → to` with gains `a_{to,from}`.
        edges: Vec<EdgeSpec>,
    },
    /// Explicit adjacency matrix `A`, row i = gains of driver i.
    Matrix {
        /// N×N matrix with zero diagonal.
        a: Vec<Vec<f64>>,
    },
}

/// One explicit arc.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeSpec {
    /// Observed vehicle j.
    pub from: usize,
    /// Reacting driver i.
    pub to: usize,
    /// Gain a_ij [1/s].
    pub weight: f64,
}

/// Bidirectional CACC (eqs. `veh1`, `veh-proto1`, `veh-proto2`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaccSpec {
    /// Speed-error gain μ_i [1/s].
    pub mu: PerVehicle,
    /// Front-gap gain η_i [1/s²].
    pub eta: PerVehicle,
    /// Rear-gap gain ν_i [1/s²] (ignored for the last vehicle).
    pub nu: PerVehicle,
    /// Desired bumper-to-bumper gap s_i to the predecessor [m].
    pub desired_gap_m: PerVehicle,
    /// Powertrain lag τ_i [s] in τ_i q''' + q'' = a_des.
    pub tau_s: PerVehicle,
    /// Vehicle lengths [m] (default 5).
    #[serde(default = "default_length")]
    pub length_m: PerVehicle,
    /// The leader's speed.
    pub leader: LeaderProfile,
}

fn default_length() -> PerVehicle {
    PerVehicle::Uniform(5.0)
}

/// The leader's speed over time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum LeaderProfile {
    /// Constant speed v_0.
    Constant {
        /// v_0 [m/s].
        speed_mps: f64,
    },
    /// Cruise at v_0, brake at `decel_mps2` from `start_s` down to `low_mps`, hold for `hold_s`,
    /// then accelerate back at `accel_mps2`.
    BrakeAndRecover {
        /// Cruise speed [m/s].
        speed_mps: f64,
        /// Start of braking [s].
        start_s: f64,
        /// Lowest speed [m/s].
        low_mps: f64,
        /// Braking deceleration (positive) [m/s²].
        decel_mps2: f64,
        /// Time at the low speed [s].
        hold_s: f64,
        /// Acceleration back to cruise [m/s²].
        accel_mps2: f64,
    },
    /// Piecewise-linear speed through `(t, v)` points, constant outside.
    Points {
        /// `[t_s, v_mps]` pairs with increasing times.
        points: Vec<[f64; 2]>,
    },
}

impl LeaderProfile {
    /// Leader speed at time `t` [m/s].
    pub fn speed_at(&self, t: f64) -> f64 {
        match self {
            LeaderProfile::Constant { speed_mps } => *speed_mps,
            LeaderProfile::BrakeAndRecover {
                speed_mps,
                start_s,
                low_mps,
                decel_mps2,
                hold_s,
                accel_mps2,
            } => {
                let t_brake = (speed_mps - low_mps) / decel_mps2;
                let t_acc = (speed_mps - low_mps) / accel_mps2;
                let t1 = start_s + t_brake;
                let t2 = t1 + hold_s;
                if t < *start_s {
                    *speed_mps
                } else if t < t1 {
                    speed_mps - decel_mps2 * (t - start_s)
                } else if t < t2 {
                    *low_mps
                } else if t < t2 + t_acc {
                    low_mps + accel_mps2 * (t - t2)
                } else {
                    *speed_mps
                }
            }
            LeaderProfile::Points { points } => {
                let first = points[0];
                let last = points[points.len() - 1];
                if t <= first[0] {
                    return first[1];
                }
                if t >= last[0] {
                    return last[1];
                }
                let k = points.partition_point(|p| p[0] <= t);
                let (a, b) = (points[k - 1], points[k]);
                a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0])
            }
        }
    }

    /// Initial (t = 0) leader speed [m/s].
    pub fn initial_speed(&self) -> f64 {
        self.speed_at(0.0)
    }

    fn validate(&self) -> Result<(), ScenarioError> {
        let f = "model.leader";
        let nonneg = |name: &str, x: f64| -> Result<(), ScenarioError> {
            if !x.is_finite() || x < 0.0 {
                return Err(invalid(
                    format!("{f}.{name}"),
                    x,
                    "must be a finite number ≥ 0",
                ));
            }
            Ok(())
        };
        match self {
            LeaderProfile::Constant { speed_mps } => nonneg("speed_mps", *speed_mps),
            LeaderProfile::BrakeAndRecover {
                speed_mps,
                start_s,
                low_mps,
                decel_mps2,
                hold_s,
                accel_mps2,
            } => {
                nonneg("speed_mps", *speed_mps)?;
                nonneg("start_s", *start_s)?;
                nonneg("low_mps", *low_mps)?;
                nonneg("hold_s", *hold_s)?;
                for (name, x) in [("decel_mps2", *decel_mps2), ("accel_mps2", *accel_mps2)] {
                    if !x.is_finite() || x <= 0.0 {
                        return Err(invalid(
                            format!("{f}.{name}"),
                            x,
                            "must be a finite number > 0",
                        ));
                    }
                }
                if low_mps > speed_mps {
                    return Err(invalid(
                        format!("{f}.low_mps"),
                        low_mps,
                        format!("must not exceed speed_mps = {speed_mps}"),
                    ));
                }
                Ok(())
            }
            LeaderProfile::Points { points } => {
                if points.is_empty() {
                    return Err(invalid(
                        format!("{f}.points"),
                        "[]",
                        "needs at least one [t_s, v_mps] pair",
                    ));
                }
                for (k, p) in points.iter().enumerate() {
                    nonneg(&format!("points[{k}][0]"), p[0])?;
                    nonneg(&format!("points[{k}][1]"), p[1])?;
                    if k > 0 && p[0] <= points[k - 1][0] {
                        return Err(invalid(
                            format!("{f}.points[{k}][0]"),
                            p[0],
                            format!("times must increase (previous is {})", points[k - 1][0]),
                        ));
                    }
                }
                Ok(())
            }
        }
    }
}

/// Initial state.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// Initial speeds [m/s] (before the perturbation); default 10 m/s.
    #[serde(default)]
    pub speed_mps: Option<PerVehicle>,
    /// Initial bumper-to-bumper gaps to the predecessor [m]. Default: even spacing on a ring,
    /// the desired gaps for a platoon, 20 m otherwise.
    #[serde(default)]
    pub gap_m: Option<PerVehicle>,
    /// Seeded uniform perturbation added to the initial state.
    #[serde(default)]
    pub perturbation: PerturbationSpec,
}

/// Initial speed when none is given [m/s].
pub const DEFAULT_SPEED_MPS: f64 = 10.0;

/// Uniform random perturbation, drawn from the scenario seed.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerturbationSpec {
    /// Each speed gets a uniform offset in `[−speed_mps, speed_mps]`.
    #[serde(default)]
    pub speed_mps: f64,
    /// Each gap gets a uniform offset in `[−gap_m, gap_m]`.
    #[serde(default)]
    pub gap_m: f64,
}

/// Thresholds of the synchronization verdict (see [`crate::metrics::Verdict`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VerdictSpec {
    /// Speeds are synchronized when the spread stays below this over the final window [m/s].
    #[serde(default = "default_tol")]
    pub tolerance_mps: f64,
    /// Length of the final window [s].
    #[serde(default = "default_window")]
    pub window_s: f64,
}

fn default_tol() -> f64 {
    0.05
}
fn default_window() -> f64 {
    5.0
}

impl Default for VerdictSpec {
    fn default() -> Self {
        Self {
            tolerance_mps: default_tol(),
            window_s: default_window(),
        }
    }
}

/// SUMO settings: network and vehicle type.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SumoSpec {
    /// Network file; relative paths are resolved against the scenario file's folder.
    #[serde(default)]
    pub net: Option<PathBuf>,
    /// Vehicle length [m].
    #[serde(default = "d_length")]
    pub length_m: f64,
    /// SUMO `minGap` [m].
    #[serde(default = "d_min_gap")]
    pub min_gap_m: f64,
    /// Maximum acceleration [m/s²].
    #[serde(default = "d_accel")]
    pub accel_mps2: f64,
    /// Comfortable deceleration [m/s²].
    #[serde(default = "d_decel")]
    pub decel_mps2: f64,
    /// Emergency deceleration [m/s²].
    #[serde(default = "d_edecel")]
    pub emergency_decel_mps2: f64,
    /// Maximum speed [m/s].
    #[serde(default = "d_vmax")]
    pub max_speed_mps: f64,
    /// Wall-clock limit of one SUMO run [s].
    #[serde(default = "d_timeout")]
    pub timeout_s: f64,
}

fn d_length() -> f64 {
    5.0
}
fn d_min_gap() -> f64 {
    2.5
}
fn d_accel() -> f64 {
    2.6
}
fn d_decel() -> f64 {
    4.5
}
fn d_edecel() -> f64 {
    9.0
}
fn d_vmax() -> f64 {
    30.0
}
fn d_timeout() -> f64 {
    600.0
}

impl Default for SumoSpec {
    fn default() -> Self {
        Self {
            net: None,
            length_m: d_length(),
            min_gap_m: d_min_gap(),
            accel_mps2: d_accel(),
            decel_mps2: d_decel(),
            emergency_decel_mps2: d_edecel(),
            max_speed_mps: d_vmax(),
            timeout_s: d_timeout(),
        }
    }
}

/// The validated delayed-driver model.
#[derive(Debug, Clone)]
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
#[derive(Debug, Clone)]
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
#[derive(Debug, Clone)]
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

impl ScenarioFile {
    /// Parses JSON text; `origin` names the source in error messages.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        serde_json::from_str(text).map_err(|source| ScenarioError::Json {
            path: origin.to_string(),
            source,
        })
    }

    /// Validates and resolves the scenario; `base_dir` resolves relative paths.
    pub fn validate(self, base_dir: &Path) -> Result<Scenario, ScenarioError> {
        let n = self.vehicles.count();
        let entries = self.vehicles.entries();
        if n == 0 {
            return Err(invalid("vehicles", 0, "must be ≥ 1"));
        }
        if !(self.step_s.is_finite() && self.step_s > 0.0 && self.step_s <= 1.0) {
            return Err(invalid(
                "step_s",
                self.step_s,
                "must be a finite number in (0, 1] s; 0.1 or less is usual",
            ));
        }
        if !(self.horizon_s.is_finite() && self.horizon_s > 0.0) {
            return Err(invalid(
                "horizon_s",
                self.horizon_s,
                "must be a finite number > 0",
            ));
        }
        let steps = (self.horizon_s / self.step_s).round() as usize;
        if steps == 0 {
            return Err(invalid(
                "horizon_s",
                self.horizon_s,
                format!("must be at least one step ({} s)", self.step_s),
            ));
        }
        if !(self.verdict.tolerance_mps.is_finite() && self.verdict.tolerance_mps > 0.0) {
            return Err(invalid(
                "verdict.tolerance_mps",
                self.verdict.tolerance_mps,
                "must be a finite number > 0",
            ));
        }
        if !(self.verdict.window_s.is_finite()
            && self.verdict.window_s > 0.0
            && self.verdict.window_s <= self.horizon_s)
        {
            return Err(invalid(
                "verdict.window_s",
                self.verdict.window_s,
                format!("must be > 0 and ≤ horizon_s = {}", self.horizon_s),
            ));
        }
        self.validate_sumo()?;
        let road_len = match self.road {
            RoadSpec::Ring { length_m } | RoadSpec::Straight { length_m } => length_m,
        };
        if !(road_len.is_finite() && road_len > 0.0) {
            return Err(invalid(
                "road.length_m",
                road_len,
                "must be a finite number > 0",
            ));
        }

        let model = match &self.model {
            ModelSpec::DelayedDriver {
                graph,
                delay_s,
                leader,
                history,
            } => {
                let graph = build_graph(graph, n)?;
                let delay_s = merge("model.delay_s", "delay_s", delay_s.as_ref(), entries, |e| {
                    e.delay_s
                })?
                .ok_or_else(|| {
                    invalid(
                        "model.delay_s",
                        "missing",
                        "give the reaction delays α_i [s] here or in every vehicle entry",
                    )
                })?
                .resolve_nonneg("model.delay_s", n)?;
                let mut delay_steps = Vec::with_capacity(n);
                for (i, &d) in delay_s.iter().enumerate() {
                    let m = (d / self.step_s).round();
                    if (m * self.step_s - d).abs() > 1e-9 * self.step_s.max(d) {
                        return Err(ScenarioError::DelayNotMultipleOfStep {
                            vehicle: i,
                            delay_s: d,
                            step_s: self.step_s,
                            nearest: (m.max(1.0) * self.step_s * 1e9).round() / 1e9,
                        });
                    }
                    delay_steps.push(m as usize);
                }
                let leader = match leader {
                    None => None,
                    Some(l) => {
                        if !(l.speed_mps.is_finite() && l.speed_mps >= 0.0) {
                            return Err(invalid(
                                "model.leader.speed_mps",
                                l.speed_mps,
                                "must be a finite number ≥ 0",
                            ));
                        }
                        let b = l.pinning.resolve_nonneg("model.leader.pinning", n)?;
                        if b.iter().all(|&x| x == 0.0) {
                            return Err(invalid(
                                "model.leader.pinning",
                                "all zero",
                                "at least one driver must see the leader (some b_i > 0, Theorem thm.1+)",
                            ));
                        }
                        Some((l.speed_mps, b))
                    }
                };
                if matches!(self.road, RoadSpec::Ring { .. }) && leader.is_some() {
                    return Err(invalid(
                        "model.leader",
                        "given",
                        "a leader needs a straight road (road.type = \"straight\")",
                    ));
                }
                Model::DelayedDriver(DelayedDriverModel {
                    graph,
                    delay_s,
                    delay_steps,
                    leader,
                    history: *history,
                })
            }
            ModelSpec::Cacc(c) => {
                if matches!(self.road, RoadSpec::Ring { .. }) {
                    return Err(invalid("road.type", "ring", "a CACC platoon drives behind its leader on a straight road: use \"straight\""));
                }
                c.leader.validate()?;
                let mut nu = c.nu.resolve_nonneg("model.nu", n)?;
                nu[n - 1] = 0.0;
                Model::Cacc(CaccModel {
                    mu: c.mu.resolve_pos("model.mu", n)?,
                    eta: c.eta.resolve_pos("model.eta", n)?,
                    nu,
                    desired_gap_m: c.desired_gap_m.resolve_nonneg("model.desired_gap_m", n)?,
                    tau_s: c.tau_s.resolve_pos("model.tau_s", n)?,
                    length_m: c.length_m.resolve_pos("model.length_m", n)?,
                    leader: c.leader.clone(),
                })
            }
        };

        let length_m = match &model {
            Model::Cacc(c) => c.length_m.clone(),
            Model::DelayedDriver(_) => vec![self.sumo.length_m; n],
        };
        let mut rng = SplitMix64::new(self.seed);
        let pert = &self.initial.perturbation;
        for (name, x) in [("speed_mps", pert.speed_mps), ("gap_m", pert.gap_m)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(invalid(
                    format!("initial.perturbation.{name}"),
                    x,
                    "must be a finite amplitude ≥ 0",
                ));
            }
        }
        let mut speeds = merge(
            "initial.speed_mps",
            "speed_mps",
            self.initial.speed_mps.as_ref(),
            entries,
            |e| e.speed_mps,
        )?
        .unwrap_or(PerVehicle::Uniform(DEFAULT_SPEED_MPS))
        .resolve_nonneg("initial.speed_mps", n)?;
        for v in speeds.iter_mut() {
            *v = (*v + rng.symmetric(pert.speed_mps)).max(0.0);
        }
        let gap_spec = merge(
            "initial.gap_m",
            "gap_m",
            self.initial.gap_m.as_ref(),
            entries,
            |e| e.gap_m,
        )?;
        let mut gaps = match (&gap_spec, &self.road, &model) {
            (Some(g), _, _) => g.resolve_nonneg("initial.gap_m", n)?,
            (None, RoadSpec::Ring { length_m: ring }, _) => {
                let used: f64 = length_m.iter().sum();
                vec![(ring - used) / n as f64; n]
            }
            (None, RoadSpec::Straight { .. }, Model::Cacc(c)) => c.desired_gap_m.clone(),
            (None, RoadSpec::Straight { .. }, _) => vec![20.0; n],
        };
        let offsets: Vec<f64> = (0..n).map(|_| rng.symmetric(pert.gap_m)).collect();
        // On a ring the gaps must still close the circle: remove the offsets' mean.
        let shift = if matches!(self.road, RoadSpec::Ring { .. }) {
            offsets.iter().sum::<f64>() / n as f64
        } else {
            0.0
        };
        for (g, o) in gaps.iter_mut().zip(&offsets) {
            *g += o - shift;
        }
        for (i, g) in gaps.iter().enumerate() {
            if *g < 0.0 {
                return Err(invalid(
                    format!("initial.gap_m[{i}]"),
                    g,
                    "the gap (after perturbation) must be ≥ 0: vehicles may not overlap; lower initial.perturbation.gap_m or use fewer vehicles",
                ));
            }
        }
        if let RoadSpec::Ring { length_m: ring } = self.road {
            let used: f64 = gaps.iter().sum::<f64>() + length_m.iter().sum::<f64>();
            if (used - ring).abs() > 1e-6 * ring {
                return Err(invalid(
                    "initial.gap_m",
                    format!("{used:.3} m of gaps and vehicle lengths"),
                    format!("on a ring, gaps plus vehicle lengths must add up to road.length_m = {ring} m (omit initial.gap_m for even spacing)"),
                ));
            }
        }
        let name = self.name.clone().unwrap_or_else(|| "scenario".to_string());
        Ok(Scenario {
            name,
            n,
            step_s: self.step_s,
            steps,
            model,
            initial_speed_mps: speeds,
            initial_gap_m: gaps,
            length_m,
            base_dir: base_dir.to_path_buf(),
            file: self,
        })
    }

    fn validate_sumo(&self) -> Result<(), ScenarioError> {
        let s = &self.sumo;
        for (name, x) in [
            ("length_m", s.length_m),
            ("accel_mps2", s.accel_mps2),
            ("decel_mps2", s.decel_mps2),
            ("emergency_decel_mps2", s.emergency_decel_mps2),
            ("max_speed_mps", s.max_speed_mps),
            ("timeout_s", s.timeout_s),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(invalid(
                    format!("sumo.{name}"),
                    x,
                    "must be a finite number > 0",
                ));
            }
        }
        if !(s.min_gap_m.is_finite() && s.min_gap_m >= 0.0) {
            return Err(invalid(
                "sumo.min_gap_m",
                s.min_gap_m,
                "must be a finite number ≥ 0",
            ));
        }
        Ok(())
    }
}

fn build_graph(spec: &GraphSpec, n: usize) -> Result<Graph, ScenarioError> {
    let g = match spec {
        GraphSpec::UnidirectionalRing { gain } => {
            Graph::unidirectional_ring(n, &gain.resolve_pos("model.graph.gain", n)?)?
        }
        GraphSpec::BidirectionalRing {
            gain_pred,
            gain_follow,
        } => Graph::bidirectional_ring(
            n,
            &gain_pred.resolve_pos("model.graph.gain_pred", n)?,
            &gain_follow.resolve_pos("model.graph.gain_follow", n)?,
        )?,
        GraphSpec::Chain { gain } => {
            let mut k = gain.resolve_nonneg("model.graph.gain", n)?;
            k[0] = 0.0;
            for (i, x) in k.iter().enumerate().skip(1) {
                if *x <= 0.0 {
                    return Err(invalid(format!("model.graph.gain[{i}]"), x, "must be > 0"));
                }
            }
            Graph::chain(n, &k)?
        }
        GraphSpec::AllToAll { gain } => {
            Graph::all_to_all(n, &gain.resolve_pos("model.graph.gain", n)?)?
        }
        GraphSpec::Edges { edges } => {
            let mut arcs = Vec::with_capacity(edges.len());
            for (k, e) in edges.iter().enumerate() {
                let f = format!("model.graph.edges[{k}]");
                if e.from >= n || e.to >= n {
                    return Err(invalid(
                        f,
                        format!("{} -> {}", e.from, e.to),
                        format!("vehicle indices must be in 0..{n} (there are {n} vehicles)"),
                    ));
                }
                if e.from == e.to {
                    return Err(invalid(
                        f,
                        format!("{} -> {}", e.from, e.to),
                        "self-loops are not allowed (a_ii = 0)",
                    ));
                }
                if !(e.weight.is_finite() && e.weight > 0.0) {
                    return Err(invalid(
                        format!("{f}.weight"),
                        e.weight,
                        "must be a finite number > 0",
                    ));
                }
                arcs.push(Arc {
                    from: e.from,
                    to: e.to,
                    weight: e.weight,
                });
            }
            Graph::from_arcs(n, &arcs)?
        }
        GraphSpec::Matrix { a } => {
            if a.len() != n {
                return Err(ScenarioError::LengthMismatch {
                    field: "model.graph.a".into(),
                    len: a.len(),
                    vehicles: n,
                });
            }
            let mut arcs = Vec::new();
            for (i, row) in a.iter().enumerate() {
                if row.len() != n {
                    return Err(ScenarioError::LengthMismatch {
                        field: format!("model.graph.a[{i}]"),
                        len: row.len(),
                        vehicles: n,
                    });
                }
                for (j, &w) in row.iter().enumerate() {
                    let f = format!("model.graph.a[{i}][{j}]");
                    if !(w.is_finite() && w >= 0.0) {
                        return Err(invalid(f, w, "must be a finite number ≥ 0"));
                    }
                    if i == j && w != 0.0 {
                        return Err(invalid(f, w, "diagonal entries must be 0 (no self-loops)"));
                    }
                    if w > 0.0 {
                        arcs.push(Arc {
                            from: j,
                            to: i,
                            weight: w,
                        });
                    }
                }
            }
            Graph::from_arcs(n, &arcs)?
        }
    };
    Ok(g)
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
