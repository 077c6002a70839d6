//! `syncroad map`: a preset of `syncroad sweep` over a 2-D grid of gain and delay scales of a
//! delayed-driver scenario (the native verdicts come from the sweep, in `OUT/sweep`) that
//! draws, on one plot, the region Theorem 1 certifies, the exactly stable region (rightmost
//! characteristic root), and the verdict of a native simulation at every grid point.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use plotters::prelude::*;
use rayon::prelude::*;
use serde::Serialize;
use syncroad_control::exact::analysis::{FULL_SOLVE_LIMIT, MIN_GAIN_DELAY};
use syncroad_control::exact::{self, Boundaries, Method};
use syncroad_control::scenario::{DelayedDriverModel, Model};
use syncroad_control::{theory, Scenario, Verdict};

use crate::config::{self, load_scenario};
use crate::error::{InputError, Status};
use crate::output::write_result_via_path;
use crate::plots::err;
use crate::progress::Progress;
use crate::stdout::outln;
use crate::sweep::{exec, ExecOptions, Shard, Sweep};
use syncroad_sumo::interrupt_flag;

/// Swept quantity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Param {
    /// Uniform scale c of all gains a_ij (and pinning gains b_i).
    GainScale,
    /// Uniform scale of all delays α_i (rounded to the step grid for the simulation).
    DelayScale,
}

impl Param {
    fn label(self) -> &'static str {
        match self {
            Param::GainScale => "gain scale c (every gain × c)",
            Param::DelayScale => "delay scale r (every delay × r)",
        }
    }
}

/// One axis of the grid: `lo..=hi` in `n` points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Axis {
    /// Quantity.
    pub param: Param,
    /// First value.
    pub lo: f64,
    /// Last value.
    pub hi: f64,
    /// Number of points (≥ 2).
    pub n: usize,
}

impl Axis {
    /// Parses `NAME=LO:HI:N`, e.g. `gain_scale=0.2:3:25`.
    pub fn parse(flag: &str, s: &str) -> Result<Self, InputError> {
        let bad = |why: &str| {
            InputError::new(format!("{flag} = {s:?}: {why}; expected NAME=LO:HI:N with NAME gain_scale or delay_scale, e.g. gain_scale=0.2:3:25"))
        };
        let (name, range) = s.split_once('=').ok_or_else(|| bad("missing '='"))?;
        let param = match name {
            "gain_scale" => Param::GainScale,
            "delay_scale" => Param::DelayScale,
            _ => return Err(bad("unknown parameter")),
        };
        let parts: Vec<&str> = range.split(':').collect();
        if parts.len() != 3 {
            return Err(bad("need three numbers LO:HI:N"));
        }
        let lo: f64 = parts[0].parse().map_err(|_| bad("LO is not a number"))?;
        let hi: f64 = parts[1].parse().map_err(|_| bad("HI is not a number"))?;
        let n: usize = parts[2]
            .parse()
            .map_err(|_| bad("N is not a whole number"))?;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
            return Err(bad("need 0 < LO < HI"));
        }
        if !(2..=400).contains(&n) {
            return Err(bad("N must be between 2 and 400"));
        }
        Ok(Self { param, lo, hi, n })
    }

    /// The k-th value.
    pub fn value(&self, k: usize) -> f64 {
        self.lo + (self.hi - self.lo) * k as f64 / (self.n - 1) as f64
    }
}

/// Outcome at one grid point.
#[derive(Debug, Clone, Serialize)]
pub struct Point {
    /// x value.
    pub x: f64,
    /// y value.
    pub y: f64,
    /// Theorem 1 (or 1+) certifies synchronization.
    pub certified: bool,
    /// Spectral abscissa of the roots other than the consensus root [1/s].
    pub abscissa_per_s: Option<f64>,
    /// Exactly stable (abscissa < 0).
    pub exact_stable: Option<bool>,
    /// Native simulation verdict (absent with `--no-sim`).
    pub simulated: Option<Verdict>,
    /// Delays actually simulated were rounded to the step grid; largest change [s].
    pub delay_rounding_s: f64,
}

