//! The sweep spec a user writes, validated into the list of points it stands for.
//!
//! ```json
//! {
//!   "name": "gain-delay",
//!   "base": "../scenarios/sugiyama-ring.json",
//!   "backend": "sumo",
//!   "axes": [
//!     {"field": "scale.gain",  "linspace": [0.5, 3.0, 6]},
//!     {"field": "scale.delay", "values": [0.5, 1.0, 1.5]},
//!     {"field": "initial.speed_mps", "logspace": [2, 16, 4]}
//!   ],
//!   "seeds": {"first": 1, "count": 3},
//!   "runs": ["protocol", "krauss-0.9"],
//!   "penetrations": [0.0, 0.25, 0.5],
//!   "mixed_driver": "human",
//!   "mixed_controller": "protocol",
//!   "metrics": ["sync.verdict", "congestion.speed_std_mps"]
//! }
//! ```
//!
//! An axis sets one scenario field path (`model.graph.gain_pred`, `initial.speed_mps`, ...) to
//! each of its values; `scale.gain` and `scale.delay` scale every gain and every delay of a
//! delayed-driver scenario. `linspace` is `[first, last, count]` evenly spaced, `logspace`
//! `[first, last, count]` geometrically spaced (both ends included). `runs` names who drives:
//! `protocol` (the scenario's law), a wave damper (`follower-stopper-U`, `pi-saturation`) or
//! one of SUMO's drivers, as `compare --baselines` names them; each `penetrations` entry p adds
//! a run where round(p·n) vehicles run `mixed_controller` (the law by default), spread evenly,
//! among `mixed_driver` humans. Points are the product axes × runs × seeds, numbered in
//! that order (seeds fastest); the numbering is what shards and resumption rely on.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};
use syncroad_control::drive::{mixed_controllers, mixed_series, Drive};
use syncroad_control::scenario::{Backend, Model, SafetyMode, ScenarioFile};
use syncroad_control::SumoDriver;
use syncroad_control::{LawSpec, Scenario};

pub use super::axis::Axis;
use super::axis::{set_path, AxisFile, Target};
pub use super::points::{Point, SeedsFile};
use crate::error::InputError;

/// The spec as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecFile {
    /// Name for titles (default: the file's stem).
    #[serde(default)]
    pub name: Option<String>,
    /// The base scenario, relative to the spec file.
    pub base: PathBuf,
    /// `native` or `sumo` (default: the scenario's).
    #[serde(default)]
    pub backend: Option<Backend>,
    /// The safety layer of every point, in place of the base scenario's `safety` (`off`,
    /// `sumo` or `filter`; `--safety` sets it from the command line).
    #[serde(default)]
    pub safety: Option<SafetyMode>,
    /// The axes, outermost first.
    #[serde(default)]
    pub axes: Vec<AxisFile>,
    /// Seeds: a list, or `{"first": F, "count": N}` (default: the scenario's seed).
    #[serde(default)]
    pub seeds: Option<SeedsFile>,
    /// Who drives: `protocol` or SUMO driver names (default `["protocol"]` unless
    /// `penetrations` is given).
    #[serde(default)]
    pub runs: Option<Vec<String>>,
    /// Mixed runs: fractions of law-driven vehicles, each in [0, 1].
    #[serde(default)]
    pub penetrations: Vec<f64>,
    /// The human driver of mixed runs (default `human`, the preset that jams the Sugiyama ring,
    /// `docs/src/human-preset.md`; `human-noisy` jams it from a uniform start).
    #[serde(default)]
    pub mixed_driver: Option<String>,
    /// Who drives the automated vehicles of mixed runs: `law` (default), `follower-stopper-U`
    /// or `pi-saturation`, or a list of them (a mixed run per controller and penetration).
    #[serde(default)]
    pub mixed_controller: Option<OneOrMany>,
    /// Metric paths of `metrics.json` to keep (default: [`DEFAULT_METRICS`]).
    #[serde(default)]
    pub metrics: Option<Vec<String>>,
    /// Recording stride (default: about 2000 samples per run).
    #[serde(default)]
    pub record_every: Option<usize>,
    /// Per-run wall-clock limit for SUMO runs [s] (default: the scenario's `sumo.timeout_s`).
    #[serde(default)]
    pub timeout_s: Option<f64>,
    /// Warm-up excluded from congestion metrics [s] (default: a quarter of the horizon).
    #[serde(default)]
    pub warmup_s: Option<f64>,
    /// Run points whose scenarios come out identical (`scale.delay` values that round to the
    /// same delays on the step grid) under each label instead of refusing the spec; `map`
    /// sets it, its grid records each cell's rounding.
    #[serde(default)]
    pub allow_alike_points: bool,
}

