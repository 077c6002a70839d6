//! The record of one run: the one `metrics.json` schema every command writes
//! (published as `docs/metrics.schema.json`), and beside it [`schema`], the JSON Schema derived
//! from the type with each metric's title and unit. The plain facts a SUMO run reports, which
//! the outcome reads before any record exists, are [`crate::sumo_facts`].
//!
//! Stamps (`syncroad_version`, `platform`, `sumo_version`) say what produced the record;
//! everything else is a result. Every key is always present (`null` where it does not apply),
//! so tables and regression checks see one shape.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::congestion::CongestionMetrics;
use crate::exact::gaps::GapSummary;
use crate::margins::SafetyMargins;
use crate::metrics::SyncMetrics;
use crate::outcome::{Outcome, RunOutput};
use crate::registry::PROTOCOL;
use crate::scenario::{Backend, Scenario};
use crate::stop::StopReason;
use crate::string_measured::StringAmplification;
use crate::trajectory::Trajectory;

pub mod safe;
pub mod schema;

pub use crate::sumo_facts::{Controlled, Measured, Safety, SumoFacts};

/// Stamps: the keys that say what produced a record (`regress --strict` holds a baseline to
/// them).
pub const STAMPS: [&str; 3] = ["syncroad_version", "platform", "sumo_version"];

/// Keys every run of one comparison shares: the stamps, the scenario's hash and seed, and the
/// emission class; `compare.json` holds them once, at its top.
pub const SHARED_KEYS: [&str; 6] = [
    STAMPS[0],
    STAMPS[1],
    STAMPS[2],
    "scenario_hash",
    "seed",
    "emission_class",
];

/// Version of the record's schema (`docs/metrics.schema.json`).
pub const SCHEMA_VERSION: u32 = 1;

/// Traffic measured in SUMO, per distance and time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Traffic {
    /// Seconds measured after the warm-up.
    pub measured_s: f64,
    /// Flow at the induction loop \[veh/h\].
    #[schemars(title = "flow, loop")]
    pub flow_veh_per_h: Option<f64>,
    /// Loop passages.
    pub loop_passages: Option<usize>,
    /// Ring coordinate of the loop \[m\].
    pub loop_ring_m: Option<f64>,
    /// SUMO's road length \[m\].
    pub road_length_m: f64,
    /// `N v̄ / L` \[veh/h\] on a ring (cross-check of the loop).
    #[schemars(title = "flow, N·v̄/L")]
    pub flow_from_speed_veh_per_h: Option<f64>,
    /// Time loss after the warm-up \[s\].
    pub time_loss_s: f64,
    /// Time loss per vehicle \[s\].
    #[schemars(title = "time loss / veh")]
    pub time_loss_per_vehicle_s: f64,
    /// Fuel after the warm-up \[mg\].
    ///
    /// Null when the run did not read it: a sweep reads only the emission sums its columns show.
    pub fuel_mg: Option<f64>,
    /// Fuel over the whole run \[mg\].
    ///
    /// Null when the run did not read it: a sweep reads only the emission sums its columns show.
    pub fuel_total_mg: Option<f64>,
    /// CO2 after the warm-up \[mg\].
    ///
    /// Null when the run did not read it: a sweep reads only the emission sums its columns show.
    pub co2_mg: Option<f64>,
    /// Distance driven after the warm-up, from the recorded positions \[m\].
    pub distance_m: f64,
    /// Fuel per distance \[g/km\].
    ///
    /// Null when the run did not read it: a sweep reads only the emission sums its columns show.
    #[schemars(title = "fuel")]
    pub fuel_g_per_km: Option<f64>,
    /// CO2 per distance \[g/km\].
    ///
    /// Null when the run did not read it: a sweep reads only the emission sums its columns show.
    #[schemars(title = "CO2")]
    pub co2_g_per_km: Option<f64>,
    /// Hard-braking vehicle-steps.
    #[schemars(title = "hard braking")]
    pub hard_braking_steps: usize,
}

/// Distance driven by all vehicles after `warmup_s` \[m\].
pub fn distance_after(traj: &Trajectory, warmup_s: f64) -> f64 {
    let first = traj.time_s.partition_point(|&t| t < warmup_s - 1e-9);
    if traj.len() <= first + 1 {
        return 0.0;
    }
    let n = traj.n;
    let q = |k: usize| &traj.positions_m[k * n..(k + 1) * n];
    q(traj.len() - 1)
        .iter()
        .zip(q(first))
        .map(|(b, a)| b - a)
        .sum()
}

