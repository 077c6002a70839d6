//! The native fixed-step simulator: runs a validated [`Scenario`] with the very law object the
//! SUMO loop drives ([`controller_for`]) and records a [`Trajectory`].
//!
//! Every step the controller turns the state at t_n of every vehicle on the road (the leader
//! first, when there is one) into the speeds at t_{n+1}; positions advance by the trapezoidal
//! rule, which is SUMO's ballistic update. So the native and the SUMO run of a scenario
//! compute the same numbers: delayed drivers (eq. `chandler+`) second order on the step grid,
//! CACC (eqs. `veh-proto1/2`) with `a_des` held over the step and the powertrain lag
//! integrated exactly. [`cacc_rk4_reference`] integrates the continuous CACC closed loop by
//! classical Runge–Kutta; tests use it to check the discrete law converges to it.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::cacc::{CaccLaw, PlatoonView};
use crate::collisions::Collisions;
use crate::controller::LawHost;
use crate::controller::{controller_for_in, ControllerError, LawSpec};
use crate::delayed_driver::DelayedDriverLaw;
use crate::metrics::{speed_range, spread_of_range, SpreadSeries};
use crate::observer::StepObserver;
use crate::road;
use crate::scenario::{Model, Scenario};
use crate::speed_controller::SpeedController;
use crate::start::{initial_positions, leader_start};
pub use crate::stop::StopReason;
use crate::trajectory::Trajectory;

/// Speeds beyond this magnitude [m/s] count as divergence.
pub const DIVERGENCE_MPS: f64 = 1e6;

/// Options of a native run.
#[derive(Clone, Copy)]
pub struct NativeOptions<'a> {
    /// Record every k-th step (1 = every step). The spread is kept at every step whatever
    /// the stride.
    pub record_every: usize,
    /// Checked every step: when set, the run stops with [`StopReason::Interrupted`] and keeps
    /// what it recorded (a signal handler's flag).
    pub cancel: Option<&'a AtomicBool>,
    /// Called every [`PROGRESS_EVERY`] steps with (steps done, steps in the run).
    pub progress: Option<&'a dyn Fn(usize, usize)>,
    /// Builds the user's Python controller when the scenario names one
    /// ([`crate::user_law`]); without it such a scenario's law is refused.
    pub host: Option<&'a dyn LawHost>,
    /// Wall-clock limit of the loop: past it the run stops with a failed stop naming the
    /// limit, and keeps what it recorded (a host that steps the law in another process holds
    /// a blocked step to the same limit).
    pub timeout: Option<std::time::Duration>,
}

/// Steps between two calls of [`NativeOptions::progress`].
pub const PROGRESS_EVERY: usize = 10_000;

impl Default for NativeOptions<'_> {
    fn default() -> Self {
        Self {
            record_every: 1,
            cancel: None,
            progress: None,
            timeout: None,
            host: None,
        }
    }
}

impl std::fmt::Debug for NativeOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NativeOptions")
            .field("record_every", &self.record_every)
            .field("cancel", &self.cancel)
            .field("progress", &self.progress.is_some())
            .field("host", &self.host.is_some())
            .field("timeout", &self.timeout)
            .finish()
    }
}

/// Result of a native run.
#[derive(Debug, Clone)]
pub struct NativeRun {
    /// Recorded samples.
    pub trajectory: Trajectory,
    /// Why the run stopped.
    pub stop: StopReason,
    /// The spread at every step (the metrics use it, not the recorded samples).
    pub spread: SpreadSeries,
    /// Overlapping and reversing vehicles, seen at every step.
    pub collisions: Collisions,
    /// What the safety filter under the law did; `None`: no filter ran.
    pub filter: Option<crate::speed_controller::FilterReport>,
}

/// The stop of a run whose stop flag is set at `step` (a signal: [`NativeOptions::cancel`]).
fn interrupted(opts: &NativeOptions, step: usize, time_s: f64) -> Option<StopReason> {
    opts.cancel
        .is_some_and(|c| c.load(Ordering::Relaxed))
        .then_some(StopReason::Interrupted { step, time_s })
}

/// The stop of a run past its time limit at `step` ([`NativeOptions::timeout`]); the clock is
/// read every 64 steps only: a step of a small ring costs about a microsecond.
fn timed_out(
    opts: &NativeOptions,
    started: std::time::Instant,
    step: usize,
    time_s: f64,
) -> Option<StopReason> {
    let limit = opts
        .timeout
        .filter(|t| step.is_multiple_of(64) && started.elapsed() > *t)?;
    Some(StopReason::Failed {
        error: format!(
            "the run exceeded its time limit of {} s at t = {time_s:.3} s (step {step}) and was stopped; the rows so far are written, marked incomplete (raise --timeout-s)",
            limit.as_secs_f64()
        ),
    })
}

