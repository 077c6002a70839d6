//! Congestion metrics computed from a trajectory after a warm-up.
//!
//! Definitions (samples `k` with `t_k ≥ warm-up`, vehicles `i`):
//! * **mean speed** `v̄ = mean_{k,i} v_i(t_k)` (time- and vehicle-averaged);
//! * **speed std** over time and vehicles together, `sqrt(mean (v − v̄)²)`; **across vehicles**
//!   `mean_k std_i v_i(t_k)`; **over time** `mean_i std_k v_i(t_k)`;
//! * **harmonic-mean speed** `1 / mean_{k,i} (1/v)` (space-mean speed; 0 if any vehicle stands);
//! * **minimum speed** over all samples;
//! * **stops**: a stop event starts when a vehicle's speed falls below `stop_speed_mps`
//!   (0.1 m/s, SUMO's halting threshold) and ends when it rises above it; **stopped fraction** =
//!   share of vehicle-samples below it;
//! * **wave amplitude** `½ mean_k (max_i v_i − min_i v_i)`;
//! * **wave propagation speed** on a ring: the position of the slowest vehicle is followed
//!   from sample to sample (unwrapped by the shortest signed displacement) and a line is fitted;
//!   its slope [m/s] in the ground frame is negative for waves travelling against traffic.
//!   Reported only when the amplitude exceeds 0.5 m/s;
//! * **braking events**: a vehicle's speed falls faster than [`BRAKING_DECEL_MPS2`] = 1.5 m/s²
//!   averaged over consecutive windows of at least 1 s of samples; each run of such windows is
//!   one event. 1.5 m/s² is the IDM's comfortable deceleration b of Flow's ring benchmark
//!   (`IDMController`, b = 1.5) and the decel of the `human` preset: braking beyond what the
//!   drivers themselves consider comfortable. The 1 s window keeps per-step driver noise
//!   (σ√Δt per step) from counting as braking;
//! * **jam formation time** (over the whole run, warm-up included): the first sample at which
//!   some vehicle drives below [`JAM_SPEED_MPS`] = 1 m/s (the jam threshold of Sugiyama's
//!   ring used throughout, see `docs/src/human-preset.md`) after every vehicle has driven faster
//!   than it once, so a start from rest does not count as a jam; `null` when no jam forms.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::trajectory::Trajectory;

/// SUMO's halting-speed threshold [m/s].
pub const STOP_SPEED_MPS: f64 = 0.1;

/// Deceleration above which a vehicle brakes (see the module docs) \[m/s²\].
pub const BRAKING_DECEL_MPS2: f64 = 1.5;

/// Shortest window over which a braking deceleration is measured \[s\].
pub const BRAKING_WINDOW_S: f64 = 1.0;

/// Speed below which a vehicle counts as caught in a jam \[m/s\].
pub const JAM_SPEED_MPS: f64 = 1.0;

/// Congestion metrics of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CongestionMetrics {
    /// Warm-up excluded [s].
    pub warmup_s: f64,
    /// Time- and vehicle-averaged speed [m/s].
    #[schemars(title = "mean speed")]
    pub mean_speed_mps: f64,
    /// Standard deviation over all vehicle-samples [m/s].
    #[schemars(title = "speed std")]
    pub speed_std_mps: f64,
    /// Mean over time of the std across vehicles [m/s].
    #[schemars(title = "std across vehicles")]
    pub speed_std_across_vehicles_mps: f64,
    /// Mean over vehicles of the std over time [m/s].
    #[schemars(title = "std over time")]
    pub speed_std_over_time_mps: f64,
    /// Harmonic-mean speed [m/s].
    #[schemars(title = "harmonic-mean speed")]
    pub harmonic_mean_speed_mps: f64,
    /// Minimum speed [m/s].
    #[schemars(title = "min speed")]
    pub min_speed_mps: f64,
    /// Number of stop events.
    #[schemars(title = "stop events")]
    pub stop_events: usize,
    /// Fraction of vehicle-time stopped.
    #[schemars(title = "stopped fraction")]
    pub stopped_fraction: f64,
    /// Stop-and-go wave amplitude [m/s].
    #[schemars(title = "wave amplitude")]
    pub wave_amplitude_mps: f64,
    /// Wave propagation speed [m/s] (ring roads with waves only).
    #[schemars(title = "wave speed")]
    pub wave_speed_mps: Option<f64>,
    /// Braking events after the warm-up (decelerations beyond 1.5 m/s² over ≥ 1 s windows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(title = "braking events")]
    pub braking_events: Option<usize>,
    /// First time some vehicle is below 1 m/s after all have been above it \[s\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(title = "jam formed at")]
    pub jam_formed_s: Option<f64>,
}

