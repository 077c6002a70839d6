//! End-to-end tests of the `syncroad` binary: exit codes, messages, files written.

mod common;
use common::*;

#[test]
fn check_certifies_the_example_ring_and_names_the_binding_vehicle() {
    let (code, out, _) = run(bin()
        .arg("check")
        .arg(repo().join("scenarios/ring-theorem1.json")));
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("Theorem 1 (strongly connected, α_j d_j^+ < 1/2): HOLDS"),
        "{out}"
    );
    // Vehicle 2 has α = 0.7 and d^+ = 0.7: the largest product 0.49.
    assert!(out.contains("vehicle     2: 0.490000 < 0.500000"), "{out}");
}

/// The conditions certify the model's law on every vehicle; a scenario whose runs the user's
/// own controller drives is not what they certify: the verdict line says so and the command
/// exits 1 (no `CERTIFIED` with exit 1), while the model's own ring stays certified (exit 0).
#[test]
fn check_of_a_scenario_driven_by_an_own_controller_says_not_certified_and_exits_1() {
    let (code, out, _) = run(bin()
        .arg("check")
        .arg(repo().join("scenarios/sugiyama-python.json")));
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("verdict: this scenario is NOT certified: its runs are driven by python:FollowerStopper (controller.python = "),
        "{out}"
    );
    assert!(out.contains("which they certify"), "{out}");
    assert!(!out.contains("verdict: synchronization CERTIFIED"), "{out}");
    let (code, out, _) = run(bin()
        .args(["check", "--json"])
        .arg(repo().join("scenarios/sugiyama-python.json")));
    assert_eq!(code, 1);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(
        (v["certified"].as_bool(), v["scenario_certified"].as_bool()),
        (Some(true), Some(false))
    );
    let (code, out, _) = run(bin()
        .args(["check", "--json"])
        .arg(repo().join("scenarios/sugiyama-ring.json")));
    assert_eq!(code, 0, "{out}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["scenario_certified"], true);
    assert!(v.get("not_certified_because").is_none());
}

#[test]
fn check_json_is_machine_readable_and_unstable_ring_exits_1() {
    let (code, out, _) = run(bin()
        .args(["check", "--json"])
        .arg(repo().join("scenarios/ring-unstable.json")));
    assert_eq!(code, 1);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["certified"], false);
    // ring-unstable.json: α = 0.8 s, K = 1.5 /s.
    let two_alpha_k = v["chandler"]["two_alpha_k"].as_f64().unwrap();
    assert!(
        (two_alpha_k - 2.0 * 0.8 * 1.5).abs() < 1e-12,
        "{two_alpha_k}"
    );
}

#[test]
fn simulate_writes_trajectories_and_metrics() {
    let dir = tmpdir("sim");
    let (code, out, err) = run(bin()
        .arg("simulate")
        .arg(repo().join("scenarios/ring-theorem1.json"))
        .arg("--out")
        .arg(&dir));
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("verdict: synchronized"), "{out}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["sync"]["verdict"], "synchronized");
    assert_eq!(m["seed"], 42);
    assert_eq!(m["backend"], "native");
    let csv = std::fs::read_to_string(dir.join("trajectories.csv")).unwrap();
    assert!(csv.starts_with("time_s,vehicle,speed_mps,position_m,gap_m\n"));
    // 300 s at 0.1 s: 3000 steps; the default stride is max(3000 / 2000, 1) = 1, so 3001 samples.
    assert_eq!(csv.lines().count(), 1 + 22 * 3001);
}

#[test]
fn diverging_run_is_not_synchronized_and_still_writes_results() {
    let dir = tmpdir("div");
    let (code, out, _) = run(bin()
        .arg("simulate")
        .arg(repo().join("scenarios/ring-unstable.json"))
        .arg("--out")
        .arg(&dir));
    assert_eq!(code, 1);
    assert!(out.contains("diverged"), "{out}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["stop"]["reason"], "diverged");
    assert_eq!(m["sync"]["incomplete"], true);
}

#[test]
fn bad_scenario_exits_2_naming_the_field() {
    let dir = tmpdir("bad");
    let p = dir.join("bad.json");
    std::fs::write(
        &p,
        r#"{"seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": 3, "road": {"type": "ring", "length_m": 100},
            "model": {"type": "delayed_driver", "graph": {"type": "unidirectional_ring", "gain": 0.5}, "delay_s": [0.1, 0.25, 0.1]}}"#,
    )
    .unwrap();
    let (code, _, err) = run(bin().arg("check").arg(&p));
    assert_eq!(code, 2);
    assert!(
        err.starts_with(
            "error: model.delay_s[1] = 0.25 s is not a whole multiple of step_s = 0.1 s"
        ),
        "{err}"
    );
    let (code, _, err) = run(bin().arg("check").arg(dir.join("missing.json")));
    assert_eq!(code, 2);
    assert!(
        err.contains("cannot read scenario file") && err.contains("missing.json"),
        "{err}"
    );
}

#[test]
fn simulate_is_deterministic() {
    let (a, b) = (tmpdir("det-a"), tmpdir("det-b"));
    for d in [&a, &b] {
        let (code, _, _) = run(bin()
            .arg("simulate")
            .arg(repo().join("scenarios/platoon-cacc.json"))
            .arg("--out")
            .arg(d));
        assert_eq!(code, 0);
    }
    for f in ["metrics.json", "trajectories.csv"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f} differs"
        );
    }
}

#[test]
fn committed_baselines_pass() {
    for b in ["ring-theorem1.native.json", "platoon-cacc.native.json"] {
        let (code, out, err) = run(bin()
            .arg("regress")
            .arg(repo().join("tests/baselines").join(b)));
        assert_eq!(code, 0, "{b}: {out}{err}");
        assert!(out.contains(": PASS ("), "{out}");
    }
}

