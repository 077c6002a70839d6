//! `syncroad animate` (and `--animate` of `run` and `simulate`): finished runs as an animated
//! GIF, drawn by [`crate::animate`].

use std::path::{Path, PathBuf};

use crate::animate::{self, Options, Scene};
use crate::cli::AnimateArgs;
use crate::error::{InputError, Status};
use crate::output::{self, Inputs};
use crate::stdout::outln;

/// The animation `--animate` writes into a run's folder (and `animate RUN` by default).
pub const ANIMATION_FILE: &str = "animation.gif";

/// The most frames one animation may have.
pub const MAX_FRAMES: f64 = 100_000.0;

/// The options checked, naming the flag and what is valid.
fn options(fps: f64, speedup: f64, size: usize) -> Result<Options, InputError> {
    if !(fps.is_finite() && fps > 0.0 && fps <= 100.0) {
        return Err(InputError::new(format!(
            "--fps = {fps}: frames per second must be a number in (0, 100] (GIF times frames in hundredths of a second)"
        )));
    }
    if !(speedup.is_finite() && speedup > 0.0 && speedup <= 1e6) {
        return Err(InputError::new(format!(
            "--speedup = {speedup}: simulated seconds per second of animation must be a number in (0, 1e6]"
        )));
    }
    if !(120..=2000).contains(&size) {
        return Err(InputError::new(format!(
            "--size = {size}: a panel's width and height must be 120 … 2000 px"
        )));
    }
    Ok(Options { fps, speedup, size })
}

/// Reads the runs and writes their animation to `out`; refuses an `out` that is a file of one
/// of the runs.
fn animate(runs: &[PathBuf], out: &Path, opts: &Options) -> anyhow::Result<animate::Written> {
    output::check_file_target("--out", out)?;
    let scenes = runs
        .iter()
        .map(|d| Scene::read(d))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut inputs = Inputs::default();
    for d in runs {
        inputs = inputs
            .with("a run's metrics.json", d.join(output::METRICS_FILE))
            .with("a run's trajectories.csv", d.join(output::TRAJECTORY_FILE));
    }
    output::refuse_input("--out", out, &inputs)?;
    let end = scenes.iter().map(Scene::end_s).fold(0.0, f64::max);
    let frames = end * opts.fps / opts.speedup;
    if frames > MAX_FRAMES {
        return Err(InputError::new(format!(
            "--speedup = {}: {end} s at {} frames per second would take {frames:.0} frames, more than {MAX_FRAMES}; raise --speedup or lower --fps",
            opts.speedup, opts.fps
        ))
        .into());
    }
    animate::write(&scenes, opts, out)
}

fn report(w: &animate::Written, opts: &Options) {
    outln!(
        "wrote {} ({} frames, {} × {} px, {:.1} s at {} frames per second, {}× real time)",
        w.path.display(),
        w.frames,
        w.size.0,
        w.size.1,
        w.duration_s,
        opts.fps,
        opts.speedup
    );
}

/// `syncroad animate`.
pub fn run(a: &AnimateArgs) -> anyhow::Result<Status> {
    let opts = options(a.fps, a.speedup, a.size)?;
    let out = match (&a.out, a.runs.as_slice()) {
        (Some(o), _) => o.clone(),
        (None, [one]) => one.join(ANIMATION_FILE),
        (None, _) => return Err(InputError::new(
            "--out: several runs are drawn side by side into one GIF; name it with --out FILE.gif",
        )
        .into()),
    };
    let w = animate(&a.runs, &out, &opts)?;
    report(&w, &opts);
    Ok(Status::Success)
}

/// `--animate` of `run` and `simulate`: the finished run in `dir`, with the default options,
/// into `dir/animation.gif`.
pub fn after_run(dir: &Path) -> anyhow::Result<()> {
    let opts = Options::default();
    let w = animate(&[dir.to_path_buf()], &dir.join(ANIMATION_FILE), &opts)?;
    report(&w, &opts);
    Ok(())
}
