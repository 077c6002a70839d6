//! Hostile surroundings: an output folder that is a file or holds an earlier run, a full disk,
//! a closed or full stdout. Native runs, so no SUMO is needed.

use std::os::unix::process::CommandExt as _;
use std::path::Path;
use std::process::{Command, Stdio};

mod common;
use common::*;

fn simulate(out: &Path) -> Command {
    let mut c = bin();
    c.arg("simulate")
        .arg(repo().join("scenarios/ring-theorem1.json"))
        .arg("--out")
        .arg(out)
        .arg("--no-plots");
    c
}

/// Files in `dir`, sorted, without the folder's lock file (`.syncroad.lock`, kept: removing a
/// lock file on release would let two writers hold two different files).
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name != ".syncroad.lock")
        .collect();
    v.sort();
    v
}

#[test]
fn an_existing_file_as_out_is_bad_input() {
    let dir = tmpdir("out-is-file");
    let file = dir.join("taken");
    std::fs::write(&file, "mine").unwrap();
    let (code, _, err) = run(&mut simulate(&file));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--out") && err.contains("existing file"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "mine");
}

#[test]
fn a_folder_where_a_file_goes_is_refused_before_the_run() {
    let dir = tmpdir("csv-is-dir");
    std::fs::create_dir(dir.join("trajectories.csv")).unwrap();
    let (code, out, err) = run(&mut simulate(&dir));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("trajectories.csv is a folder"), "{err}");
    // Refused before the run: nothing computed, nothing printed.
    assert!(!out.contains("verdict"), "{out}");
    assert_eq!(listing(&dir), ["trajectories.csv"]);
}

#[test]
fn a_full_disk_loses_no_verdict_and_leaves_no_cut_off_file_nor_an_earlier_record() {
    // A file-size limit of 64 KiB stands in for a full disk (the write fails with EFBIG as it
    // would with ENOSPC); the CSV of this run is about 2 MB. With SIGXFSZ ignored, and at its
    // default, where passing the limit used to kill the command with nothing written but a
    // temporary file (`ulimit -f` in a batch script): both end as a full disk does.
    for ignored in [true, false] {
        let dir = tmpdir(&format!("full-disk-{ignored}"));
        std::fs::write(dir.join("metrics.json"), r#"{"complete": true}"#).unwrap();
        let mut cmd = simulate(&dir);
        unsafe {
            cmd.pre_exec(move || {
                let action = if ignored {
                    libc::SIG_IGN
                } else {
                    libc::SIG_DFL
                };
                libc::signal(libc::SIGXFSZ, action);
                let lim = libc::rlimit {
                    rlim_cur: 64 * 1024,
                    rlim_max: 64 * 1024,
                };
                if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let (code, out, err) = run(&mut cmd);
        assert_eq!(code, 3, "SIGXFSZ ignored: {ignored}: {out}{err}");
        assert!(out.contains("verdict: synchronized"), "{out}");
        assert!(
            err.contains("cannot write") && err.contains("trajectories.csv"),
            "{err}"
        );
        // No cut-off CSV, no temporary file, and the earlier run's record is gone; this run's
        // record is kept whole under a new name that the error gives.
        let left = listing(&dir);
        assert_eq!(left.len(), 1, "{left:?}");
        assert!(
            left[0].starts_with("metrics.unsaved-") && left[0].ends_with(".json"),
            "{left:?}"
        );
        assert!(err.contains(&left[0]), "{err}");
        let kept: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join(&left[0])).unwrap()).unwrap();
        assert_eq!(kept["sync"]["verdict"], "synchronized", "{kept}");
    }
}

#[test]
fn a_closed_stdout_stops_printing_but_not_the_run() {
    for cmd in ["simulate", "check", "stability"] {
        let dir = tmpdir(&format!("epipe-{cmd}"));
        let mut c = bin();
        c.arg(cmd).arg(repo().join("scenarios/ring-theorem1.json"));
        if cmd == "simulate" {
            c.arg("--out").arg(&dir).arg("--no-plots");
        }
        if cmd == "stability" {
            c.arg("--json");
        }
        // The reader is gone before the first line: every write meets EPIPE.
        let mut child = c
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("panicked"), "{cmd}: {err}");
        assert_eq!(o.status.code(), Some(0), "{cmd}: {err}");
        if cmd == "simulate" {
            assert_eq!(
                listing(&dir),
                ["metrics.json", "road.json", "trajectories.csv"]
            );
        }
    }
}

/// `syncroad … 2>&1 | head -1`: once the reader is gone, stderr meets EPIPE too. Writing an
/// error, a warning or progress there must not panic (exit 101): the command keeps its own
/// exit code. Here the reader is gone before the first byte, so every write to either stream
/// fails, whatever the machine's timing.
#[test]
fn a_closed_stderr_never_panics_and_keeps_the_exit_code() {
    let dir = tmpdir("epipe-stderr");
    let ring = repo().join("scenarios/ring-theorem1.json");
    let sugiyama = repo().join("scenarios/sugiyama-ring.json");
    let missing = dir.join("missing.json");
    let cases: Vec<(Vec<std::ffi::OsString>, i32)> = vec![
        (vec!["schema".into()], 0),
        (vec!["--help".into()], 0),
        (vec!["check".into(), ring.clone().into()], 0),
        (vec!["stability".into(), sugiyama.clone().into()], 0),
        (vec!["check".into(), missing.clone().into()], 2),
        (vec!["frobnicate".into()], 2),
        (
            vec![
                "simulate".into(),
                ring.clone().into(),
                "--out".into(),
                dir.join("run").into(),
                "--no-plots".into(),
                "--progress".into(),
                "lines".into(),
            ],
            0,
        ),
    ];
    for (args, want) in cases {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = bin()
            .args(&args)
            .stdout(writer.try_clone().unwrap())
            .stderr(writer)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(want), "{args:?}");
    }
}

