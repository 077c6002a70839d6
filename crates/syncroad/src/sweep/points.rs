//! A sweep's points: how many there are (the product axes × runs × seeds in checked
//! arithmetic, refused past [`MAX_POINTS`]), their seeds, one point, and a shard's share.

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

use super::axis::Axis;
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
pub fn seeds_of(seeds: Option<&SeedsFile>, base_seed: u64) -> anyhow::Result<Vec<u64>> {
    let seeds = match seeds {
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

/// Seeds as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(untagged)]
pub enum SeedsFile {
    /// Explicit seeds.
    List(Vec<u64>),
    /// `count` seeds from `first` on.
    Range {
        /// First seed.
        first: u64,
        /// How many.
        count: u64,
    },
}

/// One point of the sweep.
#[derive(Debug, Clone)]
pub struct Point {
    /// Its number in the product order.
    pub id: usize,
    /// Value index per axis.
    pub at: Vec<usize>,
    /// Run index.
    pub run: usize,
    /// Seed.
    pub seed: u64,
}

/// A deterministic share of the points: those with `id % count == index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 0-based.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// Parses `I/N` with 0 ≤ I < N.
    pub fn parse(s: &str) -> Result<Self, InputError> {
        let bad = || {
            InputError::new(format!(
                "--shard = {s:?}: expected I/N with 0 ≤ I < N, e.g. 0/4 (Slurm: $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT)"
            ))
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = i.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }

    /// The whole sweep.
    pub fn all() -> Self {
        Self { index: 0, count: 1 }
    }

    /// Whether point `id` belongs to this shard.
    pub fn holds(&self, id: usize) -> bool {
        id % self.count == self.index
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
