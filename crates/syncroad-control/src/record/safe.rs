//! Whether a run was safe, and why not: a run in which vehicles collided, overlapped, were
//! teleported by SUMO or braked in an emergency counts as unsafe wherever it appears (the
//! verdict lines, `compare`, sweep and `collect` tables), so that no efficiency figure of an
//! unsafe run passes for a safe one.

use crate::outcome::RunOutput;
use crate::sumo_facts::SumoFacts;

/// `Some(reasons)`: what made the run unsafe, one line each (empty when it was safe); `None`
/// when nothing measured it (a SUMO run whose counters never arrived).
///
/// * SUMO's counters over the whole run: collision steps, teleports, emergency braking;
/// * the native simulator's overlaps (a gap below zero) and reversing vehicles, every step;
/// * the recorded gaps of every backend: a bumper-to-bumper gap below zero.
pub fn unsafe_reasons(run: &RunOutput, facts: Option<&SumoFacts>) -> Option<Vec<String>> {
    let mut why = Vec::new();
    if let Some(f) = facts {
        let s = f.safety.as_ref()?;
        // Emergency braking at the start answers the shared start, not the driver: apart.
        for (count, what) in [
            (s.collision_steps, "collision steps"),
            (s.teleports, "teleports"),
            (
                s.own_emergency_braking_warnings(),
                "emergency braking warnings after the start",
            ),
        ] {
            if count > 0 {
                why.push(format!("{count} {what} (SUMO)"));
            }
        }
    }
    if let Some(c) = &run.collisions {
        if c.overlap_steps > 0 {
            why.push(format!(
                "vehicles overlapped in {} steps (gap down to {:.2} m)",
                c.overlap_steps, c.min_gap_m
            ));
        }
        if c.reversing_steps > 0 {
            why.push(format!(
                "vehicles drove backwards in {} steps (down to {:.2} m/s)",
                c.reversing_steps, c.min_speed_mps
            ));
        }
    }
    let min_gap = run
        .trajectory
        .gaps_m
        .iter()
        .copied()
        .filter(|g| !g.is_nan())
        .fold(f64::INFINITY, f64::min);
    if min_gap < 0.0 && run.collisions.as_ref().is_none_or(|c| c.overlap_steps == 0) {
        why.push(format!("minimum recorded gap {min_gap:.2} m"));
    }
    Some(why)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collisions::Collisions;
    use crate::stop::StopReason;
    use crate::sumo_facts::Safety;
    use crate::trajectory::Trajectory;

    fn run(gaps: &[f64]) -> RunOutput {
        let mut t = Trajectory::new(gaps.len());
        let v = vec![5.0; gaps.len()];
        let q: Vec<f64> = (0..gaps.len()).map(|i| -10.0 * i as f64).collect();
        t.push(0.0, &v, &q, gaps, None);
        RunOutput {
            trajectory: t,
            stop: StopReason::Horizon,
            ring_length_m: None,
            sumo: None,
            spread: None,
            collisions: None,
            drivers: None,
            safety_layer: None,
        }
    }

    #[test]
    fn each_unsafe_event_is_named_and_a_clean_run_is_safe() {
        assert_eq!(unsafe_reasons(&run(&[f64::NAN, 5.0]), None), Some(vec![]));
        // A recorded overlap on any backend.
        assert_eq!(
            unsafe_reasons(&run(&[f64::NAN, -1.804]), None),
            Some(vec!["minimum recorded gap -1.80 m".to_string()])
        );
        // The native simulator's own counts replace the recorded gap's line.
        let mut r = run(&[f64::NAN, -1.0]);
        let mut c = Collisions::default();
        c.observe(0.1, &[f64::NAN, -1.0], &[3.0, 3.0]);
        r.collisions = Some(c);
        assert_eq!(
            unsafe_reasons(&r, None),
            Some(vec![
                "vehicles overlapped in 1 steps (gap down to -1.00 m)".to_string()
            ])
        );
        // SUMO's counters; none at all: unknown.
        let mut f = SumoFacts::default();
        assert_eq!(unsafe_reasons(&run(&[5.0]), Some(&f)), None);
        f.safety = Some(Safety {
            collision_steps: 304,
            emergency_braking_warnings: 5,
            start_emergency_braking_warnings: 3,
            ..Safety::default()
        });
        assert_eq!(
            unsafe_reasons(&run(&[5.0]), Some(&f)),
            Some(vec![
                "304 collision steps (SUMO)".to_string(),
                "2 emergency braking warnings after the start (SUMO)".to_string()
            ])
        );
        // Emergency braking at the shared start alone is no reason.
        f.safety = Some(Safety {
            emergency_braking_warnings: 7,
            start_emergency_braking_warnings: 7,
            ..Safety::default()
        });
        assert_eq!(unsafe_reasons(&run(&[5.0]), Some(&f)), Some(vec![]));
    }
}
