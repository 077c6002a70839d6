//! The benchmark's probe: what `syncroad sumo-bench` asks a worker to time, and what the worker
//! measures. A run's [`Request`](crate::protocol::Request) carries none of it; the benchmark
//! sends its request inside a [`Job::Bench`](crate::protocol::Job) and the worker adds the
//! timing observer of the loop (`cosim::timing`) for that job only.

use serde::{Deserialize, Serialize};

/// How the benchmark drives the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum ProbeMode {
    /// SUMO alone: one full step commands every vehicle once (SUMO keeps a `setSpeed` until it
    /// is changed), every later step is `simulationStep` only (no law, reads, commands,
    /// counters or rows). SUMO does the same work per step as under the law.
    Alone,
    /// The full loop on every step, each phase and each observer timed.
    Loop,
    /// The full loop on every step with only an ordinary run's clocks (the two around SUMO's
    /// step, and the start and end of the timed steps): the loop's cost as a user's run pays
    /// it, over SUMO's step in the same run.
    Plain,
    /// Blocks of `block` steps alternate between SUMO alone and the full loop in one process,
    /// so both kinds of step share caches, frequency and neighbours (same-process overhead).
    Interleaved {
        /// Steps per block.
        block: usize,
    },
}

/// What the benchmark asks of one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Probe {
    /// How the loop is driven.
    #[serde(flatten)]
    pub mode: ProbeMode,
    /// Steps at the start that the timer leaves out (warm-up).
    pub untimed_steps: usize,
}

impl Probe {
    /// True when step `step` is run in full (law, commands, reads, observers); false for a
    /// bare `simulationStep`.
    pub fn full_step(&self, step: usize) -> bool {
        match self.mode {
            ProbeMode::Alone => step == 0,
            ProbeMode::Loop | ProbeMode::Plain => true,
            ProbeMode::Interleaved { block } => !(step / block.max(1)).is_multiple_of(2),
        }
    }
}

/// Wall time of the timed steps by phase \[s\].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimes {
    /// The law plus the speed commands.
    pub command_s: f64,
    /// `simulation.step` (SUMO itself).
    pub step_s: f64,
    /// Reading every vehicle's speed (and, every few steps, its odometer) back.
    pub read_speeds_s: f64,
    /// Each observer of the loop by name (safety counters, rows, measurements, ...), in the
    /// order the loop calls them.
    pub observers: Vec<(String, f64)>,
    /// With [`ProbeMode::Interleaved`]: wall time of the bare steps (SUMO only) and of the full
    /// steps \[s\], over equally many timed steps.
    pub bare_wall_s: f64,
    /// See `bare_wall_s`.
    pub controlled_wall_s: f64,
    /// Timed steps of each kind.
    pub bare_steps: usize,
    /// See `bare_steps`.
    pub controlled_steps: usize,
}

impl PhaseTimes {
    /// Adds the wall time of one step of either kind.
    pub fn add_step(&mut self, bare: bool, seconds: f64) {
        if bare {
            self.bare_wall_s += seconds;
            self.bare_steps += 1;
        } else {
            self.controlled_wall_s += seconds;
            self.controlled_steps += 1;
        }
    }

    /// Adds `seconds` to the observer called `name`.
    pub fn add_observer(&mut self, name: &str, seconds: f64) {
        match self.observers.iter_mut().find(|(n, _)| n == name) {
            Some((_, s)) => *s += seconds,
            None => self.observers.push((name.to_string(), seconds)),
        }
    }

    /// Time of all observers \[s\].
    pub fn observers_s(&self) -> f64 {
        self.observers.iter().map(|(_, s)| s).sum()
    }
}

/// What the worker measured for a [`Probe`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ProbeTimes {
    /// Wall time of the stepping loop after the untimed steps \[s\].
    pub loop_wall_s: f64,
    /// Steps inside that timing.
    pub timed_steps: usize,
    /// Where the timed wall time went.
    pub phases: PhaseTimes,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interleaved_blocks_start_bare_and_alternate() {
        let p = Probe {
            mode: ProbeMode::Interleaved { block: 3 },
            untimed_steps: 0,
        };
        let full: Vec<bool> = (0..12).map(|s| p.full_step(s)).collect();
        let f = false;
        let t = true;
        assert_eq!(full, [f, f, f, t, t, t, f, f, f, t, t, t]);
    }

    #[test]
    fn plain_and_loop_run_every_step_in_full() {
        for mode in [ProbeMode::Plain, ProbeMode::Loop] {
            let p = Probe {
                mode,
                untimed_steps: 5,
            };
            assert!((0..100).all(|s| p.full_step(s)), "{mode:?}");
        }
    }

    #[test]
    fn alone_commands_once_then_only_steps() {
        let p = Probe {
            mode: ProbeMode::Alone,
            untimed_steps: 5,
        };
        assert!(p.full_step(0));
        assert!((1..100).all(|s| !p.full_step(s)));
    }

    #[test]
    fn a_probe_reads_back_as_sent() {
        let p = Probe {
            mode: ProbeMode::Interleaved { block: 25 },
            untimed_steps: 100,
        };
        let s = serde_json::to_string(&p).unwrap();
        assert_eq!(
            s,
            r#"{"mode":"interleaved","block":25,"untimed_steps":100}"#
        );
        assert_eq!(serde_json::from_str::<Probe>(&s).unwrap(), p);
    }
}
