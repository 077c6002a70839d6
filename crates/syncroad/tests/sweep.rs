//! `syncroad sweep` end to end: the table is the same whatever the jobs, the shards and
//! interruptions; native verdicts fall where the closed-form stability boundary says; the
//! Parquet file loads in pandas; SUMO sweeps resume after Ctrl-C.

mod common;

use std::f64::consts::FRAC_PI_2;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::{bin, repo, run, tmpdir};

/// A uniform bidirectional ring (22 vehicles, gains 0.6 ahead and 0.1 behind, one delay α
/// for all) and a gain × delay sweep over it. The ring is 1 km long: the speeds do not depend
/// on it, and its 40 m gaps stay open while weakly coupled points drift apart (on a 230 m
/// ring, gain scales of 0.3 drive vehicles through each other: a collision, not synchronized).
fn uniform_ring(dir: &Path, alpha: f64) -> PathBuf {
    let sc = dir.join("uniform-ring.json");
    std::fs::write(
        &sc,
        format!(
            r#"{{"name": "uniform-ring", "backend": "native", "seed": 42, "step_s": 0.05,
                "horizon_s": 300, "vehicles": 22, "road": {{"type": "ring", "length_m": 1000}},
                "model": {{"type": "delayed_driver",
                          "graph": {{"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1}},
                          "delay_s": {alpha}}},
                "initial": {{"speed_mps": 8.0, "perturbation": {{"speed_mps": 1.5, "gap_m": 0.5}}}},
                "verdict": {{"tolerance_mps": 0.05, "window_s": 10}}}}"#
        ),
    )
    .unwrap();
    sc
}

fn write_spec(dir: &Path, body: &str) -> PathBuf {
    let p = dir.join("spec.json");
    std::fs::write(&p, body).unwrap();
    p
}

fn csv(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("results.csv")).unwrap()
}

/// Column `name` of a results.csv text.
fn column<'a>(text: &'a str, name: &str) -> Vec<&'a str> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header.iter().position(|h| *h == name).unwrap();
    lines.map(|l| l.split(',').nth(k).unwrap()).collect()
}

