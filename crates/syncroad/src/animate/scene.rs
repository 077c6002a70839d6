//! A finished run as an animation sees it: its record, its trajectories (read back from
//! `trajectories.csv`) and the road they lie on (the network's lanes of a SUMO run, a circle or
//! a line of the run's length for a native run).

use std::path::Path;

use serde::{Deserialize, Serialize};
use syncroad_control::record::RunRecord;
use syncroad_sumo::RoadTrace;

use crate::error::InputError;
use crate::output::{METRICS_FILE, SUMO_WORK_DIR, TRAJECTORY_FILE};

/// Where a native run's road lies (`road.json` in its folder): a ring of `length_m`, or an
/// open road.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NativeRoad {
    /// The ring's circumference \[m\]; `None` on an open road.
    pub ring_length_m: Option<f64>,
}

/// The file a native run writes its road into.
pub const NATIVE_ROAD_FILE: &str = "road.json";

/// The road as a centre line: points `[s, x, y]` by increasing `s` (the trajectory's position
/// of the point, \[m\]), and the length after which a closed road starts again.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadLine {
    /// The points.
    pub points: Vec<[f64; 3]>,
    /// A closed road's length \[m\] (positions are taken modulo it); `None` when open.
    pub closed_m: Option<f64>,
}

impl RoadLine {
    /// A circle of circumference `length_m`, centred at the origin, driven counter-clockwise.
    pub fn circle(length_m: f64) -> Self {
        let r = length_m / std::f64::consts::TAU;
        let n = 360;
        let points = (0..=n)
            .map(|k| {
                let s = length_m * k as f64 / n as f64;
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                [s, r * a.cos(), r * a.sin()]
            })
            .collect();
        Self {
            points,
            closed_m: Some(length_m),
        }
    }

    /// A straight road from `from_m` to `to_m` along x.
    pub fn line(from_m: f64, to_m: f64) -> Self {
        Self {
            points: vec![[from_m, from_m, 0.0], [to_m, to_m, 0.0]],
            closed_m: None,
        }
    }

    /// The point at position `s` \[m\]: interpolated along the line, wrapped on a closed road,
    /// held at the ends of an open one.
    pub fn at(&self, s: f64) -> (f64, f64) {
        let s = match self.closed_m {
            Some(l) if l > 0.0 => s.rem_euclid(l),
            _ => s,
        };
        let p = &self.points;
        let k = p.partition_point(|q| q[0] <= s);
        if k == 0 {
            return (p[0][1], p[0][2]);
        }
        if k == p.len() {
            // Past the last point: on a closed road the segment back to the first point.
            if let Some(l) = self.closed_m {
                let (a, b) = (p[k - 1], p[0]);
                let span = l - a[0] + b[0];
                let f = if span > 0.0 { (s - a[0]) / span } else { 0.0 };
                return (a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]));
            }
            return (p[k - 1][1], p[k - 1][2]);
        }
        let (a, b) = (p[k - 1], p[k]);
        let f = if b[0] > a[0] {
            (s - a[0]) / (b[0] - a[0])
        } else {
            0.0
        };
        (a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]))
    }

    /// The smallest box holding the road: (x0, y0, x1, y1).
    pub fn bounds(&self) -> (f64, f64, f64, f64) {
        self.points.iter().fold(
            (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ),
            |b, p| (b.0.min(p[1]), b.1.min(p[2]), b.2.max(p[1]), b.3.max(p[2])),
        )
    }
}

/// One run read back for drawing.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Its record.
    pub record: RunRecord,
    /// Vehicles per sample.
    pub n: usize,
    /// Sample times \[s\].
    pub time_s: Vec<f64>,
    /// Positions \[m\], sample-major (`k * n + i`).
    pub position_m: Vec<f64>,
    /// Speeds \[m/s\], sample-major.
    pub speed_mps: Vec<f64>,
    /// The road.
    pub road: RoadLine,
    /// Vehicles a controller drives among others (marked); empty when every vehicle is driven
    /// alike.
    pub marked: Vec<bool>,
}

/// The folder is not a finished run (exit 2).
fn not_a_run(dir: &Path, why: String) -> anyhow::Error {
    InputError::new(format!(
        "{}: not a run folder syncroad can draw: {why}; give the --out folder of `syncroad run` or `syncroad simulate` (or a run folder under a compare's or a sweep's --keep-runs output)",
        dir.display()
    ))
    .into()
}

