//! Failure is loud: every bad input or singular model gives an error naming the joint, the
//! coordinate or the element, never NaN and never a panic.

use spatial_dynamics_core::algorithms::{crba, forward_dynamics, gravity, rnea};
use spatial_dynamics_core::{
    urdf, DynamicsError, Externals, ForwardDynamicsMethod, ModelError, ModelOptions, Workspace,
};

fn model(text: &str) -> Result<spatial_dynamics_core::Model, ModelError> {
    urdf::model_from_str(text, &ModelOptions::default())
}

const ARM2: &str = r#"<robot name="a"><link name="world"/>
  <joint name="shoulder" type="revolute"><parent link="world"/><child link="l1"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
  <link name="l1"><inertial><origin xyz="0 0 -0.2"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial></link>
  <joint name="slide" type="prismatic"><parent link="l1"/><child link="l2"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="5" velocity="1"/></joint>
  LEAF
</robot>"#;

#[test]
fn massless_leaf_behind_a_prismatic_joint_is_named() {
    // Nothing with mass moves when 'slide' moves: H is singular there.
    let m = model(&ARM2.replace("LEAF", r#"<link name="l2"/>"#)).unwrap();
    let mut ws = Workspace::new(&m);
    let (q, v, tau) = ([0.3, 0.1], [0.2, -0.1], [1.0, 1.0]);
    for method in ForwardDynamicsMethod::ALL {
        let err =
            forward_dynamics(&m, &mut ws, &q, &v, &tau, method, &Externals::none()).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("slide"), "{method}: {text}");
        match method {
            // The leaf's articulated inertia is zero: D = Sᵀ I^A S is exactly 0.
            ForwardDynamicsMethod::Aba => assert_eq!(
                err,
                DynamicsError::SingularArticulatedInertia {
                    joint: "slide".into(),
                    body: "l2".into(),
                    coordinate: "slide".into(),
                    pivot: 0.0,
                }
            ),
            _ => assert!(matches!(err, DynamicsError::SingularMassMatrix { .. })),
        }
    }
    // Inverse dynamics is still well defined.
    assert!(rnea(&m, &mut ws, &q, &v, &tau).is_ok());
}

#[test]
fn aba_names_the_pivot_of_a_floating_point_mass() {
    // A point mass on a floating joint: D = I^A is positive along the three translations
    // (`v[0..3]`, pivots m) and zero along the rotations: the fourth pivot, about 'x', fails.
    let m = urdf::model_from_str(r#"<robot name="p"><link name="ball"><inertial><mass value="2"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link></robot>"#, &ModelOptions { floating_base: true, ..Default::default() }).unwrap();
    let mut ws = Workspace::new(&m);
    let (q, v, tau) = (m.neutral(), [0.0; 6], [0.0; 6]);
    let err = forward_dynamics(
        &m,
        &mut ws,
        &q,
        &v,
        &tau,
        ForwardDynamicsMethod::Aba,
        &Externals::none(),
    )
    .unwrap_err();
    match &err {
        DynamicsError::SingularArticulatedInertia {
            joint,
            body,
            coordinate,
            pivot,
        } => {
            assert_eq!((joint.as_str(), body.as_str()), ("root_joint", "ball"));
            assert_eq!(coordinate, "root_joint[3]");
            assert!(pivot.abs() < 1e-12, "{err}");
        }
        other => panic!("{other:?}"),
    }
    let text = err.to_string();
    assert!(
        text.contains("(body 'ball')") && text.contains("coordinate 'root_joint[3]'"),
        "{text}"
    );
}

#[test]
fn bad_vectors_are_named() {
    let m = model(&ARM2.replace("LEAF", r#"<link name="l2"><inertial><mass value="0.5"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>"#)).unwrap();
    let mut ws = Workspace::new(&m);
    let err = rnea(&m, &mut ws, &[0.0], &[0.0, 0.0], &[0.0, 0.0]).unwrap_err();
    assert_eq!(err.to_string(), "q has 1 values, the model needs 2");
    let err = rnea(&m, &mut ws, &[0.0, 0.0], &[0.0, f64::NAN], &[0.0, 0.0]).unwrap_err();
    assert!(err.to_string().contains("v[1] (slide)"), "{err}");
    let err = gravity(&m, &mut ws, &[f64::INFINITY, 0.0]).unwrap_err();
    assert!(err.to_string().contains("q[0] (shoulder) is inf"), "{err}");
    let err = forward_dynamics(
        &m,
        &mut ws,
        &[0.0; 2],
        &[0.0; 2],
        &[0.0; 3],
        ForwardDynamicsMethod::Crba,
        &Externals::none(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("tau has 3 values"), "{err}");
    // Overflow inside the algorithm is caught at the output, not passed on as inf or NaN.
    let err = rnea(&m, &mut ws, &[0.0; 2], &[1e200, 1e200], &[0.0; 2]).unwrap_err();
    assert!(
        matches!(err, DynamicsError::NonFiniteResult { .. }),
        "{err}"
    );
    assert!(crba(&m, &mut ws, &[0.1, 0.2]).is_ok());
}

#[test]
fn integrate_names_the_vector_of_the_wrong_length() {
    let m = urdf::model_from_str(r#"<robot name="b"><link name="b"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#, &ModelOptions { floating_base: true, ..Default::default() }).unwrap();
    let (q, v) = (m.neutral(), [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
    let mut out = [0.0; 7];
    m.integrate(&q, &v, 0.5, &mut out).unwrap();
    assert_eq!(out[2], 0.5, "the base rises along z: {out:?}");
    // Each vector of the wrong length in turn: its error, and `out` untouched.
    let refused = |q: &[f64], v: &[f64], n: usize| {
        let mut out = vec![-1.0; n];
        let err = m.integrate(q, v, 0.5, &mut out).unwrap_err();
        assert!(out.iter().all(|&x| x == -1.0), "out was written: {out:?}");
        err
    };
    for (err, vector, expected, got) in [
        (refused(&q[..6], &v, 7), "q", 7, 6),
        (refused(&q, &v[..5], 7), "v", 6, 5),
        (refused(&q, &v, 8), "out", 7, 8),
    ] {
        assert_eq!(
            err,
            DynamicsError::Length {
                vector,
                expected,
                got
            }
        );
        assert_eq!(
            err.to_string(),
            format!("{vector} has {got} values, the model needs {expected}")
        );
    }
}

#[test]
fn a_zero_quaternion_is_refused() {
    let m = urdf::model_from_str(r#"<robot name="b"><link name="b"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#, &ModelOptions { floating_base: true, ..Default::default() }).unwrap();
    let mut ws = Workspace::new(&m);
    let err = gravity(&m, &mut ws, &[0.0; 7]).unwrap_err();
    assert!(err.to_string().contains("root_joint"), "{err}");
}

#[test]
fn bad_descriptions_are_named() {
    let cases = [
        ("<robot", "cannot parse"),
        ("<notrobot/>", "<notrobot>"),
        (
            r#"<robot name="x"><link name="a"/><link name="b"/></robot>"#,
            "several root links (a, b)",
        ),
        (
            r#"<robot name="x"><link name="a"/><link name="a"/></robot>"#,
            "link 'a' is defined twice",
        ),
        (
            r#"<robot name="x"><link name="a"/><joint name="j" type="fixed"><parent link="a"/><child link="nope"/></joint></robot>"#,
            "child link 'nope' does not exist",
        ),
        (
            r#"<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint><joint name="k" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#,
            "cycle",
        ),
        (
            r#"<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint></robot>"#,
            "joint 'j': <axis xyz> (0e0, 0e0, 0e0)",
        ),
        (
            r#"<robot name="x"><link name="a"><inertial><mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#,
            "link 'a': mass",
        ),
        (
            r#"<robot name="x"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/><limit lower="0" upper="1" effort="1" velocity="1"/><mimic joint="ghost"/></joint></robot>"#,
            "mimic joint 'j' follows 'ghost'",
        ),
    ];
    for (text, expected) in cases {
        let err = model(text).unwrap_err().to_string();
        assert!(
            err.contains(expected),
            "for {text}\n got: {err}\n expected to contain: {expected}"
        );
    }
}

#[test]
fn drawing_details_never_refuse_a_model() {
    // A <texture/> without a file name (as iCub's URDF has) and meshes that do not exist.
    let text = r#"<robot name="x"><material name="m"><texture/></material><link name="a"><visual><geometry><mesh filename="nowhere.dae"/></geometry><material name="n"><texture/></material></visual><collision><geometry><box size="1 1 1"/></geometry></collision></link></robot>"#;
    assert!(model(text).is_ok());
}

#[test]
fn doubtful_inertias_load_with_a_warning_naming_the_link() {
    // Principal moments 1, 1, 5 break I1 + I2 ≥ I3; real URDFs have such links (ANYmal's cameras).
    let text = r#"<robot name="x"><link name="a"/><link name="b"><inertial><mass value="1"/>
        <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5"/></inertial></link>
        <joint name="j" type="continuous"><parent link="a"/><child link="b"/></joint></robot>"#;
    let m = model(text).unwrap();
    assert_eq!(m.warnings().len(), 1, "{:?}", m.warnings());
    assert!(
        m.warnings()[0].contains("link 'b'") && m.warnings()[0].contains("triangle"),
        "{:?}",
        m.warnings()
    );
    let fine = model(&text.replace(r#"izz="5""#, r#"izz="1.5""#)).unwrap();
    assert!(fine.warnings().is_empty(), "{:?}", fine.warnings());
    let not_psd = model(&text.replace(r#"izz="5""#, r#"izz="-1""#)).unwrap();
    assert!(
        not_psd.warnings()[0].contains("not positive semi-definite"),
        "{:?}",
        not_psd.warnings()
    );
}

#[test]
fn a_subnormal_tip_mass_is_refused_by_aba_with_its_pivot() {
    // 1e-310 kg is subnormal: D⁻¹ would overflow. ABA refuses, naming the joint and the pivot;
    // CRBA still solves it.
    let text = |mass: &str| {
        format!(
            r#"<robot name="x"><link name="a"/>
        <link name="b"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.01"/></inertial></link>
        <link name="c"><inertial><origin xyz="0 0 -0.5"/><mass value="{mass}"/><inertia ixx="{mass}" ixy="0" ixz="0" iyy="{mass}" iyz="0" izz="{mass}"/></inertial></link>
        <joint name="j1" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/></joint>
        <joint name="j2" type="continuous"><parent link="b"/><child link="c"/><origin xyz="0 0 -1"/><axis xyz="0 1 0"/></joint></robot>"#
        )
    };
    let m = model(&text("1e-310")).unwrap();
    let mut ws = Workspace::new(&m);
    let err = forward_dynamics(
        &m,
        &mut ws,
        &[0.3, 0.2],
        &[0.0; 2],
        &[0.0; 2],
        ForwardDynamicsMethod::Aba,
        &Externals::none(),
    )
    .unwrap_err();
    let message = err.to_string();
    assert!(
        message.contains("'j2'") && !message.contains("inf"),
        "{message}"
    );
}

#[test]
fn deep_nesting_is_refused_without_overflowing_the_stack() {
    // 1 000 000 nested elements would keep an XML tree builder busy for more than 15 minutes of
    // CPU (each level costs more the deeper it is), and walking such a tree recursively
    // overflows the stack. They are refused from the token stream before any tree is built; the
    // test runs on a 256 KiB stack to show that no recursion over the depth is left.
    let depth = 1_000_000;
    let text = format!(
        r#"<robot name="x"><link name="a"/>{}{}</robot>"#,
        "<g>".repeat(depth),
        "</g>".repeat(depth)
    );
    let err = std::thread::Builder::new()
        .stack_size(256 << 10)
        .spawn(move || model(&text).unwrap_err().to_string())
        .unwrap()
        .join()
        .expect("no stack overflow");
    assert!(err.contains("nested more than 100 deep (at <g>)"), "{err}");
    // 100 levels are still fine (drawing elements of real URDFs nest about 6 deep).
    let text = format!(
        r#"<robot name="x"><link name="a"><visual>{}{}</visual></link></robot>"#,
        "<g>".repeat(97),
        "</g>".repeat(97)
    );
    assert!(model(&text).is_ok());
}

#[test]
fn eval_requests_that_are_not_json_or_not_utf8_are_answered_with_an_error() {
    use spatial_dynamics_core::requests::answer_line;
    let m = model(&ARM2.replace("LEAF", r#"<link name="l2"><inertial><mass value="0.5"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>"#)).unwrap();
    let mut ws = Workspace::new(&m);
    let cases: [(&[u8], &str); 7] = [
        (b"\xff\xfe{", "bad request"),
        (b"{\"op\":\"gravity\",\"q\":[\"\xff\"]}", "bad request"),
        (format!("{{\"op\":\"gravity\",\"q\":{}0{}}}", "[".repeat(200), "]".repeat(200)).into_bytes().leak(), "invalid type: sequence, expected f64 at line 1 column 21"),
        (b"{\"op\":\"gravity\",\"q\":[1e999, 0]}", "bad request"),
        (b"{\"op\":\"gravity\",\"q\":[0]}", "q has 1 values, the model needs 2"),
        (b"{\"op\":\"forward_dynamics\",\"q\":[0,0],\"v\":[0,0],\"tau\":[0,0],\"method\":\"magic\"}", "magic"),
        (b"{\"op\":\"inverse_dynamics\",\"q\":[0,0],\"v\":[1e200,1e200],\"a\":[0,0]}", "overflowed to a non-finite value"),
    ];
    for (line, expected) in cases {
        let answer = answer_line(&m, &mut ws, line);
        let error = answer["error"]
            .as_str()
            .unwrap_or_else(|| panic!("{answer}"));
        assert!(
            error.contains(expected),
            "{}: {error}",
            String::from_utf8_lossy(line)
        );
    }
}

/// A revolute joint carrying a prismatic one: `H` holds `m x²` for the slide's coordinate `x`.
const TURN_SLIDE: &str = include_str!("models/turn_slide.urdf");

#[test]
fn finite_inputs_that_overflow_are_errors_not_infinities() {
    // Found by fuzzing `eval`: {"op":"mass_matrix","q":[0,1e200]} answered {"M":[[null,0.0],..]}
    // (CRBA had no check of its result), and forward dynamics at that state called the
    // articulated inertia "singular: nothing with mass moves" when it had overflowed.
    use spatial_dynamics_core::algorithms::energy;
    use spatial_dynamics_core::algorithms::kinematics::{body_motion, body_placements};
    use spatial_dynamics_core::requests::answer_line;
    let m = model(TURN_SLIDE).unwrap();
    let mut ws = Workspace::new(&m);
    let answer = answer_line(&m, &mut ws, br#"{"op":"mass_matrix","q":[0,1e200]}"#);
    assert_eq!(
        answer["error"].as_str(),
        Some("mass matrix at 'turn' overflowed to a non-finite value"),
        "{answer}"
    );
    let err = crba(&m, &mut ws, &[0.0, 1e200]).unwrap_err();
    assert!(
        matches!(err, DynamicsError::NonFiniteResult { .. }),
        "{err}"
    );
    for method in ForwardDynamicsMethod::ALL {
        let err = forward_dynamics(
            &m,
            &mut ws,
            &[0.0, 1e200],
            &[0.0; 2],
            &[0.0; 2],
            method,
            &Externals::none(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            (err.contains("'turn'") || err.contains("'slide'")) && err.contains("overflowed"),
            "{method}: {err}"
        );
        assert!(!err.contains("nothing with mass"), "{method}: {err}");
    }
    // Kinetic energy ½ m v² at v = 1e200, and body velocities and placements that overflow.
    let err = energy(&m, &mut ws, &[0.0; 2], &[0.0, 1e200]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "kinetic energy at 'slide' overflowed to a non-finite value"
    );
    let err = body_motion(&m, &mut ws, &[0.0, 1e200], &[1e200, 0.0]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "velocity at 'slide' overflowed to a non-finite value"
    );
    let far = model(&TURN_SLIDE.replace(
        r#"<child link="b"/>"#,
        r#"<child link="b"/><origin xyz="1e308 0 0"/>"#,
    ))
    .unwrap();
    let mut ws = Workspace::new(&far);
    let err = body_placements(&far, &mut ws, &[0.0, 1e308]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "placement at 'slide' overflowed to a non-finite value"
    );
    // Sane states still answer.
    assert!(crba(&m, &mut ws_for(&m), &[0.3, 2.0]).is_ok());
}

/// A robot with no moving joint (one link, or everything fixed) has no coordinates: every
/// algorithm answers with empty vectors and a 0 × 0 mass matrix, none panics.
#[test]
fn a_model_without_coordinates_answers_every_algorithm() {
    let m = model(
        r#"<robot name="r"><link name="a"><inertial><mass value="1"/>
        <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"#,
    )
    .unwrap();
    assert_eq!((m.nq(), m.nv()), (0, 0));
    let mut ws = ws_for(&m);
    assert!(rnea(&m, &mut ws, &[], &[], &[]).unwrap().is_empty());
    assert!(gravity(&m, &mut ws, &[]).unwrap().is_empty());
    assert_eq!(crba(&m, &mut ws, &[]).unwrap().shape(), (0, 0));
    for method in ForwardDynamicsMethod::ALL {
        let qdd = forward_dynamics(&m, &mut ws, &[], &[], &[], method, &Externals::none());
        assert!(qdd.unwrap().is_empty(), "{method:?}");
    }
}

fn ws_for(m: &spatial_dynamics_core::Model) -> Workspace {
    Workspace::new(m)
}
