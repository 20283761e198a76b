//! The three quantities of one measured joint state, computed together: what the node publishes
//! for it, and the efforts that explain the measured motion.
//!
//! ```text
//! g  = RNEA(q, 0, 0)                  gravity torques                       (node: gravity_effort)
//! q̈  = FD(q, q̇, τ_cmd)                forward dynamics by a chosen method   (node: acceleration)
//! τ  = RNEA(q, q̇, q̈_measured)         inverse dynamics of the measured motion (optional)
//! ```
//!
//! Called one by one ([`gravity`](super::gravity()), [`forward_dynamics`](super::forward_dynamics()),
//! [`rnea`](super::rnea())) each recomputes the joint transforms `ⁱX_λ(q)` and motion subspaces;
//! here they are computed once. So is the first (velocity) pass of ABA, which leaves, in world
//! (root) coordinates, everything the two RNEA evaluations need (see [`aba`](mod@super::aba)):
//! placements `ⁱX_0`, axes `⁰S_i`, body velocities `v_i`, velocity-product accelerations
//! `c_i = ⁰X_i c_J + v_i ×̂ ⁰S_i q̇_i`, inertias `⁰I_i` and bias forces `p_i = v_i ×* ⁰I_i v_i`.
//!
//! RNEA (handout eqs. 13–16) holds in any one frame; in the world frame a spatial vector needs
//! no transform on its way between bodies, and the passes are (all quantities in world
//! coordinates, which here, as in ABA, means the world's axes about an anchor body's origin;
//! at an anchor, `a_λ` enters as `xlt(r_i) a_λ` and `f_i`, `f^g_i` leave as `xlt(r_i)ᵀ f`):
//!
//! ```text
//! outward:  a_i   = a_λ + c_i + ⁰S_i q̈_i          a_0 = [0; −g] (gravity as a fictitious
//!           f_i   = ⁰I_i a_i + p_i                              upward acceleration, eq. 21)
//!           f^g_i = ⁰I_i [0; −g]                   (q̇ = q̈ = 0: every body accelerates as the root)
//! inward:   τ_i = ⁰S_iᵀ f_i,   g_i = ⁰S_iᵀ f^g_i,   f_λ += f_i,   f^g_λ += f^g_i
//! ```
//!
//! A mimic follower moves with `μ q̇_leader`, `μ q̈_leader` and adds `μ ⁰S_iᵀ f_i` to its
//! leader's effort, as in [`rnea`](fn@super::rnea). Base at rest in an inertial frame, no external
//! wrenches. With `aba` the two RNEA passes run between ABA's first and second passes (before
//! the second overwrites `⁰I_i` and `p_i` with articulated quantities); with `crba` and
//! `rnea_columns` forward dynamics runs first, on the same joint transforms, then ABA's first
//! pass for the world-frame quantities.

use super::aba::{acceleration_pass, articulated_pass, refuse_mimic, velocity_pass};
use super::forward_dynamics::crba_solve_on_joints;
use super::kinematics::{force_out_of_aligned, motion_into_aligned, update_joints};
use super::rnea_columns::rnea_columns;
use super::validate::{check_q, check_result, check_v};
use super::{Externals, ForwardDynamicsMethod};
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::{Force, Motion, Vector3};
use crate::Workspace;

/// One joint state: `q`, `q̇` (measured), the commanded effort `τ_cmd` and, when it could be
/// estimated, the measured acceleration `q̈` (all in model coordinate order).
#[derive(Clone, Copy, Debug)]
pub struct JointStateInputs<'a> {
    /// Positions, `nq` values.
    pub q: &'a [f64],
    /// Velocities, `nv` values.
    pub v: &'a [f64],
    /// Commanded effort for forward dynamics, `nv` values.
    pub effort_command: &'a [f64],
    /// Measured acceleration for inverse dynamics, `nv` values; `None`: no inverse dynamics.
    pub measured_acceleration: Option<&'a [f64]>,
}

/// The results of [`joint_state_outputs`], `nv` values each, sized once for a model.
#[derive(Clone, Debug)]
pub struct JointStateOutputs {
    gravity: Vec<f64>,
    acceleration: Vec<f64>,
    inverse_dynamics: Vec<f64>,
}

impl JointStateOutputs {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        JointStateOutputs {
            gravity: vec![0.0; model.nv],
            acceleration: vec![0.0; model.nv],
            inverse_dynamics: vec![0.0; model.nv],
        }
    }

    /// `g(q)`, the efforts that hold the robot still against gravity.
    pub fn gravity(&self) -> &[f64] {
        &self.gravity
    }

    /// `q̈ = FD(q, q̇, τ_cmd)`.
    pub fn acceleration(&self) -> &[f64] {
        &self.acceleration
    }

    /// `τ = RNEA(q, q̇, q̈_measured)`; zero after a call without a measured acceleration.
    pub fn inverse_dynamics(&self) -> &[f64] {
        &self.inverse_dynamics
    }
}

