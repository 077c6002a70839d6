//! Reading a SUMO network file before SUMO starts: which roads it holds, in driving order, and
//! how long they are.
//!
//! SUMO itself is never asked about a file that has not passed these checks, because libsumo
//! crashes the whole process on malformed nets. The lengths read here are the numbers SUMO
//! loads; the worker cross-checks them against `lane.getLength` once SUMO runs.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

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
    #[error("SUMO network {path}: edge `{edge}` has {lanes} lanes; syncroad drives single-lane roads only")]
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
    /// The scenario wants a straight road but the network is not one edge.
    #[error("SUMO network {path} is not a straight road: it has {edges} normal edges, expected 1 (e.g. sumo-nets/straight-20km.net.xml)")]
    NotStraight {
        /// The file.
        path: PathBuf,
        /// Number of normal edges.
        edges: usize,
    },
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
}

impl Road {
    /// Total length \[m\]: for a ring, the circumference as SUMO measures it (normal plus
    /// internal lanes).
    pub fn length_m(&self) -> f64 {
        self.segments.iter().map(|s| s.length_m).sum()
    }

    /// Lowest speed limit along the road [m/s].
    pub fn speed_limit_mps(&self) -> f64 {
        self.segments
            .iter()
            .map(|s| s.speed_mps)
            .fold(f64::INFINITY, f64::min)
    }

    /// Normal edges in driving order.
    pub fn normal_edges(&self) -> Vec<&str> {
        self.segments
            .iter()
            .filter(|s| !s.internal)
            .map(|s| s.edge.as_str())
            .collect()
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

/// A lane as parsed: id, length \[m\], speed limit [m/s].
type ParsedLane = (String, f64, f64);

struct Parsed {
    /// Normal edges in file order with their lanes.
    normal: Vec<(String, Vec<ParsedLane>)>,
    /// Every lane's length and speed limit.
    lane_length: HashMap<String, (f64, f64)>,
    /// (from edge, to edge, via lane) of every connection.
    connections: Vec<(String, String, Option<String>)>,
}

fn parse(path: &Path) -> Result<Parsed, NetError> {
    let text = std::fs::read_to_string(path).map_err(|e| NetError::Unreadable {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| NetError::Malformed {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let invalid = |reason: String| NetError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let root = doc.root_element();
    if root.tag_name().name() != "net" {
        return Err(invalid(format!(
            "root element is <{}>, expected <net>",
            root.tag_name().name()
        )));
    }
    let mut parsed = Parsed {
        normal: Vec::new(),
        lane_length: HashMap::new(),
        connections: Vec::new(),
    };
    for el in root.children().filter(|n| n.is_element()) {
        match el.tag_name().name() {
            "edge" => {
                let id = el
                    .attribute("id")
                    .ok_or_else(|| invalid("an <edge> has no id".into()))?;
                let internal = el.attribute("function") == Some("internal");
                let mut lanes = Vec::new();
                for lane in el.children().filter(|n| n.has_tag_name("lane")) {
                    let lid = lane
                        .attribute("id")
                        .ok_or_else(|| invalid(format!("a lane of edge `{id}` has no id")))?;
                    let len: f64 = lane
                        .attribute("length")
                        .and_then(|x| x.parse().ok())
                        .filter(|x: &f64| x.is_finite() && *x >= 0.0)
                        .ok_or_else(|| {
                            invalid(format!("lane `{lid}` has no valid length attribute"))
                        })?;
                    let speed: f64 = lane
                        .attribute("speed")
                        .and_then(|x| x.parse().ok())
                        .filter(|x: &f64| x.is_finite() && *x > 0.0)
                        .ok_or_else(|| {
                            invalid(format!("lane `{lid}` has no valid speed attribute"))
                        })?;
                    parsed.lane_length.insert(lid.to_string(), (len, speed));
                    lanes.push((lid.to_string(), len, speed));
                }
                if lanes.is_empty() {
                    return Err(invalid(format!("edge `{id}` has no <lane>")));
                }
                if !internal && el.attribute("function").is_none() {
                    parsed.normal.push((id.to_string(), lanes));
                }
            }
            "connection" => {
                let (Some(from), Some(to)) = (el.attribute("from"), el.attribute("to")) else {
                    return Err(invalid("a <connection> lacks from/to".into()));
                };
                parsed.connections.push((
                    from.to_string(),
                    to.to_string(),
                    el.attribute("via").map(str::to_string),
                ));
            }
            _ => {}
        }
    }
    if parsed.normal.is_empty() {
        return Err(invalid("no normal <edge> with lanes".into()));
    }
    for (id, lanes) in &parsed.normal {
        if lanes.len() != 1 {
            return Err(NetError::MultiLane {
                path: path.to_path_buf(),
                edge: id.clone(),
                lanes: lanes.len(),
            });
        }
    }
    Ok(parsed)
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
    })
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
        let dir = std::env::temp_dir().join(format!("syncroad-net-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("bad.net.xml");
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
