//! The FollowerStopper of Stern et al. (2018): a command velocity that is the desired
//! speed `U` when the gap is large, the leader's speed (capped at `U`) in a band of gaps, and
//! zero when the gap is small, with bands that widen when the vehicle closes in on its leader.
//!
//! With `Δx` the bumper-to-bumper gap, `Δv = v_lead − v` and `Δv⁻ = min(Δv, 0)`, the band
//! edges are
//!
//! `Δx_k = Δx⁰_k + (Δv⁻)² / (2 d_k)`, k = 1, 2, 3,
//!
//! and with `v = min(max(v_lead, 0), U)` the command is
//!
//! ```text
//! v_cmd = 0                                         if Δx ≤ Δx_1
//!       = v (Δx − Δx_1)/(Δx_2 − Δx_1)               if Δx_1 < Δx ≤ Δx_2
//!       = v + (U − v)(Δx − Δx_2)/(Δx_3 − Δx_2)      if Δx_2 < Δx ≤ Δx_3
//!       = U                                         if Δx_3 < Δx
//! ```
//!
//! with `Δx⁰ = (4.5, 5.25, 6.0)` m and `d = (1.5, 1.0, 0.5)` m/s² in the field experiment.
//! The command is continuous in `Δx`: the third band ends at exactly `U`.
//!
//! # Where Flow departs, and what we follow
//! Flow's `FollowerStopper` (flow-project/flow, `flow/controllers/velocity_controllers.py`)
//! uses the same edges and parameters, but writes the third band as
//! `v + (U − v_ego)(Δx − Δx_2)/(Δx_3 − Δx_2)` with the vehicle's *own* speed `v_ego` in place of
//! `v`. That band then ends at `U + v − v_ego`, not `U`, so Flow's command jumps at `Δx_3`
//! whenever the two cars drive at different speeds. **We follow Stern et al.** (continuous,
//! `U − v`); the research group's own later code (e.g. FangChiehChou/safe_FollowerStopper,
//! `modified_FollowerStopper2.m`) has the same `(r − v)` form. Flow's master code returns no
//! command on internal junction lanes and near "danger edges" (simulation plumbing, left out
//! here), has no warm-up skip, applies `(v_cmd − v)/Δt` unclipped and then its
//! `safe_velocity` failsafe (delay 1 s); here the command is tracked within the vehicle's
//! [`AccelLimits`] and there is no failsafe in the law (see `docs/src/wave-dampers.md`).
//!
//! # Reference
//! R. E. Stern, S. Cui, M. L. Delle Monache, R. Bhadani, M. Bunting, M. Churchill,
//! N. Hamilton, R. Haulcy, H. Pohlmann, F. Wu, B. Piccoli, B. Seibold, J. Sprinkle,
//! D. B. Work, "Dissipation of stop-and-go waves via control of autonomous vehicles: Field
//! experiments", Transp. Res. C 89 (2018) 205–221, arXiv:1705.01693: the FollowerStopper.

use serde::Deserialize;

use crate::actuation::{check_step, mismatched_slice, AccelLimits, ActuationError};
use crate::damper::{FleetLaw, RingFleet};
use crate::speed_controller::{law_params, LawContext, LawEntry, Road, SpeedController};

/// The law's entry in [`crate::registry`]: `follower-stopper-U`, or
/// `{"desired_speed_mps": U, "dx0_m": [..], "decel_mps2": [..]}` (the bands default to the
/// field experiment's).
pub const ENTRY: LawEntry = LawEntry {
    name: "follower-stopper",
    summary:
        "FollowerStopper of Stern et al. (2018): desired speed U, the field experiment's bands",
    road: Road::Ring,
    looks_behind: false,
    shorthand: Some("desired_speed_mps"),
    check: |p| {
        let p: FollowerStopperParams = law_params(p)?;
        p.validate().map_err(|e| e.to_string())
    },
    build,
};

fn build(c: &LawContext, p: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
    let fleet = FollowerStopper::new(law_params(p)?, c.ids.len(), c.step_s, c.limits())
        .map_err(|e| e.to_string())?;
    Ok(Box::new(RingFleet::new(c, fleet)))
}

impl FleetLaw for FollowerStopper {
    fn step_fleet(&mut self, v: &[f64], gaps: &[f64], lead: &[f64], out: &mut [f64]) -> bool {
        self.step(v, gaps, lead, out).is_ok()
    }
}

