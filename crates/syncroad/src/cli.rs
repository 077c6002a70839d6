//! Command-line definitions (clap derive). Doc comments are the help text.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use crate::progress::ProgressMode;
use syncroad_control::scenario::SafetyMode;

/// Velocity-synchronization experiments on ring roads and platoons (Proskurnikov & Mazo's
/// delayed-driver and bidirectional CACC protocols), natively and in SUMO.
///
/// Exit codes, the same for every command: 0 the command did its job and what it checks held
/// (synchronized, certified, stable, no regression; a comparison or sweep whose runs all ran;
/// a run of an open road with no vehicles of its own, which checks nothing); 1 what it checks
/// did not hold (not synchronized or inconclusive, not certified for the scenario as it runs,
/// not proven stable, a regression, a run matching `--fail-on`); 2 bad input, refused before
/// any work; 3 a run itself failed (partial results written); 128 + n signal n (130 Ctrl-C,
/// 143 SIGTERM, 129 SIGHUP).
#[derive(Debug, Parser)]
#[command(name = "syncroad", version, about, long_about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// Also write every plot as a PDF beside its PNG and SVG: vector, with real text in the
    /// embedded font, for a paper (a time–space plot takes about a second more).
    #[arg(long, global = true)]
    pub pdf: bool,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print which of the paper's sufficient conditions certify synchronization
    /// (Theorem 1, Theorem 1+, the CACC theorem, Chandler's 2αK < 1) with per-vehicle margins.
    Check {
        /// Scenario file (JSON).
        scenario: PathBuf,
        /// Print the report as JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Run the scenario on its backend (`"backend"` in the file: `sumo`, the default, or
    /// `native`): SUMO through libsumo in a supervised worker process, the scenario's law
    /// commanding every vehicle every step. Writes trajectories.csv, metrics.json and plots to
    /// --out and prints the verdict. Runs `bash python-host/bootstrap.sh` first on a new checkout.
    Run {
        /// Scenario file (JSON).
        scenario: PathBuf,
        #[command(flatten)]
        out: OutputArgs,
        #[command(flatten)]
        sumo: SumoArgs,
    },
    /// Run the scenario with its law and with SUMO's own drivers (Krauss σ 0.5 and 0.9, IDM;
    /// ACC and CACC for platoons; mixed rings with --mixed) on the same network, vehicles,
    /// initial state and seed, each run a fresh SUMO of its own; print a side-by-side table of
    /// congestion, flow, time loss, fuel, CO2 and safety; write one folder per run and
    /// compare.json to --out.
    Compare(CompareArgs),
    /// Measure the SUMO loop in one run: SUMO alone vs SUMO + controller (every vehicle read
    /// and commanded every step) vs a TraCI-socket loop doing the same, at N = 22 and N = 2000.
    SumoBench {
        /// Shorter runs (a smoke test of the benchmark).
        #[arg(long, conflicts_with = "step_time")]
        quick: bool,
        /// Only the case whose name starts with this: `sugiyama-ring` (N = 22) or `ring-20km`
        /// (N = 2000).
        #[arg(long, value_name = "NAME", conflicts_with = "step_time")]
        case: Option<String>,
        /// Leave out the TraCI reference: the loop's own figures in a fraction of the time.
        #[arg(long, conflicts_with = "step_time")]
        no_traci: bool,
        /// Also write the results as JSON to this file.
        #[arg(long, conflicts_with = "step_time")]
        json: Option<PathBuf>,
        /// Instead of the standard cases: run each of these SUMO scenarios through one worker
        /// and print the seconds spent inside SUMO's `simulation.step` in each, and their sum
        /// (a sweep's stepping bound is that sum over its points divided by the cores).
        #[arg(long, num_args = 1.., value_name = "SCENARIO")]
        step_time: Vec<PathBuf>,
    },
    /// Run the scenario on the native fixed-step simulator; write trajectories.csv and
    /// metrics.json to --out and print the verdict.
    Simulate {
        /// Scenario file (JSON).
        scenario: PathBuf,
        #[command(flatten)]
        out: OutputArgs,
    },
    /// Exact stability: rightmost characteristic roots, critical gain and delay scales, the
    /// conservatism of Theorem 1; for CACC platoons the closed-loop eigenvalues and string
    /// stability — beside the paper's sufficient conditions.
    Stability {
        /// Scenario file (JSON).
        scenario: PathBuf,
        /// Print JSON instead of tables.
        #[arg(long)]
        json: bool,
        /// CACC platoons: also the least-stable eigenvalue against platoon size
        /// (N = 10 … 200) with the fitted exponent, for the scenario's mean gains, symmetric
        /// gap gains, and Barooah–Mehta–Hespanha's relative-velocity law (symmetric and with
        /// mistuned velocity gains).
        #[arg(long)]
        platoon_scaling: bool,
    },
    /// Sweep a 2-D grid of gain and delay scales of a delayed-driver scenario: the region
    /// Theorem 1 certifies, the exactly stable region, and native simulations at every point,
    /// drawn on one plot (map.png, map.svg) with map.csv.
    Map {
        /// Scenario file (JSON).
        scenario: PathBuf,
        /// x axis as NAME=LO:HI:N, NAME one of gain_scale, delay_scale.
        #[arg(long, default_value = "gain_scale=0.1:3:30")]
        x: String,
        /// y axis as NAME=LO:HI:N.
        #[arg(long, default_value = "delay_scale=0.1:3:30")]
        y: String,
        /// Output folder (created if missing).
        #[arg(long, short)]
        out: PathBuf,
        /// Skip the native simulations (theory and exact regions only).
        #[arg(long)]
        no_sim: bool,
        /// Worker threads (default: all cores).
        #[arg(long)]
        jobs: Option<usize>,
    },
    /// Play a finished SUMO run back in sumo-gui: its network, and every vehicle moving as it
    /// moved, coloured by speed, through SUMO's fcd-replay device. The run must have written
    /// SUMO's floating-car data (`--fcd` on run, compare and sweep, or `"sumo": {"fcd": true}`
    /// in the scenario). Without a display it prints the command to run where there is one.
    Replay {
        /// The run's folder (the --out of `syncroad run`, a run folder of a compare, or of a
        /// sweep's --keep-runs).
        run: PathBuf,
        /// Take one picture of the replay at --at-s into this PNG file through sumo-gui's own
        /// snapshot setting, and quit (a display is still needed: `xvfb-run -a syncroad
        /// replay …` on a machine without one).
        #[arg(long, value_name = "FILE")]
        snapshot: Option<PathBuf>,
        /// Simulated time of the snapshot [s].
        #[arg(long, default_value_t = 0.0, requires = "snapshot")]
        at_s: f64,
        /// Print the sumo-gui command instead of starting it.
        #[arg(long)]
        print: bool,
    },
    /// Animate finished runs (SUMO or native) into a GIF: the road drawn from its own
    /// geometry (the network's lanes, or a native ring's circle), every vehicle coloured by
    /// speed with a colour bar, the vehicles a controller drives among humans ringed, the time
    /// shown. Several runs are drawn side by side on one clock and one colour scale.
    Animate(AnimateArgs),
    /// Run a parameter sweep (a JSON spec: base scenario, axes over its fields, runs, seeds)
    /// through the run pipeline, in parallel and resumable; the results table is written as
    /// results.parquet and results.csv, with plots. `syncroad sweep collect` merges shards.
    Sweep(SweepArgs),
    /// Compare a fresh run's metrics with a committed baseline (per-metric tolerances); print
    /// a readable diff; exit 1 on regression. The baseline names its scenario.
    Regress {
        /// Baseline file (JSON), e.g. tests/baselines/ring-theorem1.native.json.
        baseline: PathBuf,
        /// Rewrite the baseline's metrics and stamps from the fresh run (tolerances are kept).
        #[arg(long)]
        update: bool,
        /// Compare this metrics.json instead of running the baseline's scenario.
        #[arg(long)]
        metrics: Option<PathBuf>,
        /// Also write the result as JUnit XML (one test case per metric and stamp), which
        /// GitLab, GitHub and Jenkins display.
        #[arg(long, value_name = "FILE")]
        junit: Option<PathBuf>,
        /// Also write a Markdown summary (e.g. to "$GITHUB_STEP_SUMMARY" for a job page).
        #[arg(long, value_name = "FILE")]
        markdown: Option<PathBuf>,
        /// Fail when the baseline was recorded on another syncroad or SUMO version or platform
        /// (by default that is reported and the metrics are compared with the stated tolerances).
        #[arg(long)]
        strict: bool,
        /// Make a new baseline at BASELINE for this scenario from a fresh run (the scenario
        /// named relative to the baseline's folder; an existing file is never replaced).
        #[arg(long, value_name = "SCENARIO", conflicts_with_all = ["update", "metrics", "junit", "markdown", "strict"])]
        init: Option<PathBuf>,
        /// With --init: what the baseline re-runs: `native`, `sumo` (one SUMO run of the law)
        /// or `compare` (the default comparison); default: the scenario's backend.
        #[arg(long, value_enum, requires = "init")]
        kind: Option<crate::commands::regress::baseline::Kind>,
    },
    /// Prints the JSON Schema of `metrics.json`, derived from the record's type (the
    /// published `docs/metrics.schema.json` is this output).
    Schema,
    /// The laws that can drive in place of the scenario's model law, one line each: the wave
    /// dampers and the other built-in laws (as `--baselines`, `mixed.controller` and
    /// `"controller": {"law": NAME}` name them), the road each needs, its shorthand.
    Laws,
    /// The IFP index α = −inf_ω Re W(iω) of an agent W(λ) = η(λ)/(λ ρ(λ)) (Lemma lem.linear-pass),
    /// e.g. the CACC agent τ y''' + y'' + μ y' = u is `--eta 1 --rho MU,1,TAU`.
    Ifp {
        /// Coefficients of η, ascending (η_0, η_1, ...), comma-separated.
        #[arg(
            long,
            value_delimiter = ',',
            allow_hyphen_values = true,
            required = true
        )]
        eta: Vec<f64>,
        /// Coefficients of ρ, ascending (ρ_0, ρ_1, ...), comma-separated; ρ must be Hurwitz.
        #[arg(
            long,
            value_delimiter = ',',
            allow_hyphen_values = true,
            required = true
        )]
        rho: Vec<f64>,
        /// Input delay τ [s]: W(λ) = η(λ)/(λ ρ(λ)) · e^{−λτ}. A delayed integrator's index is
        /// exact (kτ); any other delayed agent gets a rigorous upper bound with a lower bound.
        #[arg(long, default_value_t = 0.0)]
        delay_s: f64,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Measure the native simulator: vehicle-steps per second on rings of 22, 2000 and 20000
    /// vehicles with heterogeneous on-grid delays (Δt = 0.01 s), and its error against a
    /// 16× finer reference.
    Bench {
        /// Simulated seconds per measurement.
        #[arg(long, default_value_t = 20.0)]
        horizon_s: f64,
        /// Ring sizes to measure.
        #[arg(long, value_delimiter = ',', default_values_t = [22usize, 2000, 20000])]
        sizes: Vec<usize>,
    },
}

