//! Direct batch calls into the loaded libsumo ([`ReadMode::Direct`]) against the calls through
//! the Python module: same simulation, same numbers (real SUMO; needs the virtualenv).

use std::path::Path;

use syncroad_control::Scenario;
use syncroad_sumo::ReadMode;
use syncroad_sumo::{run_scenario, MeasureOptions, RunOptions, WorkerCommand};

fn scenario() -> Scenario {
    let net = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../sumo-nets/sugiyama-ring.net.xml");
    Scenario::from_json(&format!(
        r#"{{"name": "direct", "backend": "sumo", "seed": 3, "step_s": 0.1, "horizon_s": 40, "vehicles": 22,
            "road": {{"type": "ring", "length_m": 230}},
            "model": {{"type": "delayed_driver", "graph": {{"type": "unidirectional_ring", "gain": 0.9}}, "delay_s": 0.4}},
            "initial": {{"speed_mps": 8.0, "perturbation": {{"speed_mps": 1.0, "gap_m": 1.0}}}},
            "sumo": {{"net": "{}"}}}}"#,
        net.canonicalize().unwrap().display()
    ))
    .unwrap()
}

fn run(mode: ReadMode, dir: &str) -> syncroad_sumo::SumoRun {
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join(dir);
    let _ = std::fs::remove_dir_all(&work);
    let mut opts = RunOptions::new(
        work,
        WorkerCommand::binary(env!("CARGO_BIN_EXE_syncroad-sumo-worker")),
    );
    opts.read = mode;
    // SUMO's own measurements too: fuel and CO2 are read every step, in one batch like the
    // speeds with direct calls.
    opts.warmup_s = 10.0;
    opts.measure = Some(MeasureOptions {
        emission_every: 1,
        tripinfo: false,
        ssm: false,
        emissions: syncroad_control::sumo_facts::Emissions::ALL,
    });
    let r = run_scenario(&scenario(), &opts).unwrap();
    r.outcome().unwrap();
    r
}

#[test]
fn direct_calls_give_the_same_run_as_python_calls() {
    let d = run(ReadMode::Direct, "direct");
    let p = run(ReadMode::Getters, "python-getters");
    let totals = |r: &syncroad_sumo::SumoRun| r.worker.result.as_ref().unwrap().totals.clone();
    assert!(
        totals(&d).direct_calls,
        "the pinned libsumo exports the functions"
    );
    assert!(!totals(&p).direct_calls);
    assert_eq!(d.worker.rows.speeds_mps, p.worker.rows.speeds_mps);
    assert_eq!(d.worker.rows.positions_m, p.worker.rows.positions_m);
    // The speeds really change over the run (the comparison is not of constants).
    let n = 22;
    let first = &d.worker.rows.speeds_mps[..n];
    let last = &d.worker.rows.speeds_mps[d.worker.rows.speeds_mps.len() - n..];
    assert!(first.iter().zip(last).any(|(a, b)| (a - b).abs() > 0.1));
    assert!(totals(&d).odometer_deviation_max_m < 1e-9);
    // The emissions summed from the batch reads are Python's sums, bit for bit.
    let measured =
        |r: &syncroad_sumo::SumoRun| r.worker.result.as_ref().unwrap().measured.clone().unwrap();
    let (md, mp) = (measured(&d), measured(&p));
    let (fuel, co2, total) = (
        md.fuel_mg.unwrap(),
        md.co2_mg.unwrap(),
        md.fuel_total_mg.unwrap(),
    );
    assert!(fuel > 0.0 && co2 > fuel, "{md:?}");
    assert!(total > fuel, "{md:?}");
    assert_eq!(md, mp);
}
