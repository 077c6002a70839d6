//! Tests with real SUMO (libsumo 1.28.0 from the project's virtualenv: run
//! `bash python-host/bootstrap.sh` first). Every run goes through a real worker process.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use approx::assert_relative_eq;
use syncroad_control::native::{simulate, NativeOptions};
use syncroad_control::{Scenario, SumoDriver};
use syncroad_sumo::{
    load_road, run_scenario, PrepareError, Prepared, RunOptions, SupervisorError, WorkerCommand,
};

/// A rows hook that calls `act` once, when the run has recorded at least `min` samples: tests
/// act on what the run has done, never after a guessed delay.
fn once_recorded(
    min: usize,
    act: impl Fn(&syncroad_sumo::RowsProgress) + Send + Sync + 'static,
) -> syncroad_sumo::RowsHook {
    let done = AtomicBool::new(false);
    Arc::new(move |p: &syncroad_sumo::RowsProgress| {
        if p.records >= min && !done.swap(true, Ordering::SeqCst) {
            act(p);
        }
    })
}

fn nets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../sumo-nets")
        .canonicalize()
        .unwrap()
}

fn work(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn opts(name: &str) -> RunOptions {
    RunOptions::new(
        work(name),
        WorkerCommand::binary(env!("CARGO_BIN_EXE_syncroad-sumo-worker")),
    )
}

/// A Sugiyama-ring scenario with delayed drivers (Theorem 1 holds: α_j d_j^+ < 1/2).
fn ring_scenario(vehicles: usize, horizon_s: f64, net: &Path, seed: u64) -> Scenario {
    ring_scenario_with(vehicles, horizon_s, net, seed, 8.0, 30.0)
}

fn ring_scenario_with(
    vehicles: usize,
    horizon_s: f64,
    net: &Path,
    seed: u64,
    speed_mps: f64,
    max_speed_mps: f64,
) -> Scenario {
    let json = format!(
        r#"{{
        "name": "sumo-ring-test", "backend": "sumo", "seed": {seed}, "step_s": 0.1,
        "horizon_s": {horizon_s}, "vehicles": {vehicles},
        "road": {{"type": "ring", "length_m": 230}},
        "model": {{"type": "delayed_driver",
                   "graph": {{"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1}},
                   "delay_s": 0.5}},
        "initial": {{"speed_mps": {speed_mps}, "perturbation": {{"speed_mps": 1.5}}}},
        "sumo": {{"net": "{}", "max_speed_mps": {max_speed_mps}}}
    }}"#,
        net.display()
    );
    Scenario::from_json(&json).expect("valid scenario")
}

mod rejected_before_sumo_starts {
    use super::*;

    #[test]
    fn missing_net_file() {
        let sc = ring_scenario(22, 10.0, Path::new("/nonexistent/ring.net.xml"), 1);
        let err = run_scenario(&sc, &opts("missing-net")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "sumo.net = /nonexistent/ring.net.xml: file not found (checked before starting SUMO)"
        );
    }

    #[test]
    fn overfull_ring() {
        let sc = ring_scenario(31, 10.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let err = run_scenario(&sc, &opts("overfull")).unwrap_err();
        assert!(matches!(err, PrepareError::Layout(_)), "{err}");
        let msg = err.to_string();
        assert!(
            msg.contains(
                "31 vehicles × (length 5 m + minGap 2.5 m) = 232.50 m exceed its length 230.3592 m"
            ),
            "{msg}"
        );
    }

    #[test]
    fn step_and_seed_sumo_cannot_take() {
        let net = nets().join("sugiyama-ring.net.xml");
        let sc = ring_scenario(22, 10.0, &net, 4_000_000_000);
        let err = run_scenario(&sc, &opts("big-seed")).unwrap_err();
        assert_eq!(
            err.to_string(),
            "seed = 4000000000: SUMO's --seed takes 0 ..= 2147483647"
        );
    }

    #[test]
    fn stochastic_humans_on_a_straight_road() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/straight-chandler.json"),
        )
        .unwrap();
        let mut file: serde_json::Value = serde_json::from_str(&text).unwrap();
        file["sumo"] = serde_json::json!({"net": nets().join("straight-20km.net.xml")});
        let sc = Scenario::from_json(&file.to_string()).unwrap();
        let mut o = opts("noisy-straight");
        o.drivers = vec![Some(SumoDriver::parse("d", "human-noisy").unwrap()); sc.vehicles()];
        let err = run_scenario(&sc, &o).unwrap_err();
        assert!(matches!(err, PrepareError::HumansNeedRing { .. }), "{err}");
        assert!(
            err.to_string().starts_with(
                "the stochastic human drivers (human-noisy, flow-idm-noise, noisy-idm:...) drive on a ring"
            ),
            "{err}"
        );
    }

    #[test]
    fn malformed_net_is_caught_by_the_parser() {
        let dir = work("malformed-parse");
        let bad = dir.join("bad.net.xml");
        std::fs::write(&bad, "<net><edge id='x'>").unwrap();
        let sc = ring_scenario(22, 10.0, &bad, 1);
        let err = run_scenario(&sc, &opts("malformed-parse-run")).unwrap_err();
        assert!(
            err.to_string().starts_with(&format!(
                "SUMO network {} is not well-formed XML",
                bad.display()
            )),
            "{err}"
        );
    }
}

