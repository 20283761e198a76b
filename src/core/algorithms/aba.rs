//! Forward dynamics in O(n) by the articulated-body algorithm (Featherstone, RBDA Table 7.1),
//! with every spatial quantity in world-aligned coordinates, as Pinocchio's `aba` in its WORLD
//! convention does: the recursion holds in any one frame, and in the world frame an
//! articulated inertia needs no 6×6 transform on its way to the parent. Each body's inertia and
//! joint axes are carried to the world once, by its placement `⁰X_i`.
//!
//! "World" frames here have the world's axes and their origin at an anchor body, a root or a
//! body a few links further out (`kinematics::update_aligned_placements`): `q̈` does not depend
//! on the origin, but an inertia about a point `d` away carries `m d²` terms that cancel, so a
//! robot far from the world origin, or the far end of a long chain about its root, would lose
//! digits. Where body `i` anchors a frame at `r_i` in its parent's, quantities cross by the
//! translation `xlt(r_i)` (the root's motion and gravity, `a_0`, `v_0`, likewise into the root's
//! frame; gravity is the same about every point); elsewhere `xlt` is the identity.
//!
//! Pass 1, outward (`ⁱX_0 = ⁱX_λ ᵏX_0`, `S_i ← ⁰X_i S_i`, `I_i ← ⁰X_i⁻ᵀ I_i ⁱX_0`):
//! ```text
//! v_i = xlt(r_i) v_λ + S_i q̇_i,    c_i = ⁰X_i c_J + v_i ×̂ S_i q̇_i
//! I^A_i = I_i,                     p^A_i = v_i ×* I_i v_i − ⁰X_i⁻ᵀ f^x_i
//! ```
//! Pass 2, inward:
//! ```text
//! U_i = I^A_i S_i,   D_i = S_iᵀ U_i,   u_i = τ_i − S_iᵀ p^A_i
//! I^a = I^A_i − U_i D_i⁻¹ U_iᵀ,   p^a = p^A_i + I^a c_i + U_i D_i⁻¹ u_i
//! I^A_λ += xlt(r_i)ᵀ I^a xlt(r_i),   p^A_λ += xlt(r_i)ᵀ p^a
//! ```
//! Pass 3, outward, from `a_0 = a_base − g`:
//! ```text
//! a' = xlt(r_i) a_λ + c_i,   q̈_i = D_i⁻¹ (u_i − U_iᵀ a'),   a_i = a' + S_i q̈_i
//! ```
//! (`c_i` in the world frame: the world-frame `S` moves with the body, `d(⁰X_i S_i)/dt =
//! v_i ×̂ ⁰X_i S_i + ⁰X_i S̊_i`.) Down a chain of one-dof joints pass 3 writes
//! `U_iᵀ a' = U_iᵀ (a'_λ + c_i) + (U_iᵀ S_λ) q̈_λ`, all of it known but one multiply-add before
//! the parent's `q̈_λ` ([`accelerate_one_dof_below_one_dof`]). Passes 2 and 3 take these
//! equations in one of three forms by joint: one degree of freedom (`D_i` a scalar,
//! `articulate_one_dof`), a floating root
//! (`S_i` invertible and orthonormal in world axes: `a_i = (I^A_i)⁻¹ (S_i τ_i − p^A_i)`,
//! `q̈_i = S_iᵀ (a_i − a')`, `articulate_floating_root`), any other
//! (`articulate`). Mimic joints tie coordinates across bodies, which the
//! recursion cannot express: models with them are refused (use the `crba` or `rnea_columns`
//! method).

use super::cholesky::{spd_inverse, spd_solve};
use super::kinematics::{
    force_across_anchor, motion_across_anchor, update_aligned_placements, update_joints,
    world_axes, Anchors,
};
use super::validate::{check_forward_inputs, check_result};
use super::Externals;
use crate::error::DynamicsError;
use crate::instruction_set::run_pass;
use crate::model::{Body, JointKind, Model, MotionSubspace};
use crate::mul_add::MulAdd;
use crate::spatial::{Force, Matrix3, Matrix6, Motion, Translation, Vector3};
use crate::Workspace;
use nalgebra::Vector6;

/// `q̈ = FD(q, q̇, τ)` into `ws.qdd()`.
pub fn aba<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    refuse_mimic(model)?;
    aba_on_checked_inputs(model, ws, q, v, tau, ext)
}

/// [`aba`] without its input checks, for a caller that has established them: `ws` was made for
/// `model`, which has no mimic joint; `q`, `v`, `τ` have the model's lengths and finite values,
/// every floating joint's quaternion is not (near) zero; the externals are finite, one wrench
/// per body. The result is checked (`q̈` finite, the error naming the first coordinate that is
/// not).
#[inline(always)]
pub(crate) fn aba_on_checked_inputs<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<&'w [f64], DynamicsError> {
    // [X_J, S_i] = jcalc(jtype(i), q_i),  ⁱX_λ(i) = X_J X_T(i)   (RBDA Table 7.1, for every i)
    update_joints(model, ws, q);
    velocity_pass(model, ws, v, ext);
    articulated_pass(model, ws, tau)?;
    acceleration_pass(model, ws, ext);
    check_result(model, "acceleration", ws.qdd.as_slice())?;
    Ok(ws.qdd.as_slice())
}

/// The error for a model with mimic joints, which the recursion cannot express.
pub(crate) fn refuse_mimic(model: &Model) -> Result<(), DynamicsError> {
    match model.bodies.iter().find(|b| b.joint.is_mimic()) {
        Some(b) => Err(DynamicsError::Unsupported {
            method: "aba",
            reason: format!(
                "joint '{}' mimics another joint; use 'crba' or 'rnea_columns'",
                b.joint.name
            ),
        }),
        None => Ok(()),
    }
}

