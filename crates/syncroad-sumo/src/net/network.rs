//! A SUMO `.net.xml` as syncroad needs it: normal edges with their lanes (length, speed limit,
//! permissions), every lane by id (junction-internal lanes too) and the lane-to-lane
//! connections with the internal lane (`via`) each one drives through.
//!
//! SUMO's format: `<edge id function?>` holds `<lane id index length speed allow? disallow?>`;
//! `<connection from to fromLane toLane via?>` joins a lane of one edge to a lane of the next,
//! through the internal lane `via`; a connection from an internal edge continues the chain
//! (through a second internal lane at junctions with internal stops) to the target lane.

use std::collections::HashMap;
use std::path::Path;

use super::NetError;

/// One lane as parsed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Lane {
    /// Lane id (`<edge>_<index>`).
    pub id: String,
    /// Length \[m\] as SUMO stores it.
    pub length_m: f64,
    /// Speed limit \[m/s\].
    pub speed_mps: f64,
    /// The `allow` attribute (vehicle classes), if given.
    pub allow: Option<String>,
    /// The `disallow` attribute, if given.
    pub disallow: Option<String>,
}

impl Lane {
    /// Whether SUMO lets the vehicle class `class` drive here (`allow` wins over
    /// `disallow`; `all` stands for every class).
    pub fn permits(&self, class: &str) -> bool {
        let has = |list: &str| list.split_whitespace().any(|c| c == class || c == "all");
        match (&self.allow, &self.disallow) {
            (Some(a), _) => has(a),
            (None, Some(d)) => !has(d),
            (None, None) => true,
        }
    }

    /// The permissions as written, for messages.
    pub fn permissions(&self) -> String {
        match (&self.allow, &self.disallow) {
            (Some(a), _) => format!("allow=\"{a}\""),
            (None, Some(d)) => format!("disallow=\"{d}\""),
            (None, None) => "every class".into(),
        }
    }
}

/// One lane-to-lane connection.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Connection {
    /// Target edge.
    pub to: String,
    /// Lane index on the source edge.
    pub from_lane: usize,
    /// Lane index on the target edge.
    pub to_lane: usize,
    /// The internal lane driven through, if any.
    pub via: Option<String>,
}

/// A parsed network.
#[derive(Debug, Clone, Default)]
pub(crate) struct Network {
    /// Normal edges (no `function`) in file order, each with its lanes by index.
    pub normal: Vec<(String, Vec<Lane>)>,
    /// Index into `normal` by edge id.
    pub normal_index: HashMap<String, usize>,
    /// Every lane (normal and internal) by id.
    pub lanes: HashMap<String, Lane>,
    /// Connections by source edge (normal or internal) in file order.
    pub connections: HashMap<String, Vec<Connection>>,
}

/// A numeric attribute, `None` when missing or not a number.
fn number(node: &roxmltree::Node<'_, '_>, name: &str) -> Option<f64> {
    node.attribute(name).and_then(|x| x.parse().ok())
}

impl Network {
    /// Reads and parses `path`. Malformed XML and missing attributes are refused here: libsumo
    /// crashes the whole process on them.
    pub fn read(path: &Path) -> Result<Self, NetError> {
        let text = crate::input_file::read_text(path, None)
            .map_err(|reason| NetError::Unreadable {
                path: path.to_path_buf(),
                reason,
            })?
            .unwrap_or_default();
        Self::parse(path, &text)
    }

