//! Floating-point operation counts of the algorithms *as implemented here*, for a given model:
//! each spatial operation's cost, summed over the tree (and, for `crba` and the `LᵀL`
//! factorisation, over the mass matrix's sparsity pattern).
//!
//! A FLOP is one scalar multiplication, addition or subtraction, division or square root
//! ([`Flops::total`]); a joint angle's sine and cosine are ours (`spatial::sin_cos`, counted
//! like the rest), but an axis rotation's (nalgebra's, for a revolute joint about another axis
//! or a planar joint) is a library call, counted apart ([`Flops::sincos`]). No fused
//! multiply-add: Rust does not contract `a * b + c`. Negations, comparisons, absolute values,
//! copies and index arithmetic are not FLOPs.
//!
//! **What is counted: the operations the compiled code performs, one per scalar result.** That
//! is the source's arithmetic after the simplifications the compiler makes without changing any
//! result: a product written twice is computed once (nalgebra's `from_axis_angle`), `2 x`
//! becomes `x + x`, `0 − 0` and `−0 + x` on constants are folded. Validation that computes
//! (a quaternion's norm, a pivot's threshold `H_kk ε`) is counted. Packed SIMD instructions the
//! vectoriser emits are not counted by the lane: a packed instruction whose second lane
//! computes nothing needed is one operation here, two in the executed count.
//!
//! **How it is checked** (`benches/count_flops.py`, `tests/python/test_flop_counts.py`):
//! valgrind (callgrind) counts how often each machine instruction of `benches/flop_harness.rs`
//! runs while it calls a kernel, and `objdump` says which are floating-point arithmetic. Built
//! without LLVM's vectorisers (`--scalar`, one operation per instruction), the count executed
//! is this table's for every building block below, and for `rnea`, `crba`, `gravity` and
//! `fd_rnea_columns` on the default arm (fixed and floating), a 12-link chain,
//! `src/core/tests/models/tree.urdf` and the mimic gripper; `fd_aba` executes an addition a body
//! more than the table (5 to 12), and `fd_crba`'s sparse `LᵀL` from one addition fewer to 30
//! more, both within 1 %. The input and result checks are arithmetic too ([`all_finite`],
//! [`MOTION_FINITE`]). The
//! release build executes more, since its packed instructions compute lanes nobody needs
//! (`docs/performance.md` lists how much more per kernel).
//!
//! Costs of the building blocks (multiplications m, additions a), each also checked alone
//! (`count_flops.py --ops`):
//!
//! | operation | code | m | a |
//! |---|---|---:|---:|
//! | 3-vector cross product | `Vector3::cross` | 6 | 3 |
//! | 3×3 matrix × 3-vector (or `Eᵀ v`) | `Matrix3 * Vector3`, `tr_mul` | 9 | 6 |
//! | 3×3 × 3×3 | `Matrix3 * Matrix3` | 27 | 18 |
//! | `X m`, `X* f`, `X⁻¹ m`, `Xᵀ f` | `Transform::apply_*` | 24 | 18 |
//! | `X₁ X₂` | `Transform::compose` | 36 | 27 |
//! | `Xᵀ I X` (rigid inertia) | `Transform::transpose_apply_inertia` | 55 | 58 |
//! | `xlt(r) m`, `xlt(r)ᵀ f` | `Translation::apply_motion`, `transpose_apply_force` | 6 | 6 |
//! | `xlt(r)ᵀ I xlt(r)` | `Translation::transpose_apply_inertia` | 18 | 23 |
//! | `X m`, `Xᵀ f`, `X` a turn about a coordinate axis after a translation | `AxisTransform::*` | 14 | 10 |
//! | `Xᵀ I X`, same `X` | `AxisTransform::transpose_apply_inertia` | 36 | 35 |
//! | `X₁ X₂`, `X₁` that turn | `AxisTransform::compose` | 21 | 15 |
//! | `xlt(r) X₂` | `Translation::compose` | 9 | 9 |
//! | `I v` | `Inertia::apply` | 24 | 18 |
//! | `v ×̂ m`, `v ×* f` | `Motion::cross_*` | 18 | 12 |
//! | `mᵀ f` | `Motion::dot` | 6 | 5 |
//! | 6-vector sum | `+` on `Motion`, `Force` | 0 | 6 |
//! | `I₁ + I₂` (rigid inertias) | `Inertia + Inertia` | 0 | 13 |
//! | 6×6 × 6-vector | `Matrix6 * Vector6` | 36 | 30 |
//! | `S q̇` (per column) | `MotionSubspace::apply` | 7 | 6 |
//! | rigid inertia as 6×6 | `Inertia::to_matrix` | 1 | 0 |
//!
//! and `jcalc_up` (`JointKind::jcalc_up`, [`jcalc_up`]) per joint kind, after the joint's
//! coordinates `scale · q + offset` (1 m + 1 a each, for every joint): revolute about a
//! coordinate axis 13 m + 6 a and one `sin_cos` (1 m and `sin_cos` when its placement has no
//! rotation: `update_joints` writes the turn itself); prismatic 12 m + 9 a; revolute about
//! another axis [`AXIS_ROTATION`] then `compose`; floating [`QUATERNION_ROTATION`] then
//! `compose`; planar ([`AXIS_ROTATION`], then `E u`, `E w`, `u x + w y`: 24 m + 15 a more) then
//! `compose`.
//!
//! A body's `ⁱX_λ` is priced in the form the passes use for it (`JointKind::up_shape`): a
//! translation for a slide, a turn after a translation for a revolute joint about a coordinate
//! axis, when the joint's placement has no rotation; a general transform otherwise.
//!
//! Dense factorisations and ABA's inverse of a joint's `D` ([`spd_inverse`]) count exactly their
//! loops.

