//! `syncroad compare` and SUMO baselines in `syncroad regress`, end to end with real SUMO.
//!
//! Every number is checked against something the code under test did not compute: SUMO's own
//! trip-info totals, the trajectory's kinematics, or a second run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

mod common;
use common::*;

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn sugiyama() -> PathBuf {
    repo().join("scenarios/sugiyama-ring.json")
}

/// Per vehicle: (time, speed, unwrapped rear-bumper position) rows of trajectories.csv.
fn trajectories(path: &Path) -> BTreeMap<usize, Vec<(f64, f64, f64)>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out: BTreeMap<usize, Vec<(f64, f64, f64)>> = BTreeMap::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        out.entry(f[1].parse().unwrap()).or_default().push((
            f[0].parse().unwrap(),
            f[2].parse().unwrap(),
            f[3].parse().unwrap(),
        ));
    }
    out
}

/// The largest difference of any vehicle's speed at any sample between two runs' trajectories
/// (both of 22 vehicles) [m/s].
fn worst_speed_difference(a: &Path, b: &Path) -> f64 {
    let (a, b) = (trajectories(a), trajectories(b));
    assert_eq!(a.len(), 22);
    let mut worst: f64 = 0.0;
    for (i, rows) in &a {
        for (x, y) in rows.iter().zip(&b[i]) {
            worst = worst.max((x.1 - y.1).abs());
        }
    }
    worst
}

/// Σ over the `<tripinfo>` elements of SUMO's trip-info output of one attribute.
fn tripinfo_sum(path: &Path, attr: &str) -> (f64, usize) {
    let text = std::fs::read_to_string(path).unwrap();
    let key = format!(" {attr}=\"");
    let mut sum = 0.0;
    let mut count = 0;
    for part in text.split(&key).skip(1) {
        let v: f64 = part[..part.find('"').unwrap()].parse().unwrap();
        sum += v;
        count += 1;
    }
    (sum, count)
}

