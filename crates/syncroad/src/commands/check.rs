//! `syncroad check`: which of the paper's sufficient conditions certify synchronization, and
//! the gap certificate of the linear model (will the law make the cars touch?).

use std::path::Path;

use syncroad_control::exact::gaps::gap_certificate;
use syncroad_control::theory;

use crate::config::load_scenario;
use crate::error::Status;
use crate::report;
use crate::stdout::{out, outln};

/// Prints the theory report and the gap certificate (table or JSON); success when certified.
pub fn run(path: &Path, json: bool) -> anyhow::Result<Status> {
    let sc = load_scenario(path)?;
    let rep = theory::report(&sc);
    let gaps = gap_certificate(&sc);
    if json {
        let mut v = serde_json::to_value(&rep)?;
        v["gap_certificate"] = match &gaps {
            Ok(g) => serde_json::to_value(g)?,
            Err(e) => serde_json::json!({ "error": e.to_string() }),
        };
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        out!("{}", report::theory_table(&rep));
        out!("{}", crate::gaps::gap_lines(&gaps, rep.certified));
    }
    Ok(Status::verdict(rep.certified))
}
