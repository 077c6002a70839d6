//! Helpers shared by the binary's end-to-end tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `syncroad` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_syncroad"))
}

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A fresh, empty folder for one test, removed with everything in it when the test ends
/// (also when it fails). Use it as a `&Path`.
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<std::ffi::OsStr> for Scratch {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.path().as_os_str()
    }
}

/// A fresh, empty folder for one test, named after it (`syncroad-test-NAME-…` in the system's
/// temporary folder).
pub fn tmpdir(name: &str) -> Scratch {
    Scratch(
        tempfile::Builder::new()
            .prefix(&format!("syncroad-test-{name}-"))
            .tempdir()
            .unwrap(),
    )
}

/// Runs a command: (exit code, stdout, stderr).
pub fn run(cmd: &mut Command) -> (i32, String, String) {
    let Output {
        status,
        stdout,
        stderr,
    } = cmd.output().expect("binary runs");
    (
        status.code().unwrap_or(-1),
        String::from_utf8_lossy(&stdout).into_owned(),
        String::from_utf8_lossy(&stderr).into_owned(),
    )
}

/// Every violation of `schema` by `doc`, with its JSON path (a maintained validator,
/// `jsonschema`, draft 2020-12).
pub fn schema_violations(schema: &serde_json::Value, doc: &serde_json::Value) -> Vec<String> {
    let v = jsonschema::draft202012::new(schema).expect("the schema compiles");
    v.iter_errors(doc)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect()
}

/// The published metrics schema.
pub fn metrics_schema() -> serde_json::Value {
    let text = std::fs::read_to_string(repo().join("docs/metrics.schema.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The pids whose parent is `parent` (from /proc).
pub fn children_of(parent: u32) -> Vec<i32> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        // pid (comm) state ppid ...: comm may hold spaces, so split after its ')'.
        let ppid = stat
            .rsplit_once(')')
            .and_then(|(_, rest)| rest.split_whitespace().nth(1))
            .and_then(|p| p.parse::<u32>().ok());
        if ppid == Some(parent) {
            out.push(pid);
        }
    }
    out
}

/// A child's stderr read line by line on a thread, so a test can act once the child has said
/// something (a progress line: the run is under way and has recorded samples) instead of after
/// a guessed delay, which a loaded machine or a slow start can outlast.
pub struct StderrLines {
    lines: std::sync::mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl StderrLines {
    /// Takes the piped stderr of `child`.
    pub fn of(child: &mut std::process::Child) -> Self {
        use std::io::BufRead;
        let err = child.stderr.take().expect("stderr is piped");
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in std::io::BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self {
            lines,
            seen: Vec::new(),
        }
    }

    /// Waits for the first line that satisfies `pred` and returns it; panics with everything
    /// seen when the child closes stderr first, or after two minutes.
    pub fn wait_for(&mut self, pred: impl Fn(&str) -> bool) -> String {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if pred(&line) {
                        return line;
                    }
                }
                Err(e) => panic!(
                    "no such line on stderr ({e}); it said:\n{}",
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Waits for a progress line (`--progress lines`) that reports at least `samples`
    /// recorded samples; returns how many it reports.
    pub fn wait_for_samples(&mut self, samples: usize) -> usize {
        let line = self.wait_for(|l| samples_in(l).is_some_and(|n| n >= samples));
        samples_in(&line).expect("a progress line")
    }

    /// All of stderr, once the child has closed it (it has exited).
    pub fn rest(mut self) -> String {
        self.seen.extend(self.lines.iter());
        self.seen.join("\n")
    }
}

/// The samples a progress line (`run: t = … s (…%), N samples recorded; …`) reports.
pub fn samples_in(line: &str) -> Option<usize> {
    let (before, _) = line.split_once(" samples recorded")?;
    before.rsplit(' ').next()?.parse().ok()
}

/// True while process `pid` exists and has not exited (a zombie waiting for its parent has).
pub fn running(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|stat| {
        stat.rsplit_once(')')
            .and_then(|(_, rest)| rest.split_whitespace().next())
            .is_some_and(|state| state != "Z")
    })
}

/// A copy of the shipped scenario `name` (its network path made absolute) changed by `edit`,
/// written to `dir/sc.json`.
pub fn edited_scenario(
    dir: &std::path::Path,
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value),
) -> std::path::PathBuf {
    let scenarios = repo().join("scenarios");
    let text = std::fs::read_to_string(scenarios.join(format!("{name}.json"))).unwrap();
    let mut sc: serde_json::Value = serde_json::from_str(&text).unwrap();
    if let Some(net) = sc["sumo"]["net"].as_str() {
        sc["sumo"]["net"] = serde_json::json!(scenarios.join(net));
    }
    edit(&mut sc);
    let path = dir.join("sc.json");
    std::fs::write(&path, sc.to_string()).unwrap();
    path
}

/// The guide's two-lane test track (`examples/track`) in `dir/track`: the files named in
/// `files` copied beside its node and edge files, and `track.net.xml` built by the project's
/// netconvert, as docs/src/own-network.md builds it. Returns the folder.
pub fn guide_track(dir: &Path, files: &[&str]) -> PathBuf {
    let track = dir.join("track");
    std::fs::create_dir_all(&track).unwrap();
    for f in ["track.nod.xml", "track.edg.xml"].iter().chain(files) {
        std::fs::copy(repo().join("examples/track").join(f), track.join(f)).unwrap();
    }
    let netconvert = repo().join(".venv/lib/python3.11/site-packages/sumo/bin/netconvert");
    let (code, _, err) = run(Command::new(netconvert).current_dir(&track).args([
        "--node-files",
        "track.nod.xml",
        "--edge-files",
        "track.edg.xml",
        "--no-turnarounds",
        "true",
        "-o",
        "track.net.xml",
    ]));
    assert_eq!(code, 0, "netconvert: {err}");
    track
}
