//! Dense Cholesky `H = L Lᵀ` with loud failure, for matrices whose sparsity does not follow the
//! tree (mimic joints couple branches) and for the n+1-RNEA method; and the inverse of a joint's
//! small `D = Sᵀ Iᴬ S` for ABA ([`spd_inverse`]).

use super::pivot_is_sound;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Matrix6;
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

/// The inverse of the symmetric positive definite top-left `n × n` block of `d` (`n ≤ 6`) into
/// the same block of `d_inv` (its other entries are not written), through `D = L Lᵀ`:
///
/// ```text
/// L_jj = √(D_jj − Σ_{k<j} L_jk²),   L_ij = (D_ij − Σ_{k<j} L_ik L_jk) / L_jj      (i > j)
/// W = L⁻¹:   W_jj = 1 / L_jj,        W_ij = −(Σ_{j≤k<i} L_ik W_kj) / L_ii         (i > j)
/// D⁻¹ = Wᵀ W:   (D⁻¹)_ij = Σ_{k≥i} W_ki W_kj                                   (i ≥ j)
/// ```
///
/// (about `n³/2` multiplications, 156 for `n = 6`, and `n` divisions, where an inverse through
/// the factor solves `n` right-hand sides). False as soon as a pivot `D_jj − Σ L_jk²` fails
/// `sound` (`d_inv` is then unspecified).
pub fn spd_inverse(
    d: &Matrix6,
    n: usize,
    sound: impl Fn(f64) -> bool,
    d_inv: &mut Matrix6,
) -> bool {
    let mut l = [[0.0; 6]; 6]; // lower triangle, row by row
    let mut inv_diag = [0.0; 6]; // 1 / L_jj
    for j in 0..n {
        let mut pivot = d[(j, j)];
        for k in 0..j {
            pivot -= l[j][k] * l[j][k];
        }
        if !sound(pivot) {
            return false;
        }
        inv_diag[j] = 1.0 / pivot.sqrt();
        for i in j + 1..n {
            let mut s = d[(i, j)];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = s * inv_diag[j];
        }
    }
    let mut w = [[0.0; 6]; 6];
    for j in 0..n {
        w[j][j] = inv_diag[j];
        for i in j + 1..n {
            let mut s = l[i][j] * w[j][j];
            for k in j + 1..i {
                s += l[i][k] * w[k][j];
            }
            w[i][j] = -(s * inv_diag[i]);
        }
    }
    for j in 0..n {
        for i in j..n {
            let mut s = w[i][i] * w[i][j];
            for k in i + 1..n {
                s += w[k][i] * w[k][j];
            }
            (d_inv[(i, j)], d_inv[(j, i)]) = (s, s);
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `D⁻¹ D = 1` for SPD blocks of every size, and a singular block is refused.
    #[test]
    fn spd_inverse_inverts_and_refuses_singular_blocks() {
        let a = Matrix6::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 - 1.5 + (i == j) as u8 as f64);
        let spd = a.transpose() * a + Matrix6::identity() * 0.1;
        for n in 1..=6 {
            let mut inv = Matrix6::zeros();
            assert!(spd_inverse(&spd, n, |p| p > 1e-12, &mut inv));
            let block = spd.view((0, 0), (n, n)) * inv.view((0, 0), (n, n));
            let err = (block - nalgebra::DMatrix::<f64>::identity(n, n)).amax();
            assert!(err < 1e-12, "n = {n}: D⁻¹ D off the identity by {err:e}");
            assert_eq!(
                inv.view((0, 0), (n, n)),
                inv.view((0, 0), (n, n)).transpose()
            );
        }
        let mut singular = spd;
        singular.set_column(2, &singular.column(1).clone_owned());
        singular.set_row(2, &singular.row(1).clone_owned());
        assert!(!spd_inverse(
            &singular,
            6,
            |p| p > 1e-9,
            &mut Matrix6::zeros()
        ));
    }
}
