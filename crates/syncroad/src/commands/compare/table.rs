//! `compare`'s side-by-side table, one column per run, read from the typed run records. Each
//! row names its metric by the record's path only to take the title and unit the record's
//! schema gives it; the value comes from the typed field.

use syncroad_control::record::schema::{metric_infos, MetricInfo};
use syncroad_control::{RunRecord, Verdict};

/// One cell's value.
enum Cell {
    Num(Option<f64>),
    Count(Option<usize>),
    Text(&'static str),
    Flag(bool),
    Absent,
}

/// One row: the record path (for the title and unit), decimals, the typed field.
struct Row {
    path: &'static str,
    decimals: usize,
    get: fn(&RunRecord) -> Cell,
}

fn congestion(
    r: &RunRecord,
    f: fn(&syncroad_control::congestion::CongestionMetrics) -> f64,
) -> Cell {
    Cell::Num(r.congestion.as_ref().map(f))
}

fn traffic(r: &RunRecord, f: fn(&syncroad_control::record::Traffic) -> Option<f64>) -> Cell {
    Cell::Num(r.sumo.as_ref().and_then(f))
}

fn safety(r: &RunRecord, f: fn(&syncroad_control::sumo_facts::Safety) -> usize) -> Cell {
    Cell::Count(r.safety.as_ref().map(f))
}

const ROWS: [Row; 22] = [
    Row {
        path: "sync.verdict",
        decimals: 0,
        get: |r| {
            // A run that never produced a sample has no verdict.
            Cell::Text(match r.sync.verdict {
                _ if r.sync.final_spread_mps.is_none() => "did not run",
                Verdict::Synchronized => "synchronized",
                Verdict::NotSynchronized => "not sync",
                Verdict::Inconclusive => "inconclusive",
            })
        },
    },
    Row {
        path: "safe",
        decimals: 0,
        get: |r| match r.safe {
            Some(true) => Cell::Text("yes"),
            Some(false) => Cell::Text("UNSAFE"),
            None => Cell::Absent,
        },
    },
    Row {
        path: "sync.final_spread_mps",
        decimals: 4,
        get: |r| Cell::Num(r.sync.final_spread_mps),
    },
    Row {
        path: "congestion.mean_speed_mps",
        decimals: 3,
        get: |r| congestion(r, |c| c.mean_speed_mps),
    },
    Row {
        path: "congestion.speed_std_mps",
        decimals: 3,
        get: |r| congestion(r, |c| c.speed_std_mps),
    },
    Row {
        path: "congestion.speed_std_across_vehicles_mps",
        decimals: 3,
        get: |r| congestion(r, |c| c.speed_std_across_vehicles_mps),
    },
    Row {
        path: "congestion.min_speed_mps",
        decimals: 3,
        get: |r| congestion(r, |c| c.min_speed_mps),
    },
    Row {
        path: "congestion.stop_events",
        decimals: 0,
        get: |r| Cell::Count(r.congestion.as_ref().map(|c| c.stop_events)),
    },
    Row {
        path: "congestion.stopped_fraction",
        decimals: 4,
        get: |r| congestion(r, |c| c.stopped_fraction),
    },
    Row {
        path: "congestion.wave_amplitude_mps",
        decimals: 3,
        get: |r| congestion(r, |c| c.wave_amplitude_mps),
    },
    Row {
        path: "congestion.wave_speed_mps",
        decimals: 2,
        get: |r| Cell::Num(r.congestion.as_ref().and_then(|c| c.wave_speed_mps)),
    },
    Row {
        path: "sumo.flow_veh_per_h",
        decimals: 0,
        get: |r| traffic(r, |t| t.flow_veh_per_h),
    },
    Row {
        path: "sumo.flow_from_speed_veh_per_h",
        decimals: 0,
        get: |r| traffic(r, |t| t.flow_from_speed_veh_per_h),
    },
    Row {
        path: "sumo.time_loss_per_vehicle_s",
        decimals: 1,
        get: |r| traffic(r, |t| Some(t.time_loss_per_vehicle_s)),
    },
    Row {
        path: "sumo.fuel_g_per_km",
        decimals: 2,
        get: |r| traffic(r, |t| t.fuel_g_per_km),
    },
    Row {
        path: "sumo.co2_g_per_km",
        decimals: 1,
        get: |r| traffic(r, |t| t.co2_g_per_km),
    },
    Row {
        path: "sumo.hard_braking_steps",
        decimals: 0,
        get: |r| Cell::Count(r.sumo.as_ref().map(|t| t.hard_braking_steps)),
    },
    Row {
        path: "safety.emergency_braking_warnings",
        decimals: 0,
        get: |r| safety(r, |s| s.emergency_braking_warnings),
    },
    Row {
        path: "safety.start_emergency_braking_warnings",
        decimals: 0,
        get: |r| safety(r, |s| s.start_emergency_braking_warnings),
    },
    Row {
        path: "safety.collision_steps",
        decimals: 0,
        get: |r| safety(r, |s| s.collision_steps),
    },
    Row {
        path: "safety.teleports",
        decimals: 0,
        get: |r| safety(r, |s| s.teleports),
    },
    Row {
        path: "safety.overridden_commands",
        decimals: 0,
        get: |r| safety(r, |s| s.overridden_commands),
    },
];

/// Rows added for runs behind a leader: the measured string amplification.
const STRING_ROWS: [Row; 3] = [
    Row {
        path: "string_amplification.worst_step_ratio",
        decimals: 3,
        get: |r| Cell::Num(r.string_amplification.and_then(|s| s.worst_step_ratio)),
    },
    Row {
        path: "string_amplification.worst_step_vehicle",
        decimals: 0,
        get: |r| Cell::Count(r.string_amplification.and_then(|s| s.worst_step_vehicle)),
    },
    Row {
        path: "string_amplification.end_to_end_ratio",
        decimals: 3,
        get: |r| Cell::Num(r.string_amplification.and_then(|s| s.end_to_end_ratio)),
    },
];

/// Rows added when the runs measured safety margins (`--ssm`).
const MARGIN_ROWS: [Row; 8] = [
    Row {
        path: "safety_margins.time_headway_min_s",
        decimals: 2,
        get: |r| Cell::Num(r.safety_margins.as_ref().and_then(|m| m.time_headway_min_s)),
    },
    Row {
        path: "safety_margins.time_headway_mean_s",
        decimals: 2,
        get: |r| {
            Cell::Num(
                r.safety_margins
                    .as_ref()
                    .and_then(|m| m.time_headway_mean_s),
            )
        },
    },
    Row {
        path: "safety_margins.min_gap_m",
        decimals: 2,
        get: |r| Cell::Num(r.safety_margins.as_ref().and_then(|m| m.min_gap_m)),
    },
    Row {
        path: "safety_margins.ssm.ttc_conflicts",
        decimals: 0,
        get: |r| Cell::Count(r.safety_margins.as_ref().map(|m| m.ssm.ttc_conflicts)),
    },
    Row {
        path: "safety_margins.ssm.ttc_min_s",
        decimals: 2,
        get: |r| Cell::Num(r.safety_margins.as_ref().and_then(|m| m.ssm.ttc_min_s)),
    },
    Row {
        path: "safety_margins.ssm.drac_conflicts",
        decimals: 0,
        get: |r| Cell::Count(r.safety_margins.as_ref().map(|m| m.ssm.drac_conflicts)),
    },
    Row {
        path: "safety_margins.ssm.drac_max_mps2",
        decimals: 2,
        get: |r| Cell::Num(r.safety_margins.as_ref().and_then(|m| m.ssm.drac_max_mps2)),
    },
    Row {
        path: "safety_margins.ignores_safe_speed",
        decimals: 0,
        get: |r| match &r.safety_margins {
            Some(m) => Cell::Flag(m.ignores_safe_speed),
            None => Cell::Absent,
        },
    },
];

impl Cell {
    fn text(&self, decimals: usize) -> String {
        match self {
            Cell::Num(Some(x)) => format!("{x:.decimals$}"),
            Cell::Count(Some(n)) => n.to_string(),
            Cell::Text(s) => (*s).to_string(),
            Cell::Flag(b) => if *b { "yes" } else { "no" }.to_string(),
            Cell::Num(None) | Cell::Count(None) | Cell::Absent => "—".to_string(),
        }
    }
}

fn info(infos: &[MetricInfo], path: &str) -> String {
    infos
        .iter()
        .find(|m| m.path == path)
        .map_or_else(|| path.to_string(), MetricInfo::label)
}

/// The side-by-side table of `runs` (name, record if the run produced one), in the given
/// order; Markdown, so it pastes into a report.
pub fn table(runs: &[(&str, Option<&RunRecord>)]) -> String {
    let infos = metric_infos();
    let mut s = String::from("| metric |");
    for (name, r) in runs {
        let ok = r.is_some_and(|r| r.complete);
        s.push_str(&format!(" {name}{} |", if ok { "" } else { " (FAILED)" }));
    }
    s.push_str("\n|---|");
    s.push_str(&"---:|".repeat(runs.len()));
    s.push('\n');
    let any = |f: fn(&RunRecord) -> bool| runs.iter().any(|(_, r)| r.is_some_and(f));
    let string: &[Row] = if any(|r| r.string_amplification.is_some()) {
        &STRING_ROWS
    } else {
        &[]
    };
    let margins: &[Row] = if any(|r| r.safety_margins.is_some()) {
        &MARGIN_ROWS
    } else {
        &[]
    };
    for row in ROWS.iter().chain(string).chain(margins) {
        s.push_str(&format!("| {} |", info(&infos, row.path)));
        for (_, r) in runs {
            let cell = r.map_or(Cell::Absent, |r| (row.get)(r));
            s.push_str(&format!(" {} |", cell.text(row.decimals)));
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    /// Each row's typed field is the value the record's JSON holds at the row's path, on the
    /// committed compare baselines (records SUMO wrote, read back into the typed record), and
    /// every row's path is a metric of the schema.
    #[test]
    fn rows_read_the_field_their_path_names() {
        let infos = metric_infos();
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/baselines");
        let mut checked = 0;
        for file in ["sugiyama-ring.compare.json", "platoon-cacc.compare.json"] {
            let doc: Value =
                serde_json::from_str(&std::fs::read_to_string(root.join(file)).unwrap()).unwrap();
            for (name, run) in doc["metrics"]["runs"].as_object().unwrap() {
                let rec: RunRecord = serde_json::from_value(run.clone())
                    .unwrap_or_else(|e| panic!("{file} run {name}: {e}"));
                for row in ROWS.iter().chain(&STRING_ROWS).chain(&MARGIN_ROWS) {
                    assert!(
                        infos.iter().any(|m| m.path == row.path),
                        "{} is no metric of the record",
                        row.path
                    );
                    let json = row
                        .path
                        .split('.')
                        .try_fold(run, |v, k| v.get(k))
                        .unwrap_or(&Value::Null);
                    let typed = (row.get)(&rec).text(6);
                    let expect = match json {
                        Value::Null => "—".to_string(),
                        Value::Number(x) if x.is_f64() => format!("{:.6}", x.as_f64().unwrap()),
                        Value::Number(x) => x.to_string(),
                        // An unsafe run says so in capitals.
                        Value::Bool(false) if row.path == "safe" => "UNSAFE".to_string(),
                        Value::Bool(b) => if *b { "yes" } else { "no" }.to_string(),
                        Value::String(v) => v.replace("not_synchronized", "not sync"),
                        other => other.to_string(),
                    };
                    assert_eq!(typed, expect, "{file} run {name} row {}", row.path);
                    checked += 1;
                }
            }
        }
        assert!(checked > 200, "{checked} cells checked");
    }
}
