//! Real polynomials with coefficients in ascending order: `p(λ) = Σ_k c_k λ^k`.

use nalgebra::DMatrix;
use num_complex::Complex64;

/// A real polynomial, coefficients ascending (`coeffs[k]` multiplies `λ^k`).
#[derive(Debug, Clone, PartialEq)]
pub struct Poly {
    /// Coefficients, ascending; trailing zeros are trimmed.
    pub coeffs: Vec<f64>,
}

impl Poly {
    /// A polynomial from ascending coefficients (trailing zeros trimmed).
    pub fn new(coeffs: &[f64]) -> Self {
        let mut c = coeffs.to_vec();
        while c.len() > 1 && c.last() == Some(&0.0) {
            c.pop();
        }
        if c.is_empty() {
            c.push(0.0);
        }
        Self { coeffs: c }
    }

    /// Degree (0 for constants, including the zero polynomial).
    pub fn degree(&self) -> usize {
        self.coeffs.len() - 1
    }

    /// Value at a real point (Horner).
    pub fn eval(&self, x: f64) -> f64 {
        self.coeffs.iter().rev().fold(0.0, |acc, c| acc * x + c)
    }

    /// Value at a complex point (Horner).
    pub fn eval_c(&self, z: Complex64) -> Complex64 {
        self.coeffs
            .iter()
            .rev()
            .fold(Complex64::new(0.0, 0.0), |acc, &c| acc * z + c)
    }

    /// Derivative.
    pub fn derivative(&self) -> Self {
        if self.coeffs.len() <= 1 {
            return Self::new(&[0.0]);
        }
        Self::new(
            &self.coeffs[1..]
                .iter()
                .enumerate()
                .map(|(k, c)| (k + 1) as f64 * c)
                .collect::<Vec<_>>(),
        )
    }

    /// Product.
    pub fn mul(&self, o: &Self) -> Self {
        let mut c = vec![0.0; self.coeffs.len() + o.coeffs.len() - 1];
        for (i, a) in self.coeffs.iter().enumerate() {
            for (j, b) in o.coeffs.iter().enumerate() {
                c[i + j] += a * b;
            }
        }
        Self::new(&c)
    }

    fn zip_with(&self, o: &Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let n = self.coeffs.len().max(o.coeffs.len());
        let c: Vec<f64> = (0..n)
            .map(|k| {
                f(
                    self.coeffs.get(k).copied().unwrap_or(0.0),
                    o.coeffs.get(k).copied().unwrap_or(0.0),
                )
            })
            .collect();
        Self::new(&c)
    }

    /// Sum.
    pub fn add(&self, o: &Self) -> Self {
        self.zip_with(o, |a, b| a + b)
    }

    /// Difference.
    pub fn sub(&self, o: &Self) -> Self {
        self.zip_with(o, |a, b| a - b)
    }

    /// All complex roots, as eigenvalues of the companion matrix.
    pub fn roots(&self) -> Vec<Complex64> {
        let d = self.degree();
        if d == 0 {
            return Vec::new();
        }
        let lead = self.coeffs[d];
        let mut m = DMatrix::<f64>::zeros(d, d);
        for k in 0..d {
            m[(0, k)] = -self.coeffs[d - 1 - k] / lead;
        }
        for k in 1..d {
            m[(k, k - 1)] = 1.0;
        }
        m.complex_eigenvalues().iter().copied().collect()
    }

    /// Hurwitz test by the Routh array: all roots in the open left half-plane.
    pub fn is_hurwitz(&self) -> bool {
        let d = self.degree();
        let lead = self.coeffs[d];
        if lead == 0.0 {
            return false;
        }
        // Normalise to a positive leading coefficient; descending order for the Routh array.
        let desc: Vec<f64> = self
            .coeffs
            .iter()
            .rev()
            .map(|c| c * lead.signum())
            .collect();
        if desc.iter().any(|&c| c <= 0.0) {
            return false; // necessary condition: all coefficients positive
        }
        let r0: Vec<f64> = desc.iter().step_by(2).copied().collect();
        let r1: Vec<f64> = desc.iter().skip(1).step_by(2).copied().collect();
        let mut rows = vec![r0, r1];
        while rows.len() < d + 1 {
            let (a, b) = (&rows[rows.len() - 2], &rows[rows.len() - 1]);
            if b.first().is_none_or(|&x| x <= 0.0) {
                return false;
            }
            let next: Vec<f64> = (0..a.len().saturating_sub(1))
                .map(|k| a[k + 1] - a[0] * b.get(k + 1).copied().unwrap_or(0.0) / b[0])
                .collect();
            rows.push(next);
        }
        rows.iter()
            .take(d + 1)
            .all(|r| r.first().is_some_and(|&x| x > 0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn roots_of_known_cubic() {
        // (λ+1)(λ+2)(λ−3) = λ³ − 7λ − 6
        let p = Poly::new(&[-6.0, -7.0, 0.0, 1.0]);
        let mut r: Vec<f64> = p.roots().iter().map(|z| z.re).collect();
        r.sort_by(f64::total_cmp);
        assert_relative_eq!(r[0], -2.0, epsilon = 1e-12);
        assert_relative_eq!(r[1], -1.0, epsilon = 1e-12);
        assert_relative_eq!(r[2], 3.0, epsilon = 1e-12);
        assert!(!p.is_hurwitz());
    }

    #[test]
    fn routh_matches_cubic_closed_form() {
        // s³ + p s² + q s + k is Hurwitz iff p, q, k > 0 and k < p q (Remark rem.weak).
        let (p, q) = (2.0, 3.0);
        for k in [0.5, 5.9, 6.1, 10.0] {
            let poly = Poly::new(&[k, q, p, 1.0]);
            assert_eq!(poly.is_hurwitz(), k < p * q, "k = {k}");
            let max_re = poly
                .roots()
                .iter()
                .map(|z| z.re)
                .fold(f64::NEG_INFINITY, f64::max);
            assert_eq!(max_re < 0.0, k < p * q);
        }
        assert!(Poly::new(&[2.0, 3.0, 1.0]).is_hurwitz());
        assert!(!Poly::new(&[2.0, -3.0, 1.0]).is_hurwitz());
        assert!(!Poly::new(&[0.0, 3.0, 1.0]).is_hurwitz());
    }
}