#[test]
fn planted_regression_fails_with_a_readable_diff() {
    // The same baseline against a scenario whose predecessor gain dropped from 0.6 to 0.5.
    let dir = tmpdir("planted");
    let scenario = std::fs::read_to_string(repo().join("scenarios/ring-theorem1.json")).unwrap();
    let planted = scenario.replace(r#""gain_pred": 0.6"#, r#""gain_pred": 0.5"#);
    assert_ne!(planted, scenario, "the planted change must apply");
    std::fs::write(dir.join("ring.json"), planted).unwrap();
    let baseline =
        std::fs::read_to_string(repo().join("tests/baselines/ring-theorem1.native.json")).unwrap();
    let mut b: serde_json::Value = serde_json::from_str(&baseline).unwrap();
    b["scenario"] = "ring.json".into();
    std::fs::write(
        dir.join("baseline.json"),
        serde_json::to_string(&b).unwrap(),
    )
    .unwrap();
    let (code, out, err) = run(bin().arg("regress").arg(dir.join("baseline.json")));
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains(": FAIL ("), "{out}");
    assert!(out.contains("sync.spread_l2"), "{out}");
    assert!(out.contains("scenario_hash"), "{out}");
    // --update accepts the new behaviour, after which it passes.
    let (code, _, _) = run(bin()
        .arg("regress")
        .arg(dir.join("baseline.json"))
        .arg("--update"));
    assert_eq!(code, 0);
    let (code, out, _) = run(bin().arg("regress").arg(dir.join("baseline.json")));
    assert_eq!(code, 0, "{out}");
}

#[test]
fn a_tolerance_for_a_metric_the_baseline_lacks_is_refused_naming_the_nearest() {
    let dir = tmpdir("tolerance-typo");
    let mut b: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("tests/baselines/ring-theorem1.native.json")).unwrap(),
    )
    .unwrap();
    b["scenario"] = repo()
        .join("scenarios/ring-theorem1.json")
        .display()
        .to_string()
        .into();
    let write = |b: &serde_json::Value| {
        let p = dir.join("baseline.json");
        std::fs::write(&p, serde_json::to_string(b).unwrap()).unwrap();
        p
    };
    // A typo, and a prefix under which no metric lies: each would silently keep the default.
    for (key, says) in [
        (
            "sync.spread_l3",
            "no metric of the baseline is called that; the nearest is sync.spread_l2",
        ),
        (
            "syncc.*",
            "no metric of the baseline is under that prefix; the nearest is sync.*",
        ),
    ] {
        b["tolerances"]["keys"] = serde_json::json!({ key: {"abs": 1.0, "rel": 0.0} });
        let (code, out, err) = run(bin().arg("regress").arg(write(&b)));
        assert_eq!(code, 2, "{key}: {out}{err}");
        assert!(
            err.contains(&format!("tolerances.keys.{key}: {says}")),
            "{err}"
        );
    }
    // Real keys and prefixes pass.
    b["tolerances"]["keys"] = serde_json::json!({
        "sync.spread_l2": {"abs": 1e-6, "rel": 0.0}, "congestion.*": {"abs": 1e-6, "rel": 0.0}});
    let (code, out, err) = run(bin().arg("regress").arg(write(&b)));
    assert_eq!(code, 0, "{out}{err}");
}

#[test]
fn ifp_command_reproduces_the_cacc_index_and_rejects_non_hurwitz_rho() {
    // CACC agent with μ = 1.25, τ = 0.2 (μτ < 1/2): α = 1/μ² = 0.64 (proof of Theorem thm.cacc).
    let (code, out, _) = run(bin().args(["ifp", "--eta", "1", "--rho", "1.25,1,0.2", "--json"]));
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!((v["alpha"].as_f64().unwrap() - 0.64).abs() < 1e-12, "{out}");
    let (code, _, err) = run(bin().args(["ifp", "--eta", "1", "--rho", "1,-1,1"]));
    assert_eq!(code, 2);
    assert!(err.contains("is not Hurwitz"), "{err}");
}

#[test]
fn stability_of_the_unstable_ring_matches_the_closed_form_critical_gain() {
    // Uniform one-way ring: the slowest mode crosses at αKc* = (π/N)/(2 sin(π/N)).
    let (code, out, err) = run(bin()
        .args(["stability", "--json"])
        .arg(repo().join("scenarios/ring-unstable.json")));
    assert_eq!(code, 1, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["exactly_stable"], false);
    let n = 22.0f64;
    let x = std::f64::consts::PI / n;
    let expect = x / (2.0 * x.sin()) / (0.8 * 1.5);
    let fast = v["ring"]["critical_gain_scale"].as_f64().unwrap();
    let full = v["network"]["critical"]["critical_gain_scale"]
        .as_f64()
        .unwrap();
    assert!((fast - expect).abs() < 1e-12 * expect, "{fast} vs {expect}");
    assert!((full - expect).abs() < 1e-7 * expect, "{full} vs {expect}");
}

#[test]
fn a_graph_without_a_spanning_tree_does_not_synchronize_on_any_path() {
    // 22 drivers on a ring of which only 1 and 3 see anybody (0 → 1, 2 → 3): acyclic, so the
    // per-driver factors once read the twenty d_i = 0 drivers' roots s = 0 as consensus.
    let dir = tmpdir("no-spanning-tree");
    let mut sc: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/ring-theorem1.json")).unwrap(),
    )
    .unwrap();
    sc["model"]["graph"] = serde_json::json!({"type": "edges", "edges": [
        {"from": 0, "to": 1, "weight": 0.5}, {"from": 2, "to": 3, "weight": 0.5}]});
    let path = dir.join("two-edges.json");
    std::fs::write(&path, sc.to_string()).unwrap();
    let (code, out, err) = run(bin().arg("stability").arg(&path));
    assert_eq!(code, 1, "{out}{err}");
    assert!(out.contains("exact: does NOT synchronize"), "{out}");
    // One zero root per driver nobody influences: 0, 2 and 4 … 21.
    assert!(out.contains("has multiplicity 20"), "{out}");
    let (_, json, _) = run(bin().args(["stability", "--json"]).arg(&path));
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["verdict"], "does_not_synchronize", "{v}");
    assert_eq!(v["no_spanning_tree"]["consensus_multiplicity"], 20);
    // The independent witness: simulated, the initial spread stays (drivers 4 … 21 never
    // change speed), where a synchronizing ring ends below the tolerance.
    let (code, out, err) = run(bin()
        .arg("simulate")
        .arg(&path)
        .arg("--out")
        .arg(dir.join("sim"))
        .arg("--no-plots"));
    assert_eq!(code, 1, "{out}{err}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sim/metrics.json")).unwrap())
            .unwrap();
    let (initial, last) = (
        m["sync"]["initial_spread_mps"].as_f64().unwrap(),
        m["sync"]["final_spread_mps"].as_f64().unwrap(),
    );
    assert!(last > 0.5 * initial, "{initial} → {last}");
}

