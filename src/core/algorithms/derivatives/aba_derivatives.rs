//! `∂q̈/∂q`, `∂q̈/∂q̇` and `H⁻¹ = ∂q̈/∂τ` of `q̈ = FD(q, q̇, τ)` (Carpentier & Mansard, RSS 2018,
//! section IV): `τ = ID(q, q̇, FD(q, q̇, τ))` for every state, so differentiating both sides at
//! `q̈ = FD(q, q̇, τ)` gives, exactly,
//!
//! ```text
//! ∂q̈/∂q = −H⁻¹ ∂τ/∂q,   ∂q̈/∂q̇ = −H⁻¹ ∂τ/∂q̇,   ∂q̈/∂τ = H⁻¹
//! ```
//!
//! with `∂τ/∂q`, `∂τ/∂q̇` from [`rnea_derivatives`](super::rnea_derivatives) at `(q, q̇, q̈)`.
//! `q̈` comes from `H q̈ = τ − C` (`H` by CRBA, factored as `LᵀL` along the tree or by Cholesky
//! with mimic joints) and `H⁻¹` from that factor, one solve per column.

use super::rnea_derivatives::{check_matrix, derivative_passes};
use crate::algorithms::cholesky::cholesky_solve;
use crate::algorithms::forward_dynamics::crba_solve_on_joints;
use crate::algorithms::kinematics::update_joints;
use crate::algorithms::ltl::ltl_solve;
use crate::algorithms::validate::check_forward_inputs;
use crate::algorithms::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;
use nalgebra::{DMatrix, DVector};

/// The derivatives of forward dynamics at one state, held in the workspace: `nv × nv`, full,
/// row `i` the derivative of `q̈_i`, columns in `v` order, on the tangent of
/// [the module](super) (`q ⊕ ε e_k`).
#[derive(Clone, Copy, Debug)]
pub struct AbaDerivatives<'w> {
    /// `∂q̈/∂q`.
    pub ddq_dq: &'w DMatrix<f64>,
    /// `∂q̈/∂q̇`.
    pub ddq_dv: &'w DMatrix<f64>,
    /// `H⁻¹ = ∂q̈/∂τ`.
    pub minv: &'w DMatrix<f64>,
}

/// The derivatives of `q̈ = FD(q, q̇, τ)` with external wrenches and base motion as
/// [`aba`](crate::algorithms::aba()) takes them. `q̈` itself is left in `ws.qdd()`. Models with
/// mimic joints are supported (`q̈` by CRBA and a dense Cholesky factor).
pub fn aba_derivatives<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<AbaDerivatives<'w>, DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    update_joints(model, ws, q);
    crba_solve_on_joints(model, ws, v, tau, ext)?;
    inverse_from_factor(ws);
    // The passes read q̈ while they write the workspace: lend it out (an empty vector holds no
    // allocation) and put it back.
    let qdd = std::mem::replace(&mut ws.qdd, DVector::zeros(0));
    derivative_passes(model, ws, v, qdd.as_slice(), ext);
    ws.qdd = qdd;
    let d = &mut ws.derivatives;
    times_minus_minv(&d.minv, &d.dtau_dq, &mut d.ddq_dq);
    times_minus_minv(&d.minv, &d.dtau_dv, &mut d.ddq_dv);
    check_matrix(model, "ddq_dq", &d.ddq_dq)?;
    check_matrix(model, "ddq_dv", &d.ddq_dv)?;
    check_matrix(model, "Minv", &d.minv)?;
    Ok(AbaDerivatives {
        ddq_dq: &ws.derivatives.ddq_dq,
        ddq_dv: &ws.derivatives.ddq_dv,
        minv: &ws.derivatives.minv,
    })
}

/// `H⁻¹` into `ws.derivatives.minv`, column `k` solving `H x = e_k` with the factor
/// `crba_solve_on_joints` left in `ws.factor`.
fn inverse_from_factor(ws: &mut Workspace) {
    let (plan, factor, d) = (&ws.plan, &ws.factor, &mut ws.derivatives);
    for k in 0..d.minv.ncols() {
        d.column.fill(0.0);
        d.column[k] = 1.0;
        match &plan.dof_ancestors {
            Some(ancestors) => ltl_solve(ancestors, factor, &mut d.column),
            None => cholesky_solve(factor, &mut d.column),
        }
        d.minv.set_column(k, &d.column);
    }
}

/// `out = −H⁻¹ x`, column by column (a matrix-vector product each: `gemm` on dynamic matrices
/// allocates its packing buffers).
fn times_minus_minv(minv: &DMatrix<f64>, x: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    for (mut out, x) in out.column_iter_mut().zip(x.column_iter()) {
        out.gemv(-1.0, minv, &x, 0.0);
    }
}