/// Pass 1: placements, world-frame axes, velocities, velocity-product accelerations, initial
/// articulated quantities (joints already updated). A mimic follower moves with `μ q̇_leader`
/// (a 1-DOF joint: its `c_J` is zero), so these quantities are right for mimic models too.
#[inline]
pub(crate) fn velocity_pass(model: &Model, ws: &mut Workspace, v: &[f64], ext: &Externals<'_>) {
    // ⁱX_0 = ⁱX_λ(i) λ(i)X_0   (RBDA Table 7.1), from each body's aligned frame
    update_aligned_placements(model, ws, Anchors::Spaced);
    velocities(model, ws, v, ext);
    rigid_inertias(model, ws);
    rigid_bias_forces(model, ws, ext);
}

/// Pass 1's world-frame axes `S_i`, velocities `v_i` and velocity-product accelerations `c_i`
/// from the placements.
fn velocities(model: &Model, ws: &mut Workspace, v: &[f64], ext: &Externals<'_>) {
    run_pass!(velocities_in(model, ws, v, ext))
}

/// [`velocities`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn velocities_in(model: &Model, ws: &mut Workspace, v: &[f64], ext: &Externals<'_>) {
    let Workspace {
        plan,
        s,
        x_aligned,
        s_world,
        v_world,
        c: c_world,
        q_joint,
        anchor_shift,
        ..
    } = ws;
    // Zipped slices: one pointer step per body; only the parent's velocity is indexed.
    let bodies = model.bodies.iter().zip(s.iter()).zip(&plan.s_axes);
    let frames = x_aligned
        .iter()
        .zip(plan.anchors.iter().zip(anchor_shift.iter()));
    let outputs = s_world.iter_mut().zip(c_world.iter_mut());
    // The previous body's velocity, kept for a child that follows its parent (a chain).
    let mut v_previous = ext.root_velocity;
    for (i, (((body, s), axes), ((x, (&anchor, shift)), (s_world, c_i)))) in
        bodies.zip(frames.zip(outputs)).enumerate()
    {
        let coords = body.joint.coords;
        let rates = &v[coords.v_index..coords.v_index + s.nv];
        // v_J = S_i q̇_i   (RBDA Table 7.1's jcalc), with S_i ← ⁰X_i S_i in world coordinates
        let v_joint = world_axes(x, s, axes, s_world, rates, coords.scale);
        let v_parent = match body.parent {
            Some(p) if p + 1 == i => v_previous,
            Some(p) => v_world[p],
            None => ext.root_velocity,
        };
        // v_i = ⁱX_λ(i) v_λ(i) + v_J   (RBDA Table 7.1): in world coordinates ⁱX_λ(i) is the
        // identity, xlt(r_i) where body i anchors a frame
        let v_i = motion_across_anchor(anchor, shift, v_parent) + v_joint;
        v_world[i] = v_i;
        v_previous = v_i;
        // c_i = c_J + v_i × v_J   (RBDA Table 7.1), c_J carried into world coordinates
        *c_i = v_i.cross_motion(&v_joint);
        // Only a planar joint's S moves in its child frame: the others' c_J is zero, known
        // without calling `JointKind::bias`.
        if matches!(body.joint.kind, JointKind::Planar { .. }) {
            let q_joint = &q_joint[i][..body.joint.kind.nq()];
            if let Some(c_joint) = body.joint.kind.bias(q_joint, rates) {
                *c_i += x.inverse_apply_motion(&c_joint);
            }
        }
    }
}

/// Pass 1's initial articulated inertias, `I^A_i = I_i` in world coordinates, from the
/// placements: each as the 6×6 `ws.ia[i]` and, for [`rigid_bias_forces`], in its compact form
/// `(m, h, Ī)` in `ws.ic[i]`. A function of its own, not inlined, and apart from the bias
/// forces: with the kinematics of [`velocity_pass`] or the products of `p^A_i` in the same
/// loop, the processor's registers overflow to the stack.
fn rigid_inertias(model: &Model, ws: &mut Workspace) {
    run_pass!(rigid_inertias_in(model, ws))
}

/// [`rigid_inertias`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn rigid_inertias_in(model: &Model, ws: &mut Workspace) {
    // Zipped slices: one pointer step per body, no index arithmetic or bounds checks.
    let bodies = model.bodies.iter().zip(&ws.x_aligned);
    let outputs = ws.ia.iter_mut().zip(ws.ic.iter_mut());
    for ((body, x), (ia, ic)) in bodies.zip(outputs) {
        // I^A_i = I_i   (RBDA Table 7.1): ⁰X_i⁻ᵀ I_i ⁱX_0, in world coordinates
        let inertia = x.transpose_apply_inertia(&body.inertia);
        inertia.write_matrix(ia);
        *ic = inertia;
    }
}

/// Pass 1's initial articulated bias forces `p^A_i` from the velocities and the rigid inertias
/// in world coordinates ([`rigid_inertias`]).
fn rigid_bias_forces(model: &Model, ws: &mut Workspace, ext: &Externals<'_>) {
    run_pass!(rigid_bias_forces_in(model, ws, ext; mul_add))
}

/// [`rigid_bias_forces`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn rigid_bias_forces_in(model: &Model, ws: &mut Workspace, ext: &Externals<'_>, mul_add: MulAdd) {
    let n = model.bodies.len();
    // Zipped slices: one pointer step per body.
    let bodies = ws.x_aligned[..n].iter().zip(&ws.ic).zip(&ws.v_world);
    for (i, (((x, inertia), v_i), pa)) in bodies.zip(ws.pa.iter_mut()).enumerate() {
        // p^A_i = v_i ×* I_i v_i − ⁱX*_0 f^x_i   (RBDA Table 7.1): f^x_i is given in body i's
        // frame, carried into world coordinates by ⁱX_0ᵀ
        *pa = v_i.cross_force_with(&inertia.apply_with(v_i, mul_add), mul_add);
        if let Some(w) = ext.wrenches {
            *pa -= x.transpose_apply_force(&w[i]);
        }
    }
}

