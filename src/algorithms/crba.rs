//! The joint-space inertia matrix `H(q)` by the composite rigid-body algorithm (Featherstone,
//! RBDA Table 6.2), with every spatial quantity in world (root) coordinates, as Pinocchio's
//! `crba` in its WORLD convention does (RBDA §6.2 notes the algorithm works in any frame).
//!
//! In world coordinates a composite inertia needs no transform on its way to the parent and a
//! column force `F` none on its way to the root; only each body's inertia and joint axes are
//! carried to the world once, by its placement `⁰X_i`:
//!
//! ```text
//! outward:  ⁱX_0 = ⁱX_λ ᵏX_0,   ⁰S_i = ⁰X_i S_i,   ⁰I^c_i = ⁱX_0ᵀ I_i ⁱX_0
//! inward:   F = ⁰I^c_i ⁰S_i,   H_ii = ⁰S_iᵀ F,   H_ji = ⁰S_jᵀ F = H_ijᵀ  (j ancestor of i)
//!           ⁰I^c_λ(i) += ⁰I^c_i
//! ```
//!
//! which is RBDA Table 6.2 with `ʲX_iᵀ` replaced by the identity (all in one frame). When every
//! subtree's coordinates are contiguous (the usual depth-first order) the inward pass fills `H`
//! by row blocks, Pinocchio's way: the `F` of each coordinate is kept, and body `i` fills its
//! rows from its own columns to the end of its subtree, `H_ij = S_iᵀ F_j` (see `row_blocks`).
//!
//! With mimic joints, body `i` contributes to the column of its leader scaled by `μ_i`:
//! `H[c_j, c_i] += μ_j μ_i S_jᵀ F` (and its mirror), which is `Jᵀ H_full J` for the coordinate
//! map `J`.

use super::kinematics::{update_joints, update_placements};
use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::{Force, Motion};
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
    // Finite inputs can still overflow (a prismatic coordinate of 1e200 under a revolute joint
    // puts m·x² on the diagonal). The passes say whether every entry came out finite; only
    // then is the matrix searched, for the coordinate to name (column-major: entry i is in row
    // i mod nv).
    if !crba_passes(model, ws) {
        let i = ws
            .mass_matrix
            .iter()
            .position(|x| !x.is_finite())
            .unwrap_or(0);
        return Err(DynamicsError::NonFiniteResult {
            quantity: "mass matrix",
            coordinate: model.v_name(i % model.nv),
        });
    }
    Ok(&ws.mass_matrix)
}

/// The two passes, on joints already updated for `q`. Writes `ws.x_world`, `ws.s_world`,
/// `ws.ic` (world coordinates) and `ws.mass_matrix`; true when every entry of `H` is finite.
pub(crate) fn crba_passes(model: &Model, ws: &mut Workspace) -> bool {
    update_placements(model, ws);
    for (i, body) in model.bodies.iter().enumerate() {
        let x = &ws.x_world[i];
        ws.ic[i] = x.transpose_apply_inertia(&body.inertia);
        let (s, s_world) = (&ws.s[i], &mut ws.s_world[i]);
        s_world.nv = s.nv;
        for k in 0..s.nv {
            s_world.cols[k] = x.inverse_apply_motion(&s.cols[k]);
        }
    }
    match ws.subtree_end.take() {
        Some(subtree_end) => {
            let finite = row_blocks(model, ws, &subtree_end);
            ws.subtree_end = Some(subtree_end);
            finite
        }
        None => {
            along_paths(model, ws);
            ws.mass_matrix.iter().all(|x| x.is_finite())
        }
    }
}

