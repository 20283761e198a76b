//! Frame Jacobians (Pinocchio's `computeFrameJacobian`, and `computeJointJacobians` with
//! `getFrameJacobian` for many frames at one configuration).
//!
//! The Jacobian `J` of a link frame `L` maps the velocity coordinates to the frame's twist,
//! `[v; ω] = J q̇`, rows `[linear; angular]` (the twist's linear part first, unlike the
//! `[angular; linear]` spatial vectors inside the library), one column per velocity coordinate
//! in the model's `v` order. The [`ReferenceFrame`] says which twist:
//!
//! | reference | linear rows `v` | angular rows `ω` |
//! |---|---|---|
//! | `World` | velocity of the body-fixed point at the world origin, world axes | world axes |
//! | `Local` | velocity of the link origin, link axes (`R_Lᵀ ṗ_L`) | link axes |
//! | `LocalWorldAligned` | velocity of the link origin, world axes (`ṗ_L`) | world axes |
//!
//! Column `k` sums the contributions of the joints that move the frame (the bodies from the
//! root to the frame's body). A joint of body `i` with motion subspace `S_i` (body
//! coordinates) contributes, for each of its columns `s = [s_ω; s_v]`, the twist
//! `a = R_i s_ω`, `l = R_i s_v` in world axes at its body's origin `p_i`, moved to the point
//! `o` of the reference (`o = 0` for `World`, `o = p_L` otherwise): `[l + a × (o − p_i); a]`,
//! then turned into link axes by `R_Lᵀ` for `Local`. A floating base's columns follow its
//! `v = [linear; angular]` in the base frame; a mimic follower adds `μ` times its column to its
//! leader's (`q̇_follower = μ q̇_leader`).
//!
//! For `Local` and `LocalWorldAligned` the offset `δ_i = p_L − p_i` (world axes) is composed
//! from the placements along the support, from the frame's body `B` back to the root, as
//! Pinocchio's `LOCAL` Jacobian composes them, never as a difference of world positions:
//!
//! ```text
//! δ_B = R_B r_BL                 r_BL: the link's origin in B's coordinates (ᴸX_B.trans)
//! δ_λ = δ_i + R_λ r_i            r_i: body i's origin in its parent λ's coordinates (ⁱX_λ.trans)
//! ```
//!
//! so that these Jacobians depend on the robot's own lengths only: a robot 1000 km from the world
//! origin gets the digits it gets at the origin (a difference of world positions would lose
//! about `ε |p|`, 1e-10 there). `World` columns are about the world origin: their linear rows
//! hold `p_i × a`, as large as the robot is far.

use super::frames::{
    check_finite, floating_coordinates, place_all, place_support, placement_of, support_turns,
    Frame, FrameScratch, Placing,
};
use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::{floating_up, turned, Body, JointKind, Model, UpShape};
use crate::spatial::{Matrix3, Motion, Transform, Vector3};
use crate::Workspace;
use nalgebra::DMatrix;
use std::str::FromStr;

/// The frame a twist (or Jacobian, or acceleration) is expressed in, with Pinocchio's meaning
/// (`pinocchio::ReferenceFrame`); see the [module](self) documentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceFrame {
    /// World axes, about the world origin (the spatial twist).
    World,
    /// The link's axes, at the link's origin (the body twist).
    Local,
    /// World axes, at the link's origin.
    LocalWorldAligned,
}

impl ReferenceFrame {
    /// The names [`FromStr`] accepts, as the command line and the node spell them.
    pub const NAMES: [&'static str; 3] = ["world", "local", "local_world_aligned"];
}

impl FromStr for ReferenceFrame {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "world" => Ok(ReferenceFrame::World),
            "local" => Ok(ReferenceFrame::Local),
            "local_world_aligned" => Ok(ReferenceFrame::LocalWorldAligned),
            _ => Err(format!(
                "unknown reference '{s}': expected one of {}",
                Self::NAMES.join(", ")
            )),
        }
    }
}

