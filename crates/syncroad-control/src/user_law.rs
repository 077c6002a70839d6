//! The user's own controller: a Python class named in the scenario, built once with its
//! parameters and stepped every step by the backend that runs the vehicles.
//!
//! ```json
//! "controller": {"python": "controllers/my_law.py:MyLaw", "params": {"gain": 0.4}}
//! ```
//! * `python`: `FILE.py:Class` (a file, relative to the scenario's folder) or
//!   `package.module:Class` (a module the interpreter imports);
//! * `params`: keyword arguments of the class, `MyLaw(**params)`;
//! * `state`: a pickled instance instead of `params` (what `syncroad.run(..., controller=obj)`
//!   writes; the class is still loaded from `python`).
//!
//! The controller drives the vehicles the scenario's law would drive: all of them, or the
//! automated ones of a `mixed` block whose controller is `law`. This crate holds it as data
//! ([`UserLaw`], built per run for the [`LawContext`] its backend resolved); the crates that embed Python
//! build the [`SpeedController`](crate::SpeedController) through a [`LawHost`](crate::LawHost) — the SUMO
//! worker inside its loop, the CLI in its own process for the native simulator.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::fingerprint::fnv1a_hex;
use crate::registry::NamedLaw;

pub use crate::speed_controller::LawContext;

/// The largest controller source or pickled state read \[bytes\].
pub const MAX_SOURCE_BYTES: u64 = 16 << 20;

/// The `controller` block as written in the scenario file: `python` or `rust`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSpec {
    /// `FILE.py:Class` or `package.module:Class`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub python: Option<String>,
    /// A law of the registry by name (`syncroad laws`, or a Rust law the running program
    /// registered), the one shape a scenario names a law with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<String>,
    /// The older spelling of `law`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rust: Option<String>,
    /// Keyword arguments of the class (a JSON object).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub params: Option<serde_json::Value>,
    /// A pickled instance of the class (a file, relative to the scenario's folder), in place
    /// of `params`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state: Option<PathBuf>,
}

/// Where the class comes from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum PythonSource {
    /// A source file, loaded as a module of its own.
    File {
        /// The file, resolved against the scenario's folder.
        path: PathBuf,
    },
    /// A module the interpreter imports.
    Module {
        /// Its dotted name.
        module: String,
    },
}

/// A validated Python controller: where its class is, how it is built, and the hash of what
/// was read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PythonLaw {
    /// As written in the scenario (`controller.python`).
    pub python: String,
    /// Where the class comes from.
    pub source: PythonSource,
    /// The class's (possibly dotted) name in its module.
    pub class: String,
    /// Keyword arguments (a JSON object; empty when none).
    pub params: serde_json::Value,
    /// A pickled instance to restore instead of calling the class.
    pub state: Option<PathBuf>,
    /// FNV-1a (64 bits, hex) of the source file and the state as read at validation; `None`
    /// for a module, whose source the interpreter finds.
    pub source_hash: Option<String>,
}

impl PythonLaw {
    /// The driver's name in tables, folders and labels: `python:Class`.
    pub fn label(&self) -> String {
        format!("python:{}", self.class)
    }
}

/// The user's own law of a scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum UserLaw {
    /// A Python class.
    Python(PythonLaw),
    /// A law of the registry ([`crate::registry`]): one the program registered, or a
    /// built-in one.
    Rust(NamedLaw),
}

impl UserLaw {
    /// The driver's name in tables, folders and labels: `python:Class`, `rust:name`, or a
    /// built-in law's own name (`follower-stopper-4.3`).
    pub fn label(&self) -> String {
        match self {
            UserLaw::Python(p) => p.label(),
            UserLaw::Rust(r) if r.is_built_in() => r.to_string(),
            UserLaw::Rust(r) => format!("rust:{r}"),
        }
    }

