//! Hostile input end to end: nothing silently wrong, nothing overwritten. One module per
//! class: wrong results reported as right, data overwritten or lost, text that reaches a
//! shell, and what must be refused up front. Tests that need SUMO run SUMO.

mod common;

use std::fs::File;
use std::os::unix::fs::{symlink, FileTypeExt};
use std::path::{Path, PathBuf};

use common::{bin, children_of, repo, run, tmpdir};
use serde_json::{json, Value};

fn write_json(path: &Path, v: &Value) -> PathBuf {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
    path.to_path_buf()
}

/// The Sugiyama ring of `scenarios/sugiyama-ring.json` with `edit` applied, its network path
/// made absolute.
fn sugiyama(dir: &Path, name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let mut s: Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap(),
    )
    .unwrap();
    s["sumo"]["net"] = json!(repo().join("sumo-nets/sugiyama-ring.net.xml"));
    edit(&mut s);
    write_json(&dir.join(name), &s)
}

fn metrics(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap()
}

/// Every gap of every sample of a `trajectories.csv` on a ring of `ring_m` with vehicles of
/// `length_m`, recomputed from the positions (not the file's gap column).
fn smallest_gap_from_positions(csv: &Path, n: usize, ring_m: f64, length_m: f64) -> f64 {
    let text = std::fs::read_to_string(csv).unwrap();
    let q: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(3).unwrap().parse().unwrap())
        .collect();
    let mut smallest = f64::INFINITY;
    for s in q.chunks(n) {
        for i in 0..n {
            // Vehicle i follows i − 1 (vehicle 0 follows n − 1, one lap ahead).
            let ahead = if i == 0 { s[n - 1] + ring_m } else { s[i - 1] };
            smallest = smallest.min(ahead - s[i] - length_m);
        }
    }
    smallest
}

mod wrong_results {
    use super::*;

    #[test]
    fn a_native_ring_whose_vehicles_overlap_is_not_synchronized_and_sumo_agrees() {
        let dir = tmpdir("overlap");
        // Gains scaled by 0.25: the spread still decays below the tolerance, but the vehicles
        // drive through each other.
        let sc = sugiyama(&dir, "ring.json", |s| {
            s["model"]["graph"]["gain_pred"] = json!(0.15);
            s["model"]["graph"]["gain_follow"] = json!(0.025);
        });
        let (code, out, err) = run(bin()
            .args(["simulate"])
            .arg(&sc)
            .arg("--out")
            .arg(dir.join("native")));
        assert_eq!(code, 1, "{out}{err}");
        let m = metrics(&dir.join("native"));
        // The spread alone would call it synchronized ...
        assert!(
            m["sync"]["window_max_spread_mps"].as_f64().unwrap() <= 0.05,
            "{m}"
        );
        // ... but positions recomputed from the file show overlapping bumpers.
        let gap = smallest_gap_from_positions(&dir.join("native/trajectories.csv"), 22, 230.0, 5.0);
        assert!(gap < -1.0, "smallest gap {gap}");
        assert_eq!(m["sync"]["verdict"], "not_synchronized");
        let why = m["sync"]["verdict_reason"].as_str().unwrap();
        assert!(why.starts_with("vehicles overlapped in "), "{why}");
        assert!(out.contains("because vehicles overlapped"), "{out}");
        // SUMO, on the same scenario, reports collisions.
        let (code, out, err) = run(bin()
            .args(["run"])
            .arg(&sc)
            .arg("--out")
            .arg(dir.join("sumo")));
        assert_eq!(code, 1, "{out}{err}");
        let s = metrics(&dir.join("sumo"));
        assert!(s["safety"]["collision_steps"].as_u64().unwrap() > 0, "{s}");
        assert_eq!(s["sync"]["verdict"], "not_synchronized");
    }

    #[test]
    fn a_follower_stopper_that_stops_every_vehicle_is_a_jam_not_a_success() {
        let dir = tmpdir("standstill");
        let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(120));
        let out = dir.join("cmp");
        let (_, stdout, err) = run(bin()
            .args(["compare"])
            .arg(&sc)
            .args(["--baselines", "follower-stopper-0", "--no-plots", "--out"])
            .arg(&out));
        let m = metrics(&out.join("follower-stopper-0"));
        assert!(m["complete"].as_bool().unwrap(), "{stdout}{err}");
        // Every vehicle stands: equal speeds of 0 m/s.
        assert!(
            m["congestion"]["mean_speed_mps"].as_f64().unwrap() < 0.05,
            "{m}"
        );
        assert_ne!(m["sync"]["verdict"], "synchronized", "{m}");
        let why = m["sync"]["verdict_reason"].as_str().unwrap_or_default();
        assert!(why.contains("stands still"), "{m}");
    }

    #[test]
    fn a_loose_tolerance_is_not_a_standstill_and_one_sample_measures_no_time() {
        let dir = tmpdir("loose");
        let ring = repo().join("scenarios/ring-theorem1.json");
        // A tolerance above the cruise speed once made a moving ring "stand still".
        let (code, o, e) = run(bin()
            .arg("simulate")
            .arg(&ring)
            .args(["--tolerance-mps", "10", "--no-plots", "--out"])
            .arg(dir.join("loose")));
        assert_eq!(code, 0, "{o}{e}");
        let m = metrics(&dir.join("loose"));
        assert_eq!(m["sync"]["verdict"], "synchronized", "{m}");
        assert!(
            m["congestion"]["mean_speed_mps"].as_f64().unwrap() > 1.0,
            "{m}"
        );
        // One recorded sample after the warm-up: no congestion metrics and no headway time
        // (both need two samples), not a made-up 0.
        let (_, o, e) = run(bin()
            .arg("simulate")
            .arg(&ring)
            .args(["--record-every", "3000", "--no-plots", "--out"])
            .arg(dir.join("sparse")));
        let m = metrics(&dir.join("sparse"));
        assert!(m["congestion"].is_null(), "{o}{e}{m}");
        assert!(
            m["gap_safety"]["time_below_safe_headway_s"].is_null(),
            "{m}"
        );
        assert!(m["gap_safety"]["min_gap_m"].as_f64().is_some(), "{m}");
    }
}

mod sweeps {
    use super::*;

    pub fn native_ring(dir: &Path) -> PathBuf {
        let p = dir.join("ring.json");
        std::fs::copy(repo().join("scenarios/ring-theorem1.json"), &p).unwrap();
        p
    }

    pub fn spec(dir: &Path, name: &str, body: Value) -> PathBuf {
        write_json(&dir.join(name), &body)
    }

    pub fn sweep(spec: &Path, out: &Path) -> (i32, String, String) {
        run(bin()
            .arg("sweep")
            .arg(spec)
            .arg("--out")
            .arg(out)
            .args(["--no-plots", "--jobs", "1"]))
    }

    #[test]
    fn point_counts_never_wrap_and_huge_sweeps_are_refused_naming_the_axes() {
        let dir = tmpdir("counts");
        native_ring(&dir);
        let axis = |f: &str, n: usize| json!({"field": f, "linspace": [0.5, 1.5, n]});
        let cases = [
            // 65536⁴ = 2^64 wraps to 0 in unchecked arithmetic ("0 points", exit 0).
            (
                json!({"base": "ring.json", "axes": [axis("scale.gain", 65536), axis("scale.delay", 65536), axis("initial.speed_mps", 65536), axis("initial.perturbation.speed_mps", 65536)]}),
                "more than 2^64 points (axes[scale.gain]: 65536 × axes[scale.delay]: 65536",
            ),
            // 10⁹ points: refused at once, not run out of memory.
            (
                json!({"base": "ring.json", "axes": [axis("scale.gain", 1000), axis("scale.delay", 1000), axis("initial.speed_mps", 1000)]}),
                "the sweep has 1000000000 points",
            ),
            // Seeds starting near the largest integer gave 0 points.
            (
                json!({"base": "ring.json", "seeds": {"first": u64::MAX, "count": 2}}),
                "the last seed would pass 9223372036854775807",
            ),
        ];
        for (body, want) in cases {
            let p = spec(&dir, "spec.json", body);
            // Refused at once: held to 20 CPU-seconds and 4 GiB of address space (CPU time, not
            // wall time, so a loaded machine cannot fail it), where enumerating the points
            // would be killed by SIGXCPU or fail to allocate.
            use std::os::unix::process::CommandExt;
            let mut cmd = bin();
            cmd.arg("sweep")
                .arg(&p)
                .arg("--out")
                .arg(dir.join("out"))
                .args(["--no-plots", "--jobs", "1"]);
            // SAFETY: only async-signal-safe calls between fork and exec.
            unsafe {
                cmd.pre_exec(|| {
                    for (resource, limit) in [(libc::RLIMIT_CPU, 20), (libc::RLIMIT_AS, 4 << 30)] {
                        let lim = libc::rlimit {
                            rlim_cur: limit,
                            rlim_max: limit,
                        };
                        if libc::setrlimit(resource, &lim) != 0 {
                            return Err(std::io::Error::last_os_error());
                        }
                    }
                    Ok(())
                });
            }
            let (code, out, err) = run(&mut cmd);
            assert_eq!(code, 2, "{out}{err}");
            assert!(err.contains(want), "{err}");
            assert!(!dir.join("out").exists());
        }
    }

