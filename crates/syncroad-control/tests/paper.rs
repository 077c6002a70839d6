//! Checks against answers the code did not produce: the paper's remarks, closed forms of
//! homogeneous rings, convergence order, and the theorems' claims.

use approx::assert_relative_eq;
use num_complex::Complex64;
use syncroad_control::graph::{Arc, Graph};
use syncroad_control::lti_network::{LtiAgent, LtiNetwork};
use syncroad_control::metrics::{fit_decay_rate, spread_series};
use syncroad_control::poly::Poly;
use syncroad_control::scenario::Scenario;
use syncroad_control::{simulate, theory, NativeOptions, Verdict};

fn spread(y: &[f64]) -> f64 {
    let hi = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = y.iter().copied().fold(f64::INFINITY, f64::min);
    hi - lo
}

/// Remark rem.weak: identical agents y''' + p y'' + q y' = u, all-to-all gain κ. Each
/// disagreement mode obeys s³ + p s² + q s + κλ with λ a nonzero Laplacian eigenvalue. The paper
/// writes λ = κ(N−1); for all-to-all coupling the nonzero eigenvalue is in fact κN (checked in
/// `all_to_all_laplacian_spectrum`), so the Routh boundary is κN < pq. The simulation must agree
/// on both sides, with the rate of the rightmost root.
#[test]
fn remark_weak_routh_boundary_on_both_sides() {
    let (p, q, n) = (1.0, 2.0, 4usize);
    let boundary = p * q / n as f64; // κ·N = pq
    for (kappa, expect_sync) in [(0.9 * boundary, true), (1.1 * boundary, false)] {
        // The characteristic polynomial of each disagreement mode, independently by Routh.
        assert_eq!(
            Poly::new(&[kappa * n as f64, q, p, 1.0]).is_hurwitz(),
            expect_sync
        );
        let agents = (0..n)
            .map(|_| LtiAgent::from_pole_at_zero(&[1.0], &[q, p, 1.0]))
            .collect();
        let net = LtiNetwork::new(agents, Graph::all_to_all(n, &vec![kappa; n]).unwrap());
        let x0: Vec<f64> = (0..3 * n)
            .map(|k| ((k * 7919) % 13) as f64 / 13.0 - 0.5)
            .collect();
        let ys = net.simulate(&x0, 0.01, 20_000);
        // Spread decays or grows like the rightmost root of the mode polynomial.
        let rightmost = Poly::new(&[kappa * n as f64, q, p, 1.0])
            .roots()
            .iter()
            .map(|z| z.re)
            .fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(rightmost < 0.0, expect_sync);
        let t: Vec<f64> = (10_000..=20_000)
            .step_by(10)
            .map(|k| k as f64 * 0.01)
            .collect();
        let s: Vec<f64> = (10_000..=20_000)
            .step_by(10)
            .map(|k| spread(&ys[k]))
            .collect();
        let rate = fit_decay_rate(&t, &s, 1e-300).unwrap();
        assert_relative_eq!(rate, rightmost, max_relative = 0.02);
        let (early, late) = (spread(&ys[2_000]), spread(&ys[20_000]));
        assert_eq!(
            late < early,
            expect_sync,
            "κ = {kappa}: spread {early} → {late}"
        );
    }
}

/// The Laplacian of all-to-all coupling with gain κ has the nonzero eigenvalue κN: check the
/// statement used above independently of the simulator.
#[test]
fn all_to_all_laplacian_spectrum() {
    let n = 5;
    let l = Graph::all_to_all(n, &[0.3; 5]).unwrap().laplacian_dense();
    let eig = l.symmetric_eigenvalues();
    let mut e: Vec<f64> = eig.iter().copied().collect();
    e.sort_by(f64::total_cmp);
    assert_relative_eq!(e[0], 0.0, epsilon = 1e-12);
    for x in &e[1..] {
        assert_relative_eq!(*x, 0.3 * n as f64, epsilon = 1e-12);
    }
}

