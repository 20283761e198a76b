//! Mechanical energy: kinetic `T = Σ ½ v_iᵀ I_i v_i` (= ½ q̇ᵀ H q̇) and potential
//! `V = −Σ m_i gᵀ c_i` (centres of mass in the world), with the model's gravity.

use super::kinematics::{update_joints, update_placements, update_velocities};
use super::validate::{check_q, check_v};
use crate::error::DynamicsError;
use crate::instruction_set::run_pass;
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
    energy_of_checked(model, ws, q, v)
}

/// [`energy`] for a caller that has checked `q` and `v` as it does: `ws` made for `model`,
/// the model's sizes, finite values, every floating joint's quaternion not (near) zero. The
/// sums are checked once at the end: a non-finite term keeps them non-finite.
pub(crate) fn energy_of_checked(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(f64, f64), DynamicsError> {
    run_pass!(energy_of_checked_in(model, ws, q, v))
}

/// [`energy_of_checked`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn energy_of_checked_in(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(f64, f64), DynamicsError> {
    update_joints(model, ws, q);
    update_placements(model, ws);
    update_velocities(model, ws, v);
    let (mut kinetic, mut potential) = (0.0, 0.0);
    for i in 0..model.bodies.len() {
        let (t, u) = body_energy(model, ws, i);
        kinetic += t;
        potential += u;
    }
    if kinetic.is_finite() && potential.is_finite() {
        Ok((kinetic, potential))
    } else {
        Err(first_non_finite(model, ws))
    }
}

/// Body `i`'s `(½ v_iᵀ I_i v_i, −m_i gᵀ c_i)` from the placements and velocities in `ws`.
#[inline(always)]
fn body_energy(model: &Model, ws: &Workspace, i: usize) -> (f64, f64) {
    let body = &model.bodies[i];
    let kinetic = 0.5 * ws.v[i].dot(&body.inertia.apply(&ws.v[i]));
    // Centre of mass in the world: r + Eᵀ c (E: world → body rotation, r: body origin).
    let x = &ws.x_world[i];
    let com_world = x.trans + x.rot.tr_mul(&body.inertia.com());
    (kinetic, -body.inertia.mass * model.gravity.dot(&com_world))
}

/// The error for finite inputs whose energy overflows (½ m v² at v = 1e200), naming the joint
/// of the first body at which a partial sum stops being finite.
#[cold]
fn first_non_finite(model: &Model, ws: &Workspace) -> DynamicsError {
    let (mut kinetic, mut potential) = (0.0, 0.0);
    for (i, body) in model.bodies.iter().enumerate() {
        let (t, u) = body_energy(model, ws, i);
        kinetic += t;
        potential += u;
        for (quantity, value) in [("kinetic energy", kinetic), ("potential energy", potential)] {
            if !value.is_finite() {
                return DynamicsError::NonFiniteResult {
                    quantity,
                    coordinate: body.joint.name.clone(),
                };
            }
        }
    }
    // Not reached: the same sums, in the same order, are not finite.
    let last = model
        .bodies
        .last()
        .map_or(String::new(), |b| b.joint.name.clone());
    DynamicsError::NonFiniteResult {
        quantity: "energy",
        coordinate: last,
    }
}
