//! Dense Cholesky `H = L Lᵀ` with loud failure, for matrices whose sparsity does not follow the
//! tree (mimic joints couple branches) and for the n+1-RNEA method; and the inverse of a joint's
//! small `D = Sᵀ Iᴬ S` for ABA ([`spd_inverse`]).

use super::pivot_is_sound;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::spatial::Matrix6;
use nalgebra::{DMatrix, DVector};

/// Factorises `h = L Lᵀ` from its lower triangle into the lower triangle of `factor` (diagonal
/// included; nothing else is written), failing (and naming the coordinate) when a pivot is not
/// positive or has lost every digit against the original diagonal entry. Column by column, each
/// from the columns before it (Golub and Van Loan's gaxpy Cholesky):
///
/// ```text
/// v = H[j.., j] − Σ_{k<j} L_jk L[j.., k],   L_jj = √v_j,   L[j+1.., j] = v[j+1..] / L_jj
/// ```
///
/// Every update runs down a column, contiguous in column-major storage and independent entry by
/// entry; the sum of each entry takes its terms in the order `k = 0, 1, …` of the textbook dot
/// products. Dot products along rows would step `n` entries at a time, and for `n` a multiple of
/// 64 every step would miss the L1 cache (docs/performance.md, long chains).
///
/// The lower triangle is the one to read when `H` comes from n+1 RNEA calls: its column `k` is
/// `RNEA(e_k) − C`, and `H_ij` loses digits against body `i`'s bias `C_i`, small below
/// (`i > j`, the lighter end of a graded chain) and large above (`test_conditioning.py` fails by
/// a factor of 10¹³ on the upper triangle of a chain with mass ratio 10⁻⁶).
pub fn cholesky_factor(
    model: &Model,
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    let n = h.nrows();
    let (h, l) = (h.as_slice(), factor.as_mut_slice());
    for j in 0..n {
        let (done, rest) = l.split_at_mut(j * n);
        let v = &mut rest[j..n]; // column j of L from the diagonal down
        v.copy_from_slice(&h[j * n + j..(j + 1) * n]);
        for l_k in done.chunks_exact(n) {
            let l_jk = l_k[j];
            for (v_i, l_ik) in v.iter_mut().zip(&l_k[j..]) {
                *v_i -= l_jk * l_ik;
            }
        }
        let pivot = v[0];
        if !pivot_is_sound(pivot, h[j * n + j]) {
            return Err(DynamicsError::SingularMassMatrix {
                coordinate: model.v_name(j),
                pivot,
            });
        }
        let l_jj = pivot.sqrt();
        v[0] = l_jj;
        for v_i in &mut v[1..] {
            *v_i /= l_jj;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ x = b` in place (`x` holds `b` on entry), with `L` in the lower triangle of
/// `factor` ([`cholesky_factor`]), reading `L` down its columns: `L y = b` by columns
/// (`y_k = b_k / L_kk`, then `b_i −= L_ik y_k` below), `Lᵀ x = y` by dot products with the
/// columns (`x_i = (y_i − Σ_{k>i} L_ki x_k) / L_ii`).
pub fn cholesky_solve(factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    let n = factor.nrows();
    if n == 0 {
        return; // nothing to solve (and no columns to walk: `chunks_exact(0)` would panic)
    }
    let x = x.as_mut_slice();
    for (k, l_k) in factor.as_slice().chunks_exact(n).enumerate() {
        x[k] /= l_k[k];
        let x_k = x[k];
        for (x_i, l_ik) in x[k + 1..].iter_mut().zip(&l_k[k + 1..]) {
            *x_i -= l_ik * x_k;
        }
    }
    for (i, l_i) in factor.as_slice().chunks_exact(n).enumerate().rev() {
        let mut s = x[i];
        for (l_ki, x_k) in l_i[i + 1..].iter().zip(&x[i + 1..]) {
            s -= l_ki * x_k;
        }
        x[i] = s / l_i[i];
    }
}

/// Solves `L Lᵀ X = B` in place for `k` right-hand sides held row by row (`w` is `n` rows of `k`
/// entries, the column-major storage of `Bᵀ`), `L` as [`cholesky_factor`] left it. Each step is
/// a whole-row update, independent entry by entry:
///
/// ```text
/// L Y = B:    Y_j = B_j / L_jj, then B_i −= L_ij Y_j for i > j
/// Lᵀ X = Y:   X_i = (Y_i − Σ_{j>i} L_ji X_j) / L_ii, from the last row up
/// ```
pub(crate) fn cholesky_solve_rows(factor: &DMatrix<f64>, w: &mut [f64], k: usize) {
    let n = factor.nrows();
    let l = factor.as_slice();
    for j in 0..n {
        let (head, tail) = w.split_at_mut((j + 1) * k);
        let row_j = &mut head[j * k..];
        let inv = 1.0 / l[j + j * n];
        row_j.iter_mut().for_each(|y| *y *= inv);
        for (row_i, l_ij) in tail.chunks_exact_mut(k).zip(&l[j * n + j + 1..(j + 1) * n]) {
            for (b, y) in row_i.iter_mut().zip(&*row_j) {
                *b -= l_ij * y;
            }
        }
    }
    for i in (0..n).rev() {
        let (head, tail) = w.split_at_mut((i + 1) * k);
        let row_i = &mut head[i * k..];
        for (row_j, l_ji) in tail.chunks_exact(k).zip(&l[i * n + i + 1..(i + 1) * n]) {
            for (y, x) in row_i.iter_mut().zip(row_j) {
                *y -= l_ji * x;
            }
        }
        let inv = 1.0 / l[i + i * n];
        row_i.iter_mut().for_each(|x| *x *= inv);
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
/// the factor solves `n` right-hand sides). As soon as a pivot `D_jj − Σ L_jk²` fails `sound`,
/// `Err((j, pivot))`: its row `j` and its value (`d_inv` is then unspecified).
pub fn spd_inverse(
    d: &Matrix6,
    n: usize,
    sound: impl Fn(f64) -> bool,
    d_inv: &mut Matrix6,
) -> Result<(), (usize, f64)> {
    let (l, inv_diag) = spd_factor(d, n, sound)?;
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
    Ok(())
}

/// Solves `D x = b` in place (`b` holds the right-hand side on entry) for the symmetric
/// positive definite top-left `n × n` block of `d` (`n ≤ 6`), through `D = L Lᵀ` as in
/// [`spd_inverse`], then `L y = b` and `Lᵀ x = y` (for `n = 6`, 92 multiplications where the
/// inverse and its product with `b` take 192):
///
/// ```text
/// y_j = (b_j − Σ_{k<j} L_jk y_k) / L_jj,   x_j = (y_j − Σ_{k>j} L_kj x_k) / L_jj   (j from n − 1 down)
/// ```
///
/// A pivot that fails `sound`: `Err((j, pivot))`, as [`spd_inverse`] (`b` is then unspecified).
pub fn spd_solve(
    d: &Matrix6,
    n: usize,
    sound: impl Fn(f64) -> bool,
    b: &mut [f64; 6],
) -> Result<(), (usize, f64)> {
    let (l, inv_diag) = spd_factor(d, n, sound)?;
    for j in 0..n {
        let mut s = b[j];
        for k in 0..j {
            s -= l[j][k] * b[k];
        }
        b[j] = s * inv_diag[j];
    }
    for j in (0..n).rev() {
        let mut s = b[j];
        for k in j + 1..n {
            s -= l[k][j] * b[k];
        }
        b[j] = s * inv_diag[j];
    }
    Ok(())
}

/// A small Cholesky factor: `L`'s lower triangle row by row, and the reciprocals `1 / L_jj`.
type SmallFactor = ([[f64; 6]; 6], [f64; 6]);

/// The factor `L` of `D = L Lᵀ` and the reciprocals `1 / L_jj` for the top-left `n × n` block of
/// `d`, as [`spd_inverse`] states; `Err((j, pivot))` for the first pivot that fails `sound`.
#[inline(always)]
fn spd_factor(
    d: &Matrix6,
    n: usize,
    sound: impl Fn(f64) -> bool,
) -> Result<SmallFactor, (usize, f64)> {
    let mut l = [[0.0; 6]; 6]; // lower triangle, row by row
    let mut inv_diag = [0.0; 6]; // 1 / L_jj
    for j in 0..n {
        let mut pivot = d[(j, j)];
        for k in 0..j {
            pivot -= l[j][k] * l[j][k];
        }
        if !sound(pivot) {
            return Err((j, pivot));
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
    Ok((l, inv_diag))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Row by row, the solve gives `H X = B` for several right-hand sides at once.
    #[test]
    fn row_solve_inverts_h() {
        let text = crate::model::examples::DEFAULT_ARM_URDF;
        let model = crate::urdf::model_from_str(text, &crate::ModelOptions::default()).unwrap();
        let n = model.nv();
        let mut ws = crate::Workspace::new(&model);
        let q = crate::sampling::random_q(&model, &mut crate::sampling::Rng::new(5));
        let h = crate::algorithms::crba(&model, &mut ws, &q)
            .unwrap()
            .clone();
        let mut factor = DMatrix::zeros(n, n);
        cholesky_factor(&model, &h, &mut factor).unwrap();
        let b = DMatrix::from_fn(n, 4, |i, j| ((i * 4 + j) as f64 * 0.9).sin());
        let mut rows = b.transpose().as_slice().to_vec();
        cholesky_solve_rows(&factor, &mut rows, 4);
        let x = DMatrix::from_column_slice(4, n, &rows).transpose();
        let err = (&h * &x - &b).amax();
        assert!(err < 1e-12 * h.amax() * x.amax(), "|H X − B| = {err:e}");
    }

    /// `D⁻¹ D = 1` and `D x = b` for SPD blocks of every size, and a singular block is refused.
    #[test]
    fn spd_inverse_inverts_and_refuses_singular_blocks() {
        let a = Matrix6::from_fn(|i, j| ((i * 7 + j * 3) % 5) as f64 - 1.5 + (i == j) as u8 as f64);
        let spd = a.transpose() * a + Matrix6::identity() * 0.1;
        for n in 1..=6 {
            let mut inv = Matrix6::zeros();
            assert_eq!(spd_inverse(&spd, n, |p| p > 1e-12, &mut inv), Ok(()));
            let block = spd.view((0, 0), (n, n)) * inv.view((0, 0), (n, n));
            let err = (block - nalgebra::DMatrix::<f64>::identity(n, n)).amax();
            assert!(err < 1e-12, "n = {n}: D⁻¹ D off the identity by {err:e}");
            assert_eq!(
                inv.view((0, 0), (n, n)),
                inv.view((0, 0), (n, n)).transpose()
            );
        }
        for n in 1..=6 {
            let b = [0.3, -1.2, 0.7, 2.0, -0.4, 1.1];
            let mut x = b;
            assert_eq!(spd_solve(&spd, n, |p| p > 1e-12, &mut x), Ok(()));
            let residual = spd.view((0, 0), (n, n)) * nalgebra::DVector::from_column_slice(&x[..n])
                - nalgebra::DVector::from_column_slice(&b[..n]);
            assert!(
                residual.amax() < 1e-12,
                "n = {n}: D x − b = {:e}",
                residual.amax()
            );
        }
        let mut singular = spd;
        singular.set_column(2, &singular.column(1).clone_owned());
        singular.set_row(2, &singular.row(1).clone_owned());
        // Row 2 repeats row 1: the third pivot is (to rounding) zero.
        let (j, pivot) =
            spd_inverse(&singular, 6, |p| p > 1e-9, &mut Matrix6::zeros()).unwrap_err();
        assert_eq!(j, 2);
        assert!(pivot.abs() < 1e-9 * singular.amax(), "pivot {pivot:e}");
        let refused = spd_solve(&singular, 6, |p| p > 1e-9, &mut [1.0; 6]).unwrap_err();
        assert_eq!(refused, (j, pivot));
    }
}
