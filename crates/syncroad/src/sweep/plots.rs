//! Plots of a sweep's table, each as PNG and SVG under `OUT/plots`:
//!
//! * one numeric axis (or penetrations alone): each metric against it, the mean over seeds
//!   with its 95 % interval, one line per run (`<metric>.png`);
//! * two numeric axes: a heat map of each metric's mean over seeds per run
//!   (`heat-<metric>-<run>.png`);
//! * `scale.gain` × `scale.delay` on a delayed-driver scenario: the fraction of seeds that
//!   synchronized in each cell, with Theorem 1's and the exact boundary drawn over it
//!   (`stability-<run>.png`).
//!
//! The verdict enters the plots as the fraction of synchronized seeds.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use plotters::prelude::*;
use serde_json::{Map, Value};
use syncroad_control::exact::gain_delay_boundaries;

use super::axis::Target;
use super::spec::Sweep;
use super::stats::{mean_ci, MeanCi};
use super::table::{metric_label, Kind, Table};
use crate::plots::{axis, ensure_font, err, render_both};

/// A metric's value in a row as a number: numbers as they are, the verdict as 1
/// (synchronized) or 0, booleans as 1 or 0.
fn number(row: &Map<String, Value>, metric: &str) -> Option<f64> {
    match row.get(metric)? {
        Value::Number(n) => n.as_f64(),
        Value::Bool(b) => Some(f64::from(u8::from(*b))),
        Value::String(s) if metric == "sync.verdict" => match s.as_str() {
            "synchronized" => Some(1.0),
            "not_synchronized" => Some(0.0),
            _ => None,
        },
        _ => None,
    }
}

/// A metric's title and unit from the record's schema; the verdict plots as a fraction.
fn label(metric: &str) -> String {
    if metric == "sync.verdict" {
        "fraction synchronized".into()
    } else {
        metric_label(metric)
    }
}

/// An axis's label: a scenario field as written; penetration says what its fraction counts.
fn axis_label(axis: &str) -> String {
    if axis == "penetration" {
        "penetration [share of the vehicles automated]".into()
    } else {
        axis.to_string()
    }
}

