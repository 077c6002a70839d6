//! Roads through a network (`road.type` = `loop` or `route`): their shape checked here, their
//! length measured by whoever reads network files. The maths never parses a network; the SUMO
//! crate implements [`RoadReader`] and hands the measured length in before validation ends.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{invalid, RoadSpec, RouteLanes, ScenarioError, VehicleClass};

/// A road through a network as its reader measured it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasuredRoad {
    /// The normal edges in driving order (for `through`, the cycle that was found).
    pub edges: Vec<String>,
    /// The lane index driven on each of `edges`.
    pub lanes: Vec<usize>,
    /// Driven length \[m\]: normal plus junction-internal lanes, as the simulator measures it.
    pub length_m: f64,
}

/// The input section of a SUMO configuration file (`sumo.config`), as its reader found it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConfigInputs {
    /// `net-file`, resolved against the configuration's folder.
    pub net: Option<std::path::PathBuf>,
    /// `route-files`, in their order.
    pub routes: Vec<std::path::PathBuf>,
    /// `additional-files`, in their order.
    pub additional: Vec<std::path::PathBuf>,
    /// Every other option, as `name = value`: not passed to SUMO.
    pub ignored: Vec<String>,
}

/// Reads roads through network files: checks the edges, lanes and connections of a
/// [`RoadSpec::Loop`] or [`RoadSpec::Route`] on the network `net` and measures it. The error
/// is the reader's own, naming the `road.…` field at fault.
pub trait RoadReader {
    /// The measured road for vehicles of class `vclass` (its lanes must admit them), or why
    /// the network does not hold it.
    fn measure(
        &self,
        road: &RoadSpec,
        net: &Path,
        vclass: VehicleClass,
    ) -> Result<MeasuredRoad, Box<dyn std::error::Error + Send + Sync>>;

    /// The circumference of the single-lane ring `net` as SUMO measures it (normal and
    /// junction lanes); `None` when the reader does not measure rings.
    fn ring_length(
        &self,
        net: &Path,
    ) -> Option<Result<f64, Box<dyn std::error::Error + Send + Sync>>> {
        let _ = net;
        None
    }

    /// The input section of the SUMO configuration file `config`. The error is the reader's
    /// own, naming `sumo.config`.
    fn read_config(
        &self,
        config: &Path,
    ) -> Result<ConfigInputs, Box<dyn std::error::Error + Send + Sync>>;
}

/// Checks the shape of a network road and measures it with `reader` on `net`, for vehicles of
/// class `vclass`.
pub(super) fn measure(
    road: &RoadSpec,
    net: Option<&Path>,
    vclass: VehicleClass,
    reader: Option<&dyn RoadReader>,
) -> Result<MeasuredRoad, ScenarioError> {
    let (kind, edges) = match road {
        RoadSpec::Loop { edges, through, .. } => {
            match (edges, through) {
                (Some(_), Some(_)) => {
                    return Err(invalid(
                        "road.through",
                        "given with road.edges",
                        "give either the cycle (road.edges) or one edge on it (road.through), not both",
                    ))
                }
                (None, None) => {
                    return Err(invalid(
                        "road.edges",
                        "missing",
                        "a loop needs its edges in driving order (road.edges) or one edge on it (road.through)",
                    ))
                }
                _ => {}
            }
            ("loop", edges.as_deref())
        }
        RoadSpec::Route { edges, lane } => {
            if let RouteLanes::PerEdge(lanes) = lane {
                if lanes.len() != edges.len() {
                    return Err(invalid(
                        "road.lane",
                        lane,
                        format!(
                            "gives {} lane(s) for {} edge(s): one lane index per edge of road.edges, one index for all, or \"follow\"",
                            lanes.len(),
                            edges.len()
                        ),
                    ));
                }
            }
            ("route", Some(edges.as_slice()))
        }
        RoadSpec::Ring { .. } | RoadSpec::Straight { .. } => {
            unreachable!("only loops and routes are measured on a network")
        }
    };
    if edges.is_some_and(<[String]>::is_empty) {
        return Err(invalid(
            "road.edges",
            "[]",
            format!("a {kind} needs at least one edge"),
        ));
    }
    let Some(net) = net else {
        return Err(invalid(
            "sumo.net",
            "missing",
            format!("road.type = \"{kind}\" runs through a network: name its .net.xml in sumo.net (or as net-file in sumo.config)"),
        ));
    };
    let Some(reader) = reader else {
        return Err(invalid(
            "road.type",
            kind,
            "a road through a network is measured on the network: load the scenario with a network reader (the syncroad command line does)",
        ));
    };
    let measured = reader
        .measure(road, net, vclass)
        .map_err(|e| ScenarioError::Road(e.to_string()))?;
    if !(measured.length_m.is_finite() && measured.length_m > 0.0) {
        return Err(invalid(
            "road",
            measured.length_m,
            "the network gives the road no positive length",
        ));
    }
    Ok(measured)
}
