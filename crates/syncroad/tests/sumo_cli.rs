//! `syncroad run` on the SUMO backend, end to end with real SUMO (needs the virtualenv of
//! `bash python-host/bootstrap.sh`, which scripts/test.sh runs first).

use std::path::Path;

mod common;
use common::*;

fn run_backend(args: &[&str], scenario: &Path, out: &Path) -> (i32, String, serde_json::Value) {
    let o = bin()
        .args(args)
        .arg(scenario)
        .arg("--out")
        .arg(out)
        .arg("--no-plots")
        .output()
        .unwrap();
    let stdout =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    let m = std::fs::read_to_string(out.join("metrics.json"))
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or_default();
    (o.status.code().unwrap_or(-1), stdout, m)
}

#[test]
fn theorem1_ring_synchronizes_in_sumo_like_the_native_simulator() {
    let (a, b) = (tmpdir("ring-sumo"), tmpdir("ring-native"));
    let (code, out, sumo) = run_backend(&["run"], &repo().join("scenarios/sugiyama-ring.json"), &a);
    assert_eq!(code, 0, "{out}");
    assert_eq!(sumo["backend"], "sumo");
    assert_eq!(sumo["sync"]["verdict"], "synchronized");
    assert_eq!(sumo["safety"]["collision_steps"], 0);
    assert!(sumo["sumo_version"].as_str().unwrap().contains("1.28.0"));
    // Same law, same initial state: the SUMO speeds follow the native simulator's.
    let (code, _, native) = run_backend(
        &["simulate"],
        &repo().join("scenarios/sugiyama-ring.json"),
        &b,
    );
    assert_eq!(code, 0);
    for key in ["final_spread_mps", "spread_l2", "decay_rate_per_s"] {
        let (x, y) = (
            sumo["sync"][key].as_f64().unwrap(),
            native["sync"][key].as_f64().unwrap(),
        );
        assert!(
            (x - y).abs() <= 1e-6 * y.abs().max(1e-3),
            "{key}: sumo {x} native {y}"
        );
    }
}

#[test]
fn ring_past_the_exact_boundary_grows_at_the_predicted_rate_in_sumo() {
    let scenario = repo().join("scenarios/sugiyama-unstable.json");
    let o = bin()
        .args(["stability", "--json"])
        .arg(&scenario)
        .output()
        .unwrap();
    let st: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let abscissa = st["ring"]["abscissa"].as_f64().unwrap();
    assert!(abscissa > 0.0);
    let dir = tmpdir("unstable");
    let (code, out, m) = run_backend(&["run"], &scenario, &dir);
    assert_eq!(code, 1, "{out}");
    assert_eq!(m["sync"]["verdict"], "not_synchronized");
    assert!(
        m["sync"]["final_spread_mps"].as_f64().unwrap()
            > 10.0 * m["sync"]["initial_spread_mps"].as_f64().unwrap()
    );
    // The spread mixes several modes of nearly the same rate: within 15 % of the rightmost root.
    let rate = m["sync"]["decay_rate_per_s"].as_f64().unwrap();
    assert!(
        (rate - abscissa).abs() < 0.15 * abscissa,
        "fitted {rate}, predicted {abscissa}"
    );
}

