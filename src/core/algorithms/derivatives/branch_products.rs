//! The products of [`aba_derivatives`](super::aba_derivatives) on a tree, column by column,
//! each column the sum of a few columns of a matrix over a branch of the tree.
//!
//! `X = H⁻¹ B` from the full `H⁻¹`: column `j` of `B = −∂τ/∂q` (or `−∂τ/∂q̇`) is zero outside
//! `j`'s branch (turning or moving coordinate `j` changes no force on a coordinate that is
//! neither its ancestor nor below it), so
//!
//! ```text
//! X[:, j] = Σ_{i ∈ branch(j)} H⁻¹[:, i] B_ij,   branch(j) = ancestors(j) ∪ {j} ∪ D(j)
//! ```
//!
//! `|branch(j)|` columns of `H⁻¹` a column of `X` instead of `nv`: for a floating humanoid
//! (TALOS, `nv` = 50) 1,084 of the 2,500 pairs `(i, j)`. `H⁻¹` itself is `Yᵀ Y` from the rows of
//! `Y = L⁻ᵀ`, its column `s` the sum of the rows of `Y` over `s` and its ancestors.
//!
//! A column is summed in blocks of its rows held in registers, stored once when its branch is
//! done: the loop has no stores, and the two products share each block of `H⁻¹` they read.
//! Each block is added to a finiteness [`Probe`] as it is stored, so that no pass reads the
//! results again to check them.

use crate::mul_add::MulAdd;
use crate::plan::Ancestors;

/// `H⁻¹ = L⁻¹ L⁻ᵀ = Yᵀ Y` into `minv` (`n × n`, column-major, full) from the rows of
/// `Y = L⁻ᵀ` in `y` (row `c` at `y[c n ..]`, zero outside the columns `c .. e(c)`: `Lᵀ Y = 1`
/// gathers into row `c` only the rows of `D(c)`). Entry `Y_cs` is non-zero only for `c` an
/// ancestor of `s` or `s` itself, so column `s` is
///
/// ```text
/// H⁻¹[:, s] = Σ_{c ∈ ancestors(s) ∪ {s}} (row c of Y)ᵀ Y_cs
/// ```
///
/// A coordinate and the next, when it is the next's parent (`s + 1` with parent `s`), go
/// together: the next's ancestors are `s` and `s`'s, so the two columns are sums over the same
/// rows of `Y` (with row `s + 1` for both, `Y_{s+1,s}` being zero), each row read once for both.
/// With `WIDE` the blocks are those of the AVX-512 copy ([`Column::fill`]). Every value stored
/// is added to `probe`.
#[inline(always)]
pub(super) fn inverse_from_rows<const WIDE: bool>(
    ancestors: &Ancestors,
    y: &[f64],
    minv: &mut [f64],
    probe: &mut Probe,
    mul_add: MulAdd,
) {
    let n = ancestors.len();
    let mut s = 0;
    while s < n {
        let pair = s + 1 < n && ancestors.of(s + 1).first() == Some(&s);
        let width = if pair { 2 } else { 1 };
        let columns = &mut minv[s * n..(s + width) * n];
        if pair {
            let (column, next) = columns.split_at_mut(n);
            Column::<2>::of_inverse(ancestors, y, s, mul_add).fill::<WIDE>([column, next], probe);
        } else {
            Column::<1>::of_inverse(ancestors, y, s, mul_add).fill::<WIDE>([columns], probe);
        }
        s += width;
    }
}

/// `X_q = H⁻¹ B_q` into `x_q` and `X_v = H⁻¹ B_v` into `x_v` (`n × n`, column-major), `minv`
/// the full `H⁻¹` (column-major), `b` holding `(B_q)_ij` at `2 (j n + i)` and `(B_v)_ij` after
/// it for every `i` in `branch(j)` (other entries are not read). Columns `j < q_from` of
/// `X_q` and `j < v_from` of `X_v` are the caller's to write (a free-floating root's closed
/// form, `v_from ≤ q_from`): they are not made, nor their entries of `B` read. With `WIDE`
/// the blocks are those of the AVX-512 copy ([`Column::fill`]). Every value stored is added to
/// `probe`.
#[inline(always)]
pub(super) fn branch_products<const WIDE: bool>(
    ancestors: &Ancestors,
    minv: &[f64],
    b: &[f64],
    (x_q, x_v): (&mut [f64], &mut [f64]),
    (v_from, q_from): (usize, usize),
    probe: &mut Probe,
    mul_add: MulAdd,
) {
    let n = ancestors.len();
    let columns = x_q.chunks_exact_mut(n).zip(x_v.chunks_exact_mut(n));
    for (j, (x_q, x_v)) in columns.enumerate().skip(v_from) {
        let (ancestors, own_and_below) = (ancestors.of(j), j..ancestors.below(j).end);
        let b_j = &b[2 * j * n..2 * (j + 1) * n];
        if j < q_from {
            let sum = Column::<1> {
                n,
                columns: minv,
                coefficients: &b_j[1..],
                stride: 2,
                ancestors,
                own_and_below,
                mul_add,
            };
            sum.fill::<WIDE>([x_v], probe);
        } else {
            let sum = Column::<2> {
                n,
                columns: minv,
                coefficients: b_j,
                stride: 2,
                ancestors,
                own_and_below,
                mul_add,
            };
            sum.fill::<WIDE>([x_q, x_v], probe);
        }
    }
}

