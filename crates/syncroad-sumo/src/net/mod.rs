//! Reading a SUMO network file before SUMO starts: which roads it holds, in driving order, and
//! how long they are.
//!
//! SUMO itself is never asked about a file that has not passed these checks, because libsumo
//! crashes the whole process on malformed nets. The lengths read here are the numbers SUMO
//! loads; the worker cross-checks them against `lane.getLength` once SUMO runs.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

mod config;
pub(crate) mod network;
pub(crate) mod roads;

pub use config::{read_config, ConfigError};
use network::Network;
pub use roads::{read_network_road, NetReader};

/// Errors reading a network file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NetError {
    /// The file does not exist or cannot be read.
    #[error("cannot read SUMO network {path}: {reason}")]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        reason: String,
    },
    /// The file is not well-formed XML.
    #[error("SUMO network {path} is not well-formed XML: {reason} (SUMO would crash on it; rebuild it with `bash sumo-nets/build.sh` or netconvert)")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line and column).
        reason: String,
    },
    /// The root element is not `<net>` or an element lacks a required attribute.
    #[error("SUMO network {path}: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A road has more than one lane (the loop drives single-lane roads).
    #[error("SUMO network {path}: edge `{edge}` has {lanes} lanes; road.type \"ring\" and \"straight\" take single-lane networks (like sumo-nets/sugiyama-ring.net.xml); on a road of several lanes give road.type \"loop\" (a closed cycle) or \"route\" (an open road) with its edges and the lane to drive (the guide's \"Your own network\")")]
    MultiLane {
        /// The file.
        path: PathBuf,
        /// The edge.
        edge: String,
        /// Its number of lanes.
        lanes: usize,
    },
    /// The scenario wants a ring but the normal edges do not form one closed cycle.
    #[error("SUMO network {path} is not a ring: {reason} (a ring is a cycle of single-lane edges, e.g. sumo-nets/sugiyama-ring.net.xml)")]
    NotARing {
        /// The file.
        path: PathBuf,
        /// Where the cycle breaks.
        reason: String,
    },
    /// An edge of `road.edges` (or `road.through`) is not a normal edge of the network.
    #[error("{field} = `{edge}`: {path} has no normal edge of that id; nearest ids: {nearest}")]
    UnknownEdge {
        /// The network.
        path: PathBuf,
        /// The scenario field (`road.edges[3]`).
        field: String,
        /// The id given.
        edge: String,
        /// The closest ids of the network (edit distance).
        nearest: String,
    },
    /// An edge has no lane of the chosen index.
    #[error("{lane_field} = {lane}: edge `{edge}` ({field}) has {lanes} lane(s), indices 0..={max}; choose a lane it has", max = lanes - 1)]
    LaneOutOfRange {
        /// The scenario field of the lane (`road.lane`, or `road.lane[2]` of a list).
        lane_field: String,
        /// The scenario field of the edge.
        field: String,
        /// The edge.
        edge: String,
        /// The lane index asked for.
        lane: usize,
        /// Its number of lanes.
        lanes: usize,
    },
    /// A lane of the road does not admit the vehicles' class.
    #[error("{field}: lane `{lane}` of {path} is closed to class {vclass} ({permissions}); syncroad's vehicles are of class {vclass} (sumo.vclass), so choose another lane (road.lane), edges open to them, or a class the lanes allow (sumo.vclass)")]
    LaneForbidden {
        /// The vehicles' class.
        vclass: &'static str,
        /// The network.
        path: PathBuf,
        /// The scenario field of the edge.
        field: String,
        /// The lane id (normal or junction-internal).
        lane: String,
        /// Its permissions as written.
        permissions: String,
    },
    /// Two consecutive edges have no connection from the chosen lane to the chosen lane.
    #[error(transparent)]
    NoConnection(Box<Disconnected>),
    /// `road.lane = "follow"`: no sequence of connected lanes open to the class runs the
    /// whole route.
    #[error(transparent)]
    NoLaneSequence(Box<NoLanes>),
    /// The last edge of a loop does not lead back to its first.
    #[error(transparent)]
    LoopNotClosed(Box<Unclosed>),
    /// An edge is listed twice.
    #[error("{field} = `{edge}` repeats {first_field}; a road passes each edge once")]
    RepeatedEdge {
        /// The later field.
        field: String,
        /// The edge.
        edge: String,
        /// The earlier field.
        first_field: String,
    },
    /// No cycle on the chosen lane passes the `through` edge.
    #[error("road.through = `{edge}`: no cycle on lane {lane} leads back to it through the connections of {path} ({detail}); give the cycle as road.edges, another edge or another lane")]
    NoCycle {
        /// The network.
        path: PathBuf,
        /// The edge.
        edge: String,
        /// The lane.
        lane: usize,
        /// What was reached.
        detail: String,
    },
    /// The scenario wants a straight road but the network is not one edge.
    #[error("SUMO network {path} is not a straight road: it has {edges} normal edges, expected 1 (e.g. sumo-nets/straight-20km.net.xml)")]
    NotStraight {
        /// The file.
        path: PathBuf,
        /// Number of normal edges.
        edges: usize,
    },
}