#[test]
fn cacc_platoon_reaches_desired_gaps_and_leader_speed_in_sumo() {
    let dir = tmpdir("platoon");
    let scenario = dir.join("platoon.json");
    std::fs::write(
        &scenario,
        format!(
            r#"{{"name": "platoon", "backend": "sumo", "seed": 4, "step_s": 0.05, "horizon_s": 150, "vehicles": 6,
                "road": {{"type": "straight"}},
                "model": {{"type": "cacc", "mu": 1.5, "eta": 0.4, "nu": 0.3, "desired_gap_m": 12.0, "tau_s": 0.3,
                          "leader": {{"type": "constant", "speed_mps": 20}}}},
                "initial": {{"speed_mps": 20.0, "perturbation": {{"speed_mps": 1.5, "gap_m": 3.0}}}},
                "sumo": {{"net": "{}"}}}}"#,
            repo().join("sumo-nets/straight-20km.net.xml").display()
        ),
    )
    .unwrap();
    let o = bin().arg("check").arg(&scenario).output().unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "the CACC theorem must hold for this platoon"
    );
    let (code, out, m) = run_backend(&["run"], &scenario, &dir.join("out"));
    assert_eq!(code, 0, "{out}");
    // Slowest closed-loop mode decays at 0.027/s: 3 m gap errors shrink below 0.05 m in 150 s.
    assert!(
        m["sync"]["final_gap_error_m"].as_f64().unwrap() < 0.05,
        "{m}"
    );
    assert!(
        m["sync"]["final_spread_mps"].as_f64().unwrap() < 0.01,
        "{m}"
    );
    assert_eq!(m["safety"]["collision_steps"], 0);
}

#[test]
fn same_seed_gives_identical_metrics_in_separate_runs() {
    let (a, b) = (tmpdir("det-a"), tmpdir("det-b"));
    let scenario = repo().join("scenarios/sugiyama-unstable.json");
    let (ca, _, _) = run_backend(&["run"], &scenario, &a);
    let (cb, _, _) = run_backend(&["run"], &scenario, &b);
    assert_eq!((ca, cb), (1, 1));
    // metrics.json and trajectories.csv are identical byte for byte.
    let strip = |p: &Path| std::fs::read_to_string(p.join("metrics.json")).unwrap();
    assert_eq!(strip(&a), strip(&b));
    assert_eq!(
        std::fs::read(a.join("trajectories.csv")).unwrap(),
        std::fs::read(b.join("trajectories.csv")).unwrap()
    );
}

#[test]
fn missing_net_is_rejected_before_sumo_starts() {
    let dir = tmpdir("missing-net");
    let text = std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap();
    let scenario = dir.join("s.json");
    std::fs::write(
        &scenario,
        text.replace("sugiyama-ring.net.xml", "no-such.net.xml"),
    )
    .unwrap();
    let (code, out, _) = run_backend(&["run"], &scenario, &dir.join("out"));
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("no-such.net.xml"), "{out}");
}

/// The Sugiyama ring scenario, changed by `edit`, written into `dir` (the net path made
/// absolute so the copy finds it).
fn sugiyama_variant(dir: &Path, edit: impl FnOnce(&mut serde_json::Value)) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap();
    let mut s: serde_json::Value = serde_json::from_str(&text).unwrap();
    s["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .to_string_lossy()
        .into();
    edit(&mut s);
    let path = dir.join("scenario.json");
    std::fs::write(&path, serde_json::to_string_pretty(&s).unwrap()).unwrap();
    path
}

#[test]
fn a_diverging_law_that_sumo_clamps_is_not_reported_synchronized() {
    // Absurd gains: SUMO caps the commands, the cars collide and all end at 0 m/s, so the
    // spread alone would say "synchronized".
    for gain in [1e6, 1e300] {
        let dir = tmpdir(&format!("clamped-{:e}", gain));
        let scenario = sugiyama_variant(&dir, |s| {
            s["horizon_s"] = 60.into();
            s["model"]["graph"]["gain_pred"] = gain.into();
            s["model"]["graph"]["gain_follow"] = gain.into();
        });
        let (code, out, m) = run_backend(&["run"], &scenario, &dir.join("out"));
        assert_eq!(code, 1, "gain {gain}: {out}");
        assert!(m["safety"]["collision_steps"].as_u64().unwrap() > 0, "{m}");
        assert_eq!(m["sync"]["verdict"], "not_synchronized", "{out}");
        let why = m["sync"]["verdict_reason"].as_str().unwrap();
        assert!(why.contains("collision steps"), "{why}");
        assert!(out.contains("because SUMO reported"), "{out}");
    }
}

