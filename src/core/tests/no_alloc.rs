//! Hot paths allocate nothing: every algorithm, called on a warmed-up workspace, makes zero heap
//! allocations (counted by a global allocator; this file holds one test so nothing else runs
//! in the process while it counts).

use spatial_dynamics_core::algorithms::{
    aba, aba_derivatives, bias, center_of_mass_jacobian, crba, find_frame, forward_dynamics,
    frame_classical_acceleration, frame_jacobian, frame_placement, gravity, joint_jacobians, rnea,
    rnea_derivatives, rnea_derivatives_with, rnea_rows, rnea_with, ReferenceFrame,
};
use spatial_dynamics_core::model::examples::DEFAULT_ARM_URDF;
use spatial_dynamics_core::spatial::Force;
use spatial_dynamics_core::{urdf, Externals, ForwardDynamicsMethod, ModelOptions, Workspace};

mod common;
use common::allocations_during;

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

#[test]
fn algorithms_do_not_allocate() {
    // The counter does count: a fresh vector is one allocation.
    assert_eq!(
        allocations_during(|| drop(std::hint::black_box(vec![1u8; 16]))),
        1
    );
    let tree = include_str!("models/tree.urdf");
    for floating_base in [false, true] {
        let text = if floating_base {
            tree.replace(r#"type="planar""#, r#"type="floating""#)
        } else {
            tree.to_string()
        };
        let model = urdf::model_from_str(&text, &ModelOptions::default()).unwrap();
        let mut ws = Workspace::new(&model);
        let mut q = vec![0.1; model.nq()];
        if floating_base {
            q[3..7].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
        }
        let v = vec![0.2; model.nv()];
        let a = vec![-0.3; model.nv()];
        let wrenches = vec![Force::zero(); model.nbodies()];
        let ext = Externals {
            wrenches: Some(&wrenches),
            ..Default::default()
        };
        let hand = find_frame(&model, "right_hand").unwrap();
        // Five states as rows (the tree is not in lanes: every row through `rnea`).
        let (q_rows, v_rows, a_rows) = (q.repeat(5), v.repeat(5), a.repeat(5));
        let mut tau_rows = vec![0.0; 5 * model.nv()];
        let references = [
            ReferenceFrame::World,
            ReferenceFrame::Local,
            ReferenceFrame::LocalWorldAligned,
        ];
        let mut run_all = |ws: &mut Workspace| {
            rnea(&model, ws, &q, &v, &a).unwrap();
            rnea_rows(&model, ws, &q_rows, &v_rows, &a_rows, &mut tau_rows).unwrap();
            rnea_with(&model, ws, &q, &v, &a, &ext).unwrap();
            bias(&model, ws, &q, &v, &ext).unwrap();
            gravity(&model, ws, &q).unwrap();
            crba(&model, ws, &q).unwrap();
            aba(&model, ws, &q, &v, &a, &ext).unwrap();
            rnea_derivatives(&model, ws, &q, &v, &a).unwrap();
            rnea_derivatives_with(&model, ws, &q, &v, &a, &ext).unwrap();
            aba_derivatives(&model, ws, &q, &v, &a, &ext).unwrap();
            for method in ForwardDynamicsMethod::ALL {
                forward_dynamics(&model, ws, &q, &v, &a, method, &ext).unwrap();
            }
            frame_placement(&model, ws, &q, &hand).unwrap();
            for reference in references {
                frame_jacobian(&model, ws, &q, &hand, reference).unwrap();
            }
            let local = ReferenceFrame::Local;
            frame_classical_acceleration(&model, ws, &q, &v, &a, &hand, local).unwrap();
            center_of_mass_jacobian(&model, ws, &q).unwrap();
            let mut all = joint_jacobians(&model, ws, &q).unwrap();
            for reference in references {
                all.frame_jacobian(&hand, reference).unwrap();
            }
        };
        run_all(&mut ws);
        let count = allocations_during(|| run_all(&mut ws));
        assert_eq!(
            count, 0,
            "floating base {floating_base}: {count} allocations in the algorithms"
        );
    }
    // RNEA on many states in lanes: two models the lanes cover, one with a turn about a general
    // axis (its transform from the scalar joint calculation, lane by lane); an odd number of
    // rows, so that the last runs alone.
    let quarter_turns = include_str!("models/quarter_turns.urdf");
    for text in [DEFAULT_ARM_URDF, quarter_turns] {
        let model = urdf::model_from_str(text, &ModelOptions::default()).unwrap();
        let mut ws = Workspace::new(&model);
        let (nq, nv, rows) = (model.nq(), model.nv(), 7);
        let q: Vec<f64> = (0..rows * nq).map(|k| 0.1 * k as f64).collect();
        let v: Vec<f64> = (0..rows * nv).map(|k| 0.2 - 0.05 * k as f64).collect();
        let a = vec![-0.3; rows * nv];
        let mut tau = vec![0.0; rows * nv];
        let mut run = || rnea_rows(&model, &mut ws, &q, &v, &a, &mut tau).unwrap();
        run();
        let count = allocations_during(run);
        assert_eq!(count, 0, "{}: allocations in rnea_rows", model.name());
    }
}
