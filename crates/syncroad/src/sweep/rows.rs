//! The rows of a sweep folder (`OUT/rows/<point>.json`), each checked to be a row of this
//! sweep before it enters a table: named for its point, a point the spec has (of this
//! shard), written by this spec (its hash) with this point's parameters. A row that is not
//! is an error naming its file, never a silent extra row or a silently collapsed duplicate.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde_json::{json, Map, Value};

use super::points::{Point, Shard};
use super::spec::Sweep;
use crate::error::InputError;

/// The folder of the rows.
pub fn rows_dir(out: &Path) -> PathBuf {
    out.join("rows")
}

/// The file of point `id`'s row.
pub fn row_path(out: &Path, id: usize) -> PathBuf {
    rows_dir(out).join(row_name(id))
}

fn row_name(id: usize) -> String {
    format!("{id:07}.json")
}

/// Why `row` in file `name` is not the row of a point of `sweep` in `shard`, if it is not.
fn foreign(sweep: &Sweep, shard: Shard, name: &str, row: &Map<String, Value>) -> Option<String> {
    let Some(id) = row.get("point").and_then(Value::as_u64) else {
        return Some("it has no point number".into());
    };
    let id = usize::try_from(id).unwrap_or(usize::MAX);
    if id >= sweep.len() {
        return Some(format!(
            "it holds point {id}, and the spec has {} points (0 to {})",
            sweep.len(),
            sweep.len() - 1
        ));
    }
    if name != row_name(id) {
        return Some(format!(
            "it holds point {id}, whose row is {}",
            row_name(id)
        ));
    }
    if !shard.holds(id) {
        return Some(format!(
            "it holds point {id}, which is not in shard {}/{}",
            shard.index, shard.count
        ));
    }
    let expected = point_cells(sweep, &sweep.point(id));
    for (key, want) in expected.iter().filter(|(k, _)| *k != "syncroad_version") {
        let got = row.get(key).unwrap_or(&Value::Null);
        if got != want {
            return Some(format!(
                "its {key} is {got}, but point {id} of this spec has {want}"
            ));
        }
    }
    None
}

/// Reads every row in `out/rows` by point id; refuses (an input error naming each file) a
/// row that is not a row of `sweep` in `shard`.
pub fn read_rows(
    sweep: &Sweep,
    out: &Path,
    shard: Shard,
) -> anyhow::Result<BTreeMap<usize, Map<String, Value>>> {
    let mut rows = BTreeMap::new();
    let mut strangers = Vec::new();
    let dir = rows_dir(out);
    if !dir.is_dir() {
        return Ok(rows);
    }
    let mut paths = Vec::new();
    for e in std::fs::read_dir(&dir).with_context(|| format!("cannot read {}", dir.display()))? {
        paths.push(e?.path());
    }
    paths.sort();
    for path in paths {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        // Temporary files of a write in flight (or cut short) are hidden.
        if name.starts_with('.') || path.extension().is_none_or(|x| x != "json") {
            continue;
        }
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let row: Map<String, Value> = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a sweep row", path.display()))?;
        match foreign(sweep, shard, &name, &row) {
            Some(why) => strangers.push(format!("{}: {why}", path.display())),
            None => {
                let id = row["point"].as_u64().expect("checked") as usize;
                rows.insert(id, row);
            }
        }
    }
    if !strangers.is_empty() {
        let shown: Vec<&str> = strangers.iter().take(5).map(String::as_str).collect();
        return Err(InputError::new(format!(
            "{}: {} row files are not rows of this sweep ({}{}); remove them, or give a new folder",
            out.display(),
            strangers.len(),
            shown.join("; "),
            if strangers.len() > 5 { "; ..." } else { "" }
        ))
        .into());
    }
    Ok(rows)
}

/// The parameter cells of a point's row.
pub(super) fn point_cells(sweep: &Sweep, p: &Point) -> Map<String, Value> {
    let mut r = Map::new();
    r.insert("point".into(), json!(p.id));
    for (a, &k) in sweep.axes.iter().zip(&p.at) {
        r.insert(a.field.clone(), a.values[k].clone());
    }
    let run = &sweep.runs[p.run];
    r.insert("run".into(), json!(run.spec.name));
    r.insert("penetration".into(), json!(run.penetration));
    r.insert("seed".into(), json!(p.seed));
    r.insert(
        "backend".into(),
        serde_json::to_value(sweep.backend).unwrap_or_default(),
    );
    r.insert("spec_hash".into(), json!(sweep.hash));
    r.insert("syncroad_version".into(), json!(env!("CARGO_PKG_VERSION")));
    r
}