    /// The scenario's field and value that named it (`controller.python = FILE.py:Class`).
    pub fn named_by(&self) -> (&'static str, &str) {
        match self {
            UserLaw::Python(p) => ("controller.python", p.python.as_str()),
            UserLaw::Rust(r) => ("controller.rust", r.name.as_str()),
        }
    }

    /// The parameters it is built with.
    pub fn params(&self) -> &serde_json::Value {
        match self {
            UserLaw::Python(p) => &p.params,
            UserLaw::Rust(r) => &r.params,
        }
    }

    /// The hash of what was read for it (a Python source and state).
    pub fn source_hash(&self) -> Option<&str> {
        match self {
            UserLaw::Python(p) => p.source_hash.as_deref(),
            UserLaw::Rust(_) => None,
        }
    }
}

/// Errors of the `controller` block, each naming the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field} = {value}: {expected}")]
pub struct ControllerSpecError {
    /// `controller.python`, `controller.params`, `controller.state`.
    pub field: String,
    /// The value as written.
    pub value: String,
    /// What would be valid.
    pub expected: String,
}

fn spec_error(
    field: &str,
    value: impl ToString,
    expected: impl Into<String>,
) -> ControllerSpecError {
    ControllerSpecError {
        field: field.into(),
        value: value.to_string(),
        expected: expected.into(),
    }
}

impl ControllerSpec {
    /// Checks the block and reads its files (relative to `base_dir`).
    pub fn resolve(&self, base_dir: &Path) -> Result<UserLaw, ControllerSpecError> {
        let params = match &self.params {
            None => serde_json::Value::Object(Default::default()),
            Some(p @ serde_json::Value::Object(_)) => p.clone(),
            Some(p) => {
                return Err(spec_error(
                    "controller.params",
                    p,
                    "must be an object of keyword arguments, e.g. {\"gain\": 0.4}",
                ))
            }
        };
        let named = match (&self.law, &self.rust) {
            (Some(_), Some(_)) => {
                return Err(spec_error(
                    "controller",
                    "law and rust",
                    "give one: \"rust\" is the older spelling of \"law\"",
                ))
            }
            (law, rust) => law
                .as_ref()
                .map(|l| ("controller.law", l))
                .or(rust.as_ref().map(|r| ("controller.rust", r))),
        };
        match (&self.python, named.map(|(_, n)| n)) {
            (Some(python), None) => self
                .resolve_python(python, params, base_dir)
                .map(UserLaw::Python),
            (None, Some(name)) => {
                if let Some(s) = &self.state {
                    return Err(spec_error(
                        "controller.state",
                        s.display(),
                        "a pickled state is for Python controllers; give params",
                    ));
                }
                let field = named.map_or("controller.law", |(f, _)| f);
                crate::registry::lookup(name).map_err(|expected| spec_error(field, name, expected))?;
                let law = NamedLaw {
                    name: name.clone(),
                    params,
                };
                (law.entry().map_err(|e| spec_error(field, name, e))?.check)(
                    &law.params,
                )
                .map_err(|e| spec_error("controller.params", &law.params, e))?;
                Ok(UserLaw::Rust(law))
            }
            (Some(_), Some(_)) => Err(spec_error(
                "controller",
                "python and law",
                "give one: \"python\": \"FILE.py:Class\" or \"law\": \"NAME\"",
            )),
            (None, None) => Err(spec_error(
                "controller",
                "{}",
                "name the law: \"python\": \"FILE.py:Class\" (or \"module:Class\"), or \"law\": \"NAME\" of `syncroad laws` or a Rust law the program registered",
            )),
        }
    }

