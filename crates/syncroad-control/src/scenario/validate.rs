//! Validation: every check that can be made before a simulation starts; every error names the
//! field path, the value and what would be valid.

use std::path::Path;

use super::file::merge;
use super::graph_spec::{build_graph, graph_shape};
use super::*;
use crate::fingerprint::fnv1a_hex;
use crate::metrics::VerdictThresholds;
use crate::rng::SplitMix64;

/// JSON has no NaN or Infinity; a scenario that writes one gets an error naming the field
/// (the nearest key before the literal) instead of serde_json's "expected value".
fn non_finite_literal(text: &str, line: usize, column: usize) -> Option<ScenarioError> {
    let offset = text
        .split_inclusive('\n')
        .take(line.saturating_sub(1))
        .map(str::len)
        .sum::<usize>()
        + column.saturating_sub(1);
    // serde_json stops after a sign: `-Infinity` is reported at its `I`.
    let offset = if text.get(..offset)?.ends_with('-') {
        offset - 1
    } else {
        offset
    };
    let rest = text.get(offset..)?;
    let literal = ["-Infinity", "Infinity", "NaN", "-inf", "inf", "nan"]
        .into_iter()
        .find(|l| rest.starts_with(l))?;
    // The key: the last `"name":` before the literal.
    let before = &text[..offset];
    let colon = before.rfind(':')?;
    let key_end = before[..colon].rfind('"')?;
    let key_start = before[..key_end].rfind('"')? + 1;
    Some(invalid(
        &before[key_start..key_end],
        literal,
        format!("JSON has no {literal}: write a finite number (line {line}, column {column})"),
    ))
}

/// The most vehicles a scenario may have.
pub const MAX_VEHICLES: usize = 1_000_000;