/// The critical product c·r of gain scale c and delay scale r for `s + c μ_k e^{−s r α} = 0`
/// over the ring's Laplacian eigenvalues μ_k = a(1 − e^{iθ}) + b(1 − e^{−iθ}),
/// θ = 2πk/n: with μ = |μ| e^{iφ}, a mode is stable iff c·r·|μ|·α < π/2 − |φ|.
fn critical_product(n: usize, a: f64, b: f64, alpha: f64) -> f64 {
    (1..n)
        .map(|k| {
            let th = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            let re = a * (1.0 - th.cos()) + b * (1.0 - th.cos());
            let im = -a * th.sin() + b * th.sin();
            let (m, phi) = (re.hypot(im), im.atan2(re));
            (FRAC_PI_2 - phi.abs()) / (m * alpha)
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn native_verdicts_follow_the_closed_form_boundary_whatever_the_jobs_and_shards() {
    let dir = tmpdir("sweep-native");
    let sc = uniform_ring(&dir, 0.5);
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"name": "uniform ring", "base": "{}", "axes": [
                {{"field": "scale.gain", "logspace": [0.3, 4.0, 9]}},
                {{"field": "scale.delay", "logspace": [0.3, 4.0, 9]}}],
                "metrics": ["sync.verdict", "sync.final_spread_mps", "certified"]}}"#,
            sc.display()
        ),
    );
    let one = dir.join("jobs1");
    let (code, out, err) = run(bin()
        .args(["sweep"])
        .arg(&spec)
        .arg("--out")
        .arg(&one)
        .args(["--jobs", "1", "--no-plots"]));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("81 points; ran 81 (0 failed)"), "{out}");
    let table = csv(&one);

    // Independent check: the closed-form boundary of the uniform ring.
    let p_star = critical_product(22, 0.6, 0.1, 0.5);
    let (c, r, verdict) = (
        column(&table, "scale.gain"),
        column(&table, "scale.delay"),
        column(&table, "sync.verdict"),
    );
    let (mut below, mut above) = (0, 0);
    for k in 0..c.len() {
        let p: f64 = c[k].parse::<f64>().unwrap() * r[k].parse::<f64>().unwrap();
        if p <= 0.7 * p_star && p >= 0.2 * p_star {
            below += 1;
            assert_eq!(verdict[k], "synchronized", "c·r = {p} < 0.7·{p_star}");
        }
        if p >= 1.3 * p_star {
            above += 1;
            assert_eq!(verdict[k], "not_synchronized", "c·r = {p} > 1.3·{p_star}");
        }
    }
    assert!(
        below >= 10 && above >= 20,
        "{below} points below, {above} above"
    );

    // The same table with two jobs, and from three shards merged.
    let two = dir.join("jobs2");
    let (code, _, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&two).args([
        "--jobs",
        "2",
        "--no-plots",
    ]));
    assert_eq!(code, 0, "{err}");
    assert_eq!(csv(&two), table);
    let shards: Vec<PathBuf> = (0..3).map(|i| dir.join(format!("shard-{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        let (code, out, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(s).args([
            "--shard",
            &format!("{i}/3"),
            "--no-plots",
        ]));
        assert_eq!(code, 0, "{out}\n{err}");
        assert!(out.contains("27 points (shard"), "{out}");
    }
    let merged = dir.join("merged");
    let (code, out, err) = run(bin()
        .args(["sweep", "collect"])
        .arg(&spec)
        .arg("--out")
        .arg(&merged)
        .args(&shards)
        .arg("--no-plots"));
    assert_eq!(code, 0, "{out}\n{err}");
    assert_eq!(csv(&merged), table);

    // A missing shard is reported, and so is a shard given twice.
    let partial = dir.join("partial");
    let (code, _, err) = run(bin()
        .args(["sweep", "collect"])
        .arg(&spec)
        .arg("--out")
        .arg(&partial)
        .args([&shards[0], &shards[1], &shards[1]])
        .arg("--no-plots"));
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("error: 27 points missing: 2, 5, 8"), "{err}");
    assert!(err.contains("27 points duplicated"), "{err}");

    // Running again skips everything; another spec is refused in the same folder.
    let (code, out, _) = run(bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--out")
        .arg(&one)
        .arg("--no-plots"));
    assert_eq!(code, 0);
    assert!(
        out.contains("ran 0 (0 failed), 81 finished before"),
        "{out}"
    );

    // For CI: the same finished sweep exits 1 on the findings it is told to fail on, naming
    // as many points as the table holds, and 0 on those it does not hold.
    let not_sync = verdict.iter().filter(|v| **v == "not_synchronized").count();
    let unsafe_points = column(&table, "safe")
        .iter()
        .filter(|s| **s == "false")
        .count();
    let gated = |on: &str, out_dir: &Path| {
        run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(out_dir)
            .args(["--no-plots", "--fail-on", on]))
    };
    let (code, _, err) = gated("not-synchronized", &one);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains(&format!(
            "fail-on not synchronized: {not_sync} of 81 runs: "
        )),
        "{err}"
    );
    let (code, _, err) = gated("unsafe", &one);
    assert_eq!(
        code,
        i32::from(unsafe_points > 0),
        "{unsafe_points} unsafe: {err}"
    );
    let (code, _, err) = run(bin()
        .args(["sweep", "collect"])
        .arg(&spec)
        .arg("--out")
        .arg(dir.join("merged-gated"))
        .args(&shards)
        .args(["--no-plots", "--fail-on", "unsafe,not-synchronized"]));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("fail-on not synchronized"), "{err}");
    let no_verdict = write_spec(
        &dir,
        &format!(
            r#"{{"base": "{}", "seeds": [1], "metrics": ["sync.final_spread_mps"]}}"#,
            sc.display()
        ),
    );
    let (code, _, err) = run(bin()
        .arg("sweep")
        .arg(&no_verdict)
        .arg("--out")
        .arg(dir.join("no-verdict"))
        .args(["--fail-on", "inconclusive"]));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--fail-on inconclusive: the sweep's metrics leave out sync.verdict"),
        "{err}"
    );
    assert!(!dir.join("no-verdict/rows").exists());
    let other = write_spec(
        &dir,
        &format!(r#"{{"base": "{}", "seeds": [1, 2]}}"#, sc.display()),
    );
    let (code, _, err) = run(bin().arg("sweep").arg(&other).arg("--out").arg(&one));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("holds a sweep of another spec"), "{err}");
}

