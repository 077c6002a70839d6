//! Flow's own FollowerStopper and PISaturation, as its master code computes them, for runs that
//! must reproduce Flow rather than the paper's equations (`flow-follower-stopper-U`,
//! `flow-pi-saturation`). Transcribed from flow-project/flow (master):
//! `flow/controllers/velocity_controllers.py` (`FollowerStopper.get_accel`,
//! `PISaturation.get_accel`), `flow/controllers/base_controller.py` (`get_action`, the
//! `safe_velocity` failsafe) and `flow/core/kernel/vehicle/traci.py` (`apply_acceleration`:
//! `max(v + a Δt, 0)`). Gaps are bumper to bumper, as Flow's `get_headway` (SUMO's leader
//! distance plus the follower's minGap).
//!
//! What differs from [`crate::follower_stopper`] and [`crate::pi_saturation`] (see
//! `docs/src/wave-dampers.md`):
//! * FollowerStopper: the third band `v + (U − v_ego)(Δx − Δx_2)/(Δx_3 − Δx_2)`; the
//!   acceleration `(v_cmd − v)/Δt` unclipped; then the `safe_velocity` failsafe with Flow's
//!   delay of 1 s, `v_safe = 2h/Δt + Δv − 2 v`: if `v + aΔt > v_safe`, `a = (v_safe − v)/Δt`
//!   (or `−v/Δt` when `v_safe ≤ 0`);
//! * PISaturation: the history drops its oldest entry when it reaches `int(38/Δt)` entries
//!   (so it averages `int(38/Δt) − 1` samples), `v_cmd` starts at 0, and the acceleration is
//!   bounded from above only, `min(a, a_max)`.
//!
//! Flow gives no command on junction-internal lanes (SUMO drives the car there); on syncroad's
//! ring every lane is commanded, which is the one difference left.

use std::collections::VecDeque;

use crate::damper::{FleetLaw, RingFleet};
use crate::follower_stopper::FollowerStopperParams;
use crate::pi_saturation::PiSaturationParams;
use crate::speed_controller::{law_params, LawContext, LawEntry, Road, SpeedController};

/// Flow's FollowerStopper in [`crate::registry`]: `flow-follower-stopper-U`, parameters as
/// [`crate::follower_stopper::ENTRY`]'s.
pub const FOLLOWER_STOPPER_ENTRY: LawEntry = LawEntry {
    name: "flow-follower-stopper",
    summary: "Flow's master FollowerStopper (its third band, unclipped acceleration, safe_velocity failsafe)",
    build: |c, p| {
        let params: FollowerStopperParams = law_params(p)?;
        params.validate().map_err(|e| e.to_string())?;
        fleet(c, FlowFollowerStopper::new(params, c.step_s))
    },
    ..crate::follower_stopper::ENTRY
};

/// Flow's PISaturation in [`crate::registry`]: `flow-pi-saturation`, parameters as
/// [`crate::pi_saturation::ENTRY`]'s.
pub const PI_SATURATION_ENTRY: LawEntry = LawEntry {
    name: "flow-pi-saturation",
    summary: "Flow's master PISaturation (its history window, v_cmd from 0, acceleration bounded above only)",
    road: Road::Ring,
    looks_behind: false,
    build: |c, p| {
        let params: PiSaturationParams = law_params(p)?;
        params.validate().map_err(|e| e.to_string())?;
        let n = c.ids.len();
        fleet(c, FlowPiSaturation::new(params, n, c.step_s, c.accel_mps2))
    },
    ..crate::pi_saturation::ENTRY
};

fn fleet<F: FleetLaw + 'static>(c: &LawContext, f: F) -> Result<Box<dyn SpeedController>, String> {
    Ok(Box::new(RingFleet::new(c, f)))
}

impl FleetLaw for FlowFollowerStopper {
    fn step_fleet(&mut self, v: &[f64], gaps: &[f64], lead: &[f64], out: &mut [f64]) -> bool {
        self.step(v, gaps, lead, out);
        true
    }
}

impl FleetLaw for FlowPiSaturation {
    fn step_fleet(&mut self, v: &[f64], gaps: &[f64], lead: &[f64], out: &mut [f64]) -> bool {
        self.step(v, gaps, lead, out);
        true
    }
}

