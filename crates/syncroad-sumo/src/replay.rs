//! Watching a run again. A SUMO run can write SUMO's own floating-car data (`fcd.xml`, every
//! step, or every k-th with `--fcd-every`) beside the files sumo-gui needs to play it back
//! through SUMO's fcd-replay device (`replay.sumocfg`, `replay.types.xml`); every SUMO run
//! writes where its road lies on the
//! network (`road.json`), so an animation can draw syncroad's own trajectories on the road's
//! real geometry.
//!
//! The replay's vehicle types keep each type's length, width, class and shape, with
//! car-following values that let SUMO insert every recorded vehicle where it was recorded
//! (the replay moves them; their own model never acts).
//!
//! # Reference
//! SUMO documentation, "FCDReplay" (`--device.fcd-replay.file`) and "Simulation/Output/FCDOutput".

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::layout::Layout;

/// SUMO's floating-car data of a run, in the run's `sumo/` folder.
pub const FCD_FILE: &str = "fcd.xml";
/// The SUMO configuration that replays [`FCD_FILE`].
pub const REPLAY_CONFIG: &str = "replay.sumocfg";
/// The vehicle types the replay inserts its vehicles with.
pub const REPLAY_TYPES: &str = "replay.types.xml";
/// The run's network, copied beside its replay so that the run folder replays wherever it is
/// copied (every path of [`REPLAY_CONFIG`] is relative to the folder).
pub const REPLAY_NET: &str = "replay.net.xml";
/// Where the run's road lies on the network ([`RoadTrace`]).
pub const ROAD_FILE: &str = "road.json";

/// Why a run's road or replay files cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A file could not be read.
    #[error("{path}: cannot be read: {reason}")]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A file is not what it should be.
    #[error("{path}: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong and what would be valid.
        reason: String,
    },
}

/// One lane of a run's road, in driving order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceLane {
    /// SUMO lane id (junction-internal lanes start with `:`).
    pub id: String,
    /// Its length as SUMO stores it \[m\].
    pub length_m: f64,
}

/// Where a run's road lies: the network, the lanes driven in order, whether the road closes
/// on itself, and how the trajectory's positions map onto it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoadTrace {
    /// The network file the run drove on.
    pub net: PathBuf,
    /// True for a ring or a loop.
    pub closed: bool,
    /// The lanes in driving order.
    pub lanes: Vec<TraceLane>,
    /// The road coordinate of a point (from the first lane's start) is its trajectory
    /// position (rear bumpers, as in `trajectories.csv`) plus this \[m\].
    pub offset_m: f64,
}

impl RoadTrace {
    /// The trace of a laid-out run (vehicles syncroad inserts), from its first follower's
    /// departure: its front bumper's road coordinate against its trajectory position.
    pub fn of(layout: &Layout) -> Option<Self> {
        let road = &layout.road;
        if layout.vehicles.is_empty() {
            // No vehicles of syncroad's own (only an inflow's): the road's own coordinate.
            return Some(Self::on(road, 0.0));
        }
        let dep = layout.vehicles.get(usize::from(layout.leader_vehicle))?;
        let mut normal = 0usize;
        let mut start = 0.0;
        for seg in &road.segments {
            if !seg.internal {
                if normal == dep.edge_index {
                    break;
                }
                normal += 1;
            }
            start += seg.length_m;
        }
        let front_road = start + dep.pos_m;
        Some(Self::on(road, front_road - (dep.q0_m + dep.length_m)))
    }

    /// The trace of `road`, trajectory positions shifted by `offset_m` from its coordinate.
    fn on(road: &crate::net::Road, offset_m: f64) -> Self {
        Self {
            net: std::path::absolute(&road.path).unwrap_or_else(|_| road.path.clone()),
            closed: road.ring,
            lanes: road
                .segments
                .iter()
                .map(|s| TraceLane {
                    id: s.lane.clone(),
                    length_m: s.length_m,
                })
                .collect(),
            offset_m,
        }
    }

