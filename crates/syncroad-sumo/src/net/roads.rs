//! Loops and routes through any network: the lane sequence a vehicle drives along a list of
//! normal edges on one lane index (normal lanes and the junction-internal lanes of the
//! connections between them), the checks that name the scenario field at fault, and the
//! shortest cycle through one edge.
//!
//! The length of a loop or route is the sum of its lanes' lengths as SUMO stores them, normal
//! and internal: the distance SUMO's odometer counts along it (the worker compares it with
//! `lane.getLength` once SUMO runs).

use std::collections::HashMap;
use std::path::Path;

use petgraph::graph::{DiGraph, NodeIndex};
use syncroad_control::scenario::{ConfigInputs, MeasuredRoad, RoadReader, RoadSpec};

use super::network::{Lane, Network};
use super::{Disconnected, NetError, Road, Segment, Unclosed};

/// Vehicle class of every vehicle syncroad inserts (SUMO's default vType class).
pub const VEHICLE_CLASS: &str = "passenger";

/// How many nearest ids an unknown-edge message lists.
const NEAREST: usize = 3;

/// Reads the loop or route of `spec` on the network `path`.
pub fn read_network_road(path: &Path, spec: &RoadSpec) -> Result<Road, NetError> {
    let net = Network::read(path)?;
    network_road(&net, path, spec)
}

/// The loop or route of `spec` on a parsed network.
pub(crate) fn network_road(net: &Network, path: &Path, spec: &RoadSpec) -> Result<Road, NetError> {
    match spec {
        RoadSpec::Loop {
            edges: Some(edges),
            lane,
            ..
        } => road_along(net, path, edges, *lane, true, &|i| {
            format!("road.edges[{i}]")
        }),
        RoadSpec::Loop {
            through: Some(edge),
            lane,
            ..
        } => {
            let cycle = shortest_cycle(net, path, edge, *lane)?;
            road_along(net, path, &cycle, *lane, true, &|i| {
                format!("the cycle through road.through (edge {i})")
            })
        }
        RoadSpec::Route { edges, lane } => road_along(net, path, edges, *lane, false, &|i| {
            format!("road.edges[{i}]")
        }),
        other => Err(NetError::Invalid {
            path: path.to_path_buf(),
            reason: format!("{other:?} is not a road through a network"),
        }),
    }
}

/// The `k` normal edge ids closest to `id` by edit distance (ties in file order).
pub(crate) fn nearest(net: &Network, id: &str) -> String {
    let mut all: Vec<(usize, usize)> = net
        .normal
        .iter()
        .enumerate()
        .map(|(i, (e, _))| (strsim::levenshtein(id, e), i))
        .collect();
    all.sort_unstable();
    all.iter()
        .take(NEAREST)
        .map(|&(_, i)| format!("`{}`", net.normal[i].0))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Lane `lane` of normal edge `edge`, checked to exist and to admit passenger cars.
fn lane_of<'n>(
    net: &'n Network,
    path: &Path,
    edge: &str,
    lane: usize,
    field: &str,
) -> Result<&'n Lane, NetError> {
    let lanes = net.edge_lanes(edge).ok_or_else(|| NetError::UnknownEdge {
        path: path.to_path_buf(),
        field: field.to_string(),
        edge: edge.to_string(),
        nearest: nearest(net, edge),
    })?;
    let l = lanes.get(lane).ok_or_else(|| NetError::LaneOutOfRange {
        field: field.to_string(),
        edge: edge.to_string(),
        lane,
        lanes: lanes.len(),
    })?;
    permitted(path, l, field)?;
    Ok(l)
}

fn permitted(path: &Path, l: &Lane, field: &str) -> Result<(), NetError> {
    if l.permits(VEHICLE_CLASS) {
        Ok(())
    } else {
        Err(NetError::LaneForbidden {
            path: path.to_path_buf(),
            field: field.to_string(),
            lane: l.id.clone(),
            permissions: l.permissions(),
        })
    }
}

/// What connects `from` to `to`, for a message: the lane pairs, or where `from` leads.
fn joined(net: &Network, from: &str, to: &str) -> String {
    let out = net.outgoing(from);
    let pairs: Vec<String> = out
        .iter()
        .filter(|c| c.to == to)
        .map(|c| format!("{}→{}", c.from_lane, c.to_lane))
        .collect();
    if !pairs.is_empty() {
        return format!("its connections to `{to}` join lanes {}", pairs.join(", "));
    }
    let mut targets: Vec<String> = Vec::new();
    for c in out.iter().filter(|c| net.normal_index.contains_key(&c.to)) {
        let t = format!("`{}`", c.to);
        if !targets.contains(&t) {
            targets.push(t);
        }
    }
    if targets.is_empty() {
        format!("`{from}` has no outgoing connection (a dead end)")
    } else {
        format!(
            "`{from}` does not lead to `{to}` at all; it leads to {}",
            targets.join(", ")
        )
    }
}

