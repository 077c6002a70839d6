//! The program's own Rust laws, by name: a scenario's `"controller": {"rust": "NAME",
//! "params": {...}}` drives its vehicles with the law the running program registered under
//! that name.
//!
//! A SUMO run steps its law inside a worker process, which is the program itself started
//! again (see `syncroad_sumo::worker_main`): the law travels as its name and parameters, and
//! the worker builds it from its own registry. So a program registers its laws first thing in
//! `main`, before it serves as a worker or runs anything:
//!
//! ```
//! use syncroad_control::registry::{self, RustLawEntry};
//! use syncroad_control::user_law::LawContext;
//! use syncroad_control::SpeedController;
//!
//! struct Hold;
//! impl SpeedController for Hold {
//!     fn step(&mut self, _t: f64, v: &[f64], _q: &[f64], next: &mut [f64]) {
//!         next.copy_from_slice(v);
//!     }
//! }
//! fn hold(_: &LawContext, _: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
//!     Ok(Box::new(Hold))
//! }
//! registry::register(RustLawEntry { name: "hold", build: hold }).unwrap();
//! assert!(registry::lookup("hold").is_ok());
//! ```

use std::sync::RwLock;

use crate::speed_controller::{LawContext, SpeedController};

/// Builds a law for a run from its parameters; an `Err` says what is wrong with them.
pub type BuildLaw = fn(&LawContext, &serde_json::Value) -> Result<Box<dyn SpeedController>, String>;

/// One registered law.
#[derive(Debug, Clone, Copy)]
pub struct RustLawEntry {
    /// Its name in scenarios (`controller.rust`): letters, digits, `-` and `_`.
    pub name: &'static str,
    /// Builds it.
    pub build: BuildLaw,
}

static LAWS: RwLock<Vec<RustLawEntry>> = RwLock::new(Vec::new());

/// Errors registering a law.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegistryError {
    /// The name is taken.
    #[error("a Rust law named {0} is already registered")]
    Taken(String),
    /// The name has characters a folder or a table column would not keep.
    #[error("Rust law name {0:?}: use letters, digits, - and _ (at least one character)")]
    BadName(String),
}

/// Registers `entry` for this process.
pub fn register(entry: RustLawEntry) -> Result<(), RegistryError> {
    let ok = !entry.name.is_empty()
        && entry
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !ok {
        return Err(RegistryError::BadName(entry.name.to_string()));
    }
    let mut laws = LAWS.write().unwrap_or_else(|e| e.into_inner());
    if laws.iter().any(|l| l.name == entry.name) {
        return Err(RegistryError::Taken(entry.name.to_string()));
    }
    laws.push(entry);
    Ok(())
}

/// The law registered as `name`, or what would be valid (for an error naming the field).
pub fn lookup(name: &str) -> Result<RustLawEntry, String> {
    let laws = LAWS.read().unwrap_or_else(|e| e.into_inner());
    if let Some(l) = laws.iter().find(|l| l.name == name) {
        return Ok(*l);
    }
    Err(if laws.is_empty() {
        "this program registered no Rust laws; a Rust law runs from the program that registers it (syncroad_control::registry::register, see the guide's \"Your own controller\")".to_string()
    } else {
        let names: Vec<&str> = laws.iter().map(|l| l.name).collect();
        format!(
            "no Rust law of that name is registered; registered: {}",
            names.join(", ")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Hold;
    impl SpeedController for Hold {
        fn step(&mut self, _t: f64, v: &[f64], _q: &[f64], next: &mut [f64]) {
            next.copy_from_slice(v);
        }
    }

    fn hold(_: &LawContext, _: &serde_json::Value) -> Result<Box<dyn SpeedController>, String> {
        Ok(Box::new(Hold))
    }

    #[test]
    fn names_are_unique_and_plain() {
        register(RustLawEntry {
            name: "registry-test-hold",
            build: hold,
        })
        .unwrap();
        assert_eq!(
            register(RustLawEntry {
                name: "registry-test-hold",
                build: hold,
            })
            .unwrap_err()
            .to_string(),
            "a Rust law named registry-test-hold is already registered"
        );
        assert!(matches!(
            register(RustLawEntry {
                name: "a b",
                build: hold
            }),
            Err(RegistryError::BadName(_))
        ));
        assert_eq!(
            lookup("registry-test-hold").unwrap().name,
            "registry-test-hold"
        );
        let e = lookup("nope").unwrap_err();
        assert!(
            e.contains("registered: ") && e.contains("registry-test-hold"),
            "{e}"
        );
    }
}
