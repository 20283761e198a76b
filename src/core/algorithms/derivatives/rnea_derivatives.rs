//! `∂τ/∂q`, `∂τ/∂q̇` and `H = ∂τ/∂q̈` of `τ = RNEA(q, q̇, q̈)` (Carpentier & Mansard, RSS 2018,
//! Algorithm 1), in the aligned frame of each tree (world axes, origin at the root body's
//! origin: `kinematics::update_aligned_placements` with [`Anchors::Roots`]). Every quantity
//! below is in that frame; `S_i` is body `i`'s motion subspace there, each column scaled by the
//! joint's mimic multiplier.
//!
//! Forward pass, root outward (`a_0 = a_base − g`):
//! ```text
//! v_i = v_λ + S_i q̇_i,    a_i = a_λ + Σ_k (S_ik q̈_ik + v_λ × S_ik q̇_ik)
//! f_i = I_i a_i + v_i ×* I_i v_i − f^x_i
//! ψ_ik = v_λ × S_ik,   α_ik = a_λ × S_ik + v_λ × ψ_ik,   β_ik = ψ_ik + v_i × S_ik
//! B_i ψ = I_i (ψ × v_i) + v_i ×* I_i ψ + ψ ×* I_i v_i      (sparse: velocity_product.rs)
//! ```
//! Turning column `k` of joint `j` by `ε` carries every body of the subtree of `j` rigidly by
//! `ε S_jk` (a motion `m` becomes `m + ε S_jk × m`, a force `f + ε S_jk ×* f`) and, on top of
//! that, adds `ε ψ_jk` to its velocities and `ε (ψ_jk × v_k + α_jk)` to its accelerations (the
//! parent's motion `v_λ`, `a_λ` does not turn). A rate `q̇_jk` adds `S_jk` to the velocities
//! and `S_jk × v_k + β_jk` to the accelerations. The body forces change by
//! `I_k α + B_k ψ` (and `I_k β + B_k S_jk` for a rate) beyond their rigid motion, which leaves
//! `τ_i = S_iᵀ F_i` unchanged for `i` inside the subtree.
//!
//! Backward pass, leaves inward, summing over each subtree `I^C_i = Σ I_k`, `B^C_i = Σ B_k`,
//! `F_i = Σ f_k`: with `j` an ancestor of `i` or `i` itself,
//! ```text
//! τ_i = S_iᵀ F_i
//! ∂τ_i/∂q_j = S_iᵀ (I^C_i α_j + B^C_i ψ_j)                 ∂τ_j/∂q_i = S_jᵀ (S_i ×* F_i + I^C_i α_i + B^C_i ψ_i)
//! ∂τ_i/∂q̇_j = S_iᵀ (I^C_i β_j + B^C_i S_j)                 ∂τ_j/∂q̇_i = S_jᵀ (I^C_i β_i + B^C_i S_i)
//! ∂τ_i/∂q̈_j = S_iᵀ I^C_i S_j                              ∂τ_j/∂q̈_i = S_jᵀ I^C_i S_i
//! ```
//! (left: the row's body is inside the subtree that moves; right: above it, `j ≠ i`). The left
//! column is read as `(I^C_i S_i)ᵀ α_j + (B^C_iᵀ S_i)ᵀ ψ_j`, so that both walk the ancestors of
//! `i` once per column.
//!
//! A floating joint's columns all move with its body (its `S` is constant there), so turning
//! one column carries the others: its own block is on the left. A planar joint's translation
//! columns stay with the parent while `θ` turns, as though `x`, `y`, `θ` were three joints in
//! series ([`in_series`]): each column is then the child of the columns before it, with
//! `v_λ`, `a_λ` the motion after them and `v_i` in `β` the motion after the column itself.

use super::velocity_product::VelocityProduct;
use super::DerivativeScratch;
use crate::algorithms::kinematics::{
    update_aligned_placements, update_joints, update_world_axes, Anchors,
};
use crate::algorithms::validate::{all_finite_long, check_inverse_inputs, check_result};
use crate::algorithms::Externals;
use crate::error::DynamicsError;
use crate::instruction_set::run_pass;
use crate::model::{JointKind, Model, MotionSubspace};
use crate::spatial::{Force, Inertia, Motion, Translation, Vector3};
use crate::Workspace;
use nalgebra::DMatrix;

/// The derivatives of inverse dynamics at one state, held in the workspace: `nv × nv`, full,
/// row `i` the derivative of `τ_i`, columns in `v` order, on the tangent of
/// [the module](super) (`q ⊕ ε e_k`).
#[derive(Clone, Copy, Debug)]
pub struct RneaDerivatives<'w> {
    /// `∂τ/∂q`.
    pub dtau_dq: &'w DMatrix<f64>,
    /// `∂τ/∂q̇`.
    pub dtau_dv: &'w DMatrix<f64>,
    /// `H = ∂τ/∂q̈`, the joint-space inertia matrix (also `ws.mass_matrix()`).
    pub mass_matrix: &'w DMatrix<f64>,
}

/// The derivatives of `τ = RNEA(q, q̇, q̈)` with gravity, no external wrenches, base at rest.
/// `τ` itself is left in `ws.tau()`.
pub fn rnea_derivatives<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
) -> Result<RneaDerivatives<'w>, DynamicsError> {
    rnea_derivatives_with(model, ws, q, v, a, &Externals::none())
}

