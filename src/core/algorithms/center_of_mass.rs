//! Centre of mass, total mass and the centre-of-mass Jacobian (Pinocchio's `centerOfMass` and
//! `jacobianCenterOfMass`).
//!
//! The mass counted is the model's bodies' (every fused, locked or lumped link included); links
//! fixed to the world (a fixed base's root link and whatever is welded to it) never move and
//! are not counted, as in Pinocchio, whose universe inertia is left out the same way.
//!
//! Inward over the tree, each body's subtree mass `m_i` and first moment about the body's own
//! origin `d_i = Σ_j m_j (c_j − p_i)` (world axes; `c_j` body `j`'s centre of mass, `p_i` body
//! `i`'s origin), which keeps the digits a sum about the world origin would lose far from it,
//! divided by the total mass `M` (`h_i` the body's first moment in its own coordinates):
//!
//! ```text
//! d_i / M = R_i h_i / M + Σ_children (d_j / M + (m_j / M) (p_j − p_i))
//! c = Σ_roots (m_r / M) p_r + d_r / M
//! ```
//!
//! `p_j − p_i` is body `j`'s origin in body `i`'s coordinates (its joint's placement) turned
//! into world axes, not the difference of two world positions, which far from the world origin
//! would lose the digits of their size. Every term is a mass fraction (at most 1) times an
//! offset, so no sum overflows when the offsets and `c` are numbers (`m_j (p_j − p_i)` could:
//! 10 kg at 1e308 m).
//!
//! A joint column `s` of body `i` (world axes at `p_i`: `a = R_i s_ω`, `l = R_i s_v`) moves the
//! subtree's centre of mass with `l + a × d_i / m_i`, so column `k` of `J_c` (`ċ = J_c q̇`) is
//! `Σ (m_i / M) l + a × d_i / M` over the joints with that coordinate (a mimic follower's
//! scaled by its multiplier).

use super::frames::place_all;
use super::jacobian::world_axes;
use super::validate::{all_finite, check_q};
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Vector3;
use crate::Workspace;
use nalgebra::DMatrix;

/// The total mass of the moving bodies and their centre of mass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CenterOfMass {
    /// Total mass `M` (kg).
    pub mass: f64,
    /// Centre of mass `c` in world coordinates (m).
    pub position: Vector3,
}

/// The centre of mass at `q`. A model without mass has none: an error.
pub fn center_of_mass(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
) -> Result<CenterOfMass, DynamicsError> {
    check_q(model, ws, q)?;
    place_all(model, ws, q);
    subtree_moments(model, ws);
    total(model, ws)
}

/// The centre of mass at `q` and its Jacobian `J_c` (`3 × nv`, `ċ = J_c q̇` in world
/// coordinates), in the workspace.
pub fn center_of_mass_jacobian<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<(CenterOfMass, &'w DMatrix<f64>), DynamicsError> {
    let com = center_of_mass(model, ws, q)?;
    let scratch = &mut ws.frame_scratch;
    let jacobian = &mut scratch.com_jacobian;
    // Without mimic followers every column is one joint's and is assigned below.
    let own_columns = ws.plan.own_columns;
    let values = jacobian.as_mut_slice();
    if !own_columns {
        values.fill(0.0);
    }
    let inverse_mass = scratch.inverse_mass;
    let placed = model.bodies.iter().zip(&ws.x_world).zip(&ws.s);
    let subtrees = scratch.subtree_mass.iter().zip(&scratch.subtree_moment);
    for (((body, x), s), ((&m, d), axes)) in placed.zip(subtrees.zip(&ws.plan.s_axes)) {
        let c = body.joint.coords;
        let fraction = m * inverse_mass;
        for (k, (col, &axis)) in s.cols[..s.nv].iter().zip(axes).enumerate() {
            let (a, l) = world_axes(&x.rot, col, axis);
            let col = l * fraction + a.cross(d);
            let out = &mut values[3 * (c.v_index + k)..3 * (c.v_index + k) + 3];
            if own_columns {
                out.copy_from_slice(col.as_slice());
            } else {
                for r in 0..3 {
                    out[r] += c.scale * col[r];
                }
            }
        }
    }
    if all_finite(jacobian.as_slice()) {
        return Ok((com, &ws.frame_scratch.com_jacobian));
    }
    if let Some(k) = (0..model.nv).find(|&k| !all_finite(jacobian.column(k).as_slice())) {
        return Err(DynamicsError::NonFiniteResult {
            quantity: "centre-of-mass Jacobian",
            coordinate: model.v_name(k),
        });
    }
    Ok((com, &ws.frame_scratch.com_jacobian))
}

/// `subtree_mass` (`m_i`) and `subtree_moment` (`d_i / M`, see the module documentation) from
/// the placed bodies, children before parents.
fn subtree_moments(model: &Model, ws: &mut Workspace) {
    let scratch = &mut ws.frame_scratch;
    let inverse_mass = scratch.inverse_mass;
    let sums = scratch
        .subtree_mass
        .iter_mut()
        .zip(&mut scratch.subtree_moment);
    for ((body, x), (m, d)) in model.bodies.iter().zip(&ws.x_world).zip(sums) {
        *m = body.inertia.mass;
        *d = x.rot.tr_mul(&body.inertia.h) * inverse_mass;
    }
    // What body `i + 1` adds to its parent `i`, carried in registers: stored and read back at
    // once, it would put a store-to-load round trip on the chain at each level.
    let mut carried = None;
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let (mut m, mut d) = (scratch.subtree_mass[i], scratch.subtree_moment[i]);
        if let Some((mc, dc)) = carried.take() {
            m += mc;
            d += dc;
            (scratch.subtree_mass[i], scratch.subtree_moment[i]) = (m, d);
        }
        if let Some(p) = body.parent {
            // p_i − p_λ from the joint's own placement (body i's origin in its parent's
            // coordinates, turned into world axes), not from the two world positions: far
            // from the world origin their difference would lose the digits of their size.
            let shift = ws.x_world[p].rot.tr_mul(&ws.x_up[i].trans);
            let added = (m, d + shift * (m * inverse_mass));
            if p + 1 == i {
                carried = Some(added);
            } else {
                scratch.subtree_mass[p] += added.0;
                scratch.subtree_moment[p] += added.1;
            }
        }
    }
}

/// `M` and `c = Σ_roots (m_r / M) p_r + d_r / M` from the roots' subtrees (`d_r / M` as the
/// inward pass left it), a sum of mass fractions times positions and offsets (a centre of mass
/// that is a number is one, however far out); an error for a massless model, or naming the
/// root joint whose subtree's sum overflowed.
fn total(model: &Model, ws: &Workspace) -> Result<CenterOfMass, DynamicsError> {
    let scratch = &ws.frame_scratch;
    let roots = || {
        (model.bodies.iter().zip(&ws.x_world))
            .zip(scratch.subtree_mass.iter().zip(&scratch.subtree_moment))
            .filter(|((body, _), _)| body.parent.is_none())
    };
    let mass: f64 = roots().map(|(_, (&m, _))| m).sum();
    if mass <= 0.0 {
        return Err(DynamicsError::Unsupported {
            method: "center of mass",
            reason: "no moving body of the model has mass".into(),
        });
    }
    let mut position = Vector3::zeros();
    for ((body, x), (&m, d)) in roots() {
        position += x.trans * (m / mass) + d;
        if !position.iter().all(|x| x.is_finite()) {
            return Err(DynamicsError::NonFiniteResult {
                quantity: "centre of mass",
                coordinate: body.joint.name.clone(),
            });
        }
    }
    Ok(CenterOfMass { mass, position })
}
