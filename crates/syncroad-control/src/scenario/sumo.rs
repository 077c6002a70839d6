//! The validated `sumo` section: network file, vehicle type and wall-clock limit, checked once
//! when the scenario is validated. The SUMO backend reads only this typed value, never the raw
//! [`SumoSpec`].

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::{
    invalid, ConfigInputs, InflowControl, InflowSpec, RoadReader, ScenarioError, SumoSpec,
    VehicleSelector,
};
use crate::registry::NamedLaw;
use crate::user_law::UserLaw;

/// The input section of `sumo.config`, read by `reader` (the SUMO crate's: the maths reads no
/// XML).
fn read_config(
    config: &Path,
    reader: Option<&dyn RoadReader>,
) -> Result<ConfigInputs, ScenarioError> {
    let Some(reader) = reader else {
        return Err(invalid(
            "sumo.config",
            config.display(),
            "a SUMO configuration is read by the SUMO backend's reader: load the scenario with a network reader (the syncroad command line does)",
        ));
    };
    reader
        .read_config(config)
        .map_err(|e| ScenarioError::Road(e.to_string()))
}

/// The longest wall-clock limit of a run [s] (about 31 years; past it a limit means none): for
/// `sumo.timeout_s` and every `--timeout-s`.
pub const MAX_TIMEOUT_S: f64 = 1e9;

/// SUMO's vehicle classes, as its own network reader lists them
/// (`sumolib.net.lane.SUMO_VEHICLE_CLASSES` without the deprecated names); the first is the
/// default.
pub const VEHICLE_CLASSES: [&str; 32] = [
    "passenger",
    "private",
    "emergency",
    "authority",
    "army",
    "vip",
    "pedestrian",
    "hov",
    "taxi",
    "bus",
    "coach",
    "delivery",
    "truck",
    "trailer",
    "motorcycle",
    "moped",
    "bicycle",
    "evehicle",
    "tram",
    "rail_urban",
    "rail",
    "rail_electric",
    "ship",
    "container",
    "cable_car",
    "subway",
    "aircraft",
    "wheelchair",
    "scooter",
    "drone",
    "custom1",
    "custom2",
];

/// The vehicle class of the vehicles syncroad inserts (`sumo.vclass`, SUMO's `vClass`): lane
/// permissions are checked for it before SUMO starts, and their vType carries it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VehicleClass(u8);

impl VehicleClass {
    /// SUMO's default class.
    pub const PASSENGER: VehicleClass = VehicleClass(0);

    /// The class named `name`, if SUMO has it.
    pub fn parse(name: &str) -> Option<Self> {
        VEHICLE_CLASSES
            .iter()
            .position(|&c| c == name)
            .map(|i| VehicleClass(i as u8))
    }

    /// Its name in SUMO's files.
    pub fn name(self) -> &'static str {
        VEHICLE_CLASSES[usize::from(self.0)]
    }
}

impl std::fmt::Display for VehicleClass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for VehicleClass {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for VehicleClass {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        VehicleClass::parse(&name).ok_or_else(|| {
            serde::de::Error::custom(format!("{name:?} is not one of SUMO's vehicle classes"))
        })
    }
}

/// SUMO vehicle-type values shared by every vehicle of a run (lengths may differ per vehicle).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SumoVehicleType {
    /// minGap \[m\]: the car-following model's standstill gap.
    pub min_gap_m: f64,
    /// accel [m/s²].
    pub accel_mps2: f64,
    /// decel [m/s²].
    pub decel_mps2: f64,
    /// emergencyDecel [m/s²].
    pub emergency_decel_mps2: f64,
    /// maxSpeed [m/s].
    pub max_speed_mps: f64,
    /// vClass.
    #[serde(default)]
    pub vclass: VehicleClass,
}