/// The derivatives of `τ = RNEA(q, q̇, q̈)` with external wrenches (fixed to their bodies) and
/// base motion (fixed in the world). `τ` itself is left in `ws.tau()`.
pub fn rnea_derivatives_with<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
    ext: &Externals<'_>,
) -> Result<RneaDerivatives<'w>, DynamicsError> {
    check_inverse_inputs(model, ws, q, v, a, ext)?;
    run_pass!(passes_of_checked(model, ws, q, v, a, ext))?;
    Ok(RneaDerivatives {
        dtau_dq: &ws.derivatives.dtau_dq,
        dtau_dv: &ws.derivatives.dtau_dv,
        mass_matrix: &ws.mass_matrix,
    })
}

/// [`rnea_derivatives_with`]'s passes on checked inputs, the results checked finite; compiled
/// once per instruction set ([`run_pass`]).
#[inline(always)]
fn passes_of_checked(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
    ext: &Externals<'_>,
) -> Result<(), DynamicsError> {
    update_joints(model, ws, q);
    let known_finite = derivative_passes(model, ws, v, a, ext, Target::Matrices);
    check_result(model, "tau", ws.tau.as_slice())?;
    if known_finite {
        return Ok(());
    }
    let d = &ws.derivatives;
    check_matrix(model, "dtau_dq", &d.dtau_dq)?;
    check_matrix(model, "dtau_dv", &d.dtau_dv)?;
    check_matrix(model, "mass matrix", &ws.mass_matrix)
}

/// Both passes, on joints already updated for `q` (inputs already checked), the backward pass
/// writing into `target`: with [`Target::Matrices`] `ws.tau`, `ws.mass_matrix` and the
/// derivatives of `ws.derivatives`; with [`Target::SolveRows`] `−∂τ/∂q` and `−∂τ/∂q̇` straight
/// into the right-hand sides of `aba_derivatives`' dense solve, `ws.derivatives.rhs` laid out as
/// [`SolveRows`] says, which must already hold zeros there, and neither `τ` nor `H` (CRBA made
/// `H`, and `q̈` from `τ`). Returns what [`backward_pass`] returns.
pub(crate) fn derivative_passes(
    model: &Model,
    ws: &mut Workspace,
    v: &[f64],
    a: &[f64],
    ext: &Externals<'_>,
    target: Target,
) -> bool {
    forward_pass(model, ws, v, a, ext);
    backward_pass(model, ws, target)
}

/// A planar joint's columns act in series (translations fixed to the parent, the turn to the
/// child); every other joint's columns all move with its child body.
fn in_series(kind: &JointKind) -> bool {
    matches!(kind, JointKind::Planar { .. })
}

/// Forward pass, root outward: [`forward_terms`] of each body.
fn forward_pass(model: &Model, ws: &mut Workspace, v: &[f64], a: &[f64], ext: &Externals<'_>) {
    update_aligned_placements(model, ws, Anchors::Roots);
    let root = RootMotion::of(model, ext);
    for i in 0..model.bodies.len() {
        forward_terms(model, ws, i, v, Accelerations::Given(a), &root, ext);
    }
}

/// The motion of the roots' parent (the world) in the forward pass, about the world origin:
/// the base's velocity `v_0 = v_base` and `a_0 = a_base − g`.
pub(super) struct RootMotion {
    pub(super) v: Motion,
    pub(super) a: Motion,
}

impl RootMotion {
    pub(super) fn of(model: &Model, ext: &Externals<'_>) -> Self {
        RootMotion {
            v: ext.root_velocity,
            a: ext.root_acceleration - Motion::new(Vector3::zeros(), model.gravity),
        }
    }
}

/// The motion of body `i`'s parent from `motions` (one per body), or for a root `root` (about
/// the world origin) in `i`'s aligned frame.
#[inline(always)]
pub(super) fn parent_motion(
    ws: &Workspace,
    motions: &[Motion],
    i: usize,
    parent: Option<usize>,
    root: &Motion,
) -> Motion {
    match parent {
        Some(p) => motions[p],
        None => Translation(ws.anchor_shift[i]).apply_motion(root),
    }
}

