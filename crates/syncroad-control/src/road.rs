//! The gap rule and what each vehicle sees ahead ([`RingView`]), shared by the native
//! simulator, the SUMO layout, the wave dampers and the safety layer, so that none of them
//! keeps its own geometry (where a scenario's vehicles start is [`crate::start`]).
//!
//! Positions are unwrapped rear-bumper coordinates along the direction of travel; vehicle 0
//! drives in front (behind the leader, when there is one) and each next vehicle follows the
//! one before it. On a closed road (a ring, or a loop through a network) of length `C`,
//! vehicle 0 follows vehicle N−1 one lap ahead.

use crate::sensed::{Neighbors, Sensed};

/// The vehicle each vehicle follows: `i − 1`, and for vehicle 0 vehicle N−1 on a closed road
/// (with the lap `C` to add to its position), or the leader / nobody on an open one (`None`).
pub fn ahead(i: usize, n: usize, loop_length_m: Option<f64>) -> Option<(usize, f64)> {
    if i > 0 {
        Some((i - 1, 0.0))
    } else {
        loop_length_m.map(|c| (n - 1, c))
    }
}

/// Bumper-to-bumper gaps `Δx_i = q_{i−1} − q_i − ℓ_i` into `out`: vehicle 0 behind the
/// leader's rear bumper `front` when there is one, behind vehicle N−1 one lap ahead on a closed
/// road of length `loop_length_m`, and NaN (nobody ahead) otherwise.
pub fn gaps(
    q: &[f64],
    length_m: &[f64],
    front: Option<f64>,
    loop_length_m: Option<f64>,
    out: &mut [f64],
) {
    let n = q.len();
    for i in 0..n {
        out[i] = match (i, front) {
            (0, Some(f)) => f - q[0] - length_m[0],
            _ => match ahead(i, n, loop_length_m) {
                Some((j, lap)) => q[j] + lap - q[i] - length_m[i],
                None => f64::NAN,
            },
        };
    }
}

/// What each vehicle sees, kept between steps by the controllers that need it (wave dampers,
/// stochastic humans, the user's own controller): the gap to the vehicle ahead by [`gaps`]
/// (on a ring vehicle 0 follows vehicle N−1 one lap ahead) and that vehicle's speed. On an
/// open road vehicle 0 has nobody ahead: gap ∞, speed NaN.
#[derive(Debug, Clone)]
pub struct RingView {
    ring_length_m: Option<f64>,
    length_m: Vec<f64>,
    /// Bumper-to-bumper gap of each vehicle \[m\].
    pub gaps_m: Vec<f64>,
    /// Speed of the vehicle each one follows \[m/s\].
    pub leader_speeds_mps: Vec<f64>,
    /// The graph from the simulator this step ([`RingView::sense`]); `None`: the layout's.
    sensed: Option<Neighbors>,
}

impl RingView {
    /// The view of vehicles `length_m` long on a ring of `ring_length_m`.
    pub fn new(ring_length_m: f64, length_m: &[f64]) -> Self {
        Self::on(Some(ring_length_m), length_m)
    }

    /// The view on a ring of `ring_length_m`, or on an open road (`None`).
    pub fn on(ring_length_m: Option<f64>, length_m: &[f64]) -> Self {
        let n = length_m.len();
        Self {
            ring_length_m,
            length_m: length_m.to_vec(),
            gaps_m: vec![0.0; n],
            leader_speeds_mps: vec![0.0; n],
            sensed: None,
        }
    }

    /// Updates the gaps and leader speeds from this step's speeds and unwrapped positions.
    pub fn observe(&mut self, speeds: &[f64], positions: &[f64]) {
        let n = speeds.len();
        let ring = self.ring_length_m;
        gaps(positions, &self.length_m, None, ring, &mut self.gaps_m);
        for i in 0..n {
            match ahead(i, n, ring) {
                Some((j, _)) => self.leader_speeds_mps[i] = speeds[j],
                None => self.nobody_ahead(i),
            }
        }
        if let Some(nb) = &self.sensed {
            for (i, s) in nb.ahead.iter().enumerate() {
                match *s {
                    Sensed::Other { speed_mps, gap_m } => {
                        self.gaps_m[i] = gap_m;
                        self.leader_speeds_mps[i] = speed_mps;
                    }
                    // On a ring the layout predecessor is there (see `sense`).
                    Sensed::Nobody if ring.is_none() => {
                        self.gaps_m[i] = f64::INFINITY;
                        self.leader_speeds_mps[i] = f64::NAN;
                    }
                    Sensed::Nobody | Sensed::Layout => {}
                }
            }
        }
    }