/// The `sumo` section of a validated scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct SumoSettings {
    net: Option<PathBuf>,
    routes: Vec<PathBuf>,
    additional: Vec<PathBuf>,
    vehicle_type: SumoVehicleType,
    timeout: Duration,
    config: Option<PathBuf>,
    config_ignored: Vec<String>,
    controlled: Option<VehicleSelector>,
    fcd: bool,
    inflows: Vec<InflowSpec>,
    /// Who drives each inflow's controlled vehicles, resolved (`None`: the inflow has none).
    inflow_drivers: Vec<Option<UserLaw>>,
}

impl SumoSettings {
    /// Who drives the controlled vehicles of inflow `k` (`sumo.inflows[k].controlled`): a
    /// registry law or the user's Python class, resolved and checked; `None` when it has none.
    pub fn inflow_driver(&self, k: usize) -> Option<&UserLaw> {
        self.inflow_drivers.get(k).and_then(Option::as_ref)
    }

    /// The source hashes of the Python classes that drive inflows' vehicles.
    pub(super) fn inflow_source_hashes(&self) -> impl Iterator<Item = &str> {
        self.inflow_drivers
            .iter()
            .flatten()
            .filter_map(UserLaw::source_hash)
    }

    /// The network file (`sumo.net`), relative paths resolved against the scenario's folder;
    /// `None` when the scenario names none. Whether the file exists is checked by the SUMO
    /// backend before it starts (a native run needs no network).
    pub fn net(&self) -> Option<&Path> {
        self.net.as_deref()
    }

    /// The user's own route files (`sumo.routes`), resolved like [`SumoSettings::net`]; the
    /// SUMO backend checks that they exist before it starts.
    pub fn routes(&self) -> &[PathBuf] {
        &self.routes
    }

    /// The user's additional files (`sumo.additional`), resolved like [`SumoSettings::net`].
    pub fn additional(&self) -> &[PathBuf] {
        &self.additional
    }

    /// The user's own traffic shares the road (route or additional files, of `sumo.config`
    /// too): the law's graph in SUMO is the road's, and the run measures every vehicle.
    pub fn other_traffic(&self) -> bool {
        !self.routes.is_empty() || !self.additional.is_empty() || !self.inflows.is_empty()
    }

