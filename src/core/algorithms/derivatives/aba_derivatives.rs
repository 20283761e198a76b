//! `∂q̈/∂q`, `∂q̈/∂q̇` and `H⁻¹ = ∂q̈/∂τ` of `q̈ = FD(q, q̇, τ)` (Carpentier & Mansard, RSS 2018,
//! section IV): `τ = ID(q, q̇, FD(q, q̇, τ))` for every state, so differentiating both sides at
//! `q̈ = FD(q, q̇, τ)` gives, exactly,
//!
//! ```text
//! ∂q̈/∂q = −H⁻¹ ∂τ/∂q,   ∂q̈/∂q̇ = −H⁻¹ ∂τ/∂q̇,   ∂q̈/∂τ = H⁻¹
//! ```
//!
//! with `∂τ/∂q`, `∂τ/∂q̇` from [`rnea_derivatives`](super::rnea_derivatives) at `(q, q̇, q̈)`.
//! `q̈` comes from `H q̈ = τ − C` (`H` by CRBA, factored as `LᵀL` along the tree or by Cholesky
//! with mimic joints); `H⁻¹` and both products with it from that factor, one solve per column.

use super::rnea_derivatives::{check_matrix, derivative_passes, Target};
use crate::algorithms::cholesky::cholesky_solve_rows;
use crate::algorithms::forward_dynamics::crba_solve_on_joints;
use crate::algorithms::kinematics::update_joints;
use crate::algorithms::ltl::ltl_solve_rows;
use crate::algorithms::validate::{all_finite, check_forward_inputs};
use crate::algorithms::Externals;
use crate::error::DynamicsError;
use crate::model::Model;
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
/// [`aba`](crate::algorithms::aba()) takes them. `q̈` itself is left in `ws.qdd()`. Models with
/// mimic joints are supported (`q̈` by CRBA and a dense Cholesky factor).
pub fn aba_derivatives<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    ext: &Externals<'_>,
) -> Result<AbaDerivatives<'w>, DynamicsError> {
    check_forward_inputs(model, ws, q, v, tau, ext)?;
    update_joints(model, ws, q);
    crba_solve_on_joints(model, ws, v, tau, ext)?;
    // The passes read q̈ while they write the workspace: lend it out (an empty vector holds no
    // allocation) and put it back.
    let qdd = std::mem::replace(&mut ws.qdd, DVector::zeros(0));
    identity_and_zeros(&mut ws.derivatives.rhs_rows, model.nv);
    derivative_passes(model, ws, v, qdd.as_slice(), ext, Target::SolveRows);
    ws.qdd = qdd;
    solve_with_factor(ws);
    let d = &ws.derivatives;
    // One branch-free pass over each result; the coordinate is looked for only on failure.
    for (quantity, m) in [
        ("ddq_dq", &d.ddq_dq),
        ("ddq_dv", &d.ddq_dv),
        ("Minv", &d.minv),
    ] {
        if !all_finite(m.as_slice()) {
            check_matrix(model, quantity, m)?;
        }
    }
    Ok(AbaDerivatives {
        ddq_dq: &ws.derivatives.ddq_dq,
        ddq_dv: &ws.derivatives.ddq_dv,
        minv: &ws.derivatives.minv,
    })
}

/// The right-hand sides before the passes add the derivatives: row `i` (of `3 nv` entries) is
/// `e_iᵀ` then zeros.
fn identity_and_zeros(rows: &mut [f64], nv: usize) {
    let k = 3 * nv;
    let rows = &mut rows[..k * nv];
    rows.fill(0.0);
    for i in 0..nv {
        rows[i * k + i] = 1.0;
    }
}

/// `H⁻¹` into `ws.derivatives.minv` and `−H⁻¹ ∂τ/∂q`, `−H⁻¹ ∂τ/∂q̇` into `ddq_dq`, `ddq_dv`,
/// solving `H X = B` for `B = [1 | −∂τ/∂q | −∂τ/∂q̇]` (held row by row in
/// `ws.derivatives.rhs_rows`, `nv` rows of `3 nv`, the columns of `−∂τ/∂q` and `−∂τ/∂q̇` side by
/// side: column `c` of each at `nv + 2 c` and `nv + 2 c + 1`) with the factor
/// `crba_solve_on_joints` left in `ws.factor`. Row `i` of `∂τ/∂q`, `∂τ/∂q̇` is zero outside
/// `i`'s branch (its ancestors and subtree: turning or moving a joint elsewhere changes no force
/// on `i`), so in particular at every column from `e(i)` on, as the tree solve takes it. The `3 nv` right-hand sides go row by row (each step an update of whole rows):
/// along the tree ([`ltl_solve_rows`]) over the non-zeros of `L`, `O(nv d)` per column for depth
/// `d`, where a product with the dense `H⁻¹` costs `nv²`; with mimic joints through the dense
/// Cholesky factor ([`cholesky_solve_rows`]). Of the symmetric `H⁻¹` the tree solve computes
/// the upper triangle, which is mirrored here.
fn solve_with_factor(ws: &mut Workspace) {
    let (plan, factor, d) = (&ws.plan, &ws.factor, &mut ws.derivatives);
    let nv = d.minv.nrows();
    if nv == 0 {
        return; // no columns (and `chunks_exact(0)` would panic)
    }
    let k = 3 * nv;
    let rows = &mut d.rhs_rows[..k * nv];
    match &plan.dof_ancestors {
        Some(ancestors) => ltl_solve_rows(ancestors, factor, rows, 2),
        None => cholesky_solve_rows(factor, rows, k),
    }
    // H⁻¹ from its upper triangle (symmetric; the tree solve computes only that), the
    // products in full. Column c of H⁻¹: entries i ≤ c from column c of rows 0..=c, entries
    // i > c from row c itself.
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
    use crate::algorithms::rnea_derivatives;
    use crate::model::ModelOptions;
    use crate::sampling::{random_q, Rng};
    use crate::urdf::model_from_str;
    use crate::Workspace;

    /// The tree solve takes row `i` of `∂τ/∂q`, `∂τ/∂q̇` as zero in every column from `e(i)`
    /// (the end of `i`'s subtree) on: it is, exactly, on a branched tree with a fixed, a
    /// planar and a floating base, where `e(i) < nv` for most rows.
    #[test]
    fn rows_of_the_inverse_dynamics_derivatives_end_with_their_subtree() {
        let tree = include_str!("../../tests/models/tree.urdf");
        let floating = ModelOptions {
            floating_base: true,
            ..Default::default()
        };
        for (text, options) in [
            (tree.to_string(), ModelOptions::default()),
            (tree.to_string(), floating),
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
            let (mut ending, mut nonzero) = (0, 0);
            for i in 0..nv {
                let end = ancestors.below(i).end;
                ending += usize::from(end < nv);
                for j in 0..nv {
                    let (dq, dv) = (d.dtau_dq[(i, j)], d.dtau_dv[(i, j)]);
                    if j >= end {
                        assert_eq!((dq, dv), (0.0, 0.0), "{}: row {i}, column {j}", model.name);
                    } else {
                        nonzero += usize::from(dq != 0.0 || dv != 0.0);
                    }
                }
            }
            assert!(ending >= 2, "{}: {ending} rows end before nv", model.name);
            assert!(nonzero > 0, "{}: all zeros", model.name);
        }
    }
}
