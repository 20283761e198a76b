//! Forward dynamics `q̈ = H(q)⁻¹ (τ − C(q, q̇))` by a selectable method.
//!
//! | method | how | cost |
//! |---|---|---|
//! | `aba` | articulated-body algorithm | O(n) |
//! | `crba` | `C` by RNEA, `H` by CRBA, sparse `LᵀL` (dense Cholesky with mimic joints) | O(n d²) |
//! | `rnea_columns` | `C` and each column of `H` by RNEA, dense Cholesky (the handout) | O(n²) + O(n³) |

use super::cholesky::{cholesky_factor, cholesky_solve};
use super::crba::crba_passes;
use super::kinematics::update_joints;
use super::ltl::{ltl_factor, ltl_solve};
use super::rnea::rnea_passes;
use super::validate::{all_finite, check_forward_inputs, check_result};
use super::{aba, rnea_columns, Externals};
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;
use std::fmt;
use std::str::FromStr;

/// How forward dynamics is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ForwardDynamicsMethod {
    /// Articulated-body algorithm.
    Aba,
    /// Composite rigid-body algorithm and a sparse factorisation.
    Crba,
    /// n+1 inverse-dynamics calls and a dense factorisation.
    RneaColumns,
}

impl ForwardDynamicsMethod {
    /// Every method, in a fixed order.
    pub const ALL: [ForwardDynamicsMethod; 3] = [Self::Aba, Self::Crba, Self::RneaColumns];

    /// The method's name on the command line and in messages.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Aba => "aba",
            Self::Crba => "crba",
            Self::RneaColumns => "rnea_columns",
        }
    }
}

impl fmt::Display for ForwardDynamicsMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ForwardDynamicsMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                format!("unknown forward-dynamics method '{s}' (use aba, crba or rnea_columns)")
            })
    }
}

/// `q̈ = FD(q, q̇, τ)` by `method`, into `ws.qdd()`.
pub fn forward_dynamics<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    method: ForwardDynamicsMethod,
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    match method {
        ForwardDynamicsMethod::Aba => aba::aba(model, ws, q, v, tau, ext),
        ForwardDynamicsMethod::Crba => crba_solve(model, ws, q, v, tau, ext),
        ForwardDynamicsMethod::RneaColumns => rnea_columns::rnea_columns(model, ws, q, v, tau, ext),
    }
}

/// [`forward_dynamics`] for a caller that has established the inputs' shapes: `ws` was made for
/// `model`; `q`, `v`, `τ` have the model's lengths and every floating joint's quaternion in `q`
/// is not (near) zero; the root motion is finite and the wrenches, if any, one per body; with
/// `aba`, the model has no mimic joint. The values' finiteness is tested in one branch-free pass
/// (when it fails, the checks of [`forward_dynamics`] name the first bad value); the result is
/// checked.
pub(crate) fn forward_dynamics_on_checked_shapes<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    method: ForwardDynamicsMethod,
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    let wrenches_finite = ext.wrenches.is_none_or(|w| w.iter().all(|f| f.is_finite()));
    if !(all_finite(q) & all_finite(v) & all_finite(tau) & wrenches_finite) {
        check_forward_inputs(model, ws, q, v, tau, ext)?;
    }
    match method {
        ForwardDynamicsMethod::Aba => aba::aba_on_checked_inputs(model, ws, q, v, tau, ext),
        // The other methods keep their input checks, a few per cent of their work.
        ForwardDynamicsMethod::Crba => crba_solve(model, ws, q, v, tau, ext),
        ForwardDynamicsMethod::RneaColumns => rnea_columns::rnea_columns(model, ws, q, v, tau, ext),
    }
}

/// `C` by RNEA, `H` by CRBA (both from one set of joint transforms), then `H q̈ = τ − C` by the
/// tree-sparse `LᵀL` (or dense Cholesky when mimic joints break the tree pattern).
fn crba_solve<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    update_joints(model, ws, q);
    crba_solve_on_joints(model, ws, v, tau, ext)
}

/// [`crba_solve`] on joints already updated for `q` (inputs already checked).
pub(crate) fn crba_solve_on_joints<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    rnea_passes(model, ws, Some(v), None, ext);
    // A non-finite H fails the factorisation or shows in q̈ (checked below).
    crba_passes(model, ws);
    ws.qdd.copy_from_slice(tau);
    ws.qdd -= &ws.tau;
    match &ws.plan.dof_ancestors {
        Some(ancestors) => {
            ltl_factor(model, ancestors, &ws.mass_matrix, &mut ws.factor)?;
            ltl_solve(ancestors, &ws.factor, &mut ws.qdd);
        }
        None => {
            cholesky_factor(model, &ws.mass_matrix, &mut ws.factor)?;
            cholesky_solve(&ws.factor, &mut ws.qdd);
        }
    }
    check_result(model, "acceleration", ws.qdd.as_slice())?;
    Ok(ws.qdd.as_slice())
}
