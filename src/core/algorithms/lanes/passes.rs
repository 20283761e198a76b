//! RNEA on [`LANES`] states at once (handout eqs. 13–16; Featherstone, RBDA Table 5.1), for a
//! model whose every joint is revolute or prismatic ([`lane_column`]). The passes are
//! [`rnea`](crate::algorithms::rnea)'s, with each `f64` a lane value ([`Lanes`]):
//!
//! ```text
//! v_i = ⁱX_λ v_λ + S_i q̇_i                          (13)
//! a_i = ⁱX_λ a_λ + S_i q̈_i + v_i ×̂ S_i q̇_i          (14)
//! f_i = I_i a_i + v_i ×* I_i v_i                      (15, first part)
//! τ_i = S_iᵀ f_i                                      (16)
//! f_λ += ⁱX_λᵀ f_i                                    (15, second part)
//! ```
//!
//! with `v_0 = 0`, `a_0 = −g` and a mimic follower's `q̇_i = μ q̇_leader`, `q̈_i = μ q̈_leader`
//! (its `μ S_iᵀ f_i` added to the leader's `τ`). The joints' transforms are
//! `kinematics::update_joints`'s and act in the same cheaper forms
//! ([`with_lane_transform`]); the sines and cosines of the turn angles are the scalar
//! [`sin_cos_all`]'s, over every lane's angles in one call. Every operation is the scalar
//! kernel's, in its order: lane `ℓ`'s `τ` has the bits `rnea` gives on state `ℓ`.

use super::spatial::{with_lane_transform, LaneMotion, LaneSpatialTransform};
use super::value::{tr_mul, Lanes};
use super::LANES;
use crate::algorithms::rnea::along_axis;
use crate::model::{JointKind, Model, MotionSubspace, UpShape};
use crate::spatial::{sin_cos_all, Motion, Transform, Vector3};
use crate::Workspace;

/// The joint's `S` when the lane passes cover it, a revolute or prismatic joint (one degree of
/// freedom, `S` constant, no `c_J`): `Ok((j, σ))` for `S = σ e_j`, one signed unit vector of
/// `[ω; v]` (`Plan::s_axes`: about or along a coordinate axis; `S q̇`, `S q̈` and `Sᵀ f` are one
/// component, `rnea::along_axis`), `Err(S)` for any other axis (`rnea::joint_motion`). `None`
/// for a planar or floating joint.
pub(crate) fn lane_column(kind: &JointKind) -> Option<Result<(usize, f64), Motion>> {
    let column = match *kind {
        JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
            Motion::new(axis, Vector3::zeros())
        }
        JointKind::Prismatic { axis } => Motion::new(Vector3::zeros(), axis),
        _ => return None,
    };
    Some(kind.subspace_axes()[0].ok_or(column))
}

/// `τ` of the [`LANES`] states whose rows (`nq`, `nv` values each, consecutive) are `q`, `v`,
/// `a`, into `tau` (`nv` values a row), on a covered model ([`lane_column`]), inputs finite.
pub(crate) fn rnea_lanes(
    model: &Model,
    ws: &mut Workspace,
    q: &[f64],
    v: &[f64],
    a: &[f64],
    tau: &mut [f64],
) {
    update_joints(model, ws, q);
    // Compiled apart for models whose every `S` is a unit axis (most), without the test for a
    // general column at each body.
    if ws.lanes.any_general {
        forward_pass::<true>(model, ws, v, a);
        inward_pass::<true>(model, ws);
    } else {
        forward_pass::<false>(model, ws, v, a);
        inward_pass::<false>(model, ws);
    }
    for (k, t) in ws.lanes.tau.iter().enumerate() {
        t.scatter(tau, model.nv, k);
    }
}

