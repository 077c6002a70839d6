//! Dual numbers `a + a'ε` (`ε² = 0`) over the complex numbers: an LU in this ring carries the
//! derivative of its matrix in `s` along, so `d/ds log det M(s)` comes out of the pivots and a
//! solve gives `x` with `dx/ds` ([`super::banded`], [`super::sparse_lu`]).

use multiversion::{multiversion, target::target_cfg_f};
use num_complex::Complex64;

/// A complex number with its derivative in `s`: `v + d·ε`, `ε² = 0`. Laid out as four `f64`
/// (`v.re, v.im, d.re, d.im`), one 256-bit register of [`sub_mul_each`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C)]
pub(crate) struct Dual {
    /// Value.
    pub(crate) v: Complex64,
    /// Derivative.
    pub(crate) d: Complex64,
}

impl Dual {
    /// The constant 1.
    pub(crate) const ONE: Dual = Dual {
        v: Complex64::new(1.0, 0.0),
        d: Complex64::new(0.0, 0.0),
    };

    /// `c·(v + d·ε)` for a real `c`.
    #[inline]
    pub(crate) fn scale(self, c: f64) -> Dual {
        Dual {
            v: self.v * c,
            d: self.d * c,
        }
    }

    #[inline]
    pub(crate) fn mul(self, o: Dual) -> Dual {
        Dual {
            v: self.v * o.v,
            d: self.v * o.d + self.d * o.v,
        }
    }
    /// `self − a·b`, the update of an elimination as the complex products read (the
    /// reference of [`sub_mul_each`]).
    #[cfg(test)]
    pub(crate) fn sub_mul(self, a: Dual, b: Dual) -> Dual {
        let (av, ad, bv, bd) = (a.v, a.d, b.v, b.d);
        Dual {
            v: Complex64::new(
                self.v.re - (av.re * bv.re - av.im * bv.im),
                self.v.im - (av.re * bv.im + av.im * bv.re),
            ),
            d: Complex64::new(
                self.d.re - (av.re * bd.re - av.im * bd.im + ad.re * bv.re - ad.im * bv.im),
                self.d.im - (av.re * bd.im + av.im * bd.re + ad.re * bv.im + ad.im * bv.re),
            ),
        }
    }
    #[inline]
    pub(crate) fn div(self, o: Dual) -> Dual {
        let v = self.v / o.v;
        Dual {
            v,
            d: (self.d - v * o.d) / o.v,
        }
    }
    #[inline]
    pub(crate) fn sub(self, o: Dual) -> Dual {
        Dual {
            v: self.v - o.v,
            d: self.d - o.d,
        }
    }
}

