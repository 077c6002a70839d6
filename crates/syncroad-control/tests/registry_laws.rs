//! Laws of the registry checked against the scenario's own law, run by the native simulator.

use syncroad_control::native::{simulate, NativeOptions};
use syncroad_control::Scenario;

fn ring(extra: &str) -> Scenario {
    ring_seeded(extra, 3)
}

fn ring_seeded(extra: &str, seed: u64) -> Scenario {
    let json = format!(
        r#"{{"name": "ring", "seed": {seed}, "step_s": 0.1, "horizon_s": 40, "vehicles": 8,
            "road": {{"type": "ring", "length_m": 200}},
            "model": {{"type": "delayed_driver", "history": "no_reaction",
                       "graph": {{"type": "unidirectional_ring", "gain": 0.8}},
                       "delay_s": 0.3}},
            "initial": {{"speed_mps": 6, "perturbation": {{"speed_mps": 1.5}}}}{extra}}}"#
    );
    Scenario::from_json(&json).unwrap()
}

/// The largest |a_k − b_k|.
fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// On a ring, the registry's delayed driver behind its predecessor is the scenario's own
/// law on a unidirectional ring of the same gain and delay (two implementations of eq.
/// `chandler+`: one law over the graph, one one-driver law per vehicle pinned to the
/// vehicle ahead): the same speeds to rounding.
#[test]
fn on_a_ring_it_is_the_scenario_law_on_a_unidirectional_ring() {
    let own = simulate(&ring(""), NativeOptions::default()).trajectory;
    let reg = simulate(
        &ring(r#", "controller": {"rust": "delayed-driver", "params": {"gain": 0.8, "delay_s": 0.3}}"#),
        NativeOptions::default(),
    )
    .trajectory;
    assert_eq!(own.len(), reg.len());
    let worst = largest_difference(&own.speeds_mps, &reg.speeds_mps);
    // The run is not trivial: the perturbation is damped by a factor of ten or more.
    let spread = |k: usize| {
        let v = own.speeds(k);
        v.iter().copied().fold(f64::MIN, f64::max) - v.iter().copied().fold(f64::MAX, f64::min)
    };
    assert!(
        spread(own.len() - 1) < 0.1 * spread(0),
        "{} {}",
        spread(0),
        spread(own.len() - 1)
    );
    assert!(worst <= 1e-12, "largest speed difference {worst} m/s");
    // And the registry's law is what drove: at half the gain the speeds differ.
    let half = simulate(
        &ring(r#", "controller": {"rust": "delayed-driver", "params": {"gain": 0.4, "delay_s": 0.3}}"#),
        NativeOptions::default(),
    )
    .trajectory;
    let apart = largest_difference(&own.speeds_mps, &half.speeds_mps);
    assert!(apart > 1e-2, "{apart}");
}

/// The registry's first entry, `protocol`, is the scenario's own law: built through the
/// table from the run's context it steps exactly the delayed-driver law of the scenario's
/// model (seeded with its initial speeds), takes no parameters of its own, and refuses vehicles
/// that are not a scenario's.
#[test]
fn the_protocol_entry_is_the_scenarios_law_and_takes_nothing_else() {
    use syncroad_control::model::Model;
    use syncroad_control::{LawSpec, NamedLaw, PROTOCOL};
    let sc = ring("");
    let spec = LawSpec::of(&sc);
    let mut law = NamedLaw::protocol().build(&spec.context).unwrap();
    let n = sc.vehicles();
    let v = sc.initial_speed_mps().to_vec();
    let q: Vec<f64> = (0..n).map(|i| -(i as f64) * 25.0).collect();
    let mut out = vec![0.0; n];
    let Model::DelayedDriver(m) = sc.model() else {
        panic!("a delayed-driver scenario")
    };
    let mut reference = m.law(sc.step_s(), &v).unwrap();
    let mut expected = vec![0.0; n];
    for step in 0..20 {
        law.step(step as f64 * 0.1, &v, &q, &mut out);
        reference.step(&v, 0.0, &mut expected);
        assert_eq!(out, expected, "step {step}");
    }
    assert!(largest_difference(&out, &v) > 0.0, "the law moved");
    // No parameters of its own, and no law without a scenario's model.
    let with = NamedLaw {
        name: PROTOCOL.into(),
        params: serde_json::json!({"gain": 1.0}),
    };
    let e = with.build(&spec.context).err().unwrap();
    assert!(e.contains("give none"), "{e}");
    let mut bare = spec.context.clone();
    bare.protocol = None;
    let e = NamedLaw::protocol().build(&bare).err().unwrap();
    assert!(e.contains("not a scenario's"), "{e}");
    // The table lists it first.
    assert_eq!(syncroad_control::registry::entries()[0].name, PROTOCOL);
}

/// The table's `noisy-idm` is the stochastic human driver of that name: as the scenario's
/// controller on every vehicle of a ring it gives the run of the driver
/// `noisy-idm:accel=1.3:tau=0.8:noise=0.2` on every vehicle (each vehicle's stream from the
/// seed and its index) bit for bit; another seed gives other noise, and another noise other
/// speeds, so the comparison can fail.
#[test]
fn the_noisy_idm_entry_drives_as_the_driver_of_its_name() {
    use syncroad_control::drive::Drive;
    use syncroad_control::LawSpec;
    let params = r#"{"accel": 1.3, "tau": 0.8, "noise": 0.2}"#;
    let entry = |seed: u64, params: &str| {
        let sc = ring_seeded(
            &format!(r#", "controller": {{"rust": "noisy-idm", "params": {params}}}"#),
            seed,
        );
        simulate(&sc, NativeOptions::default()).trajectory
    };
    let sc = ring("");
    let drive = Drive::parse(
        "--baselines",
        "noisy-idm:accel=1.3:tau=0.8:noise=0.2",
        sc.vehicles(),
    )
    .unwrap();
    assert!(drive.damper.is_none(), "the driver, not the table's law");
    let law = LawSpec::of_drive(&sc, &drive).unwrap();
    let driver = syncroad_control::native::simulate_with(&sc, &law, NativeOptions::default())
        .unwrap()
        .trajectory;
    let table = entry(sc.seed(), params);
    assert_eq!(driver.len(), table.len());
    assert_eq!(
        largest_difference(&driver.speeds_mps, &table.speeds_mps),
        0.0
    );
    let other_seed = entry(sc.seed() + 1, params);
    assert!(largest_difference(&table.speeds_mps, &other_seed.speeds_mps) > 1e-3);
    let quiet = entry(sc.seed(), r#"{"accel": 1.3, "tau": 0.8, "noise": 0.0}"#);
    assert!(largest_difference(&table.speeds_mps, &quiet.speeds_mps) > 1e-3);
    // Its parameters are the driver's, checked as the driver's are.
    let bad = syncroad_control::NamedLaw {
        name: "noisy-idm".into(),
        params: serde_json::json!({"noise": -1}),
    };
    assert!(bad.check("controller.params").is_err());
    let bad = syncroad_control::NamedLaw {
        name: "noisy-idm".into(),
        params: serde_json::json!({"sigma": 0.2}),
    };
    let e = bad.check("controller.params").unwrap_err().to_string();
    assert!(e.contains("valid: accel, decel, tau, minGap"), "{e}");
}
