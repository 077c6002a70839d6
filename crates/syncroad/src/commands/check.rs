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

/// Prints the theory report and the gap certificate (table or JSON); success when certified.
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
    if json {
        let mut v = serde_json::to_value(&rep)?;
        v["gap_certificate"] = match (&not_described, &gaps) {
            (Some(why), _) => serde_json::json!({ "not_applicable": why }),
            (None, Ok(g)) => serde_json::to_value(g)?,
            (None, Err(e)) => serde_json::json!({ "error": e.to_string() }),
        };
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        out!("{}", tables::theory_table(&rep));
        match &not_described {
            Some(why) => out!(
                "\ngap certificate (linear model; the law couples speeds, not gaps):\n  does not apply: {why}\n"
            ),
            None => out!("{}", crate::gaps::gap_lines(&gaps, rep.certified)),
        }
    }
    crate::config::note_fixed_graph(&sc);
    if crate::config::note_own_controller(&sc) {
        // The conditions certify the model's law, which does not drive this scenario's runs.
        return Ok(Status::verdict(false));
    }
    if let Some(m) = sc.mixed() {
        // The theorems speak of the law on every vehicle: a mixed ring is not certified by
        // them, whatever they say of its all-law version.
        let n = sc.vehicles();
        let automated = m.automated(n, sc.seed()).len();
        let law = if m.damper().ok().flatten().is_none() {
            automated
        } else {
            0
        };
        crate::stdout::errln!(
            "note: the scenario's mixed block drives {} of its {n} vehicles otherwise than by the law (humans: {}, automated: {}); the conditions above are for the ring with the law on every vehicle and do not certify this scenario",
            n - law,
            m.human,
            m.controller
        );
        return Ok(Status::verdict(false));
    }
    Ok(Status::verdict(rep.certified))
}
