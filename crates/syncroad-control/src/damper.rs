//! The field's wave dampers as ring controllers: [`RingFleet`] runs a fleet law (the
//! FollowerStopper or the PI controller with saturation of Stern et al. (2018), or Flow's
//! versions of them) on every vehicle of a ring, so that a SUMO run (or a mixed ring, where
//! only some vehicles take its commands) drives them through the same bridge as the
//! synchronization law. Each damper is an entry of [`crate::registry`].
//!
//! Each vehicle i follows vehicle i−1 (vehicle 0 follows vehicle N−1, one lap ahead). From the
//! unwrapped rear-bumper positions `q` the controller forms the bumper-to-bumper gap
//! `Δx_i = q_{i−1} − q_i − ℓ_i` (`+ C` for vehicle 0, C the ring's circumference as the backend
//! measures it) and the leader's speed `v_{i−1}`, and steps the fleet law, which tracks each
//! command velocity within the vehicle's acceleration bounds ([`AccelLimits`]).
//!
//! # Reference
//! R. E. Stern et al., "Dissipation of stop-and-go waves via control of autonomous vehicles:
//! Field experiments", Transp. Res. C 89 (2018) 205–221.

use crate::actuation::AccelLimits;
use crate::road::RingView;
use crate::speed_controller::{LawContext, SpeedController};

/// A law that steps every vehicle of a ring from its speed, its gap to the vehicle ahead and
/// that vehicle's speed, writing the speeds reached one step later.
pub trait FleetLaw: Send {
    /// One step; `false` when the inputs do not fit the fleet (a bug in the caller).
    fn step_fleet(
        &mut self,
        speeds_mps: &[f64],
        gaps_m: &[f64],
        leader_speeds_mps: &[f64],
        next_speeds_mps: &mut [f64],
    ) -> bool;
}

/// A [`FleetLaw`] on every vehicle of a road (a mixed ring sends only some of its commands):
/// the ring's gaps and leader speeds formed from the positions, or sensed from SUMO.
pub struct RingFleet<F> {
    fleet: F,
    view: RingView,
}

impl<F: FleetLaw> RingFleet<F> {
    /// `fleet` on the road of `context`.
    pub fn new(context: &LawContext, fleet: F) -> Self {
        Self {
            fleet,
            view: RingView::on(context.ring_length_m, &context.length_m),
        }
    }
}

impl<F: FleetLaw> SpeedController for RingFleet<F> {
    fn step(&mut self, _t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        self.view.observe(speeds, positions);
        // The slices have the fleet's length by construction; a mismatch is a bug in the
        // caller, reported as NaN commands, which the loop stops on before they reach SUMO.
        let ok =
            self.fleet
                .step_fleet(speeds, &self.view.gaps_m, &self.view.leader_speeds_mps, out);
        if !ok {
            out.fill(f64::NAN);
        }
    }

    fn sense(&mut self, neighbors: &crate::sensed::Neighbors) {
        self.view.sense(neighbors);
    }
}

impl LawContext {
    /// The bounds a velocity command is tracked within: the vehicles' type's.
    pub fn limits(&self) -> AccelLimits {
        AccelLimits {
            accel_mps2: self.accel_mps2,
            decel_mps2: self.decel_mps2,
        }
    }
}
