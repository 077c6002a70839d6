//! The animation's 256 colours and the indexed canvas its frames are drawn on: white, 32 greys
//! (text and the road, anti-aliased), a colour no drawing uses (GIF transparency: "unchanged
//! since the last frame") and the viridis map in 200 steps for speeds, the same map as the
//! run's time-space diagram.

use std::collections::HashMap;

use plotters::style::colors::colormaps::ViridisRGB;

/// Palette index of white.
pub const WHITE: u8 = 0;
/// Palette index of black (the darkest grey).
pub const BLACK: u8 = 1;
/// Palette index meaning "as in the previous frame".
pub const UNCHANGED: u8 = 33;
const GREYS: usize = 32;
const SPEED0: usize = 34;
/// Speed colours in the palette.
pub const SPEEDS: usize = 256 - SPEED0;

/// The palette as GIF wants it (RGB triples).
pub fn rgb() -> Vec<u8> {
    let mut p = Vec::with_capacity(768);
    p.extend([255, 255, 255]);
    for g in 0..GREYS {
        let v = (g * 255 / (GREYS - 1)) as u8;
        p.extend([v, v, v]);
    }
    p.extend([255, 0, 255]);
    for k in 0..SPEEDS {
        let c = ViridisRGB::get_color(k as f64 / (SPEEDS - 1) as f64);
        p.extend([c.0, c.1, c.2]);
    }
    p
}

/// Palette index of a speed on the scale `vmin..vmax` (its ends beyond it).
pub fn speed_index(v: f64, vmin: f64, vmax: f64) -> u8 {
    let x = if vmax > vmin && v.is_finite() {
        ((v - vmin) / (vmax - vmin)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    (SPEED0 + (x * (SPEEDS - 1) as f64).round() as usize) as u8
}

/// Maps drawn RGB pixels to the nearest palette colour (remembering each colour it met).
pub struct Quantizer {
    palette: Vec<[u8; 3]>,
    seen: HashMap<[u8; 3], u8>,
}

impl Default for Quantizer {
    fn default() -> Self {
        let p = rgb();
        Self {
            palette: p.chunks(3).map(|c| [c[0], c[1], c[2]]).collect(),
            seen: HashMap::new(),
        }
    }
}

impl Quantizer {
    /// The palette index nearest to `c` (never [`UNCHANGED`]).
    pub fn index(&mut self, c: [u8; 3]) -> u8 {
        if let Some(&i) = self.seen.get(&c) {
            return i;
        }
        let d = |p: &[u8; 3]| {
            (0..3)
                .map(|k| (i32::from(p[k]) - i32::from(c[k])).pow(2))
                .sum::<i32>()
        };
        let i = self
            .palette
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != usize::from(UNCHANGED))
            .min_by_key(|(_, p)| d(p))
            .map_or(WHITE, |(i, _)| i as u8);
        self.seen.insert(c, i);
        i
    }

    /// Every pixel of an RGB buffer, as indices.
    pub fn indices(&mut self, rgb: &[u8]) -> Vec<u8> {
        rgb.chunks(3)
            .map(|p| self.index([p[0], p[1], p[2]]))
            .collect()
    }
}

/// An indexed picture.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    /// Width \[px\].
    pub w: usize,
    /// Height \[px\].
    pub h: usize,
    /// Palette indices, row by row.
    pub px: Vec<u8>,
}

impl Canvas {
    /// A white canvas.
    #[cfg(test)]
    pub fn new(w: usize, h: usize) -> Self {
        Self {
            w,
            h,
            px: vec![WHITE; w * h],
        }
    }

    /// A filled disc of radius `r` px centred at (`cx`, `cy`), clipped to the canvas.
    pub fn disc(&mut self, cx: f64, cy: f64, r: f64, colour: u8) {
        let (x0, x1) = ((cx - r).floor().max(0.0), (cx + r).ceil());
        let (y0, y1) = ((cy - r).floor().max(0.0), (cy + r).ceil());
        let (x1, y1) = (x1.min(self.w as f64 - 1.0), y1.min(self.h as f64 - 1.0));
        if !(x0 <= x1 && y0 <= y1) {
            return;
        }
        for y in y0 as usize..=y1 as usize {
            for x in x0 as usize..=x1 as usize {
                let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                if dx * dx + dy * dy <= r * r {
                    self.px[y * self.w + x] = colour;
                }
            }
        }
    }

    /// Copies `src` with its top left corner at (`left`, `top`), clipped.
    pub fn blit(&mut self, src: &Canvas, left: usize, top: usize) {
        for y in 0..src.h.min(self.h.saturating_sub(top)) {
            let n = src.w.min(self.w.saturating_sub(left));
            let d = (top + y) * self.w + left;
            self.px[d..d + n].copy_from_slice(&src.px[y * src.w..y * src.w + n]);
        }
    }

    /// The part of `self` that differs from `prev` (same size): its bounding box (left, top,
    /// width, height) and the pixels in it, [`UNCHANGED`] where they did not change; `None`
    /// when nothing changed.
    pub fn delta(&self, prev: &Canvas) -> Option<(usize, usize, usize, usize, Vec<u8>)> {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..self.h {
            let row = &self.px[y * self.w..(y + 1) * self.w];
            let old = &prev.px[y * self.w..(y + 1) * self.w];
            if row == old {
                continue;
            }
            let first = row.iter().zip(old).position(|(a, b)| a != b).unwrap_or(0);
            let last = self.w
                - 1
                - row
                    .iter()
                    .rev()
                    .zip(old.iter().rev())
                    .position(|(a, b)| a != b)
                    .unwrap_or(0);
            x0 = x0.min(first);
            x1 = x1.max(last);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if x0 == usize::MAX {
            return None;
        }
        let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut px = Vec::with_capacity(w * h);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (a, b) = (self.px[y * self.w + x], prev.px[y * self.w + x]);
                px.push(if a == b { UNCHANGED } else { a });
            }
        }
        Some((x0, y0, w, h, px))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_palette_holds_the_plots_colour_map_and_keeps_one_colour_for_transparency() {
        let p = rgb();
        assert_eq!(p.len(), 768);
        // The speed scale's ends are the time-space diagram's.
        let lo = usize::from(speed_index(0.0, 0.0, 10.0)) * 3;
        let hi = usize::from(speed_index(10.0, 0.0, 10.0)) * 3;
        assert_eq!(&p[lo..lo + 3], &[68, 1, 84]);
        assert_eq!(&p[hi..hi + 3], &[254, 232, 37]);
        let mut q = Quantizer::default();
        assert_eq!(q.index([255, 255, 255]), WHITE);
        assert_eq!(q.index([0, 0, 0]), BLACK);
        // Magenta is drawn by nothing; a magenta pixel still never becomes "unchanged".
        assert_ne!(q.index([255, 0, 255]), UNCHANGED);
    }

    #[test]
    fn a_delta_holds_only_the_changed_box() {
        let a = Canvas::new(20, 10);
        let mut b = a.clone();
        b.px[3 * 20 + 4] = 40;
        b.px[5 * 20 + 7] = 41;
        let (x, y, w, h, px) = b.delta(&a).unwrap();
        assert_eq!((x, y, w, h), (4, 3, 4, 3));
        assert_eq!(px.iter().filter(|p| **p != UNCHANGED).count(), 2);
        assert!(a.delta(&a).is_none());
        let mut c = Canvas::new(20, 10);
        c.disc(10.0, 5.0, 3.0, 50);
        // A disc of radius 3 covers about π·9 pixels.
        let n = c.px.iter().filter(|p| **p == 50).count();
        assert!((24..=32).contains(&n), "{n}");
    }
}
