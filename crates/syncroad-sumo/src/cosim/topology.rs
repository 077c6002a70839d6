//! The law's graph taken from SUMO each step: when other traffic shares the road (the user's
//! `sumo.routes` or `sumo.additional`), a vehicle the law does not know may change lanes into
//! or out of the controlled lane, or merge into it at a junction, and become the one a
//! controlled vehicle follows.
//!
//! Before each step of the law the vehicles on the road's lanes are read in driving order
//! (`lane.getLastStepVehicleIDs` of each normal and internal lane, each list ordered by
//! position), and for each of syncroad's vehicles the one directly ahead and directly behind
//! is found. Where that is the layout's neighbour the fixed graph holds; where it is another
//! vehicle, its speed (`vehicle.getSpeed`) and the bumper-to-bumper gap (front positions
//! `vehicle.getLanePosition` along the road's lane sequence, its length `vehicle.getLength`)
//! go to the law as [`Sensed::Other`] (see `syncroad_control::sensed`). Each time the vehicle
//! ahead of one of syncroad's vehicles differs from the step before counts as one topology
//! change. (`vehicle.getLeader` was tried first: with libsumo 1.28.0 it returned no leader at
//! some steps on a two-lane loop with nobody else on the road, which would count changes
//! that never happened.)

use std::collections::HashMap;

use indexmap::IndexSet;

use pyo3::prelude::*;
use pyo3::types::{PyString, PyTuple};
use syncroad_control::scenario::SelectorMatch;
use syncroad_control::sensed::{Neighbors, Sensed};

use super::libsumo::Libsumo;
use crate::protocol::Request;
use crate::python::{py_error, PythonError};

/// Who is seen on one side of a vehicle, for counting changes.
#[derive(Debug, Clone, PartialEq)]
enum Who {
    /// One of syncroad's vehicles (its layout index).
    Ours(usize),
    /// Another vehicle (its index among the others met, [`Topology::met`]).
    Other(usize),
    /// Nobody on the road's lanes.
    Nobody,
}

/// A place in the road's order: one of syncroad's vehicles (its layout index) or another
/// (its index among the others met, [`Topology::met`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    Ours(usize),
    Other(usize),
}

/// What is known of another vehicle once met.
#[derive(Debug, Clone, Copy, Default)]
struct Met {
    /// The read of the road's order it was last listed in (a vehicle listed on two lanes
    /// keeps its first place).
    listed: u64,
    /// Its length, asked once \[m\].
    length_m: Option<f64>,
    /// Its vehicle type was looked up for `sumo.controlled`'s selection.
    typed: bool,
}

/// The vehicles along the road, read each step, and the graph they give.
pub(crate) struct Topology<'py> {
    /// The road's lanes in driving order, with where each starts along the road \[m\].
    lanes: Vec<(String, f64)>,
    /// The same lane ids as Python strings, made once.
    lane_args: Vec<Bound<'py, PyTuple>>,
    /// `lane.getLastStepVehicleIDs`, looked up once.
    lane_vehicles: Bound<'py, PyAny>,
    /// The road's length \[m\] (a closed road wraps).
    length_m: f64,
    ring: bool,
    /// syncroad's vehicles: id → layout index.
    ours: HashMap<String, usize>,
    /// Their ids by layout index.
    our_ids: Vec<String>,
    /// Their lengths \[m\].
    our_length_m: Vec<f64>,
    /// The others met so far, each given an index the first time it is listed (an open road
    /// meets thousands; a lookup per listed vehicle and step, no copy of its id after the
    /// first).
    met: IndexSet<String>,
    /// What is known of each, by that index.
    met_facts: Vec<Met>,
    /// Reads of the road's order so far.
    reads: u64,
    /// The vehicle seen ahead of each of ours at the step before.
    seen_ahead: Vec<Who>,
    /// This step's road order: (who, lane index).
    order: Vec<(Slot, usize)>,
    /// The others on the road this step, in road order (their indices).
    others: Vec<usize>,
    /// Place in `order` of each of ours.
    our_place: Vec<Option<usize>>,
    /// The order was read at the current state (by [`Topology::gaps_ahead`] after a step):
    /// the next [`Topology::sense`], at the same state, uses it instead of reading it again.
    order_current: bool,
    /// What the law gets this step.
    pub neighbors: Neighbors,
    /// Changes of the vehicle ahead counted so far.
    pub changes: usize,
    /// `sumo.controlled`'s selection, when the law drives the user's own vehicles.
    chosen: Option<SelectorMatch>,
    /// Vehicles the selection chooses that came onto the road after the start (SUMO drives
    /// them, by their own vehicle type).
    pub chosen_later: usize,
}