/// A name or a list of names.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
pub enum OneOrMany {
    /// One.
    One(String),
    /// Several.
    Many(Vec<String>),
}

/// Metrics kept by default: the verdict, the spread, congestion and safety.
pub const DEFAULT_METRICS: [&str; 13] = [
    "sync.verdict",
    "sync.final_spread_mps",
    "sync.window_max_spread_mps",
    "sync.time_to_tolerance_s",
    "sync.decay_rate_per_s",
    "certified",
    "congestion.mean_speed_mps",
    "congestion.speed_std_mps",
    "congestion.wave_amplitude_mps",
    "congestion.stopped_fraction",
    "safety.collision_steps",
    "safety.overridden_commands",
    "sumo.fuel_g_per_km",
];

/// One run of a point: its name, penetration and drivers.
#[derive(Debug, Clone)]
pub struct RunChoice {
    /// The run spec (name and per-vehicle drivers).
    pub spec: Drive,
    /// Fraction of vehicles running the law.
    pub penetration: f64,
}

/// A validated sweep.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// Name for titles.
    pub name: String,
    /// The spec as written.
    pub file: SpecFile,
    /// The base scenario, validated.
    pub base: Scenario,
    /// The base scenario's JSON as written.
    base_json: Value,
    /// Its folder (relative paths inside it resolve here).
    base_dir: PathBuf,
    /// The backend every point runs on.
    pub backend: Backend,
    /// The axes.
    pub axes: Vec<Axis>,
    /// The runs.
    pub runs: Vec<RunChoice>,
    /// The seeds.
    pub seeds: Vec<u64>,
    /// Metric paths kept.
    pub metrics: Vec<String>,
    /// Number of points.
    count: usize,
    /// SHA-256 of the spec, the base scenario as written and the files the points read
    /// (networks, route, additional and configuration files, the user's controller and the
    /// modules beside it): what resumption checks.
    pub hash: String,
    /// SHA-256 of each of those files, by path: what a refused resume names as changed.
    pub inputs: BTreeMap<String, String>,
}

fn bad(m: impl Into<String>) -> InputError {
    InputError::new(m)
}