mod supervision {
    use super::*;

    /// libsumo segfaults on `<net><edge id='x'>`; sent straight to a worker (bypassing the
    /// pre-start checks) the crash is contained and reported, and this process goes on.
    #[test]
    fn malformed_net_crash_is_contained() {
        let dir = work("malformed-crash");
        let bad = dir.join("bad.net.xml");
        std::fs::write(&bad, "<net><edge id='x'>").unwrap();
        let sc = ring_scenario(22, 10.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let o = opts("malformed-crash-run");
        let mut p = Prepared::new(&sc, &load_road(&sc).unwrap(), &o).unwrap();
        p.request_mut().layout.road.path = bad;
        let run = p.run().worker;
        let err = run.result.unwrap_err();
        eprintln!("malformed net in the worker: {err}");
        match &err {
            SupervisorError::Crashed { name, records, .. } => {
                assert_eq!(*name, "SIGSEGV");
                assert_eq!(*records, 0);
            }
            // A SUMO build that reports the error instead of crashing is fine too.
            SupervisorError::Worker(m) => assert!(m.contains("SUMO did not start"), "{m}"),
            other => panic!("unexpected: {other}"),
        }
        assert!(run.start.is_none());
    }

    /// A start failure SUMO reports itself (here: a routes file that vanished) comes back with
    /// the Python exception and the tail of SUMO's log.
    #[test]
    fn start_failure_reports_the_sumo_log() {
        let sc = ring_scenario(22, 10.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let o = opts("start-failure");
        let mut p = Prepared::new(&sc, &load_road(&sc).unwrap(), &o).unwrap();
        p.request_mut().routes_file = o.work_dir.join("vanished.rou.xml");
        let run = p.run().worker;
        let msg = run.result.unwrap_err().to_string();
        assert!(
            msg.starts_with("SUMO did not start: libsumo.start refused the run: "),
            "{msg}"
        );
        assert!(msg.contains("vanished.rou.xml"), "{msg}");
        // SUMO's own words, not the binding's traceback.
        assert!(!msg.contains("Traceback"), "{msg}");
    }

    /// A run stopped by its time limit keeps every row it received and says it is incomplete.
    /// The limit counts from the request (the worker's Python and SUMO start inside it), so on a
    /// loaded machine a short limit may end the run before its first chunk of rows arrives: a
    /// limit that let fewer than 11 rows through is doubled and the run made again, so what is
    /// checked is the rows a time limit keeps, never how fast this machine is at the moment.
    #[test]
    fn timeout_keeps_rows_and_marks_incomplete() {
        let sc = ring_scenario(22, 100_000.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let mut limit_s = 3;
        let (run, limit_s) = loop {
            let mut o = opts(&format!("timeout-{limit_s}"));
            o.timeout = Some(Duration::from_secs(limit_s));
            let run = run_scenario(&sc, &o).unwrap();
            let err = run.failure().unwrap();
            // Whatever the machine's load, a 100 000 s run ends on its time limit, and the
            // error counts exactly the rows received.
            match err {
                SupervisorError::Timeout { seconds, records } => {
                    assert_eq!(*seconds, limit_s as f64);
                    assert_eq!(*records, run.worker.rows.len());
                }
                other => panic!("unexpected: {other}"),
            }
            if run.worker.rows.len() > 10 || limit_s >= 192 {
                break (run, limit_s);
            }
            limit_s *= 2;
        };
        assert!(
            run.worker.rows.len() > 10,
            "rows streamed before the timeout of {limit_s} s"
        );
        let err = run.failure().unwrap();
        assert!(
            err.to_string().starts_with(&format!(
                "the SUMO run exceeded its time limit of {limit_s} s"
            )),
            "{err}"
        );
        // The run's output keeps every row received and says it is incomplete.
        let out = run.output(&sc);
        assert!(!out.stop.is_complete(), "{:?}", out.stop);
        assert_eq!(out.trajectory.len(), run.worker.rows.len());
        assert_eq!(out.trajectory.speeds_mps.len(), 22 * run.worker.rows.len());
    }

    /// A worker that dies mid-run (here SIGABRT, as libsumo's own assertions would raise)
    /// becomes a Crashed error; the rows streamed before the crash are kept.
    #[test]
    fn crash_mid_run_keeps_the_rows() {
        let sc = ring_scenario(22, 100_000.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let mut o = opts("crash-mid-run");
        // Once rows have arrived (not after a guessed delay: a loaded machine may take seconds
        // to start Python).
        o.on_rows = Some(once_recorded(20, |p| {
            // SAFETY: signals our own child worker.
            unsafe { libc::kill(p.pid as i32, libc::SIGABRT) };
        }));
        let run = run_scenario(&sc, &o).unwrap();
        let err = run.failure().unwrap();
        match err {
            SupervisorError::Crashed { name, records, .. } => {
                assert_eq!(*name, "SIGABRT");
                assert_eq!(*records, run.worker.rows.len());
            }
            other => panic!("unexpected: {other}"),
        }
        assert!(
            run.worker.rows.len() >= 20,
            "rows streamed before the crash"
        );
        assert!(
            err.to_string().contains("crashed with signal 6 (SIGABRT)"),
            "{err}"
        );
    }

    #[test]
    fn interrupt_stops_with_exit_code_130() {
        let sc = ring_scenario(22, 100_000.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let mut o = opts("interrupt");
        let flag = Arc::new(AtomicBool::new(false));
        o.interrupt = Some(flag.clone());
        let f = flag.clone();
        // Ctrl-C once the run has recorded rows (not after a delay: on a busy machine starting
        // Python alone can take seconds).
        o.on_rows = Some(once_recorded(20, move |_| f.store(true, Ordering::SeqCst)));
        let run = run_scenario(&sc, &o).unwrap();
        let err = run.failure().unwrap();
        assert_eq!(err.exit_code(), Some(130), "{err}");
        assert!(run.worker.rows.len() >= 20);
    }
}

mod ring {
    use super::*;

    #[test]
    fn vehicles_keep_circling_past_one_lap() {
        let sc = ring_scenario(22, 90.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let o = opts("circling");
        let wall = std::time::Instant::now();
        let run = run_scenario(&sc, &o).unwrap();
        let wall = wall.elapsed().as_secs_f64();
        let fin = run.outcome().expect("horizon reached");
        // The time inside SUMO's step (a sweep's stepping bound) is part of the run's wall
        // time, and SUMO cannot step 22 vehicles 900 times in under a microsecond a step.
        assert!(
            fin.step_s > 1e-6 * sc.steps() as f64 && fin.step_s < wall,
            "step_s {} of a {wall} s run",
            fin.step_s
        );
        let start = run.worker.start.as_ref().unwrap();
        assert_relative_eq!(
            start.road_length_m,
            4.0 * 57.4898 + 4.0 * 0.1,
            epsilon = 1e-9
        );
        assert_eq!(start.vehicles, 22);
        assert_eq!(run.worker.rows.len(), sc.steps() + 1);
        let traj = run.trajectory(&sc);
        let k = traj.len() - 1;
        let n = 22;
        for i in 0..n {
            let travelled = traj.positions_m[k * n + i] - traj.positions_m[i];
            assert!(
                travelled > 2.5 * start.road_length_m,
                "vehicle {i} drove {travelled} m"
            );
        }
        // Gaps add up to the ring: lengths + gaps = SUMO's ring length at every sample.
        let sum: f64 = traj.gaps(k).iter().sum::<f64>() + 5.0 * n as f64;
        assert_relative_eq!(sum, start.road_length_m, epsilon = 1e-6);
        assert_eq!(fin.totals.collision_steps, 0);
        assert_eq!(fin.totals.teleports, 0);
        assert_eq!(fin.totals.overrides, 0);
    }

    /// The actuation timing the loop relies on: a command set before a step is the speed
    /// SUMO reports after it, and with the ballistic update positions advance by the
    /// trapezoidal rule — so SUMO reproduces the native simulator's speeds exactly.
    #[test]
    fn actuation_timing_matches_the_native_simulator() {
        let sc = ring_scenario(22, 30.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let o = opts("timing");
        let run = run_scenario(&sc, &o).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.overrides, 0);
        assert!(fin.totals.odometer_deviation_max_m < 1e-9);
        let rows = &run.worker.rows;
        let n = rows.n;
        for k in 1..rows.len() {
            for i in 0..n {
                assert_eq!(rows.speeds_mps[k * n + i], rows.commands_mps[k * n + i]);
            }
        }
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        let sumo = run.trajectory(&sc);
        assert_eq!(native.len(), sumo.len());
        for j in 0..native.speeds_mps.len() {
            assert_relative_eq!(native.speeds_mps[j], sumo.speeds_mps[j], epsilon = 1e-9);
        }
        // Positions: same increments (the ring is 0.36 m longer in SUMO, so gaps differ).
        let k = native.len() - 1;
        for i in 0..n {
            let dn = native.positions_m[k * n + i] - native.positions_m[i];
            let ds = sumo.positions_m[k * n + i] - sumo.positions_m[i];
            assert_relative_eq!(dn, ds, epsilon = 1e-6);
        }
    }

    /// The user's linear agents (a lag behind an integrator, and a delayed one) drive SUMO's
    /// vehicles as they drive the native simulator's: no safety layer acts, and the two runs
    /// agree speed for speed.
    #[test]
    fn linear_agents_drive_sumo_as_they_drive_the_native_simulator() {
        let json = format!(
            r#"{{
            "name": "sumo-linear", "backend": "sumo", "seed": 5, "step_s": 0.1,
            "horizon_s": 40, "vehicles": 12,
            "road": {{"type": "ring", "length_m": 230}},
            "model": {{"type": "linear",
                       "graph": {{"type": "bidirectional_ring", "gain_pred": 0.5, "gain_follow": 0.1}},
                       "agents": [{{"eta": [1], "rho": [1, 0.5]}}, {{"eta": [1], "rho": [1], "delay_s": 0.3}},
                                  {{"eta": [1], "rho": [1, 0.5]}}, {{"eta": [1], "rho": [1], "delay_s": 0.3}},
                                  {{"eta": [1], "rho": [1, 0.5]}}, {{"eta": [1], "rho": [1], "delay_s": 0.3}},
                                  {{"eta": [1], "rho": [1, 0.5]}}, {{"eta": [1], "rho": [1], "delay_s": 0.3}},
                                  {{"eta": [1], "rho": [1, 0.5]}}, {{"eta": [1], "rho": [1], "delay_s": 0.3}},
                                  {{"a": [[0, 1], [0, -2]], "b": [0, 2], "c": [1, 0]}}, {{"eta": [1], "rho": [1]}}]}},
            "initial": {{"speed_mps": 8.0, "perturbation": {{"speed_mps": 1.0}}}},
            "sumo": {{"net": "{}", "max_speed_mps": 30}}
        }}"#,
            nets().join("sugiyama-ring.net.xml").display()
        );
        let sc = Scenario::from_json(&json).expect("valid scenario");
        let run = run_scenario(&sc, &opts("linear-agents")).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.overrides, 0);
        assert_eq!(fin.totals.collision_steps, 0);
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        let sumo = run.trajectory(&sc);
        assert_eq!(native.len(), sumo.len());
        let worst = native
            .speeds_mps
            .iter()
            .zip(&sumo.speeds_mps)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "largest speed difference {worst} m/s");
        // And the agents moved: the initial spread of about 2 m/s has shrunk.
        let n = native.n;
        let spread = |k: usize| {
            let v = &native.speeds_mps[k * n..(k + 1) * n];
            v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min)
        };
        assert!(spread(native.len() - 1) < 0.5 * spread(0));
    }

    /// What SUMO does with commands in speed mode 32, measured: everything is realised, even
    /// above the vehicle type's maxSpeed (9 m/s here) and the lane limit, so the override
    /// counter stays at 0; negative commands (which SUMO would read as "release control") are
    /// sent as 0 and counted; collisions are recorded, not prevented. Predecessor following
    /// with αK = 1.2 (past Chandler's bound 2αK < 1) drives the oscillation there.
    #[test]
    fn speed_mode_32_realises_every_command_and_collisions_are_counted() {
        let json = format!(
            r#"{{"name": "unstable", "seed": 7, "step_s": 0.1, "horizon_s": 15, "vehicles": 22,
            "road": {{"type": "ring", "length_m": 230}},
            "model": {{"type": "delayed_driver",
                       "graph": {{"type": "unidirectional_ring", "gain": 1.5}}, "delay_s": 0.8}},
            "initial": {{"speed_mps": 8.0, "perturbation": {{"speed_mps": 0.5}}}},
            "sumo": {{"net": "{}", "max_speed_mps": 9.0}}}}"#,
            nets().join("sugiyama-ring.net.xml").display()
        );
        let sc = Scenario::from_json(&json).unwrap();
        let run = run_scenario(&sc, &opts("mode32")).unwrap();
        let fin = run.outcome().expect("horizon reached");
        let rows = &run.worker.rows;
        let fastest = rows.speeds_mps.iter().copied().fold(0.0, f64::max);
        assert!(fastest > 9.0, "fastest {fastest}");
        assert_eq!(fin.totals.overrides, 0, "{:?}", fin.totals);
        assert!(fin.totals.negative_commands_clamped > 0);
        assert!(fin.totals.collision_steps > 0);
        let collisions = run
            .worker
            .events
            .iter()
            .filter(|e| matches!(e, syncroad_sumo::Event::Collision { .. }))
            .count();
        assert_eq!(collisions, fin.totals.collision_steps);
    }

    #[test]
    fn euler_update_is_not_trapezoidal() {
        let sc = ring_scenario(22, 5.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let mut o = opts("euler");
        o.ballistic = false;
        let run = run_scenario(&sc, &o).unwrap();
        run.outcome().expect("horizon reached");
        let rows = &run.worker.rows;
        let n = rows.n;
        // x^{n+1} = x^n + Δt v^{n+1}.
        for k in 1..rows.len() {
            for i in 0..n {
                let dx = rows.positions_m[k * n + i] - rows.positions_m[(k - 1) * n + i];
                assert_relative_eq!(dx, 0.1 * rows.speeds_mps[k * n + i], epsilon = 1e-9);
            }
        }
    }

    #[test]
    fn same_seed_same_rows_in_separate_workers() {
        // SUMO's own Krauss model with σ = 0.5 draws random numbers every step.
        let sc = ring_scenario(22, 30.0, &nets().join("sugiyama-ring.net.xml"), 7);
        let mut a = opts("seed-a");
        a.drivers = vec![Some(SumoDriver::Krauss { sigma: 0.5 }); 22];
        let mut b = opts("seed-b");
        b.drivers = vec![Some(SumoDriver::Krauss { sigma: 0.5 }); 22];
        let ra = run_scenario(&sc, &a).unwrap();
        let rb = run_scenario(&sc, &b).unwrap();
        ra.outcome().unwrap();
        rb.outcome().unwrap();
        assert_ne!(
            ra.worker.start.as_ref().unwrap().pid,
            rb.worker.start.as_ref().unwrap().pid
        );
        assert_eq!(ra.worker.rows.speeds_mps, rb.worker.rows.speeds_mps);
        assert_eq!(ra.worker.rows.positions_m, rb.worker.rows.positions_m);
        // ... and another seed gives another run (the test can fail).
        let sc2 = ring_scenario(22, 30.0, &nets().join("sugiyama-ring.net.xml"), 8);
        let mut c = opts("seed-c");
        c.drivers = vec![Some(SumoDriver::Krauss { sigma: 0.5 }); 22];
        let rc = run_scenario(&sc2, &c).unwrap();
        assert_ne!(ra.worker.rows.speeds_mps, rc.worker.rows.speeds_mps);
    }
}

