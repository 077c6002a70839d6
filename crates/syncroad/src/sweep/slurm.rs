//! A sweep as a Slurm job array: one array task per shard, each resuming its own folder, and
//! a collect job that merges them. syncroad schedules nothing itself; the scripts are written
//! for the user to read, adapt and submit.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::error::InputError;

/// What the scripts ask of the cluster.
#[derive(Debug, Clone)]
pub struct SlurmOptions {
    /// Array tasks (= shards).
    pub shards: usize,
    /// Tasks running at once.
    pub max_running: usize,
    /// CPUs per task.
    pub cpus_per_task: usize,
    /// `--partition`.
    pub partition: Option<String>,
    /// `--account`.
    pub account: Option<String>,
    /// `--time`.
    pub time: Option<String>,
    /// Other sbatch options, verbatim.
    pub extra: Vec<String>,
}

/// The files written.
#[derive(Debug, Clone)]
pub struct Emitted {
    /// The array job.
    pub array: PathBuf,
    /// The merge job.
    pub collect: PathBuf,
    /// Submits both, the merge after the array.
    pub submit: PathBuf,
}

/// Quotes `s` for a POSIX shell.
fn sh(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,@%".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

fn abs(p: &Path) -> anyhow::Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

fn header(name: &str, opts: &SlurmOptions, lines: &mut Vec<String>) {
    lines.push("#!/bin/bash".into());
    lines.push(format!("#SBATCH --job-name={}", sh(name)));
    if let Some(p) = &opts.partition {
        lines.push(format!("#SBATCH --partition={}", sh(p)));
    }
    if let Some(a) = &opts.account {
        lines.push(format!("#SBATCH --account={}", sh(a)));
    }
    if let Some(t) = &opts.time {
        lines.push(format!("#SBATCH --time={}", sh(t)));
    }
    for x in &opts.extra {
        lines.push(format!("#SBATCH {x}"));
    }
}

/// Writes `sweep.sbatch`, `collect.sbatch` and `submit.sh` into `dir`. Shard `i` writes
/// `OUT/shard-i`; running the array again resumes every shard where it stopped.
pub fn emit(
    name: &str,
    spec: &Path,
    out: &Path,
    dir: &Path,
    opts: &SlurmOptions,
) -> anyhow::Result<Emitted> {
    if opts.shards == 0 || opts.shards > 100_000 {
        return Err(InputError::new(format!(
            "--shards = {}: must be between 1 and 100000",
            opts.shards
        ))
        .into());
    }
    if opts.max_running == 0 {
        return Err(InputError::new("--max-running = 0: must be ≥ 1").into());
    }
    if opts.cpus_per_task == 0 {
        return Err(InputError::new("--cpus-per-task = 0: must be ≥ 1").into());
    }
    for x in &opts.extra {
        if !x.starts_with('-') || x.contains('\n') {
            return Err(InputError::new(format!(
                "--sbatch-option = {x:?}: give one sbatch option as written on its command line, e.g. --mem=4G"
            ))
            .into());
        }
    }
    std::fs::create_dir_all(dir.join("logs"))
        .with_context(|| format!("cannot create {}", dir.join("logs").display()))?;
    let exe = std::env::current_exe().context("cannot locate the syncroad executable")?;
    let (exe, spec, out, dir) = (abs(&exe)?, abs(spec)?, abs(out)?, abs(dir)?);
    let s = |p: &Path| sh(&p.display().to_string());
    let job = format!("syncroad-{name}");

    let mut a = Vec::new();
    header(&job, opts, &mut a);
    a.push(format!(
        "#SBATCH --array=0-{}%{}",
        opts.shards - 1,
        opts.max_running
    ));
    a.push(format!("#SBATCH --cpus-per-task={}", opts.cpus_per_task));
    a.push(format!(
        "#SBATCH --output={}",
        s(&dir.join("logs/%A_%a.out"))
    ));
    a.push(format!(
        "#SBATCH --error={}",
        s(&dir.join("logs/%A_%a.err"))
    ));
    a.push(String::new());
    a.push("# One shard per array task; a resubmitted array resumes each shard's folder.".into());
    a.push("set -euo pipefail".into());
    a.push(format!(
        "exec {} sweep {} --out {}/shard-\"$SLURM_ARRAY_TASK_ID\" --shard \"$SLURM_ARRAY_TASK_ID\"/{} --jobs \"${{SLURM_CPUS_PER_TASK:-1}}\" --no-plots",
        s(&exe),
        s(&spec),
        s(&out),
        opts.shards
    ));
    let array = dir.join("sweep.sbatch");
    std::fs::write(&array, a.join("\n") + "\n")
        .with_context(|| format!("cannot write {}", array.display()))?;

    let mut c = Vec::new();
    header(&format!("{job}-collect"), opts, &mut c);
    c.push(format!(
        "#SBATCH --output={}",
        s(&dir.join("logs/collect_%j.out"))
    ));
    c.push(String::new());
    c.push("set -euo pipefail".into());
    let shards: Vec<String> = (0..opts.shards)
        .map(|i| s(&out.join(format!("shard-{i}"))))
        .collect();
    c.push(format!(
        "exec {} sweep collect {} --out {} {}",
        s(&exe),
        s(&spec),
        s(&out.join("merged")),
        shards.join(" ")
    ));
    let collect = dir.join("collect.sbatch");
    std::fs::write(&collect, c.join("\n") + "\n")
        .with_context(|| format!("cannot write {}", collect.display()))?;

    let submit = dir.join("submit.sh");
    let text = format!(
        "#!/bin/bash\n# Submits the array, then the merge once every task has ended (finished or not:\n# collect reports missing points, and submitting the array again resumes them).\nset -euo pipefail\narray=$(sbatch --parsable \"$@\" {})\necho \"array job $array\"\nsbatch --dependency=afterany:\"${{array%%;*}}\" \"$@\" {}\n",
        s(&array),
        s(&collect)
    );
    std::fs::write(&submit, text).with_context(|| format!("cannot write {}", submit.display()))?;
    Ok(Emitted {
        array,
        collect,
        submit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quoting_survives_spaces_and_quotes() {
        assert_eq!(sh("/a/b.json"), "/a/b.json");
        assert_eq!(sh("a b"), "'a b'");
        assert_eq!(sh("it's"), "'it'\\''s'");
    }
}
