//! SUMO's summary output (`--summary-output`): one `<step>` per simulation step with the
//! network's totals, whoever drives — syncroad's vehicles and the user's own traffic. A run
//! with other traffic writes it into its work folder, and the record's metrics for all
//! vehicles come from it.
//!
//! Each `<step time running halting arrived collisions meanSpeed …>` holds the state after the
//! step at `time`; `arrived` and `collisions` are running totals, `meanSpeed` is the mean over
//! the running vehicles (-1 when none runs).
//!
//! # Reference
//! SUMO documentation, "Output: Summary" (eclipse-sumo/sumo, `docs/web/docs/Simulation/Output/Summary.md`).

use std::path::Path;

use syncroad_control::sumo_facts::AllVehicles;

/// The SUMO options that write the summary to `file`, every `every` steps of `step_s` (the
/// trajectory's stride: formatting a `<step>` costs SUMO more than a small network's step, and
/// a run of the CLI records about 2000 samples whatever its length).
pub fn summary_args(file: &Path, step_s: f64, every: usize) -> Vec<String> {
    let mut a = vec!["--summary-output".into(), file.display().to_string()];
    if every > 1 {
        a.push("--summary-output.period".into());
        a.push(format!("{}", step_s * every as f64));
    }
    a
}

/// Errors reading the summary.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SummaryError {
    /// Missing or unreadable.
    #[error("cannot read SUMO's summary output {path}: {reason}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// Not the XML SUMO writes.
    #[error("SUMO's summary output {path} is not what SUMO writes: {reason}")]
    Xml {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// Reads the summary `path` over the samples at or after `warmup_s` (`step_s` is the run's step:
/// times are compared to half a step).
pub fn read(path: &Path, warmup_s: f64, step_s: f64) -> Result<AllVehicles, SummaryError> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| SummaryError::Io {
        path: shown.clone(),
        reason: e.to_string(),
    })?;
    summarize(&text, warmup_s, step_s).map_err(|reason| SummaryError::Xml {
        path: shown,
        reason,
    })
}

