//! Model reduction is exact for the coordinates kept: with every removed joint held at its
//! position (locked or frozen) with zero velocity and acceleration, the reduced model's τ, H and
//! q̈ equal the full model's. Pruned massless subtrees may move as they like: they exert nothing.

mod common;

use common::{random_q, Rng};
use spatial_dynamics_core::algorithms::{crba, forward_dynamics, rnea};
use spatial_dynamics_core::model::examples::{DEFAULT_ARM_URDF, MIMIC_GRIPPER_URDF};
use spatial_dynamics_core::{
    urdf, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

const TREE: &str = include_str!("models/tree.urdf");

/// The default arm with a massless sensor head on two revolute joints at its flange (and a
/// massless frame fixed to it): the full model's H has two zero rows and columns.
fn arm_with_massless_sensor() -> String {
    DEFAULT_ARM_URDF.replace(
        "</robot>",
        r#"<joint name="sensor_pan" type="revolute"><parent link="link7"/><child link="sensor_mount"/>
             <origin xyz="0 0.05 0.1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
           <link name="sensor_mount"/>
           <joint name="sensor_tilt" type="revolute"><parent link="sensor_mount"/><child link="sensor"/>
             <origin xyz="0 0 0.02" rpy="0.3 0 0"/><axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
           <link name="sensor"/>
           <joint name="sensor_optical" type="fixed"><parent link="sensor"/><child link="sensor_optical_frame"/></joint>
           <link name="sensor_optical_frame"/>
         </robot>"#,
    )
}

fn load(text: &str, options: ModelOptions) -> Model {
    urdf::model_from_str(text, &options).unwrap_or_else(|e| panic!("{options:?}: {e}"))
}

/// The full model's coordinate slots of a joint: (q index, v index, nq, nv).
fn slots(model: &Model, name: &str) -> (usize, usize, usize, usize) {
    let j = model
        .coordinate_joints()
        .find(|j| j.name == name)
        .unwrap_or_else(|| panic!("no coordinate joint '{name}'"));
    (j.q_index, j.v_index, j.nq, j.nv)
}

/// Checks τ, H and q̈ of `reduced` against `full` at random states: kept coordinates random,
/// locked and frozen ones at the positions the reduced model reports with zero rates, pruned
/// ones random (position, velocity and acceleration).
fn assert_exact(full: &Model, reduced: &Model, seed: u64) {
    let held: Vec<(String, Vec<f64>)> = reduced
        .locked_joints()
        .iter()
        .map(|(n, v)| (n.clone(), vec![*v]))
        .chain(reduced.reduction().frozen_joints.iter().cloned())
        .collect();
    // (reduced v index, full v index) of every kept velocity coordinate.
    let kept: Vec<(usize, usize)> = reduced
        .coordinate_joints()
        .flat_map(|j| {
            let (_, fv, _, _) = slots(full, j.name);
            (0..j.nv).map(move |k| (j.v_index + k, fv + k))
        })
        .collect();
    let kept_q: Vec<(usize, usize)> = reduced
        .coordinate_joints()
        .flat_map(|j| {
            let (fq, _, _, _) = slots(full, j.name);
            (0..j.nq).map(move |k| (j.q_index + k, fq + k))
        })
        .collect();
    let (mut wr, mut wf) = (Workspace::new(reduced), Workspace::new(full));
    let mut rng = Rng::new(seed);
    for _ in 0..5 {
        let qr = random_q(reduced, &mut rng);
        let (vr, ar) = (rng.vector(reduced.nv(), 1.0), rng.vector(reduced.nv(), 1.0));
        // Pruned coordinates (and anything else not held) random; held ones overwritten below.
        let mut qf = random_q(full, &mut rng);
        let (mut vf, mut af) = (rng.vector(full.nv(), 1.0), rng.vector(full.nv(), 1.0));
        for (name, position) in &held {
            if let Some(j) = full.coordinate_joints().find(|j| j.name == name) {
                qf[j.q_index..j.q_index + j.nq].copy_from_slice(position);
                vf[j.v_index..j.v_index + j.nv].fill(0.0);
                af[j.v_index..j.v_index + j.nv].fill(0.0);
            }
        }
        for &(r, f) in &kept_q {
            qf[f] = qr[r];
        }
        for &(r, f) in &kept {
            (vf[f], af[f]) = (vr[r], ar[r]);
        }
        let tau_r = rnea(reduced, &mut wr, &qr, &vr, &ar).unwrap().to_vec();
        let tau_f = rnea(full, &mut wf, &qf, &vf, &af).unwrap().to_vec();
        let scale = 1.0 + tau_f.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for &(r, f) in &kept {
            let d = (tau_r[r] - tau_f[f]).abs();
            assert!(d < 1e-12 * scale, "τ at {}: {d:e}", reduced.v_name(r));
        }
        // H_kk with pruned coordinates anywhere: CRBA's kept block ignores them.
        let h_r = crba(reduced, &mut wr, &qr).unwrap().clone();
        let h_f = crba(full, &mut wf, &qf).unwrap().clone();
        for &(r, f) in &kept {
            for &(r2, f2) in &kept {
                let d = (h_r[(r, r2)] - h_f[(f, f2)]).abs();
                assert!(
                    d < 1e-12 * (1.0 + h_f[(f, f)].abs()),
                    "H at {r},{r2}: {d:e}"
                );
            }
        }
        // q̈ of the reduced model under τ_r, fed to the full model's inverse dynamics, gives τ_r
        // back on the kept coordinates.
        // (ABA does not take mimic joints.)
        let methods = [ForwardDynamicsMethod::Crba, ForwardDynamicsMethod::Aba];
        for &method in &methods[..if reduced.has_mimic() { 1 } else { 2 }] {
            let qdd = forward_dynamics(reduced, &mut wr, &qr, &vr, &ar, method, &Externals::none())
                .unwrap()
                .to_vec();
            for &(r, f) in &kept {
                af[f] = qdd[r];
            }
            let tau_back = rnea(full, &mut wf, &qf, &vf, &af).unwrap().to_vec();
            for &(r, f) in &kept {
                let d = (tau_back[f] - ar[r]).abs();
                assert!(
                    d < 1e-9 * (1.0 + ar[r].abs()),
                    "{method:?}: q̈ at {}: {d:e}",
                    reduced.v_name(r)
                );
            }
        }
    }
}

#[test]
fn locking_a_joint_keeps_the_other_coordinates_exact() {
    let full = load(TREE, ModelOptions::default());
    let reduced = load(
        TREE,
        ModelOptions {
            locked: vec![("left_shoulder".into(), 0.7), ("right_wrist".into(), -1.2)],
            ..Default::default()
        },
    );
    assert_eq!(reduced.nv(), full.nv() - 2);
    assert_exact(&full, &reduced, 14);
}

#[test]
fn a_tip_keeps_the_chain_and_lumps_the_rest_onto_it() {
    let full = load(DEFAULT_ARM_URDF, ModelOptions::default());
    let reduced = load(
        DEFAULT_ARM_URDF,
        ModelOptions {
            tips: vec!["link4".into()],
            locked: vec![("joint6".into(), 0.8)],
            ..Default::default()
        },
    );
    assert_eq!(reduced.nv(), 4);
    let r = reduced.reduction();
    assert_eq!(r.frozen_joint_names(), ["joint5", "joint7"]);
    assert_eq!(reduced.locked_joints(), [("joint6".to_string(), 0.8)]);
    assert!(r.payload_links.contains(&"link5".to_string()));
    assert_exact(&full, &reduced, 21);
}

#[test]
fn root_and_tips_keep_a_subtree_of_a_branching_tree() {
    let full = load(TREE, ModelOptions::default());
    // From the torso (its planar base frozen, gravity still in the world frame) to the left
    // hand and the right arm: the head and the right wrist freeze.
    let reduced = load(
        TREE,
        ModelOptions {
            root: Some("torso".into()),
            tips: vec!["left_hand".into(), "right_arm".into()],
            ..Default::default()
        },
    );
    let names: Vec<&str> = reduced.coordinate_joints().map(|j| j.name).collect();
    assert_eq!(names, ["left_shoulder", "left_slide", "right_shoulder"]);
    assert_eq!(
        reduced.reduction().frozen_joints[0],
        ("base".to_string(), vec![0.0; 3])
    );
    assert_exact(&full, &reduced, 22);
    // A root alone keeps its whole subtree.
    let subtree = load(
        TREE,
        ModelOptions {
            root: Some("torso".into()),
            ..Default::default()
        },
    );
    assert_eq!(subtree.nv(), full.nv() - 3);
    assert_exact(&full, &subtree, 23);
}

#[test]
fn massless_leaves_are_pruned_with_their_coordinates() {
    let text = arm_with_massless_sensor();
    let full = load(&text, ModelOptions::default());
    let pruned = load(
        &text,
        ModelOptions {
            prune_massless: true,
            ..Default::default()
        },
    );
    assert_eq!((full.nv(), pruned.nv()), (9, 7));
    assert_eq!(
        pruned.reduction().pruned_joints,
        ["sensor_pan", "sensor_tilt", "sensor_optical"]
    );
    // The full model cannot even run forward dynamics: H has zero rows.
    let mut ws = Workspace::new(&full);
    let (q, v) = (vec![0.1; full.nq()], vec![0.0; full.nv()]);
    assert!(forward_dynamics(
        &full,
        &mut ws,
        &q,
        &v,
        &v,
        ForwardDynamicsMethod::Crba,
        &Externals::none()
    )
    .is_err());
    assert_exact(&full, &pruned, 24);
    // A link that carries mass stops the pruning: nothing in the plain arm goes.
    let arm = load(
        DEFAULT_ARM_URDF,
        ModelOptions {
            prune_massless: true,
            ..Default::default()
        },
    );
    assert!(arm.reduction().is_empty() && arm.nv() == 7);
}

#[test]
fn reductions_combine_with_mimic_joints() {
    let full = load(MIMIC_GRIPPER_URDF, ModelOptions::default());
    // Keep the wrist only: the fingers (leader and follower) freeze and lump onto the palm; the
    // thumb mimics the kept wrist and stays coupled to it.
    let reduced = load(
        MIMIC_GRIPPER_URDF,
        ModelOptions {
            tips: vec!["palm".into(), "thumb_link".into()],
            ..Default::default()
        },
    );
    assert_eq!(reduced.nv(), 1);
    assert_exact(&full, &reduced, 25);
}

#[test]
fn bad_reductions_are_refused_by_name() {
    let refuse = |text: &str, options: ModelOptions, expected: &str| {
        let err = urdf::model_from_str(text, &options)
            .unwrap_err()
            .to_string();
        assert!(err.contains(expected), "{err}");
    };
    refuse(
        TREE,
        ModelOptions {
            root: Some("nope".into()),
            ..Default::default()
        },
        "root: there is no link named 'nope'",
    );
    refuse(
        TREE,
        ModelOptions {
            tips: vec!["nope".into()],
            ..Default::default()
        },
        "tip: there is no link named 'nope'",
    );
    refuse(
        TREE,
        ModelOptions {
            root: Some("left_arm".into()),
            tips: vec!["right_hand".into()],
            ..Default::default()
        },
        "tip 'right_hand' is not below the root 'left_arm'",
    );
    refuse(
        TREE,
        ModelOptions {
            root: Some("torso".into()),
            floating_base: true,
            ..Default::default()
        },
        "with a floating base the root must be the description's root link 'world'",
    );
    // The follower finger would freeze while its leader keeps moving.
    refuse(
        MIMIC_GRIPPER_URDF,
        ModelOptions {
            tips: vec!["left_finger".into()],
            ..Default::default()
        },
        "joint 'finger_right' mimics 'finger_left', which stays moving",
    );
}

/// A lock on a mimic follower is taken only with its leader held at a position the lock agrees
/// with (`thumb = −0.5 · wrist + 0.1`); a lock on the leader locks its followers with it.
#[test]
fn a_mimic_follower_locks_only_with_its_leader() {
    let full = load(MIMIC_GRIPPER_URDF, ModelOptions::default());
    let locked = |locks: &[(&str, f64)]| ModelOptions {
        locked: locks.iter().map(|(n, v)| (n.to_string(), *v)).collect(),
        ..Default::default()
    };
    let refused = |locks: &[(&str, f64)]| {
        urdf::model_from_str(MIMIC_GRIPPER_URDF, &locked(locks))
            .unwrap_err()
            .to_string()
    };
    let err = refused(&[("thumb", 0.3)]);
    assert!(
        err.contains("cannot lock joint 'thumb' at 3e-1: it mimics 'wrist' (thumb = -5e-1 · wrist + 1e-1), which stays moving: lock 'wrist' instead"),
        "{err}"
    );
    let err = refused(&[("wrist", 0.4), ("thumb", 0.2)]);
    assert!(
        err.contains("cannot lock joint 'thumb' at 2e-1: it mimics 'wrist'")
            && err.contains("held at 4e-1, which puts 'thumb' at -1e-1"),
        "{err}"
    );
    for locks in [
        &[("wrist", 0.4), ("thumb", -0.1)][..],
        &[("wrist", 0.4)][..],
    ] {
        let reduced = load(MIMIC_GRIPPER_URDF, locked(locks));
        let thumb = reduced.locked_joints().iter().find(|(n, _)| n == "thumb");
        assert!(
            thumb.is_some_and(|(_, q)| (q + 0.1).abs() < 1e-12),
            "{locks:?}: {:?}",
            reduced.locked_joints()
        );
        assert_eq!(reduced.nv(), 1);
        assert_exact(&full, &reduced, 31);
    }
}

/// A follower frozen with its frozen leader takes the leader's position mapped through the
/// mimic, not its own neutral position: the thumb at −0.5 · 0 + 0.1 when the wrist is outside
/// the kept part.
#[test]
fn a_frozen_follower_of_a_frozen_leader_follows_it() {
    let full = load(MIMIC_GRIPPER_URDF, ModelOptions::default());
    let reduced = load(
        MIMIC_GRIPPER_URDF,
        ModelOptions {
            root: Some("palm".into()),
            tips: vec!["left_finger".into(), "right_finger".into()],
            ..Default::default()
        },
    );
    let frozen = &reduced.reduction().frozen_joints;
    assert!(
        frozen.iter().any(|(n, q)| n == "thumb" && q == &[0.1]),
        "{frozen:?}"
    );
    assert_exact(&full, &reduced, 37);
}

/// A massless chain of 4 000 joints with a massive joint elsewhere mimicking its last: no joint
/// of the chain can go (each subtree leads the follower outside it), and deciding so is linear
/// (it took seconds when each subtree's followers were looked for among every joint, cubic).
#[test]
fn pruning_with_a_mimic_into_a_long_massless_chain_is_fast() {
    let n = 4000;
    let inertial = r#"<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>"#;
    let mut text = format!(
        r#"<robot name="r"><link name="base">{inertial}</link><link name="f">{inertial}</link>"#
    );
    let mut prev = "base".to_string();
    for i in 1..=n {
        text += &format!(
            r#"<link name="cl{i}"/><joint name="c{i}" type="continuous"><parent link="{prev}"/><child link="cl{i}"/><axis xyz="0 1 0"/></joint>"#
        );
        prev = format!("cl{i}");
    }
    text += &format!(
        r#"<joint name="jf" type="continuous"><parent link="base"/><child link="f"/><axis xyz="0 1 0"/><mimic joint="c{n}"/></joint></robot>"#
    );
    let options = ModelOptions {
        prune_massless: true,
        ..Default::default()
    };
    let start = std::time::Instant::now();
    let model = load(&text, options.clone());
    let took = start.elapsed();
    assert!(model.reduction().pruned_joints.is_empty());
    assert_eq!(model.nv(), n);
    assert!(took.as_secs_f64() < 2.0, "{took:?}");
    // Without the mimic joint the whole chain goes.
    let free = load(
        &text.replace(&format!(r#"<mimic joint="c{n}"/>"#), ""),
        options.clone(),
    );
    assert_eq!((free.reduction().pruned_joints.len(), free.nv()), (n, 1));
    // A mimic joint inside the chain (c3 follows c2) goes with it; one leading from below c2 to
    // outside keeps c1 and c2 and lets c3 … go.
    let inside = text
        .replace(&format!(r#"<mimic joint="c{n}"/>"#), "")
        .replace(
            r#"<child link="cl3"/><axis xyz="0 1 0"/>"#,
            r#"<child link="cl3"/><axis xyz="0 1 0"/><mimic joint="c2"/>"#,
        );
    let inside = load(&inside, options.clone());
    assert_eq!(
        (inside.reduction().pruned_joints.len(), inside.nv()),
        (n, 1)
    );
    let out = load(
        &text.replace(
            &format!(r#"<mimic joint="c{n}"/>"#),
            r#"<mimic joint="c2"/>"#,
        ),
        options,
    );
    let pruned = &out.reduction().pruned_joints;
    assert_eq!((pruned.len(), pruned[0].as_str()), (n - 2, "c3"));
    assert_eq!(out.nv(), 2);
}