/// The bodies' slots that pass 2 reads and writes, each slice exactly one per body: with the
/// lengths known and held apart from the workspace, indexing by body needs no bounds check,
/// and no length is read again after each store.
struct Slots<'w> {
    anchors: &'w [bool],
    anchor_shift: &'w [Vector3],
    s_world: &'w [MotionSubspace],
    c: &'w [Motion],
    ia: &'w mut [Matrix6],
    pa: &'w mut [Force],
    u: &'w mut [[Force; 6]],
    d_inv: &'w mut [Matrix6],
    u_bias: &'w mut [[f64; 6]],
}

impl<'w> Slots<'w> {
    /// The slots of the `n` bodies of `ws`.
    #[inline(always)]
    fn of(ws: &'w mut Workspace, n: usize) -> Self {
        Slots {
            anchors: &ws.plan.anchors[..n],
            anchor_shift: &ws.anchor_shift[..n],
            s_world: &ws.s_world[..n],
            c: &ws.c[..n],
            ia: &mut ws.ia[..n],
            pa: &mut ws.pa[..n],
            u: &mut ws.u[..n],
            d_inv: &mut ws.d_inv[..n],
            u_bias: &mut ws.u_bias[..n],
        }
    }
}

/// Pass 2: articulated-body inertias and bias forces, from the leaves inward.
pub(crate) fn articulated_pass(
    model: &Model,
    ws: &mut Workspace,
    tau: &[f64],
) -> Result<(), DynamicsError> {
    run_pass!(articulated_pass_in(model, ws, tau; mul_add))
}

/// [`articulated_pass`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn articulated_pass_in(
    model: &Model,
    ws: &mut Workspace,
    tau: &[f64],
    mul_add: MulAdd,
) -> Result<(), DynamicsError> {
    let slots = &mut Slots::of(ws, model.bodies.len());
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let tau_i = &tau[body.joint.coords.v_index..];
        let articulated = if slots.s_world[i].nv == 1 {
            articulate_one_dof(slots, i, tau_i[0], body.parent, mul_add)
        } else if is_floating_root(body) {
            articulate_floating_root(slots, i, tau_i)
        } else {
            articulate(slots, i, tau_i, body.parent)
        };
        if let Err((k, pivot)) = articulated {
            return Err(singular_pivot(model, i, k, pivot));
        }
    }
    Ok(())
}

/// `I^A_λ(i) = I^A_λ(i) + λ(i)X*_i I^a ⁱX_λ(i)`, `p^A_λ(i) = p^A_λ(i) + λ(i)X*_i p^a` (RBDA Table
/// 7.1) with `I^a`, `p^a` in body `i`'s slots of `slots.ia`, `slots.pa`, and `p` its parent:
/// in world coordinates the transforms are the identity, `xlt(r_i)` where body `i` anchors its
/// own frame.
fn add_to_parent(slots: &mut Slots<'_>, i: usize, p: usize) {
    if slots.anchors[i] {
        slots.ia[i] = Translation(slots.anchor_shift[i]).transpose_apply_matrix6(&slots.ia[i]);
    }
    let pa_i = force_across_anchor(slots.anchors[i], &slots.anchor_shift[i], slots.pa[i]);
    // The parent comes before the child: split so both can be borrowed.
    let (before, from_i) = slots.ia.split_at_mut(i);
    before[p] += from_i[0];
    slots.pa[p] += pa_i;
}

/// Pass 2 at body `i` with a joint of any number of degrees of freedom: `U_i`, `D_i⁻¹`, `u_i`
/// into `slots.u`, `slots.d_inv`, `slots.u_bias` and, below a parent, `I^a`, `p^a` over
/// `I^A_i`, `p^A_i` (which body `i` no longer needs), added to the parent's
/// ([`add_to_parent`]). `tau` starts at the joint's first coordinate. `Err((k, pivot))` for a pivot of `D_i` that fails ([`invert_spd`]).
fn articulate(
    slots: &mut Slots<'_>,
    i: usize,
    tau: &[f64],
    parent: Option<usize>,
) -> Result<(), (usize, f64)> {
    // Work on body i's slots in place (each is a 6×6 or six 6-vectors: no copies).
    let s = &slots.s_world[i];
    let nv = s.nv;
    let (u_cols, d_inv, u) = (&mut slots.u[i], &mut slots.d_inv[i], &mut slots.u_bias[i]);
    // Only D's top-left nv × nv block is used.
    let mut d = Matrix6::zeros();
    for k in 0..nv {
        // U_i = I^A_i S_i   (RBDA Table 7.1)
        u_cols[k] = Force::from_vector(&(slots.ia[i] * s.cols[k].to_vector()));
    }
    for k in 0..nv {
        for k2 in 0..nv {
            d[(k2, k)] = s.project(k2, &u_cols[k]); // D_i = S_iᵀ U_i   (RBDA Table 7.1)
        }
        // u_i = τ_i − S_iᵀ p^A_i   (RBDA Table 7.1)
        u[k] = tau[k] - s.project(k, &slots.pa[i]);
    }
    invert_spd(&d, nv, &slots.ia[i], d_inv)?;
    if let Some(p) = parent {
        // I^a = I^A_i − U_i D_i⁻¹ U_iᵀ,  p^a = p^A_i + I^a c_i + U_i D_i⁻¹ u_i   (RBDA
        // Table 7.1).
        for k in 0..nv {
            let mut d_inv_u = 0.0;
            let mut w = Force::zero();
            for k2 in 0..nv {
                d_inv_u += d_inv[(k, k2)] * u[k2];
                w += u_cols[k2] * d_inv[(k, k2)];
            }
            // Σ_k U_k (D⁻¹ Uᵀ)_k: w is row k of D⁻¹ applied to U's columns.
            slots.ia[i] -= u_cols[k].to_vector() * w.to_vector().transpose();
            slots.pa[i] += u_cols[k] * d_inv_u;
        }
        let bias = Force::from_vector(&(slots.ia[i] * slots.c[i].to_vector()));
        slots.pa[i] += bias;
        add_to_parent(slots, i, p);
    }
    Ok(())
}