#[test]
fn sigterm_and_sighup_keep_the_rows_like_ctrl_c() {
    // What `timeout`, CI cancellation and `docker stop` send to the parent.
    for (sig, code) in [
        (libc::SIGTERM, 143),
        (libc::SIGHUP, 129),
        (libc::SIGINT, 130),
    ] {
        let dir = tmpdir(&format!("signal-{sig}"));
        let scenario = sugiyama_variant(&dir, |s| s["horizon_s"] = 6000.into());
        let out = dir.join("out");
        let mut child = bin()
            .arg("run")
            .arg(&scenario)
            .arg("--out")
            .arg(&out)
            .args(["--no-plots", "--progress", "lines"])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Once the run reports recorded samples, whatever the machine's load.
        let mut stderr = StderrLines::of(&mut child);
        let reported = stderr.wait_for_samples(11);
        // SAFETY: signalling a child this test started.
        assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0);
        let o = child.wait_with_output().unwrap();
        let err = stderr.rest();
        assert_eq!(o.status.code(), Some(code), "signal {sig}: {err}");
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["complete"], false);
        assert!(m["error"].as_str().unwrap().contains("interrupted"), "{m}");
        let rows = std::fs::read_to_string(out.join("trajectories.csv"))
            .unwrap()
            .lines()
            .count();
        // The header and every sample reported before the signal, at least.
        assert!(rows > 22 * reported, "signal {sig}: {rows} rows kept");
        assert_ne!(m["sync"]["verdict"], "synchronized");
    }
}

#[test]
fn the_recording_stride_does_not_change_sumo_metrics() {
    // Metrics come from the spread of every step, which the worker sends whatever the stride:
    // recording every 1000th step (two samples) must give the very same numbers.
    let dir = tmpdir("sumo-stride");
    let scenario = sugiyama_variant(&dir, |s| s["horizon_s"] = 60.into());
    let (c1, o1, fine) = run_backend(&["run", "--record-every", "1"], &scenario, &dir.join("a"));
    let (c2, o2, coarse) = run_backend(
        &["run", "--record-every", "1000"],
        &scenario,
        &dir.join("b"),
    );
    assert_eq!(c1, c2, "{o1}{o2}");
    assert!(fine["sync"]["spread_l2"].as_f64().unwrap() > 0.1, "{fine}");
    assert_eq!(fine["sync"], coarse["sync"], "{o1}\n{o2}");
    let rows = |d: &str| {
        std::fs::read_to_string(dir.join(d).join("trajectories.csv"))
            .unwrap()
            .lines()
            .count()
    };
    assert_eq!((rows("a"), rows("b")), (601 * 22 + 1, 2 * 22 + 1));
}

#[test]
fn an_ordinary_path_finds_the_embedded_interpreters_own_library() {
    // PATH without the build interpreter: the embedded Python once took /usr/bin/python3's
    // standard library and every run failed on `_posixsubprocess`.
    let dir = tmpdir("plain-path");
    let scenario = sugiyama_variant(&dir, |s| s["horizon_s"] = 10.into());
    let o = bin()
        .env_clear()
        .env("PATH", "/usr/local/bin:/usr/bin:/bin")
        .arg("run")
        .arg(&scenario)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--no-plots")
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(!text.contains("_posixsubprocess"), "{text}");
    assert!(text.contains("SUMO: SUMO 1.28.0"), "{text}");
    assert_ne!(o.status.code(), Some(3), "{text}");
}

#[test]
fn a_missing_environment_is_an_error_without_a_verdict() {
    let dir = tmpdir("no-venv");
    let scenario = sugiyama_variant(&dir, |s| s["horizon_s"] = 10.into());
    let o = bin()
        .env("SYNCROAD_VENV", dir.join("no-such-venv"))
        .arg("run")
        .arg(&scenario)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--no-plots")
        .output()
        .unwrap();
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert_eq!(o.status.code(), Some(3), "{out}{err}");
    assert!(
        !out.contains("verdict") && !out.contains("certified"),
        "{out}"
    );
    assert!(
        err.contains("SUMO did not start")
            && err.contains("SYNCROAD_VENV=")
            && err.contains("is not a virtualenv"),
        "{err}"
    );
    assert!(!dir.join("out/metrics.json").exists());
}