    /// The field that brings other traffic onto the road and its value as a message shows it
    /// (`sumo.routes` and its files, `sumo.additional` and its files, or `sumo.inflows` and
    /// their edges, the first given); `None` without other traffic.
    pub fn other_traffic_source(&self) -> Option<(&'static str, String)> {
        let show = |files: &[PathBuf]| {
            files
                .iter()
                .map(|f| f.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        if !self.routes.is_empty() {
            Some(("sumo.routes", show(&self.routes)))
        } else if !self.additional.is_empty() {
            Some(("sumo.additional", show(&self.additional)))
        } else if !self.inflows.is_empty() {
            let edges: Vec<String> = self
                .inflows
                .iter()
                .map(|f| format!("{} → {}", f.from, f.to))
                .collect();
            Some(("sumo.inflows", edges.join(", ")))
        } else {
            None
        }
    }

    /// The inflows of human traffic (`sumo.inflows`), their numbers checked; their edges are
    /// checked on the network by the SUMO backend before it starts.
    pub fn inflows(&self) -> &[InflowSpec] {
        &self.inflows
    }

    /// The vehicle type every SUMO vehicle shares.
    pub fn vehicle_type(&self) -> &SumoVehicleType {
        &self.vehicle_type
    }

    /// Wall-clock limit of one SUMO run (`sumo.timeout_s`).
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// The SUMO configuration file (`sumo.config`) whose input section was merged into
    /// [`SumoSettings::net`], [`SumoSettings::routes`] and [`SumoSettings::additional`].
    pub fn config(&self) -> Option<&Path> {
        self.config.as_deref()
    }

    /// The user's own vehicles the law drives (`sumo.controlled`), instead of vehicles
    /// syncroad inserts; `None`: syncroad inserts the scenario's vehicles.
    pub fn controlled(&self) -> Option<&VehicleSelector> {
        self.controlled.as_ref()
    }

    /// SUMO's floating-car data of the run is written for replay (`sumo.fcd`).
    pub fn fcd(&self) -> bool {
        self.fcd
    }

    /// The configuration's other options (`name = value`), which SUMO is not given.
    pub fn config_ignored(&self) -> &[String] {
        &self.config_ignored
    }
}

impl SumoSpec {
    /// The vehicle type's numbers, the time limit and the vehicle class, each checked.
    fn vehicle_class(&self) -> Result<VehicleClass, ScenarioError> {
        for (name, x) in [
            ("length_m", self.length_m),
            ("accel_mps2", self.accel_mps2),
            ("decel_mps2", self.decel_mps2),
            ("emergency_decel_mps2", self.emergency_decel_mps2),
            ("max_speed_mps", self.max_speed_mps),
            ("timeout_s", self.timeout_s),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(invalid(
                    format!("sumo.{name}"),
                    x,
                    "must be a finite number > 0",
                ));
            }
        }
        if !(self.min_gap_m.is_finite() && self.min_gap_m >= 0.0) {
            return Err(invalid(
                "sumo.min_gap_m",
                self.min_gap_m,
                "must be a finite number ≥ 0",
            ));
        }
        if self.timeout_s > MAX_TIMEOUT_S {
            return Err(invalid(
                "sumo.timeout_s",
                self.timeout_s,
                format!("must be at most {MAX_TIMEOUT_S:e} s (about 31 years), like --timeout-s"),
            ));
        }
        Ok(match &self.vclass {
            None => VehicleClass::PASSENGER,
            Some(name) => VehicleClass::parse(name).ok_or_else(|| {
                invalid(
                    "sumo.vclass",
                    format!("{name:?}"),
                    format!(
                        "not one of SUMO's vehicle classes: {}",
                        VEHICLE_CLASSES.join(", ")
                    ),
                )
            })?,
        })
    }

    /// Checks every number of the section; `base_dir` resolves a relative `net`; `reader`
    /// reads a `config`.
    pub(super) fn validate(
        &self,
        base_dir: &Path,
        reader: Option<&dyn RoadReader>,
    ) -> Result<SumoSettings, ScenarioError> {
        let vclass = self.vehicle_class()?;
        let timeout = Duration::from_secs_f64(self.timeout_s);
        let resolve = |p: &PathBuf| {
            if p.is_absolute() {
                p.clone()
            } else {
                base_dir.join(p)
            }
        };
        let mut net = self.net.as_ref().map(resolve);
        let mut routes: Vec<PathBuf> = Vec::new();
        let mut additional: Vec<PathBuf> = Vec::new();
        let config = self.config.as_ref().map(resolve);
        let mut config_ignored = Vec::new();
        if let Some(c) = &config {
            let inputs = read_config(c, reader)?;
            match (&net, inputs.net) {
                (Some(n), Some(cn)) => {
                    return Err(invalid(
                        "sumo.net",
                        n.display(),
                        format!(
                            "sumo.config {} names a network too (net-file {}); give the network once, in either",
                            c.display(),
                            cn.display()
                        ),
                    ))
                }
                (None, cn) => net = cn,
                _ => {}
            }
            // The configuration's files first, as if SUMO had read it before the command line.
            routes = inputs.routes;
            additional = inputs.additional;
            config_ignored = inputs.ignored;
        }
        routes.extend(self.routes.iter().map(resolve));
        additional.extend(self.additional.iter().map(resolve));
        if let Some(c) = &self.controlled {
            c.check()?;
            if routes.is_empty() && additional.is_empty() {
                return Err(invalid(
                    "sumo.controlled",
                    c,
                    "chooses among your own vehicles, but the scenario names none: give their route file in sumo.routes (or a sumo.config naming it)",
                ));
            }
        }
        let mut inflow_drivers = Vec::with_capacity(self.inflows.len());
        for (k, f) in self.inflows.iter().enumerate() {
            check_inflow(k, f)?;
            inflow_drivers.push(
                f.controlled
                    .as_ref()
                    .map(|c| c.driver(k, base_dir))
                    .transpose()?,
            );
        }
        Ok(SumoSettings {
            inflows: self.inflows.clone(),
            inflow_drivers,
            controlled: self.controlled.clone(),
            fcd: self.fcd,
            net,
            routes,
            additional,
            config,
            config_ignored,
            vehicle_type: SumoVehicleType {
                min_gap_m: self.min_gap_m,
                accel_mps2: self.accel_mps2,
                decel_mps2: self.decel_mps2,
                emergency_decel_mps2: self.emergency_decel_mps2,
                max_speed_mps: self.max_speed_mps,
                vclass,
            },
            timeout,
        })
    }
}

/// The most vehicles per hour one inflow may ask for (ten lanes at a headway of one second;
/// the SUMO backend checks the entry's own capacity).
pub const MAX_VEHS_PER_HOUR: f64 = 36_000.0;

/// The most vehicles at given times one inflow may name (`controlled.at_s`).
pub const MAX_CONTROLLED_AT: usize = 100_000;

/// The numbers of inflow `k`.
fn check_inflow(k: usize, f: &InflowSpec) -> Result<(), ScenarioError> {
    let field = |name: &str| format!("sumo.inflows[{k}].{name}");
    if !(f.vehs_per_hour.is_finite()
        && f.vehs_per_hour > 0.0
        && f.vehs_per_hour <= MAX_VEHS_PER_HOUR)
    {
        return Err(invalid(
            field("vehs_per_hour"),
            f.vehs_per_hour,
            format!("must be a number > 0 and at most {MAX_VEHS_PER_HOUR} (vehicles per hour)"),
        ));
    }
    if let Some(v) = f.depart_speed_mps {
        if !(v.is_finite() && v >= 0.0) {
            return Err(invalid(
                field("depart_speed_mps"),
                v,
                "must be a finite number ≥ 0, or left out for the most SUMO allows",
            ));
        }
    }
    if !(f.begin_s.is_finite() && f.begin_s >= 0.0) {
        return Err(invalid(
            field("begin_s"),
            f.begin_s,
            "must be a finite number ≥ 0",
        ));
    }
    if let Some(end) = f.end_s {
        if !(end.is_finite() && end > f.begin_s) {
            return Err(invalid(
                field("end_s"),
                end,
                format!("must be a finite number after begin_s = {}", f.begin_s),
            ));
        }
    }
    for (name, edge) in [("from", &f.from), ("to", &f.to)] {
        if edge.is_empty() {
            return Err(invalid(field(name), "\"\"", "name an edge of the network"));
        }
    }
    if let Some(c) = &f.controlled {
        let field = |name: &str| format!("sumo.inflows[{k}].controlled.{name}");
        if !(c.share.is_finite() && (0.0..=1.0).contains(&c.share)) {
            return Err(invalid(
                field("share"),
                c.share,
                "must be a share in [0, 1] of the inflow's vehicles",
            ));
        }
        if c.at_s.len() > MAX_CONTROLLED_AT {
            return Err(invalid(
                field("at_s"),
                format!("{} departure times", c.at_s.len()),
                format!("at most {MAX_CONTROLLED_AT} (each is a vehicle of its own in SUMO's route file); for more, give a share of the inflow"),
            ));
        }
        for (j, &t) in c.at_s.iter().enumerate() {
            if !(t.is_finite() && t >= 0.0) {
                return Err(invalid(
                    field(&format!("at_s[{j}]")),
                    t,
                    "must be a departure time ≥ 0 s",
                ));
            }
        }
    }
    Ok(())
}

impl InflowControl {
    /// Who drives the controlled vehicles of inflow `k`: the registry law [`Self::law`] or the
    /// user's Python class (its file read relative to `base_dir`, as the scenario's
    /// `controller` is), one of the two.
    pub fn driver(&self, k: usize, base_dir: &Path) -> Result<UserLaw, ScenarioError> {
        let at = format!("sumo.inflows[{k}].controlled");
        match (&self.law, &self.python) {
            (Some(_), None) => self.law(k).map(UserLaw::Rust),
            (None, Some(python)) => {
                let spec = crate::user_law::ControllerSpec {
                    python: Some(python.clone()),
                    params: self.params.clone(),
                    ..Default::default()
                };
                spec.resolve(base_dir).map_err(|e| ScenarioError::Invalid {
                    field: e.field.replacen("controller", &at, 1),
                    value: e.value,
                    expected: e.expected,
                })
            }
            (Some(law), Some(python)) => Err(invalid(
                at,
                format!("law = {law}, python = {python}"),
                "give one: \"law\": NAME of the registry or \"python\": \"FILE.py:Class\"",
            )),
            (None, None) => Err(invalid(
                at,
                "{}",
                format!(
                    "name who drives them: \"law\": NAME ({}) or \"python\": \"FILE.py:Class\"",
                    crate::registry::valid_names_alone()
                ),
            )),
        }
    }

