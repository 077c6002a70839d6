//! Every point of a sweep checked before anything runs: each point's scenario is built and
//! validated with its own seed (the seed draws the perturbed gaps), its warm-up and recording
//! stride, and on SUMO its road layout and drivers (the checks a SUMO run makes before it
//! starts), so no point of a sweep that starts can fail on its input.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use sha2::{Digest, Sha256};
use syncroad_control::scenario::Backend;
use syncroad_control::sumo_facts::Emissions;
use syncroad_control::{EvalOptions, LawSpec, Scenario};
use syncroad_sumo::{load_road, Road, WorkerCommand};

use super::points::Point;
use super::spec::Sweep;
use crate::config;
use crate::error::InputError;
use crate::plan::{Measurements, RunPlan};

impl Sweep {
    /// The plan of point `p` on its scenario `sc`: the one the checks validate and the point
    /// runs.
    pub(super) fn plan_point(&self, p: &Point, sc: &Scenario) -> anyhow::Result<RunPlan> {
        let record_every = config::record_every_as("record_every", self.file.record_every, sc)?;
        let mut eval = EvalOptions::of(sc);
        eval.warmup_s = config::warmup_s_as("warmup_s", self.file.warmup_s, sc)?;
        // The certificate costs a tenth of a second and more per point: only when a column
        // holds it.
        eval.gap_certificate = self
            .metrics
            .iter()
            .any(|m| m.starts_with("gap_certificate."));
        let mut plan = RunPlan::new(self.runs[p.run].spec.clone(), record_every, eval);
        plan.timeout = self
            .file
            .timeout_s
            .and_then(|t| Duration::try_from_secs_f64(t).ok());
        // SUMO's own measurements (the record's `sumo` block: flow, time loss, fuel, CO2,
        // braking) only when a column holds them, and of the emission sums only those a
        // column shows: each runs SUMO's emission model for every vehicle and step, a quarter
        // of a small ring's step each. The dynamics, and so every other column, are the same
        // either way.
        let measured = self
            .metrics
            .iter()
            .any(|m| m.starts_with("sumo.") || m == "emission_every");
        if self.backend == Backend::Sumo && measured {
            plan.measure = Some(Measurements {
                emission_every: 1,
                tripinfo: false,
                ssm: false,
                emissions: Emissions::shown_by(self.metrics.iter().map(String::as_str)),
            });
        }
        Ok(plan)
    }

    /// Checks every point as it will run, before anything runs; returns every file the points
    /// read (networks, route, additional and configuration files, the user's controller).
    pub(super) fn check_points(&self) -> anyhow::Result<BTreeSet<PathBuf>> {
        let mut roads: BTreeMap<PathBuf, Arc<Road>> = BTreeMap::new();
        // Each point's scenario (a hash of all it holds) with its run and seed: two points
        // alike are one run under two labels (scale.delay values that round to the same
        // delays on the step grid, …).
        let mut runs_alike: BTreeMap<([u8; 32], usize, u64), String> = BTreeMap::new();
        // The worker is never started: the options only carry the drivers to check.
        let worker = WorkerCommand::binary("syncroad");
        // Every file a SUMO point reads besides its network: route, additional and
        // configuration files are as much the experiment as the net.
        let mut inputs: BTreeSet<PathBuf> = BTreeSet::new();
        for p in self.points() {
            let sc = self.scenario(&p)?;
            let print: [u8; 32] = Sha256::digest(format!("{sc:?}").as_bytes()).into();
            let alike = runs_alike.insert((print, p.run, p.seed), self.describe(&p));
            if let (Some(first), false) = (alike, self.file.allow_alike_points) {
                return Err(InputError::new(format!(
                    "{first} and {} run the same scenario (their axis values give identical runs, e.g. delays that round to the same steps of step_s), so one run would stand in the table twice under two labels; give one of the values, a finer step_s, or \"allow_alike_points\": true",
                    self.describe(&p)
                ))
                .into());
            }
            let here = |e: anyhow::Error| e.context(self.describe(&p));
            let plan = self.plan_point(&p, &sc).map_err(here)?;
            // The user's controllers are as much the experiment as the scenario, on either
            // backend: their sources and pickled states (the vehicles' own, and the inflows').
            let inflows = (0..sc.sumo().inflows().len()).filter_map(|k| sc.sumo().inflow_driver(k));
            for law in sc.controller().into_iter().chain(inflows) {
                let syncroad_control::UserLaw::Python(c) = law else {
                    continue;
                };
                if let syncroad_control::user_law::PythonSource::File { path } = &c.source {
                    inputs.insert(path.clone());
                    // And every module it can import from its folder.
                    inputs.extend(syncroad_control::user_law::folder_sources(path));
                }
                inputs.extend(c.state.clone());
            }
            if self.backend != Backend::Sumo {
                if let Some(why) = sc.native_refusal() {
                    return Err(InputError::new(format!("{}: {why}", self.describe(&p))).into());
                }
                let spec = &self.runs[p.run].spec;
                if LawSpec::of_drive(&sc, spec).is_none() {
                    return Err(InputError::new(format!(
                        "{}: {}; run it with \"backend\": \"sumo\"",
                        self.describe(&p),
                        if sc.mixed().is_some() && spec.drivers.is_empty() {
                            "the scenario's mixed block puts SUMO drivers among the law's vehicles, which the native simulator does not run (a native sweep mixes through its penetrations)".to_string()
                        } else {
                            format!("run {} needs SUMO drivers or a ring", spec.name)
                        }
                    ))
                    .into());
                }
                continue;
            }
            let net = syncroad_sumo::net_path(&sc)
                .map_err(|e| InputError::caused(self.describe(&p), e))?;
            let files = sc.sumo();
            inputs.extend(files.routes().iter().cloned());
            inputs.extend(files.additional().iter().cloned());
            inputs.extend(files.config().map(Path::to_path_buf));
            let road = match roads.get(&net) {
                Some(r) => r.clone(),
                None => {
                    let r = Arc::new(
                        load_road(&sc).map_err(|e| InputError::caused(self.describe(&p), e))?,
                    );
                    roads.insert(net.clone(), r.clone());
                    r
                }
            };
            let o = plan.sumo_options(PathBuf::new(), worker.clone(), None);
            syncroad_sumo::check_run(&sc, &road, &o)
                .map_err(|e| InputError::caused(self.describe(&p), e))?;
        }
        inputs.extend(roads.into_keys());
        Ok(inputs)
    }