fn scaled(m: &DelayedDriverModel, gain: f64, delay: f64, step_s: f64) -> (DelayedDriverModel, f64) {
    let mut s = m.clone();
    s.graph = m.graph.scaled(gain);
    if let Some((_, b)) = s.leader.as_mut() {
        b.iter_mut().for_each(|x| *x *= gain);
    }
    let mut worst: f64 = 0.0;
    for (i, a) in m.delay_s.iter().enumerate() {
        let exact = a * delay;
        let steps = (exact / step_s).round();
        s.delay_steps[i] = steps as usize;
        s.delay_s[i] = exact;
        worst = worst.max((steps * step_s - exact).abs());
    }
    (s, worst)
}

fn evaluate_point(
    sc: &Scenario,
    base: &DelayedDriverModel,
    method: Method,
    x: (Param, f64),
    y: (Param, f64),
) -> Point {
    let scale = |p: Param| {
        [x, y]
            .iter()
            .filter(|(q, _)| *q == p)
            .map(|(_, v)| *v)
            .product::<f64>()
    };
    let (gain, delay) = (scale(Param::GainScale), scale(Param::DelayScale));
    let (m, rounding) = scaled(base, gain, delay, sc.step_s());
    let certified = match &m.leader {
        None => theory::theorem1(&m.graph, &m.delay_s).holds,
        Some((_, b)) => theory::theorem1_plus(&m.graph, &m.delay_s, b).holds,
    };
    let abscissa = method.abscissa(&m, gain, delay);
    Point {
        x: x.1,
        y: y.1,
        certified,
        abscissa_per_s: abscissa,
        exact_stable: abscissa.map(|a| a < 0.0),
        simulated: None,
        delay_rounding_s: rounding,
    }
}

/// The native verdict at every grid point, from a sweep over `scale.gain` × `scale.delay` (the
/// map is a preset of `syncroad sweep`: the same pipeline, table and folder, in `OUT/sweep`).
/// Returned in grid order, x fastest.
fn simulate_grid(
    path: &Path,
    sc: &Scenario,
    xa: &Axis,
    ya: &Axis,
    out: &Path,
    jobs: usize,
) -> anyhow::Result<Vec<Option<Verdict>>> {
    let field = |p: Param| match p {
        Param::GainScale => "scale.gain",
        Param::DelayScale => "scale.delay",
    };
    let base =
        std::path::absolute(path).with_context(|| format!("cannot resolve {}", path.display()))?;
    let spec = serde_json::json!({
        "name": format!("{} map", sc.name()),
        "base": base,
        "backend": "native",
        "axes": [
            {"field": field(xa.param), "linspace": [xa.lo, xa.hi, xa.n]},
            {"field": field(ya.param), "linspace": [ya.lo, ya.hi, ya.n]},
        ],
        "metrics": ["sync.verdict", "sync.final_spread_mps", "certified"],
        // Neighbouring cells may round to the same delays; map.csv records each rounding.
        "allow_alike_points": true,
    });
    let sweep = Sweep::new(spec, Path::new("."), "map".into())?;
    let dir = out.join("sweep");
    // The caller holds `out`'s lock (one map at a time writes there); the map owns
    // `out/sweep` and starts it afresh.
    check_sweep_folder(&dir)?;
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove the previous {}", dir.display()))?;
    }
    let _sweep_lock = exec::open_out(&sweep, &dir, Shard::all())?;
    let opts = ExecOptions {
        jobs,
        shard: Shard::all(),
        keep_runs: false,
        run_plots: false,
        retry_failed: false,
        fcd: false,
        fcd_every: 1,
    };
    let summary = exec::run(&sweep, &dir, &opts, interrupt_flag()?)?;
    if summary.interrupted > 0 {
        return Err(anyhow::anyhow!(
            "interrupted; the finished grid points are in {}",
            dir.display()
        ));
    }
    let rows = crate::sweep::rows::read_rows(&sweep, &dir, Shard::all())?;
    let mut verdicts = vec![None; xa.n * ya.n];
    for (id, row) in &rows {
        let p = sweep.point(*id);
        verdicts[p.at[0] + p.at[1] * xa.n] = row
            .get("sync.verdict")
            .and_then(|v| v.as_str())
            .and_then(|v| match v {
                "synchronized" => Some(Verdict::Synchronized),
                "not_synchronized" => Some(Verdict::NotSynchronized),
                "inconclusive" => Some(Verdict::Inconclusive),
                _ => None,
            });
    }
    let table = exec::table(&sweep, rows);
    table.write_parquet(&dir.join("results.parquet"))?;
    table.write_csv(&dir.join("results.csv"))?;
    Ok(verdicts)
}

