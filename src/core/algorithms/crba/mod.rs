//! The joint-space inertia matrix `H(q)` by the composite rigid-body algorithm (Featherstone,
//! RBDA Table 6.2). With `λ(i)` the parent of body `i`, `S_i` its joint's motion subspace and
//! `ⁱX_λ` the motion transform from the parent's frame to body `i`'s (its transpose
//! `ⁱX_λᵀ = ᵏX_i*`, `ᵏ` standing for `λ(i)`, carries a force from body `i` to the parent), and
//! every quantity in the frame of the body it is indexed by:
//!
//! ```text
//! composite inertias:  I^c_i = I_i;   for i = n−1 … 0:  I^c_λ(i) += ⁱX_λᵀ I^c_i ⁱX_λ
//! columns:             F = I^c_i S_i,   H_ii = S_iᵀ F,
//!                      j = i; while λ(j) exists:  F ← ʲX_λᵀ F,  j = λ(j),  H_ji = S_jᵀ F = H_ijᵀ
//! ```
//!
//! `body_frame_pass` is this recursion with the column walk reordered: body `i` is visited
//! once, inward, and by then every column force `F_c` of its subtree has been carried into its
//! frame, so it fills its rows `H_ic = S_iᵀ F_c` at once and moves all those forces, with its
//! composite inertia, one body up. `world_frame_pass` is the same recursion with every
//! quantity in one frame (the world's axes at the root body's origin): `ⁱX_λ` drops out of the
//! inward pass (`I^c_λ += I^c_i`, `F` unchanged on its way up), and each body's inertia and
//! axes are carried into that frame once instead, `⁰I_i = ⁱX_0ᵀ I_i ⁱX_0`, `⁰S_i = ⁰X_i S_i`.
//! Which of the two runs is the model's plan's choice
//! ([`Plan::crba_frames`](crate::plan::Plan::crba_frames): body coordinates for short branches,
//! world coordinates for long chains). Mimic joints, whose coordinates are shared across bodies,
//! take the world recursion column by column (submodule `general`).
//!
//! How `H` is written (row blocks over contiguous subtree coordinates, each entry's mirror
//! beside it or the upper triangle copied by tiles afterwards, a finiteness probe on the way)
//! is the submodules `rows` and `mirror`.

mod general;
mod mirror;
mod rows;

use super::kinematics::{
    update_aligned_placements, update_joints, update_world_axes, with_up_transform, Anchors,
};
use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::plan::CrbaFrames;
use crate::spatial::SpatialTransform;
use crate::Workspace;
use nalgebra::DMatrix;
use rows::{column_forces, Rows};

/// `H(q)` into `ws.mass_matrix()` (full and symmetric).
pub fn crba<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w DMatrix<f64>, DynamicsError> {
    check_q(model, ws, q)?;
    // [X_J, S_i] = jcalc(jtype(i), q_i),  ⁱX_λ(i) = X_J X_T(i)   (as RBDA Table 5.1)
    update_joints(model, ws, q);
    // Finite inputs can still overflow (a prismatic coordinate of 1e200 under a revolute joint
    // puts m·x² on the diagonal). Only when the passes report a non-finite entry is the matrix
    // searched, for the coordinate to name (column-major: entry i is in row i mod nv).
    if !crba_passes(model, ws) {
        let i = ws
            .mass_matrix
            .iter()
            .position(|x| !x.is_finite())
            .unwrap_or(0);
        return Err(DynamicsError::NonFiniteResult {
            quantity: "mass matrix",
            coordinate: model.v_name(i % model.nv),
        });
    }
    Ok(&ws.mass_matrix)
}

/// `H` into `ws.mass_matrix` (and the composite inertias into `ws.ic`) on joints already
/// updated for `q`, by the pass the plan chose; true when every entry is finite.
pub(crate) fn crba_passes(model: &Model, ws: &mut Workspace) -> bool {
    let Some(subtree_end) = ws.plan.subtree_end.take() else {
        world_axes_and_inertias(model, ws);
        return general::along_paths(model, ws);
    };
    let finite = if ws.plan.mirror_by_tiles {
        let finite = frame_pass::<false>(model, ws, &subtree_end);
        mirror::mirror_lower(ws.mass_matrix.as_mut_slice(), model.nv, &subtree_end);
        finite
    } else {
        frame_pass::<true>(model, ws, &subtree_end)
    };
    ws.plan.subtree_end = Some(subtree_end);
    finite
}

/// [`body_frame_pass`] or [`world_frame_pass`], as the plan's `crba_frames` says; with `MIRROR`
/// each entry's mirror is written beside it, else the caller copies the upper triangle.
fn frame_pass<const MIRROR: bool>(
    model: &Model,
    ws: &mut Workspace,
    subtree_end: &[usize],
) -> bool {
    match ws.plan.crba_frames {
        CrbaFrames::Local => body_frame_pass::<MIRROR>(model, ws, subtree_end),
        CrbaFrames::World => {
            world_axes_and_inertias(model, ws);
            world_frame_pass::<MIRROR>(model, ws, subtree_end)
        }
    }
}