use super::Plan;
use crate::model::{Body, JointKind, Model, UpShape};
use std::ops::{Add, AddAssign, Mul};

/// Operation counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Flops {
    /// Multiplications.
    pub mul: u64,
    /// Additions and subtractions.
    pub add: u64,
    /// Divisions.
    pub div: u64,
    /// Square roots.
    pub sqrt: u64,
    /// Calls to `sin_cos` (not in [`total`](Self::total)).
    pub sincos: u64,
}

impl Flops {
    /// `mul` multiplications and `add` additions.
    pub const fn new(mul: u64, add: u64) -> Self {
        Flops {
            mul,
            add,
            div: 0,
            sqrt: 0,
            sincos: 0,
        }
    }

    /// Multiplications, additions, divisions and square roots.
    pub fn total(&self) -> u64 {
        self.mul + self.add + self.div + self.sqrt
    }
}

impl Add for Flops {
    type Output = Flops;
    fn add(self, o: Flops) -> Flops {
        Flops {
            mul: self.mul + o.mul,
            add: self.add + o.add,
            div: self.div + o.div,
            sqrt: self.sqrt + o.sqrt,
            sincos: self.sincos + o.sincos,
        }
    }
}

impl AddAssign for Flops {
    fn add_assign(&mut self, o: Flops) {
        *self = *self + o;
    }
}

impl Mul<u64> for Flops {
    type Output = Flops;
    fn mul(self, k: u64) -> Flops {
        Flops {
            mul: self.mul * k,
            add: self.add * k,
            div: self.div * k,
            sqrt: self.sqrt * k,
            sincos: self.sincos * k,
        }
    }
}

