//! Who drives in a run: the scenario's law, one of SUMO's drivers, or a mix. `compare` and
//! `sweep` name runs the same way.

use syncroad_sumo::SumoDriver;

use crate::error::InputError;

/// One run: a name and who drives each scenario vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    /// Folder and column name (`protocol`, `krauss-0.9`, `mixed-2`, ...).
    pub name: String,
    /// Per scenario vehicle: `None` = the law, `Some` = that SUMO model.
    pub drivers: Vec<Option<SumoDriver>>,
}

impl RunSpec {
    /// `protocol` (every vehicle runs the law) or a SUMO driver name for all `n` vehicles;
    /// `field` names where the name was given, for errors.
    pub fn parse(field: &str, name: &str, n: usize) -> Result<Self, InputError> {
        if name.eq_ignore_ascii_case("protocol") {
            return Ok(Self {
                name: "protocol".into(),
                drivers: vec![None; n],
            });
        }
        let d = SumoDriver::parse(field, name).map_err(|e| InputError::caused(field, e))?;
        Ok(Self {
            name: d.to_string(),
            drivers: vec![Some(d); n],
        })
    }

    /// `k` of `n` vehicles run the law, spread evenly ([`mixed_controlled`]); the others are
    /// `human`.
    pub fn mixed(name: String, n: usize, k: usize, human: SumoDriver) -> Self {
        let mut drivers = vec![Some(human); n];
        for i in mixed_controlled(n, k) {
            drivers[i] = None;
        }
        Self { name, drivers }
    }
}

/// Law-controlled vehicles of a mixed ring with `k` of `n`: `⌊j n / k⌋`, j = 0..k.
pub fn mixed_controlled(n: usize, k: usize) -> Vec<usize> {
    (0..k).map(|j| j * n / k).collect()
}
