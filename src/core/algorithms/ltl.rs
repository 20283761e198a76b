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
//!
//! The diagonal of the stored factor holds `1 / L_kk` instead of `L_kk`: the factor needs
//! the reciprocal anyway, and the solves then multiply by it where each would otherwise wait on
//! a division.

use super::pivot_is_sound;
use crate::error::DynamicsError;
use crate::model::Model;
use crate::mul_add::MulAdd;
use crate::plan::Ancestors;
use nalgebra::{DMatrix, DVector};

/// Factorises `h` (full symmetric) into `factor`: afterwards `factor` holds `L` strictly below
/// its diagonal along the tree pattern (entry `(k, j)` is `L_kj`; column `j` of `L` is
/// contiguous in memory) and `1 / L_kk` on it, with `H = Lᵀ L`. Other entries of `factor` are
/// left as they were.
///
/// Row `k` takes its descendants' entries of column `k`, `c = L[D(k), k]` (`s = |D(k)|` of
/// them), once: `L_kk = √(H_kk − c·c)`, then `L_kj = (H_kj − c·L[D(k), j]) / L_kk` for each
/// ancestor `j`, multiplied by `1 / L_kk` taken once. The descendants of a coordinate near the
/// leaves are few (none, one or two on a leg), so those lengths have their own loops with `c`
/// held in registers ([`short_row`]); a longer `c` is read in place ([`long_row`]).
///
/// Fails, naming the coordinate, when a pivot is not positive, or is so small against the
/// original diagonal entry that every digit was lost (`H` singular or indefinite).
#[inline(always)]
pub(crate) fn ltl_factor(
    model: &Model,
    ancestors: &Ancestors,
    h: &DMatrix<f64>,
    factor: &mut DMatrix<f64>,
) -> Result<(), DynamicsError> {
    factor_rows(model, ancestors, h.as_slice(), factor.as_mut_slice())
}

/// [`ltl_factor`] on the storage (slices, which the compiler knows not to overlap).
#[inline(always)]
fn factor_rows(
    model: &Model,
    ancestors: &Ancestors,
    h: &[f64],
    l: &mut [f64],
) -> Result<(), DynamicsError> {
    let n = ancestors.len();
    for k in (0..n).rev() {
        let row = Row {
            k,
            n,
            ancestors: ancestors.of(k),
        };
        let done = match ancestors.below(k).len() {
            0 => short_row::<0>(l, h, row),
            1 => short_row::<1>(l, h, row),
            2 => short_row::<2>(l, h, row),
            3 => short_row::<3>(l, h, row),
            s => long_row(l, h, row, s),
        };
        if let Err(pivot) = done {
            return Err(DynamicsError::SingularMassMatrix {
                coordinate: model.v_name(k),
                pivot,
            });
        }
    }
    Ok(())
}

/// Which row of `L` to compute: row `k` of `n`, with its ancestors. Column-major storage: entry
/// `(r, c)` of the `n × n` matrices is at `r + c n`, so `L_kj` and `H_kj` are at `k + j n`
/// and `L[D(k), j]` follows `L_kj`.
#[derive(Clone, Copy)]
struct Row<'a> {
    k: usize,
    n: usize,
    ancestors: &'a [usize],
}

/// `1 / L_kk = 1 / √pivot` into the diagonal entry `inverse`, and returned; the pivot back
/// when it is not sound ([`pivot_is_sound`] against `H_kk`).
#[inline(always)]
fn set_pivot(inverse: &mut f64, pivot: f64, h_kk: f64) -> Result<f64, f64> {
    if !pivot_is_sound(pivot, h_kk) {
        return Err(pivot);
    }
    *inverse = 1.0 / pivot.sqrt();
    Ok(*inverse)
}

/// Row `k` of `L` for `S < 4` descendants, `c` copied out of column `k` first (the terms
/// subtracted from the last to the first, as in [`subtract_dot`]):
/// `L_kk = √(H_kk − Σ_t c_t²)`, `L_kj = (H_kj − Σ_t c_t L_{k+1+t, j}) / L_kk`.
#[inline(always)]
fn short_row<const S: usize>(l: &mut [f64], h: &[f64], row: Row<'_>) -> Result<(), f64> {
    let Row { k, n, ancestors } = row;
    let diagonal = k + k * n;
    let c: [f64; S] = l[diagonal + 1..][..S].try_into().expect("S entries");
    let h_kk = h[diagonal];
    // The nearest descendant's entry (t = 0, computed just before) last, as in `subtract_dot`.
    let mut pivot = h_kk;
    for c in c.into_iter().rev() {
        pivot -= c * c;
    }
    let scale = set_pivot(&mut l[diagonal], pivot, h_kk)?;
    for &j in ancestors {
        let at = k + j * n;
        let column = &mut l[at..=at + S];
        let mut sum = h[at];
        for t in (0..S).rev() {
            sum -= c[t] * column[1 + t];
        }
        column[0] = sum * scale;
    }
    Ok(())
}

