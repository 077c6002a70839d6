//! `syncroad run` and `syncroad simulate`: one scenario through the one pipeline, on the
//! scenario's backend (`run`: SUMO by default) or the native simulator (`simulate`).
//!
//! A SUMO run checks everything it can before SUMO starts (scenario, network file, ring
//! capacity, road length); a run that fails part-way still writes every row received, marked
//! incomplete.

use std::path::Path;
use std::sync::Arc;

use anyhow::Context;
use syncroad_control::drive::Drive;
use syncroad_control::scenario::Backend;
use syncroad_control::SumoDriver;
use syncroad_control::{LawSpec, NativeOptions, Scenario, StopReason, Verdict};
use syncroad_sumo::{interrupt_flag, load_road, ReadMode, RowsProgress, WorkerCommand};

use crate::cli::{OutputArgs, SumoArgs};
use crate::config::{self, RunConfig};
use crate::error::{InputError, Status};
use crate::lock::FolderLock;
use crate::pipeline::{self, Finished};
use crate::plan::RunPlan;
use crate::progress::RunProgress;
use crate::stdout::{out, outln};
use crate::{output, tables};

/// `syncroad run`: the scenario's backend.
pub fn run(path: &Path, out: &OutputArgs, sumo: &SumoArgs) -> anyhow::Result<Status> {
    let sc = config::load_scenario_with(path, out.safety)?;
    match sc.backend() {
        Backend::Sumo => run_sumo(&sc, path, out, sumo),
        Backend::Native => {
            refuse_sumo_flags(sumo)?;
            run_native(&sc, path, out, config::timeout(sumo.timeout_s)?)
        }
    }
}

/// The plots every run with a trajectory writes (three, PNG and SVG each).
/// The plots of one run (time-space, speeds, spread).
const RUN_PLOTS: usize = 3;

/// `syncroad simulate`: the native simulator whatever the scenario's backend.
pub fn simulate(path: &Path, out: &OutputArgs) -> anyhow::Result<Status> {
    run_native(
        &config::load_scenario_with(path, out.safety)?,
        path,
        out,
        None,
    )
}

/// Checks and locks `--out` and clears the record and rows an earlier run left there; none of
/// them may be the scenario at `path` or a file it names.
fn prepare_out(dir: &Path, path: &Path, sc: &Scenario) -> anyhow::Result<FolderLock> {
    // The plots too: a folder where one goes is refused before the run, and an earlier run's
    // plots never stand beside this run's record.
    let mut files = vec![
        output::METRICS_FILE,
        output::TRAJECTORY_FILE,
        syncroad_control::user_text::FULL_TEXT_FILE,
        crate::animate::NATIVE_ROAD_FILE,
        crate::commands::animate::ANIMATION_FILE,
    ];
    files.extend(crate::plots::RUN_PLOT_FILES);
    files.extend(crate::plots::FIELD_PLOT_FILES);
    output::prepare_dir("--out", dir, &files, &output::Inputs::scenario(path, sc))
}

/// The SUMO options mean nothing to the native simulator: a scenario on the native backend
/// that names one is refused rather than run as if it had not.
fn refuse_sumo_flags(a: &SumoArgs) -> anyhow::Result<()> {
    let given = [
        (a.krauss_sigma.is_some(), "--krauss-sigma"),
        (a.euler, "--euler"),
        (a.subscriptions, "--subscriptions"),
        (a.fcd, "--fcd"),
        (a.emissions, "--emissions"),
    ];
    match given.iter().find(|(on, _)| *on) {
        Some((_, flag)) => Err(InputError::new(format!(
            "{flag}: a SUMO option, but the scenario's backend is \"native\"; set \"backend\": \"sumo\" in the scenario or drop {flag}"
        ))
        .into()),
        None => Ok(()),
    }
}

/// Who drives the scenario as written on the native simulator, resolved as on SUMO
/// ([`syncroad_control::controller::drivers_for`]): its law, or its `mixed` block when its
/// humans are the stochastic ones syncroad computes. SUMO's own drivers among the law's
/// vehicles are refused, not run without them.
fn native_drive(sc: &Scenario) -> anyhow::Result<(Drive, LawSpec)> {
    if let Some(why) = sc.native_refusal() {
        return Err(InputError::new(why).into());
    }
    let (drivers, damper) = syncroad_control::controller::drivers_for(sc, &[], None)
        .map_err(|e| InputError::caused("mixed.human", e))?;
    let drive = Drive {
        name: Drive::as_written(sc.mixed().is_some(), sc.vehicles()).name,
        drivers,
        damper,
        user: None,
    };
    match LawSpec::of_drive(sc, &drive) {
        Some(law) => Ok((drive, law)),
        None => Err(InputError::new(format!(
            "scenario {}: its mixed block puts SUMO's own drivers among the law's vehicles, which only SUMO runs (the native simulator computes only the stochastic humans, human-noisy and flow-idm-noise); run it on SUMO (\"backend\": \"sumo\", `syncroad run`), or as a native sweep with penetrations",
            sc.name()
        ))
        .into()),
    }
}

