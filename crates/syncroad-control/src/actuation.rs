//! From a commanded speed to the speed a vehicle reaches one step later.
//!
//! The wave dampers of Stern et al. ([`follower_stopper`](crate::follower_stopper),
//! [`pi_saturation`](crate::pi_saturation)) output a *command velocity* `v_cmd` that a
//! lower-level controller tracks. In a fixed-step simulation the simplest tracker reaches
//! `v_cmd` in one step, `a = (v_cmd − v)/Δt` (Flow's choice), here bounded by what the vehicle
//! can do: `−b ≤ a ≤ a_max` (Flow's master code does not bound it; see
//! [`flow_dampers`](crate::flow_dampers)). [`AccelLimits::next_speed_mps`] applies exactly that, and never
//! returns a negative speed.
//!
//! # Reference
//! R. E. Stern et al., "Dissipation of stop-and-go waves via control of autonomous vehicles:
//! Field experiments", Transp. Res. C 89 (2018) 205–221 (the command velocity is tracked
//! by the vehicle's own low-level controller).

/// Errors naming a bad acceleration bound.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActuationError {
    /// A bound is not a number > 0 (∞ is allowed: no bound).
    #[error("{name} = {value} m/s²: must be > 0 (use infinity for no bound)")]
    NotPositive {
        /// Which bound.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The step is not a finite number > 0.
    #[error("dt_s = {0} s: the step must be a finite number > 0")]
    BadStep(f64),
}

/// Bounds on the acceleration that tracks a commanded speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelLimits {
    /// Largest acceleration a_max \[m/s²\] (> 0, may be ∞).
    pub accel_mps2: f64,
    /// Largest deceleration b \[m/s²\] (> 0, may be ∞), applied as `a ≥ −b`.
    pub decel_mps2: f64,
}

impl AccelLimits {
    /// No bounds: the command is reached in one step.
    pub const UNBOUNDED: AccelLimits = AccelLimits {
        accel_mps2: f64::INFINITY,
        decel_mps2: f64::INFINITY,
    };

    /// Checked bounds.
    pub fn new(accel_mps2: f64, decel_mps2: f64) -> Result<Self, ActuationError> {
        for (name, value) in [("accel_mps2", accel_mps2), ("decel_mps2", decel_mps2)] {
            if value.is_nan() || value <= 0.0 {
                return Err(ActuationError::NotPositive { name, value });
            }
        }
        Ok(Self {
            accel_mps2,
            decel_mps2,
        })
    }

    /// The speed after one step `dt_s` of tracking `command_mps` from `speed_mps`:
    /// `max(0, v + clamp(v_cmd − v, −b Δt, a_max Δt))`.
    pub fn next_speed_mps(&self, speed_mps: f64, command_mps: f64, dt_s: f64) -> f64 {
        let dv = (command_mps - speed_mps).clamp(-self.decel_mps2 * dt_s, self.accel_mps2 * dt_s);
        (speed_mps + dv).max(0.0)
    }
}

/// Checks a step length.
pub(crate) fn check_step(dt_s: f64) -> Result<(), ActuationError> {
    if dt_s.is_finite() && dt_s > 0.0 {
        Ok(())
    } else {
        Err(ActuationError::BadStep(dt_s))
    }
}

/// The first of a fleet controller's slices whose length is not the fleet size `n`, as
/// `(name, length)`.
pub fn mismatched_slice<const K: usize>(
    n: usize,
    slices: [(&'static str, usize); K],
) -> Option<(&'static str, usize)> {
    slices.into_iter().find(|&(_, len)| len != n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn bounds_clip_the_one_step_acceleration() {
        let lim = AccelLimits::new(1.0, 3.0).unwrap();
        // Up: 5 → 9 wanted, a_max Δt = 1.0 · 0.1 = 0.1, so 5.1.
        assert_relative_eq!(lim.next_speed_mps(5.0, 9.0, 0.1), 5.1);
        // Down: 5 → 0 wanted, b Δt = 3.0 · 0.1 = 0.3, so 4.7.
        assert_relative_eq!(lim.next_speed_mps(5.0, 0.0, 0.1), 4.7);
        // Inside the bounds the command is reached: 5 → 5.05.
        assert_relative_eq!(lim.next_speed_mps(5.0, 5.05, 0.1), 5.05);
        // Unbounded reaches any command, but never a negative speed.
        assert_relative_eq!(AccelLimits::UNBOUNDED.next_speed_mps(5.0, 0.0, 0.1), 0.0);
        assert_relative_eq!(AccelLimits::UNBOUNDED.next_speed_mps(1.0, -2.0, 0.1), 0.0);
    }

    #[test]
    fn bad_bounds_are_named() {
        assert_eq!(
            AccelLimits::new(0.0, 1.0).unwrap_err().to_string(),
            "accel_mps2 = 0 m/s²: must be > 0 (use infinity for no bound)"
        );
        assert!(matches!(
            AccelLimits::new(1.0, f64::NAN),
            Err(ActuationError::NotPositive {
                name: "decel_mps2",
                ..
            })
        ));
        assert_eq!(
            check_step(-0.1).unwrap_err().to_string(),
            "dt_s = -0.1 s: the step must be a finite number > 0"
        );
    }
}