/// Two consecutive edges of a road with no connection from the lane chosen on the first to
/// the lane chosen on the next.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{from_field} `{from}` → {to_field} `{to}`: {path} connects no lane {from_lane} of `{from}` to lane {to_lane} of `{to}`; {joined}{hint}")]
pub struct Disconnected {
    /// The network.
    pub path: PathBuf,
    /// Field of the first edge.
    pub from_field: String,
    /// The first edge.
    pub from: String,
    /// Field of the second edge.
    pub to_field: String,
    /// The second edge.
    pub to: String,
    /// The lane on the first edge.
    pub from_lane: usize,
    /// The lane on the second edge.
    pub to_lane: usize,
    /// What does connect (lane pairs, or where the first edge leads).
    pub joined: String,
    /// How else the road could be given (a route may change lanes), or nothing.
    pub hint: &'static str,
}

/// A route with `road.lane = "follow"` that no sequence of connected lanes open to the
/// vehicles' class runs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("road.lane = \"follow\": no lane that the route reaches on {from_field} `{from}` leads on to {to_field} `{to}` through {path}'s connections for class {vclass}; {joined}")]
pub struct NoLanes {
    /// The network.
    pub path: PathBuf,
    /// Field of the edge the search got furthest to.
    pub from_field: String,
    /// That edge.
    pub from: String,
    /// Field of the edge it could not reach.
    pub to_field: String,
    /// That edge.
    pub to: String,
    /// The vehicles' class.
    pub vclass: &'static str,
    /// What does connect.
    pub joined: String,
}

/// A loop whose last edge does not lead back to its first on the chosen lane.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("road.edges: the loop does not close: {last_field} `{last}` has no connection back to road.edges[0] `{first}` on lane {lane} in {path}; {joined} (a loop lists its cycle in driving order; for an open road use road.type = \"route\")")]
pub struct Unclosed {
    /// The network.
    pub path: PathBuf,
    /// Field of the last edge.
    pub last_field: String,
    /// The last edge.
    pub last: String,
    /// The first edge.
    pub first: String,
    /// The lane.
    pub lane: usize,
    /// What does connect.
    pub joined: String,
}

/// One lane of the road in driving order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Edge id (internal edges start with `:`).
    pub edge: String,
    /// Lane id.
    pub lane: String,
    /// Lane length \[m\] as SUMO stores it.
    pub length_m: f64,
    /// True for a junction-internal lane (vehicles cannot depart there).
    pub internal: bool,
    /// Speed limit of the lane [m/s].
    pub speed_mps: f64,
}

/// A single-lane road: a closed ring or one straight edge.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Road {
    /// The network file.
    pub path: PathBuf,
    /// Lanes in driving order; for a ring the last one leads back to the first.
    pub segments: Vec<Segment>,
    /// True for a ring.
    pub ring: bool,
    /// True when an edge of the road has more than one lane: every vehicle syncroad inserts
    /// (law-driven or driven by a SUMO model) then keeps the road's lanes (lane-change mode
    /// 0: it changes lanes only where a connection leads it onto another), so the vehicles
    /// stay in the order the law's graph assumes.
    #[serde(default)]
    pub multi_lane: bool,
}

impl Road {
    /// Total length \[m\]: for a ring, the circumference as SUMO measures it (normal plus
    /// internal lanes).
    pub fn length_m(&self) -> f64 {
        self.segments.iter().map(|s| s.length_m).sum()
    }

