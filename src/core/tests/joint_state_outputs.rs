//! `joint_state_outputs` (gravity, forward dynamics and inverse dynamics at one state, sharing
//! the kinematics) equals the three separate calls — `gravity`, `forward_dynamics` by each
//! method, `rnea` — on fixed-base, floating-base, planar-base and mimic models; it refuses what
//! they refuse and allocates nothing.

mod common;

use common::{allocations_during, max_diff, norm, random_q, Rng};
use spatial_dynamics_core::algorithms::{
    forward_dynamics, gravity, joint_state_outputs, rnea, JointStateInputs, JointStateOutputs,
};
use spatial_dynamics_core::model::examples::{self, pendulum_urdf};
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

const TREE: &str = include_str!("models/tree.urdf");

fn load(text: &str) -> Model {
    urdf::model_from_str(text, &ModelOptions::default()).unwrap()
}

fn models() -> Vec<(&'static str, Model)> {
    vec![
        ("default arm", load(examples::DEFAULT_ARM_URDF)),
        (
            "default arm, floating base",
            urdf::model_from_str(
                examples::DEFAULT_ARM_URDF,
                &ModelOptions {
                    floating_base: true,
                    ..Default::default()
                },
            )
            .unwrap(),
        ),
        ("tree (planar base joint)", load(TREE)),
        (
            "tree, floating joint",
            load(&TREE.replace(r#"type="planar""#, r#"type="floating""#)),
        ),
        ("pendulum 12", load(&pendulum_urdf(12, 0.5, 0.7))),
        ("lamp", load(examples::LAMP_URDF)),
        ("mimic gripper", load(examples::MIMIC_GRIPPER_URDF)),
    ]
}

/// Each output within 1e-12 relative to its size.
fn assert_close(what: &str, got: &[f64], want: &[f64]) {
    let err = max_diff(got, want);
    assert!(
        err <= 1e-12 * (1.0 + norm(want)),
        "{what}: |combined − separate| = {err:e} (|separate| = {:e})\n{got:?}\n{want:?}",
        norm(want)
    );
}

#[test]
fn equals_the_separate_calls() {
    for (name, model) in models() {
        let mimic = model.bodies().iter().any(|b| b.joint.is_mimic());
        let (mut ws, mut separate) = (Workspace::new(&model), Workspace::new(&model));
        let mut out = JointStateOutputs::new(&model);
        let mut rng = Rng::new(7);
        for trial in 0..8 {
            let q = random_q(&model, &mut rng);
            let v = rng.vector(model.nv(), 2.0);
            let tau = rng.vector(model.nv(), 10.0);
            let a = rng.vector(model.nv(), 5.0);
            for method in ForwardDynamicsMethod::ALL {
                let measured = (trial % 2 == 0).then_some(a.as_slice());
                let input = JointStateInputs {
                    q: &q,
                    v: &v,
                    effort_command: &tau,
                    measured_acceleration: measured,
                };
                let result = joint_state_outputs(&model, &mut ws, method, &input, &mut out);
                let what = format!("{name}, {method}, trial {trial}");
                let fd = forward_dynamics(
                    &model,
                    &mut separate,
                    &q,
                    &v,
                    &tau,
                    method,
                    &Externals::none(),
                );
                if mimic && method == ForwardDynamicsMethod::Aba {
                    // ABA refuses mimic joints, alone and here.
                    assert!(
                        matches!(fd, Err(DynamicsError::Unsupported { .. })),
                        "{what}"
                    );
                    assert!(
                        matches!(result, Err(DynamicsError::Unsupported { .. })),
                        "{what}: {result:?}"
                    );
                    continue;
                }
                result.unwrap_or_else(|e| panic!("{what}: {e}"));
                assert_close(&format!("{what}: q̈"), out.acceleration(), fd.unwrap());
                let g = gravity(&model, &mut separate, &q).unwrap();
                assert_close(&format!("{what}: g"), out.gravity(), g);
                match measured {
                    Some(a) => {
                        let id = rnea(&model, &mut separate, &q, &v, a).unwrap();
                        assert_close(&format!("{what}: τ"), out.inverse_dynamics(), id);
                    }
                    None => assert!(out.inverse_dynamics().iter().all(|&x| x == 0.0)),
                }
            }
        }
    }
}

#[test]
fn bad_input_is_an_error_naming_it() {
    let model = load(examples::DEFAULT_ARM_URDF);
    let mut ws = Workspace::new(&model);
    let mut out = JointStateOutputs::new(&model);
    let (q, v, tau) = (
        vec![0.1; model.nq()],
        vec![0.2; model.nv()],
        vec![0.3; model.nv()],
    );
    let mut a = vec![0.0; model.nv()];
    a[3] = f64::NAN;
    let input = JointStateInputs {
        q: &q,
        v: &v,
        effort_command: &tau,
        measured_acceleration: Some(&a),
    };
    let err = joint_state_outputs(
        &model,
        &mut ws,
        ForwardDynamicsMethod::Aba,
        &input,
        &mut out,
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            DynamicsError::NonFinite {
                vector: "a",
                index: 3,
                ..
            }
        ),
        "{err:?}"
    );
    let short = JointStateInputs {
        v: &v[1..],
        measured_acceleration: None,
        ..input
    };
    let err = joint_state_outputs(
        &model,
        &mut ws,
        ForwardDynamicsMethod::Crba,
        &short,
        &mut out,
    )
    .unwrap_err();
    assert!(
        matches!(err, DynamicsError::Length { vector: "v", .. }),
        "{err:?}"
    );
    // Outputs sized for another model.
    let other = load(&pendulum_urdf(2, 0.5, 0.7));
    let mut small = JointStateOutputs::new(&other);
    let ok = JointStateInputs {
        measured_acceleration: None,
        ..input
    };
    let err = joint_state_outputs(&model, &mut ws, ForwardDynamicsMethod::Aba, &ok, &mut small)
        .unwrap_err();
    assert!(
        matches!(
            err,
            DynamicsError::Length {
                vector: "outputs",
                ..
            }
        ),
        "{err:?}"
    );
}

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

#[test]
fn allocates_nothing() {
    assert_eq!(
        allocations_during(|| drop(std::hint::black_box(vec![1u8; 16]))),
        1,
        "the counter counts"
    );
    for (name, model) in models() {
        let mut ws = Workspace::new(&model);
        let mut out = JointStateOutputs::new(&model);
        let q = random_q(&model, &mut Rng::new(3));
        let (v, tau, a) = (
            vec![0.2; model.nv()],
            vec![0.3; model.nv()],
            vec![-0.1; model.nv()],
        );
        let input = JointStateInputs {
            q: &q,
            v: &v,
            effort_command: &tau,
            measured_acceleration: Some(&a),
        };
        for method in [ForwardDynamicsMethod::Crba, ForwardDynamicsMethod::Aba] {
            if model.bodies().iter().any(|b| b.joint.is_mimic())
                && method == ForwardDynamicsMethod::Aba
            {
                continue;
            }
            let n = allocations_during(|| {
                joint_state_outputs(&model, &mut ws, method, &input, &mut out).unwrap();
            });
            assert_eq!(n, 0, "{name}, {method}: {n} allocations");
        }
    }
}
