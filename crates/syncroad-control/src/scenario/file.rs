//! The scenario file as a user writes it: the JSON schema, unknown fields rejected.

use std::fmt;
use std::path::PathBuf;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{invalid, LeaderProfile, MixedSpec, PerVehicle, ScenarioError, VehicleSelector};

/// Where a run executes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
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
    /// The controller and its parameters; left out only when the scenario has no vehicles of
    /// its own (`"vehicles": 0`, an open road of inflows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelSpec>,
    /// Initial speeds and gaps.
    #[serde(default)]
    pub initial: InitialSpec,
    /// Thresholds of the synchronization verdict.
    #[serde(default)]
    pub verdict: VerdictSpec,
    /// SUMO-specific settings (used by the `sumo` backend).
    #[serde(default)]
    pub sumo: SumoSpec,
    /// Mixed traffic: a fraction of the vehicles runs the law or a wave damper, the others are
    /// SUMO drivers ([`MixedSpec`]; SUMO backend, rings only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mixed: Option<MixedSpec>,
    /// The user's own controller in place of the model's law ([`crate::user_law`]): a Python
    /// class stepped every step on either backend.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<crate::user_law::ControllerSpec>,
    /// The safety layer under the law ([`crate::safety`]): `off`, `sumo` or `filter`; by
    /// default `sumo` when other traffic shares the road, else `off`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safety: Option<SafetyMode>,
}

/// The scenario's `safety` key: which safety layer sits between the law and the command
/// ([`crate::safety`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SafetyMode {
    /// No layer: the law's command as it is (SUMO's speed mode 32).
    Off,
    /// SUMO's own checks through the speed mode (SUMO backend only).
    Sumo,
    /// syncroad's own filter (Gipps' safe speed), the same on both backends.
    Filter,
}

impl SafetyMode {
    /// SUMO's speed mode for the law's vehicles: 32 (every check off) for `off`; 25 (bit 0:
    /// the safe speed towards the leader, bit 3: right of way at junctions, bit 4: brake for a
    /// red light; accelerations stay the law's) for `sumo`; 48 (every check off but braking
    /// for red lights) for `filter`, whose car following is syncroad's.
    pub fn speed_mode(self) -> i32 {
        match self {
            SafetyMode::Off => 32,
            SafetyMode::Sumo => 25,
            SafetyMode::Filter => 48,
        }
    }

    /// Its name in the scenario and the record.
    pub fn name(self) -> &'static str {
        match self {
            SafetyMode::Off => "off",
            SafetyMode::Sumo => "sumo",
            SafetyMode::Filter => "filter",
        }
    }
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

    pub(crate) fn entries(&self) -> &[VehicleEntry] {
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
pub(crate) fn merge(
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
    /// A closed loop through the network of `sumo.net`: the cycle of `edges` in driving order,
    /// or the shortest cycle through the edge `through`, driven on lane `lane` of every edge.
    /// Its length is measured on the network (normal plus junction-internal lanes).
    Loop {
        /// The normal edges of the cycle in driving order (the last one leads to the first).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        edges: Option<Vec<String>>,
        /// One edge of the cycle: the shortest cycle through it is taken.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        through: Option<String>,
        /// Lane index (0 = rightmost) the controlled vehicles keep on every edge.
        #[serde(default, deserialize_with = "loop_lane")]
        lane: usize,
    },
    /// An open route through the network of `sumo.net` (platoons, a chain behind a leader):
    /// `edges` in driving order, on the lanes `lane` chooses. Its length is measured on the
    /// network along the lanes driven.
    Route {
        /// The normal edges in driving order.
        edges: Vec<String>,
        /// The lane driven on each edge: one index kept on every edge, one index per edge, or
        /// `"follow"` (the network's connections from lane to lane).
        #[serde(default)]
        lane: RouteLanes,
    },
}

/// `road.lane` of a loop: one lane index, with a message that says so (a route's other forms
/// are not a loop's).
fn loop_lane<'de, D: serde::Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    match RouteLanes::deserialize(d)? {
        RouteLanes::Index(i) => Ok(i),
        other => Err(serde::de::Error::custom(format!(
            "road.lane = {other}: a loop keeps one lane index (0 = rightmost) on every edge; one index per edge and \"follow\" are for routes (road.type = \"route\")"
        ))),
    }
}

/// The lanes a route drives (`road.lane` of a route).
///
/// * a number: that lane index (0 = rightmost) on every edge;
/// * a list: the lane index on each edge, in the order of `road.edges`;
/// * `"follow"`: the lanes the network's connections lead along: from the lowest lane of the
///   first edge from which they reach the last edge, each connection to the next edge taken
///   to its lowest lane that still leads on (through a merge, the lane that continues).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RouteLanes {
    /// One lane index on every edge.
    Index(usize),
    /// The lane index on each edge.
    PerEdge(Vec<usize>),
    /// Along the network's connections.
    Follow,
}