/// Row `k` of `L` for `s ≥ 4` descendants, `c` read in place from column `k` (after the
/// columns of the ancestors, where the row's entries go).
#[inline(always)]
fn long_row(l: &mut [f64], h: &[f64], row: Row<'_>, s: usize) -> Result<(), f64> {
    let Row { k, n, ancestors } = row;
    let (before, from_k) = l.split_at_mut(k * n);
    let (inverse, c) = from_k[k..=k + s].split_first_mut().expect("s + 1 entries");
    let h_kk = h[k + k * n];
    let scale = set_pivot(inverse, subtract_dot(h_kk, c, c), h_kk)?;
    for &j in ancestors {
        let at = k + j * n;
        let (l_kj, below) = before[at..=at + s]
            .split_first_mut()
            .expect("s + 1 entries");
        *l_kj = subtract_dot(h[at], c, below) * scale;
    }
    Ok(())
}

/// `b − Σ x_m y_m` over the entries of `x` (`y` exactly as long): `s` multiplications and `s`
/// subtractions for `s` entries. The first term goes last: in the solves and the factor it
/// holds the value computed just before (the nearest descendant's), so the other terms are
/// subtracted while it is still on its way. Up to four entries are subtracted one by one; from
/// five on the other terms are summed in four interleaved partial sums (independent additions
/// that pair up in SIMD registers, where one running sum would wait on each addition), each
/// starting from its first product, and the sum subtracted.
#[inline(always)]
fn subtract_dot(b: f64, x: &[f64], y: &[f64]) -> f64 {
    match (x, y) {
        ([], _) => b,
        ([x0], [y0]) => b - x0 * y0,
        ([x0, x1], [y0, y1]) => b - x1 * y1 - x0 * y0,
        ([x0, x1, x2], [y0, y1, y2]) => b - x2 * y2 - x1 * y1 - x0 * y0,
        ([x0, x1, x2, x3], [y0, y1, y2, y3]) => b - x3 * y3 - x2 * y2 - x1 * y1 - x0 * y0,
        ([x0, x @ ..], [y0, y @ ..]) => b - dot(x, y) - x0 * y0,
        _ => unreachable!("x and y have the same length"),
    }
}

/// `Σ x_m y_m` for at least four entries (`y` exactly as long as `x`), in four interleaved
/// partial sums: `s` multiplications, `s − 1` additions.
#[inline(always)]
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let ((x_first, x), (y_first, y)) = (x.split_at(4), y.split_at(4));
    let mut acc: [f64; 4] = std::array::from_fn(|t| x_first[t] * y_first[t]);
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

/// `y ← y − a x` over the entries of `y` (`x` exactly as long): `s` multiplications and `s`
/// subtractions. Up to three entries one by one; from four on, four at a time.
#[inline(always)]
fn subtract_scaled(y: &mut [f64], a: f64, x: &[f64]) {
    match (y, x) {
        ([], _) => {}
        ([y0], [x0]) => *y0 -= a * x0,
        ([y0, y1], [x0, x1]) => {
            *y0 -= a * x0;
            *y1 -= a * x1;
        }
        ([y0, y1, y2], [x0, x1, x2]) => {
            *y0 -= a * x0;
            *y1 -= a * x1;
            *y2 -= a * x2;
        }
        (y, x) => {
            let (mut y4, mut x4) = (y.chunks_exact_mut(4), x.chunks_exact(4));
            for (p, q) in (&mut y4).zip(&mut x4) {
                for t in 0..4 {
                    p[t] -= a * q[t];
                }
            }
            for (p, q) in y4.into_remainder().iter_mut().zip(x4.remainder()) {
                *p -= a * q;
            }
        }
    }
}