impl<'py> Topology<'py> {
    /// The topology of the request's road, starting from the layout's order (vehicle i behind
    /// i − 1, vehicle 0 behind N − 1 on a loop).
    pub fn new(ls: &Libsumo<'py>, req: &Request) -> Result<Self, PythonError> {
        let py = ls.py;
        let v = &req.layout.vehicles;
        let n = v.len();
        let ring = req.layout.road.ring;
        let neighbors = Neighbors::layout(n, ring);
        let seen_ahead = (0..n)
            .map(|i| neighbors.layout_ahead(i).map_or(Who::Nobody, Who::Ours))
            .collect();
        let mut start = 0.0;
        let lanes: Vec<(String, f64)> = req
            .layout
            .road
            .segments
            .iter()
            .map(|s| {
                let at = start;
                start += s.length_m;
                (s.lane.clone(), at)
            })
            .collect();
        let lane_args = lanes
            .iter()
            .map(|(l, _): &(String, f64)| PyTuple::new(py, [PyString::intern(py, l)]))
            .collect::<PyResult<_>>()
            .map_err(|e| py_error(py, "argument tuples", e))?;
        let lane_vehicles = ls
            .native
            .getattr("lane_getLastStepVehicleIDs")
            .map_err(|e| py_error(py, "_libsumo.lane_getLastStepVehicleIDs", e))?;
        Ok(Self {
            lanes,
            lane_args,
            lane_vehicles,
            length_m: start,
            ring,
            ours: v
                .iter()
                .enumerate()
                .map(|(i, d)| (d.id.clone(), i))
                .collect(),
            our_ids: v.iter().map(|d| d.id.clone()).collect(),
            our_place: vec![None; n],
            our_length_m: v.iter().map(|d| d.length_m).collect(),
            met: IndexSet::new(),
            met_facts: Vec::new(),
            reads: 0,
            seen_ahead,
            order: Vec::new(),
            others: Vec::new(),
            neighbors,
            changes: 0,
            order_current: false,
            chosen: req.adopt.as_ref().and_then(|s| s.matcher().ok()),
            chosen_later: 0,
        })
    }

    /// Reads the road's order from SUMO and fills [`Topology::neighbors`]; counts the changes
    /// of the vehicles ahead.
    pub fn sense(&mut self, py: Python<'_>, ls: &Libsumo<'_>) -> Result<(), PythonError> {
        if self.idle() {
            return Ok(());
        }
        if !std::mem::take(&mut self.order_current) {
            self.read_order(py)?;
        }
        if let Some(m) = &self.chosen {
            for &x in &self.others {
                if !std::mem::replace(&mut self.met_facts[x].typed, true) {
                    let id = &self.met[x];
                    let t: String = ls
                        .call("vehicle_getTypeID", (id.as_str(),))?
                        .extract()
                        .map_err(|e| py_error(py, format!("vehicle.getTypeID({id})"), e))?;
                    self.chosen_later += usize::from(m.matches(id, &t));
                }
            }
        }
        let n = self.neighbors.len();
        for i in 0..n {
            // A vehicle of ours not on the road's lanes (lost: the step reports it) keeps the
            // layout's neighbours.
            let Some(k) = self.our_place[i] else {
                self.neighbors.ahead[i] = Sensed::Layout;
                self.neighbors.behind[i] = Sensed::Layout;
                continue;
            };
            let ahead = self.at(k, true);
            let behind = self.at(k, false);
            let who = self.who(ahead);
            if self.neighbors.layout_ahead(i).is_some() && who != self.seen_ahead[i] {
                self.changes += 1;
            }
            self.seen_ahead[i] = who;
            self.neighbors.ahead[i] = self.sensed(py, ls, i, k, ahead, true)?;
            self.neighbors.behind[i] = self.sensed(py, ls, i, k, behind, false)?;
        }
        Ok(())
    }