/// `OUT/sweep` is the map's own: absent, or a folder an earlier map's sweep wrote (it holds
/// `sweep.json` with a spec named `SCENARIO map`). Anything else there is the user's and is never
/// removed; checked before any work.
fn check_sweep_folder(dir: &Path) -> anyhow::Result<()> {
    let Ok(meta) = std::fs::symlink_metadata(dir) else {
        return Ok(());
    };
    let ours = meta.is_dir()
        && std::fs::read_to_string(dir.join("sweep.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .is_some_and(|v| {
                v["spec"]["name"]
                    .as_str()
                    .is_some_and(|n| n.ends_with(" map"))
            });
    if ours {
        return Ok(());
    }
    Err(InputError::new(format!(
        "--out: {} exists and is not a sweep an earlier map wrote there; map writes its simulations into OUT/sweep, so move it away or give another --out",
        dir.display()
    ))
    .into())
}

/// Theory at every grid point (Theorem 1 and the exact abscissa), in parallel over the cores,
/// with progress on stderr.
pub fn theory_grid(sc: &Scenario, xa: Axis, ya: Axis, jobs: usize) -> anyhow::Result<Vec<Point>> {
    let Model::DelayedDriver(base) = sc.model() else {
        return Err(InputError::new("map sweeps delayed-driver scenarios (model.type = \"delayed_driver\"); use `syncroad stability` for CACC platoons").into());
    };
    if xa.param == ya.param {
        return Err(InputError::new(format!(
            "--x and --y both sweep {:?}; choose two different parameters",
            xa.param
        ))
        .into());
    }
    let size = base.graph.len() + usize::from(base.leader.is_some());
    let method = Method::of(sc, base);
    if method == Method::Network && size > FULL_SOLVE_LIMIT {
        return Err(InputError::new(format!(
            "the scenario has {size} vehicles: exact roots at every grid point need a uniform ring (any size) or at most {FULL_SOLVE_LIMIT} vehicles"
        ))
        .into());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()?;
    let progress = Progress::new("map", (xa.n * ya.n) as u64);
    let pts = pool.install(|| {
        (0..xa.n * ya.n)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % xa.n, k / xa.n);
                let p = evaluate_point(
                    sc,
                    base,
                    method,
                    (xa.param, xa.value(i)),
                    (ya.param, ya.value(j)),
                );
                progress.finished("grid point", None);
                p
            })
            .collect()
    });
    progress.done();
    Ok(pts)
}

/// The boundaries of the scenario (NaN / none for models without gains and delays to scale).
pub fn boundaries(sc: &Scenario) -> Boundaries {
    exact::gain_delay_boundaries(sc).unwrap_or(Boundaries {
        theorem1_product: f64::NAN,
        exact_product: None,
        exact_certified: false,
    })
}

/// Writes map.csv.
pub fn write_csv(path: &Path, pts: &[Point]) -> anyhow::Result<()> {
    let mut s = String::from(
        "x,y,certified_theorem1,abscissa_per_s,exact_stable,simulated,delay_rounding_s\n",
    );
    for p in pts {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{}",
            p.x,
            p.y,
            p.certified,
            p.abscissa_per_s.map_or(String::new(), |a| a.to_string()),
            p.exact_stable.map_or(String::new(), |b| b.to_string()),
            p.simulated
                .map_or(String::new(), |v| v.to_string().replace(' ', "_")),
            p.delay_rounding_s
        );
    }
    crate::output::write_text(path, &s)
}

