//! Why a run stopped: one typed reason for every backend.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Why a run stopped. Serialized with a `reason` tag (`{"reason": "horizon"}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum StopReason {
    /// The horizon was reached.
    Horizon,
    /// A speed became non-finite or exceeded the divergence bound (native simulator).
    Diverged {
        /// Step index.
        step: usize,
        /// Vehicle index.
        vehicle: usize,
        /// Time \[s\].
        time_s: f64,
    },
    /// The law produced a non-finite speed; it was not sent to SUMO.
    NonFiniteCommand {
        /// SUMO vehicle id.
        vehicle: String,
        /// Step index n (the command was for step n+1).
        step: usize,
        /// The value (as text: NaN, inf).
        value: String,
    },
    /// A vehicle disappeared from the road: the end of a straight road, or on a ring SUMO
    /// removed it (a collision or a teleport).
    VehicleLost {
        /// SUMO vehicle id.
        vehicle: String,
        /// Step index.
        step: usize,
        /// True on a ring, where no road ends.
        #[serde(default)]
        ring: bool,
    },
    /// A signal (Ctrl-C, SIGTERM, SIGHUP) stopped the native simulator; the steps before it
    /// are kept.
    Interrupted {
        /// Steps done.
        step: usize,
        /// Time reached \[s\].
        time_s: f64,
    },
    /// The controller failed: the user's controller raised or returned commands that are not
    /// speeds. The steps before it are kept.
    ControllerFailed {
        /// Step index n (the commands were for step n+1).
        step: usize,
        /// Time \[s\].
        time_s: f64,
        /// What went wrong, with the controller's traceback.
        error: String,
    },
    /// The controller ended the run on purpose before its horizon (the caller closed a
    /// stepping loop); the steps before it are kept.
    StoppedByController {
        /// Step index n.
        step: usize,
        /// Time \[s\].
        time_s: f64,
        /// The controller's reason.
        why: String,
    },
    /// The run failed: the worker crashed, timed out, was interrupted or SUMO refused to start.
    Failed {
        /// What happened, with its cause.
        error: String,
    },
}

impl StopReason {
    /// True when the run reached its horizon.
    pub fn is_complete(&self) -> bool {
        matches!(self, StopReason::Horizon)
    }

    /// What an early stop says about the run's verdict: `Some(true)` when the stop is itself a
    /// finding about the law (its speeds diverged, it commanded a non-finite speed, a vehicle
    /// was lost: the run did not synchronize), `Some(false)` when the run was cut off by
    /// something else (a failure, a signal, the user's controller raising or ending the run:
    /// what the law would have done is not known), `None` when it reached its horizon.
    pub fn is_finding(&self) -> Option<bool> {
        match self {
            StopReason::Horizon => None,
            StopReason::Diverged { .. }
            | StopReason::NonFiniteCommand { .. }
            | StopReason::VehicleLost { .. } => Some(true),
            StopReason::Interrupted { .. }
            | StopReason::ControllerFailed { .. }
            | StopReason::StoppedByController { .. }
            | StopReason::Failed { .. } => Some(false),
        }
    }

    /// The user's whole text behind an early stop, when [`StopReason::message`] shows only
    /// part of it (the run's writer puts it in [`crate::user_text::FULL_TEXT_FILE`]).
    pub fn full_text(&self) -> Option<&str> {
        match self {
            StopReason::ControllerFailed { error, .. } | StopReason::Failed { error } => {
                crate::user_text::is_cut(error).then_some(error.as_str())
            }
            _ => None,
        }
    }

    /// The stop as a record holds it: the user's text in it escaped and cut as messages show
    /// it ([`crate::user_text::capped`]; the whole text goes to the run folder's
    /// [`crate::user_text::FULL_TEXT_FILE`]).
    pub fn recorded(&self) -> StopReason {
        let mut stop = self.clone();
        if let StopReason::ControllerFailed { error, .. } | StopReason::Failed { error } = &mut stop
        {
            *error = crate::user_text::capped(error);
        }
        stop
    }

    /// Why the run stopped early, in words; `None` when it reached the horizon. The user's
    /// text in it (a controller's exception, a worker's last output) is escaped and cut
    /// ([`crate::user_text`]).
    pub fn message(&self) -> Option<String> {
        match self {
            StopReason::Horizon => None,
            StopReason::Diverged {
                vehicle, time_s, ..
            } => Some(format!(
                "speed of vehicle {vehicle} diverged at t = {time_s} s"
            )),
            StopReason::NonFiniteCommand {
                vehicle,
                step,
                value,
            } => Some(format!(
                "the law commanded a non-finite speed ({value} m/s) to vehicle {vehicle} at step {step}; the run stopped before sending it to SUMO"
            )),
            StopReason::VehicleLost {
                vehicle,
                step,
                ring: false,
            } => Some(format!(
                "vehicle {vehicle} left the road at step {step} (end of the straight road?)"
            )),
            StopReason::VehicleLost {
                vehicle,
                step,
                ring: true,
            } => Some(format!(
                "vehicle {vehicle} left the ring at step {step}: SUMO removed it (a collision or a teleport; see sumo/sumo.log)"
            )),
            StopReason::Interrupted { step, time_s } => Some(format!(
                "interrupted at t = {time_s:.3} s (step {step}); the rows so far are written, marked incomplete"
            )),
            StopReason::ControllerFailed {
                step,
                time_s,
                error,
            } => Some(format!(
                "the controller failed at t = {time_s:.3} s (step {step}); the rows before it are written, marked incomplete:\n{}",
                crate::user_text::shown(error)
            )),
            StopReason::StoppedByController { step, time_s, why } => Some(format!(
                "the controller ended the run at t = {time_s:.3} s (step {step}): {why}; the rows before it are written, marked incomplete"
            )),
            StopReason::Failed { error } => Some(crate::user_text::capped(error)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reasons_serialize_with_a_tag_and_name_vehicle_and_step() {
        assert_eq!(
            serde_json::to_string(&StopReason::Horizon).unwrap(),
            r#"{"reason":"horizon"}"#
        );
        let e = StopReason::NonFiniteCommand {
            vehicle: "v3".into(),
            step: 41,
            value: "NaN".into(),
        };
        assert_eq!(
            e.message().unwrap(),
            "the law commanded a non-finite speed (NaN m/s) to vehicle v3 at step 41; the run stopped before sending it to SUMO"
        );
        let back: StopReason = serde_json::from_str(&serde_json::to_string(&e).unwrap()).unwrap();
        assert_eq!(back, e);
        assert!(!e.is_complete() && StopReason::Horizon.is_complete());
    }

    #[test]
    fn a_vehicle_lost_on_a_ring_is_not_blamed_on_the_end_of_a_road() {
        let lost = |ring| StopReason::VehicleLost {
            vehicle: "v17".into(),
            step: 224,
            ring,
        };
        let m = lost(true).message().unwrap();
        assert_eq!(
            m,
            "vehicle v17 left the ring at step 224: SUMO removed it (a collision or a teleport; see sumo/sumo.log)"
        );
        assert!(lost(false)
            .message()
            .unwrap()
            .contains("end of the straight road?"));
        // Records written before the field existed still read.
        let old: StopReason =
            serde_json::from_str(r#"{"reason":"vehicle_lost","vehicle":"v1","step":3}"#).unwrap();
        assert_eq!(
            old,
            StopReason::VehicleLost {
                vehicle: "v1".into(),
                step: 3,
                ring: false
            }
        );
    }
}