/// Stochastic humans computed by the bridge (the noisy IDM): the same controller on both
/// backends, so with SUMO's ballistic update and every check off (speed mode 32) SUMO
/// reproduces the native run's speeds, noise and all.
mod noisy_humans {
    use super::*;
    use syncroad_control::{native::simulate_with, HumanSetup, LawSpec};

    /// 22 vehicles evenly spaced on a ring of `length_m`, at rest, no perturbation.
    fn uniform_ring(length_m: f64, horizon_s: f64, seed: u64) -> Scenario {
        let json = format!(
            r#"{{"name": "noisy-ring", "backend": "sumo", "seed": {seed}, "step_s": 0.1,
            "horizon_s": {horizon_s}, "vehicles": 22,
            "road": {{"type": "ring", "length_m": {length_m}}},
            "model": {{"type": "delayed_driver",
                       "graph": {{"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1}},
                       "delay_s": 0.5}},
            "initial": {{"speed_mps": 0.0}},
            "sumo": {{"net": "{}"}}}}"#,
            nets().join("sugiyama-ring.net.xml").display()
        );
        Scenario::from_json(&json).unwrap()
    }

    #[test]
    fn sumo_reproduces_the_native_noisy_ring_run_against_run() {
        let road = load_road(&uniform_ring(230.0, 10.0, 1)).unwrap();
        // The scenario's ring is SUMO's (normal plus internal lanes), so gaps agree too.
        let sc = uniform_ring(road.length_m(), 120.0, 5);
        let driver = SumoDriver::parse("d", "human-noisy").unwrap();
        let SumoDriver::Noisy(human) = driver.clone() else {
            unreachable!()
        };
        let mut o = opts("noisy-agree");
        o.drivers = vec![Some(driver); 22];
        let run = run_scenario(&sc, &o).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.overrides, 0);
        let out = run.output(&sc);
        let facts = out.sumo.as_ref().unwrap();
        assert!(
            facts.drivers.iter().all(|d| d == "human-noisy"),
            "{:?}",
            facts.drivers
        );
        assert_eq!(facts.law_speed_mode, Some(32));
        let mut law = LawSpec::of(&sc);
        law.humans = Some(HumanSetup {
            drivers: vec![Some(human); 22],
            ring_length_m: road.length_m(),
            length_m: vec![5.0; 22],
            seed: 5,
            speed_limit_mps: None,
        });
        let native = simulate_with(&sc, &law, NativeOptions::default())
            .unwrap()
            .trajectory;
        let sumo = run.trajectory(&sc);
        assert_eq!(native.len(), sumo.len());
        let worst = native
            .speeds_mps
            .iter()
            .zip(&sumo.speeds_mps)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!("noisy ring: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
        // The noise acts: from a uniform start the speeds spread.
        let k = native.len() - 1;
        let last = &native.speeds_mps[k * 22..];
        let (lo, hi) = last
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
        assert!(hi - lo > 0.1, "speeds {lo}..{hi}");
        // Another seed, another run.
        let sc2 = uniform_ring(road.length_m(), 120.0, 6);
        let mut o2 = opts("noisy-agree-2");
        o2.drivers = o.drivers.clone();
        let run2 = run_scenario(&sc2, &o2).unwrap();
        assert_ne!(run2.trajectory(&sc2).speeds_mps, sumo.speeds_mps);
    }