/// `Vector3::cross`.
pub const CROSS3: Flops = Flops::new(6, 3);
/// 3×3 matrix times 3-vector.
pub const MAT3_VEC3: Flops = Flops::new(9, 6);
/// Motion or force transform (any of the four `apply` forms).
pub const TRANSFORM_VECTOR: Flops = Flops::new(24, 18);
/// `Transform::compose`.
pub const COMPOSE: Flops = Flops::new(36, 27);
/// `Transform::transpose_apply_inertia`.
pub const TRANSFORM_INERTIA: Flops = Flops::new(55, 58);
/// `Translation::apply_motion` or `transpose_apply_force`: a cross product and three sums.
pub const TRANSLATE_VECTOR: Flops = Flops::new(6, 6);
/// `Translation::transpose_apply_inertia`: `h + m r`, `r·(h + h_A)` and six entries
/// `Ī_jk − h_A,j r_k − r_j h_k`, three of them plus the dot.
pub const TRANSLATE_INERTIA: Flops = Flops::new(18, 23);
/// `AxisTransform`'s actions on a motion or a force: two planar turns (4 m + 2 a each) and a
/// translation ([`TRANSLATE_VECTOR`]).
pub const AXIS_TURN_VECTOR: Flops = Flops::new(14, 10);
/// `AxisTransform::transpose_apply_inertia`: the `(I, J)` block (10 m + 8 a: of the source's 12
/// products, `b c` and `b s` each serve twice), the `(I, K)` and `(J, K)` entries and `h`
/// turned (4 m + 2 a each), then [`TRANSLATE_INERTIA`].
pub const AXIS_TURN_INERTIA: Flops = Flops::new(36, 35);
/// `Translation::compose`: the origin moved, `r_BA + E_BAᵀ r`.
pub const TRANSLATE_COMPOSE: Flops = Flops::new(9, 9);
/// `AxisTransform::compose`: two rows of `E_BA` mixed (12 m + 6 a) and the origin moved.
pub const AXIS_TURN_COMPOSE: Flops = Flops::new(21, 15);
/// `Transform::inverse_apply_axis` for a turn: a row of `E` signed (3 m) and its moment `r ×`.
pub const WORLD_TURN_AXIS: Flops = Flops::new(9, 3);
/// `Transform::inverse_apply_axis` for a slide: a row of `E` signed.
pub const WORLD_SLIDE_AXIS: Flops = Flops::new(3, 0);
/// `Translation::transpose_apply_matrix6`: nine cross products and 27 sums.
pub const TRANSLATE_MATRIX6: Flops = Flops::new(54, 54);
/// `Inertia::apply`.
pub const INERTIA_APPLY: Flops = Flops::new(24, 18);
/// Spatial cross product, motion or force.
pub const CROSS6: Flops = Flops::new(18, 12);
/// `Motion::dot`.
pub const DOT6: Flops = Flops::new(6, 5);
/// Sum of two 6-vectors.
pub const ADD6: Flops = Flops::new(0, 6);
/// Sum of two rigid-body inertias.
pub const INERTIA_ADD: Flops = Flops::new(0, 13);
/// 6×6 matrix times 6-vector.
pub const MAT6_VEC6: Flops = Flops::new(36, 30);
/// One column of `S q̇` with the coordinate scale.
pub const SUBSPACE_COLUMN: Flops = Flops::new(7, 6);
/// `Inertia::to_matrix`: copies of `Ī`, `m` and the components of `h`, some negated (none a
/// FLOP).
pub const INERTIA_TO_MATRIX: Flops = Flops::new(0, 0);
/// `cholesky::spd_inverse` of an `n × n` block: the factor `L` (`n` square roots and
/// reciprocals), `W = L⁻¹` and the lower triangle of `Wᵀ W`, loop by loop.
pub fn spd_inverse(n: usize) -> Flops {
    let mut total = spd_factor(n);
    for j in 0..n as u64 {
        // Column `j` of `W` below the diagonal: row `i` sums `i − j` products, then scales.
        for i in j + 1..n as u64 {
            total += Flops::new(i - j + 1, i - j - 1);
        }
        // Row `i ≥ j` of `Wᵀ W`'s column `j`: `n − i` products.
        for i in j..n as u64 {
            total += Flops::new(n as u64 - i, n as u64 - i - 1);
        }
    }
    total
}

