//! A robot a kilometre from the world origin has the joint-space dynamics it has at the origin:
//! `τ`, `g`, `H` and `q̈` (by every method, alone and through `joint_state_outputs`) do not depend
//! on where the robot stands. Fixed bases are moved by their root joint's `<origin>`, floating
//! bases by the position coordinates of `q`, a pendulum on a rail by the rail's coordinate (a
//! joint below the root: the frames of the world-frame passes must follow its travel).
//! Spatial inertias about the world origin carry `m r²` terms that cancel in these quantities,
//! so a pass that works about the world origin loses about `log₁₀(r² / ℓ²)` digits (ℓ the
//! robot's size): 1e-7 relative error at 1 km.
//!
//! The centre-of-mass Jacobian and the frame Jacobians about a link's origin (`local`,
//! `local_world_aligned`) hold offsets between the robot's own points: taken as differences of
//! world positions they would lose `ε |p|` (1e-10 at 1000 km), so they are checked 1000 km out.

mod common;

use common::{max_diff, norm, pendulum_on_a_rail, random_q, Rng};
use spatial_dynamics_core::algorithms::{
    crba, forward_dynamics, gravity, joint_state_outputs, rnea, rnea_with, JointStateInputs,
    JointStateOutputs,
};
use spatial_dynamics_core::model::examples::{self, pendulum_urdf};
use spatial_dynamics_core::spatial::{Force, Motion, Vector3};
use spatial_dynamics_core::{
    urdf, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

const TREE: &str = include_str!("models/tree.urdf");

/// How far the robot is moved: about a kilometre along every axis.
const FAR: [f64; 3] = [1000.0, -700.0, 300.0];

fn load(text: &str, floating_base: bool) -> Model {
    let options = ModelOptions {
        floating_base,
        ..Default::default()
    };
    urdf::model_from_str(text, &options).unwrap()
}

/// `text` with its first `<origin xyz="x y z"` (the root joint's) moved by [`FAR`].
fn moved_root_origin(text: &str) -> String {
    let start = text.find("<origin xyz=\"").unwrap() + "<origin xyz=\"".len();
    let end = start + text[start..].find('"').unwrap();
    let xyz: Vec<f64> = text[start..end]
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    let moved: Vec<String> = xyz
        .iter()
        .zip(FAR)
        .map(|(x, d)| (x + d).to_string())
        .collect();
    format!("{}{}{}", &text[..start], moved.join(" "), &text[end..])
}

/// A model at the origin, the same robot far from it, and how a configuration of the first
/// maps to the second.
struct Case {
    name: &'static str,
    near: Model,
    far: Model,
    move_q: fn(&[f64]) -> Vec<f64>,
}

fn same_q(q: &[f64]) -> Vec<f64> {
    q.to_vec()
}

/// A floating base's position coordinates (`q[0..3]`) moved by [`FAR`].
fn moved_floating_base(q: &[f64]) -> Vec<f64> {
    let mut q = q.to_vec();
    for (x, d) in q.iter_mut().zip(FAR) {
        *x += d;
    }
    q
}

/// The rail coordinate (`q[1]`, after the slide's) moved 1.5 km.
fn moved_carriage(q: &[f64]) -> Vec<f64> {
    let mut q = q.to_vec();
    q[1] += 1500.0;
    q
}

fn cases() -> Vec<Case> {
    let fixed = |name, text: &str| Case {
        name,
        near: load(text, false),
        far: load(&moved_root_origin(text), false),
        move_q: same_q,
    };
    let on_a_rail = |name, n| Case {
        name,
        near: load(&pendulum_on_a_rail(n), false),
        far: load(&pendulum_on_a_rail(n), false),
        move_q: moved_carriage,
    };
    let pendulum = pendulum_urdf(16, 0.5, 0.7);
    let tree_floating_joint = TREE.replace(r#"type="planar""#, r#"type="floating""#);
    vec![
        fixed("pendulum 16", &pendulum),
        fixed("tree (planar base joint)", TREE),
        fixed("tree, floating joint", &tree_floating_joint),
        fixed("default arm", examples::DEFAULT_ARM_URDF),
        on_a_rail("16-link pendulum on a rail, 1.5 km along it", 16),
        on_a_rail("60-link pendulum on a rail, 1.5 km along it", 60),
        Case {
            name: "default arm, floating base",
            near: load(examples::DEFAULT_ARM_URDF, true),
            far: load(examples::DEFAULT_ARM_URDF, true),
            move_q: moved_floating_base,
        },
    ]
}

/// Fails unless `far` equals `near` to a few ulps of `near`'s size.
fn assert_same(case: &str, quantity: &str, near: &[f64], far: &[f64]) {
    assert_within(1e-12, case, quantity, near, far);
}

/// Fails unless `far` equals `near` to `relative` times `1 + |near|`.
fn assert_within(relative: f64, case: &str, quantity: &str, near: &[f64], far: &[f64]) {
    let err = max_diff(near, far);
    assert!(
        err <= relative * (1.0 + norm(near)),
        "{case}: {quantity} far away differs from the origin's by {err:e} (|{quantity}| = {:e})",
        norm(near)
    );
}

#[test]
fn joint_space_dynamics_do_not_depend_on_where_the_robot_stands() {
    for case in cases() {
        let (mut ws_near, mut ws_far) = (Workspace::new(&case.near), Workspace::new(&case.far));
        let mut out_near = JointStateOutputs::new(&case.near);
        let mut out_far = JointStateOutputs::new(&case.far);
        let mut rng = Rng::new(41);
        for _ in 0..5 {
            let q = random_q(&case.near, &mut rng);
            let q_far = (case.move_q)(&q);
            let v = rng.vector(case.near.nv(), 2.0);
            let a = rng.vector(case.near.nv(), 3.0);
            let tau = rng.vector(case.near.nv(), 10.0);
            let name = case.name;

            let near = crba(&case.near, &mut ws_near, &q)
                .unwrap()
                .as_slice()
                .to_vec();
            let far = crba(&case.far, &mut ws_far, &q_far).unwrap().as_slice();
            assert_same(name, "H", &near, far);
            let near = gravity(&case.near, &mut ws_near, &q).unwrap().to_vec();
            assert_same(
                name,
                "g",
                &near,
                gravity(&case.far, &mut ws_far, &q_far).unwrap(),
            );
            let near = rnea(&case.near, &mut ws_near, &q, &v, &a).unwrap().to_vec();
            let far = rnea(&case.far, &mut ws_far, &q_far, &v, &a).unwrap();
            assert_same(name, "τ", &near, far);
            let none = Externals::none();
            for method in ForwardDynamicsMethod::ALL {
                let near = forward_dynamics(&case.near, &mut ws_near, &q, &v, &tau, method, &none)
                    .unwrap()
                    .to_vec();
                let far = forward_dynamics(&case.far, &mut ws_far, &q_far, &v, &tau, method, &none)
                    .unwrap();
                assert_same(name, &format!("q̈ by {method}"), &near, far);

                let input = |q| JointStateInputs {
                    q,
                    v: &v,
                    effort_command: &tau,
                    measured_acceleration: Some(&a),
                };
                joint_state_outputs(&case.near, &mut ws_near, method, &input(&q), &mut out_near)
                    .unwrap();
                joint_state_outputs(&case.far, &mut ws_far, method, &input(&q_far), &mut out_far)
                    .unwrap();
                let (n, f) = (&out_near, &out_far);
                let what = format!("joint_state_outputs by {method}");
                assert_same(name, &format!("{what}: g"), n.gravity(), f.gravity());
                assert_same(
                    name,
                    &format!("{what}: q̈"),
                    n.acceleration(),
                    f.acceleration(),
                );
                assert_same(
                    name,
                    &format!("{what}: τ"),
                    n.inverse_dynamics(),
                    f.inverse_dynamics(),
                );
            }
        }
    }
}

/// A root that moves (velocity and acceleration given about the world origin, a kilometre from
/// the robot) and wrenches on the bodies: forward dynamics by every method inverts RNEA, which
/// works in body coordinates and so moves the root's motion to each root body its own way.
#[test]
fn forward_dynamics_far_from_origin_inverts_rnea_with_a_moving_root() {
    for case in cases() {
        let model = &case.far;
        let mut ws = Workspace::new(model);
        let mut rng = Rng::new(42);
        for _ in 0..5 {
            let q = (case.move_q)(&random_q(&case.near, &mut rng));
            let v = rng.vector(model.nv(), 2.0);
            let tau = rng.vector(model.nv(), 10.0);
            let motion = |r: &mut Rng, scale| {
                let x = r.vector(6, scale);
                Motion::new(
                    Vector3::new(x[0], x[1], x[2]),
                    Vector3::new(x[3], x[4], x[5]),
                )
            };
            // Small angular rates: about the world origin, 1 km away, they are fast.
            let root_velocity = motion(&mut rng, 1e-3);
            let root_acceleration = motion(&mut rng, 1e-3);
            let wrenches: Vec<Force> = (0..model.nbodies())
                .map(|_| {
                    let m = motion(&mut rng, 5.0);
                    Force::new(m.ang, m.lin)
                })
                .collect();
            let ext = Externals {
                wrenches: Some(&wrenches),
                root_velocity,
                root_acceleration,
            };
            for method in ForwardDynamicsMethod::ALL {
                let qdd = forward_dynamics(model, &mut ws, &q, &v, &tau, method, &ext)
                    .unwrap()
                    .to_vec();
                let back = rnea_with(model, &mut ws, &q, &v, &qdd, &ext).unwrap();
                let err = max_diff(back, &tau);
                assert!(
                    err < 1e-9 * (1.0 + norm(&tau)),
                    "{}, {method}: |RNEA(FD(τ)) − τ| = {err:e}",
                    case.name
                );
            }
        }
    }
}

/// How far [`near_and_far`] moves a floating robot (m, world axes): about 1000 km.
const SHIFT: [f64; 3] = [1e6, -7e5, 3e5];

/// Five random states of floating-base `model` (seeded by `seed`), each with the same state
/// moved by [`SHIFT`] (its first three coordinates, the base's position).
fn near_and_far(model: &Model, seed: u64) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = Rng::new(seed);
    (0..5)
        .map(|_| {
            let q = random_q(model, &mut rng);
            let mut far = q.clone();
            for (x, d) in far.iter_mut().zip(SHIFT) {
                *x += d;
            }
            (q, far)
        })
        .collect()
}

/// The centre-of-mass Jacobian, a sum of each subtree's first moment about its own joint, does
/// not depend on where the robot stands: 1000 km out as at the origin (the offsets between
/// joints come from the joints' own placements, not from differences of world positions), and
/// the centre of mass moves by exactly that much.
#[test]
fn the_centre_of_mass_jacobian_does_not_depend_on_where_the_robot_stands() {
    use spatial_dynamics_core::algorithms::center_of_mass_jacobian;
    let tree_floating_joint = TREE.replace(r#"type="planar""#, r#"type="floating""#);
    for text in [examples::DEFAULT_ARM_URDF, tree_floating_joint.as_str()] {
        let model = load(text, true);
        let mut ws = Workspace::new(&model);
        for (q, far) in near_and_far(&model, 41) {
            let (com_near, j) = center_of_mass_jacobian(&model, &mut ws, &q).unwrap();
            let near: Vec<f64> = j.iter().copied().collect();
            let (com_far, j) = center_of_mass_jacobian(&model, &mut ws, &far).unwrap();
            let far_j: Vec<f64> = j.iter().copied().collect();
            assert_same(model.name(), "J_c", &near, &far_j);
            let moved = com_far.position - com_near.position - Vector3::from(SHIFT);
            assert!(moved.norm() < 1e-9, "{}: {moved:?}", model.name());
        }
    }
}

/// The `local` and `local_world_aligned` Jacobians of every link (by `frame_jacobian` and by
/// `joint_jacobians`) are about the link's own origin, so they do not depend on where a
/// floating robot stands: moved 1000 km they keep the digits they have at the origin. The
/// offsets of the joints from the link are composed from their placements along the support,
/// as Pinocchio's `LOCAL` Jacobian composes them; differences of world positions would lose
/// about `ε · 10⁶ m ≈ 1e-10`. The models: the arm, the tree with its planar joint (a joint kept whole
/// in the workspace) and with a floating joint below the floating base.
#[test]
fn local_frame_jacobians_do_not_depend_on_where_a_floating_robot_stands() {
    use spatial_dynamics_core::algorithms::{
        find_frame, frame_jacobian, joint_jacobians, ReferenceFrame,
    };
    let tree_floating_joint = TREE.replace(r#"type="planar""#, r#"type="floating""#);
    for text in [
        examples::DEFAULT_ARM_URDF,
        TREE,
        tree_floating_joint.as_str(),
    ] {
        let model = load(text, true);
        let mut ws = Workspace::new(&model);
        for (q, far) in near_and_far(&model, 43) {
            for link in model.links() {
                let frame = find_frame(&model, &link.name).unwrap();
                for reference in [ReferenceFrame::Local, ReferenceFrame::LocalWorldAligned] {
                    let what = format!("{reference:?} J of {}", link.name);
                    let mut jacobian = |q: &[f64]| {
                        let single = frame_jacobian(&model, &mut ws, q, &frame, reference)
                            .unwrap()
                            .as_slice()
                            .to_vec();
                        let mut joints = joint_jacobians(&model, &mut ws, q).unwrap();
                        let many = joints.frame_jacobian(&frame, reference).unwrap();
                        (single, many.as_slice().to_vec())
                    };
                    let (near_single, near_many) = jacobian(&q);
                    let (far_single, far_many) = jacobian(&far);
                    assert_within(1e-14, model.name(), &what, &near_single, &far_single);
                    assert_within(1e-14, model.name(), &what, &near_many, &far_many);
                }
            }
        }
    }
}

/// A fixed base whose first joint stands 1000 km from the world origin (turned by `rpy`), two
/// turns about z and a slide along x below it, and a tool fused 0.2 m past the slide: the
/// `local` and `local_world_aligned` Jacobians of its links against their closed forms, to
/// ~10 ulps (a difference of world positions would be 1e-10 off).
///
/// With `θ₁`, `θ₂` the turns, `d` the slide and `L` the link's distance from the second joint
/// along the slide, in link axes (turned by `θ₁ + θ₂` about the first joint's z):
/// the first joint's column is `[ẑ × (l₁ u(−θ₂) + L x̂); ẑ] = [(l₁ sin θ₂, l₁ cos θ₂ + L, 0); ẑ]`,
/// the second's `[(0, L, 0); ẑ]`, the slide's `[x̂; 0]` (zero for the second body's link, which
/// it does not move); `local_world_aligned` turns each by `R₀ R_z(θ₁ + θ₂)` (`R₀` the first
/// joint's `rpy`).
#[test]
fn local_frame_jacobians_of_a_joint_far_from_the_origin_match_closed_forms() {
    use nalgebra::{Rotation3, Vector3 as V3};
    use spatial_dynamics_core::algorithms::{
        find_frame, frame_jacobian, joint_jacobians, ReferenceFrame,
    };
    let (l1, l2, tool) = (0.4, 0.3, 0.2);
    let (roll, pitch, yaw) = (0.3, -0.2, 0.5);
    let inertial = r#"<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>"#;
    let limit = r#"<limit lower="-3" upper="3" effort="1" velocity="1"/>"#;
    let text = format!(
        r#"<robot name="far_joint"><link name="base"/>
        <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
          <origin xyz="1e6 -2e6 3e5" rpy="{roll} {pitch} {yaw}"/><axis xyz="0 0 1"/>{limit}</joint>
        <link name="l1">{inertial}</link>
        <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
          <origin xyz="{l1} 0 0"/><axis xyz="0 0 1"/>{limit}</joint>
        <link name="l2">{inertial}</link>
        <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/>
          <origin xyz="{l2} 0 0"/><axis xyz="1 0 0"/>{limit}</joint>
        <link name="l3">{inertial}</link>
        <joint name="mount" type="fixed"><parent link="l3"/><child link="tool"/>
          <origin xyz="{tool} 0 0"/></joint>
        <link name="tool"/></robot>"#
    );
    let model = load(&text, false);
    assert_eq!(model.nv(), 3);
    let mut ws = Workspace::new(&model);
    let r0 = Rotation3::from_axis_angle(&V3::z_axis(), yaw)
        * Rotation3::from_axis_angle(&V3::y_axis(), pitch)
        * Rotation3::from_axis_angle(&V3::x_axis(), roll);
    let mut rng = Rng::new(44);
    for _ in 0..10 {
        let q = rng.vector(3, 1.5);
        let (t2, d) = (q[1], q[2]);
        // Each link: its distance from the second joint along the slide, and whether the slide
        // moves it.
        for (link, length, slides) in [
            ("l2", 0.0, false),
            ("l3", l2 + d, true),
            ("tool", l2 + d + tool, true),
        ] {
            let z = V3::z();
            let local = [
                (V3::new(l1 * t2.sin(), l1 * t2.cos() + length, 0.0), z),
                (V3::new(0.0, length, 0.0), z),
                if slides {
                    (V3::x(), V3::zeros())
                } else {
                    (V3::zeros(), V3::zeros())
                },
            ];
            let to_world = r0 * Rotation3::from_axis_angle(&V3::z_axis(), q[0] + t2);
            let frame = find_frame(&model, link).unwrap();
            for reference in [ReferenceFrame::Local, ReferenceFrame::LocalWorldAligned] {
                let want: Vec<f64> = local
                    .iter()
                    .flat_map(|(lin, ang)| match reference {
                        ReferenceFrame::Local => [lin.as_slice(), ang.as_slice()].concat(),
                        _ => [(to_world * lin).as_slice(), (to_world * ang).as_slice()].concat(),
                    })
                    .collect();
                let what = format!("{reference:?} J of {link} at q = {q:?}");
                let single = frame_jacobian(&model, &mut ws, &q, &frame, reference)
                    .unwrap()
                    .as_slice()
                    .to_vec();
                let err = max_diff(&single, &want);
                assert!(err < 2e-15, "{what}: {single:?} against {want:?}: {err:e}");
                let mut joints = joint_jacobians(&model, &mut ws, &q).unwrap();
                let many = joints.frame_jacobian(&frame, reference).unwrap().as_slice();
                let err = max_diff(many, &want);
                assert!(err < 2e-15, "{what} (joint_jacobians): {err:e}");
            }
        }
    }
}