    /// SUMO's driver-state device on the `human` IDM: with awareness 1 (no perception error)
    /// a uniform start stays uniform; with awareness 0.5 its errors start a jam.
    #[test]
    fn the_driver_state_device_makes_the_deterministic_idm_jam() {
        let sc = uniform_ring(230.0, 300.0, 2);
        let min_speed = |name: &str| {
            let mut o = opts(&format!("ds-{name}"));
            o.drivers = vec![Some(SumoDriver::parse("d", name).unwrap()); 22];
            let run = run_scenario(&sc, &o).unwrap();
            run.outcome().expect("horizon reached");
            let routes = std::fs::read_to_string(&run.request.routes_file).unwrap();
            assert!(routes.contains(r#"<param key="has.driverstate.device" value="true"/>"#));
            let t = run.trajectory(&sc);
            let k = t.len() - 1;
            t.speeds_mps[(k / 2) * 22..]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min)
        };
        let calm = min_speed("driverstate-1");
        let jam = min_speed("driverstate-0.5");
        assert!(calm > 4.0, "awareness 1: min speed {calm}");
        assert!(jam < 1.0, "awareness 0.5: min speed {jam}");
    }
}

mod platoon {
    use super::*;

    /// The CACC platoon (eqs. `veh-proto1/2`) behind a braking leader on the 20 km straight
    /// road: the leader is a SUMO vehicle driven along its profile, the followers by the law.
    /// Both backends step the same controller (a_des held over each step, exact powertrain
    /// lag) and SUMO's ballistic update is the native trapezoidal rule, so the two agree to
    /// rounding; the continuous closed loop (RK4 reference) is O(Δt) away.
    #[test]
    fn cacc_platoon_follows_the_native_simulator() {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/platoon-cacc.json"),
        )
        .unwrap();
        let mut file: serde_json::Value = serde_json::from_str(&text).unwrap();
        file["horizon_s"] = 80.0.into();
        file["sumo"] = serde_json::json!({"net": nets().join("straight-20km.net.xml")});
        let sc = Scenario::from_json(&file.to_string()).unwrap();
        let run = run_scenario(&sc, &opts("platoon")).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(
            run.worker.start.as_ref().unwrap().vehicles,
            sc.vehicles() + 1
        );
        assert_eq!(fin.totals.collision_steps, 0);
        let sumo = run.trajectory(&sc);
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        assert_eq!(sumo.len(), native.len());
        let worst = sumo
            .speeds_mps
            .iter()
            .zip(&native.speeds_mps)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!("CACC platoon: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
        let rk4 =
            syncroad_control::native::cacc_rk4_reference(&sc, NativeOptions::default()).trajectory;
        let to_rk4 = native
            .speeds_mps
            .iter()
            .zip(&rk4.speeds_mps)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            to_rk4 < 0.05,
            "discrete law vs continuous loop: {to_rk4} m/s"
        );
        // The leader (row column 0) drives its profile exactly.
        let rows = &run.worker.rows;
        for k in 0..rows.len() {
            let t = rows.time_s[k];
            assert_relative_eq!(
                rows.speeds_mps[k * rows.n],
                sc.leader_speed_at(t).unwrap(),
                epsilon = 1e-9
            );
        }
    }
}

