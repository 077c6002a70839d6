//! Animations of finished runs: the road drawn from its own geometry (the network's lanes of a
//! SUMO run, a circle or a line for a native run), every vehicle a disc coloured by its speed
//! on the time-space diagram's scale, the vehicles a controller drives among humans ringed in
//! black, the simulated time shown; several runs side by side on one time axis and one colour
//! scale. Written as an animated GIF.
//!
//! Frames are drawn on an indexed canvas (the static picture once, through plotters; the
//! vehicles and the clock per frame), each frame stored as the box that changed since the
//! previous one, compressed in parallel and written in order.

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use rayon::prelude::*;

mod palette;
pub(crate) mod scene;

pub use palette::{speed_index, Canvas};
pub use scene::{NativeRoad, RoadLine, Scene, NATIVE_ROAD_FILE};

use crate::plots::{axis, ensure_font, err};

/// Height of the clock's row \[px\].
pub const CLOCK_H: usize = 26;
/// Height of each panel's title row \[px\].
pub const TITLE_H: usize = 22;
/// Margin around the road inside a panel \[px\].
pub const MARGIN: usize = 14;
/// Width of the colour bar's column \[px\].
pub const BAR_W: usize = 112;

/// How an animation is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Frames per second of the animation.
    pub fps: f64,
    /// Simulated seconds per second of animation.
    pub speedup: f64,
    /// Width and height of each run's panel \[px\].
    pub size: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            fps: 10.0,
            speedup: 5.0,
            size: 360,
        }
    }
}

/// What was written.
#[derive(Debug, Clone, PartialEq)]
pub struct Written {
    /// The GIF.
    pub path: PathBuf,
    /// Frames in it.
    pub frames: usize,
    /// Its width and height \[px\].
    pub size: (usize, usize),
    /// Seconds of animation.
    pub duration_s: f64,
}

/// Where a panel's road lands in the picture: pixel = (x − x0)·scale + ox, (y1 − y)·scale + oy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame2d {
    x0: f64,
    y1: f64,
    scale: f64,
    ox: f64,
    oy: f64,
}

impl Frame2d {
    /// The road `road` fitted into the panel whose top left corner is at (`left`, `top`), `size`
    /// pixels square, [`MARGIN`] all round, centred, one scale for both axes.
    pub fn fit(road: &RoadLine, left: usize, top: usize, size: usize) -> Self {
        let (x0, y0, x1, y1) = road.bounds();
        let room = (size - 2 * MARGIN) as f64;
        let (dx, dy) = ((x1 - x0).max(1e-9), (y1 - y0).max(1e-9));
        let scale = (room / dx).min(room / dy);
        let ox = left as f64 + MARGIN as f64 + 0.5 * (room - dx * scale);
        let oy = top as f64 + MARGIN as f64 + 0.5 * (room - dy * scale);
        Self {
            x0,
            y1,
            scale,
            ox,
            oy,
        }
    }

    /// The pixel of a point of the network.
    pub fn px(&self, x: f64, y: f64) -> (f64, f64) {
        (
            (x - self.x0) * self.scale + self.ox,
            (self.y1 - y) * self.scale + self.oy,
        )
    }

    /// Pixels per metre.
    pub fn scale(&self) -> f64 {
        self.scale
    }
}

/// The radius of a vehicle's disc \[px\] at `scale` px/m: about a car's half length, at least
/// 2.5 px so that it shows, at most 10 px.
pub fn disc_radius(scale: f64) -> f64 {
    (2.2 * scale).clamp(2.5, 10.0)
}

/// A speed scale: where 96 % of the speeds lie, at least 0.2 m/s wide (the time-space
/// diagram's).
pub fn speed_scale(speeds: impl Iterator<Item = f64>) -> (f64, f64) {
    let r = axis::quantiles(speeds, 0.02, 0.98, 0.2, 0.0..1.0);
    (r.start, r.end)
}

/// The speed scale of the animation: every run's speeds together.
fn speed_range(scenes: &[Scene]) -> (f64, f64) {
    speed_scale(scenes.iter().flat_map(|s| s.speed_mps.iter().copied()))
}

/// A panel's title: scenario, who drove, backend.
fn title(s: &Scene) -> String {
    let backend = match s.record.backend {
        syncroad_control::scenario::Backend::Sumo => "SUMO",
        syncroad_control::scenario::Backend::Native => "native",
    };
    format!("{} — {} ({backend})", s.record.scenario, s.record.run)
}

/// The panel's title `full` within `room` pixels as `width` measures text: the whole title,
/// else who drove and the backend without the scenario, else that cut short with an ellipsis.
fn fit_title(full: &str, room: usize, width: impl Fn(&str) -> usize) -> String {
    if width(full) <= room {
        return full.to_string();
    }
    let short = full
        .split_once(" — ")
        .map_or(full.to_string(), |(_, rest)| rest.to_string());
    if width(&short) <= room {
        return short;
    }
    let mut chars: Vec<char> = short.chars().collect();
    while !chars.is_empty() {
        chars.pop();
        let cut: String = chars.iter().collect::<String>() + "…";
        if width(&cut) <= room {
            return cut;
        }
    }
    String::new()
}