/// Body `i`'s terms of the forward pass, its parent's already made and its aligned placement
/// updated: `S_i` (scaled) into `ws.s_world`, `v_i = v_λ + S_i q̇_i` into `ws.v_world`, `ψ_i`,
/// `β_i` and `B_i` into `ws.derivatives`, `I_i` into `ws.ic`, and the acceleration terms
/// [`Accelerations`] says. All in one sweep over the columns, from the values in hand: read
/// back from the workspace just after they are stored, they would be loaded across the stores
/// that wrote them, which the processor does not forward (a stall per load).
#[inline(always)]
pub(super) fn forward_terms(
    model: &Model,
    ws: &mut Workspace,
    i: usize,
    v: &[f64],
    accelerations: Accelerations<'_>,
    root: &RootMotion,
    ext: &Externals<'_>,
) {
    let body = &model.bodies[i];
    let c = body.joint.coords;
    update_world_axes(ws, i, &[], 1.0);
    let s = &mut ws.s_world[i];
    let nv = s.nv;
    // A mimic follower's columns scaled by its multiplier; the others' left as they were
    // stored (read back to be multiplied by one, they would wait for those stores).
    if c.scale != 1.0 {
        for col in &mut s.cols[..nv] {
            *col = *col * c.scale;
        }
    }
    let v_parent = parent_motion(ws, &ws.v_world, i, body.parent, &root.v);
    let a_parent = parent_motion(ws, &ws.a_world, i, body.parent, &root.a);
    let rates = &v[c.v_index..c.v_index + nv];
    let s = &ws.s_world[i];
    let v_i = v_parent + s.apply(rates, 1.0);
    let series = in_series(&body.joint.kind);
    let d = &mut ws.derivatives;
    // The motion of what column k moves from: the parent, or in series the columns before.
    let (mut v_above, mut a_above) = (v_parent, a_parent);
    let mut a_i = a_parent;
    for k in 0..nv {
        let s_k = s.cols[k];
        let psi = v_above.cross_motion(&s_k);
        let v_k = v_above + s_k * rates[k];
        let v_after = if series { v_k } else { v_i };
        d.psi[i][k] = psi;
        d.beta[i][k] = psi + v_after.cross_motion(&s_k);
        match accelerations {
            Accelerations::Given(a) => {
                let qdd = a[c.v_index + k];
                let (share, alpha) =
                    column_acceleration(&s_k, &psi, rates[k], qdd, &v_above, &a_above);
                a_i += share;
                d.alpha[i][k] = alpha;
            }
            Accelerations::Zero => a_i += psi * rates[k],
        }
        if series {
            (v_above, a_above) = (v_k, a_i);
        }
    }
    let x = &ws.x_aligned[i];
    let inertia = x.transpose_apply_inertia(&body.inertia);
    let momentum = inertia.apply(&v_i);
    let mut f_v = v_i.cross_force(&momentum);
    if let Some(w) = ext.wrenches {
        f_v -= x.transpose_apply_force(&w[i]);
    }
    d.b[i] = VelocityProduct::new(&inertia, &v_i, &momentum);
    d.halves[i] = matches!(body.joint.kind, JointKind::Floating) && in_halves(s);
    ws.ic[i] = inertia;
    ws.v_world[i] = v_i;
    ws.a_world[i] = a_i;
    match accelerations {
        Accelerations::Given(_) => ws.f[i] = inertia.apply(&a_i) + f_v,
        Accelerations::Zero => {
            ws.f[i] = f_v;
            d.f_bias[i] = inertia.apply(&a_i) + f_v;
            d.composite[i] = inertia;
        }
    }
}

/// Which acceleration terms [`forward_terms`] makes.
#[derive(Clone, Copy)]
pub(super) enum Accelerations<'a> {
    /// The accelerations `q̈` (in `v` order) given: `a_i = a_λ + Σ_k (S_ik q̈_ik + ψ_ik q̇_ik)`
    /// into `ws.a_world`, `α_i` into `ws.derivatives` and the force
    /// `f_i = I_i a_i + v_i ×* I_i v_i − f^x_i` into `ws.f`.
    Given(&'a [f64]),
    /// `q̈ = 0` (`aba_derivatives`' bias pass): the bias acceleration
    /// `a⁰_i = a⁰_λ + Σ_k ψ_ik q̇_ik` into `ws.a_world`, its force
    /// `f⁰_i = I_i a⁰_i + v_i ×* I_i v_i − f^x_i` into `ws.derivatives.f_bias`, the
    /// velocity-dependent part `v_i ×* I_i v_i − f^x_i` into `ws.f` (for [`acceleration_terms`]
    /// to complete) and `I_i` into `ws.derivatives.composite` (to be summed); no `α`.
    Zero,
}

/// Column `k`'s share of body `i`'s acceleration, `S_ik q̈_ik + ψ_ik q̇_ik`, and its
/// `α_ik = a_above × S_ik + v_above × ψ_ik`, with `v_above`, `a_above` the motion the column
/// moves from (the parent's, or in series the motion after the columns before).
#[inline(always)]
fn column_acceleration(
    s_k: &Motion,
    psi: &Motion,
    rate: f64,
    qdd: f64,
    v_above: &Motion,
    a_above: &Motion,
) -> (Motion, Motion) {
    (
        *s_k * qdd + *psi * rate,
        a_above.cross_motion(s_k) + v_above.cross_motion(psi),
    )
}

/// The terms of body `i` that depend on accelerations, after its [`forward_terms`] at
/// [`Accelerations::Zero`] and its parent's acceleration, with `a_root` the roots' acceleration `a_0` (about the
/// world origin): `a_i = a_λ + Σ_k (S_ik q̈_ik + ψ_ik q̇_ik)` into `ws.a_world`, `α_i` into
/// `ws.derivatives` and `I_i a_i` added to the force in `ws.f`, making it `f_i`.
#[inline(always)]
pub(super) fn acceleration_terms(
    model: &Model,
    ws: &mut Workspace,
    i: usize,
    v: &[f64],
    a: &[f64],
    root: &RootMotion,
) {
    let body = &model.bodies[i];
    let c = body.joint.coords;
    let s = &ws.s_world[i];
    let nv = s.nv;
    let (rates, accelerations) = (&v[c.v_index..c.v_index + nv], &a[c.v_index..c.v_index + nv]);
    let a_parent = parent_motion(ws, &ws.a_world, i, body.parent, &root.a);
    // The motion of what column k moves from: the parent, or in series the columns before.
    let mut v_above = parent_motion(ws, &ws.v_world, i, body.parent, &root.v);
    let series = in_series(&body.joint.kind);
    let d = &mut ws.derivatives;
    let (mut a_above, mut a_i) = (a_parent, a_parent);
    for k in 0..nv {
        let (s_k, psi) = (s.cols[k], d.psi[i][k]);
        let (share, alpha) =
            column_acceleration(&s_k, &psi, rates[k], accelerations[k], &v_above, &a_above);
        a_i += share;
        d.alpha[i][k] = alpha;
        if series {
            v_above += s_k * rates[k];
            a_above = a_i;
        }
    }
    ws.f[i] += ws.ic[i].apply(&a_i);
    ws.a_world[i] = a_i;
}