/// `ws.lanes.x_up` for the configurations `q` (`kinematics::update_joints`): the turn angles
/// `σ (μ q + o)` of the joints of `Plan::turn_axes`, their sines and cosines, then the entries
/// of each `ⁱX_λ` that vary with `q` (the others were set with the scratch): a turn about
/// `e_k` mixes rows `I`, `J` of `E_tree` (`model::turn_up`), or for a placement without
/// rotation is `c`, `s` itself (`model::turn_up_unrotated`, read by the axis-turn form); a
/// slide along `axis` moves the origin to `r_tree + E_treeᵀ (axis q)`; a turn about another
/// axis is the scalar `jcalc_up_turned`'s, lane by lane.
fn update_joints(model: &Model, ws: &mut Workspace, q: &[f64]) {
    let Workspace { plan, lanes, .. } = ws;
    let nq = model.nq;
    for (i, (body, &axis)) in model.bodies.iter().zip(&plan.turn_axes).enumerate() {
        let c = body.joint.coords;
        for l in 0..LANES {
            let position = c.scale * q[l * nq + c.q_index] + c.offset;
            match axis {
                Some((_, sign)) => lanes.angles[i * LANES + l] = sign * position,
                None => lanes.positions[i].0[l] = position,
            }
        }
    }
    let turning = plan.turning.start * LANES..plan.turning.end * LANES;
    sin_cos_all(
        &lanes.angles[turning.clone()],
        &mut lanes.sines[turning.clone()],
        &mut lanes.cosines[turning],
    );
    let joints = model
        .bodies
        .iter()
        .zip(&plan.turn_axes)
        .zip(&plan.up_shapes);
    for (i, ((body, &axis), &shape)) in joints.enumerate() {
        let x_up = &mut lanes.x_up[i];
        let x_tree = &lanes.x_tree[i];
        match axis {
            Some((k, _)) => {
                let sin = Lanes::load(&lanes.sines[i * LANES..]);
                let cos = Lanes::load(&lanes.cosines[i * LANES..]);
                let (ri, rj) = ((k + 1) % 3, (k + 2) % 3);
                if let UpShape::AxisTurn(_) = shape {
                    (x_up.rot[ri][ri], x_up.rot[ri][rj]) = (cos, sin);
                } else {
                    let e = &x_tree.rot;
                    for col in 0..3 {
                        x_up.rot[ri][col] = cos * e[ri][col] + sin * e[rj][col];
                        x_up.rot[rj][col] = cos * e[rj][col] - sin * e[ri][col];
                    }
                }
            }
            None if matches!(body.joint.kind, JointKind::Prismatic { .. }) => {
                let moved = lanes.slide_axes[i].scale(lanes.positions[i]);
                x_up.trans = x_tree.trans + tr_mul(&x_tree.rot, &moved);
            }
            None => {
                // A turn about another axis: libm's sine and cosine inside nalgebra's rotation.
                let mut s = MotionSubspace::default();
                for (l, &angle) in lanes.positions[i].0.iter().enumerate() {
                    let mut x = Transform::identity();
                    let kind = &body.joint.kind;
                    // (0, 1): the sine and cosine only a turn about a coordinate axis reads
                    kind.jcalc_up_turned(&[angle], (0.0, 1.0), &body.x_tree, &mut s, &mut x);
                    x_up.set_lane(l, &x);
                }
            }
        }
    }
}