/// Gravity, forward dynamics by `method` and (when `input` has a measured acceleration) inverse
/// dynamics at one state, into `out`; nothing is allocated. The same numbers as
/// [`gravity`](super::gravity()), [`forward_dynamics`](super::forward_dynamics()) and
/// [`rnea`](super::rnea()) (to rounding). On an error none of `out` is to be used: call those
/// to learn which of the three failed.
pub fn joint_state_outputs(
    model: &Model,
    ws: &mut Workspace,
    method: ForwardDynamicsMethod,
    input: &JointStateInputs<'_>,
    out: &mut JointStateOutputs,
) -> Result<(), DynamicsError> {
    let JointStateInputs {
        q,
        v,
        effort_command: tau,
        measured_acceleration: a,
    } = *input;
    check_q(model, ws, q)?;
    check_v(model, "v", v)?;
    check_v(model, "tau", tau)?;
    if let Some(a) = a {
        check_v(model, "a", a)?;
    }
    if out.gravity.len() != model.nv {
        return Err(DynamicsError::Length {
            vector: "outputs",
            expected: model.nv,
            got: out.gravity.len(),
        });
    }
    let ext = Externals::none();
    match method {
        ForwardDynamicsMethod::Aba => {
            refuse_mimic(model)?;
            update_joints(model, ws, q);
            velocity_pass(model, ws, v, &ext);
            world_rnea(model, ws, a, out);
            articulated_pass(model, ws, tau)?;
            acceleration_pass(model, ws, &ext);
        }
        ForwardDynamicsMethod::Crba => {
            update_joints(model, ws, q);
            crba_solve_on_joints(model, ws, v, tau, &ext)?;
            velocity_pass(model, ws, v, &ext);
            world_rnea(model, ws, a, out);
        }
        ForwardDynamicsMethod::RneaColumns => {
            // The method is n+1 complete RNEA calls by definition (each with its own joint
            // transforms); only the passes after it share one set.
            rnea_columns(model, ws, q, v, tau, &ext)?;
            update_joints(model, ws, q);
            velocity_pass(model, ws, v, &ext);
            world_rnea(model, ws, a, out);
        }
    }
    check_result(model, "acceleration", ws.qdd.as_slice())?;
    out.acceleration.copy_from_slice(ws.qdd.as_slice());
    check_result(model, "gravity", &out.gravity)?;
    if a.is_some() {
        check_result(model, "tau", &out.inverse_dynamics)?;
    }
    Ok(())
}

/// Gravity and (with `a`) inverse dynamics in world coordinates from ABA's first pass (see the
/// module documentation). Uses `ws.a_world` and `ws.f_outputs` as scratch.
fn world_rnea(model: &Model, ws: &mut Workspace, a: Option<&[f64]>, out: &mut JointStateOutputs) {
    let minus_g = -model.gravity;
    let a_root = Motion::new(Vector3::zeros(), minus_g);
    for (i, body) in model.bodies.iter().enumerate() {
        let inertia = &ws.ia[i];
        // ⁰I_i [0; −g]: the last three columns of ⁰I_i times −g.
        let f_gravity = Force::from_vector(&(inertia.fixed_columns::<3>(3) * minus_g));
        let f = match a {
            Some(a) => {
                let (s, c) = (&ws.s_world[i], body.joint.coords);
                let a_parent =
                    motion_into_aligned(ws, i, body.parent.map_or(a_root, |p| ws.a_world[p]));
                let a_i = a_parent + ws.c[i] + s.apply(&a[c.v_index..c.v_index + s.nv], c.scale);
                ws.a_world[i] = a_i;
                Force::from_vector(&(inertia * a_i.to_vector())) + ws.pa[i]
            }
            None => Force::zero(),
        };
        ws.f_outputs[i] = [f, f_gravity];
    }
    out.gravity.fill(0.0);
    out.inverse_dynamics.fill(0.0);
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let (s, c) = (&ws.s_world[i], body.joint.coords);
        let [f, f_gravity] = ws.f_outputs[i];
        for k in 0..s.nv {
            out.gravity[c.v_index + k] += c.scale * s.project(k, &f_gravity);
            out.inverse_dynamics[c.v_index + k] += c.scale * s.project(k, &f);
        }
        if let Some(p) = body.parent {
            let (f, f_gravity) = (
                force_out_of_aligned(ws, i, f),
                force_out_of_aligned(ws, i, f_gravity),
            );
            ws.f_outputs[p][0] += f;
            ws.f_outputs[p][1] += f_gravity;
        }
    }
}