/// Where the backward pass writes, and what it finds made.
#[derive(Clone, Copy)]
pub(crate) enum Target {
    /// The matrices of [`RneaDerivatives`] with `τ` and `H`.
    Matrices,
    /// The rows of [`SolveRows`].
    SolveRows,
    /// The columns of [`BranchColumns`], on the composite inertias `aba_derivatives`' bias pass
    /// summed: `ws.derivatives.composite` holds `I^C_i` and `ws.f_cols` `I^C_i S_ik` for each
    /// coordinate. With `free_root`, body 0 is a free-floating root whose six pose columns of
    /// `∂τ/∂q` and three linear rate columns of `∂τ/∂q̇` are not read (`aba_derivatives` has
    /// their columns of `∂q̈/∂q`, `∂q̈/∂q̇` in closed form): those entries are written as zero.
    BranchColumnsOnComposites { free_root: bool },
}

/// Backward pass: sums `I^C` (unless [`Target::BranchColumnsOnComposites`]), `B^C`, `F` over each
/// subtree and fills the entries of `∂τ/∂q`, `∂τ/∂q̇` (and of `τ` and `H` into [`Matrices`]),
/// each from the row's and the column's bodies (one an ancestor of the other).
///
/// Returns whether every entry of `∂τ/∂q`, `∂τ/∂q̇` and `H` is known finite without reading
/// them back: with [`Target::Matrices`] on a model without mimic joints, from the probe of
/// [`Matrices`]; `false` (not known) otherwise.
pub(crate) fn backward_pass(model: &Model, ws: &mut Workspace, target: Target) -> bool {
    run_pass!(backward_pass_in(model, ws, target))
}

/// [`backward_pass`]'s body, compiled once per instruction set ([`run_pass`]).
#[inline(always)]
fn backward_pass_in(model: &Model, ws: &mut Workspace, target: Target) -> bool {
    let Workspace {
        s_world,
        ic,
        f_cols,
        f,
        tau,
        mass_matrix,
        derivatives,
        ..
    } = ws;
    let DerivativeScratch {
        psi,
        alpha,
        beta,
        b,
        dtau_dq,
        dtau_dv,
        rhs,
        halves,
        composite,
        ..
    } = derivatives;
    let parts = Parts {
        s: s_world,
        psi,
        alpha,
        beta,
        halves,
    };
    let n = tau.len();
    match target {
        Target::Matrices => {
            let (dq, dv, h) = (
                dtau_dq.as_mut_slice(),
                dtau_dv.as_mut_slice(),
                mass_matrix.as_mut_slice(),
            );
            // `H` is zeroed outside the tree's pattern (other algorithms write it whole), on
            // the storage slice: one memset, where nalgebra's `fill` walks index by index.
            // Zeroed whole even where the pattern covers it: measured faster than writing
            // only the pattern (UR5: about a sixth less CPU time per call).
            h.fill(0.0);
            if model.has_mimic() {
                // A mimic follower's entries add to its leader's: sums from zero.
                dq.fill(0.0);
                dv.fill(0.0);
                tau.fill(0.0);
                let mut out = Matrices::<false>::new(dq, dv, h, tau.as_mut_slice());
                sweep::<_, false, false>(model, &parts, ic, &[], b, f, &mut out);
                out.known_finite()
            } else {
                // Every entry on the tree's pattern is written once; those off it are zero
                // from the workspace's allocation on, as only this pass writes `∂τ/∂q`,
                // `∂τ/∂q̇` (and a workspace serves one model).
                let mut out = Matrices::<true>::new(dq, dv, h, tau.as_mut_slice());
                sweep::<_, false, false>(model, &parts, ic, &[], b, f, &mut out);
                out.known_finite()
            }
        }
        Target::SolveRows => {
            let mut out = SolveRows {
                rows: &mut rhs[..3 * n * n],
                nv: n,
            };
            sweep::<_, false, false>(model, &parts, ic, &[], b, f, &mut out);
            false
        }
        Target::BranchColumnsOnComposites { free_root } => {
            let mut out = BranchColumns {
                pairs: &mut rhs[..2 * n * n],
                nv: n,
            };
            if free_root {
                sweep::<_, true, true>(model, &parts, composite, f_cols, b, f, &mut out);
            } else {
                sweep::<_, true, false>(model, &parts, composite, f_cols, b, f, &mut out);
            }
            false
        }
    }
}

/// The forward pass's per-body columns the backward pass reads.
struct Parts<'a> {
    s: &'a [MotionSubspace],
    psi: &'a [[Motion; 6]],
    alpha: &'a [[Motion; 6]],
    beta: &'a [[Motion; 6]],
    halves: &'a [bool],
}

impl Parts<'_> {
    #[inline(always)]
    fn columns(&self, i: usize) -> Columns<'_> {
        Columns::of(&self.s[i], &self.psi[i], &self.alpha[i], &self.beta[i])
    }
}

