//! How a pass rounds `a b + c`: as one fused operation (one rounding) in the copies compiled
//! for processors with FMA, as a multiplication then an addition (two roundings) in the
//! baseline copy, which has no fused instruction. The fused operation is exact before its one
//! rounding, so both forms agree to within a rounding of each product; the AVX2 and AVX-512
//! copies fuse the same operations and compute the same bits as each other.
//!
//! A pass compiled once per instruction set ([`run_pass`](crate::instruction_set::run_pass))
//! receives its copy's [`MulAdd`] as a constant; the loops it inlines fold the choice away, so
//! each copy's loop holds only its own instructions. What takes a [`MulAdd`] must be inlined
//! into the copy: a function left out of line is compiled for the baseline, where a fused
//! multiply-add is a call into the C library's `fma` (many times slower). So the helpers here
//! are `#[inline(always)]` plain loops, never iterator adaptors such as `fold`, whose instances
//! the compiler may share out of line.

use crate::spatial::{Matrix3, Matrix6, Vector3};
use nalgebra::Vector6;

/// The rounding of the multiply-adds of one instruction set's copy of a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct MulAdd {
    fused: bool,
}

impl MulAdd {
    /// A multiplication, then an addition: what every processor computes alike.
    pub(crate) const SEPARATE: MulAdd = MulAdd { fused: false };
    /// One fused multiply-add, for copies compiled with FMA: in a copy without it
    /// `f64::mul_add` would be a call into the C library.
    pub(crate) const FUSED: MulAdd = MulAdd { fused: true };

    /// Whether `a b + c` is rounded once.
    #[inline(always)]
    pub(crate) fn is_fused(self) -> bool {
        self.fused
    }

    /// `a b + c`.
    #[inline(always)]
    pub(crate) fn mul_add(self, a: f64, b: f64, c: f64) -> f64 {
        if self.fused {
            a.mul_add(b, c)
        } else {
            a * b + c
        }
    }

    /// `c − a b`.
    #[inline(always)]
    pub(crate) fn sub_mul(self, c: f64, a: f64, b: f64) -> f64 {
        if self.fused {
            (-a).mul_add(b, c)
        } else {
            c - a * b
        }
    }

    /// `y + a x`, entry by entry.
    #[inline(always)]
    pub(crate) fn axpy(self, a: f64, x: &Vector6<f64>, y: &Vector6<f64>) -> Vector6<f64> {
        let mut out = *y;
        for r in 0..6 {
            out[r] = self.mul_add(a, x[r], y[r]);
        }
        out
    }

    /// `y − a x`, entry by entry.
    #[inline(always)]
    pub(crate) fn sub_scaled(self, y: &Vector6<f64>, a: f64, x: &Vector6<f64>) -> Vector6<f64> {
        let mut out = *y;
        for r in 0..6 {
            out[r] = self.sub_mul(y[r], a, x[r]);
        }
        out
    }

    /// `xᵀ y = Σ_r x_r y_r`, as the sum of two halves, `r < 3` and `r ≥ 3`, each from its
    /// first entry on: the halves are independent, so the result waits on three products and
    /// an addition, not six products in a row.
    #[inline(always)]
    pub(crate) fn dot(self, x: &Vector6<f64>, y: &Vector6<f64>) -> f64 {
        let low = self.mul_add(x[2], y[2], self.mul_add(x[1], y[1], x[0] * y[0]));
        let high = self.mul_add(x[5], y[5], self.mul_add(x[4], y[4], x[3] * y[3]));
        low + high
    }

    /// `m x = Σ_j m[:, j] x_j`, as the sum of two halves, `j < 3` and `j ≥ 3`, each a column
    /// at a time (independent, as in [`dot`](Self::dot)).
    #[inline(always)]
    pub(crate) fn matrix_vector(self, m: &Matrix6, x: &Vector6<f64>) -> Vector6<f64> {
        let column = |j: usize| -> Vector6<f64> { m.column(j).into() };
        let low = self.axpy(
            x[2],
            &column(2),
            &self.axpy(x[1], &column(1), &(column(0) * x[0])),
        );
        let high = self.axpy(
            x[5],
            &column(5),
            &self.axpy(x[4], &column(4), &(column(3) * x[3])),
        );
        low + high
    }