/// Remark on the harmonic oscillators (one arc 2→1): no synchronization; after transients the
/// output amplitude ratio equals |W(iω₂)| with W(s) = ks/(s² + ks + ω₁²).
#[test]
fn two_oscillators_amplitude_ratio() {
    let (w1, w2, k) = (1.0f64, 2.0f64, 1.0f64);
    let osc = |w: f64| LtiAgent {
        p: nalgebra::DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, 0.0]),
        q: nalgebra::DVector::from_vec(vec![0.0, 1.0]),
        r: nalgebra::DVector::from_vec(vec![0.0, 1.0]),
    };
    let g = Graph::from_arcs(
        2,
        &[Arc {
            from: 1,
            to: 0,
            weight: k,
        }],
    )
    .unwrap();
    let net = LtiNetwork::new(vec![osc(w1), osc(w2)], g);
    let dt = 0.002;
    let ys = net.simulate(&[0.3, 0.0, 1.0, 0.0], dt, 40_000);
    // Amplitudes over the last 10 s (several periods of ω₂), transients of agent 1 decay as e^{−kt/2}.
    let tail = &ys[35_000..];
    let amp = |j: usize| tail.iter().map(|y| y[j].abs()).fold(0.0, f64::max);
    let s = Complex64::new(0.0, w2);
    let w = k * s / (s * s + k * s + w1 * w1);
    assert_relative_eq!(amp(0) / amp(1), w.norm(), max_relative = 1e-3);
    assert!(w.norm() < 1.0, "outputs cannot synchronize");
}

fn ring_scenario(n: usize, k: f64, delay: f64, dt: f64, horizon: f64, history: &str) -> Scenario {
    Scenario::from_json(&format!(
        r#"{{"seed": 3, "step_s": {dt}, "horizon_s": {horizon}, "vehicles": {n},
            "road": {{"type": "ring", "length_m": {len}}},
            "model": {{"type": "delayed_driver", "graph": {{"type": "unidirectional_ring", "gain": {k}}},
                       "delay_s": {delay}, "history": "{history}"}},
            "initial": {{"speed_mps": 10.0, "perturbation": {{"speed_mps": 1.0}}}},
            "verdict": {{"tolerance_mps": 0.01, "window_s": 5.0}}}}"#,
        len = 30.0 * n as f64
    ))
    .unwrap()
}

/// Rightmost root of the ring mode s + λ e^{−sα} = 0 by Newton from the delay-free root −λ,
/// continued in α (independent of the simulator).
fn mode_root(lambda: Complex64, alpha: f64) -> Complex64 {
    let mut s = -lambda;
    let steps = 200;
    for j in 1..=steps {
        let a = alpha * j as f64 / steps as f64;
        for _ in 0..50 {
            let e = (-s * a).exp();
            let f = s + lambda * e;
            let df = 1.0 - a * lambda * e;
            let ds = f / df;
            s -= ds;
            if ds.norm() < 1e-15 {
                break;
            }
        }
    }
    s
}

/// Homogeneous rings: the fitted decay rate of the speed spread equals the real part of the
/// slowest Fourier mode, s + K(1 − e^{−iθ}) e^{−sα} = 0 with θ = 2π/N.
#[test]
fn ring_decay_rate_matches_fourier_modes() {
    for (n, k, delay) in [(8usize, 0.5, 0.0), (8, 0.5, 0.6), (12, 0.8, 0.3)] {
        let sc = ring_scenario(n, k, delay, 0.01, 150.0, "constant_speeds");
        let run = simulate(
            &sc,
            NativeOptions {
                record_every: 10,
                ..NativeOptions::default()
            },
        );
        let theta = 2.0 * std::f64::consts::PI / n as f64;
        let slowest = (1..n)
            .map(|m| {
                let lam = k
                    * (Complex64::new(1.0, 0.0) - Complex64::from_polar(1.0, -(m as f64) * theta));
                mode_root(lam, delay).re
            })
            .fold(f64::NEG_INFINITY, f64::max);
        if delay == 0.0 {
            assert_relative_eq!(slowest, -k * (1.0 - theta.cos()), epsilon = 1e-12);
        }
        let s = spread_series(&run.trajectory);
        let t = &run.trajectory.time_s;
        let half = t.len() / 2;
        let rate = fit_decay_rate(&t[half..], &s[half..], 1e-12).unwrap();
        assert_relative_eq!(rate, slowest, max_relative = 0.01);
    }
}

