//! The whole `syncroad stability` report (`exact::analysis::analyse`: roots and their
//! certificate, the critical scale and its certificate) over a spread of heterogeneous rings,
//! one run each: one-way and bidirectional, N = 50 and N = 200, gain levels 0.3–1.0/s
//! (follower gains 0.2–0.5 of the predecessor's), per-driver gains ±20 % or uniform, delays
//! from 0.2–0.6 s over a width of 0–0.4 s on a 0.01, 0.05 or 0.1 s grid. Prints every ring's
//! time, search method, full solves and certificate, then the median and the worst case per
//! group (the figures the guide's performance chapter quotes beside the median: the worst
//! case is what a user may meet).
//!
//! Run with `cargo bench -p syncroad-control --bench exact_spread` (about a minute); the
//! number of rings per group with `EXACT_SPREAD_RINGS=20` (N = 50; a quarter of it at N = 200).

use std::time::Instant;

use syncroad_control::exact::analysis::{analyse, CriticalScaleStatus};
use syncroad_control::Scenario;

/// xorshift64: deterministic rings whatever the machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Ring number `k` of a group: its scenario and a one-line description.
fn ring(n: usize, bidirectional: bool, k: u64) -> (Scenario, String) {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ (k + 1).wrapping_mul(0x2545_f491_4f6c_dd1d));
    let level = 0.3 + 0.7 * rng.next();
    let follow = 0.2 + 0.3 * rng.next();
    let spread = if rng.next() < 0.5 { 0.0 } else { 0.2 };
    let grid = [0.01, 0.05, 0.1][(rng.next() * 3.0) as usize % 3];
    let lo = 0.2 + 0.4 * rng.next();
    let width = 0.4 * rng.next();
    let lo = (lo / grid).round() * grid;
    let cells = (width / grid).round() as usize;
    let mut gain = |base: f64| {
        let g = base * (1.0 + spread * (2.0 * rng.next() - 1.0));
        (g * 1000.0).round() / 1000.0
    };
    let pred: Vec<f64> = (0..n).map(|_| gain(level)).collect();
    let back: Vec<f64> = (0..n).map(|_| gain(level * follow)).collect();
    let delays: Vec<f64> = (0..n)
        .map(|_| {
            let c = (rng.next() * (cells + 1) as f64) as usize % (cells + 1);
            ((lo + grid * c as f64) * 100.0).round() / 100.0
        })
        .collect();
    let graph = if bidirectional {
        serde_json::json!({"type": "bidirectional_ring", "gain_pred": pred, "gain_follow": back})
    } else {
        serde_json::json!({"type": "unidirectional_ring", "gain": pred})
    };
    let sc = serde_json::json!({
        "name": format!("ring{k}"), "seed": 1, "step_s": 0.01, "horizon_s": 10, "vehicles": n,
        "road": {"type": "ring", "length_m": 20.0 * n as f64},
        "model": {"type": "delayed_driver", "graph": graph, "delay_s": delays}
    });
    let what = format!(
        "gain {level:.2}{} ±{:.0}%, delays {lo:.2}–{:.2} s (grid {grid})",
        if bidirectional {
            format!("/{:.2}", level * follow)
        } else {
            String::new()
        },
        100.0 * spread,
        lo + grid * cells as f64
    );
    (
        Scenario::from_json(&sc.to_string()).expect("a valid ring"),
        what,
    )
}

fn main() {
    let rings: u64 = std::env::var("EXACT_SPREAD_RINGS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    // `EXACT_SPREAD_ONLY=N,bidir,K` (or `N,oneway,K`): that one ring.
    let only: Option<(usize, bool, u64)> = std::env::var("EXACT_SPREAD_ONLY").ok().map(|s| {
        let f: Vec<&str> = s.split(',').collect();
        (
            f[0].parse().unwrap(),
            f[1] == "bidir",
            f[2].parse().unwrap(),
        )
    });
    println!("whole report over a spread of heterogeneous rings (one run each)");
    for n in [50usize, 200] {
        let count = if n > 50 { rings.div_ceil(4) } else { rings };
        for bidirectional in [false, true] {
            let mut times = Vec::new();
            let mut uncertified = 0;
            for k in 0..count {
                if only.is_some_and(|o| o != (n, bidirectional, k)) {
                    continue;
                }
                let (sc, what) = ring(n, bidirectional, k);
                let start = Instant::now();
                let r = analyse(&sc).expect("the report");
                let t = start.elapsed().as_secs_f64();
                let c = r
                    .network
                    .as_ref()
                    .and_then(|x| x.delayed())
                    .and_then(|x| x.critical.as_ref());
                let (method, solves) = c.map_or(("-".to_string(), 0), |c| {
                    (format!("{:?}", c.method).to_lowercase(), c.full_solves)
                });
                if r.critical_scale_status == CriticalScaleStatus::Uncertified {
                    uncertified += 1;
                }
                println!(
                    "  N={n} {} #{k:<2} {t:>7.3} s  {method} ({solves} full solves) {:?}  {what}",
                    if bidirectional { "bidir " } else { "oneway" },
                    r.critical_scale_status
                );
                times.push(t);
            }
            if times.is_empty() {
                continue;
            }
            times.sort_by(f64::total_cmp);
            println!(
                "N = {n} {}: {} rings, median {:.3} s, worst {:.3} s, uncertified {uncertified}",
                if bidirectional {
                    "bidirectional"
                } else {
                    "one-way"
                },
                times.len(),
                times[times.len() / 2],
                times[times.len() - 1]
            );
        }
    }
}