impl ScenarioFile {
    /// Parses JSON text; `origin` names the source in error messages.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        serde_json::from_str(text).map_err(|source| {
            if let Some(e) = non_finite_literal(text, source.line(), source.column()) {
                return e;
            }
            ScenarioError::Json {
                path: origin.to_string(),
                source,
            }
        })
    }

    /// Validates and resolves the scenario; `base_dir` resolves relative paths. A road through
    /// a network (`loop`, `route`) needs [`ScenarioFile::validate_with`] and a reader.
    ///
    /// At most [`MAX_VEHICLES`] vehicles.
    pub fn validate(self, base_dir: &Path) -> Result<Scenario, ScenarioError> {
        self.validate_with(base_dir, None)
    }

    /// [`ScenarioFile::validate`] with a reader that measures a loop or a route on `sumo.net`
    /// (its length replaces `road.length_m`: the capacity, the even spacing and the ring
    /// check use it).
    pub fn validate_with(
        self,
        base_dir: &Path,
        reader: Option<&dyn RoadReader>,
    ) -> Result<Scenario, ScenarioError> {
        let (n, steps) = self.check_sizes()?;
        if n == 0 {
            // What drives a scenario's own vehicles has none to drive.
            let none = "the scenario has no vehicles of its own (\"vehicles\": 0), so this would drive none: leave it out, and drive an inflow's vehicles with sumo.inflows[k].controlled";
            if self.mixed.is_some() {
                return Err(invalid("mixed", "given", none));
            }
            if self.controller.is_some() {
                return Err(invalid("controller", "given", none));
            }
            if self.sumo.controlled.is_some() {
                return Err(invalid("sumo.controlled", "given", none));
            }
        }
        let entries = self.vehicles.entries();
        let sumo = self.sumo.validate(base_dir, reader)?;
        let closed = self.road.is_closed();
        if let Some(m) = &self.mixed {
            m.validate(closed)?;
        }
        let controller = self.resolve_controller(base_dir)?;
        let measured = if self.road.is_network() {
            Some(super::network_road::measure(
                &self.road,
                sumo.net(),
                sumo.vehicle_type().vclass,
                reader,
            )?)
        } else {
            None
        };
        let road_len = match (&self.road, &measured) {
            (RoadSpec::Ring { length_m } | RoadSpec::Straight { length_m }, _) => *length_m,
            (_, Some(m)) => m.length_m,
            (_, None) => unreachable!("a network road is measured above"),
        };
        if !(road_len.is_finite() && road_len > 0.0) {
            return Err(invalid(
                "road.length_m",
                road_len,
                "must be a finite number > 0",
            ));
        }

        let model = self.resolve_model(n, entries, closed)?;

        let length_m = match &model {
            Model::Cacc(c) => c.length_m.clone(),
            Model::DelayedDriver(_) | Model::Linear(_) => vec![self.sumo.length_m; n],
        };
        let mut rng = SplitMix64::new(self.seed);
        let pert = &self.initial.perturbation;
        for (name, x) in [("speed_mps", pert.speed_mps), ("gap_m", pert.gap_m)] {
            if !(x.is_finite() && x >= 0.0) {
                return Err(invalid(
                    format!("initial.perturbation.{name}"),
                    x,
                    "must be a finite amplitude ≥ 0",
                ));
            }
        }
        let speeds = self.initial_speeds(n, entries, &mut rng)?;
        let mut gaps = self.initial_gaps(
            entries,
            &model,
            (closed, road_len, measured.as_ref()),
            &length_m,
            &mut rng,
        )?;
        check_gaps(&gaps, &length_m, road_len, closed, measured.is_some())?;
        let ring_measured_m = self.measure_ring(&sumo, reader, &length_m, &mut gaps)?;
        let name = self.name.clone().unwrap_or_else(|| "scenario".to_string());
        Ok(Scenario {
            name,
            hash_hex: self.hash_hex(
                controller
                    .as_ref()
                    .and_then(|c| c.source_hash())
                    .into_iter()
                    .chain(sumo.inflow_source_hashes()),
            ),
            seed: self.seed,
            backend: self.backend,
            n,
            step_s: self.step_s,
            steps,
            model,
            road: self.road,
            measured,
            ring_measured_m,
            initial_speed_mps: speeds,
            initial_gap_m: gaps,
            length_m,
            verdict: VerdictThresholds {
                tolerance_mps: self.verdict.tolerance_mps,
                window_s: self.verdict.window_s,
            },
            sumo,
            mixed: self.mixed.clone(),
            controller,
            safety: self.safety,
        })
    }

    /// A ring that names its network (`sumo.net`) is as long as the network measures it, on
    /// both backends: the nominal `road.length_m` must lie within 1 % of it, and the gaps are
    /// scaled by one common factor to close the measured ring (the factor SUMO's layout would
    /// otherwise apply alone, which left the native ring shorter). Returns the measured length;
    /// `None` without a network or a reader that measures rings.
    fn measure_ring(
        &self,
        sumo: &super::SumoSettings,
        reader: Option<&dyn RoadReader>,
        length_m: &[f64],
        gaps: &mut [f64],
    ) -> Result<Option<f64>, ScenarioError> {
        let (RoadSpec::Ring { length_m: nominal }, Some(net), Some(reader)) =
            (&self.road, sumo.net(), reader)
        else {
            return Ok(None);
        };
        let Some(measured) = reader.ring_length(net) else {
            return Ok(None);
        };
        let measured = measured.map_err(|e| invalid("sumo.net", net.display(), e.to_string()))?;
        if (measured - nominal).abs() > 0.01 * nominal {
            return Err(invalid(
                "road.length_m",
                nominal,
                format!(
                    "the ring network of sumo.net ({}) measures {measured:.4} m: give road.length_m within 1 % of it (both backends then run on the measured ring), or drop sumo.net for a native ring of {nominal} m",
                    net.display()
                ),
            ));
        }
        let used: f64 = length_m.iter().sum();
        let factor = (measured - used) / (nominal - used);
        for g in gaps.iter_mut() {
            *g *= factor;
        }
        Ok(Some(measured))
    }

    /// The user's own controller, its files read relative to `base_dir`.
    /// The user's own controller, its files read relative to `base_dir`: the scenario's
    /// `controller`, or the Python class its mixed block names for the automated vehicles
    /// (`mixed.controller = {"python": …}`), never both.
    fn resolve_controller(
        &self,
        base_dir: &Path,
    ) -> Result<Option<crate::user_law::UserLaw>, ScenarioError> {
        let from_mixed = self.mixed.as_ref().and_then(|m| m.python());
        let (spec, at) = match (&self.controller, &from_mixed) {
            (Some(_), Some(m)) => {
                return Err(invalid(
                    "mixed.controller",
                    format!("{{\"python\": {:?}}}", m.python.as_deref().unwrap_or_default()),
                    "the scenario's controller already drives the automated vehicles; name the controller in one place",
                ))
            }
            (Some(c), None) => (c, "controller"),
            (None, Some(m)) => (m, "mixed.controller"),
            (None, None) => return Ok(None),
        };
        spec.resolve(base_dir)
            .map(Some)
            .map_err(|e| ScenarioError::Invalid {
                field: e.field.replacen("controller", at, 1),
                value: e.value,
                expected: e.expected,
            })
    }

    /// The vehicle count, step, horizon and verdict thresholds, each within its limits;
    /// returns the count and the number of steps.
    fn check_sizes(&self) -> Result<(usize, usize), ScenarioError> {
        let n = self.vehicles.count();
        if n == 0 && self.sumo.inflows.is_empty() {
            return Err(invalid(
                "vehicles",
                0,
                "must be ≥ 1, or 0 on an open road of inflows only (sumo.inflows)",
            ));
        }
        if n > MAX_VEHICLES {
            // 10⁸ vehicles once aborted allocating gigabytes for the graph and the histories.
            return Err(invalid(
                "vehicles",
                n,
                "at most 1000000 (the graph, the delay histories and the samples grow with it)",
            ));
        }
        if !(self.step_s.is_finite() && self.step_s > 0.0 && self.step_s <= 1.0) {
            return Err(invalid(
                "step_s",
                self.step_s,
                "must be a finite number in (0, 1] s; 0.1 or less is usual",
            ));
        }
        if !(self.horizon_s.is_finite() && self.horizon_s > 0.0) {
            return Err(invalid(
                "horizon_s",
                self.horizon_s,
                "must be a finite number > 0",
            ));
        }
        let steps_f = (self.horizon_s / self.step_s).round();
        if steps_f > MAX_STEPS as f64 {
            return Err(ScenarioError::TooManySteps {
                horizon_s: self.horizon_s,
                step_s: self.step_s,
                steps: steps_f,
                max_horizon_s: MAX_STEPS as f64 * self.step_s,
            });
        }
        let steps = steps_f as usize;
        if steps == 0 {
            return Err(invalid(
                "horizon_s",
                self.horizon_s,
                format!("must be at least one step ({} s)", self.step_s),
            ));
        }
        if !(self.verdict.tolerance_mps.is_finite() && self.verdict.tolerance_mps > 0.0) {
            return Err(invalid(
                "verdict.tolerance_mps",
                self.verdict.tolerance_mps,
                "must be a finite number > 0",
            ));
        }
        if !(self.verdict.window_s.is_finite()
            && self.verdict.window_s > 0.0
            && self.verdict.window_s <= self.horizon_s)
        {
            return Err(invalid(
                "verdict.window_s",
                self.verdict.window_s,
                format!("must be > 0 and ≤ horizon_s = {}", self.horizon_s),
            ));
        }
        Ok((n, steps))
    }

    /// The model with every per-vehicle value resolved: the delayed-driver law (graph, delays
    /// on the step grid, leader) or the CACC platoon; `closed` says the road is a ring or loop.
    /// A scenario without vehicles of its own has no model, and an empty one stands for it.
    fn resolve_model(
        &self,
        n: usize,
        entries: &[super::file::VehicleEntry],
        closed: bool,
    ) -> Result<Model, ScenarioError> {
        match (&self.model, n) {
            // No vehicles of its own: the inflows' vehicles are SUMO's, or their own law's.
            (None, 0) => Ok(Model::DelayedDriver(DelayedDriverModel::empty())),
            (Some(_), 0) => Err(invalid(
                "model",
                "given",
                "the scenario has no vehicles of its own (\"vehicles\": 0), so no law of the model drives any: leave the model out (SUMO's model drives the inflows' vehicles, or the law of sumo.inflows[k].controlled)",
            )),
            (None, _) => Err(invalid(
                "model",
                "missing",
                "give the law of the scenario's vehicles: {\"type\": \"delayed_driver\", ...}, {\"type\": \"cacc\", ...} or {\"type\": \"linear\", ...}",
            )),
            (Some(ModelSpec::DelayedDriver {
                graph,
                delay_s,
                leader,
                history,
            }), _) => {
                let shape = graph_shape(graph);
                let graph = build_graph(graph, n)?;
                let delay_s = merge("model.delay_s", "delay_s", delay_s.as_ref(), entries, |e| {
                    e.delay_s
                })?
                .ok_or_else(|| {
                    invalid(
                        "model.delay_s",
                        "missing",
                        "give the reaction delays α_i [s] here or in every vehicle entry",
                    )
                })?
                .resolve_nonneg("model.delay_s", n)?;
                let delay_steps = self.delay_steps(&delay_s)?;
                let leader = resolve_pinning(leader.as_ref(), n, closed)?;
                Ok(Model::DelayedDriver(DelayedDriverModel {
                    shape,
                    graph,
                    delay_s,
                    delay_steps,
                    leader,
                    history: *history,
                }))
            }
            (Some(ModelSpec::Linear {
                graph,
                agents,
                leader,
            }), _) => {
                let shape = graph_shape(graph);
                let graph = build_graph(graph, n)?;
                let agents = resolve_agents(agents, n)?;
                let delay_s: Vec<f64> = agents.iter().map(|a| a.transfer.delay_s).collect();
                let delay_steps = self.delay_steps(&delay_s).map_err(|e| match e {
                    ScenarioError::DelayNotMultipleOfStep { vehicle, delay_s, nearest, .. } => invalid(
                        format!("model.agents[{vehicle}].delay_s"),
                        delay_s,
                        format!("must be a whole number of steps (step_s = {}); the nearest is {nearest}", self.step_s),
                    ),
                    other => other,
                })?;
                let leader = resolve_pinning(leader.as_ref(), n, closed)?;
                Ok(Model::Linear(LinearModel {
                    graph,
                    agents,
                    delay_steps,
                    leader,
                    shape,
                }))
            }
            (Some(ModelSpec::Cacc(c)), _) => {
                if closed {
                    return Err(invalid("road.type", if self.road.is_network() { "loop" } else { "ring" }, "a CACC platoon drives behind its leader on a straight road: use \"straight\""));
                }
                c.leader.validate()?;
                let mut nu = c.nu.resolve_nonneg("model.nu", n)?;
                nu[n - 1] = 0.0;
                Ok(Model::Cacc(CaccModel {
                    mu: c.mu.resolve_pos("model.mu", n)?,
                    eta: c.eta.resolve_pos("model.eta", n)?,
                    nu,
                    desired_gap_m: c.desired_gap_m.resolve_nonneg("model.desired_gap_m", n)?,
                    tau_s: c.tau_s.resolve_pos("model.tau_s", n)?,
                    length_m: c.length_m.resolve_pos("model.length_m", n)?,
                    leader: c.leader.clone(),
                }))
            }
        }
    }

    /// The delays α_i in whole steps m_i = α_i / Δt, each on the step grid, the buffers they
    /// need within bounds.
    fn delay_steps(&self, delay_s: &[f64]) -> Result<Vec<usize>, ScenarioError> {
        let mut delay_steps = Vec::with_capacity(delay_s.len());
        for (i, &d) in delay_s.iter().enumerate() {
            let m = (d / self.step_s).round();
            if (m * self.step_s - d).abs() > 1e-9 * self.step_s.max(d) {
                return Err(ScenarioError::DelayNotMultipleOfStep {
                    vehicle: i,
                    delay_s: d,
                    step_s: self.step_s,
                    nearest: (m.max(1.0) * self.step_s * 1e9).round() / 1e9,
                });
            }
            delay_steps.push(m as usize);
        }
        check_delay_buffer(&delay_steps, delay_s, self.step_s)?;
        Ok(delay_steps)
    }

    /// The initial bumper gaps: as given, else even on a closed road (its length less the
    /// vehicles'), a platoon's desired gaps, or 20 m; with the seeded perturbation (on a closed
    /// road of zero mean, so the gaps still close it). A loop measured on its network must hold
    /// the vehicles.
    fn initial_gaps(
        &self,
        entries: &[super::file::VehicleEntry],
        model: &Model,
        (closed, road_len, measured): (bool, f64, Option<&MeasuredRoad>),
        length_m: &[f64],
        rng: &mut SplitMix64,
    ) -> Result<Vec<f64>, ScenarioError> {
        let n = length_m.len();
        let pert = &self.initial.perturbation;
        let gap_spec = merge(
            "initial.gap_m",
            "gap_m",
            self.initial.gap_m.as_ref(),
            entries,
            |e| e.gap_m,
        )?;
        let mut gaps = match (&gap_spec, &self.road, model) {
            (Some(g), _, _) => g.resolve_nonneg("initial.gap_m", n)?,
            (None, _, _) if closed => {
                let used: f64 = length_m.iter().sum();
                vec![(road_len - used) / n as f64; n]
            }
            (None, _, Model::Cacc(c)) => c.desired_gap_m.clone(),
            (None, _, _) => vec![20.0; n],
        };
        if let Some(m) = measured.filter(|_| closed) {
            let used: f64 = length_m.iter().sum();
            if used > m.length_m {
                return Err(invalid(
                    "vehicles",
                    n,
                    format!(
                        "{n} vehicles of {:.2} m in all do not fit on the loop, {:.3} m long as measured on its network; at most {} fit",
                        used,
                        m.length_m,
                        (m.length_m / length_m.iter().copied().fold(0.0, f64::max)).floor()
                    ),
                ));
            }
        }
        let offsets: Vec<f64> = (0..n).map(|_| rng.symmetric(pert.gap_m)).collect();
        // On a ring the gaps must still close the circle: remove the offsets' mean.
        let shift = if closed {
            offsets.iter().sum::<f64>() / n as f64
        } else {
            0.0
        };
        for (g, o) in gaps.iter_mut().zip(&offsets) {
            *g += o - shift;
        }
        Ok(gaps)
    }

    /// The initial speeds, each within [`MAX_SPEED_MPS`], plus the seeded uniform
    /// perturbation (drawn first from `rng`, before the gaps' offsets).
    fn initial_speeds(
        &self,
        n: usize,
        entries: &[super::file::VehicleEntry],
        rng: &mut SplitMix64,
    ) -> Result<Vec<f64>, ScenarioError> {
        let pert = &self.initial.perturbation;
        let mut speeds = merge(
            "initial.speed_mps",
            "speed_mps",
            self.initial.speed_mps.as_ref(),
            entries,
            |e| e.speed_mps,
        )?
        .unwrap_or(PerVehicle::Uniform(DEFAULT_SPEED_MPS))
        .resolve_nonneg("initial.speed_mps", n)?;
        if let Some(i) = speeds.iter().position(|&v| v > super::MAX_SPEED_MPS) {
            return Err(invalid(
                format!("initial.speed_mps[{i}]"),
                speeds[i],
                format!("must be at most {} m/s", super::MAX_SPEED_MPS),
            ));
        }
        // The perturbation is uniform in ±amplitude around each speed: an amplitude above the
        // slowest speed would draw negative speeds, clamped to 0 — another distribution than
        // the one asked for.
        let slowest = speeds.iter().copied().fold(f64::INFINITY, f64::min);
        if pert.speed_mps > 0.0 && pert.speed_mps > slowest {
            return Err(invalid(
                "initial.perturbation.speed_mps",
                pert.speed_mps,
                format!(
                    "must not exceed the slowest initial speed ({slowest} m/s): a larger amplitude draws negative speeds"
                ),
            ));
        }
        for v in speeds.iter_mut() {
            *v = (*v + rng.symmetric(pert.speed_mps)).max(0.0);
        }
        Ok(speeds)
    }

    /// The hash of the file as written (FNV-1a over its canonical JSON), and of the Python
    /// sources and states it names as read (`sources`: the controller's, the inflows').
    fn hash_hex<'a>(&self, sources: impl Iterator<Item = &'a str>) -> String {
        let mut text = serde_json::to_string(self).expect("a scenario always serializes");
        for h in sources {
            text.push_str(h);
        }
        fnv1a_hex(&text)
    }
}

