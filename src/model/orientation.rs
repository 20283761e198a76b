//! Body frames turned so that quarter-turn joint placements lose their rotation.
//!
//! Many descriptions place each joint by quarter turns about the parent's axes (Denavit–Hartenberg
//! style, `rpy="±π/2 0 0"`: Panda, KUKA iiwa, Kinova), so `E_tree` is a signed permutation `P`
//! and every move between bodies pays for a general rotation. A body's frame may be any frame
//! fixed to it, so the model turns it: body `i`'s frame `i'` has the link frame's origin and
//! axes `Q_i` (`v_{i'} = Q_i v_i`, `Q_i` a signed permutation). With the parent turned by
//! `Q_λ`, the transform from the parent's turned frame is
//!
//! ```text
//! ⁱ'X_λ' = rot(Q_i) · X_J(q; a) · rot(E) xlt(r) · rot(Q_λ)ᵀ = rot(Q_i E_J(q; a) M) xlt(Q_λ r),
//!          M = E Q_λᵀ,
//! ```
//!
//! and with `Q_i = Mᵀ` (a signed permutation when `E` is one), `Mᵀ E_J(q; a) M = E_J(q; Mᵀ a)`:
//! the placement becomes `xlt(Q_λ r)` and the joint turns about (or slides along) `a' = Q_i a`,
//! a coordinate axis when `a` is one ([`UpShape`](super::UpShape)`::AxisTurn` and
//! `Translation`). The body's inertia is expressed in the turned frame, `I' = ⁱX_i'ᵀ I ⁱX_i'` with
//! `ⁱX_i' = rot(Q_iᵀ)`, and
//! every link frame carried by the body is placed from it, `ˡX_i' = ˡX_i rot(Q_i)ᵀ`, so nothing
//! a user names (link frames, joint coordinates, efforts) changes.
//!
//! A placement is taken as a quarter-turn composition when each entry of `E` is within
//! [`QUARTER_TURN_TOLERANCE`] of 0 or ±1: `rpy="1.5707963267948966 0 0"` (π/2 rounded to a
//! double) gives `cos = 6.1e-17`, which becomes 0 (a turn changed by 6e-17 rad, below the unit
//! roundoff of the model's own numbers); `1.57079632679` (entries 5e-12) stays a general
//! rotation. A slide no body hangs from (a gripper's finger) turns by `Q_i = Mᵀ` whatever `M`:
//! its `E_J = 1`, so `Mᵀ E_J M = 1` exactly in arithmetic, and only its axis `a' = Mᵀ a` and
//! inertia carry the turn (to rounding). Only revolute, continuous and prismatic joints turn
//! their body: a planar joint's and the floating base's coordinates are expressed in their own
//! frames (their placements still absorb the parent's `Q_λ`).

use super::{JointKind, Model};
use crate::spatial::{Matrix3, Transform};

/// How far an entry of a placement's rotation may be from 0 or ±1 for the rotation to be taken
/// as a composition of quarter turns (eight unit roundoffs).
const QUARTER_TURN_TOLERANCE: f64 = 4.0 * f64::EPSILON;

/// Turns each body's frame by `Q_i` (module doc) so that quarter-turn placements of joints
/// along coordinate axes, and any placement of a slide nothing hangs from, become pure
/// translations; the model's dynamics, joint coordinates and link frames are unchanged.
pub(super) fn orient_bodies(model: &mut Model) {
    let mut is_leaf = vec![true; model.bodies.len()];
    for body in &model.bodies {
        if let Some(p) = body.parent {
            is_leaf[p] = false;
        }
    }
    let mut turns: Vec<Matrix3> = Vec::with_capacity(model.bodies.len());
    for (i, body) in model.bodies.iter_mut().enumerate() {
        let q_parent = body.parent.map_or(Matrix3::identity(), |p| turns[p]);
        let e = body.x_tree.rot;
        let snapped = quarter_turns(&e).filter(|_| turns_along_axis(&body.joint.kind));
        // ⁱ'X_λ' = rot(Q_i E_J M) xlt(Q_λ r), M = E Q_λᵀ: with Q_i = Mᵀ no rotation is left.
        // A slide's E_J = 1, so any M leaves with Q_i = Mᵀ (its axis a' = Mᵀ a need then be no
        // coordinate axis); only a leaf takes a general turn, which a body below would inherit.
        let turn = match (snapped, body.joint.kind) {
            (Some(p), _) => Some((p * q_parent.transpose()).transpose()),
            (None, JointKind::Prismatic { .. }) if is_leaf[i] => {
                Some((e * q_parent.transpose()).transpose())
            }
            _ => None,
        };
        body.x_tree = Transform {
            rot: match turn {
                Some(_) => Matrix3::identity(),
                None => e * q_parent.transpose(),
            },
            trans: q_parent * body.x_tree.trans,
        };
        let q_i = turn.unwrap_or_else(Matrix3::identity);
        body.joint.kind = turned_kind(&body.joint.kind, &q_i);
        // Inertia in the turned frame: ⁱX_i' = rot(Q_iᵀ), I' = (ⁱX_i')ᵀ I ⁱX_i'.
        body.inertia = Transform::rotation(q_i.transpose()).transpose_apply_inertia(&body.inertia);
        turns.push(q_i);
    }
    for link in &mut model.links {
        if let Some(b) = link.body {
            link.x_body_link = link
                .x_body_link
                .compose(&Transform::rotation(turns[b].transpose()));
        }
    }
}

/// The joints whose placement may snap to quarter turns: one coordinate about or along a
/// coordinate axis (which the turned frame keeps a coordinate axis).
fn turns_along_axis(kind: &JointKind) -> bool {
    match kind {
        JointKind::Revolute { .. } | JointKind::Continuous { .. } | JointKind::Prismatic { .. } => {
            kind.subspace_axes()[0].is_some()
        }
        JointKind::Planar { .. } | JointKind::Floating => false,
    }
}

