//! Body frames turned so that joint placements lose their rotation.
//!
//! Many descriptions place each joint by quarter turns about the parent's axes (Denavit–Hartenberg
//! style, `rpy="±π/2 0 0"`: Panda, KUKA iiwa, Kinova), so `E_tree` is a signed permutation `P`
//! and every move between bodies pays for a general rotation. A body's frame may be any frame
//! fixed to it, so the model turns it: body `i`'s frame `i'` has the link frame's origin and
//! axes `Q_i` (`v_{i'} = Q_i v_i`). With the parent turned by `Q_λ`, the transform from the
//! parent's turned frame is
//!
//! ```text
//! ⁱ'X_λ' = rot(Q_i) · X_J(q; a) · rot(E) xlt(r) · rot(Q_λ)ᵀ = rot(Q_i E_J(q; a) M) xlt(Q_λ r),
//!          M = E Q_λᵀ,
//! ```
//!
//! and with `Q_i = Mᵀ` (a signed permutation when `E` is one), `Mᵀ E_J(q; a) M = E_J(q; Mᵀ a)`:
//! the placement becomes `xlt(Q_λ r)` and the joint turns about (or slides along) `a' = Q_i a`,
//! a coordinate axis when `a` is one ([`UpShape`](super::UpShape)`::AxisTurn` and
//! `Translation`). A revolute joint can also absorb a turn about its own axis into its angle,
//! `E_J(q; a) E_J(γ; a) = E_J(q + γ; a)`: whenever `Mᵀ a` is a coordinate axis `a'`, a signed
//! permutation `Q_i = P` with `P a = a'` leaves `P M = E_J(γ; a')`, and the joint's coordinate
//! map adds `γ` to its angle (`CoordinateMap::offset`). UR5 places its shoulder-lift and
//! wrist-1 joints turned by `1.57079632679` about their own `y` axes: no rotation is left.
//!
//! The body's inertia is expressed in the turned frame, `I' = ⁱX_i'ᵀ I ⁱX_i'` with
//! `ⁱX_i' = rot(Q_iᵀ)`, and every link frame carried by the body is placed from it,
//! `ˡX_i' = ˡX_i rot(Q_i)ᵀ`, so nothing a user names (link frames, joint coordinates, efforts)
//! changes.
//!
//! A placement is taken as a quarter-turn composition when each entry of `E` is within
//! [`QUARTER_TURN_TOLERANCE`] of 0 or ±1: `rpy="1.5707963267948966 0 0"` (π/2 rounded to a
//! double) gives `cos = 6.1e-17`, which becomes 0 (a turn changed by 6e-17 rad, below the unit
//! roundoff of the model's own numbers); `1.57079632679` (entries 5e-12) stays a general
//! rotation (unless it turns about the joint's own axis). A slide no body hangs from (a
//! gripper's finger) turns by `Q_i = Mᵀ` whatever `M`: its `E_J = 1`, so `Mᵀ E_J M = 1` exactly
//! in arithmetic, and only its axis `a' = Mᵀ a` and inertia carry the turn (to rounding). Only
//! revolute, continuous and prismatic joints turn their body: a planar joint's and the floating
//! base's coordinates are expressed in their own frames (their placements still absorb the
//! parent's `Q_λ`).

use super::{JointKind, Model};
use crate::spatial::{Matrix3, Transform, Vector3};

/// How far an entry of a placement's rotation may be from 0 or ±1 for the rotation to be taken
/// as a composition of quarter turns (eight unit roundoffs).
const QUARTER_TURN_TOLERANCE: f64 = 4.0 * f64::EPSILON;

/// Turns each body's frame by `Q_i` (module doc) so that quarter-turn placements of joints
/// along coordinate axes, placements of revolute joints that turn about the joint's axis after
/// quarter turns (the turn moved into the joint's angle), and any placement of a slide nothing
/// hangs from, become pure translations; the model's dynamics, joint coordinates and link
/// frames are unchanged.
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
        // ⁱ'X_λ' = rot(Q_i E_J M) xlt(Q_λ r), M = E Q_λᵀ: the turn `Q_i` and the angle `γ` it
        // leaves to the joint, if any, take all the rotation out of the placement.
        let m = body.x_tree.rot * q_parent.transpose();
        let turn = body_turn(&body.joint.kind, &m, is_leaf[i]);
        body.x_tree = Transform {
            rot: match turn {
                Some(_) => Matrix3::identity(),
                None => m,
            },
            trans: q_parent * body.x_tree.trans,
        };
        let (q_i, angle) = turn.unwrap_or((Matrix3::identity(), 0.0));
        body.joint.coords.offset += angle;
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

/// The turn `Q_i` of a body whose joint is placed by `M` (seen from the parent's turned frame),
/// and the angle `γ` it adds to a revolute joint's coordinate, when they leave the placement no
/// rotation: for a joint about or along a coordinate axis, `Q_i = Mᵀ` when `M` is a composition
/// of quarter turns; for a revolute joint, also whenever `Mᵀ a` is a coordinate axis
/// ([`turn_about_axis`]); for a slide nothing hangs from, `Q_i = Mᵀ` whatever `M` (its `E_J = 1`;
/// a body below would inherit a general turn).
fn body_turn(kind: &JointKind, m: &Matrix3, is_leaf: bool) -> Option<(Matrix3, f64)> {
    let quarter = || quarter_turns(m).map(|p| (p.transpose(), 0.0));
    match *kind {
        JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
            kind.subspace_axes()[0]?;
            quarter().or_else(|| turn_about_axis(m, &axis))
        }
        JointKind::Prismatic { .. } => match quarter() {
            Some(turn) if kind.subspace_axes()[0].is_some() => Some(turn),
            _ => is_leaf.then(|| (m.transpose(), 0.0)),
        },
        JointKind::Planar { .. } | JointKind::Floating => None,
    }
}

