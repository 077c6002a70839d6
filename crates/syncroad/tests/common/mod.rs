//! Helpers shared by the binary's end-to-end tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `syncroad` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_syncroad"))
}

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A fresh, empty folder for one test (unique per test process and name).
pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("syncroad-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs a command: (exit code, stdout, stderr).
pub fn run(cmd: &mut Command) -> (i32, String, String) {
    let Output {
        status,
        stdout,
        stderr,
    } = cmd.output().expect("binary runs");
    (
        status.code().unwrap_or(-1),
        String::from_utf8_lossy(&stdout).into_owned(),
        String::from_utf8_lossy(&stderr).into_owned(),
    )
}

/// Checks `doc` against the JSON Schema subset `docs/metrics.schema.json` uses (`type`,
/// `enum`, `required`, `properties`, `additionalProperties: false`, `items`, local `$ref`);
/// returns every violation with its JSON path.
pub fn schema_violations(schema: &serde_json::Value, doc: &serde_json::Value) -> Vec<String> {
    use serde_json::Value;
    fn resolve<'a>(root: &'a Value, s: &'a Value) -> &'a Value {
        match s.get("$ref").and_then(Value::as_str) {
            Some(r) => {
                let mut v = root;
                for part in r.trim_start_matches("#/").split('/') {
                    v = &v[part];
                }
                resolve(root, v)
            }
            None => s,
        }
    }
    fn type_ok(t: &str, v: &Value) -> bool {
        match t {
            "object" => v.is_object(),
            "array" => v.is_array(),
            "string" => v.is_string(),
            "boolean" => v.is_boolean(),
            "null" => v.is_null(),
            "integer" => v.is_u64() || v.is_i64(),
            "number" => v.is_number(),
            _ => false,
        }
    }
    fn go(root: &Value, s: &Value, v: &Value, path: &str, out: &mut Vec<String>) {
        let s = resolve(root, s);
        if let Some(t) = s.get("type") {
            let ok = match t {
                Value::String(t) => type_ok(t, v),
                Value::Array(ts) => ts.iter().filter_map(Value::as_str).any(|t| type_ok(t, v)),
                _ => true,
            };
            if !ok {
                out.push(format!("{path}: {v} is not of type {t}"));
                return;
            }
        }
        if let Some(e) = s.get("enum").and_then(Value::as_array) {
            if !e.contains(v) {
                out.push(format!("{path}: {v} is not one of {e:?}"));
            }
        }
        if let Value::Object(m) = v {
            for r in s
                .get("required")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
            {
                let k = r.as_str().unwrap_or_default();
                if !m.contains_key(k) {
                    out.push(format!("{path}: missing required key {k}"));
                }
            }
            let props = s.get("properties").and_then(Value::as_object);
            for (k, x) in m {
                match props.and_then(|p| p.get(k)) {
                    Some(ps) => go(root, ps, x, &format!("{path}.{k}"), out),
                    None if s.get("additionalProperties") == Some(&Value::Bool(false)) => {
                        out.push(format!("{path}: key {k} is not in the schema"))
                    }
                    None => {}
                }
            }
        }
        if let (Value::Array(a), Some(items)) = (v, s.get("items")) {
            for (i, x) in a.iter().enumerate() {
                go(root, items, x, &format!("{path}[{i}]"), out);
            }
        }
    }
    let mut out = Vec::new();
    go(schema, schema, doc, "$", &mut out);
    out
}

/// The published metrics schema.
pub fn metrics_schema() -> serde_json::Value {
    let text = std::fs::read_to_string(repo().join("docs/metrics.schema.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}