/// Output options shared by the commands that run simulations.
#[derive(Debug, clap::Args)]
pub struct OutputArgs {
    /// Folder for trajectories.csv and metrics.json (created if missing).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Override the scenario's verdict tolerance on the speed spread [m/s].
    #[arg(long)]
    pub tolerance_mps: Option<f64>,
    /// Override the scenario's final window for the verdict [s].
    #[arg(long)]
    pub window_s: Option<f64>,
    /// Record every k-th step (default: about 2000 samples over the horizon, fewer for fleets
    /// above 2000 vehicles).
    #[arg(long)]
    pub record_every: Option<usize>,
    /// Warm-up excluded from the congestion metrics and from every vehicle's (SUMO's summary, with other traffic) [s] (default: a quarter of the horizon).
    #[arg(long)]
    pub warmup_s: Option<f64>,
    /// Do not draw the plots (time-space diagram, speeds, spread; PNG and SVG).
    #[arg(long)]
    pub no_plots: bool,
    /// Progress on stderr: `auto` redraws one line on a terminal once the run lasts over 2 s
    /// (nothing in a log or a pipe); `lines` prints a line as soon as the first samples are
    /// recorded, then one every 5 s, wherever stderr goes (batch logs); `never`.
    #[arg(long, value_enum, default_value_t = ProgressMode::Auto, value_name = "WHEN")]
    pub progress: ProgressMode,
    /// No progress on stderr (the same as `--progress never`).
    #[arg(long, short, conflicts_with = "progress")]
    pub quiet: bool,
    /// Also animate the run into OUT/animation.gif (as `syncroad animate OUT` does).
    #[arg(long)]
    pub animate: bool,
    /// The safety layer under the law, in place of the scenario's `safety`: `off` (the law's
    /// commands as they are), `sumo` (SUMO's safe speed, right of way and red lights; SUMO
    /// only) or `filter` (syncroad's Gipps safe-speed filter, the same on both backends).
    #[arg(long, value_parser = parse_safety, value_name = "LAYER")]
    pub safety: Option<SafetyMode>,
}

