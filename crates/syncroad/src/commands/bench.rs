//! `syncroad bench`: throughput and accuracy of the native delayed-driver simulator.
//!
//! Rings of N drivers, gain K_i = 0.8 /s on the predecessor, heterogeneous on-grid delays
//! α_i ∈ {0.30, 0.31, …, 0.50} s drawn from a fixed seed, Δt = 0.01 s. Throughput is
//! vehicle-steps per second of the law's step on one thread; accuracy is the largest speed
//! difference at the horizon against the same run with a 16× finer step.

use std::time::Instant;

use syncroad_control::native::run_speeds_only;
use syncroad_control::rng::SplitMix64;
use syncroad_control::scenario::HistorySpec;
use syncroad_control::{DelayedDriverLaw, Graph};

use crate::error::InputError;
use crate::error::Status;
use crate::progress::Progress;
use crate::stdout::outln;

struct Ring {
    graph: Graph,
    delays_s: Vec<f64>,
    v0: Vec<f64>,
}

fn ring(n: usize) -> Ring {
    let mut rng = SplitMix64::new(2026);
    let delays_s = (0..n)
        .map(|_| (30 + rng.next_u64() % 21) as f64 * 0.01)
        .collect();
    let v0 = (0..n).map(|_| 10.0 + rng.symmetric(1.0)).collect();
    Ring {
        graph: Graph::unidirectional_ring(n, &vec![0.8; n]).expect("n ≥ 1"),
        delays_s,
        v0,
    }
}

fn timed(r: &Ring, dt: f64, horizon_s: f64) -> (Vec<f64>, f64) {
    let steps: Vec<usize> = r
        .delays_s
        .iter()
        .map(|a| (a / dt).round() as usize)
        .collect();
    let mut law = DelayedDriverLaw::new(
        &r.graph,
        &steps,
        dt,
        None,
        &r.v0,
        None,
        HistorySpec::ConstantSpeeds,
    )
    .expect("consistent sizes");
    let mut v = r.v0.clone();
    let n_steps = (horizon_s / dt).round() as usize;
    let t = Instant::now();
    run_speeds_only(&mut law, &mut v, n_steps);
    (v, t.elapsed().as_secs_f64())
}

/// The most vehicle-steps one benchmark may take (both steps of every size).
pub const MAX_VEHICLE_STEPS: f64 = 1e11;

/// Runs the benchmark and prints one line per ring size.
pub fn run(horizon_s: f64, sizes: &[usize]) -> anyhow::Result<Status> {
    if !(horizon_s.is_finite() && horizon_s > 0.0) {
        return Err(InputError::new(format!(
            "--horizon-s = {horizon_s}: must be a finite number > 0"
        ))
        .into());
    }
    if let Some(&bad) = sizes.iter().find(|&&n| n < 2) {
        return Err(InputError::new(format!(
            "--sizes contains {bad}: a ring needs at least 2 vehicles"
        ))
        .into());
    }
    let dt = 0.01;
    // Each size runs at Δt and at Δt/16 (the accuracy reference): 17 runs' worth of steps.
    let work = sizes
        .iter()
        .fold(0.0, |w, &n| w + 17.0 * n as f64 * horizon_s / dt);
    if work > MAX_VEHICLE_STEPS {
        return Err(InputError::new(format!(
            "--horizon-s = {horizon_s} with --sizes {}: {work:.3e} vehicle-steps (17 × N × horizon_s / {dt} s, summed over the sizes), more than the {MAX_VEHICLE_STEPS:e} a benchmark may take (several minutes); give a shorter horizon or smaller rings",
            sizes.iter().map(usize::to_string).collect::<Vec<_>>().join(",")
        ))
        .into());
    }
    outln!("native delayed-driver simulator, unidirectional rings, K = 0.8/s, α_i ∈ [0.30, 0.50] s on the grid, Δt = {dt} s, {horizon_s} s simulated");
    outln!(
        "{:>7} {:>14} {:>18} {:>22}",
        "N",
        "wall [s]",
        "vehicle-steps/s",
        "max |v − v_ref| [m/s]"
    );
    // One line on stderr per ring size (a bar on a terminal): the reference runs at Δt/16 take
    // most of the time.
    let progress = Progress::new("bench", sizes.len() as u64);
    for &n in sizes {
        let r = ring(n);
        let _ = timed(&r, dt, horizon_s.min(1.0)); // warm caches
        let (v, secs) = timed(&r, dt, horizon_s);
        let rate = n as f64 * (horizon_s / dt).round() / secs;
        let (vref, _) = timed(&r, dt / 16.0, horizon_s);
        let err = v
            .iter()
            .zip(&vref)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        outln!("{n:>7} {secs:>14.4} {rate:>18.3e} {err:>22.3e}");
        progress.finished(&format!("N = {n}"), None);
    }
    progress.done();
    Ok(Status::Success)
}