#[test]
fn stability_of_chandler_chain_is_exact_and_map_draws_both_boundaries() {
    let (code, out, _) = run(bin()
        .args(["stability", "--json"])
        .arg(repo().join("scenarios/straight-chandler.json")));
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // Every driver: s + K e^{−sα} = 0 with K = 0.6, α = 0.8; critical scale π/(2αK).
    let c = v["acyclic"]["critical_gain_scale"].as_f64().unwrap();
    assert!((c - std::f64::consts::FRAC_PI_2 / 0.48).abs() < 1e-12);
    let re = v["acyclic"]["abscissa"].as_f64().unwrap();
    let im = v["acyclic"]["drivers"][0]["im"].as_f64().unwrap();
    let s = (re, im);
    // Residual of the scalar equation at the reported root.
    let e = (-s.0 * 0.8f64).exp();
    let (c1, s1) = ((s.1 * 0.8f64).cos(), (s.1 * 0.8f64).sin());
    let res = ((s.0 + 0.6 * e * c1).powi(2) + (s.1 - 0.6 * e * s1).powi(2)).sqrt();
    assert!(res < 1e-12, "{res}");

    let dir = tmpdir("map");
    let (code, out, err) = run(bin()
        .args([
            "map",
            "--x",
            "gain_scale=0.5:4:8",
            "--y",
            "delay_scale=0.5:4:6",
            "--no-sim",
            "--out",
        ])
        .arg(&dir)
        .arg(repo().join("scenarios/straight-chandler.json")));
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("48 grid points"), "{out}");
    let csv = std::fs::read_to_string(dir.join("map.csv")).unwrap();
    assert_eq!(csv.lines().count(), 49);
    // Points with c·r below the exact product π/(2·0.48) are exactly stable, above are not.
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let (x, y): (f64, f64) = (f[0].parse().unwrap(), f[1].parse().unwrap());
        let stable = f[4] == "true";
        assert_eq!(stable, x * y < std::f64::consts::FRAC_PI_2 / 0.48, "{line}");
    }
    assert!(dir.join("map.png").exists() && dir.join("map.svg").exists());
}

#[test]
fn check_prints_a_violated_bound_as_violated() {
    // straight-chandler: driver 0 has α(d + 2b) = 0.8 · (0 + 2 · 0.6) = 0.96 > 1/2.
    let (_, out, _) = run(bin()
        .arg("check")
        .arg(repo().join("scenarios/straight-chandler.json")));
    assert!(out.contains("0.960000 ≥ 0.500000"), "{out}");
    assert!(!out.contains("0.960000 < 0.500000"), "{out}");
}

#[test]
fn stability_of_an_all_to_all_graph_has_the_lambert_w_root_of_multiplicity_four() {
    // all_to_all, N = 5, k = 0.1, α = 0.5: det M = s (s + 0.5 e^{−0.5 s})⁴; the root is
    // W_0(−0.25)/0.5, W_0(−0.25) solving w e^w = −0.25 (Newton here).
    let dir = tmpdir("a2a");
    let p = dir.join("a2a.json");
    std::fs::write(
        &p,
        r#"{"name": "a2a5", "seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": 5,
            "road": {"type": "ring", "length_m": 200},
            "model": {"type": "delayed_driver", "graph": {"type": "all_to_all", "gain": 0.1},
                      "delay_s": [0.5, 0.5, 0.5, 0.5, 0.6]}}"#,
    )
    .unwrap();
    let (code, out, err) = run(bin().args(["stability", "--json"]).arg(&p));
    assert_eq!(code, 0, "{out}{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let mut w = -0.3f64;
    for _ in 0..50 {
        w -= (w * w.exp() + 0.25) / ((1.0 + w) * w.exp());
    }
    let root = &v["network"]["roots"]["roots"][0];
    assert!(
        (root["root"]["re"].as_f64().unwrap() - w / 0.5).abs() < 1e-10,
        "{root}"
    );
    // Four vehicles share the delay 0.5: the root has multiplicity 3 here (x_5 = 0, Σx = 0).
    assert_eq!(root["multiplicity"], 3, "{root}");
    assert_eq!(v["verdict"], "synchronizes");
    assert_eq!(v["network"]["certificate"]["certified"], true);
}

/// The CACC platoon's critical gain scale: a homogeneous platoon's root pair crosses where
/// `τs³ + s² + μs + cλ` meets the axis for a real coupling eigenvalue λ, at `ω = √(μ/τ)`
/// whatever λ (the real and imaginary parts vanish together), and Theorem `thm.cacc`, a
/// sufficient condition, never reaches beyond it.
#[test]
fn stability_gives_the_cacc_platoons_critical_gain_scale() {
    let (code, out, err) = run(bin()
        .args(["stability", "--json"])
        .arg(repo().join("scenarios/platoon-cacc.json")));
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let c = &v["cacc"]["critical"];
    let (mu, tau) = (1.2_f64, 0.3_f64); // the scenario's model.mu and model.tau_s
    let w = c["crossing_frequency_rad_s"].as_f64().unwrap();
    assert!((w - (mu / tau).sqrt()).abs() < 1e-9, "{c}");
    let cs = c["critical_gain_scale"].as_f64().unwrap();
    let t = c["theorem_gain_scale"].as_f64().unwrap();
    assert!(cs > 1.0 && t <= cs, "{c}");
    // The theorem's scale: its tightest margin μ²/2 − rhs_i of the table, linear in c
    // (follower 2..7: rhs = η + ν = 0.6, so 0.72/0.6 = 1.2).
    assert!((t - 0.5 * mu * mu / 0.6).abs() < 1e-12, "{c}");
}

#[test]
fn platoon_scaling_option_fits_the_exponents() {
    let (code, out, err) = run(bin()
        .args(["stability", "--json", "--platoon-scaling"])
        .arg(repo().join("scenarios/platoon-cacc.json")));
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let fits: Vec<f64> = v["platoon_scaling"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["exponent"].as_f64().unwrap())
        .collect();
    // Symmetric gap gains (paper's law) and symmetric relative-velocity law: −2; mistuned
    // relative-velocity law: −1 (Barooah, Mehta & Hespanha).
    assert!((fits[1] + 2.0).abs() < 0.1, "{fits:?}");
    assert!((fits[2] + 2.0).abs() < 0.1, "{fits:?}");
    assert!((fits[3] + 1.0).abs() < 0.1, "{fits:?}");
}