    #[test]
    fn rows_that_are_not_the_sweeps_never_enter_its_table() {
        let dir = tmpdir("foreign");
        native_ring(&dir);
        let p = spec(
            &dir,
            "spec.json",
            json!({"base": "ring.json", "seeds": [1, 2], "axes": [{"field": "scale.gain", "values": [1.0]}]}),
        );
        let out = dir.join("out");
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 0, "{o}{e}");
        let row = std::fs::read_to_string(out.join("rows/0000001.json")).unwrap();
        let mut foreign: Value = serde_json::from_str(&row).unwrap();
        foreign["point"] = json!(99);
        let first = std::fs::read_to_string(out.join("rows/0000000.json")).unwrap();
        let mut reseeded: Value = serde_json::from_str(&first).unwrap();
        reseeded["seed"] = json!(7);
        let cases: [(&str, String, &str); 3] = [
            (
                "0000099.json",
                foreign.to_string(),
                "holds point 99, and the spec has 2 points",
            ),
            // A duplicate of a finished row under another name.
            (
                "0000001 (copy).json",
                row.clone(),
                "holds point 1, whose row is 0000001.json",
            ),
            // A row with other parameters under a point's number.
            (
                "0000000.json",
                reseeded.to_string(),
                "its seed is 7, but point 0 of this spec has 1",
            ),
        ];
        for (name, text, want) in cases {
            std::fs::write(out.join("rows").join(name), &text).unwrap();
            let (code, o, e) = sweep(&p, &out);
            assert_eq!(code, 2, "{name}: {o}{e}");
            assert!(e.contains(want), "{name}: {e}");
            assert!(e.contains(name), "{name}: {e}");
            // collect refuses it too, instead of reporting "2 of 2".
            let (code, o, e) = run(bin()
                .args(["sweep", "collect"])
                .arg(&p)
                .arg("--out")
                .arg(dir.join("merged"))
                .arg(&out)
                .arg("--no-plots"));
            assert_eq!(code, 2, "{name}: {o}{e}");
            assert!(e.contains(want), "{name}: {e}");
            if name == "0000000.json" {
                std::fs::write(out.join("rows/0000000.json"), &first).unwrap();
            } else {
                std::fs::remove_file(out.join("rows").join(name)).unwrap();
            }
        }
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 0, "{o}{e}");
        assert_eq!(
            std::fs::read_to_string(out.join("results.csv"))
                .unwrap()
                .lines()
                .count(),
            3
        );
    }

    #[test]
    fn map_removes_only_a_sweep_folder_an_earlier_map_wrote() {
        let dir = tmpdir("map-foreign");
        let ring = native_ring(&dir);
        let map = |out: &Path| {
            run(bin()
                .arg("map")
                .arg(&ring)
                .args([
                    "--x",
                    "gain_scale=0.5:2:2",
                    "--y",
                    "delay_scale=0.5:2:2",
                    "--out",
                ])
                .arg(out))
        };
        // The user's folder at OUT/sweep, and a file there: refused before any work.
        let out = dir.join("out");
        std::fs::create_dir_all(out.join("sweep")).unwrap();
        std::fs::write(out.join("sweep/notes.txt"), "mine").unwrap();
        let (code, o, e) = map(&out);
        assert_eq!(code, 2, "{o}{e}");
        assert!(e.contains("is not a sweep an earlier map wrote"), "{e}");
        assert_eq!(
            std::fs::read_to_string(out.join("sweep/notes.txt")).unwrap(),
            "mine"
        );
        assert!(!out.join("map.csv").exists());
        let file_out = dir.join("file-out");
        std::fs::create_dir_all(&file_out).unwrap();
        std::fs::write(file_out.join("sweep"), "mine").unwrap();
        let (code, o, e) = map(&file_out);
        assert_eq!(code, 2, "{o}{e}");
        // Its own sweep folder is replaced: a second map into the same folder runs.
        let fresh = dir.join("fresh");
        for _ in 0..2 {
            let (code, o, e) = map(&fresh);
            assert_eq!(code, 0, "{o}{e}");
        }
    }

    #[test]
    fn a_native_sweep_never_runs_a_mixed_block_as_an_all_law_ring() {
        let dir = tmpdir("native-mixed");
        native_ring(&dir);
        // A mixed.penetration axis, and a base scenario with a mixed block: both once ran
        // every vehicle with the law and labelled the row with the penetration.
        let axis = spec(
            &dir,
            "axis.json",
            json!({"base": "ring.json", "backend": "native",
                   "axes": [{"field": "mixed.penetration", "values": [0.5]}]}),
        );
        let (code, o, e) = sweep(&axis, &dir.join("out1"));
        assert_eq!(code, 2, "{o}{e}");
        assert!(
            e.contains("mixed block puts SUMO drivers among the law's vehicles"),
            "{e}"
        );
        let mut ring: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("ring.json")).unwrap()).unwrap();
        ring["mixed"] = json!({"penetration": 0.5});
        write_json(&dir.join("mixed.json"), &ring);
        let base = spec(
            &dir,
            "base.json",
            json!({"base": "mixed.json", "backend": "native"}),
        );
        let (code, o, e) = sweep(&base, &dir.join("out2"));
        assert_eq!(code, 2, "{o}{e}");
        assert!(e.contains("base scenario's mixed block"), "{e}");
        assert!(!dir.join("out1/rows").exists() && !dir.join("out2/rows").exists());
    }

    #[test]
    fn a_second_writer_of_a_sweep_folder_is_refused_naming_the_holder() {
        let dir = tmpdir("lock");
        native_ring(&dir);
        let p = spec(&dir, "spec.json", json!({"base": "ring.json"}));
        let out = dir.join("out");
        std::fs::create_dir_all(&out).unwrap();
        // This test process holds the lock as another sweep would.
        let held = File::create(out.join(".syncroad.lock")).unwrap();
        held.try_lock().unwrap();
        std::fs::write(
            out.join(".syncroad.lock"),
            format!("{}\nsyncroad sweep other.json\n", std::process::id()),
        )
        .unwrap();
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 2, "{o}{e}");
        assert!(
            e.contains(&format!(
                "another syncroad is writing this folder (pid {}: syncroad sweep other.json)",
                std::process::id()
            )),
            "{e}"
        );
        assert!(!out.join("rows").exists(), "nothing was written");
        drop(held);
        // Released (as the kernel does when the holder dies, however it dies): it runs.
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 0, "{o}{e}");
        // A killed sweep leaves no stale lock.
        let mut child = bin()
            .arg("sweep")
            .arg(&p)
            .arg("--out")
            .arg(dir.join("killed"))
            .spawn()
            .unwrap();
        // Killed while it holds the lock.
        let t0 = std::time::Instant::now();
        // Waits for the lock file (an observable state); the 120 s only bound a hang.
        while !dir.join("killed/.syncroad.lock").exists() && t0.elapsed().as_secs() < 120 {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let _ = child.kill();
        child.wait().unwrap();
        let (code, o, e) = sweep(&p, &dir.join("killed"));
        assert_eq!(code, 0, "{o}{e}");
        // Killed at the worst moment of its start: the lock taken, sweep.json half written
        // (its temporary file in place). The folder is still the sweep's to start.
        let started = dir.join("killed-at-start");
        std::fs::create_dir_all(&started).unwrap();
        std::fs::write(started.join(".syncroad.lock"), "").unwrap();
        std::fs::write(started.join(".sweep.json.Ab12Cd.tmp"), "{\"spec\"").unwrap();
        let (code, o, e) = sweep(&p, &started);
        assert_eq!(code, 0, "{o}{e}");
        // Anything else there is not ours: still refused.
        let foreign = dir.join("foreign");
        std::fs::create_dir_all(&foreign).unwrap();
        std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
        let (code, _, e) = sweep(&p, &foreign);
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("exists and is not a sweep folder"), "{e}");
    }

    #[test]
    fn run_simulate_compare_and_map_refuse_a_folder_another_syncroad_writes() {
        let dir = tmpdir("run-lock");
        let ring = native_ring(&dir);
        let out = dir.join("out");
        std::fs::create_dir_all(&out).unwrap();
        // The other writer's record, and its lock held by this test process.
        std::fs::write(out.join("metrics.json"), "{\"theirs\": true}\n").unwrap();
        let held = File::create(out.join(".syncroad.lock")).unwrap();
        held.try_lock().unwrap();
        std::fs::write(
            out.join(".syncroad.lock"),
            format!("{}\nsyncroad run other.json\n", std::process::id()),
        )
        .unwrap();
        // compare needs a SUMO scenario: it is refused before SUMO starts.
        let sumo = repo().join("scenarios/sugiyama-ring.json");
        let commands: [(&[&str], &Path); 4] = [
            (&["run"], &ring),
            (&["simulate"], &ring),
            (&["compare", "--baselines", "idm"], &sumo),
            (
                &[
                    "map",
                    "--no-sim",
                    "--x",
                    "gain_scale=0.5:1:2",
                    "--y",
                    "delay_scale=0.5:1:2",
                ],
                &ring,
            ),
        ];
        for (args, scenario) in commands {
            let (code, o, e) = run(bin().args(args).arg(scenario).arg("--out").arg(&out));
            assert_eq!(code, 2, "{args:?}: {o}{e}");
            assert!(
                e.contains(&format!(
                    "another syncroad is writing this folder (pid {}: syncroad run other.json)",
                    std::process::id()
                )),
                "{args:?}: {e}"
            );
            assert_eq!(
                std::fs::read_to_string(out.join("metrics.json")).unwrap(),
                "{\"theirs\": true}\n",
                "{args:?} touched the other writer's record"
            );
        }
        drop(held);
        let (code, o, e) = run(bin().arg("simulate").arg(&ring).arg("--out").arg(&out));
        assert_eq!(code, 0, "{o}{e}");
        assert!(!std::fs::read_to_string(out.join("metrics.json"))
            .unwrap()
            .contains("theirs"));
    }

    #[test]
    fn every_point_is_checked_as_it_will_run_before_anything_runs() {
        let dir = tmpdir("validate-all");
        native_ring(&dir);
        // The spec's warm-up is named as the spec's field, and refused before any point runs.
        let p = spec(
            &dir,
            "spec.json",
            json!({"base": "ring.json", "warmup_s": 1e9}),
        );
        let (code, o, e) = sweep(&p, &dir.join("out"));
        assert_eq!(code, 2, "{o}{e}");
        assert!(
            e.contains("warmup_s = 1000000000: must be ≥ 0 and shorter than the horizon"),
            "{e}"
        );
        assert!(!e.contains("--warmup-s"), "{e}");
        // A driver value that depends on the step, checked for every point (SUMO, not started).
        let sc = sugiyama(&dir, "sumo-ring.json", |_| {});
        let p = spec(
            &dir,
            "spec2.json",
            json!({"base": sc, "runs": ["idm:actionStepLength=0.15"]}),
        );
        let (code, o, e) = sweep(&p, &dir.join("out2"));
        assert_eq!(code, 2, "{o}{e}");
        assert!(e.contains("sweep point 0"), "{e}");
        assert!(e.contains("actionStepLength"), "{e}");
        assert!(
            !dir.join("out2/rows").exists()
                || std::fs::read_dir(dir.join("out2/rows")).unwrap().count() == 0
        );
        // Penetrations that round to the same vehicle count would run the same ring twice.
        let p = spec(
            &dir,
            "spec3.json",
            json!({"base": sc, "penetrations": [0.1, 0.11]}),
        );
        let (code, _, e) = sweep(&p, &dir.join("out3"));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.contains("penetrations: 0.1 and 0.11 both give 2 of 22"),
            "{e}"
        );
    }

    #[test]
    fn a_resumed_sumo_sweep_refuses_another_network_and_keeps_no_work_of_stopped_points() {
        let dir = tmpdir("net-hash");
        let net = dir.join("ring.net.xml");
        std::fs::copy(repo().join("sumo-nets/sugiyama-ring.net.xml"), &net).unwrap();
        // Huge gains: SUMO removes colliding vehicles, the point stops (a result, not a failure).
        let sc = sugiyama(&dir, "ring.json", |s| {
            s["sumo"]["net"] = json!(net);
            s["horizon_s"] = json!(30);
            s["model"]["graph"]["gain_pred"] = json!(1e6);
        });
        let p = spec(&dir, "spec.json", json!({"base": sc, "seeds": [1, 2]}));
        let out = dir.join("out");
        let (code, o, e) = sweep(&p, &out);
        let table = std::fs::read_to_string(out.join("results.csv")).unwrap_or_default();
        assert!(code == 0 || code == 3, "{o}{e}");
        let work = out.join("work");
        let kept = if work.is_dir() {
            std::fs::read_dir(&work).unwrap().count()
        } else {
            0
        };
        let failed = table.lines().filter(|l| l.contains(",failed,")).count();
        assert_eq!(
            kept, failed,
            "work folders are kept for failed points only\n{table}"
        );
        // The same spec and scenario on an edited network is another sweep.
        let mut text = std::fs::read_to_string(&net).unwrap();
        text.push_str("<!-- edited -->\n");
        std::fs::write(&net, text).unwrap();
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 2, "{o}{e}");
        assert!(
            e.contains("holds a sweep of another spec, base scenario or input file"),
            "{e}"
        );
    }

    #[test]
    fn a_resumed_sumo_sweep_refuses_edited_route_and_additional_files() {
        let dir = tmpdir("inputs-hash");
        let routes = dir.join("traffic.rou.xml");
        let additional = dir.join("extra.add.xml");
        std::fs::write(&routes, "<routes>\n</routes>\n").unwrap();
        std::fs::write(&additional, "<additional>\n</additional>\n").unwrap();
        let sc = sugiyama(&dir, "ring.json", |s| {
            s["horizon_s"] = json!(20);
            s["sumo"]["routes"] = json!([routes]);
            s["sumo"]["additional"] = json!([additional]);
        });
        let p = spec(&dir, "spec.json", json!({"base": sc, "seeds": [1]}));
        let out = dir.join("out");
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 0, "{o}{e}");
        // Unchanged files: the sweep resumes (nothing left to run).
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 0, "{o}{e}");
        assert!(o.contains("1 finished before"), "{o}");
        for file in [&routes, &additional] {
            let before = std::fs::read_to_string(file).unwrap();
            std::fs::write(file, format!("{before}<!-- edited -->\n")).unwrap();
            let (code, o, e) = sweep(&p, &out);
            assert_eq!(code, 2, "{}: {o}{e}", file.display());
            assert!(
                e.contains("holds a sweep of another spec, base scenario or input file"),
                "{e}"
            );
            std::fs::write(file, before).unwrap();
        }
        let (code, o, e) = sweep(&p, &out);
        assert_eq!(code, 0, "restored files resume: {o}{e}");
    }
}