/// A scenario piped in (`/dev/stdin`) has no folder of its own: its relative paths resolve
/// against the current folder, so the Sugiyama ring runs from `scenarios/` as from its file.
#[test]
fn a_scenario_read_from_stdin_resolves_paths_from_the_current_folder() {
    use std::io::Write as _;
    let dir = tmpdir("stdin-scenario");
    let text = std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap();
    let mut child = bin()
        .current_dir(repo().join("scenarios"))
        .args(["run", "/dev/stdin", "--no-plots", "--out"])
        .arg(dir.join("out"))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("verdict: synchronized"), "{stdout}");
}

/// Fault injection through the CLI: the SUMO worker of a `syncroad run` is killed part-way
/// (SIGKILL, SIGABRT, SIGSEGV twice). The run exits 3 and its folder is consistent: a
/// `metrics.json` saying incomplete with the signal in its error and a verdict other than
/// "synchronized", and a `trajectories.csv` of whole samples (22 rows each, times increasing)
/// ending where the record's last sample is.
#[test]
fn a_worker_killed_part_way_leaves_a_consistent_folder() {
    let dir = tmpdir("cli-fault");
    let sc = sugiyama_variant(&dir, |v| {
        v["horizon_s"] = serde_json::json!(100000);
    });
    let mut recorded = 0;
    for (k, (signal, name)) in [
        (libc::SIGKILL, "SIGKILL"),
        (libc::SIGABRT, "SIGABRT"),
        (libc::SIGSEGV, "SIGSEGV"),
    ]
    .into_iter()
    .enumerate()
    {
        let out = dir.join(format!("out-{k}"));
        let mut child = bin()
            .args([
                "run",
                "--no-plots",
                "--record-every",
                "10",
                "--progress",
                "lines",
            ])
            .arg("--out")
            .arg(&out)
            .arg(&sc)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Once the run reports recorded samples (a different count each time).
        let mut lines = StderrLines::of(&mut child);
        lines.wait_for_samples(10 + 40 * k);
        let workers = children_of(child.id());
        assert_eq!(workers.len(), 1, "one worker process: {workers:?}");
        // Until it is gone: a SIGSEGV sent with kill is survived once (see the SUMO crate's
        // fault-injection test), and two signals sent close together may arrive as one.
        while running(workers[0]) {
            // SAFETY: signals the worker our child started.
            unsafe { libc::kill(workers[0], signal) };
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let done = child.wait_with_output().unwrap();
        let stderr = lines.rest();
        assert_eq!(done.status.code(), Some(3), "{name}: {stderr}");
        assert!(stderr.contains(name), "{name}: {stderr}");
        recorded += 1;
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["complete"], false, "{name}");
        let error = m["error"].as_str().unwrap_or("");
        assert!(error.contains(name), "{name}: {error}");
        assert_ne!(m["sync"]["verdict"], "synchronized", "{name}");
        let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
        let rows: Vec<&str> = csv.lines().skip(1).collect();
        assert!(rows.len() >= 22 * 10, "{name}: {} rows", rows.len());
        assert_eq!(rows.len() % 22, 0, "{name}: whole samples only");
        let times: Vec<f64> = rows
            .iter()
            .step_by(22)
            .map(|r| r.split(',').next().unwrap().parse().unwrap())
            .collect();
        assert!(
            times.windows(2).all(|w| w[1] > w[0]),
            "{name}: times increase"
        );
        let last_sample_s = m["stop"]["time_s"].as_f64();
        if let Some(t) = last_sample_s {
            assert!(*times.last().unwrap() <= t + 1e-9, "{name}");
        }
    }
    assert_eq!(recorded, 3);
}

