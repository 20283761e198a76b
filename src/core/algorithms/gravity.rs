//! The generalized gravity forces `g(q) = RNEA(q, 0, 0)`: the efforts that hold the robot
//! still against gravity (gravity compensation).
//!
//! RNEA (handout eqs. 13–16) with `q̇ = 0`, `q̈ = 0` and the root's `a_0 = [0; −g]`: every
//! velocity is zero, so every acceleration is a pure translation `a_i = [0; a_i^lin]`, and the
//! passes shrink to (body `i` coordinates)
//!
//! ```text
//! outward:  a_i^lin = E_i a_λ^lin                  (ⁱX_λ [0; a] = [0; E a])
//!           f_i = I_i [0; a_i^lin] = [h_i × a_i^lin; m_i a_i^lin]
//! inward:   τ_i = S_iᵀ f_i,   f_λ += ⁱX_λᵀ f_i
//! ```
//!
//! Only `ws.f` and `ws.tau` are written here (the force and effort outputs of the other RNEA
//! passes); `ws.a` keeps the pure translations.

use super::kinematics::update_joints;
use super::rnea::inward_pass;
use super::validate::{check_q, check_result};
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::{Force, Motion};
use crate::Workspace;

/// `g(q)` into `ws.tau()`.
pub fn gravity<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w [f64], DynamicsError> {
    check_q(model, ws, q)?;
    update_joints(model, ws, q);
    gravity_passes(model, ws);
    check_result(model, "gravity", ws.tau.as_slice())?;
    Ok(ws.tau.as_slice())
}

/// The two passes, on joints already updated for `q`. Writes `ws.v` (zero), `ws.a`, `ws.f`
/// and `ws.tau`.
pub(crate) fn gravity_passes(model: &Model, ws: &mut Workspace) {
    let a_root = -model.gravity;
    for (i, body) in model.bodies.iter().enumerate() {
        let a_parent = body.parent.map_or(a_root, |p| ws.a[p].lin);
        let a_i = ws.x_up[i].rot * a_parent;
        let inertia = &body.inertia;
        ws.v[i] = Motion::zero();
        ws.a[i] = Motion::new(nalgebra::Vector3::zeros(), a_i);
        ws.f[i] = Force::new(inertia.h.cross(&a_i), a_i * inertia.mass);
    }
    inward_pass(model, ws);
}