/// The finiteness probe of the values the products store: `Σ x · 0` in eight lanes, each
/// block of a column added just after it is stored (a read the store forwards), so that no
/// pass over the results reads them back from memory. `x · 0` is zero for a finite `x` and
/// NaN for an infinite or NaN one, so the sum stays zero while every value is finite (as
/// `validate::all_finite` sums it over a slice). With fused multiply-adds each `x · 0 + lane`
/// is one instruction.
pub(super) struct Probe {
    lanes: [f64; 8],
    mul_add: MulAdd,
}

impl Probe {
    /// A probe that has seen no value.
    pub(super) fn new(mul_add: MulAdd) -> Self {
        Probe {
            lanes: [0.0; 8],
            mul_add,
        }
    }

    /// Adds `x · 0` for each of `values`: summed in lanes of their own first, so that the
    /// lanes carried from block to block wait on one addition a block.
    #[inline(always)]
    fn add<const W: usize>(&mut self, values: &[f64; W]) {
        let mut block = [0.0; 8];
        let chunks = values.chunks_exact(8);
        for (b, x) in block.iter_mut().zip(chunks.remainder()) {
            *b = self.mul_add.mul_add(*x, 0.0, *b);
        }
        for chunk in chunks {
            for (b, x) in block.iter_mut().zip(chunk) {
                *b = self.mul_add.mul_add(*x, 0.0, *b);
            }
        }
        for (lane, b) in self.lanes.iter_mut().zip(block) {
            *lane += b;
        }
    }

    /// Whether every value added was finite.
    pub(super) fn all_finite(&self) -> bool {
        self.lanes.iter().sum::<f64>() == 0.0
    }
}

/// One column of `K` products `M C_k`, each the sum of the columns `M[:, i]` (`n` entries from
/// `columns[i n]`) scaled by `(C_k)_i` (at `coefficients[i stride + k]`) over a branch: the
/// ancestors of the column's coordinate, then the range `own_and_below`.
struct Column<'a, const K: usize> {
    n: usize,
    columns: &'a [f64],
    coefficients: &'a [f64],
    stride: usize,
    ancestors: &'a [usize],
    own_and_below: std::ops::Range<usize>,
    mul_add: MulAdd,
}

impl<'a, const K: usize> Column<'a, K> {
    /// Columns `s .. s + K` of `H⁻¹ = Yᵀ Y` ([`inverse_from_rows`]), `y` the rows of `Y`: the
    /// rows of `Y` over `s`'s ancestors and `s .. s + K`, scaled by their entries in columns
    /// `s .. s + K`.
    #[inline(always)]
    fn of_inverse(ancestors: &'a Ancestors, y: &'a [f64], s: usize, mul_add: MulAdd) -> Self {
        Column {
            n: ancestors.len(),
            columns: y,
            coefficients: &y[s..],
            stride: ancestors.len(),
            ancestors: ancestors.of(s),
            own_and_below: s..s + K,
            mul_add,
        }
    }

    /// The `K` columns into `out`, by blocks of 16 rows while more than 20 are left, then the
    /// rest (1 to 20 rows) as one block: a block's loop costs about the same bookkeeping
    /// whatever its width, so a short block of its own would cost nearly what a full one does.
    /// With `WIDE` (the AVX-512 copy, whose 32 registers of eight
    /// values hold 56 rows of two products) by blocks of 32 while more than 56 are left, then
    /// the rest as one block: a column of up to 56 rows walks its branch once.
    #[inline(always)]
    fn fill<const WIDE: bool>(&self, mut out: [&mut [f64]; K], probe: &mut Probe) {
        let n = self.n;
        let mut r = 0;
        macro_rules! blocks {
            ($width:literal, $longest_last:literal, $($w:literal)*) => {{
                while n - r > $longest_last {
                    self.rows::<$width>(r, &mut out, probe);
                    r += $width;
                }
                match n - r {
                    $($w => self.rows::<$w>(r, &mut out, probe),)*
                    _ => {} // no rows left (n = 0)
                }
            }};
        }
        if WIDE {
            blocks!(32, 56, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26
                27 28 29 30 31 32 33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53
                54 55 56)
        } else {
            blocks!(16, 20, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20)
        }
    }