impl Default for RouteLanes {
    fn default() -> Self {
        RouteLanes::Index(0)
    }
}

impl fmt::Display for RouteLanes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RouteLanes::Index(i) => write!(f, "{i}"),
            RouteLanes::PerEdge(v) => write!(f, "{v:?}"),
            RouteLanes::Follow => f.write_str("\"follow\""),
        }
    }
}

impl Serialize for RouteLanes {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            RouteLanes::Index(i) => s.serialize_u64(*i as u64),
            RouteLanes::PerEdge(v) => v.serialize(s),
            RouteLanes::Follow => s.serialize_str("follow"),
        }
    }
}

impl<'de> Deserialize<'de> for RouteLanes {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Lanes;
        const EXPECTED: &str =
            "road.lane as a lane index (0 = rightmost), a list of one lane index per edge, or \"follow\"";
        impl<'de> serde::de::Visitor<'de> for Lanes {
            type Value = RouteLanes;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(EXPECTED)
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<RouteLanes, E> {
                usize::try_from(v)
                    .map(RouteLanes::Index)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(v), &self))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<RouteLanes, E> {
                match v {
                    "follow" => Ok(RouteLanes::Follow),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<RouteLanes, A::Error> {
                let mut lanes = Vec::new();
                while let Some(l) = seq.next_element::<usize>()? {
                    lanes.push(l);
                }
                Ok(RouteLanes::PerEdge(lanes))
            }
        }
        d.deserialize_any(Lanes)
    }
}

impl RoadSpec {
    /// True for a road whose length comes from its network (a loop or a route).
    pub fn is_network(&self) -> bool {
        matches!(self, RoadSpec::Loop { .. } | RoadSpec::Route { .. })
    }

    /// True for a closed road (a ring or a loop).
    pub fn is_closed(&self) -> bool {
        matches!(self, RoadSpec::Ring { .. } | RoadSpec::Loop { .. })
    }
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
    /// The user's linear agents on a graph: `W_i = η_i/(s ρ_i) · e^{−s τ_i}` (or a state space)
    /// from `u_i = Σ_j a_ij (y_j − y_i) + b_i (y_0 − y_i)` to the speed `y_i`.
    Linear {
        /// Interaction graph with its gains `a_ij`, in any form the delayed driver takes.
        graph: GraphSpec,
        /// One agent for every driver, or one per driver.
        agents: AgentsSpec,
        /// Optional reference: a leader at speed `y_0` seen by pinned agents (`b_i > 0`).
        #[serde(default)]
        leader: Option<DriverLeaderSpec>,
    },
}

/// The linear agents: one for every driver, or a list of one per driver.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AgentsSpec {
    /// The same agent for every driver.
    One(crate::agents::LinearAgentSpec),
    /// One agent per driver.
    List(Vec<crate::agents::LinearAgentSpec>),
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

/// Delay-buffer history before t = 0 (the law's own type, named in scenario files).
pub use crate::delayed_driver::HistorySpec;

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
    /// SUMO vehicle class (`vClass`) of the vehicles syncroad inserts, e.g. `"vip"` on a
    /// circuit whose lanes allow only that class; default `"passenger"`. The road's lanes are
    /// checked to admit it before SUMO starts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vclass: Option<String>,
    /// The user's own traffic: SUMO route files (vehicle types, routes, vehicles, flows) loaded
    /// beside syncroad's vehicles, which stay the controlled set; relative paths are resolved
    /// against the scenario file's folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub routes: Vec<PathBuf>,
    /// SUMO additional files (detectors, rerouters, traffic lights, vehicle types) loaded with
    /// the network; relative paths are resolved against the scenario file's folder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub additional: Vec<PathBuf>,
    /// A whole SUMO configuration (`.sumocfg`): its input section (`net-file`, `route-files`,
    /// `additional-files`, relative to the configuration's folder as SUMO resolves them) adds
    /// to `net`, `routes` and `additional`; its other options are listed as ignored, since the
    /// scenario sets the time, the step and the outputs. Relative to the scenario's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub config: Option<PathBuf>,
    /// The law drives these of the user's own vehicles (`{"vtype": …}`, `{"id": …}` or both)
    /// instead of vehicles syncroad inserts: the ones on the road when the run starts, in
    /// their order along it. Needs `routes` or `config`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controlled: Option<VehicleSelector>,
    /// Also write SUMO's own floating-car data of the run (`sumo/fcd.xml` in the run's folder,
    /// every step), which `syncroad replay` plays back in sumo-gui.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fcd: bool,
    /// Human traffic entering the network during the run (SUMO flows of its default vehicle
    /// type, routed by SUMO from `from` to `to`, leaving at `to`'s end).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inflows: Vec<InflowSpec>,
}

