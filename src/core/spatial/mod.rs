//! Spatial (6-D) algebra in Featherstone's notation.
//!
//! Every 6-vector is stored as an `(angular, linear)` pair of 3-vectors, the order Featherstone
//! and the handout use: a motion vector is `[ω; v]` (angular velocity, velocity of the point at the
//! frame origin), a force vector is `[n; f]` (moment about the frame origin, force). Each value is
//! expressed in one coordinate frame; the doc comment of whatever holds it names that frame.
//!
//! Transforms are stored as a rotation and a translation ([`Transform`]), never as dense 6×6
//! matrices; dense 6×6 matrices appear only for articulated-body inertias ([`Matrix6`]).

mod axis_transform;
mod inertia;
mod sincos;
mod transform;
mod vector;

pub use axis_transform::AxisTransform;
pub use inertia::Inertia;
pub use sincos::{sin_cos, sin_cos_all};
pub use transform::{Transform, Translation};
pub use vector::{Force, Motion};

/// Dense 6×6 matrix acting on `[angular; linear]` coordinates.
pub type Matrix6 = nalgebra::Matrix6<f64>;
/// 3-vector.
pub type Vector3 = nalgebra::Vector3<f64>;
/// 3×3 matrix.
pub type Matrix3 = nalgebra::Matrix3<f64>;

/// The actions of a Plücker transform `rot(E) xlt(r)` the tree passes use, for each form one
/// is stored in ([`Transform`], [`Translation`], [`AxisTransform`]): a pass is written once and
/// compiled for each form (`algorithms::kinematics::with_up_transform`).
pub trait SpatialTransform {
    /// `X m`: a motion from A coordinates into B coordinates.
    fn apply_motion(&self, m: &Motion) -> Motion;
    /// `X · inner`: with `inner = ᴬX_W`, the placement `ᴮX_W`.
    fn compose(&self, inner: &Transform) -> Transform;
    /// `Xᵀ f`: a force from B coordinates back into A coordinates.
    fn transpose_apply_force(&self, f: &Force) -> Force;
    /// `Xᵀ I X`: a rigid-body inertia from B coordinates into A coordinates.
    fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia;
    /// `Xᵀ f` for each force of `forces`, in place.
    fn transpose_apply_forces(&self, forces: &mut [Force]) {
        for f in forces {
            *f = self.transpose_apply_force(f);
        }
    }
}

impl SpatialTransform for Transform {
    fn apply_motion(&self, m: &Motion) -> Motion {
        Transform::apply_motion(self, m)
    }
    fn compose(&self, inner: &Transform) -> Transform {
        Transform::compose(self, inner)
    }
    fn transpose_apply_force(&self, f: &Force) -> Force {
        Transform::transpose_apply_force(self, f)
    }
    #[inline(always)]
    fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia {
        Transform::transpose_apply_inertia(self, inertia)
    }
    fn transpose_apply_forces(&self, forces: &mut [Force]) {
        Transform::transpose_apply_forces(self, forces)
    }
}

impl SpatialTransform for Translation {
    fn apply_motion(&self, m: &Motion) -> Motion {
        Translation::apply_motion(self, m)
    }
    fn compose(&self, inner: &Transform) -> Transform {
        Translation::compose(self, inner)
    }
    fn transpose_apply_force(&self, f: &Force) -> Force {
        Translation::transpose_apply_force(self, f)
    }
    #[inline(always)]
    fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia {
        Translation::transpose_apply_inertia(self, inertia)
    }
}

impl<const K: usize> SpatialTransform for AxisTransform<K> {
    fn apply_motion(&self, m: &Motion) -> Motion {
        AxisTransform::apply_motion(self, m)
    }
    fn compose(&self, inner: &Transform) -> Transform {
        AxisTransform::compose(self, inner)
    }
    fn transpose_apply_force(&self, f: &Force) -> Force {
        AxisTransform::transpose_apply_force(self, f)
    }
    #[inline(always)]
    fn transpose_apply_inertia(&self, inertia: &Inertia) -> Inertia {
        AxisTransform::transpose_apply_inertia(self, inertia)
    }
}

/// The cross-product matrix `a×`, such that `a× b = a × b`.
pub fn skew(a: &Vector3) -> Matrix3 {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}
