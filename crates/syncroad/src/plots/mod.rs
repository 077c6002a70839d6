//! Plots of a run, each as PNG and SVG: the time-space diagram (position along the road
//! against time, coloured by speed), speed traces, and the speed spread on a log scale.
//!
//! The font comes embedded (Ubuntu Light, a proportional face whose numerals and decimal
//! point set tight, from `epaint_default_fonts`), so plots render the same on every machine
//! without system fonts.

use std::path::{Path, PathBuf};
use std::sync::Once;

use anyhow::anyhow;
use plotters::prelude::*;
use syncroad_control::Trajectory;

pub(crate) mod axis;
pub mod field;
mod spread;

pub use spread::{spread_plot, Spread, SpreadLabels};

static FONT: Once = Once::new();

pub(crate) fn ensure_font() {
    FONT.call_once(|| {
        // The embedded font is a valid TrueType file; failure would be a packaging bug.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

/// Whether the plots are also written as PDF (`--pdf`).
static PDF: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Sets whether [`render_both`] writes a PDF too (the command's `--pdf`).
pub(crate) fn set_pdf(on: bool) {
    PDF.store(on, std::sync::atomic::Ordering::Relaxed);
}

/// True when the plots are also written as PDF.
pub(crate) fn pdf() -> bool {
    PDF.load(std::sync::atomic::Ordering::Relaxed)
}

/// The plots' SVG as a PDF page with real text: the same drawing, its `sans-serif` text set in
/// the embedded font (subset into the file, with its Unicode map, so the text can be searched
/// and copied), at the SVG's size in points (96 px to the inch).
pub(crate) fn svg_to_pdf(svg: &str) -> anyhow::Result<Vec<u8>> {
    use svg2pdf::usvg;
    static FONTS: std::sync::OnceLock<std::sync::Arc<usvg::fontdb::Database>> =
        std::sync::OnceLock::new();
    let fontdb = FONTS
        .get_or_init(|| {
            let mut db = usvg::fontdb::Database::new();
            db.load_font_data(epaint_default_fonts::UBUNTU_LIGHT.to_vec());
            let family = db
                .faces()
                .next()
                .and_then(|f| f.families.first().map(|(name, _)| name.clone()))
                .unwrap_or_else(|| "Ubuntu".into());
            db.set_sans_serif_family(family);
            std::sync::Arc::new(db)
        })
        .clone();
    let options = usvg::Options {
        fontdb,
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| anyhow!("plot SVG: {e}"))?;
    svg2pdf::to_pdf(
        &tree,
        svg2pdf::ConversionOptions::default(),
        svg2pdf::PageOptions::default(),
    )
    .map_err(|e| anyhow!("plot PDF: {e}"))
}

/// The Okabe–Ito palette without its yellow: distinguishable under the common colour-vision
/// deficiencies, and no light colour on the white background (M. Okabe and K. Ito, "Color
/// Universal Design", 2008).
pub(crate) const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),   // blue
    RGBColor(213, 94, 0),    // vermillion
    RGBColor(0, 158, 115),   // bluish green
    RGBColor(204, 121, 167), // reddish purple
    RGBColor(230, 159, 0),   // orange
    RGBColor(86, 180, 233),  // sky blue
    RGBColor(0, 0, 0),       // black
];

/// The `k`-th colour of [`PALETTE`], round again after the last.
pub(crate) fn pick(k: usize) -> RGBColor {
    PALETTE[k % PALETTE.len()]
}

/// A tick label: whole numbers without a decimal point (`100`, not `100.0`), others with the
/// fewest decimals (at most three) that show them.
pub(crate) fn tick(v: f64) -> String {
    if (v - v.round()).abs() <= 1e-9 * v.abs().max(1.0) {
        return format!("{}", v.round() as i64);
    }
    let text = format!("{v:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Colour of a speed on plotters' viridis map (dark blue: slow → yellow: fast); the middle of
/// the map when the range is empty or the speed is not finite.
pub(crate) fn speed_colour(v: f64, vmin: f64, vmax: f64) -> RGBColor {
    let x = if vmax > vmin && v.is_finite() {
        ((v - vmin) / (vmax - vmin)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    ViridisRGB::get_color(x)
}

/// Draws a white picture of `size` pixels with `draw` on plotters' bitmap backend and writes
/// it to `path` as an 8-bit RGB PNG.
pub(crate) fn draw_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let mut rgb = vec![0u8; 3 * size.0 as usize * size.1 as usize];
    {
        let area = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        area.fill(&WHITE).map_err(err)?;
        draw(&area)?;
        area.present().map_err(err)?;
    }
    let file = std::fs::File::create(path)
        .map_err(|e| anyhow!("cannot create {}: {e}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(err)?;
    w.write_image_data(&rgb).map_err(err)?;
    w.finish().map_err(err)
}

/// A plotting backend error as an anyhow error.
pub(crate) fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("plotting failed: {e:?}")
}

/// Writes `<stem>.png` and `<stem>.svg`, with `--pdf` also `<stem>.pdf` (each a result file,
/// replaced atomically), from the same drawing code (a macro, because the drawing is generic
/// over the backend and closures cannot be); the PDF is the SVG's vectors and text
/// ([`svg_to_pdf`]).
macro_rules! render_both {
    ($dir:expr, $stem:expr, $size:expr, |$root:ident| $body:block) => {{
        $crate::plots::ensure_font();
        let png = $dir.join(format!("{}.png", $stem));
        let svg = $dir.join(format!("{}.svg", $stem));
        $crate::output::write_result_via_path(&png, |tmp: &std::path::Path| {
            $crate::plots::draw_png(tmp, $size, |$root| $body)
        })?;
        $crate::output::write_result_via_path(&svg, |tmp: &std::path::Path| {
            let area = SVGBackend::new(tmp, $size).into_drawing_area();
            area.fill(&WHITE).map_err(err)?;
            let $root = &area;
            (|| -> anyhow::Result<()> { $body })()?;
            area.present().map_err(err)
        })?;
        let mut files = vec![png, svg.clone()];
        if $crate::plots::pdf() {
            let pdf = $dir.join(format!("{}.pdf", $stem));
            let text = std::fs::read_to_string(&svg)
                .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", svg.display()))?;
            let bytes = $crate::plots::svg_to_pdf(&text)?;
            $crate::output::write_result_via_path(&pdf, |tmp: &std::path::Path| {
                std::fs::write(tmp, &bytes)
                    .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", tmp.display()))
            })?;
            files.push(pdf);
        }
        Ok(files)
    }};
}
pub(crate) use render_both;

/// One time-space diagram: points (time \[s\], position \[m\], speed \[m/s\]) coloured
/// by speed on a fixed scale, with its colour bar.
struct TimeSpace {
    stem: &'static str,
    title: String,
    time: std::ops::Range<f64>,
    space: std::ops::Range<f64>,
    y_desc: &'static str,
    speeds: (f64, f64),
    /// Places along the road to mark (an edge's start: an on-ramp's merge, a lane drop),
    /// each with its name.
    marks: Vec<(String, f64)>,
    /// Samples of the vehicles a law drove among the others, drawn over them in black.
    automated: Vec<(f64, f64, f64)>,
}

impl TimeSpace {
    fn draw(&self, dir: &Path, pts: &[(f64, f64, f64)]) -> anyhow::Result<Vec<PathBuf>> {
        let (vmin, vmax) = self.speeds;
        render_both!(dir, self.stem, (1100, 650), |root| {
            let (main, bar) = root.split_horizontally(root.dim_in_pixel().0 - 130);
            let mut chart = ChartBuilder::on(&main)
                .caption(&self.title, ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(self.time.clone(), self.space.clone())
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("time [s]")
                .y_desc(self.y_desc)
                .x_label_formatter(&|v| tick(*v))
                .y_label_formatter(&|v| tick(*v))
                .disable_mesh()
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            chart
                .draw_series(
                    pts.iter().filter(|p| p.1.is_finite()).map(|&(t, y, v)| {
                        Circle::new((t, y), 1, speed_colour(v, vmin, vmax).filled())
                    }),
                )
                .map_err(err)?;
            if !self.automated.is_empty() {
                chart
                    .draw_series(
                        self.automated
                            .iter()
                            .filter(|p| p.1.is_finite())
                            .map(|&(t, y, _)| Circle::new((t, y), 1, BLACK.filled())),
                    )
                    .map_err(err)?
                    .label("vehicles a law drove")
                    .legend(|(x, y)| Circle::new((x + 10, y), 3, BLACK.filled()));
            }
            for (name, at) in &self.marks {
                let (t0, t1) = (self.time.start, self.time.end);
                chart
                    .draw_series(DashedLineSeries::new(
                        [(t0, *at), (t1, *at)],
                        6,
                        4,
                        BLACK.stroke_width(1),
                    ))
                    .map_err(err)?;
                chart
                    .draw_series(std::iter::once(Text::new(
                        format!("{name} (edge starts)"),
                        (t0 + 0.01 * (t1 - t0), *at),
                        ("sans-serif", 13).into_font().color(&BLACK),
                    )))
                    .map_err(err)?;
            }
            if !self.automated.is_empty() {
                chart
                    .configure_series_labels()
                    .border_style(BLACK)
                    .background_style(WHITE.mix(0.85))
                    .draw()
                    .map_err(err)?;
            }
            // Colour bar.
            let mut cb = ChartBuilder::on(&bar)
                .margin_top(40)
                .margin_bottom(50)
                .margin_right(12)
                .y_label_area_size(84)
                .build_cartesian_2d(0.0..1.0, vmin..vmax)
                .map_err(err)?;
            cb.configure_mesh()
                .disable_x_axis()
                .disable_mesh()
                // The scale spans where 96 % of the samples lie; the rest take its end colours.
                .y_desc("speed [m/s], 2nd–98th percentile")
                .y_labels(8)
                .y_label_formatter(&|v| format!("{v:.2}"))
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
}

/// The files of the time-space diagram of every vehicle ([`field_time_space`]).
pub const FIELD_PLOT_FILES: [&str; 3] = [
    "time_space_all.png",
    "time_space_all.svg",
    "time_space_all.pdf",
];

/// The files written of each plot: PNG and SVG, and PDF with `--pdf`.
pub(crate) fn files_per_plot() -> usize {
    if pdf() {
        3
    } else {
        2
    }
}

/// SUMO writes about this many bytes per vehicle and step into its floating-car data.
const FCD_BYTES_PER_RECORD: u64 = 120;

/// The time-space diagram of every vehicle on the road, syncroad's and everyone else's (the
/// vehicles a law drove in an inflow in black, each edge's start — a merge, a lane drop —
/// dashed and named), from the floating-car data in the run's SUMO folder `sumo_dir` ([`field`]); no files when the
/// run wrote none. The time steps are thinned to keep about 150k points (judged from the
/// file's size).
pub fn field_time_space(dir: &Path, sumo_dir: &Path, title: &str) -> anyhow::Result<Vec<PathBuf>> {
    let bytes = std::fs::metadata(sumo_dir.join(syncroad_sumo::FCD_FILE)).map_or(0, |m| m.len());
    let stride = usize::try_from(bytes / FCD_BYTES_PER_RECORD / 150_000)
        .unwrap_or(usize::MAX)
        .max(1);
    let Some((road, pts, automated)) = field::run_field(sumo_dir, stride)? else {
        return Ok(Vec::new());
    };
    if pts.is_empty() {
        return Ok(Vec::new());
    }
    let speeds = axis::quantiles(pts.iter().map(|p| p.2), 0.02, 0.98, 0.2, 0.0..1.0);
    let time = axis::linear(pts.iter().map(|p| p.0), 1.0, 0.0..1.0);
    TimeSpace {
        stem: "time_space_all",
        title: format!("{title} — every vehicle on the road"),
        time: time.start.min(0.0)..time.end,
        space: 0.0..road.length_m.max(1.0),
        y_desc: "position along the road [m]",
        speeds: (speeds.start, speeds.end),
        // On an open road each edge after the first starts where the one before ends: a
        // merge, a lane drop. (A loop's edges are just its arcs.)
        marks: if road.closed {
            Vec::new()
        } else {
            road.edge_starts().into_iter().skip(1).collect()
        },
        automated,
    }
    .draw(dir, &pts)
}

/// The files [`RunPlots::write_all`] writes into a run's folder.
pub const RUN_PLOT_FILES: [&str; 9] = [
    "time_space.png",
    "time_space.svg",
    "time_space.pdf",
    "speeds.png",
    "speeds.svg",
    "speeds.pdf",
    "spread.png",
    "spread.svg",
    "spread.pdf",
];

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
        // No fixed set (only an inflow's vehicles, drawn from SUMO's own data): nothing to
        // draw here.
        if self.traj.len() < 2 || self.traj.n == 0 {
            return Ok(files);
        }
        files.extend(self.time_space(dir)?);
        files.extend(self.speed_traces(dir)?);
        files.extend(self.spread(dir)?);
        Ok(files)
    }

    /// The colour scale's speeds: where 96 % of the samples lie (the 2nd to the 98th
    /// percentile, at least 0.2 m/s wide), so that the start's transient does not stretch it
    /// over the wave; faster and slower samples take the scale's end colours.
    fn speed_range(&self) -> (f64, f64) {
        let r = axis::quantiles(
            self.traj.speeds_mps.iter().copied(),
            0.02,
            0.98,
            0.2,
            0.0..1.0,
        );
        (r.start, r.end)
    }

    /// The time axis: from 0 to the last sample, at least a second long.
    fn time_range(&self) -> std::ops::Range<f64> {
        let r = axis::linear(self.traj.time_s.iter().copied(), 1.0, 0.0..1.0);
        r.start.min(0.0)..r.end
    }

    /// Time-space diagram: every vehicle's position (wrapped on a ring) against time,
    /// coloured by speed — stop-and-go waves show as bands running backwards.
    pub fn time_space(&self, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let tr = self.traj;
        let n = tr.n;
        // Keep about 150k points in the bitmap and the vector file alike.
        let stride = ((tr.len() * n) / 150_000).max(1);
        let (ymin, ymax) = match self.ring_length_m {
            Some(l) if l.is_finite() && l > 0.0 => (0.0, l),
            _ => {
                let r = axis::linear(tr.positions_m.iter().copied(), 1.0, 0.0..1.0);
                (r.start, r.end)
            }
        };
        let pts: Vec<(f64, f64, f64)> = (0..tr.len())
            .step_by(stride.div_ceil(n).max(1))
            .flat_map(|k| {
                (0..n).map(move |i| {
                    let x = tr.positions_m[k * n + i];
                    let y = self.ring_length_m.map_or(x, |l| x.rem_euclid(l));
                    (tr.time_s[k], y, tr.speeds_mps[k * n + i])
                })
            })
            .collect();
        let y_desc = if self.ring_length_m.is_some() {
            "position on ring [m]"
        } else {
            "position [m]"
        };
        let chart = TimeSpace {
            stem: "time_space",
            title: format!("{} — time-space diagram", self.title),
            time: self.time_range(),
            space: ymin..ymax,
            y_desc,
            speeds: self.speed_range(),
            marks: Vec::new(),
            automated: Vec::new(),
        };
        chart.draw(dir, &pts)
    }

    /// Speed of each vehicle against time (at most 30 vehicles, evenly chosen), over the full
    /// range of the speeds.
    pub fn speed_traces(&self, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let tr = self.traj;
        let n = tr.n;
        // The full range of every speed shown, the start's spread included (the time-space
        // diagram's colour scale leaves out the extremes; this plot shows them).
        let (vmin, vmax) = tr
            .speeds_mps
            .iter()
            .chain(&tr.leader_speed_mps)
            .copied()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        let (vmin, vmax) = if vmin <= vmax {
            (vmin, vmax)
        } else {
            self.speed_range()
        };
        let time = self.time_range();
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
                .margin_right(24)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(time.clone(), (vmin - pad)..(vmax + pad))
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc("time [s]")
                .y_desc("speed [m/s]")
                .x_label_formatter(&|v| tick(*v))
                .label_style(("sans-serif", 13))
                .axis_desc_style(("sans-serif", 15))
                .draw()
                .map_err(err)?;
            for (c, &i) in shown.iter().enumerate() {
                let colour = pick(c).mix(0.9);
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
        let title = format!("{} — speed spread", self.title);
        let labels = SpreadLabels {
            stem: "spread",
            title: &title,
            y_desc: if self.traj.leader_speed_mps.is_empty() {
                "max |v_i − v_j| [m/s]"
            } else {
                "max |v_i − v_0| [m/s]"
            },
        };
        spread_plot(dir, &labels, &[Spread::of("", self.traj)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every character the drawing code writes is in the embedded font: a missing glyph
    /// draws as a box (an arrow did, on the stability map's axes). The string literals of
    /// every module that draws are read, their non-ASCII characters looked up.
    #[test]
    fn every_character_the_plots_write_is_in_the_embedded_font() {
        use ab_glyph::Font as _;
        let font = ab_glyph::FontRef::try_from_slice(epaint_default_fonts::UBUNTU_LIGHT).unwrap();
        let sources = [
            ("plots/mod.rs", include_str!("mod.rs")),
            ("plots/axis.rs", include_str!("axis.rs")),
            ("plots/field.rs", include_str!("field.rs")),
            ("plots/spread.rs", include_str!("spread.rs")),
            ("sweep/plots.rs", include_str!("../sweep/plots.rs")),
            (
                "commands/stability_map.rs",
                include_str!("../commands/stability_map.rs"),
            ),
            ("animate/mod.rs", include_str!("../animate/mod.rs")),
            ("animate/scene.rs", include_str!("../animate/scene.rs")),
        ];
        let mut missing = Vec::new();
        for (file, text) in sources {
            for (n, line) in text.lines().enumerate() {
                let code = line.trim_start();
                if code.starts_with("//") {
                    continue;
                }
                // The text between quotes: string literals (a comment after code has none).
                for (k, part) in code.split('"').enumerate() {
                    if k % 2 == 1 {
                        for c in part.chars().filter(|c| !c.is_ascii()) {
                            if font.glyph_id(c).0 == 0 {
                                missing.push(format!("{file}:{}: {c:?} in {part:?}", n + 1));
                            }
                        }
                    }
                }
            }
        }
        assert!(missing.is_empty(), "not in the embedded font: {missing:#?}");
        // The check sees a missing glyph: the arrow the map's axes had.
        assert_eq!(font.glyph_id('→').0, 0);
    }

    #[test]
    fn colour_scale_ends_are_the_viridis_ends() {
        assert_eq!(speed_colour(0.0, 0.0, 10.0), RGBColor(68, 1, 84));
        assert_eq!(speed_colour(10.0, 0.0, 10.0), RGBColor(254, 232, 37));
        assert_eq!(speed_colour(-5.0, 0.0, 10.0), RGBColor(68, 1, 84));
        assert_eq!(
            speed_colour(f64::NAN, 0.0, 10.0),
            speed_colour(5.0, 0.0, 10.0)
        );
    }

    #[test]
    fn ticks_drop_the_decimal_point_of_whole_numbers_and_trailing_zeros() {
        assert_eq!(tick(100.0), "100");
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(-50.0), "-50");
        assert_eq!(tick(7.85), "7.85");
        assert_eq!(tick(0.5), "0.5");
        assert_eq!(tick(1e-12), "0");
    }

    #[test]
    fn the_palette_has_no_light_colour_on_white() {
        // Relative luminance (sRGB, ITU-R BT.709 weights, linearised) of each colour: the
        // contrast ratio with white (1.0) is at least 1.9:1 for each.
        for c in PALETTE {
            let lin = |u: u8| {
                let x = f64::from(u) / 255.0;
                if x <= 0.04045 {
                    x / 12.92
                } else {
                    ((x + 0.055) / 1.055).powf(2.4)
                }
            };
            let l = 0.2126 * lin(c.0) + 0.7152 * lin(c.1) + 0.0722 * lin(c.2);
            assert!(
                1.05 / (l + 0.05) >= 1.9,
                "{c:?}: contrast {}",
                1.05 / (l + 0.05)
            );
        }
    }
}
