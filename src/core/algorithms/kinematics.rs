//! The position-dependent part shared by every algorithm: joint transforms and motion
//! subspaces (`jcalc` for each joint, then `ⁱX_λ(i) = X_J X_tree`).

use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::{
    floating_up, turn_up, turn_up_unrotated, Body, Joint, JointKind, Model, MotionSubspace, UpShape,
};
use crate::spatial::{sin_cos_all, Force, Motion, Transform, Translation, Vector3};
use crate::Workspace;

/// Evaluates `$body` with `$x` bound to body `$i`'s `ⁱX_λ` (`ws.x_up[i]`, a `&Transform`) in
/// the cheapest form its joint allows (`ws.plan.up_shapes[i]`, [`JointKind::up_shape`]): the general
/// [`Transform`], a [`Translation`] or an [`AxisTransform`](crate::spatial::AxisTransform) about
/// its axis. `$body` uses [`SpatialTransform`](crate::spatial::SpatialTransform)'s actions and
/// is compiled once for each form.
///
/// [`JointKind::up_shape`]: crate::model::JointKind::up_shape
macro_rules! with_up_transform {
    ($ws:expr, $i:expr, |$x:ident| $body:expr) => {{
        use $crate::model::UpShape;
        use $crate::spatial::{AxisTransform, Translation};
        let (shape, x_up): (UpShape, &$crate::spatial::Transform) =
            ($ws.plan.up_shapes[$i], &$ws.x_up[$i]);
        match shape {
            UpShape::General => {
                let $x = x_up;
                $body
            }
            UpShape::Translation => {
                let $x = &Translation(x_up.trans);
                $body
            }
            UpShape::AxisTurn(0) => {
                let $x = &AxisTransform::<0>::from_transform(x_up);
                $body
            }
            UpShape::AxisTurn(1) => {
                let $x = &AxisTransform::<1>::from_transform(x_up);
                $body
            }
            UpShape::AxisTurn(_) => {
                let $x = &AxisTransform::<2>::from_transform(x_up);
                $body
            }
        }
    }};
}
pub(crate) use with_up_transform;

/// Fills `ws.q_joint`, `ws.x_up` and `ws.s` for configuration `q` (already validated): the
/// joints' own coordinates (a turning joint's one coordinate straight into its angle), then
/// the sines and cosines of the turn angles at once, from the first turning joint to the last
/// (`ws.plan.turning`; `spatial::sin_cos_all`, two angles at a time), then each joint's `ⁱX_λ`
/// and `S`. A revolute joint about a coordinate
/// axis (`ws.plan.turn_axes`, most joints) mixes two rows of its placement ([`turn_up`]), or of the
/// identity when its placement has no rotation ([`turn_up_unrotated`], `ws.plan.up_shapes`); its `S`
/// is constant, set when the workspace was made.
pub(crate) fn update_joints(model: &Model, ws: &mut Workspace, q: &[f64]) {
    let Workspace {
        plan,
        q_joint,
        turn_angles,
        turn_sines,
        turn_cosines,
        s,
        x_up,
        ..
    } = ws;
    let joints = model
        .bodies
        .iter()
        .zip(&plan.turn_axes)
        .zip(q_joint.iter_mut());
    for (((body, &axis), q_joint), angle) in joints.zip(turn_angles.iter_mut()) {
        *angle = read_joint(body, axis, q_joint, q);
    }
    let turning = plan.turning.clone();
    sin_cos_all(
        &turn_angles[turning.clone()],
        &mut turn_sines[turning.clone()],
        &mut turn_cosines[turning],
    );
    let joints = model
        .bodies
        .iter()
        .zip(&plan.turn_axes)
        .zip(&plan.up_shapes);
    let turns = turn_sines.iter().zip(turn_cosines.iter());
    let outputs = q_joint.iter().zip(s.iter_mut()).zip(x_up.iter_mut());
    for ((((body, &axis), &shape), (&sin, &cos)), ((q_joint, s), x_up)) in
        joints.zip(turns).zip(outputs)
    {
        joint_up(body, axis, shape, q_joint, (sin, cos), s, x_up);
    }
}