    /// Each of syncroad's vehicles' bumper-to-bumper gap to whoever is directly ahead on the
    /// road's lanes now (one of ours or another), from SUMO's positions: what the record's
    /// gaps must be when other traffic shares the road, where the layout's predecessor may not
    /// be the vehicle ahead. NaN where nobody is ahead or the vehicle is not on the road's
    /// lanes. Reads the order of this state, which the law's next [`Topology::sense`] uses.
    pub fn gaps_ahead(
        &mut self,
        py: Python<'_>,
        ls: &Libsumo<'_>,
        gaps: &mut [f64],
    ) -> Result<(), PythonError> {
        if self.idle() {
            return Ok(());
        }
        self.read_order(py)?;
        self.order_current = true;
        // Each place's front bumper, asked of SUMO once (most are both a follower and ahead).
        let mut fronts: Vec<Option<f64>> = vec![None; self.order.len()];
        let mut front = |this: &Self, p: usize| -> Result<f64, PythonError> {
            match fronts[p] {
                Some(x) => Ok(x),
                None => {
                    let x = this.front(py, ls, p)?;
                    fronts[p] = Some(x);
                    Ok(x)
                }
            }
        };
        for (i, gap) in gaps.iter_mut().enumerate() {
            *gap = f64::NAN;
            let Some(k) = self.our_place.get(i).copied().flatten() else {
                continue;
            };
            let Some(p) = self.at(k, true) else {
                continue;
            };
            let mut d = front(self, p)? - front(self, k)?;
            if self.ring && d < 0.0 {
                d += self.length_m;
            }
            *gap = d - self.length(py, ls, p)?;
        }
        Ok(())
    }

    /// Nothing to read: none of syncroad's own vehicles (an open road of inflows only) and no
    /// selection of the user's vehicles to count. Reading the road's order each step would
    /// then only cost a list of every vehicle on every lane, through Python, per step.
    fn idle(&self) -> bool {
        self.our_ids.is_empty() && self.chosen.is_none()
    }

    /// The place ahead of (or behind) place `k` in the road order; a closed road wraps.
    fn at(&self, k: usize, ahead: bool) -> Option<usize> {
        let m = self.order.len();
        match (ahead, k) {
            (true, k) if k + 1 < m => Some(k + 1),
            (true, _) if self.ring && m > 1 => Some(0),
            (false, k) if k > 0 => Some(k - 1),
            (false, _) if self.ring && m > 1 => Some(m - 1),
            _ => None,
        }
    }

    fn who(&self, place: Option<usize>) -> Who {
        match place.map(|p| self.order[p].0) {
            None => Who::Nobody,
            Some(Slot::Ours(j)) => Who::Ours(j),
            Some(Slot::Other(x)) => Who::Other(x),
        }
    }

    /// The id of the vehicle at place `p`.
    fn id(&self, p: usize) -> &str {
        match self.order[p].0 {
            Slot::Ours(j) => &self.our_ids[j],
            Slot::Other(x) => &self.met[x],
        }
    }