fn check(v: &[f64], step: usize, dt: f64) -> Option<StopReason> {
    v.iter()
        .position(|x| !x.is_finite() || x.abs() >= DIVERGENCE_MPS)
        .map(|vehicle| StopReason::Diverged {
            step,
            vehicle,
            time_s: step as f64 * dt,
        })
}

/// Runs the scenario on the native simulator. A law that cannot be built (a Python controller
/// without [`NativeOptions::host`], or one whose class fails) gives a run of no steps that
/// stopped with [`StopReason::Failed`] naming why.
pub fn simulate(scenario: &Scenario, opts: NativeOptions) -> NativeRun {
    simulate_with(scenario, &LawSpec::of(scenario), opts).unwrap_or_else(|e| NativeRun {
        trajectory: Trajectory::new(scenario.vehicles()),
        stop: StopReason::Failed {
            error: e.to_string(),
        },
        spread: SpreadSeries::default(),
        collisions: Collisions::default(),
        filter: None,
    })
}

/// Runs the scenario on the native simulator with `law` in place of the scenario's own (a
/// wave damper or stochastic humans on a ring, resolved by the caller as for SUMO).
pub fn simulate_with(
    scenario: &Scenario,
    law: &LawSpec,
    opts: NativeOptions,
) -> Result<NativeRun, ControllerError> {
    let law = controller_for_in(law, opts.host)?;
    Ok(simulate_controller(scenario, law, opts))
}

/// Runs the scenario on the native simulator with a controller of the caller's (a Rust user's
/// own law): it is stepped with every vehicle on the road, the leader vehicle first when the
/// scenario has one.
pub fn simulate_controller(
    scenario: &Scenario,
    mut law: Box<dyn SpeedController>,
    opts: NativeOptions,
) -> NativeRun {
    let leader = leader_start(scenario);
    let k0 = usize::from(leader.is_some());
    let n = scenario.vehicles();
    let all = n + k0;
    let dt = scenario.step_s();
    let ring = scenario.ring_length_m();
    let mut q = Vec::with_capacity(all);
    let mut v = Vec::with_capacity(all);
    if let Some((q0, v0)) = leader {
        q.push(q0);
        v.push(v0);
    }
    q.extend(initial_positions(scenario, leader.map(|l| l.0)));
    v.extend_from_slice(scenario.initial_speed_mps());
    let mut next = vec![0.0; all];
    let road = RoadView {
        scenario,
        lengths: scenario.length_m(),
        leader: leader.is_some(),
        ring,
    };
    let steps = scenario.steps();
    let mut rec = Recording {
        road,
        every: opts.record_every.max(1),
        traj: Trajectory::new(n),
        gaps: vec![0.0; n],
    };
    let mut watch = Watch {
        road,
        spread: SpreadSeries::default(),
        collisions: Collisions::default(),
        gaps: vec![0.0; n],
    };
    watch.spread.time_s.reserve(steps + 1);
    watch.spread.spread_mps.reserve(steps + 1);
    let Ok(()) = rec.start(&mut NativeState::after(0, steps, dt, &q, &v));
    let Ok(()) = watch.start(&mut NativeState::after(0, steps, dt, &q, &v));
    let mut stop = StopReason::Horizon;
    let started = std::time::Instant::now();
    for step in 0..steps {
        let time_s = step as f64 * dt;
        let mut cut = timed_out(&opts, started, step, time_s).or(interrupted(&opts, step, time_s));
        if cut.is_none() {
            if let Some(p) = opts
                .progress
                .filter(|_| step % PROGRESS_EVERY == 0 && step > 0)
            {
                p(step, steps);
            }
            law.step(time_s, &v, &q, &mut next);
            // A signal that came while the law computed (a controller in another process that
            // was waited for) stops the run where it is: this step's commands are not applied.
            cut = interrupted(&opts, step, time_s);
        }
        if let Some(s) = cut {
            // The last step computed is recorded, so the files end where the run stopped.
            if rec.traj.time_s.last() != watch.spread.time_s.last() {
                rec.record(&NativeState::after(step, steps, dt, &q, &v));
            }
            stop = s;
            break;
        }
        if let Some(end) = law.ended() {
            stop = end.at(step, step as f64 * dt);
            break;
        }
        if let Some(s) = check(&next[k0..], step + 1, dt) {
            stop = s;
            break;
        }
        for i in 0..all {
            q[i] += 0.5 * dt * (v[i] + next[i]);
        }
        std::mem::swap(&mut v, &mut next);
        let mut at = NativeState::after(step + 1, steps, dt, &q, &v);
        let Ok(()) = watch.after_step(&mut at);
        let Ok(()) = rec.after_step(&mut at);
    }
    NativeRun {
        trajectory: rec.traj,
        stop,
        spread: watch.spread,
        collisions: watch.collisions,
        filter: law.filter_report(),
    }
}

