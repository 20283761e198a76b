//! The joint-space inertia matrix `H(q)` by the composite rigid-body algorithm (Featherstone,
//! RBDA Table 6.2).
//!
//! Composite inertias, inward: `I^c_i = I_i + Σ_{children j} ʲX_iᵀ I^c_j ʲX_i`.
//! Then for each body `i` and each column `S_ik` of its joint, `F = I^c_i S_ik` (in body `i`
//! coordinates) gives the diagonal block `H_ii = S_iᵀ F`; carrying `F` towards the root,
//! `F ← ʲX_λ(j)ᵀ F`, gives the off-diagonal blocks `H_ji = S_jᵀ F = H_ijᵀ` for every ancestor `j`.
//!
//! With mimic joints, body `i` contributes to the column of its leader scaled by `μ_i`:
//! `H[c_j, c_i] += μ_j μ_i S_jᵀ F` (and its mirror), which is `Jᵀ H_full J` for the coordinate
//! map `J`.

use super::kinematics::update_joints;
use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::Workspace;
use nalgebra::DMatrix;

/// `H(q)` into `ws.mass_matrix()` (full and symmetric).
pub fn crba<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w DMatrix<f64>, DynamicsError> {
    check_q(model, q)?;
    update_joints(model, ws, q);
    crba_passes(model, ws);
    // Finite inputs can still overflow (a prismatic coordinate of 1e200 under a revolute joint
    // puts m·x² on the diagonal). Column-major: entry i is in row i mod nv.
    if let Some(i) = ws.mass_matrix.iter().position(|x| !x.is_finite()) {
        return Err(DynamicsError::NonFiniteResult {
            quantity: "mass matrix",
            coordinate: model.v_name(i % model.nv),
        });
    }
    Ok(&ws.mass_matrix)
}

/// The two passes, on joints already updated for `q`. Writes `ws.ic` and `ws.mass_matrix`.
pub(crate) fn crba_passes(model: &Model, ws: &mut Workspace) {
    for (i, body) in model.bodies.iter().enumerate() {
        ws.ic[i] = body.inertia;
    }
    for (i, body) in model.bodies.iter().enumerate().rev() {
        if let Some(p) = body.parent {
            let ic_parent = ws.x_up[i].transpose_apply_inertia(&ws.ic[i]);
            ws.ic[p] += ic_parent;
        }
    }
    let h = &mut ws.mass_matrix;
    h.fill(0.0);
    for (i, body) in model.bodies.iter().enumerate() {
        let ci = body.joint.coords;
        let s_i = &ws.s[i];
        for k in 0..s_i.nv {
            let mut f = ws.ic[i].apply(&s_i.cols[k]);
            for k2 in 0..=k {
                let h_kk2 = ci.scale * ci.scale * s_i.project(k2, &f);
                h[(ci.v_index + k2, ci.v_index + k)] += h_kk2;
                if k2 != k {
                    h[(ci.v_index + k, ci.v_index + k2)] += h_kk2;
                }
            }
            let mut j = i;
            while let Some(p) = model.bodies[j].parent {
                f = ws.x_up[j].transpose_apply_force(&f);
                j = p;
                let cj = model.bodies[j].joint.coords;
                for k2 in 0..ws.s[j].nv {
                    let h_ji = ci.scale * cj.scale * ws.s[j].project(k2, &f);
                    h[(cj.v_index + k2, ci.v_index + k)] += h_ji;
                    h[(ci.v_index + k, cj.v_index + k2)] += h_ji;
                }
            }
        }
    }
}