#[test]
fn check_predicts_contact_on_the_weak_gain_ring_and_none_on_the_demo_ring() {
    let text = std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    for k in ["gain_pred", "gain_follow"] {
        let g = v["model"]["graph"][k].as_f64().unwrap();
        v["model"]["graph"][k] = serde_json::json!(0.25 * g);
    }
    v["sumo"]["net"] = serde_json::json!(repo().join("sumo-nets/sugiyama-ring.net.xml"));
    let dir = tmpdir("check-gaps");
    let weak = dir.join("weak.json");
    std::fs::write(&weak, v.to_string()).unwrap();
    let (_, out, err) = run(bin().arg("check").arg(&weak));
    assert!(
        out.contains("but the gaps may shrink by up to")
            && out.contains("contact at the scenario's own perturbation"),
        "{out}{err}"
    );
    let (_, out, _) = run(bin().args(["check", "--json"]).arg(&weak));
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["gap_certificate"]["own_contact"], true);
    assert!(j["gap_certificate"]["own_min_gap_m"].as_f64().unwrap() < 0.0);
    let (code, out, _) = run(bin()
        .arg("check")
        .arg(repo().join("scenarios/sugiyama-ring.json")));
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("synchronizes, and no contact for speed perturbations up to"),
        "{out}"
    );
}

#[test]
fn stability_certifies_the_clustered_ring_without_the_bisection() {
    let (code, out, err) = run(bin()
        .args(["stability", "--json"])
        .arg(repo().join("scenarios/het50-bidir-clustered.json")));
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let c = &v["network"]["critical"];
    assert_eq!(c["method"], "continuation", "{c}");
    assert_eq!(c["certified"], true);
    assert_eq!(c["reference"], "theorem1");
    assert_eq!(v["critical_scale_status"], "certified");
    let (_, out, _) = run(bin()
        .arg("stability")
        .arg(repo().join("scenarios/het50-bidir-clustered.json")));
    assert!(
        out.contains("full solve(s)): at c*") && out.contains("-> certified"),
        "{out}"
    );
}

/// `scenarios/ring-theorem1.json` (native) with `edit` applied, written as `name` into `dir`.
fn native_variant(
    dir: &std::path::Path,
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value),
) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo().join("scenarios/ring-theorem1.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut v);
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    p
}

/// What the native simulator cannot do is refused, not silently left out: a scenario's mixed
/// block with SUMO's own drivers (it once ran every vehicle with the law and said
/// "synchronized"; the stochastic humans syncroad computes do run), a SUMO-only flag,
/// and a fleet too large to allocate; and `check` does not certify a mixed ring.
#[test]
fn what_a_native_run_cannot_do_is_refused_up_front() {
    let d = tmpdir("native-refusals");
    let mixed = native_variant(&d, "mixed.json", |v| {
        v["horizon_s"] = 20.into();
        v["mixed"] = serde_json::json!({"penetration": 0.5, "controller": "follower-stopper-0"});
    });
    let (code, out, err) = run(bin()
        .arg("simulate")
        .arg(&mixed)
        .arg("--out")
        .arg(d.join("o1")));
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("its mixed block puts SUMO's own drivers among the law's vehicles"),
        "{err}"
    );
    assert!(!d.join("o1/metrics.json").exists());
    // What is printed and the exit code agree: the conditions may certify the law on every
    // vehicle, but not this mixed ring, and the verdict line says so.
    let (code, out, err) = run(bin().arg("check").arg(&mixed));
    assert_eq!(code, 1, "a mixed ring is not certified: {out}{err}");
    assert!(
        out.contains("verdict: this scenario is NOT certified: its mixed block drives"),
        "{out}"
    );
    assert!(!out.contains("verdict: synchronization CERTIFIED"), "{out}");
    let (code, out, _) = run(bin().args(["check", "--json"]).arg(&mixed));
    assert_eq!(code, 1);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["scenario_certified"], false, "{out}");
    assert!(v["not_certified_because"]
        .as_str()
        .unwrap()
        .starts_with("its mixed block drives"));
    let plain = native_variant(&d, "plain.json", |v| v["horizon_s"] = 20.into());
    let (code, _, err) = run(bin()
        .arg("run")
        .arg(&plain)
        .args(["--krauss-sigma", "0.5", "--out"])
        .arg(d.join("o2")));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--krauss-sigma: a SUMO option"), "{err}");
    let huge = native_variant(&d, "huge.json", |v| {
        v["vehicles"] = 100_000_000u64.into();
        v["model"]["delay_s"] = 0.5.into();
    });
    let (code, _, err) = run(bin()
        .arg("simulate")
        .arg(&huge)
        .arg("--out")
        .arg(d.join("o3")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("vehicles = 100000000: at most 1000000"),
        "{err}"
    );
}

/// `--pdf` writes each plot also as a PDF page with real text in the embedded font (poppler's
/// pdftotext reads the title and the axis labels back), and a later run without it removes
/// them with the other plots.
#[test]
fn pdf_plots_carry_real_text_and_leave_with_their_run() {
    let d = tmpdir("pdf-plots");
    let sc = native_variant(&d, "s.json", |_| {});
    let out = d.join("out");
    let (code, stdout, err) = run(bin()
        .arg("simulate")
        .arg(&sc)
        .arg("--pdf")
        .arg("--out")
        .arg(&out));
    assert_eq!(code, 0, "{err}");
    assert!(
        stdout.contains("wrote 9 plots: time_space, speeds, spread (PNG, SVG and PDF)"),
        "{stdout}"
    );
    for stem in ["time_space", "speeds", "spread"] {
        let pdf = std::fs::read(out.join(format!("{stem}.pdf"))).unwrap();
        assert!(pdf.starts_with(b"%PDF-"), "{stem}");
        let text = String::from_utf8_lossy(&pdf);
        // A TrueType subset embedded, with the map from glyphs back to Unicode.
        assert!(
            text.contains("/FontFile2") && text.contains("/ToUnicode"),
            "{stem}: no embedded font with a Unicode map"
        );
    }
    match std::process::Command::new("pdftotext")
        .arg(out.join("speeds.pdf"))
        .arg("-")
        .output()
    {
        Ok(o) => {
            let text = String::from_utf8_lossy(&o.stdout);
            assert!(
                text.contains("speeds")
                    && text.contains("speed [m/s]")
                    && text.contains("time [s]"),
                "{text}"
            );
        }
        Err(_) => {
            eprintln!("skipped the text check: pdftotext is not installed (scripts/test.sh installs Debian's poppler-utils)")
        }
    }
    let (code, stdout, err) = run(bin().arg("simulate").arg(&sc).arg("--out").arg(&out));
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("(PNG and SVG)"), "{stdout}");
    assert!(
        !out.join("speeds.pdf").exists(),
        "the first run's PDF was left behind"
    );
}