    /// Lowest speed limit of the road's normal lanes [m/s] (vehicles depart there; a
    /// junction lane's lower turning speed binds SUMO's own drivers only).
    pub fn speed_limit_mps(&self) -> f64 {
        self.segments
            .iter()
            .filter(|s| !s.internal)
            .map(|s| s.speed_mps)
            .fold(f64::INFINITY, f64::min)
    }

    /// The lane index driven on each normal edge, in driving order (0 on the built-in
    /// single-lane nets).
    pub fn lanes(&self) -> Vec<usize> {
        self.segments
            .iter()
            .filter(|s| !s.internal)
            .map(|s| network::split_lane(&s.lane).1.unwrap_or(0))
            .collect()
    }

    /// Normal edges in driving order.
    pub fn normal_edges(&self) -> Vec<&str> {
        self.segments
            .iter()
            .filter(|s| !s.internal)
            .map(|s| s.edge.as_str())
            .collect()
    }

    /// How far forward a point `s` \[m\] along the road moves when [`Road::locate`] puts it
    /// on a normal edge: the rest of the junction-internal lanes it lies on, 0 on a normal lane.
    pub fn junction_overlap_m(&self, s: f64) -> f64 {
        let total = self.length_m();
        let mut s = if self.ring { s.rem_euclid(total) } else { s };
        let mut inside: Option<f64> = None;
        for seg in &self.segments {
            if let Some(rest) = inside.as_mut() {
                if !seg.internal {
                    return *rest;
                }
                *rest += seg.length_m;
                continue;
            }
            if s < seg.length_m {
                if !seg.internal {
                    return 0.0;
                }
                inside = Some(seg.length_m - s);
            }
            s -= seg.length_m;
        }
        inside.unwrap_or(0.0)
    }

    /// Where a point `s` \[m\] along the road lies: (index of the normal edge in
    /// [`Road::normal_edges`], position on it \[m\]). A point on a junction-internal lane moves
    /// forward to the start of the next edge (at most the internal lane's length, a few cm on
    /// the shipped rings). `s` is wrapped modulo the length on a ring.
    pub fn locate(&self, s: f64) -> (usize, f64) {
        let total = self.length_m();
        let mut s = if self.ring { s.rem_euclid(total) } else { s };
        let mut normal = 0usize;
        let count = self.segments.iter().filter(|x| !x.internal).count();
        for seg in &self.segments {
            if s < seg.length_m || std::ptr::eq(seg, self.segments.last().expect("a road")) {
                if seg.internal {
                    return (normal % count, 0.0);
                }
                return (normal, s.min(seg.length_m));
            }
            s -= seg.length_m;
            if !seg.internal {
                normal += 1;
            }
        }
        (count - 1, 0.0)
    }
}

/// Where the induction loop `loop0` sits on a ring: lane, position on it \[m\] and the ring
/// coordinate of that point \[m\] (10 m into the first normal lane, or its middle).
pub fn loop_position(road: &Road) -> Option<(String, f64, f64)> {
    if !road.ring {
        return None;
    }
    let mut offset = 0.0;
    for seg in &road.segments {
        if !seg.internal {
            let pos = (seg.length_m / 2.0).min(10.0);
            return Some((seg.lane.clone(), pos, offset + pos));
        }
        offset += seg.length_m;
    }
    None
}

/// The farthest a vehicle's start may move forward off a junction-internal lane before the
/// layout turns around the loop to avoid it \[m\] (the shipped rings' joints are 0.1 m).
pub const MAX_JUNCTION_SHIFT_M: f64 = 0.5;

/// Vehicles depart on normal lanes only. When a front bumper of `fronts` lies more than
/// [`MAX_JUNCTION_SHIFT_M`] inside a junction lane, the shift along the loop (at most one lap)
/// that puts every front bumper on a normal lane, 1 cm past a lane start; 0 when none is
/// needed or none is found (for large fleets only vehicle 0's candidates are tried).
pub(crate) fn off_junctions(road: &Road, fronts: &[f64]) -> f64 {
    let worst = |d: f64| {
        fronts
            .iter()
            .map(|f| road.junction_overlap_m(f + d))
            .fold(0.0, f64::max)
    };
    if worst(0.0) <= MAX_JUNCTION_SHIFT_M {
        return 0.0;
    }
    let mut starts = Vec::new();
    let mut s = 0.0;
    for seg in &road.segments {
        if !seg.internal {
            starts.push(s);
        }
        s += seg.length_m;
    }
    let tried = if fronts.len() * starts.len() > 20_000 {
        &fronts[..1]
    } else {
        fronts
    };
    let mut best = (worst(0.0), 0.0);
    for f in tried {
        for st in &starts {
            let d = (st + 0.01 - f).rem_euclid(road.length_m());
            let w = worst(d);
            if w < best.0 || (w == best.0 && d < best.1) {
                best = (w, d);
            }
            if w == 0.0 {
                return d;
            }
        }
    }
    best.1
}

