//! The bias forces `C(q, q̇) = RNEA(q, q̇, 0)` (handout eq. 9): gravity, Coriolis and
//! centrifugal forces and the effect of external wrenches, so that `τ = H q̈ + C`.

use super::kinematics::update_joints;
use super::rnea::rnea_passes;
use super::validate::{check_externals, check_q, check_result, check_v};
use super::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;

/// `C(q, q̇)` into `ws.tau()`.
pub fn bias<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    check_externals(model, ext)?;
    update_joints(model, ws, q);
    rnea_passes(model, ws, Some(v), None, ext);
    check_result(model, "bias", ws.tau.as_slice())?;
    Ok(ws.tau.as_slice())
}
