//! Benchmarks of the exact stability analysis (issue 5).
//!
//! Targets: all ring modes for N = 1000 through the Lambert W fast path under 10 ms; a full
//! collocation + Newton solve for N = 50 with heterogeneous delays under 1 s. Also timed: the
//! argument-principle certificate and critical-scale searches (N = 10 and N = 50), and the
//! CACC eigenvalues for 50 followers.
//!
//! The whole `syncroad stability` report (roots, certificate, critical scale and its
//! certificate; `exact::analysis::analyse`) on heterogeneous rings, one-way and bidirectional,
//! at N = 50 and N = 200: target under 1 s at N = 50 and under 10 s at N = 200.
//!
//! Run with `cargo bench -p syncroad-control --bench exact`; only the whole-report group with
//! `cargo bench -p syncroad-control --bench exact -- whole_report`.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::DMatrix;
use std::hint::black_box;
use std::time::Duration;
use syncroad_control::exact::analysis::analyse;
use syncroad_control::exact::{
    cacc_modes, count_roots_right_of, critical_scale, rightmost_roots, CaccParams,
    CollocationOptions, UniformRing,
};
use syncroad_control::Scenario;

/// A ring scenario like `scenarios/het50-*.json` with `n` drivers: predecessor gains in
/// [0.4, 0.8], follower gains in [0.1, 0.4] when `bidirectional`, delays 0.3–0.7 s.
fn ring_scenario(n: usize, bidirectional: bool) -> Scenario {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut round = |lo: f64, width: f64| ((lo + width * next()) * 1000.0).round() / 1000.0;
    let pred: Vec<f64> = (0..n).map(|_| round(0.4, 0.4)).collect();
    let follow: Vec<f64> = (0..n).map(|_| round(0.1, 0.3)).collect();
    let delays: Vec<f64> = (0..n)
        .map(|_| (round(0.3, 0.4) * 10.0).round() / 10.0)
        .collect();
    let graph = if bidirectional {
        serde_json::json!({"type": "bidirectional_ring", "gain_pred": pred, "gain_follow": follow})
    } else {
        serde_json::json!({"type": "unidirectional_ring", "gain": pred})
    };
    let sc = serde_json::json!({
        "name": format!("het{n}-{}", if bidirectional { "bidir" } else { "oneway" }),
        "seed": 1, "step_s": 0.1, "horizon_s": 10, "vehicles": n,
        "road": {"type": "ring", "length_m": 20.0 * n as f64},
        "model": {"type": "delayed_driver", "graph": graph, "delay_s": delays}
    });
    Scenario::from_json(&sc.to_string()).expect("a valid benchmark scenario")
}

/// Deterministic heterogeneous network: ring backbone plus a few extra arcs, delays in
/// [0.2, 1.0] s, gains scaled so the worst driver has α_j d_j^+ = 0.6 (beyond Theorem 1).
fn heterogeneous(n: usize) -> (DMatrix<f64>, Vec<f64>) {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut a = DMatrix::zeros(n, n);
    for i in 0..n {
        a[(i, (i + n - 1) % n)] = 0.5 + next();
        if next() < 0.5 {
            a[(i, (i + 1) % n)] = 0.5 * next();
        }
        let j = (next() * n as f64) as usize % n;
        if j != i {
            a[(i, j)] += 0.3 * next();
        }
    }
    let delays: Vec<f64> = (0..n).map(|_| 0.2 + 0.8 * next()).collect();
    let worst = (0..n)
        .map(|i| delays[i] * a.row(i).sum())
        .fold(0.0, f64::max);
    a *= 0.6 / worst;
    (a, delays)
}

fn bench_exact(c: &mut Criterion) {
    let ring = UniformRing::new(1000, 1.0, 0.2, 0.4).unwrap();
    c.bench_function("ring_modes_fast_path_n1000", |b| {
        b.iter(|| black_box(&ring).modes().unwrap())
    });

    let (a50, d50) = heterogeneous(50);
    let opts = CollocationOptions::default();
    let mut group = c.benchmark_group("full_solve");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));
    group.bench_function("rightmost_roots_heterogeneous_n50", |b| {
        b.iter(|| rightmost_roots(black_box(&a50), black_box(&d50), &opts).unwrap())
    });
    let abscissa = rightmost_roots(&a50, &d50, &opts).unwrap().abscissa;
    group.bench_function("argument_principle_certificate_n50", |b| {
        b.iter(|| count_roots_right_of(black_box(&a50), black_box(&d50), abscissa + 1e-6).unwrap())
    });
    let (a10, d10) = heterogeneous(10);
    group.bench_function("critical_scale_heterogeneous_n10", |b| {
        b.iter(|| critical_scale(black_box(&a10), black_box(&d10), &opts).unwrap())
    });
    group.finish();

    // One critical-scale search at N = 50 is ~15 full solves; measured with the minimum sample.
    let mut slow = c.benchmark_group("critical_n50");
    slow.sample_size(10);
    slow.measurement_time(Duration::from_secs(60));
    slow.bench_function("critical_scale_heterogeneous_n50", |b| {
        b.iter(|| critical_scale(black_box(&a50), black_box(&d50), &opts).unwrap())
    });
    slow.finish();

    let mut whole = c.benchmark_group("whole_report");
    whole.sample_size(10);
    whole.measurement_time(Duration::from_secs(20));
    for n in [50usize, 200] {
        for bidirectional in [false, true] {
            let sc = ring_scenario(n, bidirectional);
            whole.bench_function(sc.name().to_string(), |b| {
                b.iter(|| analyse(black_box(&sc)).unwrap())
            });
        }
    }
    whole.finish();

    let platoon = CaccParams::homogeneous(50, 0.4, 1.0, 0.2, 0.1);
    c.bench_function("cacc_modes_n50", |b| {
        b.iter(|| cacc_modes(black_box(&platoon)).unwrap())
    });
}

criterion_group!(benches, bench_exact);
criterion_main!(benches);
