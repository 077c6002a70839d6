//! `sumo.controlled` before SUMO starts: what the user's own files say of the vehicles the law
//! is to drive. The worker binds them for certain after insertion (`cosim::adopt`); this check
//! catches what the files alone already show (too few or too many chosen vehicles departing at
//! t = 0, one departing on another lane) without a SUMO start.

use std::path::PathBuf;

use syncroad_control::drive::SumoDriver;
use syncroad_control::scenario::VehicleSelector;

use crate::layout::Layout;
use crate::prepare_error::PrepareError;

/// Files above this size are left to the worker's check (a parse here takes several times the
/// file's size in memory).
pub(crate) const USER_FILE_CHECK_MAX_BYTES: u64 = 64 << 20;

/// What the user's files hold of the chosen vehicles.
#[derive(Debug, Default, PartialEq)]
struct Found {
    /// Chosen `<vehicle>`/`<trip>` elements departing at t = 0: (id, departLane as written).
    at_start: Vec<(String, Option<String>)>,
    /// Chosen vehicles departing later.
    later: usize,
    /// A `<flow>`, a file too large or not XML: the count is not known here.
    uncertain: bool,
}

fn scan(sel: &VehicleSelector, files: &[PathBuf]) -> Found {
    let Ok(m) = sel.matcher() else {
        return Found {
            uncertain: true,
            ..Found::default()
        };
    };
    let mut found = Found::default();
    for path in files {
        let text = crate::input_file::read_text(path, Some(USER_FILE_CHECK_MAX_BYTES))
            .ok()
            .flatten();
        let Some(doc) = text
            .as_deref()
            .and_then(|t| roxmltree::Document::parse(t).ok())
        else {
            found.uncertain = true;
            continue;
        };
        for n in doc.descendants().filter(|n| n.is_element()) {
            let vtype = n.attribute("type").unwrap_or("DEFAULT_VEHTYPE");
            match n.tag_name().name() {
                "vehicle" | "trip" => {
                    let Some(id) = n.attribute("id") else {
                        continue;
                    };
                    if !m.matches(id, vtype) {
                        continue;
                    }
                    match n.attribute("depart").map(str::trim) {
                        Some(d) if d.parse::<f64>().is_ok_and(|t| t == 0.0) => {
                            found.at_start.push((
                                id.to_string(),
                                n.attribute("departLane").map(str::to_string),
                            ))
                        }
                        Some(d) if d.parse::<f64>().is_ok() => found.later += 1,
                        // "triggered", "now", a time with units: SUMO decides.
                        _ => found.uncertain = true,
                    }
                }
                "flow" if m.wants_type(vtype) => found.uncertain = true,
                _ => {}
            }
        }
    }
    found
}

/// Every check of `sumo.controlled` before SUMO starts: no SUMO drivers among the scenario's
/// `drivers` (the user's other vehicles have their own types; the bridge's stochastic humans
/// are the law's), and the user's `files` start with the layout's number of chosen vehicles
/// on its lane.
pub(crate) fn check_run(
    sel: &VehicleSelector,
    drivers: &[Option<SumoDriver>],
    layout: &Layout,
    files: &[PathBuf],
) -> Result<(), PrepareError> {
    if drivers
        .iter()
        .flatten()
        .any(|d| !matches!(d, SumoDriver::Noisy(_)))
    {
        return Err(PrepareError::Controlled {
            selector: sel.to_string(),
            reason: "the law drives the vehicles you choose, and your other vehicles drive by their own vehicle types, so no SUMO driver (`drivers`, `mixed`, compare's baselines) takes a vehicle of the run: run the law alone; for a baseline, give your vehicles the driver's vehicle type in your file and run without sumo.controlled".into(),
        });
    }
    let n = layout.vehicles.len();
    let wanted = match layout.leader_vehicle {
        true => format!("{n} vehicles (`vehicles` = {} and the leader)", n - 1),
        false => format!("{n} vehicles (`vehicles` = {n})"),
    };
    check(sel, files, n, &wanted, &layout.road.lanes())
}

