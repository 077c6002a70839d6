//! Who drives a run ([`Drive`]): the scenario's law, a wave damper, one of SUMO's drivers on
//! every vehicle, or a mixed series of automated vehicles among humans. Every command names
//! and builds its runs here; the native simulator's law for a run is
//! [`LawSpec::of_drive`](crate::controller::LawSpec::of_drive).

use super::placement::Placement;
use super::sumo_driver::{DriverError, SumoDriver};
use crate::registry::{LawNameError, NamedLaw, PROTOCOL};

/// What drives the automated vehicles of mixed runs unless named (`compare
/// --mixed-controller`, a sweep's `mixed_controller`).
pub const DEFAULT_MIXED_CONTROLLER: &str = PROTOCOL;

/// Errors naming who drives.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriveError {
    /// A damper name that does not parse.
    #[error(transparent)]
    Law(#[from] LawNameError),
    /// A driver name that does not parse.
    #[error(transparent)]
    Driver(#[from] DriverError),
    /// A controller named twice in one mixed series.
    #[error("{0} is listed twice")]
    Twice(String),
    /// A Python controller (`python:FILE.py:Class`) that cannot be loaded.
    #[error("{0}")]
    Python(String),
    /// A mixed series without a controller.
    #[error("no controller is named; name at least one (e.g. protocol)")]
    NoController,
}

/// Who drives one run: its name, the driver of each scenario vehicle, and a damper in place of
/// the law.
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    /// Folder and column name (`protocol`, `krauss-0.9`, `mixed-2`, ...).
    pub name: String,
    /// Per scenario vehicle: `None` = the law, `Some` = that SUMO model; empty: as the
    /// scenario says (its law, or its `mixed` ring).
    pub drivers: Vec<Option<SumoDriver>>,
    /// A wave damper in place of the law on the law's vehicles.
    pub damper: Option<NamedLaw>,
    /// The user's own controller in place of the scenario's law on the law's vehicles
    /// (`--baselines python:FILE.py:Class`); the run is the scenario with that controller
    /// ([`crate::Scenario::with_controller`]).
    pub user: Option<crate::user_law::UserLaw>,
}

impl Drive {
    /// Runs the same drivers as `other` (the same damper, and the same SUMO driver or the law
    /// on every vehicle, however the drivers were spelt).
    pub fn same_run(&self, other: &Self) -> bool {
        self.damper == other.damper
            && self.user == other.user
            && self.drivers.len() == other.drivers.len()
            && self
                .drivers
                .iter()
                .zip(&other.drivers)
                .all(|(a, b)| match (a, b) {
                    (None, None) => true,
                    (Some(a), Some(b)) => a.same_driver(b),
                    _ => false,
                })
    }

    /// The scenario as written: its law on every one of its `vehicles` (`protocol`), the
    /// mixed ring of its `mixed` block (`mixed`), or — a road without vehicles of its own —
    /// its inflows alone (`inflows`): what `syncroad run` runs and a sweep without `runs`.
    pub fn as_written(mixed: bool, vehicles: usize) -> Self {
        let name = match (vehicles, mixed) {
            (0, _) => "inflows",
            (_, true) => "mixed",
            _ => PROTOCOL,
        };
        Self {
            name: name.into(),
            drivers: Vec::new(),
            damper: None,
            user: None,
        }
    }

