//! The proportional-integral controller with saturation of Stern et al. (2018).
//!
//! The vehicle estimates the speed of the flow as the mean `U` of its *own* speed over a long
//! window (38 s in the field experiment; on a ring every vehicle has the same long-run mean
//! speed), drives a little faster than `U` when the gap is large, and blends towards the
//! leader's speed when the gap is small:
//!
//! ```text
//! v_target = U + v_catch · min(max((Δx − g_l)/(g_u − g_l), 0), 1)
//! Δx_s     = max(k_s Δv, s_min)                     (k_s = 2 s, s_min = 4 m)
//! α        = min(max((Δx − Δx_s)/γ, 0), 1),   β = 1 − α/2
//! v_cmd⁺   = β (α v_target + (1 − α) v_lead) + (1 − β) v_cmd
//! ```
//!
//! with `Δx` the bumper-to-bumper gap, `Δv = v_lead − v`, and `g_l = 7` m, `g_u = 30` m,
//! `v_catch = 1` m/s, `γ = 2` m. The integral action is the long average `U`; the saturation is
//! the clamping of the catch-up term and of the weight `α`: with a gap below `Δx_s` the command
//! is exactly the leader's speed (`α = 0`, `β = 1`); with a gap above `Δx_s + γ` it relaxes
//! halfway (`β = 1/2`) towards `v_target` each step.
//!
//! # Where Flow departs, and what we follow
//! Flow's `PISaturation` (flow-project/flow, `flow/controllers/velocity_controllers.py`) has
//! the same equations and constants (window 38 s, γ = 2, g_l = 7, g_u = 30, v_catch = 1,
//! Δx_s = max(2Δv, 4)). It differs in three details, where **we follow the equations above**:
//! * it drops the oldest entry of its speed history when the history reaches `int(38/Δt)`
//!   entries, so the mean runs over `int(38/Δt) − 1` samples (379 at Δt = 0.1 s); we average
//!   exactly `round(window/Δt)` samples, the newest being the current speed;
//! * it starts with `v_cmd = 0`, so the first commands pull a moving vehicle towards zero;
//!   the paper gives no initial command, and we start from the vehicle's current speed;
//! * it bounds the resulting acceleration only from above (`min(a, a_max)`); here the
//!   bounds are the caller's [`AccelLimits`];
//! * like every Flow controller it gives no command on junction-internal lanes (SUMO drives
//!   the car there); here every step is commanded.
//!
//! We read `U` as the average of the controlled vehicle's own speed, as Flow does. The
//! paper's full text was not at hand when this module was written, so the equations above
//! are the ones implemented and tested here; they agree with Flow's code line by line
//! except for the three details listed.
//!
//! # Reference
//! R. E. Stern et al., "Dissipation of stop-and-go waves via control of autonomous vehicles:
//! Field experiments", Transp. Res. C 89 (2018) 205–221, arXiv:1705.01693: the
//! proportional-integral controller with saturation.

use crate::actuation::{check_step, mismatched_slice, AccelLimits, ActuationError};
use crate::damper::{FleetLaw, RingFleet};
use crate::speed_controller::{law_params, LawContext, LawEntry, Road, SpeedController};

/// The law's entry in [`crate::registry`]: `pi-saturation`, or any of
/// [`PiSaturationParams`]' fields as `params` (the others the field experiment's).
pub const ENTRY: LawEntry = LawEntry {
    name: "pi-saturation",
    summary:
        "PI controller with saturation of Stern et al. (2018), the field experiment's parameters",
    road: Road::Ring,
    looks_behind: false,
    shorthand: None,
    check: |p| {
        let p: PiSaturationParams = law_params(p)?;
        p.validate().map_err(|e| e.to_string())
    },
    build,
};

fn build(c: &LawContext, p: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
    let fleet = PiSaturation::new(law_params(p)?, c.ids.len(), c.step_s, c.limits())
        .map_err(|e| e.to_string())?;
    Ok(Box::new(RingFleet::new(c, fleet)))
}

impl FleetLaw for PiSaturation {
    fn step_fleet(&mut self, v: &[f64], gaps: &[f64], lead: &[f64], out: &mut [f64]) -> bool {
        self.step(v, gaps, lead, out).is_ok()
    }
}

