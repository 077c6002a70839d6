//! Mean and 95 % confidence interval over seeds (Student's t, quantiles from `statrs`).

use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// The two-sided 95 % quantile t_{0.975, ν} of Student's t with ν degrees of freedom (NaN for
/// ν = 0); beyond 10⁷ degrees of freedom the normal quantile, which it equals there to 1e-7.
pub fn t975(dof: usize) -> f64 {
    if dof == 0 {
        return f64::NAN;
    }
    if dof > 10_000_000 {
        return Normal::standard().inverse_cdf(0.975);
    }
    StudentsT::new(0.0, 1.0, dof as f64).map_or(f64::NAN, |t| t.inverse_cdf(0.975))
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
        assert!((m.half_width.unwrap() - t975(9) * s / 10f64.sqrt()).abs() < 1e-12);
        assert!((m.half_width.unwrap() - 2.1658).abs() < 1e-3);
        // Quantiles against the NIST/SEMATECH table (1.3.6.7.2, three decimals) and exact
        // closed forms: ν = 1 is tan(0.475 π); ν = 2 is (2p − 1)/sqrt(2p(1 − p)) = 4.302653.
        assert!((t975(1) - (0.475 * std::f64::consts::PI).tan()).abs() < 1e-6);
        assert!((t975(2) - 4.302_652_7).abs() < 1e-6);
        for (dof, table) in [
            (9, 2.262),
            (10, 2.228),
            (20, 2.086),
            (30, 2.042),
            (100, 1.984),
        ] {
            assert!((t975(dof) - table).abs() < 5e-4, "t({dof}) = {}", t975(dof));
        }
        assert_eq!(mean_ci(&[3.0]).unwrap().half_width, None);
        assert_eq!(mean_ci(&[f64::NAN]), None);
        // The large-sample limit is the normal quantile.
        assert!((t975(usize::MAX) - 1.959964).abs() < 1e-5);
        assert!(t975(35) >= 2.030, "t_{{.975,35}} = 2.030: never narrower");
    }
}