/// [`articulate`] for a joint of one degree of freedom, where `U_i` is one column and `D_i` a
/// scalar: `D⁻¹` is one division and `I^a = I^A_i − U_i w_iᵀ` (`w_i = D_i⁻¹ U_i`) a rank-1
/// update. Where body `i` shares its parent's frame, each column of `I^a` is made, added to
/// the parent's and multiplied into `I^a c_i` in one sweep ([`add_one_dof_to_parent`]);
/// across an anchor `I^a` is made in place, then moved.
#[inline(always)]
fn articulate_one_dof(
    slots: &mut Slots<'_>,
    i: usize,
    tau: f64,
    parent: Option<usize>,
    mul_add: MulAdd,
) -> Result<(), (usize, f64)> {
    let s = slots.s_world[i].cols[0].to_vector();
    let ia = &slots.ia[i];
    // U_i = I^A_i S_i,   D_i = S_iᵀ U_i,   u_i = τ_i − S_iᵀ p^A_i   (RBDA Table 7.1)
    let u_col = mul_add.matrix_vector(ia, &s);
    let d = mul_add.dot(&s, &u_col);
    let u = tau - mul_add.dot(&s, &slots.pa[i].to_vector());
    let d_inv = 1.0 / d;
    (slots.u[i][0], slots.d_inv[i][(0, 0)], slots.u_bias[i][0]) =
        (Force::from_vector(&u_col), d_inv, u);
    if !pivot_is_sound_for(d, ia) {
        return Err((0, d));
    }
    let Some(p) = parent else {
        return Ok(());
    };
    // I^a = I^A_i − U_i D_i⁻¹ U_iᵀ,  p^a = p^A_i + I^a c_i + U_i D_i⁻¹ u_i   (RBDA Table 7.1)
    let w = u_col * d_inv;
    let joint_force = Force::from_vector(&(u_col * (d_inv * u)));
    if slots.anchors[i] {
        let ia = &mut slots.ia[i];
        for j in 0..6 {
            let column = mul_add.sub_scaled(&ia.column(j).into(), w[j], &u_col);
            ia.set_column(j, &column);
        }
        let bias = Force::from_vector(&mul_add.matrix_vector(ia, &slots.c[i].to_vector()));
        slots.pa[i] += bias + joint_force;
        add_to_parent(slots, i, p);
    } else {
        let bias = add_one_dof_to_parent(slots, i, p, (&u_col, &w), mul_add);
        slots.pa[i] += bias + joint_force;
        let pa_i = slots.pa[i];
        slots.pa[p] += pa_i;
    }
    Ok(())
}

/// `I^A_λ += I^a` and `I^a c_i` (returned) for `I^a = I^A_i − U_i w_iᵀ`, column by column:
/// column `j` of `I^a` is made once, added to the parent's `I^A_λ` and taken `c_{i,j}` times
/// into the product, and never stored (`slots.ia[i]` keeps `I^A_i`). For a body in its parent's
/// aligned frame.
#[inline(always)]
fn add_one_dof_to_parent(
    slots: &mut Slots<'_>,
    i: usize,
    p: usize,
    (u_col, w): (&Vector6<f64>, &Vector6<f64>),
    mul_add: MulAdd,
) -> Force {
    let c = slots.c[i].to_vector();
    let (before, from_i) = slots.ia.split_at_mut(i);
    let (parent, ia) = (&mut before[p], &from_i[0]);
    let mut bias = Vector6::zeros();
    for j in 0..6 {
        let column = mul_add.sub_scaled(&ia.column(j).into(), w[j], u_col);
        let mut parent_column = parent.column_mut(j);
        parent_column += column;
        if j == 0 {
            bias = column * c[0];
        } else {
            bias = mul_add.axpy(c[j], &column, &bias);
        }
    }
    Force::from_vector(&bias)
}

/// Whether body `i` hangs from the world by a floating joint: its `S_i` is then invertible,
/// and in world axes orthonormal (`S_i = [0 R; R 0]`, `R`'s columns the body's axes in world
/// coordinates, the translations first as the joint's coordinates are), so that
/// `S_i⁻¹ = S_iᵀ`.
fn is_floating_root(body: &Body) -> bool {
    body.parent.is_none() && body.joint.kind == JointKind::Floating
}

/// Pass 2 at a floating root ([`is_floating_root`]): its acceleration in world axes into
/// `slots.u_bias[i]` (translations first), without `U_i` or `D_i`. As `S_i` is invertible,
/// `q̈_i = D_i⁻¹ (u_i − U_iᵀ a') = S_i⁻¹ (I^A_i)⁻¹ S_i⁻ᵀ u_i − S_i⁻¹ a'`, so
/// `a_i = a' + S_i q̈_i = (I^A_i)⁻¹ S_i⁻ᵀ u_i = (I^A_i)⁻¹ (S_i⁻ᵀ τ_i − p^A_i)`: the root's
/// acceleration is its articulated inertia's answer to the forces alone, and `S_i⁻ᵀ = S_i`. It
/// is solved by one `L D Lᵀ` factorisation ([`ldlt_by_blocks`]) of `I^A_i` with its
/// translations first (`[C Bᵀ; B A]` for `I^A_i = [A B; Bᵀ C]`, angular rows first), as the
/// joint orders its coordinates: no 3×3 block is turned into the body's axes. A pivot that
/// fails is named as `D_i` in the body's axes names it ([`floating_root_pivot`]). Not inlined:
/// once per call, it would only crowd the registers of the one-dof bodies' loop.
#[inline(never)]
fn articulate_floating_root(
    slots: &mut Slots<'_>,
    i: usize,
    tau: &[f64],
) -> Result<(), (usize, f64)> {
    let s = &slots.s_world[i];
    let ia = &slots.ia[i];
    // S_i τ_i − p^A_i, a force in world axes
    let s_tau = s.cols[1..6]
        .iter()
        .zip(&tau[1..6])
        .fold(s.cols[0] * tau[0], |sum, (col, t)| sum + *col * *t);
    let b = Force::new(s_tau.ang, s_tau.lin) - slots.pa[i];
    let y = &mut slots.u_bias[i];
    *y = [b.lin.x, b.lin.y, b.lin.z, b.ang.x, b.ang.y, b.ang.z];
    let solved = ldlt_by_blocks::solve(ia, |pivot| pivot_is_sound_for(pivot, ia), y);
    solved.map_err(|world| floating_root_pivot(slots, i).unwrap_or(world))
}

