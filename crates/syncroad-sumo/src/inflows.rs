//! Human traffic that enters and leaves the network (`sumo.inflows`): each inflow checked on
//! the network before SUMO starts (its edges, a route between them along the connections, its
//! departure lane, and whether the entry can take that many vehicles), then written as a SUMO
//! `<flow>` into the run's folder. The vehicles are of SUMO's default type (Krauss, class
//! `passenger`), routed by SUMO from `from` to `to`, and leave the network at `to`'s end.
//!
//! An inflow's `controlled` vehicles are of a vehicle type of their own, [`guest_type`]`(k)`,
//! which the worker recognises when SUMO inserts them (`cosim::guests`): a share of the flow
//! through a `<vTypeDistribution>` (SUMO draws each vehicle's type with the run's seed), and
//! vehicles at given times as `<trip>`s on the flow's route.
//!
//! # Reference
//! SUMO documentation, "Definition of Vehicles, Vehicle Types, and Routes", section
//! "Repeated vehicles (Flows)" (`vehsPerHour`, `period="exp(…)"`, `departLane`, `departSpeed`),
//! and "Vehicle Type Distributions" (`vTypes`, `probabilities`).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use syncroad_control::scenario::{Arrivals, DepartLane, InflowSpec, SumoVehicleType, VehicleClass};
use syncroad_control::Scenario;

use crate::layout::Layout;

use crate::net::network::Network;
use crate::net::roads::nearest;
use crate::net::Road;
use crate::prepare_error::PrepareError;

/// The file the flows are written to, in the run's folder.
pub const INFLOWS_FILE: &str = "inflows.rou.xml";

/// SUMO's default vehicle type (`DEFAULT_VEHTYPE`): length, minGap \[m\] and Krauss's `tau`
/// \[s\], the insertion headway's terms.
const DEFAULT_LENGTH_M: f64 = 5.0;
const DEFAULT_MIN_GAP_M: f64 = 2.5;
const DEFAULT_TAU_S: f64 = 1.0;

fn refuse(field: String, value: impl std::fmt::Display, reason: String) -> PrepareError {
    PrepareError::Inflow {
        field,
        value: value.to_string(),
        reason,
    }
}

/// The most vehicles per hour one lane takes in at departure speed `v` \[m/s\]: SUMO inserts a
/// vehicle when the one before has moved its length, its minGap and a reaction time's travel
/// ahead, `3600·v / (length + minGap + v·tau)`.
pub fn lane_capacity_per_hour(v: f64) -> f64 {
    3600.0 * v / (DEFAULT_LENGTH_M + DEFAULT_MIN_GAP_M + v * DEFAULT_TAU_S)
}

/// The vehicle type of the vehicles a law drives in inflow `k` (`controlled`).
pub fn guest_type(k: usize) -> String {
    format!("syncroad_guest{k}")
}

/// The vehicle type of an inflow's controlled vehicles: syncroad's own (`sumo.length_m`,
/// `minGap`, `accel`, `decel`, `maxSpeed`, no driver randomness), of SUMO's class
/// `passenger` like the rest of the inflow.
#[derive(Debug, Clone, PartialEq)]
pub struct GuestType {
    /// The scenario's vehicle type.
    pub vtype: SumoVehicleType,
    /// Their length \[m\].
    pub length_m: f64,
}

impl GuestType {
    /// The type of the layout's vehicles (the first one's length).
    pub fn of(layout: &Layout) -> Self {
        Self {
            vtype: layout.vtype,
            length_m: layout.vehicles.first().map_or(5.0, |v| v.length_m),
        }
    }
}

/// The inflows of `scenario` on its road's network, checked, as the route file SUMO is given
/// (written into `work_dir` when `write`); `None` without inflows.
pub fn routes_file(
    scenario: &Scenario,
    road: &Road,
    guest: &GuestType,
    work_dir: &Path,
    write: bool,
) -> Result<Option<PathBuf>, PrepareError> {
    let inflows = scenario.sumo().inflows();
    if inflows.is_empty() {
        return Ok(None);
    }
    let net = Network::read(&road.path)?;
    check(&net, &road.path, inflows, scenario.horizon_s())?;
    let file = work_dir.join(INFLOWS_FILE);
    if write {
        let xml = flows_xml(inflows, scenario.horizon_s(), guest);
        std::fs::write(&file, xml).map_err(|e| PrepareError::Io {
            path: work_dir.to_path_buf(),
            reason: e.to_string(),
        })?;
    }
    Ok(Some(file))
}