/// The body's turn angle `σ q` when its joint turns about a coordinate axis (`turn_axis`, from
/// `ws.plan.turn_axes`), else 0 with the joint's own coordinates read into `q_joint` (its
/// `ws.q_joint` entry).
#[inline(always)]
pub(crate) fn read_joint(
    body: &Body,
    turn_axis: Option<(usize, f64)>,
    q_joint: &mut [f64; 7],
    q: &[f64],
) -> f64 {
    match turn_axis {
        Some((_, sign)) => sign * joint_position(&body.joint, q, 0),
        None => {
            joint_positions(&body.joint, q, q_joint);
            0.0
        }
    }
}

/// `ws.x_up[i]` (and `ws.s[i]` for a joint whose `S` varies) from the sine and cosine of body
/// `i`'s turn angle and, for other joints, `ws.q_joint[i]`. A floating joint's `S` is constant
/// (set when the workspace was made): only its transform is computed ([`floating_up`]).
#[inline(always)]
pub(crate) fn update_up(body: &Body, ws: &mut Workspace, i: usize, turn: (f64, f64)) {
    let (axis, shape) = (ws.plan.turn_axes[i], ws.plan.up_shapes[i]);
    joint_up(
        body,
        axis,
        shape,
        &ws.q_joint[i],
        turn,
        &mut ws.s[i],
        &mut ws.x_up[i],
    );
}

/// [`update_up`] given the body's entries: its plan's `turn_axis` and `shape`, its own
/// coordinates `q_joint`, and its `S` and `ⁱX_λ` to write.
#[inline(always)]
fn joint_up(
    body: &Body,
    turn_axis: Option<(usize, f64)>,
    shape: UpShape,
    q_joint: &[f64; 7],
    turn: (f64, f64),
    s: &mut MotionSubspace,
    x_up: &mut Transform,
) {
    match (turn_axis, shape) {
        (Some(_), UpShape::AxisTurn(k)) => turn_up_unrotated(k, turn, &body.x_tree, x_up),
        (Some((k, _)), _) => turn_up(k, turn, &body.x_tree, x_up),
        (None, _) if body.joint.kind == JointKind::Floating => {
            floating_up(q_joint, &body.x_tree, x_up)
        }
        (None, _) => body.joint.kind.jcalc_up_turned(
            &q_joint[..body.joint.kind.nq()],
            turn,
            &body.x_tree,
            s,
            x_up,
        ),
    }
}

/// The joint's own coordinates `scale · q[q_index..] + offset` (a mimic follower reads its
/// leader's coordinate; for every other joint scale is 1 and offset 0).
fn joint_positions(joint: &Joint, q: &[f64], out: &mut [f64; 7]) {
    for (k, o) in out[..joint.kind.nq()].iter_mut().enumerate() {
        *o = joint_position(joint, q, k);
    }
}

/// The joint's coordinate `k`, `scale · q[q_index + k] + offset`.
#[inline(always)]
fn joint_position(joint: &Joint, q: &[f64], k: usize) -> f64 {
    let c = joint.coords;
    c.scale * q[c.q_index + k] + c.offset
}

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
    let s_world = &mut ws.s_world[i];
    s_world.nv = s.nv;
    let mut v = Motion::zero();
    for k in 0..s.nv {
        let col = match axes[k] {
            Some((j, sign)) => x.inverse_apply_axis(j, sign),
            None => x.inverse_apply_motion(&s.cols[k]),
        };
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
    if ws.plan.anchors[i] {
        Translation(ws.anchor_shift[i]).apply_motion(&m)
    } else {
        m
    }
}

