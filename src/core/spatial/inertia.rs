//! Rigid-body spatial inertia.

use super::{skew, Force, Matrix3, Matrix6, Motion, Vector3};
use crate::mul_add::MulAdd;

/// The spatial inertia of a rigid body about the origin of the frame it is expressed in
/// (handout eq. 39):
///
/// `I = [Ī  h×; h×ᵀ  m 1]`, with `h = m c` and `Ī = I_c − m c× c×`,
///
/// where `m` is the mass, `c` the centre of mass and `I_c` the rotational inertia about the
/// centre of mass (all in the same frame). Stored compactly as `(m, h, Ī)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inertia {
    /// Mass m (kg).
    pub mass: f64,
    /// First moment of mass `h = m c` (kg·m).
    pub h: Vector3,
    /// Rotational inertia about the frame origin, `Ī` (kg·m²).
    pub i_bar: Matrix3,
}

impl Inertia {
    /// From mass, centre of mass `com` and rotational inertia `i_com` about the centre of mass
    /// (axes parallel to the frame's).
    pub fn from_com(mass: f64, com: &Vector3, i_com: &Matrix3) -> Self {
        let cx = skew(com);
        Inertia {
            mass,
            h: com * mass,
            i_bar: i_com - cx * cx * mass,
        }
    }

    /// The zero inertia (a massless body).
    pub fn zero() -> Self {
        Self::default()
    }

    /// `I v = [Ī ω + h × v; m v − h × ω]`: the momentum of a body moving with velocity `v`
    /// (or the force needed to give it acceleration `v`).
    pub fn apply(&self, v: &Motion) -> Force {
        self.apply_with(v, MulAdd::SEPARATE)
    }

    /// [`apply`](Self::apply) with the multiply-adds of `mul_add`: separate, as nalgebra's
    /// vectorised products; fused, a component at a time.
    #[inline(always)]
    pub(crate) fn apply_with(&self, v: &Motion, mul_add: MulAdd) -> Force {
        if !mul_add.is_fused() {
            return Force::new(
                self.i_bar * v.ang + self.h.cross(&v.lin),
                v.lin * self.mass - self.h.cross(&v.ang),
            );
        }
        let (h, m) = (&self.h, self.mass);
        let h_v = mul_add.cross(h, &v.lin);
        let h_w = mul_add.cross(h, &v.ang);
        let mut ang = mul_add.matrix3_vector(&self.i_bar, &v.ang);
        let mut lin = Vector3::zeros();
        for r in 0..3 {
            ang[r] += h_v[r];
            lin[r] = mul_add.mul_add(v.lin[r], m, -h_w[r]);
        }
        Force::new(ang, lin)
    }

    /// `I e_j`, column `j` of [`to_matrix`](Self::to_matrix): for an angular unit vector
    /// (`j < 3`) `[Ī e_j; e_j × h]`, for a linear one (`j = 3 + k`) `[h × e_k; m e_k]`, each
    /// cross product with a unit vector written out (two components of `h`, one negated).
    /// `Ī e_j` is read along row `j` (the same numbers: `Ī` is symmetric), three separate
    /// loads: a column's two adjacent entries can straddle two of the 16-byte stores that wrote
    /// the inertia (`+=`), which the processor cannot forward to one load.
    #[inline]
    pub fn column(&self, j: usize) -> Force {
        let (h, m) = (&self.h, self.mass);
        let z = 0.0;
        match j {
            0 => Force::new(self.i_bar.row(0).transpose(), Vector3::new(z, -h.z, h.y)),
            1 => Force::new(self.i_bar.row(1).transpose(), Vector3::new(h.z, z, -h.x)),
            2 => Force::new(self.i_bar.row(2).transpose(), Vector3::new(-h.y, h.x, z)),
            3 => Force::new(Vector3::new(z, h.z, -h.y), Vector3::new(m, z, z)),
            4 => Force::new(Vector3::new(-h.z, z, h.x), Vector3::new(z, m, z)),
            _ => Force::new(Vector3::new(h.y, -h.x, z), Vector3::new(z, z, m)),
        }
    }

    /// Centre of mass `c = h / m`; the frame origin for a massless body.
    pub fn com(&self) -> Vector3 {
        if self.mass > 0.0 {
            self.h / self.mass
        } else {
            Vector3::zeros()
        }
    }

    /// The dense 6×6 matrix `[Ī h×; h×ᵀ m 1]`.
    pub fn to_matrix(&self) -> Matrix6 {
        let mut m = Matrix6::zeros();
        self.write_matrix(&mut m);
        m
    }

    /// [`to_matrix`](Self::to_matrix) into `m`, column by column ([`column`](Self::column)):
    /// each entry written once, none read.
    #[inline]
    pub fn write_matrix(&self, m: &mut Matrix6) {
        for j in 0..6 {
            let column = self.column(j);
            m.fixed_view_mut::<3, 1>(0, j).copy_from(&column.ang);
            m.fixed_view_mut::<3, 1>(3, j).copy_from(&column.lin);
        }
    }
}

impl std::ops::Add for Inertia {
    type Output = Inertia;
    fn add(self, o: Inertia) -> Inertia {
        Inertia {
            mass: self.mass + o.mass,
            h: self.h + o.h,
            i_bar: self.i_bar + o.i_bar,
        }
    }
}

impl std::ops::AddAssign for Inertia {
    fn add_assign(&mut self, o: Inertia) {
        self.mass += o.mass;
        self.h += o.h;
        self.i_bar += o.i_bar;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_mass_parallel_axis() {
        // A point mass m at c = (0, 0, l) has Ī = m l² about the x and y axes, 0 about z.
        let (m, l) = (2.0, 0.5);
        let i = Inertia::from_com(m, &Vector3::new(0.0, 0.0, l), &Matrix3::zeros());
        assert!(
            (i.i_bar - Matrix3::from_diagonal(&Vector3::new(m * l * l, m * l * l, 0.0))).norm()
                < 1e-15
        );
        let v = Motion::new(Vector3::new(0.3, -0.2, 0.9), Vector3::new(1.0, 2.0, -1.0));
        assert!((i.apply(&v).to_vector() - i.to_matrix() * v.to_vector()).norm() < 1e-14);
        let fused = i.apply_with(&v, MulAdd::FUSED);
        assert!((fused.to_vector() - i.to_matrix() * v.to_vector()).norm() < 1e-14);
        assert!((i.com() - Vector3::new(0.0, 0.0, l)).norm() < 1e-15);
        let general = Inertia::from_com(
            1.5,
            &Vector3::new(0.1, -0.3, 0.2),
            &Matrix3::new(0.3, 0.01, 0.02, 0.01, 0.2, -0.03, 0.02, -0.03, 0.25),
        );
        for j in 0..6 {
            let column = general.to_matrix().column(j).into_owned();
            assert!(
                (general.column(j).to_vector() - column).norm() < 1e-15,
                "column {j}"
            );
        }
    }
}