/// Braking events from sample `first` on (see the module docs).
pub fn braking_events(traj: &Trajectory, first: usize) -> usize {
    let n = traj.n;
    let mut events = 0;
    for i in 0..n {
        let mut anchor = first;
        let mut braking = false;
        for k in first + 1..traj.len() {
            let dt = traj.time_s[k] - traj.time_s[anchor];
            if dt < BRAKING_WINDOW_S - 1e-9 {
                continue;
            }
            let decel = (traj.speeds_mps[anchor * n + i] - traj.speeds_mps[k * n + i]) / dt;
            let now = decel > BRAKING_DECEL_MPS2;
            if now && !braking {
                events += 1;
            }
            braking = now;
            anchor = k;
        }
    }
    events
}

/// The jam formation time of a trajectory (see the module docs).
pub fn jam_formed_s(traj: &Trajectory) -> Option<f64> {
    let n = traj.n;
    let mut moved = vec![false; n];
    let mut all_moved = false;
    for k in 0..traj.len() {
        let v = traj.speeds(k);
        if all_moved && v.iter().any(|&x| x < JAM_SPEED_MPS) {
            return Some(traj.time_s[k]);
        }
        for (m, &x) in moved.iter_mut().zip(v) {
            *m |= x > JAM_SPEED_MPS;
        }
        all_moved = all_moved || moved.iter().all(|&m| m);
    }
    None
}

/// Errors of the congestion computation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CongestionError {
    /// The warm-up leaves no sample.
    #[error("warm-up of {warmup_s} s leaves no sample (the run lasts {horizon_s} s); use a shorter warm-up")]
    WarmupTooLong {
        /// The warm-up [s].
        warmup_s: f64,
        /// The last sample time [s].
        horizon_s: f64,
    },
    /// One sample after the warm-up: no spread over time, no stop, no wave can be measured
    /// from it (a recording stride as long as the run).
    #[error("only one sample after the warm-up of {warmup_s} s: the congestion metrics need at least two; record more often (a smaller --record-every or record_every)")]
    OneSample {
        /// The warm-up [s].
        warmup_s: f64,
    },
}

/// Computes the congestion metrics; `ring_length_m` enables the wave speed.
pub fn congestion_metrics(
    traj: &Trajectory,
    warmup_s: f64,
    ring_length_m: Option<f64>,
) -> Result<CongestionMetrics, CongestionError> {
    let first = traj.time_s.partition_point(|&t| t < warmup_s - 1e-9);
    let horizon_s = traj.time_s.last().copied().unwrap_or(0.0);
    if first >= traj.len() {
        return Err(CongestionError::WarmupTooLong {
            warmup_s,
            horizon_s,
        });
    }
    if first + 1 == traj.len() {
        return Err(CongestionError::OneSample { warmup_s });
    }
    let n = traj.n;
    let ks = first..traj.len();
    let count = (ks.len() * n) as f64;
    let (mut sum, mut inv_sum, mut min, mut stopped, mut any_zero) =
        (0.0, 0.0, f64::INFINITY, 0usize, false);
    for k in ks.clone() {
        for &v in traj.speeds(k) {
            sum += v;
            if v > 0.0 {
                inv_sum += 1.0 / v;
            } else {
                any_zero = true;
            }
            min = min.min(v);
            if v < STOP_SPEED_MPS {
                stopped += 1;
            }
        }
    }
    let mean = sum / count;
    let mut var = 0.0;
    let mut across = 0.0;
    let mut amp = 0.0;
    for k in ks.clone() {
        let v = traj.speeds(k);
        let m = v.iter().sum::<f64>() / n as f64;
        across += (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n as f64).sqrt();
        var += v.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        amp += 0.5 * (hi - lo);
    }
    let samples = ks.len() as f64;
    let mut over_time = 0.0;
    let mut stop_events = 0;
    for i in 0..n {
        let series = ks.clone().map(|k| traj.speeds_mps[k * n + i]);
        let m = series.clone().sum::<f64>() / samples;
        over_time += (series.clone().map(|x| (x - m).powi(2)).sum::<f64>() / samples).sqrt();
        let mut was_stopped = false;
        for v in series {
            let s = v < STOP_SPEED_MPS;
            if s && !was_stopped {
                stop_events += 1;
            }
            was_stopped = s;
        }
    }
    let wave_amplitude_mps = amp / samples;
    let wave_speed_mps = ring_length_m
        .filter(|_| wave_amplitude_mps > 0.5)
        .and_then(|len| wave_speed(traj, first, len));
    Ok(CongestionMetrics {
        warmup_s,
        mean_speed_mps: mean,
        speed_std_mps: (var / count).sqrt(),
        speed_std_across_vehicles_mps: across / samples,
        speed_std_over_time_mps: over_time / n as f64,
        harmonic_mean_speed_mps: if any_zero { 0.0 } else { count / inv_sum },
        min_speed_mps: min,
        stop_events,
        stopped_fraction: stopped as f64 / count,
        wave_amplitude_mps,
        wave_speed_mps,
        braking_events: Some(braking_events(traj, first)),
        jam_formed_s: jam_formed_s(traj),
    })
}