/// With no warm-up, the loop's measurements must reproduce (a) SUMO's own trip-info totals of
/// fuel and time loss, (b) the induction-loop count of front bumpers crossing the detector in
/// the recorded trajectory, (c) the time loss Σ Δt (1 − v/v_max) of the recorded speeds, and
/// the loop flow must agree with N·v̄/L. mixed-0 (every vehicle a Krauss σ 0.9 driver) must
/// equal the krauss-0.9 run, and the mixed runs must use the stated number of law vehicles.
#[test]
fn sumo_measurements_agree_with_sumo_totals_and_kinematics() {
    let d = tmpdir("measure");
    let (code, out, err) = run(bin()
        .arg("compare")
        .arg(sugiyama())
        .args(["--baselines", "protocol,krauss-0.9,idm", "--mixed", "0,2"])
        .args(["--mixed-driver", "krauss-0.9"])
        .args([
            "--warmup-s",
            "0",
            "--no-plots",
            "--progress",
            "lines",
            "--out",
        ])
        .arg(&d));
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(
        out.contains("| metric | protocol | krauss-0.9 | idm | mixed-0 | protocol-mixed-2 |"),
        "{out}"
    );
    assert!(err.contains("[ 5/5 done"), "progress display: {err}");
    let v_max = 30.0; // sumo.max_speed_mps default; the ring's lanes allow 30 m/s as well
    let length = 5.0; // the scenario's default vehicle length
    for name in [
        "protocol",
        "krauss-0.9",
        "idm",
        "mixed-0",
        "protocol-mixed-2",
    ] {
        let dir = d.join(name);
        let m = json(&dir.join("metrics.json"));
        let s = &m["sumo"];
        let traj = trajectories(&dir.join("trajectories.csv"));
        assert_eq!(traj.len(), 22);
        // (a) SUMO's trip info (values rounded to 0.01 per vehicle).
        let tripinfo = dir.join("sumo/tripinfo.xml");
        let (fuel, trips) = tripinfo_sum(&tripinfo, "fuel_abs");
        assert_eq!(trips, 22, "{name}");
        let fuel_mg = s["fuel_mg"].as_f64().unwrap();
        assert!(fuel_mg > 0.0);
        assert!(
            (fuel_mg - fuel).abs() <= 0.01 * 22.0,
            "{name}: {fuel_mg} vs {fuel}"
        );
        let (loss, _) = tripinfo_sum(&tripinfo, "timeLoss");
        let loss_s = s["time_loss_s"].as_f64().unwrap();
        assert!(
            (loss_s - loss).abs() <= 0.01 * 22.0,
            "{name}: {loss_s} vs {loss}"
        );
        // (b) crossings of the detector by front bumpers, from the trajectory.
        let ring = s["road_length_m"].as_f64().unwrap();
        let x_d = s["loop_ring_m"].as_f64().unwrap();
        let lap = |q: f64| ((q + length - x_d) / ring).floor() as i64;
        let crossings: i64 = traj
            .values()
            .map(|r| lap(r.last().unwrap().2) - lap(r[0].2))
            .sum();
        assert_eq!(
            s["loop_passages"].as_i64().unwrap(),
            crossings,
            "{name}: loop count vs trajectory crossings"
        );
        // (c) time loss from the recorded speeds (every step is recorded here).
        let dt = 0.1;
        let from_speeds: f64 = traj
            .values()
            .map(|r| r[1..].iter().map(|x| dt * (1.0 - x.1 / v_max)).sum::<f64>())
            .sum();
        assert!(
            (loss_s - from_speeds).abs() <= 1e-6 * loss_s,
            "{name}: {loss_s} vs {from_speeds}"
        );
        let flow = s["flow_veh_per_h"].as_f64().unwrap();
        let kin = s["flow_from_speed_veh_per_h"].as_f64().unwrap();
        assert!((flow - kin).abs() <= 0.03 * kin, "{name}: {flow} vs {kin}");
        assert_eq!(m["safety"]["collision_steps"], 0, "{name}");
        // (d) emergency braking, read from SUMO's own log here: every warning, and those of
        // the first second (the start transient every driver shares, left out of `safe`).
        let log = std::fs::read_to_string(dir.join("sumo/sumo.log")).unwrap();
        let times: Vec<f64> = log
            .lines()
            .filter(|l| l.contains("performs emergency braking"))
            .map(|l| {
                let t = &l[l.find("time=").expect("SUMO stamps its warnings") + 5..];
                t.trim_end_matches('.').parse::<f64>().unwrap()
            })
            .collect();
        let safety = &m["safety"];
        assert_eq!(safety["emergency_braking_warnings"], times.len(), "{name}");
        let start = times.iter().filter(|t| **t <= 1.0).count();
        assert_eq!(safety["start_emergency_braking_warnings"], start, "{name}");
        assert_eq!(
            m["safe"],
            times.len() == start && safety["teleports"] == 0,
            "{name}: {:?}",
            m["unsafe_because"]
        );
    }
    // IDM brakes in an emergency at the shared start only (the scenario's 5.5 m gaps at
    // 8 m/s): counted, and not unsafe.
    let idm = json(&d.join("idm/metrics.json"));
    assert!(
        idm["safety"]["start_emergency_braking_warnings"]
            .as_u64()
            .unwrap()
            > 0
    );
    assert_eq!(idm["safe"], true);
    let c = json(&d.join("compare.json"));
    assert_eq!(
        c["runs"]["mixed-0"]["congestion"],
        c["runs"]["krauss-0.9"]["congestion"]
    );
    assert_eq!(
        c["runs"]["mixed-0"]["sumo"],
        c["runs"]["krauss-0.9"]["sumo"]
    );
    assert_eq!(c["runs"]["protocol-mixed-2"]["law_controlled_vehicles"], 2);
    let drivers = c["runs"]["protocol-mixed-2"]["drivers"].as_array().unwrap();
    assert_eq!(drivers[0], "protocol");
    assert_eq!(drivers[11], "protocol");
    assert_eq!(drivers[1], "krauss-0.9");
    assert!(
        c["mixed_reduction_vs_all_human"]["protocol-mixed-2"]["speed_std_reduction"].is_number()
    );
    // SUMO's drivers keep their headway and crawl far below the law's speed, with or without
    // two law vehicles among them. A law that also commanded the SUMO drivers (planted: the
    // batch setSpeed on every vehicle) lifted the all-human ring to 2.8 m/s and failed here.
    let speed = |r: &str| {
        c["runs"][r]["congestion"]["mean_speed_mps"]
            .as_f64()
            .unwrap()
    };
    assert!(
        speed("protocol-mixed-2") < 1.5 * speed("mixed-0")
            && speed("protocol") > 3.0 * speed("mixed-0"),
        "protocol-mixed-2 {} m/s, all human {} m/s, all law {} m/s",
        speed("protocol-mixed-2"),
        speed("mixed-0"),
        speed("protocol")
    );
    // The law synchronizes, SUMO's drivers at this density do not.
    assert_eq!(c["runs"]["protocol"]["sync"]["verdict"], "synchronized");
    assert_eq!(
        c["runs"]["krauss-0.9"]["sync"]["verdict"],
        "not_synchronized"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// Same scenario and seed: byte-identical metrics whether the runs go one after another
/// through one reused worker process (`--jobs 1`) or each into a fresh worker at once
/// (`--jobs 3`).
#[test]
fn metrics_are_byte_identical_across_processes_and_parallel_runs() {
    let runs = "protocol,krauss-0.9,idm";
    let a = tmpdir("det-a");
    let b = tmpdir("det-b");
    // The second asks to fail on runs that do not synchronize (for CI): the files are the
    // same, the exit code is 1 exactly when a run's own record says `not_synchronized`, and
    // stderr names those runs.
    let mut gate_err = String::new();
    for (dir, jobs, gate) in [(&a, "1", None), (&b, "3", Some("not-synchronized"))] {
        let mut cmd = bin();
        cmd.arg("compare").arg(sugiyama()).args([
            "--baselines",
            runs,
            "--no-plots",
            "--jobs",
            jobs,
        ]);
        if let Some(g) = gate {
            cmd.args(["--fail-on", g]);
        }
        let (code, out, err) = run(cmd.arg("--out").arg(dir));
        let not_sync: Vec<&str> = runs
            .split(',')
            .filter(|n| {
                json(&dir.join(n).join("metrics.json"))["sync"]["verdict"] == "not_synchronized"
            })
            .collect();
        let expected = i32::from(gate.is_some() && !not_sync.is_empty());
        assert_eq!(code, expected, "{not_sync:?}\n{out}\n{err}");
        if gate.is_some() {
            assert!(!not_sync.is_empty(), "SUMO's drivers jam the Sugiyama ring");
            assert!(
                err.contains(&format!(
                    "fail-on not synchronized: {} of 3 runs: {}",
                    not_sync.len(),
                    not_sync.join(", ")
                )),
                "{err}"
            );
            gate_err = err;
        }
    }
    assert!(
        !gate_err.contains("protocol"),
        "the law synchronizes: {gate_err}"
    );
    for name in runs.split(',') {
        let x = std::fs::read(a.join(name).join("metrics.json")).unwrap();
        let y = std::fs::read(b.join(name).join("metrics.json")).unwrap();
        assert!(x == y, "{name}: metrics.json differs between runs");
    }
    assert!(
        std::fs::read(a.join("compare.json")).unwrap()
            == std::fs::read(b.join("compare.json")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&a);
    let _ = std::fs::remove_dir_all(&b);
}

/// A planted regression (the law's predecessor gain 0.6 → 0.5) against the committed
/// Sugiyama comparison baseline fails with exit 1 and names the changed metrics; the
/// unchanged scenario passes.
#[test]
fn planted_gain_change_fails_the_compare_baseline() {
    let d = tmpdir("planted");
    let mut sc = json(&sugiyama());
    sc["model"]["graph"]["gain_pred"] = 0.5.into();
    sc["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .display()
        .to_string()
        .into();
    std::fs::write(d.join("planted.json"), sc.to_string()).unwrap();
    let mut base = json(&repo().join("tests/baselines/sugiyama-ring.compare.json"));
    base["scenario"] = "planted.json".into();
    std::fs::write(d.join("baseline.json"), base.to_string()).unwrap();
    let (code, out, err) = run(bin().arg("regress").arg(d.join("baseline.json")));
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(out.contains("FAIL"), "{out}");
    assert!(
        out.contains("runs.protocol.congestion.speed_std_mps"),
        "{out}"
    );
    assert!(out.contains("runs.protocol.sumo.fuel_mg"), "{out}");
    // SUMO's own drivers do not depend on the gain: only the hash names the change there.
    assert!(!out.contains("runs.idm.congestion"), "{out}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_compare_input_is_refused_before_sumo_starts() {
    let d = tmpdir("bad");
    let cases: [(&[&str], PathBuf, &str); 6] = [
        (
            &["--baselines", "protocol,wiedemann"],
            sugiyama(),
            "--baselines = wiedemann: unknown driver; use krauss (σ 0.5), krauss-SIGMA",
        ),
        (
            &["--baselines", "krauss-1.4"],
            sugiyama(),
            "--baselines = krauss-1.4: Krauss σ = 1.4 must lie in [0, 1]",
        ),
        (
            &["--mixed", "0,30"],
            sugiyama(),
            "--mixed = 0,30: 30 controlled vehicles but the scenario has 22",
        ),
        (
            &["--mixed", "1"],
            repo().join("scenarios/platoon-cacc-sumo.json"),
            "--mixed = 1: mixed traffic needs a ring of delayed drivers",
        ),
        // A damper on a straight road: one wording, whichever flag asked for it.
        (
            &["--baselines", "follower-stopper-4"],
            repo().join("scenarios/platoon-cacc-sumo.json"),
            "--baselines: follower-stopper-4: this law drives on a ring (each vehicle follows its predecessor); scenario platoon-cacc-sumo is a straight road",
        ),
        (
            &["--mixed", "1", "--mixed-controller", "pi-saturation"],
            repo().join("scenarios/platoon-cacc-sumo.json"),
            "--mixed = 1: pi-saturation: this law drives on a ring (each vehicle follows its predecessor); scenario platoon-cacc-sumo is a straight road",
        ),
    ];
    for (args, sc, msg) in cases {
        let out_dir = d.join("never");
        let (code, out, err) = run(bin()
            .arg("compare")
            .arg(&sc)
            .args(args)
            .arg("--out")
            .arg(&out_dir));
        assert_eq!(code, 2, "{args:?}: {out}\n{err}");
        assert!(err.contains(msg), "{args:?}: {err}");
        assert!(!out_dir.exists(), "nothing may be written for bad input");
    }
    // A scenario without a SUMO network names the field.
    let (code, _, err) = run(bin()
        .arg("compare")
        .arg(repo().join("scenarios/platoon-cacc.json"))
        .arg("--out")
        .arg(d.join("never")));
    assert_eq!(code, 2);
    assert!(err.contains("sumo.net is not set"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

/// A run that fails is marked and keeps its folder; the others still report (here SUMO refuses
/// every run at its start, for a detector of an additional file beyond its lane's end, which
/// only SUMO checks), and the command exits 3 with compare.json written.
#[test]
fn failed_runs_are_marked_and_reported() {
    let d = tmpdir("fail");
    std::fs::write(
        d.join("bad.add.xml"),
        r#"<additional><inductionLoop id="d" lane="arc0_0" pos="100000" period="10" file="d.xml"/></additional>"#,
    )
    .unwrap();
    let sc = edited_scenario(&d, "sugiyama-ring", |s| {
        s["horizon_s"] = serde_json::json!(10);
        s["sumo"]["additional"] = serde_json::json!([d.join("bad.add.xml")]);
    });
    let out = d.join("out");
    let (code, stdout, err) = run(bin()
        .arg("compare")
        .arg(&sc)
        .args(["--baselines", "protocol,krauss", "--no-plots", "--out"])
        .arg(&out));
    assert_eq!(code, 3, "{stdout}\n{err}");
    assert!(stdout.contains("protocol (FAILED)"), "{stdout}");
    assert!(err.contains("error: run krauss failed"), "{err}");
    let c = json(&out.join("compare.json"));
    assert_eq!(c["runs"]["protocol"]["complete"], false);
    assert!(
        c["runs"]["krauss"]["error"]
            .as_str()
            .unwrap()
            .contains("lies beyond the lane"),
        "{c}"
    );
    let _ = std::fs::remove_dir_all(&d);
}

/// `--out` relative to the working directory (as in scripts/demo.sh): SUMO resolves the
/// detector's output relative to the additional file, so a relative path must still work.
#[test]
fn relative_output_folder_works() {
    let d = tmpdir("relative");
    let (code, out, err) = run(bin().current_dir(&d).arg("compare").arg(sugiyama()).args([
        "--baselines",
        "krauss",
        "--no-plots",
        "--out",
        "out/cmp",
    ]));
    assert_eq!(code, 0, "{out}\n{err}");
    let m = json(&d.join("out/cmp/krauss/metrics.json"));
    assert!(m["sumo"]["loop_passages"].as_u64().unwrap() > 0, "{m}");
    let _ = std::fs::remove_dir_all(&d);
}

/// A baseline of kind `sumo` re-runs the law alone in SUMO: `--update` records it, a rerun
/// passes, and a planted tolerance violation (a baseline value moved by 1 %) fails with exit 1.
/// The plots of every run and the combined spread plot are written when asked.
#[test]
fn sumo_kind_baseline_and_plots() {
    let d = tmpdir("sumo-kind");
    let base = serde_json::json!({
        "kind": "sumo",
        "scenario": sugiyama().display().to_string(),
        "tolerances": {"default": {"abs": 1e-9, "rel": 1e-6}},
        "metrics": {}
    });
    let path = d.join("b.json");
    std::fs::write(&path, base.to_string()).unwrap();
    let (code, out, err) = run(bin().arg("regress").arg(&path).arg("--update"));
    assert_eq!(code, 0, "{out}\n{err}");
    let mut b = json(&path);
    let runs: Vec<&String> = b["metrics"]["runs"].as_object().unwrap().keys().collect();
    assert_eq!(runs, ["protocol"]);
    let (code, out, _) = run(bin().arg("regress").arg(&path));
    assert_eq!(code, 0, "{out}");
    let std = &mut b["metrics"]["runs"]["protocol"]["congestion"]["speed_std_mps"];
    *std = (std.as_f64().unwrap() * 1.01).into();
    std::fs::write(&path, b.to_string()).unwrap();
    let (code, out, _) = run(bin().arg("regress").arg(&path));
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("FAIL (1 of"), "{out}");

    let (code, out, err) = run(bin()
        .arg("compare")
        .arg(sugiyama())
        .args(["--baselines", "protocol,krauss", "--out"])
        .arg(d.join("plots")));
    assert_eq!(code, 0, "{out}\n{err}");
    for f in [
        "compare_spread.png",
        "compare_spread.svg",
        "protocol/time_space.png",
        "krauss/speeds.svg",
        "krauss/spread.png",
    ] {
        assert!(d.join("plots").join(f).is_file(), "{f} missing");
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_law_diverging_on_a_vehicle_sumo_drives_does_not_stop_the_mixed_run() {
    // Vehicle 1's gain makes the law's output for it non-finite from step 0; in mixed-2 SUMO
    // drives vehicle 1 (the law drives 0 and 11), so the law's output for it is never sent.
    let dir = tmpdir("compare-mixed-nonfinite");
    let mut s = json(&sugiyama());
    s["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .to_string_lossy()
        .into();
    s["horizon_s"] = 60.into();
    let mut gain = vec![Value::from(0.6); 22];
    gain[1] = 1e308.into();
    s["model"]["graph"]["gain_pred"] = gain.into();
    let scenario = dir.join("s.json");
    std::fs::write(&scenario, s.to_string()).unwrap();
    let (code, out, err) = run(bin()
        .args([
            "compare",
            "--no-plots",
            "--baselines",
            "krauss",
            "--mixed",
            "0,2",
        ])
        .arg(&scenario)
        .arg("--out")
        .arg(dir.join("out")));
    assert!(code == 0 || code == 1, "{out}{err}");
    let m = json(&dir.join("out/protocol-mixed-2/metrics.json"));
    assert_eq!(m["complete"], true, "{m}");
    assert_eq!(m["safety"]["negative_commands_clamped"], 0, "{m}");
}

#[test]
fn an_interrupted_regress_exits_130_and_leaves_the_baseline_whole() {
    let d = tmpdir("regress-interrupted");
    let mut base = json(&repo().join("tests/baselines/sugiyama-ring.compare.json"));
    base["scenario"] = sugiyama().display().to_string().into();
    let path = d.join("baseline.json");
    let before = serde_json::to_string_pretty(&base).unwrap();
    std::fs::write(&path, &before).unwrap();
    for update in [true, false] {
        let mut cmd = bin();
        cmd.arg("regress").arg(&path);
        if update {
            cmd.arg("--update");
        }
        let mut child = cmd
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Once its first run has finished (the batch's progress line), with others to come.
        let mut lines = StderrLines::of(&mut child);
        lines.wait_for(|l| l.contains(" done, "));
        // SAFETY: signalling a child this test started.
        assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
        let o = child.wait_with_output().unwrap();
        let err = lines.rest();
        assert_eq!(o.status.code(), Some(130), "update {update}: {err}");
        assert!(err.contains("interrupted"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), before);
    }
}

/// `compare` shows its progress the way `run` does: nothing in a pipe by default (a bar only
/// on a terminal), a line per finished run with `--progress lines`, nothing with `--quiet`.
#[test]
fn compare_reports_progress_only_where_asked() {
    let d = tmpdir("compare-progress");
    let sc = edited_scenario(&d, "sugiyama-ring", |s| {
        s["horizon_s"] = serde_json::json!(12.0);
    });
    for (flag, lines) in [
        (None, false),
        (Some("--progress=lines"), true),
        (Some("--quiet"), false),
    ] {
        let out = d.join(format!(
            "out-{}",
            flag.unwrap_or("auto").trim_start_matches('-')
        ));
        let mut cmd = bin();
        cmd.args([
            "compare",
            "--baselines",
            "protocol,idm",
            "--no-plots",
            "--out",
        ])
        .arg(&out)
        .arg(&sc);
        if let Some(f) = flag {
            cmd.arg(f);
        }
        let (code, stdout, stderr) = run(&mut cmd);
        assert!(code == 0 || code == 1, "{stdout}\n{stderr}");
        let shown = stderr
            .lines()
            .filter(|l| l.starts_with("compare: ["))
            .count();
        assert_eq!(shown, if lines { 2 } else { 0 }, "{flag:?}: {stderr}");
    }
}

/// `run --emissions` gives a single run the fuel and CO2 a comparison measures: the same
/// `sumo` block as the comparison's run of the law, and fuel that SUMO's own trip info sums
/// to over the whole run (no warm-up here; its values rounded to 0.01 mg per vehicle); a native
/// scenario refuses the flag.
#[test]
fn a_single_run_measures_fuel_and_co2_with_emissions() {
    let d = tmpdir("run-emissions");
    let (code, out, err) = run(bin()
        .arg("run")
        .arg(sugiyama())
        .args([
            "--emissions",
            "--warmup-s",
            "0",
            "--no-plots",
            "-q",
            "--out",
        ])
        .arg(d.join("run")));
    assert_eq!(code, 0, "{out}{err}");
    assert!(
        out.contains("  SUMO measured (after the warm-up): fuel "),
        "{out}"
    );
    let m = json(&d.join("run/metrics.json"));
    let (fuel, trips) = tripinfo_sum(&d.join("run/sumo/tripinfo.xml"), "fuel_abs");
    assert_eq!(trips, 22);
    let fuel_mg = m["sumo"]["fuel_mg"].as_f64().unwrap();
    assert!((fuel_mg - fuel).abs() <= 0.01 * 22.0, "{fuel_mg} vs {fuel}");
    let (code, _, err) = run(bin()
        .arg("compare")
        .arg(sugiyama())
        .args([
            "--baselines",
            "protocol",
            "--warmup-s",
            "0",
            "--no-plots",
            "-q",
            "--out",
        ])
        .arg(d.join("cmp")));
    assert_eq!(code, 0, "{err}");
    let c = json(&d.join("cmp/protocol/metrics.json"));
    assert_eq!(m["sumo"], c["sumo"]);
    let (code, _, err) = run(bin()
        .arg("run")
        .arg(repo().join("scenarios/ring-theorem1.json"))
        .args(["--emissions", "--out"])
        .arg(d.join("native")));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--emissions: a SUMO option"), "{err}");
}

/// The guide's Python FollowerStopper at U = 4.3 m/s, named as `--baselines` and
/// `--mixed-controller` name one's own class.
fn python_follower_stopper() -> String {
    let fs = repo().join("examples/controllers/follower_stopper.py");
    format!(
        "python:{}:FollowerStopper:desired_speed_mps=4.3",
        fs.display()
    )
}

/// `--baselines` names the user's Python class as it names a law (`python:FILE.py:Class`, its
/// keyword arguments as `:NAME=VALUE`): the guide's Python FollowerStopper, written apart from
/// the built-in law, runs beside `follower-stopper-4.3` at its speeds to rounding, under its
/// class's name; a file that is not there is refused before SUMO starts.
#[test]
fn a_comparison_runs_ones_own_python_class_beside_the_laws() {
    let d = tmpdir("compare-python");
    let own = python_follower_stopper();
    let (code, out, err) = run(bin()
        .arg("compare")
        .arg(sugiyama())
        .args([
            "--baselines",
            &format!("follower-stopper-4.3,{own}"),
            "--no-plots",
            "-q",
            "--out",
        ])
        .arg(&d));
    assert_eq!(code, 0, "{out}{err}");
    assert!(
        out.contains("| metric | follower-stopper-4.3 | python:FollowerStopper |"),
        "{out}"
    );
    let doc = json(&d.join("compare.json"));
    let py = &doc["runs"]["python:FollowerStopper"];
    assert!(
        py["drivers"]
            .as_array()
            .unwrap()
            .iter()
            .all(|x| x == "python:FollowerStopper"),
        "{py}"
    );
    let worst = worst_speed_difference(
        &d.join("follower-stopper-4.3/trajectories.csv"),
        &d.join("python_FollowerStopper/trajectories.csv"),
    );
    assert!(
        worst < 1e-9,
        "the Python FollowerStopper differs by {worst} m/s"
    );
    let (code, _, err) = run(bin()
        .arg("compare")
        .arg(sugiyama())
        .args(["--baselines", "python:missing.py:X", "--out"])
        .arg(d.join("bad")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--baselines") && err.contains("missing.py"),
        "{err}"
    );
    assert!(!d.join("bad/compare.json").exists());
}

/// The automated vehicles of a mixed comparison take one's own Python class as they take a
/// law: the Python FollowerStopper among the noisy humans drives as the law of the same
/// equations, the humans (the same noise streams) too.
#[test]
fn the_automated_vehicles_of_mixed_runs_take_ones_own_python_class() {
    let d = tmpdir("compare-mixed-python");
    let own = python_follower_stopper();
    let (code, out, err) = run(bin()
        .arg("compare")
        .arg(sugiyama())
        .args([
            "--baselines",
            "protocol",
            "--mixed",
            "0,2",
            "--mixed-driver",
            "human-noisy",
            "--mixed-controller",
            &format!("follower-stopper-4.3,{own}"),
            "--no-plots",
            "-q",
            "--out",
        ])
        .arg(&d));
    assert_eq!(code, 0, "{out}{err}");
    assert!(
        out.contains("| follower-stopper-4.3-mixed-2 | python:FollowerStopper-mixed-2 |"),
        "{out}"
    );
    let doc = json(&d.join("compare.json"));
    let drivers = |run: &str| -> Vec<String> {
        doc["runs"][run]["drivers"]
            .as_array()
            .unwrap_or_else(|| panic!("{run}: {doc}"))
            .iter()
            .map(|x| x.as_str().unwrap().to_string())
            .collect()
    };
    // Two of 22 evenly spaced (vehicles 0 and 11) are the class's; the others the humans'.
    let py = drivers("python:FollowerStopper-mixed-2");
    let ours: Vec<usize> = (0..22)
        .filter(|&i| py[i] == "python:FollowerStopper")
        .collect();
    assert_eq!(ours, [0, 11], "{py:?}");
    let worst = worst_speed_difference(
        &d.join("follower-stopper-4.3-mixed-2/trajectories.csv"),
        &d.join("python_FollowerStopper-mixed-2/trajectories.csv"),
    );
    assert!(worst < 1e-9, "the mixed runs differ by {worst} m/s");
}