impl Sweep {
    /// Reads and validates a spec file: every point's scenario is built and validated, so a
    /// bad value stops the sweep before anything runs.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| bad(format!("cannot read sweep spec {}: {e}", path.display())))?;
        // Parsed once as the schema for errors with line and column, once as written.
        serde_json::from_str::<SpecFile>(&text)
            .map_err(|e| bad(format!("sweep spec {}: {e}", path.display())))?;
        let raw: Value = serde_json::from_str(&text)
            .map_err(|e| bad(format!("sweep spec {}: {e}", path.display())))?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let stem = path
            .file_stem()
            .map_or("sweep".into(), |s| s.to_string_lossy().into_owned());
        Self::new(raw, &dir, stem)
    }

    /// [`Sweep::load`] with `--safety` in place of the spec's `safety` key: the spec as run,
    /// which its hash covers (a resumed sweep keeps the layer it started with).
    pub fn load_with(path: &Path, safety: Option<SafetyMode>) -> anyhow::Result<Self> {
        let Some(mode) = safety else {
            return Self::load(path);
        };
        let text = std::fs::read_to_string(path)
            .map_err(|e| bad(format!("cannot read sweep spec {}: {e}", path.display())))?;
        let mut raw: Value = serde_json::from_str(&text)
            .map_err(|e| bad(format!("sweep spec {}: {e}", path.display())))?;
        if let Some(obj) = raw.as_object_mut() {
            obj.insert("safety".into(), Value::String(mode.name().into()));
        }
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let stem = path
            .file_stem()
            .map_or("sweep".into(), |s| s.to_string_lossy().into_owned());
        Self::new(raw, &dir, stem)
    }

    /// Validates a spec (JSON as written) whose relative paths resolve against `dir`;
    /// `default_name` names it when the spec gives no name.
    pub fn new(raw: Value, dir: &Path, default_name: String) -> anyhow::Result<Self> {
        let file: SpecFile =
            serde_json::from_value(raw.clone()).map_err(|e| bad(format!("sweep spec: {e}")))?;
        let name = file.name.clone().unwrap_or(default_name);
        let base_path = dir.join(&file.base);
        let base_text = std::fs::read_to_string(&base_path).map_err(|e| {
            bad(format!(
                "base = {}: cannot read {}: {e}",
                file.base.display(),
                base_path.display()
            ))
        })?;
        let base_json: Value = serde_json::from_str(&base_text)
            .map_err(|e| bad(format!("base = {}: {e}", file.base.display())))?;
        let base_dir = base_path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        // Validated from the text just read, so the scenario and the hash see the same file.
        let base = ScenarioFile::from_json(&base_text, &base_path.display().to_string())
            .and_then(|f| f.validate_with(&base_dir, Some(&syncroad_sumo::NetReader)))
            .map_err(|e| InputError::caused(format!("base = {}", file.base.display()), e))?;
        let backend = file.backend.unwrap_or(base.backend());
        let axes = file
            .axes
            .iter()
            .map(AxisFile::validate)
            .collect::<Result<Vec<_>, _>>()?;
        let mut seen = BTreeSet::new();
        for a in &axes {
            if !seen.insert(a.field.as_str()) {
                return Err(bad(format!("axes[{}] appears twice", a.field)).into());
            }
            if let (Some(m), "safety") = (file.safety, a.field.as_str()) {
                return Err(bad(format!(
                    "safety = {}: the spec also sweeps safety on an axis; give one or the other",
                    m.name()
                ))
                .into());
            }
        }
        let seeds = super::points::seeds_of(file.seeds.as_ref(), base.seed())?;
        let runs = runs_of(&file, &base, backend)?;
        let metrics = metrics_of(&file)?;
        if file.record_every == Some(0) {
            return Err(bad("record_every = 0: must be ≥ 1").into());
        }
        if let Some(t) = file.timeout_s {
            if t == 0.0 {
                return Err(bad("timeout_s = 0: must be > 0").into());
            }
            crate::config::timeout_as("timeout_s", t)?;
        }
        let count = super::points::count(&axes, runs.len(), seeds.len())?;
        let mut h = Sha256::new();
        // The spec as written (keys sorted), so the hash does not move with syncroad's defaults.
        h.update(serde_json::to_string(&raw)?.as_bytes());
        h.update([0]);
        h.update(serde_json::to_string(&base_json)?.as_bytes());
        let mut sweep = Self {
            name,
            file,
            base,
            base_json,
            base_dir,
            backend,
            axes,
            runs,
            seeds,
            metrics,
            count,
            hash: String::new(),
            inputs: BTreeMap::new(),
        };
        // Every point is checked as it will run before anything runs; every file they read
        // (networks, route, additional and configuration files: their contents, so a moved folder
        // still resumes) is part of
        // what a resumed sweep must match.
        for file in sweep.check_points()? {
            let bytes = std::fs::read(&file)
                .map_err(|e| bad(format!("cannot read {}: {e}", file.display())))?;
            h.update([0]);
            h.update(&bytes);
            let each: String = Sha256::digest(&bytes)
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
            sweep.inputs.insert(file.display().to_string(), each);
        }
        sweep.hash = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
        Ok(sweep)
    }

    /// Number of points (at most [`super::points::MAX_POINTS`]).
    pub fn len(&self) -> usize {
        self.count
    }

    /// The points in order.
    pub fn points(&self) -> impl Iterator<Item = Point> + '_ {
        (0..self.len()).map(|id| self.point(id))
    }

    /// Point `id` (seeds vary fastest, then runs, then the last axis).
    pub fn point(&self, id: usize) -> Point {
        let mut rest = id;
        let seed = self.seeds[rest % self.seeds.len()];
        rest /= self.seeds.len();
        let run = rest % self.runs.len();
        rest /= self.runs.len();
        let mut at = vec![0; self.axes.len()];
        for (k, a) in self.axes.iter().enumerate().rev() {
            at[k] = rest % a.values.len();
            rest /= a.values.len();
        }
        Point { id, at, run, seed }
    }

    /// The validated scenario of a point (seed included; scales applied last).
    pub fn scenario(&self, p: &Point) -> anyhow::Result<Scenario> {
        let mut doc = self.base_json.clone();
        if let Some(m) = self.file.safety {
            doc["safety"] = Value::String(m.name().into());
        }
        let mut gain = 1.0;
        let mut delay = 1.0;
        for (a, &k) in self.axes.iter().zip(&p.at) {
            let v = a.values[k].clone();
            match &a.target {
                Target::Field(path) => set_path(&mut doc, path, v, &a.field)?,
                Target::GainScale => gain = v.as_f64().unwrap_or(1.0),
                Target::DelayScale => delay = v.as_f64().unwrap_or(1.0),
            }
        }
        doc["seed"] = serde_json::json!(p.seed);
        doc["backend"] = serde_json::to_value(self.backend)?;
        let at = || {
            self.axes
                .iter()
                .zip(&p.at)
                .map(|(a, &k)| format!("{} = {}", a.field, a.values[k]))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let file = ScenarioFile::from_json(&doc.to_string(), "<sweep point>")
            .map_err(|e| InputError::caused(format!("sweep point {} ({})", p.id, at()), e))?;
        let mut sc = file
            .validate_with(&self.base_dir, Some(&syncroad_sumo::NetReader))
            .map_err(|e| InputError::caused(format!("sweep point {} ({})", p.id, at()), e))?;
        // A run of the user's own class (`"runs": ["python:FILE.py:Class"]`) is the scenario
        // with it, which the point's hash covers.
        if let Some(u) = &self.runs[p.run].spec.user {
            sc = sc.with_controller(u.clone());
        }
        if gain == 1.0 && delay == 1.0 {
            return Ok(sc);
        }
        if !matches!(sc.model(), Model::DelayedDriver(_)) {
            return Err(bad(format!(
                "axes[scale.*]: scale.gain and scale.delay need a delayed-driver scenario; {} is a CACC platoon",
                self.base.name()
            ))
            .into());
        }
        Ok(sc
            .scaled(gain, delay)
            .map_err(|e| InputError::caused(format!("sweep point {} ({})", p.id, at()), e))?
            .scenario)
    }
}

