//! Motion and force vectors and the two spatial cross products.

use super::Vector3;
use crate::mul_add::MulAdd;
use nalgebra::Vector6;
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial motion vector `[ω; v]`: angular velocity (or acceleration) `ω` and the linear
/// velocity (or acceleration) `v` of the point at the origin of the frame it is expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Angular part ω.
    pub ang: Vector3,
    /// Linear part v (of the frame origin).
    pub lin: Vector3,
}

/// A spatial force vector `[n; f]`: moment `n` about the origin of the frame it is expressed in,
/// and force `f`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Force {
    /// Moment n about the frame origin.
    pub ang: Vector3,
    /// Force f.
    pub lin: Vector3,
}

macro_rules! spatial_vector_ops {
    ($t:ident) => {
        impl $t {
            /// The zero vector.
            pub fn zero() -> Self {
                Self::default()
            }
            /// From angular and linear parts.
            pub fn new(ang: Vector3, lin: Vector3) -> Self {
                Self { ang, lin }
            }
            /// As a dense 6-vector `[angular; linear]`.
            pub fn to_vector(&self) -> Vector6<f64> {
                Vector6::new(
                    self.ang.x, self.ang.y, self.ang.z, self.lin.x, self.lin.y, self.lin.z,
                )
            }
            /// From a dense 6-vector `[angular; linear]`.
            pub fn from_vector(x: &Vector6<f64>) -> Self {
                Self::new(x.fixed_rows::<3>(0).into(), x.fixed_rows::<3>(3).into())
            }
            /// Component `j` of `[angular; linear]`.
            pub fn component(&self, j: usize) -> f64 {
                if j < 3 {
                    self.ang[j]
                } else {
                    self.lin[j - 3]
                }
            }
            /// True when all six components are finite, without a branch per component: `x · 0`
            /// is zero for a finite `x` and NaN otherwise, so the six products sum to zero
            /// exactly when all are finite.
            #[inline]
            pub fn is_finite(&self) -> bool {
                let z = self.ang * 0.0 + self.lin * 0.0;
                z.x + z.y + z.z == 0.0
            }
        }
        impl Add for $t {
            type Output = $t;
            fn add(self, o: $t) -> $t {
                $t::new(self.ang + o.ang, self.lin + o.lin)
            }
        }
        impl Sub for $t {
            type Output = $t;
            fn sub(self, o: $t) -> $t {
                $t::new(self.ang - o.ang, self.lin - o.lin)
            }
        }
        impl AddAssign for $t {
            fn add_assign(&mut self, o: $t) {
                self.ang += o.ang;
                self.lin += o.lin;
            }
        }
        impl SubAssign for $t {
            fn sub_assign(&mut self, o: $t) {
                self.ang -= o.ang;
                self.lin -= o.lin;
            }
        }
        impl Neg for $t {
            type Output = $t;
            fn neg(self) -> $t {
                $t::new(-self.ang, -self.lin)
            }
        }
        impl Mul<f64> for $t {
            type Output = $t;
            fn mul(self, s: f64) -> $t {
                $t::new(self.ang * s, self.lin * s)
            }
        }
    };
}

spatial_vector_ops!(Motion);
spatial_vector_ops!(Force);

impl Motion {
    /// Spatial cross product for motions (handout eq. 40, Featherstone's `crm`):
    /// `[ω; v] ×̂ [m_ω; m_v] = [ω × m_ω; ω × m_v + v × m_ω]`.
    pub fn cross_motion(&self, m: &Motion) -> Motion {
        Motion::new(
            self.ang.cross(&m.ang),
            self.ang.cross(&m.lin) + self.lin.cross(&m.ang),
        )
    }

    /// Spatial cross product for forces (Featherstone's `crf`, `v ×* f = −(v ×̂)ᵀ f`):
    /// `[ω; v] ×* [n; f] = [ω × n + v × f; ω × f]`.
    pub fn cross_force(&self, f: &Force) -> Force {
        self.cross_force_with(f, MulAdd::SEPARATE)
    }

    /// [`cross_force`](Self::cross_force) with the multiply-adds of `mul_add`: separate, as
    /// nalgebra's cross products; fused, a component at a time.
    #[inline(always)]
    pub(crate) fn cross_force_with(&self, f: &Force, mul_add: MulAdd) -> Force {
        if !mul_add.is_fused() {
            return Force::new(
                self.ang.cross(&f.ang) + self.lin.cross(&f.lin),
                self.ang.cross(&f.lin),
            );
        }
        Force::new(
            mul_add.cross(&self.ang, &f.ang) + mul_add.cross(&self.lin, &f.lin),
            mul_add.cross(&self.ang, &f.lin),
        )
    }

    /// `self + x e_j`: `x` added to component `j` of `[ω; v]` (`0..3` angular, `3..6` linear).
    #[inline(always)]
    pub fn add_along(&mut self, j: usize, x: f64) {
        if j < 3 {
            self.ang[j] += x;
        } else {
            self.lin[j - 3] += x;
        }
    }

