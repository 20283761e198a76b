//! The joint-space inertia matrix `H(q)` by the composite rigid-body algorithm (Featherstone,
//! RBDA Table 6.2), in either of the two frames Pinocchio's `crba` offers (RBDA §6.2 notes the
//! algorithm works in any frame), whichever counts fewer operations for the model
//! ([`crba_frames`]).
//!
//! **World (root) coordinates** (`CrbaFrames::World`): a composite inertia needs no transform on
//! its way to the parent and a column force `F` none on its way to the root; only each body's
//! inertia and joint axes are carried to the world once, by its placement `⁰X_i`:
//!
//! ```text
//! outward:  ⁱX_0 = ⁱX_λ ᵏX_0,   ⁰S_i = ⁰X_i S_i,   ⁰I^c_i = ⁱX_0ᵀ I_i ⁱX_0
//! inward:   F = ⁰I^c_i ⁰S_i,   H_ii = ⁰S_iᵀ F,   H_ji = ⁰S_jᵀ F = H_ijᵀ  (j ancestor of i)
//!           ⁰I^c_λ(i) += ⁰I^c_i
//! ```
//!
//! which is RBDA Table 6.2 with `ʲX_iᵀ` replaced by the identity (all in one frame). The "world"
//! frame has the world's axes and its origin at the root body's: `H` does not depend on the
//! origin, but inertias about a far origin carry large `m d²` terms that cancel
//! (`kinematics::update_aligned_placements`).
//!
//! **Body coordinates** (`CrbaFrames::Local`), RBDA Table 6.2 as written: no placements, each
//! body's own `S_i` (a coordinate axis for most joints, so `S_iᵀ F` reads one component), and
//! every column force moved up one body at a time:
//!
//! ```text
//! inward:   F = ⁱI^c_i S_i,   H_ii = S_iᵀ F,   then at each ancestor j:  F ← ᵏX_jᵀ F,
//!           H_ji = S_jᵀ F;    ᵏI^c_λ(i) += ⁱX_λᵀ ⁱI^c_i ⁱX_λ
//! ```
//!
//! A force moved costs four times a world product `⁰S_jᵀ F`, but the world frame pays a
//! placement, an axis and an inertia transform per body: body coordinates win on short
//! branches (arms, legs, a floating base over them), world coordinates on long chains.
//!
//! When every subtree's coordinates are contiguous (the usual depth-first order) the inward
//! pass fills `H` by row blocks, Pinocchio's way: the `F` of each coordinate is kept, and body
//! `i` fills its rows from its own columns to the end of its subtree, `H_ij = S_iᵀ F_j` (see
//! `row_blocks` and `local_row_blocks`; each entry written down a column of the lower
//! triangle with its mirror beside it, or, for the sizes where those mirror stores conflict in
//! the L1 cache, the upper triangle copied afterwards by tiles, `mirror_lower`). Otherwise
//! (mimic joints) it runs in world coordinates along each column's path to the root: body `i`
//! contributes to the column of its leader scaled by `μ_i`, `H[c_j, c_i] += μ_j μ_i S_jᵀ F` (and
//! its mirror), which is `Jᵀ H_full J` for the coordinate map `J`.

use super::kinematics::{
    update_aligned_placements, update_joints, update_world_axes, with_up_transform, Anchors,
};
use super::validate::check_q;
use crate::error::DynamicsError;
use crate::model::{JointKind, Model, MotionSubspace};
use crate::plan::CrbaFrames;
use crate::spatial::{Force, Motion, SpatialTransform};
use crate::Workspace;
use nalgebra::DMatrix;

/// `H(q)` into `ws.mass_matrix()` (full and symmetric).
pub fn crba<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
) -> Result<&'w DMatrix<f64>, DynamicsError> {
    check_q(model, q)?;
    update_joints(model, ws, q);
    // Finite inputs can still overflow (a prismatic coordinate of 1e200 under a revolute joint
    // puts m·x² on the diagonal). The passes say whether every entry came out finite; only
    // then is the matrix searched, for the coordinate to name (column-major: entry i is in row
    // i mod nv).
    if !crba_passes(model, ws) {
        let i = ws
            .mass_matrix
            .iter()
            .position(|x| !x.is_finite())
            .unwrap_or(0);
        return Err(DynamicsError::NonFiniteResult {
            quantity: "mass matrix",
            coordinate: model.v_name(i % model.nv),
        });
    }
    Ok(&ws.mass_matrix)
}