/// Solves `Lᵀ L x = b` in place (`x` holds `b` on entry), `factor` as [`ltl_factor`] left it:
///
/// ```text
/// Lᵀ y = b, leaves inward:  y_i = (b_i − L[D(i), i]·y[D(i)]) / L_ii
/// L x = y, root outward:    x_i = y_i / L_ii, then y[D(i)] −= L[D(i), i] x_i
/// ```
///
/// each step on the contiguous segment of column `i` below its diagonal (none for a leaf), the
/// division a multiplication by the stored `1 / L_ii`.
#[inline(always)]
pub(crate) fn ltl_solve(ancestors: &Ancestors, factor: &DMatrix<f64>, x: &mut DVector<f64>) {
    solve(ancestors, factor.as_slice(), x.as_mut_slice());
}

/// [`ltl_solve`] on the storage: slices passed in, which the compiler then knows not to
/// overlap (the matrices' buffers, reached through their structs, could as far as it knows).
#[inline(always)]
fn solve(ancestors: &Ancestors, l: &[f64], x: &mut [f64]) {
    let n = ancestors.len();
    // Rows i..e(i) of column i of L, and of x.
    let rows = |i: usize| i..ancestors.below(i).end;
    for i in (0..n).rev() {
        let (inverse, l_below) = l[i * n..][rows(i)].split_first().expect("i < e(i)");
        let (x_i, x_below) = x[rows(i)].split_first_mut().expect("i < e(i)");
        *x_i = subtract_dot(*x_i, l_below, x_below) * inverse;
    }
    for i in 0..n {
        let (inverse, l_below) = l[i * n..][rows(i)].split_first().expect("i < e(i)");
        let (x_i, x_below) = x[rows(i)].split_first_mut().expect("i < e(i)");
        *x_i *= inverse;
        subtract_scaled(x_below, *x_i, l_below);
    }
}

/// `Y = L⁻ᵀ` into `y` (`n` rows of `n`, row `i` at `y[i n ..]`, the column-major storage of
/// `L⁻¹`), solving `Lᵀ Y = 1`. Row `i` of `Y` is zero outside the columns `i .. e(i)` (its
/// entry `Y_ik` is non-zero only for `k` in `i`'s subtree), so only those entries are written:
/// every other entry of `y` must be zero.
///
/// Below [`BY_COLUMNS_BELOW`] coordinates a column at a time ([`inverse_transpose_by_columns`],
/// `Σ_k d_k² / 2` multiply-adds for coordinates at depths `d_k`), else a row at a time
/// ([`inverse_transpose_by_rows`], whole-row sweeps that vectorise but also sweep the zeros of
/// each row they gather from).
#[inline(always)]
pub(crate) fn ltl_inverse_transpose(
    ancestors: &Ancestors,
    factor: &DMatrix<f64>,
    y: &mut [f64],
    mul_add: MulAdd,
) {
    if ancestors.len() < BY_COLUMNS_BELOW {
        inverse_transpose_by_columns(ancestors, factor, y, mul_add)
    } else {
        inverse_transpose_by_rows(ancestors, factor, y)
    }
}

/// The fewest coordinates for which [`ltl_inverse_transpose`] goes by rows: by columns measured
/// faster on UR5, Baxter, Solo12, ANYmal and TALOS (6 to 50 coordinates); the rows' sweeps
/// vectorise, so on longer models, not measured, they are kept.
const BY_COLUMNS_BELOW: usize = 64;

/// [`ltl_inverse_transpose`] column by column: column `k` of `Y` solves `Lᵀ y = e_k` from `k`
/// up its path to the root (`y` is zero elsewhere), each ancestor `c` of `k` (parent first)
/// from the entries already made below it on the path, `P(c) = {k} ∪ (ancestors of k below c)`:
///
/// ```text
/// Y_kk = 1 / L_kk,   Y_ck = −(Σ_{m ∈ P(c)} L_mc Y_mk) / L_cc
/// ```
///
/// (`L_mc` non-zero only for `m` below `c`, `Y_mk` only for `m` on `k`'s path). Each entry
/// waits on the one made just before it, a chain of dependent sums
/// ([`ChainColumns::up_the_path`] keeps each link short). A coordinate and the next, when it is
/// the next's parent, go together ([`ChainColumns`]): their two columns walk the first's path
/// side by side, two independent chains sharing the loads of `L`.
#[inline(always)]
fn inverse_transpose_by_columns(
    ancestors: &Ancestors,
    factor: &DMatrix<f64>,
    y: &mut [f64],
    mul_add: MulAdd,
) {
    let n = ancestors.len();
    debug_assert_eq!(y.len(), n * n, "n rows of n");
    let mut k = 0;
    while k < n {
        let columns = ChainColumns {
            n,
            l: factor.as_slice(),
            first: k,
            mul_add,
        };
        let path = ancestors.of(k);
        if k + 1 < n && ancestors.of(k + 1).first() == Some(&k) {
            columns.solve::<2>(path, y);
            k += 2;
        } else {
            columns.solve::<1>(path, y);
            k += 1;
        }
    }
}

