//! What a SUMO run reports beside its trajectory: counters, SUMO-side measurements and how
//! SUMO ran. Plain data, filled by the SUMO backend; the maths never sees SUMO.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Counters of a SUMO run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Safety {
    /// Steps with at least one collision.
    #[schemars(title = "collision steps")]
    pub collision_steps: usize,
    /// Sum over steps of colliding vehicles.
    pub colliding_vehicles: usize,
    /// Teleports started.
    #[schemars(title = "teleports")]
    pub teleports: usize,
    /// SUMO's "performs emergency braking" warnings in its log.
    #[schemars(title = "emergency braking warn.")]
    pub emergency_braking_warnings: usize,
    /// Of those, the warnings within the first [`START_TRANSIENT_S`] of the run (SUMO's
    /// reaction time τ): a driver's answer to the start every compared driver shares (the
    /// scenario's gaps and speeds at t = 0), before its own driving could have caused them.
    /// Reported apart and left out of `safe`; collisions and teleports count from the start.
    #[serde(default)]
    #[schemars(title = "emergency braking at the start (t ≤ 1 s)")]
    pub start_emergency_braking_warnings: usize,
    /// Law commands SUMO did not realise within the override tolerance.
    #[schemars(title = "overridden commands")]
    pub overridden_commands: usize,
    /// Negative commands sent as 0 (SUMO reads a negative speed as "release control").
    pub negative_commands_clamped: usize,
    /// How often the vehicle SUMO sees ahead of one of syncroad's vehicles on its lane changed
    /// from one step to the next while other traffic shared the road (`sumo.routes` or
    /// `sumo.additional`); the law took its graph from SUMO each step
    /// (`syncroad_control::sensed`). `None`: no other traffic, the graph cannot change and the
    /// law ran the scenario's.
    #[serde(default)]
    #[schemars(title = "topology changes")]
    pub topology_changes: Option<usize>,
}

/// The start transient \[s\]: emergency braking in SUMO up to this time answers the start
/// state, not the driver's own driving (SUMO's default reaction time τ, the safety filter's
/// [`crate::safety::REACTION_S`]).
pub const START_TRANSIENT_S: f64 = crate::safety::REACTION_S;

impl Safety {
    /// Emergency braking after the start transient: the driver's own.
    pub fn own_emergency_braking_warnings(&self) -> usize {
        self.emergency_braking_warnings
            .saturating_sub(self.start_emergency_braking_warnings)
    }

    /// The vehicle ahead of one of syncroad's vehicles changed in SUMO at least once: the run
    /// is outside the theory of the scenario's fixed graph.
    pub fn graph_changed(&self) -> bool {
        self.topology_changes.is_some_and(|c| c > 0)
    }
}

/// Which emission sums a run reads from SUMO's emission model. Each read runs the model (HBEFA
/// by default) for every vehicle, every `emission_every` steps: on a small ring, reading all
/// three costs a quarter of SUMO's own step, so a run that shows none of them (a sweep's
/// columns) reads none. Unread sums are `None` in [`Measured`] and `null` in the record.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Emissions {
    /// Fuel after the warm-up ([`Measured::fuel_mg`], the record's `fuel_g_per_km`).
    pub fuel: bool,
    /// Fuel over the whole run, warm-up included ([`Measured::fuel_total_mg`]).
    pub fuel_total: bool,
    /// CO2 after the warm-up ([`Measured::co2_mg`], the record's `co2_g_per_km`).
    pub co2: bool,
}

impl Emissions {
    /// Every sum (a run's or a comparison's record).
    pub const ALL: Self = Self {
        fuel: true,
        fuel_total: true,
        co2: true,
    };
    /// No sum: the emission model never runs.
    pub const NONE: Self = Self {
        fuel: false,
        fuel_total: false,
        co2: false,
    };

    /// The sums a record's columns `paths` (`sumo.fuel_g_per_km`, …) show.
    pub fn shown_by<'a>(paths: impl IntoIterator<Item = &'a str>) -> Self {
        let mut e = Self::NONE;
        for p in paths {
            match p.strip_prefix("sumo.") {
                Some("fuel_mg" | "fuel_g_per_km") => e.fuel = true,
                Some("fuel_total_mg") => e.fuel_total = true,
                Some("co2_mg" | "co2_g_per_km") => e.co2 = true,
                _ => {}
            }
        }
        e
    }
}

impl Default for Emissions {
    fn default() -> Self {
        Self::ALL
    }
}