impl Scenario {
    /// The same scenario with another model of the same type (a gain- or delay-scaled copy, for
    /// instance), checked to fit it: one value per vehicle, delays on the step grid, and for a
    /// platoon the same vehicle lengths.
    pub fn with_model(&self, model: Model) -> Result<Scenario, ScenarioError> {
        let n = self.n;
        let per_vehicle = |field: &str, len: usize| {
            if len == n {
                Ok(())
            } else {
                Err(ScenarioError::LengthMismatch {
                    field: field.to_string(),
                    len,
                    vehicles: n,
                })
            }
        };
        match (&self.model, &model) {
            (Model::DelayedDriver(_), Model::DelayedDriver(m)) => {
                per_vehicle("model.graph", m.graph.len())?;
                per_vehicle("model.delay_s", m.delay_s.len())?;
                per_vehicle("model.delay_s (steps)", m.delay_steps.len())?;
                if let Some((_, b)) = &m.leader {
                    per_vehicle("model.leader.pinning", b.len())?;
                }
                check_delay_buffer(&m.delay_steps, &m.delay_s, self.step_s)?;
                for (i, (&d, &k)) in m.delay_s.iter().zip(&m.delay_steps).enumerate() {
                    let on_grid = k as f64 * self.step_s;
                    if !(d.is_finite() && (on_grid - d).abs() <= 1e-9 * self.step_s.max(d)) {
                        return Err(ScenarioError::DelayNotMultipleOfStep {
                            vehicle: i,
                            delay_s: d,
                            step_s: self.step_s,
                            nearest: (on_grid * 1e9).round() / 1e9,
                        });
                    }
                }
            }
            (Model::Cacc(_), Model::Cacc(c)) => {
                for (field, len) in [
                    ("model.mu", c.mu.len()),
                    ("model.eta", c.eta.len()),
                    ("model.nu", c.nu.len()),
                    ("model.desired_gap_m", c.desired_gap_m.len()),
                    ("model.tau_s", c.tau_s.len()),
                ] {
                    per_vehicle(field, len)?;
                }
                if c.length_m != self.length_m {
                    return Err(invalid(
                        "model.length_m",
                        format!("{:?}", c.length_m),
                        format!(
                            "the scenario's vehicles are {:?} m long; a replacement model keeps them",
                            self.length_m
                        ),
                    ));
                }
            }
            (Model::Linear(_), Model::Linear(m)) => {
                per_vehicle("model.graph", m.graph.len())?;
                per_vehicle("model.agents", m.agents.len())?;
                per_vehicle("model.agents (delay steps)", m.delay_steps.len())?;
                if let Some((_, b)) = &m.leader {
                    per_vehicle("model.leader.pinning", b.len())?;
                }
            }
            (_, Model::Linear(_)) => {
                return Err(invalid(
                    "model.type",
                    "linear",
                    "a replacement model keeps the scenario's model type",
                ))
            }
            (_, Model::DelayedDriver(_)) => {
                return Err(invalid(
                    "model.type",
                    "delayed_driver",
                    "a replacement model keeps the scenario's model type",
                ))
            }
            (_, Model::Cacc(_)) => {
                return Err(invalid(
                    "model.type",
                    "cacc",
                    "a replacement model keeps the scenario's model type",
                ))
            }
        }
        // Another model is another scenario: its hash covers the file's and the new model, so
        // two gain-scaled copies never share one.
        let model_json = serde_json::to_string(&model).expect("a model always serializes");
        let hash_hex = fnv1a_hex(format!("{}{model_json}", self.hash_hex));
        Ok(Scenario {
            model,
            hash_hex,
            ..self.clone()
        })
    }
}

