//! `syncroad check`: which of the paper's sufficient conditions certify synchronization.

use std::path::Path;

use syncroad_control::theory;

use crate::config::load_scenario;
use crate::error::Status;
use crate::report;
use crate::stdout::{out, outln};

/// Prints the theory report (table or JSON); success when certified.
pub fn run(path: &Path, json: bool) -> anyhow::Result<Status> {
    let sc = load_scenario(path)?;
    let rep = theory::report(&sc);
    if json {
        outln!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        out!("{}", report::theory_table(&rep));
    }
    Ok(Status::verdict(rep.certified))
}
