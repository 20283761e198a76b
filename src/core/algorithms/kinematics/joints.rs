//! Joint transforms: each joint's `jcalc` and `ⁱX_λ(i) = X_J X_tree` from its coordinates, and
//! the cheapest form each transform acts in ([`with_up_transform`]).

use crate::instruction_set::run_pass;
use crate::model::{
    floating_up, turn_up, turn_up_unrotated, Body, Joint, JointKind, Model, MotionSubspace, UpShape,
};
use crate::spatial::{sin_cos_all, Transform};
use crate::Workspace;

/// Evaluates `$body` with `$x` bound to body `$i`'s `ⁱX_λ` (`ws.x_up[i]`, a `&Transform`) in
/// the cheapest form its joint allows (`ws.plan.up_shapes[i]`, [`JointKind::up_shape`]): the general
/// [`Transform`], a [`Translation`] or an [`AxisTransform`](crate::spatial::AxisTransform) about
/// its axis. `$body` uses [`SpatialTransform`](crate::spatial::SpatialTransform)'s actions and
/// is compiled once for each form.
///
/// [`JointKind::up_shape`]: crate::model::JointKind::up_shape
///
/// `with_up_transform!(shape: s, x_up: x, |x| ...)` takes the form and the transform themselves,
/// for a pass that has already borrowed them from the workspace.
macro_rules! with_up_transform {
    ($ws:expr, $i:expr, |$x:ident| $body:expr) => {
        $crate::algorithms::kinematics::with_up_transform!(
            shape: $ws.plan.up_shapes[$i],
            x_up: &$ws.x_up[$i],
            |$x| $body
        )
    };
    (shape: $shape:expr, x_up: $x_up:expr, |$x:ident| $body:expr) => {{
        use $crate::model::UpShape;
        use $crate::spatial::{AxisTransform, Translation};
        let (shape, x_up): (UpShape, &$crate::spatial::Transform) = ($shape, $x_up);
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
    run_pass!(update_joints_in(model, ws, q))
}

/// [`update_joints`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn update_joints_in(model: &Model, ws: &mut Workspace, q: &[f64]) {
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
            include_str!("../../tests/models/turn_slide.urdf").to_string(),
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