/// Checks the user's `files` against `sel`: `wanted` vehicles must depart at t = 0, on a lane
/// the road drives (`lanes`, one per edge).
fn check(
    sel: &VehicleSelector,
    files: &[PathBuf],
    wanted: usize,
    wanted_text: &str,
    lanes: &[usize],
) -> Result<(), PrepareError> {
    let mut driven: Vec<usize> = lanes.to_vec();
    driven.sort_unstable();
    driven.dedup();
    let lane = driven
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(" or ");
    let f = scan(sel, files);
    let err = |reason: String| PrepareError::Controlled {
        selector: sel.to_string(),
        reason,
    };
    if let Some((id, l)) = f.at_start.iter().find(|(_, l)| {
        l.as_deref().is_some_and(|l| {
            l.trim()
                .parse::<usize>()
                .is_ok_and(|l| !driven.contains(&l))
        })
    }) {
        let given = l.as_deref().unwrap_or_default();
        return Err(err(if driven.len() == 1 {
            format!("vehicle {id} departs on lane {given}, but the law drives lane {lane} of the road: give it departLane=\"{lane}\"")
        } else {
            format!("vehicle {id} departs on lane {given}, but the law drives lanes {lane} of the road (one per edge): give it the departLane the road drives on its depart edge")
        }));
    }
    if f.uncertain || f.at_start.len() == wanted {
        return Ok(());
    }
    let ids = match f.at_start.as_slice() {
        [] => "none".to_string(),
        [one] => one.0.clone(),
        [a, b] => format!("{}, {}", a.0, b.0),
        [first, .., last] => format!("{} … {}", first.0, last.0),
    };
    let later = match f.later {
        0 => String::new(),
        k => format!(", {k} more depart later (the law drives those on the road at t = 0)"),
    };
    Err(err(format!(
        "{} of your vehicles depart at t = 0 and match ({ids}){later}, but the run drives {wanted_text}: give as many vehicles in the scenario as your files start with",
        f.at_start.len()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sel(vtype: &str) -> VehicleSelector {
        VehicleSelector {
            vtype: Some(vtype.into()),
            id: None,
        }
    }

    fn file(d: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
        let p = d.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    const CAVS: &str = r#"<routes>
    <vType id="cav"/>
    <vehicle id="c0" type="cav" route="r" depart="0" departLane="0"/>
    <vehicle id="c1" type="cav" route="r" depart="0.00"/>
    <vehicle id="c2" type="cav" route="r" depart="30"/>
    <vehicle id="h0" route="r" depart="0"/>
</routes>"#;

    #[test]
    fn the_files_count_the_chosen_vehicles_departing_at_the_start() {
        let d = tempfile::tempdir().unwrap();
        let p = file(&d, "cavs.rou.xml", CAVS);
        let f = scan(&sel("cav"), std::slice::from_ref(&p));
        assert_eq!(f.at_start.len(), 2);
        assert_eq!((f.later, f.uncertain), (1, false));
        // A vehicle without a type has SUMO's default type.
        assert_eq!(
            scan(&sel("DEFAULT_VEHTYPE"), std::slice::from_ref(&p)).at_start[0].0,
            "h0"
        );
        assert!(check(&sel("cav"), std::slice::from_ref(&p), 2, "2 vehicles", &[0]).is_ok());
        assert_eq!(
            check(
                &sel("cav"),
                std::slice::from_ref(&p),
                3,
                "3 vehicles (`vehicles` = 3)",
                &[0]
            )
            .unwrap_err()
            .to_string(),
            r#"sumo.controlled = {"vtype":"cav"}: 2 of your vehicles depart at t = 0 and match (c0, c1), 1 more depart later (the law drives those on the road at t = 0), but the run drives 3 vehicles (`vehicles` = 3): give as many vehicles in the scenario as your files start with (checked before starting SUMO)"#
        );
        assert_eq!(
            check(&sel("cav"), &[p], 2, "2 vehicles", &[1])
                .unwrap_err()
                .to_string(),
            r#"sumo.controlled = {"vtype":"cav"}: vehicle c0 departs on lane 0, but the law drives lane 1 of the road: give it departLane="1" (checked before starting SUMO)"#
        );
    }

    #[test]
    fn flows_and_unreadable_files_leave_the_count_to_the_worker() {
        let d = tempfile::tempdir().unwrap();
        let flows = file(
            &d,
            "flows.rou.xml",
            r#"<routes><flow id="f" type="cav" begin="0" end="10" number="3" route="r"/></routes>"#,
        );
        assert!(scan(&sel("cav"), std::slice::from_ref(&flows)).uncertain);
        assert!(check(&sel("cav"), std::slice::from_ref(&flows), 5, "5", &[0]).is_ok());
        // A flow of another type cannot bring a chosen vehicle.
        assert!(!scan(&sel("truck"), &[flows]).uncertain);
        let junk = file(&d, "junk.rou.xml", "not xml <");
        assert!(scan(&sel("cav"), &[junk]).uncertain);
    }
}
