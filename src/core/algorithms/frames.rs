//! Frames of URDF links and their placement in the world (Pinocchio's `Frame` and
//! `updateFramePlacement`).
//!
//! Every URDF link the model kept is a frame: a link with a moving joint is its body's frame
//! (possibly turned by quarter turns, see [`Body::name`](crate::model::Body)), a link fused
//! into its parent through a fixed joint, locked, or lumped onto a tip or a kept body by a
//! reduction sits at a constant placement `ᴸX_B` in the body that carries it
//! ([`LinkFrame::x_body_link`](crate::model::LinkFrame)); a link fixed to the world sits at a
//! constant placement in the world. A link pruned with a massless subtree is not a frame: no
//! body carries it any more.
//!
//! The placement of link `L` carried by body `B` is `ᴸX_0 = ᴸX_B ᴮX_0`, its origin
//! `p_L = ᴸX_0.trans` in the world and its orientation `R_L = ᴸX_0.rotᵀ` (link axes in world
//! coordinates, mapping link-frame vectors to world ones).
//!
//! The frame algorithms ([`frame_placement`], [`jacobian`](super::jacobian),
//! [`frame_acceleration`](super::frame_acceleration)) place only the bodies that support the
//! frame (the path from the root to its body), as Pinocchio's `computeFrameJacobian` does; the
//! whole-tree ones ([`joint_jacobians`](super::jacobian::joint_jacobians),
//! [`center_of_mass`](mod@super::center_of_mass)) place every body. Their scratch is the
//! workspace's [`FrameScratch`].

use super::kinematics::{
    read_joint, update_joints, update_placements, update_up, with_up_transform,
};
use super::validate::{all_finite, check_q, check_q_of};
use crate::error::{check_len, DynamicsError, NAMES_SHOWN};
use crate::model::{
    floating_up, quaternion_is_usable, turn_up, turn_up_unrotated, Body, JointKind, Model,
    MotionSubspace, UpShape,
};
use crate::spatial::{sin_cos_all, AxisTransform, Motion, Transform, Vector3};
use crate::Workspace;
use nalgebra::DMatrix;

/// A URDF link resolved once against a model ([`find_frame`]), so that the per-call algorithms
/// look nothing up by name.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Index of the link in [`Model::links`].
    pub(crate) link: usize,
    /// The body carrying the link; `None` for a link fixed to the world.
    pub(crate) body: Option<usize>,
    /// `ᴸX_B`: the carrying body's frame (the world for `body = None`) → the link frame.
    pub(crate) x_body_link: Transform,
    /// The identity of the model the frame was found in (see [`Workspace::check`]).
    pub(crate) model_id: u64,
}

impl Frame {
    /// Index of the link in [`Model::links`].
    pub fn link(&self) -> usize {
        self.link
    }

    /// The body carrying the link; `None` for a link fixed to the world.
    pub fn body(&self) -> Option<usize> {
        self.body
    }

    /// `ᴸX_B`: the carrying body's frame (the world for `body = None`) → the link frame.
    pub fn x_body_link(&self) -> Transform {
        self.x_body_link
    }

    /// `Ok` when the frame was found in `model` (or a clone of it), else
    /// [`DynamicsError::ForeignFrame`]: its link and body indices mean nothing in another model.
    pub fn check(&self, model: &Model) -> Result<(), DynamicsError> {
        if self.model_id == model.id {
            Ok(())
        } else {
            Err(DynamicsError::ForeignFrame {
                link: self.link,
                frame_model_id: self.model_id,
                model: model.name.clone(),
                model_id: model.id,
            })
        }
    }
}

/// The frame of link `name`, or an error naming it and listing the model's links.
pub fn find_frame(model: &Model, name: &str) -> Result<Frame, DynamicsError> {
    match model.links.iter().position(|l| l.name == name) {
        Some(link) => {
            let l = &model.links[link];
            Ok(Frame {
                link,
                body: l.body,
                x_body_link: l.x_body_link,
                model_id: model.id,
            })
        }
        None => Err(DynamicsError::UnknownLink {
            link: name.to_string(),
            pruned: model.reduction.pruned_links.iter().any(|l| l == name),
            known: (model.links.iter().take(NAMES_SHOWN))
                .map(|l| l.name.clone())
                .collect(),
            links: model.links.len(),
        }),
    }
}