/// The Jacobian of `frame` at `q` in `reference` (`6 × nv`, rows `[linear; angular]`, see the
/// [module](self) documentation), in the workspace. Only the bodies supporting the frame are
/// placed (every coordinate of `q` must be finite all the same); a link fixed to the world has
/// a zero Jacobian.
pub fn frame_jacobian<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    frame: &Frame,
    reference: ReferenceFrame,
) -> Result<&'w DMatrix<f64>, DynamicsError> {
    ws.check(model)?;
    frame.check(model)?;
    let turns_and_slides = frame.body.filter(|&b| ws.plan.supports.turns_and_slides(b));
    // One loop per reference, each compiled with its own map. The world columns read of the
    // frame's body only its joint axis and origin (`Placing::UpToLastTurn`).
    match (reference, turns_and_slides) {
        (ReferenceFrame::World, Some(b)) => {
            let turns = support_turns(model, ws, q, b, Placing::UpToLastTurn)?;
            world_columns_of_turns_and_slides(model, ws, q, b, turns).finish(model, frame)
        }
        (ReferenceFrame::World, None) => {
            place_support(model, ws, q, frame.body, Placing::UpToLastTurn)?;
            support_columns::<false>(model, ws, q, frame, |a, l, o| (l + a.cross(o), *a))
        }
        (ReferenceFrame::LocalWorldAligned, _) => {
            place_support(model, ws, q, frame.body, Placing::Placements)?;
            support_columns::<true>(model, ws, q, frame, |a, l, o| (l + a.cross(o), *a))
        }
        (ReferenceFrame::Local, _) => {
            place_support(model, ws, q, frame.body, Placing::Placements)?;
            let e = placement_of(&ws.x_world, frame).rot;
            support_columns::<true>(model, ws, q, frame, |a, l, o| (e * (l + a.cross(o)), e * a))
        }
    }?;
    Ok(&ws.frame_scratch.jacobian)
}

/// The columns of the joints supporting `frame` (placed), from the frame's body back to the
/// root, each the twist `[a; l]` of a joint column (world axes, at its body's origin `p_i`)
/// mapped by `map(a, l, o − p_i)` to the reference's `(linear, angular)`: about the link's
/// origin, `o − p_i = δ_i` composed from the placements (see the [module](self) documentation),
/// when `AT_LINK`; about the world origin, `−p_i`, otherwise.
#[inline(always)]
fn support_columns<const AT_LINK: bool>(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    frame: &Frame,
    map: impl Fn(&Vector3, &Vector3, &Vector3) -> (Vector3, Vector3),
) -> Result<(), DynamicsError> {
    let FrameScratch {
        jacobian,
        jacobian_support,
        ..
    } = &mut ws.frame_scratch;
    let mut out = Columns::new(jacobian, jacobian_support, ws.plan.own_columns, frame.body);
    let Some(last) = frame.body else {
        return out.finish(model, frame);
    };
    let mut delta = if AT_LINK {
        ws.x_world[last].rot.tr_mul(&frame.x_body_link.trans)
    } else {
        Vector3::zeros()
    };
    for &i in ws.plan.supports.of(last).iter().rev() {
        let (x, s, body) = (&ws.x_world[i], &ws.s[i], &model.bodies[i]);
        let offset = if AT_LINK { delta } else { -x.trans };
        let c = body.joint.coords;
        if body.joint.kind == JointKind::Floating {
            // `S = 1` (`v` linear then angular, base axes): the columns are the rows of `E`,
            // as linear and then as angular axes, written without a lookup per column.
            let zero = Vector3::zeros();
            for j in 0..3 {
                let row = x.rot.row(j).transpose();
                out.put(c.v_index + j, 1.0, map(&zero, &row, &offset));
                out.put(c.v_index + 3 + j, 1.0, map(&row, &zero, &offset));
            }
        } else {
            for k in 0..s.nv {
                let (a, l) = world_axes(&x.rot, &s.cols[k], ws.plan.s_axes[i][k]);
                out.put(c.v_index + k, c.scale, map(&a, &l, &offset));
            }
        }
        if let (true, Some(p)) = (AT_LINK, body.parent) {
            let r_i = origin_in_parent(body, ws.plan.turn_axes[i], &ws.x_up[i], q);
            delta += ws.x_world[p].rot.tr_mul(&r_i);
        }
    }
    out.finish(model, frame)
}

