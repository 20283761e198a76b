//! Mechanical energy: kinetic `T = Σ ½ v_iᵀ I_i v_i` (= ½ q̇ᵀ H q̇) and potential
//! `V = −Σ m_i gᵀ c_i` (centres of mass in the world), with the model's gravity.

use super::kinematics::{update_joints, update_placements, update_velocities};
use super::validate::{check_q, check_v};
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;

/// `(T, V)` at `(q, v)`, in joules; the base is at rest in the world.
pub fn energy(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(f64, f64), DynamicsError> {
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    update_joints(model, ws, q);
    update_placements(model, ws);
    update_velocities(model, ws, v);
    let (mut kinetic, mut potential) = (0.0, 0.0);
    for (i, body) in model.bodies.iter().enumerate() {
        kinetic += 0.5 * ws.v[i].dot(&body.inertia.apply(&ws.v[i]));
        // Centre of mass in the world: r + Eᵀ c (E: world → body rotation, r: body origin).
        let x = &ws.x_world[i];
        let com_world = x.trans + x.rot.tr_mul(&body.inertia.com());
        potential -= body.inertia.mass * model.gravity.dot(&com_world);
        // Finite inputs can still overflow (½ m v² at v = 1e200).
        for (quantity, value) in [("kinetic energy", kinetic), ("potential energy", potential)] {
            if !value.is_finite() {
                return Err(DynamicsError::NonFiniteResult {
                    quantity,
                    coordinate: body.joint.name.clone(),
                });
            }
        }
    }
    Ok((kinetic, potential))
}
