//! Plücker coordinate transforms, stored as a rotation and a translation, and pure translations.

use super::{skew, Force, Inertia, Matrix3, Matrix6, Motion, Vector3};

/// The Plücker transform `ᴮX_A` taking motion vectors from frame A coordinates to frame B
/// coordinates (handout eq. 38, Featherstone's `rot(E) · xlt(r)`):
///
/// `ᴮX_A = [E 0; −E r× E]`,
///
/// where `rot` is `E` (rotates A coordinates into B coordinates, so `E = Rᵀ` for `R` the
/// orientation of B in A) and `trans` is `r` (the origin of B, in A coordinates).
/// Forces transform with `ᴮX*_A = ᴮX_A^{-T}`; `Xᵀ` takes forces from B back to A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// `E`: rotation from A coordinates to B coordinates.
    pub rot: Matrix3,
    /// `r`: position of B's origin, in A coordinates.
    pub trans: Vector3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::identity()
    }
}

impl Transform {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rot: Matrix3::identity(),
            trans: Vector3::zeros(),
        }
    }

    /// The transform into a frame B placed in A at `position` with orientation `rotation`
    /// (rotation matrix of B's axes in A coordinates, as a URDF `<origin>` gives them).
    pub fn from_pose(rotation: &Matrix3, position: &Vector3) -> Self {
        Self {
            rot: rotation.transpose(),
            trans: *position,
        }
    }

    /// A pure rotation, `rot(E)`.
    pub fn rotation(e: Matrix3) -> Self {
        Self {
            rot: e,
            trans: Vector3::zeros(),
        }
    }

    /// A pure translation, `xlt(r)`: B's origin at `r` in A, axes parallel.
    pub fn translation(r: Vector3) -> Self {
        Self {
            rot: Matrix3::identity(),
            trans: r,
        }
    }

    /// `X m = [E ω; E (v − r × ω)]`.
    pub fn apply_motion(&self, m: &Motion) -> Motion {
        Motion::new(
            self.rot * m.ang,
            self.rot * (m.lin - self.trans.cross(&m.ang)),
        )
    }

    /// `X* f = [E (n − r × f); E f]`: a force from A coordinates into B coordinates.
    pub fn apply_force(&self, f: &Force) -> Force {
        Force::new(
            self.rot * (f.ang - self.trans.cross(&f.lin)),
            self.rot * f.lin,
        )
    }

    /// `X⁻¹ m = [Eᵀ ω; Eᵀ v + r × Eᵀ ω]`: a motion from B coordinates back into A coordinates.
    pub fn inverse_apply_motion(&self, m: &Motion) -> Motion {
        let ang = self.rot.tr_mul(&m.ang);
        Motion::new(ang, self.rot.tr_mul(&m.lin) + self.trans.cross(&ang))
    }

    /// `X⁻¹ (σ e_j)`, a unit motion along coordinate `j` of B (`0..3` angular, `3..6` linear),
    /// signed, in A coordinates: `Eᵀ e_j` is row `j` of `E`, so a turn is `[σ E_j; r × σ E_j]`
    /// and a slide `[0; σ E_(j−3)]`, with no product for the rotation.
    #[inline(always)]
    pub fn inverse_apply_axis(&self, j: usize, sign: f64) -> Motion {
        if j < 3 {
            let ang = self.rot.row(j).transpose() * sign;
            Motion::new(ang, self.trans.cross(&ang))
        } else {
            Motion::new(Vector3::zeros(), self.rot.row(j - 3).transpose() * sign)
        }
    }

    /// `Xᵀ f = [Eᵀ n + r × Eᵀ f; Eᵀ f]`: a force from B coordinates back into A coordinates.
    pub fn transpose_apply_force(&self, f: &Force) -> Force {
        let lin = self.rot.tr_mul(&f.lin);
        Force::new(self.rot.tr_mul(&f.ang) + self.trans.cross(&lin), lin)
    }

    /// `Xᵀ f` for each force of `forces`, in place. Kept out of line, so that its loop is
    /// compiled the same wherever it is called (two forces at a time in SSE2 registers).
    #[inline(never)]
    pub fn transpose_apply_forces(&self, forces: &mut [Force]) {
        for f in forces {
            *f = self.transpose_apply_force(f);
        }
    }

    /// Composition `ᶜX_A = ᶜX_B · ᴮX_A` (`self` is `ᶜX_B`, `inner` is `ᴮX_A`):
    /// `E = E_CB E_BA`, `r = r_BA + E_BAᵀ r_CB`.
    #[inline(always)]
    pub fn compose(&self, inner: &Transform) -> Transform {
        Transform {
            rot: self.rot * inner.rot,
            trans: inner.trans + inner.rot.tr_mul(&self.trans),
        }
    }

    /// `ᴬX_B = (ᴮX_A)⁻¹`: `E' = Eᵀ`, `r' = −E r`.
    pub fn inverse(&self) -> Transform {
        Transform {
            rot: self.rot.transpose(),
            trans: -(self.rot * self.trans),
        }
    }

    /// `Xᵀ I X`: a rigid-body inertia given in B coordinates, expressed in A coordinates.
    ///
    /// Rotate into A's axes (still about B's origin), `h' = Eᵀ h`, `Ī' = Eᵀ Ī E`, then move the
    /// origin by `r` ([`Translation::transpose_apply_inertia`]). Inlined, as every action that
    /// returns an [`Inertia`] is: returned through memory, its 8-byte stores would reach the
    /// caller's 16-byte loads (`+=`) only after the store buffer drains, a stall per body.
    #[inline(always)]
    pub fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia {
        let rotated = Inertia {
            mass: inertia.mass,
            h: self.rot.tr_mul(&inertia.h),
            i_bar: rotate_symmetric(&self.rot, &inertia.i_bar),
        };
        Translation(self.trans).transpose_apply_inertia(&rotated)
    }

    /// `Xᵀ M X` for a dense symmetric 6×6 inertia `M = [A B; Bᵀ C]` given in B coordinates
    /// (an articulated-body inertia), expressed in A coordinates; computed by blocks.
    ///
    /// Rotate the blocks (`a = Eᵀ A E`, `b = Eᵀ B E`, `c = Eᵀ C E`), then translate
    /// ([`Translation::transpose_apply_matrix6`]).
    pub fn transpose_apply_matrix6(&self, m: &Matrix6) -> Matrix6 {
        let e = &self.rot;
        let a = rotate_symmetric(e, &m.fixed_view::<3, 3>(0, 0).into_owned());
        let b = e.tr_mul(&(m.fixed_view::<3, 3>(0, 3) * e));
        let c = rotate_symmetric(e, &m.fixed_view::<3, 3>(3, 3).into_owned());
        Translation(self.trans).transpose_apply_blocks(&a, &b, &c)
    }

    /// The dense 6×6 motion transform `[E 0; −E r× E]` (for tests and edges, not hot paths).
    pub fn to_matrix(&self) -> Matrix6 {
        let mut x = Matrix6::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rot);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.rot);
        x.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(-self.rot * skew(&self.trans)));
        x
    }
}