/// Flow's FollowerStopper acceleration before its failsafe \[m/s²\].
pub fn flow_follower_stopper_accel(
    p: &FollowerStopperParams,
    this_vel: f64,
    dx: f64,
    lead_vel: f64,
    sim_step: f64,
) -> f64 {
    let v_des = p.desired_speed_mps;
    let dv_minus = (lead_vel - this_vel).min(0.0);
    let dx_1 = p.dx0_m[0] + 1.0 / (2.0 * p.decel_mps2[0]) * dv_minus.powi(2);
    let dx_2 = p.dx0_m[1] + 1.0 / (2.0 * p.decel_mps2[1]) * dv_minus.powi(2);
    let dx_3 = p.dx0_m[2] + 1.0 / (2.0 * p.decel_mps2[2]) * dv_minus.powi(2);
    let v = lead_vel.max(0.0).min(v_des);
    let v_cmd = if dx <= dx_1 {
        0.0
    } else if dx <= dx_2 {
        v * (dx - dx_1) / (dx_2 - dx_1)
    } else if dx <= dx_3 {
        v + (v_des - this_vel) * (dx - dx_2) / (dx_3 - dx_2)
    } else {
        v_des
    };
    (v_cmd - this_vel) / sim_step
}

/// Flow's `safe_velocity` failsafe applied to `action` \[m/s²\] (`delay` \[s\] as Flow's
/// `BaseController.delay`, 1 s for its FollowerStopper).
pub fn flow_safe_velocity_action(
    action: f64,
    this_vel: f64,
    h: f64,
    lead_vel: f64,
    sim_step: f64,
    delay: f64,
) -> f64 {
    let v_safe = 2.0 * h / sim_step + (lead_vel - this_vel) - this_vel * (2.0 * delay);
    if this_vel + action * sim_step > v_safe {
        if v_safe > 0.0 {
            (v_safe - this_vel) / sim_step
        } else {
            -this_vel / sim_step
        }
    } else {
        action
    }
}

/// Flow's `apply_acceleration`: the speed after one step.
pub fn flow_next_speed(this_vel: f64, accel: f64, sim_step: f64) -> f64 {
    (this_vel + accel * sim_step).max(0.0)
}

/// Flow's FollowerStopper on a fleet (memoryless).
#[derive(Debug, Clone)]
pub struct FlowFollowerStopper {
    params: FollowerStopperParams,
    dt_s: f64,
}

/// Flow's `delay` of its FollowerStopper, used by the `safe_velocity` failsafe \[s\].
pub const FLOW_FOLLOWER_STOPPER_DELAY_S: f64 = 1.0;

impl FlowFollowerStopper {
    /// A fleet with step `dt_s` (parameters checked by the caller).
    pub fn new(params: FollowerStopperParams, dt_s: f64) -> Self {
        Self { params, dt_s }
    }

    /// One step of every vehicle.
    pub fn step(&mut self, speeds: &[f64], gaps: &[f64], leaders: &[f64], out: &mut [f64]) {
        let dt = self.dt_s;
        for i in 0..speeds.len() {
            let a = flow_follower_stopper_accel(&self.params, speeds[i], gaps[i], leaders[i], dt);
            let a = flow_safe_velocity_action(
                a,
                speeds[i],
                gaps[i],
                leaders[i],
                dt,
                FLOW_FOLLOWER_STOPPER_DELAY_S,
            );
            out[i] = flow_next_speed(speeds[i], a, dt);
        }
    }
}

/// Flow's PISaturation on a fleet: per-vehicle history and command.
#[derive(Debug, Clone)]
pub struct FlowPiSaturation {
    params: PiSaturationParams,
    dt_s: f64,
    max_accel_mps2: f64,
    /// `int(38/Δt)`: the history length at which Flow drops its oldest entry.
    cut: usize,
    history: Vec<VecDeque<f64>>,
    v_cmd: Vec<f64>,
}

impl FlowPiSaturation {
    /// `n` vehicles, step `dt_s`, Flow's `max_accel` (the vehicle type's accel).
    pub fn new(params: PiSaturationParams, n: usize, dt_s: f64, max_accel_mps2: f64) -> Self {
        Self {
            params,
            dt_s,
            max_accel_mps2,
            cut: (params.window_s / dt_s).trunc() as usize,
            history: vec![VecDeque::new(); n],
            v_cmd: vec![0.0; n],
        }
    }

    /// Samples Flow averages once its history is full, `int(38/Δt) − 1`.
    pub fn window_len(&self) -> usize {
        self.cut.saturating_sub(1)
    }

