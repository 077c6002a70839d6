//! Running a sweep's points through the one pipeline, in parallel, resumable and sharded.
//!
//! The output folder:
//!
//! ```text
//! OUT/sweep.json        the spec, its hash and the shard: written first, checked on resume
//! OUT/rows/<point>.json one row per finished point, written atomically when it finishes
//! OUT/runs/<point>/     each point's run folder (only with --keep-runs)
//! OUT/work/<point>/     SUMO's files of a point in flight; kept when the point failed
//! OUT/results.parquet   the table of every row, in point order (and results.csv)
//! ```

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use anyhow::Context;
use serde_json::{json, Map, Value};
use syncroad_control::scenario::Backend;
use syncroad_control::{LawSpec, NativeOptions, Scenario, StopReason};
use syncroad_sumo::{load_road, Road, WorkerCommand, WorkerPool};

use super::points::{Point, Shard};
use super::rows::{point_cells, read_rows, row_path, rows_dir};
use super::spec::Sweep;
use super::table::{at_path, metric_kinds, Column, Kind, Table};
use crate::batch::JobEnd;
use crate::error::InputError;
use crate::lock::{self, FolderLock};
use crate::output::write_text;
use crate::pipeline::{self, Finished};

/// How to run.
#[derive(Debug, Clone)]
pub struct ExecOptions {
    /// Points in flight at once.
    pub jobs: usize,
    /// The share of points to run.
    pub shard: Shard,
    /// Keep each point's run folder (trajectories, metrics.json).
    pub keep_runs: bool,
    /// Also draw each kept run's plots.
    pub run_plots: bool,
    /// Run again the points whose row says they failed.
    pub retry_failed: bool,
    /// Kept SUMO runs also write SUMO's floating-car data for `syncroad replay`.
    pub fcd: bool,
    /// That floating-car data every this many steps (1: every step).
    pub fcd_every: usize,
}

/// What a call to [`run`] did.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    /// Points of this shard.
    pub points: usize,
    /// Already finished before this call.
    pub skipped: usize,
    /// Run now.
    pub ran: usize,
    /// Of those, failed (no result, or the run stopped with an error).
    pub failed: usize,
    /// Not run because of Ctrl-C (or interrupted part-way).
    pub interrupted: usize,
    /// Worker processes started.
    pub workers: usize,
    /// Seconds the points run now spent inside SUMO's step (0 on the native simulator): the
    /// sweep's stepping bound on J jobs is this over J.
    pub sumo_step_s: f64,
}

/// The table's columns: point, axes, run, penetration, seed, status, the metrics, stamps.
pub fn columns(sweep: &Sweep) -> Vec<Column> {
    let mut c = vec![Column::new("point", Kind::Int)];
    for a in &sweep.axes {
        let kind = if a.values.iter().all(Value::is_number) {
            Kind::Float
        } else if a.values.iter().all(Value::is_boolean) {
            Kind::Bool
        } else {
            Kind::Text
        };
        c.push(Column::new(&a.field, kind));
    }
    c.push(Column::new("run", Kind::Text));
    c.push(Column::new("penetration", Kind::Float));
    c.push(Column::new("seed", Kind::Int));
    c.push(Column::new("status", Kind::Text));
    c.push(Column::new("safe", Kind::Bool));
    c.push(Column::new("stop", Kind::Text));
    c.push(Column::new("error", Kind::Text));
    let kinds = metric_kinds();
    for m in sweep.metrics.iter().filter(|m| *m != "safe") {
        let k = kinds
            .iter()
            .find(|(p, _)| p == m)
            .map_or(Kind::Text, |(_, k)| *k);
        c.push(Column::new(m, k));
    }
    for s in [
        "backend",
        "scenario_hash",
        "spec_hash",
        "syncroad_version",
        "sumo_version",
    ] {
        c.push(Column::new(s, Kind::Text));
    }
    c
}