/// Second-order convergence where delays lie on the step grid: halving Δt quarters the error
/// against a much finer reference.
#[test]
fn native_simulator_is_second_order() {
    let (n, k, delay, horizon) = (6, 0.6, 0.4, 8.0);
    let reference = simulate(
        &ring_scenario(n, k, delay, 0.4 / 256.0, horizon, "constant_speeds"),
        NativeOptions::default(),
    );
    let final_ref = reference
        .trajectory
        .speeds(reference.trajectory.len() - 1)
        .to_vec();
    let mut errs = Vec::new();
    for dt in [0.1, 0.05, 0.025] {
        let run = simulate(
            &ring_scenario(n, k, delay, dt, horizon, "constant_speeds"),
            NativeOptions::default(),
        );
        let last = run.trajectory.speeds(run.trajectory.len() - 1);
        errs.push(
            last.iter()
                .zip(&final_ref)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max),
        );
    }
    eprintln!("errors at Δt = 0.1, 0.05, 0.025: {errs:?}");
    for w in errs.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!(order > 1.9, "errors {errs:?}, observed order {order}");
    }
}

/// Theorem thm.1 with heterogeneous delays and gains: certified, and the simulation synchronizes.
#[test]
fn theorem1_scenario_synchronizes() {
    let sc = Scenario::from_json(
        r#"{"seed": 11, "step_s": 0.05, "horizon_s": 200, "vehicles": 6,
            "road": {"type": "ring", "length_m": 180},
            "model": {"type": "delayed_driver",
                      "graph": {"type": "bidirectional_ring", "gain_pred": [0.5, 0.4, 0.6, 0.3, 0.5, 0.45],
                                "gain_follow": [0.1, 0.2, 0.05, 0.3, 0.1, 0.15]},
                      "delay_s": [0.6, 0.75, 0.7, 0.8, 0.55, 0.8]},
            "initial": {"speed_mps": 10.0, "perturbation": {"speed_mps": 2.0}}}"#,
    )
    .unwrap();
    let rep = theory::report(&sc);
    assert!(rep.certified, "{:?}", rep.theorem1);
    let run = simulate(
        &sc,
        NativeOptions {
            record_every: 5,
            ..NativeOptions::default()
        },
    );
    let m = syncroad_control::sync_metrics(
        &run.trajectory,
        syncroad_control::VerdictThresholds {
            tolerance_mps: 1e-3,
            window_s: 5.0,
        },
        None,
        false,
    );
    assert_eq!(m.verdict, Verdict::Synchronized, "{m:?}");
}

/// Chandler's predecessor following on a ring: far past the boundary (αK well above π/2 for the
/// slowest mode) the spread grows, and the verdict says so.
#[test]
fn unstable_ring_is_not_synchronized() {
    let sc = ring_scenario(8, 1.0, 1.5, 0.05, 120.0, "constant_speeds");
    let rep = theory::report(&sc);
    assert!(!rep.certified);
    assert!(!rep.chandler.unwrap().holds);
    let run = simulate(
        &sc,
        NativeOptions {
            record_every: 2,
            ..NativeOptions::default()
        },
    );
    let m = syncroad_control::sync_metrics(
        &run.trajectory,
        syncroad_control::VerdictThresholds {
            tolerance_mps: 0.01,
            window_s: 5.0,
        },
        None,
        !matches!(run.stop, syncroad_control::StopReason::Horizon),
    );
    assert!(m.decay_rate_per_s.unwrap() > 0.0);
    // The spread alone, cut off before the horizon, is no verdict; the stop is the finding:
    // the speeds diverged, so the run did not synchronize.
    assert!(
        matches!(run.stop, syncroad_control::StopReason::Diverged { .. }),
        "{:?}",
        run.stop
    );
    assert_eq!(m.verdict, Verdict::Inconclusive);
    let out = syncroad_control::RunOutput::native(&sc, run, None);
    let judged = syncroad_control::evaluate(&sc, &out, syncroad_control::EvalOptions::of(&sc));
    assert_eq!(judged.sync.verdict, Verdict::NotSynchronized);
    assert!(
        judged
            .sync
            .verdict_reason
            .as_deref()
            .is_some_and(|r| r.contains("its speeds diverged")),
        "{:?}",
        judged.sync.verdict_reason
    );
}