/// The laws that drive the inflows' controlled vehicles, each registry law built once here for
/// one vehicle so that a law that refuses its context does so before SUMO starts.
pub fn guests(
    scenario: &Scenario,
    guest: &GuestType,
) -> Result<Vec<crate::protocol::GuestLaw>, PrepareError> {
    let mut laws = Vec::new();
    for k in 0..scenario.sumo().inflows().len() {
        // Resolved and checked with the scenario.
        let Some(law) = scenario.sumo().inflow_driver(k).cloned() else {
            continue;
        };
        let t = &guest.vtype;
        let context = syncroad_control::speed_controller::LawContext {
            step_s: scenario.step_s(),
            ids: vec![guest_type(k)],
            length_m: vec![guest.length_m],
            ring_length_m: None,
            controlled: vec![true],
            accel_mps2: t.accel_mps2,
            decel_mps2: t.decel_mps2,
            // The lane's own limit is read for each vehicle every step.
            speed_limit_mps: None,
            signals: false,
            seed: scenario.seed(),
            protocol: None,
        };
        // A registry law is built here once, so that one refusing its context does so before
        // SUMO starts; a Python class is built in the worker, which embeds the interpreter.
        if let syncroad_control::UserLaw::Rust(named) = &law {
            named
                .build_alone(&context)
                .map_err(|e| refuse(format!("sumo.inflows[{k}].controlled.law"), named, e))?;
        }
        laws.push(crate::protocol::GuestLaw {
            inflow: k,
            law,
            context,
            min_gap_m: t.min_gap_m,
        });
    }
    Ok(laws)
}

/// Checks every inflow on the network `net` (read from `path`) for a run of `horizon_s`.
pub fn check(
    net: &Network,
    path: &Path,
    inflows: &[InflowSpec],
    horizon_s: f64,
) -> Result<(), PrepareError> {
    for (k, f) in inflows.iter().enumerate() {
        check_route(net, path, k, f)?;
        let open = open_entry_lanes(net, k, f)?;
        check_times(k, f, horizon_s)?;
        check_capacity(net, k, f, inflows, &open, horizon_s)?;
    }
    Ok(())
}

/// Inflow `k`'s edges exist and a route along the connections leads from one to the other.
fn check_route(net: &Network, path: &Path, k: usize, f: &InflowSpec) -> Result<(), PrepareError> {
    let field = |name: &str| format!("sumo.inflows[{k}].{name}");
    for (name, edge) in [("from", &f.from), ("to", &f.to)] {
        if net.edge_lanes(edge).is_none() {
            return Err(refuse(
                field(name),
                format!("`{edge}`"),
                format!(
                    "{} has no normal edge of that id; nearest ids: {}",
                    path.display(),
                    nearest(net, edge)
                ),
            ));
        }
    }
    if !reaches(net, &f.from, &f.to) {
        return Err(refuse(
            field("to"),
            format!("`{}`", f.to),
            format!(
                "no route along the connections of {} leads from `{}` to it",
                path.display(),
                f.from
            ),
        ));
    }
    Ok(())
}