    /// `self += w (m ×̂ e_j)`, the motion cross product with unit vector `j` of `[ω; v]`
    /// scaled by `w`, computing only its nonzero components: for `j < 3`
    /// `m ×̂ e_j = [m_ω × e_j; m_v × e_j]` (four), for `j = 3 + k` `[0; m_ω × e_k]` (two), where
    /// `x × e_0 = (0, x_z, −x_y)`, `x × e_1 = (−x_z, 0, x_x)`, `x × e_2 = (x_y, −x_x, 0)`.
    /// With `j` a constant the components are known at compile time.
    #[inline(always)]
    pub fn add_cross_axis(&mut self, m: &Motion, j: usize, w: f64) {
        if j < 3 {
            add_cross_unit(&mut self.ang, &m.ang, j, w);
            add_cross_unit(&mut self.lin, &m.lin, j, w);
        } else {
            add_cross_unit(&mut self.lin, &m.ang, j - 3, w);
        }
    }

    /// The scalar product with a force, `mᵀ f` (power when `m` is a velocity; the handout's
    /// spatial transpose `m^S f`). Both must be expressed in the same frame.
    pub fn dot(&self, f: &Force) -> f64 {
        self.ang.dot(&f.ang) + self.lin.dot(&f.lin)
    }
}

/// `out += w (x × e_k)`: the two nonzero components of `x × e_k`, scaled by `w` (see
/// [`Motion::add_cross_axis`]).
#[inline(always)]
fn add_cross_unit(out: &mut Vector3, x: &Vector3, k: usize, w: f64) {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    // e_k × e_i = e_j and e_j × e_k = e_i, so x × e_k = x_j e_i − x_i e_j.
    out[i] += x[j] * w;
    out[j] -= x[i] * w;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::skew;
    use nalgebra::Matrix6;

    fn crm_matrix(v: &Motion) -> Matrix6<f64> {
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&v.ang));
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&skew(&v.ang));
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&skew(&v.lin));
        m
    }

    #[test]
    fn cross_products_match_featherstone_matrices() {
        let v = Motion::new(Vector3::new(0.3, -1.2, 0.7), Vector3::new(2.0, 0.1, -0.4));
        let m = Motion::new(Vector3::new(-0.5, 0.9, 1.1), Vector3::new(0.2, -0.3, 0.6));
        let f = Force::new(Vector3::new(1.5, 0.4, -2.2), Vector3::new(-0.7, 0.8, 0.05));
        let crm = crm_matrix(&v);
        let crf = -crm.transpose();
        assert!((v.cross_motion(&m).to_vector() - crm * m.to_vector()).norm() < 1e-14);
        assert!((v.cross_force(&f).to_vector() - crf * f.to_vector()).norm() < 1e-14);
        let fused = v.cross_force_with(&f, crate::mul_add::MulAdd::FUSED);
        assert!((fused.to_vector() - crf * f.to_vector()).norm() < 1e-14);
        // v ×̂ v = 0, and the power of m ×̂ v against f equals −(power of v against m ×* f)... the
        // duality (v ×̂ m)·f = −m·(v ×* f).
        assert!(v.cross_motion(&v).to_vector().norm() < 1e-15);
        assert!((v.cross_motion(&m).dot(&f) + m.dot(&v.cross_force(&f))).abs() < 1e-13);
    }

    /// `a + w (v ×̂ e_j)` and `a + x e_j` equal the general forms with the unit vector written
    /// out, for every `j`; the sums of the components left alone are unchanged.
    #[test]
    fn unit_axis_forms_match_the_general_ones() {
        let v = Motion::new(Vector3::new(0.3, -1.2, 0.7), Vector3::new(2.0, 0.1, -0.4));
        let a = Motion::new(Vector3::new(-0.5, 0.9, 1.1), Vector3::new(0.2, -0.3, 0.6));
        let w = -1.7;
        for j in 0..6 {
            let mut e = Vector6::zeros();
            e[j] = 1.0;
            let unit = Motion::from_vector(&e);
            let mut ours = a;
            ours.add_cross_axis(&v, j, w);
            let general = a + v.cross_motion(&(unit * w));
            assert!(
                (ours.to_vector() - general.to_vector()).amax() < 1e-15,
                "j = {j}"
            );
            let mut moved = a;
            moved.add_along(j, w);
            assert_eq!(moved.to_vector(), (a + unit * w).to_vector(), "j = {j}");
        }
    }

    #[test]
    fn finiteness_sees_every_component() {
        let finite = Motion::new(
            Vector3::new(1e300, -2.0, 0.0),
            Vector3::new(-0.0, 5.0, 1e-300),
        );
        assert!(finite.is_finite());
        for k in 0..6 {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut x = finite.to_vector();
                x[k] = bad;
                assert!(
                    !Motion::from_vector(&x).is_finite(),
                    "component {k} = {bad}"
                );
                assert!(!Force::from_vector(&x).is_finite(), "component {k} = {bad}");
            }
        }
    }
}