impl OutputArgs {
    /// How the run shows its progress (`--quiet` is `--progress never`).
    pub fn progress_mode(&self) -> ProgressMode {
        if self.quiet {
            ProgressMode::Never
        } else {
            self.progress
        }
    }
}

/// Options of the SUMO backend.
#[derive(Debug, Clone, clap::Args)]
pub struct SumoArgs {
    /// Wall-clock limit of the run [s] (SUMO: default the scenario's sumo.timeout_s; native:
    /// none). A run past it stops, keeps its rows and exits 3.
    #[arg(long)]
    pub timeout_s: Option<f64>,
    /// Baseline: let SUMO's own car-following model (Krauss with this σ, e.g. 0.5) drive
    /// instead of the scenario's law.
    #[arg(long)]
    pub krauss_sigma: Option<f64>,
    /// Use SUMO's default Euler position update (x += Δt v^{n+1}) instead of the ballistic
    /// (trapezoidal) one the native simulator shares.
    #[arg(long)]
    pub euler: bool,
    /// Read states through libsumo subscriptions instead of per-vehicle getters.
    #[arg(long)]
    pub subscriptions: bool,
    /// Also measure what `compare` measures of each run: fuel and CO2 (HBEFA, every step),
    /// the induction loop's flow, time loss and braking, in the record's `sumo` block and the
    /// summary.
    #[arg(long)]
    pub emissions: bool,
    /// Also write SUMO's floating-car data of the run (OUT/sumo/fcd.xml, every step) for
    /// `syncroad replay`.
    #[arg(long)]
    pub fcd: bool,
    /// With --fcd, SUMO writes its floating-car data every k-th step only (a tenth of the file
    /// at k = 10); the replay then steps k steps at a time.
    #[arg(long, value_name = "K", requires = "fcd")]
    pub fcd_every: Option<usize>,
}