/// The two passes, on joints already updated for `q`, in the frames `ws.plan.crba_frames` says (world
/// coordinates for the general pass). Writes `ws.ic` and `ws.mass_matrix` (the row blocks also
/// `ws.f_cols`, world coordinates `ws.x_aligned` and `ws.s_world`); true when every entry of `H`
/// is finite.
pub(crate) fn crba_passes(model: &Model, ws: &mut Workspace) -> bool {
    match ws.plan.subtree_end.take() {
        Some(subtree_end) => {
            let finite = if ws.plan.mirror_by_tiles {
                let finite = row_block_pass::<false>(model, ws, &subtree_end);
                mirror_lower(ws.mass_matrix.as_mut_slice(), model.nv, &subtree_end);
                finite
            } else {
                row_block_pass::<true>(model, ws, &subtree_end)
            };
            ws.plan.subtree_end = Some(subtree_end);
            finite
        }
        None => {
            world_axes_and_inertias(model, ws);
            along_paths(model, ws);
            ws.mass_matrix.iter().all(|x| x.is_finite())
        }
    }
}

/// The row blocks in the frames `ws.plan.crba_frames` says. Each entry is written down its column of
/// the lower triangle and, with `MIRROR`, its mirror in the upper triangle beside it (else
/// [`mirror_lower`] copies the triangle up afterwards, `ws.plan.mirror_by_tiles`). True when every
/// entry written is finite.
fn row_block_pass<const MIRROR: bool>(
    model: &Model,
    ws: &mut Workspace,
    subtree_end: &[usize],
) -> bool {
    match ws.plan.crba_frames {
        CrbaFrames::World => {
            world_axes_and_inertias(model, ws);
            row_blocks::<MIRROR>(model, ws, subtree_end)
        }
        CrbaFrames::Local => local_row_blocks::<MIRROR>(model, ws, subtree_end),
    }
}

/// `ⁱX_0`, `⁰S_i = ⁰X_i S_i` and `⁰I_i = ⁱX_0ᵀ I_i ⁱX_0` for every body.
fn world_axes_and_inertias(model: &Model, ws: &mut Workspace) {
    update_aligned_placements(model, ws, Anchors::Roots);
    for (i, body) in model.bodies.iter().enumerate() {
        ws.ic[i] = ws.x_aligned[i].transpose_apply_inertia(&body.inertia);
        update_world_axes(ws, i, &[], 0.0);
    }
}

/// Inward pass when every subtree's coordinates are contiguous (Pinocchio's layout): for body
/// `i` with coordinates `v_i .. v_i + n_i` and subtree coordinates `v_i .. e_i`,
/// `F_c = ⁰I^c_i ⁰S_c` for its own columns, then the row block
/// `H[v_i + k, c] = ⁰S_ikᵀ F_c` for `c` from `v_i + k` to `e_i` (and its mirror, see
/// [`row_block_pass`]): each descendant's `F_c` was stored when that descendant was visited.
/// Entries outside the pattern are never written (they stay zero). True when every entry
/// written is finite (see [`fill_rows`]).
fn row_blocks<const MIRROR: bool>(
    model: &Model,
    ws: &mut Workspace,
    subtree_end: &[usize],
) -> bool {
    let h = ws.mass_matrix.as_mut_slice();
    let mut probe = 0.0;
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let v0 = body.joint.coords.v_index;
        let s_i = &ws.s_world[i];
        for k in 0..s_i.nv {
            ws.f_cols[v0 + k] = ws.ic[i].apply(&s_i.cols[k]);
        }
        probe += fill_rows::<MIRROR>(
            h,
            model.nv,
            v0,
            s_i,
            &[None; 6],
            &ws.f_cols[..subtree_end[v0]],
        );
        if let Some(p) = body.parent {
            let ic_i = ws.ic[i];
            ws.ic[p] += ic_i;
        }
    }
    probe == 0.0
}