    /// One step of every vehicle.
    // Flow's `min(max(x, 0), 1)` is kept as written (clamp differs for NaN).
    #[allow(clippy::manual_clamp)]
    pub fn step(&mut self, speeds: &[f64], gaps: &[f64], leaders: &[f64], out: &mut [f64]) {
        let p = &self.params;
        for i in 0..speeds.len() {
            let (this_vel, dx, lead_vel) = (speeds[i], gaps[i], leaders[i]);
            let dv = lead_vel - this_vel;
            let dx_s = (p.safe_gap_gain_s * dv).max(p.safe_gap_min_m);
            let h = &mut self.history[i];
            h.push_back(this_vel);
            if h.len() == self.cut {
                h.pop_front();
            }
            let v_des = h.iter().sum::<f64>() / h.len() as f64;
            let v_target = v_des
                + p.catch_up_speed_mps
                    * ((dx - p.gap_lower_m) / (p.gap_upper_m - p.gap_lower_m))
                        .max(0.0)
                        .min(1.0);
            let alpha = ((dx - dx_s) / p.blend_width_m).max(0.0).min(1.0);
            let beta = 1.0 - 0.5 * alpha;
            self.v_cmd[i] =
                beta * (alpha * v_target + (1.0 - alpha) * lead_vel) + (1.0 - beta) * self.v_cmd[i];
            let accel = ((self.v_cmd[i] - this_vel) / self.dt_s).min(self.max_accel_mps2);
            out[i] = flow_next_speed(this_vel, accel, self.dt_s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuation::AccelLimits;
    use crate::follower_stopper::{follower_stopper_command_mps, FollowerStopper};
    use crate::pi_saturation::PiSaturation;
    use approx::assert_relative_eq;

    /// States recorded from a noisy ring: 22 stochastic humans from a uniform start, 300 s,
    /// on the native simulator (speeds, gaps, leader speeds every step).
    fn recorded_states() -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        use crate::noisy_idm::{HumanController, HumanSetup, NoisyIdm};
        use crate::speed_controller::SpeedController;
        struct Hold;
        impl SpeedController for Hold {
            fn step(&mut self, _: f64, v: &[f64], _: &[f64], out: &mut [f64]) {
                out.copy_from_slice(v);
            }
        }
        let n = 22;
        let ring = 230.0;
        let setup = HumanSetup {
            drivers: vec![Some(NoisyIdm::HUMAN_NOISY); n],
            ring_length_m: ring,
            length_m: vec![5.0; n],
            seed: 3,
            speed_limit_mps: None,
        };
        let mut c = HumanController::new(Box::new(Hold), &setup, 0.1);
        let mut q: Vec<f64> = (0..n).map(|i| -(i as f64) * ring / n as f64).collect();
        let mut v = vec![4.0; n];
        let mut next = vec![0.0; n];
        let mut states = Vec::new();
        for k in 0..3000 {
            c.step(k as f64 * 0.1, &v, &q, &mut next);
            for i in 0..n {
                q[i] += 0.05 * (v[i] + next[i]);
            }
            std::mem::swap(&mut v, &mut next);
            let gaps: Vec<f64> = (0..n)
                .map(|i| {
                    let (a, wrap) = if i == 0 { (n - 1, ring) } else { (i - 1, 0.0) };
                    q[a] + wrap - q[i] - 5.0
                })
                .collect();
            let leaders: Vec<f64> = (0..n).map(|i| v[(i + n - 1) % n]).collect();
            states.push((v.clone(), gaps, leaders));
        }
        states
    }

    #[test]
    fn flow_follower_stopper_differs_from_ours_only_as_documented() {
        // On every recorded state: Flow's speed equals ours (unbounded tracking) wherever its
        // failsafe is inactive and the gap is outside the third band; in the third band the two
        // commands differ by exactly (v − v_ego)(Δx − Δx_2)/(Δx_3 − Δx_2).
        let p = FollowerStopperParams::stern2018(4.3);
        let dt = 0.1;
        let mut ours = FollowerStopper::new(p, 22, dt, AccelLimits::UNBOUNDED).unwrap();
        let mut flow = FlowFollowerStopper::new(p, dt);
        let (mut a, mut b) = (vec![0.0; 22], vec![0.0; 22]);
        let (mut third, mut failsafe, mut same) = (0, 0, 0);
        for (v, g, l) in recorded_states() {
            ours.step(&v, &g, &l, &mut a).unwrap();
            flow.step(&v, &g, &l, &mut b);
            for i in 0..22 {
                let raw = flow_follower_stopper_accel(&p, v[i], g[i], l[i], dt);
                let safe = flow_safe_velocity_action(raw, v[i], g[i], l[i], dt, 1.0);
                let [x1, x2, x3] = p.band_edges_m(l[i] - v[i]);
                if safe != raw {
                    failsafe += 1;
                    continue;
                }
                let cmd = follower_stopper_command_mps(&p, v[i], g[i], l[i]);
                if g[i] > x2 && g[i] <= x3 {
                    third += 1;
                    let vv = l[i].clamp(0.0, 4.3);
                    let diff = (vv - v[i]) * (g[i] - x2) / (x3 - x2);
                    // Flow's speed is never negative: max(v + aΔt, 0).
                    assert_relative_eq!(b[i], (cmd + diff).max(0.0), epsilon = 1e-9);
                } else {
                    same += 1;
                    let _ = x1;
                    assert_relative_eq!(a[i], b[i], epsilon = 1e-9);
                }
            }
        }
        // The test saw every case.
        assert!(
            third > 100 && same > 1000,
            "third band {third}, same {same}"
        );
        eprintln!("FollowerStopper states: {same} equal, {third} third band, {failsafe} failsafe");
    }

    #[test]
    fn flow_follower_stopper_by_hand() {
        let p = FollowerStopperParams::stern2018(8.0);
        // v_ego = 4 behind a 5 m/s leader (Δv > 0: bands 4.5, 5.25, 6), gap 5.625 m in the
        // third band: Flow's command 5 + (8 − 4)·0.5 = 7, the paper's 5 + (8 − 5)·0.5 = 6.5;
        // Flow's acceleration (7 − 4)/0.1 = 30 m/s², unclipped.
        assert_relative_eq!(
            flow_follower_stopper_accel(&p, 4.0, 5.625, 5.0, 0.1),
            30.0,
            epsilon = 1e-12
        );
        assert_relative_eq!(
            follower_stopper_command_mps(&p, 4.0, 5.625, 5.0),
            6.5,
            epsilon = 1e-12
        );
        // The failsafe: h = 0.5 m at 6 m/s behind a 5 m/s leader: v_safe = 10 − 1 − 12 < 0,
        // so the car stops in one step.
        assert_relative_eq!(
            flow_safe_velocity_action(3.0, 6.0, 0.5, 5.0, 0.1, 1.0),
            -60.0,
            epsilon = 1e-12
        );
        // A large gap: v_safe = 2·20/0.1 + 0 − 12 = 388, no change.
        assert_eq!(
            flow_safe_velocity_action(3.0, 6.0, 20.0, 6.0, 0.1, 1.0),
            3.0
        );
    }

    #[test]
    fn flow_pi_saturation_window_first_command_and_one_sided_bound() {
        let p = PiSaturationParams::default();
        // int(38/0.1) = 380 in IEEE arithmetic (as in Python), so 379 samples are averaged.
        let mut f = FlowPiSaturation::new(p, 1, 0.1, 1.0);
        assert_eq!(f.window_len(), 379);
        // First step at 5 m/s, leader 5 m/s, gap 3 m (below Δx_s = 4: α = 0, β = 1):
        // v_cmd = v_lead = 5, as ours; with a gap of 20 m (α = 1, β = 1/2) Flow's
        // v_cmd = ½ v_target + ½·0 pulls towards 0: v_target = 5 + (20 − 7)/23,
        // v_cmd = 2.7826, a = (2.7826 − 5)/0.1 = −22.17 (no lower bound), next 2.7826.
        let mut out = [0.0];
        f.step(&[5.0], &[20.0], &[5.0], &mut out);
        let target = 5.0 + 13.0 / 23.0;
        assert_relative_eq!(out[0], 0.5 * target, epsilon = 1e-12);
        let mut ours = PiSaturation::new(p, 1, 0.1, AccelLimits::UNBOUNDED).unwrap();
        let mut o2 = [0.0];
        ours.step(&[5.0], &[20.0], &[5.0], &mut o2).unwrap();
        // Ours starts from the current speed: ½ target + ½ · 5.
        assert_relative_eq!(o2[0], 0.5 * target + 2.5, epsilon = 1e-12);
        // Upper bound only: a leader far faster cannot pull harder than a_max = 1 m/s².
        let mut g = FlowPiSaturation::new(p, 1, 0.1, 1.0);
        g.step(&[5.0], &[3.0], &[9.0], &mut out);
        assert_relative_eq!(out[0], 5.1, epsilon = 1e-12);
        // After 400 steps at a constant speed the history holds 379 samples.
        let mut h = FlowPiSaturation::new(p, 1, 0.1, 1.0);
        for _ in 0..400 {
            h.step(&[5.0], &[3.0], &[5.0], &mut out);
        }
        assert_eq!(h.history[0].len(), 379);
    }
}
