//! The user's Python controller, on both backends: the guide's Python FollowerStopper and
//! Python delayed-driver law reproduce the built-in laws' trajectories, and a controller that
//! raises, blocks or prints is stopped or contained with every row before it kept.

use super::*;
use syncroad_control::drive::Drive;
use syncroad_control::NamedLaw;
use syncroad_control::{simulate_with, LawSpec, StopReason, Trajectory};
use syncroad_sumo::PythonHost;

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/controllers")
        .canonicalize()
        .unwrap()
}

/// The Sugiyama ring's reaction delays α_i \[s\].
const DELAYS: [f64; 22] = [
    0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.5,
    0.6, 0.7, 0.6,
];

/// The ring of `ring_scenario` (22 vehicles, delays 0.5–0.7 s) with `controller`, if any.
fn ring(horizon_s: f64, controller: Option<serde_json::Value>) -> Scenario {
    let mut file = serde_json::json!({
        "name": "python-law", "backend": "sumo", "seed": 7, "step_s": 0.1,
        "horizon_s": horizon_s, "vehicles": 22,
        "road": {"type": "ring", "length_m": 230},
        "model": {"type": "delayed_driver",
                  "graph": {"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1},
                  "delay_s": DELAYS},
        "initial": {"speed_mps": 4.0, "perturbation": {"speed_mps": 1.5, "gap_m": 0.5}},
        "sumo": {"net": nets().join("sugiyama-ring.net.xml")}
    });
    if let Some(c) = controller {
        file["controller"] = c;
    }
    Scenario::from_json(&file.to_string()).expect("valid scenario")
}

fn delayed_driver() -> serde_json::Value {
    serde_json::json!({
        "python": examples().join("delayed_driver.py:DelayedDriver").display().to_string(),
        "params": {"gain_pred": 0.6, "gain_follow": 0.1, "delay_s": DELAYS}
    })
}

fn follower_stopper() -> serde_json::Value {
    serde_json::json!({
        "python": examples().join("follower_stopper.py:FollowerStopper").display().to_string(),
        "params": {"desired_speed_mps": 4.3}
    })
}

fn native(sc: &Scenario, law: &LawSpec) -> syncroad_control::NativeRun {
    let opts = NativeOptions {
        host: Some(&PythonHost),
        ..NativeOptions::default()
    };
    simulate_with(sc, law, opts).expect("the law builds")
}

/// Largest speed difference of two runs of the same length.
fn worst(a: &Trajectory, b: &Trajectory) -> f64 {
    assert_eq!(a.len(), b.len());
    a.speeds_mps
        .iter()
        .zip(&b.speeds_mps)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The Python copy must be doing something: speeds move away from the start by more than
/// the tolerance the comparison uses.
fn moved(t: &Trajectory) -> f64 {
    let k = t.len() - 1;
    t.speeds(k)
        .iter()
        .zip(t.speeds(0))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Natively, the built-in law `run` (`protocol` or a damper) on the 60 s ring against the
/// Python `controller`: the built-in run moves, and the two agree to 1e-9 m/s.
fn native_agrees(run: &str, controller: serde_json::Value) {
    let plain = ring(60.0, None);
    let drive = Drive::parse("--x", run, 22).unwrap();
    let built_in = native(&plain, &LawSpec::of_drive(&plain, &drive).unwrap());
    let sc = ring(60.0, Some(controller));
    let python = native(&sc, &LawSpec::of(&sc));
    assert_eq!(python.stop, StopReason::Horizon);
    assert!(moved(&built_in.trajectory) > 0.5);
    let w = worst(&built_in.trajectory, &python.trajectory);
    assert!(w < 1e-9, "{run}: largest speed difference {w} m/s");
}

#[test]
fn the_python_delayed_driver_law_reproduces_the_built_in_law_natively() {
    native_agrees("protocol", delayed_driver());
}

#[test]
fn the_python_follower_stopper_reproduces_the_built_in_damper_natively() {
    native_agrees("follower-stopper-4.3", follower_stopper());
}

#[test]
fn both_python_laws_reproduce_the_built_in_laws_in_sumo() {
    let law = run_scenario(&ring(40.0, None), &opts("py-law-builtin")).unwrap();
    let sc = ring(40.0, Some(delayed_driver()));
    let python = run_scenario(&sc, &opts("py-law-python")).unwrap();
    assert!(python.outcome().is_ok(), "{:?}", python.stop());
    let (a, b) = (law.trajectory(&sc), python.trajectory(&sc));
    assert!(moved(&a) > 0.5);
    let w = worst(&a, &b);
    assert!(
        w < 1e-9,
        "delayed drivers: largest speed difference {w} m/s"
    );

    let mut o = opts("py-fs-builtin");
    o.damper = NamedLaw::parse("damper", "follower-stopper-4.3").unwrap();
    let damper = run_scenario(&ring(40.0, None), &o).unwrap();
    let sc = ring(40.0, Some(follower_stopper()));
    let python = run_scenario(&sc, &opts("py-fs-python")).unwrap();
    assert!(python.outcome().is_ok(), "{:?}", python.stop());
    let (a, b) = (damper.trajectory(&sc), python.trajectory(&sc));
    assert!(moved(&a) > 0.2);
    let w = worst(&a, &b);
    assert!(
        w < 1e-9,
        "FollowerStopper: largest speed difference {w} m/s"
    );
}

/// A controller file of this test, written into its work folder.
fn controller_file(dir: &Path, source: &str) -> String {
    let path = dir.join("mine.py");
    std::fs::write(&path, source).unwrap();
    path.display().to_string()
}

const MISBEHAVING: &str = r#"
import time, sys, os
import numpy as np

class Raises:
    def step(self, obs):
        print("controller output on stdout", obs.step)
        sys.stdout.flush()
        os.write(1, b"raw bytes on descriptor 1\n")
        if obs.step == 25:
            raise RuntimeError("the law broke at step %d" % obs.step)
        return obs.speed_mps

class Blocks:
    def step(self, obs):
        if obs.step == 25:
            # A step that never returns (the hour outlasts any test): only a limit ends it.
            time.sleep(3600)
        return obs.speed_mps

class Negative:
    def step(self, obs):
        v = np.array(obs.speed_mps)
        if obs.step == 12:
            v[3] = -0.5
        return v

class NotANumber:
    def step(self, obs):
        v = np.array(obs.speed_mps)
        if obs.step == 12:
            v[5] = float("nan")
        return v

class WrongLength:
    def step(self, obs):
        return obs.speed_mps[:-1] if obs.step == 12 else obs.speed_mps

class WrongType:
    def step(self, obs):
        return {"speeds": 1} if obs.step == 12 else obs.speed_mps

class Strings:
    def step(self, obs):
        return ["5.0"] * len(obs.ids) if obs.step == 12 else obs.speed_mps

class Booleans:
    def step(self, obs):
        return [True] * len(obs.ids) if obs.step == 12 else obs.speed_mps

class Complex:
    def step(self, obs):
        return obs.speed_mps + 1j if obs.step == 12 else obs.speed_mps
"#;

#[test]
fn a_controller_that_raises_stops_the_run_with_its_traceback_and_keeps_the_rows() {
    let dir = work("py-raises");
    let file = controller_file(&dir, MISBEHAVING);
    let sc = ring(
        30.0,
        Some(serde_json::json!({"python": format!("{file}:Raises")})),
    );
    let run = run_scenario(&sc, &opts("py-raises-run")).unwrap();
    let StopReason::ControllerFailed { step, error, .. } = run.stop() else {
        panic!("expected a controller failure, got {:?}", run.stop());
    };
    assert_eq!(step, 25);
    assert!(
        error.contains(&format!("File \"{file}\", line 11, in step")),
        "{error}"
    );
    assert!(
        error.ends_with("RuntimeError: the law broke at step 25"),
        "{error}"
    );
    // Printing did not corrupt the protocol: every step before the failure arrived.
    assert_eq!(run.trajectory(&sc).len(), 26);
    // Natively: the same stop at the same step, the same rows.
    let nat = native(&sc, &LawSpec::of(&sc));
    assert!(
        matches!(nat.stop, StopReason::ControllerFailed { step: 25, .. }),
        "{:?}",
        nat.stop
    );
    assert_eq!(nat.trajectory.len(), 26);
}

#[test]
fn negative_speeds_name_the_step_and_the_vehicle() {
    let dir = work("py-negative");
    let file = controller_file(&dir, MISBEHAVING);
    let sc = ring(
        30.0,
        Some(serde_json::json!({"python": format!("{file}:Negative")})),
    );
    let run = run_scenario(&sc, &opts("py-negative-run")).unwrap();
    let StopReason::ControllerFailed { error, .. } = run.stop() else {
        panic!("expected a controller failure, got {:?}", run.stop());
    };
    assert_eq!(
        error,
        "at step 12 (t = 1.200 s) the controller's target speed for vehicle v3 (obs.ids[3]) is -0.5; target speeds must be finite and ≥ 0 m/s"
    );
}

/// What a controller returned that is no speed per vehicle stops the run at that step with a
/// message naming what was wrong (and, for a value, the vehicle), the rows before it kept.
#[test]
fn a_nan_a_wrong_length_or_a_wrong_type_names_what_was_wrong() {
    let dir = work("py-wrong-commands");
    let file = controller_file(&dir, MISBEHAVING);
    for (class, want) in [
        (
            "NotANumber",
            &["at step 12 (t = 1.200 s) the controller's target speed for vehicle v5 (obs.ids[5]) is NaN; target speeds must be finite and ≥ 0 m/s"][..],
        ),
        (
            "WrongLength",
            &["ValueError: step returned 21 value(s) of shape (21,); 22 are needed, one per vehicle of obs.ids"],
        ),
        (
            "WrongType",
            &["TypeError: step returned a dict ({'speeds': 1}) where speeds go; return 22 real numbers (int or float), one per vehicle of obs.ids"],
        ),
        (
            "Strings",
            &["TypeError: step returned strings where speeds go; return 22 real numbers (int or float), one per vehicle of obs.ids"],
        ),
        (
            "Booleans",
            &["TypeError: step returned booleans where speeds go"],
        ),
        (
            "Complex",
            &["TypeError: step returned complex numbers where speeds go"],
        ),
    ] {
        let sc = ring(
            5.0,
            Some(serde_json::json!({"python": format!("{file}:{class}")})),
        );
        let run = run_scenario(&sc, &opts(&format!("py-wrong-{class}"))).unwrap();
        let StopReason::ControllerFailed { error, step, .. } = run.stop() else {
            panic!("{class}: expected a controller failure, got {:?}", run.stop());
        };
        assert_eq!(step, 12, "{class}");
        for w in want {
            assert!(error.contains(w), "{class}: {error}");
        }
        // The rows of steps 0 … 12 (the initial state and twelve steps) are kept.
        assert_eq!(run.trajectory(&sc).len(), 13, "{class}");
    }
}

#[test]
fn a_controller_that_blocks_is_stopped_by_the_runs_timeout() {
    let dir = work("py-blocks");
    let file = controller_file(&dir, MISBEHAVING);
    let sc = ring(
        30.0,
        Some(serde_json::json!({"python": format!("{file}:Blocks")})),
    );
    let mut o = opts("py-blocks-run");
    // The step at 25 never returns, so this limit is what ends the run on any machine; the
    // checks hold whether it passes before step 25 (a slow start) or after (no row past 25).
    o.timeout = Some(Duration::from_secs(3));
    let run = run_scenario(&sc, &o).unwrap();
    assert!(
        matches!(run.failure(), Some(SupervisorError::Timeout { .. })),
        "{:?}",
        run.stop()
    );
    // The rows before the blocked step are kept (those that reached the parent in a chunk).
    assert!(run.trajectory(&sc).len() <= 26);
}

#[test]
fn a_class_that_cannot_be_built_is_refused_before_sumo_starts() {
    let dir = work("py-build");
    let file = controller_file(&dir, "class Law:\n    def __init__(self, gain):\n        self.gain = gain\n    def step(self, obs):\n        return obs.speed_mps\n");
    for (python, params, expected) in [
        (
            format!("{file}:Missing"),
            serde_json::json!({}),
            "has no class Missing; its classes: Law",
        ),
        (
            format!("{file}:Law"),
            serde_json::json!({}),
            "TypeError: Law.__init__() missing 1 required positional argument: 'gain'",
        ),
        (
            format!("{file}:Law"),
            serde_json::json!({"gain": 1, "bias": 2}),
            "unexpected keyword argument 'bias'",
        ),
    ] {
        let sc = ring(
            10.0,
            Some(serde_json::json!({"python": python, "params": params})),
        );
        let run = run_scenario(&sc, &opts("py-build-run")).unwrap();
        let StopReason::Failed { error } = run.stop() else {
            panic!("expected a failure, got {:?}", run.stop());
        };
        assert!(error.contains(expected), "{error}");
        assert!(run.worker.start.is_none(), "SUMO started");
        let e = simulate_with(
            &sc,
            &LawSpec::of(&sc),
            NativeOptions {
                host: Some(&PythonHost),
                ..NativeOptions::default()
            },
        )
        .expect_err("refused natively");
        assert!(e.to_string().contains(expected), "{e}");
    }
}

/// The observation carries the road's speed limit: SUMO's lanes of the Sugiyama net (built at
/// 30 m/s, `sumo-nets/gen_sources.py`) in SUMO, none (inf) natively. The controller checks it
/// every step and fails the run if it differs.
#[test]
fn the_observation_carries_the_roads_speed_limit() {
    let dir = work("py-limit");
    let file = controller_file(
        &dir,
        "class Limit:\n    def __init__(self, expected):\n        self.expected = float(expected)\n    def step(self, obs):\n        if obs.speed_limit_mps != self.expected:\n            raise ValueError(f'speed_limit_mps = {obs.speed_limit_mps}, expected {self.expected}')\n        return obs.speed_mps\n",
    );
    let law = |expected: &str| {
        ring(
            5.0,
            Some(
                serde_json::json!({"python": format!("{file}:Limit"), "params": {"expected": expected}}),
            ),
        )
    };
    let sc = law("30");
    let run = run_scenario(&sc, &opts("py-limit-run")).unwrap();
    assert_eq!(run.stop(), StopReason::Horizon, "{:?}", run.stop());
    let sc = law("inf");
    assert_eq!(native(&sc, &LawSpec::of(&sc)).stop, StopReason::Horizon);
}

/// Whether process `pid` still runs (a zombie, dead but not yet reaped by init, does not).
fn alive(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, r)| !r.trim_start().starts_with('Z'))
        })
        .unwrap_or(false)
}

