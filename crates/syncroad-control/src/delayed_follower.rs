//! The delayed-driver law of eq. `chandler+` as a law of the registry, for drivers that each
//! follow whoever is ahead of them: `v_i'(t) = u_i(t − α)`, `u_i = K (v_ahead − v_i)`, and no
//! input while nobody is ahead. On a ring this is the scenario law on a unidirectional ring of
//! gain K; on an open road it drives vehicles that enter and leave (an inflow's `controlled`
//! vehicles), each on its own behind whoever the simulator reports ahead of it.
//!
//! Each driver runs a one-driver [`DelayedDriverLaw`] whose leader, with pinning gain K, is the
//! vehicle ahead at each step, so the discretisation is the scenario law's own (its stencils on
//! the delay grid). The history before the driver's first step is "no reaction pending"
//! (`u = 0` for t < 0, `"history": "no_reaction"`): a vehicle that has just entered has not yet
//! reacted to anyone. The delay is at least one step, so every input a step needs is in the
//! past and the scheme is the scenario law's explicit one.

use serde::Deserialize;

use crate::delayed_driver::{DelayedDriverLaw, HistorySpec};
use crate::graph::Graph;
use crate::road::RingView;
use crate::speed_controller::{law_params, LawContext, LawEntry, Road, SpeedController};

/// The law's entry in [`crate::registry`]: `delayed-driver`, parameters `gain` and `delay_s`.
pub const ENTRY: LawEntry = LawEntry {
    name: "delayed-driver",
    summary: "the paper's delayed driver (eq. chandler+) following whoever is ahead: u = K (v_ahead − v), acted on after α",
    road: Road::Any,
    looks_behind: false,
    shorthand: None,
    check: |p| law_params::<Params>(p)?.check(),
    build,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// The gain K \[1/s\] on the speed difference to the vehicle ahead.
    gain: f64,
    /// The reaction delay α \[s\], a whole number of steps, at least one.
    delay_s: f64,
}

impl Params {
    fn check(&self) -> Result<(), String> {
        if !(self.gain.is_finite() && self.gain > 0.0) {
            return Err(format!(
                "gain = {}: valid is a finite number > 0 (1/s)",
                self.gain
            ));
        }
        if !(self.delay_s.is_finite() && self.delay_s > 0.0) {
            return Err(format!(
                "delay_s = {}: valid is a finite number > 0 s, a whole number of steps",
                self.delay_s
            ));
        }
        Ok(())
    }

    /// The delay in steps of `dt_s`.
    fn delay_steps(&self, dt_s: f64) -> Result<usize, String> {
        let m = (self.delay_s / dt_s).round();
        if m < 1.0 || (m * dt_s - self.delay_s).abs() > 1e-9 * dt_s.max(self.delay_s) {
            return Err(format!(
                "delay_s = {}: must be a whole number of steps of {dt_s} s, at least one (nearest: {})",
                self.delay_s,
                (m.max(1.0) * dt_s * 1e9).round() / 1e9
            ));
        }
        Ok(m as usize)
    }
}

fn build(c: &LawContext, p: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
    let p: Params = law_params(p)?;
    p.check()?;
    let m = p.delay_steps(c.step_s)?;
    let alone = Graph::from_arcs(1, &[]).map_err(|e| e.to_string())?;
    let drivers = (0..c.ids.len())
        .map(|_| {
            DelayedDriverLaw::new(
                &alone,
                &[m],
                c.step_s,
                Some(&[p.gain]),
                &[0.0],
                None,
                HistorySpec::NoReaction,
            )
            .map_err(|e| e.to_string())
        })
        .collect::<Result<_, _>>()?;
    Ok(Box::new(DelayedFollower {
        drivers,
        view: RingView::on(c.ring_length_m, &c.length_m),
    }))
}

/// One delayed driver per vehicle, each pinned to the vehicle ahead of it.
struct DelayedFollower {
    drivers: Vec<DelayedDriverLaw>,
    view: RingView,
}

impl SpeedController for DelayedFollower {
    fn step(&mut self, _t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        if speeds.len() != self.drivers.len() {
            // A bug in the caller: NaN commands stop the run before they reach SUMO.
            out.fill(f64::NAN);
            return;
        }
        self.view.observe(speeds, positions);
        for (i, d) in self.drivers.iter_mut().enumerate() {
            let ahead = self.view.leader_speeds_mps[i];
            // Nobody ahead: no input (the driver's own speed as its leader's).
            let v0 = if ahead.is_finite() { ahead } else { speeds[i] };
            d.step(&speeds[i..=i], v0, &mut out[i..=i]);
        }
    }

    fn sense(&mut self, neighbors: &crate::sensed::Neighbors) {
        self.view.sense(neighbors);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn its_parameters_are_checked() {
        let law = |p: &str| {
            let p: serde_json::Value = serde_json::from_str(p).unwrap();
            (super::ENTRY.check)(&p)
        };
        assert!(law(r#"{"gain": 0.5, "delay_s": 0.4}"#).is_ok());
        assert_eq!(
            law(r#"{"gain": 0, "delay_s": 0.4}"#).unwrap_err(),
            "gain = 0: valid is a finite number > 0 (1/s)"
        );
        assert!(law(r#"{"gain": 1}"#)
            .unwrap_err()
            .contains("missing field `delay_s`"));
        let p: super::Params = serde_json::from_str(r#"{"gain": 1, "delay_s": 0.25}"#).unwrap();
        assert_eq!(
            p.delay_steps(0.1).unwrap_err(),
            "delay_s = 0.25: must be a whole number of steps of 0.1 s, at least one (nearest: 0.3)"
        );
        let p: super::Params = serde_json::from_str(r#"{"gain": 1, "delay_s": 0.3}"#).unwrap();
        assert_eq!(p.delay_steps(0.1), Ok(3));
    }
}