impl Scene {
    /// Reads the run in `dir`: `metrics.json`, `trajectories.csv` and the road.
    pub fn read(dir: &Path) -> anyhow::Result<Self> {
        let record = read_record(dir)?;
        let Rows {
            n,
            time_s,
            position_m,
            speed_mps,
        } = read_rows(dir, record.vehicles)?;
        let road = read_road(dir, &record, &position_m)?;
        let law = |d: &str| {
            d == syncroad_control::PROTOCOL
                || d.starts_with("python:")
                || d.starts_with("rust:")
                || syncroad_control::registry::NamedLaw::parse("driver", d).is_ok()
        };
        let marked: Vec<bool> = record.drivers.iter().map(|d| law(d)).collect();
        let alike = marked.iter().all(|m| *m) || marked.iter().all(|m| !*m);
        let marked = if alike || marked.len() != n {
            Vec::new()
        } else {
            marked
        };
        Ok(Self {
            record,
            n,
            time_s,
            position_m,
            speed_mps,
            road,
            marked,
        })
    }

    /// The last sample's time \[s\].
    pub fn end_s(&self) -> f64 {
        self.time_s.last().copied().unwrap_or(0.0)
    }

    /// Positions and speeds at `t`, interpolated linearly between the samples around it
    /// (the first or last sample outside them).
    pub fn state_at(&self, t: f64, pos: &mut Vec<f64>, speed: &mut Vec<f64>) {
        let n = self.n;
        let k = self.time_s.partition_point(|x| *x <= t);
        let (a, b, f) = if k == 0 {
            (0, 0, 0.0)
        } else if k >= self.time_s.len() {
            (k - 1, k - 1, 0.0)
        } else {
            let (ta, tb) = (self.time_s[k - 1], self.time_s[k]);
            (k - 1, k, if tb > ta { (t - ta) / (tb - ta) } else { 0.0 })
        };
        pos.clear();
        speed.clear();
        for i in 0..n {
            let (pa, pb) = (self.position_m[a * n + i], self.position_m[b * n + i]);
            let (va, vb) = (self.speed_mps[a * n + i], self.speed_mps[b * n + i]);
            pos.push(pa + f * (pb - pa));
            speed.push(va + f * (vb - va));
        }
    }
}

/// A run folder's `metrics.json`.
pub(crate) fn read_record(dir: &Path) -> anyhow::Result<RunRecord> {
    if !dir.is_dir() {
        return Err(not_a_run(dir, "no such folder".into()));
    }
    let path = dir.join(METRICS_FILE);
    let text = std::fs::read_to_string(&path)
        .map_err(|e| not_a_run(dir, format!("{} cannot be read ({e})", path.display())))?;
    serde_json::from_str(&text).map_err(|e| {
        not_a_run(
            dir,
            format!("{} is not a syncroad run record ({e})", path.display()),
        )
    })
}

/// A run's rows read back: samples of `n` vehicles.
pub(crate) struct Rows {
    /// Vehicles per sample.
    pub n: usize,
    /// Sample times \[s\].
    pub time_s: Vec<f64>,
    /// Positions \[m\], sample-major.
    pub position_m: Vec<f64>,
    /// Speeds \[m/s\], sample-major.
    pub speed_mps: Vec<f64>,
}

