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

/// The proper ancestors of every degree of freedom, nearest first (`λ(k), λ(λ(k)), …`), listed
/// once per model so that the factorisation and the solves walk plain slices.
#[derive(Clone, Debug)]
pub struct Ancestors {
    list: Vec<usize>,
    start: Vec<usize>,
}

impl Ancestors {
    /// From `λ` over degrees of freedom ([`Model::dof_parent`](crate::Model)).
    pub fn new(lambda: &[Option<usize>]) -> Self {
        let mut list = Vec::new();
        let mut start = vec![0];
        for k in 0..lambda.len() {
            list.extend(std::iter::successors(lambda[k], |&i| lambda[i]));
            start.push(list.len());
        }
        Ancestors { list, start }
    }

    /// The ancestors of `k`, nearest first; those of `of(k)[m]` are `of(k)[m + 1..]`.
    pub fn of(&self, k: usize) -> &[usize] {
        &self.list[self.start[k]..self.start[k + 1]]
    }

    /// The number of degrees of freedom.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// True for a model without degrees of freedom.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Factorises `h` (full symmetric) into `factor`: afterwards `factor` holds `Lᵀ` in its upper
/// triangle along the tree pattern (entry `(j, k)` is `L_kj`, so row `k` of `L` is column `k` of
/// `factor`, contiguous in memory), with `H = Lᵀ L`. Other entries of `factor` are left as
/// they were.
///
/// Fails, naming the coordinate, when a pivot is not positive, or is so small against the
/// original diagonal entry that every digit was lost (`H` singular or indefinite).
pub fn ltl_factor(
    model: &Model,
    ancestors: &Ancestors,
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    let n = ancestors.len();
    let (h, l) = (h.as_slice(), factor.as_mut_slice());
    // Column-major storage: entry (r, c) of the n × n matrix is at r + c n.
    let at = |r: usize, c: usize| r + c * n;
    for k in 0..n {
        l[at(k, k)] = h[at(k, k)];
        for &j in ancestors.of(k) {
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
        let chain = ancestors.of(k);
        let (before_k, from_k) = l.split_at_mut(k * n);
        let row_k = &mut from_k[..n];
        for &i in chain {
            row_k[i] /= l_kk;
        }
        // H_ij −= L_ki L_kj for i an ancestor of k and j = i or an ancestor of i.
        for (m, &i) in chain.iter().enumerate() {
            let l_ki = row_k[i];
            let column_i = &mut before_k[i * n..(i + 1) * n];
            for &j in &chain[m..] {
                column_i[j] -= l_ki * row_k[j];
            }
        }
    }
    Ok(())
}

/// Solves `Lᵀ L x = b` in place (`x` holds `b` on entry), `factor` as [`ltl_factor`] left it.
pub fn ltl_solve(ancestors: &Ancestors, factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    let n = ancestors.len();
    let l = factor.as_slice();
    let x = x.as_mut_slice();
    // Lᵀ y = b, from the leaves inward.
    for i in (0..n).rev() {
        let row_i = &l[i * n..(i + 1) * n];
        x[i] /= row_i[i];
        for &j in ancestors.of(i) {
            x[j] -= row_i[j] * x[i];
        }
    }
    // L x = y, from the root outward.
    for i in 0..n {
        let row_i = &l[i * n..(i + 1) * n];
        for &j in ancestors.of(i) {
            x[i] -= row_i[j] * x[j];
        }
        x[i] /= row_i[i];
    }
}
