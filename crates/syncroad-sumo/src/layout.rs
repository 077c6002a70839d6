//! Where the vehicles start: departure edge, position and speed for every SUMO vehicle, the
//! vehicle types, and the routes file that keeps them driving. Everything here is decided
//! before SUMO starts, so that impossible layouts (an overfull ring, a road too short for the
//! horizon) are rejected with numbers instead of vehicles silently left pending.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use syncroad_control::drive::SumoDriver;
use syncroad_control::scenario::SumoVehicleType;

use crate::net::{off_junctions, Road, MAX_JUNCTION_SHIFT_M};

/// Emission class set on every vehicle type, so fuel and CO2 come from one stated model
/// (HBEFA 4, petrol passenger car, Euro 6ab; built into SUMO 1.28).
pub const EMISSION_CLASS: &str = "HBEFA4/PC_petrol_Euro-6ab";

/// Errors laying out a run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LayoutError {
    /// More vehicles than fit on the ring.
    #[error("ring {net} is overfull: {vehicles} vehicles × (length {length_m} m + minGap {min_gap_m} m) = {needed_m:.2} m exceed its length {ring_m:.4} m (as SUMO measures it); use at most {max_vehicles} vehicles, a shorter length/minGap, or a longer ring")]
    RingOverfull {
        /// The network.
        net: String,
        /// Number of vehicles.
        vehicles: usize,
        /// Longest vehicle length \[m\].
        length_m: f64,
        /// SUMO minGap \[m\].
        min_gap_m: f64,
        /// Space needed \[m\].
        needed_m: f64,
        /// Ring length \[m\].
        ring_m: f64,
        /// How many would fit.
        max_vehicles: usize,
    },
    /// The road ends before the horizon.
    #[error("straight road {net} is {road_m:.1} m long but the run needs about {needed_m:.1} m (platoon {platoon_m:.1} m + leader travel over {horizon_s} s); use a longer road or a shorter horizon_s")]
    RoadTooShort {
        /// The network.
        net: String,
        /// Road length \[m\].
        road_m: f64,
        /// Space needed \[m\].
        needed_m: f64,
        /// Length of the platoon at the start \[m\].
        platoon_m: f64,
        /// Horizon \[s\].
        horizon_s: f64,
    },
    /// The horizon needs more laps than SUMO's route `repeat` (a 32-bit integer) can count.
    #[error("horizon_s = {horizon_s} s needs {repeats:.3e} laps of the {ring_m:.1} m ring {net} at up to {speed_mps} m/s, but SUMO counts route repeats as a 32-bit integer (at most {max}); give horizon_s ≤ {max_horizon_s:.0} s", max = i32::MAX)]
    TooManyLaps {
        /// The network.
        net: String,
        /// Horizon \[s\].
        horizon_s: f64,
        /// Repeats needed.
        repeats: f64,
        /// Ring length \[m\].
        ring_m: f64,
        /// The speed the route is sized for (twice the faster of maxSpeed and the lane limit) \[m/s\].
        speed_mps: f64,
        /// The longest horizon that fits \[s\].
        max_horizon_s: f64,
    },
    /// A per-vehicle number is out of range.
    #[error("{field} = {value} is invalid: {expected}")]
    Invalid {
        /// Field name.
        field: String,
        /// The value.
        value: f64,
        /// What would be valid.
        expected: String,
    },
}

/// One SUMO vehicle's start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Departure {
    /// SUMO vehicle id.
    pub id: String,
    /// SUMO's car-following model drives this vehicle (`None`: the law commands it).
    #[serde(default)]
    pub driver: Option<SumoDriver>,
    /// Vehicle length \[m\].
    pub length_m: f64,
    /// Index into [`Road::normal_edges`] of the departure edge.
    pub edge_index: usize,
    /// departPos (front bumper) on that edge \[m\].
    pub pos_m: f64,
    /// departSpeed [m/s].
    pub speed_mps: f64,
    /// Unwrapped rear-bumper position at t = 0 in the native simulator's coordinates \[m\];
    /// positions during the run are this plus SUMO's odometer.
    pub q0_m: f64,
}