/// `ᴸX_0`, the placement of `frame` in the world at configuration `q` (world coordinates → link
/// coordinates): its `trans` is the link origin in the world, its `rot` the rotation from world
/// to link coordinates (`rotᵀ` holds the link axes in world coordinates). Only the bodies
/// supporting the frame are placed.
pub fn frame_placement(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    frame: &Frame,
) -> Result<Transform, DynamicsError> {
    frame.check(model)?;
    place_support(model, ws, q, frame.body, Placing::Placements)?;
    let x = placement_of(&ws.x_world, frame);
    let mut values = [0.0; 12];
    values[..9].copy_from_slice(x.rot.as_slice());
    values[9..].copy_from_slice(x.trans.as_slice());
    check_finite(model, frame, "frame placement", &values)?;
    Ok(x)
}

/// Scratch of the frame algorithms, one per [`Workspace`]: quantities per body are kept here,
/// apart from the dynamics algorithms' own, so that a frame call placing only a frame's support
/// leaves theirs whole. The bodies' placements `ⁱX_0` are the workspace's `x_world`, shared with
/// [`body_placements`](super::kinematics::body_placements): no dynamics algorithm reads them
/// (each places what it needs in the same call), and a frame call leaves the entries of the
/// bodies off its frame's support as they were, as it does their `ⁱX_λ` in `x_up`.
#[derive(Clone, Debug)]
pub struct FrameScratch {
    /// The turn angles of the support's joints, their sines and cosines (support order).
    pub(crate) angles: Vec<f64>,
    pub(crate) sines: Vec<f64>,
    pub(crate) cosines: Vec<f64>,
    /// Each joint's motion subspace in world axes at its body's origin, `R_i S_i` with
    /// `R_i = ⁱX_0.rotᵀ` (both halves of each column rotated, no change of point), from
    /// [`joint_jacobians`](super::jacobian::joint_jacobians).
    pub(crate) axes: Vec<MotionSubspace>,
    /// Body spatial velocities and classical-acceleration recursion terms along the support, in
    /// body coordinates ([`frame_acceleration`](super::frame_acceleration)).
    pub(crate) v: Vec<Motion>,
    pub(crate) a: Vec<Motion>,
    /// Mass `m_i` and first moment `d_i = Σ_j m_j (c_j − p_i)` of each body `i`'s subtree
    /// (bodies `j`, centres of mass `c_j`), the moment divided by the total mass `M`: about
    /// body `i`'s own origin `p_i`, in world axes, so that a robot far from the world origin
    /// keeps its digits ([`center_of_mass`](super::center_of_mass)).
    pub(crate) subtree_mass: Vec<f64>,
    pub(crate) subtree_moment: Vec<Vector3>,
    /// `1 / M`, `M` the model's total mass (infinite for a massless model).
    pub(crate) inverse_mass: f64,
    /// A frame Jacobian, `6 × nv`, rows `[linear; angular]`.
    pub(crate) jacobian: DMatrix<f64>,
    /// The body whose support's columns are the only ones of `jacobian` that may be non-zero
    /// (the last Jacobian's frame body); `None` when unknown.
    pub(crate) jacobian_support: Option<usize>,
    /// The centre-of-mass Jacobian, `3 × nv`.
    pub(crate) com_jacobian: DMatrix<f64>,
}

impl FrameScratch {
    /// Buffers sized for `model`.
    pub(crate) fn new(model: &Model) -> Self {
        let (n, nv) = (model.nbodies(), model.nv);
        FrameScratch {
            angles: vec![0.0; n],
            sines: vec![0.0; n],
            cosines: vec![0.0; n],
            axes: vec![MotionSubspace::default(); n],
            v: vec![Motion::zero(); n],
            a: vec![Motion::zero(); n],
            subtree_mass: vec![0.0; n],
            subtree_moment: vec![Vector3::zeros(); n],
            inverse_mass: 1.0 / model.bodies.iter().map(|b| b.inertia.mass).sum::<f64>(),
            jacobian: DMatrix::zeros(6, nv),
            jacobian_support: None,
            com_jacobian: DMatrix::zeros(3, nv),
        }
    }
}