#[test]
fn bad_specs_are_refused_before_anything_runs() {
    let dir = tmpdir("sweep-bad");
    let sc = repo().join("scenarios/ring-theorem1.json");
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"base": "{}", "axes": [{{"field": "model.graph.gain_pred", "values": [0.5, -1]}}]}}"#,
            sc.display()
        ),
    );
    let out = dir.join("out");
    let (code, _, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&out));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("sweep point 1 (model.graph.gain_pred = -1)"),
        "{err}"
    );
    assert!(!out.exists(), "nothing was created");
}

fn rows_in(dir: &Path) -> usize {
    std::fs::read_dir(dir.join("rows"))
        .map(|d| {
            d.filter_map(Result::ok)
                .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
                .count()
        })
        .unwrap_or(0)
}

/// A SUMO sweep stopped by Ctrl-C keeps its finished rows and exits 130; run again, it ends
/// with the table of an uninterrupted sweep, which pandas reads in one line.
#[test]
fn an_interrupted_sumo_sweep_resumes_to_the_same_table() {
    let dir = tmpdir("sweep-sumo");
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"name": "sugiyama", "base": "{}", "backend": "sumo",
                "axes": [{{"field": "scale.gain", "values": [1.0, 1.3, 3.0]}}],
                "runs": ["protocol", "krauss-0.9"], "seeds": [1, 2, 3]}}"#,
            repo().join("scenarios/sugiyama-ring.json").display()
        ),
    );
    let whole = dir.join("whole");
    let (code, out, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&whole));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("18 points; ran 18 (0 failed)"), "{out}");
    assert!(out.contains("2 SUMO worker processes"), "{out}");

    let resumed = dir.join("resumed");
    let mut child = bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--out")
        .arg(&resumed)
        .args(["--jobs", "1"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    // Waits for rows written (an observable state); the 120 s only bounds a hang.
    while rows_in(&resumed) < 4 && t0.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: signals our own child.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let status = child.wait().unwrap();
    let kept = rows_in(&resumed);
    assert_eq!(status.code(), Some(130));
    assert!((4..18).contains(&kept), "{kept} rows kept");
    let (code, out, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&resumed));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains(&format!("{kept} finished before")), "{out}");
    assert_eq!(csv(&resumed), csv(&whole));

    // The law synchronizes at c = 1 and 1.3 and not at c = 3 (exact boundary c ≈ 1.71 at r = 1).
    let t = csv(&whole);
    let (gain, run_name, verdict) = (
        column(&t, "scale.gain"),
        column(&t, "run"),
        column(&t, "sync.verdict"),
    );
    for k in 0..gain.len() {
        if run_name[k] == "protocol" {
            let want = if gain[k] == "3" {
                "not_synchronized"
            } else {
                "synchronized"
            };
            assert_eq!(verdict[k], want, "row {k}");
        }
    }

    // pandas reads the Parquet table in one line, with the CSV's values and typed columns.
    let py = repo().join(".venv/bin/python");
    let check = format!(
        r#"
import pandas
df = pandas.read_parquet("{}")
csv = pandas.read_csv("{}", float_precision="round_trip")
assert len(df) == 18, len(df)
assert list(df.columns) == list(csv.columns), (list(df.columns), list(csv.columns))
assert str(df["scale.gain"].dtype) == "float64" and str(df["seed"].dtype) == "int64"
assert (df["sync.final_spread_mps"] == csv["sync.final_spread_mps"]).all()
assert set(df["run"]) == {{"protocol", "krauss-0.9"}}
print("pandas ok", flush=True)
# pyarrow can abort at interpreter shutdown after the work is done ("terminate called without
# an active exception" from a parquet thread, apache/arrow#34314): every check above has run,
# so leave without the teardown.
import os
os._exit(0)
"#,
        whole.join("results.parquet").display(),
        whole.join("results.csv").display()
    );
    let (code, out, err) = run(std::process::Command::new(py).args(["-c", &check]));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("pandas ok"));
}