/// A run its controller ended on purpose (a stepping loop closed early): incomplete, so exit
/// 3, with a note rather than an error, which `--quiet` leaves out.
fn ended_by_controller(f: &Finished, out: &OutputArgs) -> Status {
    if out.progress_mode() != crate::progress::ProgressMode::Never {
        crate::stdout::errln!("note: {}", f.output.stop.message().unwrap_or_default());
    }
    Status::RunFailed
}

/// After the summary is printed: the files written, or why they could not be.
fn report_files(dir: &Path, written: anyhow::Result<usize>, complete: bool) -> anyhow::Result<()> {
    let files = written?;
    let per = crate::plots::files_per_plot();
    let plots = files / per;
    outln!(
        "wrote {} and {}{}",
        dir.join(output::TRAJECTORY_FILE).display(),
        dir.join(output::METRICS_FILE).display(),
        if complete { "" } else { " (incomplete run)" }
    );
    if plots > 0 {
        let names = match plots {
            // Only every vehicle's speed field: no fixed set of syncroad's own.
            1 => "time_space_all (every vehicle on the road)",
            p if p > RUN_PLOTS => {
                "time_space, speeds, spread, time_space_all (every vehicle on the road)"
            }
            _ => "time_space, speeds, spread",
        };
        let kinds = if per == 3 {
            "PNG, SVG and PDF"
        } else {
            "PNG and SVG"
        };
        outln!("wrote {files} plots: {names} ({kinds})");
    }
    Ok(())
}

/// The summary of a finished run on stdout: the synchronization table, then the congestion
/// metrics of a native run or what SUMO reported of a SUMO run.
fn print_summary(sc: &Scenario, f: &Finished) {
    let backend = if f.output.sumo.is_some() {
        "sumo"
    } else {
        "native"
    };
    out!(
        "{}",
        tables::metrics_table(
            sc,
            backend,
            &f.outcome.sync,
            f.output.stop.message().as_deref(),
            &f.record,
        )
    );
    let Some(facts) = &f.output.sumo else {
        match &f.outcome.congestion {
            Ok(c) => out!("{}", tables::congestion_lines(c)),
            Err(e) => outln!("  congestion metrics skipped: {e}"),
        }
        return;
    };
    if let (Some(v), Some(l)) = (&facts.sumo_version, &facts.libsumo) {
        outln!(
            "  SUMO: {v} (libsumo {l}), ring/road length {:.4} m",
            facts.road_length_m
        );
    }
    if let Some(t) = &facts.safety {
        outln!(
            "  SUMO safety: {} collision steps, {} teleports, {} overridden commands (max {:.3e} m/s), {} negative commands sent as 0",
            t.collision_steps, t.teleports, t.overridden_commands, facts.max_override_mps, t.negative_commands_clamped
        );
    }
    if let Some(t) = &f.record.sumo {
        // `--emissions`: what a comparison's table shows of the run.
        let or_dash =
            |x: Option<f64>, d: usize| x.map_or("—".to_string(), |v| format!("{v:.d$}"));
        outln!(
            "  SUMO measured (after the warm-up): fuel {} g/km, CO2 {} g/km, flow at the loop {} veh/h, time loss {:.1} s per vehicle",
            or_dash(t.fuel_g_per_km, 2),
            or_dash(t.co2_g_per_km, 1),
            or_dash(t.flow_veh_per_h, 0),
            t.time_loss_per_vehicle_s
        );
    }
    if let Some(c) = &facts.controlled {
        outln!(
            "  the law drove your vehicles (sumo.controlled), front to back: {}",
            c.vehicles.join(", ")
        );
        if let Some(k) = c.later.filter(|&k| k > 0) {
            outln!("  note: {k} more of the vehicles sumo.controlled chooses came onto the road after the start; the law drives the vehicles of the start, so SUMO drove these by their own vehicle type");
        }
    }
    if let Some(g) = &facts.guests {
        outln!(
            "  inflow vehicles a law drove ({}): {} entered, {} left at their route's end, {} on the road at the end (most {} at once); mean speed {}, mean travel time {}; {} of {} commands held back by SUMO (max {:.3e} m/s), {} capped at the speed limit",
            g.laws.join(", "),
            g.entered,
            g.left,
            g.present_at_end,
            g.present_max,
            g.mean_speed_mps.map_or("—".to_string(), |v| format!("{v:.2} m/s")),
            g.mean_travel_time_s.map_or("—".to_string(), |t| format!("{t:.1} s")),
            g.overridden_commands,
            g.commands,
            g.max_override_mps,
            g.speed_limited_commands
        );
    }
    if let Some(a) = &facts.all_vehicles {
        outln!(
            "  all vehicles (SUMO's summary over {:.1} s): {:.2} running (max {}), mean speed {}, {:.2} halting, {} arrived ({:.0} an hour, mean travel time {}), {} collisions",
            a.measured_s,
            a.vehicles_mean,
            a.vehicles_max,
            a.mean_speed_mps.map_or("—".to_string(), |v| format!("{v:.2} m/s")),
            a.halting_mean,
            a.arrived,
            a.throughput_per_hour,
            a.mean_travel_time_s.map_or("—".to_string(), |t| format!("{t:.1} s")),
            a.collisions
        );
        if a.waiting_at_end > 0 {
            outln!(
                "  note: {} vehicles of the demand were still waiting to enter at the end ({} entered): SUMO delays insertions while an entry is full, so the network took less than the scenario asked",
                a.waiting_at_end,
                a.inserted
            );
        }
    }
}

