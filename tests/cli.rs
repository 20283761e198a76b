//! The command-line contract, run as a process: `model --json`, the `eval` request loop, the
//! global model options and reductions, `simulate` and `bench`'s JSON.

use spatial_dynamics_core::sampling::Rng;

use serde_json::Value;
use spatial_dynamics_core::algorithms::rnea;
use spatial_dynamics_core::{urdf, ModelOptions, Workspace};
use std::io::Write;
use std::process::{Command, Stdio};

const TREE: &str = "src/core/tests/models/tree.urdf";

fn run(args: &[&str], stdin: &str) -> (bool, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_spatial_dynamics"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(stdin.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    (
        out.status.success(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

/// Runs the program, which must succeed; its standard output.
fn run_ok(args: &[&str], stdin: &str) -> String {
    let (ok, out, err) = run(args, stdin);
    assert!(ok, "{args:?}: {err}");
    out
}

/// [`run_ok`] printing one JSON value: the value, and the text for messages.
fn run_json(args: &[&str], stdin: &str) -> (Value, String) {
    let out = run_ok(args, stdin);
    let v = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    (v, out)
}

/// Runs the program, which must fail with an error message containing `needle`.
fn fails_with(args: &[&str], stdin: &str, needle: &str) {
    let (ok, _, err) = run(args, stdin);
    assert!(!ok && err.contains(needle), "{args:?}: {err}");
}

/// `eval` with `args`, one request a line: one JSON answer a request, and the text.
fn eval_lines<S: AsRef<str>>(args: &[&str], requests: &[S]) -> (Vec<Value>, String) {
    let lines: Vec<&str> = requests.iter().map(AsRef::as_ref).collect();
    let out = run_ok(&[&["eval"], args].concat(), &(lines.join("\n") + "\n"));
    let answers: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(answers.len(), requests.len(), "{out}");
    (answers, out)
}

/// Each `(line, text)`: the answer on that line is an error containing the text.
fn assert_errors(answers: &[Value], expected: &[(usize, &str)]) {
    for &(i, text) in expected {
        let error = answers[i]["error"]
            .as_str()
            .unwrap_or_else(|| panic!("line {i}: {}", answers[i]));
        assert!(error.contains(text), "line {i}: {error}");
    }
}

/// `bench --json` with `args`, quick (`--min-time 0.001`): its report.
fn bench_json(args: &[&str]) -> (Value, String) {
    run_json(
        &[&["bench", "--json", "--min-time", "0.001"], args].concat(),
        "",
    )
}

#[test]
fn model_json_lists_coordinate_joints_in_order() {
    let (v, _) = run_json(&["model", "--urdf", TREE, "--json"], "");
    assert_eq!(v["nq"], 8);
    assert_eq!(v["nv"], 8);
    let joints = v["joints"].as_array().unwrap();
    let names: Vec<&str> = joints.iter().map(|j| j["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "base",
            "left_shoulder",
            "left_slide",
            "right_shoulder",
            "right_wrist",
            "head_tilt"
        ]
    );
    assert_eq!(
        joints[0],
        serde_json::json!({"name": "base", "type": "planar", "q_index": 0, "nq": 3, "v_index": 0, "nv": 3})
    );
    assert_eq!(joints[3]["type"], "continuous");
    let (v, _) = run_json(&["model", "--urdf", TREE, "--json", "--floating-base"], "");
    assert_eq!(
        v["joints"][0],
        serde_json::json!({"name": "root_joint", "type": "floating", "q_index": 0, "nq": 7, "v_index": 0, "nv": 6})
    );
}

#[test]
fn eval_answers_every_line_in_order_and_survives_bad_ones() {
    let requests = [
        r#"{"op":"gravity","q":[0,0,0,0.1,0.2,0.3,0.4,0.5]}"#,
        r#"{"op":"gravity","q":[0,0]}"#,
        r#"{"op":"fly","q":[]}"#,
        r#"{"op":"gravity","q":[NaN,0,0,0,0,0,0,0]}"#,
        r#"not json"#,
        r#"{"op":"forward_dynamics","q":[0,0,0,0,0,0,0,0],"v":[0,0,0,0,0,0,0,0],"tau":[0,0,0,0,0,0,0,0],"method":"magic"}"#,
        r#"{"op":"inverse_dynamics","q":[0,0,0,0,0,0,0,0],"v":[0,0,0,0,0,0,0,0],"a":[1,0,0,0,0,0,0,1e999]}"#,
        r#"{"op":"mass_matrix","q":[0,0,0,0,0,0,0,0]}"#,
        r#"{"op":"forward_dynamics","q":[0,0,0,0,0,0,0,0],"v":[0,0,0,0,0,0,0,0],"tau":[0,0,0,0,0,0,0,0],"method":"crba"}"#,
    ];
    let (answers, _) = eval_lines(&["--urdf", TREE], &requests);
    assert_eq!(answers[0]["tau"].as_array().unwrap().len(), 8);
    assert_errors(
        &answers,
        &[
            (1, "q has 2 values, the model needs 8"),
            (2, "unknown op 'fly' (one of: inverse_dynamics, "),
            (3, "bad request"),
            (4, "bad request"),
            (5, "unknown forward-dynamics method 'magic'"),
            (6, "bad request"),
        ],
    );
    let m = answers[7]["M"].as_array().unwrap();
    assert_eq!(m.len(), 8);
    assert!(m.iter().all(|row| row.as_array().unwrap().len() == 8));
    assert_eq!(answers[8]["a"].as_array().unwrap().len(), 8);
}

/// A bad value is placed by its column; a field an op does not take, a duplicate field and a
/// request that is not an object are named; a line longer than the limit is answered and
/// skipped without being held, and the requests after it are answered.
#[test]
fn eval_names_where_a_request_is_wrong() {
    let long = format!(r#"{{"op":"gravity","q":[{}0]}}"#, "0,".repeat(9 << 20));
    let requests = [
        r#"{"op":"gravity","q":[0,0,null,0,0,0,0,0]}"#.to_string(),
        r#"{"op":"gravity","q":[0,0,0,0,0,0,0,0],"frame":"link1"}"#.to_string(),
        r#"{"op":"gravity","q":[0],"q":[0,0,0,0,0,0,0,0]}"#.to_string(),
        r#"["gravity",[0,0,0,0,0,0,0,0]]"#.to_string(),
        long,
        r#"{"op":"gravity","q":[0,0,0,0,0,0,0,0]}"#.to_string(),
    ];
    let (answers, _) = eval_lines(&["--urdf", TREE], &requests);
    assert_errors(
        &answers,
        &[
            (0, "invalid type: null, expected f64 at line 1 column 29"),
            (1, "op gravity takes no field 'frame' (its fields: q)"),
            (2, "duplicate field `q`"),
            (3, "a request is one JSON object with an \"op\" field"),
            (4, "line 5 is longer than 16777216 bytes"),
        ],
    );
    assert_eq!(answers[5]["tau"].as_array().unwrap().len(), 8);
}

#[test]
fn eval_floats_round_trip_exactly() {
    let model =
        urdf::model_from_file(std::path::Path::new(TREE), &ModelOptions::default()).unwrap();
    let mut ws = Workspace::new(&model);
    let mut rng = Rng::new(30);
    let (q, v, a) = (rng.vector(8, 1.0), rng.vector(8, 1.0), rng.vector(8, 1.0));
    let expected = rnea(&model, &mut ws, &q, &v, &a).unwrap().to_vec();
    let request = serde_json::json!({"op": "inverse_dynamics", "q": q, "v": v, "a": a}).to_string();
    let (answer, _) = run_json(&["eval", "--urdf", TREE], &(request + "\n"));
    let tau: Vec<f64> = answer["tau"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(
        tau, expected,
        "printed values must parse back to the same f64"
    );
}

#[test]
fn gravity_option_and_unusable_urdf() {
    let out = run_ok(
        &["eval", "--builtin", "pendulum:1", "--gravity", "0,0,0"],
        "{\"op\":\"gravity\",\"q\":[1.0]}\n",
    );
    assert_eq!(out.trim(), r#"{"tau":[0.0]}"#);
    fails_with(
        &["model", "--urdf", "/nonexistent.urdf", "--json"],
        "",
        "/nonexistent.urdf",
    );
    let dir = std::env::temp_dir().join(format!("sd_cli_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("two_roots.urdf");
    std::fs::write(
        &bad,
        r#"<robot name="x"><link name="a"/><link name="b"/></robot>"#,
    )
    .unwrap();
    fails_with(
        &["eval", "--urdf", bad.to_str().unwrap()],
        "",
        "several root links (a, b)",
    );
    fails_with(&["model", "--gravity", "0,0", "--json"], "", "--gravity");
}

#[test]
fn simulate_writes_the_trajectory_and_reports_divergence() {
    let dir = std::env::temp_dir().join(format!("sd_sim_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("pendulum.csv");
    let output = csv.to_str().unwrap();
    // `simulate` with `args`, writing the trajectory to `output`.
    let simulate = |args: &[&'static str]| [&["simulate"], args, &["--output", output]].concat();
    run_ok(
        &simulate(&[
            "--scene",
            "pendulum:2",
            "--integrator",
            "rk4",
            "--dt",
            "0.001",
            "--duration",
            "0.5",
            "--initial",
            r#"{"joint1": 0.5}"#,
        ]),
        "",
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "time,joint1.position,joint2.position,joint1.velocity,joint2.velocity,energy"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 501);
    assert_eq!(rows[0][..5], [0.0, 0.5, 0.0, 0.0, 0.0]);
    assert!((rows[500][0] - 0.5).abs() < 1e-12);
    // A passive double pendulum under RK4 at 1 kHz keeps its energy.
    let drift = rows
        .iter()
        .map(|r| (r[5] - rows[0][5]).abs())
        .fold(0.0, f64::max);
    assert!(drift < 1e-6, "energy drift {drift}");
    // Semi-implicit Euler past ωh = 2 diverges, and says so.
    let (ok, _, err) = run(
        &simulate(&[
            "--scene",
            "pendulum:1",
            "--integrator",
            "semi_implicit_euler",
            "--dt",
            "0.6",
            "--duration",
            "99.6",
            "--initial",
            r#"{"joint1": 0.05}"#,
        ]),
        "",
    );
    assert!(!ok);
    assert!(
        err.contains("diverged at t =") && err.contains("creating energy"),
        "{err}"
    );
    fails_with(
        &simulate(&[
            "--scene",
            "pendulum:1",
            "--integrator",
            "rk4",
            "--dt",
            "0.01",
            "--duration",
            "1",
            "--initial",
            r#"{"elbow": 1}"#,
        ]),
        "",
        "unknown joint 'elbow'",
    );
    fails_with(
        &simulate(&[
            "--integrator",
            "leapfrog",
            "--dt",
            "0.01",
            "--duration",
            "1",
        ]),
        "",
        "unknown integrator 'leapfrog'",
    );
}

#[test]
fn lock_reduces_the_model() {
    let (v, _) = run_json(
        &[
            "model",
            "--lock",
            "joint7=0.5",
            "--lock",
            "joint6=-0.2",
            "--json",
        ],
        "",
    );
    assert_eq!(v["nv"], 5);
    let out = run_ok(&["model", "--lock", "joint7=0.5"], "");
    assert!(out.contains("locked: 'joint7' at 0.5"), "{out}");
    fails_with(
        &["model", "--lock", "joint9=0.5"],
        "",
        "cannot lock joint 'joint9'",
    );
    fails_with(&["model", "--lock", "joint7"], "", "--lock 'joint7'");
}

#[test]
fn root_and_tip_reduce_the_model_and_say_so() {
    let (v, _) = run_json(
        &["model", "--root", "link2", "--tip", "link5", "--json"],
        "",
    );
    assert_eq!(v["nv"], 3);
    let r = &v["reduction"];
    assert_eq!(r["root"], "link2");
    assert_eq!(r["frozen_joints"][0][0], "joint1");
    assert_eq!(r["payload_links"][0], "link6");
    let out = run_ok(&["model", "--tip", "link3"], "");
    assert!(
        out.contains("reduced: frozen (outside the kept part): joint4, joint5, joint6, joint7"),
        "{out}"
    );
    // Every command takes the reduction: eval answers for the three joints kept.
    let (answer, out) = run_json(
        &["eval", "--tip", "link3"],
        "{\"op\": \"gravity\", \"q\": [0.1, 0.2, 0.3]}\n",
    );
    assert_eq!(answer["tau"].as_array().map(Vec::len), Some(3), "{out}");
    fails_with(
        &["model", "--tip", "nowhere"],
        "",
        "tip: there is no link named 'nowhere'",
    );
}

/// `bench --json` names the instruction set it timed: the processor's best without a flag (the
/// library's own detection), the baseline with `--baseline-instructions`, for the kernels and
/// for the simulation alone.
#[test]
fn bench_reports_the_instruction_set_it_timed() {
    let best = spatial_dynamics_core::InstructionSet::best().name();
    for (kernels, flags, expected) in [
        ("fd_aba", &[][..], best),
        ("fd_aba", &["--baseline-instructions"][..], "baseline"),
        ("sim_rk4", &[][..], best),
        ("sim_rk4", &["--baseline-instructions"][..], "baseline"),
    ] {
        let args = [
            &["--builtin", "pendulum:2", "--states", "4", "--repeats", "1"][..],
            &["--kernels", kernels, "--sim-steps", "10"][..],
            flags,
        ]
        .concat();
        let (v, out) = bench_json(&args);
        assert_eq!(v["instruction_set"], expected, "{kernels} {flags:?}: {out}");
        assert!(v["ns_per_call"][kernels].as_f64().is_some(), "{out}");
    }
}

#[test]
fn bench_prints_the_json_contract() {
    let (v, out) = bench_json(&[
        "--builtin",
        "pendulum:3",
        "--states",
        "1000",
        "--repeats",
        "3",
    ]);
    assert_eq!(v["nv"], 3);
    assert_eq!(v["frame"], "link3", "frame_jacobian times the deepest link");
    for kernel in [
        "rnea",
        "crba",
        "fd_aba",
        "fd_crba",
        "fd_rnea_columns",
        "gravity",
        "frame_jacobian",
        "center_of_mass",
    ] {
        let ns = v["ns_per_call"][kernel]
            .as_f64()
            .unwrap_or_else(|| panic!("{kernel} missing in {out}"));
        assert!(ns > 0.0 && ns.is_finite(), "{kernel}: {ns}");
    }
    // Mimic joints: aba refuses, reported as null.
    let (v, out) = bench_json(&[
        "--builtin",
        "mimic_gripper",
        "--states",
        "1000",
        "--repeats",
        "1",
    ]);
    assert!(v["ns_per_call"]["fd_aba"].is_null(), "{out}");
    assert_ne!(v["auto_method"], "aba", "{out}");
    // A reduction: the full model is timed beside it, with the speed-up.
    let (v, out) = bench_json(&["--tip", "link3", "--states", "100", "--repeats", "1"]);
    assert_eq!(
        (v["nv"].as_u64(), v["full"]["nv"].as_u64()),
        (Some(3), Some(7)),
        "{out}"
    );
    for kernel in ["rnea", "crba", "fd_aba", "gravity"] {
        let (ours, full, up) = (
            v["ns_per_call"][kernel].as_f64().unwrap(),
            v["full"]["ns_per_call"][kernel].as_f64().unwrap(),
            v["speedup"][kernel].as_f64().unwrap(),
        );
        // `speedup` is printed to two decimals, the times to 0.1 ns.
        assert!(
            (up - full / ours).abs() <= 0.005 + 0.01 * up,
            "{kernel}: {out}"
        );
    }
    // `--kernels` times only those named (`rnea_rows` only when named: ns per state, no FLOP
    // count); a name it does not know is an error naming it.
    let (v, out) = bench_json(&[
        "--kernels",
        "rnea,center_of_mass,rnea_rows",
        "--states",
        "10",
        "--repeats",
        "1",
    ]);
    let timed: Vec<&String> = v["ns_per_call"].as_object().unwrap().keys().collect();
    assert_eq!(timed, ["center_of_mass", "rnea", "rnea_rows"], "{out}");
    assert!(
        v["ns_per_call"]["rnea_rows"].as_f64().unwrap() > 0.0,
        "{out}"
    );
    assert!(v["flops_per_call"]["rnea_rows"].is_null(), "{out}");
    fails_with(
        &[
            "bench",
            "--json",
            "--kernels",
            "rnea,nope",
            "--states",
            "10",
        ],
        "",
        "unknown kernel 'nope'",
    );
    // A massless floating root: no forward dynamics, so no method for `auto`, but the
    // kinematics are timed all the same.
    let (v, out) = bench_json(&[
        "--builtin",
        "pendulum:2",
        "--floating-base",
        "--kernels",
        "frame_jacobian",
        "--states",
        "10",
        "--repeats",
        "1",
    ]);
    assert!(
        v["ns_per_call"]["frame_jacobian"].as_f64().is_some(),
        "{out}"
    );
    assert!(v["auto_method"].is_null(), "{out}");
    let reason = v["auto_method_error"].as_str().unwrap_or_default();
    assert!(reason.contains("singular"), "{out}");
}

/// The frame requests' contract: shapes, the rotation printed by rows (link axes in world
/// coordinates, checked on a pendulum turned by θ about y: `R_y(θ)`), `[linear; angular]`
/// rows, and errors that name the unknown link (listing the known ones) or reference.
#[test]
fn eval_answers_frame_requests() {
    let t: f64 = 0.3;
    let requests = [
        format!(r#"{{"op":"frame_placement","q":[{t}],"frame":"link1"}}"#),
        format!(r#"{{"op":"frame_jacobian","q":[{t}],"frame":"link1","reference":"local"}}"#),
        format!(
            r#"{{"op":"frame_acceleration","q":[{t}],"v":[2],"a":[0],"frame":"link1","reference":"local_world_aligned"}}"#
        ),
        format!(r#"{{"op":"center_of_mass","q":[{t}]}}"#),
        format!(r#"{{"op":"frame_placement","q":[{t}],"frame":"hand"}}"#),
        format!(r#"{{"op":"frame_jacobian","q":[{t}],"frame":"link1","reference":"body"}}"#),
        format!(
            r#"{{"op":"frame_acceleration","q":[{t}],"v":[0],"a":[0],"frame":"link1","reference":"world"}}"#
        ),
        format!(r#"{{"op":"frame_jacobian","q":[{t}],"frame":"link1"}}"#),
    ];
    let (answers, _) = eval_lines(&["--builtin", "pendulum:1"], &requests);
    let (s, c) = t.sin_cos();
    let rotation = serde_json::json!([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]);
    let close = |a: &Value, b: &Value| {
        let (a, b) = (a.as_array().unwrap(), b.as_array().unwrap());
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| match (x.as_f64(), y.as_f64()) {
                    (Some(x), Some(y)) => (x - y).abs() < 1e-15,
                    _ => x.is_array() && y.is_array(),
                })
    };
    let got = &answers[0]["rotation"];
    assert!((0..3).all(|r| close(&got[r], &rotation[r])), "{got}");
    assert!(close(
        &answers[0]["translation"],
        &serde_json::json!([0.0, 0.0, 0.0])
    ));
    // One revolute joint about y at the link origin: J = [0 0 0 0 1 0]ᵀ in its own axes.
    let j = answers[1]["J"].as_array().unwrap();
    assert_eq!(j.len(), 6);
    let column: Vec<f64> = j.iter().map(|row| row[0].as_f64().unwrap()).collect();
    assert_eq!(column, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    assert_eq!(answers[2]["acceleration"].as_array().unwrap().len(), 6);
    assert_eq!(answers[3]["J"].as_array().unwrap().len(), 3);
    assert!(answers[3]["mass"].as_f64().unwrap() > 0.0);
    assert_errors(
        &answers,
        &[
            (4, "no link named 'hand'; its links are: world, link1"),
            (5, "unknown reference 'body'"),
            (6, "'world'"),
            (7, "op frame_jacobian needs field 'reference'"),
        ],
    );
}

/// The derivative requests on a one-rod pendulum (1 kg, 1 m, about y, hanging along −z), whose
/// dynamics is `τ = (m l²/3) q̈ + m g (l/2) sin q`: `∂τ/∂q = m g (l/2) cos q`, `∂τ/∂q̇ = 0`,
/// `M = m l²/3`, and `q̈ = (τ − m g (l/2) sin q) / M` gives `∂q̈/∂q = −m g (l/2) cos q / M`,
/// `∂q̈/∂q̇ = 0`, `M⁻¹`; a bad request's error names the vector.
#[test]
fn eval_answers_derivative_requests() {
    let (q, g, inertia) = (0.4f64, 9.81, 1.0 / 3.0);
    let requests = [
        format!(r#"{{"op":"inverse_dynamics_derivatives","q":[{q}],"v":[0.7],"a":[-1.3]}}"#),
        format!(r#"{{"op":"forward_dynamics_derivatives","q":[{q}],"v":[0.7],"tau":[2.1]}}"#),
        format!(r#"{{"op":"forward_dynamics_derivatives","q":[{q}],"v":[0.7],"tau":[2.1, 1]}}"#),
        format!(r#"{{"op":"inverse_dynamics_derivatives","q":[{q}],"v":[0.7]}}"#),
    ];
    let (ok, out, _) = run(
        &["eval", "--builtin", "pendulum:1"],
        &(requests.join("\n") + "\n"),
    );
    assert!(ok);
    let answers: Vec<Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(answers.len(), requests.len(), "{out}");
    let gravity_slope = g * 0.5 * q.cos();
    for (answer, key, expected) in [
        (&answers[0], "dtau_dq", gravity_slope),
        (&answers[0], "dtau_dv", 0.0),
        (&answers[0], "M", inertia),
        (&answers[1], "ddq_dq", -gravity_slope / inertia),
        (&answers[1], "ddq_dv", 0.0),
        (&answers[1], "Minv", 1.0 / inertia),
    ] {
        let m = answer[key]
            .as_array()
            .unwrap_or_else(|| panic!("{key}: {answer}"));
        assert_eq!(m.len(), 1, "{key}: one row");
        let got = m[0].as_array().unwrap();
        assert_eq!(got.len(), 1, "{key}: one column");
        let got = got[0].as_f64().unwrap();
        assert!(
            (got - expected).abs() < 1e-12,
            "{key}: {got} against {expected}"
        );
    }
    let error = |i: usize| answers[i]["error"].as_str().unwrap_or_default().to_string();
    assert!(error(2).contains("tau"), "{}", answers[2]);
    assert!(error(3).contains("needs field 'a'"), "{}", answers[3]);
}

/// `model` whose reader goes away (`| head -1`) ends quietly; a built-in pendulum past the
/// URDF's link limit is refused before its text is made; `simulate` picks a method a mimic
/// model can take, and refuses `aba` on one before the run.
#[test]
fn commands_refuse_or_end_cleanly_before_doing_harm() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_spatial_dynamics"))
        .args(["model", "--builtin", "pendulum:2000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(out.status.success() && stderr.is_empty(), "{stderr}");

    fails_with(
        &["eval", "--builtin", "pendulum:100000000"],
        "",
        "the number of links must be 1 to",
    );

    let dir = std::env::temp_dir().join(format!("sd_cli_mimic_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("gripper.csv");
    let sim = |method: Option<&str>| {
        let mut args = vec![
            "simulate",
            "--builtin",
            "mimic_gripper",
            "--integrator",
            "rk4",
            "--dt",
            "0.01",
            "--duration",
            "0.05",
            "--output",
            csv.to_str().unwrap(),
        ];
        args.extend(method.map(|m| ["--method", m]).into_iter().flatten());
        run(&args, "")
    };
    let (ok, _, err) = sim(None);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 7);
    let (ok, _, err) = sim(Some("aba"));
    assert!(
        !ok && err.contains("--method aba cannot take a model with mimic joints"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `simulate` refuses before it writes: an output that is its URDF, sub-steps of 0, a duration
/// that is not whole steps or too many of them, an `--effort-until` that is not a time; a run
/// that fails at its initial state leaves an earlier output as it was; a floating base's
/// initial quaternion is normalised from the first row on.
#[test]
fn simulate_checks_its_arguments_before_writing() {
    let dir = std::env::temp_dir().join(format!("sd_sim_args_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let urdf = dir.join("arm.urdf");
    std::fs::copy("config/models/default_arm.urdf", &urdf).unwrap();
    let before = std::fs::read(&urdf).unwrap();
    let csv = dir.join("out.csv");
    // `simulate` on the copied arm writing `output`, `--dt 0.01 --duration 0.1` unless `extra`
    // gives either.
    let base = |output: &str, extra: &[&str]| -> Vec<String> {
        let mut args: Vec<String> = [
            "simulate",
            "--urdf",
            urdf.to_str().unwrap(),
            "--integrator",
            "rk4",
            "--output",
            output,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        for (flag, default) in [("--dt", "0.01"), ("--duration", "0.1")] {
            if !extra.contains(&flag) {
                args.extend([flag.to_string(), default.to_string()]);
            }
        }
        args.extend(extra.iter().map(|s| s.to_string()));
        args
    };
    let refused = |args: Vec<String>, needle: &str| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails_with(&args, "", needle);
    };
    let out = csv.to_str().unwrap();
    refused(base(urdf.to_str().unwrap(), &[]), "is the model's file");
    assert_eq!(std::fs::read(&urdf).unwrap(), before);
    refused(
        base(out, &["--substeps", "0"]),
        "--substeps must be at least 1",
    );
    refused(
        base(out, &["--duration", "0.105"]),
        "not a whole number of --dt",
    );
    refused(base(out, &["--dt", "1e-300"]), "more than 1e7");
    refused(
        base(out, &["--substeps", "1000000000"]),
        "more than 1e9 sub-steps",
    );
    refused(
        base(out, &["--effort-until", "NaN"]),
        "--effort-until must be",
    );
    refused(base(out, &["--effort-until=-1"]), "--effort-until must be");
    refused(
        base(out, &["--initial", r#"{"joint1": 0.1, "joint1": 0.2}"#]),
        "--initial: joint 'joint1' is named twice",
    );
    // Checked with or without contact points.
    refused(
        base(out, &["--ground-stiffness=-1"]),
        "--ground-stiffness: ground stiffness is -1",
    );
    assert!(!csv.exists());

    std::fs::write(&csv, "earlier").unwrap();
    let floating = |initial: &str| -> Vec<String> {
        let mut args = base(out, &["--floating-base", "--initial", initial]);
        args.retain(|a| a != "--urdf" && !a.ends_with("arm.urdf"));
        args
    };
    refused(
        floating(r#"{"root_joint": [0, 0, 0, 0, 0, 0, 0]}"#),
        "is (nearly) zero or too large to normalise",
    );
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "earlier");
    let args = floating(r#"{"root_joint": [0, 0, 1, 0, 0, 0, 2]}"#);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run_ok(&args, "");
    let text = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let first: Vec<f64> = text
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    let w = header
        .iter()
        .position(|c| *c == "root_joint.position[6]")
        .unwrap();
    assert_eq!(first[w], 1.0, "{text}");
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs the program, which must end within `seconds` (it is killed otherwise and the test
/// fails); whether it succeeded, and its standard error.
fn run_within(args: &[&str], seconds: u64) -> (bool, String) {
    use std::io::Read;
    let mut child = Command::new(env!("CARGO_BIN_EXE_spatial_dynamics"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(seconds);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("{args:?} still running after {seconds} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (status.success(), err)
}

/// `bench` refuses, at once and naming the flag, settings past its limits: states whose memory
/// passes 1 GiB (on the reduced model and on the full one timed beside it), more than a million
/// repeats, repeats longer than an hour, simulation runs of more than 10⁹ steps.
#[test]
fn bench_refuses_settings_past_their_limits() {
    let huge = "18446744073709551615";
    // pendulum:1 holds 1 + 2·1 numbers a state, 96 bytes with the bookkeeping.
    let most = (1usize << 30) / 96;
    let just_over = (most + 1).to_string();
    let cases: [(&[&str], String); 9] = [
        (&["--states", huge], format!("--states {huge}")),
        (&["--states", "100000000"], format!("at most {most} states")),
        (
            &["--states", just_over.as_str()],
            format!("--states {just_over}"),
        ),
        (&["--repeats", huge], format!("--repeats {huge}")),
        (&["--repeats", "1000001"], "--repeats 1000001".into()),
        (&["--min-time", "1e300"], "--min-time".into()),
        (&["--min-time", "3601"], "--min-time".into()),
        (
            &["--kernels", "sim_rk4", "--sim-steps", huge],
            format!("--sim-steps {huge}"),
        ),
        (&["--sim-steps", "1000000001"], "--sim-steps".into()),
    ];
    for (flags, needle) in cases {
        let args = [&["bench", "--builtin", "pendulum:1"], flags].concat();
        let (ok, err) = run_within(&args, 20);
        assert!(!ok && err.contains(&needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // The default arm's first three joints fit 5 000 000 states; the full arm, timed beside
    // them, does not.
    let (ok, err) = run_within(&["bench", "--tip", "link3", "--states", "5000000"], 20);
    assert!(!ok && err.contains("--states 5000000"), "{err}");
    // Within the limits it runs.
    let (v, out) = bench_json(&[
        "--builtin",
        "pendulum:1",
        "--kernels",
        "rnea,rnea_rows,sim_rk4",
        "--states",
        "70",
        "--repeats",
        "3",
        "--sim-steps",
        "10",
    ]);
    for kernel in ["rnea", "rnea_rows", "sim_rk4"] {
        assert!(v["ns_per_call"][kernel].as_f64().unwrap() > 0.0, "{out}");
    }
}

/// `--sim-initial` is always checked, whether a simulation kernel is timed or not: a JSON
/// object with no keys but "q" and "v", each an array of the model's length; an error names the
/// flag and the key.
#[test]
fn bench_checks_the_simulation_initial_state() {
    for (kernels, initial, needle) in [
        ("sim_rk4", r#"{"Q":[1.0]}"#, r#"unknown key "Q""#),
        ("sim_rk4", "[1.0]", "expected a JSON object"),
        ("rnea", "not json", "not JSON"),
        ("rnea", r#"{"Q":[1.0]}"#, r#"unknown key "Q""#),
        (
            "rnea",
            r#"{"q":[1.0,2.0]}"#,
            r#""q" must be an array of 1 finite numbers"#,
        ),
        (
            "sim_rk4",
            r#"{"v":[null]}"#,
            r#""v" must be an array of 1 finite numbers"#,
        ),
        ("sim_rk4", r#"{"q":1.0}"#, r#""q" must be an array"#),
    ] {
        let args = [
            "bench",
            "--builtin",
            "pendulum:1",
            "--kernels",
            kernels,
            "--states",
            "4",
            "--repeats",
            "1",
            "--min-time",
            "0.001",
            "--sim-steps",
            "10",
            "--sim-initial",
            initial,
        ];
        let (ok, err) = run_within(&args, 20);
        assert!(
            !ok && err.contains("--sim-initial") && err.contains(needle),
            "{initial}: {err}"
        );
    }
    let (v, out) = bench_json(&[
        "--builtin",
        "pendulum:1",
        "--kernels",
        "sim_rk4",
        "--repeats",
        "1",
        "--sim-steps",
        "10",
        "--sim-initial",
        r#"{"v":[2.0]}"#,
    ]);
    assert!(
        v["sim_end"]["sim_rk4"]["q"][0].as_f64().unwrap() > 0.01,
        "{out}"
    );
}

/// The simulation kernels run on models with mimic joints (by CRBA, which takes them).
#[test]
fn bench_simulates_mimic_models() {
    for kernel in ["sim_rk4", "sim_semi_implicit_euler"] {
        let (v, out) = bench_json(&[
            "--builtin",
            "mimic_gripper",
            "--kernels",
            kernel,
            "--repeats",
            "1",
            "--sim-steps",
            "10",
        ]);
        assert!(v["ns_per_call"][kernel].as_f64().unwrap() > 0.0, "{out}");
        assert!(v["sim_end"][kernel]["q"].is_array(), "{out}");
    }
}
