//! `∂q̈/∂q`, `∂q̈/∂q̇` and `H⁻¹ = ∂q̈/∂τ` of `q̈ = FD(q, q̇, τ)` (Carpentier & Mansard, RSS 2018,
//! section IV): `τ = ID(q, q̇, FD(q, q̇, τ))` for every state, so differentiating both sides at
//! `q̈ = FD(q, q̇, τ)` gives, exactly,
//!
//! ```text
//! ∂q̈/∂q = −H⁻¹ ∂τ/∂q,   ∂q̈/∂q̇ = −H⁻¹ ∂τ/∂q̇,   ∂q̈/∂τ = H⁻¹
//! ```
//!
//! with `∂τ/∂q`, `∂τ/∂q̇` from the passes of [`rnea_derivatives`](super::rnea_derivatives) at
//! `(q, q̇, q̈)`. Those passes make, on the way, what `q̈` itself needs (the placements, `S_i`,
//! `v_i`, `I_i`, the composite inertias `I^C_i`), so `q̈` and the derivatives share them: a
//! first forward and backward pass (A) make what does not depend on `q̈`, and `q̈` from it; a
//! second pair (B) what does. Every quantity is in the aligned frame of its tree (world axes,
//! origin at the root body's origin), as in `rnea_derivatives`.
//!
//! Forward pass A, root outward (what does not depend on `q̈`; `a⁰_0 = a_base − g`):
//! ```text
//! v_i = v_λ + S_i q̇_i,   ψ_ik = v_λ × S_ik,   β_ik = ψ_ik + v_i × S_ik,   B_i,   I_i
//! a⁰_i = a⁰_λ + Σ_k ψ_ik q̇_ik                     (the acceleration at q̈ = 0)
//! f⁰_i = I_i a⁰_i + v_i ×* I_i v_i − f^x_i
//! ```
//! Backward pass A, leaves inward (`C = τ(q, q̇, 0)` and CRBA's `H` in world axes):
//! ```text
//! I^C_i = Σ_{k ∈ subtree(i)} I_k,   F⁰_i = Σ_{k ∈ subtree(i)} f⁰_k
//! C_i = S_iᵀ F⁰_i,   H_ij = H_jiᵀ = S_iᵀ I^C_i S_j   (j = i or an ancestor of i)
//! ```
//! Then `H = Lᵀ L` along the tree and `q̈ = H⁻¹ (τ − C)`. Forward pass B, root outward (what
//! depends on `q̈`):
//! ```text
//! a_i = a_λ + Σ_k (S_ik q̈_ik + ψ_ik q̇_ik),   α_ik = a_λ × S_ik + v_λ × ψ_ik
//! f_i = I_i a_i + v_i ×* I_i v_i − f^x_i
//! ```
//! Backward pass B, leaves inward: the entries of `∂τ/∂q`, `∂τ/∂q̇` of `rnea_derivatives`'
//! backward pass, with `I^C_i` and `I^C_i S_i` from pass A and `B^C_i`, `F_i` summed there,
//! stored negated by column. Then `H⁻¹` from the factor of `H`, and each column of
//! `−H⁻¹ ∂τ/∂q`, `−H⁻¹ ∂τ/∂q̇` as the sum of the columns of `H⁻¹` over its branch (the column
//! of `∂τ/∂q` is zero elsewhere).
//!
//! A free-floating root on a tree (body 0 on a floating joint to the world) in a world at rest
//! and not turning (`root_velocity` zero, `root_acceleration = (0, a_lin)`) has six columns
//! of `∂q̈/∂q` and three of `∂q̈/∂q̇` in closed form. Gravity enters as the world's acceleration
//! `a_0 = (0, a_lin − g)`, which reaches the root in its own axes as `(0, −g_b)`, with
//! `g_b = R_bᵀ (g − a_lin)` the effective gravity (`R_b` the root's orientation), and adds to
//! its acceleration `S_0 q̈_0 = (ω̇, v̇)` as `−g_b` in its linear coordinates would. Nothing
//! else depends on the root's pose: the velocities come from `q̇` alone and the external
//! wrenches are fixed to their bodies. So `q̈ = q̈* + (g_b; 0; …; 0)`, `q̈*` the accelerations
//! at `g − a_lin = 0`, and on the tangent (`R_b → R_b exp(ε e_k×)`, so
//! `g_b → g_b + ε g_b × e_k`) the root's pose columns are, exactly, for `k = 0, 1, 2`:
//! ```text
//! ∂q̈/∂q_k = 0,   ∂q̈/∂q_{3+k} = (g_b × e_k; 0; …; 0)
//! ```
//! Its linear rates `u = q̇_0..3` are the velocity of its origin in its own axes, `R_bᵀ ṗ`, so
//! `q̈_0..3 = u̇ = R_bᵀ p̈ − ω × u` (`ω = q̇_3..6`). Adding `ε e_k` to `u` moves every body by
//! the same constant velocity `ε R_b e_k` in a world that does not turn, which changes no force
//! and so neither `p̈`, `ω̇` nor any joint's `q̈`: for `k = 0, 1, 2`
//! ```text
//! ∂q̈/∂q̇_k = (e_k × ω; 0; …; 0)
//! ```
//! Those nine columns are written so, with `(g_b)_k = S_0k,lin · (g − a_lin)` from the root's
//! linear columns in world axes; the products make only `∂q̈/∂q̇` in the angular columns and
//! nothing in the linear ones, and backward pass B does not make `∂τ/∂q`'s and `∂τ/∂q̇`'s
//! entries in those nine columns (it writes them as zero). In a moving or turning world the
//! root's velocity `X v_0 + S_0 q̇_0` and acceleration `X a_0 + …` in its own axes depend on its
//! pose (`X` the world-to-root transform): then, and for any other root, every column goes
//! through the products.
//!
//! With mimic joints (whose shared coordinates break the tree pattern of `H`) `q̈` comes from
//! CRBA, a bias RNEA and a dense Cholesky factor instead, and the passes of `rnea_derivatives`
//! run whole at `(q, q̇, q̈)`.

