//! Sparse `H = Lᵀ L` factorisation exploiting the branch-induced sparsity of the joint-space
//! inertia matrix (Featherstone, RBDA §6.5, Tables 6.3 and 6.4).
//!
//! `λ(k)` is the parent of degree of freedom `k` ([`Model::dof_parent`](crate::Model)); `H_ij`
//! is non-zero only when `i` is `j`, or an ancestor or descendant of `j`. `L` is lower
//! triangular with the same pattern, so the factorisation costs O(n d²) for a tree of depth `d`
//! and fills nothing in.
//!
//! The degrees of freedom are numbered depth-first, so the descendants of `k` are the range
//! `D(k) = k + 1 .. e(k)`. Row `k` of `L` then follows from the rows below it (RBDA's Table 6.3
//! reordered to read columns instead of updating rows, the same operations):
//!
//! ```text
//! L_kk = √(H_kk − Σ_{m ∈ D(k)} L_mk²),   L_kj = (H_kj − Σ_{m ∈ D(k)} L_mk L_mj) / L_kk   (j ancestor of k)
//! ```
//!
//! each sum a product of two contiguous column segments of `L`, as are the solves.

use super::pivot_is_sound;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::plan::Ancestors;
use nalgebra::{DMatrix, DVector};

/// Factorises `h` (full symmetric) into `factor`: afterwards `factor` holds `L` in its lower
/// triangle along the tree pattern (entry `(k, j)` is `L_kj`; column `j` of `L` is contiguous in
/// memory), with `H = Lᵀ L`. Other entries of `factor` are left as they were.
///
/// Fails, naming the coordinate, when a pivot is not positive, or is so small against the
/// original diagonal entry that every digit was lost (`H` singular or indefinite).
pub(crate) fn ltl_factor(
    model: &Model,
    ancestors: &Ancestors,
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    let n = ancestors.len();
    let (h, l) = (h.as_slice(), factor.as_mut_slice());
    // Column-major storage: entry (r, c) of the n × n matrix is at r + c n.
    for k in (0..n).rev() {
        let below = ancestors.below(k);
        let pivot = h[k + k * n] - column_dot(l, n, k, k, below.clone());
        if !pivot_is_sound(pivot, h[k + k * n]) {
            return Err(DynamicsError::SingularMassMatrix {
                coordinate: model.v_name(k),
                pivot,
            });
        }
        let l_kk = pivot.sqrt();
        l[k + k * n] = l_kk;
        for &j in ancestors.of(k) {
            l[k + j * n] = (h[k + j * n] - column_dot(l, n, k, j, below.clone())) / l_kk;
        }
    }
    Ok(())
}

/// `Σ_{m ∈ rows} L_ma L_mb`: two contiguous column segments ([`dot`]).
#[inline(always)]
fn column_dot(l: &[f64], n: usize, a: usize, b: usize, rows: std::ops::Range<usize>) -> f64 {
    if rows.is_empty() {
        return 0.0; // a leaf: nothing below it
    }
    dot(&l[a * n..][rows.clone()], &l[b * n..][rows])
}

/// `Σ x_m y_m` in four interleaved partial sums (independent additions that pair up in SIMD
/// registers, where one running sum would wait on each addition).
#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (x4, y4) = (x.chunks_exact(4), y.chunks_exact(4));
    let (x_rest, y_rest) = (x4.remainder(), y4.remainder());
    for (p, q) in x4.zip(y4) {
        for t in 0..4 {
            acc[t] += p[t] * q[t];
        }
    }
    for (t, (p, q)) in x_rest.iter().zip(y_rest).enumerate() {
        acc[t] += p * q;
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3])
}

/// Solves `Lᵀ L x = b` in place (`x` holds `b` on entry), `factor` as [`ltl_factor`] left it.
pub(crate) fn ltl_solve(ancestors: &Ancestors, factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    ltl_solve_columns(ancestors, factor, x.as_mut_slice());
}

/// [`ltl_solve`] on every column of the column-major `n × k` matrix `x` (its `k` right-hand
/// sides side by side). The loops run coordinate outside, column inside: each column's solve
/// is a chain of dependent divisions, and interleaving the columns lets them overlap.
pub(crate) fn ltl_solve_columns(ancestors: &Ancestors, factor: &DMatrix<f64>, x: &mut [f64]) {
    let n = ancestors.len();
    if n == 0 {
        return; // no columns (and `chunks_exact_mut(0)` would panic)
    }
    let l = factor.as_slice();
    // Lᵀ y = b, from the leaves inward: y_i = (b_i − Σ_{m ∈ D(i)} L_mi y_m) / L_ii.
    for i in (0..n).rev() {
        let below = ancestors.below(i);
        let column_i = &l[i * n..(i + 1) * n];
        let (l_below, l_ii) = (&column_i[below.clone()], column_i[i]);
        for x in x.chunks_exact_mut(n) {
            x[i] = (x[i] - dot(l_below, &x[below.clone()])) / l_ii;
        }
    }
    // L x = y, from the root outward: x_i = y_i / L_ii, then y_m −= L_mi x_i below i.
    for i in 0..n {
        let below = ancestors.below(i);
        let column_i = &l[i * n..(i + 1) * n];
        let (l_below, l_ii) = (&column_i[below.clone()], column_i[i]);
        for x in x.chunks_exact_mut(n) {
            x[i] /= l_ii;
            let x_i = x[i];
            for (y, a) in x[below.clone()].iter_mut().zip(l_below) {
                *y -= a * x_i;
            }
        }
    }
}

