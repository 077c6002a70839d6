//! The files a run writes: `trajectories.csv` (long format, one row per vehicle and sample)
//! and `metrics.json` (the [`RunRecord`], pretty JSON with a trailing newline).
//!
//! Every file goes through [`write_result`]: written under a temporary name in its folder,
//! synced and renamed into place, so a full disk or a crash never leaves a cut-off file under
//! the real name; `metrics.json` is
//! written last, so a folder holding one is complete. [`prepare_dir`] checks an output folder
//! before a run starts and clears what an earlier run left there.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use syncroad_control::{RunRecord, Trajectory};

use crate::lock::FolderLock;

use crate::error::InputError;

/// The record of a run folder, written last.
pub const METRICS_FILE: &str = "metrics.json";
/// The samples of a run folder.
pub const TRAJECTORY_FILE: &str = "trajectories.csv";
/// A SUMO run's work folder inside its run folder (SUMO's inputs and log).
pub const SUMO_WORK_DIR: &str = "sumo";

/// Checks the output folder `dir` (given as `flag`) before any work starts, takes its lock
/// ([`crate::lock::hold`]: a second syncroad writing the same folder is refused, naming the
/// first) and clears the files this run will write (`files`, removed in order: list the record
/// first), so a failed run never leaves an earlier run's record beside its own rows. Refuses an
/// existing file as the folder and a folder where a file goes, and checks the folder is
/// writable; refuses a file to write that is one of the command's `inputs` (the scenario, its
/// network …), before anything is removed. Hold the returned lock until the last file is
/// written.
pub fn prepare_dir(
    flag: &str,
    dir: &Path,
    files: &[&str],
    inputs: &Inputs,
) -> anyhow::Result<FolderLock> {
    if dir.exists() && !dir.is_dir() {
        return Err(InputError::new(format!(
            "{flag} = {}: is an existing file, not a folder; name a folder (it is created if missing)",
            dir.display()
        ))
        .into());
    }
    std::fs::create_dir_all(dir).map_err(|e| crate::error::folder_error(flag, dir, e))?;
    for name in files {
        refuse_input(flag, &dir.join(name), inputs)?;
    }
    // What a SUMO run writes into its work folder `DIR/sumo` (its routes, log, detectors).
    for name in syncroad_sumo::WORK_FILES {
        refuse_input(flag, &dir.join(SUMO_WORK_DIR).join(name), inputs)?;
    }
    let held = crate::lock::hold(flag, dir)?;
    for name in files {
        let path = dir.join(name);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if meta.is_dir() {
            return Err(InputError::new(format!(
                "{flag} = {}: {} is a folder, but this run writes a file there; remove it or choose another {flag}",
                dir.display(),
                path.display()
            ))
            .into());
        }
        // Only a regular file is cleared: a symlink, a FIFO or a device is left to
        // `write_result`, which writes through it (or refuses it), never replaces it.
        if !meta.is_file() {
            continue;
        }
        std::fs::remove_file(&path).with_context(|| {
            format!(
                "{flag} = {}: cannot remove {} left by an earlier run",
                dir.display(),
                path.display()
            )
        })?;
    }
    let probe = temp_name(&dir.join(".write-probe"));
    std::fs::write(&probe, b"").with_context(|| {
        format!(
            "{flag} = {}: the output folder is not writable",
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(held)
}

/// The files a command reads, each with what it is ("the scenario", "sumo.net" …): no output
/// may be one of them.
#[derive(Debug, Default, Clone)]
pub struct Inputs(Vec<(String, PathBuf)>);

impl Inputs {
    /// No inputs worth guarding (a scenario read from stdin, a computation without files).
    pub fn none() -> Self {
        Self::default()
    }

    /// Adds the file `path`, described as `what`.
    pub fn with(mut self, what: impl Into<String>, path: impl Into<PathBuf>) -> Self {
        self.0.push((what.into(), path.into()));
        self
    }

    /// The scenario file at `path` and the SUMO files it names (those of `sumo.config`
    /// included: they are merged into its network, routes and additional files).
    pub fn scenario(path: &Path, sc: &syncroad_control::Scenario) -> Self {
        let mut i = Self::none().with("the scenario", path);
        let sumo = sc.sumo();
        if let Some(net) = sumo.net() {
            i = i.with("the scenario's sumo.net", net);
        }
        for (k, r) in sumo.routes().iter().enumerate() {
            i = i.with(format!("the scenario's sumo.routes[{k}]"), r);
        }
        for (k, a) in sumo.additional().iter().enumerate() {
            i = i.with(format!("the scenario's sumo.additional[{k}]"), a);
        }
        if let Some(c) = sumo.config() {
            i = i.with("the scenario's sumo.config", c);
        }
        i
    }
}

/// Refuses to write `out` (given as `flag`, or in the folder given as `flag`) when it is the
/// same file as one of `inputs` (same device and inode, whatever the path: a link, `..`,
/// another spelling): writing it would destroy what the command reads. A path that does not
/// exist yet is never an input.
pub fn refuse_input(flag: &str, out: &Path, inputs: &Inputs) -> Result<(), InputError> {
    for (what, input) in &inputs.0 {
        if same_file(out, input) {
            return Err(InputError::new(format!(
                "{flag}: {} is {what} ({}), which this command reads; writing it would destroy it — choose another {flag}",
                out.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// Whether `a` and `b` are one file (device and inode, links followed), read with `stat`: never
/// opened, so a FIFO cannot block the check. A path that does not exist is no file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Checks, before any work, that the file `path` (given as `flag`) can be written where it is:
/// not an existing folder, and its folder (a symlink's target's folder) exists.
pub fn check_file_target(flag: &str, path: &Path) -> Result<(), InputError> {
    let target = match std::fs::read_link(path) {
        Ok(t) if t.is_relative() => path.parent().unwrap_or(Path::new(".")).join(t),
        Ok(t) => t,
        Err(_) => path.to_path_buf(),
    };
    if target.is_dir() {
        return Err(InputError::new(format!(
            "{flag} = {}: is a folder; name a file (it is created, or replaced if it is a regular file)",
            path.display()
        )));
    }
    let parent = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        return Err(InputError::new(format!(
            "{flag} = {}: the folder {} does not exist; create it or name a file in an existing folder",
            path.display(),
            parent.display()
        )));
    }
    Ok(())
}

fn temp_name(path: &Path) -> PathBuf {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// The one writer of result files (see `syncroad_sumo::write_result`): a regular file or a
/// new one is replaced atomically (synced, renamed, folder synced), a symlink's target
/// likewise, a FIFO or device is written through, anything else is refused.
pub use syncroad_sumo::{write_result, write_result_via_path};

/// Writes `text` to the result file `path` ([`write_result`]).
pub fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    Ok(write_result(path, |w| w.write_all(text.as_bytes()))?)
}

/// Writes the trajectory as CSV: `time_s,vehicle,speed_mps,position_m,gap_m`.
pub fn write_trajectory_csv(path: &Path, traj: &Trajectory) -> anyhow::Result<()> {
    Ok(write_result(path, |file| -> anyhow::Result<()> {
        let mut w = csv::Writer::from_writer(file);
        w.write_record(["time_s", "vehicle", "speed_mps", "position_m", "gap_m"])?;
        let n = traj.n;
        // One buffer per field, reused: a large fleet writes millions of rows.
        let mut t = String::new();
        let mut field = String::new();
        let mut put = |w: &mut csv::Writer<_>, x: &dyn std::fmt::Display| {
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
                w.write_field(&t)?;
                put(&mut w, &i)?;
                put(&mut w, &traj.speeds_mps[j])?;
                put(&mut w, &traj.positions_m[j])?;
                put(&mut w, &gap)?;
                w.write_record(None::<&[u8]>)?;
            }
        }
        w.flush()?;
        Ok(())
    })?)
}

/// Writes a run's `trajectories.csv` into `dir`: the one place every backend's rows are
/// written.
pub fn write_run_rows(dir: &Path, traj: &Trajectory) -> anyhow::Result<()> {
    write_trajectory_csv(&dir.join(TRAJECTORY_FILE), traj)
}

/// Writes a run's `metrics.json` into `dir`, after every other file of the run.
pub fn write_run_record(dir: &Path, record: &RunRecord) -> anyhow::Result<()> {
    write_json(&dir.join(METRICS_FILE), &record.to_json())
}

/// Keeps a record that could not be written to `metrics.json`: in a new file
/// `metrics.unsaved-*.json` beside it, else in the temporary folder, else on stderr. Never
/// replaces a file. Returns where it went, for the error message.
pub fn rescue_record(dir: &Path, record: &RunRecord) -> String {
    use std::io::Write as _;
    let text = match serde_json::to_string_pretty(&record.to_json()) {
        Ok(t) => t + "\n",
        Err(e) => return format!("nowhere: it cannot be encoded ({e})"),
    };
    for folder in [dir.to_path_buf(), std::env::temp_dir()] {
        let kept = tempfile::Builder::new()
            .prefix("metrics.unsaved-")
            .suffix(".json")
            .tempfile_in(&folder)
            .and_then(|mut f| {
                f.write_all(text.as_bytes())?;
                f.as_file().sync_all()?;
                f.keep().map_err(|e| e.error)
            });
        if let Ok((_, path)) = kept {
            return format!("in {}", path.display());
        }
    }
    crate::stdout::errln!("{text}");
    "on stderr (above)".to_string()
}

/// Writes pretty JSON with a trailing newline, atomically.
pub fn write_json(path: &Path, doc: &serde_json::Value) -> anyhow::Result<()> {
    write_text(path, &(serde_json::to_string_pretty(doc)? + "\n"))
}
