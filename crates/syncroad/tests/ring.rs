//! The ring experiments in real SUMO: SUMO's calibrated human drivers form Sugiyama's jam, one
//! wave damper dissolves it, every compared run starts from the same state, the records carry
//! the safety margins in the published shape, and mixed traffic draws its automated vehicles
//! from the seed.

mod common;

use std::path::Path;

use common::{bin, metrics_schema, repo, run, schema_violations, tmpdir};
use serde_json::Value;

fn read(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The rows of `trajectories.csv` at t = 0, as written.
fn initial_rows(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join("trajectories.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .take_while(|l| l.starts_with("0,"))
        .map(str::to_string)
        .collect()
}

#[test]
fn human_drivers_form_sugiyamas_jam_and_one_follower_stopper_dissolves_it() {
    let d = tmpdir("ring-jam");
    let (code, out, err) = run(bin()
        .arg("compare")
        .arg(repo().join("scenarios/sugiyama-human.json"))
        .args([
            "--mixed",
            "0,1",
            "--mixed-driver",
            "human",
            "--mixed-controller",
            "follower-stopper-4.3",
            "--warmup-s",
            "400",
            "--ssm",
            "--no-plots",
            "--out",
        ])
        .arg(&d));
    assert_eq!(code, 0, "{out}{err}");
    let humans = read(&d.join("mixed-0/metrics.json"));
    let damped = read(&d.join("follower-stopper-4.3-mixed-1/metrics.json"));
    assert_eq!(humans["law_controlled_vehicles"], 0);
    assert!(humans["drivers"]
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x == "human"));
    // Sugiyama et al. (2008): from a near-uniform start a jam forms by itself, cars stop in
    // it (below 1 m/s), and it moves backward at about 20 km/h; the band is 15–25 km/h.
    let c = &humans["congestion"];
    assert!(c["min_speed_mps"].as_f64().unwrap() < 1.0, "{c}");
    let wave_kmh = c["wave_speed_mps"].as_f64().unwrap() * 3.6;
    assert!((-25.0..=-15.0).contains(&wave_kmh), "wave {wave_kmh} km/h");
    // One FollowerStopper among 21 humans: nobody stops any more (the jam's 1 m/s), and the
    // wave amplitude falls below a tenth of the humans' ring.
    let dc = &damped["congestion"];
    assert!(dc["min_speed_mps"].as_f64().unwrap() > 1.0, "{dc}");
    assert!(
        dc["wave_amplitude_mps"].as_f64().unwrap()
            < 0.1 * c["wave_amplitude_mps"].as_f64().unwrap(),
        "{dc} vs {c}"
    );
    let drivers = damped["drivers"].as_array().unwrap();
    assert_eq!(drivers[0], "follower-stopper-4.3");
    assert!(drivers[1..].iter().all(|x| x == "human"));
    // Both runs start from the scenario's positions and speeds, to the last digit.
    let start = initial_rows(&d.join("mixed-0"));
    assert_eq!(start.len(), 22);
    assert_eq!(start, initial_rows(&d.join("follower-stopper-4.3-mixed-1")));
    // The margins are in the published shape; among 21 humans the damper keeps SUMO's checks
    // (the default safety layer with SUMO's drivers on the road, speed mode 25: safe speed,
    // right of way, red lights), and a ring of humans has no law-commanded vehicle.
    let schema = metrics_schema();
    for doc in [&humans, &damped] {
        let v = schema_violations(&schema, doc);
        assert!(v.is_empty(), "{v:#?}");
    }
    let m = &damped["safety_margins"];
    assert_eq!(m["ignores_safe_speed"], false, "{m}");
    assert_eq!(m["law_speed_mode"], 25, "{m}");
    assert_eq!(damped["safety_layer"]["mode"], "sumo");
    assert_eq!(humans["safety_margins"]["law_speed_mode"], Value::Null);
    // Without collisions every gap stays positive.
    assert_eq!(humans["safety"]["collision_steps"], 0);
    assert!(humans["safety_margins"]["min_gap_m"].as_f64().unwrap() > 0.0);
    assert!(out.contains("| ignores SUMO's safe speed |"), "{out}");
}

/// A copy of the human ring with `mixed` and the given seed, 10 s long (absolute net path).
fn mixed_scenario(dir: &Path, seed: u64, mixed: Value) -> std::path::PathBuf {
    let mut sc = read(&repo().join("scenarios/sugiyama-human.json"));
    sc["seed"] = seed.into();
    sc["horizon_s"] = 10.0.into();
    sc["mixed"] = mixed;
    sc["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .display()
        .to_string()
        .into();
    let p = dir.join(format!("mixed-{seed}.json"));
    std::fs::write(&p, serde_json::to_string_pretty(&sc).unwrap()).unwrap();
    p
}

#[test]
fn half_penetration_automates_half_the_vehicles_drawn_from_the_seed() {
    let d = tmpdir("ring-mixed");
    let drivers_of = |seed: u64, out: &str| -> Vec<String> {
        let sc = mixed_scenario(&d, seed, serde_json::json!({"penetration": 0.5}));
        let o = d.join(out);
        let (code, stdout, err) = run(bin()
            .arg("run")
            .arg(&sc)
            .args(["--no-plots", "--out"])
            .arg(&o));
        assert!(code == 0 || code == 1, "{stdout}{err}");
        let m = read(&o.join("metrics.json"));
        assert_eq!(m["law_controlled_vehicles"], 11, "{m}");
        m["drivers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_str().unwrap().to_string())
            .collect()
    };
    let a = drivers_of(42, "a");
    let again = drivers_of(42, "again");
    let other = drivers_of(43, "other");
    assert_eq!(a, again);
    assert_ne!(a, other);
    // SUMO ran exactly the vehicles the library draws for the seed; the rest are humans.
    for (seed, drivers) in [(42, &a), (43, &other)] {
        let law: Vec<usize> = (0..22).filter(|&i| drivers[i] == "protocol").collect();
        assert_eq!(
            law,
            syncroad_control::drive::Placement::Seeded.automated(22, 11, seed)
        );
        assert!(drivers.iter().all(|x| x == "protocol" || x == "human"));
    }
    // An unknown human driver is named before SUMO starts, with the valid ones.
    let sc = mixed_scenario(
        &d,
        7,
        serde_json::json!({"penetration": 0.5, "human": "wiedemann"}),
    );
    let (code, _, err) = run(bin()
        .arg("run")
        .arg(&sc)
        .args(["--no-plots", "--out"])
        .arg(d.join("bad")));
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("mixed.human = wiedemann: unknown driver; use krauss"),
        "{err}"
    );
}

/// The stochastic humans of a scenario's `mixed` block are resolved by both backends in one
/// place: `syncroad run` of the human-noisy ring as written (its mixed block of penetration 0)
/// drives every vehicle with the same noisy driver natively and in SUMO, and the two runs'
/// speeds agree row for row (SUMO's ballistic update is the native one; both read the net's
/// ring length). Before, the native simulator refused the mixed block.
#[test]
fn the_human_noisy_ring_as_written_runs_the_same_humans_on_both_backends() {
    let d = tmpdir("ring-noisy-both");
    let mut sc = read(&repo().join("scenarios/sugiyama-human-noisy.json"));
    sc["horizon_s"] = 60.0.into();
    sc["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .display()
        .to_string()
        .into();
    let mut speeds = Vec::new();
    for backend in ["sumo", "native"] {
        sc["backend"] = backend.into();
        let p = d.join(format!("{backend}.json"));
        std::fs::write(&p, serde_json::to_string_pretty(&sc).unwrap()).unwrap();
        let out = d.join(backend);
        let (code, o, e) = run(bin()
            .arg("run")
            .arg(&p)
            .args(["--no-plots", "--out"])
            .arg(&out));
        assert!(code == 0 || code == 1, "{backend}: {o}{e}");
        let m = read(&out.join("metrics.json"));
        assert_eq!(m["run"], "mixed", "{backend}");
        assert!(
            m["drivers"]
                .as_array()
                .unwrap()
                .iter()
                .all(|x| x == "human-noisy"),
            "{backend}: {}",
            m["drivers"]
        );
        let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
        let v: Vec<f64> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
            .collect();
        speeds.push(v);
    }
    assert_eq!(speeds[0].len(), speeds[1].len());
    assert!(speeds[0].len() > 22 * 100, "{}", speeds[0].len());
    let worst = speeds[0]
        .iter()
        .zip(&speeds[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "SUMO and native differ by {worst} m/s");
    // The noise moved the humans apart: the agreement is not of a standing ring.
    let (lo, hi) = speeds[1]
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi - lo > 0.5, "speeds {lo}..{hi}");
}

/// Among syncroad's own stochastic humans the law's vehicles are automated cars, held to a
/// safe speed by default: a mixed noisy ring without a `safety` key runs syncroad's filter on
/// both backends alike (the same commands lowered, the same speeds), and the scenario's own
/// `"safety": "off"` still lets the law drive unfiltered.
#[test]
fn automated_vehicles_among_noisy_humans_keep_a_safe_speed_by_default_on_both_backends() {
    let d = tmpdir("ring-noisy-default-safety");
    let mut sc = read(&repo().join("scenarios/sugiyama-human-noisy.json"));
    assert_eq!(
        sc["safety"], "off",
        "the published ring says it drives unfiltered"
    );
    sc.as_object_mut().unwrap().remove("safety");
    sc["horizon_s"] = 60.0.into();
    sc["mixed"]["penetration"] = 0.1.into();
    sc["sumo"]["net"] = repo()
        .join("sumo-nets/sugiyama-ring.net.xml")
        .display()
        .to_string()
        .into();
    let mut layers = Vec::new();
    let mut speeds = Vec::new();
    for (backend, safety) in [("sumo", None), ("native", None), ("native", Some("off"))] {
        sc["backend"] = backend.into();
        if let Some(s) = safety {
            sc["safety"] = s.into();
        }
        let name = format!("{backend}-{}", safety.unwrap_or("default"));
        let p = d.join(format!("{name}.json"));
        std::fs::write(&p, serde_json::to_string_pretty(&sc).unwrap()).unwrap();
        let out = d.join(&name);
        let (code, o, e) = run(bin()
            .arg("run")
            .arg(&p)
            .args(["--no-plots", "-q", "--warmup-s", "10", "--out"])
            .arg(&out));
        assert!(code == 0 || code == 1, "{name}: {o}{e}");
        let m = read(&out.join("metrics.json"));
        layers.push(m["safety_layer"].clone());
        let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
        speeds.push(
            csv.lines()
                .skip(1)
                .map(|l| l.split(',').nth(2).unwrap().parse::<f64>().unwrap())
                .collect::<Vec<_>>(),
        );
    }
    assert_eq!(layers[0]["mode"], "filter", "{}", layers[0]);
    // SUMO and native filter alike (the cut to rounding: SUMO's positions pass through f64
    // sums of their own).
    assert_eq!(layers[1]["mode"], "filter");
    assert_eq!(
        layers[0]["filter"]["overrides"],
        layers[1]["filter"]["overrides"]
    );
    let cut = |k: usize| layers[k]["filter"]["largest_cut_mps"].as_f64().unwrap();
    assert!((cut(0) - cut(1)).abs() < 1e-9, "{} vs {}", cut(0), cut(1));
    assert!(
        layers[0]["filter"]["overrides"].as_u64().unwrap() > 0,
        "{}",
        layers[0]
    );
    let worst = speeds[0]
        .iter()
        .zip(&speeds[1])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "SUMO and native differ by {worst} m/s");
    assert_eq!(layers[2]["mode"], "off", "{}", layers[2]);
    assert_ne!(speeds[1], speeds[2], "the filter changed the run");
}

/// One shape names a law wherever it goes: the automated vehicle of a mixed noisy ring driven
/// by `{"law": "follower-stopper", "params": {...}}` is the run of the older
/// `"follower-stopper-4.3"` (which keeps working, with a note) to the byte, and `{"python": "…:FollowerStopper", …}` (the guide's
/// Python class, written apart from the built-in law) drives it at the same speeds to
/// rounding, labelled by its class; a Python class named in both places is refused.
#[test]
fn the_automated_vehicles_of_a_mixed_ring_take_a_law_or_a_python_class_in_one_shape() {
    let d = tmpdir("ring-mixed-shapes");
    let mut sc = read(&repo().join("scenarios/sugiyama-human-noisy.json"));
    sc["backend"] = "native".into();
    sc["horizon_s"] = 60.0.into();
    sc["mixed"]["penetration"] = 0.05.into();
    sc.as_object_mut().unwrap().remove("sumo");
    let fs = repo().join("examples/controllers/follower_stopper.py");
    let shapes = [
        ("old", serde_json::json!("follower-stopper-4.3")),
        (
            "law",
            serde_json::json!({"law": "follower-stopper", "params": {"desired_speed_mps": 4.3}}),
        ),
        (
            "python",
            serde_json::json!({"python": format!("{}:FollowerStopper", fs.display()),
                                      "params": {"desired_speed_mps": 4.3}}),
        ),
    ];
    let mut rows = Vec::new();
    for (name, controller) in &shapes {
        sc["mixed"]["controller"] = controller.clone();
        let p = d.join(format!("{name}.json"));
        std::fs::write(&p, sc.to_string()).unwrap();
        let out = d.join(name);
        let (code, o, e) = run(bin()
            .arg("simulate")
            .arg(&p)
            .args(["--no-plots", "-q", "--warmup-s", "10", "--out"])
            .arg(&out));
        assert!(code == 0 || code == 1, "{name}: {o}{e}");
        // The older shape keeps working, with one line naming the one shape.
        let note = "note: mixed.controller = \"follower-stopper-4.3\" is the older shape of a law; the one shape is {\"law\": \"follower-stopper\", \"params\": {\"desired_speed_mps\":4.3}}";
        assert_eq!(e.contains(note), *name == "old", "{name}: {e}");
        let m = read(&out.join("metrics.json"));
        rows.push((
            m,
            std::fs::read_to_string(out.join("trajectories.csv")).unwrap(),
        ));
    }
    assert_eq!(rows[0].1, rows[1].1, "the law's object is its older name");
    assert_eq!(rows[0].0["drivers"], rows[1].0["drivers"]);
    let drivers = rows[2].0["drivers"].as_array().unwrap();
    assert_eq!(
        drivers
            .iter()
            .filter(|d| *d == "python:FollowerStopper")
            .count(),
        1,
        "{drivers:?}"
    );
    let speeds = |t: &str| -> Vec<f64> {
        t.lines()
            .skip(1)
            .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
            .collect()
    };
    let (a, b) = (speeds(&rows[0].1), speeds(&rows[2].1));
    assert_eq!(a.len(), b.len());
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-9,
        "the Python FollowerStopper differs by {worst} m/s"
    );
    // A Python class in both places is refused, naming the field.
    sc["controller"] = serde_json::json!({"python": format!("{}:FollowerStopper", fs.display())});
    let p = d.join("both.json");
    std::fs::write(&p, sc.to_string()).unwrap();
    let (code, _, err) = run(bin().arg("check").arg(&p));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("mixed.controller = {\"python\": "), "{err}");
    sc.as_object_mut().unwrap().remove("controller");
    sc["mixed"]["controller"] = serde_json::json!({"law": "follower-stopper", "python": "x.py:X"});
    std::fs::write(&p, sc.to_string()).unwrap();
    let (code, _, err) = run(bin().arg("check").arg(&p));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("one of the two"), "{err}");
}