    /// The registry law that drives the controlled vehicles of inflow `k`, its name and
    /// parameters checked, and refused when it needs a ring (each vehicle is driven on its
    /// own, behind whoever is ahead of it).
    pub fn law(&self, k: usize) -> Result<NamedLaw, ScenarioError> {
        let field = format!("sumo.inflows[{k}].controlled.law");
        let name = self.law.as_deref().unwrap_or_default();
        let to_err = |e: crate::registry::LawNameError| {
            let why = match e {
                // The laws that drive a vehicle alone (not the protocol, not one that looks behind).
                crate::registry::LawNameError::Unknown { .. } => {
                    format!(
                        "unknown controller; use {}",
                        crate::registry::valid_names_alone()
                    )
                }
                e => e.why(),
            };
            invalid(&field, name, why)
        };
        let extra = match &self.params {
            None => None,
            Some(p) => Some(p.as_object().ok_or_else(|| {
                invalid(
                    format!("sumo.inflows[{k}].controlled.params"),
                    p,
                    "must be a JSON object of the law's parameters",
                )
            })?),
        };
        let Some(law) = NamedLaw::named(&field, name, extra).map_err(to_err)? else {
            return Err(invalid(
                &field,
                name,
                format!(
                    "the scenario's own law drives its fixed set of vehicles; name a law of the registry for vehicles that enter and leave: {}",
                    crate::registry::valid_names_alone()
                ),
            ));
        };
        // Each vehicle is driven alone, behind whoever SUMO reports ahead of it: any law that
        // reads only that (a ring law's predecessor is that vehicle), none that looks behind.
        if law.entry().is_ok_and(|e| e.looks_behind) {
            return Err(invalid(
                &field,
                name,
                "this law reads the vehicle behind each vehicle too; a vehicle that enters and leaves is driven alone, behind whoever is ahead of it: choose a law that reads only the vehicle ahead (follower-stopper-U, pi-saturation, their flow- versions, lacc, constant-speed-U)",
            ));
        }
        Ok(law)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::time::Duration;

    use super::{VehicleClass, VEHICLE_CLASSES};
    use crate::scenario::ScenarioFile;

    fn ring(sumo: &str) -> String {
        format!(
            r#"{{"seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": 4,
                "road": {{"type": "ring", "length_m": 200}},
                "model": {{"type": "delayed_driver", "delay_s": 0.2,
                          "graph": {{"type": "unidirectional_ring", "gain": 0.5}}}},
                "sumo": {sumo}}}"#
        )
    }