/// Uniform flow — the most basic experiment: every vehicle at the same speed and gap, no
/// perturbation. The spread is 0 at every sample (natively exactly; in SUMO up to round-off),
/// and both backends write the whole folder: plots (a log axis over zeros once made plotters
/// allocate without bound) and `metrics.json`.
#[test]
fn a_ring_in_uniform_flow_writes_its_whole_folder_on_both_backends() {
    let d = tmpdir("uniform-flow");
    let sc = sugiyama_variant(&d, |v| {
        v["initial"].as_object_mut().unwrap().remove("perturbation");
        v["horizon_s"] = serde_json::json!(30);
    });
    for (backend, cmd) in [("native", "simulate"), ("sumo", "run")] {
        let out = d.join(backend);
        let o = bin()
            .arg(cmd)
            .arg(&sc)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let text =
            String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{backend}: {text}");
        for f in [
            "metrics.json",
            "trajectories.csv",
            "spread.png",
            "spread.svg",
            "speeds.png",
            "time_space.png",
        ] {
            assert!(out.join(f).is_file(), "{backend}: {f} missing\n{text}");
        }
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["sync"]["verdict"], "synchronized", "{backend}");
        assert_eq!(m["sync"]["initial_spread_mps"], 0.0, "{backend}");
        let max = m["sync"]["max_spread_mps"].as_f64().unwrap();
        assert!(
            max < 1e-9,
            "{backend}: uniform flow stays uniform, max spread {max}"
        );
    }
}

/// The shipped files of docs/src/own-network.md (`examples/track/`): netconvert builds the
/// two-lane track from their node and edge files, the cycle through `e0` is found and printed, the run
/// synchronizes in SUMO, and a misspelt edge is refused with exit code 2 before SUMO starts.
#[test]
fn own_loop_from_netconvert_runs_and_a_misspelt_edge_exits_2() {
    let dir = tmpdir("own-loop");
    let track = guide_track(&dir, &["own-loop.json"]);
    let scenario = track.join("own-loop.json");
    let (code, out, m) = run_backend(&["run"], &scenario, &dir.join("out"));
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains(
            "road: the shortest cycle through `e0` on lane 1: e0 e1 e2 e3 e4 e5 e6 e7 (8 edges, "
        ),
        "{out}"
    );
    assert_eq!(m["sync"]["verdict"], "synchronized");
    assert_eq!(m["safety"]["collision_steps"], 0);
    // A misspelt edge: exit 2, the field and the nearest ids, and SUMO never started.
    let text = std::fs::read_to_string(&scenario)
        .unwrap()
        .replace(r#""through": "e0""#, r#""edges": ["e0", "e1", "e22"]"#);
    let bad = track.join("typo.json");
    std::fs::write(&bad, text).unwrap();
    let (code, out, _) = run_backend(&["run"], &bad, &dir.join("typo"));
    assert_eq!(code, 2, "{out}");
    assert!(
        out.contains("road.edges[2] = `e22`: ") && out.contains("nearest ids: `e2`, `e0`, `e1`"),
        "{out}"
    );
    assert!(!dir.join("typo/sumo.log").exists());
    // With other traffic (sumo.routes) check and stability say their results are for the
    // fixed graph only.
    std::fs::write(track.join("traffic.rou.xml"), "<routes/>\n").unwrap();
    let text = std::fs::read_to_string(&scenario).unwrap().replace(
        r#""net": "track.net.xml""#,
        r#""net": "track.net.xml", "routes": ["traffic.rou.xml"]"#,
    );
    let traffic = track.join("traffic.json");
    std::fs::write(&traffic, text).unwrap();
    for cmd in ["check", "stability"] {
        let (code, _, err) = run(bin().arg(cmd).arg(&traffic));
        assert_eq!(code, 0, "{cmd}: {err}");
        assert!(
            err.contains("the results above hold for the scenario's fixed graph only"),
            "{cmd}: {err}"
        );
    }
    // The run with the (empty) traffic file: its record, `all_vehicles` included, is in the
    // published shape, and every vehicle is syncroad's, so SUMO's mean over all vehicles is the
    // trajectory's mean speed after the warm-up (to SUMO's printed 0.01 m/s).
    let (code, out, m) = run_backend(&["run"], &traffic, &dir.join("traffic"));
    // Other traffic puts the law under SUMO's checks by default: SUMO holds it back (here at
    // the loop's junction lanes), so its speeds are partly SUMO's and the verdict says
    // inconclusive (exit 1).
    assert_eq!(m["safety_layer"]["mode"], "sumo", "{out}");
    assert_eq!(m["sync"]["verdict"], "inconclusive", "{out}");
    assert_eq!(code, 1, "{out}");
    let v = schema_violations(&metrics_schema(), &m);
    assert!(v.is_empty(), "{v:#?}");
    // The user's traffic can change who follows whom: no certificate of the fixed graph.
    assert!(m["gap_certificate"].is_null(), "{}", m["gap_certificate"]);
    let all = &m["all_vehicles"];
    assert_eq!(all["vehicles_max"], 16, "{all}");
    let rows = std::fs::read_to_string(dir.join("traffic/trajectories.csv")).unwrap();
    let warmup_s = m["warmup_s"].as_f64().unwrap();
    assert!(warmup_s > 0.0, "{}", m["warmup_s"]);
    let speeds: Vec<f64> = rows
        .lines()
        .skip(1)
        .filter(|l| l.split(',').next().unwrap().parse::<f64>().unwrap() >= warmup_s)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    let mean = speeds.iter().sum::<f64>() / speeds.len() as f64;
    let got = all["mean_speed_mps"].as_f64().unwrap();
    assert!(
        (got - mean).abs() < 0.01,
        "SUMO {got} m/s, trajectory {mean} m/s"
    );
    assert!(out.contains("all vehicles (SUMO's summary over "), "{out}");
}