/// The row block in body coordinates (Pinocchio's LOCAL convention), same layout as
/// [`row_blocks`]: body `i`'s composite inertia `ⁱI^c_i` and the forces `F_c` of its subtree's
/// columns are in its own coordinates, so `H[v_i + k, c] = S_ikᵀ F_c` with the joint's own
/// `S_i`; then the forces and the inertia move to the parent,
///
/// ```text
/// F_c ← ⁱX_λᵀ F_c  (c in v_i .. e_i),   ᵏI^c_λ += ⁱX_λᵀ ⁱI^c_i ⁱX_λ
/// ```
///
/// (RBDA Table 6.2's inward pass with its column forces kept). No world placements or world
/// axes are needed; each force is transformed once per ancestor instead, by `ⁱX_λ` in the
/// cheapest form its joint allows (`with_up_transform`): for a revolute joint about a
/// coordinate axis whose placement has no rotation (most joints of most robots), a turn after a
/// translation, 24 flops a force and 71 the inertia instead of 42 and 113.
fn local_row_blocks<const MIRROR: bool>(
    model: &Model,
    ws: &mut Workspace,
    subtree_end: &[usize],
) -> bool {
    let h = ws.mass_matrix.as_mut_slice();
    let mut probe = 0.0;
    for (ic, body) in ws.ic.iter_mut().zip(&model.bodies) {
        *ic = body.inertia;
    }
    for i in (0..model.bodies.len()).rev() {
        let body = &model.bodies[i];
        let v0 = body.joint.coords.v_index;
        let (s_i, axes, end) = (&ws.s[i], &ws.plan.s_axes[i], subtree_end[v0]);
        for k in 0..s_i.nv {
            ws.f_cols[v0 + k] = match axes[k] {
                Some((j, sign)) => ws.ic[i].column(j) * sign,
                None => ws.ic[i].apply(&s_i.cols[k]),
            };
        }
        probe += match body.joint.kind {
            JointKind::Floating => floating_rows::<MIRROR>(h, model.nv, v0, &ws.f_cols[..end]),
            _ => fill_rows::<MIRROR>(h, model.nv, v0, s_i, axes, &ws.f_cols[..end]),
        };
        if let Some(p) = body.parent {
            // The parent's sum is taken where the moved inertia is made, so that it stays in
            // registers (one form per arm) rather than passing through memory.
            let forces = &mut ws.f_cols[v0..end];
            let (ic_above, ic_from) = ws.ic.split_at_mut(i);
            let (ic_p, ic) = (&mut ic_above[p], &ic_from[0]);
            with_up_transform!(ws, i, |x| {
                x.transpose_apply_forces(forces);
                *ic_p += x.transpose_apply_inertia(ic);
            });
        }
    }
    probe == 0.0
}

/// Rows `v0 .. v0 + n_i` of `H` (`n × n`, column-major) from the diagonal to the end of
/// `f_cols`, `H[v0 + k, c] = S_kᵀ F_c`, written as their mirror `H[c, v0 + k]` (down a column of
/// the lower triangle, contiguous) and, with `MIRROR`, also as themselves, where a column `S_k`
/// that is a signed unit vector `σ e_j` (`axes[k]`) reads `σ F_c[j]` instead of a product.
/// Returns the sum of `0·H_rc` over the entries written: `0·x` is 0 for a finite `x` and NaN
/// otherwise, so the sum is 0 exactly when every entry is finite (two flops an entry and one
/// addition a row, no branch).
#[inline(always)]
fn fill_rows<const MIRROR: bool>(
    h: &mut [f64],
    n: usize,
    v0: usize,
    s: &MotionSubspace,
    axes: &[Option<(usize, f64)>; 6],
    f_cols: &[Force],
) -> f64 {
    let mut probe = 0.0;
    for (k, s_k) in s.cols[..s.nv].iter().enumerate() {
        probe += match axes[k] {
            Some((j, sign)) => fill_row::<MIRROR>(h, n, v0 + k, f_cols, |f| sign * f.component(j)),
            None => {
                let s_k = *s_k; // a copy held in registers through the sweep
                fill_row::<MIRROR>(h, n, v0 + k, f_cols, |f| dot6(&s_k, f))
            }
        };
    }
    probe
}

