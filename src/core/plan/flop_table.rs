//! The FLOP count of each kernel as `spatial_dynamics bench` names them, for a model and the
//! [`Plan`] its calls follow: the sum of its passes' costs from [`flops`](super::flops).

use super::flops::*;
use super::{Ancestors, CrbaFrames, Plan};
use crate::model::{JointKind, Model};

/// The count of kernel `name` (as `spatial_dynamics bench` names them: `rnea`, `crba`,
/// `fd_aba`, `fd_crba`, `fd_rnea_columns`, `gravity`) on `model` as its [`Plan`] runs it; `None`
/// for another name, or for `fd_aba` on a model with mimic joints (ABA refuses them).
pub fn kernel_flops(model: &Model, name: &str) -> Option<Flops> {
    let plan = &Plan::new(model);
    let n = model.nv as u64;
    let joints = joints(model, plan);
    // Inverse and forward dynamics check `q`, two more input vectors, the root's motion and
    // the result; CRBA `q` (its matrix by a probe the passes carry); gravity `q` and `τ`.
    let dynamics_checks = check_q(model) + all_finite(n) * 3 + MOTION_FINITE * 2;
    Some(match name {
        "rnea" => dynamics_checks + joints + rnea_passes(model, true, true),
        "crba" => check_q(model) + joints + crba_passes(model, plan),
        "gravity" => check_q(model) + all_finite(n) + joints + gravity_passes(model),
        "fd_aba" => {
            if model.bodies.iter().any(|b| b.joint.is_mimic()) {
                return None;
            }
            dynamics_checks + joints + aba_passes(model, &plan.anchors)
        }
        "fd_crba" => {
            let solve = match &plan.dof_ancestors {
                Some(ancestors) => ltl(ancestors),
                None => dense_cholesky(n),
            };
            dynamics_checks + joints + rnea_passes(model, true, false) + crba_passes(model, plan) + solve
                // τ − C; each pivot checked against H_kk ε
                + Flops::new(n, n)
        }
        "fd_rnea_columns" => {
            dynamics_checks
                + (joints + rnea_passes(model, true, false))
                + (joints + rnea_passes(model, true, true)) * n
                // H_k = τ − C for each column, τ − C once; each pivot checked against H_kk ε
                + Flops::new(n, n * n + n)
                + dense_cholesky(n)
        }
        _ => return None,
    })
}

/// CRBA's passes in the frames the plan chose ([`crate::plan::crba_frames`]).
fn crba_passes(model: &Model, plan: &Plan) -> Flops {
    match plan.crba_frames {
        CrbaFrames::World => crba_world(model, plan.subtree_end.is_none()),
        CrbaFrames::Local => crba_local(model),
    }
}

/// The three ABA passes (world frame), each body's passes 2 and 3 as its joint takes them:
/// one degree of freedom, a floating root, or the general form.
fn aba_passes(model: &Model, anchors: &[bool]) -> Flops {
    // Pass 3's a_0 = a_base − [0; g] (as in `rnea_passes`).
    let mut total = placements(model) + Flops::new(0, 3);
    for (i, body) in model.bodies.iter().enumerate() {
        let nv = body.joint.kind.nv() as u64;
        let has_parent = body.parent.is_some();
        // Pass 1: ⁰S, v_J (`S q̇`, each rate scaled by the mimic factor), v_i, c_i, ⁰I (and as
        // a 6×6), p^A.
        total += world_axes(&body.joint.kind) + world_rates(nv) + ADD6;
        total += CROSS6 + bias_added(&body.joint.kind, TRANSFORM_VECTOR);
        total += TRANSFORM_INERTIA + INERTIA_TO_MATRIX + INERTIA_APPLY + CROSS6;
        // Pass 2's u = τ − Sᵀ p^A (a floating root's S τ − p^A: the same count); the pivot
        // check's scale `64 ε · max diag I^A` is the one multiplication counted with `D`.
        total += (DOT6 + Flops::new(0, 1)) * nv;
        // Pass 3's a' = a_λ + c_i.
        total += ADD6;
        total += if nv == 1 {
            aba_one_dof(has_parent)
        } else if !has_parent && body.joint.kind == JointKind::Floating {
            aba_floating_root()
        } else {
            aba_general(nv, has_parent)
        };
        if anchors[i] {
            // The parent's (or the root's) velocity and acceleration moved into the body's
            // aligned frame (`Translation::apply_motion`: a cross product and three
            // subtractions each).
            total += TRANSLATE_VECTOR * 2;
            if has_parent {
                // I^a and p^a moved into the parent's frame.
                total += TRANSLATE_MATRIX6 + TRANSLATE_VECTOR;
            }
        }
        if has_parent {
            // The parent sums of I^a and p^a.
            total += Flops::new(0, 36) + ADD6;
        }
    }
    total
}

