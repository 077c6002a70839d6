//! `sumo.controlled`: which of the user's own SUMO vehicles the law drives, chosen by vehicle
//! type, by an id pattern, or by both.

use std::fmt;

use regex::Regex;
use serde::{Deserialize, Serialize};

use super::{invalid, ScenarioError};

/// The user's vehicles the law drives instead of vehicles syncroad inserts: every vehicle of
/// the user's route files whose vehicle type is `vtype` and whose id matches `id` (a regular
/// expression matched against the whole id) and that is on the road when the run starts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleSelector {
    /// The vehicle type id (`<vType id=…>`; a vehicle without `type` has SUMO's
    /// `DEFAULT_VEHTYPE`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vtype: Option<String>,
    /// A regular expression the whole vehicle id must match (`cav\d+`, `platoon\..*`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
}

/// A checked [`VehicleSelector`], ready to match.
#[derive(Debug, Clone)]
pub struct SelectorMatch {
    vtype: Option<String>,
    id: Option<Regex>,
}

impl VehicleSelector {
    /// Checks the selection names something and that `id` is a regular expression.
    pub(super) fn check(&self) -> Result<(), ScenarioError> {
        if self.vtype.is_none() && self.id.is_none() {
            return Err(invalid(
                "sumo.controlled",
                self,
                r#"must choose vehicles by "vtype" (a vehicle type id), "id" (a regular expression of vehicle ids) or both"#,
            ));
        }
        if self.vtype.as_deref().is_some_and(|t| t.trim().is_empty()) {
            return Err(invalid(
                "sumo.controlled.vtype",
                r#""""#,
                "must be a vehicle type id of your files",
            ));
        }
        if let Err(e) = self.matcher() {
            return Err(invalid(
                "sumo.controlled.id",
                self.id.as_deref().unwrap_or_default(),
                format!("must be a regular expression: {e}"),
            ));
        }
        Ok(())
    }

    /// The selection compiled (the pattern anchored at both ends of the id).
    pub fn matcher(&self) -> Result<SelectorMatch, regex::Error> {
        Ok(SelectorMatch {
            vtype: self.vtype.clone(),
            id: self
                .id
                .as_ref()
                .map(|p| Regex::new(&format!("^(?:{p})$")))
                .transpose()?,
        })
    }
}

impl SelectorMatch {
    /// The vehicle `id` of type `vtype` is chosen.
    pub fn matches(&self, id: &str, vtype: &str) -> bool {
        self.vtype.as_deref().is_none_or(|t| t == vtype)
            && self.id.as_ref().is_none_or(|r| r.is_match(id))
    }

    /// Whether the vehicle type alone already rules the vehicle out (its id unknown yet).
    pub fn wants_type(&self, vtype: &str) -> bool {
        self.vtype.as_deref().is_none_or(|t| t == vtype)
    }
}

impl fmt::Display for VehicleSelector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&serde_json::to_string(self).map_err(|_| fmt::Error)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sel(vtype: Option<&str>, id: Option<&str>) -> VehicleSelector {
        VehicleSelector {
            vtype: vtype.map(str::to_string),
            id: id.map(str::to_string),
        }
    }

    #[test]
    fn a_type_an_anchored_pattern_or_both_choose_the_vehicles() {
        let by_type = sel(Some("cav"), None).matcher().unwrap();
        assert!(by_type.matches("anything", "cav"));
        assert!(!by_type.matches("cav0", "human"));
        let by_id = sel(None, Some(r"cav\d+")).matcher().unwrap();
        assert!(by_id.matches("cav12", "DEFAULT_VEHTYPE"));
        // The whole id: neither a prefix nor a suffix is enough.
        assert!(!by_id.matches("cav12b", "cav") && !by_id.matches("xcav1", "cav"));
        // An alternation stays inside the anchors.
        let alt = sel(None, Some("a|b")).matcher().unwrap();
        assert!(alt.matches("a", "t") && !alt.matches("ab", "t") && !alt.matches("xa", "t"));
        let both = sel(Some("cav"), Some("p.*")).matcher().unwrap();
        assert!(
            both.matches("p1", "cav") && !both.matches("p1", "car") && !both.matches("q1", "cav")
        );
    }

    #[test]
    fn an_empty_or_broken_selection_names_the_field() {
        assert_eq!(
            sel(None, None).check().unwrap_err().to_string(),
            r#"sumo.controlled = {}: must choose vehicles by "vtype" (a vehicle type id), "id" (a regular expression of vehicle ids) or both"#
        );
        let e = sel(None, Some("cav(")).check().unwrap_err().to_string();
        assert!(
            e.starts_with("sumo.controlled.id = cav(: must be a regular expression: "),
            "{e}"
        );
        assert_eq!(
            sel(Some(" "), None).check().unwrap_err().to_string(),
            r#"sumo.controlled.vtype = "": must be a vehicle type id of your files"#
        );
    }
}