/// The native loop's state after a step, as its observers see it.
#[derive(Debug, Clone, Copy)]
pub struct NativeState<'s> {
    /// Steps done.
    pub steps_done: usize,
    /// Time of the state \[s\].
    pub time_s: f64,
    /// Unwrapped positions of every vehicle on the road, the leader vehicle first when there
    /// is one \[m\].
    pub positions_m: &'s [f64],
    /// Their speeds \[m/s\].
    pub speeds_mps: &'s [f64],
    /// The horizon's last step.
    pub last: bool,
}

impl<'s> NativeState<'s> {
    /// The state after `steps_done` of `steps` steps of `dt_s`.
    fn after(
        steps_done: usize,
        steps: usize,
        dt_s: f64,
        positions_m: &'s [f64],
        speeds_mps: &'s [f64],
    ) -> Self {
        Self {
            steps_done,
            time_s: steps_done as f64 * dt_s,
            positions_m,
            speeds_mps,
            last: steps_done == steps,
        }
    }
}

/// What the native observers need of the road: the judged vehicles (after the leader vehicle,
/// when there is one), their lengths and the ring's length.
#[derive(Clone, Copy)]
struct RoadView<'sc> {
    scenario: &'sc Scenario,
    lengths: &'sc [f64],
    leader: bool,
    ring: Option<f64>,
}

impl RoadView<'_> {
    /// Index of the first judged vehicle (1 behind a leader vehicle).
    fn k0(&self) -> usize {
        usize::from(self.leader)
    }

    /// The gaps of the judged vehicles at `at` (the one gap rule of [`road::gaps`]).
    fn gaps(&self, at: &NativeState<'_>, out: &mut [f64]) {
        let q = at.positions_m;
        let front = self.leader.then(|| q[0]);
        road::gaps(&q[self.k0()..], self.lengths, front, self.ring, out);
    }
}

/// Records every `every`-th step and the last one.
struct Recording<'sc> {
    road: RoadView<'sc>,
    every: usize,
    traj: Trajectory,
    gaps: Vec<f64>,
}

impl Recording<'_> {
    fn record(&mut self, at: &NativeState<'_>) {
        let k0 = self.road.k0();
        self.road.gaps(at, &mut self.gaps);
        let leader_speed = self.road.scenario.leader_speed_at(at.time_s);
        let (v, q) = (&at.speeds_mps[k0..], &at.positions_m[k0..]);
        self.traj.push(at.time_s, v, q, &self.gaps, leader_speed);
    }
}

impl StepObserver<NativeState<'_>> for Recording<'_> {
    type Error = std::convert::Infallible;

    fn name(&self) -> &'static str {
        "rows"
    }

    fn start(&mut self, at: &mut NativeState<'_>) -> Result<(), Self::Error> {
        self.record(at);
        Ok(())
    }

    fn after_step(&mut self, at: &mut NativeState<'_>) -> Result<(), Self::Error> {
        if at.steps_done.is_multiple_of(self.every) || at.last {
            self.record(at);
        }
        Ok(())
    }
}

/// The spread and the collision watch, at every step whatever the recording stride.
struct Watch<'sc> {
    road: RoadView<'sc>,
    spread: SpreadSeries,
    collisions: Collisions,
    gaps: Vec<f64>,
}

impl StepObserver<NativeState<'_>> for Watch<'_> {
    type Error = std::convert::Infallible;