    fn nobody_ahead(&mut self, i: usize) {
        self.gaps_m[i] = f64::INFINITY;
        self.leader_speeds_mps[i] = f64::NAN;
    }

    /// Takes the graph from the simulator for the next [`RingView::observe`]: a vehicle with
    /// another one ahead of it follows that one (its gap and speed). Nobody ahead cannot
    /// happen on a ring whose vehicles keep their lane (the layout predecessor is there); it
    /// keeps the layout's.
    pub fn sense(&mut self, neighbors: &Neighbors) {
        neighbors.keep_in(&mut self.sensed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_follow_the_vehicle_ahead_and_wrap_on_a_loop() {
        // Three 5 m cars on a 100 m ring, rear bumpers at 60, 40, 10.
        let q = [60.0, 40.0, 10.0];
        let l = [5.0; 3];
        let mut g = [0.0; 3];
        gaps(&q, &l, None, Some(100.0), &mut g);
        // Vehicle 0 behind vehicle 2 one lap on: 10 + 100 − 60 − 5; then 60 − 40 − 5 and
        // 40 − 10 − 5.
        assert_eq!(g, [45.0, 15.0, 25.0]);
        gaps(&q, &l, Some(70.0), None, &mut g);
        assert_eq!(g, [5.0, 15.0, 25.0]);
        gaps(&q, &l, None, None, &mut g);
        assert!(g[0].is_nan());
        assert_eq!(ahead(0, 3, Some(100.0)), Some((2, 100.0)));
        assert_eq!(ahead(2, 3, None), Some((1, 0.0)));
        assert_eq!(ahead(0, 3, None), None);
    }

    #[test]
    fn a_ring_view_follows_the_vehicle_sensed_ahead() {
        // The three cars of the test above; a car cuts in 4 m ahead of vehicle 1 at 2 m/s.
        let (q, v) = ([60.0, 40.0, 10.0], [5.0, 6.0, 7.0]);
        let mut view = RingView::new(100.0, &[5.0; 3]);
        let mut nb = Neighbors::layout(3, true);
        view.sense(&nb);
        view.observe(&v, &q);
        assert_eq!(view.gaps_m, [45.0, 15.0, 25.0]);
        assert_eq!(view.leader_speeds_mps, [7.0, 5.0, 6.0]);
        nb.ahead[1] = Sensed::Other {
            speed_mps: 2.0,
            gap_m: 4.0,
        };
        view.sense(&nb);
        view.observe(&v, &q);
        assert_eq!(view.gaps_m, [45.0, 4.0, 25.0]);
        assert_eq!(view.leader_speeds_mps, [7.0, 2.0, 6.0]);
    }

    #[test]
    fn on_an_open_road_the_first_vehicle_has_nobody_ahead() {
        // The three cars of the tests above on a straight road: vehicle 0 leads.
        let (q, v) = ([60.0, 40.0, 10.0], [5.0, 6.0, 7.0]);
        let mut view = RingView::on(None, &[5.0; 3]);
        view.observe(&v, &q);
        assert_eq!(view.gaps_m, [f64::INFINITY, 15.0, 25.0]);
        assert!(view.leader_speeds_mps[0].is_nan());
        assert_eq!(view.leader_speeds_mps[1..], [5.0, 6.0]);
        // Vehicle 1 changed lanes and sees nobody ahead on its new one.
        let mut nb = Neighbors::layout(3, false);
        nb.ahead[1] = Sensed::Nobody;
        view.sense(&nb);
        view.observe(&v, &q);
        assert_eq!(view.gaps_m, [f64::INFINITY, f64::INFINITY, 25.0]);
        assert!(view.leader_speeds_mps[1].is_nan());
    }
}
