//! The dynamics algorithms, all of the form `f(model, workspace, inputs…)`: a file each, and
//! CRBA a folder (its passes, the rows they write and the tiled mirror of `H`).
//!
//! | module | computes |
//! |---|---|
//! | [`rnea`](mod@rnea) | inverse dynamics `τ = H(q) q̈ + C(q, q̇)` (recursive Newton–Euler) |
//! | [`lanes`] | inverse dynamics of many states at once ([`rnea_rows`]), several in the lanes of each instruction |
//! | [`bias`](mod@bias) | `C(q, q̇)`: gravity, Coriolis and centrifugal terms, external forces |
//! | [`gravity`](mod@gravity) | `g(q)`: the gravity part of `C` |
//! | [`crba`](mod@crba) | `H(q)` (composite rigid-body algorithm) |
//! | [`aba`](mod@aba) | forward dynamics in O(n) (articulated-body algorithm) |
//! | [`derivatives`] | `∂τ/∂q`, `∂τ/∂q̇` of inverse dynamics and `∂q̈/∂q`, `∂q̈/∂q̇`, `H⁻¹` of forward dynamics; the linearised `A`, `B` |
//! | [`rnea_columns`] | forward dynamics from n+1 inverse-dynamics calls (the handout's §2) |
//! | [`forward_dynamics`](mod@forward_dynamics) | forward dynamics by a chosen [`ForwardDynamicsMethod`] |
//! | [`method_choice`] | `method: auto`: of the methods whose `q̈` agrees with `aba`'s on sampled states, the one with the fewest FLOPs per call on this model (a count, not a timing) |
//! | [`joint_state_outputs`](mod@joint_state_outputs) | `g(q)`, `FD(q, q̇, τ)` and `RNEA(q, q̇, q̈)` at one state, sharing the kinematics |
//! | [`energy`](mod@energy) | kinetic and potential energy |
//! | [`kinematics`] | joint transforms, body placements and velocities: the passes the others share |
//! | [`frames`] | link frames ([`find_frame`]) and their placement in the world |
//! | [`jacobian`] | frame Jacobians in three references, one frame or many ([`joint_jacobians`]) |
//! | [`frame_acceleration`] | a link frame's classical acceleration |
//! | [`center_of_mass`](mod@center_of_mass) | centre of mass, total mass and the centre-of-mass Jacobian |
//! | [`ltl`], [`cholesky`] | the factorisations that solve `H q̈ = τ − C` |

// The algorithms index per-coordinate arrays the way the equations do.
#![allow(clippy::needless_range_loop)]

pub mod aba;
pub mod bias;
pub mod center_of_mass;
pub mod cholesky;
pub mod crba;
pub mod derivatives;
pub mod energy;
pub mod forward_dynamics;
pub mod frame_acceleration;
pub mod frames;
pub mod gravity;
pub mod jacobian;
pub mod joint_state_outputs;
pub mod kinematics;
pub mod lanes;
pub mod ltl;
pub mod method_choice;
pub mod rnea;
pub mod rnea_columns;
pub(crate) mod validate;

pub use aba::aba;
pub use bias::bias;
pub use center_of_mass::{center_of_mass, center_of_mass_jacobian, CenterOfMass};
pub use crba::crba;
pub use derivatives::{
    aba_derivatives, integrate_jacobians, linearize, linearize_with_passive, rnea_derivatives,
    rnea_derivatives_with, AbaDerivatives, Linearization, RneaDerivatives,
};
pub use energy::energy;
pub use forward_dynamics::{forward_dynamics, ForwardDynamicsMethod};
pub use frame_acceleration::frame_classical_acceleration;
pub use frames::{find_frame, frame_placement, Frame};
pub use gravity::gravity;
pub use jacobian::{frame_jacobian, joint_jacobians, JointJacobians, ReferenceFrame};
pub use joint_state_outputs::{joint_state_outputs, JointStateInputs, JointStateOutputs};
pub use lanes::rnea_rows;
pub use method_choice::{choose_method, MethodChoice};
pub use rnea::{rnea, rnea_with};

use crate::spatial::{Force, Motion};

/// What acts on the tree besides the joint forces.
#[derive(Clone, Copy, Debug, Default)]
pub struct Externals<'a> {
    /// External wrench on each body (one per body, in model body order), expressed in that
    /// body's own frame (about the body frame origin; a wrench `f` in the frame of a link `l`
    /// on the body is `l.x_body_link.transpose_apply_force(&f)` there, see
    /// [`LinkFrame`](crate::model::LinkFrame)). `None`: no external forces.
    pub wrenches: Option<&'a [Force]>,
    /// Spatial velocity of the root (world) frame, in root coordinates. Zero for a base fixed in
    /// an inertial frame.
    pub root_velocity: Motion,
    /// Spatial acceleration of the root frame, in root coordinates, not counting gravity.
    pub root_acceleration: Motion,
}

/// A factorisation pivot is sound when it is finite and positive and has kept some digits
/// relative to `reference` (the diagonal entry or scale it came from): a pivot at or below
/// `reference · ε` means the matrix is singular, indefinite or numerically so.
pub(crate) fn pivot_is_sound(pivot: f64, reference: f64) -> bool {
    pivot.is_finite() && pivot > reference * f64::EPSILON
}

impl Externals<'_> {
    /// No external wrench, base at rest in an inertial frame.
    pub fn none() -> Self {
        Self::default()
    }
}