/// The six rows of a floating joint in its body's coordinates: its `S` is `[0 1; 1 0]`
/// (`v = [linear; angular]`), so `H[v0 .. v0 + 6, c] = Sᵀ F_c = [f_c; n_c]`, each column's force
/// as it is, written as the mirror `H[c, v0 .. v0 + 6]` (lower triangle, as [`fill_rows`]) and,
/// with `MIRROR`, as itself; column by column, the 6×6 diagonal block in full (it is symmetric:
/// its columns are those of the composite inertia). Returns the sum of `0·H_rc` over the
/// entries written (see [`fill_rows`]).
fn floating_rows<const MIRROR: bool>(h: &mut [f64], n: usize, v0: usize, f_cols: &[Force]) -> f64 {
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
    probe
}

/// `H`'s upper triangle from its lower one, `H[r, c] = H[c, r]` for `r < c` up to the end of
/// row `r`'s pattern (`subtree_end[r]`; entries beyond are zero in both triangles), by tiles of
/// eight rows and eight columns.
///
/// The passes write each row of `H` down its column (`H[c, r]` for `c ≥ r`, contiguous in
/// column-major storage); its mirror beside it steps `n` entries a store, and for some `n`
/// (multiples of 64 from 128 on the worst) those stores fall in a few sets of the L1 cache and
/// miss (a 256-link chain's CRBA took 3.2× as long: 196 µs against 62). A tile reads eight
/// contiguous runs of the lower triangle and writes eight of the upper, a cache line each. For
/// other sizes the mirror beside each entry is 2–10 % faster ([`mirror_by_tiles`] decides).
fn mirror_lower(h: &mut [f64], n: usize, subtree_end: &[usize]) {
    const TILE: usize = 8;
    for r0 in (0..n).step_by(TILE) {
        let r1 = (r0 + TILE).min(n);
        let last = subtree_end[r0..r1].iter().copied().max().unwrap_or(r1);
        for c0 in (r0..last).step_by(TILE) {
            for c in c0..(c0 + TILE).min(last) {
                for r in r0..r1.min(c) {
                    h[c * n + r] = h[r * n + c];
                }
            }
        }
    }
}