/// The gaps after perturbation: none negative, and on a closed road gaps plus vehicle lengths
/// add up to its length (`measured`: a loop measured on its network).
fn check_gaps(
    gaps: &[f64],
    length_m: &[f64],
    road_len: f64,
    closed: bool,
    measured: bool,
) -> Result<(), ScenarioError> {
    for (i, g) in gaps.iter().enumerate() {
        if *g < 0.0 {
            return Err(invalid(
                    format!("initial.gap_m[{i}]"),
                    g,
                    "the gap (after perturbation) must be ≥ 0: vehicles may not overlap; lower initial.perturbation.gap_m or use fewer vehicles",
                ));
        }
    }
    if closed {
        let ring = road_len;
        let used: f64 = gaps.iter().sum::<f64>() + length_m.iter().sum::<f64>();
        if (used - ring).abs() > 1e-6 * ring {
            let what = if measured {
                format!("on a loop, gaps plus vehicle lengths must add up to the loop's length measured on its network, {ring} m")
            } else {
                format!(
                    "on a ring, gaps plus vehicle lengths must add up to road.length_m = {ring} m"
                )
            };
            return Err(invalid(
                "initial.gap_m",
                format!("{used:.3} m of gaps and vehicle lengths"),
                format!("{what} (omit initial.gap_m for even spacing)"),
            ));
        }
    }
    Ok(())
}