    /// `protocol` (the scenario's law on every vehicle, whatever its `mixed` block says), a
    /// damper (`follower-stopper-U`, `pi-saturation`) on every vehicle, the user's Python class
    /// (`python:FILE.py:Class`, the file relative to the current folder, its keyword arguments
    /// after it as `:NAME=VALUE`) on every vehicle, or a
    /// SUMO driver name for all `n` vehicles; `field` names where the name was given, for
    /// errors.
    pub fn parse(field: &str, name: &str, n: usize) -> Result<Self, DriveError> {
        if let Some(python) = name.trim().strip_prefix("python:") {
            // The user's class, its file relative to the current folder, on every vehicle;
            // its keyword arguments follow as `:NAME=VALUE` (JSON values, else strings).
            let parts: Vec<&str> = python.split(':').collect();
            let first = parts
                .iter()
                .position(|p| p.contains('='))
                .unwrap_or(parts.len());
            let mut params = serde_json::Map::new();
            for kv in &parts[first..] {
                let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
                let value = serde_json::from_str(v).unwrap_or_else(|_| serde_json::json!(v));
                params.insert(k.to_string(), value);
            }
            let spec = crate::user_law::ControllerSpec {
                python: Some(parts[..first].join(":")),
                params: Some(serde_json::Value::Object(params)),
                ..Default::default()
            };
            let user = spec
                .resolve(std::path::Path::new("."))
                .map_err(|e| DriveError::Python(format!("{name}: {}: {}", e.value, e.expected)))?;
            return Ok(Self {
                name: user.label(),
                drivers: vec![None; n],
                damper: None,
                user: Some(user),
            });
        }
        let low = name.trim().to_ascii_lowercase();
        if low == PROTOCOL || low == "law" {
            return Ok(Self {
                name: PROTOCOL.into(),
                drivers: vec![None; n],
                damper: None,
                user: None,
            });
        }
        let driver = SumoDriver::parse(field, name);
        // A stochastic human is the driver of its name on each vehicle, as `mixed.human` and
        // `--mixed-driver` name it (the table's `noisy-idm` drives as that driver does); else
        // a law of the registry (a damper, a built-in law, the program's own) by its name;
        // any other name is one of SUMO's drivers.
        if !matches!(driver, Ok(SumoDriver::Noisy(_))) {
            match NamedLaw::parse(field, name) {
                Ok(Some(d)) => {
                    return Ok(Self {
                        name: d.to_string(),
                        drivers: vec![None; n],
                        damper: Some(d),
                        user: None,
                    })
                }
                Err(e @ LawNameError::Params { .. }) => return Err(e.into()),
                Ok(None) | Err(_) => {}
            }
        }
        let d = driver?;
        Ok(Self {
            name: d.to_string(),
            drivers: vec![Some(d); n],
            damper: None,
            user: None,
        })
    }

    /// `k` of `n` vehicles run the law (or the controller in its place), spread evenly ([`Placement::Even`]);
    /// the others are `human`.
    pub fn mixed(
        name: String,
        n: usize,
        k: usize,
        human: SumoDriver,
        controller: MixedController,
    ) -> Self {
        let mut drivers = vec![Some(human); n];
        for i in Placement::Even.automated(n, k, 0) {
            drivers[i] = None;
        }
        let MixedController { damper, user } = controller;
        Self {
            name,
            drivers,
            damper: if k > 0 { damper } else { None },
            user: if k > 0 { user } else { None },
        }
    }

    /// Labels of who drives each vehicle, as SUMO runs report them (`protocol`, a damper's or a
    /// driver's name).
    pub fn labels(&self, n: usize) -> Vec<String> {
        let commanded = self
            .damper
            .as_ref()
            .map_or_else(|| PROTOCOL.to_string(), |d| d.to_string());
        if self.drivers.is_empty() {
            return vec![commanded; n];
        }
        self.drivers
            .iter()
            .map(|d| {
                d.as_ref()
                    .map_or_else(|| commanded.clone(), |d| d.to_string())
            })
            .collect()
    }
}

/// What drives the automated vehicles of one mixed series: the scenario's law (neither set),
/// a law of the registry in its place, or the user's Python class.
#[derive(Debug, Clone, PartialEq)]
pub struct MixedController {
    /// A law of the registry in place of the scenario's law.
    pub damper: Option<NamedLaw>,
    /// The user's Python class in place of the scenario's law (`python:FILE.py:Class`).
    pub user: Option<crate::user_law::UserLaw>,
}

impl MixedController {
    /// The scenario's own law drives.
    pub fn is_law(&self) -> bool {
        self.damper.is_none() && self.user.is_none()
    }
}

impl std::fmt::Display for MixedController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (&self.user, &self.damper) {
            (Some(u), _) => f.write_str(&u.label()),
            (None, Some(d)) => write!(f, "{d}"),
            (None, None) => f.write_str(PROTOCOL),
        }
    }
}

/// The controllers of a mixed series by name: `protocol`, a law of the registry
/// ([`NamedLaw::parse`]) or the user's Python class (`python:FILE.py:Class:NAME=VALUE`, as
/// [`Drive::parse`] reads it), each once, at least one; `field` names where they were given.
pub fn mixed_controllers<S: AsRef<str>>(
    field: &str,
    names: &[S],
) -> Result<Vec<MixedController>, DriveError> {
    let mut out = Vec::new();
    for c in names.iter().map(|c| c.as_ref().trim()) {
        let d = if c.starts_with("python:") {
            MixedController {
                damper: None,
                user: Drive::parse(field, c, 0)?.user,
            }
        } else {
            MixedController {
                damper: NamedLaw::parse(field, c)?,
                user: None,
            }
        };
        if out.contains(&d) {
            return Err(DriveError::Twice(c.to_string()));
        }
        out.push(d);
    }
    if out.is_empty() {
        return Err(DriveError::NoController);
    }
    Ok(out)
}