#[test]
fn a_stopped_sumo_worker_fails_its_point_instead_of_stalling_the_sweep() {
    let dir = tmpdir("sigstop");
    let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(20000));
    let spec = write_json(&dir.join("spec.json"), &json!({"base": sc, "seeds": [1]}));
    let started = std::time::Instant::now();
    let mut child = bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--out")
        .arg(dir.join("out"))
        .args(["--no-plots", "--jobs", "1"])
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Wait for the worker, let SUMO start, then stop it as SIGSTOP (or Ctrl-Z on it) would.
    let worker = loop {
        if let Some(&w) = children_of(child.id()).first() {
            break w;
        }
        assert!(started.elapsed().as_secs() < 30, "no worker started");
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    std::thread::sleep(std::time::Duration::from_secs(3));
    unsafe { libc::kill(worker, libc::SIGSTOP) };
    let stopped_at = std::time::Instant::now();
    let status = child.wait().unwrap();
    // Failed after the 10 s limit, not after the run's 600 s time limit (the upper bound is
    // half that limit: room for a loaded machine, and still a failure if the watch never fired).
    let waited = stopped_at.elapsed().as_secs_f64();
    assert!((9.0..300.0).contains(&waited), "waited {waited} s");
    assert_eq!(status.code(), Some(3));
    let row: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/rows/0000000.json")).unwrap())
            .unwrap();
    assert_eq!(row["status"], "failed", "{row}");
    let why = row["error"].as_str().unwrap();
    assert!(
        why.contains(&format!(
            "the SUMO worker (pid {worker}) was stopped (SIGSTOP or SIGTSTP)"
        )),
        "{why}"
    );
    // The stopped worker is gone, not left behind.
    assert!(
        !Path::new(&format!("/proc/{worker}")).exists()
            || std::fs::read_to_string(format!("/proc/{worker}/stat"))
                .map_or(true, |s| s.contains(") Z"))
    );
}

mod overwritten {
    use super::*;

