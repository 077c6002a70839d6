//! Plots of a run, each as PNG and SVG: the time-space diagram (position along the road
//! against time, coloured by speed), speed traces, and the speed spread on a log scale.
//!
//! Fonts come embedded (Hack, from `epaint_default_fonts`), so plots render the same on
//! every machine without system fonts.

use std::path::{Path, PathBuf};
use std::sync::Once;

use anyhow::anyhow;
use plotters::prelude::*;
use syncroad_control::metrics::spread_series;
use syncroad_control::Trajectory;

static FONT: Once = Once::new();

pub(crate) fn ensure_font() {
    FONT.call_once(|| {
        // The embedded font is a valid TrueType file; failure would be a packaging bug.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::HACK_REGULAR,
        );
    });
}

/// Colour of a speed on a blue (slow) → yellow (fast) scale (viridis-like).
fn speed_colour(v: f64, vmin: f64, vmax: f64) -> RGBColor {
    let x = if vmax > vmin {
        ((v - vmin) / (vmax - vmin)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    // Piecewise-linear through five viridis anchors.
    const A: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let s = x * 4.0;
    let k = (s.floor() as usize).min(3);
    let f = s - k as f64;
    let lerp = |a: f64, b: f64| (a + (b - a) * f).round() as u8;
    RGBColor(
        lerp(A[k].0, A[k + 1].0),
        lerp(A[k].1, A[k + 1].1),
        lerp(A[k].2, A[k + 1].2),
    )
}

/// A plotting backend error as an anyhow error.
pub(crate) fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// Writes `<stem>.png` and `<stem>.svg` (each a result file, replaced atomically) from the same drawing code (a macro, because the
/// drawing is generic over the backend and closures cannot be).
macro_rules! render_both {
    ($dir:expr, $stem:expr, $size:expr, |$root:ident| $body:block) => {{
        ensure_font();
        let png = $dir.join(format!("{}.png", $stem));
        let svg = $dir.join(format!("{}.svg", $stem));
        $crate::output::write_result_via_path(&png, |tmp: &std::path::Path| {
            let area = BitMapBackend::new(tmp, $size).into_drawing_area();
            area.fill(&WHITE).map_err(err)?;
            let $root = &area;
            (|| -> anyhow::Result<()> { $body })()?;
            area.present().map_err(err)
        })?;
        $crate::output::write_result_via_path(&svg, |tmp: &std::path::Path| {
            let area = SVGBackend::new(tmp, $size).into_drawing_area();
            area.fill(&WHITE).map_err(err)?;
            let $root = &area;
            (|| -> anyhow::Result<()> { $body })()?;
            area.present().map_err(err)
        })?;
        Ok(vec![png, svg])
    }};
}
pub(crate) use render_both;

/// The drawings of one run.
pub struct RunPlots<'a> {
    /// The trajectory.
    pub traj: &'a Trajectory,
    /// Ring circumference [m] (positions are wrapped onto it), `None` on a straight road.
    pub ring_length_m: Option<f64>,
    /// Title prefix, e.g. scenario and backend.
    pub title: String,
}

impl RunPlots<'_> {
    /// Writes all plots into `dir`; returns the files written.
    pub fn write_all(&self, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        if self.traj.len() < 2 {
            return Ok(files);
        }
        files.extend(self.time_space(dir)?);
        files.extend(self.speed_traces(dir)?);
        files.extend(self.spread(dir)?);
        Ok(files)
    }

    fn speed_range(&self) -> (f64, f64) {
        let (lo, hi) = self
            .traj
            .speeds_mps
            .iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        if lo.is_finite() {
            (lo, hi.max(lo + 1e-9))
        } else {
            (0.0, 1.0)
        }
    }

    /// Time-space diagram: every vehicle's position (wrapped on a ring) against time,
    /// coloured by speed — stop-and-go waves show as bands running backwards.
    pub fn time_space(&self, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let tr = self.traj;
        let n = tr.n;
        let (vmin, vmax) = self.speed_range();
        // Keep about 150k points in the bitmap and the vector file alike.
        let stride = ((tr.len() * n) / 150_000).max(1);
        let t_end = *tr.time_s.last().unwrap_or(&1.0);
        let (ymin, ymax) = match self.ring_length_m {
            Some(l) => (0.0, l),
            None => {
                let (a, b) = tr
                    .positions_m
                    .iter()
                    .filter(|x| x.is_finite())
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                        (a.min(x), b.max(x))
                    });
                (a, b.max(a + 1.0))
            }
        };
        render_both!(dir, "time_space", (1100, 650), |root| {
            let (main, bar) = root.split_horizontally(root.dim_in_pixel().0 - 90);
            let mut chart = ChartBuilder::on(&main)
                .caption(
                    format!("{} — time-space diagram", self.title),
                    ("sans-serif", 20),
                )
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..t_end, ymin..ymax)
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("time [s]")
                .y_desc(if self.ring_length_m.is_some() {
                    "position on ring [m]"
                } else {
                    "position [m]"
                })
                .disable_mesh()
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            let pts = (0..tr.len())
                .step_by(stride.div_ceil(n).max(1))
                .flat_map(|k| {
                    (0..n).map(move |i| {
                        let x = tr.positions_m[k * n + i];
                        let y = self.ring_length_m.map_or(x, |l| x.rem_euclid(l));
                        (tr.time_s[k], y, tr.speeds_mps[k * n + i])
                    })
                });
            chart
                .draw_series(
                    pts.filter(|p| p.1.is_finite()).map(|(t, y, v)| {
                        Circle::new((t, y), 1, speed_colour(v, vmin, vmax).filled())
                    }),
                )
                .map_err(err)?;
            // Colour bar.
            let mut cb = ChartBuilder::on(&bar)
                .margin_top(40)
                .margin_bottom(50)
                .y_label_area_size(50)
                .build_cartesian_2d(0.0..1.0, vmin..vmax)
                .map_err(err)?;
            cb.configure_mesh()
                .disable_x_axis()
                .disable_mesh()
                .y_desc("speed [m/s]")
                .y_label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 14))
                .draw()
                .map_err(err)?;
            let steps = 100;
            cb.draw_series((0..steps).map(|k| {
                let a = vmin + (vmax - vmin) * k as f64 / steps as f64;
                let b = vmin + (vmax - vmin) * (k + 1) as f64 / steps as f64;
                Rectangle::new(
                    [(0.0, a), (1.0, b)],
                    speed_colour(0.5 * (a + b), vmin, vmax).filled(),
                )
            }))
            .map_err(err)?;
            Ok(())
        })
    }

    /// Speed of each vehicle against time (at most 30 vehicles, evenly chosen).
    pub fn speed_traces(&self, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let tr = self.traj;
        let n = tr.n;
        let (vmin, vmax) = self.speed_range();
        let t_end = *tr.time_s.last().unwrap_or(&1.0);
        let shown: Vec<usize> = if n <= 30 {
            (0..n).collect()
        } else {
            (0..30).map(|k| k * n / 30).collect()
        };
        render_both!(dir, "speeds", (1100, 600), |root| {
            let pad = 0.05 * (vmax - vmin).max(0.1);
            let mut chart = ChartBuilder::on(root)
                .caption(format!("{} — speeds", self.title), ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..t_end, (vmin - pad)..(vmax + pad))
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("time [s]")
                .y_desc("speed [m/s]")
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            for (c, &i) in shown.iter().enumerate() {
                let colour = Palette99::pick(c).mix(0.9);
                chart
                    .draw_series(LineSeries::new(
                        (0..tr.len())
                            .map(|k| (tr.time_s[k], tr.speeds_mps[k * n + i]))
                            .filter(|p| p.1.is_finite()),
                        colour.stroke_width(1),
                    ))
                    .map_err(err)?;
            }
            if !tr.leader_speed_mps.is_empty() {
                chart
                    .draw_series(LineSeries::new(
                        (0..tr.len()).map(|k| (tr.time_s[k], tr.leader_speed_mps[k])),
                        BLACK.stroke_width(2),
                    ))
                    .map_err(err)?
                    .label("leader v_0")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
                chart
                    .configure_series_labels()
                    .border_style(BLACK)
                    .background_style(WHITE.mix(0.8))
                    .draw()
                    .map_err(err)?;
            }
            Ok(())
        })
    }

    /// The spread `max_ij |v_i − v_j|` (or `max_i |v_i − v_0|`) on a log scale.
    pub fn spread(&self, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let tr = self.traj;
        let s = spread_series(tr);
        let t_end = *tr.time_s.last().unwrap_or(&1.0);
        let pos: Vec<f64> = s
            .iter()
            .copied()
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        let lo = pos.iter().copied().fold(f64::INFINITY, f64::min).max(1e-12);
        let hi = pos.iter().copied().fold(0.0, f64::max).max(lo * 10.0);
        render_both!(dir, "spread", (900, 500), |root| {
            let mut chart = ChartBuilder::on(root)
                .caption(format!("{} — speed spread", self.title), ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(0.0..t_end, (lo * 0.5..hi * 2.0).log_scale())
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("time [s]")
                .y_desc(if tr.leader_speed_mps.is_empty() {
                    "max |v_i − v_j| [m/s]"
                } else {
                    "max |v_i − v_0| [m/s]"
                })
                .y_label_formatter(&|y| format!("{y:.0e}"))
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            chart
                .draw_series(LineSeries::new(
                    tr.time_s
                        .iter()
                        .zip(&s)
                        .filter(|(_, y)| y.is_finite() && **y > 0.0)
                        .map(|(t, y)| (*t, *y)),
                    BLUE.stroke_width(2),
                ))
                .map_err(err)?;
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_scale_ends_are_the_viridis_ends() {
        assert_eq!(speed_colour(0.0, 0.0, 10.0), RGBColor(68, 1, 84));
        assert_eq!(speed_colour(10.0, 0.0, 10.0), RGBColor(253, 231, 37));
        assert_eq!(speed_colour(-5.0, 0.0, 10.0), RGBColor(68, 1, 84));
    }
}

/// One run's speed spread over time, for [`spread_plot`].
#[derive(Debug, Clone, Default)]
pub struct Spread {
    /// The run's name (legend).
    pub name: String,
    /// `(t, spread)` samples.
    pub points: Vec<(f64, f64)>,
}

impl Spread {
    /// The spread series of a trajectory.
    pub fn of(name: &str, traj: &Trajectory) -> Self {
        Self {
            name: name.to_string(),
            points: traj
                .time_s
                .iter()
                .copied()
                .zip(spread_series(traj))
                .collect(),
        }
    }
}

/// `compare_spread.png` and `.svg`: every run's speed spread on one log scale.
pub fn spread_plot(out: &Path, title: &str, results: &[Spread]) -> anyhow::Result<Vec<PathBuf>> {
    let pos = || {
        results
            .iter()
            .flat_map(|r| r.points.iter())
            .filter(|(_, y)| y.is_finite() && *y > 0.0)
    };
    if pos().next().is_none() {
        // No run recorded a positive spread (every run failed before its first sample): a log
        // axis over nothing has no range, so there is no plot.
        return Ok(Vec::new());
    }
    let t_end = pos().map(|p| p.0).fold(1.0, f64::max);
    let lo = pos().map(|p| p.1).fold(f64::INFINITY, f64::min).max(1e-12);
    let hi = pos().map(|p| p.1).fold(0.0, f64::max).max(lo * 10.0);
    render_both!(out, "compare_spread", (900, 500), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 20))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_end, (lo * 0.5..hi * 2.0).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc("speed spread [m/s]")
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .draw()
            .map_err(err)?;
        for (k, r) in results.iter().enumerate() {
            let colour = Palette99::pick(k).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    r.points
                        .iter()
                        .copied()
                        .filter(|(_, y)| y.is_finite() && *y > 0.0),
                    colour.stroke_width(2),
                ))
                .map_err(err)?
                .label(r.name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
        Ok(())
    })
}