/// The row of a point that produced a record.
fn row_of(sweep: &Sweep, p: &Point, record: &Value) -> Map<String, Value> {
    let mut r = point_cells(sweep, p);
    let reason = at_path(record, "stop.reason").as_str().unwrap_or("failed");
    let status = if record["complete"].as_bool() == Some(true) {
        "complete"
    } else if matches!(reason, "failed" | "controller_failed") {
        // The run failed (a worker that died, a time limit) or the user's controller raised or
        // returned what is not a speed: a bug in the law is no finding about it, so the point
        // counts as failed and `--retry-failed` runs it again.
        "failed"
    } else {
        // Diverged, a non-finite command, a lost vehicle: a result, not a failure.
        "stopped"
    };
    r.insert("status".into(), json!(status));
    r.insert("safe".into(), record["safe"].clone());
    r.insert("stop".into(), json!(reason));
    r.insert("error".into(), record["error"].clone());
    // A run that never produced a sample has no verdict (its record's "not synchronized" is
    // the verdict of nothing): the cell is empty, as its metrics are.
    let ran = !at_path(record, "sync.final_spread_mps").is_null();
    for m in &sweep.metrics {
        let v = at_path(record, m).clone();
        let v = if m == "sync.verdict" && !ran {
            Value::Null
        } else {
            v
        };
        r.insert(m.clone(), v);
    }
    for s in ["scenario_hash", "sumo_version"] {
        r.insert(s.into(), record[s].clone());
    }
    r
}

/// The row of a point that never produced a record.
fn failed_row(sweep: &Sweep, p: &Point, error: &str) -> Map<String, Value> {
    let mut r = point_cells(sweep, p);
    r.insert("status".into(), json!("failed"));
    r.insert("stop".into(), json!("failed"));
    r.insert("error".into(), json!(error));
    r
}

/// Which of a sweep's input files differ from those of the sweep in a folder (`old`, as its
/// `sweep.json` lists them), for the refusal's message: `; changed: a.py; new: b.py`, or
/// nothing when the files are alike (the spec or the base scenario changed) or the folder's
/// sweep listed none.
fn changed_inputs(old: &Value, now: &BTreeMap<String, String>) -> String {
    let Some(old) = old.as_object() else {
        return String::new();
    };
    let mut said = String::new();
    let mut say = |what: &str, names: Vec<&str>| {
        if !names.is_empty() {
            said.push_str(&format!("; {what}: {}", names.join(", ")));
        }
    };
    say(
        "changed",
        now.iter()
            .filter(|(k, v)| old.get(*k).is_some_and(|o| o.as_str() != Some(v.as_str())))
            .map(|(k, _)| k.as_str())
            .collect(),
    );
    say(
        "new",
        now.keys()
            .filter(|k| !old.contains_key(*k))
            .map(String::as_str)
            .collect(),
    );
    say(
        "gone",
        old.keys()
            .filter(|k| !now.contains_key(*k))
            .map(String::as_str)
            .collect(),
    );
    if said.is_empty() {
        "; the files it reads are alike, so the spec or the base scenario changed".into()
    } else {
        said
    }
}

/// Locks `out` ([`lock::hold`]: one writer at a time), checks it and writes `sweep.json`: a
/// new folder, or one this spec (and shard) made before, whose finished points are skipped.
/// Keep the returned lock while writing into `out`.
pub fn open_out(sweep: &Sweep, out: &Path, shard: Shard) -> anyhow::Result<FolderLock> {
    let meta = out.join("sweep.json");
    let doc = json!({
        "name": sweep.name,
        "spec_hash": sweep.hash,
        "inputs": sweep.inputs,
        "points": sweep.len(),
        "shard": {"index": shard.index, "count": shard.count},
        "spec": sweep.file,
        "syncroad_version": env!("CARGO_PKG_VERSION"),
    });
    if out.is_file() {
        return Err(InputError::new(format!(
            "--out = {}: is a file; give a folder for the sweep's results",
            out.display()
        ))
        .into());
    }
    let held = lock::hold("--out", out)?;
    if meta.is_file() {
        let old: Value = serde_json::from_str(&std::fs::read_to_string(&meta)?)
            .with_context(|| format!("{} is not valid JSON", meta.display()))?;
        if old["spec_hash"] != doc["spec_hash"] {
            return Err(InputError::new(format!(
                "--out = {}: holds a sweep of another spec, base scenario or input file (network, route, additional or configuration file, the controller or a module beside it; hash {} here, {} now{}); give a new folder, or remove it to start over",
                out.display(),
                old["spec_hash"].as_str().unwrap_or("?"),
                sweep.hash,
                changed_inputs(&old["inputs"], &sweep.inputs)
            ))
            .into());
        }
        if old["shard"] != doc["shard"] {
            return Err(InputError::new(format!(
                "--out = {}: holds shard {}/{} of this sweep, not {}/{}; give each shard its own folder",
                out.display(),
                old["shard"]["index"],
                old["shard"]["count"],
                shard.index,
                shard.count
            ))
            .into());
        }
    } else if std::fs::read_dir(out)
        .with_context(|| format!("cannot read {}", out.display()))?
        .any(|e| e.is_ok_and(|e| !left_by_a_start(&e)))
    {
        return Err(InputError::new(format!(
            "--out = {}: exists and is not a sweep folder (no sweep.json); give a new or empty folder",
            out.display()
        ))
        .into());
    }
    // sweep.json first: a sweep stopped before it is written leaves nothing but the lock (and
    // perhaps the temporary file of that write), which the next start takes as empty.
    write_text(&meta, &(serde_json::to_string_pretty(&doc)? + "\n"))?;
    std::fs::create_dir_all(rows_dir(out))
        .with_context(|| format!("cannot create {}", rows_dir(out).display()))?;
    Ok(held)
}