/// A force in body `i`'s aligned frame into its parent's aligned frame ([`Anchors::Spaced`]):
/// moved by `xlt(anchor_shift)ᵀ` when `i` anchors a frame.
pub(crate) fn force_out_of_aligned(ws: &Workspace, i: usize, f: Force) -> Force {
    if ws.plan.anchors[i] {
        Translation(ws.anchor_shift[i]).transpose_apply_force(&f)
    } else {
        f
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
    check_q(model, ws, q)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::crba::crba;
    use crate::algorithms::{forward_dynamics, rnea, Externals, ForwardDynamicsMethod};
    use crate::model::examples::{self, pendulum_urdf};
    use crate::model::UpShape;
    use crate::plan::CrbaFrames;
    use crate::sampling::{random_q, Rng};
    use crate::{urdf, ModelOptions};

    /// The cheaper forms of `ⁱX_λ` that [`with_up_transform`] picks (a translation for a slide, a
    /// turn after a translation for a revolute joint about a coordinate axis) give the general
    /// transform's `τ` (RNEA), `H` (body coordinates) and `q̈` (ABA, whose aligned placements
    /// compose through them) to rounding, on models where each form occurs.
    #[test]
    fn cheaper_transform_forms_match_the_general_transform() {
        let options = ModelOptions::default();
        let models = [
            include_str!("../tests/models/turn_slide.urdf").to_string(),
            // Axes x, −z, y, y, y.
            pendulum_urdf(5, 0.5, 0.7)
                .replacen(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="1 0 0"/>"#, 1)
                .replacen(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="0 0 -1"/>"#, 1),
            examples::DEFAULT_ARM_URDF.to_string(),
        ]
        .map(|text| urdf::model_from_str(&text, &options).unwrap());
        let mut seen = Vec::new();
        for model in &models {
            let mut ws = Workspace::new(model);
            ws.plan.crba_frames = CrbaFrames::Local;
            let shapes = ws.plan.up_shapes.clone();
            seen.extend_from_slice(&shapes);
            let mut rng = Rng::new(5);
            let aba = |ws: &mut Workspace, q: &[f64], v: &[f64], tau: &[f64]| {
                let (method, none) = (ForwardDynamicsMethod::Aba, Externals::none());
                forward_dynamics(model, ws, q, v, tau, method, &none)
                    .unwrap()
                    .to_vec()
            };
            for _ in 0..4 {
                let q = random_q(model, &mut rng);
                let (v, a) = (rng.vector(model.nv, 2.0), rng.vector(model.nv, 3.0));
                let effort = rng.vector(model.nv, 10.0);
                ws.plan.up_shapes.clone_from(&shapes);
                let tau = rnea(model, &mut ws, &q, &v, &a).unwrap().to_vec();
                let h = crba(model, &mut ws, &q).unwrap().clone();
                let qdd = aba(&mut ws, &q, &v, &effort);
                ws.plan.up_shapes.fill(UpShape::General);
                let tau_general = rnea(model, &mut ws, &q, &v, &a).unwrap();
                let scale = tau.iter().fold(1.0, |m: f64, x| m.max(x.abs()));
                for (x, y) in tau.iter().zip(tau_general) {
                    assert!(
                        (x - y).abs() < 1e-13 * scale,
                        "{}: τ {x} vs {y}",
                        model.name
                    );
                }
                let h_general = crba(model, &mut ws, &q).unwrap();
                assert!(
                    (&h - h_general).amax() < 1e-13 * h.amax(),
                    "{}: H",
                    model.name
                );
                let qdd_general = aba(&mut ws, &q, &v, &effort);
                let scale = qdd.iter().fold(1.0, |m: f64, x| m.max(x.abs()));
                for (x, y) in qdd.iter().zip(&qdd_general) {
                    assert!(
                        (x - y).abs() < 1e-12 * scale,
                        "{}: q̈ {x} vs {y}",
                        model.name
                    );
                }
            }
        }
        for shape in [0, 1, 2].map(UpShape::AxisTurn) {
            assert!(seen.contains(&shape), "no body of form {shape:?}");
        }
        assert!(seen.contains(&UpShape::Translation));
    }
}