/// The mixed runs with `k` of `n` vehicles automated among `human` drivers, `label` naming
/// the share (`2` vehicles in `compare`, `0.25` of them in a sweep): one run per controller,
/// `CONTROLLER-mixed-LABEL` (`protocol-mixed-2`, `pi-saturation-mixed-2`,
/// `python:MyLaw-mixed-2`). The all-human ring (`k = 0`) is the same whatever would control,
/// so it is one run, `mixed-LABEL`.
pub fn mixed_series(
    n: usize,
    k: usize,
    label: &str,
    controllers: &[MixedController],
    human: &SumoDriver,
) -> Vec<Drive> {
    let with = if k == 0 {
        &controllers[..controllers.len().min(1)]
    } else {
        controllers
    };
    with.iter()
        .map(|c| {
            let name = if k == 0 {
                format!("mixed-{label}")
            } else {
                format!("{c}-mixed-{label}")
            };
            Drive::mixed(name, n, k, human.clone(), c.clone())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mixed_series_names_each_controller_and_runs_the_all_human_ring_once() {
        let human = SumoDriver::parse("d", "human").unwrap();
        let c = mixed_controllers("--mixed-controller", &["protocol", "pi-saturation"]).unwrap();
        let names = |k| -> Vec<String> {
            mixed_series(22, k, &k.to_string(), &c, &human)
                .into_iter()
                .map(|r| r.name)
                .collect()
        };
        assert_eq!(names(0), ["mixed-0"]);
        assert_eq!(names(2), ["protocol-mixed-2", "pi-saturation-mixed-2"]);
        let runs = mixed_series(22, 2, "2", &c, &human);
        // k of n vehicles are the controller's, spread evenly (vehicles 0 and 11); the
        // damper drives them in the second run only.
        for r in &runs {
            let automated: Vec<usize> = (0..22).filter(|&i| r.drivers[i].is_none()).collect();
            assert_eq!(automated, [0, 11]);
        }
        assert_eq!(
            (runs[0].damper.is_none(), runs[1].damper.is_some()),
            (true, true)
        );
        assert_eq!(
            // `law` is the protocol's older spelling: the same controller twice.
            mixed_controllers("mixed_controller", &["protocol", "law"]),
            Err(DriveError::Twice("law".into()))
        );
        assert_eq!(
            mixed_controllers::<&str>("mixed_controller", &[]),
            Err(DriveError::NoController)
        );
    }

    #[test]
    fn runs_parse_by_name_and_spellings_of_one_driver_are_the_same_run() {
        let p = Drive::parse("--baselines", "protocol", 22).unwrap();
        assert!(p.drivers == vec![None; 22] && p.damper.is_none());
        assert_eq!(Drive::parse("--baselines", "law", 22).unwrap(), p);
        let d = Drive::parse("--baselines", "pi-saturation", 22).unwrap();
        assert_eq!((d.drivers.len(), d.damper.is_some()), (22, true));
        let a = Drive::parse("--baselines", "krauss-0.9", 22).unwrap();
        let b = Drive::parse("--baselines", "krauss:sigma=0.9", 22).unwrap();
        assert!(a.same_run(&b) && !a.same_run(&p));
        assert!(matches!(
            Drive::parse("--baselines", "wiedemann", 22),
            Err(DriveError::Driver(_))
        ));
        assert_eq!(a.labels(22), vec!["krauss-0.9".to_string(); 22]);
        assert_eq!(d.labels(22), vec!["pi-saturation".to_string(); 22]);
        // The scenario's own law labels the vehicles it drives, given or not.
        assert_eq!(p.labels(22), vec!["protocol".to_string(); 22]);
        assert_eq!(
            Drive::as_written(false, 2).labels(2),
            ["protocol", "protocol"]
        );
        assert_eq!(Drive::as_written(true, 2).name, "mixed");
        assert_eq!(Drive::as_written(false, 0).name, "inflows");
    }
}