/// `v_J = ⁰S q̇` in ABA's pass 1 (`kinematics::world_axes`): one column scaled by `μ q̇` (7 m), or
/// the columns summed from zero ([`SUBSPACE_COLUMN`] each).
fn world_rates(nv: u64) -> Flops {
    if nv == 1 {
        Flops::new(7, 0)
    } else {
        SUBSPACE_COLUMN * nv
    }
}

/// ABA's passes 2 and 3 at a joint of one degree of freedom (`aba::articulate_one_dof`,
/// `accelerate_one_dof`), beyond [`aba_passes`]' shared terms: `U = I^A S`, `D = Sᵀ U`, `1/D`
/// and its pivot check; below a parent `w = U / D`, the rank-1 update `I^A − U wᵀ`,
/// `I^a c + U (u / D)` added to `p^A`; then `q̈ = (u − Uᵀ a') / D` and `a' + S q̈`.
fn aba_one_dof(has_parent: bool) -> Flops {
    let mut total = MAT6_VEC6 + DOT6;
    total += Flops {
        div: 1,
        ..Flops::new(1, 0)
    };
    if has_parent {
        total += Flops::new(6, 0) + Flops::new(36, 36) + MAT6_VEC6 + Flops::new(7, 0);
        total += ADD6 * 2;
    }
    total + DOT6 + Flops::new(1, 1) + Flops::new(6, 6)
}

/// ABA's passes 2 and 3 at a floating root (`aba::articulate_floating_root`,
/// `accelerate_floating_root`), beyond [`aba_passes`]' shared terms (whose `u = τ − Sᵀ p^A`
/// stands for the right-hand side `S τ − p^A`, the same 36 m + 36 a): `a = (I^A)⁻¹ (S τ − p^A)`
/// by an `L D Lᵀ` solve in world axes (its pivots checked against one scale); then
/// `q̈ = Sᵀ (a − a')`.
fn aba_floating_root() -> Flops {
    let pass_2 = ldlt_solve(6) + Flops::new(1, 0);
    pass_2 + Flops::new(0, 6) + DOT6 * 6
}

/// ABA's passes 2 and 3 at any other joint (`aba::articulate`): `U`, `D`, `D⁻¹` (its pivots
/// checked against one scale); below a parent `D⁻¹ u` and the rows of `D⁻¹ Uᵀ`, the rank-nv
/// update, `U D⁻¹ u` and `I^a c` added to `p^A`; then the right-hand side `u − Uᵀ a'`,
/// `q̈ = D⁻¹ rhs` (a `sum` of nv products: its first addition, to −0, is folded), `a' + S q̈`.
fn aba_general(nv: u64, has_parent: bool) -> Flops {
    let mut total = MAT6_VEC6 * nv + DOT6 * (nv * nv) + spd_inverse(nv as usize) + Flops::new(1, 0);
    if has_parent {
        total += (Flops::new(nv, nv) + Flops::new(6, 6) * nv) * nv;
        total += (Flops::new(36, 36) + Flops::new(6, 6)) * nv;
        total += MAT6_VEC6 + ADD6;
    }
    total + (DOT6 + Flops::new(0, 1)) * nv + Flops::new(nv, nv - 1) * nv + Flops::new(6, 6) * nv
}

