//! A workspace belongs to the model it was made for: every algorithm refuses another model,
//! even one with the same bodies and coordinates, with an error naming both; a clone of the
//! model (or the model with another gravity) is the same model and is accepted.

use spatial_dynamics_core::algorithms::kinematics::{body_motion, body_placements};
use spatial_dynamics_core::algorithms::rnea_columns::rnea_columns;
use spatial_dynamics_core::algorithms::{
    aba, aba_derivatives, bias, center_of_mass, center_of_mass_jacobian, crba, energy, find_frame,
    forward_dynamics, frame_classical_acceleration, frame_jacobian, frame_placement, gravity,
    joint_jacobians, joint_state_outputs, rnea, rnea_derivatives, rnea_with, JointStateInputs,
    JointStateOutputs, ReferenceFrame,
};
use spatial_dynamics_core::model::examples::pendulum_urdf;
use spatial_dynamics_core::requests::answer_line;
use spatial_dynamics_core::sim::{SimConfig, SimError, Simulator, State};
use spatial_dynamics_core::spatial::Vector3;
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, Model, ModelOptions, Workspace,
};

const TURN_SLIDE: &str = include_str!("models/turn_slide.urdf");

fn load(text: &str) -> Model {
    urdf::model_from_str(text, &ModelOptions::default()).unwrap()
}

/// Every algorithm taking `(model, ws, …)` called on `model` with `ws`, at a valid state of
/// `model`: the name of each call with its result (`Ok(())` or the error).
fn every_algorithm(model: &Model, ws: &mut Workspace) -> Vec<(String, Result<(), DynamicsError>)> {
    let (nq, nv) = (model.nq(), model.nv());
    let q = model.neutral();
    let (v, a, tau) = (vec![0.1; nv], vec![0.2; nv], vec![0.3; nv]);
    assert_eq!(q.len(), nq);
    let ext = Externals::none();
    let link = model.links().last().unwrap().name.clone();
    let frame = find_frame(model, &link).unwrap();
    let mut results: Vec<(String, Result<(), DynamicsError>)> = vec![
        ("rnea".into(), rnea(model, ws, &q, &v, &a).map(drop)),
        (
            "rnea_with".into(),
            rnea_with(model, ws, &q, &v, &a, &ext).map(drop),
        ),
        ("bias".into(), bias(model, ws, &q, &v, &ext).map(drop)),
        ("gravity".into(), gravity(model, ws, &q).map(drop)),
        ("crba".into(), crba(model, ws, &q).map(drop)),
        ("aba".into(), aba(model, ws, &q, &v, &tau, &ext).map(drop)),
        (
            "rnea_columns".into(),
            rnea_columns(model, ws, &q, &v, &tau, &ext).map(drop),
        ),
        (
            "rnea_derivatives".into(),
            rnea_derivatives(model, ws, &q, &v, &a).map(drop),
        ),
        (
            "aba_derivatives".into(),
            aba_derivatives(model, ws, &q, &v, &tau, &ext).map(drop),
        ),
        ("energy".into(), energy(model, ws, &q, &v).map(drop)),
        (
            "body_placements".into(),
            body_placements(model, ws, &q).map(drop),
        ),
        ("body_motion".into(), body_motion(model, ws, &q, &v)),
        (
            "frame_placement".into(),
            frame_placement(model, ws, &q, &frame).map(drop),
        ),
        (
            "joint_jacobians".into(),
            joint_jacobians(model, ws, &q).map(drop),
        ),
        (
            "center_of_mass".into(),
            center_of_mass(model, ws, &q).map(drop),
        ),
        (
            "center_of_mass_jacobian".into(),
            center_of_mass_jacobian(model, ws, &q).map(drop),
        ),
    ];
    for method in ForwardDynamicsMethod::ALL {
        let result = forward_dynamics(model, ws, &q, &v, &tau, method, &ext).map(drop);
        results.push((format!("forward_dynamics {method}"), result));
        let mut out = JointStateOutputs::new(model);
        let input = JointStateInputs {
            q: &q,
            v: &v,
            effort_command: &tau,
            measured_acceleration: Some(&a),
        };
        let result = joint_state_outputs(model, ws, method, &input, &mut out);
        results.push((format!("joint_state_outputs {method}"), result));
    }
    let references = [
        ReferenceFrame::World,
        ReferenceFrame::Local,
        ReferenceFrame::LocalWorldAligned,
    ];
    for reference in references {
        let result = frame_jacobian(model, ws, &q, &frame, reference).map(drop);
        results.push((format!("frame_jacobian {reference:?}"), result));
    }
    for reference in &references[1..] {
        let reference = *reference;
        let result =
            frame_classical_acceleration(model, ws, &q, &v, &a, &frame, reference).map(drop);
        results.push((
            format!("frame_classical_acceleration {reference:?}"),
            result,
        ));
    }
    results
}

