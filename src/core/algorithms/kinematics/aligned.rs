//! Aligned frames (world axes, origin at an anchor body's origin): the frames in which the
//! passes said to work in world coordinates (ABA, CRBA's world rows, `joint_state_outputs`) hold
//! their quantities, how a motion or force crosses an anchor, and the joints' motion subspaces
//! in them.

use super::placements::below_parent;
use crate::instruction_set::run_pass;
use crate::model::{Model, MotionSubspace};
use crate::spatial::{Force, Motion, Transform, Translation, Vector3};
use crate::Workspace;

/// `ws.x_aligned` and `ws.anchor_shift` from `ws.x_up` (joints already updated): `ⁱX_A`, from
/// the *aligned frame* `A` of body `i` to body `i`. An aligned frame has the world's axes and
/// its origin at an *anchor* body's origin: every root is an anchor and, with
/// [`Anchors::Spaced`], so is each body far enough along the tree from the anchor above it
/// ([`frame_anchors`]). An anchor `a` gets `ᵃX_A = rot(E_a)` (its placement in its parent's
/// aligned frame, or in the world for a root, without the translation), which it records as
/// `anchor_shift[a]` (its origin in that frame); every other body shares its parent's frame,
/// `ⁱX_A = ⁱX_λ ᵏX_A`.
///
/// The passes that work in "world coordinates" (ABA, CRBA's world rows, `joint_state_outputs`)
/// work in these frames. A translation of the frame changes none of `H`, `τ`, `q̈` (gravity
/// `[0; g]` is the same about every point), but a spatial inertia about a point `d` away from
/// the body carries `m d²` terms that cancel in them: about the world origin, a robot a
/// kilometre away would lose seven digits, and a long chain about its root loses digits in
/// proportion to its length (ABA: 1.8e-12 relative error at 256 equal links, 3.8e-14 spaced).
/// Quantities cross between an anchor's frame and its parent's by the pure translation
/// `xlt(anchor_shift)` ([`Translation`](crate::spatial::Translation)).
pub(crate) fn update_aligned_placements(model: &Model, ws: &mut Workspace, anchors: Anchors) {
    run_pass!(update_aligned_placements_in(model, ws, anchors))
}

/// [`update_aligned_placements`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn update_aligned_placements_in(model: &Model, ws: &mut Workspace, anchors: Anchors) {
    let mut previous = Transform::identity();
    for (i, body) in model.bodies.iter().enumerate() {
        let mut x = below_parent(ws, &ws.x_aligned, &previous, i, body.parent);
        let anchor = match anchors {
            Anchors::Roots => body.parent.is_none(),
            Anchors::Spaced => ws.plan.anchors[i],
        };
        if anchor {
            // `rot(E_a)`: the placement without its translation, which is recorded.
            ws.anchor_shift[i] = x.trans;
            x.trans = Vector3::zeros();
        }
        ws.x_aligned[i] = x;
        previous = x;
    }
}

/// Which bodies [`update_aligned_placements`] starts an aligned frame at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Anchors {
    /// The roots only: one frame per tree (CRBA, whose error on long chains comes from the
    /// conditioning of `H`, not from the frame, and which would have to move every column
    /// force of a subtree across each anchor).
    Roots,
    /// The roots and the bodies `ws.plan.anchors` marks ([`frame_anchors`]): ABA and
    /// `joint_state_outputs`, which cross an anchor with one motion, force and inertia each,
    /// through [`motion_into_aligned`] and [`force_out_of_aligned`].
    Spaced,
}

/// `⁰S_i = ⁰X_i S_i` into `ws.s_world[i]` from the aligned placement `ws.x_aligned[i]`: a column
/// along a coordinate axis (`ws.plan.s_axes`) is a row of the rotation
/// ([`Transform::inverse_apply_axis`]), any other a general inverse transform. Returns
/// `⁰S_i q̇_i` for the joint's `rates` scaled by `scale` (zero for no rates), summed as the
/// columns are made: read back from `ws` just after they are written, the columns would be
/// loaded across the stores that wrote them, which the processor cannot forward.
#[inline(always)]
pub(crate) fn update_world_axes(ws: &mut Workspace, i: usize, rates: &[f64], scale: f64) -> Motion {
    let (x, s, axes) = (&ws.x_aligned[i], &ws.s[i], &ws.plan.s_axes[i]);
    world_axes(x, s, axes, &mut ws.s_world[i], rates, scale)
}

/// [`update_world_axes`] from body `i`'s aligned placement `x`, joint subspace `s` and
/// coordinate axes `axes` (`ws.plan.s_axes[i]`) into `s_world`, for a pass that walks the
/// bodies' slots itself.
#[inline(always)]
pub(crate) fn world_axes(
    x: &Transform,
    s: &MotionSubspace,
    axes: &[Option<(usize, f64)>; 6],
    s_world: &mut MotionSubspace,
    rates: &[f64],
    scale: f64,
) -> Motion {
    s_world.nv = s.nv;
    let column = |k: usize| match axes[k] {
        Some((j, sign)) => x.inverse_apply_axis(j, sign),
        None => x.inverse_apply_motion(&s.cols[k]),
    };
    if s.nv == 1 {
        // One column, without the loop's bookkeeping (most joints).
        let col = column(0);
        s_world.cols[0] = col;
        return rates.first().map_or(Motion::zero(), |r| col * (r * scale));
    }
    let mut v = Motion::zero();
    for k in 0..s.nv {
        let col = column(k);
        s_world.cols[k] = col;
        if let Some(r) = rates.get(k) {
            v += col * (r * scale);
        }
    }
    v
}

/// A motion in the aligned frame of body `i`'s parent (about the world origin for a root) into
/// body `i`'s aligned frame ([`Anchors::Spaced`]): moved by `xlt(anchor_shift)` when `i`
/// anchors a frame.
pub(crate) fn motion_into_aligned(ws: &Workspace, i: usize, m: Motion) -> Motion {
    motion_across_anchor(ws.plan.anchors[i], &ws.anchor_shift[i], m)
}

/// [`motion_into_aligned`] for a body that is an `anchor` or not, with its `anchor_shift`.
#[inline(always)]
pub(crate) fn motion_across_anchor(anchor: bool, shift: &Vector3, m: Motion) -> Motion {
    if anchor {
        Translation(*shift).apply_motion(&m)
    } else {
        m
    }
}

/// A force in body `i`'s aligned frame into its parent's aligned frame ([`Anchors::Spaced`]):
/// moved by `xlt(anchor_shift)ᵀ` when `i` anchors a frame.
pub(crate) fn force_out_of_aligned(ws: &Workspace, i: usize, f: Force) -> Force {
    force_across_anchor(ws.plan.anchors[i], &ws.anchor_shift[i], f)
}

/// [`force_out_of_aligned`] for a body that is an `anchor` or not, with its `anchor_shift`.
#[inline(always)]
pub(crate) fn force_across_anchor(anchor: bool, shift: &Vector3, f: Force) -> Force {
    if anchor {
        Translation(*shift).transpose_apply_force(&f)
    } else {
        f
    }
}