    fn resolve_python(
        &self,
        python: &str,
        params: serde_json::Value,
        base_dir: &Path,
    ) -> Result<PythonLaw, ControllerSpecError> {
        let field = "controller.python";
        let usage = "give FILE.py:Class (a file relative to the scenario) or package.module:Class";
        let Some((where_, class)) = python.rsplit_once(':') else {
            return Err(spec_error(
                field,
                python,
                format!("no class is named; {usage}"),
            ));
        };
        let identifier = |s: &str| {
            let mut c = s.chars();
            c.next().is_some_and(|f| f.is_alphabetic() || f == '_')
                && c.all(|x| x.is_alphanumeric() || x == '_')
        };
        if !class.split('.').all(identifier) {
            return Err(spec_error(
                field,
                python,
                format!("`{class}` is not a Python class name; {usage}"),
            ));
        }
        let mut hashed = Vec::new();
        let source = if where_.ends_with(".py") || where_.contains('/') {
            let path = base_dir.join(where_);
            hashed.extend(read_file(field, python, &path)?);
            // What the file can import from its folder is as much the controller as the file.
            // Named relative to the folder, so a moved folder keeps its hash.
            let folder = path.parent().unwrap_or(Path::new(""));
            for other in folder_sources(&path) {
                if other != path {
                    let name = other.strip_prefix(folder).unwrap_or(&other);
                    hashed.extend(name.display().to_string().as_bytes());
                    hashed.extend(read_file(field, python, &other)?);
                }
            }
            PythonSource::File { path }
        } else if !where_.is_empty() && where_.split('.').all(identifier) {
            PythonSource::Module {
                module: where_.to_string(),
            }
        } else {
            return Err(spec_error(
                field,
                python,
                format!("`{where_}` is neither a .py file nor a module name; {usage}"),
            ));
        };
        let state = match &self.state {
            None => None,
            Some(_) if self.params.is_some() => {
                return Err(spec_error(
                    "controller.state",
                    self.state.as_ref().expect("given").display(),
                    "give params or a pickled state, not both",
                ))
            }
            Some(s) => {
                let path = base_dir.join(s);
                hashed.extend(read_file("controller.state", s.display(), &path)?);
                Some(path)
            }
        };
        let source_hash = match source {
            PythonSource::File { .. } => Some(fnv1a_hex(&hashed)),
            PythonSource::Module { .. } => state.as_ref().map(|_| fnv1a_hex(&hashed)),
        };
        Ok(PythonLaw {
            python: python.to_string(),
            source,
            class: class.to_string(),
            params,
            state,
            source_hash,
        })
    }
}

/// Most Python files of a controller's folder that [`folder_sources`] lists.
pub const MAX_FOLDER_SOURCES: usize = 2000;