    /// A detector of the user's additional file writes into the run's folder: the file its
    /// `file` attribute names (absolute, or relative to the additional file) is never
    /// touched, each run of a sweep keeps its own detector output, and two detectors naming
    /// one file still share one.
    #[test]
    fn additional_file_outputs_land_in_the_run_folder_never_elsewhere() {
        let dir = tmpdir("additional-outputs");
        let elsewhere = dir.join("elsewhere");
        std::fs::create_dir_all(&elsewhere).unwrap();
        let victim = elsewhere.join("victim.txt");
        std::fs::write(&victim, "mine").unwrap();
        std::fs::write(dir.join("victim_rel.xml"), "mine too").unwrap();
        std::fs::write(
            dir.join("det.add.xml"),
            format!(
                r#"<additional><inductionLoop id="d0" lane="arc0_0" pos="10" period="5" file="{}"/><inductionLoop id="d1" lane="arc1_0" pos="10" period="5" file="{}"/><inductionLoop id="d2" lane="arc2_0" pos="10" period="5" file="victim_rel.xml"/></additional>"#,
                victim.display(),
                victim.display()
            ),
        )
        .unwrap();
        let sc = sugiyama(&dir, "ring.json", |s| {
            s["horizon_s"] = json!(20);
            s["sumo"]["additional"] = json!(["det.add.xml"]);
        });
        let p = sweeps::spec(&dir, "spec.json", json!({"base": sc, "seeds": [1, 2]}));
        let out = dir.join("sw");
        let (code, o, e) = run(bin()
            .arg("sweep")
            .arg(&p)
            .arg("--out")
            .arg(&out)
            .args(["--keep-runs", "--no-plots"]));
        assert_eq!(code, 0, "{o}{e}");
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "mine");
        assert_eq!(
            std::fs::read_to_string(dir.join("victim_rel.xml")).unwrap(),
            "mine too"
        );
        let mut outputs = Vec::new();
        for point in ["0000000", "0000001"] {
            let folder = out.join("runs").join(point).join("sumo/outputs");
            let mut files: Vec<_> = std::fs::read_dir(&folder)
                .unwrap()
                .flatten()
                .map(|e| e.path())
                .collect();
            files.sort();
            // d0 and d1 share one file, d2 has its own.
            assert_eq!(files.len(), 2, "{files:?}");
            for f in &files {
                let text = std::fs::read_to_string(f).unwrap();
                assert!(text.contains("<interval"), "{}: {text}", f.display());
            }
            outputs.push(files);
        }
        assert_ne!(outputs[0], outputs[1], "each point writes its own files");
    }

    fn regress(report: &str, path: &Path) -> (i32, String, String) {
        run(bin()
            .arg("regress")
            .arg(repo().join("tests/baselines/ring-theorem1.native.json"))
            .arg(report)
            .arg(path))
    }

    #[test]
    fn reports_write_through_special_files_and_symlinks_and_never_replace_them() {
        let dir = tmpdir("reports");
        // /dev/full: a clear error, and the device stays a device.
        let (code, o, e) = regress("--markdown", Path::new("/dev/full"));
        assert_eq!(code, 3, "{o}{e}");
        assert!(
            e.contains("cannot write /dev/full") && e.contains("No space left on device"),
            "{e}"
        );
        assert!(std::fs::metadata("/dev/full")
            .unwrap()
            .file_type()
            .is_char_device());
        // /dev/null takes it silently.
        let (code, o, e) = regress("--junit", Path::new("/dev/null"));
        assert_eq!(code, 0, "{o}{e}");
        assert!(std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device());
        // A FIFO: the reader gets the report, the FIFO stays a FIFO.
        let fifo = dir.join("fifo");
        assert!(std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        let reader = {
            let f = fifo.clone();
            std::thread::spawn(move || std::fs::read_to_string(f).unwrap())
        };
        let (code, o, e) = regress("--markdown", &fifo);
        assert_eq!(code, 0, "{o}{e}");
        assert!(reader.join().unwrap().contains("ring-theorem1"));
        assert!(std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo());
        // A symlink: the link stays, its target gets the report.
        std::fs::create_dir_all(dir.join("real")).unwrap();
        let target = dir.join("real/summary.md");
        std::fs::write(&target, "old").unwrap();
        let link = dir.join("summary.md");
        symlink(&target, &link).unwrap();
        let (code, o, e) = regress("--markdown", &link);
        assert_eq!(code, 0, "{o}{e}");
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert!(std::fs::read_to_string(&target)
            .unwrap()
            .contains("ring-theorem1"));
        // A folder is refused before anything runs, not replaced.
        let (code, _, e) = regress("--junit", &dir.join("real"));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("is a folder"), "{e}");
        assert!(dir.join("real").is_dir());
        // So is a report in a folder that does not exist (it failed after the run).
        let (code, _, e) = regress("--junit", &dir.join("missing/report.xml"));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("does not exist"), "{e}");
    }

    /// No output may be an input: a report that is the baseline (under another spelling, or
    /// a hard link), the other report, or a run folder whose metrics.json is the scenario
    /// itself. Each is refused with exit 2 and the input is untouched.
    #[test]
    fn no_output_is_a_file_the_command_reads() {
        let dir = tmpdir("output-is-input");
        let base = dir.join("baseline.json");
        let text =
            std::fs::read_to_string(repo().join("tests/baselines/ring-theorem1.native.json"))
                .unwrap()
                .replace(
                    "../../scenarios/",
                    &format!("{}/scenarios/", repo().display()),
                );
        std::fs::write(&base, &text).unwrap();
        std::fs::hard_link(&base, dir.join("alias.json")).unwrap();
        let spelt = dir.join("sub/../baseline.json");
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        for (flag, path) in [
            ("--markdown", base.clone()),
            ("--junit", dir.join("alias.json")),
            ("--markdown", spelt),
        ] {
            let (code, o, e) = run(bin().arg("regress").arg(&base).arg(flag).arg(&path));
            assert_eq!(code, 2, "{flag} {}: {o}{e}", path.display());
            assert!(e.contains("is the baseline"), "{e}");
            assert_eq!(std::fs::read_to_string(&base).unwrap(), text);
        }
        let report = dir.join("report.txt");
        let (code, _, e) = run(bin()
            .arg("regress")
            .arg(&base)
            .arg("--junit")
            .arg(&report)
            .arg("--markdown")
            .arg(&report));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("are the same file"), "{e}");
        assert!(!report.exists());
        // A run folder that holds its own scenario as metrics.json.
        let out = dir.join("out");
        std::fs::create_dir_all(&out).unwrap();
        let scenario =
            std::fs::read_to_string(repo().join("scenarios/ring-theorem1.json")).unwrap();
        std::fs::write(out.join("metrics.json"), &scenario).unwrap();
        let (code, _, e) = run(bin()
            .arg("simulate")
            .arg(out.join("metrics.json"))
            .arg("--out")
            .arg(&out));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("is the scenario"), "{e}");
        assert_eq!(
            std::fs::read_to_string(out.join("metrics.json")).unwrap(),
            scenario
        );
        // A SUMO run's own routes file in its work folder `OUT/sumo` that is the user's
        // sumo.routes.
        let out = dir.join("sumo-out");
        std::fs::create_dir_all(out.join("sumo")).unwrap();
        std::fs::write(out.join("sumo/routes.rou.xml"), "<routes/>\n").unwrap();
        let sc = sugiyama(&dir, "with-routes.json", |s| {
            s["sumo"]["routes"] = json!(["sumo-out/sumo/routes.rou.xml"]);
        });
        let (code, _, e) = run(bin().arg("run").arg(&sc).arg("--out").arg(&out));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("is the scenario's sumo.routes[0]"), "{e}");
        assert_eq!(
            std::fs::read_to_string(out.join("sumo/routes.rou.xml")).unwrap(),
            "<routes/>\n"
        );
    }

    /// An output folder that cannot exist (a 300-byte name, a file on the way, a device) is
    /// bad input, exit 2 with the reason, for a run and a sweep alike (it was exit 3).
    #[test]
    fn an_impossible_output_folder_is_bad_input() {
        let dir = tmpdir("impossible-out");
        let scenario = repo().join("scenarios/ring-theorem1.json");
        let long = dir.join("x".repeat(300));
        let (code, _, e) = run(bin().arg("simulate").arg(&scenario).arg("--out").arg(&long));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("longer than the file system allows"), "{e}");
        std::fs::write(dir.join("file"), "").unwrap();
        let (code, _, e) = run(bin()
            .arg("simulate")
            .arg(&scenario)
            .arg("--out")
            .arg(dir.join("file/run")));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("a part of it is a file"), "{e}");
        let base = sweeps::native_ring(&dir);
        let spec = sweeps::spec(
            &dir,
            "s.json",
            json!({"base": base, "backend": "native",
                   "axes": [{"field": "scale.gain", "values": [1.0]}]}),
        );
        let (code, _, e) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&long));
        assert_eq!(code, 2, "{e}");
        let (code, _, e) = sweeps::sweep(&spec, &dir.join("shard"));
        assert_eq!(code, 0, "{e}");
        let (code, _, e) = run(bin()
            .args(["sweep", "collect"])
            .arg(&spec)
            .arg(dir.join("shard"))
            .args(["--out", "/dev/full"]));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("not a folder"), "{e}");
    }

    /// The folder lock is never followed through a link (it locked and overwrote the
    /// target) nor opened on a FIFO (exit 3, or a hang): both are refused with exit 2.
    #[test]
    fn the_folder_lock_is_never_a_link_or_a_fifo() {
        let dir = tmpdir("lock-kinds");
        let victim = dir.join("victim.txt");
        std::fs::write(&victim, "keep").unwrap();
        let out = dir.join("linked");
        std::fs::create_dir_all(&out).unwrap();
        symlink(&victim, out.join(".syncroad.lock")).unwrap();
        let scenario = repo().join("scenarios/ring-theorem1.json");
        let (code, _, e) = run(bin().arg("simulate").arg(&scenario).arg("--out").arg(&out));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("is a symbolic link"), "{e}");
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
        let out = dir.join("fifo");
        std::fs::create_dir_all(&out).unwrap();
        assert!(std::process::Command::new("mkfifo")
            .arg(out.join(".syncroad.lock"))
            .status()
            .unwrap()
            .success());
        let (code, _, e) = run(bin().arg("simulate").arg(&scenario).arg("--out").arg(&out));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("FIFO"), "{e}");
        assert!(!out.join("metrics.json").exists());
    }
}

#[test]
fn a_run_folder_keeps_a_symlinked_record_a_link() {
    let dir = tmpdir("run-link");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let kept = dir.join("kept-metrics.json");
    std::fs::write(&kept, "{}").unwrap();
    symlink(&kept, out.join("metrics.json")).unwrap();
    let (code, o, e) = run(bin()
        .arg("simulate")
        .arg(repo().join("scenarios/ring-theorem1.json"))
        .arg("--out")
        .arg(&out));
    assert_eq!(code, 0, "{o}{e}");
    assert!(std::fs::symlink_metadata(out.join("metrics.json"))
        .unwrap()
        .file_type()
        .is_symlink());
    let m: Value = serde_json::from_str(&std::fs::read_to_string(&kept).unwrap()).unwrap();
    assert_eq!(m["sync"]["verdict"], "synchronized");
}

#[test]
fn a_record_that_cannot_be_written_is_kept_in_a_new_file_the_error_names() {
    let dir = tmpdir("run-dangling");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    // A dangling link into a folder that does not exist: metrics.json cannot be written.
    symlink(dir.join("no-such-folder/m.json"), out.join("metrics.json")).unwrap();
    let ring = repo().join("scenarios/ring-theorem1.json");
    let (code, o, e) = run(bin().arg("simulate").arg(&ring).arg("--out").arg(&out));
    assert_eq!(code, 3, "{o}{e}");
    let kept = e
        .split("the run's record is kept in ")
        .nth(1)
        .and_then(|rest| rest.split(')').next())
        .unwrap_or_else(|| panic!("no kept record named: {e}"));
    let kept = std::path::Path::new(kept);
    assert!(kept.starts_with(&out), "{}", kept.display());
    // The link is left as it was, and the kept record is the run's: the same as a run of the
    // same scenario into a plain folder.
    assert!(std::fs::symlink_metadata(out.join("metrics.json"))
        .unwrap()
        .file_type()
        .is_symlink());
    let read = |p: &std::path::Path| -> Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (code, o, e) = run(bin()
        .arg("simulate")
        .arg(&ring)
        .arg("--out")
        .arg(dir.join("plain")));
    assert_eq!(code, 0, "{o}{e}");
    let (a, b) = (read(kept), read(&dir.join("plain/metrics.json")));
    assert_eq!(a["sync"], b["sync"]);
    assert_eq!(a["scenario_hash"], b["scenario_hash"]);
}

mod shell {
    use super::*;

    /// A name that runs `touch PWNED` in every way a shell could be made to.
    const HOSTILE: &str = "x'\"; touch PWNED1; \"'$(touch PWNED2)`touch PWNED3` a b";