/// What SUMO measured after the warm-up.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Measured {
    /// Steps measured (after the warm-up).
    pub steps: usize,
    /// Vehicles entering the induction loop `loop0`; `None` without a loop.
    pub loop_passages: Option<usize>,
    /// Σ over vehicles of `vehicle.getTimeLoss` at the end minus at the end of the warm-up \[s\].
    pub time_loss_s: f64,
    /// Σ over vehicles and sampled steps of `vehicle.getFuelConsumption` × held time \[mg\];
    /// `None` when not read ([`Emissions::fuel`]).
    pub fuel_mg: Option<f64>,
    /// The same for `vehicle.getCO2Emission` \[mg\]; `None` when not read.
    pub co2_mg: Option<f64>,
    /// Fuel over the whole run, warm-up included \[mg\] (cross-check with trip info); `None`
    /// when not read.
    pub fuel_total_mg: Option<f64>,
    /// Vehicle-steps after the warm-up whose deceleration exceeded the vehicle type's `decel`.
    pub hard_braking_steps: usize,
}

/// Facts only a SUMO run knows, filled by the SUMO backend.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SumoFacts {
    /// SUMO's version, once it started.
    pub sumo_version: Option<String>,
    /// The libsumo module that ran (for the summary; not part of the record, it names a path).
    pub libsumo: Option<String>,
    /// SUMO's road length \[m\] (normal plus internal lanes).
    pub road_length_m: f64,
    /// Gap scale applied to fit the vehicles on SUMO's ring.
    pub gap_scale: f64,
    /// `ballistic` (trapezoidal, as the native simulator) or `euler`.
    pub step_method: String,
    /// Per scenario vehicle: `law` or the SUMO driver that drives it.
    pub drivers: Vec<String>,
    /// Counters; `None` when the worker never reported its end.
    pub safety: Option<Safety>,
    /// Largest |realised − commanded| speed \[m/s\].
    pub max_override_mps: f64,
    /// Largest odometer deviation from the integrated positions \[m\].
    pub odometer_deviation_max_m: f64,
    /// SUMO-side measurements, when asked for.
    pub measured: Option<Measured>,
    /// Ring coordinate of the induction loop \[m\].
    pub loop_ring_m: Option<f64>,
    /// Emission class set on every vehicle type.
    pub emission_class: String,
    /// Fuel and CO2 read every this many steps, when measured.
    pub emission_every: Option<usize>,
    /// Speed mode of the law-commanded vehicles (32: every check off; 1: SUMO's safe speed
    /// kept), when some vehicle takes commands.
    #[serde(default)]
    pub law_speed_mode: Option<i32>,
    /// SUMO's surrogate safety measures, when measured.
    #[serde(default)]
    pub ssm: Option<SsmSummary>,
    /// Every vehicle in the network, syncroad's and the user's own, from SUMO's summary
    /// output; present when other traffic shares the road.
    #[serde(default)]
    pub all_vehicles: Option<AllVehicles>,
    /// The user's own vehicles the law drove (`sumo.controlled`); `None` when syncroad
    /// inserted its own.
    #[serde(default)]
    pub controlled: Option<Controlled>,
    /// The inflows' vehicles a law drove (`sumo.inflows[k].controlled`); `None` when no
    /// inflow has any.
    #[serde(default)]
    pub guests: Option<Guests>,
}

/// The vehicles of the inflows that a law drove (`sumo.inflows[k].controlled`), each one
/// alone, behind whoever SUMO reported ahead of it, from the step it entered to the step it
/// left at the end of its route. Entries and exits change the set of vehicles the law drives:
/// they are counted here.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Guests {
    /// The law of each inflow that has controlled vehicles: `inflow0: follower-stopper-20`.
    pub laws: Vec<String>,
    /// Vehicles that entered the network (the law drove them from their first step on).
    pub entered: usize,
    /// Vehicles that left it at the end of their route.
    pub left: usize,
    /// Vehicles still on the road at the end.
    pub present_at_end: usize,
    /// Most vehicles driven at once.
    pub present_max: usize,
    /// Mean travel time of those that left, from entering to leaving \[s\]; `null` when none
    /// left.
    #[schemars(title = "mean travel time (controlled)")]
    pub mean_travel_time_s: Option<f64>,
    /// Mean speed over the vehicles and the steps they were driven \[m/s\]; `null` when none
    /// was.
    #[schemars(title = "mean speed (controlled)")]
    pub mean_speed_mps: Option<f64>,
    /// Commands sent.
    pub commands: usize,
    /// Commands above the lane's speed limit, sent as the limit.
    pub speed_limited_commands: usize,
    /// Commands SUMO did not realise within the tolerance (its safe speed, right of way or a
    /// red light held the vehicle back, under the safety layer).
    pub overridden_commands: usize,
    /// Largest |realised − commanded| speed \[m/s\].
    pub max_override_mps: f64,
}

