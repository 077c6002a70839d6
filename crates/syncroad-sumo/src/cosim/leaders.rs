//! Watching the law's graph in SUMO: when other traffic shares a road of several lanes, a
//! vehicle may change lanes into or out of the controlled lane and become the one a controlled
//! vehicle follows. Every [`LEADER_CHECK_EVERY`] steps the vehicles on the road's lanes are
//! read in driving order (`lane.getLastStepVehicleIDs` of each normal and internal lane, each
//! list ordered by position); each time the vehicle ahead of a controlled vehicle differs from
//! the one seen at the check before counts as one topology change. (`vehicle.getLeader` was
//! tried first: with libsumo 1.28.0 it returned no leader at some checks on a two-lane loop
//! with nobody else on the road, which would count changes that never happened.) The law keeps its fixed graph (a graph taken from SUMO each step is
//! not built), so the record says how often it no longer matched SUMO.

use std::collections::HashMap;

use pyo3::prelude::*;

use super::libsumo::Libsumo;
use crate::protocol::Request;
use crate::python::{py_error, PythonError};

/// Steps between two checks of the vehicles ahead.
pub const LEADER_CHECK_EVERY: usize = 10;

/// The vehicle ahead of each controlled vehicle, as last seen.
pub(crate) struct LeaderWatch {
    /// (vehicle id, id of the vehicle seen ahead) per watched vehicle.
    seen: Vec<(String, Option<String>)>,
    /// The road's lanes in driving order.
    lanes: Vec<String>,
    /// A closed road: the first vehicle follows the last.
    ring: bool,
    /// Changes counted so far.
    pub changes: usize,
}

impl LeaderWatch {
    /// A watch of every vehicle that follows another in the layout, starting from the order
    /// the layout placed them in (vehicle i behind i − 1, vehicle 0 behind N − 1 on a loop).
    pub fn new(req: &Request) -> Self {
        let v = &req.layout.vehicles;
        let n = v.len();
        let ring = req.layout.road.ring;
        let seen = (0..n)
            .filter_map(|i| {
                let ahead = match i {
                    0 if ring => n - 1,
                    0 => return None,
                    _ => i - 1,
                };
                Some((v[i].id.clone(), Some(v[ahead].id.clone())))
            })
            .collect();
        Self {
            seen,
            lanes: req
                .layout
                .road
                .segments
                .iter()
                .map(|s| s.lane.clone())
                .collect(),
            ring,
            changes: 0,
        }
    }

    /// Reads the vehicles along the road and counts the changes of the vehicles ahead.
    pub fn check(&mut self, py: Python<'_>, ls: &Libsumo<'_>) -> Result<(), PythonError> {
        let mut order: Vec<String> = Vec::new();
        for lane in &self.lanes {
            let ids: Vec<String> = ls
                .call("lane_getLastStepVehicleIDs", (lane.as_str(),))?
                .extract()
                .map_err(|e| py_error(py, format!("lane.getLastStepVehicleIDs({lane})"), e))?;
            for id in ids {
                // A vehicle across two lanes is listed on both: keep its first place.
                if order.last() != Some(&id) && !order.contains(&id) {
                    order.push(id);
                }
            }
        }
        let place: HashMap<&str, usize> = order
            .iter()
            .enumerate()
            .map(|(k, id)| (id.as_str(), k))
            .collect();
        let m = order.len();
        for (id, last) in &mut self.seen {
            let now = place.get(id.as_str()).and_then(|&k| match k + 1 {
                j if j < m => Some(order[j].clone()),
                _ if self.ring && m > 1 => Some(order[0].clone()),
                _ => None,
            });
            if now != *last {
                self.changes += 1;
                *last = now;
            }
        }
        Ok(())
    }
}