use super::branch_products::{branch_products, inverse_from_rows, Probe};
use super::rnea_derivatives::{
    acceleration_terms, ancestors, backward_pass, check_matrix, derivative_passes, dot_in_halves,
    forward_terms, Accelerations, RootMotion, Target,
};
use super::DerivativeScratch;
use crate::algorithms::cholesky::cholesky_solve_rows;
use crate::algorithms::forward_dynamics::crba_solve_on_joints;
use crate::algorithms::kinematics::{update_aligned_placements, update_joints, Anchors};
use crate::algorithms::ltl::{ltl_factor, ltl_inverse_transpose, ltl_solve};
use crate::algorithms::validate::{
    all_finite, all_finite_long, check_forward_inputs, check_result,
};
use crate::algorithms::Externals;
use crate::error::DynamicsError;
use crate::instruction_set::{run_pass, run_wide_pass};
use crate::model::{JointKind, Model};
use crate::mul_add::MulAdd;
use crate::spatial::Vector3;
use crate::Workspace;
use nalgebra::{DMatrix, DVector};

/// The derivatives of forward dynamics at one state, held in the workspace: `nv × nv`, full,
/// row `i` the derivative of `q̈_i`, columns in `v` order, on the tangent of
/// [the module](super) (`q ⊕ ε e_k`).
#[derive(Clone, Copy, Debug)]
pub struct AbaDerivatives<'w> {
    /// `∂q̈/∂q`.
    pub ddq_dq: &'w DMatrix<f64>,
    /// `∂q̈/∂q̇`.
    pub ddq_dv: &'w DMatrix<f64>,
    /// `H⁻¹ = ∂q̈/∂τ`.
    pub minv: &'w DMatrix<f64>,
}

/// The derivatives of `q̈ = FD(q, q̇, τ)` with external wrenches and base motion as
/// [`aba`](crate::algorithms::aba()) takes them. `q̈` itself is left in `ws.qdd()`, `H` in
/// `ws.mass_matrix()` and the bias forces `C` in `ws.tau()`. Models with mimic joints are
/// supported (`q̈` by CRBA and a dense Cholesky factor).
pub fn aba_derivatives<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<AbaDerivatives<'w>, DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    run_pass!(derivatives_of_checked(model, ws, q, v, tau, ext))?;
    Ok(AbaDerivatives {
        ddq_dq: &ws.derivatives.ddq_dq,
        ddq_dv: &ws.derivatives.ddq_dv,
        minv: &ws.derivatives.minv,
    })
}

