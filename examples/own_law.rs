//! A Rust program with its own law, run on both backends through syncroad's one path.
//!
//!     cargo run --release --example own_law
//!
//! "follow": each driver closes a fraction `gain` of the speed difference to the vehicle ahead
//! every step, `v_i ← v_i + g (v_{i−1} − v_i)`. On a ring every vehicle has one predecessor and
//! one follower with the same weight, so the speeds' sum is conserved and they agree on the
//! initial mean: the run is checked against that closed form.
use std::process::ExitCode;

use syncroad::{Backend, Run};
use syncroad_control::registry;
use syncroad_control::speed_controller::{LawContext, LawEntry, Road};
use syncroad_control::{Scenario, SpeedController};

struct Follow {
    gain: f64,
}

impl SpeedController for Follow {
    fn step(&mut self, _t: f64, v: &[f64], _q: &[f64], next: &mut [f64]) {
        let n = v.len();
        for i in 0..n {
            let ahead = v[(i + n - 1) % n];
            next[i] = v[i] + self.gain * (ahead - v[i]);
        }
    }
}

fn follow(_: &LawContext, params: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
    match params.get("gain").and_then(serde_json::Value::as_f64) {
        Some(gain) if gain > 0.0 && gain <= 1.0 => Ok(Box::new(Follow { gain })),
        _ => Err(format!(
            "params = {params}: give \"gain\", a number in (0, 1]"
        )),
    }
}

fn main() -> anyhow::Result<ExitCode> {
    // First thing: the laws, then the worker (SUMO runs start this program again as one).
    registry::register(LawEntry {
        summary: "each driver closes a fraction gain of the speed difference to the one ahead",
        road: Road::Ring,
        ..LawEntry::new("follow", follow)
    })?;
    if syncroad_sumo::is_worker_invocation() {
        return Ok(syncroad_sumo::worker_main());
    }
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/sugiyama-ring.json"
    );
    let sc = Scenario::load(path.as_ref())?;
    let mean = sc.initial_speed_mps().iter().sum::<f64>() / sc.vehicles() as f64;
    for backend in [Backend::Native, Backend::Sumo] {
        let run = Run::new(&sc)
            .law("follow", serde_json::json!({"gain": 0.5}))?
            .backend(backend)
            .run()?;
        let t = &run.output.trajectory;
        let last = t.speeds(t.len() - 1);
        let worst = last.iter().map(|v| (v - mean).abs()).fold(0.0, f64::max);
        println!(
            "{backend:?}: {:?}, drivers {}, every speed within {worst:.2e} m/s of the initial mean {mean:.6} m/s",
            run.outcome.sync.verdict, run.record.drivers[0]
        );
        anyhow::ensure!(worst < 1e-9, "the speeds did not agree on the initial mean");
    }
    Ok(ExitCode::SUCCESS)
}