fn file_stem(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Metrics that plot as numbers.
fn plotted_metrics(sweep: &Sweep, table: &Table) -> Vec<String> {
    sweep
        .metrics
        .iter()
        .filter(|m| {
            m.as_str() == "sync.verdict"
                || table.columns.iter().any(|c| {
                    &c.name == *m && matches!(c.kind, Kind::Float | Kind::Int | Kind::Bool)
                })
        })
        .cloned()
        .collect()
}

/// Mean and interval of `metric` over the rows sharing (run, x[, y]).
type Cells = BTreeMap<(String, Vec<u64>), (Vec<f64>, Vec<f64>)>;

fn cells(table: &Table, metric: &str, keys: &[&str]) -> Cells {
    let mut out: Cells = BTreeMap::new();
    for r in &table.rows {
        if r.get("status").and_then(Value::as_str) == Some("failed") {
            continue;
        }
        let run = r.get("run").and_then(Value::as_str).unwrap_or("");
        // Against penetration, the mixed runs of one controller form one line.
        let run = if keys == ["penetration"] {
            run.find("mixed-")
                .map_or(run, |i| &run[..i + 5])
                .to_string()
        } else {
            run.to_string()
        };
        let xs: Option<Vec<f64>> = keys
            .iter()
            .map(|k| r.get(*k).and_then(Value::as_f64))
            .collect();
        let (Some(xs), Some(v)) = (xs, number(r, metric)) else {
            continue;
        };
        let e = out
            .entry((run, xs.iter().map(|x| x.to_bits()).collect()))
            .or_insert_with(|| (xs.clone(), Vec::new()));
        e.1.push(v);
    }
    out
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// What one plotted value averages over: the seeds, and every axis with several values that
/// the plot does not show (`shown`), named so that a pooled mean is never called a mean over
/// seeds.
fn pooled_over(sweep: &Sweep, shown: &[&str]) -> String {
    let others: Vec<String> = sweep
        .axes
        .iter()
        .filter(|a| a.values.len() > 1 && !shown.contains(&a.field.as_str()))
        .map(|a| format!("{} ({} values)", a.field, a.values.len()))
        .collect();
    if others.is_empty() {
        "seeds".into()
    } else {
        format!("seeds and {}", others.join(", "))
    }
}

/// Each metric against one axis: mean over seeds with 95 % interval bars, a line per run.
fn line_plots(sweep: &Sweep, table: &Table, x: &str, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for metric in plotted_metrics(sweep, table) {
        let c = cells(table, &metric, &[x]);
        let mut series: BTreeMap<String, Vec<(f64, MeanCi)>> = BTreeMap::new();
        for ((run, _), (xs, vals)) in &c {
            if let Some(m) = mean_ci(vals) {
                series.entry(run.clone()).or_default().push((xs[0], m));
            }
        }
        if series.is_empty() {
            continue;
        }
        if x == "penetration" {
            // The all-human ring (penetration 0, the run `mixed`) ran once: it starts every
            // controller's line, and has no line of its own unless nothing else ran (no
            // legend entry without a line of data).
            if let Some(zero) = series
                .get("mixed")
                .and_then(|s| s.iter().find(|(p, _)| *p == 0.0).copied())
            {
                for (name, s) in series.iter_mut() {
                    if name.ends_with("-mixed") && !s.iter().any(|(p, _)| *p == 0.0) {
                        s.push(zero);
                    }
                }
            }
            if let Some(humans) = series.remove("mixed") {
                if series.is_empty() {
                    series.insert("all humans".into(), humans);
                }
            }
        }
        for s in series.values_mut() {
            s.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        let all = || series.values().flatten();
        let xr = axis::padded(axis::of_data(all().map(|(x, _)| *x), 0.0..1.0));
        let yr = axis::padded(axis::of_data(
            all().flat_map(|(_, m)| {
                let h = m.half_width.unwrap_or(0.0);
                [m.mean - h, m.mean + h]
            }),
            0.0..1.0,
        ));
        let title = format!(
            "{} (mean, 95 % interval over {})",
            label(&metric),
            pooled_over(sweep, &[x])
        );
        let stem = file_stem(&metric);
        let drawn: anyhow::Result<Vec<PathBuf>> = render_both!(dir, stem, (1000, 650), |root| {
            let mut chart = ChartBuilder::on(root)
                .caption(&title, ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(70)
                .build_cartesian_2d(xr.clone(), yr.clone())
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc(axis_label(x))
                .y_desc(label(&metric))
                .draw()
                .map_err(err)?;
            for (k, (run, pts)) in series.iter().enumerate() {
                let col = PALETTE[k % PALETTE.len()];
                chart
                    .draw_series(
                        LineSeries::new(pts.iter().map(|(x, m)| (*x, m.mean)), col.stroke_width(2))
                            .point_size(4),
                    )
                    .map_err(err)?
                    .label(run.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 15, y)], col.stroke_width(2))
                    });
                chart
                    .draw_series(pts.iter().filter_map(|(x, m)| {
                        m.half_width.map(|h| {
                            PathElement::new(
                                vec![(*x, m.mean - h), (*x, m.mean + h)],
                                col.stroke_width(2),
                            )
                        })
                    }))
                    .map_err(err)?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(err)?;
            Ok(())
        });
        files.extend(drawn?);
    }
    Ok(files)
}

/// plotters' viridis colour of `t` in [0, 1] (clamped; NaN: the low end).
fn viridis(t: f64) -> RGBColor {
    ViridisRGB::get_color(if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    })
}