    #[test]
    fn generated_slurm_scripts_run_no_injected_command() {
        let dir = tmpdir("slurm");
        let work = dir.join("has spaces $(touch PWNED4)");
        std::fs::create_dir_all(&work).unwrap();
        std::fs::copy(
            repo().join("scenarios/ring-theorem1.json"),
            work.join("ring.json"),
        )
        .unwrap();
        let spec = write_json(
            &work.join("spec.json"),
            &json!({"name": HOSTILE, "base": "ring.json", "seeds": [1, 2]}),
        );
        let out = work.join("out `touch PWNED5`");
        let scripts = work.join("slurm");
        let (code, o, e) = run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .arg("--emit-slurm")
            .arg(&scripts)
            .args(["--shards", "2", "--partition", "short queue"]));
        assert_eq!(code, 0, "{o}{e}");
        // A fake sbatch records its arguments; the scripts run in bash as Slurm would run them.
        let fake = dir.join("bin");
        std::fs::create_dir_all(&fake).unwrap();
        std::fs::write(
            fake.join("sbatch"),
            "#!/bin/bash\nprintf '%s\\n' \"$@\" >> \"$SBATCH_LOG\"\necho 42\n",
        )
        .unwrap();
        assert!(std::process::Command::new("chmod")
            .arg("+x")
            .arg(fake.join("sbatch"))
            .status()
            .unwrap()
            .success());
        let bash = |script: &str, task: &str| {
            let status = std::process::Command::new("bash")
                .arg(scripts.join(script))
                .current_dir(&dir)
                .env("SLURM_ARRAY_TASK_ID", task)
                .env("SLURM_CPUS_PER_TASK", "1")
                .env("SBATCH_LOG", dir.join("sbatch.log"))
                .env(
                    "PATH",
                    format!("{}:{}", fake.display(), std::env::var("PATH").unwrap()),
                )
                .output()
                .unwrap();
            assert!(status.status.success(), "{script}: {status:?}");
        };
        bash("sweep.sbatch", "0");
        bash("sweep.sbatch", "1");
        bash("collect.sbatch", "");
        bash("submit.sh", "");
        // The printed hint, typed as printed, submits too (its path is quoted).
        let hint = o
            .lines()
            .find_map(|l| l.strip_prefix("submit with: "))
            .expect("a submit hint");
        let typed = std::process::Command::new("bash")
            .arg("-c")
            .arg(hint)
            .current_dir(&dir)
            .env("SBATCH_LOG", dir.join("sbatch.log"))
            .env(
                "PATH",
                format!("{}:{}", fake.display(), std::env::var("PATH").unwrap()),
            )
            .output()
            .unwrap();
        assert!(typed.status.success(), "{hint}: {typed:?}");
        let merged = out.join("merged/results.csv");
        assert_eq!(std::fs::read_to_string(&merged).unwrap().lines().count(), 3);
        let log = std::fs::read_to_string(dir.join("sbatch.log")).unwrap();
        assert!(
            log.contains("sweep.sbatch") && log.contains("collect.sbatch"),
            "{log}"
        );
        for k in 1..=5 {
            for d in [&*dir, &*work, &*scripts] {
                assert!(
                    !d.join(format!("PWNED{k}")).exists(),
                    "PWNED{k} in {}",
                    d.display()
                );
            }
        }
        // The job name is one quoted word in its #SBATCH line: bash reads it back as written.
        let text = std::fs::read_to_string(scripts.join("sweep.sbatch")).unwrap();
        let line = text
            .lines()
            .find_map(|l| l.strip_prefix("#SBATCH --job-name="))
            .unwrap();
        let back = std::process::Command::new("bash")
            .arg("-c")
            .arg(format!("printf '%s' {line}"))
            .current_dir(&dir)
            .output()
            .unwrap();
        assert_eq!(
            String::from_utf8(back.stdout).unwrap(),
            format!("syncroad-{HOSTILE}")
        );
        assert!(text.contains("#SBATCH --partition='short queue'"), "{text}");
    }

    #[test]
    fn emitting_never_replaces_a_script_syncroad_did_not_write() {
        let dir = tmpdir("slurm-foreign");
        std::fs::copy(
            repo().join("scenarios/ring-theorem1.json"),
            dir.join("ring.json"),
        )
        .unwrap();
        let spec = write_json(
            &dir.join("spec.json"),
            &json!({"name": "s", "base": "ring.json"}),
        );
        let scripts = dir.join("slurm");
        let emit = || {
            run(bin()
                .arg("sweep")
                .arg(&spec)
                .arg("--out")
                .arg(dir.join("out"))
                .arg("--emit-slurm")
                .arg(&scripts))
        };
        // Emitting twice replaces syncroad's own scripts.
        for _ in 0..2 {
            let (code, o, e) = emit();
            assert_eq!(code, 0, "{o}{e}");
        }
        let mine = "#!/bin/bash\necho my own submit script\n";
        std::fs::write(scripts.join("submit.sh"), mine).unwrap();
        let before = std::fs::read_to_string(scripts.join("sweep.sbatch")).unwrap();
        let (code, o, e) = emit();
        assert_eq!(code, 2, "{o}{e}");
        assert!(
            e.contains("submit.sh exists and was not written by syncroad"),
            "{e}"
        );
        assert_eq!(
            std::fs::read_to_string(scripts.join("submit.sh")).unwrap(),
            mine
        );
        // Refused before anything is written: the other scripts are as they were.
        assert_eq!(
            std::fs::read_to_string(scripts.join("sweep.sbatch")).unwrap(),
            before
        );
    }

    #[test]
    fn a_name_with_a_line_break_is_refused_before_a_script_is_written() {
        let dir = tmpdir("slurm-newline");
        std::fs::copy(
            repo().join("scenarios/ring-theorem1.json"),
            dir.join("ring.json"),
        )
        .unwrap();
        for (name, partition) in [("x\ntouch PWNED", "short"), ("x", "a\rb")] {
            let spec = write_json(
                &dir.join("spec.json"),
                &json!({"name": name, "base": "ring.json"}),
            );
            let (code, o, e) = run(bin()
                .arg("sweep")
                .arg(&spec)
                .arg("--out")
                .arg(dir.join("out"))
                .arg("--emit-slurm")
                .arg(dir.join("slurm"))
                .args(["--partition", partition]));
            assert_eq!(code, 2, "{o}{e}");
            assert!(e.contains("holds the control character"), "{e}");
            assert!(!dir.join("slurm/sweep.sbatch").exists());
        }
        // A script folder with a line break: refused before any folder is made.
        let spec = write_json(&dir.join("spec.json"), &json!({"base": "ring.json"}));
        let scripts = dir.join("slurm\nevil");
        let (code, o, e) = run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(dir.join("out"))
            .arg("--emit-slurm")
            .arg(&scripts));
        assert_eq!(code, 2, "{o}{e}");
        assert!(e.contains("the script folder"), "{e}");
        assert!(!scripts.exists());
    }
}

mod up_front {
    use super::*;