macro_rules! draw_map {
    ($area:expr, $title:expr, $xa:expr, $ya:expr, $pts:expr, $bounds:expr) => {{
        let (xa, ya, pts, bounds): (&Axis, &Axis, &[Point], &Boundaries) =
            ($xa, $ya, $pts, $bounds);
        let dx = (xa.hi - xa.lo) / (xa.n - 1) as f64 / 2.0;
        let dy = (ya.hi - ya.lo) / (ya.n - 1) as f64 / 2.0;
        let mut chart = ChartBuilder::on($area)
            .caption($title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d((xa.lo - dx)..(xa.hi + dx), (ya.lo - dy)..(ya.hi + dy))
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(xa.param.label())
            .y_desc(ya.param.label())
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(err)?;
        let stable = RGBColor(200, 235, 200);
        let unstable = RGBColor(245, 205, 205);
        let unknown = RGBColor(225, 225, 225);
        chart
            .draw_series(pts.iter().map(|p| {
                let c = match p.exact_stable {
                    Some(true) => stable,
                    Some(false) => unstable,
                    None => unknown,
                };
                Rectangle::new([(p.x - dx, p.y - dy), (p.x + dx, p.y + dy)], c.filled())
            }))
            .map_err(err)?
            .label("exactly stable (green) / unstable (red)")
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], stable.filled()));
        chart
            .draw_series(pts.iter().filter(|p| p.certified).map(|p| {
                Rectangle::new(
                    [
                        (p.x - dx * 0.25, p.y - dy * 0.25),
                        (p.x + dx * 0.25, p.y + dy * 0.25),
                    ],
                    RGBColor(40, 120, 40).filled(),
                )
            }))
            .map_err(err)?
            .label("certified by Theorem 1")
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x + 4, y - 3), (x + 10, y + 3)],
                    RGBColor(40, 120, 40).filled(),
                )
            });
        chart
            .draw_series(pts.iter().filter(|p| p.simulated.is_some()).map(|p| {
                let (col, r) = match p.simulated {
                    Some(Verdict::Synchronized) => (BLUE, 4),
                    Some(Verdict::NotSynchronized) => (RED, 4),
                    _ => (RGBColor(120, 120, 120), 3),
                };
                Circle::new((p.x, p.y), r, col.stroke_width(1))
            }))
            .map_err(err)?
            .label("simulation: synchronized (blue) / not (red) / inconclusive (grey)")
            .legend(|(x, y)| Circle::new((x + 7, y), 4, BLUE.stroke_width(1)));
        // Boundaries c·r = const as curves over the x range.
        let curve = |product: f64| {
            (0..=400).filter_map(move |k| {
                let x = xa.lo + (xa.hi - xa.lo) * k as f64 / 400.0;
                let y = product / x;
                (y >= ya.lo - dy && y <= ya.hi + dy).then_some((x, y))
            })
        };
        if bounds.theorem1_product.is_finite() {
            chart
                .draw_series(LineSeries::new(
                    curve(bounds.theorem1_product),
                    RGBColor(40, 120, 40).stroke_width(2),
                ))
                .map_err(err)?
                .label(format!(
                    "Theorem 1 boundary c·r = {:.4}",
                    bounds.theorem1_product
                ))
                .legend(|(x, y)| {
                    PathElement::new(
                        vec![(x, y), (x + 15, y)],
                        RGBColor(40, 120, 40).stroke_width(2),
                    )
                });
        }
        if let Some(c) = bounds.exact_product {
            chart
                .draw_series(LineSeries::new(curve(c), BLACK.stroke_width(2)))
                .map_err(err)?
                .label(format!("exact boundary c·r = {c:.4}"))
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 15, y)], BLACK.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(err)?;
        anyhow::Ok(())
    }};
}

/// Draws map.png and map.svg.
pub fn plot(
    dir: &Path,
    title: &str,
    xa: &Axis,
    ya: &Axis,
    pts: &[Point],
    bounds: &Boundaries,
) -> anyhow::Result<Vec<PathBuf>> {
    crate::plots::ensure_font();
    let png = dir.join("map.png");
    let svg = dir.join("map.svg");
    write_result_via_path(&png, |tmp: &Path| {
        crate::plots::draw_png(tmp, (1000, 800), |area| {
            draw_map!(area, title, xa, ya, pts, bounds)
        })
    })?;
    write_result_via_path(&svg, |tmp: &Path| {
        let area = SVGBackend::new(tmp, (1000, 800)).into_drawing_area();
        area.fill(&WHITE).map_err(err)?;
        draw_map!(&area, title, xa, ya, pts, bounds)?;
        area.present().map_err(err)
    })?;
    Ok(vec![png, svg])
}