/// The same robot with the slide along y instead of x: the same bodies, names and coordinates.
fn turned_slide() -> Model {
    load(&TURN_SLIDE.replace(
        r#"<child link="b"/><axis xyz="1 0 0"/>"#,
        r#"<child link="b"/><axis xyz="0 1 0"/>"#,
    ))
}

fn assert_refused(a: &Model, b: &Model) {
    let mut ws = Workspace::new(a);
    for (call, result) in every_algorithm(b, &mut ws) {
        match result {
            Err(DynamicsError::ForeignWorkspace {
                workspace_model,
                model,
                ..
            }) => {
                assert_eq!(workspace_model, a.name(), "{call}");
                assert_eq!(model, b.name(), "{call}");
            }
            other => panic!("{call}: a workspace of another model gave {other:?}"),
        }
    }
}

#[test]
fn another_model_with_the_same_shape_is_refused_by_every_algorithm() {
    let (a, b) = (load(TURN_SLIDE), turned_slide());
    assert_eq!((a.nbodies(), a.nq(), a.nv()), (b.nbodies(), b.nq(), b.nv()));
    assert_refused(&a, &b);
    assert_refused(&b, &a);
    // The same description loaded twice makes two models.
    assert_refused(&a, &load(TURN_SLIDE));
}

#[test]
fn a_model_with_more_bodies_is_refused_not_a_panic() {
    let (small, big) = (
        load(&pendulum_urdf(2, 0.5, 1.0)),
        load(&pendulum_urdf(5, 0.5, 1.0)),
    );
    assert_refused(&small, &big);
    assert_refused(&big, &small);
}

#[test]
fn mimic_and_ignore_mimic_variants_are_different_models() {
    let text = TURN_SLIDE.replace(
        r#"<limit lower="-1" upper="1" effort="1" velocity="1"/>"#,
        r#"<limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="turn" multiplier="0.5"/>"#,
    );
    let mimic = load(&text);
    let options = ModelOptions {
        ignore_mimic: true,
        ..ModelOptions::default()
    };
    let independent = urdf::model_from_str(&text, &options).unwrap();
    assert!(mimic.has_mimic() && !independent.has_mimic());
    assert_refused(&mimic, &independent);
    assert_refused(&independent, &mimic);
}

#[test]
fn a_clone_and_a_regravitated_model_are_the_same_model() {
    let a = load(TURN_SLIDE);
    let mut own = Workspace::new(&a);
    let expected = every_algorithm(&a, &mut own);
    assert!(expected.iter().all(|(_, r)| r.is_ok()), "{expected:?}");
    let mut ws = Workspace::new(&a);
    for (call, result) in every_algorithm(&a.clone(), &mut ws) {
        assert!(result.is_ok(), "{call} on a clone: {result:?}");
    }
    let upside_down = a
        .clone()
        .with_gravity(Vector3::new(0.0, 0.0, 9.81))
        .unwrap();
    let q = [0.3, 0.2];
    let g = gravity(&upside_down, &mut ws, &q).unwrap().to_vec();
    let g_own = gravity(&a, &mut own, &q).unwrap();
    assert!(
        g.iter().zip(g_own).all(|(x, y)| (x + y).abs() < 1e-12),
        "{g:?}"
    );
}

