//! Inverse dynamics by the recursive Newton–Euler algorithm (handout eqs. 13–16; Featherstone,
//! RBDA Table 5.1).
//!
//! Outward pass, for each body `i` with parent `λ(i)` (quantities in body `i` coordinates):
//!
//! ```text
//! v_i = ⁱX_λ v_λ + S_i q̇_i                          (13)
//! a_i = ⁱX_λ a_λ + S_i q̈_i + c_J + v_i ×̂ S_i q̇_i     (14)
//! f_i = I_i a_i + v_i ×* I_i v_i − f^x_i              (15, first part)
//! ```
//!
//! with the root's `v_0` and `a_0 = a_base − g` (gravity as a fictitious upward acceleration of
//! the world, the handout's eq. 21). Inward pass:
//!
//! ```text
//! τ_i = S_iᵀ f_i                                      (16)
//! f_λ += ⁱX_λᵀ f_i                                    (15, second part)
//! ```
//!
//! A mimic follower uses `q̇_i = μ q̇_leader`, `q̈_i = μ q̈_leader` and adds `μ S_iᵀ f_i` to the
//! leader's `τ`. External wrenches `f^x_i` are given in body `i`'s own frame.
//!
//! `ⁱX_λ` acts in the cheapest form its joint allows (`kinematics::with_up_transform`): a turn
//! about the joint axis after a translation costs 24 flops a vector where a general transform
//! costs 42.

use super::kinematics::{update_joints, with_up_transform};
use super::validate::{check_inverse_inputs, check_result};
use super::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Motion;
use crate::Workspace;

/// `τ = RNEA(q, q̇, q̈)` with gravity, no external wrenches, base at rest. Returns `ws.tau()`.
pub fn rnea<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
) -> Result<&'w [f64], DynamicsError> {
    rnea_with(model, ws, q, v, a, &Externals::none())
}

/// `τ = RNEA(q, q̇, q̈)` with external wrenches and base motion. Returns `ws.tau()`.
pub fn rnea_with<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    check_inverse_inputs(model, ws, q, v, a, ext)?;
    // [X_J, S_i] = jcalc(jtype(i), q_i),  ⁱX_λ(i) = X_J X_T(i)   (RBDA Table 5.1, for every i)
    update_joints(model, ws, q);
    rnea_passes(model, ws, Some(v), Some(a), ext);
    check_result(model, "tau", ws.tau.as_slice())?;
    Ok(ws.tau.as_slice())
}

/// The two passes, on joints already updated for `q`; `None` for `v` or `a` means zero.
/// Writes `ws.v`, `ws.a`, `ws.f` and `ws.tau`.
pub(crate) fn rnea_passes(
    model: &Model,
    ws: &mut Workspace,
    v: Option<&[f64]>,
    a: Option<&[f64]>,
    ext: &Externals<'_>,
) {
    // a_0 = −a_g   (RBDA Table 5.1; plus the root's own acceleration, and v_0 its velocity)
    let a_root = ext.root_acceleration - Motion::new(nalgebra::Vector3::zeros(), model.gravity);
    // The previous body's motion, kept in registers: along a chain it is the parent's, and
    // reading it back from `ws` just after writing it would load across the stores that wrote
    // it, which the processor cannot forward (a stall per body).
    let mut last = (Motion::zero(), Motion::zero());
    for (i, body) in model.bodies.iter().enumerate() {
        let (s, c) = (&ws.s[i], body.joint.coords);
        let nv = s.nv;
        let (v_parent, a_parent) = match body.parent {
            Some(p) if p + 1 == i => last,
            Some(p) => (ws.v[p], ws.a[p]),
            None => (ext.root_velocity, a_root),
        };
        // v_J = S_i q̇_i, c_J   (RBDA Table 5.1's jcalc; a mimic follower's q̇_i = μ q̇_leader)
        let (v_joint, c_joint) = match v {
            Some(v) => {
                let rates = &v[c.v_index..c.v_index + nv];
                let q_joint = &ws.q_joint[i][..body.joint.kind.nq()];
                (
                    s.apply(rates, c.scale),
                    body.joint.kind.bias(q_joint, rates),
                )
            }
            None => (Motion::zero(), None),
        };
        let (v_up, a_up) = with_up_transform!(ws, i, |x| (
            x.apply_motion(&v_parent),
            x.apply_motion(&a_parent)
        ));
        // v_i = ⁱX_λ(i) v_λ(i) + v_J   (RBDA Table 5.1; handout 13)
        let v_i = v_up + v_joint;
        // a_i = ⁱX_λ(i) a_λ(i) + S_i q̈_i + c_J + v_i × v_J   (RBDA Table 5.1; handout 14)
        let mut a_i = a_up + v_i.cross_motion(&v_joint);
        if let Some(c_joint) = c_joint {
            a_i += c_joint;
        }
        if let Some(a) = a {
            a_i += s.apply(&a[c.v_index..c.v_index + nv], c.scale);
        }
        // f_i = I_i a_i + v_i ×* I_i v_i − ⁱX*_0 f^x_i   (RBDA Table 5.1; handout 15): f^x_i is
        // given in body i's frame, so it is subtracted as it is
        let inertia = &body.inertia;
        let mut f_i = inertia.apply(&a_i) + v_i.cross_force(&inertia.apply(&v_i));
        if let Some(w) = ext.wrenches {
            f_i -= w[i];
        }
        ws.v[i] = v_i;
        ws.a[i] = a_i;
        ws.f[i] = f_i;
        last = (v_i, a_i);
    }
    inward_pass(model, ws);
}

/// The inward pass on the body forces `ws.f` (eqs. 15–16): `τ_i = S_iᵀ f_i`,
/// `f_λ += ⁱX_λᵀ f_i`. Writes `ws.tau`; leaves in `ws.f` each joint's transmitted force.
pub(crate) fn inward_pass(model: &Model, ws: &mut Workspace) {
    ws.tau.as_mut_slice().fill(0.0);
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let c = body.joint.coords;
        // τ_i = S_iᵀ f_i   (RBDA Table 5.1; handout 16); a mimic follower's μ S_iᵀ f_i is added
        // to its leader's τ
        for k in 0..ws.s[i].nv {
            ws.tau[c.v_index + k] += c.scale * ws.s[i].project(k, &ws.f[i]);
        }
        if let Some(p) = body.parent {
            // f_λ(i) = f_λ(i) + λ(i)X*_i f_i   (RBDA Table 5.1; handout 15)
            let f_parent = with_up_transform!(ws, i, |x| x.transpose_apply_force(&ws.f[i]));
            ws.f[p] += f_parent;
        }
    }
}