/// The user's own vehicles the law drove (`sumo.controlled`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Controlled {
    /// Their ids in the law's order, the trajectory's vehicle order: vehicle 0 in front (on a
    /// loop the first from the start of its first edge on), each following the one before.
    pub vehicles: Vec<String>,
    /// Vehicles the selection chooses that came onto the road after the start: the law runs
    /// on the vehicles of the start, so SUMO drove these by their own vehicle type; `null`
    /// when the worker never reported its end.
    pub later: Option<usize>,
}

/// Every vehicle in SUMO's network after the warm-up, syncroad's and the user's own traffic
/// (`sumo.routes`, `sumo.additional`, `sumo.config`), from SUMO's summary output
/// (`--summary-output`, one `<step>` per sample at the trajectory's stride, speeds to SUMO's
/// output precision of 0.01 m/s; means are over the samples).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct AllVehicles {
    /// Time measured, from the first sample after the warm-up to the last \[s\].
    pub measured_s: f64,
    /// Mean number of vehicles running.
    #[schemars(title = "vehicles (all) mean")]
    pub vehicles_mean: f64,
    /// Largest number of vehicles running.
    #[schemars(title = "vehicles (all) max")]
    pub vehicles_max: usize,
    /// Mean speed over vehicles and time, Σ running · meanSpeed / Σ running \[m/s\]; `null`
    /// when nobody ran.
    #[schemars(title = "mean speed (all)")]
    pub mean_speed_mps: Option<f64>,
    /// Mean number of halting vehicles (SUMO: speed below 0.1 m/s).
    #[schemars(title = "halting (all) mean")]
    pub halting_mean: f64,
    /// Vehicles that reached the end of their route.
    pub arrived: usize,
    /// Arrivals per hour over the measured time: the network's throughput.
    #[serde(default)]
    #[schemars(title = "throughput (all)")]
    pub throughput_per_hour: f64,
    /// Mean travel time of the vehicles that arrived after the warm-up \[s\] (from entering
    /// the network to leaving it); `null` when none arrived.
    #[serde(default)]
    #[schemars(title = "mean travel time (all)")]
    pub mean_travel_time_s: Option<f64>,
    /// Vehicles SUMO inserted into the network.
    #[serde(default)]
    pub inserted: usize,
    /// Vehicles of the demand (route files, inflows) still waiting to enter at the last
    /// sample: SUMO delays an insertion while its entry is full, without a word, so a positive
    /// count says the network took less than the demand asked.
    #[serde(default)]
    #[schemars(title = "waiting to enter at the end")]
    pub waiting_at_end: usize,
    /// Collisions SUMO counted among all vehicles.
    #[schemars(title = "collisions (all)")]
    pub collisions: usize,
}

/// What SUMO's SSM device logged after the warm-up: conflicts (one `<conflict>` record per
/// encounter of an ego vehicle with a foe; every vehicle carries a device, so one encounter can
/// be logged from both sides) whose time to collision fell below the TTC threshold or whose
/// deceleration rate to avoid a crash rose above the DRAC threshold.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SsmSummary {
    /// TTC threshold of the device \[s\] (SUMO's default 3 s).
    pub ttc_threshold_s: f64,
    /// DRAC threshold of the device \[m/s²\] (SUMO's default 3 m/s²).
    pub drac_threshold_mps2: f64,
    /// Conflicts with a TTC below the threshold after the warm-up.
    #[schemars(title = "TTC < 3 s conflicts")]
    pub ttc_conflicts: usize,
    /// Smallest TTC among them \[s\] (`null`: none).
    #[schemars(title = "min TTC")]
    pub ttc_min_s: Option<f64>,
    /// Conflicts with a DRAC above the threshold after the warm-up.
    #[schemars(title = "DRAC > 3 m/s² conflicts")]
    pub drac_conflicts: usize,
    /// Largest DRAC among them \[m/s²\] (`null`: none).
    #[schemars(title = "max DRAC")]
    pub drac_max_mps2: Option<f64>,
}
