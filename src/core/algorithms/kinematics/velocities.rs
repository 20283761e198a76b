//! Body spatial velocities, `v_i = ⁱX_λ v_λ + S_i q̇_i`, and the placements and velocities of
//! every body at one state.

use super::joints::update_joints;
use super::placements::{check_bodies, check_placements, update_placements};
use crate::algorithms::validate::{check_q, check_v};
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Motion;
use crate::Workspace;

/// Body spatial velocities `v_i = ⁱX_λ v_λ + S_i q̇_i` into `ws.v` (joints already updated; base
/// at rest).
#[inline]
pub(crate) fn update_velocities(model: &Model, ws: &mut Workspace, v: &[f64]) {
    for (i, body) in model.bodies.iter().enumerate() {
        let c = body.joint.coords;
        let v_joint = ws.s[i].apply(&v[c.v_index..c.v_index + ws.s[i].nv], c.scale);
        let v_parent = body.parent.map_or(Motion::zero(), |p| ws.v[p]);
        ws.v[i] = ws.x_up[i].apply_motion(&v_parent) + v_joint;
    }
}

/// Placements `ⁱX_0` and velocities of every body at `(q, v)`, into the workspace (see
/// [`Workspace::body_velocity`] and [`body_placements`](super::body_placements)).
pub fn body_motion(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(), DynamicsError> {
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    update_joints(model, ws, q);
    update_placements(model, ws);
    update_velocities(model, ws, v);
    check_placements(model, ws)?;
    check_bodies(model, "velocity", |i| {
        ws.v[i]
            .ang
            .iter()
            .chain(ws.v[i].lin.iter())
            .all(|e| e.is_finite())
    })
}
