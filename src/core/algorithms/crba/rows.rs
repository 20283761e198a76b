//! How CRBA's passes write `H` (`n × n`, column-major): by row blocks, Pinocchio's layout. When
//! every subtree's coordinates are contiguous, body `i` owns rows `v_i .. v_i + n_i` and its
//! subtree the columns `v_i .. e_i`; row `r` is written from the diagonal to `e_i` and is zero
//! beyond. Each row is stored down its column of the lower triangle (`H[c, r]` for `c ≥ r`,
//! contiguous) and, with `MIRROR`, also as itself in the upper triangle (else
//! `mirror::mirror_lower` copies the triangle up afterwards).
//!
//! The passes report whether every entry came out finite without a branch per entry: each entry
//! `x` adds `0·x` to a probe, which is 0 for a finite `x` and NaN otherwise, so the probe stays 0
//! exactly when every entry is finite (two flops an entry).

use crate::model::{JointKind, MotionSubspace};
use crate::spatial::{Force, Inertia, Motion};

/// The columns `S_k` of a joint's subspace that are a signed unit vector `σ e_j` of `[ω; v]`
/// (`Some((j, σ))`, from the plan) or general (`None`).
pub(super) type Axes = [Option<(usize, f64)>; 6];

/// `F_k = I S_k` for each column of `s` into `f[k]`; a column `σ e_j` (`axes[k]`) reads column `j`
/// of `I` instead of a product.
#[inline(always)]
pub(super) fn column_forces(ic: &Inertia, s: &MotionSubspace, axes: &Axes, f: &mut [Force]) {
    for k in 0..s.nv {
        f[k] = match axes[k] {
            Some((j, sign)) => ic.column(j) * sign,
            None => ic.apply(&s.cols[k]),
        };
    }
}

/// `H`'s storage as the passes write it, with the finiteness probe of the entries written.
pub(super) struct Rows<'h, const MIRROR: bool> {
    h: &'h mut [f64],
    n: usize,
    probe: f64,
}

impl<'h, const MIRROR: bool> Rows<'h, MIRROR> {
    /// Rows of the `n × n` column-major `h`, none written yet.
    pub(super) fn new(h: &'h mut [f64], n: usize) -> Self {
        Rows { h, n, probe: 0.0 }
    }

    /// True when every entry written so far is finite.
    pub(super) fn all_finite(&self) -> bool {
        self.probe == 0.0
    }

    /// A joint's rows in its body's coordinates: [`floating_rows`](Self::floating_rows) for a
    /// floating joint, else [`rows`](Self::rows).
    #[inline(always)]
    pub(super) fn joint_rows(
        &mut self,
        kind: &JointKind,
        v0: usize,
        s: &MotionSubspace,
        axes: &Axes,
        f_cols: &[Force],
    ) {
        match kind {
            JointKind::Floating => self.floating_rows(v0, f_cols),
            _ => self.rows(v0, s, axes, f_cols),
        }
    }

    /// Rows `v0 .. v0 + n_s` from the diagonal to the end of `f_cols`,
    /// `H[v0 + k, c] = S_kᵀ F_c`, where a column `S_k = σ e_j` (`axes[k]`) reads `σ F_c[j]`
    /// instead of a product.
    #[inline(always)]
    pub(super) fn rows(&mut self, v0: usize, s: &MotionSubspace, axes: &Axes, f_cols: &[Force]) {
        let mut probe = 0.0;
        for (k, s_k) in s.cols[..s.nv].iter().enumerate() {
            probe += match axes[k] {
                Some((j, sign)) => self.row(v0 + k, f_cols, |f| sign * f.component(j)),
                None => {
                    let s_k = *s_k; // a copy held in registers through the sweep
                    self.row(v0 + k, f_cols, |f| dot6(&s_k, f))
                }
            };
        }
        self.probe += probe;
    }

    /// The six rows of a floating joint in its body's coordinates: its `S` is `[0 1; 1 0]`
    /// (`v = [linear; angular]`), so `H[v0 .. v0 + 6, c] = Sᵀ F_c = [f_c; n_c]`, each column's
    /// force as it is; column by column, the 6×6 diagonal block in full (it is symmetric: its
    /// columns are those of the composite inertia).
    pub(super) fn floating_rows(&mut self, v0: usize, f_cols: &[Force]) {
        let (h, n) = (&mut *self.h, self.n);
        let mut probe = 0.0;
        for (c, f) in f_cols.iter().enumerate().skip(v0) {
            let rows = [f.lin.x, f.lin.y, f.lin.z, f.ang.x, f.ang.y, f.ang.z];
            if MIRROR {
                h[c * n + v0..c * n + v0 + 6].copy_from_slice(&rows);
            }
            for (k, x) in rows.iter().enumerate() {
                h[(v0 + k) * n + c] = *x;
                probe += 0.0 * x;
            }
        }
        self.probe += probe;
    }

    /// Row `row` from the diagonal to the end of `f_cols`, `H[row, c] = s_dot(F_c)`; returns
    /// the row's probe.
    #[inline(always)]
    fn row(&mut self, row: usize, f_cols: &[Force], s_dot: impl Fn(&Force) -> f64) -> f64 {
        let (h, n) = (&mut *self.h, self.n);
        let mut probe = 0.0;
        for (c, f) in f_cols.iter().enumerate().skip(row) {
            let x = s_dot(f);
            // Column-major: `H[c, row]` is at `row·n + c`, `H[row, c]` at `c·n + row`.
            h[row * n + c] = x;
            if MIRROR {
                h[c * n + row] = x;
            }
            probe += 0.0 * x;
        }
        probe
    }
}

