//! Mimic joints: the reduced model must equal the full model (mimic ignored) evaluated at the
//! expanded coordinates, projected onto the leaders: `τ = Jᵀ τ_full`, `H = Jᵀ H_full J`, where
//! `q_full = J q + offset`.

mod common;

use common::{max_diff, Rng};
use nalgebra::{DMatrix, DVector};
use spatial_dynamics_core::algorithms::{crba, forward_dynamics, rnea};
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, ModelOptions, Workspace,
};

const GRIPPER: &str = r#"<robot name="g">
  <link name="world"/>
  <joint name="wrist" type="revolute"><parent link="world"/><child link="palm"/><axis xyz="0 0 1"/>
    <origin xyz="0 0 0.1" rpy="0.3 0 0"/><limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
  <link name="palm"><inertial><origin xyz="0.01 0.02 0.05"/><mass value="0.5"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.0012" iyz="0" izz="0.0008"/></inertial></link>
  <joint name="finger_left" type="prismatic"><parent link="palm"/><child link="left"/><axis xyz="0 1 0"/>
    <origin xyz="0 0.02 0.1"/><limit lower="0" upper="0.04" effort="20" velocity="0.1"/></joint>
  <link name="left"><inertial><origin xyz="0 0.01 0.02"/><mass value="0.05"/>
    <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>
  <joint name="finger_right" type="prismatic"><parent link="palm"/><child link="right"/><axis xyz="0 -1 0"/>
    <origin xyz="0 -0.02 0.1"/><limit lower="0" upper="0.04" effort="20" velocity="0.1"/>
    <mimic joint="finger_left" multiplier="1.0" offset="0.0"/></joint>
  <link name="right"><inertial><origin xyz="0 -0.01 0.02"/><mass value="0.06"/>
    <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>
  <joint name="thumb" type="revolute"><parent link="palm"/><child link="thumb_link"/><axis xyz="1 0 0"/>
    <origin xyz="0.03 0 0.05"/><limit lower="-1" upper="1" effort="2" velocity="1"/>
    <mimic joint="wrist" multiplier="-0.5" offset="0.1"/></joint>
  <link name="thumb_link"><inertial><origin xyz="0 0.02 0.03"/><mass value="0.02"/>
    <inertia ixx="2e-6" ixy="0" ixz="0" iyy="2e-6" iyz="0" izz="1e-6"/></inertial></link>
</robot>"#;

#[test]
fn mimic_model_is_the_projected_full_model() {
    let reduced = urdf::model_from_str(GRIPPER, &ModelOptions::default()).unwrap();
    let full = urdf::model_from_str(
        GRIPPER,
        &ModelOptions {
            ignore_mimic: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((reduced.nq(), full.nq()), (2, 4));
    // J maps reduced coordinates to full ones, found by joint name: q_full = J q + offset.
    let index = |m: &spatial_dynamics_core::Model, name: &str| {
        m.coordinate_joints()
            .find(|j| j.name == name)
            .unwrap()
            .v_index
    };
    let mut j = DMatrix::zeros(4, 2);
    let mut offset = DVector::zeros(4);
    for (follower, leader, mult, off) in [
        ("wrist", "wrist", 1.0, 0.0),
        ("finger_left", "finger_left", 1.0, 0.0),
        ("finger_right", "finger_left", 1.0, 0.0),
        ("thumb", "wrist", -0.5, 0.1),
    ] {
        j[(index(&full, follower), index(&reduced, leader))] = mult;
        offset[index(&full, follower)] = off;
    }
    let (mut wr, mut wf) = (Workspace::new(&reduced), Workspace::new(&full));
    let mut rng = Rng::new(20);
    for _ in 0..10 {
        let (q, v, a) = (
            DVector::from_vec(rng.vector(2, 1.0)),
            DVector::from_vec(rng.vector(2, 1.0)),
            DVector::from_vec(rng.vector(2, 1.0)),
        );
        let (qf, vf, af) = (&j * &q + &offset, &j * &v, &j * &a);
        let tau = rnea(&reduced, &mut wr, q.as_slice(), v.as_slice(), a.as_slice())
            .unwrap()
            .to_vec();
        let tau_full = DVector::from_column_slice(
            rnea(&full, &mut wf, qf.as_slice(), vf.as_slice(), af.as_slice()).unwrap(),
        );
        let expected = j.transpose() * tau_full;
        assert!(
            max_diff(&tau, expected.as_slice()) < 1e-13,
            "{tau:?} vs {expected:?}"
        );
        let h = crba(&reduced, &mut wr, q.as_slice()).unwrap().clone();
        let h_full = crba(&full, &mut wf, qf.as_slice()).unwrap();
        let h_expected = j.transpose() * h_full * &j;
        assert!((&h - &h_expected).amax() < 1e-14, "{h} vs {h_expected}");
        for method in [
            ForwardDynamicsMethod::Crba,
            ForwardDynamicsMethod::RneaColumns,
        ] {
            let acc = forward_dynamics(
                &reduced,
                &mut wr,
                q.as_slice(),
                v.as_slice(),
                &tau,
                method,
                &Externals::none(),
            )
            .unwrap();
            assert!(
                max_diff(acc, a.as_slice()) < 1e-9,
                "{method}: {acc:?} vs {a:?}"
            );
        }
    }
}

#[test]
fn aba_refuses_mimic_models_by_name() {
    let model = urdf::model_from_str(GRIPPER, &ModelOptions::default()).unwrap();
    let mut ws = Workspace::new(&model);
    let err = forward_dynamics(
        &model,
        &mut ws,
        &[0.0, 0.0],
        &[0.0, 0.0],
        &[0.0, 0.0],
        ForwardDynamicsMethod::Aba,
        &Externals::none(),
    )
    .unwrap_err();
    assert!(matches!(
        &err,
        DynamicsError::Unsupported { method: "aba", .. }
    ));
    assert!(err.to_string().contains("finger_right"), "{err}");
}