/// The native backend runs the stochastic humans and the dampers the SUMO runs use: from the
/// uniform start of `sugiyama-human-noisy.json` the noisy humans jam (at another time for
/// another seed, the same time for the same seed), the PI ring stays smooth, and a SUMO-only
/// driver is refused before anything runs.
#[test]
fn native_sweeps_run_stochastic_humans_and_dampers() {
    let dir = tmpdir("sweep-native-noisy");
    let base = repo().join("scenarios/sugiyama-human-noisy.json");
    let body = |runs: &str| {
        format!(
            r#"{{"base": "{}", "backend": "native", "runs": [{runs}],
                "seeds": [1, 2], "warmup_s": 400,
                "metrics": ["congestion.jam_formed_s", "congestion.speed_std_mps", "gap_safety.min_gap_m"]}}"#,
            base.display()
        )
    };
    let spec = write_spec(&dir, &body(r#""human-noisy", "pi-saturation""#));
    let out = dir.join("out");
    let (code, stdout, err) = run(bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--no-plots")
        .arg("--out")
        .arg(&out));
    assert_eq!(code, 0, "{stdout}{err}");
    let text = csv(&out);
    let jam = column(&text, "congestion.jam_formed_s");
    let std = column(&text, "congestion.speed_std_mps");
    // Rows: human-noisy seeds 1, 2, then pi-saturation seeds 1, 2.
    let t: Vec<f64> = jam[..2].iter().map(|x| x.parse().unwrap()).collect();
    assert!(t.iter().all(|&x| x > 0.0 && x < 400.0), "{jam:?}");
    assert_ne!(t[0], t[1]);
    assert!(
        std[..2].iter().all(|x| x.parse::<f64>().unwrap() > 2.0),
        "{std:?}"
    );
    assert!(jam[2..].iter().all(|x| x.is_empty()), "{jam:?}");
    // The same seeds again: the same table.
    let again = dir.join("again");
    let (code, _, _) = run(bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--no-plots")
        .arg("--out")
        .arg(&again));
    assert_eq!(code, 0);
    assert_eq!(column(&csv(&again), "congestion.speed_std_mps"), std);
    let spec = write_spec(&dir, &body(r#""human-noisy", "krauss-0.9""#));
    let (code, _, err) = run(bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--out")
        .arg(dir.join("refused")));
    assert_ne!(code, 0);
    assert!(err.contains("runs: krauss-0.9 has SUMO drivers"), "{err}");
}

/// A plot that shows one axis of two averages over the other too, and says so: a mean pooled
/// over `description`'s two values is not "a mean over seeds".
#[test]
fn a_plot_names_every_axis_it_pools() {
    let dir = tmpdir("sweep-pooled");
    let sc = uniform_ring(&dir, 0.5);
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"base": "{}", "axes": [
                {{"field": "scale.gain", "values": [0.5, 1.0]}},
                {{"field": "description", "values": ["first", "second"]}}],
                "metrics": ["sync.final_spread_mps"]}}"#,
            sc.display()
        ),
    );
    let out = dir.join("out");
    let (code, o, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&out));
    assert_eq!(code, 0, "{o}\n{err}");
    let captions: Vec<String> = std::fs::read_dir(out.join("plots"))
        .unwrap()
        .filter_map(|e| {
            let p = e.ok()?.path();
            (p.extension()? == "svg").then(|| std::fs::read_to_string(p).unwrap())
        })
        .collect();
    assert!(!captions.is_empty(), "no plot drawn");
    assert!(
        captions
            .iter()
            .all(|svg| svg.contains("over seeds and description (2 values)")),
        "every plot names the pooled axis"
    );
}

/// A sweep of a scenario driven by the user's Python controller runs it at every point, and
/// the controller's source is part of the experiment: an edited controller is another sweep,
/// which the folder of the first refuses to resume.
#[test]
fn a_sweep_runs_the_users_controller_and_hashes_its_source() {
    let dir = tmpdir("sweep-python-controller");
    let law = dir.join("law.py");
    let source =
        std::fs::read_to_string(repo().join("examples/controllers/follower_stopper.py")).unwrap();
    std::fs::write(&law, &source).unwrap();
    let mut sc: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/sugiyama-python.json")).unwrap(),
    )
    .unwrap();
    sc["horizon_s"] = 60.into();
    sc["controller"]["python"] = format!("{}:FollowerStopper", law.display()).into();
    sc["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .display()
        .to_string()
        .into();
    let base = dir.join("sc.json");
    std::fs::write(&base, sc.to_string()).unwrap();
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"base": "{}", "backend": "sumo", "runs": ["protocol"], "seeds": [1, 2],
                "warmup_s": 10, "metrics": ["congestion.mean_speed_mps"]}}"#,
            base.display()
        ),
    );
    let out = dir.join("out");
    let sweep = || {
        run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--no-plots")
            .arg("--out")
            .arg(&out))
    };
    let (code, stdout, err) = sweep();
    assert_eq!(code, 0, "{stdout}{err}");
    let text = csv(&out);
    let speeds: Vec<f64> = column(&text, "congestion.mean_speed_mps")
        .iter()
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(speeds.len(), 2);
    // The FollowerStopper at U = 4.3 m/s moves the ring off its 4 m/s start.
    assert!(speeds.iter().all(|v| (v - 4.0).abs() > 0.05), "{speeds:?}");
    // The same controller again: the sweep is complete, nothing runs.
    assert_eq!(sweep().0, 0);
    std::fs::write(
        &law,
        source.replace(
            "self.u = float(desired_speed_mps)",
            "self.u = 2.0 * float(desired_speed_mps)",
        ),
    )
    .unwrap();
    let (code, _, err) = sweep();
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("holds a sweep of another spec, base scenario or input file"),
        "{err}"
    );
}

