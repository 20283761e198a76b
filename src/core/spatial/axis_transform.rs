//! A turn about a coordinate axis after a translation, `rot(E_K(θ)) · xlt(r)`: the transform
//! across a revolute joint about a coordinate axis when the joint's placement has no rotation
//! of its own (a URDF `<origin rpy="0 0 0">`, the common case). Its rotation mixes only the two
//! other coordinates, so its actions cost about half a general [`Transform`]'s.

use super::{Force, Inertia, Matrix3, Motion, Transform, Translation, Vector3};

/// `rot(E) · xlt(r)` with `E` a turn by `θ` about coordinate axis `K`: with `I = K + 1` and
/// `J = K + 2` (mod 3), `E` has rows `ε_I = c e_I + s e_J`, `ε_J = c e_J − s e_I`, `ε_K = e_K`
/// (`c = cos θ`, `s = sin θ`; `E` takes parent coordinates to child coordinates, as in
/// [`Transform`]), and `r` is the child's origin in parent coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisTransform<const K: usize> {
    /// `cos θ`.
    pub cos: f64,
    /// `sin θ`.
    pub sin: f64,
    /// `r`: the child's origin, in parent coordinates.
    pub trans: Vector3,
}

impl<const K: usize> AxisTransform<K> {
    const I: usize = (K + 1) % 3;
    const J: usize = (K + 2) % 3;

    /// The turn read off a transform whose rotation is one about axis `K`
    /// (`c = E_II`, `s = E_IJ`); the caller knows it is (a revolute joint about `e_K` whose
    /// placement has no rotation).
    #[inline(always)]
    pub fn from_transform(x: &Transform) -> Self {
        debug_assert_eq!(x.rot[(K, K)], 1.0, "not a turn about axis {K}");
        AxisTransform {
            cos: x.rot[(Self::I, Self::I)],
            sin: x.rot[(Self::I, Self::J)],
            trans: x.trans,
        }
    }

    /// `Eᵀ u`: `(c u_I − s u_J, s u_I + c u_J, u_K)` in the `(I, J, K)` slots.
    #[inline(always)]
    fn turn_back(&self, u: &Vector3) -> Vector3 {
        let (c, s) = (self.cos, self.sin);
        let mut out = *u;
        out[Self::I] = c * u[Self::I] - s * u[Self::J];
        out[Self::J] = s * u[Self::I] + c * u[Self::J];
        out
    }

    /// `E u`: `(c u_I + s u_J, c u_J − s u_I, u_K)` in the `(I, J, K)` slots.
    #[inline(always)]
    fn turn(&self, u: &Vector3) -> Vector3 {
        let (c, s) = (self.cos, self.sin);
        let mut out = *u;
        out[Self::I] = c * u[Self::I] + s * u[Self::J];
        out[Self::J] = c * u[Self::J] - s * u[Self::I];
        out
    }

    /// Composition `X · ᴮX_A` (`inner` is `ᴮX_A`): `E E_BA`, whose rows `I` and `J` are those of
    /// `E_BA` mixed by the turn (the others kept), and `r_BA + E_BAᵀ r`.
    #[inline(always)]
    pub fn compose(&self, inner: &Transform) -> Transform {
        let (c, s, e) = (self.cos, self.sin, &inner.rot);
        let mut rot = *e;
        for col in 0..3 {
            rot[(Self::I, col)] = c * e[(Self::I, col)] + s * e[(Self::J, col)];
            rot[(Self::J, col)] = c * e[(Self::J, col)] - s * e[(Self::I, col)];
        }
        Transform {
            rot,
            trans: inner.trans + inner.rot.tr_mul(&self.trans),
        }
    }

    /// `X m = [E ω; E (v − r × ω)]` (the translation, then the turn).
    #[inline(always)]
    pub fn apply_motion(&self, m: &Motion) -> Motion {
        let m = Translation(self.trans).apply_motion(m);
        Motion::new(self.turn(&m.ang), self.turn(&m.lin))
    }

    /// `Xᵀ f = xlt(r)ᵀ [Eᵀ n; Eᵀ f]`: a force from child coordinates back into the parent's.
    #[inline(always)]
    pub fn transpose_apply_force(&self, f: &Force) -> Force {
        let turned = Force::new(self.turn_back(&f.ang), self.turn_back(&f.lin));
        Translation(self.trans).transpose_apply_force(&turned)
    }

