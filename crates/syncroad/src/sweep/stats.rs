//! Mean and 95 % confidence interval over seeds (Student's t).

/// Two-sided 95 % quantile t_{0.975, ν} of Student's t for ν = 1..=30 degrees of freedom
/// (standard tables, e.g. NIST/SEMATECH e-Handbook 1.3.6.7.2). Between tabulated rows the
/// value of the row below is used (30, 40, 60, 120), which widens the interval slightly and
/// never narrows it; the normal quantile 1.95996 only in the limit.
const T975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];

/// t_{0.975, ν}.
pub fn t975(dof: usize) -> f64 {
    match dof {
        0 => f64::NAN,
        1..=30 => T975[dof - 1],
        31..=40 => 2.042,
        41..=60 => 2.021,
        61..=120 => 2.000,
        121..=1_000_000 => 1.980,
        _ => 1.95996,
    }
}

/// Mean of the finite values and the half-width of its 95 % interval (`None` with fewer than
/// two values), with the count used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanCi {
    /// Sample mean.
    pub mean: f64,
    /// Half-width of the 95 % confidence interval of the mean.
    pub half_width: Option<f64>,
    /// Values used.
    pub count: usize,
}

/// [`MeanCi`] of the finite values of `xs` (`None` when there are none).
pub fn mean_ci(xs: &[f64]) -> Option<MeanCi> {
    let v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    let n = v.len();
    if n == 0 {
        return None;
    }
    let mean = v.iter().sum::<f64>() / n as f64;
    let half_width = (n >= 2).then(|| {
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        t975(n - 1) * (var / n as f64).sqrt()
    });
    Some(MeanCi {
        mean,
        half_width,
        count: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_of_a_textbook_sample() {
        // 10 values 1..=10: mean 5.5, s = 3.02765, t_{.975,9} = 2.262 → ±2.1657.
        let xs: Vec<f64> = (1..=10).map(f64::from).collect();
        let m = mean_ci(&xs).unwrap();
        assert_eq!(m.mean, 5.5);
        let s = (82.5f64 / 9.0).sqrt();
        assert!((m.half_width.unwrap() - 2.262 * s / 10f64.sqrt()).abs() < 1e-12);
        assert!((m.half_width.unwrap() - 2.1658).abs() < 1e-3);
        assert_eq!(mean_ci(&[3.0]).unwrap().half_width, None);
        assert_eq!(mean_ci(&[f64::NAN]), None);
        // The large-sample limit is the normal quantile.
        assert!((t975(usize::MAX) - 1.959964).abs() < 1e-5);
        assert!(t975(35) >= 2.030, "t_{{.975,35}} = 2.030: never narrower");
    }
}