/// `syncroad map`: the grid, its CSV and its plot.
pub fn run(
    path: &Path,
    x: &str,
    y: &str,
    out: &Path,
    no_sim: bool,
    jobs: Option<usize>,
) -> anyhow::Result<Status> {
    let sc = load_scenario(path)?;
    let xa = Axis::parse("--x", x)?;
    let ya = Axis::parse("--y", y)?;
    let jobs = config::jobs(jobs)?;
    let _lock = crate::output::prepare_dir(
        "--out",
        out,
        &["map.csv"],
        &crate::output::Inputs::scenario(path, &sc),
    )?;
    if !no_sim {
        check_sweep_folder(&out.join("sweep"))?;
        // The simulated grid's largest delays must fit their buffers: refused now, not after
        // the exact analysis of every point.
        for (flag, a) in [("--x", &xa), ("--y", &ya)] {
            if a.param == Param::DelayScale {
                sc.scaled(1.0, a.hi).map_err(|e| {
                    InputError::new(format!(
                        "{flag} = delay_scale up to {}: {e}; or give --no-sim (the exact analysis has no such limit)",
                        a.hi
                    ))
                })?;
            }
        }
    }
    let mut pts = theory_grid(&sc, xa, ya, jobs)?;
    if !no_sim {
        for (p, v) in pts
            .iter_mut()
            .zip(simulate_grid(path, &sc, &xa, &ya, out, jobs)?)
        {
            p.simulated = v;
        }
    }
    write_csv(&out.join("map.csv"), &pts)?;
    let bounds = boundaries(&sc);
    plot(
        out,
        &format!("{}: Theorem 1 vs exact stability", sc.name()),
        &xa,
        &ya,
        &pts,
        &bounds,
    )?;
    outln!(
        "boundaries (gain scale × delay scale): Theorem 1 at {:.6}, exact at {}",
        bounds.theorem1_product,
        bounds
            .exact_product
            .map_or("— (not computed)".to_string(), |c| format!(
                "{c:.6} (ratio {:.4}){}",
                c / bounds.theorem1_product,
                if bounds.exact_certified {
                    ""
                } else {
                    ", UNCERTIFIED: the root counts at c* do not confirm it"
                }
            ))
    );
    let certified = pts.iter().filter(|p| p.certified).count();
    let stable = pts.iter().filter(|p| p.exact_stable == Some(true)).count();
    let contradictions = pts
        .iter()
        .filter(|p| p.certified && p.exact_stable == Some(false))
        .count();
    let unknown = pts.iter().filter(|p| p.exact_stable.is_none()).count();
    outln!(
        "{} grid points: {certified} certified by Theorem 1, {stable} exactly stable{}{}",
        pts.len(),
        if unknown > 0 {
            format!(", {unknown} without an exact verdict (blank: the roots could not be computed, or gain × delay is below {MIN_GAIN_DELAY:e}, where they lie within the root searches' tolerances of s = 0)")
        } else {
            String::new()
        },
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
        outln!("simulations: {sync} synchronized; {disagree} disagree with the exact verdict (near the boundary the horizon may be too short)");
    }
    outln!("wrote {}/map.csv, map.png, map.svg", out.display());
    Ok(Status::Success)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_parsing_names_the_problem() {
        let a = Axis::parse("--x", "gain_scale=0.5:2:4").unwrap();
        assert_eq!(a.param, Param::GainScale);
        assert_eq!(a.value(3), 2.0);
        let e = Axis::parse("--x", "speed=1:2:3").unwrap_err().to_string();
        assert!(
            e.starts_with("--x = \"speed=1:2:3\": unknown parameter"),
            "{e}"
        );
        let e = Axis::parse("--y", "delay_scale=2:1:3")
            .unwrap_err()
            .to_string();
        assert!(e.contains("need 0 < LO < HI"), "{e}");
    }
}