/// The floating root's `I^A y = b` with its translations first, `[C Bᵀ; B A] y = b` for
/// `I^A = [A B; Bᵀ C]` (angular rows first), by the square-root-free Cholesky factorisation
/// `M = L D Lᵀ` (`L` unit lower triangular) taken in blocks of three, so that every loop has a
/// fixed length of at most three and unrolls: with `M = [P Qᵀ; Q R]` (`P = C`, `Q = B`,
/// `R = A`),
/// ```text
/// P = L₁ D₁ L₁ᵀ,   T = Q L₁⁻ᵀ,   L₂₁ = T D₁⁻¹,   R − L₂₁ Tᵀ = L₂ D₂ L₂ᵀ,
/// L₁ z₁ = b₁,   L₂ z₂ = b₂ − L₂₁ z₁,   L₂ᵀ x₂ = D₂⁻¹ z₂,   L₁ᵀ x₁ = D₁⁻¹ z₁ − L₂₁ᵀ x₂
/// ```
/// Each pivot `D_jj` is the square of the Cholesky factor's diagonal entry that
/// [`spd_solve`] makes, tested by `sound` in the same order (`Err((k, pivot))`, `k` the row of
/// `M`); a pivot costs one division and no square root, which the chain of pivots would wait
/// on.
mod ldlt_by_blocks {
    use crate::spatial::Matrix6;

    /// A unit lower-triangular 3×3 factor, row by row (the entries below the diagonal), and
    /// the reciprocals of its pivots `D_jj`.
    struct Factor {
        l: [[f64; 3]; 3],
        inv_d: [f64; 3],
    }

    /// `I^A y = b` in the order of the floating joint's coordinates (see the module above);
    /// reads the lower triangles of `ia`'s blocks `A` and `C`, and its block `B`.
    #[inline(always)]
    pub(super) fn solve(
        ia: &Matrix6,
        sound: impl Fn(f64) -> bool,
        b: &mut [f64; 6],
    ) -> Result<(), (usize, f64)> {
        // P = C (rows and columns 3..6 of I^A), Q = B (rows 0..3, columns 3..6), R = A.
        let first = factor(|j, k| ia[(3 + j, 3 + k)], &sound, 0)?;
        // T = Q L₁⁻ᵀ row by row, L₂₁ = T D₁⁻¹
        let mut t = [[0.0; 3]; 3];
        let mut l21 = [[0.0; 3]; 3];
        for r in 0..3 {
            t[r] = forward(&first, [ia[(r, 3)], ia[(r, 4)], ia[(r, 5)]]);
            for k in 0..3 {
                l21[r][k] = t[r][k] * first.inv_d[k];
            }
        }
        let schur = |j: usize, k: usize| {
            let mut s = ia[(j, k)];
            for m in 0..3 {
                s -= l21[j][m] * t[k][m];
            }
            s
        };
        let second = factor(schur, &sound, 3)?;
        let z1 = forward(&first, [b[0], b[1], b[2]]);
        let mut b2 = [b[3], b[4], b[5]];
        for (r, b2_r) in b2.iter_mut().enumerate() {
            for k in 0..3 {
                *b2_r -= l21[r][k] * z1[k];
            }
        }
        let z2 = forward(&second, b2);
        let x2 = backward(&second, scaled(&second, z2));
        let mut y1 = scaled(&first, z1);
        for (j, y1_j) in y1.iter_mut().enumerate() {
            for r in 0..3 {
                *y1_j -= l21[r][j] * x2[r];
            }
        }
        let x1 = backward(&first, y1);
        *b = [x1[0], x1[1], x1[2], x2[0], x2[1], x2[2]];
        Ok(())
    }

    /// The `L D Lᵀ` factors of the 3×3 block whose lower triangle `m(j, k)` (`j ≥ k`) gives:
    /// `D_jj = m_jj − Σ_k L_jk² D_kk`, `L_ij = (m_ij − Σ_k L_ik L_jk D_kk) / D_jj`;
    /// `Err((offset + j, pivot))` for the first pivot `D_jj` that fails `sound`.
    #[inline(always)]
    fn factor(
        m: impl Fn(usize, usize) -> f64,
        sound: &impl Fn(f64) -> bool,
        offset: usize,
    ) -> Result<Factor, (usize, f64)> {
        let mut f = Factor {
            l: [[0.0; 3]; 3],
            inv_d: [0.0; 3],
        };
        // L_jk D_kk, kept so that each term of a sum is one multiplication
        let mut ld = [[0.0; 3]; 3];
        for j in 0..3 {
            let mut pivot = m(j, j);
            for k in 0..j {
                pivot -= f.l[j][k] * ld[j][k];
            }
            if !sound(pivot) {
                return Err((offset + j, pivot));
            }
            f.inv_d[j] = 1.0 / pivot;
            for i in j + 1..3 {
                let mut s = m(i, j);
                for k in 0..j {
                    s -= f.l[i][k] * ld[j][k];
                }
                ld[i][j] = s;
                f.l[i][j] = s * f.inv_d[j];
            }
        }
        Ok(f)
    }

    /// `L⁻¹ b` by forward substitution (`L` with a unit diagonal).
    #[inline(always)]
    fn forward(f: &Factor, mut b: [f64; 3]) -> [f64; 3] {
        for j in 0..3 {
            for k in 0..j {
                b[j] -= f.l[j][k] * b[k];
            }
        }
        b
    }

    /// `D⁻¹ z`.
    #[inline(always)]
    fn scaled(f: &Factor, z: [f64; 3]) -> [f64; 3] {
        [z[0] * f.inv_d[0], z[1] * f.inv_d[1], z[2] * f.inv_d[2]]
    }