/// Long-lived workers: many runs in one process, each as if it had its own.
mod pool {
    use super::*;
    use syncroad_sumo::WorkerPool;

    fn krauss_run(pool: &WorkerPool, seed: u64, name: &str) -> syncroad_sumo::SumoRun {
        let sc = ring_scenario(22, 30.0, &nets().join("sugiyama-ring.net.xml"), seed);
        let road = load_road(&sc).unwrap();
        let mut o = opts(name);
        o.drivers = vec![Some(SumoDriver::Krauss { sigma: 0.5 }); 22];
        Prepared::new(&sc, &road, &o).unwrap().run_in(pool)
    }

    /// Reusing a process changes nothing: the second and third runs of one worker give the
    /// rows a fresh worker gives, bit for bit, and a different seed still gives other rows.
    #[test]
    fn a_reused_worker_gives_the_rows_of_a_fresh_one() {
        let pool = WorkerPool::new(WorkerCommand::binary(env!(
            "CARGO_BIN_EXE_syncroad-sumo-worker"
        )));
        let first = krauss_run(&pool, 7, "pool-1");
        let other_seed = krauss_run(&pool, 8, "pool-2");
        let again = krauss_run(&pool, 7, "pool-3");
        for r in [&first, &other_seed, &again] {
            r.outcome().unwrap();
        }
        let pid = |r: &syncroad_sumo::SumoRun| r.worker.start.as_ref().unwrap().pid;
        assert_eq!(pid(&first), pid(&again), "one process served all runs");
        assert_eq!(pid(&first), pid(&other_seed));
        assert_eq!(pool.workers_started(), 1);
        assert_eq!(first.worker.rows.speeds_mps, again.worker.rows.speeds_mps);
        assert_eq!(first.worker.rows.positions_m, again.worker.rows.positions_m);
        assert_ne!(
            first.worker.rows.speeds_mps,
            other_seed.worker.rows.speeds_mps
        );
        // A fresh process agrees with the reused one.
        let sc = ring_scenario(22, 30.0, &nets().join("sugiyama-ring.net.xml"), 7);
        let mut o = opts("pool-fresh");
        o.drivers = vec![Some(SumoDriver::Krauss { sigma: 0.5 }); 22];
        let fresh = run_scenario(&sc, &o).unwrap();
        assert_ne!(fresh.worker.start.as_ref().unwrap().pid, pid(&first));
        assert_eq!(fresh.worker.rows.speeds_mps, again.worker.rows.speeds_mps);
    }