/// What a sweep killed while it started (before `sweep.json` was in place) leaves in its
/// folder: the lock file, and the temporary file of an unfinished write of `sweep.json`.
fn left_by_a_start(e: &std::fs::DirEntry) -> bool {
    let name = e.file_name();
    let name = name.to_string_lossy();
    name == lock::LOCK_FILE || (name.starts_with(".sweep.json.") && name.ends_with(".tmp"))
}

/// The table of the rows in `out`, in point order.
pub fn table(sweep: &Sweep, rows: BTreeMap<usize, Map<String, Value>>) -> Table {
    Table {
        columns: columns(sweep),
        rows: rows.into_values().collect(),
    }
}

/// Everything a point's run needs that is the same for every point.
struct Shared<'a> {
    sweep: &'a Sweep,
    out: &'a Path,
    opts: &'a ExecOptions,
    pool: Option<WorkerPool>,
    roads: Mutex<HashMap<PathBuf, Arc<Road>>>,
    interrupt: Arc<AtomicBool>,
    /// Σ of the points' time inside SUMO's step.
    step_s: Mutex<f64>,
}

enum PointEnd {
    Row(Map<String, Value>),
    Interrupted,
}

impl Shared<'_> {
    fn road(&self, sc: &Scenario) -> anyhow::Result<Arc<Road>> {
        let key = syncroad_sumo::net_path(sc)
            .map_err(|e| InputError::caused("before starting SUMO", e))?;
        if let Some(r) = self.roads.lock().expect("road cache").get(&key) {
            return Ok(r.clone());
        }
        let road =
            Arc::new(load_road(sc).map_err(|e| InputError::caused("before starting SUMO", e))?);
        self.roads
            .lock()
            .expect("road cache")
            .insert(key, road.clone());
        Ok(road)
    }

    fn run_point(&self, p: &Point) -> anyhow::Result<PointEnd> {
        let sweep = self.sweep;
        let sc = sweep.scenario(p)?;
        let mut plan = sweep.plan_point(p, &sc)?;
        plan.fcd = self.opts.fcd;
        plan.fcd_every = self.opts.fcd_every;
        let run_dir = self.out.join("runs").join(format!("{:07}", p.id));
        let work = if self.opts.keep_runs {
            run_dir.join("sumo")
        } else {
            self.out.join("work").join(format!("{:07}", p.id))
        };
        let (output, interrupted) = match sweep.backend {
            Backend::Native => {
                let opts = NativeOptions {
                    record_every: plan.record_every,
                    cancel: Some(&self.interrupt),
                    ..NativeOptions::default()
                };
                let law = LawSpec::of_drive(&sc, &plan.drive).ok_or_else(|| {
                    InputError::new(format!(
                        "runs: {} needs SUMO (backend \"sumo\")",
                        plan.name()
                    ))
                })?;
                let out = pipeline::native_law(&sc, &law, plan.drive.labels(sc.vehicles()), opts)
                    .map_err(|e| InputError::caused("runs", e))?;
                let interrupted = matches!(out.stop, StopReason::Interrupted { .. });
                (out, interrupted)
            }
            Backend::Sumo => {
                let road = self.road(&sc)?;
                let pool = self.pool.as_ref().expect("a SUMO sweep has a worker pool");
                let o = plan.sumo_options(
                    work.clone(),
                    pool.command().clone(),
                    Some(self.interrupt.clone()),
                );
                let r = pipeline::sumo_pooled(&sc, &road, &o, pool)
                    .map_err(|e| InputError::caused("before starting SUMO", e))?;
                *self.step_s.lock().expect("step time") += r.step_s.unwrap_or(0.0);
                (r.output, r.interrupted)
            }
        };
        if interrupted {
            // Run again from the start on resume: nothing of this attempt is kept.
            if !self.opts.keep_runs {
                let _ = std::fs::remove_dir_all(&work);
            }
            return Ok(PointEnd::Interrupted);
        }
        let f = Finished::new(&sc, plan.name(), output, plan.eval);
        if self.opts.keep_runs {
            std::fs::create_dir_all(&run_dir)
                .with_context(|| format!("cannot create {}", run_dir.display()))?;
            let title = self
                .opts
                .run_plots
                .then(|| format!("{} point {}: {}", sweep.name, p.id, plan.name()));
            f.write(&run_dir, title)?;
        }
        let row = row_of(sweep, p, &f.record.to_json());
        // SUMO's files are kept for failed points only (a stopped point is a result).
        if row.get("status") != Some(&json!("failed")) && !self.opts.keep_runs {
            let _ = std::fs::remove_dir_all(&work);
        }
        Ok(PointEnd::Row(row))
    }
}