/// The shipped ring of a Python controller (`sugiyama-python.json`) for `horizon_s`, driven by
/// `controller` (`FILE.py:Class`), its network path made absolute, written to `dir/sc.json`.
fn python_ring(dir: &Path, controller: &str, horizon_s: u64) -> PathBuf {
    let mut sc: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/sugiyama-python.json")).unwrap(),
    )
    .unwrap();
    sc["horizon_s"] = horizon_s.into();
    sc["controller"] = serde_json::json!({"python": controller});
    sc["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .display()
        .to_string()
        .into();
    let base = dir.join("sc.json");
    std::fs::write(&base, sc.to_string()).unwrap();
    base
}

/// A module the controller imports from its folder is part of the experiment too: editing
/// it makes another sweep, which the first one's folder refuses to resume, naming the file.
/// Before, only the controller's own file was hashed and the resumed sweep mixed two versions.
#[test]
fn a_resume_refuses_an_edited_module_beside_the_controller_and_names_it() {
    let dir = tmpdir("sweep-controller-module");
    let gains = dir.join("gains.py");
    std::fs::write(&gains, "FACTOR = 1.0\n").unwrap();
    let law = dir.join("law.py");
    std::fs::write(
        &law,
        "import gains\n\nclass Law:\n    def step(self, obs):\n        return obs.speed_mps * gains.FACTOR\n",
    )
    .unwrap();
    let base = python_ring(&dir, &format!("{}:Law", law.display()), 12);
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"base": "{}", "backend": "sumo", "seeds": [1], "metrics": ["sync.verdict"]}}"#,
            base.display()
        ),
    );
    let out = dir.join("out");
    let sweep = || {
        run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--no-plots")
            .arg("--out")
            .arg(&out))
    };
    let (code, stdout, err) = sweep();
    assert!(code == 0 || code == 1, "{stdout}{err}");
    assert_eq!(sweep().0, code, "the same sweep resumes");
    std::fs::write(&gains, "FACTOR = 1.01\n").unwrap();
    let (code, _, err) = sweep();
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(&format!("; changed: {}", gains.display())),
        "{err}"
    );
    assert!(!err.contains(&law.display().to_string()), "{err}");
}

/// A controller that raises is a failed point, not a result: counted as failed, the sweep
/// exits 3, its rows say `failed` with the controller's error (and no verdict of the run
/// that never finished), and `--retry-failed` runs them again once the controller is mended.
#[test]
fn a_controller_that_raises_fails_its_points_and_retry_failed_runs_them_again() {
    let dir = tmpdir("sweep-raising-controller");
    let flag = dir.join("broken");
    std::fs::write(&flag, "").unwrap();
    let law = dir.join("law.py");
    std::fs::write(
        &law,
        format!(
            "import os\n\nclass Law:\n    def step(self, obs):\n        if obs.step == 25 and os.path.exists({:?}):\n            raise RuntimeError('the law broke')\n        return obs.speed_mps\n",
            flag.display().to_string()
        ),
    )
    .unwrap();
    let base = python_ring(&dir, &format!("{}:Law", law.display()), 10);
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"base": "{}", "backend": "sumo", "seeds": [1, 2, 3],
                "metrics": ["sync.verdict"]}}"#,
            base.display()
        ),
    );
    let out = dir.join("out");
    let sweep = |extra: &[&str]| {
        run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--no-plots")
            .args(extra)
            .arg("--out")
            .arg(&out))
    };
    let (code, stdout, err) = sweep(&[]);
    assert_eq!(code, 3, "{stdout}{err}");
    assert!(stdout.contains("ran 3 (3 failed)"), "{stdout}");
    // The rows as the sweep streamed them (the table's error cells hold commas).
    let rows: Vec<serde_json::Value> = (0..3)
        .map(|k| {
            serde_json::from_str(
                &std::fs::read_to_string(out.join(format!("rows/{k:07}.json"))).unwrap(),
            )
            .unwrap()
        })
        .collect();
    for row in &rows {
        assert_eq!(row["status"], "failed", "{row}");
        assert_eq!(row["stop"], "controller_failed", "{row}");
        assert!(
            row["error"]
                .as_str()
                .unwrap()
                .contains("RuntimeError: the law broke"),
            "{row}"
        );
        // A run cut off by its controller has no verdict of its own.
        assert_eq!(row["sync.verdict"], "inconclusive", "{row}");
    }
    // Mended: a plain resume keeps the failed rows; --retry-failed runs them again.
    std::fs::remove_file(&flag).unwrap();
    let (code, stdout, _) = sweep(&[]);
    assert_eq!(code, 3, "{stdout}");
    assert!(
        stdout.contains("ran 0 (0 failed), 3 finished before"),
        "{stdout}"
    );
    let (code, stdout, err) = sweep(&["--retry-failed"]);
    assert_eq!(code, 0, "{stdout}{err}");
    assert!(stdout.contains("ran 3 (0 failed)"), "{stdout}");
    assert_eq!(column(&csv(&out), "status"), ["complete"; 3]);
}

