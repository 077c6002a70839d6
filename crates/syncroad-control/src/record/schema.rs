//! The JSON Schema of the run record, derived from [`RunRecord`] itself, and what it says of
//! each metric: its type, title and unit. `docs/metrics.schema.json` is this schema as
//! written by `syncroad schema` (a test fails when the committed file differs), and the sweep
//! table takes its columns and the plots their labels from it, so adding a metric is adding
//! one field to the record.
//!
//! * **titles** come from the field's doc comment (its first sentence, without the unit);
//! * **units** from the field's name, whose suffix carries the unit by the project's
//!   convention (`_mps` → m/s, `_s` → s, …), written as `x-unit`;
//! * every key is required except the blocks a record carries only when measured
//!   (`OPTIONAL_BLOCKS`), and no other key is allowed.

use schemars::generate::SchemaSettings;
use schemars::transform::{RecursiveTransform, Transform};
use schemars::Schema;
use serde_json::{json, Map, Value};

use crate::record::RunRecord;

/// The `$id` of the record's schema.
pub const SCHEMA_ID: &str = "syncroad-metrics-v1";

/// Keys a record holds only when the run measured them.
const OPTIONAL_BLOCKS: [&str; 10] = [
    "safety_margins",
    "string_amplification",
    "gap_certificate",
    "gap_safety",
    "braking_events",
    "jam_formed_s",
    "all_vehicles",
    "controlled",
    "guests",
    "controller",
];

/// Unit suffixes of field names, longest first.
const UNITS: [(&str, &str); 13] = [
    ("hard_braking_steps", "veh-steps"),
    ("_veh_per_h", "veh/h"),
    ("_g_per_km", "g/km"),
    ("_per_vehicle_s", "s"),
    ("_mps2", "m/s²"),
    ("_per_s", "1/s"),
    ("_mps", "m/s"),
    ("_mg", "mg"),
    ("_m", "m"),
    ("_s", "s"),
    ("spread_l2", "m/s·√s"),
    ("_fraction", "1"),
    ("_ratio", "1"),
];

/// The unit of a field named `name`, from its suffix (`None`: a count, a flag or text).
pub fn unit_of(name: &str) -> Option<&'static str> {
    UNITS
        .iter()
        .find(|(suffix, _)| name.ends_with(suffix))
        .map(|(_, u)| *u)
}

/// The title of a doc comment: its first sentence without a trailing `[unit]` or full stop.
fn title_of(description: &str) -> String {
    let first = description
        .split("\n\n")
        .next()
        .unwrap_or("")
        .replace('\n', " ");
    let first = match first.find(". ") {
        Some(k) => &first[..k],
        None => first.trim_end_matches('.'),
    };
    let first = match first.rfind(" [") {
        Some(k) if first.ends_with(']') => &first[..k],
        _ => first,
    };
    let first = first.trim().trim_end_matches('.');
    let mut c = first.chars();
    match c.next() {
        Some(h) => h.to_lowercase().chain(c).collect(),
        None => String::new(),
    }
}

/// Titles, units, `additionalProperties: false` and every key required.
fn annotate(schema: &mut Schema) {
    let Some(obj) = schema.as_object_mut() else {
        return;
    };
    let Some(Value::Object(props)) = obj.get_mut("properties") else {
        return;
    };
    let mut names = Vec::new();
    for (name, p) in props.iter_mut() {
        names.push(name.clone());
        let Some(p) = p.as_object_mut() else { continue };
        if !p.contains_key("title") {
            if let Some(d) = p.get("description").and_then(Value::as_str) {
                let t = title_of(d);
                if !t.is_empty() {
                    p.insert("title".into(), Value::String(t));
                }
            }
        }
        if let Some(u) = unit_of(name) {
            p.insert("x-unit".into(), Value::String(u.into()));
        }
    }
    let is_tagged = props.contains_key("reason");
    obj.insert("additionalProperties".into(), Value::Bool(false));
    if !is_tagged {
        let required: Vec<Value> = names
            .into_iter()
            .filter(|n| !OPTIONAL_BLOCKS.contains(&n.as_str()))
            .map(Value::String)
            .collect();
        obj.insert("required".into(), Value::Array(required));
    }
}

