//! Bad scenarios are rejected before any simulation, with messages naming field, value and fix.

use syncroad_control::scenario::Scenario;

fn base(model: &str, extra: &str) -> String {
    format!(
        r#"{{"seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": 4,
            "road": {{"type": "ring", "length_m": 100}}, "model": {model} {extra}}}"#
    )
}

const RING: &str = r#"{"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}, "delay_s": 0.3}"#;

fn err(json: &str) -> String {
    Scenario::from_json(json)
        .expect_err("scenario must be rejected")
        .to_string()
}

#[test]
fn valid_base_scenario_is_accepted() {
    let s = Scenario::from_json(&base(RING, "")).unwrap();
    assert_eq!(s.vehicles(), 4);
    assert_eq!(s.steps(), 100);
    // Even spacing: 100 m ring, 4 vehicles of 5 m → 20 m gaps.
    assert!(s.initial_gap_m().iter().all(|g| (g - 20.0).abs() < 1e-12));
}

#[test]
fn delay_off_the_step_grid() {
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}, "delay_s": [0.3, 0.3, 0.35, 0.3]}"#,
        "",
    ));
    assert!(
        e.starts_with("model.delay_s[2] = 0.35 s is not a whole multiple of step_s = 0.1 s"),
        "{e}"
    );
    assert!(e.contains("(e.g. 0.3 s)"), "{e}");
}

#[test]
fn negative_delay_and_nonfinite_gain() {
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}, "delay_s": -0.1}"#,
        "",
    ));
    assert_eq!(e, "model.delay_s[0] = -0.1: must be ≥ 0");
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": [0.5, 0.5, -1, 0.5]}, "delay_s": 0.1}"#,
        "",
    ));
    assert_eq!(e, "model.graph.gain[2] = -1: must be > 0");
}

#[test]
fn list_length_mismatch() {
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}, "delay_s": [0.1, 0.2]}"#,
        "",
    ));
    assert_eq!(e, "model.delay_s has 2 entries but the scenario has 4 vehicles; give one value per vehicle or a single number");
}

#[test]
fn self_loop_and_unknown_vehicle_in_edges() {
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "edges", "edges": [{"from": 1, "to": 1, "weight": 1}]}, "delay_s": 0.1}"#,
        "",
    ));
    assert_eq!(
        e,
        "model.graph.edges[0] = 1 -> 1: self-loops are not allowed (a_ii = 0)"
    );
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "edges", "edges": [{"from": 0, "to": 9, "weight": 1}]}, "delay_s": 0.1}"#,
        "",
    ));
    assert_eq!(
        e,
        "model.graph.edges[0] = 0 -> 9: vehicle indices must be in 0..4 (there are 4 vehicles)"
    );
    let e = err(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "matrix", "a": [[1,0,0,0],[0,0,0,0],[0,0,0,0],[0,0,0,0]]}, "delay_s": 0.1}"#,
        "",
    ));
    assert_eq!(
        e,
        "model.graph.a[0][0] = 1: diagonal entries must be 0 (no self-loops)"
    );
}

