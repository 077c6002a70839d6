//! Stochastic human drivers computed by the bridge: the Intelligent Driver Model with Gaussian
//! noise, stepped in Rust through the same [`SpeedController`] seam as the laws and the wave
//! dampers and sent to SUMO as a speed command (the way Flow drives its humans).
//!
//! With gap `h` (bumper to bumper), speed `v` and leader speed `v_l`, the IDM acceleration is
//!
//! `a_IDM = a (1 − (v/v0)^δ − (s*/h)²)`, `s* = s0 + max(0, v T + v (v − v_l) / (2 √(a b)))`,
//!
//! written as Flow's `IDMController` (flow-project/flow, `flow/controllers/car_following_models.py`,
//! including its `h = 10⁻³ m` floor for `|h| < 10⁻³`). Each step one standard normal `ξ` per
//! vehicle is drawn and the next speed is, by [`NoiseForm`]:
//!
//! * [`NoiseForm::Flow`]: Flow's master code (`BaseController.get_action`,
//!   `accel += sqrt(sim_step) · normal(0, noise)`, then `apply_acceleration`,
//!   `max(v + accel · sim_step, 0)`): `v' = max(0, v + (a_IDM + σ √Δt ξ) Δt)`. The velocity gets
//!   variance σ² Δt³ per step, σ² Δt² per second: **the noise vanishes as Δt shrinks**, so a
//!   run's statistics depend on the step.
//! * [`NoiseForm::StepConsistent`]: Euler–Maruyama of the SDE `dv = a_IDM dt + σ dW`:
//!   `v' = max(0, v + a_IDM Δt + σ √Δt ξ)`, variance σ² Δt per step, σ² per second whatever the
//!   step, so statistics converge as Δt → 0 (tests check both against the closed-form
//!   stationary variance of the linearised free-road dynamics).
//!
//! Every vehicle has its own stream, seeded from the scenario's seed and the vehicle's index
//! ([`vehicle_seed`]): the same seed gives the same run, another seed another, and a vehicle's
//! noise does not change when another vehicle is made automated (paired comparisons).
//!
//! # Reference
//! M. Treiber, A. Hennecke, D. Helbing, "Congested traffic states in empirical observations
//! and microscopic simulations", Phys. Rev. E 62 (2000) 1805 (the IDM).
//! C. Wu, A. Kreidieh, K. Parvate, E. Vinitsky, A. Bayen, "Flow: a modular learning framework
//! for mixed autonomy traffic", IEEE T-RO 38 (2022); code flow-project/flow (master).

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;
use crate::road::RingView;
use crate::speed_controller::{LawContext, LawEntry, Road, SpeedController};

/// Parameters of the IDM (Flow's `IDMController` names in the docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdmParams {
    /// Maximum acceleration a \[m/s²\] (Flow `a`).
    pub accel_mps2: f64,
    /// Comfortable deceleration b \[m/s²\] (Flow `b`).
    pub decel_mps2: f64,
    /// Safe time headway T \[s\] (Flow `T`).
    pub time_headway_s: f64,
    /// Linear jam distance s0 \[m\] (Flow `s0`).
    pub min_gap_m: f64,
    /// Acceleration exponent δ (Flow `delta`).
    pub delta: f64,
    /// Desired speed v0 \[m/s\] (Flow `v0`).
    pub desired_speed_mps: f64,
}

impl IdmParams {
    /// Flow's `IDMController` defaults: v0 = 30 m/s, T = 1 s, a = 1 m/s², b = 1.5 m/s², δ = 4,
    /// s0 = 2 m.
    pub const FLOW: IdmParams = IdmParams {
        accel_mps2: 1.0,
        decel_mps2: 1.5,
        time_headway_s: 1.0,
        min_gap_m: 2.0,
        delta: 4.0,
        desired_speed_mps: 30.0,
    };

    /// The IDM acceleration \[m/s²\] at speed `v`, leader speed `v_lead` and bumper-to-bumper
    /// gap `gap_m`, exactly as Flow's `IDMController.get_accel` computes it.
    pub fn accel(&self, v: f64, v_lead: f64, gap_m: f64) -> f64 {
        let h = if gap_m.abs() < 1e-3 { 1e-3 } else { gap_m };
        let ab = (self.accel_mps2 * self.decel_mps2).sqrt();
        let s_star =
            self.min_gap_m + (v * self.time_headway_s + v * (v - v_lead) / (2.0 * ab)).max(0.0);
        self.accel_mps2
            * (1.0 - (v / self.desired_speed_mps).powf(self.delta) - (s_star / h).powi(2))
    }
}