/// Errors of the FollowerStopper: a bad parameter (named, with its value and the valid range)
/// or inputs of the wrong length.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FollowerStopperError {
    /// A parameter outside its valid range.
    #[error("FollowerStopper {name} = {value}: valid is {valid}")]
    Parameter {
        /// The parameter, e.g. `dx0_m[1]`.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The valid range, in words.
        valid: String,
    },
    /// A per-vehicle slice has the wrong length.
    #[error("FollowerStopper: {what} has {len} entries for {n} vehicles")]
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

/// Parameters of the FollowerStopper (as a law's `params`, the bands default to the field
/// experiment's).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FollowerStopperParams {
    /// Desired speed U \[m/s\] (chosen per experiment in Stern et al.; Flow's default is 15).
    pub desired_speed_mps: f64,
    /// Band intercepts Δx⁰_1, Δx⁰_2, Δx⁰_3 \[m\], strictly increasing.
    #[serde(default = "stern2018_dx0_m")]
    pub dx0_m: [f64; 3],
    /// Deceleration rates d_1 ≥ d_2 ≥ d_3 > 0 \[m/s²\] that widen the bands when closing in.
    #[serde(default = "stern2018_decel_mps2")]
    pub decel_mps2: [f64; 3],
}

fn stern2018_dx0_m() -> [f64; 3] {
    FollowerStopperParams::stern2018(0.0).dx0_m
}

fn stern2018_decel_mps2() -> [f64; 3] {
    FollowerStopperParams::stern2018(0.0).decel_mps2
}

impl FollowerStopperParams {
    /// The field experiment's bands, Δx⁰ = (4.5, 5.25, 6.0) m and d = (1.5, 1.0, 0.5) m/s²
    /// (Stern et al. 2018; the same values are Flow's defaults), with desired speed U.
    pub fn stern2018(desired_speed_mps: f64) -> Self {
        Self {
            desired_speed_mps,
            dx0_m: [4.5, 5.25, 6.0],
            decel_mps2: [1.5, 1.0, 0.5],
        }
    }

    /// Checks every parameter. The orderings keep the bands ordered for every Δv:
    /// `Δx_1 < Δx_2 < Δx_3` needs increasing intercepts and non-increasing rates.
    pub fn validate(&self) -> Result<(), FollowerStopperError> {
        let bad = |name, value, valid: String| {
            Err(FollowerStopperError::Parameter { name, value, valid })
        };
        let u = self.desired_speed_mps;
        if !(u.is_finite() && u >= 0.0) {
            return bad("desired_speed_mps", u, "a finite number ≥ 0 m/s".into());
        }
        const DX: [&str; 3] = ["dx0_m[0]", "dx0_m[1]", "dx0_m[2]"];
        const D: [&str; 3] = ["decel_mps2[0]", "decel_mps2[1]", "decel_mps2[2]"];
        for k in 0..3 {
            let dx = self.dx0_m[k];
            if !(dx.is_finite() && dx >= 0.0) {
                return bad(DX[k], dx, "a finite number ≥ 0 m".into());
            }
            if k > 0 && dx <= self.dx0_m[k - 1] {
                let valid = format!(
                    "> {} = {} m (intercepts increase)",
                    DX[k - 1],
                    self.dx0_m[k - 1]
                );
                return bad(DX[k], dx, valid);
            }
            let d = self.decel_mps2[k];
            if !(d.is_finite() && d > 0.0) {
                return bad(D[k], d, "a finite number > 0 m/s²".into());
            }
            if k > 0 && d > self.decel_mps2[k - 1] {
                let valid = format!(
                    "≤ {} = {} m/s² (rates do not increase)",
                    D[k - 1],
                    self.decel_mps2[k - 1]
                );
                return bad(D[k], d, valid);
            }
        }
        Ok(())
    }

    /// Band edges `Δx_k = Δx⁰_k + (Δv⁻)²/(2 d_k)` \[m\] for the relative speed
    /// `dv_mps = v_lead − v`.
    pub fn band_edges_m(&self, dv_mps: f64) -> [f64; 3] {
        let closing = dv_mps.min(0.0);
        std::array::from_fn(|k| self.dx0_m[k] + closing * closing / (2.0 * self.decel_mps2[k]))
    }
}