/// Errors of the PI controller with saturation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PiSaturationError {
    /// A parameter outside its valid range.
    #[error("PI with saturation {name} = {value}: valid is {valid}")]
    Parameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The valid range, in words.
        valid: String,
    },
    /// A per-vehicle slice has the wrong length.
    #[error("PI with saturation: {what} has {len} entries for {n} vehicles")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Its length.
        len: usize,
        /// Number of vehicles.
        n: usize,
    },
    /// Bad acceleration bounds or step.
    #[error(transparent)]
    Actuation(#[from] ActuationError),
}

/// Parameters of the PI controller with saturation (as a law's `params`, each defaults to the
/// field experiment's).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PiSaturationParams {
    /// Averaging window of the vehicle's own speed, giving U \[s\] (38 s).
    pub window_s: f64,
    /// Gap g_l below which no catch-up speed is added \[m\] (7 m).
    pub gap_lower_m: f64,
    /// Gap g_u above which the full catch-up speed is added \[m\] (30 m).
    pub gap_upper_m: f64,
    /// Catch-up speed v_catch added to U at large gaps \[m/s\] (1 m/s).
    pub catch_up_speed_mps: f64,
    /// Width γ of the gap band over which α rises from 0 to 1 \[m\] (2 m).
    pub blend_width_m: f64,
    /// Gain k_s of the safe gap Δx_s = max(k_s Δv, s_min) \[s\] (2 s).
    pub safe_gap_gain_s: f64,
    /// Floor s_min of the safe gap \[m\] (4 m).
    pub safe_gap_min_m: f64,
}

impl Default for PiSaturationParams {
    /// The field experiment's values (Stern et al. 2018; the same are Flow's).
    fn default() -> Self {
        Self {
            window_s: 38.0,
            gap_lower_m: 7.0,
            gap_upper_m: 30.0,
            catch_up_speed_mps: 1.0,
            blend_width_m: 2.0,
            safe_gap_gain_s: 2.0,
            safe_gap_min_m: 4.0,
        }
    }
}

impl PiSaturationParams {
    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), PiSaturationError> {
        let bad =
            |name, value, valid: String| Err(PiSaturationError::Parameter { name, value, valid });
        let positive = [
            ("window_s", self.window_s, "s"),
            ("blend_width_m", self.blend_width_m, "m"),
        ];
        for (name, value, unit) in positive {
            if !(value.is_finite() && value > 0.0) {
                return bad(name, value, format!("a finite number > 0 {unit}"));
            }
        }
        let non_negative = [
            ("gap_lower_m", self.gap_lower_m, "m"),
            ("catch_up_speed_mps", self.catch_up_speed_mps, "m/s"),
            ("safe_gap_gain_s", self.safe_gap_gain_s, "s"),
            ("safe_gap_min_m", self.safe_gap_min_m, "m"),
        ];
        for (name, value, unit) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return bad(name, value, format!("a finite number ≥ 0 {unit}"));
            }
        }
        let gu = self.gap_upper_m;
        if !(gu.is_finite() && gu > self.gap_lower_m) {
            return bad(
                "gap_upper_m",
                gu,
                format!("a finite number > gap_lower_m = {} m", self.gap_lower_m),
            );
        }
        Ok(())
    }

    /// Target speed `v_target = U + v_catch · min(max((Δx − g_l)/(g_u − g_l), 0), 1)` \[m/s\]
    /// for the mean own speed `mean_speed_mps` (U) and the gap `gap_m`.
    pub fn target_speed_mps(&self, mean_speed_mps: f64, gap_m: f64) -> f64 {
        let ramp = (gap_m - self.gap_lower_m) / (self.gap_upper_m - self.gap_lower_m);
        mean_speed_mps + self.catch_up_speed_mps * ramp.clamp(0.0, 1.0)
    }

    /// Weights `(α, β)`: `Δx_s = max(k_s Δv, s_min)`, `α = min(max((Δx − Δx_s)/γ, 0), 1)`,
    /// `β = 1 − α/2`, for the gap `gap_m` and `dv_mps = v_lead − v`.
    pub fn weights(&self, gap_m: f64, dv_mps: f64) -> (f64, f64) {
        let safe_gap_m = (self.safe_gap_gain_s * dv_mps).max(self.safe_gap_min_m);
        let alpha = ((gap_m - safe_gap_m) / self.blend_width_m).clamp(0.0, 1.0);
        (alpha, 1.0 - 0.5 * alpha)
    }
}