/// Options of `syncroad compare`.
#[derive(Debug, Clone, clap::Args)]
pub struct CompareArgs {
    /// Scenario file (JSON) with a SUMO network (`sumo.net`).
    pub scenario: PathBuf,
    /// Output folder: one subfolder per run, compare.json (created if missing).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Runs, comma-separated: protocol (the scenario's law on every vehicle),
    /// SUMO drivers krauss (SUMO's default, σ 0.5), krauss-SIGMA (e.g. krauss-0.9), idm, acc,
    /// cacc, the presets human (IDM calibrated on the Sugiyama ring) and flow-idm, SUMO's
    /// driver-state device driverstate-A (awareness A), on rings the stochastic humans
    /// computed by syncroad human-noisy and flow-idm-noise (noisy IDM, e.g.
    /// human-noisy:noise=0.1), and the wave dampers of Stern et al. (2018) on every vehicle:
    /// follower-stopper-U (desired speed U in m/s, e.g. follower-stopper-4.3) and
    /// pi-saturation (flow-follower-stopper-U, flow-pi-saturation: Flow's code), and every
    /// other law of `syncroad laws` (e.g. constant-speed-U), and your own Python class as
    /// python:FILE.py:Class (its keyword arguments after it as :NAME=VALUE). Default:
    /// protocol,krauss,krauss-0.9,idm on rings; protocol,krauss,idm,acc,cacc on straight roads.
    #[arg(long)]
    pub baselines: Option<String>,
    /// Mixed traffic on a ring: for each count K, a run where K evenly spaced vehicles run the
    /// law and the others are --mixed-driver (e.g. 0,1,2,4; 0 is the all-human ring).
    #[arg(long)]
    pub mixed: Option<String>,
    /// The human drivers of --mixed runs: any --baselines driver (default human, the preset
    /// that jams the Sugiyama ring; e.g. krauss-0.9, human-noisy).
    #[arg(long, default_value = syncroad_control::drive::DEFAULT_HUMAN)]
    pub mixed_driver: String,
    /// What drives the K automated vehicles of --mixed runs, comma-separated: protocol (the
    /// scenario's law), follower-stopper-U, pi-saturation, any law of `syncroad laws`, your
    /// own Python class as python:FILE.py:Class (its keyword arguments after it as
    /// :NAME=VALUE). One run per controller and K > 0, named CONTROLLER-mixed-K
    /// (protocol-mixed-2, python:MyLaw-mixed-2); the all-human mixed-0 runs once.
    #[arg(long, default_value = syncroad_control::drive::DEFAULT_MIXED_CONTROLLER)]
    pub mixed_controller: String,
    /// Also measure safety margins in every run: time headway (min, mean), minimum gap, SUMO's
    /// surrogate safety measures (TTC, DRAC conflicts from its SSM device) and whether the
    /// law's vehicles ignore SUMO's safe speed.
    #[arg(long)]
    pub ssm: bool,
    /// Runs at once (default: the number of cores): as many SUMO worker processes, each
    /// running one run after another.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Warm-up excluded from every congestion and SUMO metric [s] (default: a quarter of the
    /// horizon).
    #[arg(long)]
    pub warmup_s: Option<f64>,
    /// Read fuel and CO2 every k steps (1 = every step, exact at SUMO's step).
    #[arg(long, default_value_t = 1)]
    pub emission_every: usize,
    /// Record every k-th step in trajectories.csv (default: about 2000 samples).
    #[arg(long)]
    pub record_every: Option<usize>,
    /// Wall-clock limit of each SUMO run [s] (default: the scenario's sumo.timeout_s).
    #[arg(long)]
    pub timeout_s: Option<f64>,
    /// Do not draw plots.
    #[arg(long)]
    pub no_plots: bool,
    /// Every run also writes SUMO's floating-car data (RUN/sumo/fcd.xml) for `syncroad
    /// replay`.
    #[arg(long)]
    pub fcd: bool,
    /// With --fcd, SUMO writes its floating-car data every k-th step only; the replay then
    /// steps k steps at a time.
    #[arg(long, value_name = "K", requires = "fcd")]
    pub fcd_every: Option<usize>,
    /// Progress on stderr: `auto` a bar of finished runs with the time left on a terminal
    /// (nothing in a log or a pipe); `lines` a line per finished run wherever stderr goes;
    /// `never`.
    #[arg(long, value_enum, default_value_t = ProgressMode::Auto, value_name = "WHEN")]
    pub progress: ProgressMode,
    /// No progress on stderr (the same as `--progress never`).
    #[arg(long, short, conflicts_with = "progress")]
    pub quiet: bool,
    /// The safety layer under the law in every run that has one, in place of the scenario's
    /// `safety`: `off` (the law's commands as they are), `sumo` (SUMO's safe speed, right of way and red lights; SUMO
    /// only) or `filter` (syncroad's Gipps safe-speed filter, the same on both backends).
    #[arg(long, value_parser = parse_safety, value_name = "LAYER")]
    pub safety: Option<SafetyMode>,
    /// Exit 1 when a run is unsafe, not synchronized or inconclusive (comma-separated; each
    /// matching run is named on stderr). Without it a comparison whose runs all ran exits 0
    /// whatever they found.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "FINDING")]
    pub fail_on: Vec<crate::gate::FailOn>,
}