/// The resolved layout of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Layout {
    /// The road.
    pub road: Road,
    /// Vehicle type.
    pub vtype: SumoVehicleType,
    /// All SUMO vehicles, the leader (if it is a SUMO vehicle) first.
    pub vehicles: Vec<Departure>,
    /// True when `vehicles[0]` is a leader driven by its speed profile.
    pub leader_vehicle: bool,
    /// Factor applied to the scenario's gaps on a ring so that lengths plus gaps fill SUMO's
    /// ring length exactly (1 on straight roads).
    pub gap_scale: f64,
    /// How many times the ring route repeats (enough for the horizon at maxSpeed).
    pub route_repeats: usize,
    /// How far along a loop the whole layout was turned to keep departures off junction
    /// lanes \[m\]: SUMO's loop coordinate of a point is its trajectory coordinate plus this
    /// (0 on the shipped rings and on straight roads).
    #[serde(default)]
    pub ring_offset_m: f64,
}

fn check_pos(field: &str, x: f64) -> Result<(), LayoutError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(LayoutError::Invalid {
            field: field.to_string(),
            value: x,
            expected: "must be a finite number > 0".into(),
        })
    }
}

/// Departure speeds must not exceed what SUMO accepts at insertion: the vehicle type's
/// maxSpeed and the road's speed limit.
fn check_departure_speeds(
    road: &Road,
    vtype: &SumoVehicleType,
    speeds_mps: &[f64],
) -> Result<(), LayoutError> {
    let limit = vtype.max_speed_mps.min(road.speed_limit_mps());
    for (i, v) in speeds_mps.iter().enumerate() {
        if !(v.is_finite() && *v >= 0.0 && *v <= limit) {
            return Err(LayoutError::Invalid {
                field: format!("initial speed of vehicle {i}"),
                value: *v,
                expected: format!(
                    "must lie in [0, {limit}] m/s (sumo.max_speed_mps = {}, speed limit of {} = {} m/s); SUMO refuses faster departures",
                    vtype.max_speed_mps,
                    road.path.display(),
                    road.speed_limit_mps()
                ),
            });
        }
    }
    Ok(())
}

/// Checks that `n` vehicles of the given lengths fit on the ring: `Σ (ℓ_i + minGap) ≤ L`.
pub fn check_ring_capacity(
    road: &Road,
    lengths_m: &[f64],
    min_gap_m: f64,
) -> Result<(), LayoutError> {
    let ring = road.length_m();
    let needed: f64 = lengths_m.iter().map(|l| l + min_gap_m).sum();
    if needed > ring {
        let longest = lengths_m.iter().copied().fold(0.0, f64::max);
        return Err(LayoutError::RingOverfull {
            net: road.path.display().to_string(),
            vehicles: lengths_m.len(),
            length_m: longest,
            min_gap_m,
            needed_m: needed,
            ring_m: ring,
            max_vehicles: (ring / (longest + min_gap_m)).floor() as usize,
        });
    }
    Ok(())
}