/// The picture every frame starts from: titles, roads, colour bar.
fn background(
    scenes: &[Scene],
    frames: &[Frame2d],
    (w, h): (usize, usize),
    opts: &Options,
    (vmin, vmax): (f64, f64),
) -> anyhow::Result<Canvas> {
    ensure_font();
    let mut rgb = vec![255u8; w * h * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w as u32, h as u32)).into_drawing_area();
        for (k, (s, f)) in scenes.iter().zip(frames).enumerate() {
            let left = k * opts.size;
            let font = ("sans-serif", 14).into_font().color(&BLACK);
            // The title in its panel's width, so that side-by-side titles never collide.
            let width = |text: &str| {
                root.estimate_text_size(text, &font)
                    .map_or(usize::MAX, |(w, _)| w as usize)
            };
            let label = fit_title(&title(s), opts.size.saturating_sub(16), width);
            root.draw_text(&label, &font, ((left + 8) as i32, (CLOCK_H + 3) as i32))
                .map_err(err)?;
            let lane = (3.2 * f.scale()).clamp(3.0, 14.0) as u32;
            let mut pts: Vec<(i32, i32)> = s
                .road
                .points
                .iter()
                .map(|p| {
                    let (x, y) = f.px(p[1], p[2]);
                    (x.round() as i32, y.round() as i32)
                })
                .collect();
            if s.road.closed_m.is_some() {
                if let Some(first) = pts.first().copied() {
                    pts.push(first);
                }
            }
            root.draw(&PathElement::new(
                pts,
                RGBColor(205, 205, 205).stroke_width(lane),
            ))
            .map_err(err)?;
        }
        // The colour bar: speeds bottom (slow) to top (fast), labels at ends and middle.
        let bx = (w - BAR_W + 10) as i32;
        let (top, bottom) = ((CLOCK_H + TITLE_H + 10) as i32, (h - 24) as i32);
        let steps = (bottom - top).max(1);
        for k in 0..steps {
            let v = vmin + (vmax - vmin) * f64::from(steps - 1 - k) / f64::from(steps - 1).max(1.0);
            let c = crate::plots::speed_colour(v, vmin, vmax);
            root.draw(&Rectangle::new(
                [(bx, top + k), (bx + 16, top + k + 1)],
                c.filled(),
            ))
            .map_err(err)?;
        }
        let font = ("sans-serif", 12).into_font().color(&BLACK);
        for (frac, v) in [(0.0, vmax), (0.5, 0.5 * (vmin + vmax)), (1.0, vmin)] {
            let y = top + (frac * f64::from(steps - 1)) as i32 - 6;
            root.draw_text(&format!("{v:.2}"), &font, (bx + 20, y))
                .map_err(err)?;
        }
        root.draw_text(
            "speed [m/s]",
            &font,
            (bx - 6, (CLOCK_H + TITLE_H - 6) as i32),
        )
        .map_err(err)?;
        if scenes.iter().any(|s| !s.marked.is_empty()) {
            let y = bottom + 12;
            root.draw(&Circle::new((bx + 5, y), 5, BLACK.filled()))
                .map_err(err)?;
            root.draw_text("controlled", &font, (bx + 14, y - 6))
                .map_err(err)?;
        }
        root.present().map_err(err)?;
    }
    let mut q = palette::Quantizer::default();
    Ok(Canvas {
        w,
        h,
        px: q.indices(&rgb),
    })
}

/// The clock `t = 12.3 s` as an indexed patch.
fn clock(t: f64, q: &mut palette::Quantizer) -> anyhow::Result<Canvas> {
    let (w, h) = (190usize, CLOCK_H - 4);
    let mut rgb = vec![255u8; w * h * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w as u32, h as u32)).into_drawing_area();
        let font = ("sans-serif", 16).into_font().color(&BLACK);
        root.draw_text(&format!("t = {t:.1} s"), &font, (2, 3))
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    Ok(Canvas {
        w,
        h,
        px: q.indices(&rgb),
    })
}

/// Draws frame `t` on a copy of `base`.
fn frame(
    base: &Canvas,
    scenes: &[Scene],
    frames: &[Frame2d],
    t: f64,
    range: (f64, f64),
    q: &mut palette::Quantizer,
) -> anyhow::Result<Canvas> {
    let mut c = base.clone();
    c.blit(&clock(t, q)?, 8, 2);
    let (mut pos, mut speed) = (Vec::new(), Vec::new());
    for (s, f) in scenes.iter().zip(frames) {
        s.state_at(t, &mut pos, &mut speed);
        let r = disc_radius(f.scale());
        for i in 0..s.n {
            let (x, y) = s.road.at(pos[i]);
            let (px, py) = f.px(x, y);
            if s.marked.get(i).copied().unwrap_or(false) {
                c.disc(px, py, r + 2.0, palette::BLACK);
            }
            c.disc(px, py, r, speed_index(speed[i], range.0, range.1));
        }
    }
    Ok(c)
}

