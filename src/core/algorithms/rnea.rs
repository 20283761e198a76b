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
//! costs 42. A joint whose `S_i` is one signed unit vector `σ e_j` of `[ω; v]` (a revolute or
//! prismatic joint along a coordinate axis) has `S_i q̇_i`, `S_i q̈_i` and `S_iᵀ f_i` as one
//! component and `v_i ×̂ S_i q̇_i` as four products, two for a slide (`along_axis`).

use super::kinematics::{update_joints, with_up_transform};
use super::validate::{check_inverse_inputs, check_result};
use super::Externals;
use crate::error::DynamicsError;
use crate::model::{Body, Model, MotionSubspace};
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
    let Workspace {
        plan,
        s,
        x_up,
        q_joint,
        v: v_body,
        a: a_body,
        f,
        ..
    } = ws;
    let joints = model.bodies.iter().zip(s.iter()).zip(&plan.s_axes);
    let ups = x_up.iter().zip(&plan.up_shapes).zip(q_joint.iter());
    for (i, (((body, s), axes), ((x_up, &shape), q_joint))) in joints.zip(ups).enumerate() {
        let c = body.joint.coords;
        let (v_parent, a_parent) = match body.parent {
            Some(p) if p + 1 == i => last,
            Some(p) => (v_body[p], a_body[p]),
            None => (ext.root_velocity, a_root),
        };
        let (v_up, a_up) = with_up_transform!(shape: shape, x_up: x_up, |x| (
            x.apply_motion(&v_parent),
            x.apply_motion(&a_parent)
        ));
        // v_i = ⁱX_λ(i) v_λ(i) + v_J,   v_J = S_i q̇_i   (RBDA Table 5.1; handout 13)
        // a_i = ⁱX_λ(i) a_λ(i) + S_i q̈_i + c_J + v_i × v_J   (RBDA Table 5.1; handout 14)
        let (v_i, a_i) = match unit_axis(s, axes) {
            Some((j, sign)) => {
                // S_i = σ e_j: q̇_i and q̈_i scaled by σ μ (μ a mimic follower's multiplier)
                let k = sign * c.scale;
                let rate = v.map_or(0.0, |v| k * v[c.v_index]);
                let accel = a.map_or(0.0, |a| k * a[c.v_index]);
                along_axis(j, rate, accel, v_up, a_up)
            }
            None => {
                let q_joint = &q_joint[..body.joint.kind.nq()];
                joint_motion(body, s, q_joint, v, a, v_up, a_up)
            }
        };
        // f_i = I_i a_i + v_i ×* I_i v_i − ⁱX*_0 f^x_i   (RBDA Table 5.1; handout 15): f^x_i is
        // given in body i's frame, so it is subtracted as it is
        let inertia = &body.inertia;
        let mut f_i = inertia.apply(&a_i) + v_i.cross_force(&inertia.apply(&v_i));
        if let Some(w) = ext.wrenches {
            f_i -= w[i];
        }
        v_body[i] = v_i;
        a_body[i] = a_i;
        f[i] = f_i;
        last = (v_i, a_i);
    }
    inward_pass(model, ws);
}

/// The inward pass on the body forces `ws.f` (eqs. 15–16): `τ_i = S_iᵀ f_i`,
/// `f_λ += ⁱX_λᵀ f_i`. Writes `ws.tau`; leaves in `ws.f` each joint's transmitted force.
pub(crate) fn inward_pass(model: &Model, ws: &mut Workspace) {
    let Workspace {
        plan,
        s,
        x_up,
        f,
        tau,
        ..
    } = ws;
    tau.as_mut_slice().fill(0.0);
    let joints = model.bodies.iter().zip(s.iter()).zip(&plan.s_axes);
    let ups = x_up.iter().zip(&plan.up_shapes);
    for (i, (((body, s), axes), (x_up, &shape))) in joints.zip(ups).enumerate().rev() {
        let (c, f_i) = (body.joint.coords, f[i]);
        // τ_i = S_iᵀ f_i   (RBDA Table 5.1; handout 16); a mimic follower's μ S_iᵀ f_i is added
        // to its leader's τ
        match unit_axis(s, axes) {
            // S_i = σ e_j: S_iᵀ f_i is σ times component j of f_i
            Some((j, sign)) => tau[c.v_index] += (sign * c.scale) * f_i.component(j),
            None => {
                for k in 0..s.nv {
                    tau[c.v_index + k] += c.scale * s.project(k, &f_i);
                }
            }
        }
        if let Some(p) = body.parent {
            // f_λ(i) = f_λ(i) + λ(i)X*_i f_i   (RBDA Table 5.1; handout 15)
            let f_parent = with_up_transform!(shape: shape, x_up: x_up, |x| x
                .transpose_apply_force(&f_i));
            f[p] += f_parent;
        }
    }
}