/// Table 6.2 in body coordinates (Pinocchio's LOCAL convention). Body `i` (coordinates
/// `v_i ..`, subtree coordinates `v_i .. e_i`) sets the forces of its own columns,
/// `F_c = ⁱI^c_i S_c`, fills rows `H_rc = S_rᵀ F_c` for `c` from `r` to `e_i` (its descendants'
/// forces already in its frame), then carries its subtree's forces and its composite inertia
/// to its parent: `F_c ← ⁱX_λᵀ F_c`, `I^c_λ += ⁱX_λᵀ ⁱI^c_i ⁱX_λ`, with `ⁱX_λ` in the cheapest
/// form its joint allows ([`Plan::up_shapes`](crate::plan::Plan::up_shapes)).
fn body_frame_pass<const MIRROR: bool>(
    model: &Model,
    ws: &mut Workspace,
    subtree_end: &[usize],
) -> bool {
    let mut h = Rows::<MIRROR>::new(ws.mass_matrix.as_mut_slice(), model.nv);
    for (ic, body) in ws.ic.iter_mut().zip(&model.bodies) {
        *ic = body.inertia; // I^c_i = I_i   (RBDA Table 6.2)
    }
    for i in (0..model.bodies.len()).rev() {
        let body = &model.bodies[i];
        let v0 = body.joint.coords.v_index;
        let (s_i, axes, end) = (&ws.s[i], &ws.plan.s_axes[i], subtree_end[v0]);
        // F = I^c_i S_i, one per column of S_i   (RBDA Table 6.2)
        column_forces(&ws.ic[i], s_i, axes, &mut ws.f_cols[v0..]);
        // H_ii = S_iᵀ F, and H_di = Fᵀ S_i, H_id = H_diᵀ for the F of each descendant d's
        // columns, already carried here   (RBDA Table 6.2, its `while` loop turned inside out)
        h.joint_rows(&body.joint.kind, v0, s_i, axes, &ws.f_cols[..end]);
        if let Some(p) = body.parent {
            let forces = &mut ws.f_cols[v0..end];
            let (ic_above, ic_from) = ws.ic.split_at_mut(i);
            let (ic_p, ic_i) = (&mut ic_above[p], &ic_from[0]);
            // Both moves in one arm per form of `ⁱX_λ`, so the moved inertia is summed into
            // the parent's from registers.
            with_up_transform!(ws, i, |x| {
                // F = λ(i)X*_i F for the subtree's columns   (RBDA Table 6.2)
                x.transpose_apply_forces(forces);
                // I^c_λ(i) = I^c_λ(i) + λ(i)X*_i I^c_i ⁱX_λ(i)   (RBDA Table 6.2)
                *ic_p += x.transpose_apply_inertia(ic_i);
            });
        }
    }
    h.all_finite()
}

/// Table 6.2 in world coordinates, on `⁰I^c_i` and `⁰S_i` from [`world_axes_and_inertias`]:
/// body `i` sets `F_c = ⁰I^c_i ⁰S_c` for its own columns and fills rows `H_rc = ⁰S_rᵀ F_c` for
/// `c` from `r` to `e_i` (its descendants' forces, stored when they were visited, need no
/// move), then `⁰I^c_λ += ⁰I^c_i`.
fn world_frame_pass<const MIRROR: bool>(
    model: &Model,
    ws: &mut Workspace,
    subtree_end: &[usize],
) -> bool {
    let mut h = Rows::<MIRROR>::new(ws.mass_matrix.as_mut_slice(), model.nv);
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let v0 = body.joint.coords.v_index;
        let s_i = &ws.s_world[i];
        // F = I^c_i S_i, one per column of S_i   (RBDA Table 6.2, world coordinates)
        column_forces(&ws.ic[i], s_i, &[None; 6], &mut ws.f_cols[v0..]);
        // H_ii = S_iᵀ F, and H_di = Fᵀ S_i, H_id = H_diᵀ for the F of each descendant d's
        // columns: in world coordinates F = λ(j)X*_j F leaves F as it is   (RBDA Table 6.2)
        h.rows(v0, s_i, &[None; 6], &ws.f_cols[..subtree_end[v0]]);
        if let Some(p) = body.parent {
            // I^c_λ(i) = I^c_λ(i) + λ(i)X*_i I^c_i ⁱX_λ(i)   (RBDA Table 6.2; the transforms
            // are the identity in world coordinates)
            let ic_i = ws.ic[i];
            ws.ic[p] += ic_i;
        }
    }
    h.all_finite()
}

/// `⁰I_i = ⁱX_0ᵀ I_i ⁱX_0` into `ws.ic` and `⁰S_i = ⁰X_i S_i` into `ws.s_world` for every body,
/// `ⁱX_0` from the root's aligned frame (world axes at the root body's origin: `H` does not
/// depend on the origin, but inertias about a far one carry large `m d²` terms that cancel).
fn world_axes_and_inertias(model: &Model, ws: &mut Workspace) {
    // ⁱX_0 = ⁱX_λ(i) λ(i)X_0   (as RBDA Table 5.1), from the root's aligned frame
    update_aligned_placements(model, ws, Anchors::Roots);
    for (i, body) in model.bodies.iter().enumerate() {
        // I^c_i = I_i   (RBDA Table 6.2), in world coordinates ⁰I_i = ⁱX_0ᵀ I_i ⁱX_0
        ws.ic[i] = ws.x_aligned[i].transpose_apply_inertia(&body.inertia);
        // ⁰S_i = ⁰X_i S_i: the S_i of RBDA Table 6.2 in world coordinates
        update_world_axes(ws, i, &[], 0.0);
    }
}

#[cfg(test)]
mod tests;