/// The square-root-free `L D Lᵀ` solve of an `n × n` block (ABA's floating root,
/// `aba::ldlt_by_blocks` for `n = 6`): the factor's operations are those of `L` in
/// [`spd_inverse`] with a reciprocal of each pivot and no square root, then `L z = b`, `D⁻¹ z`
/// and `Lᵀ x = D⁻¹ z`, `n − 1` products subtracted from each right-hand side in all and one
/// scaling per entry.
pub fn ldlt_solve(n: usize) -> Flops {
    let n = n as u64;
    let factor = spd_factor(n as usize);
    let factor = Flops {
        sqrt: factor.sqrt - n,
        ..factor
    };
    factor + Flops::new(n * (n - 1) + n, n * (n - 1))
}

/// The factor `L` of `cholesky::spd_inverse`: for each column the pivot, its
/// root's reciprocal and the column below it.
fn spd_factor(n: usize) -> Flops {
    let mut total = Flops::new(0, 0);
    for j in 0..n as u64 {
        total += Flops::new(j, j)
            + Flops {
                div: 1,
                sqrt: 1,
                ..Flops::new(0, 0)
            };
        total += Flops::new(j + 1, j) * (n as u64 - 1 - j);
    }
    total
}

/// `axis_rotation` (nalgebra's `Rotation3::from_axis_angle`), without its `sin_cos`: as written
/// 24 m + 13 a, but the repeated products `u_i u_j (1 − c)` and `u_k s` are computed once.
pub const AXIS_ROTATION: Flops = Flops::new(15, 13);
/// `quaternion_rotation`: `σ = 2 / |q|²` (4 m + 3 a, a division), `σx, σy, σz` (3 m), the nine
/// products `wσx … zσz` (9 m), then the nine entries (12 a).
pub const QUATERNION_ROTATION: Flops = Flops {
    mul: 4 + 3 + 9,
    add: 3 + 12,
    div: 1,
    sqrt: 0,
    sincos: 0,
};

/// `check_q`: the squared norm of every floating joint's quaternion (4 m + 3 a), after `q`'s
/// finiteness ([`all_finite`]).
pub(crate) fn check_q(model: &Model) -> Flops {
    let floating = model
        .bodies
        .iter()
        .filter(|b| b.joint.kind == JointKind::Floating && !b.joint.is_mimic())
        .count() as u64;
    all_finite(model.nq as u64) + Flops::new(4, 3) * floating
}

/// `validate::all_finite` on `n` values: `x · 0` for each, summed into four lanes that start
/// at 0, and the lanes joined, `(l₀ + l₁) + (l₂ + l₃)`; a join of two lanes that were never
/// added to (`0 + 0`) is folded.
pub(crate) fn all_finite(n: u64) -> Flops {
    let lanes = n.min(4);
    let joins = match lanes {
        0 => 0,
        1 | 2 => 2,
        _ => 3,
    };
    Flops::new(n, n + joins)
}

/// `Motion::is_finite`: `ω · 0 + v · 0` and its three components summed.
pub const MOTION_FINITE: Flops = Flops::new(6, 5);

/// `update_joints`: every joint's coordinates, [`SIN_COS`] for each body of the plan's turning
/// range (`Plan::turning`, from the first revolute joint about a coordinate axis to the last:
/// one branch-free loop, on a turn angle of 0 for a body between them that has none), and each
/// joint's transform: `jcalc_up` without its `sin_cos`, or for a revolute joint about a
/// coordinate axis whose placement has no rotation (`UpShape::AxisTurn`) its turn angle and
/// `model::turn_up_unrotated`, which computes nothing.
pub(crate) fn joints(model: &Model, plan: &Plan) -> Flops {
    let mut total = SIN_COS * plan.turning.len() as u64;
    for body in &model.bodies {
        // The joint's coordinates `scale · q + offset` (the identity map unless mimic; still
        // computed), then its transform.
        let kind = &body.joint.kind;
        let nq = kind.nq() as u64;
        let transform = match kind.up_shape(&body.x_tree) {
            UpShape::AxisTurn(_) => turn_angle(kind),
            _ => turn_angle(kind) + jcalc_up_turned(kind),
        };
        total += Flops::new(nq, nq) + transform;
    }
    total
}

