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
/// Each update is written lane by lane over the four numbers of a dual, `x − a.v.re·c₁ −
/// a.v.im·c₂ − a.d.re·c₃ − a.d.im·c₄` subtracted in this order, with `c₁ … c₄` made from `b`
/// once, so that the compiler makes one 256-bit operation of each lane-wise step (the value's
/// lanes have `c₃ = c₄ = 0`). Compiled also for AVX2 with fused multiply–adds and chosen at
/// run time where the processor has them (the default x86-64 target has only 128-bit
/// registers): there each subtraction is one fused multiply–add, one rounding instead of two.
/// Elsewhere each product is rounded before it is subtracted. The two differ in the last bits,
/// as glibc's `exp` and `sin`, which also choose fused versions at run time, already do
/// between such processors; on one machine every run gives the same bits. [`sub_mul_blocks`]
/// makes the same subtractions on the dense part of a factorization, so both give the same
/// numbers.
#[multiversion(targets("x86_64+avx2+avx+fma"))]
pub(crate) fn sub_mul_each(x: &mut [Dual], rows: &[usize], a: &[Dual], b: Dual) {
    let (bv, bd) = (b.v, b.d);
    let c1 = [bv.re, bv.im, bd.re, bd.im];
    let c2 = [-bv.im, bv.re, -bd.im, bd.re];
    let c3 = [0.0, 0.0, bv.re, bv.im];
    let c4 = [0.0, 0.0, -bv.im, bv.re];
    // `x − a·c`, fused where the processor has it.
    let sub = |x: f64, a: f64, c: f64| {
        if target_cfg_f!(target_feature = "fma") {
            (-a).mul_add(c, x)
        } else {
            x - a * c
        }
    };
    for (&i, a) in rows.iter().zip(a) {
        let xi = &mut x[i];
        let t = [xi.v.re, xi.v.im, xi.d.re, xi.d.im];
        let (ar, ai, adr, adi) = (a.v.re, a.v.im, a.d.re, a.d.im);
        let r: [f64; 4] = std::array::from_fn(|k| {
            sub(
                sub(sub(sub(t[k], ar, c1[k]), ai, c2[k]), adr, c3[k]),
                adi,
                c4[k],
            )
        });
        *xi = Dual {
            v: Complex64::new(r[0], r[1]),
            d: Complex64::new(r[2], r[3]),
        };
    }
}

/// Four consecutive duals as sixteen `f64`: the four values' real parts, their imaginary parts,
/// the derivatives' real parts, their imaginary parts. The dense part of a factorization is
/// stored in such blocks, and [`sub_mul_blocks`] updates four duals with each 256-bit operation
/// instead of one.
pub(crate) type DualBlock = [f64; 16];

/// The dual at `t` of duals stored in [`DualBlock`]s.
#[inline]
pub(crate) fn block_get(blocks: &[DualBlock], t: usize) -> Dual {
    let (b, l) = (&blocks[t / 4], t % 4);
    Dual {
        v: Complex64::new(b[l], b[4 + l]),
        d: Complex64::new(b[8 + l], b[12 + l]),
    }
}

/// Writes `x` at `t` of duals stored in [`DualBlock`]s.
#[inline]
pub(crate) fn block_set(blocks: &mut [DualBlock], t: usize, x: Dual) {
    let (b, l) = (&mut blocks[t / 4], t % 4);
    (b[l], b[4 + l], b[8 + l], b[12 + l]) = (x.v.re, x.v.im, x.d.re, x.d.im);
}

