//! The lane value: one `f64` of the scalar kernel for each of [`LANES`] states, and its
//! 3-vectors. Every operation acts lane by lane with the scalar operation of the same name (no
//! fused multiply-add, no reassociation), so lane `ℓ` of a result has the bits the scalar
//! expression gives on state `ℓ`'s operands; on baseline x86-64 a lane operation is packed SSE2
//! instructions, one per two lanes.

use super::LANES;
use crate::spatial::Vector3;
use std::ops::{Add, AddAssign, Mul, MulAssign, Sub, SubAssign};

/// One value for each of [`LANES`] states (structure of arrays: lane `ℓ` is state `ℓ`'s).
/// Aligned to the SSE2 register, so that a lane value in memory is an operand of a packed
/// instruction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(align(16))]
pub(crate) struct Lanes(pub(crate) [f64; LANES]);

impl Lanes {
    /// The same value in every lane (a model constant).
    #[inline(always)]
    pub(crate) fn splat(x: f64) -> Self {
        Lanes([x; LANES])
    }

    /// Lane `ℓ` from `values[ℓ * stride + offset]`: one coordinate of [`LANES`] rows of
    /// `stride` values each.
    #[inline(always)]
    pub(crate) fn gather(values: &[f64], stride: usize, offset: usize) -> Self {
        Lanes(std::array::from_fn(|l| values[l * stride + offset]))
    }

    /// Lane `ℓ` into `values[ℓ * stride + offset]` (the inverse of [`gather`](Self::gather)).
    #[inline(always)]
    pub(crate) fn scatter(self, values: &mut [f64], stride: usize, offset: usize) {
        for (l, x) in self.0.into_iter().enumerate() {
            values[l * stride + offset] = x;
        }
    }

    /// [`LANES`] consecutive values.
    #[inline(always)]
    pub(crate) fn load(values: &[f64]) -> Self {
        Lanes(std::array::from_fn(|l| values[l]))
    }
}

macro_rules! lane_op {
    ($trait:ident, $method:ident, $op:tt, $assign:ident, $assign_method:ident) => {
        impl $trait for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $method(self, o: Lanes) -> Lanes {
                Lanes(std::array::from_fn(|l| self.0[l] $op o.0[l]))
            }
        }
        impl $assign for Lanes {
            #[inline(always)]
            fn $assign_method(&mut self, o: Lanes) {
                *self = *self $op o;
            }
        }
    };
}
lane_op!(Add, add, +, AddAssign, add_assign);
lane_op!(Sub, sub, -, SubAssign, sub_assign);
lane_op!(Mul, mul, *, MulAssign, mul_assign);

/// A 3-vector of lane values (`V3[k]` is coordinate `k` of every state's vector).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct V3(pub(crate) [Lanes; 3]);

impl V3 {
    /// A model constant in every lane.
    pub(crate) fn splat(x: &Vector3) -> Self {
        V3([0, 1, 2].map(|k| Lanes::splat(x[k])))
    }

    /// `self × b` as nalgebra's `cross`: `(a_y b_z − a_z b_y, a_z b_x − a_x b_z, a_x b_y − a_y b_x)`.
    #[inline(always)]
    pub(crate) fn cross(&self, b: &V3) -> V3 {
        let ([ax, ay, az], [bx, by, bz]) = (self.0, b.0);
        V3([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])
    }

    /// `a · b` as nalgebra's `dot`: `(a₀ b₀ + a₁ b₁) + a₂ b₂`.
    #[inline(always)]
    pub(crate) fn dot(&self, b: &V3) -> Lanes {
        self[0] * b[0] + self[1] * b[1] + self[2] * b[2]
    }

    /// Every coordinate times `s` (nalgebra's `v * s`).
    #[inline(always)]
    pub(crate) fn scale(&self, s: Lanes) -> V3 {
        V3(self.0.map(|x| x * s))
    }
}

impl std::ops::Index<usize> for V3 {
    type Output = Lanes;
    #[inline(always)]
    fn index(&self, k: usize) -> &Lanes {
        &self.0[k]
    }
}

impl std::ops::IndexMut<usize> for V3 {
    #[inline(always)]
    fn index_mut(&mut self, k: usize) -> &mut Lanes {
        &mut self.0[k]
    }
}

impl Add for V3 {
    type Output = V3;
    #[inline(always)]
    fn add(self, o: V3) -> V3 {
        V3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}

impl Sub for V3 {
    type Output = V3;
    #[inline(always)]
    fn sub(self, o: V3) -> V3 {
        V3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}

impl AddAssign for V3 {
    #[inline(always)]
    fn add_assign(&mut self, o: V3) {
        *self = *self + o;
    }
}

/// A 3×3 matrix of lane values, by rows (`M3[r][c]`).
pub(crate) type M3 = [V3; 3];

/// `M u` as nalgebra's matrix–vector product: row `r` is `(M_r0 u_0 + M_r1 u_1) + M_r2 u_2`.
#[inline(always)]
pub(crate) fn mul(m: &M3, u: &V3) -> V3 {
    V3([0, 1, 2].map(|r| m[r][0] * u[0] + m[r][1] * u[1] + m[r][2] * u[2]))
}

/// `Mᵀ u` as nalgebra's `tr_mul`: coordinate `c` is `(M_0c u_0 + M_1c u_1) + M_2c u_2`.
#[inline(always)]
pub(crate) fn tr_mul(m: &M3, u: &V3) -> V3 {
    V3([0, 1, 2].map(|c| m[0][c] * u[0] + m[1][c] * u[1] + m[2][c] * u[2]))
}

/// A model constant matrix in every lane.
pub(crate) fn splat_matrix(m: &crate::spatial::Matrix3) -> M3 {
    [0, 1, 2].map(|r| V3([0, 1, 2].map(|c| Lanes::splat(m[(r, c)]))))
}