/// A full device is not a closed reader: what the command printed is lost, so it says so and
/// does not exit 0 — for a run (its files are whole) and for the commands whose result is
/// what they print.
#[test]
fn stdout_on_a_full_device_is_an_error_not_a_success() {
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let dir = tmpdir("dev-full");
    let o = simulate(&dir).stdout(full()).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(
        err.contains("cannot write to standard output: No space left on device"),
        "{err}"
    );
    assert_eq!(
        listing(&dir),
        ["metrics.json", "road.json", "trajectories.csv"]
    );
    let scenario = repo().join("scenarios/sugiyama-ring.json");
    for args in [vec!["schema"], vec!["check", "--json"], vec!["stability"]] {
        let mut c = bin();
        c.arg(args[0]);
        if args[0] != "schema" {
            c.arg(&scenario).args(&args[1..]);
        }
        let o = c.stdout(full()).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{args:?}: {err}");
        assert!(
            err.contains("cannot write to standard output"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn regress_update_refuses_an_incomplete_run_and_keeps_the_baseline() {
    let dir = tmpdir("update-incomplete");
    let (code, _, err) = run(&mut simulate(&dir.join("run")));
    assert_eq!(code, 0, "{err}");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("run/metrics.json")).unwrap())
            .unwrap();
    m["complete"] = false.into();
    m["error"] = "interrupted (Ctrl-C) after 12 recorded samples".into();
    std::fs::write(dir.join("partial.json"), m.to_string()).unwrap();
    let base = dir.join("baseline.json");
    let before = std::fs::read_to_string(repo().join("tests/baselines/ring-theorem1.native.json"))
        .unwrap()
        .replace(
            "../../scenarios/",
            &format!("{}/scenarios/", repo().display()),
        );
    std::fs::write(&base, &before).unwrap();
    let (code, _, err) = run(bin()
        .args(["regress", "--update", "--metrics"])
        .arg(dir.join("partial.json"))
        .arg(&base));
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains("only from complete runs") && err.contains("interrupted"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&base).unwrap(), before);
}

/// The committed native baseline, its scenario path made absolute, with `edit` applied.
fn native_baseline(dir: &Path, edit: impl FnOnce(&mut serde_json::Value)) -> std::path::PathBuf {
    let text =
        std::fs::read_to_string(repo().join("tests/baselines/ring-theorem1.native.json")).unwrap();
    let mut b: serde_json::Value = serde_json::from_str(&text).unwrap();
    b["scenario"] = repo()
        .join("scenarios/ring-theorem1.json")
        .display()
        .to_string()
        .into();
    edit(&mut b);
    let path = dir.join("baseline.json");
    std::fs::write(&path, b.to_string()).unwrap();
    path
}

#[test]
fn regress_writes_junit_and_markdown_and_strict_fails_on_a_foreign_stamp() {
    let dir = tmpdir("regress-reports");
    // Recorded "elsewhere", and one metric planted off.
    let base = native_baseline(&dir, |b| {
        b["stamp"]["platform"] = "riscv64-plan9".into();
        b["metrics"]["sync"]["spread_l2"] = 99.0.into();
    });
    let (junit, md) = (dir.join("r.xml"), dir.join("r.md"));
    let (code, out, err) = run(bin()
        .arg("regress")
        .arg(&base)
        .arg("--junit")
        .arg(&junit)
        .arg("--markdown")
        .arg(&md));
    assert_eq!(code, 1, "{out}{err}");
    let x = std::fs::read_to_string(&junit).unwrap();
    let doc = roxmltree::Document::parse(&x).expect("the JUnit report is XML");
    let cases: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("testcase"))
        .collect();
    assert!(cases.len() > 50, "{x}");
    let failed: Vec<_> = cases
        .iter()
        .filter(|c| c.children().any(|k| k.has_tag_name("failure")))
        .collect();
    assert_eq!(failed.len(), 1, "{x}");
    assert_eq!(failed[0].attribute("name"), Some("sync.spread_l2"), "{x}");
    let suite = doc
        .descendants()
        .find(|n| n.has_tag_name("testsuite"))
        .unwrap();
    assert_eq!(suite.attribute("failures"), Some("1"), "{x}");
    assert_eq!(
        suite.attribute("tests"),
        Some(cases.len().to_string().as_str())
    );
    let stamp = cases
        .iter()
        .find(|c| c.attribute("name") == Some("stamp.platform"))
        .expect("a test case for the platform stamp");
    let out = stamp
        .children()
        .find(|k| k.has_tag_name("system-out"))
        .and_then(|k| k.text())
        .unwrap_or("");
    assert!(out.starts_with("platform: baseline"), "{x}");
    let m = std::fs::read_to_string(&md).unwrap();
    assert!(
        m.contains(": FAIL") && m.contains("| `sync.spread_l2` | 99.0 |"),
        "{m}"
    );
    assert!(m.contains("riscv64-plan9"), "{m}");

    // Only the stamp differs: reported and passing, unless --strict.
    let base = native_baseline(&dir, |b| b["stamp"]["platform"] = "riscv64-plan9".into());
    let (code, out, _) = run(bin().arg("regress").arg(&base));
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("note: stamp differs"), "{out}");
    let (code, out, err) = run(bin()
        .arg("regress")
        .arg(&base)
        .arg("--strict")
        .arg("--junit")
        .arg(&junit));
    assert_eq!(code, 1, "{out}{err}");
    assert!(err.contains("--strict"), "{err}");
    let x = std::fs::read_to_string(&junit).unwrap();
    let doc = roxmltree::Document::parse(&x).expect("the JUnit report is XML");
    let stamp = doc
        .descendants()
        .find(|n| n.has_tag_name("testcase") && n.attribute("name") == Some("stamp.platform"))
        .expect("a test case for the platform stamp");
    assert!(stamp.children().any(|k| k.has_tag_name("failure")), "{x}");
}