/// The Python files a controller file can import from its own folder, which syncroad puts on
/// the interpreter's path: the folder's modules (`*.py`) and its packages (subfolders with an
/// `__init__.py`, and the packages in them), the file itself among them; sorted, hidden
/// folders and `__pycache__` skipped, at most [`MAX_FOLDER_SOURCES`]. A sweep's hash covers
/// them, so a resume never mixes two versions of a module the controller imports.
pub fn folder_sources(file: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
        entries.sort();
        for path in entries {
            if out.len() >= MAX_FOLDER_SOURCES {
                return;
            }
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
            let Some(name) = name else { continue };
            if name.starts_with('.') || name == "__pycache__" {
                continue;
            }
            if path.is_dir() {
                if path.join("__init__.py").is_file() {
                    walk(&path, out);
                }
            } else if name.ends_with(".py") && path.is_file() {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    if let Some(dir) = file.parent() {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        walk(dir, &mut out);
        // The folder as named in the scenario: the file's own path is among them as given.
        out.iter_mut().for_each(|p| {
            if p.file_name() == file.file_name() && p.parent() == Some(dir) {
                *p = file.to_path_buf();
            }
        });
    }
    out
}

/// Reads a regular file of at most [`MAX_SOURCE_BYTES`].
fn read_file(
    field: &str,
    value: impl ToString,
    path: &Path,
) -> Result<Vec<u8>, ControllerSpecError> {
    let meta = std::fs::metadata(path).map_err(|e| {
        spec_error(
            field,
            value.to_string(),
            format!("cannot read {}: {e}", path.display()),
        )
    })?;
    if !meta.is_file() {
        return Err(spec_error(
            field,
            value.to_string(),
            format!("{} is not a regular file", path.display()),
        ));
    }
    if meta.len() > MAX_SOURCE_BYTES {
        return Err(spec_error(
            field,
            value.to_string(),
            format!(
                "{} is {} bytes; at most {MAX_SOURCE_BYTES} are read",
                path.display(),
                meta.len()
            ),
        ));
    }
    std::fs::read(path).map_err(|e| {
        spec_error(
            field,
            value.to_string(),
            format!("cannot read {}: {e}", path.display()),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(python: &str) -> ControllerSpec {
        ControllerSpec {
            python: Some(python.into()),
            ..Default::default()
        }
    }

    /// `law` is the one shape's key; `rust`, its older spelling, names the same law.
    #[test]
    fn a_registry_law_is_named_by_law_as_by_rust() {
        let params = Some(serde_json::json!({"desired_speed_mps": 4.3}));
        let by = |law: Option<&str>, rust: Option<&str>| ControllerSpec {
            law: law.map(str::to_string),
            rust: rust.map(str::to_string),
            params: params.clone(),
            ..Default::default()
        };
        let here = Path::new(".");
        let new = by(Some("follower-stopper"), None).resolve(here).unwrap();
        assert_eq!(
            new,
            by(None, Some("follower-stopper")).resolve(here).unwrap()
        );
        assert_eq!(new.label(), "follower-stopper-4.3");
        let both = by(Some("lacc"), Some("lacc")).resolve(here).unwrap_err();
        assert_eq!(
            (both.field.as_str(), both.value.as_str()),
            ("controller", "law and rust")
        );
        let unknown = by(Some("wiedemann"), None).resolve(here).unwrap_err();
        assert_eq!(unknown.field, "controller.law");
    }

    fn python(law: UserLaw) -> PythonLaw {
        match law {
            UserLaw::Python(p) => p,
            UserLaw::Rust(r) => panic!("a Python law, got {r:?}"),
        }
    }

    #[test]
    fn files_and_modules_resolve_and_bad_names_are_refused() {
        let dir = std::env::temp_dir().join(format!("syncroad-user-law-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("law.py"), "class Law: pass\n").unwrap();
        let law = python(spec("law.py:Law").resolve(&dir).unwrap());
        assert_eq!(
            law.source,
            PythonSource::File {
                path: dir.join("law.py")
            }
        );
        assert_eq!(
            law.source_hash.as_deref(),
            Some(fnv1a_hex(b"class Law: pass\n").as_str())
        );
        assert_eq!(law.params, serde_json::json!({}));
        assert_eq!(law.label(), "python:Law");
        let m = python(spec("mypkg.laws:Outer.Inner").resolve(&dir).unwrap());
        assert_eq!(
            (m.source, m.class.as_str(), m.source_hash),
            (
                PythonSource::Module {
                    module: "mypkg.laws".into()
                },
                "Outer.Inner",
                None
            )
        );
        let e = spec("law.py").resolve(&dir).unwrap_err().to_string();
        assert!(
            e.starts_with("controller.python = law.py: no class is named"),
            "{e}"
        );
        let e = spec("missing.py:Law")
            .resolve(&dir)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot read") && e.contains("missing.py"), "{e}");
        let e = spec("law.py:1Law").resolve(&dir).unwrap_err().to_string();
        assert!(e.contains("`1Law` is not a Python class name"), "{e}");
        let e = spec(".:Law").resolve(&dir).unwrap_err().to_string();
        assert!(e.contains("neither a .py file nor a module name"), "{e}");
        let mut p = spec("law.py:Law");
        p.params = Some(serde_json::json!([1, 2]));
        let e = p.resolve(&dir).unwrap_err().to_string();
        assert!(
            e.starts_with("controller.params = [1,2]: must be an object"),
            "{e}"
        );
        let e = spec("./:Law").resolve(&dir).unwrap_err().to_string();
        assert!(e.contains("is not a regular file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