/// Solves `Lᵀ L X = B` in place for `k` right-hand sides held row by row: `w` is `n` rows of
/// `k` entries, row `i` of `B` at `w[i k .. (i + 1) k]` (the column-major storage of `Bᵀ`).
/// Every step is then a whole-row update, contiguous and independent entry by entry, where a
/// column-by-column solve waits on one division after another:
///
/// ```text
/// Lᵀ Y = B, leaves inward:  Y_i = (B_i − Σ_{m ∈ D(i)} L_mi Y_m) / L_ii
/// L X = Y, root outward:    X_m = (Y_m − Σ_{a ∈ A(m)} L_ma X_a) / L_mm      (A(m): m's ancestors)
/// ```
///
/// Each row gathers its sum four rows at a time and divides in the last sweep
/// ([`subtract_combination_and_scale`]), reading and writing its own entries once per four
/// terms.
///
/// With `identity_first`, the first `n` columns of `B` are the identity (`k ≥ n`), and there:
/// row `i` of `Y = L⁻ᵀ` is zero outside the columns `i` and `D(i)` (`Y_i` gathers `e_i` and the
/// rows below `i`, each zero outside its own subtree's range), so the first pass updates only
/// the columns from `i` on (one contiguous range: the zeros past `D(i)` cost less to recompute
/// than a second sweep per group); and `X = H⁻¹` is symmetric, its row `m` at columns `c ≥ m` needs only its ancestors'
/// rows at the same columns (`c ≥ m > a`), so the second pass computes only the upper triangle
/// of that block (the entries below it are left as scratch, not `H⁻¹`).
pub(crate) fn ltl_solve_rows(
    ancestors: &Ancestors,
    factor: &DMatrix<f64>,
    w: &mut [f64],
    k: usize,
    identity_first: bool,
) {
    let n = ancestors.len();
    let l = factor.as_slice();
    for i in (0..n).rev() {
        let (head, tail) = w.split_at_mut((i + 1) * k);
        let row_i = &mut head[i * k..];
        let below = ancestors.below(i);
        // The columns to update: from i on with the identity first (columns before i are zero
        // in every row of the sum, and those past i's subtree up to n as well), or all.
        let columns = if identity_first { i..k } else { 0..k };
        let terms = below.clone().map(|m| {
            let row_m = &tail[(m - i - 1) * k..(m - i) * k];
            (l[m + i * n], &row_m[columns.clone()])
        });
        subtract_combination_and_scale(&mut row_i[columns.clone()], terms, 1.0 / l[i + i * n]);
    }
    for m in 0..n {
        let (head, tail) = w.split_at_mut(m * k);
        let first = if identity_first { m } else { 0 };
        let row_m = &mut tail[first..k];
        let terms = ancestors
            .of(m)
            .iter()
            .map(|&a| (l[m + a * n], &head[a * k + first..(a + 1) * k]));
        subtract_combination_and_scale(row_m, terms, 1.0 / l[m + m * n]);
    }
}