/// [`read`] of the file's text.
pub fn summarize(text: &str, warmup_s: f64, step_s: f64) -> Result<AllVehicles, String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| e.to_string())?;
    let num = |n: &roxmltree::Node<'_, '_>, a: &str| -> Result<f64, String> {
        n.attribute(a)
            .ok_or_else(|| format!("a <step> without {a}"))?
            .parse::<f64>()
            .map_err(|e| format!("<step {a}>: {e}"))
    };
    let mut out = AllVehicles::default();
    let mut span: Option<(f64, f64)> = None;
    let (mut steps, mut running_sum, mut speed_sum, mut halting_sum) = (0usize, 0.0, 0.0, 0.0);
    // Totals at the last step before the warm-up ended.
    let (mut arrived0, mut collisions0, mut inserted0) = (0.0, 0.0, 0.0);
    let (mut arrived, mut collisions, mut inserted, mut waiting) = (0.0, 0.0, 0.0, 0.0);
    // SUMO's mean travel time of every vehicle arrived so far (−1 before the first), at the
    // warm-up's end and at the last sample: the mean of those arrived in between follows.
    let (mut travel0, mut travel) = (Some(0.0), Some(0.0));
    // Half a step of slack: SUMO prints times rounded to its output precision.
    let from = warmup_s - 0.5 * step_s;
    for s in doc.descendants().filter(|n| n.has_tag_name("step")) {
        let t = num(&s, "time")?;
        arrived = num(&s, "arrived")?;
        collisions = num(&s, "collisions")?;
        // Older summaries lack these two: counted as none.
        inserted = num(&s, "inserted").unwrap_or(0.0);
        waiting = num(&s, "waiting").unwrap_or(0.0);
        travel = num(&s, "meanTravelTime").ok().map(|x| x.max(0.0));
        if t < from {
            arrived0 = arrived;
            collisions0 = collisions;
            inserted0 = inserted;
            travel0 = travel;
            continue;
        }
        let running = num(&s, "running")?;
        span = Some(span.map_or((t, t), |(a, _)| (a, t)));
        steps += 1;
        running_sum += running;
        halting_sum += num(&s, "halting")?;
        if running > 0.0 {
            speed_sum += running * num(&s, "meanSpeed")?;
        }
        out.vehicles_max = out.vehicles_max.max(running as usize);
    }
    if steps > 0 {
        out.measured_s = span.map_or(0.0, |(a, b)| b - a);
        out.vehicles_mean = running_sum / steps as f64;
        out.halting_mean = halting_sum / steps as f64;
        out.mean_speed_mps = (running_sum > 0.0).then(|| speed_sum / running_sum);
    }
    out.arrived = (arrived - arrived0) as usize;
    out.collisions = (collisions - collisions0) as usize;
    out.inserted = (inserted - inserted0) as usize;
    out.waiting_at_end = waiting as usize;
    if out.measured_s > 0.0 {
        out.throughput_per_hour = out.arrived as f64 / out.measured_s * 3600.0;
    }
    if let (true, Some(t), Some(t0)) = (arrived > arrived0, travel, travel0) {
        out.mean_travel_time_s = Some((t * arrived - t0 * arrived0) / (arrived - arrived0));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_means_weigh_each_step_by_its_running_vehicles_after_the_warm_up() {
        let text = r#"<summary>
    <step time="1.00" running="2" halting="0" arrived="0" collisions="0" meanSpeed="9.00"/>
    <step time="2.00" running="4" halting="1" arrived="1" collisions="0" meanSpeed="3.00"/>
    <step time="3.00" running="1" halting="1" arrived="3" collisions="1" meanSpeed="1.00"/>
    <step time="4.00" running="0" halting="0" arrived="4" collisions="1" meanSpeed="-1.00"/>
</summary>"#;
        let a = summarize(text, 2.0, 1.0).unwrap();
        // Steps 2, 3, 4: (4·3 + 1·1) / (4 + 1 + 0) m/s; the empty step counts in the means.
        assert_eq!(a.mean_speed_mps, Some(13.0 / 5.0));
        assert_eq!(a.vehicles_mean, 5.0 / 3.0);
        assert_eq!(a.vehicles_max, 4);
        assert_eq!(a.halting_mean, 2.0 / 3.0);
        assert_eq!((a.arrived, a.collisions), (4, 1));
        assert_eq!(a.measured_s, 2.0);
        // No inserted, waiting or meanTravelTime attributes (older summaries): none counted.
        assert_eq!((a.inserted, a.waiting_at_end), (0, 0));
        assert_eq!(a.mean_travel_time_s, None);
        let with_demand = r#"<summary>
    <step time="1.00" inserted="3" waiting="0" running="3" halting="0" arrived="1" collisions="0" meanSpeed="9.00" meanTravelTime="10.00"/>
    <step time="2.00" inserted="5" waiting="2" running="5" halting="1" arrived="1" collisions="0" meanSpeed="3.00" meanTravelTime="10.00"/>
    <step time="3.00" inserted="5" waiting="2" running="2" halting="1" arrived="4" collisions="0" meanSpeed="3.00" meanTravelTime="16.00"/>
</summary>"#;
        let a = summarize(with_demand, 2.0, 1.0).unwrap();
        // Inserted after the warm-up: 5 − 3; waiting at the last sample: 2.
        assert_eq!((a.inserted, a.waiting_at_end), (2, 2));
        // Three arrived after the warm-up in the 1 s measured, travelling (16·4 − 10·1)/3 s.
        assert_eq!(a.throughput_per_hour, 3.0 * 3600.0);
        assert_eq!(a.mean_travel_time_s, Some(18.0));
        let e = summarize("<summary><step time=\"1\"/></summary>", 0.0, 1.0).unwrap_err();
        assert_eq!(e, "a <step> without arrived");
    }
}