/// Lays out `n` vehicles on a ring: vehicle 0's rear bumper at 0, vehicle i one length plus
/// its (scaled) gap behind vehicle i−1, as in the native simulator. The scenario's gaps are
/// scaled by one common factor so that lengths plus gaps equal SUMO's ring length.
pub fn ring_layout(
    road: &Road,
    vtype: SumoVehicleType,
    lengths_m: &[f64],
    gaps_m: &[f64],
    speeds_mps: &[f64],
    horizon_s: f64,
) -> Result<Layout, LayoutError> {
    for (i, l) in lengths_m.iter().enumerate() {
        check_pos(&format!("length_m[{i}]"), *l)?;
    }
    check_ring_capacity(road, lengths_m, vtype.min_gap_m)?;
    check_departure_speeds(road, &vtype, speeds_mps)?;
    let ring = road.length_m();
    let free = ring - lengths_m.iter().sum::<f64>();
    let gap_sum: f64 = gaps_m.iter().sum();
    let gap_scale = if gap_sum > 0.0 { free / gap_sum } else { 1.0 };
    let mut vehicles = Vec::with_capacity(lengths_m.len());
    let mut fronts = Vec::with_capacity(lengths_m.len());
    let mut q = 0.0;
    for i in 0..lengths_m.len() {
        if i > 0 {
            q -= lengths_m[i] + gaps_m[i] * gap_scale;
        }
        fronts.push(q + lengths_m[i]);
    }
    let offset = off_junctions(road, &fronts);
    let mut q = 0.0;
    for i in 0..lengths_m.len() {
        if i > 0 {
            q -= lengths_m[i] + gaps_m[i] * gap_scale;
        }
        // Positions are relative: turning the whole layout by `offset` along the loop changes
        // no gap; a vehicle still moved off a junction lane starts where SUMO puts it.
        let front = q + lengths_m[i] + offset;
        let moved = road.junction_overlap_m(front);
        let (edge_index, pos_m) = road.locate(front);
        let q = if moved > MAX_JUNCTION_SHIFT_M {
            q + moved
        } else {
            q
        };
        vehicles.push(Departure {
            id: format!("v{i}"),
            driver: None,
            length_m: lengths_m[i],
            edge_index,
            pos_m,
            speed_mps: speeds_mps[i],
            q0_m: q,
        });
    }
    // Speed mode 32 lets commands exceed maxSpeed (and the lane limit), so the route is sized
    // for twice the faster of the two; a vehicle that still reaches its end is reported as
    // lost, never silently removed.
    let fastest = vtype.max_speed_mps.max(road.speed_limit_mps());
    let laps = horizon_s * 2.0 * fastest / ring;
    let repeats = laps.ceil() + 2.0;
    if repeats.is_nan() || repeats > f64::from(i32::MAX) {
        return Err(LayoutError::TooManyLaps {
            net: road.path.display().to_string(),
            horizon_s,
            repeats,
            ring_m: ring,
            speed_mps: 2.0 * fastest,
            max_horizon_s: (f64::from(i32::MAX) - 3.0) * ring / (2.0 * fastest),
        });
    }
    Ok(Layout {
        road: road.clone(),
        vtype,
        vehicles,
        leader_vehicle: false,
        gap_scale,
        route_repeats: repeats as usize,
        ring_offset_m: offset,
    })
}

/// Lays out a platoon on a straight road. With `leader = Some((q0, length, travel_m))` a
/// leader vehicle with rear bumper at `q0` (native coordinates) is placed first; `travel_m`
/// bounds how far it drives over the horizon. Followers are at the given rear-bumper
/// positions `q_m`. The whole platoon is shifted so the last rear bumper starts 1 m into the
/// road.
#[allow(clippy::too_many_arguments)]
pub fn straight_layout(
    road: &Road,
    vtype: SumoVehicleType,
    lengths_m: &[f64],
    q_m: &[f64],
    speeds_mps: &[f64],
    leader: Option<(f64, f64, f64)>,
    leader_speed_mps: f64,
    horizon_s: f64,
) -> Result<Layout, LayoutError> {
    check_departure_speeds(road, &vtype, speeds_mps)?;
    check_departure_speeds(road, &vtype, &[leader_speed_mps])?;
    let mut all: Vec<(String, f64, f64, f64)> = Vec::new();
    if let Some((q0, len, _)) = leader {
        all.push(("leader".into(), len, q0, leader_speed_mps));
    }
    for i in 0..lengths_m.len() {
        check_pos(&format!("length_m[{i}]"), lengths_m[i])?;
        all.push((format!("v{i}"), lengths_m[i], q_m[i], speeds_mps[i]));
    }
    let rear = all.iter().map(|v| v.2).fold(f64::INFINITY, f64::min);
    let front = all
        .iter()
        .map(|v| v.2 + v.1)
        .fold(f64::NEG_INFINITY, f64::max);
    let shift = 1.0 - rear;
    let platoon = front - rear;
    let max_speed = all.iter().map(|v| v.3).fold(vtype.max_speed_mps, f64::min);
    let travel = match leader {
        Some((_, _, t)) => t,
        None => horizon_s * max_speed.max(all.iter().map(|v| v.3).fold(0.0, f64::max)),
    };
    let needed = 1.0 + platoon + travel;
    if needed > road.length_m() {
        return Err(LayoutError::RoadTooShort {
            net: road.path.display().to_string(),
            road_m: road.length_m(),
            needed_m: needed,
            platoon_m: platoon,
            horizon_s,
        });
    }
    // On a route of several edges the front bumper may lie on a later edge (or on a junction
    // lane, moved to the start of the next edge as on a ring).
    let vehicles = all
        .into_iter()
        .map(|(id, len, q, v)| {
            let moved = road.junction_overlap_m(q + len + shift);
            let (edge_index, pos_m) = road.locate(q + len + shift);
            Departure {
                id,
                driver: None,
                length_m: len,
                edge_index,
                pos_m,
                speed_mps: v,
                // A vehicle moved off a junction lane starts where SUMO puts it.
                q0_m: if moved > MAX_JUNCTION_SHIFT_M {
                    q + moved
                } else {
                    q
                },
            }
        })
        .collect();
    Ok(Layout {
        road: road.clone(),
        vtype,
        vehicles,
        leader_vehicle: leader.is_some(),
        gap_scale: 1.0,
        route_repeats: 0,
        ring_offset_m: 0.0,
    })
}