    /// A worker that crashes is reported as the run's failure and replaced for the next run;
    /// a run that fails cleanly (SUMO refuses to start) leaves its worker in service.
    #[test]
    fn a_crashed_worker_is_replaced() {
        let pool = WorkerPool::new(WorkerCommand::binary(env!(
            "CARGO_BIN_EXE_syncroad-sumo-worker"
        )));
        let sc = ring_scenario(22, 100_000.0, &nets().join("sugiyama-ring.net.xml"), 1);
        let road = load_road(&sc).unwrap();
        let mut o = opts("pool-crash");
        o.on_start = Some(Arc::new(|s: &syncroad_sumo::StartInfo| {
            let pid = s.pid as i32;
            std::thread::spawn(move || {
                // Any moment of the 100 000 s run will do: the kill lands mid-run however
                // slow the machine, and the test checks the crash, not when it came.
                std::thread::sleep(Duration::from_millis(500));
                // SAFETY: signals our own child worker.
                unsafe { libc::kill(pid, libc::SIGKILL) };
            });
        }));
        let crashed = Prepared::new(&sc, &road, &o).unwrap().run_in(&pool);
        assert!(
            matches!(
                crashed.failure(),
                Some(SupervisorError::Crashed {
                    name: "SIGKILL",
                    ..
                })
            ),
            "{:?}",
            crashed.failure()
        );
        let next = krauss_run(&pool, 7, "pool-after-crash");
        next.outcome().unwrap();
        assert_eq!(pool.workers_started(), 2, "the dead worker was replaced");
        assert_ne!(
            next.worker.start.as_ref().unwrap().pid,
            crashed.worker.pid,
            "a new process"
        );
        let again = krauss_run(&pool, 7, "pool-after-crash-2");
        again.outcome().unwrap();
        assert_eq!(pool.workers_started(), 2, "the new worker stays in service");
    }
}