/// The joint seen from the turned frame: its axis `a' = Q a`.
fn turned_kind(kind: &JointKind, q: &Matrix3) -> JointKind {
    match *kind {
        JointKind::Revolute { axis } => JointKind::Revolute { axis: q * axis },
        JointKind::Continuous { axis } => JointKind::Continuous { axis: q * axis },
        JointKind::Prismatic { axis } => JointKind::Prismatic { axis: q * axis },
        other => other,
    }
}

/// `Some(P)` when every entry of the rotation `e` is within [`QUARTER_TURN_TOLERANCE`] of 0 or
/// ±1 and the rounded matrix `P` is a signed permutation with determinant +1.
fn quarter_turns(e: &Matrix3) -> Option<Matrix3> {
    let mut p = Matrix3::zeros();
    for (out, x) in p.iter_mut().zip(e.iter()) {
        let rounded = x.round();
        if (x - rounded).abs() > QUARTER_TURN_TOLERANCE {
            return None;
        }
        *out = rounded;
    }
    let signed_permutation = p.row_iter().all(|row| row.abs().sum() == 1.0)
        && p.column_iter().all(|col| col.abs().sum() == 1.0);
    (signed_permutation && p.determinant() == 1.0).then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::kinematics::body_placements;
    use crate::algorithms::rnea;
    use crate::model::UpShape;
    use crate::sampling::{random_q, Rng};
    use crate::urdf::builder_from_str;
    use crate::{ModelOptions, Workspace};

    const URDF: &str = include_str!("../../tests/models/quarter_turns.urdf");

    /// Turned body frames change nothing a user names: every link's world placement and `τ`
    /// equal those of the model in link frames, and each quarter-turn placement of a joint along
    /// a coordinate axis (and the fingers' slides) lost its rotation. (`q̈`, `H` and `g` on this
    /// model are checked against Pinocchio in `tests/python/test_pinocchio_reference.py`.)
    #[test]
    fn turned_frames_keep_link_placements_and_torques() {
        for floating_base in [false, true] {
            let options = ModelOptions {
                floating_base,
                ..ModelOptions::default()
            };
            let builder = builder_from_str(URDF).unwrap();
            let turned = builder.build(&options).unwrap();
            let plain = builder.build_in_link_frames(&options).unwrap();
            let shapes = |m: &Model| -> Vec<(String, UpShape)> {
                let b = &m.bodies;
                b.iter()
                    .map(|b| (b.joint.name.clone(), b.joint.kind.up_shape(&b.x_tree)))
                    .collect()
            };
            let general = |m: &Model| -> Vec<String> {
                let s = shapes(m).into_iter();
                s.filter(|(_, s)| *s == UpShape::General)
                    .map(|(n, _)| n)
                    .collect()
            };
            // j7 turns by 1.57079632679 (not a quarter turn), j8 about a non-coordinate axis.
            let mut expected = vec!["j7".to_string(), "j8".to_string()];
            if floating_base {
                expected.insert(0, "root_joint".to_string());
            }
            assert_eq!(general(&turned), expected);
            assert!(general(&plain).len() > expected.len() + 5);

            let (mut ws_t, mut ws_p) = (Workspace::new(&turned), Workspace::new(&plain));
            let mut rng = Rng::new(11);
            for _ in 0..5 {
                let q = random_q(&turned, &mut rng);
                let (v, a) = (rng.vector(turned.nv, 2.0), rng.vector(turned.nv, 3.0));
                let tau_t = rnea(&turned, &mut ws_t, &q, &v, &a).unwrap().to_vec();
                let tau_p = rnea(&plain, &mut ws_p, &q, &v, &a).unwrap();
                for (x, y) in tau_t.iter().zip(tau_p) {
                    assert!((x - y).abs() < 1e-12 * (1.0 + y.abs()), "τ {x} vs {y}");
                }
                let world_t = body_placements(&turned, &mut ws_t, &q).unwrap().to_vec();
                let world_p = body_placements(&plain, &mut ws_p, &q).unwrap();
                for (lt, lp) in turned.links.iter().zip(&plain.links) {
                    assert_eq!(lt.name, lp.name);
                    let place = |l: &crate::model::LinkFrame, world: &[Transform]| match l.body {
                        Some(b) => l.x_body_link.compose(&world[b]),
                        None => l.x_body_link,
                    };
                    let (t, p) = (place(lt, &world_t), place(lp, world_p));
                    let err = (t.rot - p.rot).amax().max((t.trans - p.trans).amax());
                    assert!(err < 1e-14, "link {}: placement off by {err}", lt.name);
                }
            }
        }
    }

    /// π/2 rounded to a double turns by exactly a quarter; π/2 to 11 digits does not.
    #[test]
    fn only_rounded_quarter_turns_snap() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let turn = |angle: f64| crate::model::axis_rotation(&crate::spatial::Vector3::x(), angle);
        let snapped = quarter_turns(&turn(half_pi)).unwrap();
        assert_eq!(
            snapped,
            Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0)
        );
        assert!(turn(half_pi)[(1, 1)] != 0.0);
        // Baxter's and the test model's joint j7 write π/2 to 11 digits.
        let eleven_digits = "1.57079632679".parse().unwrap();
        assert!(quarter_turns(&turn(eleven_digits)).is_none());
        assert!(quarter_turns(&turn(0.3)).is_none());
        // A reflection is no rotation.
        assert!(quarter_turns(&Matrix3::from_diagonal_element(-1.0)).is_none());
    }
}