/// A lane as parsed: id, length \[m\], speed limit [m/s].
type ParsedLane = (String, f64, f64);

/// A single-lane network as the built-in rings and straight roads read it.
struct Parsed {
    /// Normal edges in file order with their lanes.
    normal: Vec<(String, Vec<ParsedLane>)>,
    /// Every lane's length and speed limit.
    lane_length: HashMap<String, (f64, f64)>,
    /// (from edge, to edge, via lane) of every connection.
    connections: Vec<(String, String, Option<String>)>,
}

/// Reads a network whose normal edges all have one lane.
fn parse(path: &Path) -> Result<Parsed, NetError> {
    let net = Network::read(path)?;
    let lane = |l: &network::Lane| (l.id.clone(), l.length_m, l.speed_mps);
    let normal: Vec<(String, Vec<ParsedLane>)> = net
        .normal
        .iter()
        .map(|(id, lanes)| (id.clone(), lanes.iter().map(lane).collect()))
        .collect();
    for (id, lanes) in &normal {
        if lanes.len() != 1 {
            return Err(NetError::MultiLane {
                path: path.to_path_buf(),
                edge: id.clone(),
                lanes: lanes.len(),
            });
        }
    }
    let mut connections = Vec::new();
    // One fixed order of the sources (a map has none), so that every read is the same.
    let mut sources: Vec<&String> = net.connections.keys().collect();
    sources.sort();
    for from in sources {
        for c in &net.connections[from] {
            connections.push((from.clone(), c.to.clone(), c.via.clone()));
        }
    }
    Ok(Parsed {
        normal,
        lane_length: net
            .lanes
            .values()
            .map(|l| (l.id.clone(), (l.length_m, l.speed_mps)))
            .collect(),
        connections,
    })
}

fn edge_of_lane(lane: &str) -> &str {
    lane.rsplit_once('_').map(|(e, _)| e).unwrap_or(lane)
}

/// Reads a ring: the normal edges must form one cycle through single-lane connections.
pub fn read_ring(path: &Path) -> Result<Road, NetError> {
    let p = parse(path)?;
    let not_ring = |reason: String| NetError::NotARing {
        path: path.to_path_buf(),
        reason,
    };
    let normal: HashMap<&str, (f64, f64)> = p
        .normal
        .iter()
        .map(|(id, lanes)| (id.as_str(), (lanes[0].1, lanes[0].2)))
        .collect();
    let mut segments = Vec::new();
    let start = p.normal[0].0.as_str();
    let mut current = start;
    for _ in 0..p.normal.len() {
        segments.push(Segment {
            edge: current.to_string(),
            lane: p
                .normal
                .iter()
                .find(|(id, _)| id == current)
                .expect("normal")
                .1[0]
                .0
                .clone(),
            length_m: normal[current].0,
            internal: false,
            speed_mps: normal[current].1,
        });
        let outgoing: Vec<_> = p
            .connections
            .iter()
            .filter(|(f, t, _)| f == current && normal.contains_key(t.as_str()))
            .collect();
        let [(_, to, via)] = outgoing.as_slice() else {
            return Err(not_ring(format!(
                "edge `{current}` has {} outgoing connections to normal edges, expected 1",
                outgoing.len()
            )));
        };
        // Follow the chain of internal lanes between the two edges.
        let mut via = via.clone();
        let mut guard = 0;
        while let Some(lane) = via {
            let (len, speed) = *p
                .lane_length
                .get(&lane)
                .ok_or_else(|| not_ring(format!("connection via unknown lane `{lane}`")))?;
            let edge = edge_of_lane(&lane).to_string();
            segments.push(Segment {
                edge: edge.clone(),
                lane: lane.clone(),
                length_m: len,
                internal: true,
                speed_mps: speed,
            });
            via = p
                .connections
                .iter()
                .find(|(f, t, _)| *f == edge && t == to)
                .and_then(|(_, _, v)| v.clone());
            guard += 1;
            if guard > 16 {
                return Err(not_ring(format!("internal lanes after `{current}` loop")));
            }
        }
        current = to.as_str();
        if current == start {
            break;
        }
    }
    if current != start {
        return Err(not_ring(format!(
            "following the connections from `{start}` does not return to it"
        )));
    }
    let visited = segments.iter().filter(|s| !s.internal).count();
    if visited != p.normal.len() {
        return Err(not_ring(format!(
            "the cycle through `{start}` visits {visited} of {} normal edges",
            p.normal.len()
        )));
    }
    Ok(Road {
        path: path.to_path_buf(),
        segments,
        ring: true,
        multi_lane: false,
    })
}

