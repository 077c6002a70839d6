//! `syncroad check`: which of the paper's sufficient conditions certify synchronization, and
//! the gap certificate of the linear model (will the law make the cars touch?).

use std::path::Path;

use syncroad_control::exact::analysis::AnalysisError;
use syncroad_control::exact::gaps::gap_certificate;
use syncroad_control::theory;

use crate::config::load_scenario;
use crate::error::{InputError, Status};
use crate::stdout::{out, outln};
use crate::tables;

/// Prints the theory report and the gap certificate (table or JSON); success when the
/// scenario, as it runs, is certified (its model's law drives every vehicle and the conditions
/// hold).
pub fn run(path: &Path, json: bool) -> anyhow::Result<Status> {
    let sc = load_scenario(path)?;
    if sc.vehicles() == 0 {
        return Err(anyhow::Error::new(InputError::caused(
            format!("scenario {}", path.display()),
            AnalysisError::TooFewVehicles { vehicles: 0 },
        )));
    }
    let rep = theory::report(&sc);
    // The certificate is of the scenario's own start (`initial`); a run of the user's own
    // vehicles starts from theirs, which it does not describe.
    // Nor does it describe a road shared with the user's own traffic, which SUMO drives: it
    // can enter the law's lane and change who follows whom.
    let not_described = sc
        .sumo()
        .controlled()
        .map(|sel| {
            format!(
                "sumo.controlled = {}: the run starts the user's own vehicles from their own positions and speeds, not from the scenario's `initial`, which the certificate would describe",
                serde_json::to_string(sel).unwrap_or_default()
            )
        })
        .or_else(|| {
            let (field, value) = sc
                .sumo()
                .other_traffic_source()
                .filter(|_| sc.backend() == syncroad_control::scenario::Backend::Sumo)?;
            Some(format!(
                "{field} = {value}: the run shares the road with other traffic, which SUMO drives; it can enter the law's lane or merge into it and change who follows whom, so the gaps are not those of the law's fixed graph that the certificate describes (the run's record measures the gaps it drove: gap_safety)"
            ))
        });
    let gaps = gap_certificate(&sc);
    let otherwise = driven_otherwise(&sc);
    let holds = rep.certified && otherwise.is_none();
    if json {
        let mut v = serde_json::to_value(&rep)?;
        // `certified` is the model's law on every vehicle; `scenario_certified` is this
        // scenario as it runs, which the exit code follows.
        v["scenario_certified"] = serde_json::json!(holds);
        if let Some(why) = &otherwise {
            v["not_certified_because"] = serde_json::json!(why);
        }
        v["gap_certificate"] = match (&not_described, &gaps) {
            (Some(why), _) => serde_json::json!({ "not_applicable": why }),
            (None, Ok(g)) => serde_json::to_value(g)?,
            (None, Err(e)) => serde_json::json!({ "error": e.to_string() }),
        };
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        out!("{}", tables::theory_table(&rep, otherwise.as_deref()));
        match &not_described {
            Some(why) => out!(
                "\ngap certificate (linear model; the law couples speeds, not gaps):\n  does not apply: {why}\n"
            ),
            None => out!("{}", crate::gaps::gap_lines(&gaps, rep.certified)),
        }
    }
    crate::config::note_fixed_graph(&sc);
    Ok(Status::verdict(holds))
}

/// What drives the scenario's runs instead of its model's law on every vehicle, which is all
/// the paper's conditions speak of: the user's own controller, or a mixed block's humans and
/// dampers. `None` when the model's law drives every vehicle.
fn driven_otherwise(sc: &syncroad_control::scenario::Scenario) -> Option<String> {
    if let Some(c) = sc.controller() {
        let (field, value) = c.named_by();
        return Some(format!(
            "its runs are driven by {} ({field} = {value}), not by the model's law",
            c.label()
        ));
    }
    let m = sc.mixed()?;
    let n = sc.vehicles();
    let automated = m.automated(n, sc.seed()).len();
    let law = if m.damper().ok().flatten().is_none() {
        automated
    } else {
        0
    };
    Some(format!(
        "its mixed block drives {} of its {n} vehicles otherwise than by the law (humans: {}, automated: {})",
        n - law,
        m.human,
        m.controller
    ))
}