/// A ring that names its network runs on the ring the network measures on both backends: the
/// shipped noisy-human ring (`road.length_m` 230, SUMO's ring 230.3592 m) gives the same mean
/// speed natively and in SUMO, seed by seed (the stochastic humans are computed alike on both),
/// and a nominal length the network does not have is refused before anything runs.
#[test]
fn native_and_sumo_sweeps_of_a_networked_ring_run_on_the_same_ring() {
    let dir = tmpdir("networked-ring");
    let mut means = Vec::new();
    for backend in ["native", "sumo"] {
        let spec = write_spec(
            &dir,
            &format!(
                r#"{{"name": "noisy", "base": "{}", "backend": "{backend}", "runs": ["human-noisy"],
                    "seeds": [1, 2], "warmup_s": 400, "metrics": ["congestion.mean_speed_mps"]}}"#,
                repo().join("scenarios/sugiyama-human-noisy.json").display()
            ),
        );
        let out = dir.join(backend);
        let (code, stdout, stderr) = run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .arg("--no-plots"));
        assert_eq!(code, 0, "{stdout}\n{stderr}");
        let text = csv(&out);
        let m: Vec<f64> = column(&text, "congestion.mean_speed_mps")
            .iter()
            .map(|x| x.parse().unwrap())
            .collect();
        means.push(m);
    }
    assert_eq!(means[0].len(), 2);
    for (a, b) in means[0].iter().zip(&means[1]) {
        assert!((a - b).abs() < 1e-9, "native {a} vs SUMO {b}");
    }
    // The native run's ring is SUMO's: 230.3592 m (the net's lanes), not the nominal 230.
    let native = dir.join("simulated");
    let (code, _, stderr) = run(bin()
        .args(["simulate", "--no-plots", "-q", "--out"])
        .arg(&native)
        .arg(repo().join("scenarios/sugiyama-ring.json")));
    assert!(code == 0 || code == 1, "{stderr}");
    let road: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(native.join("road.json")).unwrap()).unwrap();
    assert_eq!(road["ring_length_m"], serde_json::json!(230.3592));
    let sc = {
        let text =
            std::fs::read_to_string(repo().join("scenarios/sugiyama-human-noisy.json")).unwrap();
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["sumo"]["net"] = serde_json::json!(repo().join("sumo-nets/sugiyama-ring.net.xml"));
        v["road"]["length_m"] = serde_json::json!(260);
        let p = dir.join("260.json");
        std::fs::write(&p, v.to_string()).unwrap();
        p
    };
    let (code, _, stderr) = run(bin().arg("check").arg(&sc));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("road.length_m = 260") && stderr.contains("measures 230.3592 m"),
        "{stderr}"
    );
}

/// The run folders of a sweep's points, by number (`OUT/runs/NNNNNNN`).
fn kept_runs(out: &Path) -> Vec<usize> {
    let Ok(dir) = std::fs::read_dir(out.join("runs")) else {
        return Vec::new();
    };
    let mut ids: Vec<usize> = dir
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("metrics.json").is_file())
        .map(|p| p.file_name().unwrap().to_str().unwrap().parse().unwrap())
        .collect();
    ids.sort();
    ids
}