/// A controller that starts helpers: a `subprocess.Popen` that inherits the worker's stdio
/// (it held the worker's pipes open, and the run never returned), one with its stdio closed
/// (it outlived the run), and a fork whose own child is orphaned. Every one of them ends with
/// the run, and the run returns with its rows; the pids the controller wrote are checked.
#[test]
fn helpers_a_controller_starts_end_with_its_run() {
    let dir = work("py-helpers");
    let pids = dir.join("pids.txt");
    let source = format!(
        r#"
import os, subprocess

class Helpers:
    def __init__(self):
        inherited = subprocess.Popen(["sleep", "600"])
        quiet = subprocess.Popen(["sleep", "600"], stdin=subprocess.DEVNULL,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        r, w = os.pipe()
        forked = os.fork()
        if forked == 0:
            grandchild = os.fork()
            if grandchild == 0:
                os.close(r)
                os.write(w, b"%d\n" % os.getpid())
                os.close(w)
                import time
                # Outlives the run by far: only being killed with it ends it early.
                time.sleep(600)
                os._exit(0)
            # The fork's child is orphaned: its parent exits at once.
            os._exit(0)
        os.close(w)
        grandchild = int(os.read(r, 64))
        os.close(r)
        with open({pids:?}, "w") as f:
            f.write("%d %d %d\n" % (inherited.pid, quiet.pid, grandchild))

    def step(self, obs):
        return obs.speed_mps
"#,
        pids = pids.display().to_string()
    );
    let file = controller_file(&dir, &source);
    let sc = ring(
        5.0,
        Some(serde_json::json!({"python": format!("{file}:Helpers")})),
    );
    let run = run_scenario(&sc, &opts("py-helpers-run")).unwrap();
    assert_eq!(run.stop(), StopReason::Horizon, "{:?}", run.failure());
    assert_eq!(run.trajectory(&sc).len(), 51);
    let started: Vec<i32> = std::fs::read_to_string(&pids)
        .unwrap()
        .split_whitespace()
        .map(|p| p.parse().unwrap())
        .collect();
    assert_eq!(started.len(), 3);
    for pid in started {
        assert!(!alive(pid), "helper {pid} outlived the run");
    }
}
