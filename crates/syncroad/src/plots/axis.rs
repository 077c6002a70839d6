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
    }
}