/// One call of libm's `sin_cos` (in nalgebra's axis rotation), counted apart.
const SINCOS: Flops = Flops {
    sincos: 1,
    ..Flops::new(0, 0)
};

/// `spatial::sin_cos` for one angle: the reduction (4 m + 13 a with its two-sum and tail),
/// `y²`, `y²/2`, `z²`, `z⁴` (4 m), the two kernels by Estrin's scheme (7 m + 7 a each) and
/// their assembly with the tail (`1 − z/2` once, 1 a; 3 m + 2 a for `sin`, 2 m + 5 a for
/// `cos`).
pub const SIN_COS: Flops = Flops::new(27, 35);

/// `JointKind::jcalc_up` for a joint of kind `kind`: its turn angle, `spatial::sin_cos` of it,
/// and `jcalc_up_turned` (libm's `sin_cos` for an axis rotation in `sincos`).
pub fn jcalc_up(kind: &JointKind) -> Flops {
    turn_angle(kind) + SIN_COS + jcalc_up_turned(kind)
}

/// `JointKind::turn_angle`: `σ q` for a revolute joint about a coordinate axis, else nothing.
fn turn_angle(kind: &JointKind) -> Flops {
    match kind {
        JointKind::Revolute { axis } | JointKind::Continuous { axis }
            if is_coordinate_axis(axis) =>
        {
            Flops::new(1, 0)
        }
        _ => Flops::default(),
    }
}

/// `JointKind::jcalc_up_turned` given the turn's sine and cosine.
fn jcalc_up_turned(kind: &JointKind) -> Flops {
    match kind {
        JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
            if is_coordinate_axis(axis) {
                Flops::new(12, 6) // two rows of E_tree mixed
            } else {
                SINCOS + AXIS_ROTATION + COMPOSE
            }
        }
        JointKind::Prismatic { .. } => Flops::new(12, 9),
        JointKind::Floating => QUATERNION_ROTATION + COMPOSE,
        // E = rot(θ)ᵀ, S's columns E u and E w, the origin u x + w y.
        JointKind::Planar { .. } => {
            SINCOS + AXIS_ROTATION + MAT3_VEC3 * 2 + Flops::new(6, 3) + COMPOSE
        }
    }
}

fn is_coordinate_axis(axis: &crate::spatial::Vector3) -> bool {
    let zeros = axis.iter().filter(|x| **x == 0.0).count();
    zeros == 2 && axis.iter().any(|x| x.abs() == 1.0)
}

/// `JointKind::bias`, `c_J`; computed (and then added where it is used) only for a planar
/// joint: rotation, `E (u ẋ + w ẏ)`, cross product and scale.
pub fn joint_bias(kind: &JointKind) -> Flops {
    match kind {
        JointKind::Planar { .. } => {
            SINCOS + AXIS_ROTATION + Flops::new(6, 3) + MAT3_VEC3 + CROSS3 + Flops::new(3, 0)
        }
        _ => Flops::default(),
    }
}

/// `kinematics::update_world_axes`: each column of `S` into world coordinates, a row of the
/// rotation for a coordinate axis, a general transform otherwise.
pub(crate) fn world_axes(kind: &JointKind) -> Flops {
    let axes = kind.subspace_axes();
    let mut total = Flops::default();
    for axis in &axes[..kind.nv()] {
        total += match axis {
            Some((j, _)) if *j < 3 => WORLD_TURN_AXIS,
            Some(_) => WORLD_SLIDE_AXIS,
            None => TRANSFORM_VECTOR,
        };
    }
    total
}

/// `c_J` computed, moved by `moved` and added to a 6-vector, for the kinds that have one.
pub(crate) fn bias_added(kind: &JointKind, moved: Flops) -> Flops {
    match kind {
        JointKind::Planar { .. } => joint_bias(kind) + moved + ADD6,
        _ => Flops::default(),
    }
}