/// `Sᵀ F = ω·n + v·f`, written out (nalgebra's generic dot does not unroll), summed as two
/// interleaved halves, `(ω_x n_x + ω_z n_z + v_y f_y) + (ω_y n_y + v_x f_x + v_z f_z)`: the
/// lanes of the stored pairs `(x, y), (z, x'), (y', z')`, so the products pair up in SIMD
/// registers.
#[inline(always)]
fn dot6(s: &Motion, f: &Force) -> f64 {
    let (w, v, n, f) = (&s.ang, &s.lin, &f.ang, &f.lin);
    (w.x * n.x + w.z * n.z + v.y * f.y) + (w.y * n.y + v.x * f.x + v.z * f.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::Vector3;

    fn force(seed: f64) -> Force {
        Force {
            ang: Vector3::new(seed, 2.0 * seed - 1.0, 0.5 - seed),
            lin: Vector3::new(3.0 - seed, seed * seed, -seed),
        }
    }

    /// A revolute-like subspace (one general column) and a two-column one with an axis column:
    /// the rows written equal `S_kᵀ F_c` by `Motion::dot`, in the lower triangle and, with
    /// `MIRROR`, in the upper; entries left of the diagonal and outside `f_cols` stay 0.
    #[test]
    fn rows_are_the_projections_of_the_column_forces() {
        let n = 5;
        let f_cols: Vec<Force> = (0..4).map(|c| force(0.3 + c as f64)).collect();
        let mut s = MotionSubspace {
            nv: 2,
            ..Default::default()
        };
        s.cols[0] = Motion {
            ang: Vector3::new(0.0, 0.0, -1.0),
            lin: Vector3::zeros(),
        };
        s.cols[1] = Motion {
            ang: Vector3::new(0.2, -0.7, 0.4),
            lin: Vector3::new(1.5, 0.1, -0.3),
        };
        let mut axes: Axes = [None; 6];
        axes[0] = Some((2, -1.0));
        for mirror in [false, true] {
            let mut h = vec![0.0; n * n];
            let finite = if mirror {
                let mut rows = Rows::<true>::new(&mut h, n);
                rows.rows(1, &s, &axes, &f_cols);
                rows.all_finite()
            } else {
                let mut rows = Rows::<false>::new(&mut h, n);
                rows.rows(1, &s, &axes, &f_cols);
                rows.all_finite()
            };
            assert!(finite);
            // Column-major: `H[r, c]` at `c·n + r`.
            let mut expected = vec![0.0; n * n];
            for r in 1..3 {
                for (c, f) in f_cols.iter().enumerate().skip(r) {
                    let x = s.cols[r - 1].dot(f);
                    expected[r * n + c] = x; // H[c, r], the lower triangle
                    if mirror {
                        expected[c * n + r] = x;
                    }
                }
            }
            for (k, (x, e)) in h.iter().zip(&expected).enumerate() {
                assert!((x - e).abs() < 1e-15, "H[{}, {}]: {x} vs {e}", k % n, k / n);
            }
        }
    }

    /// A floating joint's rows are `[f_c; n_c]`, its diagonal block written in full and every
    /// entry mirrored.
    #[test]
    fn floating_rows_are_the_forces() {
        let n = 7;
        // The diagonal block's columns are those of a symmetric matrix, as `Sᵀ I^c S` is.
        let m = |k: usize, c: usize| 1.0 / (1.0 + k as f64 + c as f64);
        let mut f_cols: Vec<Force> = (0..6)
            .map(|c| Force {
                lin: Vector3::new(m(0, c), m(1, c), m(2, c)),
                ang: Vector3::new(m(3, c), m(4, c), m(5, c)),
            })
            .collect();
        f_cols.push(force(0.7));
        let mut h = vec![0.0; n * n];
        let mut rows = Rows::<true>::new(&mut h, n);
        rows.floating_rows(0, &f_cols);
        assert!(rows.all_finite());
        for (c, f) in f_cols.iter().enumerate() {
            let expected = [f.lin.x, f.lin.y, f.lin.z, f.ang.x, f.ang.y, f.ang.z];
            for (k, x) in expected.iter().enumerate() {
                assert_eq!(h[k * n + c], *x, "H[{c}, {k}]");
                assert_eq!(h[c * n + k], *x, "H[{k}, {c}]");
            }
        }
    }

    /// The probe reports an entry that is infinite or NaN, and only then.
    #[test]
    fn the_probe_finds_a_non_finite_entry() {
        let mut s = MotionSubspace {
            nv: 1,
            ..Default::default()
        };
        s.cols[0] = Motion {
            ang: Vector3::new(0.0, 1.0, 0.0),
            lin: Vector3::new(0.5, 0.0, 0.0),
        };
        for (bad, finite) in [(1.0, true), (f64::INFINITY, false), (f64::NAN, false)] {
            let mut f_cols = vec![force(0.4); 3];
            f_cols[2].lin.x = bad;
            let mut h = vec![0.0; 9];
            let mut rows = Rows::<true>::new(&mut h, 3);
            rows.rows(0, &s, &[None; 6], &f_cols);
            assert_eq!(rows.all_finite(), finite, "{bad}");
        }
    }
}