/// `sumo-bench --step-time` times SUMO's own step of real runs: each figure is positive and
/// below the command's whole wall time, the total is their sum, and a native scenario is
/// refused (exit 2) naming the file and the backend before any worker starts.
#[test]
fn step_time_is_a_part_of_the_runs_and_refuses_native_scenarios() {
    let ring = repo().join("scenarios/sugiyama-ring.json");
    let t0 = std::time::Instant::now();
    let o = bin()
        .args(["sumo-bench", "--step-time"])
        .arg(&ring)
        .arg(&ring)
        .output()
        .unwrap();
    let wall = t0.elapsed().as_secs_f64();
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{text}");
    let values: Vec<f64> = text
        .lines()
        .map(|l| l.rsplit('\t').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(values.len(), 3, "{text}");
    for v in &values[..2] {
        assert!(
            *v > 0.0 && *v < wall,
            "{v} s inside SUMO's step of a {wall} s command"
        );
    }
    assert!((values[2] - values[0] - values[1]).abs() <= 2e-6, "{text}");
    // Refused with exit 2 before any worker starts; the message is returned.
    let refused = |args: &[&std::ffi::OsStr]| -> String {
        let o = bin().arg("sumo-bench").args(args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        err
    };
    let native = repo().join("scenarios/ring-theorem1.json");
    let step_time = |extra: &[&str]| {
        let mut a = vec![std::ffi::OsStr::new("--step-time"), native.as_os_str()];
        a.extend(extra.iter().map(std::ffi::OsStr::new));
        refused(&a)
    };
    let err = step_time(&[]);
    assert!(
        err.contains("ring-theorem1.json") && err.contains("backend is not \"sumo\""),
        "{err}"
    );
    let err = refused(&["--case", "ring-2km"].map(std::ffi::OsStr::new));
    assert!(
        err.contains("\"ring-2km\"") && err.contains("sugiyama-ring, ring-20km"),
        "{err}"
    );
    // The standard cases' options do not apply to --step-time: refused, not ignored.
    for extra in [&["--quick"][..], &["--no-traci"], &["--case", "ring-20km"]] {
        let err = step_time(extra);
        assert!(
            err.contains(extra[0]) && err.contains("--step-time"),
            "{err}"
        );
    }
}

/// The guide's on-ramp (`examples/open-road`), netconvert-built: a scenario with no vehicles of
/// its own is refused, as bad input naming why, by every command that would analyse or swap
/// drivers of a fixed set (`check`, `stability`, `compare`, a sweep's `runs`), before SUMO
/// starts; a sweep over its inflow's controlled block is accepted (`--emit-slurm` plans it
/// without running).
#[test]
fn an_open_road_of_inflows_only_is_refused_where_no_fixed_set_exists() {
    let dir = tmpdir("open-road-refusals");
    let road = dir.join("open-road");
    std::fs::create_dir_all(&road).unwrap();
    for f in [
        "onramp.nod.xml",
        "onramp.edg.xml",
        "onramp.json",
        "onramp.sweep.json",
    ] {
        std::fs::copy(repo().join("examples/open-road").join(f), road.join(f)).unwrap();
    }
    let netconvert = repo().join(".venv/lib/python3.11/site-packages/sumo/bin/netconvert");
    let (code, _, err) = run(std::process::Command::new(netconvert)
        .current_dir(&road)
        .args([
            "--node-files",
            "onramp.nod.xml",
            "--edge-files",
            "onramp.edg.xml",
            "--no-turnarounds",
            "true",
            "-o",
            "onramp.net.xml",
        ]));
    assert_eq!(code, 0, "netconvert: {err}");
    let sc = road.join("onramp.json");
    for cmd in ["check", "stability"] {
        let (code, _, err) = run(bin().arg(cmd).arg(&sc));
        assert_eq!(code, 2, "{cmd}: {err}");
        assert!(err.contains("the scenario has no vehicles of its own (\"vehicles\": 0, an open road of inflows): there is no network to analyse"), "{cmd}: {err}");
    }
    let (code, _, err) = run(bin()
        .arg("compare")
        .arg(&sc)
        .arg("--out")
        .arg(dir.join("cmp")));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("scenario onramp: no vehicles of its own (\"vehicles\": 0), so every driver a comparison swaps in would drive nobody"), "{err}");
    assert!(!dir.join("cmp").exists());
    let spec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(road.join("onramp.sweep.json")).unwrap())
            .unwrap();
    let mut with_runs = spec.clone();
    with_runs["runs"] = serde_json::json!(["protocol", "idm"]);
    let bad = road.join("runs.sweep.json");
    std::fs::write(&bad, with_runs.to_string()).unwrap();
    let (code, _, err) = run(bin()
        .arg("sweep")
        .arg(&bad)
        .arg("--out")
        .arg(dir.join("sw")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("runs and penetrations: the base scenario has no vehicles of its own"),
        "{err}"
    );
    let (code, out, err) = run(bin()
        .arg("sweep")
        .arg(road.join("onramp.sweep.json"))
        .arg("--out")
        .arg(dir.join("sw-ok"))
        .arg("--emit-slurm")
        .arg(dir.join("jobs")));
    assert_eq!(code, 0, "{out}{err}");
    // `run` runs it as written: its inflows, which is the run's name (no law of syncroad's
    // drives a fixed set here, so the run is not called `protocol`).
    let mut short: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sc).unwrap()).unwrap();
    short["horizon_s"] = 60.into();
    let short_path = road.join("short.json");
    std::fs::write(&short_path, short.to_string()).unwrap();
    let (code, out, err) = run(bin()
        .arg("run")
        .arg(&short_path)
        .args(["--no-plots", "--warmup-s", "0", "--out"])
        .arg(dir.join("one")));
    assert!(code == 0 || code == 1, "{out}{err}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("one/metrics.json")).unwrap())
            .unwrap();
    assert_eq!(m["run"], "inflows");
}
