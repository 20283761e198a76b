//! Forward dynamics from n+1 inverse-dynamics calls (the handout's §2, after Walker and Orin):
//!
//! ```text
//! C   = RNEA(q, q̇, 0)                 (9)
//! H_k = RNEA(q, q̇, e_k) − C           (11), for each coordinate k
//! H q̈ = τ − C                          (6), solved by Cholesky
//! ```
//!
//! Each RNEA call is a complete inverse-dynamics evaluation, as the method prescribes, so it costs
//! O(n²) and serves as the reference the faster methods are measured against.

use super::cholesky::{cholesky_factor, cholesky_solve};
use super::kinematics::update_joints;
use super::rnea::rnea_passes;
use super::validate::{check_forward_inputs, check_result};
use super::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;

/// `q̈ = FD(q, q̇, τ)` into `ws.qdd()`; leaves `H` in `ws.mass_matrix()`.
pub fn rnea_columns<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    inverse_dynamics(model, ws, q, v, None, ext);
    ws.bias.copy_from(&ws.tau);
    ws.unit.fill(0.0);
    for k in 0..model.nv {
        ws.unit[k] = 1.0;
        let unit = std::mem::take(&mut ws.unit);
        inverse_dynamics(model, ws, q, v, Some(unit.as_slice()), ext);
        ws.unit = unit;
        ws.unit[k] = 0.0;
        for r in 0..model.nv {
            ws.mass_matrix[(r, k)] = ws.tau[r] - ws.bias[r];
        }
    }
    cholesky_factor(model, &ws.mass_matrix, &mut ws.factor)?;
    ws.qdd.copy_from_slice(tau);
    ws.qdd -= &ws.bias;
    cholesky_solve(&ws.factor, &mut ws.qdd);
    check_result(model, "acceleration", ws.qdd.as_slice())?;
    Ok(ws.qdd.as_slice())
}

/// One complete RNEA call on validated inputs (joint transforms included).
fn inverse_dynamics(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
    a: Option<&[f64]>,
    ext: &Externals<'_>,
) {
    update_joints(model, ws, q);
    rnea_passes(model, ws, Some(v), a, ext);
}