/// The lanes of inflow `k`'s entry edge open to its vehicles (SUMO's default type, class
/// passenger), at least one, with its departure lane, when it names one, among them.
fn open_entry_lanes(net: &Network, k: usize, f: &InflowSpec) -> Result<Vec<usize>, PrepareError> {
    let field = |name: &str| format!("sumo.inflows[{k}].{name}");
    let lanes = net.edge_lanes(&f.from).unwrap_or_default();
    let open: Vec<usize> = (0..lanes.len())
        .filter(|&l| lanes[l].permits(VehicleClass::PASSENGER.name()))
        .collect();
    if open.is_empty() {
        return Err(refuse(
            field("from"),
            format!("`{}`", f.from),
            "no lane of it admits SUMO's default vehicle type, class passenger".into(),
        ));
    }
    if let Some(DepartLane::Index(l)) = f.depart_lane {
        if l >= lanes.len() {
            return Err(refuse(
                field("depart_lane"),
                l,
                format!(
                    "edge `{}` has {} lane(s), indices 0..={}",
                    f.from,
                    lanes.len(),
                    lanes.len() - 1
                ),
            ));
        }
        if !open.contains(&l) {
            return Err(refuse(
                field("depart_lane"),
                l,
                format!(
                    "lane `{}` is closed to SUMO's default vehicle type, class passenger ({})",
                    lanes[l].id,
                    lanes[l].permissions()
                ),
            ));
        }
    }
    Ok(open)
}

/// Inflow `k` begins, and its controlled vehicles depart, before the horizon.
fn check_times(k: usize, f: &InflowSpec, horizon_s: f64) -> Result<(), PrepareError> {
    if let Some(c) = &f.controlled {
        if let Some((j, t)) = c.at_s.iter().enumerate().find(|(_, t)| **t >= horizon_s) {
            return Err(refuse(
                format!("sumo.inflows[{k}].controlled.at_s[{j}]"),
                t,
                format!("the run ends at horizon_s = {horizon_s} s; depart before it"),
            ));
        }
    }
    if f.begin_s >= horizon_s {
        return Err(refuse(
            format!("sumo.inflows[{k}].begin_s"),
            f.begin_s,
            format!("the run ends at horizon_s = {horizon_s} s; begin before it"),
        ));
    }
    Ok(())
}

/// Inflow `k`'s entry can take its vehicles on the lanes it departs on, and the inflows
/// entering there at the same time together on the lanes they use between them (`open`: the
/// entry's lanes open to them).
fn check_capacity(
    net: &Network,
    k: usize,
    f: &InflowSpec,
    inflows: &[InflowSpec],
    open: &[usize],
    horizon_s: f64,
) -> Result<(), PrepareError> {
    let limit = net
        .edge_lanes(&f.from)
        .unwrap_or_default()
        .iter()
        .map(|l| l.speed_mps)
        .fold(f64::INFINITY, f64::min);
    let v = f.depart_speed_mps.unwrap_or(limit).min(limit);
    let window = |g: &InflowSpec| (g.begin_s, g.end_s.unwrap_or(horizon_s));
    let (b, e) = window(f);
    let sharing: Vec<&InflowSpec> = inflows
        .iter()
        .filter(|g| g.from == f.from)
        .filter(|g| window(g).0 < e && b < window(g).1)
        .collect();
    let mut used: Vec<usize> = sharing
        .iter()
        .flat_map(|g| departure_lanes(net, g, open))
        .collect();
    used.sort_unstable();
    used.dedup();
    let own = departure_lanes(net, f, open).len();
    let total: f64 = sharing.iter().map(|g| g.vehs_per_hour).sum();
    for (demand, lanes_used, shared) in [
        (f.vehs_per_hour, own, false),
        (total, used.len(), total > f.vehs_per_hour),
    ] {
        let capacity = lanes_used as f64 * lane_capacity_per_hour(v);
        if demand <= capacity {
            continue;
        }
        let shared = if shared {
            format!(" (with the other inflows entering there at the same time, {total})")
        } else {
            String::new()
        };
        return Err(refuse(
            format!("sumo.inflows[{k}].vehs_per_hour"),
            f.vehs_per_hour,
            format!(
                "above what edge `{}` can take in{shared}: at most about {:.0} vehicles per hour on {lanes_used} lane(s) departing at {v:.1} m/s (3600·v / (length + minGap + v·tau) per lane for SUMO's default vehicle type); SUMO would silently delay the insertions, so the inflow would not be what the scenario says: give at most {:.0} in all",
                f.from,
                capacity,
                capacity.floor()
            ),
        ));
    }
    Ok(())
}