/// The lanes driven along `edges` on lane index `lane`, closed back to the first edge when
/// `closed`; `field(i)` names edge `i` in messages.
fn road_along(
    net: &Network,
    path: &Path,
    edges: &[String],
    lane: usize,
    closed: bool,
    field: &dyn Fn(usize) -> String,
) -> Result<Road, NetError> {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    for (i, e) in edges.iter().enumerate() {
        lane_of(net, path, e, lane, &field(i))?;
        if let Some(&j) = seen.get(e.as_str()) {
            return Err(NetError::RepeatedEdge {
                field: field(i),
                edge: e.clone(),
                first_field: field(j),
            });
        }
        seen.insert(e, i);
    }
    let m = edges.len();
    let mut segments = Vec::new();
    for (i, e) in edges.iter().enumerate() {
        let l = lane_of(net, path, e, lane, &field(i))?;
        segments.push(Segment {
            edge: e.clone(),
            lane: l.id.clone(),
            length_m: l.length_m,
            internal: false,
            speed_mps: l.speed_mps,
        });
        if i + 1 == m && !closed {
            break;
        }
        let j = (i + 1) % m;
        let next = &edges[j];
        let chain = match net.via_chain(e, lane, next, lane) {
            Some(chain) => chain.map_err(|reason| NetError::Invalid {
                path: path.to_path_buf(),
                reason,
            })?,
            None if j == 0 => {
                return Err(NetError::LoopNotClosed(Box::new(Unclosed {
                    path: path.to_path_buf(),
                    last_field: field(i),
                    last: e.clone(),
                    first: next.clone(),
                    lane,
                    joined: joined(net, e, next),
                })))
            }
            None => {
                return Err(NetError::NoConnection(Box::new(Disconnected {
                    path: path.to_path_buf(),
                    from_field: field(i),
                    from: e.clone(),
                    to_field: field(j),
                    to: next.clone(),
                    lane,
                    joined: joined(net, e, next),
                })))
            }
        };
        for il in chain {
            permitted(
                path,
                il,
                &format!("{} → {} (junction lane)", field(i), field(j)),
            )?;
            segments.push(Segment {
                edge: super::network::split_lane(&il.id).0.to_string(),
                lane: il.id.clone(),
                length_m: il.length_m,
                internal: true,
                speed_mps: il.speed_mps,
            });
        }
    }
    Ok(Road {
        path: path.to_path_buf(),
        segments,
        ring: closed,
        lane_index: lane,
        multi_lane: edges
            .iter()
            .any(|e| net.edge_lanes(e).is_some_and(|l| l.len() > 1)),
    })
}

/// The shortest cycle (by driven length) through `through` on lane index `lane`: Dijkstra's
/// search (petgraph's A* with a zero estimate) over the normal edges whose lane `lane` admits
/// passenger cars, an arc wherever a connection joins lane `lane` to lane `lane` through
/// junction lanes that admit them, weighted by the junction lanes plus the next edge's lane.
fn shortest_cycle(
    net: &Network,
    path: &Path,
    through: &str,
    lane: usize,
) -> Result<Vec<String>, NetError> {
    lane_of(net, path, through, lane, "road.through")?;
    let mut g: DiGraph<usize, f64> = DiGraph::with_capacity(net.normal.len() + 1, 0);
    let nodes: Vec<NodeIndex> = (0..net.normal.len()).map(|i| g.add_node(i)).collect();
    // The walk ends at a copy of `through`: every arc into it also enters the copy.
    let target = g.add_node(usize::MAX);
    let start = net.normal_index[through];
    for (i, (id, lanes)) in net.normal.iter().enumerate() {
        if !lanes.get(lane).is_some_and(|l| l.permits(VEHICLE_CLASS)) {
            continue;
        }
        for c in net.outgoing(id) {
            if c.from_lane != lane || c.to_lane != lane {
                continue;
            }
            let Some(&j) = net.normal_index.get(&c.to) else {
                continue;
            };
            let Some(to_lane) = net.normal[j]
                .1
                .get(lane)
                .filter(|l| l.permits(VEHICLE_CLASS))
            else {
                continue;
            };
            let Some(Ok(chain)) = net.via_chain(id, lane, &c.to, lane) else {
                continue;
            };
            if !chain.iter().all(|l| l.permits(VEHICLE_CLASS)) {
                continue;
            }
            let cost = chain.iter().map(|l| l.length_m).sum::<f64>() + to_lane.length_m;
            let to = if j == start { target } else { nodes[j] };
            g.add_edge(nodes[i], to, cost);
        }
    }
    let found = petgraph::algo::astar(&g, nodes[start], |n| n == target, |e| *e.weight(), |_| 0.0);
    let Some((_, walk)) = found else {
        let reached = petgraph::algo::dijkstra(&g, nodes[start], None, |e| *e.weight()).len() - 1;
        return Err(NetError::NoCycle {
            path: path.to_path_buf(),
            edge: through.to_string(),
            lane,
            detail: format!(
                "{reached} other edges are reachable from it on that lane, none leads back"
            ),
        });
    };
    Ok(walk[..walk.len() - 1]
        .iter()
        .map(|&n| net.normal[g[n]].0.clone())
        .collect())
}

/// The network reader the scenario validation uses: measures a loop or route on its network,
/// and a ring's circumference.
#[derive(Debug, Clone, Copy, Default)]
pub struct NetReader;

impl RoadReader for NetReader {
    fn measure(
        &self,
        road: &RoadSpec,
        net: &Path,
    ) -> Result<MeasuredRoad, Box<dyn std::error::Error + Send + Sync>> {
        let r = read_network_road(net, road)?;
        Ok(MeasuredRoad {
            edges: r.normal_edges().iter().map(|e| e.to_string()).collect(),
            lane: r.lane_index,
            length_m: r.length_m(),
        })
    }

    fn ring_length(
        &self,
        net: &Path,
    ) -> Option<Result<f64, Box<dyn std::error::Error + Send + Sync>>> {
        Some(
            super::read_ring(net)
                .map(|r| r.length_m())
                .map_err(Into::into),
        )
    }

    fn read_config(
        &self,
        config: &Path,
    ) -> Result<ConfigInputs, Box<dyn std::error::Error + Send + Sync>> {
        Ok(super::read_config(config)?)
    }
}
