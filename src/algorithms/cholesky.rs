//! Dense Cholesky `H = L Lᵀ` with loud failure, for matrices whose sparsity does not follow the
//! tree (mimic joints couple branches) and for the n+1-RNEA method.

use super::pivot_is_sound;
use crate::error::DynamicsError;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// Factorises `h` into the lower triangle of `factor`, failing (and naming the coordinate) when
/// a pivot is not positive or has lost every digit against the original diagonal entry.
pub fn cholesky_factor(
    model: &Model,
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    factor.as_mut_slice().copy_from_slice(h.as_slice());
    let n = h.nrows();
    for j in 0..n {
        let mut pivot = factor[(j, j)];
        for k in 0..j {
            pivot -= factor[(j, k)] * factor[(j, k)];
        }
        if !pivot_is_sound(pivot, h[(j, j)]) {
            return Err(DynamicsError::SingularMassMatrix {
                coordinate: model.v_name(j),
                pivot,
            });
        }
        let l_jj = pivot.sqrt();
        factor[(j, j)] = l_jj;
        for i in j + 1..n {
            let mut s = factor[(i, j)];
            for k in 0..j {
                s -= factor[(i, k)] * factor[(j, k)];
            }
            factor[(i, j)] = s / l_jj;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ x = b` in place (`x` holds `b` on entry).
pub fn cholesky_solve(factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    let n = factor.nrows();
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= factor[(i, k)] * x[k];
        }
        x[i] = s / factor[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= factor[(k, i)] * x[k];
        }
        x[i] = s / factor[(i, i)];
    }
}
