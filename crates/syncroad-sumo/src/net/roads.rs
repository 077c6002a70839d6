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
use syncroad_control::scenario::{
    ConfigInputs, MeasuredRoad, RoadReader, RoadSpec, RouteLanes, VehicleClass,
};

use super::network::{Lane, Network};
use super::{Disconnected, NetError, NoLanes, Road, Segment, Unclosed};

/// How many nearest ids an unknown-edge message lists.
const NEAREST: usize = 3;

/// Reads the loop or route of `spec` on the network `path`, for vehicles of class `vclass`.
pub fn read_network_road(
    path: &Path,
    spec: &RoadSpec,
    vclass: VehicleClass,
) -> Result<Road, NetError> {
    let net = Network::read(path)?;
    network_road(&net, path, spec, vclass)
}

/// The loop or route of `spec` on a parsed network.
pub(crate) fn network_road(
    net: &Network,
    path: &Path,
    spec: &RoadSpec,
    vclass: VehicleClass,
) -> Result<Road, NetError> {
    let on = Lanes { vclass, path };
    let edges = match spec {
        RoadSpec::Loop { edges, .. } => edges.as_deref(),
        RoadSpec::Route { edges, .. } => Some(edges.as_slice()),
        _ => None,
    };
    if edges.is_some_and(<[String]>::is_empty) {
        return Err(NetError::Invalid {
            path: path.to_path_buf(),
            reason: "road.edges = []: a road needs at least one edge".into(),
        });
    }
    match spec {
        RoadSpec::Loop {
            edges: Some(edges),
            lane,
            ..
        } => on.road_along(net, edges, &vec![*lane; edges.len()], true, &|i| {
            format!("road.edges[{i}]")
        }),
        RoadSpec::Loop {
            through: Some(edge),
            lane,
            ..
        } => {
            let cycle = on.shortest_cycle(net, edge, *lane)?;
            on.road_along(net, &cycle, &vec![*lane; cycle.len()], true, &|i| {
                format!("the cycle through road.through (edge {i})")
            })
        }
        RoadSpec::Route { edges, lane } => {
            let field = |i: usize| format!("road.edges[{i}]");
            let lanes = match lane {
                RouteLanes::Index(l) => vec![*l; edges.len()],
                RouteLanes::PerEdge(l) if l.len() == edges.len() => l.clone(),
                RouteLanes::PerEdge(l) => {
                    return Err(NetError::Invalid {
                        path: path.to_path_buf(),
                        reason: format!(
                            "road.lane gives {} lane(s) for {} edge(s) of road.edges",
                            l.len(),
                            edges.len()
                        ),
                    })
                }
                RouteLanes::Follow => on.follow(net, edges, &field)?,
            };
            on.road_along(net, edges, &lanes, false, &field)
        }
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

/// The lanes of one road's network open to its vehicles' class: the checks and searches of a
/// loop or route.
struct Lanes<'a> {
    vclass: VehicleClass,
    path: &'a Path,
}

impl Lanes<'_> {
    /// Lane `lane` of normal edge `edge`, checked to exist and to admit the class;
    /// `lane_field` names the lane's scenario field.
    fn lane_of<'n>(
        &self,
        net: &'n Network,
        edge: &str,
        lane: usize,
        field: &str,
        lane_field: &str,
    ) -> Result<&'n Lane, NetError> {
        let lanes = self.lanes_of(net, edge, field)?;
        let l = lanes.get(lane).ok_or_else(|| NetError::LaneOutOfRange {
            lane_field: lane_field.to_string(),
            field: field.to_string(),
            edge: edge.to_string(),
            lane,
            lanes: lanes.len(),
        })?;
        self.permitted(l, field)?;
        Ok(l)
    }

    /// The lanes of normal edge `edge`, checked to exist.
    fn lanes_of<'n>(
        &self,
        net: &'n Network,
        edge: &str,
        field: &str,
    ) -> Result<&'n [Lane], NetError> {
        net.edge_lanes(edge).ok_or_else(|| NetError::UnknownEdge {
            path: self.path.to_path_buf(),
            field: field.to_string(),
            edge: edge.to_string(),
            nearest: nearest(net, edge),
        })
    }

    fn permitted(&self, l: &Lane, field: &str) -> Result<(), NetError> {
        if l.permits(self.vclass.name()) {
            Ok(())
        } else {
            Err(NetError::LaneForbidden {
                path: self.path.to_path_buf(),
                field: field.to_string(),
                lane: l.id.clone(),
                permissions: l.permissions(),
                vclass: self.vclass.name(),
            })
        }
    }

    /// The junction lanes from lane `a` of `from` to lane `b` of `to`, every one open to the
    /// class; `None` when no connection joins the two lanes or a junction lane is closed.
    fn junction<'n>(
        &self,
        net: &'n Network,
        (from, a): (&str, usize),
        (to, b): (&str, usize),
    ) -> Option<Vec<&'n Lane>> {
        match net.via_chain(from, a, to, b)? {
            Ok(chain) if chain.iter().all(|l| l.permits(self.vclass.name())) => Some(chain),
            _ => None,
        }
    }

    /// The lanes a route follows along the network's connections (`road.lane = "follow"`):
    /// from the lowest lane of the first edge open to the class, each connection to the next
    /// edge taken to its lowest lane from which the route still reaches its last edge (a
    /// depth-first search, every dead end remembered).
    fn follow(
        &self,
        net: &Network,
        edges: &[String],
        field: &dyn Fn(usize) -> String,
    ) -> Result<Vec<usize>, NetError> {
        let all: Vec<&[Lane]> = edges
            .iter()
            .enumerate()
            .map(|(i, e)| self.lanes_of(net, e, &field(i)))
            .collect::<Result<_, _>>()?;
        // At least one edge: `network_road` refuses an empty road.
        let m = edges.len();
        let open =
            |i: usize, l: usize| all[i].get(l).is_some_and(|x| x.permits(self.vclass.name()));
        if !(0..all[0].len()).any(|l| open(0, l)) {
            // No lane of the first edge open to the class: the check of lane 0 says why.
            self.lane_of(net, &edges[0], 0, &field(0), "road.lane")?;
        }
        // dead[i][l]: from lane l of edge i the route cannot reach its last edge.
        let mut dead: Vec<Vec<bool>> = all.iter().map(|l| vec![false; l.len()]).collect();
        // The furthest edge reached, for the message when no lane sequence exists.
        let mut furthest = 0;
        let mut path: Vec<usize> = Vec::with_capacity(m);
        // Each frame: the lane on edge i and the next target lanes still to try.
        let mut stack: Vec<(usize, Vec<usize>)> = Vec::new();
        let next_lanes = |i: usize, l: usize| -> Vec<usize> {
            let mut to: Vec<usize> = net
                .outgoing(&edges[i])
                .iter()
                .filter(|c| c.to == edges[i + 1] && c.from_lane == l)
                .map(|c| c.to_lane)
                .filter(|&b| open(i + 1, b))
                .filter(|&b| {
                    self.junction(net, (&edges[i], l), (&edges[i + 1], b))
                        .is_some()
                })
                .collect();
            to.sort_unstable();
            to.dedup();
            to.reverse();
            to
        };
        for start in (0..all[0].len()).filter(|&l| open(0, l)) {
            if m == 1 {
                return Ok(vec![start]);
            }
            path.clear();
            path.push(start);
            stack.clear();
            stack.push((start, next_lanes(0, start)));
            while let Some((lane, todo)) = stack.last_mut() {
                let (lane, next) = (*lane, todo.pop());
                let i = path.len() - 1;
                furthest = furthest.max(i);
                match next {
                    Some(b) if !dead[i + 1][b] => {
                        path.push(b);
                        if i + 2 == m {
                            return Ok(path);
                        }
                        let more = next_lanes(i + 1, b);
                        stack.push((b, more));
                    }
                    Some(_) => {}
                    None => {
                        dead[i][lane] = true;
                        stack.pop();
                        path.pop();
                    }
                }
            }
        }
        // Here the route has two edges or more (one edge returns its first open lane above).
        let i = furthest.min(m - 2);
        Err(NetError::NoLaneSequence(Box::new(NoLanes {
            path: self.path.to_path_buf(),
            from_field: field(i),
            from: edges[i].clone(),
            to_field: field(i + 1),
            to: edges[i + 1].clone(),
            vclass: self.vclass.name(),
            joined: joined(net, &edges[i], &edges[i + 1]),
        })))
    }

    /// The lanes driven along `edges` on lane `lanes[i]` of edge `i`, closed back to the
    /// first edge when `closed`; `field(i)` names edge `i` in messages.
    fn road_along(
        &self,
        net: &Network,
        edges: &[String],
        lanes: &[usize],
        closed: bool,
        field: &dyn Fn(usize) -> String,
    ) -> Result<Road, NetError> {
        let uniform = lanes.iter().all(|&l| l == lanes[0]);
        let lane_field = |i: usize| {
            if uniform {
                "road.lane".to_string()
            } else {
                format!("road.lane[{i}]")
            }
        };
        // Every lane checked (and no edge twice) before any connection is looked at.
        let mut seen: HashMap<&str, usize> = HashMap::new();
        let mut driven: Vec<&Lane> = Vec::with_capacity(edges.len());
        for (i, e) in edges.iter().enumerate() {
            driven.push(self.lane_of(net, e, lanes[i], &field(i), &lane_field(i))?);
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
        for (i, (e, l)) in edges.iter().zip(&driven).enumerate() {
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
            let (a, b) = (lanes[i], lanes[j]);
            let chain = match net.via_chain(e, a, next, b) {
                Some(chain) => chain.map_err(|reason| NetError::Invalid {
                    path: self.path.to_path_buf(),
                    reason,
                })?,
                None if j == 0 => {
                    return Err(NetError::LoopNotClosed(Box::new(Unclosed {
                        path: self.path.to_path_buf(),
                        last_field: field(i),
                        last: e.clone(),
                        first: next.clone(),
                        lane: a,
                        joined: joined(net, e, next),
                    })))
                }
                None => {
                    return Err(NetError::NoConnection(Box::new(Disconnected {
                        path: self.path.to_path_buf(),
                        from_field: field(i),
                        from: e.clone(),
                        to_field: field(j),
                        to: next.clone(),
                        from_lane: a,
                        to_lane: b,
                        joined: joined(net, e, next),
                        hint: if closed {
                            ""
                        } else {
                            " (a route may change lanes where the connections do: road.lane = \"follow\", or one lane index per edge)"
                        },
                    })))
                }
            };
            for il in chain {
                self.permitted(il, &format!("{} → {} (junction lane)", field(i), field(j)))?;
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
            path: self.path.to_path_buf(),
            segments,
            ring: closed,
            multi_lane: edges
                .iter()
                .any(|e| net.edge_lanes(e).is_some_and(|l| l.len() > 1)),
        })
    }

    /// The shortest cycle (by driven length) through `through` on lane index `lane`:
    /// Dijkstra's search (petgraph's A* with a zero estimate) over the normal edges whose lane
    /// `lane` admits the class, an arc wherever a connection joins lane `lane` to lane `lane`
    /// through junction lanes that admit it, weighted by the junction lanes plus the next
    /// edge's lane.
    fn shortest_cycle(
        &self,
        net: &Network,
        through: &str,
        lane: usize,
    ) -> Result<Vec<String>, NetError> {
        self.lane_of(net, through, lane, "road.through", "road.lane")?;
        let class = self.vclass.name();
        let mut g: DiGraph<usize, f64> = DiGraph::with_capacity(net.normal.len() + 1, 0);
        let nodes: Vec<NodeIndex> = (0..net.normal.len()).map(|i| g.add_node(i)).collect();
        // The walk ends at a copy of `through`: every arc into it also enters the copy.
        let target = g.add_node(usize::MAX);
        let start = net.normal_index[through];
        for (i, (id, lanes)) in net.normal.iter().enumerate() {
            if !lanes.get(lane).is_some_and(|l| l.permits(class)) {
                continue;
            }
            for c in net.outgoing(id) {
                if c.from_lane != lane || c.to_lane != lane {
                    continue;
                }
                let Some(&j) = net.normal_index.get(&c.to) else {
                    continue;
                };
                let Some(to_lane) = net.normal[j].1.get(lane).filter(|l| l.permits(class)) else {
                    continue;
                };
                let Some(chain) = self.junction(net, (id, lane), (&c.to, lane)) else {
                    continue;
                };
                let cost = chain.iter().map(|l| l.length_m).sum::<f64>() + to_lane.length_m;
                let to = if j == start { target } else { nodes[j] };
                g.add_edge(nodes[i], to, cost);
            }
        }
        let found =
            petgraph::algo::astar(&g, nodes[start], |n| n == target, |e| *e.weight(), |_| 0.0);
        let Some((_, walk)) = found else {
            let reached =
                petgraph::algo::dijkstra(&g, nodes[start], None, |e| *e.weight()).len() - 1;
            return Err(NetError::NoCycle {
                path: self.path.to_path_buf(),
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
        vclass: VehicleClass,
    ) -> Result<MeasuredRoad, Box<dyn std::error::Error + Send + Sync>> {
        let r = read_network_road(net, road, vclass)?;
        Ok(MeasuredRoad {
            edges: r.normal_edges().iter().map(|e| e.to_string()).collect(),
            lanes: r.lanes(),
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