impl Traffic {
    fn new(
        m: &Measured,
        facts: &SumoFacts,
        sc: &Scenario,
        run: &RunOutput,
        outcome: &Outcome,
    ) -> Self {
        let measured_s = m.steps as f64 * sc.step_s();
        let distance_m = distance_after(&run.trajectory, outcome.warmup_s);
        let per_km = |mg: f64| {
            if distance_m > 0.0 {
                mg / 1000.0 / (distance_m / 1000.0)
            } else {
                f64::NAN
            }
        };
        Self {
            measured_s,
            flow_veh_per_h: m.loop_passages.map(|p| p as f64 / measured_s * 3600.0),
            loop_passages: m.loop_passages,
            loop_ring_m: facts.loop_ring_m,
            road_length_m: facts.road_length_m,
            flow_from_speed_veh_per_h: match (run.ring_length_m, &outcome.congestion) {
                (Some(l), Ok(c)) => Some(sc.vehicles() as f64 * c.mean_speed_mps / l * 3600.0),
                _ => None,
            },
            time_loss_s: m.time_loss_s,
            time_loss_per_vehicle_s: m.time_loss_s / sc.vehicles() as f64,
            fuel_mg: m.fuel_mg,
            fuel_total_mg: m.fuel_total_mg,
            co2_mg: m.co2_mg,
            distance_m,
            fuel_g_per_km: m.fuel_mg.map(per_km),
            co2_g_per_km: m.co2_mg.map(per_km),
            hard_braking_steps: m.hard_braking_steps,
        }
    }
}

/// How SUMO ran, beyond the counters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct BackendFacts {
    /// SUMO's road length \[m\].
    pub road_length_m: f64,
    /// Gap scale applied on a ring.
    pub gap_scale: f64,
    /// `ballistic` or `euler`.
    pub step_method: String,
    /// Largest |realised − commanded| speed \[m/s\].
    pub max_override_mps: f64,
    /// Largest odometer deviation \[m\].
    pub odometer_deviation_max_m: f64,
}

/// The metrics document of one run (`metrics.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RunRecord {
    /// Stamp: syncroad's version.
    #[serde(default)]
    pub syncroad_version: String,
    /// Stamp: `arch-os`.
    #[serde(default)]
    pub platform: String,
    /// Stamp: SUMO's version (`null` for native runs).
    pub sumo_version: Option<String>,
    /// Scenario name.
    pub scenario: String,
    /// Hash of the scenario as written.
    #[serde(default)]
    pub scenario_hash: String,
    /// Seed.
    #[serde(default)]
    pub seed: u64,
    /// `native` or `sumo`.
    pub backend: Backend,
    /// The run's name (`law`, `krauss-0.9`, `mixed-2`, ...).
    pub run: String,
    /// Controlled vehicles N.
    pub vehicles: usize,
    /// Step \[s\].
    pub step_s: f64,
    /// Horizon \[s\].
    pub horizon_s: f64,
    /// Per vehicle: `law` or the SUMO driver.
    pub drivers: Vec<String>,
    /// Vehicles the law drives.
    pub law_controlled_vehicles: usize,
    /// Reached the horizon.
    pub complete: bool,
    /// Why not.
    pub error: Option<String>,
    /// Why the run stopped.
    pub stop: StopReason,
    /// Certified by the paper's sufficient conditions: `null` when they do not speak of this
    /// run (some vehicle is not driven by the law — a human or a damper is outside the
    /// theorem's graph —, the graph changed in SUMO, `safety.topology_changes` > 0, while the
    /// theorem is for a fixed graph, or the run produced no sample).
    pub certified: Option<bool>,
    /// Warm-up excluded from congestion and SUMO measures \[s\].
    pub warmup_s: f64,
    /// Synchronization metrics and verdict.
    pub sync: SyncMetrics,
    /// Congestion metrics (`null` when the warm-up leaves no sample).
    pub congestion: Option<CongestionMetrics>,
    /// Emission class of SUMO's vehicles (`null` for native runs).
    pub emission_class: Option<String>,
    /// Emission sampling stride (`null` unless measured).
    pub emission_every: Option<usize>,
    /// SUMO-measured traffic (`null` unless measured).
    pub sumo: Option<Traffic>,
    /// SUMO's safety counters (`null` for native runs).
    pub safety: Option<Safety>,
    /// How SUMO ran; `null` for native runs and for SUMO runs in which SUMO never started.
    pub backend_facts: Option<BackendFacts>,
    /// Time headway, gaps, SUMO's surrogate safety measures and the safe-speed label; present
    /// only when the run measured SSM (records of runs that did not keep their earlier shape).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub safety_margins: Option<SafetyMargins>,
    /// Minimum gap and time below a safe headway, from the trajectory (every run with gaps).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap_safety: Option<crate::margins::GapSafety>,
    /// String amplification measured behind a leader (present only for runs with a leader).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub string_amplification: Option<StringAmplification>,
    /// The gap certificate of the scenario's linear model (`exact::gaps`), present for runs
    /// of the scenario's law on every vehicle that it covers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap_certificate: Option<GapSummary>,
    /// Every vehicle in SUMO's network, syncroad's and the user's own traffic (SUMO's summary
    /// output after the warm-up), when other traffic shared the road; the other metrics are of
    /// syncroad's vehicles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub all_vehicles: Option<crate::sumo_facts::AllVehicles>,
    /// The user's own SUMO vehicles the law drove (`sumo.controlled`); present only for such
    /// runs. Their start is the user's files', not the scenario's `initial`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controlled: Option<crate::sumo_facts::Controlled>,
    /// The inflows' vehicles a law drove from their entry to their exit
    /// (`sumo.inflows[k].controlled`); present only for such runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guests: Option<crate::sumo_facts::Guests>,
    /// The user's own controller that drove in place of the model's law (`controller` in the
    /// scenario); present only for such runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<ControllerRecord>,
    /// Whether the run was safe: no collision, overlap, teleport, emergency braking or
    /// reversing vehicle, on SUMO's counters, the native simulator's checks and the recorded
    /// gaps (`record::safe`); `null` when nothing measured it (SUMO's counters never
    /// arrived). An unsafe run is marked so in every table.
    #[serde(default)]
    #[schemars(title = "safe")]
    pub safe: Option<bool>,
    /// What made the run unsafe, one line each (empty when it was safe).
    #[serde(default)]
    #[schemars(title = "unsafe because")]
    pub unsafe_because: Vec<String>,
    /// The safety layer under the law (`crate::safety`): `off`, SUMO's checks (`sumo`) or
    /// syncroad's filter, with what the filter did; `null` when no law drove.
    #[serde(default)]
    pub safety_layer: Option<crate::safety::SafetyLayer>,
}