fn wave_speed(traj: &Trajectory, first: usize, len: f64) -> Option<f64> {
    let n = traj.n;
    let mut t = Vec::new();
    let mut x = Vec::new();
    let mut prev: Option<f64> = None;
    let mut unwrapped = 0.0;
    for k in first..traj.len() {
        let v = traj.speeds(k);
        let slow = (0..n).min_by(|&a, &b| v[a].total_cmp(&v[b]))?;
        let pos = traj.positions_m[k * n + slow].rem_euclid(len);
        match prev {
            None => unwrapped = pos,
            Some(p) => {
                let mut d = pos - p;
                d -= len * (d / len).round();
                unwrapped += d;
            }
        }
        prev = Some(pos);
        t.push(traj.time_s[k]);
        x.push(unwrapped);
    }
    if t.len() < 3 {
        return None;
    }
    let m = t.len() as f64;
    let (mt, mx) = (t.iter().sum::<f64>() / m, x.iter().sum::<f64>() / m);
    let sxx: f64 = t.iter().map(|a| (a - mt).powi(2)).sum();
    let sxy: f64 = t.iter().zip(&x).map(|(a, b)| (a - mt) * (b - mx)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn braking_events_count_onsets_of_hard_one_second_decelerations() {
        // Samples every 0.5 s: windows of 1 s. Vehicle 0 brakes at 2 m/s² for 2 s (one
        // event: two windows in a row), cruises, then at 1 m/s² (none); vehicle 1 flickers by
        // ±0.6 m/s every sample (1.2 m/s per 0.5 s, but 0 per 1 s window: none).
        let mut t = Trajectory::new(2);
        let z = [0.0, 0.0];
        let v0 = [10.0, 10.0, 9.0, 8.0, 7.0, 6.0, 6.0, 6.0, 5.5, 5.0, 4.5, 4.0];
        for (k, &a) in v0.iter().enumerate() {
            let b = if k % 2 == 0 { 5.0 } else { 5.6 };
            t.push(k as f64 * 0.5, &[a, b], &z, &z, None);
        }
        assert_eq!(braking_events(&t, 0), 1);
        // From sample 6 on only the gentle braking is left.
        assert_eq!(braking_events(&t, 6), 0);
    }

    #[test]
    fn a_jam_forms_when_a_moving_ring_first_drops_below_1_mps() {
        let mut t = Trajectory::new(2);
        let z = [0.0, 0.0];
        // From rest: not a jam until both have moved faster than 1 m/s.
        t.push(0.0, &[0.0, 0.0], &z, &z, None);
        t.push(1.0, &[2.0, 0.5], &z, &z, None);
        t.push(2.0, &[0.9, 1.5], &z, &z, None);
        t.push(3.0, &[0.8, 1.5], &z, &z, None);
        t.push(4.0, &[2.0, 1.5], &z, &z, None);
        assert_eq!(jam_formed_s(&t), Some(3.0));
        let mut free = Trajectory::new(1);
        free.push(0.0, &[4.0], &[0.0], &[0.0], None);
        free.push(1.0, &[3.0], &[0.0], &[0.0], None);
        assert_eq!(jam_formed_s(&free), None);
    }

    /// Vehicles at uniform spacing driving at mean speed u; the speed field is a travelling wave
    /// v(x, t) = u + A sin(2π (x − c t)/L) with known c.
    fn travelling_wave(
        n: usize,
        len: f64,
        u: f64,
        a: f64,
        c: f64,
        t_end: f64,
        dt: f64,
    ) -> Trajectory {
        let mut tr = Trajectory::new(n);
        let steps = (t_end / dt) as usize;
        for k in 0..=steps {
            let t = k as f64 * dt;
            let x: Vec<f64> = (0..n).map(|i| i as f64 * len / n as f64 + u * t).collect();
            let v: Vec<f64> = x
                .iter()
                .map(|x| u + a * (2.0 * std::f64::consts::PI * (x - c * t) / len).sin())
                .collect();
            tr.push(t, &v, &x, &vec![0.0; n], None);
        }
        tr
    }

    #[test]
    fn wave_speed_and_amplitude_of_a_known_travelling_wave() {
        let tr = travelling_wave(200, 1000.0, 8.0, 3.0, -5.0, 200.0, 0.5);
        let m = congestion_metrics(&tr, 20.0, Some(1000.0)).unwrap();
        // Slowest vehicle sits where sin = −1: x = c t + 3L/4 (mod L), so the slope is c up to
        // the 5 m spacing of the vehicles.
        assert_relative_eq!(m.wave_speed_mps.unwrap(), -5.0, max_relative = 0.02);
        // Amplitude: half the range of A sin sampled at 200 points ≈ A.
        assert_relative_eq!(m.wave_amplitude_mps, 3.0, max_relative = 1e-3);
        // Time- and vehicle-average of u + A sin(...) over whole periods is u.
        assert_relative_eq!(m.mean_speed_mps, 8.0, max_relative = 1e-3);
        // Std of A sin is A/√2, both across vehicles and over time.
        assert_relative_eq!(m.speed_std_mps, 3.0 / 2f64.sqrt(), max_relative = 2e-3);
        assert_relative_eq!(
            m.speed_std_across_vehicles_mps,
            3.0 / 2f64.sqrt(),
            max_relative = 2e-3
        );
        // Harmonic mean of u + A sin θ over θ is sqrt(u² − A²) (closed form).
        assert_relative_eq!(
            m.harmonic_mean_speed_mps,
            (64.0f64 - 9.0).sqrt(),
            max_relative = 2e-3
        );
        assert_eq!(m.stop_events, 0);
    }

    #[test]
    fn stop_events_and_fraction() {
        // One vehicle stops twice for 10 of 40 samples; the other never.
        let mut tr = Trajectory::new(2);
        for k in 0..40 {
            let v0 = if (5..10).contains(&k) || (20..25).contains(&k) {
                0.0
            } else {
                5.0
            };
            tr.push(k as f64, &[v0, 5.0], &[0.0, 0.0], &[0.0, 0.0], None);
        }
        let m = congestion_metrics(&tr, 0.0, None).unwrap();
        assert_eq!(m.stop_events, 2);
        assert_relative_eq!(m.stopped_fraction, 10.0 / 80.0);
        assert_eq!(m.min_speed_mps, 0.0);
        assert_eq!(m.harmonic_mean_speed_mps, 0.0);
        assert_eq!(m.wave_speed_mps, None);
    }

    #[test]
    fn warmup_beyond_the_run_is_an_error() {
        let tr = travelling_wave(4, 100.0, 8.0, 1.0, -5.0, 10.0, 1.0);
        let e = congestion_metrics(&tr, 50.0, None).unwrap_err();
        assert_eq!(
            e.to_string(),
            "warm-up of 50 s leaves no sample (the run lasts 10 s); use a shorter warm-up"
        );
    }
}