/// The lanes of its entry edge inflow `f` departs on, of the lanes `open` to its vehicles: its
/// lane, those SUMO's `"best"` takes (the lanes with a connection that leads on towards its
/// exit; every open lane when it leaves where it enters), or every open lane.
fn departure_lanes(net: &Network, f: &InflowSpec, open: &[usize]) -> Vec<usize> {
    match f.depart_lane {
        Some(DepartLane::Index(l)) => vec![l],
        None | Some(DepartLane::Best) if f.from != f.to => {
            let best: Vec<usize> = open
                .iter()
                .copied()
                .filter(|&l| {
                    net.outgoing(&f.from)
                        .iter()
                        .any(|c| c.from_lane == l && reaches(net, &c.to, &f.to))
                })
                .collect();
            if best.is_empty() {
                open.to_vec()
            } else {
                best
            }
        }
        _ => open.to_vec(),
    }
}

/// Whether a route along the network's connections leads from edge `from` to edge `to`
/// (breadth-first over the normal edges).
fn reaches(net: &Network, from: &str, to: &str) -> bool {
    if from == to {
        return true;
    }
    let mut seen = std::collections::HashSet::from([from.to_string()]);
    let mut queue = VecDeque::from([from.to_string()]);
    while let Some(e) = queue.pop_front() {
        for c in net.outgoing(&e) {
            if c.to == to {
                return true;
            }
            if net.normal_index.contains_key(&c.to) && seen.insert(c.to.clone()) {
                queue.push_back(c.to.clone());
            }
        }
    }
    false
}

