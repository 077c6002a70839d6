//! String stability of the CACC platoon: gap-error transfer peaks and a braking wave.
//!
//! Theorem `thm.cacc` concerns asymptotic stability only ("does not address the string
//! stability problem"). Here the disturbance is the leader's speed deviation `w(t)` from the
//! cruise speed `v_0`: it enters the first gap, `e_1' = w − ε_1`, and — if the leader
//! broadcasts its actual speed — every speed term, `a_des,i += μ_i w`. With the closed loop
//! `x' = Ax + bw` of [`super::cacc_modes`](mod@super::cacc_modes), the transfer from `w` to gap error `i` is
//! `G_i(s) = e_iᵀ(sI − A)^{−1}b`, and the platoon is called string stable here when
//!
//! `max_i sup_ω |G_{i+1}(iω) / G_i(iω)| ≤ 1`,
//!
//! i.e. no gap error is amplified towards the tail at any frequency. For the unidirectional
//! homogeneous platoon (`ν = 0`, gap-only disturbance) every ratio equals
//! `H(s) = η/(τs³ + s² + μs + η)` (since `q_{i+1} = H q_i`), which the tests use as an
//! independent closed form.
//!
//! The time-domain counterpart integrates the `3N` linear ODE with the classical fixed-step
//! fourth-order Runge–Kutta method for a braking pulse of the leader (decelerate, then
//! accelerate back) and reports the peak gap error of each follower.

use super::cacc_modes::{cacc_modes, CaccError, CaccParams};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use serde::Serialize;

/// Failure of the string-stability analysis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StringStabilityError {
    /// Invalid platoon parameters.
    #[error(transparent)]
    Cacc(#[from] CaccError),
    /// String stability is only meaningful for an asymptotically stable platoon.
    #[error("the platoon is not asymptotically stable (spectral abscissa {abscissa} ≥ 0); string stability is undefined")]
    Unstable {
        /// Spectral abscissa [1/s].
        abscissa: f64,
    },
    /// An option is out of range.
    #[error("option {name} = {value} must be finite and > 0")]
    InvalidOption {
        /// Option name.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
}

/// How the leader's speed disturbance reaches the followers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum LeaderDisturbance {
    /// Followers keep the nominal `v_0` as reference; only the first gap feels the leader.
    GapOnly,
    /// The leader broadcasts its actual speed `v_0 + w` to every follower's `μ` term.
    Broadcast,
}

/// Options of [`string_stability`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StringStabilityOptions {
    /// Disturbance channel.
    pub disturbance: LeaderDisturbance,
    /// Lowest frequency of the scan [rad/s].
    pub frequency_min_rad_s: f64,
    /// Highest frequency of the scan [rad/s].
    pub frequency_max_rad_s: f64,
    /// Log-spaced scan points (each maximum is then refined by golden-section search).
    pub frequency_points: usize,
    /// Leader deceleration during the braking pulse [m/s²].
    pub braking_decel_mps2: f64,
    /// Duration of the deceleration phase (the recovery takes as long) \[s\].
    pub braking_duration_s: f64,
    /// RK4 step \[s\].
    pub step_s: f64,
    /// Simulated horizon \[s\].
    pub horizon_s: f64,
}

impl Default for StringStabilityOptions {
    fn default() -> Self {
        StringStabilityOptions {
            disturbance: LeaderDisturbance::GapOnly,
            frequency_min_rad_s: 1e-3,
            frequency_max_rad_s: 1e2,
            frequency_points: 800,
            braking_decel_mps2: 3.0,
            braking_duration_s: 2.0,
            step_s: 5e-3,
            horizon_s: 150.0,
        }
    }
}