/// `Some((P, γ))` for a revolute joint about the coordinate axis `a` placed by `M` when
/// `Mᵀ a` is within [`QUARTER_TURN_TOLERANCE`] of a coordinate axis `a'`: `P` is the composition
/// of quarter turns with `P a = a'` that leaves the smallest angle `γ`, `M P = E_J(γ; a)` (to
/// rounding). With `Q_i = P`, `Q_i E_J(q; a) M = E_J(q; a') P M = E_J(q; a') E_J(γ; a') =
/// E_J(q + γ; a')`: the placement keeps its translation only and the joint turns by `q + γ`. A
/// placement turned about the joint's own axis (UR5's shoulder and wrist, `rpy="0 1.57079632679
/// 0"` about `y`) is the case `P = 1`.
fn turn_about_axis(m: &Matrix3, axis: &Vector3) -> Option<(Matrix3, f64)> {
    let turned = m.tr_mul(axis);
    let a_turned = turned.map(|x| x.round());
    if (turned - a_turned).amax() > QUARTER_TURN_TOLERANCE || a_turned.abs().sum() != 1.0 {
        return None;
    }
    let p = rotations_by_quarter_turns()
        .filter(|p| p * axis == a_turned)
        .max_by(|p, r| (m * p).trace().total_cmp(&(m * r).trace()))?;
    // `E_J(γ; a) = rot(a, γ)ᵀ`, so `R = (M P)ᵀ = rot(a, γ)`: `R − Rᵀ = 2 sin γ [a]×` and
    // `tr R = 1 + 2 cos γ`.
    let r = (m * p).transpose();
    let skew = r - r.transpose();
    let sin = axis.dot(&Vector3::new(skew[(2, 1)], skew[(0, 2)], skew[(1, 0)])) / 2.0;
    let cos = (r.trace() - 1.0) / 2.0;
    Some((p, sin.atan2(cos)))
}

/// The 24 rotations that are signed permutations (the quarter-turn compositions).
fn rotations_by_quarter_turns() -> impl Iterator<Item = Matrix3> {
    const ORDERS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    ORDERS.into_iter().flat_map(|order| {
        (0..8).filter_map(move |signs: u32| {
            let mut p = Matrix3::zeros();
            for (row, col) in order.into_iter().enumerate() {
                p[(row, col)] = if signs >> row & 1 == 1 { -1.0 } else { 1.0 };
            }
            (p.determinant() == 1.0).then_some(p)
        })
    })
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

    const URDF: &str = include_str!("../tests/models/quarter_turns.urdf");

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
            // j7 turns by 1.57079632679 (not a quarter turn, not about its own axis), j8 about a
            // non-coordinate axis; j9 and j10 turn about their own axes (the angle moves into the
            // joint's coordinate), j11 below them keeps a coordinate axis.
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

    /// A mimic follower whose placement turns about its own axis: the turn goes into its
    /// coordinate map's offset (after the mimic's own), the description's `<mimic>` is kept as
    /// written, the placement loses its rotation, and `τ` equals the unturned model's.
    #[test]
    fn a_mimic_follower_turned_about_its_axis_keeps_its_mimic() {
        let urdf = r#"<robot name="m">
  <link name="a"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="lead" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <link name="b"><inertial><origin xyz="0.1 0.02 0"/><mass value="0.8"/><inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.02" iyz="0" izz="0.015"/></inertial></link>
  <joint name="follow" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0" rpy="0 0.9 0"/><axis xyz="0 1 0"/><mimic joint="lead" multiplier="-0.5" offset="0.25"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <link name="c"><inertial><origin xyz="0 0.03 0.1"/><mass value="0.5"/><inertia ixx="0.004" ixy="0" ixz="0.0005" iyy="0.005" iyz="0" izz="0.003"/></inertial></link>
</robot>"#;
        let options = ModelOptions::default();
        let builder = builder_from_str(urdf).unwrap();
        let (turned, plain) = (
            builder.build(&options).unwrap(),
            builder.build_in_link_frames(&options).unwrap(),
        );
        let follower = &turned.bodies[1];
        let mimic = follower.joint.mimics.as_ref().unwrap();
        assert_eq!(
            (mimic.leader.as_str(), mimic.multiplier, mimic.offset),
            ("lead", -0.5, 0.25)
        );
        assert_eq!(follower.joint.coords.scale, -0.5);
        // The placement turns by 0.9 about y; the quarter turn about y leaves the smaller
        // angle, 0.9 − π/2, to the joint.
        let offset = follower.joint.coords.offset;
        let expected = 0.25 + (0.9 - std::f64::consts::FRAC_PI_2);
        assert!((offset - expected).abs() < 1e-15, "offset {offset}");
        assert_eq!(follower.x_tree.rot, Matrix3::identity());
        let (mut ws_t, mut ws_p) = (Workspace::new(&turned), Workspace::new(&plain));
        for q in [0.0, 0.7, -1.3] {
            let tau_t = rnea(&turned, &mut ws_t, &[q], &[0.4], &[-1.1]).unwrap()[0];
            let tau_p = rnea(&plain, &mut ws_p, &[q], &[0.4], &[-1.1]).unwrap()[0];
            assert!(
                (tau_t - tau_p).abs() < 1e-13 * (1.0 + tau_p.abs()),
                "τ {tau_t} vs {tau_p}"
            );
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