/// How the noise enters the speed update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseForm {
    /// Flow's: `σ √Δt ξ` added to the acceleration, which is then applied over Δt.
    Flow,
    /// Velocity diffusion `σ √Δt ξ` per step (variance σ² Δt): step-size independent.
    StepConsistent,
}

impl NoiseForm {
    /// The name used in driver strings (`flow`, `step`).
    pub fn name(self) -> &'static str {
        match self {
            NoiseForm::Flow => "flow",
            NoiseForm::StepConsistent => "step",
        }
    }
}

/// One stochastic human: IDM parameters, noise intensity σ and its form.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoisyIdm {
    /// The IDM.
    pub idm: IdmParams,
    /// Noise intensity σ ≥ 0: the standard deviation of Flow's `normal(0, noise)`
    /// \[m/s²\] for [`NoiseForm::Flow`]; the diffusion coefficient \[m/s^{3/2}\] for
    /// [`NoiseForm::StepConsistent`].
    pub noise: f64,
    /// The noise form.
    pub form: NoiseForm,
}

/// A parameter of a stochastic human out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {name} = {value}: valid is {valid}")]
pub struct NoisyIdmError {
    /// Where the driver was given.
    pub field: String,
    /// The parameter.
    pub name: &'static str,
    /// Its value.
    pub value: f64,
    /// What is valid.
    pub valid: &'static str,
}

impl NoisyIdm {
    /// Checks every parameter; `field` names where the driver was given.
    pub fn validate(&self, field: &str) -> Result<(), NoisyIdmError> {
        let p = &self.idm;
        let checks: [(&'static str, f64, bool, &'static str); 7] = [
            (
                "accel",
                p.accel_mps2,
                p.accel_mps2 > 0.0,
                "a finite number > 0 m/s²",
            ),
            (
                "decel",
                p.decel_mps2,
                p.decel_mps2 > 0.0,
                "a finite number > 0 m/s²",
            ),
            (
                "tau",
                p.time_headway_s,
                p.time_headway_s >= 0.0,
                "a finite number ≥ 0 s",
            ),
            (
                "minGap",
                p.min_gap_m,
                p.min_gap_m >= 0.0,
                "a finite number ≥ 0 m",
            ),
            ("delta", p.delta, p.delta > 0.0, "a finite number > 0"),
            (
                "maxSpeed",
                p.desired_speed_mps,
                p.desired_speed_mps > 0.0,
                "a finite number > 0 m/s",
            ),
            (
                "noise",
                self.noise,
                self.noise >= 0.0,
                "a finite number ≥ 0",
            ),
        ];
        for (name, value, ok, valid) in checks {
            if !(value.is_finite() && ok) {
                return Err(NoisyIdmError {
                    field: field.into(),
                    name,
                    value,
                    valid,
                });
            }
        }
        Ok(())
    }

    /// The speed after one step Δt = `dt_s` from speed `v` behind a leader at `v_lead`,
    /// `gap_m` ahead, with the standard normal draw `xi` (see [`NoiseForm`]).
    pub fn next_speed_mps(&self, v: f64, v_lead: f64, gap_m: f64, dt_s: f64, xi: f64) -> f64 {
        let a = self.idm.accel(v, v_lead, gap_m);
        let kick = self.noise * dt_s.sqrt() * xi;
        let next = match self.form {
            NoiseForm::Flow => v + (a + kick) * dt_s,
            NoiseForm::StepConsistent => v + a * dt_s + kick,
        };
        next.max(0.0)
    }
}

impl fmt::Display for NoisyIdm {
    /// `noisy-idm:accel=..:decel=..:tau=..:minGap=..:delta=..:maxSpeed=..:noise=..:form=..`,
    /// the string the SUMO driver names parse back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = &self.idm;
        write!(
            f,
            "noisy-idm:accel={}:decel={}:tau={}:minGap={}:delta={}:maxSpeed={}:noise={}:form={}",
            p.accel_mps2,
            p.decel_mps2,
            p.time_headway_s,
            p.min_gap_m,
            p.delta,
            p.desired_speed_mps,
            self.noise,
            self.form.name()
        )
    }
}