/// `scenarios/ring-theorem1.json` with `edit` applied, written into `dir`.
fn theorem1_variant(
    dir: &Path,
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value),
) -> std::path::PathBuf {
    let mut s: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/ring-theorem1.json")).unwrap(),
    )
    .unwrap();
    edit(&mut s);
    let p = dir.join(name);
    std::fs::write(&p, s.to_string()).unwrap();
    p
}

#[test]
fn horizons_and_steps_that_would_exhaust_memory_or_time_are_refused_up_front() {
    let dir = tmpdir("limits");
    let huge = theorem1_variant(&dir, "huge.json", |s| s["horizon_s"] = 1e12.into());
    let tiny = theorem1_variant(&dir, "tiny.json", |s| s["step_s"] = 1e-9.into());
    for (sc, needle) in [
        (&huge, "horizon_s = 1000000000000 s with step_s = 0.1 s is 10000000000000 steps; at most 10000000 steps are allowed, so give horizon_s ≤ 1000000 s"),
        (&tiny, "horizon_s = 300 s with step_s = 0.000000001 s is 300000000000 steps"),
    ] {
        for cmd in ["simulate", "run"] {
            let out = dir.join(format!("out-{cmd}"));
            let (code, stdout, err) = run(bin().arg(cmd).arg(sc).arg("--out").arg(&out));
            assert_eq!(code, 2, "{cmd} {}: {stdout}{err}", sc.display());
            assert!(err.contains(needle), "{err}");
            assert!(!stdout.contains("verdict"), "{stdout}");
        }
    }
    // Within the step limit, a stride that would keep 2.2e8 vehicle-samples is refused too.
    let long = theorem1_variant(&dir, "long.json", |s| s["horizon_s"] = 1e6.into());
    let (code, _, err) = run(bin()
        .arg("simulate")
        .arg(&long)
        .args(["--record-every", "1", "--out"])
        .arg(dir.join("o")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--record-every = 1: 10000000 steps (horizon_s = 1000000 s / step_s = 0.1 s) of 22 vehicles would record 220000044 vehicle-samples")
            && err.contains("give --record-every ≥ 5"),
        "{err}"
    );
}

#[test]
fn termination_signals_stop_a_long_native_run_and_keep_its_rows() {
    let dir = tmpdir("native-signals");
    // 10⁷ steps of 220 vehicles: about half a minute, so the signal comes mid-run.
    let long = theorem1_variant(&dir, "long.json", |s| {
        s["horizon_s"] = 1e6.into();
        s["vehicles"] = 220.into();
        s["road"]["length_m"] = 2300.into();
        s["model"]["delay_s"] = 0.6.into();
    });
    for (sig, code) in [
        (libc::SIGTERM, 143),
        (libc::SIGHUP, 129),
        (libc::SIGINT, 130),
    ] {
        let out = dir.join(format!("out-{sig}"));
        let mut child = bin()
            .arg("simulate")
            .arg(&long)
            .arg("--out")
            .arg(&out)
            .args(["--no-plots", "--progress", "lines"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Mid-run: once the run reports its first 10⁴ steps, whatever the machine's load.
        let mut lines = StderrLines::of(&mut child);
        lines.wait_for(|l| l.starts_with("simulate: t = "));
        // SAFETY: signalling our own child by its pid.
        unsafe { libc::kill(child.id() as i32, sig) };
        let o = child.wait_with_output().unwrap();
        let err = lines.rest();
        assert_eq!(o.status.code(), Some(code), "signal {sig}: {err}");
        assert!(err.contains("error: interrupted at t = "), "{err}");
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["complete"], false, "{m}");
        assert_eq!(m["stop"]["reason"], "interrupted", "{m}");
        assert_ne!(m["sync"]["verdict"], "synchronized", "{m}");
        // The CSV ends at the step the run stopped at.
        let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
        let last_t: f64 = csv
            .lines()
            .last()
            .unwrap()
            .split(',')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let stopped = m["stop"]["time_s"].as_f64().unwrap();
        assert!(
            (last_t - stopped).abs() < 1e-6 && stopped > 0.0,
            "{last_t} {stopped}"
        );
    }
}

/// A compare whose every run fails before its first sample (here: no SUMO environment) ends
/// with exit 3 and the failures named; it once spun on the spread plot's empty log axis until
/// memory ran out.
#[test]
fn a_compare_where_every_run_fails_before_starting_ends_cleanly() {
    let dir = tmpdir("compare-all-failed");
    let (code, out, err) = run(bin()
        .env("SYNCROAD_VENV", dir.join("no-such-venv"))
        .args([
            "compare",
            "--baselines",
            "protocol,idm",
            "--no-plots",
            "--out",
        ])
        .arg(dir.join("out"))
        .arg(repo().join("scenarios/sugiyama-ring.json")));
    assert_eq!(code, 3, "{out}\n{err}");
    assert!(
        err.contains("run protocol failed") && err.contains("not a virtualenv"),
        "{err}"
    );
    let (code, _, err) = run(bin()
        .env("SYNCROAD_VENV", dir.join("no-such-venv"))
        .args(["compare", "--baselines", "protocol", "--out"])
        .arg(dir.join("out-plots"))
        .arg(repo().join("scenarios/sugiyama-ring.json")));
    assert_eq!(code, 3, "{err}");
    assert!(!dir.join("out-plots/compare_spread.png").exists());
}
