//! The benchmark's timer of the loop, present only for a [`Job::Bench`](crate::protocol::Job):
//! which steps run in full ([`Probe::full_step`]), the wall time of the timed steps, of each
//! phase of a step and, in [`ProbeMode::Loop`], of each observer.

use std::time::Instant;

use super::step::StepTimes;
use crate::probe::{Probe, ProbeMode, ProbeTimes};

/// Times the loop for a [`Probe`].
pub(super) struct ProbeTimer {
    probe: Probe,
    times: ProbeTimes,
    /// Kind (bare?) and start of the step being timed.
    current: Option<(bool, Instant)>,
    loop_start: Instant,
}

impl ProbeTimer {
    pub fn new(probe: Probe) -> Self {
        Self {
            probe,
            times: ProbeTimes::default(),
            current: None,
            loop_start: Instant::now(),
        }
    }

    /// Called at the start of each step; true when the step runs in full. The wall time of the
    /// step before is attributed to its kind here.
    pub fn start_step(&mut self, step: usize) -> bool {
        if self.probe.mode == ProbeMode::Plain {
            // No clock per step: the timed steps' wall time is read at their start and end.
            if step == self.probe.untimed_steps {
                self.loop_start = Instant::now();
            }
            return true;
        }
        let now = Instant::now();
        if step == self.probe.untimed_steps {
            self.loop_start = now;
        }
        let full = self.probe.full_step(step);
        if let Some((was_bare, t0)) = self.current.take() {
            self.times
                .phases
                .add_step(was_bare, (now - t0).as_secs_f64());
        }
        if step >= self.probe.untimed_steps {
            self.current = Some((!full, now));
        }
        full
    }

    /// True when each observer is timed on its own (the profile); the overhead runs leave
    /// them untimed so the timer adds nothing to what they measure.
    pub fn profiles_observers(&self) -> bool {
        self.probe.mode == ProbeMode::Loop
    }

    /// Keeps the phase times of a full step.
    pub fn stepped(&mut self, step: usize, t: &StepTimes) {
        if step >= self.probe.untimed_steps {
            let p = &mut self.times.phases;
            p.command_s += t.command_s;
            p.step_s += t.step_s;
            p.read_speeds_s += t.read_s;
        }
    }

    /// Keeps the time an observer took after step `step`.
    pub fn observed(&mut self, step: usize, name: &str, since: Instant) {
        if step >= self.probe.untimed_steps {
            self.times
                .phases
                .add_observer(name, since.elapsed().as_secs_f64());
        }
    }

    /// The times, once the loop is done after `steps_done` steps.
    pub fn finish(mut self, steps_done: usize) -> ProbeTimes {
        if let Some((was_bare, t0)) = self.current.take() {
            self.times
                .phases
                .add_step(was_bare, t0.elapsed().as_secs_f64());
        }
        self.times.loop_wall_s = self.loop_start.elapsed().as_secs_f64();
        self.times.timed_steps = steps_done.saturating_sub(self.probe.untimed_steps);
        self.times
    }
}