    /// What vehicle `i` (at place `k`) senses on one side, the vehicle at place `other`.
    fn sensed(
        &mut self,
        py: Python<'_>,
        ls: &Libsumo<'_>,
        i: usize,
        k: usize,
        other: Option<usize>,
        ahead: bool,
    ) -> Result<Sensed, PythonError> {
        let layout = if ahead {
            self.neighbors.layout_ahead(i)
        } else {
            self.neighbors.layout_behind(i)
        };
        let Some(p) = other else {
            return Ok(Sensed::Nobody);
        };
        if let Slot::Ours(j) = self.order[p].0 {
            if Some(j) == layout {
                return Ok(Sensed::Layout);
            }
        }
        let id = self.id(p).to_string();
        let speed_mps: f64 = ls
            .call("vehicle_getSpeed", (id.as_str(),))?
            .extract()
            .map_err(|e| py_error(py, format!("vehicle.getSpeed({id})"), e))?;
        let front_other = self.front(py, ls, p)?;
        let front_ours = self.front(py, ls, k)?;
        // From the rear bumper of the one in front to the front of the one behind.
        let (front, back, front_length_m) = if ahead {
            (front_other, front_ours, self.length(py, ls, p)?)
        } else {
            (front_ours, front_other, self.our_length_m[i])
        };
        let mut d = front - back;
        if self.ring && d < 0.0 {
            d += self.length_m;
        }
        Ok(Sensed::Other {
            speed_mps,
            gap_m: d - front_length_m,
        })
    }

    /// The front bumper of the vehicle at place `p` along the road \[m\].
    fn front(&self, py: Python<'_>, ls: &Libsumo<'_>, p: usize) -> Result<f64, PythonError> {
        let (id, lane) = (self.id(p), self.order[p].1);
        let pos: f64 = ls
            .call("vehicle_getLanePosition", (id,))?
            .extract()
            .map_err(|e| py_error(py, format!("vehicle.getLanePosition({id})"), e))?;
        Ok(self.lanes[lane].1 + pos)
    }

    /// The length of the vehicle at place `p` \[m\] (asked once per vehicle).
    fn length(&mut self, py: Python<'_>, ls: &Libsumo<'_>, p: usize) -> Result<f64, PythonError> {
        let x = match self.order[p].0 {
            Slot::Ours(j) => return Ok(self.our_length_m[j]),
            Slot::Other(x) => x,
        };
        if let Some(l) = self.met_facts[x].length_m {
            return Ok(l);
        }
        let id = self.met[x].as_str();
        let l: f64 = ls
            .call("vehicle_getLength", (id,))?
            .extract()
            .map_err(|e| py_error(py, format!("vehicle.getLength({id})"), e))?;
        self.met_facts[x].length_m = Some(l);
        Ok(l)
    }

    /// The vehicles on the road's lanes in driving order (one call per lane; ids looked up as
    /// borrowed text, an other's copied only the first time it is listed).
    fn read_order(&mut self, py: Python<'_>) -> Result<(), PythonError> {
        self.order.clear();
        self.others.clear();
        self.our_place.fill(None);
        self.reads += 1;
        for (k, args) in self.lane_args.iter().enumerate() {
            let err = |e| {
                py_error(
                    py,
                    format!("lane.getLastStepVehicleIDs({})", self.lanes[k].0),
                    e,
                )
            };
            let ids = self.lane_vehicles.call1(args).map_err(err)?;
            for item in ids.try_iter().map_err(err)? {
                let item = item.map_err(err)?;
                let id = item.cast::<PyString>().map_err(|e| err(e.into()))?;
                // Borrowed text, except under the stable ABI of the Python package's build.
                let id = id.to_cow().map_err(err)?;
                let id: &str = &id;
                // A vehicle listed on two lanes keeps its first place.
                let slot = match self.ours.get(id) {
                    Some(&j) if self.our_place[j].is_none() => {
                        self.our_place[j] = Some(self.order.len());
                        Slot::Ours(j)
                    }
                    Some(_) => continue,
                    None => {
                        let x = self.met.get_index_of(id).unwrap_or_else(|| {
                            self.met_facts.push(Met::default());
                            self.met.insert_full(id.to_string()).0
                        });
                        let listed = &mut self.met_facts[x].listed;
                        if std::mem::replace(listed, self.reads) == self.reads {
                            continue;
                        }
                        self.others.push(x);
                        Slot::Other(x)
                    }
                };
                self.order.push((slot, k));
            }
        }
        Ok(())
    }
}