/// A Slurm job array emitted with `--keep-runs` keeps its points' run folders as the same
/// sweep run here would: each array task, run by bash as Slurm runs it, keeps the folders of
/// its own shard's points (points 0 and 2 of three in shard 0 of 2, point 1 in shard 1), and
/// one emitted without it keeps none. `--shard` and `--jobs`, which the array sets itself, are
/// refused.
#[test]
fn an_emitted_slurm_array_passes_the_sweeps_options_to_each_task() {
    let dir = tmpdir("sweep-slurm-flags");
    let sc = uniform_ring(&dir, 0.3);
    let spec = write_spec(
        &dir,
        &format!(
            r#"{{"name": "kept", "base": "{}", "seeds": [1, 2, 3]}}"#,
            sc.display()
        ),
    );
    // `sweep --emit-slurm DIR/NAME --out DIR/NAME-out --shards 2 FLAGS`.
    let emit = |name: &str, flags: &[&str]| {
        run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(dir.join(format!("{name}-out")))
            .arg("--emit-slurm")
            .arg(dir.join(name))
            .args(["--shards", "2"])
            .args(flags))
    };
    let emit_and_run = |name: &str, flags: &[&str]| -> PathBuf {
        let (code, o, e) = emit(name, flags);
        assert_eq!(code, 0, "{o}{e}");
        let jobs = dir.join(name);
        for task in ["0", "1"] {
            let p = std::process::Command::new("bash")
                .arg(jobs.join("sweep.sbatch"))
                .env("SLURM_ARRAY_TASK_ID", task)
                .env("SLURM_CPUS_PER_TASK", "1")
                .output()
                .unwrap();
            assert!(p.status.success(), "task {task}: {p:?}");
        }
        dir.join(format!("{name}-out"))
    };
    let kept = emit_and_run("keep", &["--keep-runs"]);
    assert_eq!(kept_runs(&kept.join("shard-0")), [0, 2]);
    assert_eq!(kept_runs(&kept.join("shard-1")), [1]);
    let plain = emit_and_run("plain", &[]);
    assert_eq!(kept_runs(&plain.join("shard-0")), Vec::<usize>::new());
    assert!(plain.join("shard-1/results.csv").is_file());
    let (code, _, e) = emit("zero", &["--keep-runs", "--fcd", "--fcd-every", "0"]);
    assert_eq!(code, 2, "{e}");
    assert!(e.contains("--fcd-every = 0: must be ≥ 1"), "{e}");
    assert!(!dir.join("zero").exists());
    // What the array decides itself is refused, not dropped.
    for (flag, value, says) in [
        (
            "--shard",
            "0/2",
            "each array task runs one shard of --shards (here 2)",
        ),
        ("--jobs", "3", "drop --jobs, or set --cpus-per-task 3"),
    ] {
        let (code, _, e) = emit("refused", &[flag, value]);
        assert_eq!(code, 2, "{flag}: {e}");
        assert!(
            e.contains(&format!("{flag} {value}: ")) && e.contains(says),
            "{e}"
        );
        assert!(!dir.join("refused").exists());
    }
}