/// `rnea_passes` with velocities (`with_v`) and accelerations (`with_a`) given.
pub(crate) fn rnea_passes(model: &Model, with_v: bool, with_a: bool) -> Flops {
    // a_0 = a_base − [0; g] (the angular part is 0 − 0 for the externals the kernels take, which
    // the compiler folds).
    let mut total = Flops::new(0, 3);
    for body in &model.bodies {
        let nv = body.joint.kind.nv() as u64;
        let (transform, _, _) = up_transform(body);
        match unit_axis(&body.joint.kind) {
            // S = σ e_j: σ μ, its products with q̇ and q̈, one component of v_i and one of a_i
            // added to, and rate · (v_i ×̂ e_j): four products, two for a slide
            Some(j) => {
                let rates = 1 + u64::from(with_v) + u64::from(with_a);
                let cross = if j < 3 { 4 } else { 2 };
                total += transform * 2 + Flops::new(rates + cross, 2 + cross);
            }
            // v_i = X v_λ + v_J;  a_i = X a_λ + v_i ×̂ v_J (+ c_J, planar only)
            None => {
                if with_v {
                    total += SUBSPACE_COLUMN * nv + bias_added(&body.joint.kind, Flops::default());
                }
                total += transform + ADD6;
                total += transform + CROSS6 + ADD6;
                if with_a {
                    total += SUBSPACE_COLUMN * nv + ADD6;
                }
            }
        }
        // f_i = I a_i + v_i ×* I v_i
        total += INERTIA_APPLY * 2 + CROSS6 + ADD6;
    }
    total + inward_pass(model)
}

/// `j` when the joint's `S` is the one signed unit vector `σ e_j` of `[ω; v]` (a revolute or
/// prismatic joint along a coordinate axis): the passes of `algorithms::rnea` then read and
/// write one component.
fn unit_axis(kind: &JointKind) -> Option<usize> {
    match (kind.nv(), kind.subspace_axes()[0]) {
        (1, Some((j, _))) => Some(j),
        _ => None,
    }
}

/// `inward_pass`: `τ_i = S_iᵀ f_i` (scaled, accumulated), `f_λ += Xᵀ f_i`.
pub(crate) fn inward_pass(model: &Model) -> Flops {
    let mut total = Flops::default();
    for body in &model.bodies {
        total += match unit_axis(&body.joint.kind) {
            // τ += (σ μ) f_j
            Some(_) => Flops::new(2, 1),
            None => (DOT6 + Flops::new(1, 1)) * body.joint.kind.nv() as u64,
        };
        if body.parent.is_some() {
            total += up_transform(body).0 + ADD6;
        }
    }
    total
}

/// What body `i`'s `ⁱX_λ` costs on a 6-vector, on a rigid inertia and composed with a placement,
/// in the form the passes use for its joint (`kinematics::with_up_transform`,
/// [`JointKind::up_shape`]).
pub(crate) fn up_transform(body: &Body) -> (Flops, Flops, Flops) {
    match body.joint.kind.up_shape(&body.x_tree) {
        UpShape::General => (TRANSFORM_VECTOR, TRANSFORM_INERTIA, COMPOSE),
        UpShape::Translation => (TRANSLATE_VECTOR, TRANSLATE_INERTIA, TRANSLATE_COMPOSE),
        UpShape::AxisTurn(_) => (AXIS_TURN_VECTOR, AXIS_TURN_INERTIA, AXIS_TURN_COMPOSE),
    }
}

/// `gravity_passes`: `a_i = E a_λ`, `f_i = [h × a; m a]`, then the inward pass.
pub(crate) fn gravity_passes(model: &Model) -> Flops {
    (MAT3_VEC3 + CROSS3 + Flops::new(3, 0)) * model.nbodies() as u64 + inward_pass(model)
}