/// The record's schema (draft 2020-12) as JSON.
pub fn metrics_schema() -> Value {
    let mut generator = SchemaSettings::draft2020_12().into_generator();
    let mut schema = generator.root_schema_for::<RunRecord>();
    RecursiveTransform(annotate).transform(&mut schema);
    let mut v = schema.to_value();
    let o = v.as_object_mut().expect("a record schema is an object");
    o.insert("$id".into(), json!(SCHEMA_ID));
    o.insert("title".into(), json!("syncroad run record (metrics.json)"));
    o.insert(
        "description".into(),
        json!("One run of `syncroad run`, `simulate`, or each run of `compare` (runs.NAME in compare.json, with the stamps lifted to the top). Every key is always present (null where it does not apply), except the blocks only runs that measured them carry (safety_margins, string_amplification, gap_certificate, gap_safety, braking_events, jam_formed_s, all_vehicles, present when other traffic shared the road, controlled, present when the law drove the user's own vehicles, guests, present when a law drove vehicles of an inflow, and controller, present when the user's own controller drove in place of the law). Units are SI, named in the keys and given as x-unit. Generated from the record's type by `syncroad schema`."),
    );
    v
}

/// The schema as `docs/metrics.schema.json` holds it: pretty JSON and a final newline.
pub fn metrics_schema_text() -> String {
    let mut text = serde_json::to_string_pretty(&metrics_schema()).expect("a schema serializes");
    text.push('\n');
    text
}

/// One scalar of the record: its dotted path, type, title and unit, in the record's order.
#[derive(Debug, Clone, PartialEq)]
pub struct MetricInfo {
    /// Dotted path (`sync.final_spread_mps`).
    pub path: String,
    /// JSON type: `number`, `integer`, `boolean` or `string`.
    pub kind: &'static str,
    /// Title from the field's doc comment.
    pub title: String,
    /// Unit from the field's name.
    pub unit: Option<&'static str>,
}

impl MetricInfo {
    /// `title [unit]`, for axes and table rows.
    pub fn label(&self) -> String {
        match self.unit {
            Some(u) if u != "1" => format!("{} [{u}]", self.title),
            _ => self.title.clone(),
        }
    }
}

/// Every scalar of the record, in field order.
pub fn metric_infos() -> Vec<MetricInfo> {
    let schema = metrics_schema();
    let mut out = Vec::new();
    walk(&schema, &schema, "", "", &mut out);
    out
}

