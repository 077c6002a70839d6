//! What the native simulator sees that SUMO would not let pass: vehicles that **overlap**
//! (a bumper-to-bumper gap below zero, a collision in SUMO) and vehicles that **reverse** (a
//! speed below zero, which SUMO never drives: it clamps the command to 0).
//!
//! The native simulator integrates the law's speeds whatever they are, so a law that brakes
//! too late drives vehicles through each other with a spread that may still decay. Every
//! step is observed (not only the recorded samples), and the verdict says what happened:
//! overlapping vehicles are at best "not synchronized", as a SUMO run with collisions is;
//! reversing ones at best "inconclusive", as a SUMO run whose negative commands were sent as 0.

use crate::metrics::Verdict;

/// The first time something happened: when, to which vehicle, and the value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstSeen {
    /// Time \[s\].
    pub time_s: f64,
    /// Vehicle index (0 = the first controlled vehicle).
    pub vehicle: usize,
    /// The gap \[m\] or the speed \[m/s\] then.
    pub value: f64,
}

/// Overlaps and reversals of a native run, observed at every step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Collisions {
    /// Steps with at least one gap below zero.
    pub overlap_steps: usize,
    /// The first overlap.
    pub first_overlap: Option<FirstSeen>,
    /// The most negative gap \[m\] (0 when none is negative).
    pub min_gap_m: f64,
    /// Steps with at least one speed below zero.
    pub reversing_steps: usize,
    /// The first reversal.
    pub first_reversing: Option<FirstSeen>,
    /// The most negative speed \[m/s\] (0 when none is negative).
    pub min_speed_mps: f64,
}

impl Collisions {
    /// Observes the gaps and speeds of the controlled vehicles at time `t` (a NaN gap, where
    /// no vehicle is ahead, is skipped).
    pub fn observe(&mut self, t: f64, gaps_m: &[f64], speeds_mps: &[f64]) {
        let mut overlap = false;
        for (i, &g) in gaps_m.iter().enumerate() {
            if g < 0.0 {
                overlap = true;
                self.min_gap_m = self.min_gap_m.min(g);
                self.first_overlap.get_or_insert(FirstSeen {
                    time_s: t,
                    vehicle: i,
                    value: g,
                });
            }
        }
        self.overlap_steps += usize::from(overlap);
        let mut reversing = false;
        for (i, &v) in speeds_mps.iter().enumerate() {
            if v < 0.0 {
                reversing = true;
                self.min_speed_mps = self.min_speed_mps.min(v);
                self.first_reversing.get_or_insert(FirstSeen {
                    time_s: t,
                    vehicle: i,
                    value: v,
                });
            }
        }
        self.reversing_steps += usize::from(reversing);
    }

    /// The best verdict each finding leaves, with its reason (empty: nothing happened).
    pub fn overruled(&self) -> Vec<(Verdict, String)> {
        let mut out = Vec::new();
        if let Some(f) = self.first_overlap {
            out.push((
                Verdict::NotSynchronized,
                format!(
                    "vehicles overlapped in {} steps (gap down to {:.3} m; first vehicle {} at t = {:.3} s, gap {:.3} m): a collision, which SUMO reports as one",
                    self.overlap_steps, self.min_gap_m, f.vehicle, f.time_s, f.value
                ),
            ));
        }
        if let Some(f) = self.first_reversing {
            out.push((
                Verdict::Inconclusive,
                format!(
                    "vehicles drove backwards in {} steps (speed down to {:.3} m/s; first vehicle {} at t = {:.3} s, {:.3} m/s), which SUMO never drives",
                    self.reversing_steps, self.min_speed_mps, f.vehicle, f.time_s, f.value
                ),
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlaps_and_reversals_are_counted_per_step_with_the_first_and_the_worst() {
        let mut c = Collisions::default();
        c.observe(0.0, &[f64::NAN, 2.0, 1.0], &[3.0, 3.0, 3.0]);
        assert!(c.overruled().is_empty());
        c.observe(0.1, &[f64::NAN, -0.5, -1.0], &[3.0, -0.2, 3.0]);
        c.observe(0.2, &[f64::NAN, -2.0, 1.0], &[3.0, 0.0, 3.0]);
        assert_eq!(c.overlap_steps, 2);
        assert_eq!(c.min_gap_m, -2.0);
        assert_eq!(
            c.first_overlap,
            Some(FirstSeen {
                time_s: 0.1,
                vehicle: 1,
                value: -0.5
            })
        );
        assert_eq!((c.reversing_steps, c.min_speed_mps), (1, -0.2));
        let v = c.overruled();
        assert_eq!(v[0].0, Verdict::NotSynchronized);
        assert_eq!(
            v[0].1,
            "vehicles overlapped in 2 steps (gap down to -2.000 m; first vehicle 1 at t = 0.100 s, gap -0.500 m): a collision, which SUMO reports as one"
        );
        assert_eq!(v[1].0, Verdict::Inconclusive);
        assert!(
            v[1].1.starts_with("vehicles drove backwards in 1 steps"),
            "{}",
            v[1].1
        );
    }
}