/// A second run into a folder removes the first run's plots (they would stand beside another
/// run's record), a folder where a plot goes is refused before the run, and a recording
/// stride as long as the run leaves the congestion metrics out instead of making them up.
#[test]
fn a_run_folder_holds_one_run_and_coarse_recording_reports_no_congestion() {
    let d = tmpdir("one-run-folder");
    let sc = native_variant(&d, "s.json", |_| {});
    let out = d.join("out");
    let (code, _, err) = run(bin().arg("simulate").arg(&sc).arg("--out").arg(&out));
    assert_eq!(code, 0, "{err}");
    assert!(out.join("time_space.png").is_file());
    let (code, _, err) = run(bin()
        .arg("simulate")
        .arg(&sc)
        .args(["--no-plots", "--record-every", "100000", "--out"])
        .arg(&out));
    assert_eq!(code, 0, "{err}");
    assert!(
        !out.join("time_space.png").exists(),
        "the first run's plot was left behind"
    );
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert!(m["congestion"].is_null(), "{}", m["congestion"]);
    assert_eq!(
        m["sync"]["verdict"], "synchronized",
        "the spread is kept at every step"
    );
    let blocked = d.join("blocked");
    std::fs::create_dir_all(blocked.join("spread.png")).unwrap();
    let (code, _, err) = run(bin().arg("simulate").arg(&sc).arg("--out").arg(&blocked));
    assert_eq!(code, 2, "{err}");
    assert!(!blocked.join("metrics.json").exists());
}

/// The Sugiyama ring run natively with every gain multiplied by `scale`.
fn sugiyama_scaled(dir: &std::path::Path, scale: f64) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["backend"] = "native".into();
    v.as_object_mut().unwrap().remove("sumo");
    for k in ["gain_pred", "gain_follow"] {
        let g = v["model"]["graph"][k].as_f64().unwrap();
        v["model"]["graph"][k] = (g * scale).into();
    }
    let path = dir.join(format!("sugiyama-x{scale:e}.json"));
    std::fs::write(&path, v.to_string()).unwrap();
    path
}

#[test]
fn exact_analysis_refuses_gains_below_its_resolution_and_map_leaves_them_blank() {
    let dir = tmpdir("tiny-gains");
    // Largest gain × delay (0.6 + 0.1) · 1e-11 · 0.7 = 4.9e-12: the root-count certificate used
    // to fail there on a spurious root (exit 3); it is below the documented limit 1e-8.
    let (code, out, err) = run(bin().arg("stability").arg(sugiyama_scaled(&dir, 1e-11)));
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("model.graph"), "{err}");
    assert!(err.contains("is 4.900e-12"), "{err}");
    assert!(err.contains("at least 1e-8"), "{err}");
    // The same cause is not printed twice.
    assert_eq!(
        err.matches("within the root searches' tolerances").count(),
        1,
        "{err}"
    );

    // A map whose gain axis reaches 1e-300 used to run without end. Theorem 1 certifies both
    // columns (α d⁺ ≤ 0.49 · 1e-6); the exact verdict is blank at 1e-300 and, at 1e-6, agrees
    // with the theorem.
    let (code, out, err) = run(bin()
        .args([
            "map",
            "--x",
            "gain_scale=1e-300:1e-6:2",
            "--y",
            "delay_scale=0.5:1:2",
        ])
        .args(["--no-sim", "--out"])
        .arg(dir.join("map"))
        .arg(sugiyama_scaled(&dir, 1.0)));
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("2 without an exact verdict"), "{out}");
    let csv = std::fs::read_to_string(dir.join("map/map.csv")).unwrap();
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[2], "true", "{line}");
        let x: f64 = f[0].parse().unwrap();
        assert_eq!(f[4], if x < 1e-100 { "" } else { "true" }, "{line}");
    }
}

/// The guide's Rust program with its own law (`examples/own_law.rs`, built with the tests):
/// on both backends its speeds agree on the initial mean, which the law conserves.
#[test]
fn a_rust_program_runs_its_own_law_on_both_backends() {
    let exe = std::env::current_exe().unwrap();
    let examples = exe.parent().unwrap().parent().unwrap().join("examples");
    let p = std::process::Command::new(examples.join("own_law"))
        .output()
        .expect("the example is built with the tests (cargo test builds examples)");
    let stdout = String::from_utf8_lossy(&p.stdout);
    assert!(
        p.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&p.stderr)
    );
    assert!(
        stdout.contains("Native: Synchronized, drivers rust:follow"),
        "{stdout}"
    );
    assert!(
        stdout.contains("Sumo: Synchronized, drivers rust:follow"),
        "{stdout}"
    );
}

/// A built-in law of the registry named in the scenario's `controller` block drives the ring
/// on both backends, and its speeds follow the closed form of a target tracked within the
/// vehicle type's bounds: `v(t) = max(v₀ − b t, U)` from above and `min(v₀ + a t, U)` from
/// below (SUMO's defaults a = 2.6, b = 4.5 m/s²), to rounding.
#[test]
fn a_built_in_law_named_in_the_scenario_follows_its_closed_form_on_both_backends() {
    let dir = tmpdir("constant-speed");
    let path = edited_scenario(&dir, "sugiyama-ring", |sc| {
        sc["horizon_s"] = serde_json::json!(20);
        sc["controller"] =
            serde_json::json!({"rust": "constant-speed", "params": {"target_speed_mps": 8.0}});
    });
    for command in ["simulate", "run"] {
        let out = dir.join(command);
        let (code, stdout, err) = run(bin().arg(command).arg(&path).arg("--out").arg(&out));
        assert!(code == 0 || code == 1, "{command}: {stdout}{err}");
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["drivers"][0], "constant-speed-8", "{command}");
        let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
        let mut v0 = std::collections::BTreeMap::new();
        let mut worst: f64 = 0.0;
        let mut moved: f64 = 0.0;
        for line in csv.lines().skip(1) {
            let f: Vec<f64> = line
                .split(',')
                .take(3)
                .map(|x| x.parse().unwrap())
                .collect();
            let (t, i, v) = (f[0], f[1] as usize, f[2]);
            let start = *v0.entry(i).or_insert(v);
            let expected = if start > 8.0 {
                (start - 4.5 * t).max(8.0)
            } else {
                (start + 2.6 * t).min(8.0)
            };
            worst = worst.max((v - expected).abs());
            moved = moved.max((v - start).abs());
        }
        assert!(
            moved > 1.0,
            "{command}: the speeds hardly moved ({moved} m/s)"
        );
        assert!(
            worst < 1e-9,
            "{command}: largest departure from the closed form {worst} m/s"
        );
    }
}