impl NoisyIdm {
    /// The `human-noisy` preset: the `human` preset's IDM (Flow's with a = 1.3 m/s²,
    /// T = 0.8 s) with step-consistent noise, calibrated so that a jam forms from a uniform
    /// start (measurements in `docs/src/human-preset.md`).
    pub const HUMAN_NOISY: NoisyIdm = NoisyIdm {
        idm: IdmParams {
            accel_mps2: 1.3,
            time_headway_s: 0.8,
            ..IdmParams::FLOW
        },
        noise: HUMAN_NOISY_SIGMA,
        form: NoiseForm::StepConsistent,
    };

    /// The driver `noisy-idm` written without changes, where its spelled-out values start
    /// (the driver and the table's `noisy-idm` alike): Flow's IDM, no noise, step-consistent.
    pub const BARE: NoisyIdm = NoisyIdm {
        idm: IdmParams::FLOW,
        noise: 0.0,
        form: NoiseForm::StepConsistent,
    };

    /// The `flow-idm-noise` preset: Flow's `IDMController` defaults ([`IdmParams::FLOW`])
    /// with Flow's ring-example noise 0.2 in Flow's form.
    pub const FLOW_IDM_NOISE: NoisyIdm = NoisyIdm {
        idm: IdmParams::FLOW,
        noise: 0.2,
        form: NoiseForm::Flow,
    };

    /// Sets one parameter by its driver-string name (`accel`, `decel`, `tau`, `minGap`,
    /// `delta`, `maxSpeed`, `noise`, `form` = `flow` | `step`); the error says what is valid.
    pub fn set(&mut self, name: &str, value: &str) -> Result<(), String> {
        if name == "form" {
            self.form = match value {
                "flow" => NoiseForm::Flow,
                "step" | "step_consistent" | "step-consistent" => NoiseForm::StepConsistent,
                _ => return Err(format!("form = {value:?}: valid are flow, step")),
            };
            return Ok(());
        }
        let v: f64 = value
            .parse()
            .map_err(|_| format!("{name}: {value:?} is not a number"))?;
        let p = &mut self.idm;
        let slot = match name {
            "accel" => &mut p.accel_mps2,
            "decel" => &mut p.decel_mps2,
            "tau" => &mut p.time_headway_s,
            "minGap" => &mut p.min_gap_m,
            "delta" => &mut p.delta,
            "maxSpeed" => &mut p.desired_speed_mps,
            "noise" => &mut self.noise,
            _ => {
                return Err(format!(
                    "the noisy IDM has no parameter {name:?}; valid: accel, decel, tau, minGap, delta, maxSpeed, noise, form"
                ))
            }
        };
        *slot = v;
        Ok(())
    }
}

/// σ of the `human-noisy` preset (step-consistent form) \[m/s^{3/2}\].
pub const HUMAN_NOISY_SIGMA: f64 = 0.2;

/// Salt of the driver-noise streams, independent of the start's perturbation and of the
/// mixed placement drawn from the same seed.
const NOISE_SALT: u64 = 0x6e6f_6973_795f_6964; // "noisy_id"

/// The seed of vehicle `vehicle`'s noise stream in a scenario seeded with `seed`.
pub fn vehicle_seed(seed: u64, vehicle: usize) -> u64 {
    let mut g = SplitMix64::new(seed ^ NOISE_SALT);
    let base = g.next_u64();
    SplitMix64::new(base ^ (vehicle as u64).wrapping_mul(0xD1B5_4A32_D192_ED03)).next_u64()
}

/// Standard normal draws from SplitMix64 by the Box–Muller transform (one draw per call, the
/// cosine branch), so the stream is fixed by this file on every platform.
///
/// # Reference
/// G. E. P. Box, M. E. Muller, "A note on the generation of random normal deviates", Ann.
/// Math. Statist. 29 (1958) 610–611.
#[derive(Debug, Clone)]
pub struct Gaussian {
    rng: SplitMix64,
}

