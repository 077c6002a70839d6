//! Building the interaction graph `G[A]` from its spec.

use super::{invalid, GraphShape, GraphSpec, ScenarioError};
use crate::graph::{Arc, Graph};

/// How the graph was given, with the gains that are uniform.
pub(super) fn graph_shape(spec: &GraphSpec) -> GraphShape {
    match spec {
        GraphSpec::UnidirectionalRing { gain } => GraphShape::UnidirectionalRing {
            gain: gain.uniform_value(0),
        },
        GraphSpec::BidirectionalRing {
            gain_pred,
            gain_follow,
        } => GraphShape::BidirectionalRing {
            gain_pred: gain_pred.uniform_value(0),
            gain_follow: gain_follow.uniform_value(0),
        },
        GraphSpec::Chain { gain } => GraphShape::Chain {
            follower_gain: gain.uniform_value(1),
        },
        GraphSpec::AllToAll { .. } | GraphSpec::Edges { .. } | GraphSpec::Matrix { .. } => {
            GraphShape::Other
        }
    }
}

pub(super) fn build_graph(spec: &GraphSpec, n: usize) -> Result<Graph, ScenarioError> {
    let g = match spec {
        GraphSpec::UnidirectionalRing { gain } => {
            Graph::unidirectional_ring(n, &gain.resolve_pos("model.graph.gain", n)?)?
        }
        GraphSpec::BidirectionalRing {
            gain_pred,
            gain_follow,
        } => Graph::bidirectional_ring(
            n,
            &gain_pred.resolve_pos("model.graph.gain_pred", n)?,
            &gain_follow.resolve_pos("model.graph.gain_follow", n)?,
        )?,
        GraphSpec::Chain { gain } => {
            let mut k = gain.resolve_nonneg("model.graph.gain", n)?;
            k[0] = 0.0;
            for (i, x) in k.iter().enumerate().skip(1) {
                if *x <= 0.0 {
                    return Err(invalid(format!("model.graph.gain[{i}]"), x, "must be > 0"));
                }
            }
            Graph::chain(n, &k)?
        }
        GraphSpec::AllToAll { gain } => {
            Graph::all_to_all(n, &gain.resolve_pos("model.graph.gain", n)?)?
        }
        GraphSpec::Edges { edges } => {
            let mut arcs = Vec::with_capacity(edges.len());
            for (k, e) in edges.iter().enumerate() {
                let f = format!("model.graph.edges[{k}]");
                if e.from >= n || e.to >= n {
                    return Err(invalid(
                        f,
                        format!("{} -> {}", e.from, e.to),
                        format!("vehicle indices must be in 0..{n} (there are {n} vehicles)"),
                    ));
                }
                if e.from == e.to {
                    return Err(invalid(
                        f,
                        format!("{} -> {}", e.from, e.to),
                        "self-loops are not allowed (a_ii = 0)",
                    ));
                }
                if !(e.weight.is_finite() && e.weight > 0.0) {
                    return Err(invalid(
                        format!("{f}.weight"),
                        e.weight,
                        "must be a finite number > 0",
                    ));
                }
                arcs.push(Arc {
                    from: e.from,
                    to: e.to,
                    weight: e.weight,
                });
            }
            Graph::from_arcs(n, &arcs)?
        }
        GraphSpec::Matrix { a } => {
            if a.len() != n {
                return Err(ScenarioError::LengthMismatch {
                    field: "model.graph.a".into(),
                    len: a.len(),
                    vehicles: n,
                });
            }
            let mut arcs = Vec::new();
            for (i, row) in a.iter().enumerate() {
                if row.len() != n {
                    return Err(ScenarioError::LengthMismatch {
                        field: format!("model.graph.a[{i}]"),
                        len: row.len(),
                        vehicles: n,
                    });
                }
                for (j, &w) in row.iter().enumerate() {
                    let f = format!("model.graph.a[{i}][{j}]");
                    if !(w.is_finite() && w >= 0.0) {
                        return Err(invalid(f, w, "must be a finite number ≥ 0"));
                    }
                    if i == j && w != 0.0 {
                        return Err(invalid(f, w, "diagonal entries must be 0 (no self-loops)"));
                    }
                    if w > 0.0 {
                        arcs.push(Arc {
                            from: j,
                            to: i,
                            weight: w,
                        });
                    }
                }
            }
            Graph::from_arcs(n, &arcs)?
        }
    };
    Ok(g)
}
