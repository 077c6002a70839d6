//! The files a run writes: `trajectories.csv` (long format, one row per vehicle and sample)
//! and `metrics.json` (the [`RunRecord`], pretty JSON with a trailing newline).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Context;
use syncroad_control::{RunRecord, Trajectory};

/// Writes the trajectory as CSV: `time_s,vehicle,speed_mps,position_m,gap_m`.
pub fn write_trajectory_csv(path: &Path, traj: &Trajectory) -> anyhow::Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("cannot write {}", path.display()))?;
    let io =
        |e: csv::Error| anyhow::Error::new(e).context(format!("cannot write {}", path.display()));
    w.write_record(["time_s", "vehicle", "speed_mps", "position_m", "gap_m"])
        .map_err(io)?;
    let n = traj.n;
    // One buffer per field, reused: a large fleet writes millions of rows.
    let mut t = String::new();
    let mut field = String::new();
    let mut put = |w: &mut csv::Writer<std::fs::File>, x: &dyn std::fmt::Display| {
        field.clear();
        let _ = write!(field, "{x}");
        w.write_field(&field)
    };
    for k in 0..traj.len() {
        t.clear();
        let _ = write!(t, "{}", traj.time_s[k]);
        for i in 0..n {
            let j = k * n + i;
            let gap = traj.gaps_m.get(j).copied().unwrap_or(f64::NAN);
            w.write_field(&t).map_err(io)?;
            put(&mut w, &i).map_err(io)?;
            put(&mut w, &traj.speeds_mps[j]).map_err(io)?;
            put(&mut w, &traj.positions_m[j]).map_err(io)?;
            put(&mut w, &gap).map_err(io)?;
            w.write_record(None::<&[u8]>).map_err(io)?;
        }
    }
    w.flush()
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Writes a run's `trajectories.csv` and `metrics.json` into `dir`: the one place every
/// backend's outputs are written.
pub fn write_run_files(dir: &Path, traj: &Trajectory, record: &RunRecord) -> anyhow::Result<()> {
    write_trajectory_csv(&dir.join("trajectories.csv"), traj)?;
    write_json(&dir.join("metrics.json"), &record.to_json())
}

/// Writes pretty JSON with a trailing newline.
pub fn write_json(path: &Path, doc: &serde_json::Value) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(doc)? + "\n")
        .with_context(|| format!("cannot write {}", path.display()))
}