/// `update_placements`: one `compose` per body below the root.
pub(crate) fn placements(model: &Model) -> Flops {
    let below_roots = model.bodies.iter().filter(|b| b.parent.is_some());
    below_roots
        .map(|b| up_transform(b).2)
        .fold(Flops::default(), Add::add)
}

/// CRBA's passes in world coordinates (`general_path`: the model's subtrees are not contiguous,
/// [`Plan::subtree_end`](crate::plan::Plan::subtree_end) is `None`): world placements, inertias and axes; `F = I^c S` per
/// coordinate; one `S_jᵀ F` per entry of `H`'s upper triangle in the tree pattern (counted
/// along each coordinate's ancestors) and its finiteness probe; composite inertias added into
/// the parents.
pub fn crba_world(model: &Model, general_path: bool) -> Flops {
    let mut total = placements(model);
    for body in &model.bodies {
        let nv = body.joint.kind.nv() as u64;
        total += TRANSFORM_INERTIA + world_axes(&body.joint.kind) + INERTIA_APPLY * nv;
        if body.parent.is_some() {
            total += INERTIA_ADD;
        }
    }
    // One product per entry in the pattern (own block and one block per ancestor).
    let entries = pattern_entries(model);
    total += DOT6 * entries;
    if general_path {
        // The general path scales every entry by μ_i μ_j (two multiplications) and adds it, an
        // entry off the diagonal to both of its places.
        let diagonal: u64 = model.bodies.iter().map(|b| b.joint.kind.nv() as u64).sum();
        total += Flops::new(2, 1) * entries + Flops::new(0, entries - diagonal);
    } else {
        total += row_probes(model, entries);
    }
    total
}

/// CRBA's passes in body coordinates (row blocks only): for each body, `F = I^c S` per column
/// (`σ I e_j` for a column that is an axis: entries of `Ī`, `h` and `m` and the sign, 6 m),
/// its rows `S_kᵀ F_c` over its subtree's columns
/// (`σ F_j`, one multiplication, for an axis; a floating joint's six rows are the forces as
/// they are, its diagonal block written in full) and their finiteness probe, then each of those
/// forces `Xᵀ F` and its composite inertia `Xᵀ I X` moved to the parent and added.
pub fn crba_local(model: &Model) -> Flops {
    let mut subtree_nv: Vec<u64> = model
        .bodies
        .iter()
        .map(|b| b.joint.kind.nv() as u64)
        .collect();
    for (i, body) in model.bodies.iter().enumerate().rev() {
        if let Some(p) = body.parent {
            subtree_nv[p] += subtree_nv[i];
        }
    }
    let probe = Flops::new(1, 1);
    let mut total = Flops::default();
    for (i, body) in model.bodies.iter().enumerate() {
        let axes = body.joint.kind.subspace_axes();
        for (k, axis) in axes[..body.joint.kind.nv()].iter().enumerate() {
            let (force, entry) = match axis {
                Some(_) => (Flops::new(6, 0), Flops::new(1, 0)),
                None => (INERTIA_APPLY, DOT6),
            };
            total += force;
            if body.joint.kind != JointKind::Floating {
                // The row's entries, and its probe added into the body's.
                total += (entry + probe) * (subtree_nv[i] - k as u64) + Flops::new(0, 1);
            }
        }
        if body.joint.kind == JointKind::Floating {
            total += probe * (6 * subtree_nv[i]);
        }
        // The body's probe added into the total.
        total += Flops::new(0, 1);
        if body.parent.is_some() {
            let (vector, inertia, _) = up_transform(body);
            total += vector * subtree_nv[i] + inertia + INERTIA_ADD;
        }
    }
    total
}

/// The row blocks' finiteness probe: `0·H_rc` added up for each of the `entries`, then each
/// row's sum added into its body's and each body's into the total.
fn row_probes(model: &Model, entries: u64) -> Flops {
    Flops::new(1, 1) * entries + Flops::new(0, (model.nv + model.nbodies()) as u64)
}

