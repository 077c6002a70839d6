//! The speed field of every vehicle on the road, syncroad's and everyone else's: SUMO's
//! floating-car data of the run (`sumo/fcd.xml`, written with `sumo.fcd` or `--fcd`) placed on
//! the road's coordinate (`sumo/road.json`: its lanes in driving order). A vehicle on a lane the
//! road drives is at that lane's start plus its position on it; one on another lane of the same
//! edge (a human passing on the next lane, a vehicle merging in from an on-ramp's acceleration
//! lane) at that edge's start; one anywhere else (a ramp, a junction lane of another
//! connection) is off the road and left out. On a closed road the coordinate wraps around.

use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;

use anyhow::Context;
use quick_xml::events::Event;
use syncroad_sumo::{RoadTrace, FCD_FILE, ROAD_FILE};

/// Where the lanes and edges of the road start along it.
#[derive(Debug)]
pub struct RoadCoordinate {
    lanes: HashMap<String, f64>,
    edges: HashMap<String, f64>,
    /// The road's length \[m\].
    pub length_m: f64,
    /// The road closes on itself (positions wrap).
    pub closed: bool,
}

/// The edge of a lane id (`h1_2` → `h1`, `:n0_0_1` → `:n0_0`).
fn edge_of(lane: &str) -> &str {
    lane.rsplit_once('_').map_or(lane, |(e, _)| e)
}

impl RoadCoordinate {
    /// The coordinate along the road a run drove (its `road.json`).
    pub fn of(road: &RoadTrace) -> Self {
        let (mut lanes, mut edges) = (HashMap::new(), HashMap::new());
        let mut start = 0.0;
        for l in &road.lanes {
            lanes.insert(l.id.clone(), start);
            if !l.id.starts_with(':') {
                edges.entry(edge_of(&l.id).to_string()).or_insert(start);
            }
            start += l.length_m;
        }
        Self {
            lanes,
            edges,
            length_m: start,
            closed: road.closed,
        }
    }

    /// Where each edge of the road starts along it, in driving order (the merge of an on-ramp
    /// or a lane drop is where an edge ends and the next begins).
    pub fn edge_starts(&self) -> Vec<(String, f64)> {
        let mut e: Vec<(String, f64)> = self.edges.iter().map(|(k, v)| (k.clone(), *v)).collect();
        e.sort_by(|a, b| a.1.total_cmp(&b.1).then_with(|| a.0.cmp(&b.0)));
        e
    }

    /// The road coordinate of position `pos` \[m\] on lane `lane`, `None` off the road.
    pub fn locate(&self, lane: &str, pos: f64) -> Option<f64> {
        let start = self.lanes.get(lane).or_else(|| {
            (!lane.starts_with(':'))
                .then(|| self.edges.get(edge_of(lane)))
                .flatten()
        })?;
        let s = start + pos;
        Some(if self.closed {
            s.rem_euclid(self.length_m)
        } else {
            s
        })
    }
}

/// Samples of the field: (time \[s\], road coordinate \[m\], speed \[m/s\]).
pub type Field = Vec<(f64, f64, f64)>;

/// The vehicle type of the vehicles a law drives in an inflow (`syncroad_guestK`).
const GUEST_TYPE: &str = "syncroad_guest";

/// Every vehicle's sample of the floating-car data read from `fcd`, every `stride`-th time
/// step, on the road `road`; and apart the samples of the vehicles a law drove in an inflow
/// (those of a `syncroad_guestK` type), which the plot marks.
pub fn read_fields(
    fcd: impl BufRead,
    road: &RoadCoordinate,
    stride: usize,
) -> anyhow::Result<(Field, Field)> {
    let mut reader = quick_xml::Reader::from_reader(fcd);
    let mut buf = Vec::new();
    let mut out = Vec::new();
    let mut guests = Vec::new();
    let (mut step, mut time, mut keep) = (0usize, 0.0, false);
    loop {
        match reader.read_event_into(&mut buf).context("fcd.xml")? {
            Event::Eof => break,
            Event::Start(e) | Event::Empty(e) => match e.name().as_ref() {
                b"timestep" => {
                    keep = step % stride.max(1) == 0;
                    step += 1;
                    time = attribute(&e, b"time")
                        .and_then(|t| t.parse().ok())
                        .context("a <timestep> without its time")?;
                }
                b"vehicle" if keep => {
                    let lane = attribute(&e, b"lane");
                    let pos = attribute(&e, b"pos").and_then(|p| p.parse::<f64>().ok());
                    let speed = attribute(&e, b"speed").and_then(|v| v.parse::<f64>().ok());
                    if let (Some(lane), Some(pos), Some(v)) = (lane, pos, speed) {
                        if let Some(s) = road.locate(&lane, pos) {
                            out.push((time, s, v));
                            if attribute(&e, b"type").is_some_and(|t| t.starts_with(GUEST_TYPE)) {
                                guests.push((time, s, v));
                            }
                        }
                    }
                }
                _ => {}
            },
            _ => {}
        }
        buf.clear();
    }
    Ok((out, guests))
}

