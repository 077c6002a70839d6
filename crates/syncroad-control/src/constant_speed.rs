//! A constant target speed: every vehicle it drives tracks the speed U within its type's
//! acceleration bounds, whatever the traffic around it — the simplest reference law (a cruise
//! control with no car following), and the guide's example of adding a law to the registry.
//!
//! `v_{n+1} = v_n + clamp(U − v_n, −b Δt, a_max Δt)` ([`AccelLimits::next_speed_mps`]).

use serde::Deserialize;

use crate::actuation::AccelLimits;
use crate::speed_controller::{law_params, LawEntry, Road, SpeedController};

/// The law's entry in [`crate::registry`]: `constant-speed-U`.
pub const ENTRY: LawEntry = LawEntry {
    name: "constant-speed",
    summary:
        "every vehicle tracks the target speed U within its acceleration bounds (no car following)",
    road: Road::Any,
    looks_behind: false,
    shorthand: Some("target_speed_mps"),
    check: |p| law_params::<Params>(p)?.check(),
    build: |c, p| {
        let p: Params = law_params(p)?;
        p.check()?;
        Ok(Box::new(ConstantSpeed {
            target_mps: p.target_speed_mps,
            limits: c.limits(),
            dt_s: c.step_s,
        }))
    },
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// Target speed U \[m/s\].
    target_speed_mps: f64,
}

impl Params {
    fn check(&self) -> Result<(), String> {
        let u = self.target_speed_mps;
        if u.is_finite() && u >= 0.0 {
            Ok(())
        } else {
            Err(format!(
                "target_speed_mps = {u}: valid is a finite number ≥ 0 m/s"
            ))
        }
    }
}

/// Every vehicle tracks one target speed.
struct ConstantSpeed {
    target_mps: f64,
    limits: AccelLimits,
    dt_s: f64,
}

impl SpeedController for ConstantSpeed {
    fn step(&mut self, _t: f64, speeds: &[f64], _positions: &[f64], out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(speeds) {
            *o = self.limits.next_speed_mps(*v, self.target_mps, self.dt_s);
        }
    }
}