/// `ltl_factor` and `ltl_solve` along the tree: for coordinate `k` with `d_k` ancestors and
/// `s_k` descendants, `d_k + 1` products of two column segments of length `s_k`, each subtracted
/// from its entry of `H` (`s_k` multiplications and `s_k` subtractions: the products' sum
/// starts from the first product; none for a leaf), one square root, one division (`1 / L_kk`,
/// stored) and `d_k` multiplications by it; the two triangular solves, `2 s_k`
/// multiply-subtracts and two multiplications by `1 / L_kk`. The multiply-subtracts are RBDA's
/// (`d_k (d_k + 1) / 2` for `k` counted at each descendant instead).
fn ltl(ancestors: &Ancestors) -> Flops {
    let mut total = Flops::default();
    for k in 0..ancestors.len() {
        let d = ancestors.of(k).len() as u64;
        let s = ancestors.below(k).len() as u64;
        let products = (d + 1) * s + 2 * s;
        total += Flops {
            sqrt: 1,
            div: 1,
            ..Flops::new(products + d + 2, products)
        };
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::flops::tests::chain;

    /// For an unbranched chain `H` is dense and the sparse `LᵀL` is a dense Cholesky. Featherstone
    /// (RBDA §6.5) gives `n³/6 + n²/2 − 2n/3` multiplications for the factorisation, counting
    /// the `n(n−1)/2` scalings by `1/L_kk` as multiplications (as we do, after one division a
    /// row), and `n` square roots; the two substitutions add `n² − n` multiply-adds and `2n`
    /// scalings, multiplications here. Against the dense Cholesky (which divides each entry by
    /// its pivot in both), the scalings are multiplications and the `n` reciprocals divisions;
    /// the additions agree.
    #[test]
    fn ltl_on_a_chain_matches_the_dense_cholesky_count() {
        for n in [1usize, 2, 7, 30] {
            let model = chain(n);
            let ancestors = Ancestors::new(model.dof_parent.as_ref().unwrap()).unwrap();
            let n = n as u64;
            let count = ltl(&ancestors);
            let solve_mul = n * n - n + 2 * n;
            assert_eq!(
                count.mul - solve_mul,
                (n * n * n + 3 * n * n - 4 * n) / 6,
                "n = {n}"
            );
            assert_eq!(count.div, n, "n = {n}");
            assert_eq!(count.sqrt, n, "n = {n}");
            let dense = dense_cholesky(n);
            let scalings = n * (n - 1) / 2 + 2 * n;
            assert_eq!(
                (count.mul, count.div + scalings),
                (dense.mul + scalings, dense.div + n),
                "n = {n}"
            );
            assert_eq!(count.add, dense.add, "n = {n}");
        }
    }

    /// Per body of a revolute chain, RNEA costs what its passes do: the joint coordinate
    /// `scale · q + offset` (1 m + 1 a), jcalc (`σ q` and `spatial::sin_cos`, 1 + 27 m, 35 a;
    /// each joint's placement has no rotation, so its turn is written as it is), two
    /// transforms (a turn about the joint axis after a translation, 14 m + 10 a), and as `S`
    /// is a unit vector along the joint axis, `σ μ` and its products with `q̇` and `q̈`
    /// (3 m), one component each of `v_i` and `a_i` added to (2 a) and `q̇ (v_i ×̂ e_j)` added
    /// to `a_i` (4 m + 4 a; a revolute joint has no `c_J`), two inertia products, a cross
    /// product and a sum for `f`, and inward `(σ μ) f_j` accumulated (2 m + 1 a) and, below the
    /// root, a transform and a sum. The checks: `x · 0` summed for each of `q`, `q̇`, `q̈` and
    /// `τ` (n m + n a, and 2 a to join the lanes when one is used, 3 when all four are) and for
    /// the root's velocity and acceleration (6 m + 5 a each).
    #[test]
    fn rnea_per_body_on_a_chain() {
        let per_body = Flops::new(
            1 + 28 + 28 + 3 + 4 + 48 + 18 + 2,
            1 + 35 + 20 + 2 + 4 + 36 + 12 + 6 + 1,
        );
        let below_root = Flops::new(14, 16);
        // a_0 = −[0; g]: three subtractions from zero.
        let root = Flops::new(0, 3);
        for n in [1usize, 4, 9] {
            let model = chain(n);
            let joins = if n == 1 { 2 } else { 3 };
            let checks = Flops::new(n as u64, n as u64 + joins) * 4 + Flops::new(12, 10);
            let expected = root + per_body * n as u64 + below_root * (n as u64 - 1) + checks;
            assert_eq!(kernel_flops(&model, "rnea"), Some(expected), "n = {n}");
        }
    }
}
