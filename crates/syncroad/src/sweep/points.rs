//! How many points a sweep has, and every point checked before anything runs.
//!
//! The count is the product axes × runs × seeds in checked arithmetic, refused past
//! [`MAX_POINTS`]; every point's scenario is then built and validated with its own seed (the
//! seed draws the perturbed gaps), its warm-up and recording stride, and on SUMO its road
//! layout and drivers (the checks a SUMO run makes before it starts), so no point of a sweep
//! that starts can fail on its input.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Arc;

use syncroad_control::scenario::Backend;
use syncroad_sumo::{load_road, MeasureOptions, Road, RunOptions, WorkerCommand};

use super::axis::Axis;
use super::spec::{Point, SeedsFile, SpecFile, Sweep};
use crate::config;
use crate::error::InputError;

/// The most points one sweep may have (a sweep of more is refused before anything runs; split
/// it into several specs).
pub const MAX_POINTS: usize = 100_000;

/// The number of points of `axes` × `runs` × `seeds`, or an error naming every factor when
/// the product passes [`MAX_POINTS`] (or would overflow).
pub fn count(axes: &[Axis], runs: usize, seeds: usize) -> Result<usize, InputError> {
    let product = axes
        .iter()
        .map(|a| a.values.len())
        .chain([runs, seeds])
        .try_fold(1usize, |acc, n| acc.checked_mul(n));
    match product {
        Some(n) if n <= MAX_POINTS => Ok(n),
        _ => {
            let factors: Vec<String> = axes
                .iter()
                .map(|a| format!("axes[{}]: {}", a.field, a.values.len()))
                .chain([format!("runs: {runs}"), format!("seeds: {seeds}")])
                .collect();
            let total = product.map_or("more than 2^64".to_string(), |n| n.to_string());
            Err(InputError::new(format!(
                "the sweep has {total} points ({}), more than the {MAX_POINTS} a sweep may have; use fewer values, or split it into several specs",
                factors.join(" × ")
            )))
        }
    }
}

/// The seeds `first, first + 1, ...` (`count` of them), refused when the last would pass the
/// largest seed the results table holds (2^63 − 1, an Int64 column).
pub fn seed_range(first: u64, count: u64) -> Result<Vec<u64>, InputError> {
    const LARGEST: u64 = i64::MAX as u64;
    match first.checked_add(count - 1) {
        Some(last) if last <= LARGEST => Ok((first..=last).collect()),
        _ => Err(InputError::new(format!(
            "seeds = {{\"first\": {first}, \"count\": {count}}}: the last seed would pass {LARGEST}, the largest the results table holds; start lower"
        ))),
    }
}

/// The seeds of a spec (default: the base scenario's), each at most 2^63 − 1.
pub fn seeds_of(file: &SpecFile, base_seed: u64) -> anyhow::Result<Vec<u64>> {
    let seeds = match &file.seeds {
        None => vec![base_seed],
        Some(SeedsFile::List(v)) if v.is_empty() => {
            return Err(InputError::new("seeds = []: give at least one seed").into())
        }
        Some(SeedsFile::List(v)) => {
            if let Some(s) = v.iter().find(|&&s| s > i64::MAX as u64) {
                return Err(InputError::new(format!(
                    "seeds: {s} is past {}, the largest seed the results table holds",
                    i64::MAX
                ))
                .into());
            }
            v.clone()
        }
        Some(SeedsFile::Range { first, count }) => {
            if *count == 0 || *count > 100_000 {
                return Err(InputError::new(format!(
                    "seeds.count = {count}: must be between 1 and 100000"
                ))
                .into());
            }
            seed_range(*first, *count)?
        }
    };
    if seeds.iter().collect::<BTreeSet<_>>().len() != seeds.len() {
        return Err(InputError::new(format!("seeds = {seeds:?}: a seed is listed twice")).into());
    }
    Ok(seeds)
}

impl Sweep {
    /// Builds and checks every point as it will run; returns the network files the points
    /// read (SUMO only), which the spec hash covers.
    pub(super) fn check_points(&self) -> anyhow::Result<BTreeSet<PathBuf>> {
        let mut roads: BTreeMap<PathBuf, Arc<Road>> = BTreeMap::new();
        let mut seen = BTreeSet::new();
        // The worker is never started: the options only carry the drivers to check.
        let worker = WorkerCommand::binary("syncroad");
        for p in self.points() {
            let sc = self.scenario(&p)?;
            let here = |e: anyhow::Error| e.context(self.describe(&p));
            if seen.insert((p.at.clone(), p.seed)) {
                config::warmup_s_as("warmup_s", self.file.warmup_s, &sc).map_err(here)?;
                config::record_every_as("record_every", self.file.record_every, &sc)
                    .map_err(here)?;
            }
            if self.backend != Backend::Sumo {
                continue;
            }
            let net = syncroad_sumo::net_path(&sc)
                .map_err(|e| InputError::caused(self.describe(&p), e))?;
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
            let choice = &self.runs[p.run];
            let mut o = RunOptions::new(PathBuf::new(), worker.clone());
            o.drivers = choice.spec.drivers.clone();
            o.damper = choice.spec.damper;
            o.measure = Some(MeasureOptions {
                warmup_s: config::warmup_s_as("warmup_s", self.file.warmup_s, &sc)?,
                emission_every: 1,
                tripinfo: false,
                ssm: false,
            });
            syncroad_sumo::check_run(&sc, &road, &o)
                .map_err(|e| InputError::caused(self.describe(&p), e))?;
        }
        Ok(roads.into_keys().collect())
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
    use super::super::axis::Target;
    use super::*;
    use serde_json::json;

    fn axis(field: &str, n: usize) -> Axis {
        Axis {
            field: field.into(),
            target: Target::GainScale,
            values: vec![json!(1.0); n],
        }
    }

    #[test]
    fn counts_are_checked_and_bounded_naming_every_factor() {
        assert_eq!(count(&[axis("a", 3), axis("b", 4)], 2, 5).unwrap(), 120);
        assert_eq!(count(&[], 1, MAX_POINTS).unwrap(), MAX_POINTS);
        // 65536⁴ = 2^64 wraps to 0 in unchecked arithmetic.
        let four: Vec<Axis> = ["a", "b", "c", "d"]
            .iter()
            .map(|f| axis(f, 65536))
            .collect();
        let e = count(&four, 1, 1).unwrap_err().to_string();
        assert_eq!(
            e,
            "the sweep has more than 2^64 points (axes[a]: 65536 × axes[b]: 65536 × axes[c]: 65536 × axes[d]: 65536 × runs: 1 × seeds: 1), more than the 100000 a sweep may have; use fewer values, or split it into several specs"
        );
        let e = count(&[axis("x", 1000)], 1, 1000).unwrap_err().to_string();
        assert!(
            e.starts_with("the sweep has 1000000 points (axes[x]: 1000 × runs: 1 × seeds: 1000)"),
            "{e}"
        );
    }

    #[test]
    fn seed_ranges_never_wrap_or_pass_the_table() {
        assert_eq!(seed_range(5, 3).unwrap(), vec![5, 6, 7]);
        let top = i64::MAX as u64;
        assert_eq!(seed_range(top, 1).unwrap(), vec![top]);
        for (first, n) in [(top, 2), (u64::MAX, 1), (u64::MAX - 1, 5)] {
            let e = seed_range(first, n).unwrap_err().to_string();
            assert!(
                e.contains("the last seed would pass 9223372036854775807"),
                "{e}"
            );
        }
    }
}
