//! The subcommands.

use std::path::Path;

use anyhow::Context;
use syncroad_control::congestion::{congestion_metrics, CongestionMetrics};
use syncroad_control::metrics::{sync_metrics, VerdictThresholds};
use syncroad_control::scenario::{Backend, Model};
use syncroad_control::{simulate, theory, NativeOptions, Scenario, StopReason, Verdict};

use crate::cli::{Cli, Command, OutputArgs};
use crate::exit_codes;
use crate::regress;
use crate::report;

/// Marks errors caused by the user's input (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InputError(pub String);

/// Loads and validates a scenario, mapping failures to [`InputError`].
pub fn load_scenario(path: &Path) -> anyhow::Result<Scenario> {
    Scenario::load(path).map_err(|e| {
        anyhow::Error::new(InputError(format!(
            "{e}\n  (scenario {}; fix the field named above — `syncroad --help` and README.md describe the format)",
            path.display()
        )))
    })
}

/// Runs a parsed command line and returns the exit code.
pub fn run(cli: Cli) -> anyhow::Result<u8> {
    match cli.command {
        Command::Check { scenario, json } => check(&scenario, json),
        Command::Simulate { scenario, out } => simulate_cmd(&scenario, &out),
        Command::Run {
            scenario,
            out,
            sumo,
        } => {
            let backend = load_scenario(&scenario)?.file.backend;
            match backend {
                Backend::Sumo => crate::sumo_cmd::run(&scenario, &out, &sumo),
                Backend::Native => simulate_cmd(&scenario, &out),
            }
        }
        Command::Compare(args) => crate::compare::run(&args),
        Command::SumoBench { quick, json } => crate::sumo_cmd::bench(quick, json.as_ref()),
        Command::Bench { horizon_s, sizes } => crate::bench::run(horizon_s, &sizes),
        Command::Ifp { eta, rho, json } => ifp_cmd(&eta, &rho, json),
        Command::Stability {
            scenario,
            json,
            platoon_scaling,
        } => stability_cmd(&scenario, json, platoon_scaling),
        Command::Map {
            scenario,
            x,
            y,
            out,
            no_sim,
            jobs,
        } => map_cmd(&scenario, &x, &y, &out, no_sim, jobs),
        Command::Regress {
            baseline,
            update,
            metrics,
        } => regress_cmd(&baseline, update, metrics.as_deref()),
    }
}

fn check(path: &Path, json: bool) -> anyhow::Result<u8> {
    let sc = load_scenario(path)?;
    let rep = theory::report(&sc);
    if json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print!("{}", report::theory_table(&rep));
    }
    Ok(if rep.certified {
        exit_codes::SUCCESS
    } else {
        exit_codes::NOT_SYNCHRONIZED
    })
}

/// Verdict thresholds: the scenario's, overridden by the command line.
pub fn thresholds(sc: &Scenario, out: &OutputArgs) -> anyhow::Result<VerdictThresholds> {
    let t = VerdictThresholds {
        tolerance_mps: out.tolerance_mps.unwrap_or(sc.file.verdict.tolerance_mps),
        window_s: out.window_s.unwrap_or(sc.file.verdict.window_s),
    };
    if !(t.tolerance_mps.is_finite() && t.tolerance_mps > 0.0) {
        return Err(InputError(format!(
            "--tolerance-mps = {}: must be a finite number > 0",
            t.tolerance_mps
        ))
        .into());
    }
    if !(t.window_s.is_finite() && t.window_s > 0.0 && t.window_s <= sc.horizon_s()) {
        return Err(InputError(format!(
            "--window-s = {}: must be > 0 and ≤ the horizon ({} s)",
            t.window_s,
            sc.horizon_s()
        ))
        .into());
    }
    Ok(t)
}

/// A finished native run with everything derived from it.
pub struct NativeOutcome {
    /// The run.
    pub run: syncroad_control::NativeRun,
    /// Synchronization metrics.
    pub sync: syncroad_control::SyncMetrics,
    /// Congestion metrics, or why they were skipped.
    pub congestion: Result<CongestionMetrics, syncroad_control::congestion::CongestionError>,
    /// Theory report.
    pub theory: theory::TheoryReport,
}

impl NativeOutcome {
    /// The record to write or compare.
    pub fn record<'a>(&'a self, sc: &'a Scenario) -> report::RunRecord<'a> {
        report::RunRecord {
            scenario: sc,
            backend: "native",
            trajectory: &self.run.trajectory,
            sync: &self.sync,
            congestion: self.congestion.as_ref().ok(),
            stop: serde_json::to_value(&self.run.stop).expect("a stop reason serializes"),
            theory: &self.theory,
            extra: None,
        }
    }
}