    /// `Xᵀ I X`: turn into the parent's axes (`h' = Eᵀ h`, `Ī' = Eᵀ Ī E`), then move the origin
    /// ([`Translation::transpose_apply_inertia`]).
    ///
    /// `Eᵀ Ī E` changes only the `(I, J)` block and the `(I, K)`, `(J, K)` entries: with
    /// `Ī_II = a`, `Ī_IJ = b`, `Ī_JJ = d`, `(Ī_IK, Ī_JK) = (g, k)` and `R = [c s; −s c]` (the
    /// `(I, J)` block of `E`), the block becomes `Rᵀ [a b; b d] R`, whose `JJ` entry follows
    /// from the trace `a + d`, and `(g, k)` becomes `Rᵀ (g, k)` (10 m + 8 a and 4 m + 2 a, where
    /// a general rotation takes 28 m + 29 a). Inlined (see
    /// [`Transform::transpose_apply_inertia`]).
    #[inline(always)]
    pub fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia {
        let (c, s) = (self.cos, self.sin);
        let (i, j) = (Self::I, Self::J);
        let m = &inertia.i_bar;
        let (a, b, d) = (m[(i, i)], m[(i, j)], m[(j, j)]);
        // Columns of [a b; b d] R, then the entries of Rᵀ (that) on and above the diagonal.
        let (u_i, u_j) = (a * c - b * s, b * c - d * s);
        let (w_i, w_j) = (a * s + b * c, b * s + d * c);
        let a_new = c * u_i - s * u_j;
        let b_new = c * w_i - s * w_j;
        let d_new = (a + d) - a_new;
        let gk = self.turn_back(&m.column(K).into_owned());
        let mut i_bar = Matrix3::zeros();
        (i_bar[(i, i)], i_bar[(j, j)], i_bar[(K, K)]) = (a_new, d_new, m[(K, K)]);
        (i_bar[(i, j)], i_bar[(j, i)]) = (b_new, b_new);
        (i_bar[(i, K)], i_bar[(K, i)]) = (gk[i], gk[i]);
        (i_bar[(j, K)], i_bar[(K, j)]) = (gk[j], gk[j]);
        let turned = Inertia {
            mass: inertia.mass,
            h: self.turn_back(&inertia.h),
            i_bar,
        };
        Translation(self.trans).transpose_apply_inertia(&turned)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::SpatialTransform;
    use nalgebra::{Rotation3, Unit};

    /// Each action equals the general [`Transform`]'s for the same `rot(E) xlt(r)`, about each
    /// axis and for turns in every quadrant.
    #[test]
    fn actions_match_the_general_transform() {
        fn check<const K: usize>(theta: f64) {
            // E takes parent coordinates to child ones: the transpose of the child's orientation.
            let orientation =
                Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::ith(K, 1.0)), theta);
            let r = Vector3::new(0.3, -1.2, 0.7);
            let general = Transform::from_pose(orientation.matrix(), &r);
            let x = AxisTransform::<K>::from_transform(&general);
            assert!((x.cos - theta.cos()).abs() < 1e-15 && (x.sin - theta.sin()).abs() < 1e-15);
            let m = Motion::new(Vector3::new(0.1, 0.2, -0.3), Vector3::new(1.0, -2.0, 0.5));
            let f = Force::new(Vector3::new(-0.4, 0.6, 0.2), Vector3::new(0.3, 0.9, -1.5));
            let close =
                |a: nalgebra::Vector6<f64>, b: nalgebra::Vector6<f64>| (a - b).amax() < 1e-15;
            assert!(close(
                x.apply_motion(&m).to_vector(),
                general.apply_motion(&m).to_vector()
            ));
            let moved = x.transpose_apply_force(&f).to_vector();
            assert!(close(moved, general.transpose_apply_force(&f).to_vector()));
            let inner = Transform::from_pose(
                Rotation3::from_euler_angles(0.4, -1.1, 2.0).matrix(),
                &Vector3::new(-0.6, 0.1, 0.9),
            );
            let (ours, reference) = (x.compose(&inner), general.compose(&inner));
            assert!((ours.rot - reference.rot).amax() < 1e-15);
            assert!((ours.trans - reference.trans).amax() < 1e-15);
            let u = Vector3::new(0.3, -0.8, 1.7);
            assert!((x.turn(&u) - general.rot * u).amax() < 1e-15);
            let mut forces = [f, f * 2.0];
            x.transpose_apply_forces(&mut forces);
            assert_eq!(
                forces[1].to_vector(),
                x.transpose_apply_force(&(f * 2.0)).to_vector()
            );
            let inertia = Inertia::from_com(
                2.5,
                &Vector3::new(0.1, -0.2, 0.3),
                &Matrix3::new(0.3, 0.01, 0.02, 0.01, 0.2, -0.03, 0.02, -0.03, 0.25),
            );
            let ours = x.transpose_apply_inertia(&inertia).to_matrix();
            let reference = general.transpose_apply_inertia(&inertia).to_matrix();
            assert!((ours - reference).amax() < 1e-14, "K = {K}, θ = {theta}");
            assert_eq!(ours, ours.transpose());
        }
        for theta in [0.0, 0.4, 2.1, -2.9, -0.7] {
            check::<0>(theta);
            check::<1>(theta);
            check::<2>(theta);
        }
    }
}