/// The outward pass (eqs. 13–15) into `ws.lanes.v`, `a`, `f`, rates and accelerations read
/// from the rows `v`, `a`.
fn forward_pass<const GENERAL: bool>(model: &Model, ws: &mut Workspace, v: &[f64], a: &[f64]) {
    let nv = model.nv;
    // a_0 = −a_g   (RBDA Table 5.1), the root at rest
    let a_root = Motion::zero() - Motion::new(Vector3::zeros(), model.gravity);
    let a_root = LaneMotion::splat(&a_root);
    let mut last = (LaneMotion::default(), LaneMotion::default());
    let Workspace { plan, lanes, .. } = ws;
    for (i, (body, &shape)) in model.bodies.iter().zip(&plan.up_shapes).enumerate() {
        let c = body.joint.coords;
        let (v_parent, a_parent) = match body.parent {
            Some(p) if p + 1 == i => last,
            Some(p) => (lanes.v[p], lanes.a[p]),
            None => (LaneMotion::default(), a_root),
        };
        let (v_up, a_up) = with_lane_transform!(shape: shape, x_up: &lanes.x_up[i], |x| (
            x.apply_motion(&v_parent),
            x.apply_motion(&a_parent)
        ));
        let (rate, accel) = (
            Lanes::gather(v, nv, c.v_index),
            Lanes::gather(a, nv, c.v_index),
        );
        // v_i = ⁱX_λ v_λ + S_i q̇_i,  a_i = ⁱX_λ a_λ + S_i q̈_i + v_i ×̂ S_i q̇_i   (13, 14)
        let general = if GENERAL {
            lanes.general[i].as_ref()
        } else {
            None
        };
        let (v_i, a_i) = match general {
            Some(s) => {
                let scale = Lanes::splat(c.scale);
                column_motion(s, rate * scale, accel * scale, v_up, a_up)
            }
            None => {
                // S_i = σ e_j: q̇_i and q̈_i scaled by σ μ (μ a mimic follower's multiplier)
                let (j, sign) = lanes.unit_axes[i];
                let k = Lanes::splat(sign * c.scale);
                along_axis(j, k * rate, k * accel, v_up, a_up)
            }
        };
        // f_i = I_i a_i + v_i ×* I_i v_i   (15)
        let inertia = &lanes.inertia[i];
        let f_i = inertia.apply(&a_i) + v_i.cross_force(&inertia.apply(&v_i));
        if lanes.read_later[i] {
            (lanes.v[i], lanes.a[i]) = (v_i, a_i);
        }
        lanes.f[i] = f_i;
        last = (v_i, a_i);
    }
}

/// The inward pass (eqs. 15–16) on `ws.lanes.f` into `ws.lanes.tau`: `τ_i = μ S_iᵀ f_i`,
/// `f_λ += ⁱX_λᵀ f_i`.
fn inward_pass<const GENERAL: bool>(model: &Model, ws: &mut Workspace) {
    let Workspace { plan, lanes, .. } = ws;
    lanes.tau.fill(Lanes::splat(0.0));
    let joints = model.bodies.iter().zip(&plan.up_shapes).enumerate();
    for (i, (body, &shape)) in joints.rev() {
        let (c, f_i) = (body.joint.coords, lanes.f[i]);
        // τ_i = S_iᵀ f_i   (16), a mimic follower's μ S_iᵀ f_i added to its leader's
        let general = if GENERAL {
            lanes.general[i].as_ref()
        } else {
            None
        };
        lanes.tau[c.v_index] += match general {
            Some(s) => Lanes::splat(c.scale) * s.dot(&f_i),
            None => {
                let (j, sign) = lanes.unit_axes[i];
                Lanes::splat(sign * c.scale) * f_i.component(j)
            }
        };
        if let Some(p) = body.parent {
            // f_λ(i) += λ(i)X*_i f_i   (15)
            let f_parent = with_lane_transform!(shape: shape, x_up: &lanes.x_up[i], |x| x
                .transpose_apply_force(&f_i));
            lanes.f[p] += f_parent;
        }
    }
}

/// `v_i = v_up + S q̇`, `a_i = a_up + v_i ×̂ S q̇ + S q̈` for one general column `S`, given
/// `rate = μ q̇` and `accel = μ q̈` (`rnea::joint_motion`; `S x` summed from zero, as
/// `MotionSubspace::apply` does). Out of line: rare, and it keeps the unit-axis loop tight.
#[inline(never)]
fn column_motion(
    s: &LaneMotion,
    rate: Lanes,
    accel: Lanes,
    v_up: LaneMotion,
    a_up: LaneMotion,
) -> (LaneMotion, LaneMotion) {
    let v_joint = LaneMotion::default() + s.scale(rate);
    let v_i = v_up + v_joint;
    let a_i = a_up + v_i.cross_motion(&v_joint);
    (v_i, a_i + (LaneMotion::default() + s.scale(accel)))
}
