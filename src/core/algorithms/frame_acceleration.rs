//! The classical acceleration of a link frame (Pinocchio's `getFrameClassicalAcceleration`
//! after `forwardKinematics(q, q̇, q̈)`).
//!
//! Outward along the bodies supporting the frame (body coordinates, base at rest, no gravity):
//!
//! ```text
//! v_i = ⁱX_λ v_λ + S_i q̇_i
//! a_i = ⁱX_λ a_λ + S_i q̈_i + c_J + v_i ×̂ S_i q̇_i
//! ```
//!
//! `a_i` is the spatial acceleration: its linear part is the rate of change of the velocity of
//! the body-fixed point passing through the origin, not the acceleration of a point. The link
//! frame, rigidly attached, has `v_L = ᴸX_B v_B` and `a_L = ᴸX_B a_B` in its own coordinates, and
//! its origin's acceleration is the classical one, `p̈_L = a_L,lin + ω_L × v_L,lin`
//! (in link axes). With `q̈ = 0` this is `J̇ q̇` of the `LocalWorldAligned` Jacobian (turned into
//! link axes for `Local`).

use super::frames::{check_finite, place_support, placement_of, Frame, Placing};
use super::jacobian::ReferenceFrame;
use super::kinematics::with_up_transform;
use super::validate::check_v;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Motion;
use crate::Workspace;

/// The classical acceleration of `frame` at `(q, q̇, q̈)`: `ang` the angular acceleration `ω̇`,
/// `lin` the acceleration `p̈_L` of the link origin, both in link axes for
/// [`ReferenceFrame::Local`] or world axes for [`ReferenceFrame::LocalWorldAligned`].
/// [`ReferenceFrame::World`] is refused: the classical acceleration belongs to a point, and the
/// world origin is not one of the link's. A link fixed to the world has zero acceleration.
pub fn frame_classical_acceleration(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
    frame: &Frame,
    reference: ReferenceFrame,
) -> Result<Motion, DynamicsError> {
    frame.check(model)?;
    check_v(model, "v", v)?;
    check_v(model, "a", a)?;
    if reference == ReferenceFrame::World {
        return Err(DynamicsError::Unsupported {
            method: "frame classical acceleration",
            reason: "it is the acceleration of the link's origin: ask for it in 'local' or 'local_world_aligned' axes, not 'world'".into(),
        });
    }
    place_support(model, ws, q, frame.body, Placing::WithJointTransforms)?;
    let Some(body) = frame.body else {
        return Ok(Motion::zero());
    };
    for k in 0..ws.plan.supports.of(body).len() {
        let i = ws.plan.supports.of(body)[k];
        let b = &model.bodies[i];
        let (s, c, nv) = (&ws.s[i], b.joint.coords, ws.s[i].nv);
        let mut rates = [0.0; 6];
        for (r, x) in rates[..nv].iter_mut().zip(&v[c.v_index..c.v_index + nv]) {
            *r = c.scale * x;
        }
        let v_joint = s.apply(&rates[..nv], 1.0);
        let (v_up, a_up) = match b.parent {
            Some(p) => {
                let (v_p, a_p) = (ws.frame_scratch.v[p], ws.frame_scratch.a[p]);
                with_up_transform!(ws, i, |x| (x.apply_motion(&v_p), x.apply_motion(&a_p)))
            }
            None => (Motion::zero(), Motion::zero()),
        };
        let v_i = v_up + v_joint;
        let mut a_i =
            a_up + s.apply(&a[c.v_index..c.v_index + nv], c.scale) + v_i.cross_motion(&v_joint);
        if let Some(c_joint) = b
            .joint
            .kind
            .bias(&ws.q_joint[i][..b.joint.kind.nq()], &rates[..nv])
        {
            a_i += c_joint;
        }
        ws.frame_scratch.v[i] = v_i;
        ws.frame_scratch.a[i] = a_i;
    }
    let x_bl = &frame.x_body_link;
    let v_l = x_bl.apply_motion(&ws.frame_scratch.v[body]);
    let a_l = x_bl.apply_motion(&ws.frame_scratch.a[body]);
    let local = Motion::new(a_l.ang, a_l.lin + v_l.ang.cross(&v_l.lin));
    let result = match reference {
        ReferenceFrame::Local => local,
        _ => {
            let e = placement_of(&ws.x_world, frame).rot;
            Motion::new(e.tr_mul(&local.ang), e.tr_mul(&local.lin))
        }
    };
    check_finite(
        model,
        frame,
        "frame acceleration",
        result.to_vector().as_slice(),
    )?;
    Ok(result)
}
