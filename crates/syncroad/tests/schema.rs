//! Every command that writes a run record writes one shape: the published
//! `docs/metrics.schema.json`. Real outputs of `run` (native and SUMO), `simulate` and each
//! run of `compare` are checked against it.

mod common;

use common::{bin, metrics_schema, repo, run, schema_violations, tmpdir};
use serde_json::{json, Value};

fn read(path: &std::path::Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn the_checker_rejects_what_the_schema_forbids() {
    let schema = metrics_schema();
    let d = tmpdir("schema-native");
    let (code, out, err) = run(bin()
        .args(["simulate"])
        .arg(repo().join("scenarios/ring-theorem1.json"))
        .args(["--no-plots", "--out"])
        .arg(&d));
    assert_eq!(code, 0, "{out}{err}");
    let good = read(&d.join("metrics.json"));
    assert_eq!(schema_violations(&schema, &good), Vec::<String>::new());
    // The checker can fail: a missing key, a wrong type, an unknown key and a bad enum.
    let mut bad = good.clone();
    bad.as_object_mut().unwrap().remove("sync");
    bad["seed"] = json!("42");
    bad["surprise"] = json!(1);
    bad["stop"]["reason"] = json!("gave_up");
    let v = schema_violations(&schema, &bad);
    assert_eq!(v.len(), 4, "{v:?}");
}

#[test]
fn every_command_writes_the_published_shape() {
    let schema = metrics_schema();
    let mut docs: Vec<(String, Value)> = Vec::new();
    // run on the native backend (the scenario says native), simulate, run on SUMO.
    let d = tmpdir("schema-run-native");
    let (code, _, err) = run(bin()
        .args(["run"])
        .arg(repo().join("scenarios/platoon-cacc.json"))
        .args(["--no-plots", "--out"])
        .arg(&d));
    assert_eq!(code, 0, "{err}");
    docs.push(("run native".into(), read(&d.join("metrics.json"))));
    let d = tmpdir("schema-run-sumo");
    let (code, _, err) = run(bin()
        .args(["run"])
        .arg(repo().join("scenarios/sugiyama-ring.json"))
        .args(["--no-plots", "--out"])
        .arg(&d));
    assert_eq!(code, 0, "{err}");
    let sumo = read(&d.join("metrics.json"));
    assert_eq!(sumo["backend"], "sumo");
    docs.push(("run sumo".into(), sumo));
    let d = tmpdir("schema-compare");
    let (code, _, err) = run(bin()
        .args(["compare"])
        .arg(repo().join("scenarios/sugiyama-ring.json"))
        .args([
            "--baselines",
            "protocol,idm",
            "--mixed",
            "0,2",
            "--no-plots",
            "--out",
        ])
        .arg(&d));
    assert_eq!(code, 0, "{err}");
    let combined = read(&d.join("compare.json"));
    for name in ["protocol", "idm", "mixed-0", "protocol-mixed-2"] {
        let per_run = read(&d.join(name).join("metrics.json"));
        // compare.json holds the same record with its stamps lifted to the top.
        let mut lifted = combined["runs"][name].clone();
        for k in [
            "syncroad_version",
            "platform",
            "sumo_version",
            "scenario_hash",
            "seed",
            "emission_class",
        ] {
            lifted[k] = combined[k].clone();
        }
        assert_eq!(lifted, per_run, "compare.json run {name}");
        docs.push((format!("compare {name}"), per_run));
    }
    for (what, doc) in &docs {
        let v = schema_violations(&schema, doc);
        assert!(v.is_empty(), "{what}: {v:#?}");
    }
}