    /// Parses the text of `path`.
    pub fn parse(path: &Path, text: &str) -> Result<Self, NetError> {
        let doc = roxmltree::Document::parse(text).map_err(|e| NetError::Malformed {
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
        let mut net = Network::default();
        for el in root.children().filter(|n| n.is_element()) {
            match el.tag_name().name() {
                "edge" => net.add_edge(&el).map_err(invalid)?,
                "connection" => {
                    let (Some(from), Some(to)) = (el.attribute("from"), el.attribute("to")) else {
                        return Err(invalid("a <connection> lacks from/to".into()));
                    };
                    let lane = |name: &str| {
                        el.attribute(name)
                            .and_then(|x| x.parse::<usize>().ok())
                            .ok_or_else(|| {
                                invalid(format!(
                                    "the <connection> from `{from}` to `{to}` has no valid {name}"
                                ))
                            })
                    };
                    let c = Connection {
                        to: to.to_string(),
                        from_lane: lane("fromLane")?,
                        to_lane: lane("toLane")?,
                        via: el.attribute("via").map(str::to_string),
                    };
                    net.connections.entry(from.to_string()).or_default().push(c);
                }
                _ => {}
            }
        }
        if net.normal.is_empty() {
            return Err(invalid("no normal <edge> with lanes".into()));
        }
        Ok(net)
    }

    fn add_edge(&mut self, el: &roxmltree::Node<'_, '_>) -> Result<(), String> {
        let id = el.attribute("id").ok_or("an <edge> has no id")?;
        let mut lanes = Vec::new();
        for lane in el.children().filter(|n| n.has_tag_name("lane")) {
            let lid = lane
                .attribute("id")
                .ok_or_else(|| format!("a lane of edge `{id}` has no id"))?;
            let length_m = number(&lane, "length")
                .filter(|x| x.is_finite() && *x >= 0.0)
                .ok_or_else(|| format!("lane `{lid}` has no valid length attribute"))?;
            let speed_mps = number(&lane, "speed")
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or_else(|| format!("lane `{lid}` has no valid speed attribute"))?;
            let l = Lane {
                id: lid.to_string(),
                length_m,
                speed_mps,
                allow: lane.attribute("allow").map(str::to_string),
                disallow: lane.attribute("disallow").map(str::to_string),
            };
            self.lanes.insert(l.id.clone(), l.clone());
            lanes.push(l);
        }
        if lanes.is_empty() {
            return Err(format!("edge `{id}` has no <lane>"));
        }
        if el.attribute("function").is_none() {
            self.normal_index.insert(id.to_string(), self.normal.len());
            self.normal.push((id.to_string(), lanes));
        }
        Ok(())
    }

    /// The lanes of normal edge `edge`, if it exists.
    pub fn edge_lanes(&self, edge: &str) -> Option<&[Lane]> {
        self.normal_index
            .get(edge)
            .map(|&i| self.normal[i].1.as_slice())
    }

    /// The connections leaving `edge` (normal or internal).
    pub fn outgoing(&self, edge: &str) -> &[Connection] {
        self.connections.get(edge).map_or(&[], Vec::as_slice)
    }

    /// The internal lanes driven from lane `from_lane` of `from` to lane `to_lane` of `to`, in
    /// order (empty for a direct connection), or `None` when no connection joins the two
    /// lanes. A chain that does not reach the target within 16 internal lanes is refused.
    pub fn via_chain(
        &self,
        from: &str,
        from_lane: usize,
        to: &str,
        to_lane: usize,
    ) -> Option<Result<Vec<&Lane>, String>> {
        let first = self
            .outgoing(from)
            .iter()
            .find(|c| c.to == to && c.from_lane == from_lane && c.to_lane == to_lane)?;
        let mut chain = Vec::new();
        let mut via = first.via.clone();
        while let Some(lane_id) = via {
            let Some(lane) = self.lanes.get(&lane_id) else {
                return Some(Err(format!(
                    "the connection `{from}`_{from_lane} → `{to}`_{to_lane} runs via unknown lane `{lane_id}`"
                )));
            };
            chain.push(lane);
            if chain.len() > 16 {
                return Some(Err(format!(
                    "the internal lanes from `{from}` to `{to}` do not reach `{to}` (a cycle of internal lanes)"
                )));
            }
            let (edge, index) = split_lane(&lane_id);
            via = self
                .outgoing(edge)
                .iter()
                .find(|c| c.to == to && c.to_lane == to_lane && Some(c.from_lane) == index)
                .and_then(|c| c.via.clone());
        }
        Some(Ok(chain))
    }
}

/// A lane id's edge and index (`:j_0_1` → (`:j_0`, 1)).
pub(crate) fn split_lane(lane: &str) -> (&str, Option<usize>) {
    match lane.rsplit_once('_') {
        Some((e, i)) => (e, i.parse().ok()),
        None => (lane, None),
    }
}
