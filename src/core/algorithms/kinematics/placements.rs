//! Body placements in the world, `ⁱX_0 = ⁱX_λ ᵏX_0`, from the joint transforms.

use super::joints::{update_joints, with_up_transform};
use crate::algorithms::validate::check_q;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Transform;
use crate::Workspace;

/// Placement of every body in the root (world) frame, `ⁱX_0` (world coordinates → body
/// coordinates), for configuration `q`: `ⁱX_0 = ⁱX_λ ᵏX_0`. One per body, in model order.
pub fn body_placements<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w [Transform], DynamicsError> {
    check_q(model, ws, q)?;
    update_joints(model, ws, q);
    update_placements(model, ws);
    check_placements(model, ws)?;
    Ok(&ws.x_world)
}

/// An error naming the joint of the first body whose placement `ws.x_world` is not finite.
pub(super) fn check_placements(model: &Model, ws: &Workspace) -> Result<(), DynamicsError> {
    check_bodies(model, "placement", |i| {
        let x = &ws.x_world[i];
        x.rot.iter().chain(x.trans.iter()).all(|e| e.is_finite())
    })
}

/// An error naming the joint of the first body for which `finite` is false: finite inputs can
/// still overflow (origins of 1e308 added up, velocities of 1e200 multiplied).
pub(super) fn check_bodies(
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

/// `ws.x_world` from `ws.x_up` (joints already updated): `ⁱX_0 = ⁱX_λ ᵏX_0` for every body.
#[inline]
pub(crate) fn update_placements(model: &Model, ws: &mut Workspace) {
    let mut previous = Transform::identity();
    for (i, body) in model.bodies.iter().enumerate() {
        previous = below_parent(ws, &ws.x_world, &previous, i, body.parent);
        ws.x_world[i] = previous;
    }
}

/// `X[i] = ⁱX_λ X[λ]` (`ⁱX_λ` for a root) from the placements made so far, `placements`, the
/// last of which, `X[i − 1]`, is also given as `previous`: a parent placed just before its
/// child (every link of a chain) is read from there rather than from memory, where each body's
/// product would wait for its parent's stores to be forwarded to its loads, one round trip
/// per level on the chain's critical path.
#[inline(always)]
pub(crate) fn below_parent(
    ws: &Workspace,
    placements: &[Transform],
    previous: &Transform,
    i: usize,
    parent: Option<usize>,
) -> Transform {
    match parent {
        Some(p) if p + 1 == i => with_up_transform!(ws, i, |x| x.compose(previous)),
        Some(p) => with_up_transform!(ws, i, |x| x.compose(&placements[p])),
        None => ws.x_up[i],
    }
}