/// `Eᵀ S E` for a symmetric `S` and a rotation `E`, in 28 m + 29 a (a product of three 3×3
/// matrices would take 135, the six distinct entries of `Eᵀ (S E)` 75), using what a rotation
/// keeps: multiples of the identity, the trace, and cross-product matrices
/// (`Eᵀ k× E = (Eᵀ k)×`).
///
/// With `S = [a b d; b c e; d e f]`, take `S' = S − f 1 = N + k×`, where
/// `N = [a−f  b  0; b  c−f  0; 2d  2e  0]` has a zero last column and `k = (−e, d, 0)`. Then
/// `Eᵀ S E = f 1 + P + t×` with `P = Eᵀ N E` and `t = Eᵀ k`. As `N = n₀ ε₀ᵀ + n₁ ε₁ᵀ` (`n_l` its
/// columns, `ε_jᵀ` row `j` of `E`), `P_pq = y₀_p E_0q + y₁_p E_1q` with `y_l = Eᵀ n_l`: only
/// the entries below the diagonal and rows 1 and 2 of the diagonal are needed, as the result
/// is symmetric (`t×` is zero on the diagonal) and its first diagonal entry follows from the
/// trace, `tr(Eᵀ S' E) = tr S' = (a − f) + (c − f)`. Inlined (see
/// [`Transform::transpose_apply_inertia`]).
#[inline(always)]
fn rotate_symmetric(e: &Matrix3, s: &Matrix3) -> Matrix3 {
    let f = s[(2, 2)];
    let (a, c) = (s[(0, 0)] - f, s[(1, 1)] - f);
    let (b, d, e_) = (s[(1, 0)], s[(2, 0)], s[(2, 1)]);
    let (n0, n1) = (Vector3::new(a, b, d + d), Vector3::new(b, c, e_ + e_));
    // y_l = Eᵀ n_l, rows 1 and 2: column p of E dotted with n_l.
    let y = |l: &Vector3, p: usize| e.column(p).dot(l);
    let (y01, y11, y02, y12) = (y(&n0, 1), y(&n1, 1), y(&n0, 2), y(&n1, 2));
    let p = |y0: f64, y1: f64, q: usize| y0 * e[(0, q)] + y1 * e[(1, q)];
    // t = Eᵀ k = −e ε₀ + d ε₁.
    let t = |q: usize| d * e[(1, q)] - e_ * e[(0, q)];
    let m10 = p(y01, y11, 0) + t(2);
    let m20 = p(y02, y12, 0) - t(1);
    let m21 = p(y02, y12, 1) + t(0);
    let (m11, m22) = (p(y01, y11, 1), p(y02, y12, 2));
    let m00 = (a + c) - m11 - m22;
    Matrix3::new(m00 + f, m10, m20, m10, m11 + f, m21, m20, m21, m22 + f)
}