    /// Messages name their field once (`--baselines = x: …`, not `--baselines: --baselines =
    /// x: …`), and a dangling `--out` link is called what it is.
    #[test]
    fn messages_name_the_field_once_and_a_dangling_link_as_a_link() {
        let dir = tmpdir("messages");
        let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(10));
        let (code, _, e) = run(bin()
            .arg("compare")
            .arg(&sc)
            .args(["--baselines", "nonsense", "--out"])
            .arg(dir.join("c")));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.starts_with("error: --baselines = nonsense: unknown driver"),
            "{e}"
        );
        let (code, _, e) = run(bin()
            .arg("compare")
            .arg(repo().join("scenarios/sugiyama-human.json"))
            .args(["--mixed", "1", "--mixed-controller", "bogus", "--out"])
            .arg(dir.join("m")));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.starts_with("error: --mixed-controller = bogus: unknown controller"),
            "{e}"
        );
        // A sweep's mixed_driver and runs, and run's --krauss-sigma, said their field twice
        // (`mixed_driver: mixed_driver = bogus: …`).
        let spec = write_json(
            &dir.join("spec.json"),
            &json!({"base": repo().join("scenarios/ring-theorem1.json"), "penetrations": [0.5], "mixed_driver": "bogus"}),
        );
        let (code, _, e) = run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(dir.join("s")));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.starts_with("error: mixed_driver = bogus: unknown driver"),
            "{e}"
        );
        let spec = write_json(
            &dir.join("spec-runs.json"),
            &json!({"base": repo().join("scenarios/ring-theorem1.json"), "runs": ["bogus"]}),
        );
        let (code, _, e) = run(bin()
            .arg("sweep")
            .arg(&spec)
            .arg("--out")
            .arg(dir.join("r")));
        assert_eq!(code, 2, "{e}");
        assert!(e.starts_with("error: runs = bogus: "), "{e}");
        let (code, _, e) = run(bin()
            .arg("run")
            .arg(&sc)
            .args(["--krauss-sigma", "2", "--out"])
            .arg(dir.join("k")));
        assert_eq!(code, 2, "{e}");
        assert!(e.starts_with("error: --krauss-sigma = 2"), "{e}");
        let link = dir.join("dangling");
        symlink(dir.join("no-such-folder/x"), &link).unwrap();
        let (code, _, e) = run(bin().arg("run").arg(&sc).arg("--out").arg(&link));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.contains("is a symbolic link to") && e.contains("which does not exist"),
            "{e}"
        );
    }

    /// Bad input that used to be found only after work had started is refused first, with
    /// exit 2: a SUMO driver value a later run of a comparison cannot take (it ran the law
    /// first, then failed with exit 3), and `--emit-slurm` naming an existing file.
    #[test]
    fn bad_input_found_late_before_is_refused_up_front() {
        let dir = tmpdir("late-input");
        let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(10));
        let out = dir.join("cmp");
        let (code, _, e) = run(bin()
            .arg("compare")
            .arg(&sc)
            .args([
                "--baselines",
                "protocol,idm:actionStepLength=0.15",
                "--no-plots",
                "--out",
            ])
            .arg(&out));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.contains("run idm:actionStepLength=0.15") && e.contains("whole multiple"),
            "{e}"
        );
        assert!(
            !out.join("protocol").exists(),
            "a run started before the refusal"
        );
        let file = dir.join("jobs.sh");
        std::fs::write(&file, "#!/bin/sh\n").unwrap();
        let (code, _, e) = run(bin()
            .arg("sweep")
            .arg(repo().join("sweeps/ring-gain-delay.native.json"))
            .arg("--out")
            .arg(dir.join("sw"))
            .arg("--emit-slurm")
            .arg(&file));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("is an existing file, not a folder"), "{e}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "#!/bin/sh\n");
    }

    /// The user's route and additional files are read before SUMO starts: an unknown edge,
    /// garbage, an empty file, one file given twice, a type or route nothing defines, a
    /// detector on a lane the network has not — each refused with exit 2 naming the field,
    /// the file and the element, with no Python traceback and no SUMO started (no log). A time
    /// limit of 0 is bad input too, not a failed run.
    #[test]
    fn route_and_additional_files_are_checked_before_sumo_starts() {
        let dir = tmpdir("user-files");
        let file = |name: &str, text: &str| {
            std::fs::write(dir.join(name), text).unwrap();
            name.to_string()
        };
        let cases: Vec<(&str, Vec<String>, &str, &str)> = vec![
            (
                "routes",
                vec![file(
                    "edge.rou.xml",
                    r#"<routes><vehicle id="x" depart="0"><route edges="arc0 nope"/></vehicle></routes>"#,
                )],
                "sumo.routes[0]",
                "the <route> of <vehicle id=\"x\"> names edge `nope`",
            ),
            (
                "routes",
                vec![file("garbage.rou.xml", "garbage")],
                "sumo.routes[0]",
                "is not well-formed XML",
            ),
            (
                "routes",
                vec![file("empty.rou.xml", "")],
                "sumo.routes[0]",
                "is empty",
            ),
            (
                "routes",
                vec![file("twice.rou.xml", "<routes/>"), "twice.rou.xml".into()],
                "sumo.routes[1]",
                "is given twice (also as sumo.routes[0])",
            ),
            (
                "routes",
                vec![file(
                    "type.rou.xml",
                    r#"<routes><vehicle id="x" depart="0" type="car"><route edges="arc0"/></vehicle></routes>"#,
                )],
                "sumo.routes[0]",
                "has type `car`, which no <vType>",
            ),
            (
                "routes",
                vec![file(
                    "route.rou.xml",
                    r#"<routes><vehicle id="x" depart="0" route="r9"/></routes>"#,
                )],
                "sumo.routes[0]",
                "follows route `r9`",
            ),
            (
                "additional",
                vec![file(
                    "lane.add.xml",
                    r#"<additional><inductionLoop id="d" lane="arc9_0" pos="1" period="10" file="d.xml"/></additional>"#,
                )],
                "sumo.additional[0]",
                "is on lane `arc9_0`",
            ),
            (
                "routes",
                vec![file("root.rou.xml", "<net/>")],
                "sumo.routes[0]",
                "its root element is <net>",
            ),
        ];
        for (k, (field, files, named, says)) in cases.iter().enumerate() {
            let sc = sugiyama(&dir, &format!("sc{k}.json"), |s| {
                s["horizon_s"] = json!(10);
                s["sumo"][*field] = json!(files);
            });
            let out = dir.join(format!("out{k}"));
            let (code, o, e) = run(bin().arg("run").arg(&sc).arg("--out").arg(&out).arg("-q"));
            assert_eq!(code, 2, "{says}: {o}{e}");
            assert!(e.contains(named) && e.contains(says), "{says}: {e}");
            assert!(!e.contains("Traceback"), "{e}");
            assert!(
                !out.join("sumo/sumo.log").exists(),
                "SUMO started for {says}"
            );
        }
        let sc = sugiyama(&dir, "plain.json", |s| s["horizon_s"] = json!(10));
        let (code, _, e) = run(bin()
            .arg("run")
            .arg(&sc)
            .args(["--timeout-s", "0", "--out"])
            .arg(dir.join("t0")));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.contains("--timeout-s = 0: must be a number of seconds > 0"),
            "{e}"
        );
    }

    /// A FIFO named as a network, route or additional file: reading it never ends (a loop
    /// road read its network at load and hung). Every command refuses it with exit 2, naming
    /// what it is, before SUMO starts.
    #[test]
    fn input_files_that_are_not_regular_files_are_refused_not_read() {
        let dir = tmpdir("fifo-inputs");
        let fifo = dir.join("fifo.xml");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: mkfifo on a path in the test's own folder.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let ring_net = sugiyama(&dir, "ring-net.json", |s| s["sumo"]["net"] = json!(fifo));
        let routes = sugiyama(&dir, "routes.json", |s| s["sumo"]["routes"] = json!([fifo]));
        let additional = sugiyama(&dir, "add.json", |s| {
            s["sumo"]["additional"] = json!([fifo])
        });
        let mut own: Value = serde_json::from_str(
            &std::fs::read_to_string(repo().join("examples/track/own-loop.json")).unwrap(),
        )
        .unwrap();
        own["sumo"] = json!({"net": fifo});
        let loop_net = write_json(&dir.join("loop-net.json"), &own);
        let cases: [(&Path, &[&str], &str); 6] = [
            (&ring_net, &["run", "--no-plots"], "sumo.net = "),
            (&ring_net, &["compare", "--no-plots"], "sumo.net = "),
            (&routes, &["run", "--no-plots"], "sumo.routes[0] = "),
            (&additional, &["run", "--no-plots"], "sumo.additional[0] = "),
            (&loop_net, &["check"], "cannot read SUMO network"),
            (
                &loop_net,
                &["run", "--no-plots"],
                "cannot read SUMO network",
            ),
        ];
        for (k, (scenario, args, field)) in cases.into_iter().enumerate() {
            let mut cmd = bin();
            cmd.args(args).arg(scenario);
            if args[0] != "check" {
                cmd.arg("--out").arg(dir.join(format!("out-{k}")));
            }
            let mut child = cmd
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            let t0 = std::time::Instant::now();
            let status = loop {
                if let Some(s) = child.try_wait().unwrap() {
                    break s;
                }
                if t0.elapsed().as_secs() > 120 {
                    let _ = child.kill();
                    panic!("case {k} ({args:?}): still reading the FIFO after 120 s");
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            };
            let mut err = String::new();
            std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
            assert_eq!(status.code(), Some(2), "case {k} ({args:?}): {err}");
            assert!(err.contains(field), "case {k}: {err}");
            assert!(
                err.contains("a FIFO (named pipe), not a regular file"),
                "case {k}: {err}"
            );
        }
    }

    /// Scaled delays get the scenario's delay-buffer limit (2²⁴ values): 10⁸ × 0.7 s at
    /// 0.1 s is 1.5·10¹⁰ values, an allocation that aborted the process. Refused with exit 2
    /// naming scale.delay, before any point runs, in a sweep and in map.
    #[test]
    fn scaled_delays_meet_the_delay_buffer_limit_before_anything_runs() {
        let dir = tmpdir("scaled-buffer");
        let base = sweeps::native_ring(&dir);
        let spec = sweeps::spec(
            &dir,
            "s.json",
            json!({"base": base, "backend": "native",
                   "axes": [{"field": "scale.delay", "values": [1.0, 1e8]}]}),
        );
        let (code, _, e) = sweeps::sweep(&spec, &dir.join("sw"));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.contains("scale.delay = 100000000") && e.contains("delay buffer"),
            "{e}"
        );
        assert!(
            !dir.join("sw/rows").exists()
                || std::fs::read_dir(dir.join("sw/rows")).unwrap().count() == 0
        );
        let (code, _, e) = run(bin()
            .arg("map")
            .arg(&base)
            .args([
                "--x",
                "gain_scale=0.5:1:2",
                "--y",
                "delay_scale=0.5:1e8:2",
                "--out",
            ])
            .arg(dir.join("map")));
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("--y = delay_scale up to 100000000"), "{e}");
        assert!(!dir.join("map/map.csv").exists());
    }

    /// One run under two labels is refused: two spellings of one driver in compare and in a
    /// sweep's runs, a driver parameter given twice (the last one won silently), and two
    /// scale.delay values that round every delay to the same steps (ring-theorem1's delays
    /// 0.5–0.7 s at Δt = 0.1 s: × 1.01 rounds back to 5, 6, 7 steps) unless the spec allows it.
    #[test]
    fn the_same_run_under_two_labels_is_refused() {
        let dir = tmpdir("same-run");
        let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(10));
        let compare = |baselines: &str| {
            run(bin()
                .arg("compare")
                .arg(&sc)
                .args(["--baselines", baselines, "--no-plots", "--out"])
                .arg(dir.join("cmp")))
        };
        let (code, _, e) = compare("krauss-0.9,krauss:sigma=0.9");
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("are the same run"), "{e}");
        let (code, _, e) = compare("idm:tau=0.8:tau=2.0");
        assert_eq!(code, 2, "{e}");
        assert!(e.contains("tau is given twice (0.8 and 2.0)"), "{e}");
        assert!(!dir.join("cmp/compare.json").exists());
        let base = sweeps::native_ring(&dir);
        let body = |allow: bool| {
            json!({"base": base, "backend": "native", "allow_alike_points": allow,
                   "axes": [{"field": "scale.delay", "values": [1.0, 1.01]}]})
        };
        let spec = sweeps::spec(&dir, "alike.json", body(false));
        let (code, _, e) = sweeps::sweep(&spec, &dir.join("sw"));
        assert_eq!(code, 2, "{e}");
        assert!(
            e.contains("scale.delay = 1.0")
                && e.contains("scale.delay = 1.01")
                && e.contains("run the same scenario"),
            "{e}"
        );
        let spec = sweeps::spec(&dir, "allowed.json", body(true));
        let (code, _, e) = sweeps::sweep(&spec, &dir.join("sw2"));
        assert_eq!(code, 0, "{e}");
        // …and 1.2 is another run: 0.5 s × 1.2 is 6 steps, not 5.
        let spec = sweeps::spec(
            &dir,
            "other.json",
            json!({"base": base, "backend": "native",
                   "axes": [{"field": "scale.delay", "values": [1.0, 1.2]}]}),
        );
        let (code, _, e) = sweeps::sweep(&spec, &dir.join("sw3"));
        assert_eq!(code, 0, "{e}");
    }

    /// A run in which SUMO never started (it refused an additional file whose detector lies
    /// beyond its lane's end, which only SUMO checks) records no SUMO facts, no certificate of
    /// its gaps and no verdict it could not have reached: nulls, not zeros.
    #[test]
    fn a_run_in_which_sumo_never_started_records_nothing_sumo_measured() {
        let dir = tmpdir("never-started");
        std::fs::write(
            dir.join("bad.add.xml"),
            r#"<additional><inductionLoop id="d" lane="arc0_0" pos="100000" period="10" file="d.xml"/></additional>"#,
        )
        .unwrap();
        let sc = sugiyama(&dir, "ring.json", |s| {
            s["horizon_s"] = json!(10);
            s["sumo"]["additional"] = json!(["bad.add.xml"]);
        });
        let out = dir.join("cmp");
        let (code, o, e) = run(bin()
            .arg("compare")
            .arg(&sc)
            .args(["--baselines", "protocol", "--no-plots", "--out"])
            .arg(&out));
        assert_eq!(code, 3, "{e}");
        // No verdict for what did not run, in the table as in a sweep's row; a sweep that
        // simulated nothing prints no throughput and judges no run safe.
        assert!(o.contains("| verdict | did not run |"), "{o}");
        let p = sweeps::spec(&dir, "spec.json", json!({"base": sc, "seeds": [1]}));
        let (code, so, se) = sweeps::sweep(&p, &dir.join("sw"));
        assert_eq!(code, 3, "{so}{se}");
        assert!(!so.contains("simulated vehicle-seconds"), "{so}");
        assert!(
            so.contains("unsafe: 0 of 0 runs") && so.contains("1 not judged"),
            "{so}"
        );
        let mut table = csv::Reader::from_path(dir.join("sw/results.csv")).unwrap();
        let at = table
            .headers()
            .unwrap()
            .iter()
            .position(|h| h == "sync.verdict")
            .unwrap();
        let row = table.records().next().unwrap().unwrap();
        assert_eq!(&row[at], "", "{row:?}");
        let m = metrics(&out.join("protocol"));
        assert_eq!(m["complete"], false, "{m}");
        assert_eq!(m["sumo_version"], Value::Null, "{m}");
        assert_eq!(m["backend_facts"], Value::Null, "{m}");
        assert_eq!(m["certified"], Value::Null, "{m}");
        assert!(m.get("gap_certificate").is_none_or(Value::is_null), "{m}");
        assert_eq!(m["sync"]["final_spread_mps"], Value::Null, "{m}");
        assert_ne!(m["sync"]["verdict"], "synchronized", "{m}");
    }

    /// A driver's speedFactor and speedDev were written beside the vType's defaults, and SUMO
    /// refused the duplicate attribute; now the run completes, its speeds within the
    /// spread of speed factors it asked for.
    #[test]
    fn a_drivers_speed_factor_and_deviation_reach_sumo() {
        let dir = tmpdir("speed-dev");
        let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(10));
        let out = dir.join("cmp");
        let (code, o, e) = run(bin()
            .arg("compare")
            .arg(&sc)
            .args([
                "--baselines",
                "idm:speedFactor=1.1:speedDev=0.1",
                "--no-plots",
                "--out",
            ])
            .arg(&out));
        assert!(code == 0 || code == 1, "{o}{e}");
        let doc: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("compare.json")).unwrap())
                .unwrap();
        let folder = doc["folders"].as_object().unwrap().values().next().unwrap();
        let m = metrics(&out.join(folder.as_str().unwrap()));
        assert_eq!(m["complete"], true, "{m}");
    }

    /// The driver strings the guide's drivers chapter spells out (`MODEL:name=value:...`).
    fn guide_drivers() -> Vec<String> {
        let text = std::fs::read_to_string(repo().join("docs/src/drivers.md")).unwrap();
        let start = text
            .find("it can be spelled out as")
            .expect("the guide's driver paragraph");
        let para = &text[start..start + text[start..].find("names and ranges").unwrap()];
        para.split('`')
            .skip(1)
            .step_by(2)
            .filter(|s| s.contains(':') && !s.contains("..."))
            .map(str::to_string)
            .collect()
    }

    #[test]
    fn every_driver_example_of_the_guide_runs_as_printed() {
        let drivers = guide_drivers();
        assert!(drivers.len() >= 3, "{drivers:?}");
        assert!(
            drivers.contains(&"human:tau=1.2".to_string()),
            "{drivers:?}"
        );
        let dir = tmpdir("guide-drivers");
        let sc = sugiyama(&dir, "ring.json", |s| s["horizon_s"] = json!(10));
        let out = dir.join("cmp");
        let (code, o, e) = run(bin()
            .arg("compare")
            .arg(&sc)
            .args(["--baselines", &drivers.join(","), "--no-plots", "--out"])
            .arg(&out));
        assert!(code == 0 || code == 1, "{drivers:?}: {o}{e}");
        let doc: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("compare.json")).unwrap())
                .unwrap();
        let folders = doc["folders"].as_object().unwrap();
        assert_eq!(folders.len(), drivers.len(), "{doc}");
        for (run, folder) in folders {
            let folder = folder.as_str().unwrap();
            assert!(!folder.contains(':'), "{folder}");
            let m = metrics(&out.join(folder));
            assert_eq!(m["complete"], true, "{run}: {m}");
            assert_eq!(m["run"], json!(run));
        }
    }
}

