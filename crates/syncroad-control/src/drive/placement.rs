//! Which vehicles of a mixed road the law (or a damper) drives: `k` of `n`, spread evenly or
//! drawn from the scenario's seed. Every mixed run of every command places its automated
//! vehicles through [`Placement::automated`].

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;

/// Where the automated vehicles of a mixed road sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Placement {
    /// Spread evenly around the road: vehicles `⌊j n / k⌋`, j = 0..k, whatever the seed (one
    /// automated vehicle is vehicle 0; two sit half a ring apart).
    Even,
    /// Drawn without replacement from the scenario's seed, so that a sweep over seeds samples
    /// placements; the same seed gives the same choice on every platform.
    #[default]
    Seeded,
}

/// Salt of the placement stream, so that it is independent of the initial perturbation and
/// the drivers' noise drawn from the same seed.
const PLACEMENT_SALT: u64 = 0x6d69_7865_645f_7031; // "mixed_p1"

/// The number of automated vehicles at penetration rate `p` among `n`: `round(p n)` (halves
/// round up), at most `n`.
pub fn automated_count(n: usize, penetration: f64) -> usize {
    ((penetration * n as f64).round() as usize).min(n)
}

impl Placement {
    /// The `k` automated vehicles among `n`, ascending (`k` is capped at `n`). [`Even`]
    /// ignores `seed`; [`Seeded`] draws them by a partial Fisher–Yates shuffle of SplitMix64
    /// draws.
    ///
    /// [`Even`]: Placement::Even
    /// [`Seeded`]: Placement::Seeded
    pub fn automated(self, n: usize, k: usize, seed: u64) -> Vec<usize> {
        let k = k.min(n);
        match self {
            Placement::Even => (0..k).map(|j| j * n / k).collect(),
            Placement::Seeded => {
                let mut rng = SplitMix64::new(seed ^ PLACEMENT_SALT);
                let mut idx: Vec<usize> = (0..n).collect();
                for j in 0..k {
                    let r = j + (rng.next_u64() % (n - j) as u64) as usize;
                    idx.swap(j, r);
                }
                let mut chosen = idx[..k].to_vec();
                chosen.sort_unstable();
                chosen
            }
        }
    }

    /// The name a scenario, a sweep spec or `--placement` takes.
    pub fn name(self) -> &'static str {
        match self {
            Placement::Even => "even",
            Placement::Seeded => "seeded",
        }
    }
}

impl fmt::Display for Placement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Placement {
    type Err = String;

    /// `even` or `seeded`; the error says what is valid.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "even" => Ok(Placement::Even),
            "seeded" => Ok(Placement::Seeded),
            _ => Err(format!(
                "{s:?} is no placement; valid: even (spread evenly), seeded (drawn from the seed)"
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn even_vehicles_are_floor_j_n_over_k() {
        let even = |n, k| Placement::Even.automated(n, k, 7);
        assert_eq!(even(22, 0), Vec::<usize>::new());
        assert_eq!(even(22, 1), [0]);
        assert_eq!(even(22, 2), [0, 11]);
        assert_eq!(even(22, 4), [0, 5, 11, 16]);
        assert_eq!(even(5, 9), [0, 1, 2, 3, 4]);
        // The seed does not move them.
        assert_eq!(Placement::Even.automated(22, 4, 8), even(22, 4));
    }

    #[test]
    fn the_count_is_round_p_n_and_the_seeded_choice_depends_on_the_seed_only() {
        assert_eq!(automated_count(22, 0.5), 11);
        assert_eq!(automated_count(21, 0.5), 11); // 10.5 rounds up
        assert_eq!(automated_count(22, 0.05), 1); // 1.1
        assert_eq!(automated_count(22, 1.0), 22);
        let seeded = |k, seed| Placement::Seeded.automated(22, k, seed);
        assert_eq!(seeded(0, 42), Vec::<usize>::new());
        assert_eq!(seeded(22, 42), (0..22).collect::<Vec<_>>());
        let a = seeded(11, 42);
        assert_eq!(a.len(), 11);
        assert_eq!(a, seeded(11, 42));
        assert_ne!(a, seeded(11, 43));
        assert!(a.windows(2).all(|w| w[0] < w[1]) && a.iter().all(|&i| i < 22));
    }

    #[test]
    fn every_vehicle_is_seeded_about_equally_often() {
        // Over 2000 seeds each of 22 vehicles is chosen with probability 1/2: the count is
        // Binomial(2000, 1/2), mean 1000, sd 22.4; ±150 is more than 6 sd.
        let mut hits = [0usize; 22];
        for seed in 0..2000 {
            for i in Placement::Seeded.automated(22, 11, seed) {
                hits[i] += 1;
            }
        }
        assert!(hits.iter().all(|&h| (850..=1150).contains(&h)), "{hits:?}");
    }

    #[test]
    fn names_parse_back_and_others_say_what_is_valid() {
        for p in [Placement::Even, Placement::Seeded] {
            assert_eq!(p.name().parse::<Placement>(), Ok(p));
            let json = serde_json::to_string(&p).unwrap();
            assert_eq!(json, format!("\"{p}\""));
        }
        assert_eq!(
            "random".parse::<Placement>().unwrap_err(),
            "\"random\" is no placement; valid: even (spread evenly), seeded (drawn from the seed)"
        );
    }
}