/// String-stability numbers of a platoon.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StringStabilityReport {
    /// Number of followers `N`.
    pub followers: usize,
    /// Disturbance channel used.
    pub disturbance: LeaderDisturbance,
    /// `sup_ω |G_i(iω)|` per follower \[s\] (gap error per unit leader speed deviation).
    pub gap_peak_gain_s: Vec<f64>,
    /// `sup_ω |G_{i+1}/G_i|` for `i = 1..N−1`.
    pub successive_peak_ratio: Vec<f64>,
    /// `max_i sup_ω |G_{i+1}/G_i|` (1 for a single follower by convention).
    pub max_successive_ratio: f64,
    /// Follower `i` (1-based) whose ratio `G_{i+1}/G_i` attains the maximum.
    pub worst_follower: usize,
    /// Frequency of that maximum [rad/s].
    pub worst_frequency_rad_s: f64,
    /// `sup|G_N| / sup|G_1|`.
    pub first_to_last_peak_ratio: f64,
    /// `max_successive_ratio ≤ 1` (to 1e-9).
    pub string_stable: bool,
    /// Simulated peak `|e_i(t)|` per follower for the braking pulse \[m\].
    pub simulated_peak_gap_error_m: Vec<f64>,
    /// Simulated `peak|e_N| / peak|e_1|`.
    pub simulated_peak_amplification: f64,
    /// Simulated `‖e_N‖₂ / ‖e_1‖₂` over the horizon.
    pub simulated_energy_amplification: f64,
}

/// Input vector `b` of the leader's speed deviation.
pub(crate) fn disturbance_input(p: &CaccParams, channel: LeaderDisturbance) -> DVector<f64> {
    let n = p.followers();
    let mut b = DVector::zeros(3 * n);
    b[0] = 1.0;
    if channel == LeaderDisturbance::Broadcast {
        for i in 0..n {
            b[3 * i + 2] = p.mu[i] / p.tau_s[i];
        }
    }
    b
}

/// All gap-error transfers `G_i(iω)`, from one solve of `(iωI − A)x = b`.
fn gap_transfers(a: &DMatrix<f64>, b: &DVector<f64>, omega: f64) -> Vec<Complex64> {
    let n = a.nrows();
    let mut m = a.map(|x| Complex64::new(-x, 0.0));
    for i in 0..n {
        m[(i, i)] += Complex64::new(0.0, omega);
    }
    let rhs = b.map(|x| Complex64::new(x, 0.0));
    let x = m
        .lu()
        .solve(&rhs)
        .unwrap_or_else(|| DVector::from_element(n, Complex64::new(f64::NAN, 0.0)));
    (0..n / 3).map(|i| x[3 * i]).collect()
}