/// `y ← (y − Σ_t c_t x_t) s` over the terms `(c_t, x_t)` (each `x_t` as long as `y`), four
/// terms per sweep over `y`: each entry of `y` is loaded and stored once per four products, and
/// the scaling is done in the last sweep.
#[inline(always)]
fn subtract_combination_and_scale<'a>(
    y: &mut [f64],
    terms: impl Iterator<Item = (f64, &'a [f64])>,
    scale: f64,
) {
    let mut terms = terms.peekable();
    let n = y.len();
    while let Some(first) = terms.next() {
        let mut group: [(f64, &[f64]); 4] = [first, (0.0, &[]), (0.0, &[]), (0.0, &[])];
        let mut len = 1;
        while len < 4 {
            match terms.next() {
                Some(term) => group[len] = term,
                None => break,
            }
            len += 1;
        }
        let last = terms.peek().is_none();
        match group[..len] {
            [(a, p), (b, q), (c, r), (d, s)] => {
                let (p, q, r, s) = (&p[..n], &q[..n], &r[..n], &s[..n]);
                let sum = |j: usize| (a * p[j] + b * q[j]) + (c * r[j] + d * s[j]);
                if last {
                    for (j, y) in y.iter_mut().enumerate() {
                        *y = (*y - sum(j)) * scale;
                    }
                } else {
                    for (j, y) in y.iter_mut().enumerate() {
                        *y -= sum(j);
                    }
                }
            }
            // Fewer than four terms: the last sweep.
            [(a, p), (b, q), (c, r)] => {
                let (p, q, r) = (&p[..n], &q[..n], &r[..n]);
                for (j, y) in y.iter_mut().enumerate() {
                    *y = (*y - ((a * p[j] + b * q[j]) + c * r[j])) * scale;
                }
            }
            [(a, p), (b, q)] => {
                let (p, q) = (&p[..n], &q[..n]);
                for (j, y) in y.iter_mut().enumerate() {
                    *y = (*y - (a * p[j] + b * q[j])) * scale;
                }
            }
            [(a, p)] => {
                let p = &p[..n];
                for (y, p) in y.iter_mut().zip(p) {
                    *y = (*y - a * p) * scale;
                }
            }
            _ => {}
        }
        if last {
            return;
        }
    }
    // No terms at all.
    y.iter_mut().for_each(|y| *y *= scale);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples;
    use crate::{urdf, ModelOptions};

    /// A tree numbered depth-first has contiguous subtrees; numbered breadth-first it does not.
    #[test]
    fn subtrees_are_ranges_when_numbered_depth_first() {
        //      0
        //     / \
        //    1   3
        //    |   |
        //    2   4
        let depth_first = [None, Some(0), Some(1), Some(0), Some(3)];
        let a = Ancestors::new(&depth_first).unwrap();
        let below: Vec<_> = (0..5).map(|k| a.below(k)).collect();
        assert_eq!(below, [1..5, 2..3, 3..3, 4..5, 5..5]);
        assert_eq!(a.of(4), &[3, 0]);
        let breadth_first = [None, Some(0), Some(0), Some(1), Some(2)];
        assert!(Ancestors::new(&breadth_first).is_none());
    }

    /// On a branched model, `Lᵀ L` rebuilds `H` and the solve inverts it.
    #[test]
    fn factor_rebuilds_h_and_solve_inverts_it() {
        let text = include_str!("../tests/models/tree.urdf");
        for model in [
            urdf::model_from_str(text, &ModelOptions::default()).unwrap(),
            urdf::model_from_str(examples::DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap(),
        ] {
            let n = model.nv;
            let ancestors = Ancestors::new(model.dof_parent.as_ref().unwrap()).unwrap();
            let mut ws = crate::Workspace::new(&model);
            let q = crate::sampling::random_q(&model, &mut crate::sampling::Rng::new(3));
            let h = crate::algorithms::crba(&model, &mut ws, &q)
                .unwrap()
                .clone();
            let mut factor = DMatrix::from_element(n, n, f64::NAN);
            ltl_factor(&model, &ancestors, &h, &mut factor).unwrap();
            // L: the pattern's entries of the lower triangle, zero elsewhere.
            let l = DMatrix::from_fn(n, n, |r, c| {
                if r == c || ancestors.of(r).contains(&c) {
                    factor[(r, c)]
                } else {
                    0.0
                }
            });
            let err = (l.transpose() * &l - &h).amax();
            assert!(
                err < 1e-13 * h.amax(),
                "{}: |LᵀL − H| = {err:e}",
                model.name
            );
            let b = DVector::from_fn(n, |i, _| (i as f64 * 0.7).sin());
            let mut x = b.clone();
            ltl_solve(&ancestors, &factor, &mut x);
            let err = (&h * &x - &b).amax();
            assert!(
                err < 1e-12 * (h.amax() * x.amax()),
                "{}: |H x − b| = {err:e}",
                model.name
            );
            // Three right-hand sides row by row: the storage of Bᵀ in, of Xᵀ out.
            let b3 = DMatrix::from_fn(n, 3, |i, j| ((i * 3 + j) as f64 * 0.7).cos());
            let mut rows = b3.transpose().as_slice().to_vec();
            ltl_solve_rows(&ancestors, &factor, &mut rows, 3, false);
            let x3 = DMatrix::from_column_slice(3, n, &rows).transpose();
            let err = (&h * &x3 - &b3).amax();
            assert!(
                err < 1e-12 * (h.amax() * x3.amax()),
                "{}: |H X − B| = {err:e} (rows)",
                model.name
            );
            // The identity first, then B: H⁻¹ and H⁻¹ B.
            let mut b4 = DMatrix::identity(n, n).insert_columns(n, 3, 0.0);
            b4.columns_mut(n, 3).copy_from(&b3);
            let mut rows = b4.transpose().as_slice().to_vec();
            ltl_solve_rows(&ancestors, &factor, &mut rows, n + 3, true);
            let mut x4 = DMatrix::from_column_slice(n + 3, n, &rows).transpose();
            for r in 0..n {
                for c in 0..r {
                    x4[(r, c)] = x4[(c, r)]; // H⁻¹ from its upper triangle
                }
            }
            let err = (&h * &x4 - &b4).amax();
            assert!(
                err < 1e-12 * (h.amax() * x4.amax()),
                "{}: |H X − [1 | B]| = {err:e} (rows, identity first)",
                model.name
            );
        }
    }
}
