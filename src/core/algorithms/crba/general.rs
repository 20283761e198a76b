//! CRBA for any coordinate map, mimic joints included: RBDA Table 6.2 in world coordinates,
//! each column walked up its path to the root and accumulated, since coordinates may be shared
//! across bodies.

use crate::model::Model;
use crate::Workspace;

/// `H` into `ws.mass_matrix` from `⁰I_i` and `⁰S_i` already in `ws.ic` and `ws.s_world`: for
/// each body `i` (inward) and column `k` of its joint, `F = ⁰I^c_i ⁰S_ik`, then at `i` and at
/// every ancestor `j`, `H[c_j, c_i] += μ_j μ_i ⁰S_jᵀ F` and its mirror (`c` a joint's
/// coordinate, `μ` its scale, 1 but for a mimic follower: `H = Jᵀ H_full J` for the coordinate
/// map `J`); then `⁰I^c_λ += ⁰I^c_i`. True when every entry is finite.
pub(super) fn along_paths(model: &Model, ws: &mut Workspace) -> bool {
    let h = &mut ws.mass_matrix;
    h.as_mut_slice().fill(0.0); // H = 0   (RBDA Table 6.2)
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let ci = body.joint.coords;
        let s_i = &ws.s_world[i];
        for k in 0..s_i.nv {
            // F = I^c_i S_i   (RBDA Table 6.2)
            let f = ws.ic[i].apply(&s_i.cols[k]);
            // H_ii = S_iᵀ F   (RBDA Table 6.2), scaled μ_i² and added: coordinates are shared
            for k2 in 0..=k {
                let h_kk2 = ci.scale * ci.scale * s_i.project(k2, &f);
                h[(ci.v_index + k2, ci.v_index + k)] += h_kk2;
                if k2 != k {
                    h[(ci.v_index + k, ci.v_index + k2)] += h_kk2;
                }
            }
            // j = i; while λ(j) ≠ 0: F = λ(j)X*_j F (the identity in world coordinates),
            // j = λ(j), H_ij = Fᵀ S_j, H_ji = H_ijᵀ   (RBDA Table 6.2), scaled μ_i μ_j and added
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
            // I^c_λ(i) = I^c_λ(i) + I^c_i   (RBDA Table 6.2, world coordinates)
            let ic_i = ws.ic[i];
            ws.ic[p] += ic_i;
        }
    }
    ws.mass_matrix.iter().all(|x| x.is_finite())
}
