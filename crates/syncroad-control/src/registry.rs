//! The one table of laws that drive vehicles in place of the scenario's model law: the field's
//! wave dampers and the other built-in laws ([`BUILT_IN`], one line each), and the laws the
//! running program registers itself ([`register`]). A law is one [`LawEntry`]: its name, the
//! road it needs, its parameters and how it is built. Scenario files
//! (`"controller": {"rust": NAME, "params": {...}}`, `mixed.controller`), the commands'
//! driver names (`compare --baselines`, sweeps) and both backends resolve a name here and
//! nowhere else.
//!
//! A name is written as the law's name, or — for a law with a shorthand parameter — with its
//! value after it: `follower-stopper-4.3` is `follower-stopper` with
//! `{"desired_speed_mps": 4.3}`. That spelling is also the law's name in tables and folders.
//!
//! A SUMO run steps its law inside a worker process, which is the program itself started
//! again (see `syncroad_sumo::worker_main`): the law travels as its name and parameters, and
//! the worker builds it from its own registry. So a program registers its laws first thing in
//! `main`, before it serves as a worker or runs anything:
//!
//! ```
//! use syncroad_control::registry;
//! use syncroad_control::speed_controller::{LawContext, LawEntry};
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
//! registry::register(LawEntry::new("hold", hold)).unwrap();
//! assert!(registry::lookup("hold").is_ok());
//! ```
//!
//! # Adding a built-in law
//! One file with the law, its [`SpeedController`] and its `ENTRY`, and one line in
//! [`BUILT_IN`] (the guide's "Your own controller" page shows the diff of `constant-speed`).

use std::fmt;
use std::sync::RwLock;

use serde::{Deserialize, Serialize};

use crate::fingerprint::fnv1a_hex;
use crate::speed_controller::{LawContext, LawEntry, Road, SpeedController};

pub use crate::protocol_law::PROTOCOL;

/// The built-in laws, one line each.
pub static BUILT_IN: &[LawEntry] = &[
    crate::protocol_law::ENTRY,
    crate::follower_stopper::ENTRY,
    crate::pi_saturation::ENTRY,
    crate::flow_dampers::FOLLOWER_STOPPER_ENTRY,
    crate::flow_dampers::PI_SATURATION_ENTRY,
    crate::constant_speed::ENTRY,
    crate::delayed_follower::ENTRY,
    crate::bcm::ENTRY,
    crate::lacc::ENTRY,
    crate::noisy_idm::ENTRY,
];

static REGISTERED: RwLock<Vec<LawEntry>> = RwLock::new(Vec::new());

/// Errors registering a law.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegistryError {
    /// The name is taken.
    #[error("a law named {0} is already registered")]
    Taken(String),
    /// The name has characters a folder or a table column would not keep.
    #[error("law name {0:?}: use letters, digits, - and _ (at least one character)")]
    BadName(String),
}

/// Registers `entry` for this process (its name must not be taken, by a built-in law
/// either).
pub fn register(entry: LawEntry) -> Result<(), RegistryError> {
    let ok = !entry.name.is_empty()
        && entry
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !ok {
        return Err(RegistryError::BadName(entry.name.to_string()));
    }
    let mut laws = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    if BUILT_IN
        .iter()
        .chain(laws.iter())
        .any(|l| l.name == entry.name)
        || entry.name == "law"
    {
        return Err(RegistryError::Taken(entry.name.to_string()));
    }
    laws.push(entry);
    Ok(())
}

/// Every law: the built-in ones, then those this program registered.
pub fn entries() -> Vec<LawEntry> {
    let laws = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    BUILT_IN.iter().chain(laws.iter()).copied().collect()
}

/// The law named `name`, or what would be valid (for an error naming the field).
pub fn lookup(name: &str) -> Result<LawEntry, String> {
    let all = entries();
    if let Some(l) = all.iter().find(|l| l.name == name) {
        return Ok(*l);
    }
    Err(format!(
        "no law of that name; valid: {}. A Rust law of your own runs from the program that registers it (syncroad_control::registry::register, see the guide's \"Your own controller\")",
        valid_names()
    ))
}

/// The valid spellings, for error messages: `protocol, follower-stopper-U (U =
/// desired_speed_mps), pi-saturation, ...`.
pub fn valid_names() -> String {
    names_of(&entries())
}