/// Drivers spelled out as `MODEL:name=value:...` reach SUMO with their values.
mod parameterized_drivers {
    use super::*;

    fn ring_run(driver: &str, name: &str) -> syncroad_sumo::SumoRun {
        let sc = ring_scenario(22, 60.0, &nets().join("sugiyama-ring.net.xml"), 3);
        let mut o = opts(name);
        o.drivers = vec![Some(SumoDriver::parse("driver", driver).unwrap()); 22];
        run_scenario(&sc, &o).unwrap()
    }

    /// The `human` preset spelled out value by value drives exactly as the preset, and one
    /// value changed changes the run: the parameters are what SUMO ran.
    #[test]
    fn a_spelled_out_preset_is_the_preset() {
        let preset = ring_run("human", "pd-preset");
        let spelled = ring_run(
            "idm:accel=1.3:decel=1.5:tau=0.8:minGap=2:delta=4:maxSpeed=30:length=5",
            "pd-spelled",
        );
        let slower = ring_run(
            "idm:accel=1.3:decel=1.5:tau=1.6:minGap=2:delta=4:maxSpeed=30:length=5",
            "pd-tau",
        );
        for r in [&preset, &spelled, &slower] {
            r.outcome().unwrap();
        }
        assert_eq!(
            preset.worker.rows.speeds_mps,
            spelled.worker.rows.speeds_mps
        );
        assert_ne!(preset.worker.rows.speeds_mps, slower.worker.rows.speeds_mps);
    }

    /// A step-dependent value off the step grid is refused before SUMO starts, naming it.
    #[test]
    fn an_action_step_off_the_grid_is_refused_before_sumo_starts() {
        let sc = ring_scenario(22, 10.0, &nets().join("sugiyama-ring.net.xml"), 3);
        let road = load_road(&sc).unwrap();
        let mut o = opts("pd-asl");
        o.drivers =
            vec![Some(SumoDriver::parse("driver", "idm:actionStepLength=0.15").unwrap()); 22];
        let e = Prepared::new(&sc, &road, &o).unwrap_err().to_string();
        assert!(e.contains("actionStepLength") && e.contains("0.15"), "{e}");
        assert!(e.contains("whole multiple"), "{e}");
    }
}