/// Columns of `Y` for a coordinate `first` and the coordinates that follow it in a chain (each
/// the parent of the next), `l` their factor (`n × n`, column-major, the diagonal holding
/// `1 / L_kk`).
struct ChainColumns<'a> {
    n: usize,
    l: &'a [f64],
    first: usize,
    mul_add: MulAdd,
}

impl ChainColumns<'_> {
    /// Columns `k .. k + W` of `Y` (`k = first`), `path` the ancestors of `k`, parent first.
    /// Their entries in the chain's own rows come first, up the chain:
    ///
    /// ```text
    /// Y_{k+g, k+g} = 1 / L_{k+g, k+g}
    /// Y_{k+i, k+g} = −(Σ_{i < m ≤ g} L_{k+m, k+i} Y_{k+m, k+g}) / L_{k+i, k+i}   (i < g)
    /// ```
    ///
    /// then the rows of `path` ([`ChainColumns::up_the_path`]).
    #[inline(always)]
    fn solve<const W: usize>(&self, path: &[usize], y: &mut [f64]) {
        let (n, l, k) = (self.n, self.l, self.first);
        // own[g][i] = Y_{k+i, k+g}
        let mut own = [[0.0; W]; W];
        for (g, column_g) in own.iter_mut().enumerate() {
            column_g[g] = l[(k + g) * (n + 1)];
            for i in (0..g).rev() {
                let column = &l[(k + i) * n..(k + i + 1) * n];
                let mut sum = 0.0;
                for m in i + 1..=g {
                    sum = self.mul_add.mul_add(column[k + m], column_g[m], sum);
                }
                column_g[i] = -sum * column[k + i];
            }
            for (i, y_ig) in column_g[..=g].iter().enumerate() {
                y[(k + i) * n + k + g] = *y_ig;
            }
        }
        self.up_the_path(path, y, &own);
    }

    /// Rows `c` of `path` of the columns `k .. k + W`, parent first: entry `(c, k + g)` is
    ///
    /// ```text
    /// −(Σ_{i ≤ g} L_{k+i, c} Y_{k+i, k+g} + Σ_{m ∈ path below c} L_mc Y_{m, k+g}) / L_cc
    /// ```
    ///
    /// (`own[g][i] = Y_{k+i, k+g}`). Each entry waits on the one made just before it. Each sum
    /// runs in two halves (the path's even and odd places), so that a deep path's additions do
    /// not all wait on one another, and its last term is the entry made just before, kept in a
    /// register: a link of the chain is one multiply-add, an addition and a multiplication. The
    /// `W` columns' chains are independent and share each load of `L`.
    #[inline(always)]
    fn up_the_path<const W: usize>(&self, path: &[usize], y: &mut [f64], own: &[[f64; W]; W]) {
        let (n, l, k, mul_add) = (self.n, self.l, self.first, self.mul_add);
        let mut last = [0.0; W];
        for (j, &c) in path.iter().enumerate() {
            let column_c = &l[c * n..(c + 1) * n];
            let (mut even, mut odd) = ([0.0; W], [0.0; W]);
            for g in 0..W {
                for (i, y_ig) in own[g][..=g].iter().enumerate() {
                    even[g] = mul_add.mul_add(column_c[k + i], *y_ig, even[g]);
                }
            }
            if let Some((&just_before, earlier)) = path[..j].split_last() {
                let row = |m: usize| -> &[f64; W] { y[m * n + k..][..W].try_into().expect("W") };
                let pairs = earlier.chunks_exact(2);
                if let [m] = pairs.remainder() {
                    let y_m = row(*m);
                    for g in 0..W {
                        odd[g] = mul_add.mul_add(column_c[*m], y_m[g], odd[g]);
                    }
                }
                for pair in pairs {
                    let (y_0, y_1) = (row(pair[0]), row(pair[1]));
                    for g in 0..W {
                        even[g] = mul_add.mul_add(column_c[pair[0]], y_0[g], even[g]);
                        odd[g] = mul_add.mul_add(column_c[pair[1]], y_1[g], odd[g]);
                    }
                }
                for g in 0..W {
                    even[g] = mul_add.mul_add(column_c[just_before], last[g], even[g]);
                }
            }
            for g in 0..W {
                last[g] = -(even[g] + odd[g]) * column_c[c];
            }
            y[c * n + k..][..W].copy_from_slice(&last);
        }
    }
}