/// The backward pass proper, into `out`: the loops of the module's equations, leaves inward.
/// With `COMPOSITES`, `ic` holds the subtree sums `I^C_i` already and `ic_s` the products
/// `I^C_i S_ik` by coordinate; else `ic` holds each body's own `I_i`, summed here. With
/// `FREE_ROOT`, body 0 is a free-floating root whose pose columns of `∂τ/∂q` and linear rate
/// columns of `∂τ/∂q̇` are written as zero, not computed
/// ([`Target::BranchColumnsOnComposites`]).
#[inline(always)]
fn sweep<O: Entries, const COMPOSITES: bool, const FREE_ROOT: bool>(
    model: &Model,
    parts: &Parts<'_>,
    ic: &mut [Inertia],
    ic_s: &[Force],
    b: &mut [VelocityProduct],
    f: &mut [Force],
    out: &mut O,
) {
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let ci = body.joint.coords.v_index;
        let series = in_series(&body.joint.kind);
        let nvi = parts.s[i].nv;
        let own = parts.columns(i);
        // The right entries (column (i, n) against the rows above it) exist only below a
        // parent or within a joint in series: a root's other joints have none.
        let right = body.parent.is_some() || series;
        let free_own = FREE_ROOT && i == 0 && nvi == 6;
        for (n_i, &s) in own.s.iter().enumerate() {
            let row = ci + n_i;
            if O::TAU_AND_H {
                out.tau(row, s.dot(&f[i]));
            }
            // Row (i, n) against the columns of i and its ancestors: I^C_i S and B^C_iᵀ S.
            // Column (i, n) against the rows above it: the forces its motion adds to F_i.
            let r = RowVectors {
                ic_s: if COMPOSITES {
                    ic_s[row]
                } else {
                    ic[i].apply(&s)
                },
                bt_s: b[i].tr_apply(&s),
                w_q: if right {
                    s.cross_force(&f[i]) + ic[i].apply(&own.alpha[n_i]) + b[i].apply(&own.psi[n_i])
                } else {
                    Force::zero()
                },
                w_v: if right {
                    ic[i].apply(&own.beta[n_i]) + b[i].apply(&s)
                } else {
                    Force::zero()
                },
            };
            // i's own columns: all of them on the left, or in series those up to n on the left
            // and those before n on the right.
            let left = if series { n_i + 1 } else { nvi };
            if free_own {
                // The free root's own block: only its angular rate columns are read.
                for m in 0..6 {
                    let left_v = if m < 3 {
                        0.0
                    } else {
                        r.left_v(own.beta[m], own.s[m])
                    };
                    out.add(row, ci + m, 0.0, left_v);
                }
                continue;
            }
            for m in 0..left {
                let col = ci + m;
                out.add(
                    row,
                    col,
                    r.left_q(own.alpha[m], own.psi[m]),
                    r.left_v(own.beta[m], own.s[m]),
                );
                if O::TAU_AND_H {
                    out.add_h(row, col, own.s[m].dot(&r.ic_s));
                }
            }
            for m in 0..if series { n_i } else { 0 } {
                let col = ci + m;
                out.add(col, row, own.s[m].dot(&r.w_q), own.s[m].dot(&r.w_v));
                if O::TAU_AND_H {
                    out.add_h(col, row, own.s[m].dot(&r.ic_s));
                }
            }
            // Each ancestor column (j, m): the left entry in row (i, n), the right one in
            // column (i, n), and H's two (equal) entries from one product. Entries add up: a
            // mimic follower's row and column are its leader's.
            for j in ancestors(model, i) {
                let (cj, c) = (model.bodies[j].joint.coords.v_index, parts.columns(j));
                if parts.halves[j] {
                    columns_in_halves(row, cj, &c, &r, out, FREE_ROOT && j == 0);
                } else {
                    ancestor_columns(row, cj, &c, &r, out);
                }
            }
        }
        if let Some(p) = body.parent {
            let (ic_i, b_i, f_i) = (ic[i], b[i], f[i]);
            if !COMPOSITES {
                ic[p] += ic_i;
            }
            b[p] += b_i;
            f[p] += f_i;
        }
    }
}

/// The ancestors of body `i`, its parent first.
#[inline(always)]
pub(super) fn ancestors(model: &Model, i: usize) -> impl Iterator<Item = usize> + '_ {
    std::iter::successors(model.bodies[i].parent, |&j| model.bodies[j].parent)
}

/// `S_m · w` for column `m` of a floating joint's `S` [`in_halves`]: over the linear parts for
/// the first three columns, the angular ones for the last three (the other half is zero).
#[inline(always)]
pub(super) fn dot_in_halves(m: usize, s: &Motion, w: &Force) -> f64 {
    if m < 3 {
        s.lin.dot(&w.lin)
    } else {
        s.ang.dot(&w.ang)
    }
}

/// The entries of row `(i, n)` (its vectors `r`) against the columns `c` of an ancestor
/// joint from `v` index `cj` on, and of those columns against it: the left entry in the row,
/// the right one in the column, and `H`'s two (equal) entries from one product. Entries add
/// up: a mimic follower's row and column are its leader's.
#[inline(always)]
fn ancestor_columns<O: Entries>(
    row: usize,
    cj: usize,
    c: &Columns<'_>,
    r: &RowVectors,
    out: &mut O,
) {
    let columns = c.s.iter().zip(c.psi).zip(c.alpha.iter().zip(c.beta));
    for (m, ((s_j, psi_j), (alpha_j, beta_j))) in columns.enumerate() {
        let col = cj + m;
        out.add(
            row,
            col,
            r.left_q(*alpha_j, *psi_j),
            r.left_v(*beta_j, *s_j),
        );
        out.add(col, row, s_j.dot(&r.w_q), s_j.dot(&r.w_v));
        if O::TAU_AND_H {
            let h_ij = s_j.dot(&r.ic_s);
            out.add_h(row, col, h_ij);
            out.add_h(col, row, h_ij);
        }
    }
}