/// vType attributes written for every vehicle type; a driver's own value replaces the
/// scenario's (`length` is the layout's).
const BASE: [&str; 8] = [
    "length",
    "minGap",
    "accel",
    "decel",
    "emergencyDecel",
    "maxSpeed",
    "speedFactor",
    "speedDev",
];

impl Layout {
    /// The SUMO routes file (vehicle types, routes, vehicles) of this layout. Deterministic
    /// text; vehicles depart at t = 0 at their exact positions and speeds
    /// (`insertionChecks="none"`: the layout has already been checked).
    pub fn routes_xml(&self) -> String {
        self.routes_xml_with(true)
    }

    /// [`Layout::routes_xml`], with syncroad's vehicles or without them (the law then drives
    /// the user's own, `sumo.controlled`: the file keeps the routes their adoption sets).
    pub fn routes_xml_with(&self, vehicles: bool) -> String {
        use quick_xml::escape::escape as esc;
        let mut s = String::from("<routes>\n");
        let t = &self.vtype;
        // One vType per (length, driver). Law-driven vehicles get σ = 0: SUMO's own model only
        // acts on them when the law does not command them, and then without randomness.
        let mut types: Vec<(u64, Option<SumoDriver>)> = Vec::new();
        for v in &self.vehicles {
            let key = (v.length_m.to_bits(), v.driver.clone());
            if !types.contains(&key) {
                types.push(key);
                // A driver's own values (a preset's accel, decel, minGap, maxSpeed) replace
                // the scenario's; its other parameters follow its carFollowModel. Lengths are
                // the layout's (a preset's length is checked to match before SUMO starts).
                let cf = v.driver.as_ref().map(|d| d.car_following());
                let own = |name: &str, x: f64| {
                    cf.as_ref()
                        .and_then(|c| c.params.get(name).copied())
                        .unwrap_or(x)
                };
                let model = match &cf {
                    Some(c) => {
                        let mut m = format!(r#"carFollowModel="{}""#, c.model.sumo_name());
                        for (name, x) in
                            c.params.iter().filter(|(k, _)| !BASE.contains(&k.as_str()))
                        {
                            let _ = write!(m, r#" {name}="{x}""#);
                        }
                        m
                    }
                    None => r#"sigma="0""#.to_string(),
                };
                let params = v
                    .driver
                    .as_ref()
                    .map(|d| d.vtype_params())
                    .unwrap_or_default();
                let close = if params.is_empty() { "/>" } else { ">" };
                let _ = writeln!(
                    s,
                    r#"    <vType id="t{}" length="{}" minGap="{}" accel="{}" decel="{}" emergencyDecel="{}" maxSpeed="{}" {model} speedFactor="{}" speedDev="{}" emissionClass="{}" vClass="{}"{close}"#,
                    types.len() - 1,
                    v.length_m,
                    own("minGap", t.min_gap_m),
                    own("accel", t.accel_mps2),
                    own("decel", t.decel_mps2),
                    own("emergencyDecel", t.emergency_decel_mps2),
                    own("maxSpeed", t.max_speed_mps),
                    own("speedFactor", 1.0),
                    own("speedDev", 0.0),
                    EMISSION_CLASS,
                    t.vclass,
                );
                if !params.is_empty() {
                    for (key, value) in &params {
                        let (key, value) = (esc(*key), esc(value.as_str()));
                        let _ = writeln!(s, r#"        <param key="{key}" value="{value}"/>"#);
                    }
                    s.push_str("    </vType>\n");
                }
            }
        }
        // The network's edge ids and the vehicles' ids are the user's: escaped, as every
        // other writer of SUMO's XML does.
        let edges: Vec<String> = self
            .road
            .normal_edges()
            .into_iter()
            .map(|e| esc(e).into_owned())
            .collect();
        let k = edges.len();
        for start in 0..k {
            let list: Vec<&str> = if self.road.ring {
                (0..k).map(|j| edges[(start + j) % k].as_str()).collect()
            } else {
                edges[start..].iter().map(String::as_str).collect()
            };
            if self.road.ring {
                let _ = writeln!(
                    s,
                    r#"    <route id="r{start}" edges="{}" repeat="{}"/>"#,
                    list.join(" "),
                    self.route_repeats
                );
            } else {
                let _ = writeln!(
                    s,
                    r#"    <route id="r{start}" edges="{}"/>"#,
                    list.join(" ")
                );
            }
        }
        let lanes = self.road.lanes();
        for v in self.vehicles.iter().filter(|_| vehicles) {
            let ty = types
                .iter()
                .position(|k| k.0 == v.length_m.to_bits() && k.1 == v.driver)
                .expect("type written above");
            let _ = writeln!(
                s,
                r#"    <vehicle id="{}" type="t{ty}" route="r{}" depart="0" departLane="{}" departPos="{}" departSpeed="{}" insertionChecks="none"/>"#,
                esc(&v.id),
                v.edge_index,
                lanes.get(v.edge_index).copied().unwrap_or(0),
                v.pos_m,
                v.speed_mps
            );
        }
        s.push_str("</routes>\n");
        s
    }

    /// Writes [`Layout::routes_xml_with`] to `dir/routes.rou.xml` and returns the path.
    pub fn write_routes(&self, dir: &Path, vehicles: bool) -> std::io::Result<PathBuf> {
        std::fs::create_dir_all(dir)?;
        let p = dir.join("routes.rou.xml");
        std::fs::write(&p, self.routes_xml_with(vehicles))?;
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::read_ring;
    use approx::assert_relative_eq;

    fn vt() -> SumoVehicleType {
        SumoVehicleType {
            min_gap_m: 2.5,
            accel_mps2: 2.6,
            decel_mps2: 4.5,
            emergency_decel_mps2: 9.0,
            max_speed_mps: 30.0,
            vclass: syncroad_control::scenario::VehicleClass::PASSENGER,
        }
    }

    fn sugiyama() -> Road {
        read_ring(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../sumo-nets/sugiyama-ring.net.xml"),
        )
        .unwrap()
    }

    /// A route of two 100 m edges joined by a 10 m junction lane.
    fn two_edge_route() -> Road {
        let seg = |edge: &str, len: f64, internal: bool| crate::net::Segment {
            edge: edge.into(),
            lane: format!("{edge}_1"),
            length_m: len,
            internal,
            speed_mps: 30.0,
        };
        Road {
            path: PathBuf::from("route.net.xml"),
            segments: vec![
                seg("a", 100.0, false),
                seg(":j_0", 10.0, true),
                seg("b", 100.0, false),
            ],
            ring: false,
            multi_lane: true,
        }
    }

    #[test]
    fn route_departures_lie_on_normal_lanes_at_their_true_positions() {
        let road = two_edge_route();
        assert_eq!(road.junction_overlap_m(104.0), 6.0);
        assert_eq!(road.junction_overlap_m(99.0), 0.0);
        assert_eq!(road.junction_overlap_m(110.5), 0.0);
        // Rear bumpers at 120, 98 and 0 (native coordinates); the platoon starts 1 m into
        // the road, so the fronts are at 126, 104 and 6.
        let lay = straight_layout(
            &road,
            vt(),
            &[5.0; 3],
            &[120.0, 98.0, 0.0],
            &[8.0; 3],
            None,
            8.0,
            1.0,
        )
        .unwrap();
        let v = &lay.vehicles;
        assert_eq!((v[0].edge_index, v[0].pos_m), (1, 16.0));
        assert_eq!((v[2].edge_index, v[2].pos_m), (0, 6.0));
        // Vehicle 1's front (104) lay 4 m into the junction lane: SUMO gets it at the start of
        // `b`, 6 m further on, and its start position says so.
        assert_eq!((v[1].edge_index, v[1].pos_m), (1, 0.0));
        assert_eq!(v[1].q0_m, 104.0);
        assert!(lay.routes_xml().contains(r#"<route id="r1" edges="b"/>"#));
        assert!(lay.routes_xml().contains(r#"departLane="1""#));
    }

    /// A network's edge ids are the user's: characters XML gives a meaning reach SUMO's route
    /// file escaped, and an XML reader gets the ids back as they were.
    #[test]
    fn the_routes_escape_the_networks_edge_ids() {
        let mut road = two_edge_route();
        road.segments[0].edge = r#"a&"<1>"#.into();
        let lay = straight_layout(
            &road,
            vt(),
            &[5.0; 2],
            &[20.0, 0.0],
            &[8.0; 2],
            None,
            8.0,
            1.0,
        )
        .unwrap();
        let xml = lay.routes_xml();
        assert!(xml.contains(r#"edges="a&amp;&quot;&lt;1&gt; b""#), "{xml}");
        let mut reader = quick_xml::Reader::from_str(&xml);
        let mut edges = Vec::new();
        loop {
            match reader.read_event().expect("well-formed XML") {
                quick_xml::events::Event::Empty(e) if e.name().as_ref() == b"route" => {
                    let a = e.try_get_attribute("edges").unwrap().unwrap();
                    let raw = String::from_utf8_lossy(&a.value).into_owned();
                    edges.push(quick_xml::escape::unescape(&raw).unwrap().into_owned());
                }
                quick_xml::events::Event::Eof => break,
                _ => {}
            }
        }
        assert_eq!(edges, [r#"a&"<1> b"#, "b"]);
    }

    #[test]
    fn overfull_ring_names_the_numbers() {
        let road = sugiyama();
        let err = check_ring_capacity(&road, &[5.0; 31], 2.5).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.contains(
                "31 vehicles × (length 5 m + minGap 2.5 m) = 232.50 m exceed its length 230.3592 m"
            ),
            "{msg}"
        );
        assert!(msg.contains("use at most 30 vehicles"), "{msg}");
        assert!(check_ring_capacity(&road, &[5.0; 30], 2.5).is_ok());
    }

    #[test]
    fn departure_faster_than_max_speed_is_rejected() {
        let road = sugiyama();
        let mut t = vt();
        t.max_speed_mps = 9.0;
        let err = ring_layout(&road, t, &[5.0; 3], &[10.0; 3], &[8.0, 9.5, 8.0], 10.0).unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("initial speed of vehicle 1 = 9.5 is invalid: must lie in [0, 9] m/s (sumo.max_speed_mps = 9, speed limit of "), "{msg}");
    }

    #[test]
    fn horizons_beyond_sumo_route_repeats_are_refused() {
        // 1e12 s at 2 × 30 m/s on 230 m is 2.6e11 laps: SUMO's 32-bit repeat count would
        // overflow and every vehicle would leave the ring after one lap.
        let road = sugiyama();
        let err = ring_layout(&road, vt(), &[5.0; 3], &[10.0; 3], &[8.0; 3], 1e12).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.starts_with("horizon_s = 1000000000000 s needs 2.605e11 laps of the 230.4 m ring"),
            "{msg}"
        );
        assert!(
            msg.contains("at most 2147483647); give horizon_s ≤ 8244"),
            "{msg}"
        );
        let max_h = 8.2e9;
        let lay = ring_layout(&road, vt(), &[5.0; 3], &[10.0; 3], &[8.0; 3], max_h).unwrap();
        assert!(lay.route_repeats <= i32::MAX as usize);
    }

    #[test]
    fn even_ring_layout_fills_sumo_length() {
        let road = sugiyama();
        let n = 22;
        let gaps = vec![(230.0 - 5.0 * n as f64) / n as f64; n];
        let lay = ring_layout(&road, vt(), &vec![5.0; n], &gaps, &vec![8.0; n], 60.0).unwrap();
        assert_relative_eq!(
            lay.gap_scale * gaps[0] * n as f64 + 5.0 * n as f64,
            road.length_m(),
            epsilon = 1e-9
        );
        // The last vehicle's gap to vehicle 0 (one lap ahead) equals the others.
        let q_last = lay.vehicles[n - 1].q0_m;
        assert_relative_eq!(
            road.length_m() + q_last - 5.0,
            lay.gap_scale * gaps[0],
            epsilon = 1e-9
        );
        assert!(lay
            .routes_xml()
            .contains(r#"<route id="r0" edges="arc0 arc1 arc2 arc3" repeat=""#));
        assert_eq!(
            lay.route_repeats,
            (60.0 * 2.0 * 30.0 / road.length_m()).ceil() as usize + 2
        );
    }

    #[test]
    fn sumo_drivers_get_their_own_vtype_and_every_type_an_emission_class() {
        let road = sugiyama();
        let n = 4;
        let mut lay = ring_layout(&road, vt(), &[5.0; 4], &[20.0; 4], &[8.0; 4], 10.0).unwrap();
        lay.vehicles[1].driver = Some(SumoDriver::parse("d", "idm").unwrap());
        lay.vehicles[2].driver = Some(SumoDriver::Krauss { sigma: 0.9 });
        let xml = lay.routes_xml();
        assert_eq!(xml.matches("<vType ").count(), 3, "{xml}");
        assert_eq!(
            xml.matches(r#"emissionClass="HBEFA4/PC_petrol_Euro-6ab""#)
                .count(),
            3
        );
        assert!(xml.contains(r#"carFollowModel="IDM""#), "{xml}");
        assert!(
            xml.contains(r#"carFollowModel="Krauss" sigma="0.9""#),
            "{xml}"
        );
        assert!(xml.contains(r#"<vehicle id="v1" type="t1""#), "{xml}");
        assert!(xml.contains(r#"<vehicle id="v3" type="t0""#), "{xml}");
        assert_eq!(lay.vehicles.len(), n);
        // A preset's own values replace the scenario's, each attribute written once.
        lay.vehicles[3].driver = Some(SumoDriver::parse("d", "human").unwrap());
        let xml = lay.routes_xml();
        assert!(
            xml.contains(r#"length="5" minGap="2" accel="1.3" decel="1.5" emergencyDecel="9" maxSpeed="30" carFollowModel="IDM" delta="4" tau="0.8" speedFactor="1""#),
            "{xml}"
        );
    }

    /// A driver's speedFactor and speedDev replace the defaults instead of being written a
    /// second time (SUMO refuses a vType with a duplicate attribute); an XML parser, which
    /// refuses duplicates as SUMO does, reads every type.
    #[test]
    fn a_drivers_speed_factor_and_deviation_are_written_once() {
        let road = sugiyama();
        let mut lay = ring_layout(&road, vt(), &[5.0; 4], &[20.0; 4], &[8.0; 4], 10.0).unwrap();
        for (i, d) in [
            "idm:speedDev=0.1",
            "idm:speedFactor=1.2:speedDev=0.05",
            "krauss:sigma=0.5:speedFactor=0.9",
        ]
        .iter()
        .enumerate()
        {
            lay.vehicles[i].driver = Some(SumoDriver::parse("--driver", d).unwrap());
        }
        let xml = lay.routes_xml();
        let doc = roxmltree::Document::parse(&xml).unwrap_or_else(|e| panic!("{e}\n{xml}"));
        let types: Vec<_> = doc
            .descendants()
            .filter(|n| n.has_tag_name("vType"))
            .map(|n| {
                (
                    n.attribute("speedFactor").unwrap().to_string(),
                    n.attribute("speedDev").unwrap().to_string(),
                )
            })
            .collect();
        assert!(types.contains(&("1".into(), "0.1".into())), "{types:?}");
        assert!(types.contains(&("1.2".into(), "0.05".into())), "{types:?}");
        assert!(types.contains(&("0.9".into(), "0".into())), "{types:?}");
    }
}