/// Exit 0 when the run synchronized, or when it had nothing to synchronize (an open road of
/// inflows only, run to its end); else 1.
fn verdict_status(f: &Finished) -> Status {
    Status::verdict(f.outcome.sync.verdict == Verdict::Synchronized || f.record.checks_nothing())
}

fn run_native(
    sc: &Scenario,
    path: &Path,
    out: &OutputArgs,
    timeout: Option<std::time::Duration>,
) -> anyhow::Result<Status> {
    let (drive, law) = native_drive(sc)?;
    let cfg = RunConfig::new(sc, out)?;
    let _lock = prepare_out(&cfg.out, path, sc)?;
    // Ctrl-C, SIGTERM and SIGHUP stop the loop; the steps so far are written, as on SUMO.
    let stop = interrupt_flag()?;
    let progress = RunProgress::new(out.progress_mode(), "simulate", sc.horizon_s(), sc.step_s());
    let every = cfg.record_every.max(1);
    // The native loop records step 0 and every k-th step; an interrupted run also keeps the
    // step it stopped at.
    let report = |done: usize, _total: usize| {
        progress.update(done as f64 * sc.step_s(), done / every + 1);
    };
    let opts = NativeOptions {
        record_every: cfg.record_every,
        cancel: Some(&stop),
        progress: Some(&report),
        host: None,
        timeout,
    };
    let output = pipeline::native_law(sc, &law, drive.labels(sc.vehicles()), opts);
    progress.finish();
    // The law could not be built (the user's controller): bad input, no run to judge, no
    // record.
    let output = output.map_err(|e| match e {
        // Stopped by the time limit or a signal while the controller was built: a failed run.
        syncroad_control::controller::ControllerError::TimedOut { .. } => {
            anyhow::anyhow!("{e}; nothing was run")
        }
        e => InputError::new(format!("{e}; nothing was run")).into(),
    })?;
    let f = Finished::new(sc, &drive.name, output, cfg.eval);
    let complete = f.output.stop.is_complete();
    // The summary is printed even when a file cannot be written (a full disk).
    let written = f.write(
        &cfg.out,
        cfg.plots.then(|| format!("{} (native)", sc.name())),
    );
    print_summary(sc, &f);
    report_files(&cfg.out, written, complete)?;
    if out.animate && f.output.trajectory.len() >= 2 {
        crate::commands::animate::after_run(&cfg.out)?;
    }
    if matches!(f.output.stop, StopReason::Interrupted { .. }) {
        crate::stdout::errln!("error: {}", f.output.stop.message().unwrap_or_default());
        return Ok(Status::Interrupted);
    }
    if matches!(
        f.output.stop,
        StopReason::ControllerFailed { .. } | StopReason::Failed { .. }
    ) {
        crate::stdout::errln!("error: {}", f.output.stop.message().unwrap_or_default());
        return Ok(Status::RunFailed);
    }
    if matches!(f.output.stop, StopReason::StoppedByController { .. }) {
        return Ok(ended_by_controller(&f, out));
    }
    Ok(verdict_status(&f))
}