/// [`ltl_inverse_transpose`] row by row, from the leaves inward:
///
/// ```text
/// Y_i = (e_iᵀ − Σ_{m ∈ D(i)} L_mi Y_m) / L_ii
/// ```
///
/// Row `i` gathers only rows of `D(i)`, each zero outside its own range within `i`'s, so only the
/// columns `i .. e(i)` are written, from `e_iᵀ` (the other entries, zero, are read as a term's
/// zeros). Every step is a whole-row update, contiguous and independent entry by entry, which
/// vectorises where the columns' sums over a path do not. Each row gathers its sum four rows at a
/// time and multiplies by the stored `1 / L_ii` in the last sweep ([`subtract_combinations`]),
/// reading and writing its own entries once per four terms; a sweep of four rows `m` of `D(i)` runs
/// up to their largest `e(m)`. A coordinate and its parent go together ([`ChainPair`]) when the
/// coordinate is the parent's only child (`c = p + 1`, `D(p) = {c} ∪ D(c)`), so each row of their
/// shared sum is loaded once for both, from column `p` on (`c`'s column `p` stays zero).
#[inline(always)]
fn inverse_transpose_by_rows(ancestors: &Ancestors, factor: &DMatrix<f64>, y: &mut [f64]) {
    let n = ancestors.len();
    let l = factor.as_slice();
    let entry = |r: usize, c: usize| l[r + c * n];
    let parent = |c: usize| ancestors.of(c).first().copied();
    let to = |m: usize| ancestors.below(m).end;
    debug_assert_eq!(y.len(), n * n, "n rows of n");
    for i in 0..n {
        let row = &mut y[i * n..][i..to(i)];
        row.fill(0.0);
        row[0] = 1.0;
    }
    // Row `c`, or `c` and then its parent `p = c − 1`. Rows from `end` on are done.
    let mut end = n;
    while end > 0 {
        let c = end - 1;
        let below = ancestors.below(c);
        let (head, tail) = y.split_at_mut(end * n);
        let tail: &[f64] = tail;
        // Row m of D(c) is tail's row m − c − 1, non-zero before `to(m)` only.
        let rows_below = |first: usize| {
            below.clone().map(move |m| {
                let row_m = &tail[(m - c - 1) * n..(m - c) * n];
                (m, &row_m[first..], to(m) - first)
            })
        };
        match parent(c) {
            Some(p) if p + 1 == c && ancestors.below(p).end == below.end => {
                let (row_p, row_c) = head[p * n..].split_at_mut(n);
                let columns = p..to(c);
                let mut pair = ChainPair {
                    y: [&mut row_c[columns.clone()], &mut row_p[columns.clone()]],
                    link: entry(c, p),
                    scale: [entry(c, c), entry(p, p)],
                };
                let terms = rows_below(columns.start)
                    .map(|(m, x, len)| ([entry(m, c), entry(m, p)], x, len));
                subtract_combinations(&mut pair, terms);
                end -= 2;
            }
            _ => {
                let mut row = OneRow {
                    y: &mut head[c * n..][c..to(c)],
                    scale: entry(c, c),
                };
                let terms = rows_below(c).map(|(m, x, len)| (entry(m, c), x, len));
                subtract_combinations(&mut row, terms);
                end -= 1;
            }
        }
    }
}

/// `Σ_t c_t x_t[j]` over a group of `T` terms.
#[inline(always)]
fn combination<const T: usize>(c: &[f64; T], x: &[&[f64]; T], j: usize) -> f64 {
    let mut sum = c[0] * x[0][j];
    for t in 1..T {
        sum += c[t] * x[t][j];
    }
    sum
}

