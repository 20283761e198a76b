//! Double-double arithmetic: a number is the unevaluated sum `hi + lo` of two `f64` with
//! `|lo| ≤ ulp(hi) / 2`, about 106 significant bits (unit round-off `u = 2⁻¹⁰⁴ ≈ 4.9e-32`
//! for the accurate operations below).
//!
//! Error-free transformations (Dekker 1971, Knuth): `two_sum(a, b) = (s, e)` with `s = fl(a + b)`
//! and `a + b = s + e` exactly; `two_prod(a, b) = (p, e)` with `p = fl(a b)` and `a b = p + e`
//! exactly, by Veltkamp's splitting (no FMA needed; valid while `|a|, |b| < 2⁹⁹⁵` and the product
//! does not underflow). On these: addition (the accurate version, relative error ≤ 2u),
//! multiplication, division (three quotient terms), square root (one Newton step from the `f64`
//! root, Karp's trick) and sine/cosine (argument reduced by `π/2` held as three doubles, then
//! Taylor series on `|t| ≤ π/4`), as in Hida, Li and Bailey's QD library.
//!
//! For reference solutions (the charts' 50-digit baselines) and accuracy tests, such as
//! `spatial::sin_cos`'s: nothing here is on a hot path.

use std::cmp::Ordering;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// `hi + lo`, normalised so that `hi = fl(hi + lo)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DoubleDouble {
    pub hi: f64,
    pub lo: f64,
}

/// `(s, e)`: `s = fl(a + b)`, `a + b = s + e` exactly (Knuth's branch-free two-sum).
pub fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// As [`two_sum`] when `|a| ≥ |b|` (or `a = 0`): three operations.
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// Veltkamp's split: `a = hi + lo`, each half with at most 26 significant bits.
fn split(a: f64) -> (f64, f64) {
    const SPLITTER: f64 = 134_217_729.0; // 2^27 + 1
    let t = SPLITTER * a;
    let hi = t - (t - a);
    (hi, a - hi)
}

/// `(p, e)`: `p = fl(a b)`, `a b = p + e` exactly (Dekker's product on split halves).
pub fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    (p, e)
}

impl DoubleDouble {
    pub const ZERO: DoubleDouble = DoubleDouble { hi: 0.0, lo: 0.0 };
    pub const ONE: DoubleDouble = DoubleDouble { hi: 1.0, lo: 0.0 };
    /// π/2 to double-double precision (the first two of the three parts below).
    pub const FRAC_PI_2: DoubleDouble = DoubleDouble {
        hi: PI_2_PARTS[0],
        lo: PI_2_PARTS[1],
    };

    /// The double `x`, exactly.
    pub const fn from_f64(x: f64) -> DoubleDouble {
        DoubleDouble { hi: x, lo: 0.0 }
    }

    /// The nearest `f64` (`hi`, since the pair is normalised).
    pub fn to_f64(self) -> f64 {
        self.hi
    }

    /// Exact `a + b` of two doubles.
    pub fn sum(a: f64, b: f64) -> DoubleDouble {
        let (hi, lo) = two_sum(a, b);
        DoubleDouble { hi, lo }
    }

    /// Exact `a b` of two doubles.
    pub fn product(a: f64, b: f64) -> DoubleDouble {
        let (hi, lo) = two_prod(a, b);
        DoubleDouble { hi, lo }
    }

    fn renormalised(hi: f64, lo: f64) -> DoubleDouble {
        let (hi, lo) = quick_two_sum(hi, lo);
        DoubleDouble { hi, lo }
    }

    /// `|self|`.
    pub fn abs(self) -> DoubleDouble {
        if self.hi < 0.0 {
            -self
        } else {
            self
        }
    }

    /// `self · x` for a double `x`.
    pub fn mul_f64(self, x: f64) -> DoubleDouble {
        let (p, e) = two_prod(self.hi, x);
        DoubleDouble::renormalised(p, e + self.lo * x)
    }

    /// `self / x` for a double `x`.
    pub fn div_f64(self, x: f64) -> DoubleDouble {
        let q1 = self.hi / x;
        let r = self - DoubleDouble::product(q1, x);
        let q2 = r.hi / x;
        let r = r - DoubleDouble::product(q2, x);
        let q3 = r.hi / x;
        DoubleDouble::renormalised(q1, q2) + DoubleDouble::from_f64(q3)
    }

    /// `√self` (`self ≥ 0`; a negative argument gives NaN): `s = fl(√hi)`, then one Newton step
    /// `s + (self − s²) / (2 s)` in the form `s + (self − s²) · (1/√hi) / 2`.
    pub fn sqrt(self) -> DoubleDouble {
        if self.hi == 0.0 {
            return DoubleDouble::ZERO;
        }
        if self.hi < 0.0 {
            return DoubleDouble::from_f64(f64::NAN);
        }
        let x = 1.0 / self.hi.sqrt();
        let s = self.hi * x;
        let residual = self - DoubleDouble::product(s, s);
        DoubleDouble::sum(s, residual.hi * (x * 0.5))
    }