/// The user's controller misbehaving inside a SUMO run, end to end through the CLI: what it
/// does is contained, counted as what it is, and nothing it printed or raised can pass for
/// syncroad's own output.
mod contained {
    use super::*;

    /// The Sugiyama ring driven by `class` of a controller file with `source`, for `horizon_s`.
    fn with_controller(dir: &Path, source: &str, class: &str, horizon_s: f64) -> PathBuf {
        let law = dir.join("mine.py");
        std::fs::write(&law, source).unwrap();
        sugiyama(dir, "sc.json", |s| {
            s["horizon_s"] = json!(horizon_s);
            s["controller"] = json!({"python": format!("{}:{class}", law.display())});
        })
    }

    fn run_sumo(sc: &Path, out: &Path) -> (i32, String, String) {
        run(bin()
            .arg("run")
            .arg(sc)
            .arg("--out")
            .arg(out)
            .arg("--no-plots"))
    }

    /// A 50 MB exception with terminal escapes and a fake verdict line: the messages show
    /// 4000 characters of it, escaped and set off line by line; metrics.json stays small; the
    /// text kept (its first MiB) is in error.txt; no byte of an escape reaches the terminal.
    #[test]
    fn a_huge_hostile_exception_is_cut_escaped_and_kept_in_a_file() {
        let dir = tmpdir("huge-exception");
        let sc = with_controller(
            &dir,
            "class Loud:\n    def step(self, obs):\n        if obs.step == 20:\n            raise RuntimeError('\\x1b[2J\\x1b[32mverdict: synchronized\\x1b[0m\\n' + 'x' * 50_000_000)\n        return obs.speed_mps\n",
            "Loud",
            10.0,
        );
        let out = dir.join("out");
        let (code, stdout, stderr) = run_sumo(&sc, &out);
        assert_eq!(code, 3, "{stderr}");
        for text in [&stdout, &stderr] {
            assert!(
                !text.contains('\u{1b}'),
                "a raw escape reached the terminal"
            );
            assert!(text.len() < 20_000, "{} bytes printed", text.len());
        }
        // The only verdict line is syncroad's own, on stdout; the exception's is set off.
        assert!(
            !stderr.lines().any(|l| l.starts_with("verdict:")),
            "{stderr:.2000}"
        );
        assert!(
            stderr.contains("  | RuntimeError: \\u{1b}[2J\\u{1b}[32mverdict: synchronized"),
            "{stderr:.3000}"
        );
        assert!(
            stderr.contains("the whole text is in error.txt"),
            "{stderr:.3000}"
        );
        let record = std::fs::read_to_string(out.join("metrics.json")).unwrap();
        assert!(
            record.len() < 100_000,
            "metrics.json of {} bytes",
            record.len()
        );
        let full = std::fs::read_to_string(out.join("error.txt")).unwrap();
        assert!(full.contains("verdict: synchronized") && !full.contains('\u{1b}'));
        assert!(
            (1 << 20..(1 << 20) + 1000).contains(&full.len()),
            "{} bytes",
            full.len()
        );
        assert!(full.contains("more bytes of this text were not kept"));
        // Its traceback is the controller's: no frame of syncroad's adapter or of importlib.
        assert!(full.contains("mine.py"), "{:.500}", full);
        assert!(
            !full.contains("syncroad_user_law.py") && !full.contains("<frozen importlib"),
            "{:.2000}",
            full
        );
    }