/// [`ancestor_columns`] for a floating joint's columns [`in_halves`]: a linear column
/// `S = (0, s)` has `Sᵀ w = s · w_lin`, and its `ψ`, `α`, `β` are linear too (`m × (0, s) =
/// (0, m_ω × s)` for any motion `m`), so `I^C_i S_i` meets only their linear parts and
/// `B^C_iᵀ S_i` (angular) none of them; an angular column `S = (s, 0)` has `Sᵀ w = s · w_ang`
/// and general `ψ`, `α`, `β`. The same sums without their zero terms (3 multiplications for
/// each product with a linear column's vectors, or with `S`, instead of 6).
///
/// With `free_root` (body 0's columns, [`Target::BranchColumnsOnComposites`]) the left entries
/// of the pose columns and of the linear rate columns are written as zero, not computed.
#[inline(always)]
fn columns_in_halves<O: Entries>(
    row: usize,
    cj: usize,
    c: &Columns<'_>,
    r: &RowVectors,
    out: &mut O,
    free_root: bool,
) {
    for m in 0..6 {
        let (col, s) = (cj + m, c.s[m]);
        if free_root {
            let (w_q, w_v, left_v) = if m < 3 {
                (s.lin.dot(&r.w_q.lin), s.lin.dot(&r.w_v.lin), 0.0)
            } else {
                let left_v = c.beta[m].dot(&r.ic_s) + r.bt_s.dot(&s.ang);
                (s.ang.dot(&r.w_q.ang), s.ang.dot(&r.w_v.ang), left_v)
            };
            out.add(row, col, 0.0, left_v);
            out.add(col, row, w_q, w_v);
            continue;
        }
        let (left_q, left_v, w_q, w_v, h_ij) = if m < 3 {
            let (s, ic_s) = (s.lin, r.ic_s.lin);
            let left_q = c.alpha[m].lin.dot(&ic_s);
            let left_v = c.beta[m].lin.dot(&ic_s);
            let (w_q, w_v) = (s.dot(&r.w_q.lin), s.dot(&r.w_v.lin));
            (left_q, left_v, w_q, w_v, s.dot(&ic_s))
        } else {
            let s = s.ang;
            let left_q = r.left_q(c.alpha[m], c.psi[m]);
            let left_v = c.beta[m].dot(&r.ic_s) + r.bt_s.dot(&s);
            let (w_q, w_v) = (s.dot(&r.w_q.ang), s.dot(&r.w_v.ang));
            (left_q, left_v, w_q, w_v, s.dot(&r.ic_s.ang))
        };
        out.add(row, col, left_q, left_v);
        out.add(col, row, w_q, w_v);
        if O::TAU_AND_H {
            out.add_h(row, col, h_ij);
            out.add_h(col, row, h_ij);
        }
    }
}

/// The six columns of a floating joint come in halves: the first three have no angular part,
/// the last three no linear part (exactly: then dropping those parts drops only zero terms).
fn in_halves(s: &MotionSubspace) -> bool {
    let zero = |v: &Vector3| v.iter().all(|&x| x == 0.0);
    s.nv == 6
        && s.cols[..3].iter().all(|c| zero(&c.ang))
        && s.cols[3..6].iter().all(|c| zero(&c.lin))
}

/// The entries the backward pass produces, `(row, column)` in `v` order. A mimic follower's
/// entries go to its leader's, so with mimic joints an entry can come more than once and the
/// values add up; without, each entry of the tree's pattern comes once.
trait Entries {
    /// Whether `τ` and `H` are wanted (else [`tau`](Self::tau), [`add_h`](Self::add_h) are
    /// not called, nor their products computed).
    const TAU_AND_H: bool;
    /// `∂τ_r/∂q_c += dq`, `∂τ_r/∂q̇_c += dv`.
    fn add(&mut self, r: usize, c: usize, dq: f64, dv: f64);
    /// `H_rc += h`.
    fn add_h(&mut self, r: usize, c: usize, h: f64);
    /// `τ_r += x`.
    fn tau(&mut self, r: usize, x: f64);
}

/// The `n × n` column-major storage of `∂τ/∂q`, `∂τ/∂q̇`, `H` (entry `(r, c)` at `c n + r`)
/// and `τ`. With `ASSIGN` each entry is written once (no mimic joints) and stored as it
/// comes, and added to `probe` as `x · 0` (zero for a finite `x`, NaN otherwise; one lane a
/// matrix), so that the matrices need no pass reading them back to be known finite: the
/// entries off the tree's pattern are zero. Without, entries add to what is there (a sum can
/// overflow where no term does: the probe is not kept).
struct Matrices<'a, const ASSIGN: bool> {
    dq: &'a mut [f64],
    dv: &'a mut [f64],
    h: &'a mut [f64],
    tau: &'a mut [f64],
    n: usize,
    probe: [f64; 3],
}