    /// `(sin self, cos self)`. `self = k π/2 + t` with `k` the nearest integer and `t` computed
    /// with π/2 to three doubles (error ≲ |k| · 1e-49), `|t| ≤ π/4 (1 + ε)`; then the Taylor
    /// series of `sin t` and `cos t` up to the first term below `1e-34`, and the quadrant rotation.
    /// Accurate to a few `u` for `|self| ≲ 1e6`.
    pub fn sin_cos(self) -> (DoubleDouble, DoubleDouble) {
        let k = (self.hi / PI_2_PARTS[0]).round();
        let mut t = self;
        for part in PI_2_PARTS {
            t = t - DoubleDouble::product(k, part);
        }
        let t2 = t * t;
        // sin t = Σ (−1)^j t^(2j+1) / (2j+1)!,  cos t = Σ (−1)^j t^(2j) / (2j)!.
        let (mut sin, mut cos) = (t, DoubleDouble::ONE);
        let (mut term_s, mut term_c) = (t, DoubleDouble::ONE);
        let mut j = 1.0;
        loop {
            term_c = -(term_c * t2).div_f64((2.0 * j - 1.0) * (2.0 * j));
            term_s = -(term_s * t2).div_f64((2.0 * j) * (2.0 * j + 1.0));
            cos = cos + term_c;
            sin = sin + term_s;
            if term_c.hi.abs() < 1e-34 && term_s.hi.abs() < 1e-34 {
                break;
            }
            j += 1.0;
        }
        match (k as i64).rem_euclid(4) {
            0 => (sin, cos),
            1 => (cos, -sin),
            2 => (-sin, -cos),
            _ => (-cos, sin),
        }
    }
}

/// π/2 as the unevaluated sum of three doubles (the leading parts of QD's quad-double π/2).
const PI_2_PARTS: [f64; 3] = [
    std::f64::consts::FRAC_PI_2,
    6.123_233_995_736_766e-17,
    -1.497_384_904_859_169_8e-33, // the next part is 5.6e-50
];