/// A pure translation `xlt(r)` (`Transform` with `E = 1`), kept apart so that moving a quantity
/// between two frames with the same axes costs no rotation: B's origin is at `r` in A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Translation(pub Vector3);

impl Translation {
    /// `xlt(r) m = [ω; v − r × ω]`: a motion from A coordinates into B coordinates (the
    /// point at B's origin moves with `v + ω × r`).
    pub fn apply_motion(&self, m: &Motion) -> Motion {
        Motion::new(m.ang, m.lin - self.0.cross(&m.ang))
    }

    /// Composition `xlt(r) · ᴮX_A` (`inner` is `ᴮX_A`): `E_BA` kept, origin `r_BA + E_BAᵀ r`.
    pub fn compose(&self, inner: &Transform) -> Transform {
        Transform {
            rot: inner.rot,
            trans: inner.trans + inner.rot.tr_mul(&self.0),
        }
    }

    /// `xlt(r)ᵀ f = [n + r × f; f]`: a force from B coordinates back into A coordinates.
    pub fn transpose_apply_force(&self, f: &Force) -> Force {
        Force::new(f.ang + self.0.cross(&f.lin), f.lin)
    }

    /// `xlt(r)ᵀ I xlt(r)`: a rigid-body inertia about B's origin, about A's: `h_A = h + m r` and
    /// `Ī_A = Ī − r× h× − h× r× − m r× r× = Ī − h_A rᵀ − r hᵀ + (r·(h + h_A)) 1`
    /// (by `a× b× = b aᵀ − (a·b) 1`), a symmetric update of six entries. Inlined (see
    /// [`Transform::transpose_apply_inertia`]).
    #[inline(always)]
    pub fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia {
        let (r, h) = (&self.0, &inertia.h);
        let h_a = h + r * inertia.mass;
        let diag = r.dot(&(h + h_a));
        let entry = |j: usize, k: usize| inertia.i_bar[(j, k)] - h_a[j] * r[k] - r[j] * h[k];
        let (xy, xz, yz) = (entry(0, 1), entry(0, 2), entry(1, 2));
        let i_bar = Matrix3::new(
            entry(0, 0) + diag,
            xy,
            xz,
            xy,
            entry(1, 1) + diag,
            yz,
            xz,
            yz,
            entry(2, 2) + diag,
        );
        Inertia {
            mass: inertia.mass,
            h: h_a,
            i_bar,
        }
    }