    /// `L⁻ᵀ y` by back substitution.
    #[inline(always)]
    fn backward(f: &Factor, mut y: [f64; 3]) -> [f64; 3] {
        for j in (0..3).rev() {
            for k in j + 1..3 {
                y[j] -= f.l[k][j] * y[k];
            }
        }
        y
    }
}

/// The failed pivot of a floating root's `D_i = S_iᵀ I^A_i S_i` in the body's axes, so that the
/// error names the joint coordinate whose direction has no inertia: with
/// `S_i = [0 R; R 0]` (`R`'s columns the body's axes in world coordinates),
/// `D_i = [Rᵀ C R  Rᵀ Bᵀ R; Rᵀ B R  Rᵀ A R]`. `None` when every pivot of `D_i` is sound (the
/// world-axes factorisation failed at the edge of the test: its pivot is reported).
#[cold]
fn floating_root_pivot(slots: &Slots<'_>, i: usize) -> Option<(usize, f64)> {
    let s = &slots.s_world[i];
    let ia = &slots.ia[i];
    let r = Matrix3::from_columns(&[s.cols[3].ang, s.cols[4].ang, s.cols[5].ang]);
    let turn = |block: Matrix3| r.tr_mul(&(block * r));
    let mut d = Matrix6::zeros();
    let lin_ang = turn(ia.fixed_view::<3, 3>(0, 3).transpose());
    d.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&turn(ia.fixed_view::<3, 3>(3, 3).into_owned()));
    d.fixed_view_mut::<3, 3>(0, 3).copy_from(&lin_ang);
    d.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&lin_ang.transpose());
    d.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&turn(ia.fixed_view::<3, 3>(0, 0).into_owned()));
    spd_solve(&d, 6, |pivot| pivot_is_sound_for(pivot, ia), &mut [0.0; 6]).err()
}

/// Pass 3 at a floating root ([`is_floating_root`]) from `a' = a_0 + c_i` and its acceleration
/// `a_i` in world axes (`y`, its slot of `ws.u_bias`, translations first,
/// [`articulate_floating_root`]): `q̈_i = S_i⁻¹ (a_i − a') = S_iᵀ (a_i − a')` into `qdd` (the
/// joint's six), and `a_i` returned.
fn accelerate_floating_root(
    s: &MotionSubspace,
    y: &[f64; 6],
    a_prime: &Motion,
    qdd: &mut [f64],
) -> Motion {
    let a_i = Motion::new(
        Vector3::new(y[3], y[4], y[5]),
        Vector3::new(y[0], y[1], y[2]),
    );
    let relative = a_i - *a_prime;
    for (qdd_k, col) in qdd.iter_mut().zip(&s.cols) {
        // (S_iᵀ (a_i − a'))_k, the plain product of the 6-vectors
        *qdd_k = col.ang.dot(&relative.ang) + col.lin.dot(&relative.lin);
    }
    a_i
}

/// Pass 3: accelerations, from the root outward, over each body's slots (zipped: one pointer
/// step per body, only the parent's acceleration indexed).
pub(crate) fn acceleration_pass(model: &Model, ws: &mut Workspace, ext: &Externals<'_>) {
    run_pass!(acceleration_pass_in(model, ws, ext))
}

/// [`acceleration_pass`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn acceleration_pass_in(model: &Model, ws: &mut Workspace, ext: &Externals<'_>) {
    // a_0 = −a_g   (RBDA Table 7.1; plus the root's own acceleration)
    let a_root = ext.root_acceleration - Motion::new(Vector3::zeros(), model.gravity);
    let Workspace {
        plan,
        anchor_shift,
        c,
        s_world,
        u,
        d_inv,
        u_bias,
        a_world,
        qdd,
        ..
    } = ws;
    let bodies = model
        .bodies
        .iter()
        .zip(plan.anchors.iter().zip(anchor_shift.iter()));
    let slots = (c.iter().zip(s_world.iter())).zip(u.iter().zip(d_inv.iter()).zip(u_bias.iter()));
    // The previous body's `a'`, `S` and `q̈` when it has one degree of freedom, kept for a
    // child that follows it (a chain), which reads neither `a_world` nor a copy of `a_λ`.
    let mut one_dof_previous: Option<(Motion, Motion, f64)> = None;
    for (i, ((body, (&anchor, shift)), ((c_i, s), ((u, d_inv), u_bias)))) in
        bodies.zip(slots).enumerate()
    {
        let v_index = body.joint.coords.v_index;
        let follows_previous = matches!(body.parent, Some(p) if p + 1 == i);
        let a_prime = match one_dof_previous {
            Some((a_prime_parent, s_parent, qdd_parent))
                if s.nv == 1 && follows_previous && !anchor =>
            {
                let (a_prime, qdd_i) = accelerate_one_dof_below_one_dof(
                    (&u[0], d_inv[(0, 0)], u_bias[0]),
                    c_i,
                    (&a_prime_parent, &s_parent, qdd_parent),
                );
                qdd[v_index] = qdd_i;
                a_world[i] = a_prime + s.cols[0] * qdd_i;
                one_dof_previous = Some((a_prime, s.cols[0], qdd_i));
                continue;
            }
            _ => {
                let a_parent = body.parent.map_or(a_root, |p| a_world[p]);
                // a' = ⁱX_λ(i) a_λ(i) + c_i   (RBDA Table 7.1; ⁱX_λ(i) as for v_i)
                motion_across_anchor(anchor, shift, a_parent) + *c_i
            }
        };
        a_world[i] = if s.nv == 1 {
            accelerate_one_dof(
                s,
                &u[0],
                d_inv[(0, 0)],
                u_bias[0],
                &a_prime,
                &mut qdd[v_index],
            )
        } else if is_floating_root(body) {
            accelerate_floating_root(s, u_bias, &a_prime, &mut qdd.as_mut_slice()[v_index..])
        } else {
            accelerate(
                s,
                u,
                d_inv,
                u_bias,
                &a_prime,
                &mut qdd.as_mut_slice()[v_index..],
            )
        };
        one_dof_previous = (s.nv == 1).then(|| (a_prime, s.cols[0], qdd[v_index]));
    }
}

