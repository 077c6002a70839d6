//! `syncroad compare`: one scenario, several drivers, side by side. The comparison itself
//! (plan, runs, the combined `compare.json`) is [`crate::comparison`]; this module turns the
//! flags into its [`Request`] and prints the table.
//!
//! Exit codes: 0 every run completed (whatever the runs found), 1 a run matched `--fail-on`,
//! 2 bad input (nothing ran), 3 some run failed (the others' results are written), 130
//! interrupted.

use std::sync::atomic::Ordering;

use serde_json::Value;
use syncroad_control::RunRecord;
use syncroad_sumo::{interrupt_flag, loop_position, EMISSION_CLASS};

use crate::cli::CompareArgs;
use crate::comparison::{compare_into, plan, Request, RunResult};
use crate::error::Status;
use crate::output;
use crate::stdout::{out, outln};

mod table;

impl From<&CompareArgs> for Request {
    fn from(a: &CompareArgs) -> Self {
        Self {
            baselines: a.baselines.clone(),
            mixed: a.mixed.clone(),
            mixed_driver: a.mixed_driver.clone(),
            mixed_controller: a.mixed_controller.clone(),
            ssm: a.ssm,
            jobs: a.jobs,
            warmup_s: a.warmup_s,
            emission_every: a.emission_every,
            record_every: a.record_every,
            timeout_s: a.timeout_s,
            plots: !a.no_plots,
            fcd: a.fcd,
            fcd_every: a.fcd_every,
            progress: Some(if a.quiet {
                crate::progress::ProgressMode::Never
            } else {
                a.progress
            }),
        }
    }
}

/// `syncroad compare`.
pub fn run(a: &CompareArgs) -> anyhow::Result<Status> {
    let sc = crate::config::load_scenario_with(&a.scenario, a.safety)?;
    let plan = plan(&sc, &Request::from(a))?;
    let interrupt = interrupt_flag()?;
    let (doc, results) = compare_into(
        &sc,
        &plan,
        &a.out,
        &output::Inputs::scenario(&a.scenario, &sc),
        interrupt.clone(),
    )?;
    outln!(
        "{}: {} vehicles, seed {}, warm-up {} s, {}, emission class {}",
        sc.name(),
        sc.vehicles(),
        sc.seed(),
        plan.warmup_s,
        doc["sumo_version"].as_str().unwrap_or("?"),
        EMISSION_CLASS
    );
    if let Some((_, _, x)) = loop_position(&plan.road) {
        outln!("induction loop loop0 at ring coordinate {x:.2} m");
    }
    let columns: Vec<(&str, Option<&RunRecord>)> = results
        .iter()
        .map(|r| (r.name.as_str(), r.record.as_ref().ok()))
        .collect();
    out!("{}", table::table(&columns));
    if let Some(red) = doc
        .get("mixed_reduction_vs_all_human")
        .and_then(|r| r.as_object())
    {
        for (k, v) in red {
            let pct = |x: &Value| {
                x.as_f64()
                    .map_or("—".into(), |x| format!("{:+.1} %", -100.0 * x))
            };
            outln!(
                "{k} vs mixed-0 (all human): speed std {}, fuel per km {}",
                pct(&v["speed_std_reduction"]),
                pct(&v["fuel_per_km_reduction"])
            );
        }
    }
    outln!(
        "wrote {}/compare.json and one folder per run ({})",
        a.out.display(),
        plan.runs
            .iter()
            .map(|r| r.folder())
            .collect::<Vec<_>>()
            .join(", ")
    );
    if interrupt.load(Ordering::SeqCst) {
        return Ok(Status::Interrupted);
    }
    let failed: Vec<&RunResult> = results.iter().filter(|r| !r.complete()).collect();
    for r in &failed {
        crate::stdout::errln!("error: run {} failed: {}", r.name, r.error().unwrap_or("?"));
    }
    if !failed.is_empty() {
        return Ok(Status::RunFailed);
    }
    Ok(crate::gate::judge(
        &a.fail_on,
        results.iter().filter_map(|r| {
            let rec = r.record.as_ref().ok()?;
            Some(crate::gate::Judged {
                name: r.name.clone(),
                verdict: Some(verdict_name(rec.sync.verdict)),
                safe: rec.safe,
            })
        }),
    ))
}

/// The verdict as the record and the sweep table write it.
fn verdict_name(v: syncroad_control::Verdict) -> &'static str {
    match v {
        syncroad_control::Verdict::Synchronized => "synchronized",
        syncroad_control::Verdict::NotSynchronized => "not_synchronized",
        syncroad_control::Verdict::Inconclusive => "inconclusive",
    }
}