/// `Some((j, σ))` when body `i`'s `S_i` is the one signed unit vector `σ e_j` of `[ω; v]` (`j`
/// in `0..6`, angular first): a revolute or prismatic joint along a coordinate axis
/// ([`Plan::s_axes`](crate::plan::Plan::s_axes)), a joint kind without `c_J`. The passes then read and write one
/// component where `S_i` would be applied ([`along_axis`]).
#[inline(always)]
fn unit_axis(s: &MotionSubspace, axes: &[Option<(usize, f64)>; 6]) -> Option<(usize, f64)> {
    if s.nv == 1 {
        axes[0]
    } else {
        None
    }
}

/// `v_i = v_up + S q̇` and `a_i = a_up + v_i ×̂ S q̇ + S q̈ + c_J` for a joint of any kind
/// (`v_up = ⁱX_λ v_λ`, `a_up = ⁱX_λ a_λ`, body `i` coordinates); `None` for `v` or `a` means
/// zero. `q_joint` holds the joint's own coordinates.
#[inline(always)]
fn joint_motion(
    body: &Body,
    s: &MotionSubspace,
    q_joint: &[f64],
    v: Option<&[f64]>,
    a: Option<&[f64]>,
    v_up: Motion,
    a_up: Motion,
) -> (Motion, Motion) {
    let (c, nv) = (body.joint.coords, s.nv);
    // v_J = S_i q̇_i, c_J   (RBDA Table 5.1's jcalc; a mimic follower's q̇_i = μ q̇_leader)
    let (v_joint, c_joint) = match v {
        Some(v) => {
            let rates = &v[c.v_index..c.v_index + nv];
            (
                s.apply(rates, c.scale),
                body.joint.kind.bias(q_joint, rates),
            )
        }
        None => (Motion::zero(), None),
    };
    let v_i = v_up + v_joint;
    let mut a_i = a_up + v_i.cross_motion(&v_joint);
    if let Some(c_joint) = c_joint {
        a_i += c_joint;
    }
    if let Some(a) = a {
        a_i += s.apply(&a[c.v_index..c.v_index + nv], c.scale);
    }
    (v_i, a_i)
}

/// [`joint_motion`] for `S = σ e_j` ([`unit_axis`]) given `rate = σ μ q̇` and `accel = σ μ q̈`:
/// `v_i = v_up + rate e_j`, `a_i = a_up + rate (v_i ×̂ e_j) + accel e_j`, the cross product with
/// a unit vector four products (two for a slide, [`Motion::add_cross_axis`]) where the general
/// form takes 18. One copy for each `j`, so that the components are known at compile time. For
/// a [`Motion`] or the motion of several states at once (`lanes`), [`AlongAxis`].
#[inline(always)]
pub(crate) fn along_axis<M: AlongAxis>(
    j: usize,
    rate: M::Scalar,
    accel: M::Scalar,
    v_up: M,
    a_up: M,
) -> (M, M) {
    #[inline(always)]
    fn along<M: AlongAxis, const J: usize>(
        rate: M::Scalar,
        accel: M::Scalar,
        v_up: M,
        a_up: M,
    ) -> (M, M) {
        let (mut v_i, mut a_i) = (v_up, a_up);
        v_i.add_along(J, rate);
        a_i.add_cross_axis(&v_i, J, rate);
        a_i.add_along(J, accel);
        (v_i, a_i)
    }
    match j {
        0 => along::<M, 0>(rate, accel, v_up, a_up),
        1 => along::<M, 1>(rate, accel, v_up, a_up),
        2 => along::<M, 2>(rate, accel, v_up, a_up),
        3 => along::<M, 3>(rate, accel, v_up, a_up),
        4 => along::<M, 4>(rate, accel, v_up, a_up),
        _ => along::<M, 5>(rate, accel, v_up, a_up),
    }
}

/// The two updates [`along_axis`] makes to a motion `[ω; v]` along component `j` of a unit
/// axis: `x e_j` added, and `w (m ×̂ e_j)` added.
pub(crate) trait AlongAxis: Copy {
    /// One value: `f64`, or one for each of several states.
    type Scalar: Copy;
    /// `self += x e_j`.
    fn add_along(&mut self, j: usize, x: Self::Scalar);
    /// `self += w (m ×̂ e_j)`.
    fn add_cross_axis(&mut self, m: &Self, j: usize, w: Self::Scalar);
}

impl AlongAxis for Motion {
    type Scalar = f64;
    #[inline(always)]
    fn add_along(&mut self, j: usize, x: f64) {
        Motion::add_along(self, j, x)
    }
    #[inline(always)]
    fn add_cross_axis(&mut self, m: &Motion, j: usize, w: f64) {
        Motion::add_cross_axis(self, m, j, w)
    }
}
