//! `syncroad stability`: exact stability beside the paper's conditions.

use std::path::Path;

use crate::config::load_scenario;
use crate::error::Status;

/// Prints the exact report (tables or JSON); success when exactly stable.
pub fn run(path: &Path, json: bool) -> anyhow::Result<Status> {
    let sc = load_scenario(path)?;
    let r = crate::stability::analyse(&sc)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", crate::stability::table(&r));
    }
    Ok(Status::verdict(r.exactly_stable))
}