/// Pass 3 at a one-dof body `i` whose parent is the body before it, also of one degree of
/// freedom, in the same aligned frame: from the parent's `a'_λ`, `S_λ` and `q̈_λ` (so that
/// `a_λ = a'_λ + S_λ q̈_λ`), `a'_i = a'_λ + c_i + S_λ q̈_λ` and
/// `q̈_i = D_i⁻¹ (u_i − U_iᵀ (a'_λ + c_i) − (U_iᵀ S_λ) q̈_λ)`, returned as `(a'_i, q̈_i)`.
/// The same equations as [`accelerate_one_dof`]'s, with `U_iᵀ a'_i` split so that all of it but
/// one multiply-add is made before `q̈_λ` is known: down a chain each `q̈` waits on its
/// parent's by that multiply-add and `D_i⁻¹`, not by a whole 6-vector sum and dot product.
#[inline(always)]
fn accelerate_one_dof_below_one_dof(
    (u, d_inv, u_bias): (&Force, f64, f64),
    c: &Motion,
    (a_prime_parent, s_parent, qdd_parent): (&Motion, &Motion, f64),
) -> (Motion, f64) {
    let before_parent = *a_prime_parent + *c;
    let qdd = d_inv * (u_bias - before_parent.dot(u) - s_parent.dot(u) * qdd_parent);
    (before_parent + *s_parent * qdd_parent, qdd)
}

/// Pass 3 at a joint of any number of degrees of freedom, from `a' = ⁱX_λ(i) a_λ(i) + c_i` and
/// body `i`'s `S_i`, `U_i`, `D_i⁻¹`, `u_i`: `q̈_i = D_i⁻¹ (u_i − U_iᵀ a')` into `qdd` (from the
/// joint's first coordinate) and `a_i = a' + S_i q̈_i` returned   (RBDA Table 7.1).
fn accelerate(
    s: &MotionSubspace,
    u: &[Force; 6],
    d_inv: &Matrix6,
    u_bias: &[f64; 6],
    a_prime: &Motion,
    qdd: &mut [f64],
) -> Motion {
    let nv = s.nv;
    let mut rhs = [0.0; 6];
    for k in 0..nv {
        rhs[k] = u_bias[k] - a_prime.dot(&u[k]);
    }
    let mut a_i = *a_prime;
    for k in 0..nv {
        let qdd_k: f64 = (0..nv).map(|k2| d_inv[(k, k2)] * rhs[k2]).sum();
        qdd[k] = qdd_k;
        a_i += s.cols[k] * qdd_k;
    }
    a_i
}

/// [`accelerate`] for a joint of one degree of freedom, all scalars but `a`:
/// `q̈_i = D_i⁻¹ (u_i − U_iᵀ a')` into `qdd`, `a_i = a' + S_i q̈_i` returned.
#[inline(always)]
fn accelerate_one_dof(
    s: &MotionSubspace,
    u: &Force,
    d_inv: f64,
    u_bias: f64,
    a_prime: &Motion,
    qdd: &mut f64,
) -> Motion {
    *qdd = d_inv * (u_bias - a_prime.dot(u));
    *a_prime + s.cols[0] * *qdd
}

/// Writes into the top-left `nv × nv` block of `d_inv` the inverse of the symmetric positive
/// definite top-left `nv × nv` block of `d` ([`spd_inverse`]); when a Cholesky pivot is not
/// clearly positive relative to the scale of the articulated inertia `ia`
/// ([`pivot_is_sound_for`]), `Err((k, pivot))`: the pivot's row `k` in the joint's coordinates
/// and its value.
fn invert_spd(
    d: &Matrix6,
    nv: usize,
    ia: &Matrix6,
    d_inv: &mut Matrix6,
) -> Result<(), (usize, f64)> {
    let sound = |pivot: f64| pivot_is_sound_for(pivot, ia);
    spd_inverse(d, nv, sound, d_inv)
}

/// Whether a pivot of `D = Sᵀ I^A S` is sound: D's scale is that of the articulated inertia
/// `ia`, so a pivot within a few ulps of it is zero, and a subnormal one has no finite inverse
/// (D⁻¹ would overflow). For a positive semi-definite `ia` the largest entry is on the
/// diagonal (|a_jk| ≤ √(a_jj a_kk)). The test of [`pivot_is_sound`](super::pivot_is_sound) against `64 max |a_kk|`
/// with the pivot at least `f64::MIN_POSITIVE`, by comparisons alone: a pivot in
/// `[MIN_POSITIVE, MAX]` is finite, and NaN fails every comparison ([`sound_pivot_range`]).
#[inline(always)]
fn pivot_is_sound_for(pivot: f64, ia: &Matrix6) -> bool {
    // max |a_kk| by `f64::max` (one instruction per entry; a NaN entry leaves the pivot NaN).
    let largest = (0..6).fold(0.0_f64, |m, k| m.max(ia[(k, k)].abs()));
    // 64 ε max |a_kk|: 64 ε = 2⁻⁴⁶ is a power of two, one exact scaling.
    pivot > largest * (64.0 * f64::EPSILON) && sound_pivot_range(pivot)
}

/// `pivot ∈ [f64::MIN_POSITIVE, f64::MAX]`: positive, normal and finite (NaN is outside), so
/// that with a pivot above `reference · ε` it passes
/// [`pivot_is_sound`](super::pivot_is_sound)'s test.
#[inline(always)]
fn sound_pivot_range(pivot: f64) -> bool {
    (f64::MIN_POSITIVE..=f64::MAX).contains(&pivot)
}