/// Default sampling stride: about 2000 samples over the horizon, fewer for large fleets so a
/// trajectory stays within about 4 million vehicle-samples (≈ 100 MB).
pub fn default_record_every(steps: usize, n: usize) -> usize {
    let samples = (4_000_000 / n.max(1)).clamp(2, 2000);
    (steps / samples).max(1)
}

/// Runs a scenario natively and computes its metrics.
pub fn run_native(
    sc: &Scenario,
    th: VerdictThresholds,
    warmup_s: Option<f64>,
    record_every: Option<usize>,
) -> NativeOutcome {
    let every = record_every.unwrap_or_else(|| default_record_every(sc.steps, sc.n));
    let run = simulate(
        sc,
        NativeOptions {
            record_every: every,
        },
    );
    let incomplete = !matches!(run.stop, StopReason::Horizon);
    let desired = match &sc.model {
        Model::Cacc(c) => Some(c.desired_gap_m.as_slice()),
        Model::DelayedDriver(_) => None,
    };
    let sync = sync_metrics(&run.trajectory, th, desired, incomplete);
    let warmup = warmup_s.unwrap_or(0.25 * sc.horizon_s());
    let congestion = congestion_metrics(&run.trajectory, warmup, sc.ring_length_m());
    NativeOutcome {
        run,
        sync,
        congestion,
        theory: theory::report(sc),
    }
}

fn simulate_cmd(path: &Path, out: &OutputArgs) -> anyhow::Result<u8> {
    let sc = load_scenario(path)?;
    let th = thresholds(&sc, out)?;
    if out.record_every == Some(0) {
        return Err(InputError("--record-every = 0: must be ≥ 1".into()).into());
    }
    std::fs::create_dir_all(&out.out)
        .with_context(|| format!("cannot create output folder {}", out.out.display()))?;
    let o = run_native(&sc, th, out.warmup_s, out.record_every);
    o.record(&sc).write(&out.out)?;
    print!(
        "{}",
        report::metrics_table(
            &sc,
            "native",
            &o.sync,
            report::native_stop_note(&o.run.stop).as_deref(),
            &o.theory
        )
    );
    match &o.congestion {
        Ok(c) => print!("{}", report::congestion_lines(c)),
        Err(e) => println!("  congestion metrics skipped: {e}"),
    }
    println!(
        "wrote {}/trajectories.csv and {}/metrics.json",
        out.out.display(),
        out.out.display()
    );
    if !out.no_plots {
        let plots = crate::plots::RunPlots {
            traj: &o.run.trajectory,
            ring_length_m: sc.ring_length_m(),
            title: format!("{} (native)", sc.name),
        };
        let files = plots.write_all(&out.out)?;
        println!(
            "wrote {} plots: time_space, speeds, spread (PNG and SVG)",
            files.len()
        );
    }
    Ok(match o.sync.verdict {
        Verdict::Synchronized => exit_codes::SUCCESS,
        _ => exit_codes::NOT_SYNCHRONIZED,
    })
}

fn regress_cmd(baseline_path: &Path, update: bool, metrics: Option<&Path>) -> anyhow::Result<u8> {
    let mut base = regress::load(baseline_path)?;
    let fresh = match metrics {
        Some(m) => {
            let text = std::fs::read_to_string(m)
                .map_err(|e| InputError(format!("cannot read metrics {}: {e}", m.display())))?;
            serde_json::from_str(&text)
                .map_err(|e| InputError(format!("metrics {}: {e}", m.display())))?
        }
        None => regress::fresh_metrics(&base, baseline_path)?,
    };
    let (stamps, results) = regress::split_stamps(fresh);
    if update {
        base.metrics = results;
        base.stamp = stamps;
        regress::save(baseline_path, &base)?;
        println!("updated {}", baseline_path.display());
        return Ok(exit_codes::SUCCESS);
    }
    let c = regress::compare(&base, &stamps, &results);
    print!("{}", regress::render(&c, baseline_path));
    Ok(if c.failures.is_empty() {
        exit_codes::SUCCESS
    } else {
        exit_codes::NOT_SYNCHRONIZED
    })
}