/// Gipps' safe speed with SUMO's defaults (τ = 1 s, b = 4.5 m/s², s₀ = 2.5 m), written again
/// here from the formula of the guide.
fn gipps(gap: f64, leader: f64) -> f64 {
    let (b, tau, s0) = (4.5, 1.0, 2.5);
    let d = (b * tau) * (b * tau) + leader * leader + 2.0 * b * (gap - s0);
    if d <= 0.0 {
        0.0
    } else {
        (d.sqrt() - b * tau).max(0.0)
    }
}

/// The safety filter under a law that wants 8 m/s on the Sugiyama ring (22 cars of 5 m on
/// 230 m, evenly spaced, from 2 m/s): every speed reached is within Gipps' safe speed from the
/// gap and the leader's speed a step before, and the ring settles where the safe speed of a
/// uniform flow is its own speed, v = (s − s₀)/τ with s = L/N − ℓ (2.9545 m/s natively, a
/// little more on SUMO's measured ring); the run is safe and the record says the filter cut
/// commands.
#[test]
fn the_safety_filter_holds_a_law_to_gipps_safe_speed_on_both_backends() {
    let dir = tmpdir("safety-filter");
    let path = edited_scenario(&dir, "sugiyama-ring", |sc| {
        sc["horizon_s"] = serde_json::json!(60);
        sc["initial"] = serde_json::json!({"speed_mps": 2.0});
        sc["controller"] =
            serde_json::json!({"rust": "constant-speed", "params": {"target_speed_mps": 8.0}});
        sc["safety"] = serde_json::json!("filter");
    });
    for command in ["simulate", "run"] {
        let out = dir.join(command);
        let (code, stdout, err) = run(bin()
            .arg(command)
            .arg(&path)
            .arg("--out")
            .arg(&out)
            .arg("--record-every")
            .arg("1"));
        assert!(code == 0 || code == 1, "{command}: {stdout}{err}");
        assert!(
            stdout.contains("  safety layer: filter (Gipps' safe speed; "),
            "{stdout}"
        );
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(m["safe"], true, "{command}: {}", m["unsafe_because"]);
        assert_eq!(m["safety_layer"]["mode"], "filter");
        assert!(m["safety_layer"]["filter"]["overrides"].as_u64().unwrap() > 0);
        let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
        // (step, vehicle) → (speed, gap); the vehicle ahead of i is i − 1 (0 follows 21).
        let mut rows: std::collections::BTreeMap<(i64, usize), (f64, f64)> = Default::default();
        for line in csv.lines().skip(1) {
            let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            rows.insert(((f[0] * 10.0).round() as i64, f[1] as usize), (f[2], f[4]));
        }
        let last = rows.keys().map(|k| k.0).max().unwrap();
        assert_eq!(last, 600, "{command}: the run reached its horizon");
        let mut worst: f64 = f64::NEG_INFINITY;
        for k in 0..last {
            for i in 0..22 {
                let (_, gap) = rows[&(k, i)];
                let (v_lead, _) = rows[&(k, (i + 21) % 22)];
                let (v_next, _) = rows[&(k + 1, i)];
                worst = worst.max(v_next - gipps(gap, v_lead));
            }
        }
        assert!(
            worst <= 1e-9,
            "{command}: a speed above the safe speed by {worst} m/s"
        );
        for i in 0..22 {
            let (v, gap) = rows[&(last, i)];
            assert!(
                (v - (gap - 2.5) / 1.0).abs() < 1e-6,
                "{command}: vehicle {i} at {v} m/s with a gap of {gap} m"
            );
        }
        // The ring its network measures on both backends: SUMO's lanes, 230.3592 m (a native
        // record names no road length; the scenario's nominal 230 m is within 1 % of it).
        let ring = m["backend_facts"]["road_length_m"]
            .as_f64()
            .unwrap_or(230.3592);
        let uniform = ring / 22.0 - 5.0 - 2.5;
        assert!(
            (rows[&(last, 0)].0 - uniform).abs() < 1e-6,
            "{command}: {} m/s, (L/N − ℓ − s₀)/τ = {uniform} m/s",
            rows[&(last, 0)].0
        );
    }
}