/// Inward pass when every subtree's coordinates are contiguous (Pinocchio's layout): for body
/// `i` with coordinates `v_i .. v_i + n_i` and subtree coordinates `v_i .. e_i`,
/// `F_c = ⁰I^c_i ⁰S_c` for its own columns, then the row block
/// `H[v_i + k, c] = ⁰S_ikᵀ F_c` for `c` from `v_i + k` to `e_i` (upper triangle, mirrored):
/// each descendant's `F_c` was stored when that descendant was visited.
/// Entries outside the pattern are never written (they stay zero). True when every entry
/// written is finite: `0·x` is 0 for a finite `x` and NaN otherwise, so the sum `probe` of
/// `0·H_rc` stays 0 exactly when every entry is finite (two flops an entry, no branch).
fn row_blocks(model: &Model, ws: &mut Workspace, subtree_end: &[usize]) -> bool {
    let n = model.nv;
    let h = ws.mass_matrix.as_mut_slice();
    let mut probe = 0.0;
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let v0 = body.joint.coords.v_index;
        let s_i = &ws.s_world[i];
        for k in 0..s_i.nv {
            ws.f_cols[v0 + k] = ws.ic[i].apply(&s_i.cols[k]);
        }
        let end = subtree_end[i];
        for (k, s_ik) in s_i.cols[..s_i.nv].iter().enumerate() {
            let row = v0 + k;
            // Column `row` from the diagonal down, `H[c, row] = S_ikᵀ F_c` (contiguous in the
            // column-major storage), and its mirror `H[row, c]` right of the diagonal (one
            // column of `right` further for each c), in one sweep.
            let (left, right) = h.split_at_mut((row + 1) * n);
            let (diagonal, below) = left[row * n + row..row * n + end]
                .split_first_mut()
                .expect("a body's subtree holds its own coordinates");
            let mirror = right.chunks_exact_mut(n).map(|column| &mut column[row]);
            let f_row = &ws.f_cols[row..end];
            let s_ik = *s_ik; // a copy held in registers through the sweep
            *diagonal = dot6(&s_ik, &f_row[0]);
            probe += 0.0 * *diagonal;
            for ((h_cr, h_rc), f) in below.iter_mut().zip(mirror).zip(&f_row[1..]) {
                let x = dot6(&s_ik, f);
                (*h_cr, *h_rc) = (x, x);
                probe += 0.0 * x;
            }
        }
        if let Some(p) = body.parent {
            let ic_i = ws.ic[i];
            ws.ic[p] += ic_i;
        }
    }
    probe == 0.0
}

/// `Sᵀ F = ω·n + v·f`, written out (nalgebra's generic dot does not unroll), summed as two
/// interleaved halves, `(ω_x n_x + ω_z n_z + v_y f_y) + (ω_y n_y + v_x f_x + v_z f_z)`: the
/// lanes of the stored pairs `(x, y), (z, x'), (y', z')`, so the products pair up in SIMD
/// registers.
#[inline(always)]
fn dot6(s: &Motion, f: &Force) -> f64 {
    let (w, v, n, f) = (&s.ang, &s.lin, &f.ang, &f.lin);
    (w.x * n.x + w.z * n.z + v.y * f.y) + (w.y * n.y + v.x * f.x + v.z * f.z)
}

/// Inward pass in general (mimic joints, coordinates out of body order): each column force `F`
/// is projected on the joint axes of every ancestor on the way to the root, and accumulated
/// (coordinates may be shared).
fn along_paths(model: &Model, ws: &mut Workspace) {
    let h = &mut ws.mass_matrix;
    h.as_mut_slice().fill(0.0);
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let ci = body.joint.coords;
        let s_i = &ws.s_world[i];
        for k in 0..s_i.nv {
            let f = ws.ic[i].apply(&s_i.cols[k]);
            for k2 in 0..=k {
                let h_kk2 = ci.scale * ci.scale * s_i.project(k2, &f);
                h[(ci.v_index + k2, ci.v_index + k)] += h_kk2;
                if k2 != k {
                    h[(ci.v_index + k, ci.v_index + k2)] += h_kk2;
                }
            }
            let mut j = i;
            while let Some(p) = model.bodies[j].parent {
                j = p;
                let cj = model.bodies[j].joint.coords;
                let s_j = &ws.s_world[j];
                for k2 in 0..s_j.nv {
                    let h_ji = ci.scale * cj.scale * s_j.project(k2, &f);
                    h[(cj.v_index + k2, ci.v_index + k)] += h_ji;
                    h[(ci.v_index + k, cj.v_index + k2)] += h_ji;
                }
            }
        }
        if let Some(p) = body.parent {
            let ic_i = ws.ic[i];
            ws.ic[p] += ic_i;
        }
    }
}