/// The flows of `inflows` for a run of `horizon_s` (an inflow without `end_s` runs to it),
/// with the vehicle type `guest` of the vehicles a law drives. Flows and trips in the order
/// of their departures, as SUMO reads a route file.
pub fn flows_xml(inflows: &[InflowSpec], horizon_s: f64, guest: &GuestType) -> String {
    let mut s = String::from("<routes>\n");
    let mut departures: Vec<(f64, String)> = Vec::new();
    for (k, f) in inflows.iter().enumerate() {
        let rate = match f.arrivals {
            Arrivals::Regular => format!(r#"vehsPerHour="{}""#, f.vehs_per_hour),
            Arrivals::Poisson => format!(r#"period="exp({})""#, f.vehs_per_hour / 3600.0),
        };
        let lane = f
            .depart_lane
            .map_or_else(|| "best".to_string(), DepartLane::sumo_value);
        let speed = f
            .depart_speed_mps
            .map_or_else(|| "max".to_string(), |v| v.to_string());
        let from = quick_xml::escape::escape(f.from.as_str());
        let to = quick_xml::escape::escape(f.to.as_str());
        let mut ty = String::new();
        if let Some(c) = &f.controlled {
            let t = &guest.vtype;
            let _ = writeln!(
                s,
                r#"    <vType id="{}" length="{}" minGap="{}" accel="{}" decel="{}" emergencyDecel="{}" maxSpeed="{}" sigma="0" speedFactor="1" speedDev="0" emissionClass="{}" vClass="{}"/>"#,
                guest_type(k),
                guest.length_m,
                t.min_gap_m,
                t.accel_mps2,
                t.decel_mps2,
                t.emergency_decel_mps2,
                t.max_speed_mps,
                crate::layout::EMISSION_CLASS,
                VehicleClass::PASSENGER.name(),
            );
            if c.share > 0.0 {
                let _ = writeln!(
                    s,
                    r#"    <vTypeDistribution id="inflow{k}_types" vTypes="DEFAULT_VEHTYPE {}" probabilities="{} {}"/>"#,
                    guest_type(k),
                    1.0 - c.share,
                    c.share
                );
                ty = format!(r#" type="inflow{k}_types""#);
            }
            for (j, t) in c.at_s.iter().enumerate() {
                departures.push((
                    *t,
                    format!(
                        r#"    <trip id="inflow{k}.at{j}" type="{}" depart="{t}" from="{from}" to="{to}" departLane="{lane}" departSpeed="{speed}"/>"#,
                        guest_type(k)
                    ),
                ));
            }
        }
        departures.push((
            f.begin_s,
            format!(
                r#"    <flow id="inflow{k}"{ty} from="{from}" to="{to}" begin="{}" end="{}" {rate} departLane="{lane}" departSpeed="{speed}"/>"#,
                f.begin_s,
                f.end_s.unwrap_or(horizon_s).min(horizon_s),
            ),
        ));
    }
    // Stable: at equal times the flows and trips keep the scenario's order.
    departures.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (_, line) in departures {
        s.push_str(&line);
        s.push('\n');
    }
    s.push_str("</routes>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_lane_takes_what_its_headway_allows() {
        // At 30 m/s a vehicle needs 5 + 2.5 + 30·1 = 37.5 m: 0.8 vehicles per second.
        assert!((lane_capacity_per_hour(30.0) - 2880.0).abs() < 1e-9);
        // Standing still nothing enters.
        assert_eq!(lane_capacity_per_hour(0.0), 0.0);
    }

    fn guest() -> GuestType {
        GuestType {
            vtype: SumoVehicleType {
                min_gap_m: 2.5,
                accel_mps2: 2.6,
                decel_mps2: 4.5,
                emergency_decel_mps2: 9.0,
                max_speed_mps: 40.0,
                vclass: VehicleClass::default(),
            },
            length_m: 5.0,
        }
    }

    #[test]
    fn controlled_vehicles_are_a_type_of_their_own_drawn_or_departing_when_given() {
        let f = InflowSpec {
            from: "h0".into(),
            to: "h2".into(),
            vehs_per_hour: 1200.0,
            arrivals: Arrivals::Regular,
            depart_lane: Some(DepartLane::Index(1)),
            depart_speed_mps: None,
            begin_s: 5.0,
            end_s: None,
            controlled: Some(syncroad_control::scenario::InflowControl {
                law: Some("follower-stopper-20".into()),
                python: None,
                params: None,
                share: 0.25,
                at_s: vec![30.0, 2.0],
            }),
        };
        let xml = flows_xml(&[f], 60.0, &guest());
        let lines: Vec<&str> = xml.lines().map(str::trim).collect();
        assert_eq!(
            lines,
            [
                "<routes>",
                r#"<vType id="syncroad_guest0" length="5" minGap="2.5" accel="2.6" decel="4.5" emergencyDecel="9" maxSpeed="40" sigma="0" speedFactor="1" speedDev="0" emissionClass="HBEFA4/PC_petrol_Euro-6ab" vClass="passenger"/>"#,
                r#"<vTypeDistribution id="inflow0_types" vTypes="DEFAULT_VEHTYPE syncroad_guest0" probabilities="0.75 0.25"/>"#,
                // In the order of their departures, as SUMO reads a route file.
                r#"<trip id="inflow0.at1" type="syncroad_guest0" depart="2" from="h0" to="h2" departLane="1" departSpeed="max"/>"#,
                r#"<flow id="inflow0" type="inflow0_types" from="h0" to="h2" begin="5" end="60" vehsPerHour="1200" departLane="1" departSpeed="max"/>"#,
                r#"<trip id="inflow0.at0" type="syncroad_guest0" depart="30" from="h0" to="h2" departLane="1" departSpeed="max"/>"#,
                "</routes>",
            ]
        );
    }

    #[test]
    fn flows_are_written_as_sumo_reads_them() {
        let f = InflowSpec {
            from: "ramp".into(),
            to: "h2".into(),
            vehs_per_hour: 720.0,
            arrivals: Arrivals::Poisson,
            depart_lane: None,
            depart_speed_mps: Some(20.0),
            begin_s: 10.0,
            end_s: None,
            controlled: None,
        };
        let xml = flows_xml(&[f], 300.0, &guest());
        assert!(
            xml.contains(r#"<flow id="inflow0" from="ramp" to="h2" begin="10" end="300" period="exp(0.2)" departLane="best" departSpeed="20"/>"#),
            "{xml}"
        );
    }
}