impl Gaussian {
    /// A stream seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: SplitMix64::new(seed),
        }
    }

    /// The next standard normal draw.
    pub fn sample(&mut self) -> f64 {
        let u1 = 1.0 - self.rng.next_f64(); // (0, 1]
        let u2 = self.rng.next_f64();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Stochastic humans on a ring, resolved by the backend.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HumanSetup {
    /// Per vehicle on the road: `Some` = that stochastic human drives it; `None` = the law or
    /// the damper (or a SUMO driver, whose command is not sent).
    pub drivers: Vec<Option<NoisyIdm>>,
    /// Circumference C of the ring as the backend measures it \[m\].
    pub ring_length_m: f64,
    /// Vehicle lengths ℓ_i \[m\].
    pub length_m: Vec<f64>,
    /// The scenario's seed; vehicle i draws from [`vehicle_seed`]`(seed, i)`.
    pub seed: u64,
    /// The road's speed limit \[m/s\] (SUMO's lanes; the lowest along the road): a human
    /// never drives faster, as SUMO's own drivers do not. `None`: no limit (the native
    /// simulator's road has none).
    #[serde(default)]
    pub speed_limit_mps: Option<f64>,
}

/// The law (or damper) of a ring with some vehicles driven by stochastic humans: the inner
/// controller's command for the others, the noisy IDM's for the humans.
pub struct HumanController {
    inner: Box<dyn SpeedController>,
    drivers: Vec<Option<NoisyIdm>>,
    noise: Vec<Gaussian>,
    dt_s: f64,
    view: RingView,
    speed_limit_mps: f64,
}

impl HumanController {
    /// Humans of `setup` over `inner`, step `dt_s`.
    pub fn new(inner: Box<dyn SpeedController>, setup: &HumanSetup, dt_s: f64) -> Self {
        let n = setup.drivers.len();
        Self {
            inner,
            drivers: setup.drivers.clone(),
            noise: (0..n)
                .map(|i| Gaussian::new(vehicle_seed(setup.seed, i)))
                .collect(),
            dt_s,
            view: RingView::new(setup.ring_length_m, &setup.length_m),
            speed_limit_mps: setup.speed_limit_mps.unwrap_or(f64::INFINITY),
        }
    }
}

/// The stochastic human as an entry of the table of laws, `noisy-idm`: every vehicle it is
/// built for is that human. Its parameters are the driver's (`{"noise": 0.2, "accel": 1.3,
/// "form": "flow"}` is the driver `noisy-idm:noise=0.2:accel=1.3:form=flow`), so a vehicle of
/// a `mixed` block's `controller` or of an inflow's `controlled` block drives as the driver
/// of that name does. On a scenario's road vehicle i draws the stream [`vehicle_seed`]`(seed,
/// i)`, as the driver's vehicles do; a vehicle driven alone (an inflow's) draws the one of its
/// own id.
pub const ENTRY: LawEntry = LawEntry {
    name: "noisy-idm",
    summary: "a stochastic human computed by syncroad: Flow's IDM with Gaussian noise, each vehicle its own stream from the run's seed (params as the driver noisy-idm:NAME=VALUE: accel, decel, tau, minGap, delta, maxSpeed, noise, form)",
    road: Road::Ring,
    looks_behind: false,
    shorthand: None,
    check: |params| human_of(params).map(|_| ()),
    build: build_humans,
};

/// The human that `params` describe, from the driver `noisy-idm`'s values
/// ([`NoisyIdm::BARE`]).
fn human_of(params: &serde_json::Value) -> Result<NoisyIdm, String> {
    let mut d = NoisyIdm::BARE;
    let empty = serde_json::Map::new();
    let given = match params {
        serde_json::Value::Null => &empty,
        serde_json::Value::Object(o) => o,
        other => {
            return Err(format!(
                "params {other}: must be an object of the driver's parameters"
            ))
        }
    };
    for (name, value) in given {
        let text = match value {
            serde_json::Value::String(s) => s.clone(),
            serde_json::Value::Number(x) => x.to_string(),
            other => return Err(format!("params.{name} = {other}: a number (form: a name)")),
        };
        d.set(name, &text).map_err(|e| format!("params: {e}"))?;
    }
    d.validate("params").map_err(|e| e.to_string())?;
    Ok(d)
}

fn build_humans(
    ctx: &LawContext,
    params: &serde_json::Value,
) -> Result<Box<dyn SpeedController>, String> {
    let d = human_of(params)?;
    let n = ctx.ids.len();
    // A vehicle driven alone, behind whoever is ahead (an inflow's): its stream is its id's.
    let alone = ctx.protocol.is_none() && n == 1;
    let noise = (0..n)
        .map(|i| {
            let seed = if alone {
                vehicle_seed(ctx.seed ^ id_seed(&ctx.ids[i]), 0)
            } else {
                vehicle_seed(ctx.seed, i)
            };
            Gaussian::new(seed)
        })
        .collect();
    Ok(Box::new(HumanController {
        inner: Box::new(Held),
        drivers: ctx.controlled.iter().map(|&c| c.then_some(d)).collect(),
        noise,
        dt_s: ctx.step_s,
        view: RingView::on(ctx.ring_length_m, &ctx.length_m),
        speed_limit_mps: ctx.speed_limit_mps.unwrap_or(f64::INFINITY),
    }))
}

/// FNV-1a of a vehicle id: a stream of its own for a vehicle that has no index on a road.
fn id_seed(id: &str) -> u64 {
    u64::from_str_radix(&crate::fingerprint::fnv1a_hex(id), 16).unwrap_or(0)
}

/// The commands of vehicles no human drives: their speeds, held (they are not sent).
struct Held;

impl SpeedController for Held {
    fn step(&mut self, _: f64, speeds: &[f64], _: &[f64], out: &mut [f64]) {
        out.copy_from_slice(speeds);
    }
}

impl SpeedController for HumanController {
    fn step(&mut self, t: f64, speeds: &[f64], positions: &[f64], out: &mut [f64]) {
        self.inner.step(t, speeds, positions, out);
        self.view.observe(speeds, positions);
        for (i, d) in self.drivers.iter().enumerate() {
            if let Some(d) = d {
                let xi = self.noise[i].sample();
                out[i] = d
                    .next_speed_mps(
                        speeds[i],
                        self.view.leader_speeds_mps[i],
                        self.view.gaps_m[i],
                        self.dt_s,
                        xi,
                    )
                    .min(self.speed_limit_mps);
            }
        }
    }

    fn sense(&mut self, neighbors: &crate::sensed::Neighbors) {
        self.inner.sense(neighbors);
        self.view.sense(neighbors);
    }

    fn ended(&mut self) -> Option<crate::speed_controller::ControllerEnd> {
        self.inner.ended()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    struct Hold;
    impl SpeedController for Hold {
        fn step(&mut self, _: f64, v: &[f64], _: &[f64], out: &mut [f64]) {
            out.copy_from_slice(v);
        }
    }

    fn human(noise: f64, form: NoiseForm) -> NoisyIdm {
        NoisyIdm {
            idm: IdmParams::FLOW,
            noise,
            form,
        }
    }

    #[test]
    fn idm_matches_the_formula_by_hand() {
        // v = 10, v_l = 8, h = 20: s* = 2 + max(0, 10 + 10·2/(2√1.5)) = 12 + 10/√1.5
        // = 20.164966, a = 1 − (1/3)^4 − (20.164966/20)² = 1 − 0.012346 − 1.016564 = −0.028910.
        let p = IdmParams::FLOW;
        let s = 12.0 + 10.0 / 1.5f64.sqrt();
        let want = 1.0 - (10.0f64 / 30.0).powi(4) - (s / 20.0).powi(2);
        assert_relative_eq!(p.accel(10.0, 8.0, 20.0), want, epsilon = 1e-14);
        assert_relative_eq!(want, -0.028_910, epsilon = 1e-6);
        // Closing in from far at equal speeds: s* = s0 + vT; standing: a = a (1 − (s0/h)²).
        assert_relative_eq!(p.accel(0.0, 0.0, 4.0), 1.0 - 0.25, epsilon = 1e-15);
        // Flow's floor: |h| < 1e-3 counts as 1e-3.
        assert_relative_eq!(p.accel(0.0, 0.0, 0.0), 1.0 - 4.0e6, epsilon = 1e-9);
    }

    #[test]
    fn the_two_noise_forms_are_the_stated_updates() {
        let f = human(0.2, NoiseForm::Flow);
        let s = human(0.2, NoiseForm::StepConsistent);
        let a = IdmParams::FLOW.accel(10.0, 8.0, 20.0);
        let dt: f64 = 0.1;
        assert_relative_eq!(
            f.next_speed_mps(10.0, 8.0, 20.0, dt, 1.5),
            10.0 + (a + 0.2 * dt.sqrt() * 1.5) * dt,
            epsilon = 1e-14
        );
        assert_relative_eq!(
            s.next_speed_mps(10.0, 8.0, 20.0, dt, 1.5),
            10.0 + a * dt + 0.2 * dt.sqrt() * 1.5,
            epsilon = 1e-14
        );
        // Flow's max(·, 0): no reversing.
        assert_eq!(s.next_speed_mps(0.0, 0.0, 3.0, dt, -5.0), 0.0);
    }

    #[test]
    fn gaussian_has_normal_moments() {
        let mut g = Gaussian::new(11);
        let n = 400_000;
        let xs: Vec<f64> = (0..n).map(|_| g.sample()).collect();
        let m = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n as f64;
        let kurt = xs.iter().map(|x| (x - m).powi(4)).sum::<f64>() / n as f64 / var.powi(2);
        // Standard errors: mean 1/√n = 0.0016, variance √(2/n) = 0.0022, kurtosis √(24/n) = 0.008.
        assert!(m.abs() < 0.008, "{m}");
        assert!((var - 1.0).abs() < 0.011, "{var}");
        assert!((kurt - 3.0).abs() < 0.05, "{kurt}");
        let tail = xs.iter().filter(|x| x.abs() > 1.959_964).count() as f64 / n as f64;
        assert!((tail - 0.05).abs() < 0.002, "{tail}");
    }

    #[test]
    fn streams_depend_on_seed_and_vehicle_only() {
        assert_eq!(vehicle_seed(42, 3), vehicle_seed(42, 3));
        assert_ne!(vehicle_seed(42, 3), vehicle_seed(43, 3));
        assert_ne!(vehicle_seed(42, 3), vehicle_seed(42, 4));
        // Vehicle 1's speeds are the same whether vehicle 0 is a human or not (it only reads
        // vehicle 0's state, held equal here by a huge gap).
        let setup = |d0: Option<NoisyIdm>| HumanSetup {
            drivers: vec![d0, Some(human(0.3, NoiseForm::StepConsistent))],
            ring_length_m: 1e6,
            length_m: vec![5.0; 2],
            seed: 7,
            speed_limit_mps: None,
        };
        let run = |d0| {
            let mut c = HumanController::new(Box::new(Hold), &setup(d0), 0.1);
            let (q, v) = ([5e5, 0.0], [10.0, 10.0]);
            let mut out = [0.0; 2];
            (0..50)
                .map(|k| {
                    c.step(k as f64 * 0.1, &v, &q, &mut out);
                    out[1]
                })
                .collect::<Vec<_>>()
        };
        let a = run(None);
        assert_eq!(a, run(Some(human(0.3, NoiseForm::Flow))));
        assert!(a.windows(2).any(|w| w[0] != w[1]));
    }

    /// Flow's ring without noise: 22 cars of 5 m with Flow's IDM, evenly spaced on 230 m and
    /// 260 m, from 4 m/s, settle on the IDM's equilibrium, the speed whose desired gap is the
    /// gap, (s₀ + vT)/√(1 − (v/v₀)⁴) = L/22 − 5, solved here by bisection: 3.4541 and 4.8159
    /// m/s, the uniform flows Flow's benchmarks quote (3.45 and 4.82).
    #[test]
    fn flows_ring_settles_on_the_idms_equilibrium() {
        let p = IdmParams::FLOW;
        for (ring, quoted) in [(230.0, 3.45), (260.0, 4.82)] {
            let gap = ring / 22.0 - 5.0;
            let desired = |v: f64| {
                (p.min_gap_m + v * p.time_headway_s)
                    / (1.0 - (v / p.desired_speed_mps).powi(4)).sqrt()
            };
            let (mut lo, mut hi) = (0.0, p.desired_speed_mps);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if desired(mid) < gap {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let v_eq = 0.5 * (lo + hi);
            assert!((v_eq - quoted).abs() < 0.005, "{v_eq} vs {quoted}");
            let n = 22;
            let setup = HumanSetup {
                drivers: vec![
                    Some(NoisyIdm {
                        noise: 0.0,
                        ..NoisyIdm::FLOW_IDM_NOISE
                    });
                    n
                ],
                ring_length_m: ring,
                length_m: vec![5.0; n],
                seed: 1,
                speed_limit_mps: None,
            };
            let mut c = HumanController::new(Box::new(Hold), &setup, 0.1);
            let mut q: Vec<f64> = (0..n).map(|i| -(i as f64) * (gap + 5.0)).collect();
            let mut v = vec![4.0; n];
            let mut out = vec![0.0; n];
            for k in 0..6000 {
                c.step(k as f64 * 0.1, &v, &q, &mut out);
                for i in 0..n {
                    q[i] += 0.05 * (v[i] + out[i]);
                }
                std::mem::swap(&mut v, &mut out);
            }
            for x in &v {
                assert_relative_eq!(*x, v_eq, epsilon = 1e-9);
            }
        }
    }

    /// Free-road humans whose desired speed (Flow's 30 m/s) is above the road's limit of
    /// 27.78 m/s (100 km/h) accelerate to the limit and never pass it, noise or not; without a
    /// limit the same draws take them above it.
    #[test]
    fn humans_keep_the_roads_speed_limit() {
        let fastest = |limit: Option<f64>| {
            let setup = HumanSetup {
                drivers: vec![Some(human(0.3, NoiseForm::StepConsistent)); 2],
                ring_length_m: 1e5,
                length_m: vec![5.0; 2],
                seed: 3,
                speed_limit_mps: limit,
            };
            let mut c = HumanController::new(Box::new(Hold), &setup, 0.1);
            let q = [5e4, 0.0];
            let mut v = vec![25.0; 2];
            let mut out = vec![0.0; 2];
            let mut top: f64 = 0.0;
            for k in 0..3000 {
                c.step(k as f64 * 0.1, &v, &q, &mut out);
                std::mem::swap(&mut v, &mut out);
                top = top.max(v[0]).max(v[1]);
            }
            top
        };
        assert_eq!(fastest(Some(27.78)), 27.78);
        assert!(fastest(None) > 28.5);
    }

    /// Stationary speed variance of `n` free-road humans (gaps of 10 km, so the interaction
    /// term is 10⁻⁵ of a) simulated for `horizon_s` after a 100 s burn-in.
    fn free_road_variance(d: NoisyIdm, dt: f64, horizon_s: f64) -> f64 {
        let n = 10;
        let ring = 1e5;
        let setup = HumanSetup {
            drivers: vec![Some(d); n],
            ring_length_m: ring,
            length_m: vec![5.0; n],
            seed: 1,
            speed_limit_mps: None,
        };
        let mut c = HumanController::new(Box::new(Hold), &setup, dt);
        let q: Vec<f64> = (0..n).map(|i| -(i as f64) * ring / n as f64).collect();
        let mut v = vec![d.idm.desired_speed_mps; n];
        let mut out = vec![0.0; n];
        let burn = (100.0 / dt) as usize;
        let steps = burn + (horizon_s / dt) as usize;
        let (mut s1, mut s2, mut m) = (0.0, 0.0, 0.0);
        for k in 0..steps {
            // Positions are held: only the (huge) gaps enter, and they stay 10 km.
            c.step(k as f64 * dt, &v, &q, &mut out);
            std::mem::swap(&mut v, &mut out);
            if k >= burn {
                for &x in &v {
                    s1 += x;
                    s2 += x * x;
                    m += 1.0;
                }
            }
        }
        s2 / m - (s1 / m).powi(2)
    }

    #[test]
    fn step_consistent_statistics_converge_as_the_step_shrinks_and_flows_do_not() {
        // Linearised free road: dv = −k (v − v0) dt + σ dW with k = a δ / v0 = 4/30; the
        // stationary variance is σ²/(2k) = 0.15 m²/s² for σ = 0.2. Flow's form injects σ² Δt³
        // per step, so its variance is σ² Δt² / (2k): it vanishes as Δt² (× 4 per halving).
        let sigma: f64 = 0.2;
        let k = 4.0 / 30.0;
        let sde = sigma * sigma / (2.0 * k);
        for dt in [0.1, 0.05, 0.025] {
            let var = free_road_variance(human(sigma, NoiseForm::StepConsistent), dt, 5000.0);
            // 10 vehicles × 5000 s / (2/k = 15 s) ≈ 3300 independent samples: SE ≈ 2.5 %.
            assert!(
                (var / sde - 1.0).abs() < 0.1,
                "dt {dt}: var {var}, SDE {sde}"
            );
            let flow = free_road_variance(human(sigma, NoiseForm::Flow), dt, 5000.0);
            let want = sde * dt * dt;
            assert!(
                (flow / want - 1.0).abs() < 0.1,
                "dt {dt}: Flow var {flow}, want {want}"
            );
        }
    }
}
