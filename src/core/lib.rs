//! `spatial_dynamics_core`: rigid-body dynamics of robots described in URDF, in Featherstone's
//! spatial vectors. No ROS types here: the library stands alone.
//!
//! The shape follows Pinocchio: an immutable [`Model`] (bodies, joints, inertias, gravity) and
//! a [`Workspace`] of scratch buffers; every algorithm takes `(model, workspace, inputs…)`,
//! writes into the workspace and allocates nothing.
//!
//! Conventions (the README's "Conventions" has them in full): SI units; spatial vectors are
//! `[angular; linear]`, a motion `[ω; v]` with `v` the velocity of the point at the frame's
//! origin, a force `[n; f]` with `n` the moment about it. Per-body quantities (velocities,
//! accelerations, [`Externals::wrenches`], placements) are in **body frames**: a body's frame has
//! its URDF link's origin and the link's axes, or those axes turned by quarter turns where that
//! takes the rotation out of the joint's placement; links joined by fixed joints fuse into one
//! body, and [`Model::link`] gives each link's [`LinkFrame`](model::LinkFrame), its placement in
//! its body's frame. `q` and `v` follow [`Model::coordinate_joints`]; a floating joint has
//! `q = [x y z qx qy qz qw]` (position in the world, unit quaternion x, y, z, w) and
//! `v = [linear; angular]` in the base frame. Gravity is a model setting in world coordinates.
//!
//! "The handout" cited in these docs is the course handout *Forward Dynamics with Spatial
//! Vectors* (after Featherstone, *Robot Dynamics Algorithms*, Kluwer 1987): its eqs. 13–16 are
//! RNEA in spatial vectors, eq. 21 gravity as an upward acceleration of the world, §3.1 the
//! particle example, Appendices A and B the spatial terms and operators (the README says more).

// One `unsafe` block, in `instruction_set`: the call into passes compiled for AVX2, made only
// once the processor has been found to run them.
#![deny(unsafe_code)]

pub mod algorithms;
pub mod double_double;
pub mod error;
pub mod instruction_set;
pub mod model;
pub(crate) mod mul_add;
pub(crate) mod plan;
pub mod requests;
pub mod sampling;
pub mod sim;
pub mod spatial;
#[cfg(test)]
mod test_models;
pub mod urdf;
mod workspace;

pub use algorithms::{Externals, ForwardDynamicsMethod};
pub use error::{DynamicsError, ModelError};
pub use instruction_set::InstructionSet;
pub use model::{Model, ModelOptions};
/// The FLOP model the plan chooses by, public for the benchmarks: `flops` prices each spatial
/// operation, `flop_table::kernel_flops(model, name)` counts a kernel on a model.
pub use plan::{flop_table, flops};
pub use workspace::Workspace;

/// The README's and docs/library.md's Rust examples, compiled by `cargo test --doc` so that they
/// keep to the library's interface.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
#[doc = include_str!("../../docs/library.md")]
struct DocumentationExamples;