/// The next command velocity \[m/s\] of one vehicle:
/// `β (α v_target + (1 − α) v_lead) + (1 − β) v_cmd`, from the mean own speed U
/// (`mean_speed_mps`), the vehicle's speed, its gap, the leader's speed and the previous
/// command (Stern et al. 2018).
pub fn pi_saturation_command_mps(
    params: &PiSaturationParams,
    mean_speed_mps: f64,
    speed_mps: f64,
    gap_m: f64,
    leader_speed_mps: f64,
    previous_command_mps: f64,
) -> f64 {
    let target = params.target_speed_mps(mean_speed_mps, gap_m);
    let (alpha, beta) = params.weights(gap_m, leader_speed_mps - speed_mps);
    // Far enough behind (α = 1, nobody ahead included: gap +∞, leader speed NaN) the leader's
    // weight is 0 and its term is left out rather than multiplied by 0.
    let lead = if alpha < 1.0 {
        (1.0 - alpha) * leader_speed_mps
    } else {
        0.0
    };
    beta * (alpha * target + lead) + (1.0 - beta) * previous_command_mps
}

/// A fleet of PI-with-saturation vehicles: parameters, per-vehicle speed history (the
/// window) and last command.
#[derive(Debug, Clone)]
pub struct PiSaturation {
    params: PiSaturationParams,
    limits: AccelLimits,
    dt_s: f64,
    n: usize,
    /// Samples per window, `round(window_s / dt_s)`.
    window_len: usize,
    /// Ring buffer of the fleet's speeds, one slot of `n` after another: vehicle i's sample in
    /// slot k is `history[k*n + i]`. Slot-major, eight vehicles' sums are added side by side
    /// as the slots go by ([`PiSaturation::update_means`]), each still in slot order.
    history: Vec<f64>,
    /// The window's mean speed of every vehicle after the last step (NaN before the first).
    means: Vec<f64>,
    /// Samples stored so far (≤ window_len), the same for every vehicle.
    filled: usize,
    /// Slot the next sample goes to.
    head: usize,
    /// Last command of each vehicle; `None` before the first step.
    command_mps: Option<Vec<f64>>,
}

