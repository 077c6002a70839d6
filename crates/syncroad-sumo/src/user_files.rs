//! The user's own route and additional files (`sumo.routes`, `sumo.additional`), read before
//! SUMO starts: libsumo refuses a malformed or inconsistent file only once it starts, with a
//! Python traceback and no field name. Each file must be given once, be well-formed XML with a
//! `<routes>` or `<additional>` root, and name only edges and lanes the network has, and only
//! vehicle types and routes some file defines (or SUMO's default types).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::net::network::Network;
use crate::prepare_error::PrepareError;

/// Vehicle types SUMO defines itself.
const SUMO_TYPES: [&str; 6] = [
    "DEFAULT_VEHTYPE",
    "DEFAULT_PEDTYPE",
    "DEFAULT_BIKETYPE",
    "DEFAULT_CONTAINERTYPE",
    "DEFAULT_TAXITYPE",
    "DEFAULT_RAILTYPE",
];

/// Largest file read here (a parsed document takes several times its size; SUMO streams
/// larger demand files and reports their errors itself).
const MAX_BYTES: u64 = 64 << 20;

/// One user file: its field, index and path.
pub(crate) struct UserFile<'a> {
    pub field: &'static str,
    pub index: usize,
    pub path: &'a Path,
}

fn bad(f: &UserFile<'_>, reason: String) -> PrepareError {
    PrepareError::UserFile {
        field: f.field,
        index: f.index,
        path: f.path.to_path_buf(),
        reason,
    }
}

/// The documents' text, each read once (`None`: too large to check here).
fn read_all(files: &[UserFile<'_>]) -> Result<Vec<Option<String>>, PrepareError> {
    let mut seen: Vec<(PathBuf, String)> = Vec::new();
    let mut texts = Vec::new();
    for f in files {
        let id = std::fs::canonicalize(f.path).unwrap_or_else(|_| f.path.to_path_buf());
        if let Some((_, other)) = seen.iter().find(|(p, _)| *p == id) {
            return Err(bad(
                f,
                format!("is given twice (also as {other}); SUMO would load its vehicles twice: give each file once"),
            ));
        }
        seen.push((id, format!("{}[{}]", f.field, f.index)));
        let text = crate::input_file::read_text(f.path, Some(MAX_BYTES))
            .map_err(|reason| bad(f, format!("cannot be read: {reason}")))?;
        texts.push(text);
    }
    Ok(texts)
}

/// Checks `files` against the network `net` and syncroad's own routes file `ours` (whose types
/// and routes the user's files may name).
pub(crate) fn check(net: &Path, ours: &str, files: &[UserFile<'_>]) -> Result<(), PrepareError> {
    if files.is_empty() {
        return Ok(());
    }
    let texts = read_all(files)?;
    let mut docs = Vec::new();
    for (f, text) in files.iter().zip(&texts) {
        let Some(text) = text else {
            docs.push(None);
            continue;
        };
        if text.trim().is_empty() {
            return Err(bad(
                f,
                "is empty; SUMO reads a <routes> (or <additional>) document here".into(),
            ));
        }
        let doc = roxmltree::Document::parse(text)
            .map_err(|e| bad(f, format!("is not well-formed XML: {e}")))?;
        let root = doc.root_element().tag_name().name().to_string();
        if root != "routes" && root != "additional" {
            return Err(bad(
                f,
                format!("its root element is <{root}>; SUMO reads <routes> (or <additional>) here"),
            ));
        }
        docs.push(Some(doc));
    }
    let own = roxmltree::Document::parse(ours).ok();
    let all: Vec<&roxmltree::Document<'_>> = docs.iter().flatten().chain(own.iter()).collect();
    let ids = |tags: &[&str]| -> HashSet<String> {
        all.iter()
            .flat_map(|d| d.descendants())
            .filter(|n| tags.contains(&n.tag_name().name()))
            .filter_map(|n| n.attribute("id").map(str::to_string))
            .collect()
    };
    let types = ids(&["vType", "vTypeDistribution"]);
    let routes = ids(&["route", "routeDistribution"]);
    let network = Network::read(net)?;
    for (f, doc) in files.iter().zip(&docs) {
        let Some(doc) = doc else { continue };
        for n in doc.descendants().filter(|n| n.is_element()) {
            check_element(f, &network, &types, &routes, n)?;
        }
    }
    Ok(())
}

/// What an element names: edges (routes, trips, flows), lanes (detectors), a type, a route.
fn check_element(
    f: &UserFile<'_>,
    net: &Network,
    types: &HashSet<String>,
    routes: &HashSet<String>,
    n: roxmltree::Node<'_, '_>,
) -> Result<(), PrepareError> {
    let tag = n.tag_name().name();
    let whose = || {
        let owner = if tag == "route" {
            n.parent_element()
                .filter(|p| p.has_tag_name("vehicle") || p.has_tag_name("flow"))
        } else {
            None
        };
        match (owner, n.attribute("id")) {
            (Some(p), _) => format!(
                "the <route> of <{} id=\"{}\">",
                p.tag_name().name(),
                p.attribute("id").unwrap_or("?")
            ),
            (None, Some(id)) => format!("<{tag} id=\"{id}\">"),
            (None, None) => format!("a <{tag}>"),
        }
    };
    let edge_attrs: &[&str] = match tag {
        "route" => &["edges"],
        "trip" | "flow" | "vehicle" => &["from", "to", "via"],
        _ => &[],
    };
    for attr in edge_attrs {
        for edge in n.attribute(*attr).unwrap_or("").split_whitespace() {
            if net.edge_lanes(edge).is_none() {
                return Err(bad(
                    f,
                    format!(
                        "{} names edge `{edge}` in its `{attr}`, which the network has not; nearest ids: {}",
                        whose(),
                        crate::net::roads::nearest(net, edge)
                    ),
                ));
            }
        }
    }
    if let Some(lane) = n.attribute("lane") {
        if !net.lanes.contains_key(lane) {
            return Err(bad(
                f,
                format!("{} is on lane `{lane}`, which the network has not", whose()),
            ));
        }
    }
    if matches!(tag, "vehicle" | "trip" | "flow") {
        if let Some(t) = n.attribute("type") {
            if !types.contains(t) && !SUMO_TYPES.contains(&t) {
                return Err(bad(
                    f,
                    format!(
                        "{} has type `{t}`, which no <vType> of the scenario's files defines (SUMO's own: {})",
                        whose(),
                        SUMO_TYPES.join(", ")
                    ),
                ));
            }
        }
        if let Some(r) = n.attribute("route") {
            if !routes.contains(r) {
                return Err(bad(
                    f,
                    format!(
                        "{} follows route `{r}`, which no <route> of the scenario's files defines",
                        whose()
                    ),
                ));
            }
        }
    }
    Ok(())
}