    /// Rows `r .. r + W` of the `K` columns, summed in registers over the branch, stored and
    /// added to `probe`.
    #[inline(always)]
    fn rows<const W: usize>(&self, r: usize, out: &mut [&mut [f64]; K], probe: &mut Probe) {
        let mut sums = [[0.0; W]; K];
        for &i in self.ancestors {
            self.add::<W>(&mut sums, r, i);
        }
        for i in self.own_and_below.clone() {
            self.add::<W>(&mut sums, r, i);
        }
        for (out, sum) in out.iter_mut().zip(&sums) {
            let out: &mut [f64; W] = (&mut out[r..r + W]).try_into().expect("W rows");
            *out = *sum;
            probe.add(out);
        }
    }

    /// `sums_k += M[r .. r + W, i] (C_k)_i`.
    #[inline(always)]
    fn add<const W: usize>(&self, sums: &mut [[f64; W]; K], r: usize, i: usize) {
        let m: &[f64; W] = self.columns[i * self.n + r..][..W]
            .try_into()
            .expect("W rows");
        let c: &[f64; K] = self.coefficients[i * self.stride..][..K]
            .try_into()
            .expect("K coefficients");
        for t in 0..W {
            for k in 0..K {
                sums[k][t] = self.mul_add.mul_add(m[t], c[k], sums[k][t]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{branch_products, inverse_from_rows, Probe};
    use crate::model::examples::pendulum_urdf;
    use crate::model::ModelOptions;
    use crate::mul_add::MulAdd;
    use crate::plan::Ancestors;
    use crate::sampling::Rng;
    use crate::test_models::{floating, TREE_URDF};
    use crate::urdf::model_from_str;
    use crate::Workspace;
    use nalgebra::DMatrix;

    /// The branched test tree (14 coordinates) on a floating base: its URDF and options.
    fn floating_tree() -> (String, ModelOptions) {
        (TREE_URDF.to_string(), floating())
    }

    /// Against the dense products `M B_q`, `M B_v` with `B` zero off the branches, on a
    /// branched tree with a floating base (14 coordinates) and on chains of 1 to 40, 55 to 60
    /// and 87 to 90 (every width of the last narrow block after none, one or two blocks of 16,
    /// and of the wide blocks around their bounds, 56 and 32 + 56), in either blocking, with
    /// every entry of `b` off the branches poisoned (NaN): none is read; and on the tree with
    /// its first three floating-base columns not made and the next three made of `X_v` alone.
    #[test]
    fn the_products_over_the_branches_are_the_dense_products() {
        let (tree, floating) = floating_tree();
        let lengths = (1..=40).chain(55..=60).chain(87..=90);
        let chains = lengths.map(|n| (pendulum_urdf(n, 0.3, 0.5), ModelOptions::default(), n));
        for (text, options, nv) in [(tree, floating, 14)].into_iter().chain(chains) {
            let model = model_from_str(&text, &options).unwrap();
            let ancestors = Workspace::new(&model).plan.dof_ancestors.expect("a tree");
            assert_eq!(ancestors.len(), nv);
            for mul_add in [MulAdd::SEPARATE, MulAdd::FUSED] {
                products_match::<false>(&ancestors, 0, 0, mul_add);
                products_match::<true>(&ancestors, 0, 0, mul_add);
                if options.floating_base {
                    products_match::<false>(&ancestors, 3, 6, mul_add);
                    products_match::<true>(&ancestors, 3, 6, mul_add);
                }
            }
        }
    }

    /// Columns `j < q_from` of `x_q` and `j < v_from` of `x_v` are left as they were (NaN), and
    /// their entries of `B_q`, `B_v` are not read (NaN too).
    fn products_match<const WIDE: bool>(
        ancestors: &Ancestors,
        v_from: usize,
        q_from: usize,
        mul_add: MulAdd,
    ) {
        let n = ancestors.len();
        let on_branch = |i: usize, j: usize| {
            ancestors.of(j).contains(&i) || (j..ancestors.below(j).end).contains(&i)
        };
        let mut rng = Rng::new(3);
        let m = DMatrix::from_fn(n, n, |_, _| rng.uniform());
        let mut b = vec![f64::NAN; 2 * n * n];
        let (mut b_q, mut b_v) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        for j in 0..n {
            for i in (0..n).filter(|&i| on_branch(i, j)) {
                let (q, v) = (2.0 * rng.uniform(), 2.0 * rng.uniform());
                (b[2 * (j * n + i)], b[2 * (j * n + i) + 1]) = (q, v);
                if j < q_from {
                    b[2 * (j * n + i)] = f64::NAN;
                }
                if j < v_from {
                    b[2 * (j * n + i) + 1] = f64::NAN;
                }
                (b_q[(i, j)], b_v[(i, j)]) = (q, v);
            }
        }
        let (mut x_q, mut x_v) = (vec![f64::NAN; n * n], vec![f64::NAN; n * n]);
        let (minv, b) = (m.as_slice(), &b);
        let x = (&mut x_q[..], &mut x_v[..]);
        let probe = &mut Probe::new(mul_add);
        branch_products::<WIDE>(ancestors, minv, b, x, (v_from, q_from), probe, mul_add);
        assert!(probe.all_finite());
        assert!(x_q[..q_from * n].iter().all(|x| x.is_nan()));
        assert!(x_v[..v_from * n].iter().all(|x| x.is_nan()));
        for (got, want, skip) in [(&x_q, &m * &b_q, q_from * n), (&x_v, &m * &b_v, v_from * n)] {
            let scale = want.amax();
            for (k, (g, w)) in got.iter().zip(want.as_slice()).enumerate().skip(skip) {
                assert!((g - w).abs() <= 1e-14 * scale, "entry {k}: {g} against {w}");
            }
        }
    }

    /// The probe says the results are finite exactly when they are. On the floating tree and
    /// on chains of 20 and 57 coordinates (the narrow and wide blocks' widths), in either
    /// blocking, one input entry at a time is made infinite: of `H⁻¹` in row `r` of the root's
    /// column (on every branch: row `r` of every product), of `B_q` on column `j`'s diagonal
    /// (column `j` of `X_q` alone), of `Y` in row `r` of its first row (row `r` of `H⁻¹`).
    #[test]
    fn the_probe_sees_every_value_that_is_not_finite() {
        let chain = |n| (pendulum_urdf(n, 0.3, 0.5), ModelOptions::default());
        for (text, options) in [floating_tree(), chain(20), chain(57)] {
            let model = model_from_str(&text, &options).unwrap();
            let ancestors = Workspace::new(&model).plan.dof_ancestors.expect("a tree");
            probe_sees::<false>(&ancestors);
            probe_sees::<true>(&ancestors);
        }
    }

    fn probe_sees<const WIDE: bool>(ancestors: &Ancestors) {
        let n = ancestors.len();
        let mul_add = MulAdd::FUSED;
        let mut rng = Rng::new(5);
        let m: Vec<f64> = (0..n * n).map(|_| 1.0 + rng.uniform()).collect();
        let b: Vec<f64> = (0..2 * n * n).map(|_| 1.0 + rng.uniform()).collect();
        let products = |m: &[f64], b: &[f64]| {
            let (mut x_q, mut x_v) = (vec![0.0; n * n], vec![0.0; n * n]);
            let probe = &mut Probe::new(mul_add);
            branch_products::<WIDE>(
                ancestors,
                m,
                b,
                (&mut x_q, &mut x_v),
                (0, 0),
                probe,
                mul_add,
            );
            let finite = x_q.iter().chain(&x_v).all(|x| x.is_finite());
            (probe.all_finite(), finite)
        };
        assert_eq!(products(&m, &b), (true, true));
        for r in 0..n {
            let mut poisoned = m.clone();
            poisoned[r] = f64::INFINITY;
            assert_eq!(products(&poisoned, &b), (false, false), "row {r}");
        }
        for j in 0..n {
            let mut poisoned = b.clone();
            poisoned[2 * (j * n + j)] = f64::INFINITY;
            assert_eq!(products(&m, &poisoned), (false, false), "column {j}");
        }
        let inverse = |y: &[f64]| {
            let mut minv = vec![0.0; n * n];
            let probe = &mut Probe::new(mul_add);
            inverse_from_rows::<WIDE>(ancestors, y, &mut minv, probe, mul_add);
            (probe.all_finite(), minv.iter().all(|x| x.is_finite()))
        };
        assert_eq!(inverse(&m), (true, true));
        for r in 0..n {
            let mut poisoned = m.clone();
            poisoned[r] = f64::INFINITY;
            assert_eq!(inverse(&poisoned), (false, false), "row {r} of Y");
        }
    }
}
