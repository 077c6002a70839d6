//! The one speed-spread plot: named `(t, spread)` series on a log axis, for a single run
//! (`spread.png`) and for every run of a comparison (`compare_spread.png`).

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use syncroad_control::metrics::spread_series;
use syncroad_control::Trajectory;

use super::{axis, err, render_both};

/// One run's speed spread over time.
#[derive(Debug, Clone, Default)]
pub struct Spread {
    /// The run's name (legend; empty: no legend).
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

/// What to call the plot.
pub struct SpreadLabels<'a> {
    /// File stem (`spread`, `compare_spread`).
    pub stem: &'a str,
    /// Caption.
    pub title: &'a str,
    /// Label of the spread axis.
    pub y_desc: &'a str,
}

/// Draws `series` on one log axis as `STEM.png` and `STEM.svg` in `dir`. Samples that are
/// not finite and positive cannot sit on a log axis and are left out; when no sample is (a run
/// in perfectly uniform flow has spread 0 throughout), the axes are drawn with a caption that
/// says so. Without any sample at all (every run failed before its first step) nothing is
/// drawn.
pub fn spread_plot(
    dir: &Path,
    labels: &SpreadLabels<'_>,
    series: &[Spread],
) -> anyhow::Result<Vec<PathBuf>> {
    let shown = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite() && p.1 > 0.0;
    let all = || series.iter().flat_map(|s| s.points.iter());
    if all().next().is_none() {
        // No run produced a sample: nothing was measured, so there is nothing to draw.
        return Ok(Vec::new());
    }
    let t = axis::linear(all().map(|p| p.0), 1.0, 0.0..1.0);
    let t = t.start.min(0.0)..t.end;
    let (y, caption) = match axis::log(all().map(|p| p.1)) {
        Some(y) => (y, labels.title.to_string()),
        None => (
            1e-12..1.0,
            format!("{} (spread 0 at every sample)", labels.title),
        ),
    };
    let legend = series.iter().any(|s| !s.name.is_empty());
    render_both!(dir, labels.stem, (900, 500), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(&caption, ("sans-serif", 20))
            .margin(10)
            // Room for the last tick's label past the axis's end.
            .margin_right(24)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(t.clone(), y.clone().log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("time [s]")
            .y_desc(labels.y_desc)
            .x_label_formatter(&|v| super::tick(*v))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(err)?;
        for (k, s) in series.iter().enumerate() {
            let colour = super::pick(k).to_rgba();
            let drawn = chart
                .draw_series(LineSeries::new(
                    s.points.iter().filter(shown).copied(),
                    colour.stroke_width(2),
                ))
                .map_err(err)?;
            if legend {
                drawn
                    .label(s.name.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            }
        }
        if legend {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(err)?;
        }
        Ok(())
    })
}