/// `x[i] −= a·b` for every pair `(i, a)` of `rows` and `a`: the inner loop of an elimination
/// (one column of `L` times one entry of the solution), where a factorization of a wide graph
/// spends nearly all of its time.
///
/// Each update is written lane by lane over the four numbers of a dual, `x − (a.v.re·c₁ +
/// a.v.im·c₂ + a.d.re·c₃ + a.d.im·c₄)` with `c₁ … c₄` made from `b` once, so that the compiler
/// makes one 256-bit operation of each lane-wise step. Compiled also for AVX2 with fused
/// multiply–adds and chosen at run time where the processor has them (the default x86-64
/// target has only 128-bit registers): there the sum is accumulated by three fused
/// multiply–adds, one rounding each instead of two, a sixth faster on a random digraph of 400.
/// Elsewhere the products are summed as [`Dual::sub_mul`] sums them, to the last bit. The two
/// differ in the last bits, as glibc's `exp` and `sin`, which also choose fused versions at run
/// time, already do between such processors; on one machine every run gives the same bits.
#[multiversion(targets("x86_64+avx2+avx+fma"))]
pub(crate) fn sub_mul_each(x: &mut [Dual], rows: &[usize], a: &[Dual], b: Dual) {
    let (bv, bd) = (b.v, b.d);
    let c1 = [bv.re, bv.im, bd.re, bd.im];
    let c2 = [-bv.im, bv.re, -bd.im, bd.re];
    let c3 = [0.0, 0.0, bv.re, bv.im];
    let c4 = [0.0, 0.0, -bv.im, bv.re];
    for (&i, a) in rows.iter().zip(a) {
        let xi = &mut x[i];
        let t = [xi.v.re, xi.v.im, xi.d.re, xi.d.im];
        let (ar, ai, adr, adi) = (a.v.re, a.v.im, a.d.re, a.d.im);
        let r: [f64; 4] = std::array::from_fn(|k| {
            if target_cfg_f!(target_feature = "fma") {
                t[k] - adi.mul_add(c4[k], adr.mul_add(c3[k], ai.mul_add(c2[k], ar * c1[k])))
            } else {
                t[k] - (ar * c1[k] + ai * c2[k] + adr * c3[k] + adi * c4[k])
            }
        });
        *xi = Dual {
            v: Complex64::new(r[0], r[1]),
            d: Complex64::new(r[2], r[3]),
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lane_wise_update_equals_its_scalar_form_to_the_last_bit() {
        // Oracle: `Dual::sub_mul`, the products as complex arithmetic reads them, and where the
        // processor runs the fused version, the same sums by scalar fused multiply–adds in
        // the same order. Random magnitudes over many decades, so that a different grouping
        // of the sums would round differently and show.
        let fused = fused_version_runs();
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            (unit - 0.5) * 10f64.powi((state % 13) as i32 - 6)
        };
        let mut dual = || Dual {
            v: Complex64::new(next(), next()),
            d: Complex64::new(next(), next()),
        };
        let n = 64;
        let x0: Vec<Dual> = (0..n).map(|_| dual()).collect();
        let rows: Vec<usize> = (0..n).rev().step_by(3).collect();
        let a: Vec<Dual> = rows.iter().map(|_| dual()).collect();
        for _ in 0..20 {
            let b = dual();
            let mut expected = x0.clone();
            for (&i, &ai) in rows.iter().zip(&a) {
                expected[i] = if fused {
                    fused_sub_mul(expected[i], ai, b)
                } else {
                    expected[i].sub_mul(ai, b)
                };
            }
            let mut x = x0.clone();
            sub_mul_each(&mut x, &rows, &a, b);
            for (got, want) in x.iter().zip(&expected) {
                for (g, w) in [
                    (got.v.re, want.v.re),
                    (got.v.im, want.v.im),
                    (got.d.re, want.d.re),
                    (got.d.im, want.d.im),
                ] {
                    assert_eq!(g.to_bits(), w.to_bits(), "{got:?} against {want:?}");
                }
            }
            // Either way within a few roundings of the complex products.
            let size = |d: &Dual| d.v.re.abs() + d.v.im.abs() + d.d.re.abs() + d.d.im.abs();
            for (&i, ai) in rows.iter().zip(&a) {
                let plain = x0[i].sub_mul(*ai, b);
                let bound = 8.0 * f64::EPSILON * (size(&x0[i]) + size(ai) * size(&b));
                for (g, w) in [
                    (x[i].v.re, plain.v.re),
                    (x[i].v.im, plain.v.im),
                    (x[i].d.re, plain.d.re),
                    (x[i].d.im, plain.d.im),
                ] {
                    assert!((g - w).abs() <= bound, "{g} against {w}");
                }
            }
        }
    }

    /// Whether [`sub_mul_each`] runs its fused version here (AVX2 with FMA).
    fn fused_version_runs() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("avx")
                && std::arch::is_x86_feature_detected!("fma")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// `x − a·b` lane by lane with the products accumulated by fused multiply–adds in the
    /// order of [`sub_mul_each`]'s fused version, written out for each lane.
    fn fused_sub_mul(x: Dual, a: Dual, b: Dual) -> Dual {
        let (ar, ai, adr, adi) = (a.v.re, a.v.im, a.d.re, a.d.im);
        let (br, bi, bdr, bdi) = (b.v.re, b.v.im, b.d.re, b.d.im);
        Dual {
            v: Complex64::new(
                x.v.re - ai.mul_add(-bi, ar * br),
                x.v.im - ai.mul_add(br, ar * bi),
            ),
            d: Complex64::new(
                x.d.re - adi.mul_add(-bi, adr.mul_add(br, ai.mul_add(-bdi, ar * bdr))),
                x.d.im - adi.mul_add(br, adr.mul_add(bi, ai.mul_add(bdr, ar * bdi))),
            ),
        }
    }
}