/// `trajectories.csv`: samples of every vehicle in order, each row `time_s, vehicle,
/// speed_mps, position_m, gap_m`; a file cut short or out of order is refused naming its line.
pub(crate) fn read_rows(dir: &Path, vehicles: usize) -> anyhow::Result<Rows> {
    let path = dir.join(TRAJECTORY_FILE);
    let bad = |line: u64, why: String| -> anyhow::Error {
        InputError::new(format!(
            "{} line {line}: {why}; a run's trajectories hold one row per vehicle (0 … {}) for every sample time, as syncroad writes them (run it again to rewrite the file)",
            path.display(),
            vehicles.saturating_sub(1)
        ))
        .into()
    };
    let file = std::fs::File::open(&path)
        .map_err(|e| not_a_run(dir, format!("{} cannot be read ({e})", path.display())))?;
    let mut rd = csv::Reader::from_reader(std::io::BufReader::new(file));
    let header: Vec<String> = rd
        .headers()
        .map_err(|e| bad(1, e.to_string()))?
        .iter()
        .map(str::to_string)
        .collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let (Some(ct), Some(cv), Some(cs), Some(cp)) = (
        col("time_s"),
        col("vehicle"),
        col("speed_mps"),
        col("position_m"),
    ) else {
        return Err(bad(
            1,
            format!(
                "the header is `{}`, expected time_s,vehicle,speed_mps,position_m,gap_m",
                header.join(",")
            ),
        ));
    };
    let (mut time_s, mut pos, mut speed) = (Vec::new(), Vec::new(), Vec::new());
    let mut rec = csv::StringRecord::new();
    let mut k = 0usize;
    loop {
        match rd.read_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(bad(k as u64 + 2, e.to_string())),
        }
        let line = rec.position().map_or(k as u64 + 2, |p| p.line());
        let num = |c: usize, what: &str| -> anyhow::Result<f64> {
            rec.get(c)
                .and_then(|x| x.parse::<f64>().ok())
                .ok_or_else(|| {
                    bad(
                        line,
                        format!("{what} `{}` is not a number", rec.get(c).unwrap_or("")),
                    )
                })
        };
        let i = k % vehicles.max(1);
        let v = num(cv, "vehicle")?;
        if v != i as f64 {
            return Err(bad(
                line,
                format!("vehicle {v} where vehicle {i} was expected"),
            ));
        }
        let t = num(ct, "time_s")?;
        if i == 0 {
            if time_s.last().is_some_and(|&last| t <= last) {
                return Err(bad(
                    line,
                    format!(
                        "time {t} s does not follow {} s",
                        time_s.last().unwrap_or(&0.0)
                    ),
                ));
            }
            time_s.push(t);
        } else if time_s.last() != Some(&t) {
            return Err(bad(
                line,
                format!(
                    "time {t} s within the sample of {} s",
                    time_s.last().unwrap_or(&0.0)
                ),
            ));
        }
        speed.push(num(cs, "speed_mps")?);
        pos.push(num(cp, "position_m")?);
        k += 1;
    }
    if vehicles == 0 || k == 0 {
        return Err(bad(2, "no rows".into()));
    }
    if !k.is_multiple_of(vehicles) {
        return Err(bad(
            k as u64 + 1,
            format!(
                "the file ends within the sample of {} s ({} of {vehicles} vehicles): it was cut short",
                time_s.last().unwrap_or(&0.0),
                k % vehicles
            ),
        ));
    }
    Ok(Rows {
        n: vehicles,
        time_s,
        position_m: pos,
        speed_mps: speed,
    })
}

/// The road of the run: a SUMO run's lanes from its network (`sumo/road.json`), a native run's
/// circle or line (`road.json`).
fn read_road(dir: &Path, record: &RunRecord, positions: &[f64]) -> anyhow::Result<RoadLine> {
    let sumo = dir.join(SUMO_WORK_DIR).join(syncroad_sumo::ROAD_FILE);
    if sumo.is_file() {
        let trace = RoadTrace::read(&sumo).map_err(|e| InputError::caused("the run's road", e))?;
        let points = trace
            .geometry()
            .map_err(|e| InputError::caused("the run's road", e))?;
        return Ok(RoadLine {
            points,
            closed_m: trace.closed.then(|| trace.length_m()),
        });
    }
    let native = dir.join(NATIVE_ROAD_FILE);
    let road = match std::fs::read_to_string(&native) {
        Ok(text) => serde_json::from_str::<NativeRoad>(&text).map_err(|e| {
            InputError::new(format!(
                "{}: not a native run's road ({e})",
                native.display()
            ))
        })?,
        Err(_) => {
            let why = if record.backend == syncroad_control::scenario::Backend::Sumo {
                "the run names no road (its sumo/road.json is missing: runs that drive the user's own vehicles, sumo.controlled, are not drawn)"
            } else {
                "its road.json is missing (runs of syncroad before animations wrote none: run it again)"
            };
            return Err(not_a_run(dir, why.into()));
        }
    };
    Ok(match road.ring_length_m {
        Some(l) if l.is_finite() && l > 0.0 => RoadLine::circle(l),
        _ => {
            let (lo, hi) = positions
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(*x), b.max(*x))
                });
            RoadLine::line(lo - 5.0, hi + 10.0)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_circle_puts_each_position_at_its_arc_length() {
        let c = RoadLine::circle(230.0);
        let r = 230.0 / std::f64::consts::TAU;
        // A chord of the 360-gon lies at most its sagitta r(1 − cos(π/360)) inside the arc.
        let sagitta = r * (1.0 - (std::f64::consts::PI / 360.0).cos());
        for s in [0.0, 10.0, 57.5, 115.0, 229.9, 230.0 + 57.5, -57.5] {
            let (x, y) = c.at(s);
            assert!((x.hypot(y) - r).abs() <= sagitta + 1e-12, "{s}");
            let a = (s / r).rem_euclid(std::f64::consts::TAU);
            let off = (x - r * a.cos()).hypot(y - r * a.sin());
            assert!(off <= 2.0 * sagitta, "{s}: {off}");
        }
    }

    #[test]
    fn a_line_holds_its_ends() {
        let l = RoadLine::line(-10.0, 90.0);
        assert_eq!(l.at(40.0), (40.0, 0.0));
        assert_eq!(l.at(-50.0), (-10.0, 0.0));
        assert_eq!(l.at(500.0), (90.0, 0.0));
    }
}
