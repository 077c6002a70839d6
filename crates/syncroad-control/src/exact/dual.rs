//! Dual numbers `a + a'ε` (`ε² = 0`) over the complex numbers: an LU in this ring carries the
//! derivative of its matrix in `s` along, so `d/ds log det M(s)` comes out of the pivots and a
//! solve gives `x` with `dx/ds` ([`super::banded`], [`super::sparse_lu`]).

use num_complex::Complex64;

/// A complex number with its derivative in `s`: `v + d·ε`, `ε² = 0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
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
    /// `self − a·b`, the update of an elimination, written out so that it compiles to one
    /// run of multiply–adds.
    #[inline]
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