fn run_sumo(
    sc: &Scenario,
    path: &Path,
    out: &OutputArgs,
    args: &SumoArgs,
) -> anyhow::Result<Status> {
    let cfg = RunConfig::new(sc, out)?;
    let timeout = config::timeout(args.timeout_s)?;
    let fcd_every = config::fcd_every(args.fcd_every)?;
    let drivers = match args.krauss_sigma {
        None => Vec::new(),
        Some(sigma) => {
            let d = SumoDriver::krauss("--krauss-sigma", &sigma.to_string(), sigma)
                .map_err(|e| InputError::about("--krauss-sigma", e))?;
            vec![Some(d); sc.vehicles()]
        }
    };
    let road = load_road(sc).map_err(|e| InputError::caused("before starting SUMO", e))?;
    let _lock = prepare_out(&cfg.out, path, sc)?;
    // The run's name says who drove: SUMO's Krauss (by its driver's name, as every command
    // names it), or the scenario as written (the protocol, or its mixed ring).
    let drive = match drivers.first() {
        Some(Some(d)) => Drive {
            name: d.to_string(),
            drivers,
            damper: None,
            user: None,
        },
        _ => Drive::as_written(sc.mixed().is_some(), sc.vehicles()),
    };
    let mut plan = RunPlan::new(drive, cfg.record_every, cfg.eval);
    plan.ballistic = !args.euler;
    plan.fcd = args.fcd;
    plan.fcd_every = fcd_every;
    plan.timeout = timeout;
    if args.subscriptions {
        plan.read = ReadMode::Subscriptions;
    }
    if args.emissions {
        // What a comparison measures of each run: fuel and CO2 every step, SUMO's trip info.
        plan.measure = Some(crate::plan::Measurements {
            emission_every: 1,
            tripinfo: true,
            ssm: false,
            emissions: syncroad_control::sumo_facts::Emissions::ALL,
        });
    }
    let worker = WorkerCommand::for_process().context("cannot locate the syncroad executable")?;
    let mut opts = plan.sumo_options(
        cfg.out.join(output::SUMO_WORK_DIR),
        worker,
        Some(interrupt_flag()?),
    );
    let progress = Arc::new(RunProgress::new(
        out.progress_mode(),
        "run",
        sc.horizon_s(),
        sc.step_s(),
    ));
    let shown = progress.clone();
    opts.on_rows = Some(Arc::new(move |p: &RowsProgress| {
        shown.update(p.time_s, p.records)
    }));
    let run = pipeline::sumo(sc, &road, &opts);
    progress.finish();
    let run = run.map_err(|e| InputError::caused("before starting SUMO", e))?;
    if let Some(why) = &run.refused {
        // The worker could not build the law (the user's controller): bad input, found
        // before SUMO started; nothing was run.
        return Err(InputError::new(format!("{why}; nothing was run")).into());
    }
    if run.output.trajectory.is_empty() && !run.interrupted {
        // SUMO never ran (no Python, no libsumo, a network SUMO refuses): there is no run to
        // judge, so no verdict and no record, only the reason (exit 3).
        let why = run.output.stop.message().unwrap_or_default();
        let started = run
            .output
            .sumo
            .as_ref()
            .is_some_and(|f| f.sumo_version.is_some());
        if started {
            anyhow::bail!("the run ended before its first sample, nothing was recorded: {why}");
        }
        anyhow::bail!(
            "SUMO did not start, nothing was run: {}",
            why.strip_prefix("SUMO did not start: ").unwrap_or(&why)
        );
    }
    let f = Finished::new(sc, plan.name(), run.output, plan.eval);
    let complete = f.output.stop.is_complete();
    let title = (cfg.plots && complete).then(|| format!("{} (SUMO)", sc.name()));
    let written = f.write(&cfg.out, title);
    print_summary(sc, &f);
    report_files(&cfg.out, written, complete)?;
    if out.animate && f.output.trajectory.len() >= 2 {
        crate::commands::animate::after_run(&cfg.out)?;
    }
    if run.interrupted {
        crate::stdout::errln!("error: {}", f.output.stop.message().unwrap_or_default());
        return Ok(Status::Interrupted);
    }
    if matches!(f.output.stop, StopReason::StoppedByController { .. }) {
        return Ok(ended_by_controller(&f, out));
    }
    if let Some(why) = f.output.stop.message() {
        crate::stdout::errln!("error: {why}");
        return Ok(Status::RunFailed);
    }
    Ok(verdict_status(&f))
}