/// One inflow of human traffic (`sumo.inflows[k]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InflowSpec {
    /// The edge the vehicles enter on.
    pub from: String,
    /// The edge they leave at (its end).
    pub to: String,
    /// Vehicles per hour.
    pub vehs_per_hour: f64,
    /// `"regular"` (evenly spaced, the default) or `"poisson"` (exponential headways drawn
    /// from the scenario's seed).
    #[serde(default)]
    pub arrivals: Arrivals,
    /// The lane they depart on: an index (0 is the rightmost), or SUMO's rule `"best"` (the
    /// lanes that lead on along their route, the default), `"free"` (the emptiest lane) or
    /// `"random"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depart_lane: Option<DepartLane>,
    /// Their departure speed \[m/s\]; default: the most SUMO allows there (`"max"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depart_speed_mps: Option<f64>,
    /// When the inflow starts \[s\] (default 0).
    #[serde(default)]
    pub begin_s: f64,
    /// When it ends \[s\] (default: the horizon).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_s: Option<f64>,
    /// Vehicles among this inflow that a law of the registry drives instead of SUMO's model:
    /// a share of the inflow's vehicles, vehicles departing at given times, or both.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controlled: Option<InflowControl>,
}

/// The vehicles of an inflow a law drives (`sumo.inflows[k].controlled`): each one from the
/// step it enters to the step it leaves at the end of its route, with the registry law `law`
/// or the user's Python controller `python` stepped for it alone on whoever SUMO reports
/// ahead of it (one instance of the class per vehicle).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InflowControl {
    /// The law, as the registry names it (`follower-stopper-20`, `pi-saturation`, a law
    /// the running program registered); a law that needs a ring is refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<String>,
    /// The user's Python controller in place of `law`: `FILE.py:Class` (relative to the
    /// scenario's folder) or `package.module:Class`, as the scenario's `controller` names one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub python: Option<String>,
    /// Its parameters: added to those a law's name carries, or a Python class's keyword
    /// arguments.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<serde_json::Value>,
    /// The share of the inflow's vehicles the law drives, in \[0, 1\]: SUMO draws each
    /// vehicle's type with the scenario's seed (0: none, the humans-alone point of a sweep
    /// over it).
    #[serde(default)]
    pub share: f64,
    /// Departure times \[s\] of further vehicles the law drives, on the inflow's route.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub at_s: Vec<f64>,
}

/// The lane an inflow's vehicles depart on (`sumo.inflows[k].depart_lane`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "serde_json::Value", into = "serde_json::Value")]
pub enum DepartLane {
    /// This lane index.
    Index(usize),
    /// SUMO's `"best"`: the lanes that lead on along the route.
    Best,
    /// SUMO's `"free"`: the lane with the most free space.
    Free,
    /// SUMO's `"random"`: a lane drawn with the run's seed.
    Random,
}

impl DepartLane {
    /// SUMO's `departLane` value.
    pub fn sumo_value(self) -> String {
        match self {
            DepartLane::Index(l) => l.to_string(),
            DepartLane::Best => "best".into(),
            DepartLane::Free => "free".into(),
            DepartLane::Random => "random".into(),
        }
    }
}

impl TryFrom<serde_json::Value> for DepartLane {
    type Error = String;
    fn try_from(v: serde_json::Value) -> Result<Self, String> {
        match &v {
            serde_json::Value::Number(n) => n.as_u64().map(|l| DepartLane::Index(l as usize)),
            serde_json::Value::String(s) => match s.as_str() {
                "best" => Some(DepartLane::Best),
                "free" => Some(DepartLane::Free),
                "random" => Some(DepartLane::Random),
                _ => None,
            },
            _ => None,
        }
        .ok_or_else(|| {
            format!(
                "depart_lane = {v}: give a lane index (0 is the rightmost) or one of \"best\", \"free\", \"random\""
            )
        })
    }
}

impl From<DepartLane> for serde_json::Value {
    fn from(d: DepartLane) -> Self {
        match d {
            DepartLane::Index(l) => l.into(),
            other => other.sumo_value().into(),
        }
    }
}

/// How an inflow's vehicles arrive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Arrivals {
    /// Evenly spaced (SUMO's `vehsPerHour`).
    #[default]
    Regular,
    /// A Poisson process (SUMO's `period="exp(rate)"`), drawn from SUMO's seed.
    Poisson,
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
            vclass: None,
            routes: Vec::new(),
            additional: Vec::new(),
            config: None,
            controlled: None,
            inflows: Vec::new(),
            fcd: false,
        }
    }
}