impl<'a, const ASSIGN: bool> Matrices<'a, ASSIGN> {
    /// The storage of the three matrices (`n × n` each) and of `τ`, nothing probed yet.
    fn new(dq: &'a mut [f64], dv: &'a mut [f64], h: &'a mut [f64], tau: &'a mut [f64]) -> Self {
        let n = tau.len();
        Matrices {
            dq,
            dv,
            h,
            tau,
            n,
            probe: [0.0; 3],
        }
    }

    /// Whether every entry of the three matrices is known finite: with `ASSIGN`, from the
    /// probe; without, never (the caller checks the storage).
    fn known_finite(&self) -> bool {
        ASSIGN && self.probe.iter().sum::<f64>() == 0.0
    }
}

/// `*y = x` with `ASSIGN`, else `*y += x`.
#[inline(always)]
fn put<const ASSIGN: bool>(y: &mut f64, x: f64) {
    if ASSIGN {
        *y = x;
    } else {
        *y += x;
    }
}

impl<const ASSIGN: bool> Entries for Matrices<'_, ASSIGN> {
    const TAU_AND_H: bool = true;
    #[inline(always)]
    fn add(&mut self, r: usize, c: usize, dq: f64, dv: f64) {
        let at = c * self.n + r;
        put::<ASSIGN>(&mut self.dq[at], dq);
        put::<ASSIGN>(&mut self.dv[at], dv);
        if ASSIGN {
            self.probe[0] += dq * 0.0;
            self.probe[1] += dv * 0.0;
        }
    }
    #[inline(always)]
    fn add_h(&mut self, r: usize, c: usize, h: f64) {
        put::<ASSIGN>(&mut self.h[c * self.n + r], h);
        if ASSIGN {
            self.probe[2] += h * 0.0;
        }
    }
    #[inline(always)]
    fn tau(&mut self, r: usize, x: f64) {
        put::<ASSIGN>(&mut self.tau[r], x);
    }
}

/// The right-hand sides of `aba_derivatives`' dense solve (with mimic joints), row by row: `nv`
/// rows of `3 nv` entries, the identity's row, then `−∂τ_r/∂q_c`, `−∂τ_r/∂q̇_c` side by side for
/// each column `c` (at `3 nv r + nv + 2 c` and the entry after it), so that the columns of a
/// row's branch up to the end of its subtree are one range.
struct SolveRows<'a> {
    rows: &'a mut [f64],
    nv: usize,
}

impl Entries for SolveRows<'_> {
    const TAU_AND_H: bool = false;
    #[inline(always)]
    fn add(&mut self, r: usize, c: usize, dq: f64, dv: f64) {
        let at = 3 * self.nv * r + self.nv + 2 * c;
        self.rows[at] -= dq;
        self.rows[at + 1] -= dv;
    }
    #[inline(always)]
    fn add_h(&mut self, _: usize, _: usize, _: f64) {}
    #[inline(always)]
    fn tau(&mut self, _: usize, _: f64) {}
}

/// The right-hand sides of `aba_derivatives`' products on a tree, column by column:
/// `−∂τ_r/∂q_c` at `2 (nv c + r)`, `−∂τ_r/∂q̇_c` after it. Each entry of the tree's pattern comes
/// once (a tree has no mimic joints) and is stored as it comes; only those are read.
struct BranchColumns<'a> {
    pairs: &'a mut [f64],
    nv: usize,
}

impl Entries for BranchColumns<'_> {
    const TAU_AND_H: bool = false;
    #[inline(always)]
    fn add(&mut self, r: usize, c: usize, dq: f64, dv: f64) {
        let at = 2 * (self.nv * c + r);
        self.pairs[at] = -dq;
        self.pairs[at + 1] = -dv;
    }
    #[inline(always)]
    fn add_h(&mut self, _: usize, _: usize, _: f64) {}
    #[inline(always)]
    fn tau(&mut self, _: usize, _: f64) {}
}

/// One body's columns `S_k` with their `ψ_k`, `α_k`, `β_k`, cut to its degrees of freedom.
struct Columns<'a> {
    s: &'a [Motion],
    psi: &'a [Motion],
    alpha: &'a [Motion],
    beta: &'a [Motion],
}

impl<'a> Columns<'a> {
    fn of(
        s: &'a MotionSubspace,
        psi: &'a [Motion; 6],
        alpha: &'a [Motion; 6],
        beta: &'a [Motion; 6],
    ) -> Self {
        let nv = s.nv;
        Columns {
            s: &s.cols[..nv],
            psi: &psi[..nv],
            alpha: &alpha[..nv],
            beta: &beta[..nv],
        }
    }
}

/// What row `(i, n)` of the backward pass reads from its body's subtree sums, with `S = S_in`:
/// `I^C_i S` and the angular part of `B^C_iᵀ S` (the left entries), and the forces column
/// `(i, n)` adds to `F_i`, `w_q = S ×* F_i + I^C_i α + B^C_i ψ` and `w_v = I^C_i β + B^C_i S`
/// (the right entries).
struct RowVectors {
    ic_s: Force,
    bt_s: Vector3,
    w_q: Force,
    w_v: Force,
}

impl RowVectors {
    /// `∂τ_i/∂q_j = (I^C_i S_i)ᵀ α_j + (B^C_iᵀ S_i)ᵀ ψ_j` (`ψ_j` read through its angular part).
    fn left_q(&self, alpha_j: Motion, psi_j: Motion) -> f64 {
        alpha_j.dot(&self.ic_s) + self.bt_s.dot(&psi_j.ang)
    }