/// The user's controller of a run, as the record names it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ControllerRecord {
    /// Its driver label in `drivers` (`python:Class`, `rust:name`).
    pub label: String,
    /// As written in the scenario (`FILE.py:Class` or `module:Class`); `null` for a Rust law.
    pub python: Option<String>,
    /// The registered name of a Rust law; `null` for a Python controller.
    #[serde(default)]
    pub rust: Option<String>,
    /// The source file read (`null` for a module).
    pub source_file: Option<String>,
    /// FNV-1a (64 bits, hex) of the source file and pickled state as read (`null` for a
    /// module without a state: the interpreter found its source).
    pub source_hash: Option<String>,
    /// The keyword arguments it was built with.
    pub params: serde_json::Value,
}

impl ControllerRecord {
    fn of(law: &crate::user_law::UserLaw) -> Self {
        use crate::user_law::{PythonSource, UserLaw};
        let (python, rust, source_file) = match law {
            UserLaw::Python(p) => (
                Some(p.python.clone()),
                None,
                match &p.source {
                    PythonSource::File { path } => Some(path.display().to_string()),
                    PythonSource::Module { .. } => None,
                },
            ),
            UserLaw::Rust(r) => (None, Some(r.name.clone()), None),
        };
        Self {
            label: law.label(),
            python,
            rust,
            source_file,
            source_hash: law.source_hash().map(str::to_string),
            params: law.params().clone(),
        }
    }
}

impl RunRecord {
    /// A complete run with nothing to judge: a road without vehicles of its own (only
    /// inflows, whose vehicles come and go). Its verdict is "inconclusive" (`NO_FIXED_SET`
    /// says why), yet the run did all it was asked, so a command exits 0 on it.
    pub fn checks_nothing(&self) -> bool {
        self.vehicles == 0 && self.complete
    }