/// The delayed-driver model's leader for `n` drivers: its speed v_0 and the pinning gains b_i,
/// at least one of them positive (Theorem `thm.1+`).
fn resolve_leader(
    l: &super::file::DriverLeaderSpec,
    n: usize,
) -> Result<(f64, Vec<f64>), ScenarioError> {
    if !(l.speed_mps.is_finite() && (0.0..=super::MAX_SPEED_MPS).contains(&l.speed_mps)) {
        return Err(invalid(
            "model.leader.speed_mps",
            l.speed_mps,
            format!(
                "must be a finite number in [0, {}] m/s",
                super::MAX_SPEED_MPS
            ),
        ));
    }
    let b = l.pinning.resolve_nonneg("model.leader.pinning", n)?;
    if b.iter().all(|&x| x == 0.0) {
        return Err(invalid(
            "model.leader.pinning",
            "all zero",
            "at least one driver must see the leader (some b_i > 0, Theorem thm.1+)",
        ));
    }
    Ok((l.speed_mps, b))
}

/// Refuses delays whose buffers would pass [`MAX_DELAY_BUFFER`] values: the law keeps
/// `max_i m_i + 2` rows of N inputs, `m_i = α_i / Δt`.
pub(super) fn check_delay_buffer(
    delay_steps: &[usize],
    delay_s: &[f64],
    step_s: f64,
) -> Result<(), ScenarioError> {
    let n = delay_steps.len();
    let Some(&m) = delay_steps.iter().max() else {
        return Ok(());
    };
    let vehicle = delay_steps.iter().position(|&k| k == m).unwrap_or(0);
    let values = (m as f64 + 2.0) * n as f64;
    if values > MAX_DELAY_BUFFER as f64 {
        return Err(ScenarioError::DelayBufferTooLarge {
            vehicle,
            delay_s: delay_s[vehicle],
            step_s,
            values,
            min_step_s: delay_s[vehicle] / (MAX_DELAY_BUFFER as f64 / n as f64 - 2.0),
        });
    }
    Ok(())
}