/// Options of `syncroad animate`.
#[derive(Debug, Clone, clap::Args)]
pub struct AnimateArgs {
    /// Run folders (the --out of `syncroad run` or `simulate`, or run folders of a compare or
    /// of a sweep's --keep-runs).
    #[arg(required = true, value_name = "RUN")]
    pub runs: Vec<PathBuf>,
    /// The GIF to write (created, or replaced if it is a regular file); default
    /// RUN/animation.gif when one run is drawn.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Frames per second.
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    /// Simulated seconds per second of animation.
    #[arg(long, default_value_t = 5.0)]
    pub speedup: f64,
    /// Width and height of each run's panel [px].
    #[arg(long, default_value_t = 360)]
    pub size: usize,
}

/// `--safety off|sumo|filter`: the names of the scenario's `safety` key.
fn parse_safety(text: &str) -> Result<SafetyMode, String> {
    serde_json::from_value(serde_json::Value::String(text.to_string())).map_err(|_| {
        format!("{text}: use off (the law's commands as they are), sumo (SUMO's safe speed, right of way and red lights) or filter (syncroad's Gipps safe-speed filter, on both backends)")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn verify_cli() {
        Cli::command().debug_assert();
    }
}

/// `syncroad sweep`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct SweepArgs {
    /// `collect`: merge shard folders.
    #[command(subcommand)]
    pub action: Option<SweepAction>,
    /// Sweep spec file (JSON).
    #[arg(required = true)]
    pub spec: Option<PathBuf>,
    /// Output folder: new, empty, or one this spec made before (finished points are skipped).
    #[arg(long, short, required = true)]
    pub out: Option<PathBuf>,
    /// Points in flight at once (default: all cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Run only shard I of N (points with number mod N = I), e.g. 0/4.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// Keep each point's run folder (trajectories.csv, metrics.json) under OUT/runs.
    #[arg(long)]
    pub keep_runs: bool,
    /// With --keep-runs, also draw each point's plots.
    #[arg(long, requires = "keep_runs")]
    pub run_plots: bool,
    /// Skip the sweep's plots.
    #[arg(long)]
    pub no_plots: bool,
    /// Run again the points that failed before.
    #[arg(long)]
    pub retry_failed: bool,
    /// The safety layer under the law at every point, in place of the base scenario's
    /// `safety` (part of the sweep's hash: a resumed sweep keeps its layer): `off` (the law's
    /// commands as they are), `sumo` (SUMO's safe speed, right of way and red lights; SUMO
    /// only) or `filter` (syncroad's Gipps safe-speed filter, the same on both backends).
    #[arg(long, value_parser = parse_safety, value_name = "LAYER")]
    pub safety: Option<SafetyMode>,
    /// Exit 1 when a point's run is unsafe, not synchronized or inconclusive
    /// (comma-separated; the matching points are named on stderr). Without it a sweep whose
    /// points all ran exits 0 whatever they found.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "FINDING")]
    pub fail_on: Vec<crate::gate::FailOn>,
    /// With --keep-runs on SUMO, each run also writes SUMO's floating-car data for
    /// `syncroad replay`.
    #[arg(long, requires = "keep_runs")]
    pub fcd: bool,
    /// With --fcd, SUMO writes its floating-car data every k-th step only; the replay then
    /// steps k steps at a time.
    #[arg(long, value_name = "K", requires = "fcd")]
    pub fcd_every: Option<usize>,
    /// Write a Slurm job array (one task per shard) and a collect job into this folder
    /// instead of running; OUT is where the cluster writes the results.
    #[arg(long, value_name = "DIR")]
    pub emit_slurm: Option<PathBuf>,
    /// Slurm: number of shards (array tasks).
    #[arg(long, default_value_t = 16)]
    pub shards: usize,
    /// Slurm: array tasks running at once (%K).
    #[arg(long, default_value_t = 8)]
    pub max_running: usize,
    /// Slurm: CPUs per array task (each runs that many points at once).
    #[arg(long, default_value_t = 1)]
    pub cpus_per_task: usize,
    /// Slurm: --partition.
    #[arg(long)]
    pub partition: Option<String>,
    /// Slurm: --account.
    #[arg(long)]
    pub account: Option<String>,
    /// Slurm: --time (e.g. 02:00:00).
    #[arg(long)]
    pub time: Option<String>,
    /// Slurm: any other sbatch option, repeatable (e.g. --sbatch-option=--mem=4G).
    #[arg(long, allow_hyphen_values = true)]
    pub sbatch_option: Vec<String>,
}

/// `syncroad sweep` actions.
#[derive(Debug, Subcommand)]
pub enum SweepAction {
    /// Merge the rows of shard folders into one table; report missing or duplicated points.
    Collect {
        /// Sweep spec file (JSON) the shards ran.
        spec: PathBuf,
        /// Merged output folder.
        #[arg(long, short)]
        out: PathBuf,
        /// Shard folders.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Skip the plots.
        #[arg(long)]
        no_plots: bool,
        /// Exit 1 when a merged point's run is unsafe, not synchronized or inconclusive.
        #[arg(long, value_enum, value_delimiter = ',', value_name = "FINDING")]
        fail_on: Vec<crate::gate::FailOn>,
        /// The `--safety` the shards ran with (the spec's hash covers it).
        #[arg(long, value_parser = parse_safety, value_name = "LAYER")]
        safety: Option<SafetyMode>,
    },
}