    /// The road's length \[m\] (normal and junction lanes).
    pub fn length_m(&self) -> f64 {
        self.lanes.iter().map(|l| l.length_m).sum()
    }

    /// Reads a run's `road.json`. The network it names is where the run found it; a run
    /// folder copied elsewhere (from a cluster to a laptop) finds it beside the file instead,
    /// as the copy a run with floating-car data keeps ([`REPLAY_NET`]).
    pub fn read(path: &Path) -> Result<Self, ReplayError> {
        let text = std::fs::read_to_string(path).map_err(|e| ReplayError::Unreadable {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        let mut trace: Self = serde_json::from_str(&text).map_err(|e| ReplayError::Invalid {
            path: path.to_path_buf(),
            reason: format!("not a road trace of a syncroad run ({e})"),
        })?;
        let here = path.parent().unwrap_or(Path::new(".")).join(REPLAY_NET);
        if !trace.net.is_file() && here.is_file() {
            trace.net = here;
        }
        Ok(trace)
    }

    /// The road's centre line as points `[s, x, y]`, `s` the trajectory position \[m\] (on a
    /// closed road from 0 to its length), x and y the network's coordinates \[m\]: each lane's
    /// shape from the network, its points spread over the lane's SUMO length.
    pub fn geometry(&self) -> Result<Vec<[f64; 3]>, ReplayError> {
        let shapes = lane_shapes(&self.net, self.lanes.iter().map(|l| l.id.as_str()))?;
        let mut pts = Vec::new();
        let mut start = 0.0;
        for lane in &self.lanes {
            let shape = &shapes[&lane.id];
            let along: Vec<f64> = std::iter::once(0.0)
                .chain(shape.windows(2).scan(0.0, |acc, w| {
                    *acc += (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
                    Some(*acc)
                }))
                .collect();
            let total = along.last().copied().unwrap_or(0.0);
            for (p, a) in shape.iter().zip(&along) {
                let f = if total > 0.0 { a / total } else { 0.0 };
                pts.push([start + f * lane.length_m - self.offset_m, p.0, p.1]);
            }
            start += lane.length_m;
        }
        if self.closed {
            let l = self.length_m();
            for p in &mut pts {
                p[0] = p[0].rem_euclid(l);
            }
            pts.sort_by(|a, b| a[0].total_cmp(&b[0]));
        }
        Ok(pts)
    }
}

/// The shapes of `ids` on the network `net` (each a polyline of at least two points).
fn lane_shapes<'a>(
    net: &Path,
    ids: impl Iterator<Item = &'a str>,
) -> Result<HashMap<String, Vec<(f64, f64)>>, ReplayError> {
    let text = std::fs::read_to_string(net).map_err(|e| ReplayError::Unreadable {
        path: net.to_path_buf(),
        reason: format!("{e} (the network the run drove on)"),
    })?;
    let invalid = |reason: String| ReplayError::Invalid {
        path: net.to_path_buf(),
        reason,
    };
    let doc = roxmltree::Document::parse(&text).map_err(|e| invalid(e.to_string()))?;
    let found: HashMap<&str, &str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("lane"))
        .filter_map(|n| Some((n.attribute("id")?, n.attribute("shape")?)))
        .collect();
    let mut out = HashMap::new();
    for id in ids {
        if out.contains_key(id) {
            continue;
        }
        let shape = found
            .get(id)
            .ok_or_else(|| invalid(format!("has no lane `{id}` with a shape (the run's road)")))?;
        let pts: Option<Vec<(f64, f64)>> = shape
            .split_whitespace()
            .map(|p| {
                let mut c = p.split(',').map(|x| x.parse::<f64>().ok());
                Some((c.next()??, c.next()??))
            })
            .collect();
        match pts {
            Some(p) if p.len() >= 2 && p.iter().all(|q| q.0.is_finite() && q.1.is_finite()) => {
                out.insert(id.to_string(), p);
            }
            _ => return Err(invalid(format!("lane `{id}` has no valid shape"))),
        }
    }
    Ok(out)
}

/// The replay's vehicle types: every `<vType>` of `sources` (syncroad's routes file, the
/// user's route and additional files), by id, with what draws it kept.
fn replay_types(sources: &[PathBuf], step_s: f64) -> std::io::Result<String> {
    const KEPT: [&str; 5] = ["length", "width", "vClass", "guiShape", "color"];
    let mut types: BTreeMap<String, Vec<(&str, String)>> = BTreeMap::new();
    for path in sources {
        let text = std::fs::read_to_string(path)?;
        let Ok(doc) = roxmltree::Document::parse(&text) else {
            continue;
        };
        for t in doc.descendants().filter(|n| n.has_tag_name("vType")) {
            let Some(id) = t.attribute("id") else {
                continue;
            };
            let kept = KEPT
                .iter()
                .filter_map(|k| Some((*k, t.attribute(*k)?.to_string())))
                .collect();
            types.entry(id.to_string()).or_insert(kept);
        }
    }
    let esc = |s: &str| quick_xml::escape::escape(s).into_owned();
    let mut s = String::from("<routes>\n");
    for (id, kept) in &types {
        s.push_str(&format!("    <vType id=\"{}\"", esc(id)));
        for (k, v) in kept {
            s.push_str(&format!(" {k}=\"{}\"", esc(v)));
        }
        s.push_str(&format!(
            " minGap=\"0\" tau=\"{step_s}\" accel=\"1000\" decel=\"1000\" emergencyDecel=\"1000\" maxSpeed=\"1000\" speedFactor=\"1\" speedDev=\"0\" sigma=\"0\"/>\n"
        ));
    }
    s.push_str("</routes>\n");
    Ok(s)
}

/// Writes the replay's configuration, vehicle types and a copy of the network `net` into
/// `work_dir`, every path relative to it (so a copied run folder replays where it is): SUMO
/// (or sumo-gui) started with `-c work_dir/replay.sumocfg` plays `fcd.xml` back on it from 0 to
/// `end_s`, one step per time step of the data, `every` steps of the run's `step_s` (SUMO's
/// fcd-replay device moves each vehicle to its next recorded place every step). The types keep
/// the run's step as their reaction time, which lets SUMO insert each vehicle at its recorded
/// gap; with `every` > 1 SUMO warns that it is below the replay's step, which does not matter
/// to vehicles that only follow the record.
pub(crate) fn write_replay_files(
    work_dir: &Path,
    net: &Path,
    type_sources: &[PathBuf],
    step_s: f64,
    every: usize,
    end_s: f64,
) -> std::io::Result<()> {
    std::fs::write(
        work_dir.join(REPLAY_TYPES),
        replay_types(type_sources, step_s)?,
    )?;
    let step_s = step_s * every.max(1) as f64;
    // A copy, not a link: the run keeps the network it ran on, whatever becomes of the file.
    std::fs::copy(net, work_dir.join(REPLAY_NET))?;
    let cfg = format!(
        "<configuration>\n    <input>\n        <net-file value=\"{REPLAY_NET}\"/>\n        <additional-files value=\"{REPLAY_TYPES}\"/>\n    </input>\n    <time>\n        <begin value=\"0\"/>\n        <end value=\"{end_s}\"/>\n        <step-length value=\"{step_s}\"/>\n    </time>\n    <processing>\n        <step-method.ballistic value=\"true\"/>\n    </processing>\n    <report>\n        <no-step-log value=\"true\"/>\n    </report>\n    <fcd-replay>\n        <device.fcd-replay.file value=\"{FCD_FILE}\"/>\n    </fcd-replay>\n</configuration>\n"
    );
    std::fs::write(work_dir.join(REPLAY_CONFIG), cfg)
}

/// Removes what an earlier run left in `work_dir` that this run will not write: its
/// floating-car data and replay files unless `fcd`, its road unless `road`.
pub(crate) fn remove_stale(work_dir: &Path, fcd: bool, road: bool) -> std::io::Result<()> {
    let stale = [FCD_FILE, REPLAY_CONFIG, REPLAY_TYPES, REPLAY_NET]
        .into_iter()
        .filter(|_| !fcd)
        .chain(std::iter::once(ROAD_FILE).filter(|_| !road));
    for name in stale {
        let p = work_dir.join(name);
        if std::fs::symlink_metadata(&p).is_ok_and(|m| m.is_file()) {
            std::fs::remove_file(&p)?;
        }
    }
    Ok(())
}

/// Writes [`RoadTrace::of`] the layout to `work_dir/road.json` (nothing when the layout's
/// vehicles are not known before SUMO starts).
pub(crate) fn write_road_trace(work_dir: &Path, layout: &Layout) -> std::io::Result<()> {
    match RoadTrace::of(layout) {
        Some(t) => std::fs::write(
            work_dir.join(ROAD_FILE),
            serde_json::to_string_pretty(&t).map_err(std::io::Error::other)? + "\n",
        ),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped Sugiyama ring, traced from its network: a circle (every point at one
    /// distance from the centre) whose points cover the road's length in order, the chords
    /// between them as long as the positions say (to the arcs' curvature).
    #[test]
    fn the_sugiyama_ring_traced_from_its_network_is_a_circle_of_its_length() {
        let net =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../sumo-nets/sugiyama-ring.net.xml");
        let road = crate::net::read_ring(&net).unwrap();
        let trace = RoadTrace::on(&road, 7.0);
        let g = trace.geometry().unwrap();
        let l = trace.length_m();
        assert!((l - 230.3592).abs() < 1e-9, "{l}");
        assert!(g.windows(2).all(|w| w[0][0] <= w[1][0]));
        assert!(g.iter().all(|p| (0.0..l).contains(&p[0])));
        let n = g.len() as f64;
        let (cx, cy) = g
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p[1] / n, a.1 + p[2] / n));
        let r: Vec<f64> = g.iter().map(|p| (p[1] - cx).hypot(p[2] - cy)).collect();
        let mean = r.iter().sum::<f64>() / n;
        // 2πr is the ring's length, up to the polygon's chords and the junctions' short lanes.
        assert!(
            (std::f64::consts::TAU * mean - l).abs() < 0.01 * l,
            "r = {mean}"
        );
        assert!(r.iter().all(|x| (x - mean).abs() < 0.01 * mean));
        // The offset shifts every point: the road's start lies at s = l − 7.
        let start = g.iter().find(|p| (p[0] - (l - 7.0)).abs() < 1e-9).unwrap();
        let shapes = lane_shapes(&net, std::iter::once(trace.lanes[0].id.as_str())).unwrap();
        let first = shapes[&trace.lanes[0].id][0];
        assert!((start[1] - first.0).abs() < 1e-9 && (start[2] - first.1).abs() < 1e-9);
    }

    #[test]
    fn replay_types_keep_what_draws_a_vehicle_and_escape_ids() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.rou.xml");
        std::fs::write(
            &a,
            r#"<routes><vType id="t0" length="5" minGap="2.5" tau="1"/><vTypeDistribution id="d"><vType id="a&amp;b" length="12" vClass="bus" color="1,0,0"/></vTypeDistribution></routes>"#,
        )
        .unwrap();
        let s = replay_types(&[a], 0.1).unwrap();
        let doc = roxmltree::Document::parse(&s).unwrap();
        let types: Vec<_> = doc
            .descendants()
            .filter(|n| n.has_tag_name("vType"))
            .collect();
        assert_eq!(types.len(), 2);
        let ab = types
            .iter()
            .find(|t| t.attribute("id") == Some("a&b"))
            .unwrap();
        assert_eq!(ab.attribute("length"), Some("12"));
        assert_eq!(ab.attribute("vClass"), Some("bus"));
        assert_eq!(ab.attribute("color"), Some("1,0,0"));
        // Insertion never refuses a recorded vehicle: no minimum gap, a step's reaction.
        let t0 = types
            .iter()
            .find(|t| t.attribute("id") == Some("t0"))
            .unwrap();
        assert_eq!(t0.attribute("minGap"), Some("0"));
        assert_eq!(t0.attribute("tau"), Some("0.1"));
    }
}