/// Maximizes `f(ln ω)` on `[lo, hi]` by golden-section search.
fn golden_max(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..80 {
        if f1 < f2 {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        } else {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    if f1 > f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

/// Classical RK4 for `x' = Ax + b w(t)` from `x(0) = 0`; calls `observe(t, x)` after each step.
pub(crate) fn rk4_simulate(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    w: impl Fn(f64) -> f64,
    step_s: f64,
    steps: usize,
    mut observe: impl FnMut(f64, &DVector<f64>),
) {
    let mut x = DVector::zeros(a.nrows());
    let f = |t: f64, x: &DVector<f64>| a * x + b * w(t);
    for k in 0..steps {
        let t = k as f64 * step_s;
        let k1 = f(t, &x);
        let k2 = f(t + 0.5 * step_s, &(&x + &k1 * (0.5 * step_s)));
        let k3 = f(t + 0.5 * step_s, &(&x + &k2 * (0.5 * step_s)));
        let k4 = f(t + step_s, &(&x + &k3 * step_s));
        x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (step_s / 6.0);
        observe(t + step_s, &x);
    }
}

/// Leader speed deviation of the braking pulse: `−d·t` while braking for `T`, then recovering
/// at the same rate, zero afterwards [m/s].
fn braking_pulse(decel: f64, duration: f64) -> impl Fn(f64) -> f64 {
    move |t: f64| {
        if t <= 0.0 || t >= 2.0 * duration {
            0.0
        } else if t <= duration {
            -decel * t
        } else {
            -decel * (2.0 * duration - t)
        }
    }
}

/// Frequency-domain and simulated string-stability numbers of a CACC platoon.
///
/// # Errors
/// [`StringStabilityError`] for invalid parameters/options or an unstable platoon.
pub fn string_stability(
    params: &CaccParams,
    options: &StringStabilityOptions,
) -> Result<StringStabilityReport, StringStabilityError> {
    for (name, value) in [
        ("frequency_min_rad_s", options.frequency_min_rad_s),
        ("frequency_max_rad_s", options.frequency_max_rad_s),
        ("braking_decel_mps2", options.braking_decel_mps2),
        ("braking_duration_s", options.braking_duration_s),
        ("step_s", options.step_s),
        ("horizon_s", options.horizon_s),
        ("frequency_points", options.frequency_points as f64),
    ] {
        if !value.is_finite() || value <= 0.0 {
            return Err(StringStabilityError::InvalidOption { name, value });
        }
    }
    let modes = cacc_modes(params)?;
    if !modes.exactly_stable {
        return Err(StringStabilityError::Unstable {
            abscissa: modes.abscissa,
        });
    }
    let n = params.followers();
    let a = params.closed_loop_matrix()?;
    let b = disturbance_input(params, options.disturbance);
    let (ln_lo, ln_hi) = (
        options.frequency_min_rad_s.ln(),
        options.frequency_max_rad_s.ln(),
    );
    let points = options.frequency_points.max(2);
    let grid: Vec<f64> = (0..points)
        .map(|k| ln_lo + (ln_hi - ln_lo) * k as f64 / (points - 1) as f64)
        .collect();
    let values: Vec<Vec<Complex64>> = grid
        .iter()
        .map(|&x| gap_transfers(&a, &b, x.exp()))
        .collect();
    // ω = 0 is evaluated exactly (A is Hurwitz); a 0/0 ratio there is skipped.
    let dc = gap_transfers(&a, &b, 0.0);
    let refine = |measure: &dyn Fn(&[Complex64]) -> f64| -> (f64, f64) {
        let (k, _) = values.iter().map(|g| measure(g)).enumerate().fold(
            (0, f64::NEG_INFINITY),
            |acc, (k, v)| if v > acc.1 { (k, v) } else { acc },
        );
        let lo = grid[k.saturating_sub(1)];
        let hi = grid[(k + 1).min(points - 1)];
        let (x, v) = golden_max(|x| measure(&gap_transfers(&a, &b, x.exp())), lo, hi);
        let grid_best = measure(&values[k]);
        let (w, v) = if grid_best >= v {
            (grid[k].exp(), grid_best)
        } else {
            (x.exp(), v)
        };
        let at_dc = measure(&dc);
        if at_dc.is_finite() && at_dc > v {
            (0.0, at_dc)
        } else {
            (w, v)
        }
    };
    let gap_peak_gain_s: Vec<f64> = (0..n)
        .map(|i| refine(&|g: &[Complex64]| g[i].norm()).1)
        .collect();
    let mut successive_peak_ratio = Vec::with_capacity(n.saturating_sub(1));
    let (mut worst_follower, mut worst_frequency, mut max_ratio) = (1, 0.0, 1.0f64);
    for i in 0..n.saturating_sub(1) {
        let (w, r) = refine(&|g: &[Complex64]| g[i + 1].norm() / g[i].norm());
        successive_peak_ratio.push(r);
        if i == 0 || r > max_ratio {
            max_ratio = r;
            worst_follower = i + 1;
            worst_frequency = w;
        }
    }
    // Braking pulse simulation.
    let steps = (options.horizon_s / options.step_s).ceil() as usize;
    let mut peaks = vec![0.0f64; n];
    let mut energy = vec![0.0f64; n];
    rk4_simulate(
        &a,
        &b,
        braking_pulse(options.braking_decel_mps2, options.braking_duration_s),
        options.step_s,
        steps,
        |_, x| {
            for i in 0..n {
                let e = x[3 * i];
                peaks[i] = peaks[i].max(e.abs());
                energy[i] += e * e * options.step_s;
            }
        },
    );
    Ok(StringStabilityReport {
        followers: n,
        disturbance: options.disturbance,
        first_to_last_peak_ratio: gap_peak_gain_s[n - 1] / gap_peak_gain_s[0],
        gap_peak_gain_s,
        successive_peak_ratio,
        max_successive_ratio: max_ratio,
        worst_follower,
        worst_frequency_rad_s: worst_frequency,
        string_stable: max_ratio <= 1.0 + 1e-9,
        simulated_peak_amplification: peaks[n - 1] / peaks[0],
        simulated_energy_amplification: (energy[n - 1] / energy[0]).sqrt(),
        simulated_peak_gap_error_m: peaks,
    })
}

/// String-stability peak of Chandler's straight road (eq. `chandler`): the speed transfer from
/// one vehicle to its follower, `H(s) = K e^{−sα}/(s + K e^{−sα})`, has
/// `sup_ω |H(iω)|` depending only on `αK`; it is returned here (by a scan of `ωα ∈ (0, 50]`
/// refined by golden-section search).
///
/// Since `|H(iω)|² = K²/(K² + ω² − 2ωK sin ωα)`, the peak is 1 (attained as `ω → 0`) iff
/// `2αK ≤ 1` — the bound the paper quotes for the straight road in Section `sec.cacc` — while
/// asymptotic stability of each follower needs only `αK < π/2` (see
/// [`super::critical`]). Returns `∞` when `αK ≥ π/2` (a follower is unstable).
///
/// # Reference
/// R. E. Chandler, R. Herman, E. W. Montroll, "Traffic dynamics: studies in car following",
/// Operations Research 6 (1958) 165–184.
pub fn chandler_string_peak(alpha_k: f64) -> f64 {
    if !(alpha_k.is_finite() && alpha_k > 0.0) {
        return f64::NAN;
    }
    if alpha_k >= std::f64::consts::FRAC_PI_2 {
        return f64::INFINITY;
    }
    // Work with x = ωα and K α = alpha_k: |H|² = κ²/(κ² + x² − 2xκ sin x).
    let gain = |x: f64| {
        let d = alpha_k * alpha_k + x * x - 2.0 * x * alpha_k * x.sin();
        (alpha_k * alpha_k / d).sqrt()
    };
    let points = 5000;
    let (mut best_x, mut best) = (0.0, 1.0); // ω → 0 limit
    for k in 1..=points {
        let x = 50.0 * k as f64 / points as f64;
        if gain(x) > best {
            best = gain(x);
            best_x = x;
        }
    }
    if best_x > 0.0 {
        let h = 50.0 / points as f64;
        let (_, v) = golden_max(gain, (best_x - h).max(1e-12), best_x + h);
        best = best.max(v);
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// `sup_ω |H(iω)|` for `H = η/(τs³ + s² + μs + η)` in closed form:
    /// `|H|² = η²/(η² + p(x))`, `p(x) = τ²x³ + (1 − 2μτ)x² + (μ² − 2η)x`, `x = ω²`.
    fn closed_form_peak(tau: f64, mu: f64, eta: f64) -> f64 {
        let (c3, c2, c1) = (tau * tau, 1.0 - 2.0 * mu * tau, mu * mu - 2.0 * eta);
        let p = |x: f64| ((c3 * x + c2) * x + c1) * x;
        // Stationary points of p: 3c3 x² + 2c2 x + c1 = 0.
        let disc = 4.0 * c2 * c2 - 12.0 * c3 * c1;
        let mut min_p: f64 = 0.0; // x = 0
        if disc >= 0.0 {
            for sign in [-1.0, 1.0] {
                let x = (-2.0 * c2 + sign * disc.sqrt()) / (6.0 * c3);
                if x > 0.0 {
                    min_p = min_p.min(p(x));
                }
            }
        }
        (eta * eta / (eta * eta + min_p)).sqrt()
    }

    #[test]
    fn unidirectional_ratio_equals_the_closed_form_peak() {
        for &(tau, mu, eta) in &[
            (0.5, 1.0, 0.3),
            (0.2, 0.5, 0.6),
            (0.4, 1.5, 1.0),
            (0.1, 0.3, 0.2),
        ] {
            let p = CaccParams::homogeneous(6, tau, mu, eta, 0.0);
            let r = string_stability(&p, &StringStabilityOptions::default()).unwrap();
            let expected = closed_form_peak(tau, mu, eta);
            for &ratio in &r.successive_peak_ratio {
                assert_relative_eq!(ratio, expected, max_relative = 1e-6);
            }
            assert_eq!(
                r.string_stable,
                expected <= 1.0 + 1e-9,
                "τ={tau} μ={mu} η={eta}"
            );
            // With μτ ≤ 1/2 the closed form reduces to: string stable iff μ² ≥ 2η.
            if mu * tau <= 0.5 {
                assert_eq!(r.string_stable, mu * mu >= 2.0 * eta);
            }
        }
    }

    #[test]
    fn simulated_energy_respects_the_frequency_domain_bounds() {
        // Parseval: ‖e_N‖₂ ≤ (sup|H|)^{N−1} ‖e_1‖₂, and for a string-unstable chain a broadband
        // pulse is amplified.
        let opts = StringStabilityOptions {
            horizon_s: 300.0,
            step_s: 5e-3,
            ..Default::default()
        };
        let stable =
            string_stability(&CaccParams::homogeneous(8, 0.5, 1.0, 0.3, 0.0), &opts).unwrap();
        assert!(stable.string_stable);
        assert!(stable.simulated_energy_amplification <= 1.0 + 1e-6);
        let unstable =
            string_stability(&CaccParams::homogeneous(8, 0.2, 0.5, 0.6, 0.0), &opts).unwrap();
        assert!(!unstable.string_stable);
        assert!(unstable.simulated_energy_amplification > 1.0);
        assert!(
            unstable.simulated_energy_amplification
                <= unstable.max_successive_ratio.powi(7) * (1.0 + 1e-6)
        );
        assert!(unstable.simulated_peak_amplification > 1.0);
    }

    #[test]
    fn rk4_converges_at_fourth_order() {
        let p = CaccParams::homogeneous(5, 0.4, 0.9, 0.3, 0.2);
        let a = p.closed_loop_matrix().unwrap();
        let b = disturbance_input(&p, LeaderDisturbance::GapOnly);
        // State at t = 6 s; the pulse corners (2 s, 4 s) are on every grid, so each RK4 step
        // sees a smooth input and the global error is O(h⁴).
        let state = |h: f64| {
            let mut last = DVector::zeros(15);
            rk4_simulate(
                &a,
                &b,
                braking_pulse(3.0, 2.0),
                h,
                (6.0 / h).round() as usize,
                |_, x| last = x.clone(),
            );
            last
        };
        let (x1, x2, x3) = (state(0.04), state(0.02), state(0.01));
        let ratio = (&x1 - &x2).norm() / (&x2 - &x3).norm();
        assert!(
            ratio > 14.0 && ratio < 18.0,
            "observed error ratio {ratio}, expected 2⁴"
        );
    }

    #[test]
    fn bidirectional_transfer_matches_steady_state_sine_response() {
        // Drive the leader with w = sin(ωt) and compare steady-state gap amplitudes with
        // |G_i(iω)| from the linear solve (two independent routes).
        let p = CaccParams::homogeneous(4, 0.3, 1.2, 0.4, 0.3);
        let a = p.closed_loop_matrix().unwrap();
        let b = disturbance_input(&p, LeaderDisturbance::Broadcast);
        let omega = 0.7;
        let g = gap_transfers(&a, &b, omega);
        let h = 1e-3;
        let period = 2.0 * std::f64::consts::PI / omega;
        let t_settle = 150.0;
        let steps = ((t_settle + period) / h) as usize;
        let mut amp = [0.0f64; 4];
        rk4_simulate(
            &a,
            &b,
            |t| (omega * t).sin(),
            h,
            steps,
            |t, x| {
                if t > t_settle {
                    for i in 0..4 {
                        amp[i] = amp[i].max(x[3 * i].abs());
                    }
                }
            },
        );
        for i in 0..4 {
            assert_relative_eq!(amp[i], g[i].norm(), max_relative = 1e-4);
        }
    }

    #[test]
    fn chandler_straight_road_is_string_stable_iff_two_alpha_k_at_most_one() {
        for &ak in &[0.1, 0.3, 0.49, 0.5] {
            assert!(chandler_string_peak(ak) <= 1.0 + 1e-15, "αK = {ak}");
        }
        let mut previous = 1.0;
        for &ak in &[0.501, 0.55, 0.8, 1.2, 1.5, 1.56] {
            let peak = chandler_string_peak(ak);
            assert!(peak > previous, "αK = {ak}: peak {peak} not increasing");
            previous = peak;
        }
        // Near αK = π/2 the follower's root approaches iK, and the peak blows up.
        assert!(chandler_string_peak(std::f64::consts::FRAC_PI_2 - 1e-4) > 1e3);
        assert_eq!(chandler_string_peak(2.0), f64::INFINITY);
    }

    #[test]
    fn errors_are_specific() {
        let p = CaccParams::homogeneous(3, 1.0, 0.1, 2.0, 0.5);
        let e = string_stability(&p, &StringStabilityOptions::default()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("the platoon is not asymptotically stable"),
            "{e}"
        );
        let opts = StringStabilityOptions {
            step_s: 0.0,
            ..Default::default()
        };
        let e =
            string_stability(&CaccParams::homogeneous(2, 0.5, 1.0, 0.3, 0.1), &opts).unwrap_err();
        assert_eq!(e.to_string(), "option step_s = 0 must be finite and > 0");
    }
}