/// SUMO's own checks need SUMO: the native simulator refuses them before it runs, naming what
/// would do.
#[test]
fn the_native_simulator_refuses_sumos_safety_checks() {
    let dir = tmpdir("safety-sumo-native");
    let path = edited_scenario(&dir, "ring-theorem1", |sc| {
        sc["safety"] = serde_json::json!("sumo");
    });
    let (code, _, err) = run(bin()
        .arg("simulate")
        .arg(&path)
        .arg("--out")
        .arg(dir.join("o")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("safety = sumo: SUMO's own checks need SUMO; on the native simulator use \"safety\": \"filter\""),
        "{err}"
    );
    assert!(!dir.join("o").exists());
}

/// A scenario naming a Rust law the CLI does not have says where Rust laws come from.
#[test]
fn a_rust_law_the_program_did_not_register_is_refused_naming_the_field() {
    let dir = tmpdir("rust-law-missing");
    let path = edited_scenario(&dir, "ring-theorem1", |sc| {
        sc["controller"] = serde_json::json!({"rust": "follow", "params": {"gain": 0.5}});
    });
    let (code, _, err) = run(bin()
        .arg("simulate")
        .arg(&path)
        .arg("--out")
        .arg(dir.join("out")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(
            "controller.rust = follow: no law of that name; valid: protocol, follower-stopper-X"
        ) && err.contains("runs from the program that registers it"),
        "{err}"
    );
}

/// The native simulator refuses what only SUMO can drive instead of reporting on a road
/// without it: the user's own traffic (`sumo.routes`) and the user's own vehicles
/// (`sumo.controlled`), with `simulate` and with `"backend": "native"` alike.
#[test]
fn the_native_simulator_refuses_the_users_own_sumo_traffic_and_vehicles() {
    let dir = tmpdir("native-refuses-sumo-traffic");
    let routes = dir.join("slow.rou.xml");
    std::fs::write(
        &routes,
        r#"<routes><vType id="slow" maxSpeed="4"/><route id="loop" edges="arc0 arc1 arc2 arc3"/><vehicle id="slow0" type="slow" route="loop" depart="0"/></routes>"#,
    )
    .unwrap();
    let base: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap(),
    )
    .unwrap();
    let net = repo().join("sumo-nets/sugiyama-ring.net.xml");
    for (key, value, expected) in [
        (
            "routes",
            serde_json::json!([routes]),
            "sumo.routes = ",
        ),
        (
            "controlled",
            serde_json::json!({"vtype": "slow"}),
            "sumo.controlled = {\"vtype\":\"slow\"}: the law drives the user's own SUMO vehicles, which exist only in SUMO",
        ),
    ] {
        let mut sc = base.clone();
        sc["sumo"] = serde_json::json!({"net": net, key: value});
        if key == "controlled" {
            sc["sumo"]["routes"] = serde_json::json!([routes]);
        }
        let path = dir.join(format!("{key}.json"));
        std::fs::write(&path, sc.to_string()).unwrap();
        for (command, out) in [("simulate", "sim"), ("run", "run")] {
            if command == "run" {
                sc["backend"] = "native".into();
                std::fs::write(&path, sc.to_string()).unwrap();
            }
            let (code, stdout, err) = run(bin()
                .arg(command)
                .arg(&path)
                .arg("--out")
                .arg(dir.join(format!("{key}-{out}"))));
            assert_eq!(code, 2, "{command} {key}: {stdout}{err}");
            assert!(err.contains(expected), "{command} {key}: {err}");
            assert!(err.contains("run it on SUMO"), "{err}");
            assert!(!dir.join(format!("{key}-{out}/metrics.json")).exists());
        }
    }
}

/// `check` certifies the start a run drives: a run of the user's own vehicles
/// (`sumo.controlled`) starts from theirs, so the gap certificate of `initial` is said not to
/// apply, in the table and in the JSON, while the same ring without them gets one.
#[test]
fn check_gives_no_gap_certificate_for_the_users_own_vehicles() {
    let dir = tmpdir("check-controlled");
    let routes = dir.join("mine.rou.xml");
    std::fs::write(
        &routes,
        r#"<routes><vType id="mine"/><route id="loop" edges="arc0 arc1 arc2 arc3"/><vehicle id="mine0" type="mine" route="loop" depart="0"/></routes>"#,
    )
    .unwrap();
    let mut sc: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("scenarios/sugiyama-ring.json")).unwrap(),
    )
    .unwrap();
    sc["sumo"] = serde_json::json!({"net": repo().join("sumo-nets/sugiyama-ring.net.xml")});
    let plain = dir.join("plain.json");
    std::fs::write(&plain, sc.to_string()).unwrap();
    sc["sumo"]["routes"] = serde_json::json!([routes]);
    // The user's traffic shares the road: it can change who follows whom, so the fixed
    // graph's certificate does not describe the run either.
    let shared = dir.join("shared.json");
    std::fs::write(&shared, sc.to_string()).unwrap();
    let (_, out, _) = run(bin().arg("check").arg(&shared));
    assert!(
        out.contains("  does not apply: sumo.routes = ") && out.contains("change who follows whom"),
        "{out}"
    );
    assert!(!out.contains("no contact for speed perturbations"), "{out}");
    sc["sumo"]["controlled"] = serde_json::json!({"vtype": "mine"});
    let own = dir.join("own.json");
    std::fs::write(&own, sc.to_string()).unwrap();
    let (_, out, _) = run(bin().arg("check").arg(&plain));
    assert!(
        out.contains("no contact for speed perturbations up to"),
        "{out}"
    );
    let (_, out, _) = run(bin().arg("check").arg(&own));
    assert!(
        out.contains("  does not apply: sumo.controlled = {\"vtype\":\"mine\"}: the run starts the user's own vehicles from their own positions"),
        "{out}"
    );
    assert!(!out.contains("no contact for speed perturbations"), "{out}");
    let (_, out, _) = run(bin().args(["check", "--json"]).arg(&own));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(v["gap_certificate"]["not_applicable"]
        .as_str()
        .unwrap()
        .starts_with("sumo.controlled = "));
}

/// A chain that synchronizes but is string unstable (Kα = 1.5 < π/2, Chandler's 2αK = 3 ≥ 1):
/// `stability` finds it stable, the frequency response amplifies the leader's speed along the
/// chain by far more than 10⁶ (an independent, frequency-domain measure of the transient), and
/// `check` says what is true of its gaps — transient growth, a lower bound on M and the
/// largest perturbation any certificate could allow — instead of "does not synchronize".
#[test]
fn a_string_unstable_chain_that_synchronizes_gets_transient_growth_not_divergence() {
    let dir = tmpdir("string-unstable-chain");
    let path = edited_scenario(&dir, "straight-chandler", |sc| {
        let n = sc["vehicles"].as_u64().unwrap() as usize;
        sc["model"]["graph"]["gain"] = serde_json::json!(1.5);
        sc["model"]["delay_s"] = serde_json::json!(1.0);
        let mut pin = vec![0.0; n];
        pin[0] = 1.5;
        sc["model"]["leader"]["pinning"] = serde_json::json!(pin);
    });
    let (code, stdout, stderr) = run(bin().arg("stability").arg(&path));
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("exact: SYNCHRONIZES"), "{stdout}");
    let amp: f64 = stdout
        .lines()
        .find_map(|l| l.split("sup_ω|T_i(iω)|: worst ").nth(1))
        .and_then(|r| r.split_whitespace().next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("{stdout}\n{stderr}"));
    assert!(amp > 1e6, "{amp}");
    let (_, stdout, _) = run(bin().arg("check").arg(&path));
    let line = stdout
        .lines()
        .find(|l| l.contains("not computed"))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        line.contains("transient growth") && line.contains("string unstable"),
        "{line}"
    );
    assert!(
        !line.contains("the network does not synchronize,"),
        "{line}"
    );
    // The number printed right after `marker` in `line`.
    let after = |marker: &str| -> f64 {
        line.split(marker)
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("no number after {marker:?}: {line}"))
    };
    let (m, safe) = (after("M ≥ "), after("perturbation above "));
    // The bound is past the growth that stopped the integration, and the largest allowed
    // perturbation is an initial gap (25 m) over it.
    assert!(m > 1e3, "{m}");
    assert!((safe * m - 25.0).abs() < 25.0 * 1e-3, "{safe} · {m}");
}

/// `stability` refuses what it cannot analyse as bad input (exit 2, naming the field and the
/// valid range) instead of failing part-way (exit 3): one vehicle, and gains beyond the root
/// searches' reach; just inside that reach (gains × 10⁴ on `ring-theorem1`, gain × delay
/// 4.9e3 ≫ π/2) it still answers, and the answer is the one a delay that long must give.
#[test]
fn stability_refuses_what_it_cannot_analyse_as_bad_input() {
    let dir = tmpdir("stability-limits");
    let one = edited_scenario(&dir, "ring-theorem1", |sc| {
        sc["vehicles"] = serde_json::json!(1);
        sc["model"]["delay_s"] = serde_json::json!(0.5);
    });
    let (code, _, err) = run(bin().arg("stability").arg(&one));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("at least 2"), "{err}");
    for (scale, code_wanted) in [(1e4, 1), (1e5, 2)] {
        let path = edited_scenario(&dir, "ring-theorem1", |sc| {
            sc["model"]["graph"]["gain_pred"] = serde_json::json!(0.6 * scale);
            sc["model"]["graph"]["gain_follow"] = serde_json::json!(0.1 * scale);
        });
        let (code, out, err) = run(bin().arg("stability").arg(&path));
        assert_eq!(code, code_wanted, "×{scale}: {out}{err}");
        if code_wanted == 2 {
            assert!(err.contains("at most 1e4"), "{err}");
        } else {
            assert!(out.contains("exact: does NOT synchronize"), "{out}");
        }
    }
}