/// The runs of a spec: `runs` by name, then a mixed run per penetration and controller.
fn runs_of(file: &SpecFile, base: &Scenario, backend: Backend) -> anyhow::Result<Vec<RunChoice>> {
    let n = base.vehicles();
    let mut runs = Vec::new();
    let names = file.runs.clone().unwrap_or_default();
    if file.runs.is_none() && file.penetrations.is_empty() {
        // Neither runs nor penetrations: the scenario as written (its law, or its mixed ring).
        let spec = Drive::as_written(base.mixed().is_some(), n);
        runs.push(RunChoice {
            penetration: penetration(&spec, base),
            spec,
        });
    }
    let only_protocol = names.iter().all(|r| {
        matches!(
            Drive::parse("runs", r, n),
            Ok(d) if d.name == syncroad_control::PROTOCOL
        )
    });
    if n == 0 && (!only_protocol || !file.penetrations.is_empty()) {
        // Every run would drive the same traffic: the drivers are SUMO's and the inflows' laws.
        return Err(bad(
            "runs and penetrations: the base scenario has no vehicles of its own (\"vehicles\": 0), so a run's drivers would drive nobody; sweep sumo.inflows[k].controlled instead (an axis whose values are controlled blocks)",
        )
        .into());
    }
    for name in &names {
        let spec = Drive::parse("runs", name, n).map_err(|e| InputError::about("runs", e))?;
        if let Some(r) = runs
            .iter()
            .find(|r: &&RunChoice| r.spec.name == spec.name || r.spec.same_run(&spec))
        {
            return Err(bad(if r.spec.name == spec.name {
                format!("runs: {} is listed twice", spec.name)
            } else {
                format!(
                    "runs: {} and {} are the same run (the same drivers, however spelt); list it once",
                    r.spec.name, spec.name
                )
            })
            .into());
        }
        runs.push(RunChoice {
            penetration: penetration(&spec, base),
            spec,
        });
    }
    if !file.penetrations.is_empty() {
        let human_name = file
            .mixed_driver
            .as_deref()
            .unwrap_or(syncroad_control::drive::DEFAULT_HUMAN);
        let human = SumoDriver::parse("mixed_driver", human_name)
            .map_err(|e| InputError::about("mixed_driver", e))?;
        let names = match &file.mixed_controller {
            None => vec![syncroad_control::PROTOCOL.to_string()],
            Some(OneOrMany::One(c)) => vec![c.clone()],
            Some(OneOrMany::Many(v)) => v.clone(),
        };
        let controllers = mixed_controllers("mixed_controller", &names)
            .map_err(|e| InputError::about("mixed_controller", e))?;
        let mut counts: Vec<(usize, f64)> = Vec::new();
        for &p in &file.penetrations {
            if !(0.0..=1.0).contains(&p) {
                return Err(bad(format!("penetrations: {p} is not a fraction in [0, 1]")).into());
            }
            let k = syncroad_control::drive::automated_count(n, p);
            if let Some((_, q)) = counts.iter().find(|(j, _)| *j == k) {
                return Err(bad(format!(
                    "penetrations: {q} and {p} both give {k} of {n} automated vehicles, so the same run twice; give one of them"
                ))
                .into());
            }
            counts.push((k, p));
            for spec in mixed_series(n, k, &p.to_string(), &controllers, &human) {
                if runs.iter().any(|r| r.spec.name == spec.name) {
                    return Err(bad(format!(
                        "penetrations: {p} gives {} again (listed twice)",
                        spec.name
                    ))
                    .into());
                }
                runs.push(RunChoice {
                    spec,
                    penetration: k as f64 / n.max(1) as f64,
                });
            }
        }
    }
    if runs.is_empty() {
        return Err(bad(
            "runs = []: name at least one run (e.g. \"protocol\") or give penetrations",
        )
        .into());
    }
    if backend == Backend::Native {
        if let Some(r) = runs
            .iter()
            .find(|r| LawSpec::of_drive(base, &r.spec).is_none())
        {
            if r.spec.drivers.is_empty() && base.mixed().is_some() {
                return Err(bad(format!(
                    "runs: {} on the base scenario's mixed block, which puts SUMO drivers among the law's vehicles and runs in SUMO only, but backend = \"native\"; use backend \"sumo\", or remove the mixed block and give penetrations",
                    r.spec.name
                ))
                .into());
            }
            return Err(bad(format!(
                "runs: {} has SUMO drivers (or a damper or stochastic humans on a straight road), which run in SUMO, but backend = \"native\"; use backend \"sumo\", or only \"protocol\", dampers and stochastic humans (human-noisy, flow-idm-noise) on a ring",
                r.spec.name
            ))
            .into());
        }
    }
    Ok(runs)
}

