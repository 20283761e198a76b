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

/// Factorises `h` (full symmetric) into `factor` in place: afterwards the lower triangle of
/// `factor` (along the tree pattern) holds `L` with `H = Lᵀ L`.
///
/// Fails, naming the coordinate, when a pivot is not positive, or is so small against the
/// original diagonal entry that every digit was lost (`H` singular or indefinite).
pub fn ltl_factor(
    model: &Model,
    lambda: &[Option<usize>],
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    factor.copy_from(h);
    let n = lambda.len();
    for k in (0..n).rev() {
        let pivot = factor[(k, k)];
        if !pivot_is_sound(pivot, h[(k, k)]) {
            return Err(DynamicsError::SingularMassMatrix {
                coordinate: model.v_name(k),
                pivot,
            });
        }
        let l_kk = pivot.sqrt();
        factor[(k, k)] = l_kk;
        let mut i = lambda[k];
        while let Some(ii) = i {
            factor[(k, ii)] /= l_kk;
            i = lambda[ii];
        }
        let mut i = lambda[k];
        while let Some(ii) = i {
            let l_ki = factor[(k, ii)];
            let mut j = Some(ii);
            while let Some(jj) = j {
                factor[(ii, jj)] -= l_ki * factor[(k, jj)];
                j = lambda[jj];
            }
            i = lambda[ii];
        }
    }
    Ok(())
}

/// Solves `Lᵀ L x = b` in place (`x` holds `b` on entry).
pub fn ltl_solve(lambda: &[Option<usize>], factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    let n = lambda.len();
    // Lᵀ y = b, from the leaves inward.
    for i in (0..n).rev() {
        x[i] /= factor[(i, i)];
        let mut j = lambda[i];
        while let Some(jj) = j {
            x[jj] -= factor[(i, jj)] * x[i];
            j = lambda[jj];
        }
    }
    // L x = y, from the root outward.
    for i in 0..n {
        let mut j = lambda[i];
        while let Some(jj) = j {
            x[i] -= factor[(i, jj)] * x[jj];
            j = lambda[jj];
        }
        x[i] /= factor[(i, i)];
    }
}