/// `r_i`, a body's origin in its parent's coordinates (`ⁱX_λ.trans`), after [`place_support`]
/// (its `turn_axis` from `ws.plan.turn_axes`): `ⁱX_λ` is in `ws.x_up` (`x_up`) but for a turn,
/// which moves no origin (`r_i` is its placement's), and a floating joint, made again from `q`.
#[inline(always)]
fn origin_in_parent(
    body: &Body,
    turn_axis: Option<(usize, f64)>,
    x_up: &Transform,
    q: &[f64],
) -> Vector3 {
    match turn_axis {
        Some(_) => body.x_tree.trans,
        None if body.joint.kind == JointKind::Floating => {
            let mut up = body.x_tree;
            floating_up(floating_coordinates(body, q), &body.x_tree, &mut up);
            up.trans
        }
        None => x_up.trans,
    }
}

/// The `world` columns of the joints supporting body `last` when each of them turns about a
/// coordinate axis or slides, under a floating root or the world
/// ([`Supports::turns_and_slides`](crate::plan::Supports::turns_and_slides)), with the sines
/// and cosines of the first `turns` turns in the scratch ([`support_turns`]).
///
/// Down the support, each body's placement `(E_i, p_i)` is made from its parent's, carried in
/// registers rather than stored and read back. A turn `E_J` about `e_k` leaves row `k` of
/// what it turns, so a turning body's column, the axis `a = σ row_k(E_i)` through `p_i` (linear
/// part `p_i × a`), is read at its joint, before its own turn; a slide by `d` along `u` (joint
/// axes) moves the body along `l = E_iᵀ u` (its column `(l, 0)`):
///
/// ```text
/// turn:   p_i = p_λ + E_λᵀ r_tree          a = σ row_k(E_tree E_λ)    E_i = (E_J E_tree) E_λ
/// slide:  p_i = p_λ + E_λᵀ (r_tree + E_treeᵀ u d)                     E_i = E_tree E_λ
/// ```
///
/// (`E_tree = 1` for a placement without rotation). The frame's body's own turn is not made:
/// nothing reads it.
fn world_columns_of_turns_and_slides<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    last: usize,
    turns: usize,
) -> Columns<'w> {
    let Workspace {
        plan,
        q_joint,
        frame_scratch: scratch,
        ..
    } = &mut *ws;
    let FrameScratch {
        sines,
        cosines,
        jacobian,
        jacobian_support,
        ..
    } = scratch;
    let mut out = Columns::new(jacobian, jacobian_support, true, Some(last));
    // `ᵏX_0` of the parent: the world's for a root.
    let (mut e, mut p) = (Matrix3::identity(), Vector3::zeros());
    for (k, &i) in plan.supports.of(last).iter().enumerate() {
        let body = &model.bodies[i];
        let (v, x_tree) = (body.joint.coords.v_index, &body.x_tree);
        let unrotated = !matches!(plan.up_shapes[i], UpShape::General);
        match (plan.turn_axes[i], body.joint.kind) {
            (Some((axis, sign)), _) => {
                p += e.tr_mul(&x_tree.trans);
                let a = if unrotated {
                    row_of(&e, axis) * sign
                } else {
                    e.tr_mul(&row_of(&x_tree.rot, axis)) * sign
                };
                out.put(v, 1.0, (p.cross(&a), a));
                if k < turns {
                    let turn = (sines[k], cosines[k]);
                    e = if unrotated {
                        turned(axis, turn, &e)
                    } else {
                        turned(axis, turn, &x_tree.rot) * e
                    };
                }
            }
            (None, JointKind::Prismatic { axis }) => {
                p += e.tr_mul(&(x_tree.trans + x_tree.rot.tr_mul(&(axis * q_joint[i][0]))));
                if !unrotated {
                    e = x_tree.rot * e;
                }
                out.put(v, 1.0, (e.tr_mul(&axis), Vector3::zeros()));
            }
            _ => {
                // The floating root, `S = 1` (`v` linear then angular, base axes): its
                // columns are the rows of `E`, as slides and then as turns.
                let mut up = body.x_tree;
                floating_up(floating_coordinates(body, q), x_tree, &mut up);
                (e, p) = (up.rot, up.trans);
                for j in 0..3 {
                    let row = e.row(j).transpose();
                    out.put(v + j, 1.0, (row, Vector3::zeros()));
                    out.put(v + 3 + j, 1.0, (p.cross(&row), row));
                }
            }
        }
    }
    out
}