/// Rows that one sweep over their columns updates together, each from the same terms `x_t`
/// with its own coefficient.
trait Rows {
    /// The terms' coefficients, one per row.
    type Coefficients: Copy;
    const NONE: Self::Coefficients;
    /// The rows' length.
    fn len(&self) -> usize;
    /// `y_r ← y_r − Σ_t c_tr x_t` over a group of `T` terms on the rows' first `len` entries
    /// (each `x_t` at least that long), and with `last` the rows' ending step after it.
    fn sweep<const T: usize>(
        &mut self,
        c: &[Self::Coefficients; T],
        x: [&[f64]; T],
        len: usize,
        last: bool,
    );
    /// The ending step alone (no terms).
    fn end(&mut self);
}

/// One row: `y ← (y − Σ_t c_t x_t) s`.
struct OneRow<'a> {
    y: &'a mut [f64],
    scale: f64,
}

impl Rows for OneRow<'_> {
    type Coefficients = f64;
    const NONE: f64 = 0.0;
    #[inline(always)]
    fn len(&self) -> usize {
        self.y.len()
    }
    #[inline(always)]
    fn sweep<const T: usize>(&mut self, c: &[f64; T], x: [&[f64]; T], len: usize, last: bool) {
        let (y, x) = (&mut self.y[..len], x.map(|x| &x[..len]));
        if last {
            for (j, y) in y.iter_mut().enumerate() {
                *y = (*y - combination(c, &x, j)) * self.scale;
            }
        } else {
            for (j, y) in y.iter_mut().enumerate() {
                *y -= combination(c, &x, j);
            }
        }
    }
    #[inline(always)]
    fn end(&mut self) {
        self.y.iter_mut().for_each(|y| *y *= self.scale);
    }
}

/// Two rows of a chain over the same columns, the second of which also takes the first's
/// result as a term: `y_0 ← (y_0 − Σ_t c_t0 x_t) s_0`, then
/// `y_1 ← (y_1 − Σ_t c_t1 x_t − link y_0) s_1` (entry by entry, in one sweep).
struct ChainPair<'a> {
    y: [&'a mut [f64]; 2],
    link: f64,
    scale: [f64; 2],
}

impl Rows for ChainPair<'_> {
    type Coefficients = [f64; 2];
    const NONE: [f64; 2] = [0.0; 2];
    #[inline(always)]
    fn len(&self) -> usize {
        self.y[0].len()
    }
    #[inline(always)]
    fn sweep<const T: usize>(&mut self, c: &[[f64; 2]; T], x: [&[f64]; T], len: usize, last: bool) {
        let [y0, y1] = &mut self.y;
        let (y0, y1, x) = (&mut y0[..len], &mut y1[..len], x.map(|x| &x[..len]));
        let (c0, c1) = (c.map(|c| c[0]), c.map(|c| c[1]));
        let ([s0, s1], link) = (self.scale, self.link);
        if last {
            for (j, (y0, y1)) in y0.iter_mut().zip(y1.iter_mut()).enumerate() {
                let first = (*y0 - combination(&c0, &x, j)) * s0;
                *y0 = first;
                *y1 = (*y1 - combination(&c1, &x, j) - link * first) * s1;
            }
        } else {
            for (j, (y0, y1)) in y0.iter_mut().zip(y1.iter_mut()).enumerate() {
                *y0 -= combination(&c0, &x, j);
                *y1 -= combination(&c1, &x, j);
            }
        }
    }
    #[inline(always)]
    fn end(&mut self) {
        let [y0, y1] = &mut self.y;
        let ([s0, s1], link) = (self.scale, self.link);
        for (y0, y1) in y0.iter_mut().zip(y1.iter_mut()) {
            *y0 *= s0;
            *y1 = (*y1 - link * *y0) * s1;
        }
    }
}