/// The FollowerStopper's command velocity \[m/s\] for one vehicle driving at `speed_mps` with
/// bumper-to-bumper gap `gap_m` behind a leader driving at `leader_speed_mps`
/// (Stern et al. 2018; see the module documentation).
pub fn follower_stopper_command_mps(
    params: &FollowerStopperParams,
    speed_mps: f64,
    gap_m: f64,
    leader_speed_mps: f64,
) -> f64 {
    let u = params.desired_speed_mps;
    let [x1, x2, x3] = params.band_edges_m(leader_speed_mps - speed_mps);
    let v = leader_speed_mps.max(0.0).min(u);
    if gap_m <= x1 {
        0.0
    } else if gap_m <= x2 {
        v * (gap_m - x1) / (x2 - x1)
    } else if gap_m <= x3 {
        v + (u - v) * (gap_m - x2) / (x3 - x2)
    } else {
        u
    }
}

/// A fleet of FollowerStopper vehicles: the parameters, the step and the acceleration bounds
/// of the low-level tracking. The law is memoryless, so the fleet holds no per-vehicle state
/// beyond its size.
#[derive(Debug, Clone)]
pub struct FollowerStopper {
    params: FollowerStopperParams,
    limits: AccelLimits,
    dt_s: f64,
    n: usize,
}