/// Cell edges of sorted grid values: midpoints between neighbours, half a spacing outside.
fn edges(v: &[f64]) -> Vec<(f64, f64)> {
    let n = v.len();
    if n == 1 {
        return vec![(v[0] - 0.5, v[0] + 0.5)];
    }
    (0..n)
        .map(|k| {
            let lo = if k == 0 {
                v[0] - (v[1] - v[0]) / 2.0
            } else {
                (v[k - 1] + v[k]) / 2.0
            };
            let hi = if k + 1 == n {
                v[k] + (v[k] - v[k - 1]) / 2.0
            } else {
                (v[k] + v[k + 1]) / 2.0
            };
            (lo, hi)
        })
        .collect()
}

/// Whether the two plotted axes are `scale.gain` and `scale.delay` (either order): then the
/// plot carries Theorem 1's and the exact boundary.
fn on_scale_axes(sweep: &Sweep, names: (&str, &str)) -> bool {
    let t = |f: &str| {
        sweep
            .axes
            .iter()
            .find(|a| a.field == f)
            .map(|a| a.target.clone())
    };
    matches!(
        (t(names.0), t(names.1)),
        (Some(Target::GainScale), Some(Target::DelayScale))
            | (Some(Target::DelayScale), Some(Target::GainScale))
    )
}

/// A cell's colour: for the verdict red (never synchronized) to blue (every seed
/// synchronized), else viridis over `lo..hi`.
fn cell_colour(verdict: bool, v: f64, lo: f64, hi: f64) -> RGBColor {
    if verdict {
        let t = v.clamp(0.0, 1.0);
        RGBColor(
            (220.0 * (1.0 - t) + 60.0 * t) as u8,
            (80.0 + 40.0 * t) as u8,
            (70.0 * (1.0 - t) + 200.0 * t) as u8,
        )
    } else {
        viridis(if hi > lo { (v - lo) / (hi - lo) } else { 0.5 })
    }
}