    /// `sweep point ID (axis = value, ..., run NAME, seed S)`, for errors.
    pub fn describe(&self, p: &Point) -> String {
        let mut parts: Vec<String> = self
            .axes
            .iter()
            .zip(&p.at)
            .map(|(a, &k)| format!("{} = {}", a.field, a.values[k]))
            .collect();
        parts.push(format!("run {}", self.runs[p.run].spec.name));
        parts.push(format!("seed {}", p.seed));
        format!("sweep point {} ({})", p.id, parts.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn sweep(backend: &str, metrics: &[&str]) -> Sweep {
        let raw = serde_json::json!({
            "base": "sugiyama-ring.json", "backend": backend,
            "axes": [{"field": "model.graph.gain_pred", "values": [0.6]}],
            "metrics": metrics,
        });
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios");
        Sweep::new(raw, &dir, "t".into()).unwrap()
    }

    fn measure(s: &Sweep) -> Option<Measurements> {
        let p = s.point(0);
        let sc = s.scenario(&p).unwrap();
        s.plan_point(&p, &sc).unwrap().measure
    }

    #[test]
    fn sumo_measures_its_own_quantities_only_when_a_column_shows_them() {
        // A verdict or a spread needs only the trajectory: SUMO reads no fuel or CO2.
        let plain = sweep("sumo", &["sync.verdict", "sync.final_spread_mps"]);
        assert!(measure(&plain).is_none());
        // A column of the record's `sumo` block needs them, every step.
        let fuel = sweep("sumo", &["sync.verdict", "sumo.fuel_g_per_km"]);
        let m = measure(&fuel).expect("a sumo.* column measures");
        assert_eq!((m.emission_every, m.tripinfo, m.ssm), (1, false, false));
        // Of the emission sums, only the one the column shows: fuel after the warm-up, not
        // the whole run's fuel nor CO2 (each read runs SUMO's emission model).
        let only_fuel = Emissions {
            fuel: true,
            ..Emissions::NONE
        };
        assert_eq!(m.emissions, only_fuel);
        let co2 = sweep("sumo", &["sumo.co2_g_per_km", "sumo.fuel_total_mg"]);
        let m = measure(&co2).unwrap();
        assert_eq!(
            m.emissions,
            Emissions {
                co2: true,
                fuel_total: true,
                fuel: false
            }
        );
        // Time loss needs SUMO's measurements and no emission model at all.
        let m = measure(&sweep("sumo", &["sumo.time_loss_s"])).unwrap();
        assert_eq!(m.emissions, Emissions::NONE);
        // The native simulator has no SUMO to measure.
        assert!(measure(&sweep("native", &["sync.verdict"])).is_none());
    }
}
