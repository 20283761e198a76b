//! The generalized gravity forces `g(q) = RNEA(q, 0, 0)`: the efforts that hold the robot
//! still against gravity (gravity compensation).

use super::kinematics::update_joints;
use super::rnea::rnea_passes;
use super::validate::{check_q, check_result};
use super::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;

/// `g(q)` into `ws.tau()`.
pub fn gravity<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w [f64], DynamicsError> {
    check_q(model, q)?;
    update_joints(model, ws, q);
    rnea_passes(model, ws, None, None, &Externals::none());
    check_result(model, "gravity", ws.tau.as_slice())?;
    Ok(ws.tau.as_slice())
}