    /// `∂τ_i/∂q̇_j = (I^C_i S_i)ᵀ β_j + (B^C_iᵀ S_i)ᵀ S_j`.
    fn left_v(&self, beta_j: Motion, s_j: Motion) -> f64 {
        beta_j.dot(&self.ic_s) + self.bt_s.dot(&s_j.ang)
    }
}

/// Every entry of `m` is finite; names the coordinate of the first row that is not. The whole
/// storage is probed at once ([`all_finite_long`]); only a matrix that fails is searched column by
/// column for the row to name.
pub(crate) fn check_matrix(
    model: &Model,
    quantity: &'static str,
    m: &DMatrix<f64>,
) -> Result<(), DynamicsError> {
    if all_finite_long(m.as_slice()) {
        return Ok(());
    }
    m.column_iter()
        .try_for_each(|col| check_result(model, quantity, col.as_slice()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ModelOptions;
    use crate::test_models::{floating, TREE_URDF};
    use crate::urdf::model_from_str;

    /// A non-finite entry anywhere fails the whole-storage probe and is named by its row's
    /// coordinate; a finite matrix with entries near overflow passes.
    #[test]
    fn check_matrix_names_the_row_of_a_non_finite_entry() {
        let text = include_str!("../../tests/models/tree.urdf");
        let model = model_from_str(text, &ModelOptions::default()).unwrap();
        let nv = model.nv();
        let mut m = DMatrix::from_element(nv, nv, 1e300);
        assert!(check_matrix(&model, "dtau_dq", &m).is_ok());
        for (value, row, col) in [(f64::NAN, nv - 1, 0), (f64::INFINITY, 1, nv - 1)] {
            m[(row, col)] = value;
            match check_matrix(&model, "dtau_dq", &m) {
                Err(DynamicsError::NonFiniteResult {
                    quantity,
                    coordinate,
                }) => assert_eq!((quantity, coordinate), ("dtau_dq", model.v_name(row))),
                other => panic!("{value} at ({row}, {col}): {other:?}"),
            }
            m[(row, col)] = 1e300;
        }
    }

    /// The probe of [`Matrices`] sees a value that is not finite in any of its three lanes
    /// (`∂τ/∂q`, `∂τ/∂q̇`, `H`), and only with `ASSIGN`.
    #[test]
    fn the_matrices_probe_sees_each_lane() {
        let n = 3;
        let storage = || {
            (
                vec![0.0; n * n],
                vec![0.0; n * n],
                vec![0.0; n * n],
                vec![0.0; n],
            )
        };
        for (dq, dv, h) in [
            (f64::INFINITY, 1.0, 1.0),
            (1.0, f64::NAN, 1.0),
            (1.0, 1.0, f64::NEG_INFINITY),
            (1e300, -1e300, 1e300),
        ] {
            let finite = [dq, dv, h].iter().all(|x| x.is_finite());
            let (mut m_dq, mut m_dv, mut m_h, mut tau) = storage();
            let mut out = Matrices::<true>::new(&mut m_dq, &mut m_dv, &mut m_h, &mut tau);
            out.add(1, 0, 2.0, 3.0);
            out.add(2, 1, dq, dv);
            out.add_h(2, 1, h);
            out.add_h(0, 0, 4.0);
            assert_eq!(out.known_finite(), finite, "{dq} {dv} {h}");
            let (mut m_dq, mut m_dv, mut m_h, mut tau) = storage();
            let mut out = Matrices::<false>::new(&mut m_dq, &mut m_dv, &mut m_h, &mut tau);
            out.add(2, 1, 1.0, 1.0);
            assert!(!out.known_finite());
        }
    }

    /// The backward pass knows its matrices finite exactly when they are: on the branched tree
    /// on a floating base, with each body's `α`, `β` (its first column) or mass made infinite in
    /// turn, the pass does not know the matrices finite and one of them has a value that is
    /// not; untouched, it knows them finite.
    #[test]
    fn the_backward_pass_knows_its_matrices_finite_only_when_they_are() {
        let model = model_from_str(TREE_URDF, &floating()).unwrap();
        let mut ws = Workspace::new(&model);
        let mut rng = crate::sampling::Rng::new(11);
        let q = crate::sampling::random_q(&model, &mut rng);
        let (v, a) = (rng.vector(model.nv, 1.0), rng.vector(model.nv, 1.0));
        let ext = Externals::none();
        let matrices_finite = |ws: &Workspace| {
            let d = &ws.derivatives;
            [&d.dtau_dq, &d.dtau_dv, &ws.mass_matrix]
                .iter()
                .all(|m| m.iter().all(|x| x.is_finite()))
        };
        update_joints(&model, &mut ws, &q);
        assert!(derivative_passes(
            &model,
            &mut ws,
            &v,
            &a,
            &ext,
            Target::Matrices
        ));
        assert!(matrices_finite(&ws));
        let inf = Motion::new(Vector3::new(f64::INFINITY, 0.0, 0.0), Vector3::zeros());
        for i in 0..model.bodies.len() {
            for poison in 0..3 {
                forward_pass(&model, &mut ws, &v, &a, &ext);
                match poison {
                    0 => ws.derivatives.alpha[i][0] = inf,
                    1 => ws.derivatives.beta[i][0] = inf,
                    _ => ws.ic[i].mass = f64::INFINITY,
                }
                let known = backward_pass(&model, &mut ws, Target::Matrices);
                assert!(!known && !matrices_finite(&ws), "body {i}, poison {poison}");
            }
        }
    }
}
