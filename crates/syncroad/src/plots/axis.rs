//! Axis ranges that plotters can draw whatever the data: all zeros, one sample, NaN and
//! infinite values. A log axis over an empty or inverted range makes plotters loop and
//! allocate without bound, so every axis of every plot is built from these.

use std::ops::Range;

/// Smallest decade a log axis shows.
const LOG_FLOOR: f64 = 1e-12;

/// A linear range holding every finite value of `values`, widened to `min_span` around a
/// single value; `fallback` when no value is finite.
pub fn linear(
    values: impl IntoIterator<Item = f64>,
    min_span: f64,
    fallback: Range<f64>,
) -> Range<f64> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return fallback;
    }
    let span = min_span.max(f64::EPSILON * lo.abs().max(hi.abs()) * 16.0);
    if hi - lo >= span {
        lo..hi
    } else {
        let mid = 0.5 * (lo + hi);
        (mid - 0.5 * span)..(mid + 0.5 * span)
    }
}

/// A linear range from the data alone: every finite value, a single value (or all equal)
/// widened by 5 % of its size (1 when it is 0), never to a fixed span that would dwarf small
/// data (penetrations 0–0.05 on a −0.5…0.55 axis).
pub fn of_data(values: impl IntoIterator<Item = f64> + Clone, fallback: Range<f64>) -> Range<f64> {
    let (lo, hi) = values
        .clone()
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let size = lo.abs().max(hi.abs());
    let floor = if hi > lo || !size.is_finite() {
        0.0
    } else if size > 0.0 {
        0.1 * size
    } else {
        1.0
    };
    linear(values, floor, fallback)
}

/// The `lo`-th and `hi`-th quantiles (fractions) of the finite values, widened to `min_span`
/// around their middle: a colour scale from where the data lie, which a short transient at
/// the start does not stretch.
pub fn quantiles(
    values: impl IntoIterator<Item = f64>,
    lo: f64,
    hi: f64,
    min_span: f64,
    fallback: Range<f64>,
) -> Range<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return fallback;
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    linear([at(lo), at(hi)], min_span, fallback)
}

/// `r` with 5 % of its span added on either side.
pub fn padded(r: Range<f64>) -> Range<f64> {
    let pad = 0.05 * (r.end - r.start);
    (r.start - pad)..(r.end + pad)
}

/// A log range holding every finite positive value of `values` with half a decade of room on
/// either side and at least one decade in all; `None` when no value is finite and positive
/// (then there is nothing to draw on a log axis).
pub fn log(values: impl IntoIterator<Item = f64>) -> Option<Range<f64>> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return None;
    }
    let lo = lo.max(LOG_FLOOR);
    let hi = hi.max(lo * 10.0);
    Some(lo * 0.5..hi * 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_data_gives_a_drawable_range() {
        let r = linear([0.0, 0.0, 0.0], 1.0, 0.0..1.0);
        assert_eq!(r, -0.5..0.5);
        assert_eq!(linear([f64::NAN, f64::INFINITY], 1.0, 0.0..1.0), 0.0..1.0);
        assert_eq!(linear([], 1.0, 2.0..3.0), 2.0..3.0);
        assert_eq!(linear([1.0, 4.0, f64::NAN], 1.0, 0.0..1.0), 1.0..4.0);
        // A value so large that min_span vanishes in round-off still gets a non-empty range.
        let big = linear([1e300], 1e-9, 0.0..1.0);
        assert!(big.end > big.start);
        assert_eq!(log([0.0, 0.0]), None);
        assert_eq!(log([f64::NAN, f64::INFINITY, -1.0]), None);
        let one = log([1e-3]).unwrap();
        assert!(one.start < 1e-3 && one.end > 1e-2, "{one:?}");
        let tiny = log([1e-300]).unwrap();
        assert_eq!(tiny.start, 0.5e-12);
        // From the data: penetrations 0–0.05 stay 0–0.05; one value gets ±5 % of itself.
        assert_eq!(of_data([0.0, 0.05], 0.0..1.0), 0.0..0.05);
        let one = of_data([2.0, 2.0], 0.0..1.0);
        assert!(
            (one.start - 1.9).abs() < 1e-12 && (one.end - 2.1).abs() < 1e-12,
            "{one:?}"
        );
        assert_eq!(of_data([0.0], 0.0..1.0), -0.5..0.5);
        // The quantiles of 2..4 m/s with a short 8 m/s start: the start does not stretch them.
        let mut speeds: Vec<f64> = (0..1000).map(|k| 2.0 + 2.0 * k as f64 / 999.0).collect();
        speeds.extend([8.0; 10]);
        let r = quantiles(speeds, 0.02, 0.98, 0.2, 0.0..1.0);
        assert!(
            r.start > 2.0 && r.start < 2.1 && r.end > 3.9 && r.end < 4.0,
            "{r:?}"
        );
    }
}
