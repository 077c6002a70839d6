//! `sumo.controlled` in the worker: after insertion, the user's vehicles the selection chooses
//! become the layout's vehicles, in their order along the road (vehicle 0 in front, each
//! following the one before; on a loop vehicle 0 is the first from the start of the loop's
//! first edge on, and follows the last), so the law's
//! per-vehicle parameters, its graph and every measurement index them as they would index
//! vehicles syncroad inserted. Each keeps circling (or driving the route) on the road's lane:
//! its route becomes syncroad's route from its edge on, and the loop's speed and lane-change
//! modes are set as for syncroad's own vehicles.

use pyo3::prelude::*;
use syncroad_control::scenario::VehicleSelector;

use super::libsumo::Libsumo;
use super::CosimError;
use crate::layout::Departure;
use crate::protocol::Request;
use crate::python::py_error;

/// A chosen vehicle as SUMO has it after insertion.
struct Chosen {
    id: String,
    /// Front bumper along the road \[m\].
    front_m: f64,
    length_m: f64,
    speed_mps: f64,
    /// Index among the road's normal edges.
    edge_index: usize,
    pos_m: f64,
}

fn get_f64(ls: &Libsumo<'_>, name: &str, id: &str) -> Result<f64, CosimError> {
    ls.call(name, (id,))?
        .extract::<f64>()
        .map_err(|e| py_error(ls.py, format!("{name}({id})"), e).into())
}

fn get_string(ls: &Libsumo<'_>, name: &str, id: &str) -> Result<String, CosimError> {
    ls.call(name, (id,))?
        .extract::<String>()
        .map_err(|e| py_error(ls.py, format!("{name}({id})"), e).into())
}

/// The request with the chosen vehicles as its layout's (bound: the worker binds once); their
/// routes set to the road's.
pub(super) fn bind(
    ls: &Libsumo<'_>,
    req: &Request,
    sel: &VehicleSelector,
) -> Result<Request, CosimError> {
    let fail = |reason: String| CosimError::Controlled {
        selector: sel.to_string(),
        reason,
    };
    let m = sel.matcher().map_err(|e| fail(e.to_string()))?;
    let road = &req.layout.road;
    let all: Vec<String> = ls
        .call("vehicle_getIDList", ())?
        .extract()
        .map_err(|e| py_error(ls.py, "vehicle.getIDList", e))?;
    let mut chosen = Vec::new();
    for id in all {
        let vtype = get_string(ls, "vehicle_getTypeID", &id)?;
        if !m.matches(&id, &vtype) {
            continue;
        }
        let lane = get_string(ls, "vehicle_getLaneID", &id)?;
        let mut start = 0.0;
        let mut normal = 0;
        let mut at = None;
        for seg in &road.segments {
            if seg.lane == lane && !seg.internal {
                at = Some((start, normal));
                break;
            }
            start += seg.length_m;
            normal += usize::from(!seg.internal);
        }
        let Some((start, edge_index)) = at else {
            let driven: Vec<String> = road
                .segments
                .iter()
                .filter(|s| !s.internal)
                .map(|s| s.lane.clone())
                .collect();
            return Err(fail(format!(
                "vehicle {id} is on lane {lane} after insertion, which is not a lane the road drives: make it depart on the road (on one of the lanes {})",
                driven.join(", ")
            )));
        };
        let pos_m = get_f64(ls, "vehicle_getLanePosition", &id)?;
        chosen.push(Chosen {
            front_m: start + pos_m,
            length_m: get_f64(ls, "vehicle_getLength", &id)?,
            speed_mps: get_f64(ls, "vehicle_getSpeed", &id)?,
            edge_index,
            pos_m,
            id,
        });
    }
    let layout = &req.layout;
    let wanted = layout.vehicles.len();
    if chosen.len() != wanted {
        let ids: Vec<&str> = chosen.iter().map(|c| c.id.as_str()).collect();
        return Err(fail(format!(
            "{} of your vehicles match and are on the road after insertion ({}), but the run drives {wanted}: give as many vehicles in the scenario as your files start with at t = 0",
            chosen.len(),
            if ids.is_empty() { "none".to_string() } else { ids.join(", ") }
        )));
    }
    // In front first (ties by id, so the order is total). On a loop, vehicle 0 is the first
    // one from the start of the loop's first edge on, as syncroad places its own, and the
    // others follow it around the loop: they sit one loop length back in the unwrapped
    // coordinate.
    chosen.sort_by(|a, b| b.front_m.total_cmp(&a.front_m).then(a.id.cmp(&b.id)));
    let mut back = vec![0.0; wanted];
    if road.ring {
        chosen.rotate_right(1);
        back[1..].fill(road.length_m());
    }
    let mut bound = req.clone();
    for (k, ((c, dep), back)) in chosen
        .into_iter()
        .zip(&mut bound.layout.vehicles)
        .zip(back)
        .enumerate()
    {
        if (c.length_m - dep.length_m).abs() > 1e-9 {
            return Err(fail(format!(
                "vehicle {} (the law's vehicle {k}) is {} m long, but the scenario's vehicles are {} m (sumo.length_m): the law, its gaps and the ring's capacity use the scenario's length; give its vType length=\"{}\" or sumo.length_m = {}",
                c.id, c.length_m, dep.length_m, dep.length_m, c.length_m
            )));
        }
        ls.call(
            "vehicle_setRouteID",
            (c.id.as_str(), format!("r{}", c.edge_index)),
        )?;
        *dep = Departure {
            q0_m: c.front_m - back - c.length_m - layout.ring_offset_m,
            id: c.id,
            driver: None,
            length_m: c.length_m,
            edge_index: c.edge_index,
            pos_m: c.pos_m,
            speed_mps: c.speed_mps,
        };
    }
    // `adopt` stays: the topology counts chosen vehicles that come onto the road later.
    Ok(bound)
}
