//! The velocity-product matrix `B` of a body's force, in the sparse form its structure allows.
//!
//! For a body of spatial inertia `I` moving with `v`, `B` is the linear map
//!
//! ```text
//! B ψ = I (ψ × v) + v ×* I ψ + ψ ×* I v
//! ```
//!
//! (`∂f/∂v` through the velocity-dependent terms). Written with `I = [Ī, [h]×; −[h]×, m 1]`,
//! `v = (ω, u)`, the momentum `I v = (n, p)` (`n = Ī ω + h × u`, `p = m u − h × ω`) and
//! `crm(v) = [[ω]×, 0; [u]×, [ω]×]`, the first two terms are `−(X + Xᵀ)` with `X = I crm(v)`,
//! and the last is `[−[n]×, −[p]×; −[p]×, 0]`. Block by block (the commutator of two skew
//! matrices is the skew matrix of the cross product, and `m [u]× − [p]× = [h × ω]×`):
//!
//! ```text
//! B = [ B_ωω  0 ]     B_ωω = −(P + Pᵀ) − (u hᵀ + h uᵀ) + 2 (h·u) 1 − [n]×,   P = Ī [ω]×
//!     [ −2[p]× 0 ]
//! ```
//!
//! so `B ψ` reads only the angular part of `ψ`, and `Bᵀ s` has no linear part. Both blocks are
//! linear in `(I, v)` term by term, so a subtree's sum `B^C = Σ B_k` is the sum of the blocks.
//! 12 numbers instead of 36, and 15 multiplications for `B ψ` or `Bᵀ s` instead of 36.

use crate::spatial::{skew, Force, Inertia, Matrix3, Motion, Vector3};
use std::ops::AddAssign;

/// `B` of [the module](self): its angular block `B_ωω` and the linear momentum `p` of its
/// lower block `−2 [p]×`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VelocityProduct {
    /// `B_ωω`.
    ww: Matrix3,
    /// `p`, the lower block being `−2 [p]×`.
    p: Vector3,
}

impl VelocityProduct {
    pub(crate) fn zero() -> Self {
        VelocityProduct {
            ww: Matrix3::zeros(),
            p: Vector3::zeros(),
        }
    }

    /// `B` of a body of inertia `inertia` moving with `v` (both in the same frame), its
    /// momentum `momentum = I v` already made.
    #[inline(always)]
    pub(crate) fn new(inertia: &Inertia, v: &Motion, momentum: &Force) -> Self {
        let (omega, u, h) = (&v.ang, &v.lin, &inertia.h);
        let p_mat = inertia.i_bar * skew(omega);
        let uh = u * h.transpose();
        let ww = -(p_mat + p_mat.transpose()) - (uh + uh.transpose())
            + Matrix3::from_diagonal_element(2.0 * h.dot(u))
            - skew(&momentum.ang);
        VelocityProduct {
            ww,
            p: momentum.lin,
        }
    }

    /// `B ψ = (B_ωω ψ_ω, −2 p × ψ_ω)`.
    pub(crate) fn apply(&self, psi: &Motion) -> Force {
        Force::new(self.ww * psi.ang, -2.0 * self.p.cross(&psi.ang))
    }

    /// The angular part of `Bᵀ s`, `B_ωωᵀ s_ω + 2 p × s_u` (its linear part is zero): `(Bᵀ s)·ψ`
    /// is this dotted with `ψ_ω`.
    pub(crate) fn tr_apply(&self, s: &Motion) -> Vector3 {
        self.ww.tr_mul(&s.ang) + 2.0 * self.p.cross(&s.lin)
    }
}

impl AddAssign for VelocityProduct {
    fn add_assign(&mut self, other: Self) {
        self.ww += other.ww;
        self.p += other.p;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::Matrix6;
    use nalgebra::Vector6;

    /// `B` from its definition, column by column (`ψ = e_c`), as a dense 6×6 matrix.
    fn dense(inertia: &Inertia, v: &Motion) -> Matrix6 {
        let momentum = inertia.apply(v);
        Matrix6::from_fn(|r, c| {
            let e = Motion::from_vector(&Vector6::ith(c, 1.0));
            let column = inertia.apply(&e.cross_motion(v))
                + v.cross_force(&inertia.apply(&e))
                + e.cross_force(&momentum);
            column.to_vector()[r]
        })
    }

    /// The sparse form applies and transposes as the definition does, for bodies with their
    /// centre of mass off the frame origin, and sums over bodies block by block.
    #[test]
    fn sparse_form_matches_the_definition() {
        let a = Matrix3::new(0.3, 0.1, -0.2, 0.0, 0.5, 0.1, 0.2, -0.1, 0.4);
        let bodies = [
            (
                Inertia::from_com(2.3, &Vector3::new(0.1, -0.4, 0.25), &(a * a.transpose())),
                Motion::new(Vector3::new(0.7, -1.1, 0.4), Vector3::new(-0.3, 0.9, 1.6)),
            ),
            (
                Inertia::from_com(
                    0.8,
                    &Vector3::new(-0.6, 0.2, 0.05),
                    &(Matrix3::identity() * 0.02),
                ),
                Motion::new(Vector3::new(-2.0, 0.3, 0.9), Vector3::new(1.2, 0.1, -0.5)),
            ),
        ];
        let mut sum = VelocityProduct::zero();
        let mut dense_sum = Matrix6::zeros();
        for (inertia, v) in &bodies {
            sum += VelocityProduct::new(inertia, v, &inertia.apply(v));
            dense_sum += dense(inertia, v);
        }
        let x = Motion::new(Vector3::new(0.3, -0.8, 0.5), Vector3::new(1.1, 0.4, -0.9));
        let by_b = sum.apply(&x).to_vector();
        let by_dense = dense_sum * x.to_vector();
        assert!(
            (by_b - by_dense).amax() < 1e-13,
            "B ψ: {by_b} against {by_dense}"
        );
        let tr_dense = dense_sum.transpose() * x.to_vector();
        let tr_b = sum.tr_apply(&x);
        assert!(
            (tr_b - tr_dense.fixed_rows::<3>(0)).amax() < 1e-13
                && tr_dense.fixed_rows::<3>(3).amax() < 1e-13,
            "Bᵀ s: {tr_b} against {tr_dense}"
        );
    }
}