/// [`aba_derivatives`] on checked inputs, the results checked finite; compiled once per
/// instruction set ([`run_pass`]).
#[inline(always)]
fn derivatives_of_checked(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<(), DynamicsError> {
    update_joints(model, ws, q);
    let free_root = if ws.plan.dof_ancestors.is_some() {
        shared_passes(model, ws, v, tau, ext)?
    } else {
        identity_and_zeros(&mut ws.derivatives.rhs, model.nv);
        crba_solve_on_joints(model, ws, v, tau, ext)?;
        let qdd = lend_qdd(ws);
        derivative_passes(model, ws, v, qdd.as_slice(), ext, Target::SolveRows);
        ws.qdd = qdd;
        None
    };
    if !solve_with_factor(model, ws, free_root) {
        // The coordinate of a value that is not finite is looked for only on failure.
        let d = &ws.derivatives;
        for (quantity, m) in [
            ("ddq_dq", &d.ddq_dq),
            ("ddq_dv", &d.ddq_dv),
            ("Minv", &d.minv),
        ] {
            check_matrix(model, quantity, m)?;
        }
    }
    Ok(())
}

/// `q̈` out of the workspace, for the passes that read it while they write the workspace (an
/// empty vector in its place holds no allocation); the caller puts it back.
fn lend_qdd(ws: &mut Workspace) -> DVector<f64> {
    std::mem::replace(&mut ws.qdd, DVector::zeros(0))
}

/// The passes of [the module](self) on a tree (`ws.plan.dof_ancestors`), on joints already
/// updated for `q`: `q̈` into `ws.qdd`, the factor of `H` into `ws.factor` and `−∂τ/∂q`,
/// `−∂τ/∂q̇` by column into `ws.derivatives.rhs`; returns [`FreeRoot`] when the root's pose
/// columns of `∂q̈/∂q` have their closed form. Fails, naming the coordinate, on a singular `H`
/// or a non-finite `q̈`.
#[inline(always)]
fn shared_passes(
    model: &Model,
    ws: &mut Workspace,
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<Option<FreeRoot>, DynamicsError> {
    let root = RootMotion::of(model, ext);
    bias_pass(model, ws, v, &root, ext);
    let free_root = FreeRoot::of(model, ws, v, ext, &root);
    composite_pass(model, ws, tau);
    let Workspace {
        plan,
        mass_matrix,
        factor,
        qdd,
        ..
    } = ws;
    let ancestors = plan.dof_ancestors.as_ref().expect("a tree");
    // A non-finite H fails the factorisation or shows in q̈.
    ltl_factor(model, ancestors, mass_matrix, factor)?;
    ltl_solve(ancestors, factor, qdd);
    check_result(model, "acceleration", qdd.as_slice())?;
    let qdd = lend_qdd(ws);
    for i in 0..model.bodies.len() {
        acceleration_terms(model, ws, i, v, qdd.as_slice(), &root);
    }
    ws.qdd = qdd;
    let free = free_root.is_some();
    backward_pass(
        model,
        ws,
        Target::BranchColumnsOnComposites { free_root: free },
    );
    Ok(free_root)
}

/// A free-floating root: body 0 on a floating joint to the world (coordinates `0..6`), the
/// world at rest (`root_velocity` zero) and not turning (`root_acceleration`'s angular part
/// zero), so that the columns of its pose in `∂q̈/∂q` and of its linear rates in `∂q̈/∂q̇` are
/// those of [the module](self): `g_b = R_bᵀ (g − a_lin)` is the effective gravity in the
/// root's axes, `ω` the root's angular velocity (its rates `q̇_3..6`).
#[derive(Clone, Copy)]
struct FreeRoot {
    g_b: Vector3,
    omega: Vector3,
}

impl FreeRoot {
    /// After forward pass A (`S_0` in `ws.s_world`): `(g_b)_k = S_0k,lin · (g − a_lin)` for
    /// the root's linear columns `S_0k = (0, R_b e_k)` in world axes, with
    /// `root.a = (0, a_lin − g)`.
    fn of(
        model: &Model,
        ws: &Workspace,
        v: &[f64],
        ext: &Externals<'_>,
        root: &RootMotion,
    ) -> Option<Self> {
        let body = model.bodies.first()?;
        let zero = Vector3::zeros();
        let free = body.parent.is_none()
            && matches!(body.joint.kind, JointKind::Floating)
            && body.joint.coords.v_index == 0
            && ext.root_velocity.ang == zero
            && ext.root_velocity.lin == zero
            && ext.root_acceleration.ang == zero;
        free.then(|| {
            let s = &ws.s_world[0].cols;
            FreeRoot {
                g_b: Vector3::from_fn(|k, _| -s[k].lin.dot(&root.a.lin)),
                omega: Vector3::new(v[3], v[4], v[5]),
            }
        })
    }

    /// The root's six columns of `∂q̈/∂q` into the first `6 nv` entries of `ddq_dq` and its
    /// three linear columns of `∂q̈/∂q̇` into the first `3 nv` of `ddq_dv` (column-major): zero
    /// but rows `0..3`, `g_b × e_k` in column `3 + k` of `ddq_dq` and `e_k × ω` in column `k`
    /// of `ddq_dv`.
    #[inline(always)]
    fn write_columns(&self, ddq_dq: &mut [f64], ddq_dv: &mut [f64], nv: usize) {
        let (g, w) = (self.g_b, self.omega);
        let pose = [[0.0, g.z, -g.y], [-g.z, 0.0, g.x], [g.y, -g.x, 0.0]];
        let rates = [[0.0, -w.z, w.y], [w.z, 0.0, -w.x], [-w.y, w.x, 0.0]];
        for (columns, first, crosses) in [(ddq_dq, 3, pose), (ddq_dv, 0, rates)] {
            let columns = &mut columns[..(first + 3) * nv];
            columns.fill(0.0);
            for (k, cross) in crosses.iter().enumerate() {
                columns[(first + k) * nv..][..3].copy_from_slice(cross);
            }
        }
    }
}

/// Forward pass A: each body's `forward_terms` at `q̈ = 0` (`S_i`, `v_i`, `ψ_i`, `β_i`, `B_i`,
/// `I_i`, the bias acceleration `a⁰_i` and its force `f⁰_i`).
#[inline(always)]
fn bias_pass(model: &Model, ws: &mut Workspace, v: &[f64], root: &RootMotion, ext: &Externals<'_>) {
    update_aligned_placements(model, ws, Anchors::Roots);
    for i in 0..model.bodies.len() {
        forward_terms(model, ws, i, v, Accelerations::Zero, root, ext);
    }
}

/// Backward pass A: sums `I^C_i` in `ws.derivatives.composite` and `F⁰_i` in
/// `ws.derivatives.f_bias`, writes the bias forces `C_i = S_iᵀ F⁰_i` into `ws.tau`, `τ − C`
/// into `ws.qdd`, `I^C_i S_ik` into `ws.f_cols` (for backward pass B) and
/// `H_ij = S_iᵀ I^C_i S_j` with its mirror into `ws.mass_matrix`, for `j` = `i` or an ancestor
/// (the composite-rigid-body recursion in world axes, where a force needs no transform on its
/// way up). That is `H`'s tree pattern; `H` is zeroed first (one memset: measured faster than
/// writing only the pattern, as `rnea_derivatives` does).
#[inline(always)]
fn composite_pass(model: &Model, ws: &mut Workspace, tau: &[f64]) {
    let Workspace {
        s_world,
        f_cols,
        tau: bias,
        qdd,
        mass_matrix,
        derivatives,
        ..
    } = ws;
    let DerivativeScratch {
        f_bias: f0,
        composite: ic,
        halves,
        ..
    } = derivatives;
    let n = model.nv;
    let h = mass_matrix.as_mut_slice();
    h.fill(0.0);
    // H_rc and H_cr (column-major storage).
    let mut put = |r: usize, c: usize, x: f64| {
        h[c * n + r] = x;
        h[r * n + c] = x;
    };
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let ci = body.joint.coords.v_index;
        let cols = &s_world[i].cols[..s_world[i].nv];
        for (k, s_k) in cols.iter().enumerate() {
            let row = ci + k;
            let ic_s = ic[i].apply(s_k);
            f_cols[row] = ic_s;
            let c = s_k.dot(&f0[i]);
            bias[row] = c;
            qdd[row] = tau[row] - c;
            for (m, s_m) in cols[..=k].iter().enumerate() {
                put(row, ci + m, s_m.dot(&ic_s));
            }
            for j in ancestors(model, i) {
                let cj = model.bodies[j].joint.coords.v_index;
                let s_j = &s_world[j];
                for (m, s_m) in s_j.cols[..s_j.nv].iter().enumerate() {
                    let h_ij = if halves[j] {
                        dot_in_halves(m, s_m, &ic_s)
                    } else {
                        s_m.dot(&ic_s)
                    };
                    put(row, cj + m, h_ij);
                }
            }
        }
        if let Some(p) = body.parent {
            let (ic_i, f0_i) = (ic[i], f0[i]);
            ic[p] += ic_i;
            f0[p] += f0_i;
        }
    }
}

/// The right-hand sides of the dense solve before the passes add the derivatives: row `i` (of
/// `3 nv` entries) is `e_iᵀ` then zeros.
#[inline(always)]
fn identity_and_zeros(rows: &mut [f64], nv: usize) {
    let k = 3 * nv;
    let rows = &mut rows[..k * nv];
    rows.fill(0.0);
    for i in 0..nv {
        rows[i * k + i] = 1.0;
    }
}

/// `H⁻¹` into `ws.derivatives.minv` and `−H⁻¹ ∂τ/∂q`, `−H⁻¹ ∂τ/∂q̇` into `ddq_dq`, `ddq_dv`,
/// with the factor of `H` in `ws.factor`.
///
/// On a tree (`ws.plan.dof_ancestors`), `Y = L⁻ᵀ` along the tree ([`ltl_inverse_transpose`],
/// in the last `nv²` entries of `ws.derivatives.rhs`), then `H⁻¹ = Yᵀ Y` by columns, two at a
/// time along a chain ([`inverse_from_rows`]), then each column of the products as
/// the sum of the columns of `H⁻¹` over its branch ([`branch_products`]), from `−∂τ/∂q`,
/// `−∂τ/∂q̇` held by column in the first `2 nv²` entries of `ws.derivatives.rhs`.
///
/// With mimic joints (the dense Cholesky factor), `H X = B` for `B = [1 | −∂τ/∂q | −∂τ/∂q̇]`
/// held row by row in `ws.derivatives.rhs` (`nv` rows of `3 nv`, the columns of `−∂τ/∂q`
/// and `−∂τ/∂q̇` side by side: column `c` of each at `nv + 2 c` and `nv + 2 c + 1`) is solved
/// through it ([`cholesky_solve_rows`]) and the solutions copied out.
///
/// A model of [`WIDE_FROM`] coordinates or more runs the AVX-512 copy where the processor has
/// it ([`run_wide_pass`]), with its wider blocks.
///
/// Returns whether every value of the three results is finite: on a tree from the [`Probe`]
/// that the inverse and the products add each block to as they store it (and the closed
/// form's columns), with mimic joints from one pass over each result.
fn solve_with_factor(model: &Model, ws: &mut Workspace, free_root: Option<FreeRoot>) -> bool {
    if model.nv >= WIDE_FROM && ws.plan.instruction_set.is_wide() {
        run_wide_pass!(solve_wide(model, ws, free_root; mul_add))
    } else {
        run_pass!(solve_narrow(model, ws, free_root; mul_add))
    }
}

/// The fewest coordinates for which [`solve_with_factor`] runs the AVX-512 copy: measured
/// faster on TALOS (50 coordinates), slower on Solo12 and ANYmal (18), whose columns fit the
/// AVX2 copy's blocks.
const WIDE_FROM: usize = 32;

/// [`solve_with_factor_in`] with the AVX-512 copy's blocks.
#[inline(always)]
fn solve_wide(
    model: &Model,
    ws: &mut Workspace,
    free_root: Option<FreeRoot>,
    mul_add: MulAdd,
) -> bool {
    solve_with_factor_in::<true>(model, ws, free_root, mul_add)
}

/// [`solve_with_factor_in`] with the blocks of the other copies.
#[inline(always)]
fn solve_narrow(
    model: &Model,
    ws: &mut Workspace,
    free_root: Option<FreeRoot>,
    mul_add: MulAdd,
) -> bool {
    solve_with_factor_in::<false>(model, ws, free_root, mul_add)
}

/// [`solve_with_factor`]'s body, compiled once per instruction set ([`run_pass`]): a pass of
/// its own, so that the solve's loops are compiled as a function of their own size.
#[inline(always)]
fn solve_with_factor_in<const WIDE: bool>(
    model: &Model,
    ws: &mut Workspace,
    free_root: Option<FreeRoot>,
    mul_add: MulAdd,
) -> bool {
    let (plan, factor, d) = (&ws.plan, &ws.factor, &mut ws.derivatives);
    let nv = model.nv;
    if nv == 0 {
        return true; // no columns (and `chunks_exact(0)` would panic)
    }
    match &plan.dof_ancestors {
        Some(ancestors) => {
            let (pairs, y) = d.rhs.split_at_mut(2 * nv * nv);
            let (y, minv) = (&mut y[..nv * nv], d.minv.as_mut_slice());
            // Y = L⁻ᵀ: the entries it does not write are zero from the allocation on (nothing
            // else writes this part of `rhs` on a tree).
            ltl_inverse_transpose(ancestors, factor, y, mul_add);
            let probe = &mut Probe::new(mul_add);
            inverse_from_rows::<WIDE>(ancestors, y, minv, probe, mul_add);
            let (ddq_dq, ddq_dv) = (d.ddq_dq.as_mut_slice(), d.ddq_dv.as_mut_slice());
            // A free root's rate columns 0..3 and pose columns 0..6 in closed form.
            let (v_from, q_from) = if free_root.is_some() { (3, 6) } else { (0, 0) };
            let x = (&mut *ddq_dq, &mut *ddq_dv);
            branch_products::<WIDE>(ancestors, minv, pairs, x, (v_from, q_from), probe, mul_add);
            if let Some(free_root) = free_root {
                free_root.write_columns(ddq_dq, ddq_dv, nv);
            }
            // Every value of the results went through the probe but the closed form's.
            probe.all_finite()
                && all_finite(&ddq_dq[..q_from * nv])
                && all_finite(&ddq_dv[..v_from * nv])
        }
        None => {
            let k = 3 * nv;
            let rows = &mut d.rhs[..k * nv];
            cholesky_solve_rows(factor, rows, k);
            copy_out(d, nv);
            [&d.ddq_dq, &d.ddq_dv, &d.minv]
                .iter()
                .all(|m| all_finite_long(m.as_slice()))
        }
    }
}

/// The solutions of the dense solve out of `ws.derivatives.rhs` into `H⁻¹` (from its
/// upper triangle: the solve computes only that) and the products.
fn copy_out(d: &mut DerivativeScratch, nv: usize) {
    let k = 3 * nv;
    let rows = &d.rhs[..k * nv];
    // Column c of H⁻¹: entries i ≤ c from column c of rows 0..=c, entries i > c from row c
    // itself.
    for (c, minv) in d.minv.as_mut_slice().chunks_exact_mut(nv).enumerate() {
        let (upper, lower) = minv.split_at_mut(c + 1);
        for (x, row) in upper.iter_mut().zip(rows.chunks_exact(k)) {
            *x = row[c];
        }
        lower.copy_from_slice(&rows[c * k + c + 1..c * k + nv]);
    }
    for (c, (dq, dv)) in d
        .ddq_dq
        .as_mut_slice()
        .chunks_exact_mut(nv)
        .zip(d.ddq_dv.as_mut_slice().chunks_exact_mut(nv))
        .enumerate()
    {
        let at = nv + 2 * c;
        for ((dq, dv), row) in dq.iter_mut().zip(dv.iter_mut()).zip(rows.chunks_exact(k)) {
            let pair = &row[at..at + 2];
            (*dq, *dv) = (pair[0], pair[1]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::aba_derivatives;
    use crate::algorithms::{
        crba, forward_dynamics, rnea_derivatives, rnea_with, Externals, ForwardDynamicsMethod,
    };
    use crate::error::DynamicsError;
    use crate::model::ModelOptions;
    use crate::sampling::{random_q, Rng};
    use crate::spatial::{Force, Motion, Vector3};
    use crate::test_models::{floating, TREE_URDF};
    use crate::urdf::model_from_str;
    use crate::Workspace;

    /// The shared passes leave what CRBA, a bias RNEA and the solve would: `ws.mass_matrix()`
    /// is `crba`'s `H`, `ws.tau()` the bias forces `C = RNEA(q, q̇, 0)` and `ws.qdd()` the
    /// forward dynamics by CRBA, with external wrenches and a moving base, on a branched tree
    /// on a planar and on a floating joint (relative to each quantity's largest entry), after
    /// every other algorithm that writes `H` ran on the workspace at another state.
    #[test]
    fn the_shared_passes_leave_h_the_bias_forces_and_the_accelerations() {
        let tree = TREE_URDF;
        for text in [
            tree.to_string(),
            tree.replace(r#"type="planar""#, r#"type="floating""#),
        ] {
            let model = model_from_str(&text, &ModelOptions::default()).unwrap();
            let mut ws = Workspace::new(&model);
            assert!(ws.plan.dof_ancestors.is_some(), "{}: a tree", model.name);
            let mut rng = Rng::new(5);
            let q = random_q(&model, &mut rng);
            let nv = model.nv();
            let (v, tau): (Vec<f64>, Vec<f64>) = (0..nv)
                .map(|i| ((i as f64 * 0.7).sin(), 3.0 * (i as f64 * 1.1).cos()))
                .unzip();
            let wrenches: Vec<Force> = (0..model.nbodies())
                .map(|i| {
                    let x = i as f64;
                    Force::new(
                        Vector3::new(0.3 * x.sin(), -0.2, 0.1 * x),
                        Vector3::new(1.0, x.cos(), -0.5),
                    )
                })
                .collect();
            let ext = Externals {
                wrenches: Some(&wrenches),
                root_velocity: Motion::new(
                    Vector3::new(0.3, -0.2, 0.1),
                    Vector3::new(0.5, 0.4, -0.6),
                ),
                root_acceleration: Motion::new(
                    Vector3::new(-0.1, 0.2, 0.4),
                    Vector3::new(1.0, -2.0, 0.5),
                ),
            };
            // Every other writer of `H` and of the workspace's scratch first, at another state:
            // nothing they leave may show.
            let q_before = random_q(&model, &mut rng);
            for method in ForwardDynamicsMethod::ALL {
                forward_dynamics(&model, &mut ws, &q_before, &v, &tau, method, &ext).unwrap();
            }
            rnea_derivatives(&model, &mut ws, &q_before, &v, &tau).unwrap();
            aba_derivatives(&model, &mut ws, &q, &v, &tau, &ext).unwrap();
            let (h, c, qdd) = (
                ws.mass_matrix().clone(),
                ws.tau().to_vec(),
                ws.qdd().to_vec(),
            );
            let mut other = Workspace::new(&model);
            let close = |name: &str, got: &[f64], want: &[f64]| {
                let scale = want.iter().fold(1.0f64, |m, x| m.max(x.abs()));
                for (k, (g, w)) in got.iter().zip(want).enumerate() {
                    assert!(
                        (g - w).abs() <= 1e-12 * scale,
                        "{} {name}[{k}]: {g} against {w}",
                        model.name
                    );
                }
            };
            close(
                "H",
                h.as_slice(),
                crba(&model, &mut other, &q).unwrap().as_slice(),
            );
            close(
                "C",
                &c,
                rnea_with(&model, &mut other, &q, &v, &vec![0.0; nv], &ext).unwrap(),
            );
            let by_crba = forward_dynamics(
                &model,
                &mut other,
                &q,
                &v,
                &tau,
                ForwardDynamicsMethod::Crba,
                &ext,
            )
            .unwrap();
            close("qdd", &qdd, by_crba);
        }
    }

    /// A massless leaf behind a prismatic joint makes `H` singular at that joint's coordinate:
    /// the factor of the shared passes names it, as forward dynamics by CRBA does.
    #[test]
    fn a_singular_mass_matrix_names_its_coordinate() {
        let text = r#"<robot name="a"><link name="world"/>
  <joint name="shoulder" type="revolute"><parent link="world"/><child link="l1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
  <link name="l1"><inertial><origin xyz="0 0 -0.2"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial></link>
  <joint name="slide" type="prismatic"><parent link="l1"/><child link="l2"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="1"/></joint>
  <link name="l2"/></robot>"#;
        let model = model_from_str(text, &ModelOptions::default()).unwrap();
        let mut ws = Workspace::new(&model);
        let (q, v, tau) = ([0.3, 0.1], [0.2, -0.1], [1.0, 1.0]);
        let none = Externals::none();
        let err = aba_derivatives(&model, &mut ws, &q, &v, &tau, &none).unwrap_err();
        assert!(
            matches!(&err, DynamicsError::SingularMassMatrix { coordinate, .. } if coordinate == "slide"),
            "{err:?}"
        );
        let by_crba = forward_dynamics(
            &model,
            &mut ws,
            &q,
            &v,
            &tau,
            ForwardDynamicsMethod::Crba,
            &none,
        );
        assert_eq!(err, by_crba.unwrap_err());
    }

    /// The products take column `j` of `∂τ/∂q`, `∂τ/∂q̇` as zero outside `j`'s branch (its
    /// ancestors, `j` and the coordinates below it), and the solve of `H⁻¹` each row `i` of
    /// `L⁻ᵀ` as zero from `e(i)` (the end of `i`'s subtree) on: `rnea_derivatives` writes no
    /// entry there, on a branched tree with a fixed, a planar and a floating base, where most
    /// pairs `(i, j)` are on no common branch. That the true derivatives are zero there is
    /// `tests/derivatives.rs`' check of every entry against central differences.
    #[test]
    fn columns_of_the_inverse_dynamics_derivatives_are_zero_off_their_branch() {
        let tree = TREE_URDF;
        for (text, options) in [
            (tree.to_string(), ModelOptions::default()),
            (tree.to_string(), floating()),
            (
                tree.replace(r#"type="planar""#, r#"type="floating""#),
                ModelOptions::default(),
            ),
        ] {
            let model = model_from_str(&text, &options).unwrap();
            let mut ws = Workspace::new(&model);
            let ancestors = ws.plan.dof_ancestors.clone().expect("numbered depth-first");
            let mut rng = Rng::new(11);
            let q = random_q(&model, &mut rng);
            let nv = model.nv();
            let (v, a): (Vec<f64>, Vec<f64>) = (0..nv)
                .map(|i| ((i as f64 * 0.9).sin(), (i as f64 * 1.3).cos()))
                .unzip();
            let d = rnea_derivatives(&model, &mut ws, &q, &v, &a).unwrap();
            let on_branch = |i: usize, j: usize| {
                ancestors.of(j).contains(&i) || (j..ancestors.below(j).end).contains(&i)
            };
            let (mut off, mut nonzero) = (0, 0);
            for i in 0..nv {
                for j in 0..nv {
                    let (dq, dv) = (d.dtau_dq[(i, j)], d.dtau_dv[(i, j)]);
                    if on_branch(i, j) {
                        nonzero += usize::from(dq != 0.0 || dv != 0.0);
                    } else {
                        off += 1;
                        assert_eq!((dq, dv), (0.0, 0.0), "{}: row {i}, column {j}", model.name);
                    }
                }
            }
            assert!(off >= nv, "{}: {off} entries off the branches", model.name);
            assert!(nonzero > 0, "{}: all zeros", model.name);
        }
    }
}