/// The valid spellings of the laws that drive a vehicle alone, behind whoever is ahead of it
/// (an inflow's vehicles): those that do not read the vehicle behind.
pub fn valid_names_alone() -> String {
    let alone: Vec<LawEntry> = entries().into_iter().filter(|e| !e.looks_behind).collect();
    names_of(&alone)
}

fn names_of(entries: &[LawEntry]) -> String {
    entries
        .iter()
        .map(|l| match l.shorthand {
            Some(key) => format!("{}-X (X = {key}, e.g. {}-4.3)", l.name, l.name),
            None => l.name.to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Errors naming a law.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LawNameError {
    /// No law of that name.
    #[error("{field} = {value}: unknown controller; use {valid}")]
    Unknown {
        /// Flag or field.
        field: String,
        /// The value.
        value: String,
        /// What would be valid.
        valid: String,
    },
    /// The law refused its parameters.
    #[error("{field}: {reason}")]
    Params {
        /// Flag or field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The law follows a predecessor around a ring.
    #[error("{law}: this law drives on a ring (each vehicle follows its predecessor); {road} is a straight road")]
    NotARing {
        /// The law.
        law: String,
        /// The road: `scenario NAME`, or `this road`.
        road: String,
    },
}

impl LawNameError {
    /// What is wrong, without the field (for errors that name it their own way).
    pub fn why(&self) -> String {
        match self {
            LawNameError::Unknown { valid, .. } => format!("unknown controller; use {valid}"),
            LawNameError::Params { reason, .. } => reason.clone(),
            e @ LawNameError::NotARing { .. } => e.to_string(),
        }
    }
}

/// A law of the registry, by name and parameters: a damper a run names, or the scenario's
/// `controller.rust`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NamedLaw {
    /// Its name in the registry.
    pub name: String,
    /// Its parameters (a JSON object; empty when none).
    pub params: serde_json::Value,
}

impl NamedLaw {
    /// Parses a driver name (`follower-stopper-4.3`, `pi-saturation`, a registered law's
    /// name) and checks its parameters; `Ok(None)` for [`PROTOCOL`] (or its older spelling
    /// `law`), the scenario's own. `field`
    /// names the flag or field in errors.
    pub fn parse(field: &str, s: &str) -> Result<Option<Self>, LawNameError> {
        let low = s.trim().to_ascii_lowercase().replace('_', "-");
        if low == PROTOCOL || low == "law" {
            return Ok(None);
        }
        let all = entries();
        let found = all.iter().find_map(|l| {
            // A law with a shorthand is named with it (`follower-stopper-4.3`).
            if l.shorthand.is_none() && l.name.replace('_', "-") == low {
                return Some((l, serde_json::json!({})));
            }
            let key = l.shorthand?;
            let x: f64 = low
                .strip_prefix(&l.name.replace('_', "-"))?
                .strip_prefix('-')?
                .parse()
                .ok()?;
            Some((l, serde_json::json!({ key: x })))
        });
        let Some((entry, params)) = found else {
            return Err(LawNameError::Unknown {
                field: field.into(),
                value: s.into(),
                valid: valid_names(),
            });
        };
        let law = NamedLaw {
            name: entry.name.to_string(),
            params,
        };
        law.check(field)?;
        Ok(Some(law))
    }

    /// The law a scenario names by `name` with `params` added (`{"law": NAME, "params": …}`):
    /// its bare name (`constant-speed`) or one with its shorthand (`constant-speed-25`), the
    /// parameters checked; `Ok(None)` for [`PROTOCOL`], the scenario's own.
    pub fn named(
        field: &str,
        name: &str,
        params: Option<&serde_json::Map<String, serde_json::Value>>,
    ) -> Result<Option<Self>, LawNameError> {
        let bare = lookup(name)
            .ok()
            .filter(|e| e.name != PROTOCOL)
            .map(|e| NamedLaw {
                name: e.name.to_string(),
                params: serde_json::json!({}),
            });
        let Some(mut law) = (match bare {
            Some(law) => Some(law),
            None => Self::parse(field, name)?,
        }) else {
            return Ok(None);
        };
        if let (Some(extra), Some(own)) = (params, law.params.as_object_mut()) {
            own.extend(extra.clone());
        }
        law.check(field)?;
        Ok(Some(law))
    }

    /// The law's entry (built-in, or registered by this program).
    pub fn entry(&self) -> Result<LawEntry, String> {
        lookup(&self.name)
    }

    /// Whether a built-in law (its name in tables has no `rust:` before it).
    pub fn is_built_in(&self) -> bool {
        BUILT_IN.iter().any(|l| l.name == self.name)
    }

    /// Checks that the law exists and takes its parameters; `field` names where it was given.
    pub fn check(&self, field: &str) -> Result<(), LawNameError> {
        let params = |reason| LawNameError::Params {
            field: field.into(),
            reason,
        };
        let entry = self.entry().map_err(params)?;
        (entry.check)(&self.params).map_err(params)
    }

    /// The one check that the law has the road it needs: every command and both backends ask
    /// it, so the refusal reads the same everywhere. `road` names the road in the message
    /// (`scenario NAME`).
    pub fn require_road(&self, ring: bool, road: &str) -> Result<(), LawNameError> {
        match self.entry().map(|e| e.road) {
            Ok(Road::Ring) if !ring => Err(LawNameError::NotARing {
                law: self.to_string(),
                road: road.to_string(),
            }),
            _ => Ok(()),
        }
    }

    /// Builds the law for a run (its road checked against the context's).
    pub fn build(&self, context: &LawContext) -> Result<Box<dyn SpeedController>, String> {
        let entry = self.entry()?;
        self.require_road(context.ring_length_m.is_some(), "this road")
            .map_err(|e| e.to_string())?;
        (entry.build)(context, &self.params)
    }

    /// Builds the law for one vehicle that drives alone behind whoever is ahead of it, which
    /// its context's sensing reports each step (an inflow's `controlled` vehicle): a ring
    /// law's predecessor is then that vehicle, so the road check does not apply; a law that
    /// looks behind is refused.
    pub fn build_alone(&self, context: &LawContext) -> Result<Box<dyn SpeedController>, String> {
        let entry = self.entry()?;
        if entry.looks_behind {
            return Err(format!(
                "{self} reads the vehicle behind each vehicle too; a vehicle driven alone senses only the one ahead"
            ));
        }
        (entry.build)(context, &self.params)
    }
}

impl NamedLaw {
    /// The scenario's own law, [`PROTOCOL`].
    pub fn protocol() -> Self {
        Self {
            name: PROTOCOL.into(),
            params: serde_json::json!({}),
        }
    }

    /// The law as a reader wants it: its name in tables when that is its name or its
    /// shorthand (`follower-stopper-4.3`), else its name with its parameters
    /// (`delayed-driver {"gain":0.6,"delay_s":0.5}`) rather than their hash.
    pub fn described(&self) -> String {
        let shown = self.to_string();
        let plain = self.params.as_object().is_none_or(|o| o.is_empty())
            || shown != format!("{}-{}", self.name, &fnv1a_hex(self.params.to_string())[..8]);
        if plain {
            shown
        } else {
            format!("{} {}", self.name, self.params)
        }
    }
}

impl fmt::Display for NamedLaw {
    /// The law's name in tables and folders: its name, with its shorthand parameter when that
    /// is the only one (`follower-stopper-4.3`), or a hash of its parameters when it has
    /// others (`follower-stopper-3f2a9c1e`), so different parameters never share a folder.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let obj = self.params.as_object();
        if obj.is_none_or(|o| o.is_empty()) {
            return write!(f, "{}", self.name);
        }
        let short = self.entry().ok().and_then(|e| e.shorthand);
        if let (Some(key), Some(o)) = (short, obj) {
            if o.len() == 1 {
                if let Some(x) = o.get(key).and_then(serde_json::Value::as_f64) {
                    return write!(f, "{}-{x}", self.name);
                }
            }
        }
        let hash = fnv1a_hex(self.params.to_string());
        write!(f, "{}-{}", self.name, &hash[..8])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_law_with_parameters_is_described_with_them() {
        let law = |name: &str, params: serde_json::Value| NamedLaw {
            name: name.into(),
            params,
        };
        assert_eq!(
            law(
                "follower-stopper",
                serde_json::json!({"desired_speed_mps": 4.3})
            )
            .described(),
            "follower-stopper-4.3"
        );
        assert_eq!(
            law("pi-saturation", serde_json::json!({})).described(),
            "pi-saturation"
        );
        let d = law(
            "delayed-driver",
            serde_json::json!({"gain": 0.6, "delay_s": 0.5}),
        );
        assert!(d.to_string().starts_with("delayed-driver-"), "{d}");
        let text = d.described();
        assert!(
            text.starts_with("delayed-driver {")
                && text.contains(r#""gain":0.6"#)
                && text.contains(r#""delay_s":0.5"#),
            "{text}"
        );
    }

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
        register(LawEntry::new("registry-test-hold", hold)).unwrap();
        assert_eq!(
            register(LawEntry::new("registry-test-hold", hold))
                .unwrap_err()
                .to_string(),
            "a law named registry-test-hold is already registered"
        );
        // A built-in name is taken too.
        assert!(matches!(
            register(LawEntry::new("pi-saturation", hold)),
            Err(RegistryError::Taken(_))
        ));
        assert!(matches!(
            register(LawEntry::new("a b", hold)),
            Err(RegistryError::BadName(_))
        ));
        assert_eq!(
            lookup("registry-test-hold").unwrap().name,
            "registry-test-hold"
        );
        let e = lookup("nope").unwrap_err();
        assert!(
            e.contains("valid: ")
                && e.contains("registry-test-hold")
                && e.contains("pi-saturation"),
            "{e}"
        );
        // A registered law is named like a built-in one.
        let l = NamedLaw::parse("--x", "registry-test-hold")
            .unwrap()
            .unwrap();
        assert!(!l.is_built_in());
        assert_eq!(l.to_string(), "registry-test-hold");
    }

    #[test]
    fn names_parse_and_round_trip() {
        assert_eq!(NamedLaw::parse("--x", "protocol").unwrap(), None);
        assert_eq!(NamedLaw::parse("--x", "law").unwrap(), None);
        let fs = NamedLaw::parse("--x", "follower-stopper-4.3")
            .unwrap()
            .unwrap();
        assert_eq!(fs.name, "follower-stopper");
        assert_eq!(fs.params, serde_json::json!({"desired_speed_mps": 4.3}));
        assert_eq!(fs.to_string(), "follower-stopper-4.3");
        for name in [
            "flow-follower-stopper-4.3",
            "flow-pi-saturation",
            "pi-saturation",
            "constant-speed-7.5",
        ] {
            let d = NamedLaw::parse("--x", name).unwrap().unwrap();
            assert!(d.is_built_in());
            assert_eq!(d.to_string(), name);
        }
        assert_eq!(
            NamedLaw::parse("--x", "PI_saturation")
                .unwrap()
                .unwrap()
                .name,
            "pi-saturation"
        );
        let e = NamedLaw::parse("--x", "follower-stopper").unwrap_err();
        assert!(
            e.to_string().starts_with(
                "--x = follower-stopper: unknown controller; use protocol, follower-stopper-X (X = desired_speed_mps"
            ),
            "{e}"
        );
        let e = NamedLaw::parse("--x", "follower-stopper--1").unwrap_err();
        assert_eq!(
            e.to_string(),
            "--x: FollowerStopper desired_speed_mps = -1: valid is a finite number ≥ 0 m/s"
        );
        // More parameters than the shorthand: the name carries their hash.
        let more = NamedLaw {
            name: "follower-stopper".into(),
            params: serde_json::json!({"desired_speed_mps": 4.3, "dx0_m": [4.0, 5.0, 6.0]}),
        };
        more.check("controller.params").unwrap();
        let shown = more.to_string();
        assert!(
            shown.starts_with("follower-stopper-") && shown.len() == 25,
            "{shown}"
        );
        assert_ne!(shown, fs.to_string());
        let bad = NamedLaw {
            name: "pi-saturation".into(),
            params: serde_json::json!({"gain": 1.0}),
        };
        let e = bad.check("controller.params").unwrap_err().to_string();
        assert!(
            e.starts_with("controller.params: params {\"gain\":1.0}: unknown field `gain`"),
            "{e}"
        );
    }

    #[test]
    fn ring_laws_refuse_a_straight_road() {
        let pi = NamedLaw::parse("--x", "pi-saturation").unwrap().unwrap();
        assert!(pi.require_road(true, "scenario r").is_ok());
        assert_eq!(
            pi.require_road(false, "scenario s").unwrap_err().to_string(),
            "pi-saturation: this law drives on a ring (each vehicle follows its predecessor); scenario s is a straight road"
        );
        let c = NamedLaw::parse("--x", "constant-speed-5").unwrap().unwrap();
        assert!(c.require_road(false, "scenario s").is_ok());
    }

    fn ring(n: usize) -> LawContext {
        LawContext {
            step_s: 0.1,
            ids: (0..n).map(|i| format!("v{i}")).collect(),
            length_m: vec![5.0; n],
            ring_length_m: Some(100.0),
            controlled: vec![true; n],
            accel_mps2: f64::INFINITY,
            decel_mps2: f64::INFINITY,
            speed_limit_mps: None,
            signals: false,
            seed: 0,
            protocol: None,
        }
    }

    fn built(name: &str) -> Box<dyn SpeedController> {
        NamedLaw::parse("--x", name)
            .unwrap()
            .unwrap()
            .build(&ring(3))
            .unwrap()
    }

    #[test]
    fn ring_gaps_wrap_and_follower_stopper_follows_its_bands() {
        // Three 5 m cars on a 100 m ring, rear bumpers at 60, 40, 10: gaps
        // vehicle 1: 60 − 40 − 5 = 15, vehicle 2: 40 − 10 − 5 = 25,
        // vehicle 0 (follows 2 one lap ahead): 10 + 100 − 60 − 5 = 45.
        let mut c = built("follower-stopper-8");
        let q = [60.0, 40.0, 10.0];
        let v = [5.0, 5.0, 5.0];
        let mut out = [0.0; 3];
        c.step(0.0, &v, &q, &mut out);
        // Every gap is beyond Δx_3 = 6 m with Δv = 0: command U = 8, reached in one step.
        assert_eq!(out, [8.0, 8.0, 8.0]);
        // Vehicle 1 closer: gap 5.625 m (q = 60 − 5 − 5.625 = 49.375) lies in the third band
        // (5.25, 6]: v = min(v_lead, U) = 5, command 5 + (8 − 5)·(5.625 − 5.25)/0.75 = 6.5.
        let q = [60.0, 49.375, 10.0];
        c.step(0.1, &v, &q, &mut out);
        approx::assert_relative_eq!(out[1], 6.5, epsilon = 1e-12);
        // Vehicle 0 at 100.1: its leader, vehicle 2, is a lap ahead, gap 10 + 100 − 100.1 − 5
        // = 4.9 m, in the second band (Δx_1, Δx_2] = (4.5, 5.25] at Δv = 0: command
        // v (Δx − Δx_1)/(Δx_2 − Δx_1) = 5 · 0.4/0.75 — only the wrap gives vehicle 0 that gap.
        let q = [100.1, 49.375, 10.0];
        c.step(0.2, &v, &q, &mut out);
        approx::assert_relative_eq!(out[0], 5.0 * 0.4 / 0.75, epsilon = 1e-12);
    }

    #[test]
    fn pi_saturation_on_the_ring_saturates_to_the_leader_at_a_small_gap() {
        // Gap below the safe gap Δx_s = max(2 Δv, 4) = 4 m: α = 0, β = 1, command = v_lead.
        let mut c = built("pi-saturation");
        // Vehicle 1 is 3 m behind vehicle 0 (q = 60 − 5 − 3 = 52); vehicle 0 drives 4 m/s.
        let q = [60.0, 52.0, 10.0];
        let v = [4.0, 6.0, 6.0];
        let mut out = [0.0; 3];
        c.step(0.0, &v, &q, &mut out);
        approx::assert_relative_eq!(out[1], 4.0, epsilon = 1e-12);
    }

    #[test]
    fn constant_speed_tracks_its_target_within_the_vehicles_bounds() {
        // Target 7 m/s from 5 m/s with a_max = 2.6, b = 4.5, Δt = 0.1: +0.26 per step, and
        // from 9 m/s −0.45 per step (SUMO's passenger-car defaults).
        let mut ctx = ring(2);
        ctx.accel_mps2 = 2.6;
        ctx.decel_mps2 = 4.5;
        ctx.ring_length_m = None;
        let law = NamedLaw::parse("--x", "constant-speed-7").unwrap().unwrap();
        let mut c = law.build(&ctx).unwrap();
        let mut out = [0.0; 2];
        c.step(0.0, &[5.0, 9.0], &[50.0, 0.0], &mut out);
        approx::assert_relative_eq!(out[0], 5.26, epsilon = 1e-12);
        approx::assert_relative_eq!(out[1], 8.55, epsilon = 1e-12);
        c.step(0.1, &[6.9, 7.0], &[50.0, 0.0], &mut out);
        assert_eq!(out, [7.0, 7.0]);
    }
}