impl FollowerStopper {
    /// A checked fleet of `n_vehicles` with step `dt_s`.
    pub fn new(
        params: FollowerStopperParams,
        n_vehicles: usize,
        dt_s: f64,
        limits: AccelLimits,
    ) -> Result<Self, FollowerStopperError> {
        params.validate()?;
        check_step(dt_s)?;
        AccelLimits::new(limits.accel_mps2, limits.decel_mps2)?;
        Ok(Self {
            params,
            limits,
            dt_s,
            n: n_vehicles,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &FollowerStopperParams {
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

    /// One step: from each vehicle's speed, gap to its predecessor and the predecessor's speed,
    /// the speed it reaches after `dt_s` tracking its command within the acceleration bounds.
    pub fn step(
        &mut self,
        speeds_mps: &[f64],
        gaps_m: &[f64],
        leader_speeds_mps: &[f64],
        next_speeds_mps: &mut [f64],
    ) -> Result<(), FollowerStopperError> {
        let lengths = [
            ("speeds_mps", speeds_mps.len()),
            ("gaps_m", gaps_m.len()),
            ("leader_speeds_mps", leader_speeds_mps.len()),
            ("next_speeds_mps", next_speeds_mps.len()),
        ];
        if let Some((what, len)) = mismatched_slice(self.n, lengths) {
            return Err(FollowerStopperError::LengthMismatch {
                what,
                len,
                n: self.n,
            });
        }
        for i in 0..self.n {
            let cmd = follower_stopper_command_mps(
                &self.params,
                speeds_mps[i],
                gaps_m[i],
                leader_speeds_mps[i],
            );
            next_speeds_mps[i] = self.limits.next_speed_mps(speeds_mps[i], cmd, self.dt_s);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const U: f64 = 8.0;

    fn fs() -> FollowerStopperParams {
        FollowerStopperParams::stern2018(U)
    }

    #[test]
    fn leader_not_slower_bands_are_the_intercepts() {
        // v = 6, v_lead = 7: Δv = +1, Δv⁻ = 0, so Δx = (4.5, 5.25, 6.0); v = min(7, 8) = 7.
        let c = |gap| follower_stopper_command_mps(&fs(), 6.0, gap, 7.0);
        assert_eq!(fs().band_edges_m(1.0), [4.5, 5.25, 6.0]);
        // Below Δx_1: stop.
        assert_eq!(c(4.0), 0.0);
        assert_eq!(c(4.5), 0.0);
        // Middle of band 1..2: 7 · (4.875 − 4.5)/(5.25 − 4.5) = 7 · 0.375/0.75 = 3.5.
        assert_relative_eq!(c(4.875), 3.5, epsilon = 1e-12);
        // Middle of band 2..3: 7 + (8 − 7) · 0.375/0.75 = 7.5 (Flow: 7 + (8 − 6) · 0.5 = 8).
        assert_relative_eq!(c(5.625), 7.5, epsilon = 1e-12);
        // Band edges are continuous: Δx_2 gives v = 7, Δx_3 gives U = 8.
        assert_relative_eq!(c(5.25), 7.0, epsilon = 1e-12);
        assert_relative_eq!(c(6.0), 8.0, epsilon = 1e-12);
        // Above Δx_3: U.
        assert_eq!(c(10.0), U);
    }

    #[test]
    fn closing_in_widens_the_bands() {
        // v = 8, v_lead = 6: Δv⁻ = −2, (Δv⁻)² = 4, so
        // Δx_1 = 4.5 + 4/3 = 35/6, Δx_2 = 5.25 + 4/2 = 7.25, Δx_3 = 6 + 4/1 = 10.
        let e = fs().band_edges_m(-2.0);
        assert_relative_eq!(e[0], 35.0 / 6.0, epsilon = 1e-12);
        assert_relative_eq!(e[1], 7.25, epsilon = 1e-12);
        assert_relative_eq!(e[2], 10.0, epsilon = 1e-12);
        let c = |gap| follower_stopper_command_mps(&fs(), 8.0, gap, 6.0);
        // 5.0 ≤ 35/6: stop (with the plain intercepts it would be band 1..2).
        assert_eq!(c(5.0), 0.0);
        // 6.5: (6.5 − 35/6)/(7.25 − 35/6) = (2/3)/(17/12) = 8/17, times v = 6: 48/17.
        assert_relative_eq!(c(6.5), 48.0 / 17.0, epsilon = 1e-12);
        // 8.625, the middle of 7.25..10: 6 + (8 − 6)/2 = 7.
        assert_relative_eq!(c(8.625), 7.0, epsilon = 1e-12);
        assert_eq!(c(12.0), U);
    }

    #[test]
    fn leader_speed_is_capped_at_u_and_at_zero() {
        // v_lead = 10 > U = 8 (Δv⁻ = 0 for v = 8): v = 8; middle of band 1..2 gives 4.
        assert_relative_eq!(
            follower_stopper_command_mps(&fs(), 8.0, 4.875, 10.0),
            4.0,
            epsilon = 1e-12
        );
        // v_lead = −1 (a reversing leader), v = 0: v = 0 (Δv⁻ = −1 widens the bands:
        // Δx_2 = 5.25 + 1/2 = 5.75, Δx_3 = 6 + 1 = 7); band 2..3 middle 6.375: 0 + 8 · 0.5 = 4.
        assert_relative_eq!(
            follower_stopper_command_mps(&fs(), 0.0, 6.375, -1.0),
            4.0,
            epsilon = 1e-12
        );
    }

    #[test]
    fn the_fleet_step_tracks_commands_within_the_bounds() {
        let limits = AccelLimits::new(1.5, 3.0).unwrap();
        let mut law = FollowerStopper::new(fs(), 3, 0.1, limits).unwrap();
        let speeds = [6.0, 8.0, 7.0];
        let gaps = [4.875, 5.0, 20.0];
        let leaders = [7.0, 6.0, 7.0];
        let mut next = [0.0; 3];
        law.step(&speeds, &gaps, &leaders, &mut next).unwrap();
        // Vehicle 0: command 3.5 (see above), 6 − b Δt = 6 − 0.3 = 5.7.
        assert_relative_eq!(next[0], 5.7, epsilon = 1e-12);
        // Vehicle 1: command 0, 8 − 0.3 = 7.7.
        assert_relative_eq!(next[1], 7.7, epsilon = 1e-12);
        // Vehicle 2: command U = 8, 7 + a_max Δt = 7 + 0.15 = 7.15.
        assert_relative_eq!(next[2], 7.15, epsilon = 1e-12);
        let err = law
            .step(&speeds, &gaps[..2], &leaders, &mut next)
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "FollowerStopper: gaps_m has 2 entries for 3 vehicles"
        );
    }

    #[test]
    fn invalid_parameters_are_named_with_their_range() {
        let mut p = fs();
        p.desired_speed_mps = f64::NAN;
        assert_eq!(
            p.validate().unwrap_err().to_string(),
            "FollowerStopper desired_speed_mps = NaN: valid is a finite number ≥ 0 m/s"
        );
        let mut p = fs();
        p.dx0_m[1] = 4.5;
        assert_eq!(
            p.validate().unwrap_err().to_string(),
            "FollowerStopper dx0_m[1] = 4.5: valid is > dx0_m[0] = 4.5 m (intercepts increase)"
        );
        let mut p = fs();
        p.decel_mps2[2] = 2.0;
        assert_eq!(
            p.validate().unwrap_err().to_string(),
            "FollowerStopper decel_mps2[2] = 2: valid is ≤ decel_mps2[1] = 1 m/s² (rates do not increase)"
        );
        let mut p = fs();
        p.decel_mps2[0] = 0.0;
        assert!(matches!(
            FollowerStopper::new(p, 1, 0.1, AccelLimits::UNBOUNDED),
            Err(FollowerStopperError::Parameter {
                name: "decel_mps2[0]",
                ..
            })
        ));
        assert!(matches!(
            FollowerStopper::new(fs(), 1, 0.0, AccelLimits::UNBOUNDED),
            Err(FollowerStopperError::Actuation(ActuationError::BadStep(_)))
        ));
    }
}