/// `--safety` on a sweep is the spec's `safety` key: the same rows as the spec that says so,
/// a hash of its own (a folder swept without it is not resumed with it), passed on to every
/// task and to the merge of an emitted Slurm job; an axis over `safety` beside it is refused.
#[test]
fn the_safety_flag_of_a_sweep_is_the_specs_key() {
    let dir = tmpdir("sweep-safety");
    let sc = uniform_ring(&dir, 0.5);
    let body = |extra: &str| {
        format!(
            r#"{{"name": "safety", "base": "{}", "seeds": [1, 2]{extra},
                "axes": [{{"field": "scale.gain", "values": [1.0, 3.0]}}],
                "metrics": ["sync.verdict", "safety_layer.mode"]}}"#,
            sc.display()
        )
    };
    let flagged = write_spec(&dir, &body(""));
    let keyed = dir.join("keyed.json");
    std::fs::write(&keyed, body(r#", "safety": "filter""#)).unwrap();
    let sweep = |spec: &Path, out: &str, extra: &[&str]| {
        run(bin()
            .arg("sweep")
            .arg(spec)
            .arg("--out")
            .arg(dir.join(out))
            .arg("--no-plots")
            .args(extra))
    };
    let (code, out, err) = sweep(&flagged, "flag", &["--safety", "filter"]);
    assert_eq!(code, 0, "{out}{err}");
    assert_eq!(sweep(&keyed, "key", &[]).0, 0);
    let table = csv(&dir.join("flag"));
    // Every column but the hash of the spec as written (keys in the order written).
    let without_spec_hash = |text: &str| -> Vec<String> {
        let k = text
            .lines()
            .next()
            .unwrap()
            .split(',')
            .position(|h| h == "spec_hash")
            .unwrap();
        text.lines()
            .map(|l| {
                let mut cells: Vec<&str> = l.split(',').collect();
                cells.remove(k);
                cells.join(",")
            })
            .collect()
    };
    assert_eq!(
        without_spec_hash(&table),
        without_spec_hash(&csv(&dir.join("key")))
    );
    assert_eq!(column(&table, "safety_layer.mode"), vec!["filter"; 4]);
    assert_eq!(sweep(&flagged, "plain", &[]).0, 0);
    assert_ne!(
        column(&csv(&dir.join("plain")), "safety_layer.mode"),
        vec!["filter"; 4]
    );
    let (code, _, err) = sweep(&flagged, "plain", &["--safety", "filter"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("holds a sweep of another spec"), "{err}");
    let (code, _, err) = sweep(&keyed, "both", &["--safety", "off"]);
    assert_eq!(code, 0, "the flag replaces the key: {err}");
    assert_eq!(
        column(&csv(&dir.join("both")), "safety_layer.mode"),
        vec!["off"; 4]
    );
    let axis = dir.join("axis.json");
    std::fs::write(
        &axis,
        format!(
            r#"{{"base": "{}", "safety": "filter", "axes": [{{"field": "safety", "values": ["off", "filter"]}}]}}"#,
            sc.display()
        ),
    )
    .unwrap();
    let (code, _, err) = sweep(&axis, "axis", &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("safety = filter: the spec also sweeps safety on an axis"),
        "{err}"
    );
    let slurm = dir.join("slurm");
    let (code, _, err) = sweep(
        &flagged,
        "cluster",
        &[
            "--safety",
            "filter",
            "--emit-slurm",
            slurm.to_str().unwrap(),
            "--shards",
            "2",
        ],
    );
    assert_eq!(code, 0, "{err}");
    for script in ["sweep.sbatch", "collect.sbatch"] {
        let text = std::fs::read_to_string(slurm.join(script)).unwrap();
        assert!(text.contains(" --safety filter"), "{script}: {text}");
    }
}

/// A penetration sweep's lines: one per controller, each starting at the all-human ring, and
/// no legend entry for the all-human ring alone (it has no line of its own).
#[test]
fn a_penetration_plot_has_a_line_per_controller_and_no_empty_legend_entry() {
    let d = tmpdir("penetration-legend");
    // The noisy humans' ring, shortened to 30 s.
    let text = std::fs::read_to_string(repo().join("scenarios/sugiyama-human-noisy.json")).unwrap();
    let mut sc: serde_json::Value = serde_json::from_str(&text).unwrap();
    sc["horizon_s"] = serde_json::json!(30);
    sc["sumo"]["net"] = serde_json::json!(repo().join("sumo-nets/sugiyama-ring.net.xml"));
    let base = d.join("base.json");
    std::fs::write(&base, sc.to_string()).unwrap();
    let spec = write_spec(
        &d,
        &format!(
            r#"{{"name": "legend", "base": {base:?}, "backend": "native",
                "penetrations": [0.0, 0.1], "mixed_driver": "human-noisy",
                "mixed_controller": ["protocol", "pi-saturation"], "seeds": [1],
                "warmup_s": 5, "metrics": ["congestion.speed_std_mps"]}}"#
        ),
    );
    let out = d.join("out");
    let (code, stdout, err) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&out));
    assert_eq!(code, 0, "{stdout}{err}");
    let svg = std::fs::read_to_string(out.join("plots/congestion_speed_std_mps.svg")).unwrap();
    let labels: Vec<&str> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| t.split('>').nth(1))
        .map(|t| t.split('<').next().unwrap_or("").trim())
        .collect();
    for want in ["protocol-mixed", "pi-saturation-mixed"] {
        assert!(labels.contains(&want), "{labels:?}");
    }
    assert!(
        !labels.iter().any(|l| *l == "mixed" || *l == "law-mixed"),
        "a legend entry without a line: {labels:?}"
    );
}