fn ifp_cmd(eta: &[f64], rho: &[f64], json: bool) -> anyhow::Result<u8> {
    let r = syncroad_control::ifp::ifp_index(eta, rho).map_err(|e| InputError(e.to_string()))?;
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        let at = r
            .omega_at_inf
            .map_or("approached as ω → ∞".to_string(), |w| {
                format!("attained at ω = {w:.6} rad/s")
            });
        println!("IFP index α = {:.9}  ({at})", r.alpha);
        println!("W(λ) = η(λ)/(λ ρ(λ)) is IFP(α): passive with respect to y + α u (Lemma lem.linear-pass)");
    }
    Ok(exit_codes::SUCCESS)
}

fn stability_cmd(path: &Path, json: bool, platoon_scaling: bool) -> anyhow::Result<u8> {
    use syncroad_control::exact::analysis::{self, AnalysisError, ExactVerdict};
    let sc = load_scenario(path)?;
    let r = analysis::analyse(&sc).map_err(|e| match e {
        AnalysisError::TooLargeForFullSolve { .. } => {
            anyhow::Error::new(e).context(InputError(format!("scenario {}", path.display())))
        }
        e => anyhow::Error::new(e),
    })?;
    let scaling = if platoon_scaling {
        Some(
            analysis::platoon_scaling_study(
                &sc,
                &syncroad_control::exact::platoon_scaling::DEFAULT_SIZES,
            )
            .map_err(|e| match e {
                AnalysisError::PlatoonScalingNeedsCacc => {
                    anyhow::Error::new(e).context(InputError("--platoon-scaling".into()))
                }
                e => anyhow::Error::new(e),
            })?,
        )
    } else {
        None
    };
    if json {
        let v = serde_json::json!({"report": r, "platoon_scaling": scaling});
        let v = if scaling.is_some() {
            v
        } else {
            serde_json::to_value(&r)?
        };
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print!("{}", crate::stability::table(&r));
        if let Some(s) = &scaling {
            print!("{}", crate::stability::scaling_table(s));
        }
    }
    Ok(if r.verdict == ExactVerdict::Synchronizes {
        exit_codes::SUCCESS
    } else {
        exit_codes::NOT_SYNCHRONIZED
    })
}

fn map_cmd(
    path: &Path,
    x: &str,
    y: &str,
    out: &Path,
    no_sim: bool,
    jobs: Option<usize>,
) -> anyhow::Result<u8> {
    let sc = load_scenario(path)?;
    let xa = crate::map::Axis::parse("--x", x)?;
    let ya = crate::map::Axis::parse("--y", y)?;
    if jobs == Some(0) {
        return Err(InputError("--jobs = 0: must be ≥ 1".into()).into());
    }
    let jobs = jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create output folder {}", out.display()))?;
    let pts = crate::map::sweep(&sc, xa, ya, !no_sim, jobs)?;
    crate::map::write_csv(&out.join("map.csv"), &pts)?;
    let bounds = crate::map::boundaries(&sc);
    crate::map::plot(
        out,
        &format!("{}: Theorem 1 vs exact stability", sc.name),
        &xa,
        &ya,
        &pts,
        &bounds,
    )?;
    println!(
        "boundaries (gain scale × delay scale): Theorem 1 at {:.6}, exact at {}",
        bounds.theorem1_product,
        bounds
            .exact_product
            .map_or("— (not computed)".to_string(), |c| format!(
                "{c:.6} (ratio {:.4})",
                c / bounds.theorem1_product
            ))
    );
    let certified = pts.iter().filter(|p| p.certified).count();
    let stable = pts.iter().filter(|p| p.exact_stable == Some(true)).count();
    let contradictions = pts
        .iter()
        .filter(|p| p.certified && p.exact_stable == Some(false))
        .count();
    println!(
        "{} grid points: {certified} certified by Theorem 1, {stable} exactly stable{}",
        pts.len(),
        if contradictions > 0 {
            format!(", {contradictions} CERTIFIED BUT UNSTABLE (please report)")
        } else {
            String::new()
        }
    );
    if !no_sim {
        let sync = pts
            .iter()
            .filter(|p| p.simulated == Some(Verdict::Synchronized))
            .count();
        let disagree = pts
            .iter()
            .filter(|p| {
                p.simulated.is_some_and(|v| v != Verdict::Inconclusive)
                    && p.exact_stable
                        .is_some_and(|e| e != (p.simulated == Some(Verdict::Synchronized)))
            })
            .count();
        println!("simulations: {sync} synchronized; {disagree} disagree with the exact verdict (near the boundary the horizon may be too short)");
    }
    println!("wrote {}/map.csv, map.png, map.svg", out.display());
    Ok(exit_codes::SUCCESS)
}