/// Theorem 1's and the exact stability boundary, the hyperbolas c·r = const, over a gain ×
/// delay heat map, with their legend.
fn draw_boundaries<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    b: &syncroad_control::exact::Boundaries,
    xr: &std::ops::Range<f64>,
    yr: &std::ops::Range<f64>,
) -> anyhow::Result<()> {
    let curve = |product: f64| {
        let (xr, yr) = (xr.clone(), yr.clone());
        (0..=400).filter_map(move |k| {
            let x = xr.start + (xr.end - xr.start) * k as f64 / 400.0;
            let y = product / x;
            (x > 0.0 && y >= yr.start && y <= yr.end).then_some((x, y))
        })
    };
    // The hyperbola is symmetric in c and r: the same curve whichever is x.
    if b.theorem1_product.is_finite() {
        chart
            .draw_series(LineSeries::new(
                curve(b.theorem1_product),
                RGBColor(20, 110, 20).stroke_width(3),
            ))
            .map_err(err)?
            .label(format!(
                "Theorem 1 boundary c·r = {:.4}",
                b.theorem1_product
            ))
            .legend(|(x, y)| {
                PathElement::new(
                    vec![(x, y), (x + 15, y)],
                    RGBColor(20, 110, 20).stroke_width(3),
                )
            });
    }
    if let Some(e) = b.exact_product {
        chart
            .draw_series(LineSeries::new(curve(e), BLACK.stroke_width(3)))
            .map_err(err)?
            .label(format!("exact boundary c·r = {e:.4}"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], BLACK.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    Ok(())
}

/// Heat maps over two axes, and the stability plot when they are the two scales.
fn grid_plots(
    sweep: &Sweep,
    table: &Table,
    xs: &[f64],
    ys: &[f64],
    names: (&str, &str),
    dir: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let (xe, ye) = (edges(xs), edges(ys));
    let xr = xe[0].0..xe[xe.len() - 1].1;
    let yr = ye[0].0..ye[ye.len() - 1].1;
    let idx = |v: &[f64], x: f64| v.iter().position(|p| *p == x);
    let scales = on_scale_axes(sweep, names);
    let bounds = if scales {
        gain_delay_boundaries(&sweep.base)
    } else {
        None
    };
    for metric in plotted_metrics(sweep, table) {
        let c = cells(table, &metric, &[names.0, names.1]);
        let mut by_run: BTreeMap<String, Vec<(usize, usize, MeanCi)>> = BTreeMap::new();
        for ((run, _), (p, vals)) in &c {
            if let (Some(i), Some(j), Some(m)) = (idx(xs, p[0]), idx(ys, p[1]), mean_ci(vals)) {
                by_run.entry(run.clone()).or_default().push((i, j, m));
            }
        }
        for (run, cells) in &by_run {
            let (lo, hi) = cells
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), (_, _, m)| {
                    (a.min(m.mean), b.max(m.mean))
                });
            let verdict = metric == "sync.verdict";
            let (lo, hi) = if verdict { (0.0, 1.0) } else { (lo, hi) };
            let stem = if verdict && scales {
                format!("stability-{}", file_stem(run))
            } else {
                format!("heat-{}-{}", file_stem(&metric), file_stem(run))
            };
            let title = format!(
                "{} ({run}; mean over {} {} … {}{})",
                label(&metric),
                pooled_over(sweep, &[names.0, names.1]),
                fmt(lo),
                fmt(hi),
                if verdict { "; grey: no verdict" } else { "" }
            );
            let drawn: anyhow::Result<Vec<PathBuf>> =
                render_both!(dir, stem, (1000, 800), |root| {
                    let mut chart = ChartBuilder::on(root)
                        .caption(&title, ("sans-serif", 14))
                        .margin(12)
                        .x_label_area_size(45)
                        .y_label_area_size(60)
                        .build_cartesian_2d(xr.clone(), yr.clone())
                        .map_err(err)?;
                    chart
                        .configure_mesh()
                        .disable_mesh()
                        .x_desc(axis_label(names.0))
                        .y_desc(axis_label(names.1))
                        .draw()
                        .map_err(err)?;
                    if verdict {
                        // Cells without a decisive verdict (inconclusive, failed) stay grey.
                        chart
                            .plotting_area()
                            .fill(&RGBColor(200, 200, 200))
                            .map_err(err)?;
                    }
                    chart
                        .draw_series(cells.iter().map(|(i, j, m)| {
                            Rectangle::new(
                                [(xe[*i].0, ye[*j].0), (xe[*i].1, ye[*j].1)],
                                cell_colour(verdict, m.mean, lo, hi).filled(),
                            )
                        }))
                        .map_err(err)?;
                    if let Some(b) = bounds {
                        draw_boundaries(&mut chart, &b, &xr, &yr)?;
                    }
                    Ok(())
                });
            files.extend(drawn?);
        }
    }
    Ok(files)
}

fn fmt(x: f64) -> String {
    if x.abs() >= 1e4 || (x != 0.0 && x.abs() < 1e-3) {
        format!("{x:.3e}")
    } else {
        format!("{x:.4}")
    }
}

/// Draws every plot the sweep's shape allows into `dir`; returns the files.
pub fn draw(sweep: &Sweep, table: &Table, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    ensure_font();
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let numeric: Vec<(&str, Vec<f64>)> = sweep
        .axes
        .iter()
        .filter(|a| a.values.len() > 1)
        .filter_map(|a| {
            let mut v = a.numbers()?;
            v.sort_by(f64::total_cmp);
            v.dedup();
            Some((a.field.as_str(), v))
        })
        .collect();
    match numeric.as_slice() {
        [] if sweep.file.penetrations.len() > 1 => line_plots(sweep, table, "penetration", dir),
        [(x, _)] => line_plots(sweep, table, x, dir),
        [(x, xs), (y, ys)] => grid_plots(sweep, table, xs, ys, (x, y), dir),
        _ => Ok(Vec::new()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_edges_are_midpoints() {
        assert_eq!(
            edges(&[1.0, 2.0, 4.0]),
            vec![(0.5, 1.5), (1.5, 3.0), (3.0, 5.0)]
        );
        assert_eq!(edges(&[2.0]), vec![(1.5, 2.5)]);
    }
}