#[test]
fn the_error_names_both_models() {
    let other_name = TURN_SLIDE.replace(r#"<robot name="turn_slide">"#, r#"<robot name="other">"#);
    let (a, b) = (load(TURN_SLIDE), load(&other_name));
    let mut ws = Workspace::new(&a);
    let err = rnea(&b, &mut ws, &[0.0; 2], &[0.0; 2], &[0.0; 2]).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("made for model 'turn_slide'") && text.contains("the model given, 'other'"),
        "{text}"
    );
    assert_eq!(ws.check(&b), Err(err));
    assert_eq!(ws.check(&a), Ok(()));
}

#[test]
fn the_simulator_and_requests_refuse_another_model() {
    let (a, b) = (load(TURN_SLIDE), turned_slide());
    let mut sim = Simulator::new(&a, SimConfig::default()).unwrap();
    let mut state = State::at_rest(&a, a.neutral());
    sim.step(&a, &mut state, &[0.0; 2]).unwrap();
    let mut state_b = State::at_rest(&b, b.neutral());
    match sim.step(&b, &mut state_b, &[0.0; 2]) {
        Err(SimError::Dynamics {
            source: DynamicsError::ForeignWorkspace { .. },
            ..
        }) => {}
        other => panic!("a simulator of another model stepped: {other:?}"),
    }
    assert!(matches!(
        sim.energy(&b, &state_b),
        Err(SimError::Dynamics {
            source: DynamicsError::ForeignWorkspace { .. },
            ..
        })
    ));
    let mut ws = Workspace::new(&a);
    for line in [
        r#"{"op":"gravity","q":[0,0]}"#,
        r#"{"op":"frame_jacobian","q":[0,0],"frame":"b","reference":"local"}"#,
    ] {
        let answer = answer_line(&b, &mut ws, line.as_bytes());
        let error = answer["error"].as_str().unwrap_or_default();
        assert!(
            error.contains("the workspace was made for model"),
            "{line}: {answer}"
        );
    }
}

/// A `Frame` found in one model and used with another (each with its own workspace) is refused
/// by every function taking a frame, even when its link index is beyond the other model's links
/// (an index that would otherwise be read out of bounds), and a frame of a clone is accepted.
#[test]
fn a_frame_of_another_model_is_refused() {
    let long = load(&pendulum_urdf(6, 0.5, 1.0));
    let short = load(&pendulum_urdf(2, 0.5, 1.0));
    let last = long.links().last().unwrap().name.clone();
    let frame = find_frame(&long, &last).unwrap();
    assert!(
        frame.link() >= short.links().len(),
        "the frame's index is out of the short model"
    );
    let mut ws = Workspace::new(&short);
    let q = short.neutral();
    let v = vec![0.1; short.nv()];
    let mut outcomes: Vec<(&str, Result<(), DynamicsError>)> = vec![
        (
            "frame_placement",
            frame_placement(&short, &mut ws, &q, &frame).map(drop),
        ),
        (
            "frame_classical_acceleration",
            frame_classical_acceleration(
                &short,
                &mut ws,
                &q,
                &v,
                &v,
                &frame,
                ReferenceFrame::Local,
            )
            .map(drop),
        ),
    ];
    for reference in [
        ReferenceFrame::World,
        ReferenceFrame::Local,
        ReferenceFrame::LocalWorldAligned,
    ] {
        outcomes.push((
            "frame_jacobian",
            frame_jacobian(&short, &mut ws, &q, &frame, reference).map(drop),
        ));
    }
    let mut all = joint_jacobians(&short, &mut ws, &q).unwrap();
    outcomes.push(("JointJacobians::placement", all.placement(&frame).map(drop)));
    outcomes.push((
        "JointJacobians::frame_jacobian",
        all.frame_jacobian(&frame, ReferenceFrame::World).map(drop),
    ));
    for (what, outcome) in outcomes {
        match outcome {
            Err(e @ DynamicsError::ForeignFrame { .. }) => {
                assert!(e.to_string().contains("find_frame"), "{what}: {e}")
            }
            other => panic!("{what}: a foreign frame gave {other:?}"),
        }
    }
    let clone = long.clone();
    let mut ws = Workspace::new(&clone);
    assert!(frame_placement(&clone, &mut ws, &clone.neutral(), &frame).is_ok());
}
