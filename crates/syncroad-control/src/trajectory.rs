//! Recorded trajectories: time, speed, position (and gaps for platoons), sampled every few steps.

use std::io::Write;

/// Samples of a run, stored time-major (`speeds_mps[k * n + i]` is vehicle i at sample k).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trajectory {
    /// Number of vehicles N.
    pub n: usize,
    /// Sample times [s].
    pub time_s: Vec<f64>,
    /// Speeds [m/s].
    pub speeds_mps: Vec<f64>,
    /// Unwrapped positions along the road (odometer) [m].
    pub positions_m: Vec<f64>,
    /// Bumper-to-bumper gaps to the predecessor [m].
    pub gaps_m: Vec<f64>,
    /// Leader (reference) speed v_0 per sample, when there is a leader.
    pub leader_speed_mps: Vec<f64>,
    /// Speeds the law commanded for each sample (NaN where another driver drives); empty
    /// unless the backend records them (the SUMO loop does).
    pub commands_mps: Vec<f64>,
}

impl Trajectory {
    /// An empty trajectory for `n` vehicles.
    pub fn new(n: usize) -> Self {
        Self {
            n,
            ..Self::default()
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// True when nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Appends one sample.
    pub fn push(
        &mut self,
        t: f64,
        speeds: &[f64],
        positions: &[f64],
        gaps: &[f64],
        leader: Option<f64>,
    ) {
        self.time_s.push(t);
        self.speeds_mps.extend_from_slice(speeds);
        self.positions_m.extend_from_slice(positions);
        self.gaps_m.extend_from_slice(gaps);
        if let Some(v0) = leader {
            self.leader_speed_mps.push(v0);
        }
    }

    /// The most samples a run of `steps` steps records every `every`-th step: the state after
    /// insertion, every `every`-th step, and the last one.
    pub fn samples_recorded(steps: usize, every: usize) -> usize {
        steps / every.max(1) + 2
    }

    /// Room for `samples` more samples of [`Trajectory::push_commanded`]: a run's rows come in
    /// chunks, and growing to the run's length chunk by chunk copied them over and over.
    pub fn reserve_commanded(&mut self, samples: usize) {
        let values = samples.saturating_mul(self.n);
        self.time_s.reserve(samples);
        self.speeds_mps.reserve(values);
        self.positions_m.reserve(values);
        self.commands_mps.reserve(values);
    }

    /// Appends one sample of speeds, positions and commands, without gaps (the rows a SUMO
    /// worker streams, every vehicle on the road).
    pub fn push_commanded(&mut self, t: f64, speeds: &[f64], positions: &[f64], commands: &[f64]) {
        self.time_s.push(t);
        self.speeds_mps.extend_from_slice(speeds);
        self.positions_m.extend_from_slice(positions);
        self.commands_mps.extend_from_slice(commands);
    }

    /// Moves the samples of `other` to the end of `self`.
    pub fn append(&mut self, other: &mut Trajectory) {
        self.time_s.append(&mut other.time_s);
        self.speeds_mps.append(&mut other.speeds_mps);
        self.positions_m.append(&mut other.positions_m);
        self.gaps_m.append(&mut other.gaps_m);
        self.leader_speed_mps.append(&mut other.leader_speed_mps);
        self.commands_mps.append(&mut other.commands_mps);
    }

    /// Speeds of sample `k`.
    pub fn speeds(&self, k: usize) -> &[f64] {
        &self.speeds_mps[k * self.n..(k + 1) * self.n]
    }

    /// Gaps of sample `k`.
    pub fn gaps(&self, k: usize) -> &[f64] {
        &self.gaps_m[k * self.n..(k + 1) * self.n]
    }

    /// Leader speed at sample `k`, if there is a leader.
    pub fn leader(&self, k: usize) -> Option<f64> {
        self.leader_speed_mps.get(k).copied()
    }

    /// Writes the trajectory as long-format CSV: `time_s,vehicle,speed_mps,position_m,gap_m`.
    pub fn write_csv(&self, mut w: impl Write) -> std::io::Result<()> {
        writeln!(w, "time_s,vehicle,speed_mps,position_m,gap_m")?;
        for k in 0..self.len() {
            let t = self.time_s[k];
            for i in 0..self.n {
                let j = k * self.n + i;
                writeln!(
                    w,
                    "{t},{i},{},{},{}",
                    self.speeds_mps[j], self.positions_m[j], self.gaps_m[j]
                )?;
            }
        }
        Ok(())
    }
}