/// CACC platoon satisfying Theorem thm.cacc reaches speed v_0 and gaps s_i.
#[test]
fn cacc_platoon_reaches_gaps_and_leader_speed() {
    let sc = Scenario::from_json(
        r#"{"seed": 5, "step_s": 0.01, "horizon_s": 400, "vehicles": 5,
            "road": {"type": "straight"},
            "model": {"type": "cacc", "mu": 1.0, "eta": [0.1, 0.2, 0.2, 0.2, 0.3], "nu": 0.15,
                      "desired_gap_m": 12.0, "tau_s": 0.3, "leader": {"type": "constant", "speed_mps": 20.0}},
            "initial": {"speed_mps": 18.0, "perturbation": {"speed_mps": 1.5, "gap_m": 3.0}}}"#,
    )
    .unwrap();
    assert!(theory::report(&sc).certified);
    let run = simulate(
        &sc,
        NativeOptions {
            record_every: 10,
            ..NativeOptions::default()
        },
    );
    let traj = &run.trajectory;
    let last = traj.len() - 1;
    for (i, v) in traj.speeds(last).iter().enumerate() {
        assert!((v - 20.0).abs() < 1e-3, "vehicle {i}: {v}");
    }
    for (i, g) in traj.gaps(last).iter().enumerate() {
        assert!((g - 12.0).abs() < 1e-2, "vehicle {i}: gap {g}");
    }
}

/// Chandler's chain: 40 predecessor-following drivers (K = 1/s, delay αK/K) behind a leader
/// at 20 m/s; the first driver starts 2 m/s slow, the others at 20 m/s, 30 m apart.
fn chandler_chain(alpha_k: f64) -> Scenario {
    let (n, k) = (40usize, 1.0);
    let delay = alpha_k / k;
    let mut speeds = vec![20.0; n];
    speeds[0] = 18.0;
    let list = speeds
        .iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let mut pin = vec!["0"; n];
    pin[0] = "1.0";
    Scenario::from_json(&format!(
        r#"{{"seed": 1, "step_s": 0.01, "horizon_s": 120, "vehicles": {n}, "road": {{"type": "straight"}},
            "model": {{"type": "delayed_driver", "graph": {{"type": "chain", "gain": {k}}}, "delay_s": {delay},
                      "leader": {{"speed_mps": 20.0, "pinning": [{}]}}, "history": "no_reaction"}},
            "initial": {{"speed_mps": [{list}], "gap_m": 30}}}}"#,
        pin.join(",")
    ))
    .unwrap()
}

