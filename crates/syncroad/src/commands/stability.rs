//! `syncroad stability`: exact stability beside the paper's conditions; with
//! `--platoon-scaling`, the least-stable eigenvalue of the CACC platoon against its size.

use std::path::Path;
use std::time::Duration;

use syncroad_control::exact::analysis::{self, AnalysisError, CriticalScaleStatus, ExactVerdict};

use crate::config::load_scenario;
use crate::error::{InputError, Status};
use crate::stdout::{out, outln};

/// Prints the exact report (tables or JSON); success when the certified verdict is
/// "synchronizes" and the critical scale, when a search found it, is certified.
pub fn run(path: &Path, json: bool, platoon_scaling: bool) -> anyhow::Result<Status> {
    let sc = load_scenario(path)?;
    let ticker = crate::progress::Ticker::start("stability", Duration::from_secs(2));
    let r = analysis::analyse_reporting(&sc, &|step| ticker.step(step));
    drop(ticker);
    let r = r.map_err(|e| match e {
        AnalysisError::BelowResolution { .. }
        | AnalysisError::AboveResolution { .. }
        | AnalysisError::TooFewVehicles { .. } => anyhow::Error::new(InputError::caused(
            format!("scenario {}", path.display()),
            e,
        )),
        AnalysisError::TooLargeForFullSolve { .. } => {
            anyhow::Error::new(e).context(InputError::new(format!("scenario {}", path.display())))
        }
        e => anyhow::Error::new(e),
    })?;
    let scaling = if platoon_scaling {
        Some(
            analysis::platoon_scaling_study(
                &sc,
                &syncroad_control::exact::platoon_scaling::DEFAULT_SIZES,
            )
            .map_err(|e| match e {
                AnalysisError::PlatoonScalingNeedsCacc => {
                    anyhow::Error::new(e).context(InputError::new("--platoon-scaling"))
                }
                e => anyhow::Error::new(e),
            })?,
        )
    } else {
        None
    };
    if json {
        let v = match &scaling {
            Some(_) => serde_json::json!({"report": r, "platoon_scaling": scaling}),
            None => serde_json::to_value(&r)?,
        };
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        out!("{}", crate::stability::table(&r));
        if let Some(s) = &scaling {
            out!("{}", crate::stability::scaling_table(s));
        }
    }
    crate::config::note_fixed_graph(&sc);
    crate::config::note_own_controller(&sc);
    Ok(Status::verdict(
        r.verdict == ExactVerdict::Synchronizes
            && r.critical_scale_status != CriticalScaleStatus::Uncertified,
    ))
}
