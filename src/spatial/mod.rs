//! Spatial (6-D) algebra in Featherstone's notation.
//!
//! Every 6-vector is stored as an `(angular, linear)` pair of 3-vectors, the order Featherstone
//! and the handout use: a motion vector is `[ω; v]` (angular velocity, velocity of the point at the
//! frame origin), a force vector is `[n; f]` (moment about the frame origin, force). Each value is
//! expressed in one coordinate frame; the doc comment of whatever holds it names that frame.
//!
//! Transforms are stored as a rotation and a translation ([`Transform`]), never as dense 6×6
//! matrices; dense 6×6 matrices appear only for articulated-body inertias ([`Matrix6`]).

mod inertia;
mod transform;
mod vector;

pub use inertia::Inertia;
pub use transform::{Transform, Translation};
pub use vector::{Force, Motion};

/// Dense 6×6 matrix acting on `[angular; linear]` coordinates.
pub type Matrix6 = nalgebra::Matrix6<f64>;
/// 3-vector.
pub type Vector3 = nalgebra::Vector3<f64>;
/// 3×3 matrix.
pub type Matrix3 = nalgebra::Matrix3<f64>;

/// The cross-product matrix `a×`, such that `a× b = a × b`.
pub fn skew(a: &Vector3) -> Matrix3 {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}
