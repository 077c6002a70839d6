//! A sweep as a Slurm job array: one array task per shard, each resuming its own folder, and
//! a collect job that merges them. syncroad schedules nothing itself; the scripts are written
//! for the user to read, adapt and submit.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::error::InputError;
use crate::output::write_text;

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
    /// Options of the sweep every array task runs with (`--keep-runs`, `--fcd`, …), one word
    /// each.
    pub task_flags: Vec<String>,
    /// Options the merge job passes on to `sweep collect` (`--safety`, which the spec's hash
    /// covers), one word each.
    pub collect_flags: Vec<String>,
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

/// Quotes `s` as one word of a POSIX shell (shlex), so no value of a spec or a flag is read
/// as shell syntax when the script runs.
fn sh(s: &str) -> anyhow::Result<String> {
    Ok(shlex::try_quote(s)
        .map_err(|_| InputError::new(format!("{s:?}: a NUL byte cannot be passed to a shell")))?
        .into_owned())
}

/// A value for an `#SBATCH` line (`field` names it for the error): quoted, and refused when it
/// holds a line break or another control character, which would end the comment line and
/// let the rest run as a command.
fn sbatch_value(field: &str, value: &str) -> anyhow::Result<String> {
    if let Some(c) = value.chars().find(|c| c.is_control()) {
        return Err(InputError::new(format!(
            "{field} = {value:?}: holds the control character {c:?}, which cannot go into an #SBATCH line of a job script; use letters, digits and punctuation"
        ))
        .into());
    }
    sh(value)
}

/// The second line of every script syncroad writes: a script that has it may be written
/// again; any other file at a script's path is the user's and is never replaced.
const MARKER: &str =
    "# Written by `syncroad sweep --emit-slurm`; emitting again replaces this file.";

/// Refuses to emit into `dir` when a script's path holds something syncroad did not write.
fn refuse_foreign_scripts(dir: &Path) -> anyhow::Result<()> {
    for name in ["sweep.sbatch", "collect.sbatch", "submit.sh"] {
        let path = dir.join(name);
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        let ours = meta.is_file()
            && std::fs::read_to_string(&path).is_ok_and(|t| t.lines().nth(1) == Some(MARKER));
        if !ours {
            return Err(InputError::new(format!(
                "--emit-slurm = {}: {} exists and was not written by syncroad; move it away or give another --emit-slurm folder",
                dir.display(),
                path.display()
            ))
            .into());
        }
    }
    Ok(())
}

/// `path` quoted as one shell word, for a command the user is told to type.
pub fn shell_word(path: &Path) -> String {
    let text = path.display().to_string();
    sh(&text).unwrap_or(text)
}

fn abs(p: &Path) -> anyhow::Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

fn header(
    field: &str,
    name: &str,
    opts: &SlurmOptions,
    lines: &mut Vec<String>,
) -> anyhow::Result<()> {
    lines.push("#!/bin/bash".into());
    lines.push(MARKER.into());
    lines.push(format!("#SBATCH --job-name={}", sbatch_value(field, name)?));
    for (flag, value) in [
        ("partition", &opts.partition),
        ("account", &opts.account),
        ("time", &opts.time),
    ] {
        if let Some(v) = value {
            lines.push(format!(
                "#SBATCH --{flag}={}",
                sbatch_value(&format!("--{flag}"), v)?
            ));
        }
    }
    for x in &opts.extra {
        lines.push(format!("#SBATCH {x}"));
    }
    Ok(())
}

/// Refuses, before anything is written, options no scheduler could run: the shard count, a
/// job name or an sbatch option that would break a script line, and a file where the script
/// folder goes.
fn check_options(name: &str, dir: &Path, opts: &SlurmOptions) -> anyhow::Result<()> {
    if opts.shards == 0 || opts.shards > 100_000 {
        return Err(InputError::new(format!(
            "--shards = {}: must be between 1 and 100000",
            opts.shards
        ))
        .into());
    }
    // The spec's name names the jobs: checked as written, before the prefix.
    sbatch_value("name", name)?;
    if opts.max_running == 0 {
        return Err(InputError::new("--max-running = 0: must be ≥ 1").into());
    }
    if opts.cpus_per_task == 0 {
        return Err(InputError::new("--cpus-per-task = 0: must be ≥ 1").into());
    }
    for x in &opts.extra {
        if !x.starts_with('-') || x.chars().any(char::is_control) {
            return Err(InputError::new(format!(
                "--sbatch-option = {x:?}: give one sbatch option as written on its command line, e.g. --mem=4G"
            ))
            .into());
        }
    }
    if dir.exists() && !dir.is_dir() {
        return Err(InputError::new(format!(
            "--emit-slurm = {}: is an existing file, not a folder; name a folder for the job scripts (it is created if missing)",
            dir.display()
        ))
        .into());
    }
    Ok(())
}