/// Chandler's result for predecessor following behind a leader: a speed disturbance of the
/// first driver is attenuated along the chain when 2αK < 1 and amplified when 2αK > 1 (even
/// though every vehicle is individually stable while αK < π/2).
#[test]
fn chandler_string_stability_boundary() {
    for (alpha_k, attenuates) in [(0.4, true), (0.75, false)] {
        let sc = chandler_chain(alpha_k);
        let rep = theory::report(&sc);
        assert_eq!(rep.chandler.unwrap().holds, attenuates);
        assert_eq!(rep.certified, attenuates);
        let run = simulate(
            &sc,
            NativeOptions {
                record_every: 5,
                ..NativeOptions::default()
            },
        );
        let tr = &run.trajectory;
        let peak = |i: usize| {
            (0..tr.len())
                .map(|k| (tr.speeds(k)[i] - 20.0).abs())
                .fold(0.0, f64::max)
        };
        // Compare a vehicle well down the chain with one near the head.
        let (near, far) = (peak(5), peak(35));
        if attenuates {
            assert!(far < near, "2αK = {}: peak {near} → {far}", 2.0 * alpha_k);
        } else {
            assert!(
                far > 2.0 * near,
                "2αK = {}: peak {near} → {far}",
                2.0 * alpha_k
            );
        }
    }
}

/// The native simulator's decay rate on a heterogeneous network (gains and delays differ per
/// driver, bidirectional coupling) matches the spectral abscissa of the exact solve to 1 %.
#[test]
fn native_decay_rate_matches_exact_abscissa_on_heterogeneous_network() {
    let sc = Scenario::from_json(
        r#"{"seed": 21, "step_s": 0.01, "horizon_s": 60, "vehicles": 7,
            "road": {"type": "ring", "length_m": 200},
            "model": {"type": "delayed_driver",
                      "graph": {"type": "bidirectional_ring", "gain_pred": [0.7, 0.5, 0.9, 0.6, 0.8, 0.55, 0.65],
                                "gain_follow": [0.1, 0.2, 0.05, 0.15, 0.1, 0.2, 0.1]},
                      "delay_s": [0.4, 0.6, 0.3, 0.5, 0.45, 0.35, 0.55]},
            "initial": {"speed_mps": 10.0, "perturbation": {"speed_mps": 1.0}}}"#,
    )
    .unwrap();
    let syncroad_control::scenario::Model::DelayedDriver(m) = sc.model() else {
        unreachable!()
    };
    let exact = syncroad_control::exact::rightmost_roots(
        &m.graph.adjacency_dense(),
        &m.delay_s,
        &syncroad_control::exact::CollocationOptions::default(),
    )
    .unwrap();
    assert!(exact.abscissa < 0.0);
    let run = simulate(
        &sc,
        NativeOptions {
            record_every: 10,
            ..NativeOptions::default()
        },
    );
    let s = spread_series(&run.trajectory);
    let t = &run.trajectory.time_s;
    let half = t.len() / 2;
    let rate = fit_decay_rate(&t[half..], &s[half..], 1e-13).unwrap();
    assert_relative_eq!(rate, exact.abscissa, max_relative = 0.01);
}

/// The measured string amplification (`string_measured`) against Chandler's theory on the
/// same chain: with αK ≤ 1/e the follower's impulse response `K e^{−αs}/(s + K e^{−αs})` is
/// non-negative, so its L∞ gain is |H(0)| = 1 and no peak grows down the chain; with
/// 2αK = 1.5 > 1 the chain amplifies.
#[test]
fn measured_string_amplification_follows_chandler() {
    for (alpha_k, stable) in [(0.3, true), (0.75, false)] {
        let sc = chandler_chain(alpha_k);
        let run = simulate(
            &sc,
            NativeOptions {
                record_every: 1,
                ..NativeOptions::default()
            },
        );
        let m = syncroad_control::string_measured::measured(&run.trajectory).unwrap();
        // The leader keeps 20 m/s: the first peak is vehicle 0's initial 2 m/s.
        assert!((m.first_peak_deviation_mps - 2.0).abs() < 1e-12);
        let worst = m.worst_step_ratio.unwrap();
        if stable {
            assert!(worst <= 1.0 + 1e-9, "αK = {alpha_k}: worst step {worst}");
            assert!(m.end_to_end_ratio.unwrap() < 1.0);
        } else {
            assert!(worst > 1.05, "αK = {alpha_k}: worst step {worst}");
            assert!(m.end_to_end_ratio.unwrap() > 2.0, "{m:?}");
        }
    }
}