/// What [`place_support`] leaves in the workspace besides the placements of the bodies above
/// the frame's body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Placing {
    /// Every support joint's `ⁱX_λ` in `ws.x_up` (the frame acceleration's recursion reads
    /// them) and the frame body's placement.
    WithJointTransforms,
    /// The frame body's placement; a joint turning about a coordinate axis or a floating joint
    /// makes its `ⁱX_λ` without storing it.
    Placements,
    /// As `Placements`, but a frame body turning about a coordinate axis `e_k` is placed at its
    /// joint, before its own turn (`E_J = 1`): what the `world` Jacobian reads of it, row `k`
    /// of its `E` (the axis, which `E_J` leaves) and its origin, is the same.
    UpToLastTurn,
}

/// Places the bodies supporting `body` (none for a link fixed to the world) for `q`, as
/// `placing` asks: `q` is validated (every coordinate finite, though only the support's move
/// the frame: a NaN anywhere is the caller's mistake; the support's quaternions usable), their
/// joints are updated (`ws.s`, and `ws.x_up` with
/// [`Placing::WithJointTransforms`]; other bodies' entries are left as they were) and
/// `ws.x_world` holds their `ⁱX_0 = ⁱX_λ ᵏX_0`. The bodies are those `ws.plan.supports`
/// lists for `body`, root first.
pub(crate) fn place_support(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    body: Option<usize>,
    placing: Placing,
) -> Result<(), DynamicsError> {
    let Some(last) = body else {
        return check_q(model, ws, q);
    };
    let turns = support_turns(model, ws, q, last, placing)?;
    for k in 0..ws.plan.supports.of(last).len() {
        let i = ws.plan.supports.of(last)[k];
        // Other joints ignore the turn; a last turn left out is none.
        let turn = if k < turns {
            (ws.frame_scratch.sines[k], ws.frame_scratch.cosines[k])
        } else {
            (0.0, 1.0)
        };
        update_and_place(model, ws, i, turn, q, placing);
    }
    Ok(())
}

/// The coordinates of the joints supporting body `last` read, `q` validated (as
/// [`place_support`] says), and the sines and cosines of their turns, in support order in
/// `scratch.sines` and `scratch.cosines`, for the first `n` of them (returned): all but, with
/// [`Placing::UpToLastTurn`], a last turn. As `update_joints` does for the whole tree: the turn
/// angles first, then their sines and cosines two at a time.
pub(crate) fn support_turns(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    last: usize,
    placing: Placing,
) -> Result<usize, DynamicsError> {
    ws.check(model)?;
    check_len("q", model.nq, q.len())?;
    if !all_finite(q) {
        // A coordinate off the support does not move the frame, but is no number either.
        check_q(model, ws, q)?;
    }
    let Workspace {
        plan,
        q_joint,
        frame_scratch: scratch,
        ..
    } = &mut *ws;
    let support = plan.supports.of(last);
    let n = support.len();
    // `x · 0` is zero for a finite `x`: one test for every coordinate read.
    let (mut finite, mut quaternions) = (0.0, true);
    for (k, &i) in support.iter().enumerate() {
        let (b, joint) = (&model.bodies[i], &mut q_joint[i]);
        let kind = b.joint.kind;
        if plan.turn_axes[i].is_some() {
            let angle = read_joint(b, plan.turn_axes[i], joint, q);
            scratch.angles[k] = angle;
            finite += angle * 0.0;
        } else if kind == JointKind::Floating {
            // Never a mimic follower: its coordinates are read where they are.
            let x = floating_coordinates(b, q);
            finite += x.iter().map(|x| x * 0.0).sum::<f64>();
            quaternions &= quaternion_is_usable(&x[3..]);
            scratch.angles[k] = 0.0;
        } else {
            scratch.angles[k] = read_joint(b, plan.turn_axes[i], joint, q);
            finite += joint[..kind.nq()].iter().map(|x| x * 0.0).sum::<f64>();
        }
    }
    if finite != 0.0 || !quaternions {
        // The error naming the coordinate; none when a finite coordinate overflowed once
        // scaled by a mimic multiplier, which the results' own check then reports.
        check_q_of(model, q, support)?;
    }
    // The sines and cosines of the angles from the first turning joint (a floating base, whose
    // angle is 0, is left out) to the last one needed.
    let first = usize::from(plan.turn_axes[support[0]].is_none());
    let end = if placing == Placing::UpToLastTurn && plan.turn_axes[last].is_some() {
        n - 1
    } else {
        n
    };
    let FrameScratch {
        angles,
        sines,
        cosines,
        ..
    } = scratch;
    if first < end {
        sin_cos_all(
            &angles[first..end],
            &mut sines[first..end],
            &mut cosines[first..end],
        );
    }
    Ok(end)
}