fn walk(node: &Value, root: &Value, path: &str, title: &str, out: &mut Vec<MetricInfo>) {
    let node = resolve(node, root);
    if let Some(props) = node.get("properties").and_then(Value::as_object) {
        if props.contains_key("reason") {
            // The tagged stop reason: its tag is the scalar.
            push(
                out,
                &format!("{path}.reason"),
                "string",
                "why the run stopped",
            );
            return;
        }
        for name in field_order(node, props) {
            let p = &props[name];
            let sub = if path.is_empty() {
                name.to_string()
            } else {
                format!("{path}.{name}")
            };
            let t = p.get("title").and_then(Value::as_str).unwrap_or(name);
            walk(p, root, &sub, t, out);
        }
        return;
    }
    // `Option<T>` of a struct is `anyOf: [T, null]`; of an enum `oneOf`.
    for key in ["anyOf", "oneOf"] {
        if let Some(alts) = node.get(key).and_then(Value::as_array) {
            if let Some(Value::String(_)) = alts.iter().find_map(|a| a.get("const")) {
                push(out, path, "string", title);
                return;
            }
            if let Some(a) = alts.iter().find(|a| a.get("type") != Some(&json!("null"))) {
                walk(a, root, path, title, out);
            }
            return;
        }
    }
    if node.get("enum").is_some() {
        push(out, path, "string", title);
        return;
    }
    let types: Vec<&str> = match node.get("type") {
        Some(Value::String(t)) => vec![t.as_str()],
        Some(Value::Array(ts)) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    for kind in ["number", "integer", "boolean", "string"] {
        if types.contains(&kind) {
            push(out, path, kind, title);
            return;
        }
    }
}

fn push(out: &mut Vec<MetricInfo>, path: &str, kind: &'static str, title: &str) {
    let name = path.rsplit('.').next().unwrap_or(path);
    out.push(MetricInfo {
        path: path.to_string(),
        kind,
        title: title.to_string(),
        unit: unit_of(name),
    });
}

fn resolve<'a>(node: &'a Value, root: &'a Value) -> &'a Value {
    match node.get("$ref").and_then(Value::as_str) {
        Some(r) => {
            let name = r.trim_start_matches("#/$defs/");
            root.get("$defs")
                .and_then(|d| d.get(name))
                .map_or(node, |d| resolve(d, root))
        }
        None => node,
    }
}

/// The properties in the record's field order: `required` lists them as declared, the
/// optional blocks follow.
fn field_order<'a>(node: &'a Value, props: &'a Map<String, Value>) -> Vec<&'a str> {
    let mut order: Vec<&str> = node
        .get("required")
        .and_then(Value::as_array)
        .map(|r| r.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    for k in props.keys() {
        if !order.contains(&k.as_str()) {
            order.push(k);
        }
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_carry_type_title_and_unit() {
        let m = metric_infos();
        let find = |p: &str| m.iter().find(|x| x.path == p).cloned();
        let spread = find("sync.final_spread_mps").unwrap();
        assert_eq!(spread.kind, "number");
        assert_eq!(spread.unit, Some("m/s"));
        assert_eq!(spread.label(), "final spread [m/s]");
        assert_eq!(
            find("sumo.hard_braking_steps").unwrap().label(),
            "hard braking [veh-steps]"
        );
        assert_eq!(
            find("safety.collision_steps").unwrap().label(),
            "collision steps"
        );
        assert_eq!(find("sync.verdict").unwrap().kind, "string");
        assert_eq!(find("safety.collision_steps").unwrap().kind, "integer");
        assert_eq!(find("certified").unwrap().kind, "boolean");
        assert_eq!(find("stop.reason").unwrap().kind, "string");
        assert_eq!(
            find("sync.thresholds.tolerance_mps").unwrap().unit,
            Some("m/s")
        );
        assert_eq!(find("sumo.fuel_g_per_km").unwrap().unit, Some("g/km"));
        assert_eq!(find("congestion.stop_events").unwrap().unit, None);
        // Arrays are not scalar metrics; the optional blocks are there.
        assert!(find("drivers").is_none());
        assert!(find("safety_margins.ssm.ttc_min_s").is_some());
        // The record's order: stamps first.
        assert_eq!(m[0].path, "syncroad_version");
        assert!(
            m.iter().all(|x| !x.title.is_empty()),
            "every metric has a title"
        );
    }

    /// The published file is the derived schema: regenerate it with
    /// `syncroad schema > docs/metrics.schema.json` after changing the record.
    #[test]
    fn the_published_schema_is_the_derived_one() {
        let published = include_str!("../../../../docs/metrics.schema.json");
        assert!(
            published == metrics_schema_text(),
            "docs/metrics.schema.json differs from the record's type: run `syncroad schema > docs/metrics.schema.json`"
        );
    }

    #[test]
    fn titles_drop_the_unit_and_the_full_stop() {
        assert_eq!(title_of("Spread at t = 0 [m/s]."), "spread at t = 0");
        assert_eq!(title_of("Minimum speed [m/s]"), "minimum speed");
        assert_eq!(
            title_of("Stamp: SUMO's version (`null` for native runs)."),
            "stamp: SUMO's version (`null` for native runs)"
        );
        assert_eq!(title_of("First. Second."), "first");
    }
}