impl PiSaturation {
    /// A checked fleet of `n_vehicles` with step `dt_s`.
    pub fn new(
        params: PiSaturationParams,
        n_vehicles: usize,
        dt_s: f64,
        limits: AccelLimits,
    ) -> Result<Self, PiSaturationError> {
        params.validate()?;
        check_step(dt_s)?;
        AccelLimits::new(limits.accel_mps2, limits.decel_mps2)?;
        let window_len = (params.window_s / dt_s).round();
        if window_len < 1.0 {
            return Err(PiSaturationError::Parameter {
                name: "window_s",
                value: params.window_s,
                valid: format!("at least half the step dt_s = {dt_s} s"),
            });
        }
        let window_len = window_len as usize;
        Ok(Self {
            params,
            limits,
            dt_s,
            n: n_vehicles,
            window_len,
            history: vec![0.0; n_vehicles * window_len],
            means: vec![f64::NAN; n_vehicles],
            filled: 0,
            head: 0,
            command_mps: None,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &PiSaturationParams {
        &self.params
    }

    /// Number of vehicles.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True for an empty fleet.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Samples in a full averaging window.
    pub fn window_len(&self) -> usize {
        self.window_len
    }

    /// Mean own speed U of vehicle `i` over the samples stored so far \[m/s\] (NaN before the
    /// first step).
    pub fn mean_speed_mps(&self, i: usize) -> f64 {
        self.means[i]
    }

    /// Every vehicle's window mean into `means`. Before the window fills, the stored samples
    /// are slots 0..filled. Each sum starts at -0.0 and adds slot after slot, as
    /// `Iterator::sum` over the vehicle's own samples would; eight vehicles' sums are kept in
    /// registers side by side (one vehicle at a time, each sum was a chain of dependent
    /// additions, most of the law's time).
    fn update_means(&mut self) {
        /// Vehicles whose sums stay in registers while the slots go by.
        const BLOCK: usize = 8;
        let (n, filled) = (self.n, self.filled);
        let slots = &self.history[..n * filled];
        for (b, means) in self.means.chunks_mut(BLOCK).enumerate() {
            let first = b * BLOCK;
            let mut acc = [-0.0f64; BLOCK];
            // A whole block has a length the compiler knows, so its sums stay in registers;
            // one loop for both cases did not (200 000 steps of 22 vehicles: 0.29 s this way,
            // 0.58 s with one loop, 0.38 s adding a whole slot across the fleet).
            if means.len() == BLOCK {
                for slot in slots.chunks_exact(n) {
                    let xs: &[f64; BLOCK] = slot[first..first + BLOCK]
                        .try_into()
                        .expect("a whole block");
                    for (a, x) in acc.iter_mut().zip(xs) {
                        *a += x;
                    }
                }
            } else {
                for slot in slots.chunks_exact(n) {
                    for (a, x) in acc.iter_mut().zip(&slot[first..]) {
                        *a += x;
                    }
                }
            }
            for (m, a) in means.iter_mut().zip(acc) {
                *m = a / filled as f64;
            }
        }
    }

    /// The last commands (empty before the first step).
    pub fn commands_mps(&self) -> &[f64] {
        self.command_mps.as_deref().unwrap_or(&[])
    }

    /// One step: records each vehicle's speed in its window, updates its command, and writes
    /// the speed it reaches after `dt_s` tracking the command within the acceleration bounds.
    pub fn step(
        &mut self,
        speeds_mps: &[f64],
        gaps_m: &[f64],
        leader_speeds_mps: &[f64],
        next_speeds_mps: &mut [f64],
    ) -> Result<(), PiSaturationError> {
        let lengths = [
            ("speeds_mps", speeds_mps.len()),
            ("gaps_m", gaps_m.len()),
            ("leader_speeds_mps", leader_speeds_mps.len()),
            ("next_speeds_mps", next_speeds_mps.len()),
        ];
        if let Some((what, len)) = mismatched_slice(self.n, lengths) {
            return Err(PiSaturationError::LengthMismatch {
                what,
                len,
                n: self.n,
            });
        }
        let n = self.n;
        self.history[self.head * n..(self.head + 1) * n].copy_from_slice(speeds_mps);
        self.head = (self.head + 1) % self.window_len;
        self.filled = (self.filled + 1).min(self.window_len);
        self.update_means();
        // The paper gives no initial command; start from the current speeds.
        let mut commands = self
            .command_mps
            .take()
            .unwrap_or_else(|| speeds_mps.to_vec());
        for i in 0..self.n {
            commands[i] = pi_saturation_command_mps(
                &self.params,
                self.means[i],
                speeds_mps[i],
                gaps_m[i],
                leader_speeds_mps[i],
                commands[i],
            );
            next_speeds_mps[i] = self
                .limits
                .next_speed_mps(speeds_mps[i], commands[i], self.dt_s);
        }
        self.command_mps = Some(commands);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn p() -> PiSaturationParams {
        PiSaturationParams::default()
    }

    #[test]
    fn target_speed_saturates_between_the_gap_thresholds() {
        // Below g_l = 7: U only.
        assert_relative_eq!(p().target_speed_mps(5.0, 3.0), 5.0);
        // Middle of 7..30 (18.5): U + 1 · (18.5 − 7)/23 = U + 0.5.
        assert_relative_eq!(p().target_speed_mps(5.0, 18.5), 5.5, epsilon = 1e-12);
        // Above g_u: U + v_catch = U + 1.
        assert_relative_eq!(p().target_speed_mps(5.0, 100.0), 6.0);
    }

    #[test]
    fn weights_follow_the_safe_gap() {
        // Δv = 0: Δx_s = max(0, 4) = 4. Gap 5: α = (5 − 4)/2 = 0.5, β = 1 − 0.25 = 0.75.
        assert_eq!(p().weights(5.0, 0.0), (0.5, 0.75));
        // Gap ≤ Δx_s: α = 0, β = 1.
        assert_eq!(p().weights(3.0, 0.0), (0.0, 1.0));
        // Gap ≥ Δx_s + γ: α = 1, β = 1/2.
        assert_eq!(p().weights(30.0, 0.0), (1.0, 0.5));
        // Leader faster by 3 m/s: Δx_s = max(2 · 3, 4) = 6; gap 7: α = 0.5.
        assert_eq!(p().weights(7.0, 3.0), (0.5, 0.75));
    }

    #[test]
    fn with_nobody_ahead_the_command_is_the_target_blended_with_the_last() {
        // An open road: no leader (gap +∞, speed NaN). α = 1, β = 1/2: the command is
        // (U + catch-up) / 2 + previous / 2, with U = 5 and the full catch-up speed.
        let c = pi_saturation_command_mps(&p(), 5.0, 5.0, f64::INFINITY, f64::NAN, 6.0);
        let target = p().target_speed_mps(5.0, f64::INFINITY);
        assert!(target.is_finite());
        assert_eq!(c, 0.5 * target + 0.5 * 6.0);
    }

    #[test]
    fn command_blends_target_leader_and_previous_command() {
        // U = 5, v = 4, v_lead = 4, gap 5 (< g_l, so v_target = U = 5), previous command 6:
        // α = 0.5, β = 0.75: 0.75 (0.5 · 5 + 0.5 · 4) + 0.25 · 6 = 3.375 + 1.5 = 4.875.
        assert_relative_eq!(
            pi_saturation_command_mps(&p(), 5.0, 4.0, 5.0, 4.0, 6.0),
            4.875,
            epsilon = 1e-12
        );
        // Gap 3 < Δx_s: saturated to the leader's speed, whatever U and the last command.
        assert_eq!(
            pi_saturation_command_mps(&p(), 5.0, 4.0, 3.0, 4.0, 6.0),
            4.0
        );
    }

    #[test]
    fn a_fleets_window_means_are_each_vehicles_own_sum_bit_for_bit() {
        // 11 vehicles (a block of 8 summed in registers and 3 more), a window of 5 samples,
        // 13 steps: the window wraps twice. The reference
        // keeps each vehicle's own ring of 5 slots and adds it with `Iterator::sum`, slot by
        // slot (the order the fleet's vector addition keeps); its mean is also the mean of
        // the last 5 speeds, chronologically.
        let params = PiSaturationParams {
            window_s: 5.0,
            ..p()
        };
        let (n, w) = (11, 5);
        let mut law = PiSaturation::new(params, n, 1.0, AccelLimits::UNBOUNDED).unwrap();
        let mut rings = vec![vec![0.0f64; w]; n];
        let mut seen: Vec<Vec<f64>> = vec![Vec::new(); n];
        let mut last_cmd: Option<Vec<f64>> = None;
        let mut next = vec![0.0; n];
        for t in 0..13 {
            // Speeds with many significant bits, so that the order of additions shows.
            let speeds: Vec<f64> = (0..n)
                .map(|i| 10.0 + 0.1 * (t as f64 * 1.7 + i as f64).sin() + 1e-7 * t as f64)
                .collect();
            // Far, in the blend band and saturated, in turn; each follows the next vehicle.
            let gaps: Vec<f64> = (0..n).map(|i| [30.0, 12.0, 3.0][i % 3]).collect();
            let lead: Vec<f64> = (0..n).map(|i| speeds[(i + 1) % n]).collect();
            law.step(&speeds, &gaps, &lead, &mut next).unwrap();
            let filled = (t + 1).min(w);
            let prev = last_cmd.take().unwrap_or_else(|| speeds.clone());
            let mut cmds = vec![0.0; n];
            for i in 0..n {
                rings[i][t % w] = speeds[i];
                seen[i].push(speeds[i]);
                let mean = rings[i][..filled].iter().sum::<f64>() / filled as f64;
                assert_eq!(
                    law.mean_speed_mps(i).to_bits(),
                    mean.to_bits(),
                    "t {t} i {i}"
                );
                let recent = &seen[i][seen[i].len() - filled..];
                let chrono = recent.iter().sum::<f64>() / filled as f64;
                assert_relative_eq!(mean, chrono, max_relative = 1e-14);
                cmds[i] =
                    pi_saturation_command_mps(&p(), mean, speeds[i], gaps[i], lead[i], prev[i]);
                assert_eq!(law.commands_mps()[i].to_bits(), cmds[i].to_bits());
            }
            last_cmd = Some(cmds);
        }
    }

    #[test]
    fn the_window_mean_drives_the_commands_of_a_scripted_run() {
        // Window 3 s at Δt = 1 s: 3 samples. Gap 30 ≥ g_u and Δv = 0: v_target = U + 1,
        // α = 1, β = 1/2, so v_cmd⁺ = (U + 1)/2 + v_cmd/2, starting from v_cmd = speed.
        let params = PiSaturationParams {
            window_s: 3.0,
            ..p()
        };
        let mut law = PiSaturation::new(params, 1, 1.0, AccelLimits::UNBOUNDED).unwrap();
        assert_eq!(law.window_len(), 3);
        let mut next = [0.0];
        // speed 3: U = 3,          cmd = 4/2 + 3/2      = 3.5
        // speed 6: U = 4.5,        cmd = 5.5/2 + 3.5/2  = 4.5
        // speed 9: U = 6,          cmd = 7/2 + 4.5/2    = 5.75
        // speed 12: U = (6+9+12)/3 = 9 (3 drops out), cmd = 10/2 + 5.75/2 = 7.875
        let expect = [
            (3.0, 3.0, 3.5),
            (6.0, 4.5, 4.5),
            (9.0, 6.0, 5.75),
            (12.0, 9.0, 7.875),
        ];
        for (speed, mean, cmd) in expect {
            law.step(&[speed], &[30.0], &[speed], &mut next).unwrap();
            assert_relative_eq!(law.mean_speed_mps(0), mean, epsilon = 1e-12);
            assert_relative_eq!(law.commands_mps()[0], cmd, epsilon = 1e-12);
            // Unbounded tracking reaches the command.
            assert_relative_eq!(next[0], cmd, epsilon = 1e-12);
        }
    }

    #[test]
    fn bounds_limit_the_tracking_not_the_command() {
        let mut law = PiSaturation::new(p(), 2, 0.1, AccelLimits::new(1.0, 2.0).unwrap()).unwrap();
        let mut next = [0.0; 2];
        // Vehicle 0 (gap 3 < Δx_s) commands the leader's 10 from 5: +a_max Δt = 5.1.
        // Vehicle 1 commands the leader's 0 from 5: −b Δt = 4.8.
        law.step(&[5.0, 5.0], &[3.0, 3.0], &[10.0, 0.0], &mut next)
            .unwrap();
        assert_eq!(law.commands_mps(), &[10.0, 0.0]);
        assert_relative_eq!(next[0], 5.1, epsilon = 1e-12);
        assert_relative_eq!(next[1], 4.8, epsilon = 1e-12);
    }

    #[test]
    fn invalid_parameters_are_named_with_their_range() {
        let bad = PiSaturationParams {
            gap_upper_m: 7.0,
            ..p()
        };
        assert_eq!(
            bad.validate().unwrap_err().to_string(),
            "PI with saturation gap_upper_m = 7: valid is a finite number > gap_lower_m = 7 m"
        );
        let bad = PiSaturationParams {
            blend_width_m: 0.0,
            ..p()
        };
        assert_eq!(
            bad.validate().unwrap_err().to_string(),
            "PI with saturation blend_width_m = 0: valid is a finite number > 0 m"
        );
        let bad = PiSaturationParams {
            window_s: 0.01,
            ..p()
        };
        assert_eq!(
            PiSaturation::new(bad, 1, 0.1, AccelLimits::UNBOUNDED)
                .unwrap_err()
                .to_string(),
            "PI with saturation window_s = 0.01: valid is at least half the step dt_s = 0.1 s"
        );
        let mut law = PiSaturation::new(p(), 2, 0.1, AccelLimits::UNBOUNDED).unwrap();
        let mut next = [0.0; 2];
        assert_eq!(
            law.step(&[1.0], &[1.0, 1.0], &[1.0, 1.0], &mut next)
                .unwrap_err()
                .to_string(),
            "PI with saturation: speeds_mps has 1 entries for 2 vehicles"
        );
    }
}