/// Entries of `H`'s upper triangle (with the diagonal) that the tree's sparsity allows: for
/// each body, its own block and one block for the coordinates of all its ancestors.
fn pattern_entries(model: &Model) -> u64 {
    let mut ancestor_nv = vec![0; model.nbodies()];
    let mut count = 0;
    for (i, body) in model.bodies.iter().enumerate() {
        let nv = body.joint.kind.nv() as u64;
        if let Some(p) = body.parent {
            ancestor_nv[i] = ancestor_nv[p] + model.bodies[p].joint.kind.nv() as u64;
        }
        count += nv * (nv + 1) / 2 + nv * ancestor_nv[i];
    }
    count
}

/// `cholesky_factor` and `cholesky_solve` on a dense `n × n` matrix.
pub(crate) fn dense_cholesky(n: u64) -> Flops {
    let mut total = Flops::default();
    for j in 0..n {
        // Pivot, then the column below it.
        total += Flops {
            sqrt: 1,
            ..Flops::new(j, j)
        };
        total += Flops {
            div: n - j - 1,
            ..Flops::new(j * (n - j - 1), j * (n - j - 1))
        };
    }
    // Forward and back substitution.
    total
        + Flops {
            div: 2 * n,
            ..Flops::new(n * (n - 1), n * (n - 1))
        }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::algorithms::crba;
    use crate::model::examples;
    use crate::urdf::model_from_str;
    use crate::{ModelOptions, Workspace};

    /// An unbranched chain of `n` revolute joints (the example pendulum, unit lengths and
    /// masses).
    pub(crate) fn chain(n: usize) -> Model {
        model_from_str(
            &examples::pendulum_urdf(n, 1.0, 1.0),
            &ModelOptions::default(),
        )
        .unwrap()
    }

    /// The number of `S_jᵀ F` products CRBA is charged for (walking bodies to the root) is the
    /// number of coordinate pairs `(j, k)` with `j = k` or `j` an ancestor of `k` (walking `λ`
    /// over coordinates), and no entry of a computed `H` outside those pairs is non-zero (CRBA
    /// writes only the pattern, so this also checks that the other writer of `H` leaves zeros).
    #[test]
    fn crba_dot_products_match_the_pattern_of_h() {
        let text = examples::DEFAULT_ARM_URDF;
        for floating in [false, true] {
            let options = ModelOptions {
                floating_base: floating,
                ..ModelOptions::default()
            };
            for model in [model_from_str(text, &options).unwrap(), chain(5)] {
                let lambda = model.dof_parent.as_ref().unwrap();
                let ancestors = |k: usize| std::iter::successors(lambda[k], |&i| lambda[i]);
                let pairs: u64 = (0..model.nv).map(|k| 1 + ancestors(k).count() as u64).sum();
                assert_eq!(pattern_entries(&model), pairs);
                let mut ws = Workspace::new(&model);
                let mut q: Vec<f64> = (0..model.nq).map(|i| 0.3 + 0.1 * i as f64).collect();
                for j in model.coordinate_joints() {
                    if *j.kind == JointKind::Floating {
                        q[j.q_index + 3..j.q_index + 7].copy_from_slice(&[0.1, 0.2, 0.3, 0.9]);
                    }
                }
                // The n+1-RNEA method writes all of H into the same workspace first.
                let v = vec![0.5; model.nv];
                let ext = crate::Externals::none();
                let method = crate::ForwardDynamicsMethod::RneaColumns;
                crate::algorithms::forward_dynamics(&model, &mut ws, &q, &v, &v, method, &ext)
                    .unwrap();
                let h = crba(&model, &mut ws, &q).unwrap();
                for c in 0..model.nv {
                    for r in 0..c {
                        if !ancestors(c).any(|a| a == r) {
                            assert_eq!(h[(r, c)], 0.0, "H[{r}, {c}] outside the pattern");
                        }
                    }
                }
            }
        }
    }
}