/// Fraction of the scenario's vehicles the law or the damper drives in `drive`: as the scenario says
/// when the run does not choose (its `mixed` block puts humans among the law's vehicles).
fn penetration(drive: &Drive, sc: &Scenario) -> f64 {
    let n = sc.vehicles().max(1) as f64;
    if drive.drivers.is_empty() {
        return match sc.mixed() {
            // round(p N) vehicles whatever the seed, which only chooses which.
            Some(m) => m.automated(sc.vehicles(), sc.seed()).len() as f64 / n,
            None => 1.0,
        };
    }
    drive.drivers.iter().filter(|d| d.is_none()).count() as f64 / n
}

/// The metric paths a spec keeps, each a metric of `metrics.json`.
fn metrics_of(file: &SpecFile) -> anyhow::Result<Vec<String>> {
    let metrics = match &file.metrics {
        None => DEFAULT_METRICS.iter().map(|s| s.to_string()).collect(),
        Some(m) => m.clone(),
    };
    let known = crate::sweep::table::metric_kinds();
    for m in &metrics {
        if !known.iter().any(|(p, _)| p == m) {
            let mut near: Vec<&str> = known
                .iter()
                .map(|(p, _)| p.as_str())
                .filter(|p| p.split('.').next() == m.split('.').next())
                .collect();
            if near.is_empty() {
                near = known.iter().map(|(p, _)| p.as_str()).take(12).collect();
            }
            return Err(bad(format!(
                "metrics: {m:?} is not a metric of metrics.json; valid are e.g. {} (`syncroad schema` lists all)",
                near.join(", ")
            ))
            .into());
        }
    }
    if metrics.iter().collect::<BTreeSet<_>>().len() != metrics.len() {
        return Err(bad("metrics: a metric is listed twice").into());
    }
    Ok(metrics)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(json: &str) -> anyhow::Result<Sweep> {
        let raw: Value = serde_json::from_str(json)?;
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
        Sweep::new(raw, &dir, "t".into())
    }

    #[test]
    fn points_are_the_product_with_seeds_fastest() {
        let s = spec(
            r#"{"base": "ring-theorem1.json", "backend": "native",
                "axes": [{"field": "scale.gain", "linspace": [0.5, 1.5, 3]},
                         {"field": "initial.speed_mps", "values": [6, 8]}],
                "seeds": {"first": 10, "count": 2}}"#,
        )
        .unwrap();
        assert_eq!(s.len(), 3 * 2 * 2);
        let p = s.point(7);
        // 7 = ((1·2 + 1)·1 + 0)·2 + 1: gain index 1, speed index 1, seed 11.
        assert_eq!((p.at.clone(), p.run, p.seed), (vec![1, 1], 0, 11));
        assert_eq!(s.axes[0].numbers().unwrap(), vec![0.5, 1.0, 1.5]);
        let sc = s.scenario(&p).unwrap();
        assert_eq!(sc.seed(), 11);
        // Point 5 differs only in its speed axis (6 instead of 8 m/s): same seed, so the same
        // perturbation on top of a 2 m/s higher base speed.
        let slower = s.scenario(&s.point(5)).unwrap();
        for (a, b) in sc
            .initial_speed_mps()
            .iter()
            .zip(slower.initial_speed_mps())
        {
            assert!((a - b - 2.0).abs() < 1e-12, "{a} vs {b}");
        }
        let ids: Vec<usize> = s.points().map(|p| p.id).collect();
        assert_eq!(ids, (0..12).collect::<Vec<_>>());
    }

    #[test]
    fn errors_name_the_axis_and_the_field() {
        let e = spec(
            r#"{"base": "ring-theorem1.json", "axes": [{"field": "initial.speed_mps", "values": [-3]}]}"#,
        )
        .unwrap_err();
        let msg = format!("{e:#}");
        assert!(msg.contains("initial.speed_mps = -3"), "{msg}");
        assert!(
            msg.starts_with("sweep point 0 (initial.speed_mps = -3)"),
            "{msg}"
        );
        let e = spec(
            r#"{"base": "ring-theorem1.json", "axes": [{"field": "model.nope", "values": [1]}]}"#,
        )
        .unwrap_err();
        assert!(format!("{e:#}").contains("nope"), "{e:#}");
        let e = spec(r#"{"base": "ring-theorem1.json", "metrics": ["sync.verdikt"]}"#).unwrap_err();
        assert!(
            e.to_string().contains("\"sync.verdikt\" is not a metric"),
            "{e}"
        );
        assert!(e.to_string().contains("sync.verdict"), "{e}");
        let e = spec(
            r#"{"base": "ring-theorem1.json", "axes": [{"field": "scale.gain", "values": [0]}]}"#,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("axes[scale.gain]: value 0 is not a number > 0"),
            "{e}"
        );
        let e = spec(r#"{"base": "ring-theorem1.json", "backend": "native", "runs": ["idm"]}"#)
            .unwrap_err();
        assert!(e.to_string().contains("backend = \"native\""), "{e}");
        let e =
            spec(r#"{"base": "ring-theorem1.json", "axes": [{"field": "seed", "values": [1]}]}"#)
                .unwrap_err();
        assert!(e.to_string().contains("\"seeds\""), "{e}");
        let e = spec(r#"{"base": "ring-theorem1.json", "timeout_s": 1e20}"#).unwrap_err();
        assert_eq!(
            e.to_string(),
            "timeout_s = 100000000000000000000: must be a number of seconds > 0 and at most 1e9"
        );
        let e =
            spec(r#"{"base": "ring-theorem1.json", "seeds": [9223372036854775808]}"#).unwrap_err();
        assert!(e.to_string().contains("is past 9223372036854775807"), "{e}");
    }
}