    #[test]
    fn sumo_section_is_validated_into_typed_values() {
        let sc = ScenarioFile::from_json(
            &ring(r#"{"net": "nets/ring.net.xml", "timeout_s": 2.5, "min_gap_m": 0}"#),
            "<test>",
        )
        .unwrap()
        .validate(Path::new("/data/scenarios"))
        .unwrap();
        let s = sc.sumo();
        assert_eq!(
            s.net(),
            Some(Path::new("/data/scenarios/nets/ring.net.xml"))
        );
        assert_eq!(s.timeout(), Duration::from_millis(2500));
        assert_eq!(s.vehicle_type().min_gap_m, 0.0);
        assert_eq!(s.vehicle_type().max_speed_mps, 30.0);
    }

    #[test]
    fn the_vehicle_class_is_one_of_sumos() {
        let class = |sumo: &str| {
            ScenarioFile::from_json(&ring(sumo), "<test>")
                .map_err(|e| e.to_string())?
                .validate(Path::new("."))
                .map(|sc| sc.sumo().vehicle_type().vclass)
                .map_err(|e| e.to_string())
        };
        assert_eq!(class("{}"), Ok(VehicleClass::PASSENGER));
        assert_eq!(class(r#"{"vclass": "vip"}"#).unwrap().name(), "vip");
        let e = class(r#"{"vclass": "VIP"}"#).unwrap_err();
        assert!(
            e.starts_with(r#"sumo.vclass = "VIP": not one of SUMO's vehicle classes: passenger, private, emergency, authority, army, vip,"#),
            "{e}"
        );
        // The list is SUMO's own (sumolib.net.lane.SUMO_VEHICLE_CLASSES without the deprecated
        // names): 32 distinct names, and serialised as written.
        let mut names = VEHICLE_CLASSES.to_vec();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), 32);
        let vip = VehicleClass::parse("vip").unwrap();
        assert_eq!(serde_json::to_string(&vip).unwrap(), r#""vip""#);
        assert_eq!(
            serde_json::from_str::<VehicleClass>(r#""vip""#).unwrap(),
            vip
        );
    }

    #[test]
    fn inflows_are_other_traffic_and_their_numbers_are_checked() {
        let validate = |inflow: &str| {
            ScenarioFile::from_json(&ring(&format!(r#"{{"inflows": [{inflow}]}}"#)), "<test>")
                .map_err(|e| e.to_string())?
                .validate(Path::new("."))
                .map_err(|e| e.to_string())
        };
        let sc = validate(r#"{"from": "in", "to": "out", "vehs_per_hour": 600}"#).unwrap();
        assert!(sc.sumo().other_traffic());
        assert_eq!(
            sc.native_refusal().unwrap(),
            "scenario scenario: sumo.inflows = in → out: the user's own traffic, which only SUMO drives, shares the road; the native simulator would run syncroad's vehicles without it and report on another road; run it on SUMO (\"backend\": \"sumo\", `syncroad run`)"
        );
        for (inflow, err) in [
            (
                r#"{"from": "in", "to": "out", "vehs_per_hour": 0}"#,
                "sumo.inflows[0].vehs_per_hour = 0: must be a number > 0 and at most 36000 (vehicles per hour)",
            ),
            (
                r#"{"from": "in", "to": "out", "vehs_per_hour": 60, "begin_s": 10, "end_s": 5}"#,
                "sumo.inflows[0].end_s = 5: must be a finite number after begin_s = 10",
            ),
            (
                r#"{"from": "", "to": "out", "vehs_per_hour": 60}"#,
                "sumo.inflows[0].from = \"\": name an edge of the network",
            ),
        ] {
            assert_eq!(validate(inflow).unwrap_err(), err);
        }
    }

    #[test]
    fn an_inflows_departure_lane_is_an_index_or_one_of_sumos_rules() {
        use crate::scenario::DepartLane;
        let lane = |json: &str| serde_json::from_str::<DepartLane>(json).map_err(|e| e.to_string());
        assert_eq!(lane("2"), Ok(DepartLane::Index(2)));
        assert_eq!(lane(r#""free""#), Ok(DepartLane::Free));
        assert_eq!(lane(r#""best""#), Ok(DepartLane::Best));
        assert_eq!(lane(r#""random""#), Ok(DepartLane::Random));
        for bad in [r#""fre""#, "-1", "1.5", "null"] {
            let e = lane(bad).unwrap_err();
            assert!(
                e.starts_with(&format!("depart_lane = {bad}: give a lane index (0 is the rightmost) or one of \"best\", \"free\", \"random\"")),
                "{e}"
            );
        }
        // Written back as SUMO and the scenario file spell it.
        assert_eq!(
            serde_json::to_string(&DepartLane::Free).unwrap(),
            r#""free""#
        );
        assert_eq!(serde_json::to_string(&DepartLane::Index(1)).unwrap(), "1");
        assert_eq!(DepartLane::Random.sumo_value(), "random");
    }

    #[test]
    fn an_inflows_controlled_vehicles_name_a_law_that_reads_only_ahead() {
        let validate = |controlled: &str| {
            let inflow = format!(
                r#"{{"from": "in", "to": "out", "vehs_per_hour": 600, "controlled": {controlled}}}"#
            );
            ScenarioFile::from_json(&ring(&format!(r#"{{"inflows": [{inflow}]}}"#)), "<test>")
                .map_err(|e| e.to_string())?
                .validate(Path::new("."))
                .map_err(|e| e.to_string())
        };
        let sc = validate(
            r#"{"law": "constant-speed", "params": {"target_speed_mps": 20}, "share": 0}"#,
        )
        .unwrap();
        let c = sc.sumo().inflows()[0].controlled.as_ref().unwrap();
        let law = c.law(0).unwrap();
        assert_eq!(law.to_string(), "constant-speed-20");
        // The shorthand spelling is the same law.
        let short = validate(r#"{"law": "constant-speed-20", "share": 0.5}"#).unwrap();
        let c = short.sumo().inflows()[0].controlled.as_ref().unwrap();
        assert_eq!(c.law(0).unwrap().to_string(), law.to_string());
        for (controlled, err) in [
            (
                r#"{"law": "bcm", "share": 0.1}"#,
                "sumo.inflows[0].controlled.law = bcm: this law reads the vehicle behind each vehicle too",
            ),
            (
                r#"{"law": "constant-speed", "params": 3, "share": 0.1}"#,
                "sumo.inflows[0].controlled.params = 3: must be a JSON object",
            ),
            (
                r#"{"law": "pi-saturation", "share": -0.1}"#,
                "sumo.inflows[0].controlled.share = -0.1: must be a share in [0, 1]",
            ),
            (
                r#"{"law": "pi-saturation", "shares": 0.1}"#,
                "unknown field `shares`",
            ),
            (
                &format!(r#"{{"law": "pi-saturation", "at_s": [{}]}}"#, vec!["1"; 100_001].join(",")),
                "sumo.inflows[0].controlled.at_s = 100001 departure times: at most 100000",
            ),
        ] {
            let e = validate(controlled).unwrap_err();
            assert!(e.contains(err), "{e}");
        }
    }

    #[test]
    fn a_routes_lanes_are_one_index_a_list_or_follow() {
        use crate::scenario::RouteLanes;
        let lanes =
            |json: &str| serde_json::from_str::<RouteLanes>(json).map_err(|e| e.to_string());
        assert_eq!(lanes("1"), Ok(RouteLanes::Index(1)));
        assert_eq!(lanes("[0, 1, 1]"), Ok(RouteLanes::PerEdge(vec![0, 1, 1])));
        assert_eq!(lanes(r#""follow""#), Ok(RouteLanes::Follow));
        for bad in [r#""folow""#, "-1", "1.5", "[0, -1]"] {
            let e = lanes(bad).unwrap_err();
            assert!(e.contains("road.lane as a lane index (0 = rightmost), a list of one lane index per edge, or \"follow\"") || e.contains("expected usize"), "{bad}: {e}");
        }
        let loop_with = |lane: &str| {
            ScenarioFile::from_json(
                &ring("{}").replace(
                    r#""road": {"type": "ring", "length_m": 200}"#,
                    &format!(r#""road": {{"type": "loop", "through": "e0", "lane": {lane}}}"#),
                ),
                "<test>",
            )
            .map(|_| ())
            .map_err(|e| e.to_string())
        };
        assert_eq!(loop_with("1"), Ok(()));
        let e = loop_with(r#""follow""#).unwrap_err();
        assert!(e.contains(r#"road.lane = "follow": a loop keeps one lane index (0 = rightmost) on every edge; one index per edge and "follow" are for routes"#), "{e}");
        for l in [
            RouteLanes::Index(2),
            RouteLanes::PerEdge(vec![0, 2]),
            RouteLanes::Follow,
        ] {
            let back: RouteLanes =
                serde_json::from_str(&serde_json::to_string(&l).unwrap()).unwrap();
            assert_eq!(back, l);
        }
    }

    #[test]
    fn controlled_vehicles_are_chosen_among_the_users_own() {
        let validate = |sumo: &str| {
            ScenarioFile::from_json(&ring(sumo), "<test>")
                .map_err(|e| e.to_string())?
                .validate(Path::new("/data"))
                .map_err(|e| e.to_string())
        };
        let sc =
            validate(r#"{"routes": ["cav.rou.xml"], "controlled": {"vtype": "cav"}}"#).unwrap();
        let c = sc.sumo().controlled().unwrap();
        assert_eq!(c.vtype.as_deref(), Some("cav"));
        assert!(validate(r#"{"routes": ["r.xml"]}"#)
            .unwrap()
            .sumo()
            .controlled()
            .is_none());
        assert_eq!(
            validate(r#"{"controlled": {"id": "cav.*"}}"#).unwrap_err(),
            r#"sumo.controlled = {"id":"cav.*"}: chooses among your own vehicles, but the scenario names none: give their route file in sumo.routes (or a sumo.config naming it)"#
        );
        assert!(
            validate(r#"{"routes": ["r.xml"], "controlled": {"id": "(("}}"#)
                .unwrap_err()
                .starts_with("sumo.controlled.id = ((: must be a regular expression")
        );
        assert!(
            validate(r#"{"routes": ["r.xml"], "controlled": {"type": "cav"}}"#)
                .unwrap_err()
                .contains("unknown field `type`")
        );
    }

    #[test]
    fn absolute_net_stays_and_missing_net_is_none() {
        let abs = ScenarioFile::from_json(&ring(r#"{"net": "/nets/ring.net.xml"}"#), "<test>")
            .unwrap()
            .validate(Path::new("/data"))
            .unwrap();
        assert_eq!(abs.sumo().net(), Some(Path::new("/nets/ring.net.xml")));
        let none = ScenarioFile::from_json(&ring("{}"), "<test>")
            .unwrap()
            .validate(Path::new("/data"))
            .unwrap();
        assert_eq!(none.sumo().net(), None);
    }

    #[test]
    fn bad_sumo_numbers_name_field_value_and_range() {
        for (sumo, msg) in [
            (
                r#"{"timeout_s": 0}"#,
                "sumo.timeout_s = 0: must be a finite number > 0",
            ),
            (
                r#"{"min_gap_m": -1}"#,
                "sumo.min_gap_m = -1: must be a finite number ≥ 0",
            ),
            (
                r#"{"accel_mps2": -2}"#,
                "sumo.accel_mps2 = -2: must be a finite number > 0",
            ),
            (
                r#"{"timeout_s": 1e10}"#,
                "sumo.timeout_s = 10000000000: must be at most 1e9 s (about 31 years), like --timeout-s",
            ),
        ] {
            let err = ScenarioFile::from_json(&ring(sumo), "<test>")
                .unwrap()
                .validate(Path::new("."))
                .unwrap_err()
                .to_string();
            assert!(err.starts_with(msg), "{sumo}: {err}");
        }
    }
}