    fn name(&self) -> &'static str {
        "spread and collisions"
    }

    fn start(&mut self, at: &mut NativeState<'_>) -> Result<(), Self::Error> {
        self.after_step(at)
    }

    fn after_step(&mut self, at: &mut NativeState<'_>) -> Result<(), Self::Error> {
        let v = &at.speeds_mps[self.road.k0()..];
        let (lo, hi) = speed_range(v);
        let leader_speed = self.road.scenario.leader_speed_at(at.time_s);
        self.spread
            .push(at.time_s, spread_of_range(lo, hi, leader_speed));
        self.road.gaps(at, &mut self.gaps);
        self.collisions.observe(at.time_s, &self.gaps, v);
        Ok(())
    }
}

/// Speed-only fast path for benchmarks: `steps` steps of the law on `v`, nothing recorded.
pub fn run_speeds_only(law: &mut DelayedDriverLaw, v: &mut Vec<f64>, steps: usize) {
    let mut next = vec![0.0; v.len()];
    for _ in 0..steps {
        law.step(v, 0.0, &mut next);
        std::mem::swap(v, &mut next);
    }
}

/// The continuous CACC closed loop `q' = v, v' = a, τ a' = a_des(q, v)` integrated by the
/// classical fourth-order Runge–Kutta method with the law evaluated at every stage: the
/// reference the sampled law of [`simulate`] (`a_des` held over each step, as SUMO applies
/// it) converges to, at first order in Δt (`exact::gaps` tests measure the order).
///
/// # Panics
/// When the scenario is not a CACC platoon.
pub fn cacc_rk4_reference(scenario: &Scenario, opts: NativeOptions) -> NativeRun {
    let Model::Cacc(m) = scenario.model() else {
        panic!("cacc_rk4_reference runs CACC platoons only")
    };
    let law = CaccLaw::new(m);
    let n = scenario.vehicles();
    let dt = scenario.step_s();
    let mut q0 = 0.0;
    // Follower 1 starts one length plus its gap behind the leader's rear bumper.
    let mut q = initial_positions(scenario, Some(q0));
    let mut v = scenario.initial_speed_mps().to_vec();
    let mut a = vec![0.0; n];
    let tau = &m.tau_s;
    let profile = &m.leader;
    let mut gaps = vec![0.0; n];
    let mut traj = Trajectory::new(n);
    road::gaps(&q, &m.length_m, Some(q0), None, &mut gaps);
    traj.push(0.0, &v, &q, &gaps, Some(profile.speed_at(0.0)));
    let every = opts.record_every.max(1);
    let mut ades = vec![0.0; n];
    // Derivative of (q, v, a) at time t with leader (q0, v0).
    let deriv = |t: f64,
                 q0: f64,
                 q: &[f64],
                 v: &[f64],
                 a: &[f64],
                 dq: &mut [f64],
                 dv: &mut [f64],
                 da: &mut [f64],
                 ades: &mut [f64]| {
        let view = PlatoonView {
            leader_position_m: q0,
            leader_speed_mps: profile.speed_at(t),
            positions_m: q,
            speeds_mps: v,
        };
        law.desired_accelerations(&view, ades);
        for i in 0..q.len() {
            dq[i] = v[i];
            dv[i] = a[i];
            da[i] = (ades[i] - a[i]) / tau[i];
        }
    };
    // Leader position by exact integration of its (piecewise-linear) speed over each stage.
    let leader_pos =
        |t0: f64, q0: f64, h: f64| q0 + 0.5 * h * (profile.speed_at(t0) + profile.speed_at(t0 + h));
    let mut k = vec![vec![0.0; 3 * n]; 4];
    let mut tmp = vec![0.0; 3 * n];
    let mut stop = StopReason::Horizon;
    for step in 0..scenario.steps() {
        let t = step as f64 * dt;
        let stages = [(0.0, 0usize), (0.5, 0), (0.5, 1), (1.0, 2)];
        for (s, &(c, from)) in stages.iter().enumerate() {
            for i in 0..n {
                let (dq, dv, da) = if s == 0 {
                    (0.0, 0.0, 0.0)
                } else {
                    (k[from][i], k[from][n + i], k[from][2 * n + i])
                };
                tmp[i] = q[i] + c * dt * dq;
                tmp[n + i] = v[i] + c * dt * dv;
                tmp[2 * n + i] = a[i] + c * dt * da;
            }
            let lq = leader_pos(t, q0, c * dt);
            let (kq, rest) = k[s].split_at_mut(n);
            let (kv, ka) = rest.split_at_mut(n);
            deriv(
                t + c * dt,
                lq,
                &tmp[..n],
                &tmp[n..2 * n],
                &tmp[2 * n..],
                kq,
                kv,
                ka,
                &mut ades,
            );
        }
        for i in 0..3 * n {
            let inc = dt / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
            match i / n {
                0 => q[i] += inc,
                1 => v[i - n] += inc,
                _ => a[i - 2 * n] += inc,
            }
        }
        q0 = leader_pos(t, q0, dt);
        if let Some(s) = check(&v, step + 1, dt) {
            stop = s;
            break;
        }
        if (step + 1) % every == 0 || step + 1 == scenario.steps() {
            road::gaps(&q, &m.length_m, Some(q0), None, &mut gaps);
            let t1 = (step + 1) as f64 * dt;
            traj.push(t1, &v, &q, &gaps, Some(profile.speed_at(t1)));
        }
    }
    let mut collisions = Collisions::default();
    for k in 0..traj.len() {
        collisions.observe(traj.time_s[k], traj.gaps(k), traj.speeds(k));
    }
    NativeRun {
        spread: SpreadSeries::of_trajectory(&traj),
        trajectory: traj,
        stop,
        collisions,
        filter: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outcome::{evaluate, EvalOptions, RunOutput};
    use std::cell::Cell;

    fn ring() -> Scenario {
        Scenario::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenarios/ring-theorem1.json"),
        )
        .expect("the shipped scenario is valid")
    }

    fn output(sc: &Scenario, run: NativeRun) -> RunOutput {
        RunOutput::native(sc, run, None)
    }

    #[test]
    fn the_recording_stride_changes_the_samples_not_the_metrics() {
        let sc = ring();
        let every = |k: usize| {
            let run = simulate(
                &sc,
                NativeOptions {
                    record_every: k,
                    ..NativeOptions::default()
                },
            );
            (
                run.trajectory.len(),
                evaluate(&sc, &output(&sc, run), EvalOptions::of(&sc)).sync,
            )
        };
        let (all, fine) = every(1);
        let (two, coarse) = every(1_000_000);
        assert_eq!((all, two), (sc.steps() + 1, 2));
        // The L2 norm, the time to tolerance, the fitted rate and the verdict are the same
        // numbers, not just close: they come from the spread of every step.
        assert_eq!(fine, coarse);
        let l2 = fine.spread_l2.unwrap();
        assert!((l2 - 3.861).abs() < 1e-3, "{l2}");
    }

    #[test]
    fn a_set_stop_flag_ends_the_run_where_it_is_and_keeps_the_samples() {
        let flag = AtomicBool::new(false);
        let calls = Cell::new(0);
        // Raised from the progress callback at step 2·PROGRESS_EVERY, as a signal would be.
        let raise = |done: usize, _total: usize| {
            calls.set(calls.get() + 1);
            if done == 2 * PROGRESS_EVERY {
                flag.store(true, Ordering::SeqCst);
            }
        };
        let sc = Scenario::from_json(
            &std::fs::read_to_string(
                std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("../../scenarios/ring-theorem1.json"),
            )
            .unwrap()
            .replace(r#""horizon_s": 300"#, r#""horizon_s": 10000"#),
        )
        .unwrap();
        let run = simulate(
            &sc,
            NativeOptions {
                record_every: 3000,
                cancel: Some(&flag),
                progress: Some(&raise),
                ..NativeOptions::default()
            },
        );
        // Set before the law's step, the flag is seen right after it: that step's commands
        // are not applied (a signal that came while a law in another process was waited for).
        let step = 2 * PROGRESS_EVERY;
        assert_eq!(
            run.stop,
            StopReason::Interrupted {
                step,
                time_s: step as f64 * sc.step_s()
            }
        );
        assert_eq!(calls.get(), 2);
        // Every step up to the stop is in the spread; the samples end at the stop.
        assert_eq!(run.spread.len(), step + 1);
        // Samples every 3000 steps from 0, and the step it stopped at.
        assert_eq!(run.trajectory.len(), step / 3000 + 2);
        assert!((run.trajectory.time_s.last().unwrap() - step as f64 * sc.step_s()).abs() < 1e-9);
        let out = output(&sc, run);
        let m = evaluate(&sc, &out, EvalOptions::of(&sc)).sync;
        assert!(m.incomplete);
        // Cut off by a signal: what the run would have done is not known.
        assert_eq!(m.verdict, crate::metrics::Verdict::Inconclusive);
        assert!(
            m.verdict_reason
                .as_deref()
                .is_some_and(|r| r.contains("interrupted") && r.contains("not known")),
            "{:?}",
            m.verdict_reason
        );
    }
}
