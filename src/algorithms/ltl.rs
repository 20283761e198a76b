//! Sparse `H = Lᵀ L` factorisation exploiting the branch-induced sparsity of the joint-space
//! inertia matrix (Featherstone, RBDA §6.5, Tables 6.3 and 6.4).
//!
//! `λ(k)` is the parent of degree of freedom `k` ([`Model::dof_parent`](crate::Model)); `H_ij`
//! is non-zero only when `i` is `j`, or an ancestor or descendant of `j`. `L` is lower
//! triangular with the same pattern, so the factorisation costs O(n d²) for a tree of depth `d`
//! and fills nothing in.

use super::pivot_is_sound;
use crate::error::DynamicsError;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Factorises `h` (full symmetric) into `factor`: afterwards `factor` holds `Lᵀ` in its upper
/// triangle along the tree pattern (entry `(j, k)` is `L_kj`, so row `k` of `L` is column `k` of
/// `factor`, contiguous in memory), with `H = Lᵀ L`. Other entries of `factor` are left as
/// they were. `chain` is scratch of length `n`.
///
/// Fails, naming the coordinate, when a pivot is not positive, or is so small against the
/// original diagonal entry that every digit was lost (`H` singular or indefinite).
pub fn ltl_factor(
    model: &Model,
    lambda: &[Option<usize>],
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
    chain: &mut [usize],
) -> Result<(), DynamicsError> {
    let n = lambda.len();
    let (h, l) = (h.as_slice(), factor.as_mut_slice());
    // Column-major storage: entry (r, c) of the n × n matrix is at r + c n.
    let at = |r: usize, c: usize| r + c * n;
    for k in 0..n {
        for j in std::iter::once(k).chain(ancestors(lambda, k)) {
            l[at(j, k)] = h[at(j, k)];
        }
    }
    for k in (0..n).rev() {
        let pivot = l[at(k, k)];
        if !pivot_is_sound(pivot, h[at(k, k)]) {
            return Err(DynamicsError::SingularMassMatrix {
                coordinate: model.v_name(k),
                pivot,
            });
        }
        let l_kk = pivot.sqrt();
        l[at(k, k)] = l_kk;
        // The ancestors of k, nearest first; the ancestors of chain[m] are chain[m + 1..].
        let mut d = 0;
        for i in ancestors(lambda, k) {
            l[at(i, k)] /= l_kk;
            chain[d] = i;
            d += 1;
        }
        // H_ij −= L_ki L_kj for i an ancestor of k and j = i or an ancestor of i.
        let (before_k, from_k) = l.split_at_mut(k * n);
        let row_k = &from_k[..n];
        for m in 0..d {
            let i = chain[m];
            let l_ki = row_k[i];
            let column_i = &mut before_k[i * n..(i + 1) * n];
            for &j in &chain[m..d] {
                column_i[j] -= l_ki * row_k[j];
            }
        }
    }
    Ok(())
}

/// Solves `Lᵀ L x = b` in place (`x` holds `b` on entry), `factor` as [`ltl_factor`] left it.
pub fn ltl_solve(lambda: &[Option<usize>], factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    let n = lambda.len();
    let l = factor.as_slice();
    let x = x.as_mut_slice();
    // Lᵀ y = b, from the leaves inward.
    for i in (0..n).rev() {
        let row_i = &l[i * n..(i + 1) * n];
        x[i] /= row_i[i];
        for j in ancestors(lambda, i) {
            x[j] -= row_i[j] * x[i];
        }
    }
    // L x = y, from the root outward.
    for i in 0..n {
        let row_i = &l[i * n..(i + 1) * n];
        for j in ancestors(lambda, i) {
            x[i] -= row_i[j] * x[j];
        }
        x[i] /= row_i[i];
    }
}

/// The proper ancestors of degree of freedom `k`, nearest first: `λ(k), λ(λ(k)), …`.
fn ancestors(lambda: &[Option<usize>], k: usize) -> impl Iterator<Item = usize> + '_ {
    std::iter::successors(lambda[k], move |&i| lambda[i])
}