/// Reads a straight road: exactly one normal single-lane edge.
pub fn read_straight(path: &Path) -> Result<Road, NetError> {
    let p = parse(path)?;
    if p.normal.len() != 1 {
        return Err(NetError::NotStraight {
            path: path.to_path_buf(),
            edges: p.normal.len(),
        });
    }
    let (id, lanes) = &p.normal[0];
    Ok(Road {
        path: path.to_path_buf(),
        segments: vec![Segment {
            edge: id.clone(),
            lane: lanes[0].0.clone(),
            length_m: lanes[0].1,
            internal: false,
            speed_mps: lanes[0].2,
        }],
        ring: false,
        multi_lane: false,
    })
}

/// Whether the network `net` has traffic lights (a `tlLogic` element): its signals bind only
/// vehicles that keep SUMO's checks, so a law drives under them by default. An unreadable file
/// has none (reading it for the road reported the error already).
pub fn has_traffic_lights(net: &Path) -> bool {
    std::fs::read(net).is_ok_and(|b| b.windows(9).any(|w| w == b"<tlLogic "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn nets() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../sumo-nets")
    }

    #[test]
    fn sugiyama_ring_is_four_arcs_and_four_joints() {
        let road = read_ring(&nets().join("sugiyama-ring.net.xml")).unwrap();
        assert_eq!(road.segments.len(), 8);
        assert_eq!(road.normal_edges(), vec!["arc0", "arc1", "arc2", "arc3"]);
        // Chords of a 230 m circle plus four 0.1 m joints: a little under the nominal length.
        assert_relative_eq!(road.length_m(), 4.0 * 57.4898 + 4.0 * 0.1, epsilon = 1e-9);
        assert!((road.length_m() - 230.0).abs() < 0.5);
    }

    #[test]
    fn locate_wraps_and_skips_junctions() {
        let road = read_ring(&nets().join("sugiyama-ring.net.xml")).unwrap();
        assert_eq!(road.locate(10.0), (0, 10.0));
        // Inside the joint after arc0: moved to the start of arc1.
        assert_eq!(road.locate(57.5), (1, 0.0));
        // 1 m behind the start: 0.1 m of joint, then 0.9 m before the end of arc3.
        let (e, p) = road.locate(-1.0);
        assert_eq!(e, 3);
        assert_relative_eq!(p, 57.4898 - 0.9, epsilon = 1e-9);
    }

    #[test]
    fn malformed_xml_is_rejected_with_the_parser_position() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("bad.net.xml");
        std::fs::write(&f, "<net><edge id='x'>").unwrap();
        let err = read_ring(&f).unwrap_err();
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!(
                "SUMO network {} is not well-formed XML:",
                f.display()
            )),
            "{msg}"
        );
        assert!(msg.contains("SUMO would crash on it"), "{msg}");
    }

    #[test]
    fn missing_file_is_named() {
        let err = read_ring(Path::new("/nonexistent/ring.net.xml")).unwrap_err();
        assert!(err
            .to_string()
            .starts_with("cannot read SUMO network /nonexistent/ring.net.xml: "));
    }

    #[test]
    fn straight_road_is_not_a_ring() {
        let err = read_ring(&nets().join("straight-20km.net.xml")).unwrap_err();
        assert!(
            err.to_string()
                .contains("is not a ring: edge `road` has 0 outgoing"),
            "{err}"
        );
        let road = read_straight(&nets().join("straight-20km.net.xml")).unwrap();
        assert_relative_eq!(road.length_m(), 20_000.0, epsilon = 1e-6);
        let err = read_straight(&nets().join("ring-20km.net.xml")).unwrap_err();
        assert!(err.to_string().contains("it has 4 normal edges"), "{err}");
    }
}
