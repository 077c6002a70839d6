//! One module per command; [`run`] dispatches a parsed command line. Commands return a
//! [`Status`] or an error, never an exit code.

use crate::cli::{Cli, Command};
use crate::error::Status;

pub(crate) mod animate;
mod bench;
mod check;
mod compare;
mod ifp;
pub(crate) mod regress;
mod replay;
mod run;
mod stability;
mod stability_map;
mod sumo_bench;
mod sweep;

/// Runs a parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<Status> {
    match cli.command {
        Command::Check { scenario, json } => check::run(&scenario, json),
        Command::Simulate { scenario, out } => run::simulate(&scenario, &out),
        Command::Run {
            scenario,
            out,
            sumo,
        } => run::run(&scenario, &out, &sumo),
        Command::Compare(args) => compare::run(&args),
        Command::SumoBench {
            quick,
            case,
            no_traci,
            json,
            step_time,
        } if step_time.is_empty() => {
            let sel = syncroad_sumo::bench::Selection {
                quick,
                case,
                no_traci,
            };
            sumo_bench::run(&sel, json.as_deref())
        }
        Command::SumoBench { step_time, .. } => sumo_bench::step_time(&step_time),
        Command::Bench { horizon_s, sizes } => bench::run(horizon_s, &sizes),
        Command::Ifp {
            eta,
            rho,
            delay_s,
            json,
        } => ifp::run(&eta, &rho, delay_s, json),
        Command::Schema => {
            crate::stdout::out!(
                "{}",
                syncroad_control::record::schema::metrics_schema_text()
            );
            Ok(Status::Success)
        }
        Command::Laws => {
            crate::stdout::out!("{}", laws_table());
            Ok(Status::Success)
        }
        Command::Stability {
            scenario,
            json,
            platoon_scaling,
        } => stability::run(&scenario, json, platoon_scaling),
        Command::Map {
            scenario,
            x,
            y,
            out,
            no_sim,
            jobs,
        } => stability_map::run(&scenario, &x, &y, &out, no_sim, jobs),
        Command::Sweep(args) => sweep::run(&args),
        Command::Replay {
            run,
            snapshot,
            at_s,
            print,
        } => replay::run(&run, snapshot.as_deref(), at_s, print),
        Command::Animate(args) => animate::run(&args),
        Command::Regress {
            baseline,
            init: Some(scenario),
            kind,
            ..
        } => regress::init(&baseline, &scenario, kind),
        Command::Regress {
            baseline,
            update,
            metrics,
            junit,
            markdown,
            strict,
            ..
        } => regress::run(
            &baseline,
            update,
            metrics.as_deref(),
            &regress::Reports {
                junit,
                markdown,
                strict,
            },
        ),
    }
}

/// The registry as a table: name (with its shorthand), road, summary.
fn laws_table() -> String {
    use syncroad_control::speed_controller::Road;
    let rows: Vec<(String, &str, &str)> = syncroad_control::registry::entries()
        .iter()
        .map(|e| {
            let name = match e.shorthand {
                Some(k) => format!("{}-X  (X = {k})", e.name),
                None => e.name.to_string(),
            };
            let road = match e.road {
                Road::Ring => "ring",
                Road::Any => "any",
            };
            (name, road, e.summary)
        })
        .collect();
    let w = rows.iter().map(|r| r.0.chars().count()).max().unwrap_or(0);
    let mut out = format!("{:<w$}  {:<4}  what it is\n", "name", "road");
    for (name, road, summary) in rows {
        out.push_str(&format!("{name:<w$}  {road:<4}  {summary}\n"));
    }
    out.push_str("SUMO's drivers (syncroad compare --help) drive too; your own laws: the guide's \"Your own controller\".");
    out
}