impl Neg for DoubleDouble {
    type Output = DoubleDouble;
    fn neg(self) -> DoubleDouble {
        DoubleDouble {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Add for DoubleDouble {
    type Output = DoubleDouble;
    /// The accurate ("IEEE") double-double sum: both parts added by two-sum.
    fn add(self, b: DoubleDouble) -> DoubleDouble {
        let (s, e) = two_sum(self.hi, b.hi);
        let (t, f) = two_sum(self.lo, b.lo);
        let (s, e) = quick_two_sum(s, e + t);
        DoubleDouble::renormalised(s, e + f)
    }
}

impl Sub for DoubleDouble {
    type Output = DoubleDouble;
    fn sub(self, b: DoubleDouble) -> DoubleDouble {
        self + (-b)
    }
}

impl Mul for DoubleDouble {
    type Output = DoubleDouble;
    fn mul(self, b: DoubleDouble) -> DoubleDouble {
        let (p, e) = two_prod(self.hi, b.hi);
        DoubleDouble::renormalised(p, e + (self.hi * b.lo + self.lo * b.hi))
    }
}

impl Div for DoubleDouble {
    type Output = DoubleDouble;
    /// Long division to three quotient digits: `q1 = hi/b.hi`, `q2`, `q3` on the remainders.
    fn div(self, b: DoubleDouble) -> DoubleDouble {
        let q1 = self.hi / b.hi;
        let r = self - b * DoubleDouble::from_f64(q1);
        let q2 = r.hi / b.hi;
        let r = r - b * DoubleDouble::from_f64(q2);
        let q3 = r.hi / b.hi;
        DoubleDouble::renormalised(q1, q2) + DoubleDouble::from_f64(q3)
    }
}

impl PartialOrd for DoubleDouble {
    fn partial_cmp(&self, other: &DoubleDouble) -> Option<Ordering> {
        match self.hi.partial_cmp(&other.hi) {
            Some(Ordering::Equal) => self.lo.partial_cmp(&other.lo),
            order => order,
        }
    }
}

impl From<f64> for DoubleDouble {
    fn from(x: f64) -> DoubleDouble {
        DoubleDouble::from_f64(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Dd = DoubleDouble;

    /// `|a − b| / |b|` in double-double, rounded to f64.
    fn rel(a: Dd, b: Dd) -> f64 {
        ((a - b).abs() / b.abs()).to_f64()
    }

    /// The double-double nearest to a value given as `hi + lo` (split by mpmath at 50 digits).
    fn dd(hi: f64, lo: f64) -> Dd {
        Dd::sum(hi, lo)
    }

    #[test]
    fn two_sum_and_two_prod_are_exact() {
        // 1 + 2^-80: the rounding error of fl(1 + 2^-80) = 1 is exactly 2^-80.
        let tiny = 2f64.powi(-80);
        assert_eq!(two_sum(1.0, tiny), (1.0, tiny));
        assert_eq!(two_sum(tiny, 1.0), (1.0, tiny));
        // (1 + 2^-30)(1 − 2^-30) = 1 − 2^-60, which rounds to 1: the error term is exactly −2^-60.
        let e30 = 2f64.powi(-30);
        assert_eq!(two_prod(1.0 + e30, 1.0 - e30), (1.0, -(2f64.powi(-60))));
        // (2^27 + 1)^2 = 2^54 + 2^28 + 1: the 1 is lost by fl and recovered by the error term.
        let a = 134_217_729.0;
        assert_eq!(two_prod(a, a), (2f64.powi(54) + 2f64.powi(28), 1.0));
    }

    #[test]
    fn arithmetic_holds_106_bits() {
        let third = Dd::ONE / Dd::from_f64(3.0);
        // hi and lo of 1/3 from mpmath (hi = fl(1/3), lo = fl(1/3 − hi)).
        assert_eq!(third, dd(0.3333333333333333, 1.850371707708594e-17));
        assert!(rel(third * Dd::from_f64(3.0), Dd::ONE) < 1e-31);
        assert!(rel(Dd::ONE.div_f64(3.0), third) < 1e-31);
        // (1 + 2^-60) − 1 = 2^-60 exactly, lost entirely in f64.
        let x = Dd::sum(1.0, 2f64.powi(-60)) - Dd::ONE;
        assert_eq!(x.to_f64(), 2f64.powi(-60));
        // Division of two double-doubles: (1/3) / (1/7) = 7/3.
        let seventh = Dd::ONE / Dd::from_f64(7.0);
        let ratio = third / seventh;
        assert!(rel(ratio, Dd::from_f64(7.0) / Dd::from_f64(3.0)) < 1e-31);
        assert!(rel(ratio.mul_f64(3.0), Dd::from_f64(7.0)) < 1e-31);
    }

    #[test]
    fn sqrt_holds_106_bits() {
        // sqrt(2) from mpmath (hi + lo of its 60-digit value).
        let r2 = Dd::from_f64(2.0).sqrt();
        assert!(rel(r2, dd(std::f64::consts::SQRT_2, -9.667293313452913e-17)) < 1e-31);
        assert!(rel(r2 * r2, Dd::from_f64(2.0)) < 1e-31);
        let third = Dd::ONE / Dd::from_f64(3.0);
        let s = third.sqrt();
        assert!(rel(s * s, third) < 1e-31);
        assert_eq!(Dd::ZERO.sqrt(), Dd::ZERO);
        assert!(Dd::from_f64(-1.0).sqrt().hi.is_nan());
    }

    #[test]
    fn sin_cos_against_mpmath() {
        // (x, sin x, cos x), each as hi + lo of mpmath's 60-digit value.
        let cases = [
            (
                1.0,
                (0.8414709848078965, 1.776845092935536e-18),
                (0.5403023058681398, -4.760954612604417e-17),
            ),
            // x = 100: the reduction subtracts 64 π/2.
            (
                100.0,
                (-0.5063656411097588, -3.050947053792115e-18),
                (0.8623188722876839, 4.334809858136501e-17),
            ),
            // x = −2.5: third quadrant.
            (
                -2.5,
                (-0.5984721441039565, 5.521403334082375e-17),
                (-0.8011436155469337, -1.8674742705085553e-17),
            ),
        ];
        for (x, (sh, sl), (ch, cl)) in cases {
            let (s, c) = Dd::from_f64(x).sin_cos();
            assert!((s - dd(sh, sl)).abs().to_f64() < 1e-31, "sin({x}) = {s:?}");
            assert!((c - dd(ch, cl)).abs().to_f64() < 1e-31, "cos({x}) = {c:?}");
        }
        // sin² + cos² = 1 across quadrants and for a double-double argument.
        for i in -40..=40 {
            let x = Dd::from_f64(f64::from(i) * 0.37) + Dd::from_f64(1e-20);
            let (s, c) = x.sin_cos();
            assert!(
                ((s * s + c * c) - Dd::ONE).abs().to_f64() < 1e-31,
                "x = {x:?}"
            );
        }
        // π/6 in double-double: sin = 1/2.
        let (s, _) = Dd::FRAC_PI_2.div_f64(3.0).sin_cos();
        assert!((s - Dd::from_f64(0.5)).abs().to_f64() < 1e-31);
    }
}