/// The seven coordinates `[p; x, y, z, w]` of floating joint `body` in `q`.
#[inline(always)]
pub(crate) fn floating_coordinates<'q>(body: &Body, q: &'q [f64]) -> &'q [f64; 7] {
    let start = body.joint.coords.q_index;
    q[start..start + 7].try_into().expect("seven coordinates")
}

/// Body `i`'s joint updated for `turn` ([`update_up`]) and the body placed ([`place_body`]).
/// A joint turning about a coordinate axis, or a floating joint (its coordinates read from `q`),
/// places its body with the `ⁱX_λ` it has just made, still in registers, rather than reading it
/// back from `ws.x_up` (loads that straddle the stores which wrote it would wait for them to
/// drain), and stores it there only for [`Placing::WithJointTransforms`].
#[inline(always)]
fn update_and_place(
    model: &Model,
    ws: &mut Workspace,
    i: usize,
    turn: (f64, f64),
    q: &[f64],
    placing: Placing,
) {
    let body = &model.bodies[i];
    let shape = ws.plan.up_shapes[i];
    let mut up = body.x_tree;
    match ws.plan.turn_axes[i] {
        Some((k, _)) if matches!(shape, UpShape::AxisTurn(_)) => {
            turn_up_unrotated(k, turn, &body.x_tree, &mut up)
        }
        Some((k, _)) => turn_up(k, turn, &body.x_tree, &mut up),
        None if body.joint.kind == JointKind::Floating => {
            floating_up(floating_coordinates(body, q), &body.x_tree, &mut up)
        }
        None => {
            update_up(body, ws, i, turn);
            place_body(model, ws, i);
            return;
        }
    }
    if placing == Placing::WithJointTransforms {
        ws.x_up[i] = up;
    }
    let (above, from_i) = ws.x_world.split_at_mut(i);
    let x_i = &mut from_i[0];
    let Some(p) = body.parent else {
        *x_i = up;
        return;
    };
    match shape {
        UpShape::AxisTurn(0) => *x_i = AxisTransform::<0>::from_transform(&up).compose(&above[p]),
        UpShape::AxisTurn(1) => *x_i = AxisTransform::<1>::from_transform(&up).compose(&above[p]),
        UpShape::AxisTurn(_) => *x_i = AxisTransform::<2>::from_transform(&up).compose(&above[p]),
        _ => *x_i = up.compose(&above[p]),
    }
}

/// Places every body for `q` (already validated): all joints updated, `ws.x_world` for every
/// body, each from its parent's placement ([`update_placements`]).
pub(crate) fn place_all(model: &Model, ws: &mut Workspace, q: &[f64]) {
    update_joints(model, ws, q);
    update_placements(model, ws);
}

/// `ws.x_world[i] = ⁱX_λ ᵏX_0` (`ⁱX_λ` for a root), the parent already placed; written in
/// place by each form of `ⁱX_λ`, without the copy a returned product needs: a frame's support
/// is a short path, whose time goes by the instructions rather than by the chain's latency
/// (`kinematics::placements::below_parent` weighs the other way, for whole trees).
#[inline(always)]
fn place_body(model: &Model, ws: &mut Workspace, i: usize) {
    let (above, from_i) = ws.x_world.split_at_mut(i);
    let x_i = &mut from_i[0];
    match model.bodies[i].parent {
        Some(p) => with_up_transform!(ws, i, |x| *x_i = x.compose(&above[p])),
        None => *x_i = ws.x_up[i],
    }
}

/// `ᴸX_0 = ᴸX_B ᴮX_0` from the bodies' placements `ᴮX_0` (`ᴸX_0 = ᴸX_B` for a link fixed to
/// the world).
pub(crate) fn placement_of(placements: &[Transform], frame: &Frame) -> Transform {
    match frame.body {
        Some(b) => frame.x_body_link.compose(&placements[b]),
        None => frame.x_body_link,
    }
}

/// An error naming the frame's link when a result is not finite (finite inputs can overflow).
pub(crate) fn check_finite(
    model: &Model,
    frame: &Frame,
    quantity: &'static str,
    values: &[f64],
) -> Result<(), DynamicsError> {
    if all_finite(values) {
        Ok(())
    } else {
        Err(DynamicsError::NonFiniteResult {
            quantity,
            coordinate: model.links[frame.link].name.clone(),
        })
    }
}
