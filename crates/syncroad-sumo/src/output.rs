//! The result of a SUMO run seen from the parent: every row the worker streamed and how the run
//! ended, turned into a [`RunOutput`] comparable with the native simulator's.

use std::io::Write as _;
use std::path::Path;

use syncroad_control::metrics::{spread_of_range, SpreadSeries};
use syncroad_control::record::{Controlled, Safety, SumoFacts};
use syncroad_control::scenario::Scenario;
use syncroad_control::sumo_facts::START_TRANSIENT_S;
use syncroad_control::{RunOutput, StopReason, Trajectory};

use crate::net::loop_position;
use crate::protocol::{Control, Finish, Request};
use crate::supervisor::{SupervisorError, WorkerRun};

/// The result of a SUMO run: every row received, and how the run ended.
#[derive(Debug, Clone)]
pub struct SumoRun {
    /// The request that was run.
    pub request: Request,
    /// What the worker produced.
    pub worker: WorkerRun,
}

/// Occurrences of SUMO's emergency-braking warning in its log: all of them, and those up to
/// [`START_TRANSIENT_S`] (the warning ends with `time=T.`).
fn emergency_braking_warnings(log: &Path) -> (usize, usize) {
    let Ok(text) = std::fs::read_to_string(log) else {
        return (0, 0);
    };
    let mut all = 0;
    let mut start = 0;
    for line in text
        .lines()
        .filter(|l| l.contains("performs emergency braking"))
    {
        all += 1;
        let t = line
            .rsplit_once("time=")
            .and_then(|(_, t)| t.trim_end().trim_end_matches('.').parse::<f64>().ok());
        if t.is_some_and(|t| t <= START_TRANSIENT_S + 1e-9) {
            start += 1;
        }
    }
    (all, start)
}

impl SumoRun {
    /// Why the run stopped: the worker's stop, or the supervision failure.
    pub fn stop(&self) -> StopReason {
        match &self.worker.result {
            Ok(f) => f.stop.clone(),
            Err(e) => StopReason::Failed {
                error: e.to_string(),
            },
        }
    }

    /// The worker's end-of-run report when the run reached its horizon, else why it stopped.
    pub fn outcome(&self) -> Result<&Finish, StopReason> {
        match &self.worker.result {
            Ok(f) if f.stop.is_complete() => Ok(f),
            _ => Err(self.stop()),
        }
    }

    /// The supervision failure (crash, timeout, Ctrl-C), if any.
    pub fn failure(&self) -> Option<&SupervisorError> {
        self.worker.result.as_ref().err()
    }

    /// Seconds spent inside SUMO's step, when the worker finished its report.
    pub fn step_s(&self) -> Option<f64> {
        self.worker.result.as_ref().ok().map(|f| f.step_s)
    }

    /// SUMO's road length, or the parsed one if SUMO never started.
    pub fn road_length_m(&self) -> f64 {
        self.worker
            .start
            .as_ref()
            .map(|s| s.road_length_m)
            .unwrap_or_else(|| self.request.layout.road.length_m())
    }

