//! The law's graph taken from the simulator: who is directly ahead of and behind each vehicle
//! on its lane, at one step.
//!
//! A scenario's graph names vehicles by their place in the layout: vehicle i follows i − 1
//! (vehicle 0 follows N − 1 on a closed road, or the leader on an open one). When other
//! traffic shares the road, a vehicle the law does not know may change lanes, or merge, into
//! the gap between two controlled vehicles, and the one a driver sees ahead is no longer its
//! layout predecessor. The SUMO loop then fills [`Neighbors`] each step from SUMO's lanes and
//! hands it to the law ([`crate::SpeedController::sense`]) before the law's step:
//!
//! * an edge of the graph from vehicle i to its layout predecessor (what i senses ahead) points
//!   at whoever is ahead of i now: the layout predecessor ([`Sensed::Layout`]), another vehicle
//!   whose speed and gap SUMO reports ([`Sensed::Other`]), or nobody ([`Sensed::Nobody`], the
//!   term drops);
//! * an edge to the layout follower (the bidirectional laws' look behind) likewise points at
//!   whoever is behind i now;
//! * every other edge (a link to a vehicle further away, which a driver cannot see but a
//!   radio can) keeps pointing at the same vehicle.
//!
//! With [`Sensed::Layout`] everywhere each law computes exactly what it computes on its fixed
//! graph (the same terms in the same order), so a run where nobody changes lanes is the fixed
//! graph's run bit for bit.

/// What a vehicle sees on one side, on its lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sensed {
    /// The vehicle the layout puts there (the fixed graph holds on this side).
    Layout,
    /// A vehicle the law does not drive or know: its speed and the bumper-to-bumper gap
    /// between the two.
    Other {
        /// Its speed \[m/s\].
        speed_mps: f64,
        /// The gap \[m\]: from the other's rear bumper to this vehicle's front when it is
        /// ahead, from this vehicle's rear to its front when it is behind.
        gap_m: f64,
    },
    /// Nobody on the road's lanes on that side.
    Nobody,
}

/// Who is ahead of and behind each vehicle on the road (the law's vehicles, indexed as the
/// speeds a [`crate::SpeedController`] steps, the leader vehicle first when there is one).
#[derive(Debug, Clone, PartialEq)]
pub struct Neighbors {
    /// A closed road: vehicle 0's layout predecessor is vehicle N − 1.
    pub ring: bool,
    /// Ahead of each vehicle.
    pub ahead: Vec<Sensed>,
    /// Behind each vehicle.
    pub behind: Vec<Sensed>,
}

impl Neighbors {
    /// Everyone where the layout put them: `n` vehicles, on a closed road when `ring`.
    pub fn layout(n: usize, ring: bool) -> Self {
        Self {
            ring,
            ahead: vec![Sensed::Layout; n],
            behind: vec![Sensed::Layout; n],
        }
    }

    /// Number of vehicles.
    pub fn len(&self) -> usize {
        self.ahead.len()
    }

    /// No vehicles.
    pub fn is_empty(&self) -> bool {
        self.ahead.is_empty()
    }

    /// Copies `self` into `slot`, reusing what the slot holds (a controller keeps this step's
    /// neighbours until its next step).
    pub fn keep_in(&self, slot: &mut Option<Neighbors>) {
        match slot {
            Some(nb) => nb.clone_from(self),
            None => *slot = Some(self.clone()),
        }
    }

    /// Every vehicle sees its layout neighbours (the fixed graph holds this step).
    pub fn is_layout(&self) -> bool {
        self.ahead
            .iter()
            .chain(&self.behind)
            .all(|s| *s == Sensed::Layout)
    }

    /// The layout predecessor of vehicle `i`: i − 1, vehicle N − 1 for vehicle 0 on a closed
    /// road, nobody for vehicle 0 on an open one.
    /// (The rule of `road::ahead`, which reads this module's types: kept apart to keep the
    /// two files out of a circle.)
    pub fn layout_ahead(&self, i: usize) -> Option<usize> {
        match i {
            0 if self.ring => self.len().checked_sub(1),
            0 => None,
            _ => Some(i - 1),
        }
    }

    /// The layout follower of vehicle `i`: i + 1, vehicle 0 for vehicle N − 1 on a closed road.
    pub fn layout_behind(&self, i: usize) -> Option<usize> {
        let n = self.len();
        match i + 1 {
            j if j < n => Some(j),
            _ if self.ring && n > 1 => Some(0),
            _ => None,
        }
    }

    /// Where the edge from vehicle `i` to vehicle `j` points this step: [`Sensed::Layout`]
    /// when it still points at `j` (a link past the neighbours always does).
    pub fn edge(&self, i: usize, j: usize) -> Sensed {
        if self.layout_ahead(i) == Some(j) {
            self.ahead[i]
        } else if self.layout_behind(i) == Some(j) {
            self.behind[i]
        } else {
            Sensed::Layout
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_to_the_neighbours_follow_what_is_sensed_and_links_further_away_do_not() {
        let mut nb = Neighbors::layout(4, true);
        assert!(nb.is_layout());
        assert_eq!(nb.layout_ahead(0), Some(3));
        assert_eq!(nb.layout_behind(3), Some(0));
        let other = Sensed::Other {
            speed_mps: 3.0,
            gap_m: 7.0,
        };
        nb.ahead[2] = other;
        nb.behind[1] = Sensed::Nobody;
        assert!(!nb.is_layout());
        assert_eq!(nb.edge(2, 1), other);
        assert_eq!(nb.edge(1, 2), Sensed::Nobody);
        // Vehicle 2 looks ahead at vehicle 0 over the radio: still vehicle 0.
        assert_eq!(nb.edge(2, 0), Sensed::Layout);
        assert_eq!(nb.edge(3, 2), Sensed::Layout);
        // An open road: vehicle 0 has no layout predecessor, the last no follower.
        let open = Neighbors::layout(3, false);
        assert_eq!(open.layout_ahead(0), None);
        assert_eq!(open.layout_behind(2), None);
    }
}