/// Row `k` of `e` as a vector, one arm per row, so that an `e` held in registers is not
/// stored to be indexed.
#[inline(always)]
fn row_of(e: &Matrix3, k: usize) -> Vector3 {
    match k {
        0 => e.row(0).transpose(),
        1 => e.row(1).transpose(),
        _ => e.row(2).transpose(),
    }
}

/// Every joint's motion subspace in world axes at `q`, from which [`JointJacobians`] assembles
/// the Jacobian of any frame without another pass over the tree (Pinocchio's
/// `computeJointJacobians`): one placement of every body, then per frame only the columns of
/// its supporting joints.
pub fn joint_jacobians<'w>(
    model: &'w Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<JointJacobians<'w>, DynamicsError> {
    check_q(model, ws, q)?;
    place_all(model, ws, q);
    let scratch = &mut ws.frame_scratch;
    for i in 0..model.nbodies() {
        let (x, s) = (&ws.x_world[i], &ws.s[i]);
        if !x.rot.iter().chain(x.trans.iter()).all(|e| e.is_finite()) {
            return Err(DynamicsError::NonFiniteResult {
                quantity: "placement",
                coordinate: model.bodies[i].joint.name.clone(),
            });
        }
        let axes = &mut scratch.axes[i];
        axes.nv = s.nv;
        for k in 0..s.nv {
            let (a, l) = world_axes(&x.rot, &s.cols[k], ws.plan.s_axes[i][k]);
            axes.cols[k] = Motion::new(a, l);
        }
    }
    Ok(JointJacobians {
        model,
        placements: &ws.x_world,
        joint_placements: &ws.x_up,
        scratch,
        own_columns: ws.plan.own_columns,
    })
}

/// The joint Jacobians of one configuration ([`joint_jacobians`]): frame placements and
/// Jacobians of any number of frames, each for the cost of its own columns.
pub struct JointJacobians<'w> {
    model: &'w Model,
    /// `ⁱX_0` of every body.
    placements: &'w [Transform],
    /// `ⁱX_λ` of every body.
    joint_placements: &'w [Transform],
    scratch: &'w mut FrameScratch,
    own_columns: bool,
}

impl JointJacobians<'_> {
    /// `ᴸX_0` of `frame` (see [`frame_placement`](super::frames::frame_placement)); a frame of
    /// another model is refused.
    pub fn placement(&self, frame: &Frame) -> Result<Transform, DynamicsError> {
        frame.check(self.model)?;
        Ok(placement_of(self.placements, frame))
    }

    /// The Jacobian of `frame` in `reference`, as [`frame_jacobian`] gives it.
    pub fn frame_jacobian(
        &mut self,
        frame: &Frame,
        reference: ReferenceFrame,
    ) -> Result<&DMatrix<f64>, DynamicsError> {
        frame.check(self.model)?;
        let map = ColumnMap::new(reference, &placement_of(self.placements, frame).rot);
        let FrameScratch {
            axes,
            jacobian,
            jacobian_support,
            ..
        } = &mut *self.scratch;
        let mut out = Columns::new(jacobian, jacobian_support, self.own_columns, frame.body);
        // `δ_i = p_L − p_i` composed from the placements (see the module documentation).
        let mut delta = match (map.at_link, frame.body) {
            (true, Some(b)) => self.placements[b].rot.tr_mul(&frame.x_body_link.trans),
            _ => Vector3::zeros(),
        };
        let mut next = frame.body;
        while let Some(i) = next {
            let body = &self.model.bodies[i];
            let (x, c) = (&self.placements[i], body.joint.coords);
            let offset = if map.at_link { delta } else { -x.trans };
            for (k, col) in axes[i].cols[..axes[i].nv].iter().enumerate() {
                out.put(
                    c.v_index + k,
                    c.scale,
                    map.column(&col.ang, &col.lin, &offset),
                );
            }
            if let (true, Some(p)) = (map.at_link, body.parent) {
                let r_i = &self.joint_placements[i].trans;
                delta += self.placements[p].rot.tr_mul(r_i);
            }
            next = body.parent;
        }
        out.finish(self.model, frame)?;
        Ok(&self.scratch.jacobian)
    }
}