/// Runs the points of `opts.shard` not finished yet, writing each row as it finishes.
pub fn run(
    sweep: &Sweep,
    out: &Path,
    opts: &ExecOptions,
    interrupt: Arc<AtomicBool>,
) -> anyhow::Result<Summary> {
    let done = read_rows(sweep, out, opts.shard)?;
    let mine: Vec<Point> = sweep.points().filter(|p| opts.shard.holds(p.id)).collect();
    let todo: Vec<&Point> = mine
        .iter()
        .filter(|p| match done.get(&p.id) {
            None => true,
            Some(r) => opts.retry_failed && r.get("status") == Some(&json!("failed")),
        })
        .collect();
    let mut summary = Summary {
        points: mine.len(),
        skipped: mine.len() - todo.len(),
        ..Summary::default()
    };
    if todo.is_empty() {
        return Ok(summary);
    }
    let pool = (sweep.backend == Backend::Sumo).then(|| {
        WorkerCommand::for_process()
            .map(WorkerPool::new)
            .context("cannot locate the syncroad executable")
    });
    let shared = Shared {
        sweep,
        out,
        opts,
        pool: pool.transpose()?,
        roads: Mutex::new(HashMap::new()),
        interrupt: interrupt.clone(),
        step_s: Mutex::new(0.0),
    };
    let write_error: Mutex<Option<anyhow::Error>> = Mutex::new(None);
    let ends = crate::batch::run(
        ("sweep", None),
        opts.jobs,
        &interrupt,
        &todo,
        |p| format!("point {}", p.id),
        |p| {
            let end = shared.run_point(p).unwrap_or_else(|e| {
                PointEnd::Row(failed_row(sweep, p, &crate::error::describe(&e)))
            });
            let PointEnd::Row(row) = end else {
                return JobEnd::Interrupted;
            };
            let failed = row.get("status") == Some(&json!("failed"));
            let error = failed.then(|| {
                row.get("error")
                    .and_then(Value::as_str)
                    .unwrap_or("failed")
                    .to_string()
            });
            // The row is streamed as soon as the point ends: a stopped sweep keeps it.
            let text = serde_json::to_string(&row).expect("a row serializes") + "\n";
            if let Err(e) = write_text(&row_path(out, p.id), &text) {
                write_error.lock().expect("error slot").get_or_insert(e);
                interrupt.store(true, Ordering::SeqCst);
            }
            JobEnd::Done(failed, error)
        },
    )?;
    summary.ran = ends.iter().flatten().count();
    summary.failed = ends.iter().flatten().filter(|&&failed| failed).count();
    summary.interrupted = ends.iter().filter(|e| e.is_none()).count();
    summary.workers = shared.pool.as_ref().map_or(0, WorkerPool::workers_started);
    summary.sumo_step_s = *shared.step_s.lock().expect("step time");
    if let Some(e) = write_error.into_inner().expect("error slot") {
        return Err(e.context("a finished point's row could not be written; the sweep stopped"));
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_split_the_points_without_overlap() {
        let shards: Vec<Shard> = (0..4)
            .map(|i| Shard::parse(&format!("{i}/4")).unwrap())
            .collect();
        for id in 0..103 {
            assert_eq!(shards.iter().filter(|s| s.holds(id)).count(), 1);
        }
        for bad in ["4/4", "1", "a/2", "0/0", "-1/3"] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.starts_with(&format!("--shard = {bad:?}")), "{e}");
        }
    }
}