/// The error for the failed pivot `k` (value `pivot`) of `D = Sᵀ I^A S` at body `i`: its body,
/// joint and velocity coordinate.
#[cold]
fn singular_pivot(model: &Model, i: usize, k: usize, pivot: f64) -> DynamicsError {
    let body = &model.bodies[i];
    DynamicsError::SingularArticulatedInertia {
        joint: body.joint.name.clone(),
        body: body.name.clone(),
        coordinate: model.v_name(body.joint.coords.v_index + k),
        pivot,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::urdf::model_from_str;
    use crate::ModelOptions;

    /// The comparisons-only pivot test gives the verdict of `pivot_is_sound` against
    /// `64 max |a_kk|` with a normal pivot, at the edges: NaN, infinities, the largest finite,
    /// subnormals, zero, negatives, and pivots either side of `64 ε max |a_kk|`.
    #[test]
    fn the_pivot_test_matches_the_finite_relative_normal_test() {
        let mut ia = Matrix6::identity() * 0.5;
        ia[(4, 4)] = -3.0; // the scale is max |a_kk| = 3
        let floor = 64.0 * 3.0 * f64::EPSILON;
        let pivots = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN_POSITIVE,
            f64::MIN_POSITIVE / 2.0,
            0.0,
            -0.0,
            -1.0,
            floor,
            floor * (1.0 + f64::EPSILON),
            floor * (1.0 - f64::EPSILON),
            1.0,
        ];
        for pivot in pivots {
            let expected =
                super::super::pivot_is_sound(pivot, 64.0 * 3.0) && pivot >= f64::MIN_POSITIVE;
            assert_eq!(pivot_is_sound_for(pivot, &ia), expected, "{pivot:e}");
        }
        assert!(!pivot_is_sound_for(floor, &ia) && pivot_is_sound_for(1.0, &ia));
        let tiny = Matrix6::identity() * 1e-300;
        assert!(!pivot_is_sound_for(f64::MIN_POSITIVE / 2.0, &tiny));
        assert!(pivot_is_sound_for(f64::MIN_POSITIVE, &tiny));
        assert!(!pivot_is_sound_for(f64::INFINITY, &tiny));
    }

    /// The floating root's solve by blocks of three gives the 6×6 factorisation's answer
    /// (`spd_solve` of `[C Bᵀ; B A]`), and fails at the same pivot with the same value.
    #[test]
    fn the_floating_root_solve_by_blocks_matches_the_six_by_six_factorisation() {
        let turn = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1);
        let inertia = crate::spatial::Inertia::from_com(
            2.5,
            &Vector3::new(0.1, -0.2, 0.3),
            &(turn.matrix()
                * Matrix3::from_diagonal(&Vector3::new(0.3, 0.2, 0.05))
                * turn.matrix().transpose()),
        );
        let sound = |pivot: f64| pivot > 1e-9;
        let swapped = |ia: &Matrix6| {
            let mut d = Matrix6::zeros();
            d.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&ia.fixed_view::<3, 3>(3, 3));
            d.fixed_view_mut::<3, 3>(3, 0)
                .copy_from(&ia.fixed_view::<3, 3>(0, 3));
            d.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&ia.fixed_view::<3, 3>(3, 0));
            d.fixed_view_mut::<3, 3>(3, 3)
                .copy_from(&ia.fixed_view::<3, 3>(0, 0));
            d
        };
        let ia = inertia.to_matrix();
        let b = [0.4, -1.3, 2.2, 0.7, 0.1, -0.5];
        let (mut ours, mut reference) = (b, b);
        ldlt_by_blocks::solve(&ia, sound, &mut ours).unwrap();
        spd_solve(&swapped(&ia), 6, sound, &mut reference).unwrap();
        for (x, r) in ours.iter().zip(&reference) {
            assert!(
                (x - r).abs() < 1e-13 * r.abs().max(1.0),
                "{ours:?} {reference:?}"
            );
        }
        // The answer satisfies [C Bᵀ; B A] y = b.
        let residual = swapped(&ia) * nalgebra::Vector6::from(ours) - nalgebra::Vector6::from(b);
        assert!(residual.amax() < 1e-13, "{residual}");
        // A singular first block (no mass) and a singular second (no rotational inertia about
        // one axis): the same failed pivot, row and value.
        for (mass, moments) in [(0.0, [0.3, 0.2, 0.05]), (1.0, [0.3, 0.2, 0.0])] {
            let singular = crate::spatial::Inertia::from_com(
                mass,
                &Vector3::zeros(),
                &Matrix3::from_diagonal(&Vector3::from(moments)),
            )
            .to_matrix();
            let ours = ldlt_by_blocks::solve(&singular, sound, &mut [1.0; 6]).unwrap_err();
            let reference = spd_solve(&swapped(&singular), 6, sound, &mut [1.0; 6]).unwrap_err();
            assert_eq!(ours, reference);
        }
    }

    /// A floating rod with no inertia about its own axis (body z), turned a quarter about y so
    /// that its axis lies along world x: `D` fails at its last pivot, the rotation about the
    /// body's z (`root_joint[5]`), where a factorisation in world axes fails first about world x.
    #[test]
    fn a_floating_root_names_its_pivot_in_the_body_axes() {
        let urdf = r#"<robot name="rod"><link name="rod"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0"/></inertial></link></robot>"#;
        let options = ModelOptions {
            floating_base: true,
            ..Default::default()
        };
        let model = model_from_str(urdf, &options).unwrap();
        let mut ws = Workspace::new(&model);
        let half = std::f64::consts::FRAC_1_SQRT_2;
        for (quaternion, coordinate) in [
            ([0.0, 0.0, 0.0, 1.0], "root_joint[5]"),
            ([0.0, half, 0.0, half], "root_joint[5]"),
        ] {
            let mut q = model.neutral();
            q[3..7].copy_from_slice(&quaternion);
            let err = aba(
                &model,
                &mut ws,
                &q,
                &[0.0; 6],
                &[0.0; 6],
                &Externals::none(),
            )
            .unwrap_err();
            match err {
                DynamicsError::SingularArticulatedInertia {
                    coordinate: named,
                    pivot,
                    ..
                } => {
                    assert_eq!(named, coordinate);
                    assert!(pivot.abs() < 1e-12, "{pivot}");
                }
                other => panic!("{other:?}"),
            }
        }
    }
}