/// `flags` as shell words, each after a space.
fn shell_words(flags: &[String]) -> anyhow::Result<String> {
    flags
        .iter()
        .map(|f| sh(f).map(|w| format!(" {w}")))
        .collect()
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
    check_options(name, dir, opts)?;
    refuse_foreign_scripts(dir)?;
    let logs = dir.join("logs");
    let exe = crate::config::program().context("cannot locate the syncroad executable")?;
    let (exe, spec, out, dir) = (abs(&exe)?, abs(spec)?, abs(out)?, abs(dir)?);
    let s = |p: &Path| sh(&p.display().to_string());
    let line = |p: &Path| sbatch_value("the script folder", &p.display().to_string());
    // Every path that goes into a script is checked before anything is created: a refused
    // one leaves no folder behind.
    line(&dir)?;
    for p in [&exe, &spec, &out, &dir] {
        s(p)?;
    }
    std::fs::create_dir_all(&logs).with_context(|| format!("cannot create {}", logs.display()))?;
    let job = format!("syncroad-{name}");

    let mut a = Vec::new();
    header("name", &job, opts, &mut a)?;
    a.push(format!(
        "#SBATCH --array=0-{}%{}",
        opts.shards - 1,
        opts.max_running
    ));
    a.push(format!("#SBATCH --cpus-per-task={}", opts.cpus_per_task));
    a.push(format!(
        "#SBATCH --output={}",
        line(&dir.join("logs/%A_%a.out"))?
    ));
    a.push(format!(
        "#SBATCH --error={}",
        line(&dir.join("logs/%A_%a.err"))?
    ));
    a.push(String::new());
    a.push("# One shard per array task; a resubmitted array resumes each shard's folder.".into());
    a.push("set -euo pipefail".into());
    let flags = shell_words(&opts.task_flags)?;
    a.push(format!(
        "exec {} sweep {} --out {}/shard-\"$SLURM_ARRAY_TASK_ID\" --shard \"$SLURM_ARRAY_TASK_ID\"/{} --jobs \"${{SLURM_CPUS_PER_TASK:-1}}\" --no-plots{flags}",
        s(&exe)?,
        s(&spec)?,
        s(&out)?,
        opts.shards
    ));
    let array = dir.join("sweep.sbatch");
    write_text(&array, &(a.join("\n") + "\n"))?;

    let mut c = Vec::new();
    header("name", &format!("{job}-collect"), opts, &mut c)?;
    c.push(format!(
        "#SBATCH --output={}",
        line(&dir.join("logs/collect_%j.out"))?
    ));
    c.push(String::new());
    c.push("set -euo pipefail".into());
    let shards = (0..opts.shards)
        .map(|i| s(&out.join(format!("shard-{i}"))))
        .collect::<anyhow::Result<Vec<String>>>()?;
    let collect_flags = shell_words(&opts.collect_flags)?;
    c.push(format!(
        "exec {} sweep collect {} --out {}{collect_flags} {}",
        s(&exe)?,
        s(&spec)?,
        s(&out.join("merged"))?,
        shards.join(" ")
    ));
    let collect = dir.join("collect.sbatch");
    write_text(&collect, &(c.join("\n") + "\n"))?;

    let submit = dir.join("submit.sh");
    let text = format!(
        "#!/bin/bash\n{MARKER}\n# Submits the array, then the merge once every task has ended (finished or not:\n# collect reports missing points, and submitting the array again resumes them).\nset -euo pipefail\narray=$(sbatch --parsable \"$@\" {})\necho \"array job $array\"\nsbatch --dependency=afterany:\"${{array%%;*}}\" \"$@\" {}\n",
        s(&array)?,
        s(&collect)?
    );
    write_text(&submit, &text)?;
    Ok(Emitted {
        array,
        collect,
        submit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What bash makes of `word`: the words it splits `echo WORD` into, run for real.
    fn bash_words(word: &str) -> Vec<String> {
        let out = std::process::Command::new("bash")
            .arg("-c")
            .arg(format!("printf '%s\\0' {word}"))
            .output()
            .expect("bash runs");
        assert!(out.status.success(), "{word}: {out:?}");
        String::from_utf8(out.stdout)
            .unwrap()
            .split_terminator('\0')
            .map(str::to_string)
            .collect()
    }

    #[test]
    fn quoting_gives_bash_back_the_value_as_one_word() {
        assert_eq!(sh("/a/b.json").unwrap(), "/a/b.json");
        for hostile in [
            "a b",
            "it's",
            "$(touch pwned)",
            "`touch pwned`",
            "x\ntouch pwned",
            "\"; touch pwned; \"",
            "'; touch pwned; '",
            "*",
            "~",
            "a\\b",
            "",
        ] {
            let q = sh(hostile).unwrap();
            assert_eq!(bash_words(&q), vec![hostile.to_string()], "{q}");
        }
        assert!(sh("a\0b").is_err());
    }

    #[test]
    fn an_sbatch_value_with_a_line_break_is_refused_naming_the_field() {
        let e = sbatch_value("name", "x\ntouch pwned")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("name = \"x\\ntouch pwned\": holds the control character '\\n'"),
            "{e}"
        );
        assert_eq!(sbatch_value("name", "gain delay").unwrap(), "'gain delay'");
    }
}
