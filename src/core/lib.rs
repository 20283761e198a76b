//! `spatial_dynamics`: rigid-body dynamics of robots described in URDF, in Featherstone's
//! spatial vectors. No ROS types here: the library stands alone.
//!
//! The shape follows Pinocchio: an immutable [`Model`] (bodies, joints, inertias, gravity) and
//! a [`Workspace`] of scratch buffers; every algorithm takes `(model, workspace, inputs…)`,
//! writes into the workspace and allocates nothing.
//!
//! Conventions: spatial vectors are `[angular; linear]`; each body's quantities are expressed
//! in its own (link) frame; `q` and `v` follow [`Model::coordinate_joints`]; a floating joint
//! has `q = [x y z qx qy qz qw]` (position in the world, unit quaternion x, y, z, w) and
//! `v = [linear; angular]` in the base frame; SI units throughout.

#![forbid(unsafe_code)]

pub mod algorithms;
pub mod double_double;
pub mod error;
pub mod model;
pub(crate) mod plan;
pub mod requests;
pub mod sampling;
pub mod sim;
pub mod spatial;
pub mod urdf;
mod workspace;

pub use algorithms::{Externals, ForwardDynamicsMethod};
pub use error::{DynamicsError, ModelError};
pub use model::{Model, ModelOptions};
pub use workspace::Workspace;