    /// The record of a run named `run`.
    pub fn new(sc: &Scenario, run_name: &str, run: &RunOutput, outcome: &Outcome) -> Self {
        let facts = run.sumo.as_ref();
        let drivers = facts
            .map(|f| f.drivers.clone())
            .or_else(|| run.drivers.clone())
            .filter(|d| !d.is_empty())
            .unwrap_or_else(|| vec![PROTOCOL.to_string(); sc.vehicles()]);
        let law_controlled = drivers.iter().filter(|d| *d == PROTOCOL).count();
        // The user's controller drives where the law would: its label replaces `protocol`.
        let drivers = match sc.controller() {
            None => drivers,
            Some(c) => {
                let label = c.label();
                drivers
                    .into_iter()
                    .map(|d| if d == PROTOCOL { label.clone() } else { d })
                    .collect()
            }
        };
        // The theory is for the scenario's fixed graph: a run whose graph changed in SUMO is
        // outside it.
        let fixed_graph = !facts
            .and_then(|f| f.safety.as_ref())
            .is_some_and(Safety::graph_changed);
        // The theory is of the scenario's model law: a user's controller is outside it.
        let all_law = sc.mixed().is_none()
            && sc.controller().is_none()
            && law_controlled == sc.vehicles()
            && fixed_graph;
        let unsafe_because = safe::unsafe_reasons(run, facts);
        Self {
            syncroad_version: env!("CARGO_PKG_VERSION").to_string(),
            platform: format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS),
            sumo_version: facts.and_then(|f| f.sumo_version.clone()),
            scenario: sc.name().to_string(),
            scenario_hash: sc.hash_hex().to_string(),
            seed: sc.seed(),
            backend: if facts.is_some() {
                Backend::Sumo
            } else {
                Backend::Native
            },
            run: run_name.to_string(),
            vehicles: sc.vehicles(),
            step_s: sc.step_s(),
            horizon_s: sc.horizon_s(),
            law_controlled_vehicles: law_controlled,
            drivers,
            complete: run.stop.is_complete(),
            error: run.stop.message(),
            stop: run.stop.recorded(),
            certified: (all_law && !run.trajectory.is_empty() && sc.vehicles() > 0)
                .then_some(outcome.theory.certified),
            warmup_s: outcome.warmup_s,
            sync: outcome.sync.clone(),
            congestion: outcome.congestion.as_ref().ok().cloned(),
            emission_class: facts.map(|f| f.emission_class.clone()),
            emission_every: facts.and_then(|f| f.emission_every),
            sumo: facts.and_then(|f| {
                f.measured
                    .as_ref()
                    .map(|m| Traffic::new(m, f, sc, run, outcome))
            }),
            safety: facts.and_then(|f| f.safety.clone()),
            // What SUMO measured (its lane lengths, overrides, odometers): absent when SUMO
            // never started, rather than zeros nobody measured.
            backend_facts: facts
                .filter(|f| f.sumo_version.is_some())
                .map(|f| BackendFacts {
                    road_length_m: f.road_length_m,
                    gap_scale: f.gap_scale,
                    step_method: f.step_method.clone(),
                    max_override_mps: f.max_override_mps,
                    odometer_deviation_max_m: f.odometer_deviation_max_m,
                }),
            safety_margins: facts
                .and_then(|f| SafetyMargins::of(&run.trajectory, outcome.warmup_s, f)),
            gap_safety: crate::margins::GapSafety::of(&run.trajectory, outcome.warmup_s),
            all_vehicles: facts.and_then(|f| f.all_vehicles.clone()),
            controlled: facts.and_then(|f| f.controlled.clone()),
            guests: facts.and_then(|f| f.guests.clone()),
            controller: sc.controller().map(ControllerRecord::of),
            safety_layer: run.safety_layer,
            safe: unsafe_because.as_ref().map(Vec::is_empty),
            unsafe_because: unsafe_because.unwrap_or_default(),
            string_amplification: crate::string_measured::measured(&run.trajectory),
            // The certificate is of the scenario's own gaps (none for a run without a sample,
            // like `certified`): a SUMO run that rescaled them by
            // more than 1 % to fit its network (a ring length that is not the net's) drove
            // other gaps, and gets none; so does a run of the user's own vehicles, and one that
            // shares the road with other traffic, the user's files or inflows (it can change
            // who follows whom).
            gap_certificate: (all_law
                && (facts.is_none() || !sc.sumo().other_traffic())
                && !run.trajectory.is_empty()
                && outcome.gap_certificate
                && facts.is_none_or(|f| (f.gap_scale - 1.0).abs() <= 0.01)
                // The user's own vehicles started from their own gaps.
                && facts.is_none_or(|f| f.controlled.is_none()))
            .then(|| crate::exact::gaps::gap_certificate(sc).ok().flatten())
            .flatten()
            .map(|c| c.summary()),
        }
    }

    /// The record as JSON.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).expect("a run record serializes")
    }
}