    /// `xlt(r)ᵀ M xlt(r)` for a dense symmetric 6×6 inertia `M = [A B; Bᵀ C]` (an
    /// articulated-body inertia) about B's origin, about A's.
    pub fn transpose_apply_matrix6(&self, m: &Matrix6) -> Matrix6 {
        self.transpose_apply_blocks(
            &m.fixed_view::<3, 3>(0, 0).into_owned(),
            &m.fixed_view::<3, 3>(0, 3).into_owned(),
            &m.fixed_view::<3, 3>(3, 3).into_owned(),
        )
    }

    /// `xlt(r)ᵀ [a b; bᵀ c] xlt(r)` with `xlt(r) = [1 0; −r× 1]` is
    /// `[a − b r× + r× bᵀ − r× c r×,  b + r× c;  (b + r× c)ᵀ,  c]`; with `b' = b + r× c` the
    /// top-left block is `a + (r× bᵀ)ᵀ + r× b'ᵀ` (as `c` is symmetric), three columnwise cross
    /// products in all.
    fn transpose_apply_blocks(&self, a: &Matrix3, b: &Matrix3, c: &Matrix3) -> Matrix6 {
        let r = &self.0;
        let b_new = b + cross_columns(r, c);
        let a_new =
            a + cross_columns(r, &b.transpose()).transpose() + cross_columns(r, &b_new.transpose());
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&a_new);
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&b_new);
        out.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&b_new.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(c);
        out
    }
}