/// `--safety` is the scenario's `safety` key from the command line: a run with the flag is
/// byte for byte the run of the file that says the same (record, hash and rows), differs from
/// the file's own layer, and a layer the backend cannot have is refused before the run.
#[test]
fn the_safety_flag_is_the_scenarios_key_from_the_command_line() {
    let dir = tmpdir("safety-flag");
    let src = repo().join("scenarios/ring-theorem1.json");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&src).unwrap()).unwrap();
    assert!(
        doc.get("safety").is_none(),
        "the file leaves the layer to its default"
    );
    doc["safety"] = "filter".into();
    let keyed = dir.join("ring-theorem1-filter.json");
    std::fs::write(&keyed, doc.to_string()).unwrap();
    let sim = |sc: &std::path::Path, out: &str, extra: &[&str]| {
        run(bin()
            .arg("simulate")
            .arg(sc)
            .args(["--no-plots", "-q", "--out"])
            .arg(dir.join(out))
            .args(extra))
    };
    let (code, out, err) = sim(&src, "flag", &["--safety", "filter"]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(
        out.contains("safety layer: filter (Gipps' safe speed;"),
        "{out}"
    );
    assert_eq!(sim(&keyed, "key", &[]).0, 0);
    assert_eq!(sim(&src, "plain", &[]).0, 0);
    let read = |run: &str, file: &str| std::fs::read(dir.join(run).join(file)).unwrap();
    for file in ["metrics.json", "trajectories.csv"] {
        assert!(read("flag", file) == read("key", file), "{file} differs");
    }
    assert!(read("flag", "metrics.json") != read("plain", "metrics.json"));
    let m: serde_json::Value = serde_json::from_slice(&read("flag", "metrics.json")).unwrap();
    assert_eq!(m["safety_layer"]["mode"], "filter");
    let (code, _, err) = sim(&src, "sumo", &["--safety", "sumo"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("safety = sumo: SUMO's own checks need SUMO"),
        "{err}"
    );
    assert!(!dir.join("sumo/metrics.json").exists());
    let (code, _, err) = sim(&src, "bad", &["--safety", "gipps"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("gipps: use off"), "{err}");
}

/// `regress --init` makes a baseline for one's own scenario from a fresh run: it names the
/// scenario relative to its own folder (the two travel together), holds the metrics a
/// separate `simulate` of the scenario writes, passes a rerun, fails a planted gain change,
/// and never replaces an existing file.
#[test]
fn regress_init_makes_a_baseline_for_ones_own_scenario() {
    let dir = tmpdir("regress-init");
    let own = dir.join("mine");
    std::fs::create_dir_all(&own).unwrap();
    let scenario = own.join("ring.json");
    std::fs::copy(repo().join("scenarios/ring-theorem1.json"), &scenario).unwrap();
    std::fs::create_dir_all(dir.join("ci")).unwrap();
    let baseline = dir.join("ci/ring.native.json");
    let (code, out, err) = run(bin()
        .args(["regress"])
        .arg(&baseline)
        .arg("--init")
        .arg(&scenario));
    assert_eq!(code, 0, "{out}{err}");
    assert!(out.contains("wrote "), "{out}");
    let b: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&baseline).unwrap()).unwrap();
    assert_eq!(b["scenario"], "../mine/ring.json");
    assert!(
        b.get("kind").is_none(),
        "a native scenario gives a native baseline: {b}"
    );
    // The metrics are those of the scenario's run, made here apart from the baseline.
    let (code, _, err) = run(bin()
        .arg("simulate")
        .arg(&scenario)
        .args(["--no-plots", "-q", "--out"])
        .arg(dir.join("sim")));
    assert_eq!(code, 0, "{err}");
    let mut sim: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sim/metrics.json")).unwrap())
            .unwrap();
    for stamp in ["syncroad_version", "platform", "sumo_version"] {
        sim.as_object_mut().unwrap().remove(stamp);
    }
    assert_eq!(b["metrics"], sim);
    let (code, out, err) = run(bin().arg("regress").arg(&baseline));
    assert_eq!(code, 0, "{out}{err}");
    // A planted change of the law's gains fails it.
    let text = std::fs::read_to_string(&scenario).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["model"]["graph"]["gain_pred"] = serde_json::json!(0.5);
    let planted = serde_json::to_string(&doc).unwrap();
    assert_ne!(
        planted,
        serde_json::to_string(&serde_json::from_str::<serde_json::Value>(&text).unwrap()).unwrap(),
        "the gain was planted"
    );
    std::fs::write(&scenario, planted).unwrap();
    let (code, out, _) = run(bin().arg("regress").arg(&baseline));
    assert_eq!(code, 1, "{out}");
    std::fs::write(&scenario, &text).unwrap();
    // An existing file is never replaced.
    let before = std::fs::read(&baseline).unwrap();
    let (code, _, err) = run(bin()
        .arg("regress")
        .arg(&baseline)
        .arg("--init")
        .arg(&scenario));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("exists; --init writes a new baseline and never replaces a file"),
        "{err}"
    );
    assert_eq!(std::fs::read(&baseline).unwrap(), before);
}

/// Every command's `--help` is plain text: no rustdoc link syntax leaks from the doc comments
/// clap reads (`[`RunProgress::BAR_AFTER_S`]` once did).
#[test]
fn help_texts_hold_no_rustdoc_links() {
    let (_, top, _) = run(bin().arg("--help"));
    let commands: Vec<String> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        // A command's own line; its description wraps onto lines indented further.
        .filter(|l| !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect();
    assert!(commands.len() >= 15, "{commands:?}");
    for c in commands.iter().map(String::as_str).chain(["sweep collect"]) {
        let (code, out, err) = run(bin().args(c.split(' ')).arg("--help"));
        assert_eq!(code, 0, "{c}: {err}");
        assert!(!out.contains("[`"), "syncroad {c} --help: {out}");
    }
}
