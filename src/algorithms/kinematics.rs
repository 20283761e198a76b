//! The position-dependent part shared by every algorithm: joint transforms and motion
//! subspaces (`jcalc` for each joint, then `ⁱX_λ(i) = X_J X_tree`).

use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::{Joint, Model};
use crate::spatial::{Motion, Transform};
use crate::Workspace;

/// Fills `ws.q_joint`, `ws.x_up` and `ws.s` for configuration `q` (already validated).
pub(crate) fn update_joints(model: &Model, ws: &mut Workspace, q: &[f64]) {
    for (i, body) in model.bodies.iter().enumerate() {
        let nq = body.joint.kind.nq();
        joint_positions(&body.joint, q, &mut ws.q_joint[i]);
        ws.x_up[i] = body
            .joint
            .kind
            .jcalc_up(&ws.q_joint[i][..nq], &body.x_tree, &mut ws.s[i]);
    }
}

/// The joint's own coordinates `scale · q[q_index..] + offset` (a mimic follower reads its
/// leader's coordinate; for every other joint scale is 1 and offset 0).
fn joint_positions(joint: &Joint, q: &[f64], out: &mut [f64; 7]) {
    let c = joint.coords;
    let nq = joint.kind.nq();
    for (o, x) in out[..nq].iter_mut().zip(&q[c.q_index..c.q_index + nq]) {
        *o = c.scale * x + c.offset;
    }
}

/// Placement of every body in the root (world) frame, `ⁱX_0` (world coordinates → body
/// coordinates), for configuration `q`: `ⁱX_0 = ⁱX_λ ᵏX_0`. One per body, in model order.
pub fn body_placements<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w [Transform], DynamicsError> {
    check_q(model, q)?;
    update_joints(model, ws, q);
    update_placements(model, ws);
    check_bodies(model, "placement", |i| {
        let x = &ws.x_world[i];
        x.rot.iter().chain(x.trans.iter()).all(|e| e.is_finite())
    })?;
    Ok(&ws.x_world)
}

/// An error naming the joint of the first body for which `finite` is false: finite inputs can
/// still overflow (origins of 1e308 added up, velocities of 1e200 multiplied).
fn check_bodies(
    model: &Model,
    quantity: &'static str,
    finite: impl Fn(usize) -> bool,
) -> Result<(), DynamicsError> {
    match (0..model.nbodies()).find(|&i| !finite(i)) {
        Some(i) => Err(DynamicsError::NonFiniteResult {
            quantity,
            coordinate: model.bodies[i].joint.name.clone(),
        }),
        None => Ok(()),
    }
}

/// `ws.x_world` from `ws.x_up` (joints already updated): `ⁱX_0 = ⁱX_λ ᵏX_0`.
pub(crate) fn update_placements(model: &Model, ws: &mut Workspace) {
    compose_down(model, &ws.x_up, &mut ws.x_world, |x_root| *x_root);
}

/// `ws.x_aligned` from `ws.x_up` (joints already updated): `ⁱX_R`, from the *root-aligned*
/// frame `R` of body `i`'s tree to body `i`. `R` has the world's axes and its origin at the
/// origin of the tree's root body `r`: `ʳX_R = rot(E_r)` (the root's placement without its
/// translation), then `ⁱX_R = ⁱX_λ ᵏX_R`.
///
/// The passes that work in "world coordinates" (ABA, CRBA's world rows, `joint_state_outputs`)
/// work in `R`. A translation of the frame changes none of `H`, `τ`, `q̈` (gravity `[0; g]` is
/// the same about every point), but a spatial inertia about a point `d` away from the body
/// carries `m d²` terms that cancel in them: about the world origin, a robot a kilometre
/// away would lose seven digits. Motions given about the world origin (the root's velocity
/// and acceleration) move to `R` by [`Motion::about`].
pub(crate) fn update_aligned_placements(model: &Model, ws: &mut Workspace) {
    compose_down(model, &ws.x_up, &mut ws.x_aligned, |x_root| {
        Transform::rotation(x_root.rot)
    });
}

/// `out[i] = x_up[i] out[λ(i)]` from the root down, `out[r] = root(x_up[r])` for each root `r`.
fn compose_down(
    model: &Model,
    x_up: &[Transform],
    out: &mut [Transform],
    root: impl Fn(&Transform) -> Transform,
) {
    for (i, body) in model.bodies.iter().enumerate() {
        out[i] = match body.parent {
            Some(p) => x_up[i].compose(&out[p]),
            None => root(&x_up[i]),
        };
    }
}

/// Body spatial velocities `v_i = ⁱX_λ v_λ + S_i q̇_i` into `ws.v` (joints already updated; base
/// at rest).
pub(crate) fn update_velocities(model: &Model, ws: &mut Workspace, v: &[f64]) {
    for (i, body) in model.bodies.iter().enumerate() {
        let c = body.joint.coords;
        let v_joint = ws.s[i].apply(&v[c.v_index..c.v_index + ws.s[i].nv], c.scale);
        let v_parent = body.parent.map_or(Motion::zero(), |p| ws.v[p]);
        ws.v[i] = ws.x_up[i].apply_motion(&v_parent) + v_joint;
    }
}

/// Placements `ⁱX_0` and velocities of every body at `(q, v)`, into the workspace (see
/// [`Workspace::body_velocity`] and [`body_placements`]).
pub fn body_motion(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
) -> Result<(), DynamicsError> {
    check_q(model, q)?;
    super::validate::check_v(model, "v", v)?;
    update_joints(model, ws, q);
    update_placements(model, ws);
    update_velocities(model, ws, v);
    check_bodies(model, "placement", |i| {
        let x = &ws.x_world[i];
        x.rot.iter().chain(x.trans.iter()).all(|e| e.is_finite())
    })?;
    check_bodies(model, "velocity", |i| {
        ws.v[i]
            .ang
            .iter()
            .chain(ws.v[i].lin.iter())
            .all(|e| e.is_finite())
    })
}