/// `r× M`: the cross product of `r` with each column of `M`.
fn cross_columns(r: &Vector3, m: &Matrix3) -> Matrix3 {
    let mut out = Matrix3::zeros();
    for j in 0..3 {
        out.set_column(j, &r.cross(&m.column(j).into_owned()));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector6};

    fn sample(seed: f64) -> Transform {
        let r = Rotation3::from_euler_angles(0.3 * seed, -0.7 + seed, 1.1 * seed);
        Transform::from_pose(r.matrix(), &Vector3::new(0.2 * seed, -0.5, 0.9 - seed))
    }

    #[test]
    fn handout_translation_matrix() {
        // Handout eq. 19: ⁻¹X₀ for a translation by q₀ along x has lower-left block
        // [0 0 0; 0 0 −q₀; 0 q₀ 0], i.e. −r× with r = (−q₀, 0, 0)... the handout writes the
        // child-to-parent transform, the inverse of xlt(q₀ x̂).
        let q0 = 0.37;
        let x_child_parent = Transform::translation(Vector3::new(q0, 0.0, 0.0));
        let m = x_child_parent.inverse().to_matrix();
        let lower_left = m.fixed_view::<3, 3>(3, 0).clone_owned();
        let expected = Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, -q0, 0.0, q0, 0.0);
        assert!((lower_left - expected).norm() < 1e-15);
    }

    /// `X⁻¹ (σ e_j)` read off rows of `E` equals the column `σ X⁻¹ e_j` of the dense inverse.
    #[test]
    fn axis_moved_back_is_a_column_of_the_inverse() {
        let x = sample(0.7);
        let inverse = x.to_matrix().try_inverse().unwrap();
        for j in 0..6 {
            for sign in [1.0, -1.0] {
                let column = inverse.column(j) * sign;
                let err = (x.inverse_apply_axis(j, sign).to_vector() - column).amax();
                assert!(err < 1e-15, "axis {j}, sign {sign}: {err}");
            }
        }
    }

    #[test]
    fn operations_match_dense_matrices() {
        let x = sample(0.4);
        let y = sample(-1.3);
        let xm = x.to_matrix();
        let m = Motion::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(1.0, -2.0, 0.5));
        let f = Force::new(Vector3::new(-0.4, 0.6, 0.2), Vector3::new(0.3, 0.9, -1.5));
        let xf = xm.try_inverse().unwrap().transpose();
        assert!((x.apply_motion(&m).to_vector() - xm * m.to_vector()).norm() < 1e-14);
        assert!((x.apply_force(&f).to_vector() - xf * f.to_vector()).norm() < 1e-14);
        assert!(
            (x.inverse_apply_motion(&m).to_vector() - xm.try_inverse().unwrap() * m.to_vector())
                .norm()
                < 1e-13
        );
        assert!(
            (x.transpose_apply_force(&f).to_vector() - xm.transpose() * f.to_vector()).norm()
                < 1e-14
        );
        assert!((x.compose(&y).to_matrix() - xm * y.to_matrix()).norm() < 1e-14);
        assert!((x.inverse().to_matrix() - xm.try_inverse().unwrap()).norm() < 1e-13);
        let inertia = Inertia::from_com(
            2.5,
            &Vector3::new(0.1, -0.2, 0.3),
            &Matrix3::new(0.3, 0.01, 0.02, 0.01, 0.2, -0.03, 0.02, -0.03, 0.25),
        );
        let dense = xm.transpose() * inertia.to_matrix() * xm;
        assert!((x.transpose_apply_inertia(&inertia).to_matrix() - dense).norm() < 1e-13);
        assert!((x.transpose_apply_matrix6(&inertia.to_matrix()) - dense).norm() < 1e-13);
        // An articulated inertia: any symmetric 6×6, its lower-right block not a multiple of 1.
        let g = Matrix6::from_fn(|r, c| ((r * 7 + c * 3) % 11) as f64 * 0.1 - 0.4);
        let articulated = g.transpose() * g + Matrix6::identity();
        let dense = xm.transpose() * articulated * xm;
        assert!((x.transpose_apply_matrix6(&articulated) - dense).norm() < 1e-12);
        // `Eᵀ S E` for symmetric matrices of very different scales, several rotations.
        for seed in [0.1, 0.7, -1.9, 2.6] {
            let e = sample(seed).rot;
            let g = Matrix3::from_fn(|r, c| ((r * 5 + c * 2) % 7) as f64 * seed - 1.0);
            let s = g.transpose() * g * 10f64.powf(3.0 * seed) + Matrix3::identity();
            let err = (rotate_symmetric(&e, &s) - e.transpose() * s * e).amax();
            assert!(err < 1e-14 * s.amax(), "seed {seed}: {err:e}");
        }
        // A pure translation is the transform with E = 1.
        let t = Translation(x.trans);
        let xt = Transform::translation(x.trans);
        let xtm = xt.to_matrix();
        assert!((t.apply_motion(&m).to_vector() - xt.apply_motion(&m).to_vector()).norm() < 1e-14);
        let moved = t.transpose_apply_force(&f).to_vector();
        assert!((moved - xtm.transpose() * f.to_vector()).norm() < 1e-14);
        let dense = xtm.transpose() * inertia.to_matrix() * xtm;
        assert!((t.transpose_apply_inertia(&inertia).to_matrix() - dense).norm() < 1e-13);
        let dense = xtm.transpose() * articulated * xtm;
        assert!((t.transpose_apply_matrix6(&articulated) - dense).norm() < 1e-12);
        let (composed, reference) = (t.compose(&y), xt.compose(&y));
        assert!((composed.to_matrix() - reference.to_matrix()).norm() < 1e-15);
        // Power is frame-invariant: (X m)·(X* f) = m·f.
        assert!((x.apply_motion(&m).dot(&x.apply_force(&f)) - m.dot(&f)).abs() < 1e-13);
        let _ = Vector6::<f64>::zeros();
    }
}