#[test]
fn zero_vehicles_zero_horizon_and_bad_step() {
    let e = err(&base(RING, "").replace(r#""vehicles": 4"#, r#""vehicles": 0"#));
    assert_eq!(
        e,
        "vehicles = 0: must be ≥ 1, or 0 on an open road of inflows only (sumo.inflows)"
    );
    let e = err(&base(RING, "").replace(r#""horizon_s": 10"#, r#""horizon_s": 0"#));
    assert_eq!(e, "horizon_s = 0: must be a finite number > 0");
    let e = err(&base(RING, "").replace(r#""step_s": 0.1"#, r#""step_s": -1"#));
    assert!(
        e.starts_with("step_s = -1: must be a finite number in (0, 1] s"),
        "{e}"
    );
}

#[test]
fn unknown_fields_are_rejected_with_position() {
    let e = err(&base(RING, r#", "horizn_s": 3"#));
    assert!(e.contains("unknown field `horizn_s`"), "{e}");
    assert!(e.contains("line"), "{e}");
}

#[test]
fn overfull_ring_is_rejected() {
    // 4 vehicles of 5 m cannot fit on a 15 m ring.
    let e = err(&base(RING, "").replace(r#""length_m": 100"#, r#""length_m": 15"#));
    assert!(
        e.starts_with("initial.gap_m[0] = -1.25: the gap (after perturbation) must be ≥ 0"),
        "{e}"
    );
}

#[test]
fn cacc_needs_a_straight_road_and_positive_gains() {
    let cacc = r#"{"type": "cacc", "mu": 1, "eta": 0.1, "nu": 0.1, "desired_gap_m": 10, "tau_s": 0.3, "leader": {"type": "constant", "speed_mps": 20}}"#;
    let e = err(&base(cacc, ""));
    assert!(
        e.starts_with("road.type = ring: a CACC platoon drives behind its leader"),
        "{e}"
    );
    let straight = base(cacc, "").replace(
        r#"{"type": "ring", "length_m": 100}"#,
        r#"{"type": "straight"}"#,
    );
    assert!(Scenario::from_json(&straight).is_ok());
    let e = err(&straight.replace(r#""mu": 1"#, r#""mu": 0"#));
    assert_eq!(e, "model.mu[0] = 0: must be > 0");
}

#[test]
fn same_seed_same_initial_state_other_seed_differs() {
    let j = base(
        RING,
        r#", "initial": {"perturbation": {"speed_mps": 1.0, "gap_m": 2.0}}"#,
    );
    let a = Scenario::from_json(&j).unwrap();
    let b = Scenario::from_json(&j).unwrap();
    assert_eq!(a.initial_speed_mps(), b.initial_speed_mps());
    assert_eq!(a.initial_gap_m(), b.initial_gap_m());
    let c = Scenario::from_json(&j.replace(r#""seed": 1"#, r#""seed": 2"#)).unwrap();
    assert_ne!(a.initial_speed_mps(), c.initial_speed_mps());
    // Perturbed gaps still close the ring.
    let total: f64 = a.initial_gap_m().iter().sum::<f64>() + 4.0 * 5.0;
    assert!((total - 100.0).abs() < 1e-9);
}

#[test]
fn vehicles_as_entries_carry_their_own_values() {
    let j = r#"{"seed": 1, "step_s": 0.1, "horizon_s": 10,
        "vehicles": [{"delay_s": 0.3, "speed_mps": 9}, {"delay_s": 0.5, "speed_mps": 11}, {"delay_s": 0.4, "speed_mps": 10}],
        "road": {"type": "ring", "length_m": 90},
        "model": {"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}}}"#;
    let s = Scenario::from_json(j).unwrap();
    assert_eq!(s.vehicles(), 3);
    assert_eq!(s.initial_speed_mps(), [9.0, 11.0, 10.0]);
    let syncroad_control::scenario::Model::DelayedDriver(m) = s.model() else {
        panic!()
    };
    assert_eq!(m.delay_steps, [3, 5, 4]);
}

#[test]
fn vehicle_entries_conflicting_or_incomplete_are_rejected() {
    let both = r#"{"seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": [{"delay_s": 0.3}, {"delay_s": 0.5}],
        "road": {"type": "ring", "length_m": 90},
        "model": {"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}, "delay_s": 0.2}}"#;
    assert_eq!(
        err(both),
        "vehicles[0].delay_s = 0.3: model.delay_s is set too; give each value once (either in model.delay_s or in every vehicle entry)"
    );
    let partial = both
        .replace(
            r#"[{"delay_s": 0.3}, {"delay_s": 0.5}]"#,
            r#"[{"delay_s": 0.3}, {}]"#,
        )
        .replace(r#", "delay_s": 0.2"#, "");
    assert_eq!(
        err(&partial),
        "vehicles[1].delay_s = missing: other vehicle entries give delay_s; give it for every vehicle, or use model.delay_s for all"
    );
    let typo = partial.replace(r#"{}"#, r#"{"delay": 0.3}"#);
    let e = err(&typo);
    assert!(e.contains("vehicles[1]: unknown field `delay`"), "{e}");
    let none = partial.replace(r#"[{"delay_s": 0.3}, {}]"#, "2");
    assert_eq!(
        err(&none),
        "model.delay_s = missing: give the reaction delays α_i [s] here or in every vehicle entry"
    );
}

#[test]
fn graph_shape_keeps_the_uniform_gains_the_closed_forms_need() {
    use syncroad_control::scenario::{GraphShape, Model};
    let s = Scenario::from_json(&base(RING, "")).unwrap();
    let Model::DelayedDriver(m) = s.model() else {
        panic!("delayed-driver scenario")
    };
    assert_eq!(m.shape, GraphShape::UnidirectionalRing { gain: Some(0.5) });
    let s = Scenario::from_json(&base(
        r#"{"type": "delayed_driver", "graph": {"type": "bidirectional_ring", "gain_pred": [0.5, 0.5, 0.6, 0.5], "gain_follow": 0.2}, "delay_s": 0.3}"#,
        "",
    ))
    .unwrap();
    let Model::DelayedDriver(m) = s.model() else {
        panic!("delayed-driver scenario")
    };
    assert_eq!(
        m.shape,
        GraphShape::BidirectionalRing {
            gain_pred: None,
            gain_follow: Some(0.2)
        }
    );
}

#[test]
fn a_replacement_model_must_fit_the_scenario() {
    use syncroad_control::scenario::Model;
    let s = Scenario::from_json(&base(RING, "")).unwrap();
    let Model::DelayedDriver(m) = s.model() else {
        panic!("delayed-driver scenario")
    };
    // Doubled delays on the grid are accepted and change nothing else but the hash: another
    // model is another scenario, and records and sweep rows must not mistake one for the other.
    let mut doubled = m.clone();
    for (d, k) in doubled
        .delay_s
        .iter_mut()
        .zip(doubled.delay_steps.iter_mut())
    {
        *d *= 2.0;
        *k *= 2;
    }
    let t = s.with_model(Model::DelayedDriver(doubled.clone())).unwrap();
    assert_eq!(t.initial_speed_mps(), s.initial_speed_mps());
    assert_ne!(t.hash_hex(), s.hash_hex());
    assert_eq!(
        s.with_model(Model::DelayedDriver(doubled.clone()))
            .unwrap()
            .hash_hex(),
        t.hash_hex(),
        "the same replacement gives the same hash"
    );
    let Model::DelayedDriver(tm) = t.model() else {
        panic!("delayed-driver scenario")
    };
    assert_eq!(tm.delay_steps, [6; 4]);
    // Off the grid.
    let mut off = doubled.clone();
    off.delay_s[1] = 0.65;
    let e = s
        .with_model(Model::DelayedDriver(off))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("model.delay_s[1] = 0.65 s is not a whole multiple of step_s = 0.1 s"),
        "{e}"
    );
    // One value too few.
    let mut short = doubled;
    short.delay_s.pop();
    let e = s
        .with_model(Model::DelayedDriver(short))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("model.delay_s has 3 entries but the scenario has 4 vehicles"),
        "{e}"
    );
}

#[test]
fn horizons_beyond_the_step_limit_are_refused_naming_both_fields() {
    let json = base(RING, "").replace(r#""horizon_s": 10"#, r#""horizon_s": 1e12"#);
    let e = err(&json);
    assert_eq!(
        e,
        "horizon_s = 1000000000000 s with step_s = 0.1 s is 10000000000000 steps; at most 10000000 steps are allowed, so give horizon_s ≤ 1000000 s at this step (or a larger step_s)"
    );
    // A tiny step over an ordinary horizon: the same limit, both fields named.
    let json = base(RING, "").replace(r#""step_s": 0.1"#, r#""step_s": 1e-9"#);
    let e = err(&json);
    assert!(
        e.starts_with("horizon_s = 10 s with step_s = 0.000000001 s is 10000000000 steps"),
        "{e}"
    );
    // Just past the limit the count is exact, never a rounded "1.000e7 steps; at most 10000000".
    let json = base(RING, "").replace(r#""horizon_s": 10"#, r#""horizon_s": 1000000.1"#);
    let e = err(&json);
    assert!(
        e.contains("is 10000001 steps; at most 10000000 steps are allowed"),
        "{e}"
    );
    // The largest horizon allowed runs.
    let json = base(RING, "").replace(r#""horizon_s": 10"#, r#""horizon_s": 1e6"#);
    assert_eq!(Scenario::from_json(&json).unwrap().steps(), 10_000_000);
}

#[test]
fn delay_buffers_beyond_the_limit_are_refused() {
    // 0.3 s at 1e-7 s is 3·10⁶ steps of 4 vehicles: 1.2·10⁷ values fit; 0.6 s does not.
    let short = base(RING, "")
        .replace(r#""step_s": 0.1"#, r#""step_s": 1e-7"#)
        .replace(r#""horizon_s": 10"#, r#""horizon_s": 0.5"#)
        .replace(
            r#""model""#,
            r#""verdict": {"tolerance_mps": 0.05, "window_s": 0.1}, "model""#,
        );
    if let Err(e) = Scenario::from_json(&short) {
        panic!("{e}");
    }
    let e = err(&short.replace(r#""delay_s": 0.3"#, r#""delay_s": 0.6"#));
    assert!(
        e.starts_with("model.delay_s[0] = 0.6 s with step_s = 0.0000001 s needs a delay buffer of 2.400e7 values; at most 16777216 are allowed, so give step_s ≥ 1.431e-7 s"),
        "{e}"
    );
}

#[test]
fn nan_and_infinity_literals_name_their_field() {
    for (lit, text) in [
        ("NaN", r#""delay_s": NaN"#),
        ("Infinity", r#""delay_s": Infinity"#),
        ("-Infinity", r#""delay_s": -Infinity"#),
    ] {
        let json = base(RING, "").replace(r#""delay_s": 0.3"#, text);
        assert!(json.contains(text), "the fixture has a delay to replace");
        let e = err(&json);
        assert!(
            e.starts_with(&format!(
                "delay_s = {lit}: JSON has no {lit}: write a finite number (line "
            )),
            "{e}"
        );
    }
}