/// The linear agents, one per driver: a single agent is every driver's; a list has one entry
/// per driver. Each is validated, its errors named below `model.agents`.
fn resolve_agents(
    spec: &super::file::AgentsSpec,
    n: usize,
) -> Result<Vec<crate::agents::LinearAgent>, ScenarioError> {
    use super::file::AgentsSpec;
    let name = |i: Option<usize>, e: crate::agents::LinearAgentError| {
        let at = i.map_or(String::new(), |i| format!("[{i}]"));
        invalid(format!("model.agents{at}.{}", e.field), e.value, e.expected)
    };
    match spec {
        AgentsSpec::One(a) => {
            let agent = a.validate().map_err(|e| name(None, e))?;
            Ok(vec![agent; n])
        }
        AgentsSpec::List(list) => {
            if list.len() != n {
                return Err(ScenarioError::LengthMismatch {
                    field: "model.agents".to_string(),
                    len: list.len(),
                    vehicles: n,
                });
            }
            list.iter()
                .enumerate()
                .map(|(i, a)| a.validate().map_err(|e| name(Some(i), e)))
                .collect()
        }
    }
}

/// The leader and pinning gains of a model, which need a straight road.
fn resolve_pinning(
    leader: Option<&super::file::DriverLeaderSpec>,
    n: usize,
    closed: bool,
) -> Result<Option<(f64, Vec<f64>)>, ScenarioError> {
    let Some(l) = leader else {
        return Ok(None);
    };
    if closed {
        return Err(invalid(
            "model.leader",
            "given",
            "a leader needs a straight road (road.type = \"straight\")",
        ));
    }
    resolve_leader(l, n).map(Some)
}