    /// The run as every backend reports it: the controlled vehicles' samples, the stop and
    /// the SUMO facts.
    pub fn output(&self, scenario: &Scenario) -> RunOutput {
        let k0 = usize::from(self.request.layout.leader_vehicle);
        let finish = self.worker.result.as_ref().ok();
        let braking = emergency_braking_warnings(&self.request.log_file);
        let start = self.worker.start.as_ref();
        // Law-commanded vehicles are labelled `protocol`, or with the damper that drives them.
        let damper = match &self.request.control {
            Control::Law { law } => law.damper.as_ref().map(|d| d.to_string()),
            _ => None,
        };
        let commanded = damper.unwrap_or_else(|| syncroad_control::PROTOCOL.to_string());
        // Stochastic humans are commanded too, labelled with their driver name.
        let humans = match &self.request.control {
            Control::Law { law } => law.humans.as_ref().map(|h| h.drivers.clone()),
            _ => None,
        };
        let label = |j: usize| -> String {
            match humans.as_ref().and_then(|h| h.get(j).copied().flatten()) {
                Some(d) => syncroad_control::drive::SumoDriver::Noisy(d).to_string(),
                None => commanded.clone(),
            }
        };
        let law_driven = matches!(self.request.control, Control::Law { .. })
            && self.request.layout.vehicles[k0..]
                .iter()
                .any(|v| v.driver.is_none());
        let (ssm, all_vehicles) = self.files_read_after(finish.is_some());
        let facts = SumoFacts {
            sumo_version: start.map(|s| s.python.sumo_version.clone()),
            libsumo: start.map(|s| s.python.libsumo_file.clone()),
            road_length_m: self.road_length_m(),
            gap_scale: self.request.layout.gap_scale,
            step_method: if self.request.ballistic {
                "ballistic"
            } else {
                "euler"
            }
            .into(),
            drivers: self.request.layout.vehicles[k0..]
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    v.driver
                        .as_ref()
                        .map_or_else(|| label(i + k0), |d| d.to_string())
                })
                .collect(),
            safety: finish.map(|f| Safety {
                collision_steps: f.totals.collision_steps,
                colliding_vehicles: f.totals.colliding_vehicles,
                teleports: f.totals.teleports,
                emergency_braking_warnings: braking.0,
                start_emergency_braking_warnings: braking.1,
                overridden_commands: f.totals.overrides,
                negative_commands_clamped: f.totals.negative_commands_clamped,
                topology_changes: f.totals.topology_changes,
            }),
            max_override_mps: finish.map_or(0.0, |f| f.totals.max_override_mps),
            odometer_deviation_max_m: finish.map_or(0.0, |f| f.totals.odometer_deviation_max_m),
            measured: finish.and_then(|f| f.measured.clone()),
            loop_ring_m: self
                .request
                .measure
                .as_ref()
                .and_then(|_| loop_position(&self.request.layout.road))
                .map(|l| {
                    // In the trajectory's coordinates (the layout may be turned along a loop).
                    let road = &self.request.layout.road;
                    (l.2 - self.request.layout.ring_offset_m).rem_euclid(road.length_m())
                }),
            emission_class: crate::layout::EMISSION_CLASS.to_string(),
            emission_every: self.request.measure.as_ref().map(|m| m.emission_every),
            law_speed_mode: law_driven.then_some(self.request.speed_mode),
            ssm,
            all_vehicles,
            controlled: self.request.adopt.as_ref().map(|_| Controlled {
                vehicles: start.map(|s| s.controlled.clone()).unwrap_or_default(),
                later: finish.and_then(|f| f.totals.chosen_later),
            }),
            guests: finish.and_then(|f| f.totals.guests.as_deref().cloned()),
        };
        RunOutput {
            trajectory: self.trajectory(scenario),
            stop: self.stop(),
            ring_length_m: self.request.layout.road.ring.then(|| self.road_length_m()),
            sumo: Some(facts),
            spread: self.spread(scenario),
            collisions: None,
            drivers: None,
            safety_layer: law_driven.then(|| syncroad_control::safety::SafetyLayer {
                mode: self.request.safety,
                filter: finish.and_then(|f| f.totals.filter),
            }),
        }
    }

    /// What SUMO wrote to files of its own and the record reads after a finished run: the
    /// surrogate safety measures and the summary of every vehicle (each `None` when not
    /// asked for, the run did not finish, or the file cannot be read, said on stderr).
    fn files_read_after(
        &self,
        finished: bool,
    ) -> (
        Option<syncroad_control::sumo_facts::SsmSummary>,
        Option<syncroad_control::sumo_facts::AllVehicles>,
    ) {
        let warmup_s = self.request.warmup_s;
        let ssm = self
            .request
            .measure
            .as_ref()
            .and_then(|m| m.ssm_file.as_ref())
            .filter(|_| finished)
            .and_then(|f| match crate::ssm::read(f, warmup_s) {
                Ok(s) => Some(s),
                Err(e) => {
                    // The run itself is fine; its record says no SSM was measured.
                    let _ = writeln!(
                        std::io::stderr(),
                        "warning: {e}; the record has no safety margins"
                    );
                    None
                }
            });
        let all_vehicles = self
            .request
            .summary_file
            .as_ref()
            .filter(|_| finished)
            .and_then(
                |f| match crate::summary::read(f, warmup_s, self.request.step_s) {
                    Ok(a) => Some(a),
                    Err(e) => {
                        let _ = writeln!(
                            std::io::stderr(),
                            "warning: {e}; the record has no metrics of all vehicles"
                        );
                        None
                    }
                },
            );
        (ssm, all_vehicles)
    }

    /// The spread at every step the worker reported (against the scenario's leader speed, as
    /// in [`SumoRun::trajectory`]); `None` when the worker sent no ranges.
    pub fn spread(&self, scenario: &Scenario) -> Option<SpreadSeries> {
        if self.worker.ranges.is_empty() {
            return None;
        }
        let mut s = SpreadSeries::default();
        for &[t, lo, hi] in &self.worker.ranges {
            s.push(t, spread_of_range(lo, hi, scenario.leader_speed_at(t)));
        }
        Some(s)
    }

    /// The controlled vehicles' samples (the leader vehicle, if any, becomes the reference
    /// speed), with bumper-to-bumper gaps as the native simulator computes them; when other
    /// traffic shares the road (the graph read from SUMO), the gap to whoever is directly
    /// ahead, as the worker measured it at each recorded state.
    pub fn trajectory(&self, scenario: &Scenario) -> Trajectory {
        let rows = &self.worker.rows;
        let all = rows.n;
        let k0 = usize::from(self.request.layout.leader_vehicle);
        let n = all - k0;
        let lengths: Vec<f64> = self
            .request
            .layout
            .vehicles
            .iter()
            .map(|v| v.length_m)
            .collect();
        let ring = self.request.layout.road.ring.then(|| self.road_length_m());
        let mut t = Trajectory::new(n);
        let mut gaps = vec![0.0; n];
        for k in 0..rows.len() {
            let q = &rows.positions_m[k * all..(k + 1) * all];
            let v = &rows.speeds_mps[k * all..(k + 1) * all];
            // Other traffic on the road: the gap to whoever is ahead, as SUMO placed them (the
            // layout's predecessor may be behind someone else).
            let sensed = rows
                .gaps_m
                .get(k * all..(k + 1) * all)
                .filter(|_| self.request.sense_graph);
            for i in 0..n {
                let j = k0 + i;
                gaps[i] = if let Some(g) = sensed {
                    g[j]
                } else if i > 0 || k0 == 1 {
                    q[j - 1] - q[j] - lengths[j]
                } else if let Some(c) = ring {
                    q[all - 1] + c - q[j] - lengths[j]
                } else {
                    f64::NAN
                };
            }
            let time = rows.time_s[k];
            t.push(
                time,
                &v[k0..],
                &q[k0..],
                &gaps,
                scenario.leader_speed_at(time),
            );
        }
        t
    }
}