/// `rows ← rows − Σ_t c_t x_t` over the terms `(c_t, x_t, len_t)` (`x_t` as long as the rows,
/// zero from `len_t` on), four terms per sweep over the rows: each entry of a row is loaded and
/// stored once per four terms, each entry of a term once per sweep for all the rows. A sweep
/// covers the columns before its terms' longest `len_t`, the last one the whole rows, with the
/// rows' ending step (the scaling).
#[inline(always)]
fn subtract_combinations<'a, R: Rows>(
    rows: &mut R,
    terms: impl Iterator<Item = (R::Coefficients, &'a [f64], usize)>,
) {
    let mut terms = terms.peekable();
    let (mut c, mut x) = ([R::NONE; 4], [&[][..]; 4]);
    loop {
        let (mut count, mut len) = (0, 0);
        while count < 4 {
            match terms.next() {
                Some((c_t, x_t, len_t)) => {
                    (c[count], x[count]) = (c_t, x_t);
                    len = len.max(len_t);
                }
                None => break,
            }
            count += 1;
        }
        let last = terms.peek().is_none();
        let len = if last { rows.len() } else { len };
        match count {
            4 => rows.sweep(&c, x, len, last),
            // Fewer than four terms: the last sweep.
            3 => rows.sweep(&[c[0], c[1], c[2]], [x[0], x[1], x[2]], len, true),
            2 => rows.sweep(&[c[0], c[1]], [x[0], x[1]], len, true),
            1 => rows.sweep(&[c[0]], [x[0]], len, true),
            _ => rows.end(), // no terms at all
        }
        if last {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples;
    use crate::test_models::{floating, TREE_URDF};
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

    /// On a branched model (planar base) and chains (fixed and floating bases), `Lᵀ L` rebuilds
    /// `H` and the solve inverts it. Between them the models have coordinates with 0, 1, 2, 3
    /// and more descendants, each length of column segment the factor and the solves treat
    /// apart ([`short_row`], [`subtract_dot`]), with and without ancestors.
    #[test]
    fn factor_rebuilds_h_and_solve_inverts_it() {
        let mut lengths = std::collections::BTreeSet::new();
        let models = [
            urdf::model_from_str(TREE_URDF, &ModelOptions::default()).unwrap(),
            urdf::model_from_str(examples::DEFAULT_ARM_URDF, &ModelOptions::default()).unwrap(),
            urdf::model_from_str(examples::DEFAULT_ARM_URDF, &floating()).unwrap(),
        ];
        // Short chains: a root with one, two, three descendants.
        let chains = (2..=4).map(crate::plan::flops::tests::chain);
        for model in models.into_iter().chain(chains) {
            let n = model.nv;
            let ancestors = Ancestors::new(model.dof_parent.as_ref().unwrap()).unwrap();
            for k in 0..n {
                let with_ancestors = !ancestors.of(k).is_empty();
                lengths.insert((ancestors.below(k).len().min(4), with_ancestors));
            }
            let mut ws = crate::Workspace::new(&model);
            let q = crate::sampling::random_q(&model, &mut crate::sampling::Rng::new(3));
            let h = crate::algorithms::crba(&model, &mut ws, &q)
                .unwrap()
                .clone();
            let mut factor = DMatrix::from_element(n, n, f64::NAN);
            ltl_factor(&model, &ancestors, &h, &mut factor).unwrap();
            // L: the pattern's entries below the diagonal, the reciprocals of the diagonal's,
            // zero elsewhere.
            let l = DMatrix::from_fn(n, n, |r, c| {
                if r == c {
                    1.0 / factor[(r, c)]
                } else if ancestors.of(r).contains(&c) {
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
            // Y = L⁻ᵀ from zeros: Lᵀ Y = 1, by rows and by columns (multiply-adds separate
            // and fused).
            let by_columns = [None, Some(MulAdd::SEPARATE), Some(MulAdd::FUSED)];
            for by_columns in by_columns {
                let mut rows = vec![0.0; n * n];
                if let Some(mul_add) = by_columns {
                    inverse_transpose_by_columns(&ancestors, &factor, &mut rows, mul_add);
                } else {
                    inverse_transpose_by_rows(&ancestors, &factor, &mut rows);
                }
                let y = DMatrix::from_column_slice(n, n, &rows).transpose();
                // (`amax` passes over NaN: the finiteness is checked on its own.)
                let err = (l.transpose() * &y - DMatrix::identity(n, n)).amax();
                assert!(
                    y.iter().all(|x| x.is_finite()) && err < 1e-12 * (l.amax() * y.amax()),
                    "{} (by columns {by_columns:?}): |Lᵀ Y − 1| = {err:e}",
                    model.name
                );
            }
        }
        let every = (0..=4).flat_map(|s| [(s, false), (s, true)]);
        let missing: Vec<_> = every.filter(|l| !lengths.contains(l)).collect();
        // A root with no descendant is a model of one coordinate: not among these.
        assert_eq!(
            missing,
            [(0, false)],
            "(descendants, has ancestors) not covered"
        );
    }
}
