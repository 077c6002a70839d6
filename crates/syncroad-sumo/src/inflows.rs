//! Human traffic that enters and leaves the network (`sumo.inflows`): each inflow checked on
//! the network before SUMO starts (its edges, a route between them along the connections, its
//! departure lane, and whether the entry can take that many vehicles), then written as a SUMO
//! `<flow>` into the run's folder. The vehicles are of SUMO's default type (Krauss, class
//! `passenger`), routed by SUMO from `from` to `to`, and leave the network at `to`'s end.
//!
//! # Reference
//! SUMO documentation, "Definition of Vehicles, Vehicle Types, and Routes", section
//! "Repeated vehicles (Flows)" (`vehsPerHour`, `period="exp(…)"`, `departLane`, `departSpeed`).

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use syncroad_control::scenario::{Arrivals, InflowSpec, VehicleClass};
use syncroad_control::Scenario;

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

/// The inflows of `scenario` on its road's network, checked, as the route file SUMO is given
/// (written into `work_dir` when `write`); `None` without inflows.
pub fn routes_file(
    scenario: &Scenario,
    road: &Road,
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
        std::fs::write(&file, flows_xml(inflows, scenario.horizon_s())).map_err(|e| {
            PrepareError::Io {
                path: work_dir.to_path_buf(),
                reason: e.to_string(),
            }
        })?;
    }
    Ok(Some(file))
}

/// Checks every inflow on the network `net` (read from `path`) for a run of `horizon_s`.
pub fn check(
    net: &Network,
    path: &Path,
    inflows: &[InflowSpec],
    horizon_s: f64,
) -> Result<(), PrepareError> {
    for (k, f) in inflows.iter().enumerate() {
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
        let lanes = net.edge_lanes(&f.from).unwrap_or_default();
        let open: Vec<usize> = (0..lanes.len())
            // SUMO's default vehicle type is of class passenger.
            .filter(|&l| lanes[l].permits(VehicleClass::PASSENGER.name()))
            .collect();
        let entry_lanes = match f.depart_lane {
            Some(l) if l >= lanes.len() => {
                return Err(refuse(
                    field("depart_lane"),
                    l,
                    format!(
                        "edge `{}` has {} lane(s), indices 0..={}",
                        f.from,
                        lanes.len(),
                        lanes.len() - 1
                    ),
                ))
            }
            Some(l) if !open.contains(&l) => {
                return Err(refuse(
                    field("depart_lane"),
                    l,
                    format!(
                        "lane `{}` is closed to SUMO's default vehicle type, class passenger ({})",
                        lanes[l].id,
                        lanes[l].permissions()
                    ),
                ))
            }
            Some(_) => 1,
            None if open.is_empty() => {
                return Err(refuse(
                    field("from"),
                    format!("`{}`", f.from),
                    "no lane of it admits SUMO's default vehicle type, class passenger".into(),
                ))
            }
            None => open.len(),
        };
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
        if f.begin_s >= horizon_s {
            return Err(refuse(
                field("begin_s"),
                f.begin_s,
                format!("the run ends at horizon_s = {horizon_s} s; begin before it"),
            ));
        }
        let limit = lanes
            .iter()
            .map(|l| l.speed_mps)
            .fold(f64::INFINITY, f64::min);
        let v = f.depart_speed_mps.unwrap_or(limit).min(limit);
        let capacity = entry_lanes as f64 * lane_capacity_per_hour(v);
        // The inflows entering on the same edge at the same time share its capacity.
        let window = |g: &InflowSpec| (g.begin_s, g.end_s.unwrap_or(horizon_s));
        let (b, e) = window(f);
        let total: f64 = inflows
            .iter()
            .filter(|g| g.from == f.from)
            .filter(|g| window(g).0 < e && b < window(g).1)
            .map(|g| g.vehs_per_hour)
            .sum();
        if total > capacity {
            let shared = if total > f.vehs_per_hour {
                format!(" (with the other inflows entering there at the same time, {total})")
            } else {
                String::new()
            };
            return Err(refuse(
                field("vehs_per_hour"),
                f.vehs_per_hour,
                format!(
                    "above what edge `{}` can take in{shared}: at most about {:.0} vehicles per hour on {entry_lanes} lane(s) departing at {v:.1} m/s (3600·v / (length + minGap + v·tau) per lane for SUMO's default vehicle type); SUMO would silently delay the insertions, so the inflow would not be what the scenario says: give at most {:.0} in all",
                    f.from,
                    capacity,
                    capacity.floor()
                ),
            ));
        }
    }
    Ok(())
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

/// The flows of `inflows` for a run of `horizon_s` (an inflow without `end_s` runs to it).
pub fn flows_xml(inflows: &[InflowSpec], horizon_s: f64) -> String {
    let mut s = String::from("<routes>\n");
    for (k, f) in inflows.iter().enumerate() {
        let rate = match f.arrivals {
            Arrivals::Regular => format!(r#"vehsPerHour="{}""#, f.vehs_per_hour),
            Arrivals::Poisson => format!(r#"period="exp({})""#, f.vehs_per_hour / 3600.0),
        };
        let lane = f
            .depart_lane
            .map_or_else(|| "best".to_string(), |l| l.to_string());
        let speed = f
            .depart_speed_mps
            .map_or_else(|| "max".to_string(), |v| v.to_string());
        let _ = writeln!(
            s,
            r#"    <flow id="inflow{k}" from="{}" to="{}" begin="{}" end="{}" {rate} departLane="{lane}" departSpeed="{speed}"/>"#,
            quick_xml::escape::escape(f.from.as_str()),
            quick_xml::escape::escape(f.to.as_str()),
            f.begin_s,
            f.end_s.unwrap_or(horizon_s).min(horizon_s),
        );
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
        };
        let xml = flows_xml(&[f], 300.0);
        assert!(
            xml.contains(r#"<flow id="inflow0" from="ramp" to="h2" begin="10" end="300" period="exp(0.2)" departLane="best" departSpeed="20"/>"#),
            "{xml}"
        );
    }
}