/// A motion-subspace column `s` (body coordinates) in world axes, `(R s_ω, R s_v)` with
/// `R = Eᵀ`: a column along a coordinate axis (`axis`, [`JointKind::subspace_axes`]) is a signed
/// row of `E`, with no product.
///
/// [`JointKind::subspace_axes`]: crate::model::JointKind::subspace_axes
#[inline(always)]
pub(crate) fn world_axes(
    e: &Matrix3,
    s: &Motion,
    axis: Option<(usize, f64)>,
) -> (Vector3, Vector3) {
    match axis {
        Some((j, sign)) if j < 3 => (e.row(j).transpose() * sign, Vector3::zeros()),
        Some((j, sign)) => (Vector3::zeros(), e.row(j - 3).transpose() * sign),
        None => (e.tr_mul(&s.ang), e.tr_mul(&s.lin)),
    }
}

/// Where a Jacobian's columns are expressed: about the link's origin (`at_link`) or the world
/// origin, in world axes or, with `rot` (world → link), in link axes.
struct ColumnMap {
    at_link: bool,
    rot: Option<Matrix3>,
}

impl ColumnMap {
    /// For `reference`, given the rotation `E_L` (world → link) of the frame's placement.
    fn new(reference: ReferenceFrame, e_link: &Matrix3) -> Self {
        let (at_link, rot) = match reference {
            ReferenceFrame::World => (false, None),
            ReferenceFrame::LocalWorldAligned => (true, None),
            ReferenceFrame::Local => (true, Some(*e_link)),
        };
        ColumnMap { at_link, rot }
    }

    /// The twist `[a; l]` (world axes, at the body origin `p_i`) as a column `(linear,
    /// angular)` in this map's point and axes, given `offset = o − p_i` (world axes) from
    /// `p_i` to the map's point `o`: `l + a × (o − p_i)`, `a`, turned if local.
    #[inline(always)]
    fn column(&self, a: &Vector3, l: &Vector3, offset: &Vector3) -> (Vector3, Vector3) {
        let lin = l + a.cross(offset);
        match &self.rot {
            Some(e) => (e * lin, e * a),
            None => (lin, *a),
        }
    }
}

/// The columns of a frame Jacobian being written (`FrameScratch::jacobian`), for the frame
/// carried by `body`: performance machinery that leaves the algorithms above to say which column
/// gets what.
///
/// When every column has one writer ([`Plan::own_columns`](crate::plan::Plan)) a column is
/// assigned, the matrix is zeroed only when the last Jacobian was another body's (its other
/// columns are still zero otherwise), and finiteness is checked on the values written. With
/// mimic followers the matrix is zeroed and their columns are added, scaled, to their leaders'.
struct Columns<'a> {
    values: &'a mut [f64],
    own_columns: bool,
    /// `Σ x · 0` over the values assigned: zero when all are finite.
    finite: Vector3,
}

impl<'a> Columns<'a> {
    fn new(
        jacobian: &'a mut DMatrix<f64>,
        support: &mut Option<usize>,
        own_columns: bool,
        body: Option<usize>,
    ) -> Self {
        let values = jacobian.as_mut_slice();
        if !(own_columns && body.is_some() && *support == body) {
            values.fill(0.0);
        }
        *support = body;
        Columns {
            values,
            own_columns,
            finite: Vector3::zeros(),
        }
    }

    /// Column `column` ← `[linear; angular]`, or `+= scale · [linear; angular]` with mimic
    /// followers.
    #[inline(always)]
    fn put(&mut self, column: usize, scale: f64, (lin, ang): (Vector3, Vector3)) {
        let col = &mut self.values[6 * column..6 * column + 6];
        if self.own_columns {
            col[..3].copy_from_slice(lin.as_slice());
            col[3..].copy_from_slice(ang.as_slice());
            self.finite += (lin + ang) * 0.0;
        } else {
            for r in 0..3 {
                col[r] += scale * lin[r];
                col[r + 3] += scale * ang[r];
            }
        }
    }

    /// An error naming the frame's link when a value is not finite.
    fn finish(self, model: &Model, frame: &Frame) -> Result<(), DynamicsError> {
        let values = if self.own_columns {
            self.finite.as_slice()
        } else {
            &*self.values
        };
        check_finite(model, frame, "frame Jacobian", values)
    }
}