/// `x[k] −= a[k]·b` for every dual of the blocks `x` and `a` (as many as the shorter holds):
/// [`sub_mul_each`] on consecutive duals kept in [`DualBlock`]s, the dense part of a
/// factorization, with the same subtractions in the same order for each number (those by the
/// value's zero `c₃, c₄` left out), so the two give the same bits; the compiler makes one
/// 256-bit operation of the same number of four duals.
#[multiversion(targets("x86_64+avx2+avx+fma"))]
pub(crate) fn sub_mul_blocks(x: &mut [DualBlock], a: &[DualBlock], b: Dual) {
    let sub = |x: f64, a: f64, c: f64| {
        if target_cfg_f!(target_feature = "fma") {
            (-a).mul_add(c, x)
        } else {
            x - a * c
        }
    };
    let (br, bi, bdr, bdi) = (b.v.re, b.v.im, b.d.re, b.d.im);
    for (x, a) in x.iter_mut().zip(a) {
        for l in 0..4 {
            let (ar, ai, adr, adi) = (a[l], a[4 + l], a[8 + l], a[12 + l]);
            x[l] = sub(sub(x[l], ar, br), ai, -bi);
            x[4 + l] = sub(sub(x[4 + l], ar, bi), ai, br);
            x[8 + l] = sub(
                sub(sub(sub(x[8 + l], ar, bdr), ai, -bdi), adr, br),
                adi,
                -bi,
            );
            x[12 + l] = sub(sub(sub(sub(x[12 + l], ar, bdi), ai, bdr), adr, bi), adi, br);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Random duals whose numbers span thirteen decades, so that a different grouping of the
    /// subtractions would round differently and show.
    fn random_duals(seed: u64) -> impl FnMut() -> Dual {
        let mut state = seed;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64;
            (unit - 0.5) * 10f64.powi((state % 13) as i32 - 6)
        };
        move || Dual {
            v: Complex64::new(next(), next()),
            d: Complex64::new(next(), next()),
        }
    }

    fn same_bits(got: &Dual, want: &Dual) -> bool {
        [
            (got.v.re, want.v.re),
            (got.v.im, want.v.im),
            (got.d.re, want.d.re),
            (got.d.im, want.d.im),
        ]
        .iter()
        .all(|(g, w)| g.to_bits() == w.to_bits())
    }

    #[test]
    fn the_lane_wise_update_equals_its_scalar_form_to_the_last_bit() {
        // Oracles: the subtractions written out number by number (fused where the processor
        // runs the fused version), to the last bit, and `Dual::sub_mul`, the products as
        // complex arithmetic reads them, within a few roundings.
        let fused = fused_version_runs();
        let mut dual = random_duals(0x9e37_79b9_7f4a_7c15);
        let n = 64;
        let x0: Vec<Dual> = (0..n).map(|_| dual()).collect();
        let rows: Vec<usize> = (0..n).rev().step_by(3).collect();
        let a: Vec<Dual> = rows.iter().map(|_| dual()).collect();
        for _ in 0..20 {
            let b = dual();
            let mut expected = x0.clone();
            for (&i, &ai) in rows.iter().zip(&a) {
                expected[i] = scalar_sub_mul(expected[i], ai, b, fused);
            }
            let mut x = x0.clone();
            sub_mul_each(&mut x, &rows, &a, b);
            for (got, want) in x.iter().zip(&expected) {
                assert!(same_bits(got, want), "{got:?} against {want:?}");
            }
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

    #[test]
    fn the_update_of_blocks_equals_the_update_of_duals_to_the_last_bit() {
        // Oracle: `sub_mul_each` on the same numbers kept as duals (itself checked above).
        let mut dual = random_duals(0x2545_f491_4f6c_dd1d);
        for blocks in [1usize, 2, 3, 17] {
            let n = 4 * blocks;
            let x0: Vec<Dual> = (0..n).map(|_| dual()).collect();
            let a: Vec<Dual> = (0..n).map(|_| dual()).collect();
            let b = dual();
            let mut expected = x0.clone();
            let rows: Vec<usize> = (0..n).collect();
            sub_mul_each(&mut expected, &rows, &a, b);
            let into_blocks = |v: &[Dual]| {
                let mut out = vec![[0.0; 16]; blocks];
                v.iter()
                    .enumerate()
                    .for_each(|(t, &d)| block_set(&mut out, t, d));
                out
            };
            let mut x = into_blocks(&x0);
            sub_mul_blocks(&mut x, &into_blocks(&a), b);
            for (t, want) in expected.iter().enumerate() {
                let got = block_get(&x, t);
                assert!(
                    same_bits(&got, want),
                    "{blocks} blocks, at {t}: {got:?} against {want:?}"
                );
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

    /// `x − a·b` number by number, in the order of [`sub_mul_each`]: `x − a.v.re·c₁ − a.v.im·c₂
    /// − a.d.re·c₃ − a.d.im·c₄`, each subtraction fused when `fused`.
    fn scalar_sub_mul(x: Dual, a: Dual, b: Dual, fused: bool) -> Dual {
        let sub = |x: f64, a: f64, c: f64| if fused { (-a).mul_add(c, x) } else { x - a * c };
        let (ar, ai, adr, adi) = (a.v.re, a.v.im, a.d.re, a.d.im);
        let (br, bi, bdr, bdi) = (b.v.re, b.v.im, b.d.re, b.d.im);
        Dual {
            v: Complex64::new(
                sub(sub(x.v.re, ar, br), ai, -bi),
                sub(sub(x.v.im, ar, bi), ai, br),
            ),
            d: Complex64::new(
                sub(sub(sub(sub(x.d.re, ar, bdr), ai, -bdi), adr, br), adi, -bi),
                sub(sub(sub(sub(x.d.im, ar, bdi), ai, bdr), adr, bi), adi, br),
            ),
        }
    }
}
