//! SUMO's SSM device (surrogate safety measures): the options that switch it on for every
//! vehicle, and a summary of the conflicts it logs.
//!
//! With `--device.ssm.probability 1` every vehicle carries the device; with
//! `--device.ssm.measures "TTC DRAC"` and `--device.ssm.thresholds "3 3"` it logs a
//! `<conflict begin end ego foe>` record for every encounter whose time to collision fell below
//! 3 s or whose deceleration rate to avoid a crash rose above 3 m/s² (SUMO's default
//! thresholds), with the extreme value and its time in `<minTTC time value>` and
//! `<maxDRAC time value>` (`value="NA"` when the measure was not defined). The file is written
//! when the run closes (checked with SUMO 1.28.0, see `SUMO-NOTES`).
//!
//! # Reference
//! SUMO documentation, "Devices: SSM Device" (eclipse-sumo/sumo, `docs/web/docs/Simulation/Output/SSM_Device.md`).

use std::path::Path;

use syncroad_control::margins::SsmSummary;

/// TTC threshold passed to the device \[s\] (SUMO's default).
pub const TTC_THRESHOLD_S: f64 = 3.0;
/// DRAC threshold passed to the device \[m/s²\] (SUMO's default).
pub const DRAC_THRESHOLD_MPS2: f64 = 3.0;

/// The SUMO options that log TTC and DRAC conflicts of every vehicle to `file`.
pub fn ssm_args(file: &Path) -> Vec<String> {
    vec![
        "--device.ssm.probability".into(),
        "1".into(),
        "--device.ssm.measures".into(),
        "TTC DRAC".into(),
        "--device.ssm.thresholds".into(),
        format!("{TTC_THRESHOLD_S} {DRAC_THRESHOLD_MPS2}"),
        "--device.ssm.file".into(),
        file.display().to_string(),
    ]
}

/// Errors reading the SSM log.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SsmError {
    /// Missing or unreadable.
    #[error("cannot read SUMO's SSM log {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Not the XML SUMO writes.
    #[error("SUMO's SSM log {path} is not valid XML: {reason}")]
    Xml {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// Summarizes the SSM log text: conflicts whose extreme TTC (DRAC) lies at or after
/// `warmup_s`, counted, and the smallest TTC (largest DRAC) among them.
pub fn summarize(text: &str, warmup_s: f64) -> Result<SsmSummary, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| e.to_string())?;
    let mut s = SsmSummary {
        ttc_threshold_s: TTC_THRESHOLD_S,
        drac_threshold_mps2: DRAC_THRESHOLD_MPS2,
        ..SsmSummary::default()
    };
    let measured = |node: roxmltree::Node<'_, '_>| -> Option<f64> {
        let time: f64 = node.attribute("time")?.parse().ok()?;
        let value: f64 = node.attribute("value")?.parse().ok()?;
        (time >= warmup_s - 1e-9 && value.is_finite()).then_some(value)
    };
    for c in doc.descendants().filter(|n| n.has_tag_name("conflict")) {
        for m in c.children().filter(roxmltree::Node::is_element) {
            let Some(value) = measured(m) else { continue };
            match m.tag_name().name() {
                "minTTC" if value < TTC_THRESHOLD_S => {
                    s.ttc_conflicts += 1;
                    s.ttc_min_s = Some(s.ttc_min_s.map_or(value, |x| x.min(value)));
                }
                "maxDRAC" if value > DRAC_THRESHOLD_MPS2 => {
                    s.drac_conflicts += 1;
                    s.drac_max_mps2 = Some(s.drac_max_mps2.map_or(value, |x| x.max(value)));
                }
                _ => {}
            }
        }
    }
    Ok(s)
}

/// Reads and summarizes the SSM log at `path` (see [`summarize`]).
pub fn read(path: &Path, warmup_s: f64) -> Result<SsmSummary, SsmError> {
    let text = std::fs::read_to_string(path).map_err(|e| SsmError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    summarize(&text, warmup_s).map_err(|reason| SsmError::Xml {
        path: path.display().to_string(),
        reason,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shape SUMO 1.28.0 wrote for a vehicle stopped dead in front of two followers.
    const LOG: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<SSMLog>
    <conflict begin="0.00" end="29.90" ego="a" foe="b">
        <minTTC time="0.70" position="25.89,25.87" type="3" value="0.63" speed="0.00"/>
        <maxDRAC time="0.50" position="25.89,25.87" type="3" value="5.75" speed="0.00"/>
    </conflict>
    <conflict begin="0.00" end="29.90" ego="a" foe="c">
        <minTTC time="0.70" position="25.89,25.87" type="3" value="2.01" speed="0.00"/>
        <maxDRAC time="0.60" position="25.89,25.87" type="3" value="1.71" speed="0.00"/>
    </conflict>
    <conflict begin="40.00" end="45.00" ego="d" foe="e">
        <minTTC time="41.00" position="1,1" type="2" value="NA" speed="0.00"/>
        <maxDRAC time="42.00" position="1,1" type="2" value="3.50" speed="0.00"/>
    </conflict>
</SSMLog>
"#;

    #[test]
    fn conflicts_beyond_the_thresholds_after_the_warm_up_are_counted() {
        let s = summarize(LOG, 0.0).unwrap();
        assert_eq!(s.ttc_conflicts, 2);
        assert_eq!(s.ttc_min_s, Some(0.63));
        // DRAC 1.71 is below the 3 m/s² threshold; 5.75 and 3.50 are above.
        assert_eq!(s.drac_conflicts, 2);
        assert_eq!(s.drac_max_mps2, Some(5.75));
        // After a 10 s warm-up only the third record remains (its TTC is NA).
        let late = summarize(LOG, 10.0).unwrap();
        assert_eq!((late.ttc_conflicts, late.ttc_min_s), (0, None));
        assert_eq!((late.drac_conflicts, late.drac_max_mps2), (1, Some(3.5)));
        assert!(summarize("<SSMLog>", 0.0).is_err());
    }
}