/// Row `row` of `H` from the diagonal to the end of `f_cols`, `H[row, c] = s_dot(F_c)`, written
/// as its mirror `H[c, row]`, down column `row`, and with `MIRROR` as itself; returns the sum of
/// `0·H_rc` (see [`fill_rows`]).
#[inline(always)]
fn fill_row<const MIRROR: bool>(
    h: &mut [f64],
    n: usize,
    row: usize,
    f_cols: &[Force],
    s_dot: impl Fn(&Force) -> f64,
) -> f64 {
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

/// `Sᵀ F = ω·n + v·f`, written out (nalgebra's generic dot does not unroll), summed as two
/// interleaved halves, `(ω_x n_x + ω_z n_z + v_y f_y) + (ω_y n_y + v_x f_x + v_z f_z)`: the
/// lanes of the stored pairs `(x, y), (z, x'), (y', z')`, so the products pair up in SIMD
/// registers.
#[inline(always)]
fn dot6(s: &Motion, f: &Force) -> f64 {
    let (w, v, n, f) = (&s.ang, &s.lin, &f.ang, &f.lin);
    (w.x * n.x + w.z * n.z + v.y * f.y) + (w.y * n.y + v.x * f.x + v.z * f.z)
}

/// Inward pass in general (mimic joints, coordinates out of body order): each column force `F`
/// is projected on the joint axes of every ancestor on the way to the root, and accumulated
/// (coordinates may be shared).
fn along_paths(model: &Model, ws: &mut Workspace) {
    let h = &mut ws.mass_matrix;
    h.as_mut_slice().fill(0.0);
    for (i, body) in model.bodies.iter().enumerate().rev() {
        let ci = body.joint.coords;
        let s_i = &ws.s_world[i];
        for k in 0..s_i.nv {
            let f = ws.ic[i].apply(&s_i.cols[k]);
            for k2 in 0..=k {
                let h_kk2 = ci.scale * ci.scale * s_i.project(k2, &f);
                h[(ci.v_index + k2, ci.v_index + k)] += h_kk2;
                if k2 != k {
                    h[(ci.v_index + k, ci.v_index + k2)] += h_kk2;
                }
            }
            let mut j = i;
            while let Some(p) = model.bodies[j].parent {
                j = p;
                let cj = model.bodies[j].joint.coords;
                let s_j = &ws.s_world[j];
                for k2 in 0..s_j.nv {
                    let h_ji = ci.scale * cj.scale * s_j.project(k2, &f);
                    h[(cj.v_index + k2, ci.v_index + k)] += h_ji;
                    h[(ci.v_index + k, cj.v_index + k2)] += h_ji;
                }
            }
        }
        if let Some(p) = body.parent {
            let ic_i = ws.ic[i];
            ws.ic[p] += ic_i;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::examples::{self, pendulum_urdf};
    use crate::sampling::{random_q, Rng};
    use crate::{urdf, ModelOptions};

    const TREE: &str = include_str!("../../../tests/models/tree.urdf");
    const TURN_SLIDE: &str = include_str!("../../../tests/models/turn_slide.urdf");

    fn load(text: &str, floating_base: bool) -> Model {
        let options = ModelOptions {
            floating_base,
            ..Default::default()
        };
        urdf::model_from_str(text, &options).unwrap()
    }

    /// `H` by the row blocks in world and in body coordinates, and by the general pass along
    /// the paths, on trees with every joint kind (planar and floating roots, axes on and off
    /// the coordinate axes, prismatic joints), agree to rounding and are exactly symmetric.
    #[test]
    fn world_and_body_frames_and_the_general_pass_agree() {
        let models = [
            load(TREE, false),
            load(
                &TREE.replace(r#"type="planar""#, r#"type="floating""#),
                false,
            ),
            load(&pendulum_urdf(9, 0.5, 0.7), false),
            load(&pendulum_urdf(20, 0.5, 0.7), true), // mirrored by three tiles of rows
            load(examples::DEFAULT_ARM_URDF, false),
            load(examples::DEFAULT_ARM_URDF, true),
            load(examples::LAMP_URDF, true),
        ];
        for model in &models {
            let mut ws = Workspace::new(model);
            let subtree_end = ws.plan.subtree_end.clone();
            assert!(subtree_end.is_some(), "{}", model.name);
            let mut rng = Rng::new(21);
            for _ in 0..5 {
                let q = random_q(model, &mut rng);
                let mut h = Vec::new();
                for (frames, subtree_end, tiles) in [
                    (CrbaFrames::World, subtree_end.clone(), false),
                    (CrbaFrames::World, subtree_end.clone(), true),
                    (CrbaFrames::Local, subtree_end.clone(), false),
                    (CrbaFrames::Local, subtree_end.clone(), true),
                    (CrbaFrames::World, None, false), // the general pass
                ] {
                    (ws.plan.crba_frames, ws.plan.subtree_end) = (frames, subtree_end);
                    ws.plan.mirror_by_tiles = tiles;
                    ws.mass_matrix.fill(0.0); // an entry a pass misses stays 0
                    let m = crba(model, &mut ws, &q).unwrap();
                    assert_eq!(m, &m.transpose(), "{}: {frames:?}", model.name);
                    h.push(m.clone());
                }
                // The mirror's two forms give the same matrix, bit for bit.
                assert_eq!(h[0], h[1], "{}: world rows", model.name);
                assert_eq!(h[2], h[3], "{}: body rows", model.name);
                let scale = h[0].amax();
                for other in &h[1..] {
                    let err = (&h[0] - other).amax();
                    assert!(err < 1e-13 * scale, "{}: H differs by {err:e}", model.name);
                }
            }
        }
    }

    /// An entry that overflows is found in either frame (`m x²` for a slide at `x = 1e200`).
    #[test]
    fn overflow_is_found_in_both_frames() {
        let model = load(TURN_SLIDE, false);
        let mut ws = Workspace::new(&model);
        for frames in [CrbaFrames::World, CrbaFrames::Local] {
            ws.plan.crba_frames = frames;
            let err = crba(&model, &mut ws, &[0.0, 1e200]).unwrap_err();
            assert!(
                matches!(err, DynamicsError::NonFiniteResult { .. }),
                "{frames:?}: {err}"
            );
        }
    }
}