/// Frames per chunk drawn and compressed by one task.
const CHUNK: usize = 48;

/// Writes the animation of `scenes` (side by side) to `path`.
pub fn write(scenes: &[Scene], opts: &Options, path: &Path) -> anyhow::Result<Written> {
    anyhow::ensure!(!scenes.is_empty(), "no run to animate");
    let (w, h) = (
        scenes.len() * opts.size + BAR_W,
        CLOCK_H + TITLE_H + opts.size,
    );
    anyhow::ensure!(
        w <= usize::from(u16::MAX) && h <= usize::from(u16::MAX),
        "the animation would be {w} × {h} px, beyond GIF's 65535; draw fewer runs or smaller panels (--size)"
    );
    let frames: Vec<Frame2d> = scenes
        .iter()
        .enumerate()
        .map(|(k, s)| Frame2d::fit(&s.road, k * opts.size, CLOCK_H + TITLE_H, opts.size))
        .collect();
    let range = speed_range(scenes);
    let base = background(scenes, &frames, (w, h), opts, range)?;
    let end = scenes.iter().map(Scene::end_s).fold(0.0, f64::max);
    let dt = opts.speedup / opts.fps;
    let count = (end / dt + 1e-9).floor() as usize + 1;
    let delay = (100.0 / opts.fps).round().clamp(1.0, f64::from(u16::MAX)) as u16;
    let chunks: Vec<(usize, usize)> = (0..count)
        .step_by(CHUNK)
        .map(|a| (a, (a + CHUNK).min(count)))
        .collect();
    let encoded: Vec<Vec<gif::Frame<'static>>> = chunks
        .par_iter()
        .map(|&(a, b)| -> anyhow::Result<Vec<gif::Frame<'static>>> {
            let mut q = palette::Quantizer::default();
            let mut prev = if a == 0 {
                None
            } else {
                Some(frame(
                    &base,
                    scenes,
                    &frames,
                    (a - 1) as f64 * dt,
                    range,
                    &mut q,
                )?)
            };
            let mut out = Vec::with_capacity(b - a);
            for k in a..b {
                let c = frame(&base, scenes, &frames, k as f64 * dt, range, &mut q)?;
                let mut f = match &prev {
                    None => gif::Frame::from_indexed_pixels(w as u16, h as u16, c.px.clone(), None),
                    Some(p) => match c.delta(p) {
                        Some((x, y, fw, fh, px)) => {
                            let mut f = gif::Frame::from_indexed_pixels(
                                fw as u16,
                                fh as u16,
                                px,
                                Some(palette::UNCHANGED),
                            );
                            f.left = x as u16;
                            f.top = y as u16;
                            f
                        }
                        // Nothing moved: one unchanged pixel keeps the frame's time.
                        None => gif::Frame::from_indexed_pixels(
                            1,
                            1,
                            vec![palette::UNCHANGED],
                            Some(palette::UNCHANGED),
                        ),
                    },
                };
                f.delay = delay;
                f.dispose = gif::DisposalMethod::Keep;
                f.make_lzw_pre_encoded();
                out.push(f);
                prev = Some(c);
            }
            Ok(out)
        })
        .collect::<anyhow::Result<_>>()?;
    let pal = palette::rgb();
    crate::output::write_result(path, |file| -> anyhow::Result<()> {
        let mut enc = gif::Encoder::new(file, w as u16, h as u16, &pal)?;
        enc.set_repeat(gif::Repeat::Infinite)?;
        for f in encoded.iter().flatten() {
            enc.write_lzw_pre_encoded_frame(f)?;
        }
        enc.into_inner()?;
        Ok(())
    })?;
    Ok(Written {
        path: path.to_path_buf(),
        frames: count,
        size: (w, h),
        duration_s: count as f64 * f64::from(delay) / 100.0,
    })
}

#[cfg(test)]
mod title_tests {
    use super::fit_title;

    #[test]
    fn a_title_fits_its_panel_by_leaving_out_the_scenario_then_cutting_short() {
        let width = |t: &str| 7 * t.chars().count();
        let full = "sugiyama-human-noisy — human-noisy (SUMO)";
        assert_eq!(fit_title(full, 400, width), full);
        assert_eq!(fit_title(full, 140, width), "human-noisy (SUMO)");
        let cut = fit_title(full, 70, width);
        assert!(cut.ends_with('…') && width(&cut) <= 70, "{cut}");
        assert_eq!(fit_title(full, 0, width), "");
    }
}