/// Fault injection: the worker is killed at a random moment of a long run, over several
/// seeds, by SIGKILL, SIGABRT (libsumo's assertions) or SIGSEGV. Every time the run reports the
/// crash with its signal, keeps every row streamed before it, and its verdict is never
/// "synchronized": a run that did not reach its horizon cannot claim it. (A SIGSEGV sent with
/// `kill` is survived once: Rust's stack-overflow handler finds no guard-page fault, restores
/// the default action and returns; a real fault re-executes and dies. So it is sent twice.)
#[test]
fn worker_killed_at_random_moments_never_yields_a_confident_verdict() {
    use syncroad_control::rng::SplitMix64;
    use syncroad_control::{evaluate, EvalOptions, Verdict};
    let mut rng = SplitMix64::new(2026);
    for case in 0..6 {
        let (signal, name) = [
            (libc::SIGKILL, "SIGKILL"),
            (libc::SIGABRT, "SIGABRT"),
            (libc::SIGSEGV, "SIGSEGV"),
        ][case % 3];
        let delay = Duration::from_millis(200 + (rng.next_f64() * 1300.0) as u64);
        let sc = ring_scenario(
            22,
            100_000.0,
            &nets().join("sugiyama-ring.net.xml"),
            case as u64 + 1,
        );
        let mut o = opts(&format!("fault-{case}"));
        o.on_start = Some(Arc::new(move |s: &syncroad_sumo::StartInfo| {
            let pid = s.pid as i32;
            std::thread::spawn(move || {
                // A random moment of a 100 000 s run, counted from SUMO's start: mid-run on
                // any machine; what is checked (a crash, rows kept) holds at every moment.
                std::thread::sleep(delay);
                // SAFETY: signals our own child worker.
                unsafe { libc::kill(pid, signal) };
                // Any gap between the two signals will do: if the first has already ended the
                // worker, the second finds no process and the checks are the same.
                std::thread::sleep(Duration::from_millis(50));
                // SAFETY: as above; a second SIGSEGV meets the default action.
                unsafe { libc::kill(pid, signal) };
            });
        }));
        let run = run_scenario(&sc, &o).unwrap();
        match run.failure() {
            Some(SupervisorError::Crashed {
                name: got, records, ..
            }) => {
                assert_eq!(*got, name, "case {case}");
                assert_eq!(*records, run.worker.rows.len(), "case {case}");
            }
            other => panic!("case {case} ({name} after {delay:?}): {other:?}"),
        }
        let out = run.output(&sc);
        assert!(!out.stop.is_complete(), "case {case}");
        assert_eq!(
            out.trajectory.len(),
            run.worker.rows.len(),
            "case {case}: rows kept"
        );
        let verdict = evaluate(&sc, &out, EvalOptions::of(&sc)).sync.verdict;
        assert_ne!(verdict, Verdict::Synchronized, "case {case}");
    }
}

/// SUMO refuses a network with a broken lane shape and libsumo says only "Process Error";
/// the run's error carries SUMO's own reasons from the worker's output.
#[test]
fn sumo_start_errors_carry_sumos_own_reasons() {
    let dir = work("garbage-shape");
    let text = std::fs::read_to_string(nets().join("sugiyama-ring.net.xml")).unwrap();
    let at = text.find("shape=\"").unwrap() + "shape=\"".len();
    let end = at + text[at..].find('"').unwrap();
    let net = dir.join("ring.net.xml");
    std::fs::write(&net, format!("{}garbage{}", &text[..at], &text[end..])).unwrap();
    let sc = ring_scenario(22, 10.0, &net, 1);
    let run = run_scenario(&sc, &opts("garbage-shape-run")).unwrap();
    let e = run.failure().expect("SUMO refuses the net").to_string();
    assert!(e.contains("Process Error"), "{e}");
    assert!(e.contains("SUMO said:"), "{e}");
    assert!(e.contains("is not a valid list of positions"), "{e}");
}

/// The benchmark's probe travels beside the run, not in it: a short case runs SUMO alone, the
/// timed loop and the interleaved loop through real workers, and the profile accounts for
/// the loop's wall time phase by phase with no phase counted twice (every share non-negative,
/// `simulation.step` never above the whole step). The profile adds up to the step by
/// construction (its last entry is the remainder); what can fail is a phase timed twice (a
/// negative remainder) or an observer missing or added.
#[test]
fn benchmark_probe_profiles_the_loop_phase_by_phase() {
    use syncroad_sumo::bench::{format_profile, run_case, BenchCase};
    let case = BenchCase {
        name: "probe".into(),
        net: nets().join("sugiyama-ring.net.xml"),
        vehicles: 22,
        nominal_length_m: 230.0,
        steps: 300,
        warmup: 20,
        repeats: 1,
        traci: false,
        traci_per_call: false,
        traci_python: false,
        traci_steps: 0,
    };
    let worker = WorkerCommand::binary(env!("CARGO_BIN_EXE_syncroad-sumo-worker"));
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let r = run_case(
        &case,
        &worker,
        &work("bench-probe"),
        &repo.join("python-host"),
        &mut |_| {},
    )
    .unwrap();
    let names: Vec<&str> = r.profile_ms.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "simulation.step",
            "law + setSpeed",
            "read speeds + odometers",
            "safety counters",
            "rows",
            "rest of the loop"
        ]
    );
    for (name, t) in &r.profile_ms {
        assert!(*t >= 0.0 && t.is_finite(), "{name}: {t} ms/step");
    }
    let total: f64 = r.profile_ms.iter().map(|(_, t)| t).sum();
    assert_relative_eq!(total, r.controlled_ms, max_relative = 1e-9);
    assert!(r.profile_ms[0].1 < r.controlled_ms);
    assert!(r.alone_ms > 0.0 && r.interleaved_samples_pct.len() == 1);
    assert!(r.interleaved_overhead_pct.is_finite());
    // The plain run's loop costs something, and less than SUMO's own step on this ring (the
    // direct calls cost about a tenth of it; one call through Python per value a third).
    assert!(
        r.in_run_plain_pct > 0.0 && r.in_run_plain_pct < 100.0,
        "{} %",
        r.in_run_plain_pct
    );
    let text = format_profile(&[r]);
    assert!(
        text.contains("safety counters") && text.contains("in a plain run"),
        "{text}"
    );
}

#[path = "sumo/user_law.rs"]
mod user_law;
