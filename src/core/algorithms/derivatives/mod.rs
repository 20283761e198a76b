//! Analytical derivatives of the dynamics (Carpentier & Mansard, "Analytical derivatives of
//! rigid body dynamics algorithms", RSS 2018): [`rnea_derivatives`] gives `∂τ/∂q`, `∂τ/∂q̇` and
//! `H = ∂τ/∂q̈` of inverse dynamics, [`aba_derivatives`] gives `∂q̈/∂q`, `∂q̈/∂q̇` and
//! `H⁻¹ = ∂q̈/∂τ` of forward dynamics; [`linearize`] assembles them into the state-space `A`, `B`
//! of `x = [q; q̇]`, `u = τ`, in continuous time or over one simulator step, with the Jacobians
//! of `⊕` ([`integrate_jacobians`]) for a floating base.
//!
//! # Tangent convention
//!
//! Column `k` of a derivative with respect to `q` is `d/dε f(q ⊕ ε e_k)` at `ε = 0`, with `⊕`
//! [`Model::integrate`](crate::Model::integrate) and `e_k` the `k`-th velocity coordinate: a
//! revolute, continuous or prismatic joint moves by `ε` along its coordinate, a floating base
//! by the twist `ε e_k` in its own body frame (linear coordinates first, then angular, as `v` is
//! ordered: Pinocchio's `integrate` to first order), a planar joint by `ε` on `x`, `y` or `θ`
//! (its `v` is `q̇`). A mimic follower moves with its leader, `q_f = μ q_l + o`: the follower's
//! columns are `μ` times its own and add into its leader's row and column (the chain rule).
//! Every matrix is full (not a triangle), row `i` the `i`-th component of `τ` or `q̈`, columns
//! in `v` order.

mod aba_derivatives;
mod branch_products;
mod integrate_jacobians;
mod linearize;
mod rnea_derivatives;
mod velocity_product;

pub use aba_derivatives::{aba_derivatives, AbaDerivatives};
pub use integrate_jacobians::integrate_jacobians;
pub use linearize::{linearize, linearize_with_passive, Linearization};
pub use rnea_derivatives::{rnea_derivatives, rnea_derivatives_with, RneaDerivatives};

use crate::model::Model;
use crate::spatial::{Force, Inertia, Motion};
use nalgebra::DMatrix;
use velocity_product::VelocityProduct;

/// Scratch of the derivative algorithms, sized once from the model. Per body `i` and joint
/// column `k` (the column scaled by a mimic follower's multiplier), in the aligned frame of `i`'s
/// tree (world axes, origin at the root body's origin, see
/// `kinematics::update_aligned_placements`).
#[derive(Clone, Debug)]
pub(crate) struct DerivativeScratch {
    /// `ψ_ik = v_λ × S_ik`: how the velocity of every body below moves, besides being carried
    /// along, when column `k` of joint `i` turns (`∂v/∂q`, Pinocchio's `dVdq`).
    pub(crate) psi: Vec<[Motion; 6]>,
    /// `α_ik = a_λ × S_ik + v_λ × ψ_ik`: the same for accelerations (`∂a/∂q`, `dAdq`).
    pub(crate) alpha: Vec<[Motion; 6]>,
    /// `β_ik = ψ_ik + v' × S_ik`: how the acceleration of every body below changes with the
    /// rate `q̇_ik`, besides `S_ik ×` its velocity (`∂a/∂q̇`, `dAdv`).
    pub(crate) beta: Vec<[Motion; 6]>,
    /// `B_i`, then its sum over the subtree `B^C_i`: the velocity-product matrix of the body
    /// forces (`∂f/∂v` through the velocity-dependent terms), in its sparse form.
    pub(crate) b: Vec<VelocityProduct>,
    /// `f⁰_i`, the force of body `i` at the bias acceleration `a⁰_i` (`q̈ = 0`), then its sum
    /// over the subtree `F⁰_i` (`aba_derivatives`' bias pass).
    pub(crate) f_bias: Vec<Force>,
    /// `I_i`, then its sum over the subtree `I^C_i` (`aba_derivatives`' bias pass; the body's
    /// own `I_i` stays in `Workspace::ic` for its forces).
    pub(crate) composite: Vec<Inertia>,
    /// `∂τ/∂q` (nv × nv). Only `rnea_derivatives` writes it, and only on the tree's pattern
    /// (row and column on one branch): the entries off it stay zero from allocation on.
    pub(crate) dtau_dq: DMatrix<f64>,
    /// `∂τ/∂q̇` (nv × nv), written as `∂τ/∂q`.
    pub(crate) dtau_dv: DMatrix<f64>,
    /// `∂q̈/∂q` (nv × nv).
    pub(crate) ddq_dq: DMatrix<f64>,
    /// `∂q̈/∂q̇` (nv × nv).
    pub(crate) ddq_dv: DMatrix<f64>,
    /// `H⁻¹ = ∂q̈/∂τ` (nv × nv).
    pub(crate) minv: DMatrix<f64>,
    /// `aba_derivatives`' right-hand sides: on a tree `−∂τ/∂q`, `−∂τ/∂q̇` by column (`2 nv²`
    /// entries, each pair `(−∂τ_r/∂q_c, −∂τ_r/∂q̇_c)` at `2 (nv c + r)`), then the rows of
    /// `L⁻ᵀ` (`nv²`, zero off each row's subtree from allocation on); with mimic joints
    /// `[1 | −∂τ/∂q | −∂τ/∂q̇]` row by row (`nv` rows of `3 nv`), then the solutions.
    pub(crate) rhs: Vec<f64>,
    /// Per body: its six columns are a floating joint's in halves, the first three purely
    /// linear and the last three purely angular (a tree's root, whose aligned frame has its
    /// origin: `S = diag(R, R)` up to the order of the halves).
    pub(crate) halves: Vec<bool>,
}

impl DerivativeScratch {
    pub(crate) fn new(model: &Model) -> Self {
        let (n, nv) = (model.nbodies(), model.nv);
        // From zeroed allocations, as `Workspace::mass_matrix`: untouched pages cost nothing.
        let square = || DMatrix::from_vec(nv, nv, vec![0.0; nv * nv]);
        DerivativeScratch {
            psi: vec![[Motion::zero(); 6]; n],
            alpha: vec![[Motion::zero(); 6]; n],
            beta: vec![[Motion::zero(); 6]; n],
            b: vec![VelocityProduct::zero(); n],
            f_bias: vec![Force::zero(); n],
            composite: vec![Inertia::zero(); n],
            dtau_dq: square(),
            dtau_dv: square(),
            ddq_dq: square(),
            ddq_dv: square(),
            minv: square(),
            rhs: vec![0.0; 3 * nv * nv],
            halves: vec![false; n],
        }
    }
}
