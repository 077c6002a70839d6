//! Who drives in a run: the scenario's law, a wave damper, one of SUMO's drivers, or a mix.
//! `compare` and `sweep` name runs the same way.

use syncroad_control::drive::Placement;
use syncroad_control::{DamperSetup, DamperSpec, HumanSetup, LawSpec, Scenario, SumoDriver};

use crate::error::InputError;

/// The longest run folder name [`RunSpec::folder`] gives (bytes).
pub const FOLDER_MAX: usize = 96;

/// The automated vehicles of mixed runs unless named (`compare --mixed-controller`).
pub const DEFAULT_MIXED_CONTROLLER: &str = "law";

/// One run: a name, who drives each scenario vehicle, and a damper in place of the law.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    /// Folder and column name (`protocol`, `krauss-0.9`, `mixed-2`, ...).
    pub name: String,
    /// Per scenario vehicle: `None` = the law, `Some` = that SUMO model; empty: as the
    /// scenario says (its law, or its `mixed` ring).
    pub drivers: Vec<Option<SumoDriver>>,
    /// A wave damper in place of the law on the law's vehicles.
    pub damper: Option<DamperSpec>,
}

impl RunSpec {
    /// Runs the same drivers as `other` (the same damper, and the same SUMO driver or the law
    /// on every vehicle, however the drivers were spelt).
    pub fn same_run(&self, other: &Self) -> bool {
        self.damper == other.damper
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

    /// `protocol` (the scenario's law), a damper (`follower-stopper-U`, `pi-saturation`) on
    /// every vehicle, or a SUMO driver name for all `n` vehicles; `field` names where the name
    /// was given, for errors.
    pub fn parse(field: &str, name: &str, n: usize) -> Result<Self, InputError> {
        let low = name.to_ascii_lowercase();
        if low == "protocol" {
            return Ok(Self {
                name: "protocol".into(),
                drivers: Vec::new(),
                damper: None,
            });
        }
        if [
            "follower-stopper",
            "pi-saturation",
            "flow-follower-stopper",
            "flow-pi-saturation",
        ]
        .iter()
        .any(|p| low.starts_with(p))
        {
            let d = DamperSpec::parse(field, name)
                .map_err(|e| InputError::caused(field, e))?
                .expect("a damper name");
            return Ok(Self {
                name: d.to_string(),
                drivers: vec![None; n],
                damper: Some(d),
            });
        }
        let d = SumoDriver::parse(field, name).map_err(|e| InputError::caused(field, e))?;
        Ok(Self {
            name: d.to_string(),
            drivers: vec![Some(d); n],
            damper: None,
        })
    }

    /// `k` of `n` vehicles run the law (or `damper`), spread evenly ([`Placement::Even`]);
    /// the others are `human`.
    pub fn mixed(
        name: String,
        n: usize,
        k: usize,
        human: SumoDriver,
        damper: Option<DamperSpec>,
    ) -> Self {
        let mut drivers = vec![Some(human); n];
        for i in Placement::Even.automated(n, k, 0) {
            drivers[i] = None;
        }
        Self {
            name,
            drivers,
            damper: if k > 0 { damper } else { None },
        }
    }

    /// The law of this run on the native simulator: the scenario's law with the damper and the
    /// stochastic humans on a ring of the scenario's length; `None` when a SUMO driver takes
    /// part (only SUMO runs it: a run that leaves the drivers to a scenario with a `mixed`
    /// block included) or a damper or human is asked for on a straight road.
    pub fn native_law(&self, sc: &Scenario) -> Option<LawSpec> {
        if self.drivers.is_empty() && sc.mixed().is_some() {
            return None;
        }
        let mut law = LawSpec::of(sc);
        if self.damper.is_none() && self.drivers.iter().all(Option::is_none) {
            return Some(law);
        }
        let ring = sc.ring_length_m()?;
        let mut humans = Vec::with_capacity(self.drivers.len());
        for d in &self.drivers {
            humans.push(match d {
                None => None,
                Some(SumoDriver::Noisy(h)) => Some(*h),
                Some(_) => return None,
            });
        }
        let vt = sc.sumo().vehicle_type();
        law.damper = self.damper.map(|spec| DamperSetup {
            spec,
            ring_length_m: ring,
            length_m: sc.length_m().to_vec(),
            accel_mps2: vt.accel_mps2,
            decel_mps2: vt.decel_mps2,
        });
        if humans.iter().any(Option::is_some) {
            law.humans = Some(HumanSetup {
                drivers: humans,
                ring_length_m: ring,
                length_m: sc.length_m().to_vec(),
                seed: sc.seed(),
            });
        }
        Some(law)
    }

    /// Labels of who drives each vehicle, as SUMO runs report them (`law`, a damper's or a
    /// driver's name).
    pub fn labels(&self, n: usize) -> Vec<String> {
        let commanded = self
            .damper
            .map_or_else(|| "law".to_string(), |d| d.to_string());
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

    /// The run's folder name: its name with every character but letters, digits and `._=+-`
    /// replaced by `_` (`human:tau=1.2` → `human_tau=1.2`), because SUMO reads `a:b` in an
    /// output path as host:port and a shell or a list option splits on others. A name longer
    /// than [`FOLDER_MAX`] keeps its first characters and ends in 16 hex digits of its SHA-256,
    /// so the folder fits a file name (255 bytes on common file systems) and stays distinct.
    pub fn folder(&self) -> String {
        let safe: String = self
            .name
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || "._=+-".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if safe.len() <= FOLDER_MAX {
            return safe;
        }
        use sha2::{Digest, Sha256};
        let digest = Sha256::digest(self.name.as_bytes());
        let hex: String = digest[..8].iter().map(|b| format!("{b:02x}")).collect();
        // `safe` is ASCII: any byte index is a character boundary.
        format!("{}-{hex}", &safe[..FOLDER_MAX - 17])
    }

    /// Fraction of the scenario's vehicles the law or the damper drives: as the scenario says
    /// when the run does not choose (its `mixed` block puts humans among the law's vehicles).
    pub fn penetration(&self, sc: &Scenario) -> f64 {
        let n = sc.vehicles().max(1) as f64;
        if self.drivers.is_empty() {
            return match sc.mixed() {
                // round(p N) vehicles whatever the seed, which only chooses which.
                Some(m) => m.automated(sc.vehicles(), sc.seed()).len() as f64 / n,
                None => 1.0,
            };
        }
        self.drivers.iter().filter(|d| d.is_none()).count() as f64 / n
    }
}

/// The controllers of a mixed series by name: `law` or a damper ([`DamperSpec::parse`]), each
/// once, at least one; `field` names where they were given.
pub fn mixed_controllers<S: AsRef<str>>(
    field: &str,
    names: &[S],
) -> Result<Vec<Option<DamperSpec>>, InputError> {
    let mut out = Vec::new();
    for c in names.iter().map(|c| c.as_ref().trim()) {
        let d = DamperSpec::parse(field, c).map_err(|e| InputError::caused(field, e))?;
        if out.contains(&d) {
            return Err(InputError::new(format!("{field}: {c} is listed twice")));
        }
        out.push(d);
    }
    if out.is_empty() {
        return Err(InputError::new(format!(
            "{field} is empty: name at least one controller (e.g. law)"
        )));
    }
    Ok(out)
}

/// The mixed runs with `k` of `n` vehicles automated among `human` drivers, `label` naming
/// the share (`2` vehicles in `compare`, `0.25` of them in a sweep): one run per controller,
/// `mixed-LABEL` for the law and `CONTROLLER-mixed-LABEL` for a damper. The all-human ring
/// (`k = 0`) is the same whatever would control, so it is one run, `mixed-LABEL`.
pub fn mixed_series(
    n: usize,
    k: usize,
    label: &str,
    controllers: &[Option<DamperSpec>],
    human: &SumoDriver,
) -> Vec<RunSpec> {
    let with = if k == 0 {
        &controllers[..controllers.len().min(1)]
    } else {
        controllers
    };
    with.iter()
        .map(|d| {
            let name = match d {
                Some(d) if k > 0 => format!("{d}-mixed-{label}"),
                _ => format!("mixed-{label}"),
            };
            RunSpec::mixed(name, n, k, human.clone(), *d)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_are_safe_bounded_and_distinct() {
        let named = |name: &str| RunSpec {
            name: name.into(),
            drivers: Vec::new(),
            damper: None,
        };
        assert_eq!(named("human:tau=1.2").folder(), "human_tau=1.2");
        // A 300-character driver value once gave a folder name past the 255-byte limit.
        let long = format!("human:tau=1.{}", "0".repeat(300));
        let other = format!("human:tau=1.{}1", "0".repeat(299));
        let (a, b) = (named(&long).folder(), named(&other).folder());
        assert_eq!(a.len(), FOLDER_MAX);
        assert!(a.starts_with("human_tau=1.000"), "{a}");
        assert_ne!(a, b);
        assert!(a
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "._=+-".contains(c)));
    }

    #[test]
    fn a_mixed_series_names_each_controller_and_runs_the_all_human_ring_once() {
        let human = SumoDriver::parse("d", "human").unwrap();
        let c = mixed_controllers("--mixed-controller", &["law", "pi-saturation"]).unwrap();
        let names = |k| -> Vec<String> {
            mixed_series(22, k, &k.to_string(), &c, &human)
                .into_iter()
                .map(|r| r.name)
                .collect()
        };
        assert_eq!(names(0), ["mixed-0"]);
        assert_eq!(names(2), ["mixed-2", "pi-saturation-mixed-2"]);
        let runs = mixed_series(22, 2, "2", &c, &human);
        // k of n vehicles are the controller's, spread evenly (vehicles 0 and 11); the
        // damper drives them in the second run only.
        for r in &runs {
            let automated: Vec<usize> = (0..22).filter(|&i| r.drivers[i].is_none()).collect();
            assert_eq!(automated, [0, 11]);
        }
        assert_eq!((runs[0].damper, runs[1].damper.is_some()), (None, true));
        assert_eq!(
            mixed_controllers("mixed_controller", &["law", "law"])
                .unwrap_err()
                .to_string(),
            "mixed_controller: law is listed twice"
        );
        assert!(mixed_controllers::<&str>("mixed_controller", &[]).is_err());
    }
}