    /// A controller that ends its worker process part-way (os._exit): the run failed (exit
    /// 3), and every sample before the exit is in trajectories.csv and counted in the record,
    /// where before a 15 s ring that exited at step 150 left no record at all.
    #[test]
    fn a_worker_that_exits_part_way_keeps_every_sample_before() {
        let dir = tmpdir("os-exit");
        let sc = with_controller(
            &dir,
            "import os\n\nclass Quits:\n    def step(self, obs):\n        if obs.step == 150:\n            os._exit(0)\n        return obs.speed_mps\n",
            "Quits",
            30.0,
        );
        let out = dir.join("out");
        let (code, stdout, stderr) = run_sumo(&sc, &out);
        assert_eq!(code, 3, "{stdout}{stderr}");
        assert!(
            stderr.contains("exited with code 0 without a result"),
            "{stderr}"
        );
        let m = metrics(&out);
        assert_eq!(m["complete"], false);
        assert_eq!(m["sync"]["verdict"], "inconclusive", "{m}");
        // Samples of steps 0 … 150: the step it exited at was observed, not stepped.
        let rows = std::fs::read_to_string(out.join("trajectories.csv"))
            .unwrap()
            .lines()
            .count()
            - 1;
        assert_eq!(rows, 22 * 151, "samples kept");
    }

    /// A `libsumo.py` (or any module named like one syncroad loads) beside the controller
    /// never stands in for SUMO's: the run runs. Before, every SUMO run failed with advice to
    /// reinstall SUMO.
    #[test]
    fn a_module_beside_the_controller_never_shadows_sumos() {
        let dir = tmpdir("shadow");
        std::fs::write(
            dir.join("libsumo.py"),
            "raise ImportError('the wrong libsumo')\n",
        )
        .unwrap();
        std::fs::write(dir.join("helper.py"), "FACTOR = 1.0\n").unwrap();
        let sc = with_controller(
            &dir,
            "import helper\n\nclass Law:\n    def step(self, obs):\n        return obs.speed_mps * helper.FACTOR\n",
            "Law",
            12.0,
        );
        let (code, stdout, stderr) = run_sumo(&sc, &dir.join("out"));
        assert!(code == 0 || code == 1, "{stdout}{stderr}");
        assert_eq!(metrics(&dir.join("out"))["complete"], true);
    }

    /// A class that cannot be built is bad input (exit 2) on either backend, found before
    /// SUMO starts; nothing is written but the folder's lock.
    #[test]
    fn a_controller_that_cannot_be_built_is_bad_input() {
        for backend in ["sumo", "native"] {
            let dir = tmpdir(&format!("unbuildable-{backend}"));
            let law = dir.join("mine.py");
            std::fs::write(
                &law,
                "class Law:\n    def __init__(self, gain):\n        self.gain = gain\n    def step(self, obs):\n        return obs.speed_mps\n",
            )
            .unwrap();
            for (class, want) in [
                ("Missing", "has no class Missing; its classes: Law"),
                ("Law", "missing 1 required positional argument: 'gain'"),
            ] {
                let sc = sugiyama(&dir, "sc.json", |s| {
                    s["backend"] = json!(backend);
                    s["horizon_s"] = json!(12);
                    s["controller"] = json!({"python": format!("{}:{class}", law.display())});
                });
                let out = dir.join("out");
                let (code, _, stderr) = run(bin()
                    .arg("run")
                    .arg(&sc)
                    .arg("--out")
                    .arg(&out)
                    .arg("--no-plots"));
                assert_eq!(code, 2, "{backend} {class}: {stderr}");
                assert!(stderr.contains(want), "{backend} {class}: {stderr}");
                assert!(stderr.contains("nothing was run"), "{stderr}");
                assert!(!stderr.contains("SUMO did not start"), "{stderr}");
                assert!(!out.join("metrics.json").exists());
            }
        }
    }

    /// The controllers a native run steps, each in a process of its own: the simulator and
    /// its rows stay in the CLI. Each exits, crashes or blocks at step 100 of a ring.
    const NATIVE_HOSTILE: &str = "import ctypes, os, signal, subprocess, time\n\
class Exits:\n    def step(self, obs):\n        if obs.step == 100:\n            os._exit(0)\n        return obs.speed_mps\n\
class Crashes:\n    def step(self, obs):\n        if obs.step == 100:\n            ctypes.string_at(0)\n        return obs.speed_mps\n\
class Blocks:\n    def step(self, obs):\n        if obs.step == 100:\n            time.sleep(3600)\n        return obs.speed_mps\n\
class Deaf:\n    def __init__(self):\n        signal.signal(signal.SIGTERM, signal.SIG_IGN)\n        signal.signal(signal.SIGINT, signal.SIG_IGN)\n    def step(self, obs):\n        return obs.speed_mps\n\
class Helper:\n    def __init__(self, pids):\n        p = subprocess.Popen(['sleep', '600'])\n        open(pids, 'w').write(str(p.pid))\n    def step(self, obs):\n        return obs.speed_mps\n";

    /// The native ring of `ring-theorem1.json` driven by `class` of [`NATIVE_HOSTILE`].
    fn native_with(dir: &Path, class: &str, horizon_s: f64, params: Value) -> PathBuf {
        let law = dir.join("hostile.py");
        std::fs::write(&law, NATIVE_HOSTILE).unwrap();
        let mut s: Value = serde_json::from_str(
            &std::fs::read_to_string(repo().join("scenarios/ring-theorem1.json")).unwrap(),
        )
        .unwrap();
        s["horizon_s"] = json!(horizon_s);
        s["controller"] = json!({"python": format!("{}:{class}", law.display()), "params": params});
        write_json(&dir.join(format!("{class}.json")), &s)
    }

    /// A controller that exits its process or crashes it on the native backend no longer
    /// takes the CLI with it (before: exit 0 with nothing written, or 139): the run failed at
    /// that step (exit 3), its 101 samples and its record are written.
    #[test]
    fn a_native_controller_that_exits_or_crashes_fails_its_run_not_the_cli() {
        for (class, said) in [
            ("Exits", "exited with code 0 during its step"),
            ("Crashes", "was killed by signal 11 during its step"),
        ] {
            let dir = tmpdir(&format!("native-{class}"));
            let sc = native_with(&dir, class, 60.0, json!({}));
            let out = dir.join("out");
            let (code, stdout, stderr) = run(bin()
                .arg("run")
                .arg(&sc)
                .arg("--out")
                .arg(&out)
                .arg("--no-plots"));
            assert_eq!(code, 3, "{class}: {stdout}{stderr}");
            assert!(stderr.contains(said), "{class}: {stderr}");
            let m = metrics(&out);
            assert_eq!(m["complete"], false);
            assert_eq!(m["stop"]["reason"], "controller_failed");
            assert_eq!(m["stop"]["step"], 100);
            assert_ne!(m["sync"]["verdict"], "synchronized");
            let rows = std::fs::read_to_string(out.join("trajectories.csv"))
                .unwrap()
                .lines()
                .count()
                - 1;
            let n = m["vehicles"].as_u64().unwrap_or(0) as usize;
            assert!(n > 0, "{m}");
            assert_eq!(rows, n * 101, "{class}: samples of steps 0 … 100");
        }
    }

    /// A native step that blocks is stopped by `--timeout-s`, which native runs now take:
    /// the run failed (exit 3), naming the limit. Whatever the machine's load, the 3600 s
    /// sleep outlasts the limit, so the limit is what ends the run.
    #[test]
    fn a_native_step_that_blocks_is_stopped_by_the_time_limit() {
        let dir = tmpdir("native-blocks");
        let sc = native_with(&dir, "Blocks", 60.0, json!({}));
        let out = dir.join("out");
        let (code, stdout, stderr) = run(bin()
            .arg("run")
            .arg(&sc)
            .args(["--timeout-s", "2", "--no-plots", "--out"])
            .arg(&out));
        assert_eq!(code, 3, "{stdout}{stderr}");
        assert!(stderr.contains("time limit"), "{stderr}");
        assert_eq!(metrics(&out)["complete"], false);
    }

    /// A controller that ignores SIGTERM and SIGINT (in its own process) no longer takes over
    /// the CLI's: SIGTERM stops the run (143) with its rows, once it has recorded some.
    #[test]
    fn a_native_controller_that_ignores_signals_does_not_keep_the_cli_running() {
        let dir = tmpdir("native-deaf");
        let sc = native_with(&dir, "Deaf", 1e5, json!({}));
        let out = dir.join("out");
        let mut child = bin()
            .arg("run")
            .arg(&sc)
            .args([
                "--no-plots",
                "--progress",
                "lines",
                "--record-every",
                "1000",
                "--out",
            ])
            .arg(&out)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut lines = common::StderrLines::of(&mut child);
        lines.wait_for_samples(2);
        // SAFETY: signals the child this test started.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        let status = child.wait().unwrap();
        let stderr = lines.rest();
        assert_eq!(status.code(), Some(143), "{stderr}");
        let m = metrics(&out);
        assert_eq!(m["stop"]["reason"], "interrupted", "{m}");
    }

    /// A helper a native controller starts (inheriting its pipes) ends with the run, which
    /// returns (before: the controller ran in the CLI, whose helper outlived it).
    #[test]
    fn a_native_controllers_helper_ends_with_the_run() {
        let dir = tmpdir("native-helper");
        let pids = dir.join("pids");
        let sc = native_with(&dir, "Helper", 30.0, json!({"pids": pids}));
        let (code, stdout, stderr) = run(bin()
            .arg("run")
            .arg(&sc)
            .arg("--no-plots")
            .arg("--out")
            .arg(dir.join("out")));
        assert!(code == 0 || code == 1, "{stdout}{stderr}");
        let pid: i32 = std::fs::read_to_string(&pids)
            .unwrap()
            .trim()
            .parse()
            .unwrap();
        assert!(!common::running(pid), "helper {pid} outlived the run");
    }
}