fn attribute(e: &quick_xml::events::BytesStart<'_>, name: &[u8]) -> Option<String> {
    e.attributes()
        .flatten()
        .find(|a| a.key.as_ref() == name)
        .and_then(|a| String::from_utf8(a.value.into_owned()).ok())
}

/// The field of the run whose SUMO folder is `sumo_dir` (`fcd.xml` and `road.json`), every
/// `stride`-th step; `None` when the run wrote no floating-car data or has no road trace.
pub fn run_field(
    sumo_dir: &Path,
    stride: usize,
) -> anyhow::Result<Option<(RoadCoordinate, Field, Field)>> {
    let (fcd, road) = (sumo_dir.join(FCD_FILE), sumo_dir.join(ROAD_FILE));
    if !fcd.is_file() || !road.is_file() {
        return Ok(None);
    }
    let coordinate = RoadCoordinate::of(&RoadTrace::read(&road)?);
    let file = std::io::BufReader::new(std::fs::File::open(&fcd)?);
    let (field, guests) = read_fields(file, &coordinate, stride)
        .with_context(|| format!("reading {}", fcd.display()))?;
    Ok(Some((coordinate, field, guests)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROAD: &str = r#"{"net": "n.net.xml", "closed": false, "offset_m": 0,
        "lanes": [{"id": "h0_0", "length_m": 400.0}, {"id": ":k1_0_0", "length_m": 2.5},
                  {"id": "h1_1", "length_m": 400.0}]}"#;

    #[test]
    fn vehicles_are_placed_on_the_roads_coordinate() {
        let road = RoadCoordinate::of(&serde_json::from_str(ROAD).unwrap());
        assert_eq!(road.length_m, 802.5);
        assert_eq!(road.locate("h0_0", 10.0), Some(10.0));
        assert_eq!(road.locate(":k1_0_0", 1.0), Some(401.0));
        assert_eq!(road.locate("h1_1", 3.0), Some(405.5));
        // Another lane of a road's edge: at that edge's start.
        assert_eq!(road.locate("h1_0", 3.0), Some(405.5));
        // Off the road: a ramp, another junction lane.
        assert_eq!(road.locate("ramp_0", 3.0), None);
        assert_eq!(road.locate(":k1_1_0", 1.0), None);
        let fcd = r#"<fcd-export>
<timestep time="0.00"><vehicle id="v0" x="0" y="0" angle="90" type="t0" speed="10.00" pos="5.00" lane="h0_0" slope="0"/><vehicle id="f.0" speed="12.00" pos="1.00" lane="ramp_0"/></timestep>
<timestep time="0.10"><vehicle id="v0" speed="11.00" pos="6.00" lane="h0_0"/></timestep>
<timestep time="0.20"><vehicle id="v0" speed="12.00" pos="7.00" lane="h0_0"/><vehicle id="f.0" type="syncroad_guest0" speed="13.00" pos="2.00" lane="h1_0"/></timestep>
</fcd-export>"#;
        let all = read_fields(fcd.as_bytes(), &road, 1).unwrap().0;
        assert_eq!(
            all,
            [
                (0.0, 5.0, 10.0),
                (0.1, 6.0, 11.0),
                (0.2, 7.0, 12.0),
                (0.2, 404.5, 13.0)
            ]
        );
        // The vehicle a law drove in an inflow, apart; the road's edges where they start.
        let (_, guests) = read_fields(fcd.as_bytes(), &road, 1).unwrap();
        assert_eq!(guests, [(0.2, 404.5, 13.0)]);
        assert_eq!(
            road.edge_starts(),
            [("h0".to_string(), 0.0), ("h1".to_string(), 402.5)]
        );
        let every_other = read_fields(fcd.as_bytes(), &road, 2).unwrap().0;
        assert_eq!(
            every_other,
            [(0.0, 5.0, 10.0), (0.2, 7.0, 12.0), (0.2, 404.5, 13.0)]
        );
    }

    #[test]
    fn a_closed_road_wraps() {
        let ring = ROAD.replace(r#""closed": false"#, r#""closed": true"#);
        let road = RoadCoordinate::of(&serde_json::from_str(&ring).unwrap());
        assert_eq!(road.locate("h1_1", 400.0), Some(400.0 + 402.5 - 802.5));
    }
}