    /// `a × b`, each component `a_j b_k − a_k b_j` as one multiply-add.
    #[inline(always)]
    pub(crate) fn cross(self, a: &Vector3, b: &Vector3) -> Vector3 {
        Vector3::new(
            self.mul_add(a.y, b.z, -(a.z * b.y)),
            self.mul_add(a.z, b.x, -(a.x * b.z)),
            self.mul_add(a.x, b.y, -(a.y * b.x)),
        )
    }

    /// `m x` for a 3×3 `m`, a column at a time.
    #[inline(always)]
    pub(crate) fn matrix3_vector(self, m: &Matrix3, x: &Vector3) -> Vector3 {
        let mut sum = m.column(0) * x.x;
        for j in 1..3 {
            for r in 0..3 {
                sum[r] = self.mul_add(m[(r, j)], x[j], sum[r]);
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::MulAdd;
    use crate::spatial::{Matrix3, Matrix6, Vector3};
    use nalgebra::Vector6;

    /// `(1 + 2⁻³⁰)(1 − 2⁻³⁰) − 1 = −2⁻⁶⁰` exactly: the product rounds to 1 when it is rounded
    /// on its own, so the separate form gives 0 and the fused one the exact value.
    #[test]
    fn fused_rounds_once_and_separate_twice() {
        let (a, b) = (1.0 + 2f64.powi(-30), 1.0 - 2f64.powi(-30));
        let exact = -(2f64.powi(-60));
        assert_eq!(MulAdd::FUSED.mul_add(a, b, -1.0), exact);
        assert_eq!(MulAdd::SEPARATE.mul_add(a, b, -1.0), 0.0);
        assert_eq!(MulAdd::FUSED.sub_mul(1.0, a, b), -exact);
        assert_eq!(MulAdd::SEPARATE.sub_mul(1.0, a, b), 0.0);
    }

    /// The helpers are the products they name, in either rounding (to within rounding of
    /// nalgebra's).
    #[test]
    fn helpers_are_their_products() {
        let m6 = Matrix6::from_fn(|r, c| ((r * 6 + c) as f64 * 0.37).sin());
        let (x6, y6) = (
            Vector6::from_fn(|r, _| r as f64 - 2.5),
            Vector6::from_fn(|r, _| 0.3 * r as f64),
        );
        let m3 = Matrix3::from_fn(|r, c| ((r * 3 + c) as f64 * 0.71).cos());
        let (a3, b3) = (Vector3::new(0.2, -1.3, 2.1), Vector3::new(-0.7, 0.4, 1.9));
        let close =
            |got: f64, want: f64| assert!((got - want).abs() <= 1e-14, "{got} against {want}");
        for m in [MulAdd::SEPARATE, MulAdd::FUSED] {
            let near6 = |got: Vector6<f64>, want: Vector6<f64>| {
                got.iter().zip(&want).for_each(|(g, w)| close(*g, *w))
            };
            near6(m.axpy(1.7, &x6, &y6), y6 + x6 * 1.7);
            near6(m.sub_scaled(&y6, 1.7, &x6), y6 - x6 * 1.7);
            near6(m.matrix_vector(&m6, &x6), m6 * x6);
            close(m.dot(&x6, &y6), x6.dot(&y6));
            let near3 = |got: Vector3, want: Vector3| {
                got.iter().zip(&want).for_each(|(g, w)| close(*g, *w))
            };
            near3(m.cross(&a3, &b3), a3.cross(&b3));
            near3(m.matrix3_vector(&m3, &a3), m3 * a3);
        }
    }
}
